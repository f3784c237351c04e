"""Hostile and careless input: configs, CLI options, graph files and result files.

Every case must end in one line on stderr naming what is wrong, exit code 2, no traceback,
and no file touched (issue 13). Property-based cases (hypothesis) throw arbitrary values at
every config key and arbitrary lines at the edge-list reader: the only outcomes allowed are a
valid config or an :class:`~antisync.errors.AntisyncError`.
"""

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from helpers import assert_one_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import AntisyncError
from antisync.physics.graphs import build_graph, from_edgelist
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job

runner = CliRunner()
REPO = Path(__file__).resolve().parent.parent
G = "graph: {kind: lollipop, nodes: 6, path: 3}\n"
SMALL = G + 'edges: ["2->1"]\nbetas: [0.5]\nrealizations: 20\ndynamics: {t_max: 60}\n'


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def snapshot(folder: Path) -> dict:
    """Every path below ``folder`` with its size and mtime: 'no file touched' is equality."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) if p.is_file() else None
        for p in sorted(folder.rglob("*"))
    }


# ---- configs ----------------------------------------------------------------------------
# (override, what the one line must say): each of these crashed with a traceback, was
# silently accepted, or left a journal behind before issue 13
BAD_OVERRIDES = [
    ("realizations=1e23", "realizations must be an integer in 1..10**15"),
    ("realizations=100000000000000000000000", "realizations must be an integer in 1..10**15"),
    ("realizations=true", "realizations must be an integer"),
    ("realizations=3.7", "realizations must be an integer"),
    ("seed=true", "seed must be an integer"),
    ("seed=-1", "seed must be an integer in 0..2**63-1"),
    ("dynamics.threshold=null", "dynamics.threshold must be in (0, 1)"),
    ("dynamics.threshold=[0.9]", "dynamics.threshold must be in (0, 1)"),
    ("dynamics.threshold=.nan", "dynamics.threshold must be in (0, 1)"),
    ("betas=[0.5, null]", "betas must lie in [0, 1)"),
    ("betas=[abc]", "betas must be a number"),
    ('histogram.betas=["abc"]', "histogram.betas must be a number"),
    ("histogram.betas=7", "histogram.betas must be a list"),
    ("histogram.bins=true", "histogram.bins must be an integer"),
    ("dynamics.t_max=1e30", "steps per trajectory"),
    ("dynamics.dt=1e-300", "steps per trajectory"),
    ("dynamics.dt=5.0", "dynamics.dt = 5 is too large for this graph"),
    ("dynamics.t_max=.inf", "dynamics.t_max must be a positive number"),
    ("keep_pairs=1e12", "keep_pairs must be an integer in 0..10**7"),
    ("threads=0", "threads must be an integer"),
    ("name=[1, 2]", "name must be a string"),
    ("output=[a.h5]", "output must be a string"),
    ("measures=[[km]]", "measures must be names"),
    ("graph={kind: atlas, index: 3.7}", "graph.index must be an integer, got 3.7"),
    ("graph={kind: lollipop, nodes: 6.9, path: 3}", "graph.nodes must be an integer, got 6.9"),
    ("graph={kind: lollipop, nodes: true, path: 3}", "graph.nodes must be an integer"),
    ("graph={kind: networkx, generator: barbell_graph, args: {m1: 1, m2: 0}}", "networkx.barbell_graph"),
    ("graph={kind: networkx, generator: path_graph, args: {n: -1}}", "networkx.path_graph"),
    ("graph={kind: networkx, generator: path_graph, args: [3]}", "graph.args must be a mapping"),
    (
        "graph={kind: networkx, generator: random_regular_graph, args: {d: 3, n: 8, seed: x}}",
        "graph.args.seed must be an integer",
    ),
    ("graph={kind: networkx, generator: 7}", "graph.generator must be a networkx function name"),
    ("dynamics.coupling=raw", ""),  # with the weights below: raw coupling at 1e99 is too stiff
    # `validate` used to say ok to these, which `run` then refused
    ("dynamics={precision: float32, integrator: rk4, dt: 0.04}", "runs dynamics.integrator euler only"),
    ("measures=[km, km_nnc, km_nnc]", "measures lists km_nnc twice"),
]


@pytest.mark.parametrize("override,message", BAD_OVERRIDES)
def test_bad_override_is_one_line_in_run_and_validate(tmp_path, monkeypatch, override, message):
    monkeypatch.chdir(tmp_path)  # a config's default output (results/...) lands here, if anywhere
    cfg = tmp_path / "c.yaml"
    if override == "dynamics.coupling=raw":
        (tmp_path / "heavy.edges").write_text("1 2 1e99\n2 3\n")
        cfg.write_text("graph: {kind: edgelist, path: heavy.edges}\nrealizations: 20\n")
        message = "too large for this graph"
    else:
        cfg.write_text(SMALL)
    out = tmp_path / "out.h5"
    before = snapshot(tmp_path)
    out_option = [] if override.startswith("output=") else ["--out", out]
    for command in (["run", cfg, "--set", override, *out_option, "-q"], ["validate", cfg, "--set", override]):
        assert_one_line(invoke(*command), message)
    assert snapshot(tmp_path) == before  # no output, no journal, nothing else


def test_config_file_that_is_not_utf8_or_a_folder(tmp_path):
    cfg = tmp_path / "latin1.yaml"
    cfg.write_bytes(G.encode() + b"name: caf\xe9\n")
    assert_one_line(invoke("run", cfg), "is not UTF-8 text")
    assert_one_line(invoke("validate", tmp_path), "is a folder")
    assert_one_line(invoke("sweep", cfg), "is not UTF-8 text")


def test_realizations_in_scientific_notation_are_integers():
    assert load_config_text(G + "realizations: 1e6\n").realizations == 1_000_000
    assert load_config_text(G, ["realizations=2.0e3"]).realizations == 2000


# arbitrary values at every key: a valid config or an AntisyncError, nothing else
KEYS = [
    "realizations",
    "seed",
    "betas",
    "edges",
    "name",
    "output",
    "block_size",
    "chunk_size",
    "keep_pairs",
    "threads",
    "backend",
    "executor",
    "measures",
    "dynamics.dt",
    "dynamics.t_max",
    "dynamics.threshold",
    "dynamics.integrator",
    "dynamics.coupling",
    "dynamics.crossing",
    "dynamics.precision",
    "lambda.method",
    "lambda.dbeta",
    "lambda.hybrid_cut",
    "histogram.bins",
    "histogram.tau_max",
    "histogram.betas",
    "linear.realizations",
    "linear.method",
    "graph.nodes",
    "graph.path",
    "graph.kind",
    "dynamics",
    "lambda",
    "histogram",
    "graph",
]
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(),
    st.text(max_size=8),
    st.sampled_from(["1e23", "0.5", "2->1", "all", "auto"]),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=4), inner, max_size=2)
    ),
    max_leaves=5,
)


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(key=st.sampled_from(KEYS), value=values, typed=st.booleans())
def test_any_value_at_any_key_is_valid_or_one_clear_error(key, value, typed):
    """Set as YAML text (``--set``) or as a typed value (the CLI's options)."""
    try:
        if typed:
            cfg = load_config_text(SMALL, values={key: value})
        else:
            cfg = load_config_text(
                SMALL,
                [f"{key}={yaml.safe_dump(value, default_flow_style=True).strip()}".replace("\n...", "")],
            )
        make_job(cfg)
    except AntisyncError as exc:
        assert str(exc) and "\n" not in str(exc).strip()


# ---- CLI options --------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["#scratch.h5", "null", "~", "123", "yes", "2024-01-01"])
def test_out_is_a_path_never_yaml(tmp_path, monkeypatch, name):
    """``--out '#scratch.h5'`` used to be a YAML comment (the config's output was overwritten);
    ``--out 123`` crashed. Each names a file of exactly that name now."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text(SMALL + "output: results/ok.h5\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "ok.h5").write_bytes(b"precious")
    res = invoke("run", "c.yaml", "--out", name, "-q")
    assert res.exit_code == 0, res.output
    assert (tmp_path / name).is_file()
    assert (tmp_path / "results" / "ok.h5").read_bytes() == b"precious"


@pytest.mark.parametrize(
    "option,value,message",
    [
        ("--backend", "gpu", "--backend must be one of cpu, cuda, auto, got 'gpu'"),
        ("--executor", "ray", "--executor must be one of local, dask, got 'ray'"),
        ("--threads", "0", "threads must be an integer in null or 1..4096"),
        ("--realizations", "many", ""),
    ],
)
def test_bad_choice_options_are_one_line(tmp_path, option, value, message):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL)
    before = snapshot(tmp_path)
    res = invoke("run", cfg, option, value, "--out", tmp_path / "o.h5", "-q")
    if option == "--realizations":  # click's own type check: exit 2, usage text, no traceback
        assert res.exit_code == 2 and "Traceback" not in res.output
    else:
        assert_one_line(res, message)
    assert snapshot(tmp_path) == before


def test_output_inside_a_file_is_one_line(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL)
    before = snapshot(tmp_path)
    assert_one_line(invoke("run", cfg, "--out", tmp_path / "c.yaml" / "x.h5", "-q"))
    assert snapshot(tmp_path) == before


# ---- graph files --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,message",
    [
        ("1 2 1.0\n2 3\n1 2 5.0\n", "edge 1-2 is listed twice (first on line 1)"),
        ("1 2\n2 1\n2 3\n", "edge 2-1 is listed twice"),
        ("1 2 nan\n", "weight must be positive and finite"),
        ("1 2 -1\n", "weight must be positive and finite"),
        ("1 2 0\n", "weight must be positive and finite"),
        ("1 2 inf\n", "weight must be positive and finite"),
        ("1 2 1e300\n2 3 1e300\n", "weights sum to"),
        ("1 1\n", "self-loop"),
        ("1\n", "expected 'u v' or 'u v weight'"),
        ("# nothing\n", "no edges found"),
        ("1 2\n3 4\n", "disconnected"),
    ],
)
def test_bad_edge_lists(tmp_path, text, message):
    (tmp_path / "g.edges").write_text(text)
    cfg = tmp_path / "c.yaml"
    cfg.write_text("graph: {kind: edgelist, path: g.edges}\nrealizations: 20\n")
    before = snapshot(tmp_path)
    assert_one_line(invoke("run", cfg, "--out", tmp_path / "o.h5", "-q"), message)
    assert snapshot(tmp_path) == before


def test_edge_list_not_utf8(tmp_path):
    (tmp_path / "g.edges").write_bytes(b"1 2\n2 \xff3\n")
    with pytest.raises(AntisyncError, match="not UTF-8"):
        from_edgelist(tmp_path / "g.edges")


tokens = st.one_of(
    st.sampled_from(["1", "2", "3", "a", "1.5", "-1", "nan", "inf", "1e400", "0", "#", "1e-320"]),
    st.text(max_size=4),
)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(lines=st.lists(st.lists(tokens, max_size=4), max_size=6))
def test_any_edge_list_is_a_graph_or_one_clear_error(tmp_path_factory, lines):
    path = tmp_path_factory.mktemp("edges") / "g.edges"
    path.write_text("\n".join(" ".join(t) for t in lines), encoding="utf-8")
    try:
        g = build_graph({"kind": "edgelist", "path": str(path)})
    except AntisyncError as exc:
        assert "\n" not in str(exc).strip()
        return
    assert g.number_of_nodes() >= 2
    assert all(np.isfinite(d["weight"]) and d["weight"] > 0 for *_, d in g.edges(data=True))


def test_random_generators_take_the_run_seed():
    """An unseeded random graph used to differ on every run (and --resume mixed graphs)."""
    text = G.replace(
        "{kind: lollipop, nodes: 6, path: 3}",
        "{kind: networkx, generator: random_regular_graph, args: {d: 3, n: 8}}",
    )
    a = make_job(load_config_text(text + "seed: 5\n"))
    b = make_job(load_config_text(text + "seed: 5\n"))
    c = make_job(load_config_text(text + "seed: 6\n"))
    assert np.array_equal(a.omega, b.omega)
    assert not np.array_equal(a.omega, c.omega)  # another run seed, another graph (here)
    with pytest.raises(AntisyncError, match="is random: give graph.args.seed"):
        build_graph({"kind": "networkx", "generator": "random_regular_graph", "args": {"d": 3, "n": 8}})


# ---- result files -------------------------------------------------------------------------
def _result(tmp_path) -> Path:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL)
    out = tmp_path / "r.h5"
    assert invoke("run", cfg, "--out", out, "-q").exit_code == 0
    return out


@pytest.mark.parametrize(
    "damage,message",
    [
        ("format_version", "newer antisync"),
        ("edges", "damaged"),
        ("nodes", "damaged"),
        ("drop_records", "damaged"),
        ("empty", "not a readable HDF5"),
        ("folder", ""),
    ],
)
def test_damaged_result_files(tmp_path, damage, message):
    out = _result(tmp_path)
    if damage == "empty":
        out.write_bytes(b"")
    elif damage == "folder":
        out.unlink()
        out.mkdir()
    else:
        with h5py.File(out, "a") as f:
            g = f["jobs/lollipop_6_3"]
            if damage == "format_version":
                f.attrs["format_version"] = 99
            elif damage == "drop_records":
                del g["block_records"]
            else:
                g.attrs[damage] = "[not json"
    before = snapshot(tmp_path)
    for command in (
        ["summary", out],
        ["summary", out, "-f", "json"],
        ["report", out, "--out", tmp_path / "f"],
    ):
        assert_one_line(invoke(*command), message)
    assert snapshot(tmp_path) == before


def test_report_out_is_an_existing_file_or_unwritable(tmp_path):
    out = _result(tmp_path)
    (tmp_path / "taken").write_text("x")
    before = snapshot(tmp_path)
    assert_one_line(invoke("report", out, "--out", tmp_path / "taken"), "is a file")
    # /proc refuses new folders even to root (CI runs as root, so chmod would not do)
    assert_one_line(invoke("report", out, "--out", "/proc/antisync-report/figs"))
    assert snapshot(tmp_path) == before


def test_nothing_synchronized_still_reports_and_says_why(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL.replace("t_max: 60", "t_max: 0.5"))
    out = tmp_path / "r.h5"
    assert invoke("run", cfg, "--out", out, "-q").exit_code == 0
    recs = json.loads(invoke("summary", out, "-f", "json").stdout)["records"]
    assert recs[0]["n_not_synced"] >= 19 and recs[0]["n"] <= 1
    table = invoke("summary", out).stdout
    assert "did not synchronize by t_max" in table and "raise dynamics.t_max" in table
    assert "only 0 batches" not in table
    res = invoke("report", out, "--out", tmp_path / "figs", "-q")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "figs" / "c_F_beta.png").exists()  # named after c.yaml


def test_disk_full_while_writing_a_chunk_is_one_line_and_resumes(tmp_path):
    """RLIMIT_FSIZE makes writes past 20 kB fail with EFBIG, as a full disk fails them
    with ENOSPC: one line, exit 2, and --resume afterwards gives the numbers of a clean run."""
    import resource

    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL.replace("realizations: 20", "realizations: 400") + "chunk_size: 20\n")
    ref = tmp_path / "ref.h5"
    assert invoke("run", cfg, "--out", ref, "-q").exit_code == 0
    out = tmp_path / "full.h5"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    proc = subprocess.run(
        [sys.executable, "-m", "antisync", "run", str(cfg), "--out", str(out), "-q"],
        cwd=REPO,
        capture_output=True,
        text=True,
        preexec_fn=limit,  # the kernels come from numba's cache, warmed by the run above
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "File too large" in proc.stderr
    assert invoke("run", cfg, "--out", out, "--resume", "-q").exit_code == 0
    with h5py.File(ref, "r") as a, h5py.File(out, "r") as b:
        for key in ("block_records", "tau0_records", "lambda_records"):
            assert np.array_equal(a[f"jobs/lollipop_6_3/{key}"][...], b[f"jobs/lollipop_6_3/{key}"][...])
