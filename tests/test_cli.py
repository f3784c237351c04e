"""The command line as a user meets it: runs, summaries, reports, bad input, resume."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from antisync.cli.app import app

runner = CliRunner()
REPO = Path(__file__).resolve().parent.parent


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture
def cfg(tmp_path, small_config_text):
    p = tmp_path / "small.yaml"
    p.write_text(small_config_text)
    return p


def _arrays(path):
    with h5py.File(path, "r") as f:
        (g,) = f["jobs"].values()
        return {
            k: g[k][...] for k in ("block_records", "tau0_records", "hist", "tail_counts", "blocks_done")
        } | {"kept": g["kept/steps"][...]}


def test_run_summary_report(tmp_path, cfg):
    out = tmp_path / "r.h5"
    res = invoke("run", cfg, "--out", out, "--quiet")
    assert res.exit_code == 0, res.output
    assert out.exists() and not (tmp_path / "r.h5.partial").exists()
    res = invoke("summary", out, "--format", "json")
    assert res.exit_code == 0
    data = json.loads(res.stdout)
    assert data["kind"] == "run" and data["complete"] and data["excluded"] == []
    recs = data["records"]
    assert [(r["edge"], r["beta"]) for r in recs] == [("2->1", 0.5), ("2->3", 0.5)]
    needed = {
        "graph",
        "edge",
        "beta",
        "F_mean",
        "F_se",
        "lambda_km",
        "lambda_km_se",
        "tau0_mean",
        "tau0_se",
        "n",
        "n_excluded",
        "n_not_synced",
    }
    assert needed <= set(recs[0])
    assert recs[0]["n"] + recs[0]["n_excluded"] + recs[0]["n_not_synced"] == 120
    assert recs[0]["F_mean"] > 1 > recs[1]["F_mean"]  # 2->1 antifragile, 2->3 fragile
    for fmt in ("table", "csv"):
        assert invoke("summary", out, "--format", fmt).exit_code == 0
    res = invoke("report", out, "--out", tmp_path / "fig", "--pdf", "--quiet")
    assert res.exit_code == 0, res.output
    pngs = sorted(p.name for p in (tmp_path / "fig").glob("*.png"))
    # named after the config (small.yaml, no name: its file name)
    assert "small_graph.png" in pngs and "small_F_beta.png" in pngs
    assert "small_histograms.png" in pngs
    assert (tmp_path / "fig" / "small_graph.pdf").exists()
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == "antisync-results"
        assert "graph:" in f.attrs["config_yaml"] and f.attrs["complete"]
        g = f["jobs/lollipop_6_3"]
        assert g.attrs["seed"] == 3 and g.attrs["backend"] == "cpu" and g.attrs["seconds"] > 0


def test_module_entry_point_and_validate(cfg):
    res = subprocess.run(
        [sys.executable, "-m", "antisync", "validate", str(cfg)], capture_output=True, text=True, cwd=REPO
    )
    assert res.returncode == 0, res.stderr
    assert "# ok: graph lollipop_6_3 with 6 nodes, 2 directed edge(s)" in res.stdout


def test_validate_counts_every_integration_per_realization():
    """Damaged variants: one per (edge, beta) plus the dbeta one for Lambda; with
    ``lambda.method: orbit`` the +-dbeta pair of each edge's orbit instead."""
    lollipop6 = REPO / "configs" / "lollipop6.yaml"
    for sets, variants in ((["betas=[]"], 12), ([], 120), (["betas=[]", "lambda.method=orbit"], 24)):
        res = invoke("validate", lollipop6, *[a for s in sets for a in ("--set", s)])
        assert res.exit_code == 0, res.output
        assert f", 12 directed edge(s), {variants} damaged variant(s)" in res.output, sets


def test_existing_result_is_never_overwritten(tmp_path, cfg):
    out = tmp_path / "r.h5"
    out.write_bytes(b"precious")
    res = invoke("run", cfg, "--out", out, "--quiet")
    assert res.exit_code == 2
    assert "already exists" in res.stderr and "--resume" in res.stderr
    assert out.read_bytes() == b"precious"


def test_same_numbers_for_threads_and_chunk_sizes(tmp_path, cfg):
    outs = []
    for i, extra in enumerate(
        [
            ["--threads", "1", "--set", "chunk_size=20"],
            ["--threads", "2", "--set", "chunk_size=60"],
            ["--threads", "2"],
        ]
    ):
        out = tmp_path / f"r{i}.h5"
        assert invoke("run", cfg, "--out", out, "--quiet", *extra).exit_code == 0
        outs.append(_arrays(out))
    for other in outs[1:]:
        for k in outs[0]:
            assert np.array_equal(outs[0][k], other[k]), k


def test_sigkill_then_resume_gives_identical_numbers(tmp_path, small_config_text):
    cfg = tmp_path / "kill.yaml"
    cfg.write_text(small_config_text.replace("realizations: 120", "realizations: 600") + "chunk_size: 20\n")
    ref = tmp_path / "ref.h5"
    assert invoke("run", cfg, "--out", ref, "--quiet").exit_code == 0
    out = tmp_path / "killed.h5"
    journal = tmp_path / "killed.h5.partial"
    proc = subprocess.Popen(
        [sys.executable, "-m", "antisync", "run", str(cfg), "--out", str(out), "--quiet"], cwd=REPO
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(journal.glob("*.npz"))) < 3:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert journal.exists(), "the run was killed before it saved anything"
    res = invoke("run", cfg, "--out", out, "--quiet")
    assert res.exit_code == 2  # no silent continuation without --resume
    res = invoke("run", cfg, "--out", out, "--resume", "--quiet")
    assert res.exit_code == 0, res.output
    a, b = _arrays(ref), _arrays(out)
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    # resuming a finished run changes nothing
    assert invoke("run", cfg, "--out", out, "--resume", "--quiet").exit_code == 0
    for k, v in _arrays(out).items():
        assert np.array_equal(a[k], v), k


def test_resume_refuses_a_different_config(tmp_path, cfg):
    out = tmp_path / "r.h5"
    assert invoke("run", cfg, "--out", out, "--quiet").exit_code == 0
    before = out.read_bytes()
    res = invoke("run", cfg, "--out", out, "--resume", "--seed", "99", "--quiet")
    assert res.exit_code == 2 and "different config" in res.stderr
    assert out.read_bytes() == before


G = "graph: {kind: lollipop, nodes: 6, path: 3}\n"
BAD_CONFIGS = [
    ("graph: {kind: lollipop, nodes: 6, path: 3\n", "invalid YAML"),
    (G + "realisations: 10\n", "did you mean 'realizations'"),
    (G + "betas: [0.5, 1.0]\n", "betas must lie in [0, 1)"),
    (G + "betas: [-0.1]\n", "betas must lie in [0, 1)"),
    (G + "dynamics: {threshold: 1.2}\n", "threshold must be in (0, 1)"),
    (G + "dynamics: {dt: 0}\n", "dynamics.dt must be a positive"),
    (G + "dynamics: {t_max: -5}\n", "dynamics.t_max must be a positive"),
    (G + "realizations: 0\n", "realizations must be an integer in 1..10**15"),
    (G + 'edges: ["1->3"]\n', "edge '1->3' is not in the graph"),
    ("graph: {kind: lolipop, nodes: 6, path: 3}\n", "did you mean 'lollipop'"),
    ("graph: {kind: lollipop, nodes: 6}\n", "needs key(s) path"),
    ("graph: {kind: networkx, generator: not_a_graph}\n", "unknown networkx generator"),
    ("graph: {kind: edgelist, path: two.edges}\n", "disconnected"),
    ("graph: {kind: edgelist, path: missing.edges}\n", "cannot read edge list"),
    (G + "dynamics: {coupling: weird}\n", "coupling must be one of"),
    (G + "backend: gpu\n", "backend must be one of"),
    (G + "lambda: {dbeta: 0}\n", "lambda.dbeta must be in (0, 1)"),
]


@pytest.mark.parametrize("text,message", BAD_CONFIGS)
def test_bad_config_is_one_clear_line(tmp_path, text, message):
    (tmp_path / "two.edges").write_text("1 2\n3 4\n")
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    out = tmp_path / "existing.h5"
    out.write_bytes(b"untouched")
    for command in (["run", cfg, "--out", out, "--overwrite"], ["validate", cfg]):
        res = invoke(*command)
        assert res.exit_code == 2, res.output
        assert message in res.stderr
        assert len(res.stderr.strip().splitlines()) == 1
        assert "Traceback" not in res.output
    assert out.read_bytes() == b"untouched"


def test_bad_cli_arguments(tmp_path, cfg):
    res = invoke("run", tmp_path / "nope.yaml")
    assert res.exit_code == 2 and "does not exist" in res.stderr
    res = invoke("run", cfg, "--set", "realizations")
    assert res.exit_code == 2 and "--set expects key=value" in res.stderr
    res = invoke("run", cfg, "--realizations", "-5")
    assert res.exit_code == 2 and "realizations must be an integer in 1..10**15" in res.stderr
    res = invoke("summary", cfg, "--format", "xml")
    assert res.exit_code == 2


@pytest.mark.parametrize("kind", ["text", "foreign", "missing"])
def test_bad_result_files(tmp_path, kind):
    p = tmp_path / "x.h5"
    if kind == "text":
        p.write_text("not hdf5")
    elif kind == "foreign":
        with h5py.File(p, "w") as f:
            f["data"] = np.arange(3)
    for command in ("summary", "report"):
        res = invoke(command, p)
        assert res.exit_code == 2
        assert len(res.stderr.strip().splitlines()) == 1
        assert {
            "text": "not a readable HDF5",
            "foreign": "not an antisync result",
            "missing": "does not exist",
        }[kind] in res.stderr


def test_debug_shows_traceback(tmp_path):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(G + "realizations: 0\n")
    res = invoke("validate", cfg, "--debug")
    assert res.exit_code != 0 and res.exception is not None
