"""``--overwrite`` never loses the file it replaces (issue 26, defect 1).

Every refusal of a run or a sweep happens before the output or its journal is touched, and a
replaced file stays in place, byte for byte, until its successor is complete: a refused,
failed, killed or interrupted ``--overwrite`` leaves the old file as it was, ``--resume``
finishes the replacement, and the finished replacement holds exactly a clean run's numbers.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import HANG_GUARD_S, comparable
from test_store_safety import (
    SMALL,
    TINY_SWEEP,
    FailingExecutor,
    arrays,
    assert_same,
    invoke,
    kill,
    one_line_error,
    start,
    wait_for_chunks,
)

from antisync.execution.runner import run_config
from antisync.plan.config import load_config
from antisync.store import ResultStore

REPO = Path(__file__).resolve().parents[1]

# two triangles joined by a bridge so weak that xi_2 rounds to zero: the exact measures refuse
# the graph, after the options and the graph itself were found valid
WEAK_BRIDGE = "1 2\n2 3\n3 1\n4 5\n5 6\n6 4\n3 4 1e-14\n"


class FailingAcrossStages(FailingExecutor):
    """FailingExecutor counting chunks over every ``run`` call (a sweep calls it per stage)."""

    def __init__(self, after: int):
        super().__init__(after)
        self.seen = 0

    def run(self, work):
        for item in self.inner.run(work):
            if self.seen == self.after:
                raise self.exc("device lost")
            self.seen += 1
            yield item


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def leftovers(folder: Path, keep: set[str]) -> list[str]:
    """Names in ``folder`` beyond ``keep``: journals, temporary files, locks."""
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


@pytest.fixture
def small(tmp_path) -> Path:
    p = tmp_path / "small.yaml"
    p.write_text(SMALL)
    (tmp_path / "weak.edges").write_text(WEAK_BRIDGE)
    return p


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> dict:
    """A clean run of SMALL (seed 8) and a clean tiny sweep, to compare replacements with."""
    from antisync.sweeps import load_sweep_text, run_sweep, sweep_summary

    d = tmp_path_factory.mktemp("clean")
    (d / "small.yaml").write_text(SMALL)
    run = run_config(load_config(d / "small.yaml", ["seed=8"]), output=d / "s8.h5")
    sweep = run_sweep(load_sweep_text(TINY_SWEEP, ["seed=4"]), output=d / "tiny.h5", progress=False)
    return {"run": arrays(run), "sweep": comparable(sweep_summary(sweep))}


# every way a run can be refused, early (options, graph, model) or late (a measure that
# rejects the graph once the run has taken the lock)
RUN_REFUSALS = [
    ["--set", "dynamics.dt=5"],
    ["--set", 'edges=["9->8"]'],
    ["--set", "model.frequencies=[1, 2]"],
    [
        "--set",
        "graph={kind: edgelist, path: weak.edges}",
        "--set",
        "edges=all",
        "--set",
        "measures=[km, xi2]",
    ],
]


@pytest.mark.parametrize("bad", RUN_REFUSALS, ids=["dt", "edge", "frequencies", "measure"])
def test_a_refused_run_overwrite_leaves_the_old_file_byte_for_byte(tmp_path, small, bad):
    out = tmp_path / "o.h5"
    assert invoke("run", small, "--out", out, "--quiet", "--set", "realizations=40").exit_code == 0
    before = digest(out)
    res = invoke("run", small, "--out", out, "--quiet", "--overwrite", *bad)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert digest(out) == before
    assert leftovers(tmp_path, {"o.h5", "small.yaml", "weak.edges"}) == []


SWEEP_REFUSALS = [
    ["--set", "dynamics.dt=5"],
    ["--set", 'edges=["9->8"]'],
    ["--set", "model.frequencies=[1, 2]"],
    ["--set", "top.betas=[2]"],
]


@pytest.mark.parametrize("bad", SWEEP_REFUSALS, ids=["dt", "edge", "frequencies", "top"])
def test_a_refused_sweep_overwrite_leaves_the_old_file_and_no_journal(tmp_path, bad):
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(TINY_SWEEP)
    out = tmp_path / "tiny.h5"
    assert invoke("sweep", cfg, "--out", out).exit_code == 0
    before = digest(out)
    res = invoke("sweep", cfg, "--out", out, "--overwrite", *bad)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert digest(out) == before
    # nothing left to refuse the corrected command with ("already exists ... --resume")
    assert leftovers(tmp_path, {"tiny.h5", "tiny.yaml"}) == []


def test_a_refused_new_sweep_leaves_no_journal(tmp_path):
    """The screening refuses the sweep (every graph excluded) after its journal was started:
    the journal goes with the failure, so the corrected command runs without --resume."""
    cfg = tmp_path / "tiny.yaml"
    # rings end in twisted states from some random starts: the screening excludes all three
    cfg.write_text(
        "sweep:\n  family: graphs\n  graphs:\n"
        + "".join(
            f"    - {{kind: networkx, generator: cycle_graph, args: {{n: {n}}}, name: C{n}}}\n"
            for n in (9, 10, 11)
        )
        + "realizations: 40\nbetas: []\nscreen: {realizations: 60, t_max: 60}\n"
    )
    out = tmp_path / "new.h5"
    res = invoke("sweep", cfg, "--out", out)
    assert res.exit_code == 2 and "every graph was excluded" in res.output, res.output
    assert leftovers(tmp_path, {"tiny.yaml"}) == []


def test_a_failed_overwrite_keeps_the_old_file_until_resume_completes_it(tmp_path, small, clean):
    out = tmp_path / "o.h5"
    config = load_config(small)
    run_config(config, output=out)
    before = digest(out)
    replacement = load_config(small, ["seed=8"])
    store = ResultStore(out)
    with pytest.raises(RuntimeError, match="device lost"):
        # checkpoints after every chunk: the replacement's progress is saved, away from o.h5
        run_config(replacement, output=out, overwrite=True, executor=FailingExecutor(6), checkpoint_seconds=0)
    assert digest(out) == before
    assert store.replacing and store.current.is_file()
    # the old file is still what a reader gets, and a plain run still refuses to touch it
    assert "already exists" in one_line_error(invoke("run", small, "--out", out, "--seed", "8"))
    assert digest(out) == before
    run_config(replacement, output=out, resume=True)
    assert_same(clean["run"], arrays(out))
    assert leftovers(tmp_path, {"o.h5", "small.yaml", "weak.edges"}) == []


def test_another_overwrite_restarts_an_interrupted_replacement(tmp_path, small, clean):
    out = tmp_path / "o.h5"
    run_config(load_config(small), output=out)
    before = digest(out)
    with pytest.raises(RuntimeError):
        run_config(
            load_config(small, ["seed=9"]),
            output=out,
            overwrite=True,
            executor=FailingExecutor(4),
            checkpoint_seconds=0,
        )
    assert digest(out) == before
    run_config(load_config(small, ["seed=8"]), output=out, overwrite=True)
    assert_same(clean["run"], arrays(out))
    assert leftovers(tmp_path, {"o.h5", "small.yaml", "weak.edges"}) == []


def test_kill_during_overwrite_leaves_the_old_file(tmp_path, small, clean):
    out = tmp_path / "k.h5"
    assert invoke("run", small, "--out", out, "--quiet").exit_code == 0
    before = digest(out)
    proc = start("run", small, "--out", out, "--overwrite", "--seed", "8", "--quiet")
    wait_for_chunks(tmp_path / "k.h5.partial", 3, proc)
    kill(proc)
    assert digest(out) == before
    res = subprocess.run(
        [sys.executable, "-m", "antisync", "run", str(small), "--out", str(out), "--seed", "8", "--resume"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert res.returncode == 0, res.stderr
    assert_same(clean["run"], arrays(out))
    assert leftovers(tmp_path, {"k.h5", "small.yaml", "weak.edges"}) == []


def test_a_failed_sweep_overwrite_in_its_top_stage_keeps_the_old_file(tmp_path, clean):
    """The main stage's final checkpoint precedes the top stage: an unfinished replacement
    sweep keeps it in the journal, never in place of the old file."""
    from antisync.sweeps import load_sweep_text, run_sweep, sweep_summary

    out = tmp_path / "tiny.h5"
    run_sweep(load_sweep_text(TINY_SWEEP), output=out, progress=False)
    before = digest(out)
    sw = load_sweep_text(TINY_SWEEP, ["seed=4"])
    # the main stage's 3 graphs x 3 blocks finish, then the top stage's first chunk fails
    with pytest.raises(RuntimeError, match="device lost"):
        run_sweep(
            sw,
            output=out,
            overwrite=True,
            progress=False,
            executor=FailingAcrossStages(9),
            chunk_realizations=20,
        )
    assert digest(out) == before
    assert ResultStore(out).replacing
    run_sweep(sw, output=out, resume=True, progress=False)
    assert comparable(sweep_summary(out)) == clean["sweep"]
    assert leftovers(tmp_path, {"tiny.h5"}) == []
