"""The stopping rule in sweeps (issue 30): one rule over every job of the main stage.

A grid sweep of the lollipop's 2->1 (antifragile) and 2->3 (fragile) at two phase lags: every
sign is resolved after a few hundred RK4 realizations, far below the budget. The stopped
file is compared, dataset by dataset, with a plain sweep of the realizations it stopped at.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import CrashAfter, assert_one_line, comparable, datasets, sweep_cli
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.store import stop_record
from antisync.sweeps import load_sweep, load_sweep_text, run_sweep, sweep_summary

PLAIN = """
name: gstop
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3"]
sweep:
  grid: {model.phase_lag: [0, 0.2]}
betas: []
realizations: 3200
block_size: 100
seed: 5
dynamics: {dt: 0.04, integrator: rk4, t_max: 60}
screen: {realizations: 16, t_max: 100}
"""
STOP = PLAIN + "stop: {when: signs-resolved, first_look: 200}\n"
BUDGET = 3200


def _same_numbers(a, b) -> None:
    da, db = datasets(a, "jobs"), datasets(b, "jobs")
    assert sorted(da) == sorted(db)
    for name in da:
        assert np.array_equal(da[name], db[name]), name
    assert sweep_summary(a)["records"] == sweep_summary(b)["records"]


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    """The stopped grid sweep (through the CLI), and a plain sweep of as many realizations."""
    folder = tmp_path_factory.mktemp("sweep_stop")
    cfg, out = sweep_cli(folder, "gstop", STOP)
    n = stop_record(out)["stopped_at"]
    _, plain = sweep_cli(folder, "plain", PLAIN.replace(f"realizations: {BUDGET}", f"realizations: {n}"))
    return cfg, out, plain, n


def test_a_grid_sweep_stops_when_every_sign_is_known(stopped):
    _, out, _, n = stopped
    rec = stop_record(out)
    assert rec["stopped_early"] and n in rec["looks"][:-1] and rec["budget"] == BUDGET
    assert rec["looks"] == [200, 400, 800, 1600, 3200]
    # every link of every grid point was looked at together
    assert rec["last_look"]["links"] == 4 and rec["last_look"]["resolved"] == 4
    s = sweep_summary(out)
    assert s["complete"]
    signs = {(r["point"], r["edge"]): np.sign(r["lambda_km"]) for r in s["records"]}
    assert signs == {
        ("model.phase_lag=0", "2->1"): 1,
        ("model.phase_lag=0", "2->3"): -1,
        ("model.phase_lag=0.2", "2->1"): 1,
        ("model.phase_lag=0.2", "2->3"): -1,
    }
    assert all(r["realizations"] == n for r in s["records"])


def test_a_stopped_sweep_holds_exactly_a_plain_sweep_of_as_many_realizations(stopped):
    _, out, plain, _ = stopped
    _same_numbers(out, plain)
    assert stop_record(plain) is None


def test_summary_of_a_stopped_sweep_says_where_it_stopped(stopped):
    _, out, plain, n = stopped
    runner = CliRunner()
    res = runner.invoke(app, ["summary", str(out)])
    assert res.exit_code == 0, res.output
    last = res.output.rstrip().splitlines()[-1]
    assert last.startswith(f"stop: the rule ended the sweep at {n:,} of {BUDGET:,} realizations")
    assert "4 of 4 link signs resolved" in last
    data = json.loads(runner.invoke(app, ["summary", str(out), "--format", "json"]).output)
    assert data["kind"] == "sweep" and data["stop"] == stop_record(out)
    # every link the rule resolved is called by the summary's Benjamini-Hochberg too
    assert [r["sign_resolved"] for r in data["records"]] == [1, -1, 1, -1]
    res = runner.invoke(app, ["summary", str(plain)])
    assert "stop:" not in res.output


def test_resuming_a_stopped_sweep_leaves_it_alone(stopped):
    cfg, out, _, n = stopped
    before = (out.stat().st_ino, out.stat().st_mtime_ns, out.read_bytes())
    said: list[str] = []
    run_sweep(load_sweep(cfg), output=out, resume=True, progress=False, log=said.append)
    assert (out.stat().st_ino, out.stat().st_mtime_ns, out.read_bytes()) == before
    assert said == [
        f"{out} is already complete: the stopping rule ended it at {n:,} of {BUDGET:,} "
        "realizations; nothing to do"
    ]


def test_a_killed_stopped_sweep_resumes_to_the_same_file(stopped, tmp_path):
    """Killed past the first look (2 jobs, chunks of 100: 4 chunks to a look at 200), then
    --resume: the numbers and the stopping record of the uninterrupted sweep."""
    cfg, ref, _, _ = stopped
    out = tmp_path / "k.h5"
    with pytest.raises(RuntimeError, match="killed"):
        run_sweep(load_sweep(cfg), output=out, progress=False, chunk_realizations=100, executor=CrashAfter(6))
    assert (tmp_path / "k.h5.partial").exists()
    res = CliRunner().invoke(app, ["sweep", str(cfg), "--out", str(out), "--resume", "-q"])
    assert res.exit_code == 0, res.output
    _same_numbers(out, ref)
    assert stop_record(out) == stop_record(ref)
    assert comparable(sweep_summary(out)) == comparable(sweep_summary(ref))


def test_the_stop_section_round_trips_through_the_stored_config():
    sw = load_sweep_text(STOP)
    assert sw.base.stop.active and all(p.config.stop.active for p in sw.points)
    assert sw.key()["stop"]["when"] == "signs-resolved"
    assert load_sweep_text(sw.to_yaml()).key() == sw.key()
    assert "stop" not in load_sweep_text(PLAIN).key()  # files of plain sweeps resume as before


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        # a family sweep with a top stage: the rule ends only the main stage
        ("sweep: {family: lollipop, nodes: 5, path: 2}\ntop: {graphs: 1}\n", "stop: with top.graphs > 0"),
        (
            "graph: {kind: lollipop, nodes: 5, path: 2}\nsweep: {grid: {realizations: [400, 800]}}\n",
            "stop: with a grid over realizations",
        ),
        (
            "graph: {kind: lollipop, nodes: 5, path: 2}\nsweep: {grid: {stop.tolerance: [0, 0.1]}}\n",
            "stop.tolerance cannot be swept (stop: is one rule over every job of the sweep)",
        ),
    ],
)
def test_what_a_rule_cannot_combine_with_is_one_line_and_touches_nothing(tmp_path, extra, message):
    text = f"betas: []\nrealizations: 800\nstop: {{when: signs-resolved}}\n{extra}"
    with pytest.raises(ConfigError) as exc:
        load_sweep_text(text)
    assert message in str(exc.value) and "\n" not in str(exc.value)
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    res = CliRunner().invoke(app, ["sweep", str(cfg), "--out", str(tmp_path / "bad.h5")])
    assert_one_line(res, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


def test_a_family_sweep_stops_over_every_graph_and_threshold(tmp_path):
    """No grid: the lollipop family at two thresholds, every job in one look; validate lists
    the looks."""
    text = STOP.replace("graph: {kind: lollipop, nodes: 6, path: 3}\n", "").replace(
        "sweep:\n  grid: {model.phase_lag: [0, 0.2]}\n",
        "sweep: {family: lollipop, nodes: 6, path: 3}\nthresholds: [0.9, 0.99]\n",
    )
    cfg = tmp_path / "fam.yaml"
    cfg.write_text(text)
    res = CliRunner().invoke(app, ["validate", str(cfg)])
    assert res.exit_code == 0, res.output
    assert (
        "up to 3,200 realizations (stop signs-resolved: looks at 200, 400, 800, 1,600, 3,200)" in res.output
    )
    out = run_sweep(load_sweep(cfg), output=tmp_path / "fam.h5", progress=False)
    rec = stop_record(out)
    assert rec["stopped_early"] and rec["last_look"]["links"] == 2 * 2
    assert all(r["realizations"] == rec["stopped_at"] for r in sweep_summary(out)["records"])
