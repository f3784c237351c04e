"""The stopping rule (``stop: {when: signs-resolved}``): looks, equality with a plain run, resume.

The runs are small and coarse (dt = 0.01) but real: the rule looks at the calibrated
intervals of the lollipop's links and the files are compared, dataset by dataset, with a
plain run of the realizations the rule stopped at.
"""

from __future__ import annotations

import json
import subprocess
import sys

import h5py
import numpy as np
import pytest
from helpers import HANG_GUARD_S, datasets

from antisync.api import summarize
from antisync.errors import ConfigError
from antisync.execution.executors.local import LocalExecutor
from antisync.execution.runner import Interrupted, run_config
from antisync.execution.stopping import look_level, stop_note
from antisync.plan.config import load_config_text
from antisync.store import records, stop_record

# 2->1 (Lambda ~ +0.27) resolves after a few hundred realizations, 5->6 (~ +0.13, heavy
# tailed) after a few thousand; 1->2 leaves the path's end: its damage changes nothing
BASE = """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "5->6", "1->2"]
betas: []
realizations: 12800
block_size: 100
seed: 5
dynamics: {dt: 0.01, t_max: 60}
"""
STOP = BASE + "stop: {when: signs-resolved, first_look: 400}\n"


def _config(text: str, *overrides: str):
    return load_config_text(text, list(overrides))


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "antisync", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )


def _same_numbers(a, b) -> None:
    """Every dataset and every record of two result files equal (provenance aside)."""
    da, db = datasets(a), datasets(b)
    assert sorted(da) == sorted(db)
    for name in da:
        assert np.array_equal(da[name], db[name]), name
    assert records(a) == records(b)


class CountingExecutor:
    """A local executor that raises ``KeyboardInterrupt`` (Ctrl-C) at its ``after``-th chunk,
    counted over every call of ``run`` (the runner calls it once per look)."""

    def __init__(self, after: int | None = None):
        self.inner, self.after, self.seen = LocalExecutor("cpu", None), after, 0

    def run(self, work):
        for item in self.inner.run(work):
            if self.seen == self.after:
                raise KeyboardInterrupt
            self.seen += 1
            yield item

    def describe(self):
        return "counting"

    def close(self):
        self.inner.close()


# ---- the looks -----------------------------------------------------------------------------------
def test_looks_double_from_the_first_to_the_budget():
    cfg = _config(STOP)
    assert cfg.stop_looks == [400, 800, 1600, 3200, 6400, 12800]
    assert cfg.stop.active and look_level(6) == pytest.approx(1 - 0.05 / 6)
    # a first look inside a block is rounded up to the block; a budget off the doubling is the last look
    assert _config(STOP, "stop.first_look=250", "realizations=3000").stop_looks == [
        300,
        600,
        1200,
        2400,
        3000,
    ]
    # auto: 32 blocks, at least 2,000 realizations
    assert _config(STOP, "stop.first_look=auto").stop_looks == [3200, 6400, 12800]
    assert _config(BASE).stop_looks == [12800] and not _config(BASE).stop.active
    # without a rule, nothing about stopping enters the stored config (old files resume as before)
    assert "stop" not in _config(BASE).simulation_key() and "stop" in _config(STOP).simulation_key()


@pytest.mark.parametrize(
    ("override", "words"),
    [
        ("stop.when=soon", "stop.when must be one of never, signs-resolved, got 'soon'"),
        ("stop.first_look=20000", "stop.first_look (20,000) is more than realizations (12,800)"),
        ("stop.first_look=0", "stop.first_look must be"),
        ("stop.tolerance=-0.1", "stop.tolerance must be a number >= 0"),
        ("stop.tolerance=yes", "stop.tolerance must be a number >= 0"),
        ("stop.after=5", "stop.after"),
        ("measures=[xi2]", "stop.when signs-resolved watches Lambda^KM: measures must include km"),
    ],
)
def test_bad_stop_options_are_one_line_errors(override, words):
    with pytest.raises(ConfigError, match=None) as err:
        _config(STOP, override)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_bad_stop_option_on_the_command_line_exits_2_and_writes_nothing(tmp_path):
    cfg = tmp_path / "s.yaml"
    cfg.write_text(STOP)
    res = _cli("run", cfg, "--set", "stop.when=soon", "--out", tmp_path / "o.h5")
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "stop.when must be one of never, signs-resolved" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.yaml"]


def test_a_sweep_takes_a_stop_section_without_a_top_stage():
    """The rule looks at every main-stage job of a sweep together (tests/test_sweep_stop.py);
    a top stage, which ranks the graphs on the finished main stage, is refused with it."""
    from antisync.sweeps.schema import load_sweep_text

    text = """
sweep: {family: lollipop, path: 1, nodes: "4..5"}
edges: fig2
realizations: 100
stop: {when: signs-resolved}
"""
    assert load_sweep_text(text).base.stop_looks == [100]
    with pytest.raises(ConfigError, match="stop: with top.graphs > 0"):
        load_sweep_text(text + "top: {graphs: 1}\n")


# ---- runs --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """The rule's run, its log, and a plain run of the realizations it stopped at."""
    tmp = tmp_path_factory.mktemp("stop")
    said: list[str] = []
    path = run_config(_config(STOP), output=tmp / "stopped.h5", log=said.append)
    n = stop_record(path)["stopped_at"]
    plain = run_config(_config(BASE, f"realizations={n}"), output=tmp / "plain.h5")
    return path, said, plain, n


def test_the_rule_stops_when_every_sign_is_known(stopped):
    path, said, _, n = stopped
    rec = stop_record(path)
    assert rec["stopped_early"] and n in rec["looks"][:-1] and rec["budget"] == 12800
    look = rec["last_look"]
    assert look["resolved"] == 2 and look["settled"] == 1 and look["unresolved"] == []
    # every look before the last one left a link open, and said which
    lines = [m for m in said if m.startswith("stop:")]
    assert len(lines) == rec["looks"].index(n) + 1
    assert all("open:" in m for m in lines[:-1]) and lines[-1].endswith("stopping")
    recs = records(path)
    assert {r["edge"]: np.sign(r["lambda_km"]) for r in recs} == {"2->1": 1, "5->6": 1, "1->2": 0}
    assert all(r["complete"] and r["realizations"] == n == r["realizations_done"] for r in recs)


def test_a_stopped_file_holds_exactly_a_plain_run_of_as_many_realizations(stopped):
    path, _, plain, _ = stopped
    _same_numbers(path, plain)


def test_summary_says_what_the_rule_did(stopped):
    path, _, plain, n = stopped
    note = stop_note(stop_record(path))
    assert note.startswith(f"stop: the rule ended the run at {n:,} of 12,800 realizations")
    assert "1 neutral" in note
    assert summarize(path)["stop"] == stop_record(path) and summarize(plain)["stop"] is None
    res = _cli("summary", path)
    assert res.returncode == 0 and res.stdout.rstrip().endswith(note[-40:])


def test_resuming_a_stopped_file_leaves_it_alone(stopped, tmp_path):
    path, _, _, n = stopped
    before = (path.stat().st_ino, path.stat().st_mtime_ns, path.read_bytes())
    said: list[str] = []
    assert run_config(_config(STOP), output=path, resume=True, log=said.append) == path
    assert (path.stat().st_ino, path.stat().st_mtime_ns, path.read_bytes()) == before
    assert any(f"the stopping rule ended it at {n:,} of 12,800" in m for m in said), said


def test_an_interrupted_rule_run_resumes_to_the_same_file(stopped, tmp_path):
    """Ctrl-C after a few chunks (past the first look), then --resume: the same numbers."""
    path, _, _, _ = stopped
    out = tmp_path / "i.h5"
    config = _config(STOP)
    with pytest.raises(Interrupted):
        run_config(config, output=out, executor=CountingExecutor(after=6), chunk_realizations=200)
    assert not records(out)[0]["complete"]
    said: list[str] = []
    run_config(config, output=out, resume=True, log=said.append, chunk_realizations=300)
    _same_numbers(out, path)
    assert stop_record(out) == stop_record(path)


def test_a_spent_budget_names_the_open_links(tmp_path):
    """Budget 800: 5->6 is still open at the last look; the file is a plain run of 800."""
    text = STOP.replace("realizations: 12800", "realizations: 800")
    path = run_config(_config(text), output=tmp_path / "b.h5")
    rec = stop_record(path)
    assert not rec["stopped_early"] and rec["stopped_at"] == 800
    assert rec["last_look"]["unresolved"] == ["5->6"]
    assert stop_note(rec).startswith(
        "stop: the budget of 800 realizations is spent"
    ) and "open: 5->6" in stop_note(rec)
    plain = run_config(_config(BASE, "realizations=800"), output=tmp_path / "p.h5")
    _same_numbers(path, plain)
    # a complete run with a spent budget resumes as any complete run: nothing to do
    said: list[str] = []
    run_config(_config(text), output=path, resume=True, log=said.append)
    assert any("already complete" in m for m in said)


def test_a_tolerance_settles_links_whose_effect_is_small(tmp_path):
    """With tolerance 1, 5->6 (|Lambda| ~ 0.13) is settled at the first look: stop at 400."""
    path = run_config(_config(STOP, "stop.tolerance=1.0", "edges=['5->6', '1->2']"), output=tmp_path / "t.h5")
    rec = stop_record(path)
    assert rec["stopped_at"] == 400 and rec["last_look"]["settled"] == 2
    assert "within +-1" in stop_note(rec)


def test_a_damaged_stop_record_is_one_line(tmp_path, stopped):
    path, *_ = stopped
    bad = tmp_path / "bad.h5"
    bad.write_bytes(path.read_bytes())
    with h5py.File(bad, "r+") as f:
        f.attrs["stop_json"] = json.dumps({"when": "signs-resolved"})
    from antisync.errors import StoreError

    with pytest.raises(StoreError, match="stop_json lacks the stopping rule's fields"):
        stop_record(bad)
    res = _cli("summary", bad)
    assert res.returncode == 2 and "Traceback" not in res.stderr and "stop_json" in res.stderr


def test_a_look_counts_no_sign_that_rests_on_a_few_tail_values(tmp_path):
    """``lambda_intervals``' thin flag is exactly the summary's heavy-tail warning, and a look
    leaves those links open: the lollipop's heavy-tailed links at 2,000 RK4 realizations."""
    from antisync.stats.summary import lambda_intervals
    from antisync.store import read_views

    text = BASE.replace('edges: ["2->1", "5->6", "1->2"]', "edges: all")
    cfg = _config(text, "realizations=2000", "dynamics.integrator=rk4", "dynamics.dt=0.04", "seed=1")
    path = run_config(cfg, output=tmp_path / "h.h5")
    (view,) = read_views(path)
    ci, thin = lambda_intervals(view)
    warned = [
        bool((r["lambda_km_warning"] or "").startswith("heavy tail: the interval rests on"))
        for r in records(path)
    ]
    assert thin.tolist() == warned and any(warned)
    low, high = ci.T
    assert np.array_equal(low, [r["lambda_km_ci_low"] for r in records(path)])
    assert np.array_equal(high, [r["lambda_km_ci_high"] for r in records(path)])
