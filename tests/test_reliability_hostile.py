"""Graph files, CLI plumbing, the writer lock and three findings of a new user (issue 41).

- a GraphML/GML ``graph.weight`` that no edge has, or that only some edges have, is refused
  (it gave unit weights silently); a GraphML key's ``<default>`` is the weight of an edge
  without its own value (it gave 1);
- ``antisync summary FILE | head -1`` ends quietly (it printed "error: Broken pipe");
- a second ``run`` on an output being written names the writer (pid, host, start, command);
- the sum rule calls a rounding-level sum consistent with 0 (a false alarm on every large run
  of the adjoint) and still flags a real violation;
- the top-links and sorted figures mark a mean outside its own 95% interval and say why, in
  the summary's words;
- the summary's ``graph`` column says the config's ``name:``, as the figures do.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import matplotlib
import networkx as nx
import numpy as np
import pytest
from helpers import assert_one_line
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.physics.graphs import GraphError, build_graph, omega_matrix
from antisync.report.links import link_figures, plot_sorted, plot_top_intervals
from antisync.stats.sum_rule import node_sums, sum_rule_note
from antisync.stats.summary import JobView
from antisync.store.result_store import ResultStore

matplotlib.use("Agg")

runner = CliRunner()
REPO = Path(__file__).resolve().parent.parent


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def _cli(*args, cwd=None, **popen):
    """``python -m antisync ARGS`` in a real process (pipes and locks are the kernel's)."""
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen([sys.executable, "-m", "antisync", *map(str, args)], cwd=cwd, env=env, **popen)


# ---- 1. graph.weight naming an attribute the edges lack ------------------------------------
GRAPHML = """<?xml version="1.0" encoding="UTF-8"?>
<graphml xmlns="http://graphml.graphdrawing.org/xmlns">
  {keys}
  <graph edgedefault="undirected">
    <node id="1"/><node id="2"/><node id="3"/><node id="4"/>
    {edges}
  </graph>
</graphml>
"""
WEIGHT_KEY = '<key id="w" for="edge" attr.name="weight" attr.type="double"{default}/>'


def _graphml(folder, weights, default=None):
    """A path 1-2-3-4 whose edges carry ``weights`` (None: no <data>)."""
    keys = WEIGHT_KEY.format(default="")
    if default is not None:
        keys = keys[:-2] + f"><default>{default}</default></key>"
    edges = []
    for (u, v), w in zip([(1, 2), (2, 3), (3, 4)], weights, strict=True):
        data = "" if w is None else f'<data key="w">{w}</data>'
        edges.append(f'<edge source="{u}" target="{v}">{data}</edge>')
    path = folder / "g.graphml"
    path.write_text(GRAPHML.format(keys=keys, edges="\n    ".join(edges)))
    return path


def _gml(folder, weights, attr="weight"):
    lines = ["graph [", "  directed 0"] + [f'  node [ id {i} label "{i}" ]' for i in (1, 2, 3, 4)]
    for (u, v), w in zip([(1, 2), (2, 3), (3, 4)], weights, strict=True):
        lines.append(f"  edge [ source {u} target {v}" + ("" if w is None else f" {attr} {w}") + " ]")
    path = folder / "g.gml"
    path.write_text("\n".join(lines + ["]"]) + "\n")
    return path


def _config(folder, graph: str) -> Path:
    cfg = folder / "cfg.yaml"
    cfg.write_text(f"graph: {graph}\nedges: ['1->2']\nbetas: []\nrealizations: 8\nblock_size: 4\n")
    return cfg


@pytest.mark.parametrize("kind", ["graphml", "gml"])
def test_a_weight_attribute_no_edge_has_is_refused_naming_those_they_have(tmp_path, kind):
    path = _graphml(tmp_path, [2, 3, 4]) if kind == "graphml" else _gml(tmp_path, [2, 3, 4])
    spec = {"kind": kind, "path": str(path), "weight": "value"}
    with pytest.raises(GraphError, match=r"graph.weight names the edge attribute 'value'.*have weight"):
        build_graph(spec)
    cfg = _config(tmp_path, f"{{kind: {kind}, path: {path.name}, weight: value}}")
    for command in ("validate", "run"):
        res = invoke(command, cfg, *(["--out", tmp_path / "x.h5", "-q"] if command == "run" else []))
        assert_one_line(res, "'value'")
        assert "the edges have weight" in res.stderr
    assert not (tmp_path / "x.h5").exists()
    # the attribute they have reads as it is; without graph.weight too
    assert build_graph({**spec, "weight": "weight"}).edges[2, 3]["weight"] == 3.0
    assert build_graph({"kind": kind, "path": str(path)}).edges[3, 4]["weight"] == 4.0


@pytest.mark.parametrize("kind", ["graphml", "gml"])
def test_a_weight_only_some_edges_have_is_refused_naming_one_that_lacks_it(tmp_path, kind):
    path = _graphml(tmp_path, [2, None, 4]) if kind == "graphml" else _gml(tmp_path, [2, None, 4])
    for spec in ({"kind": kind, "path": str(path)}, {"kind": kind, "path": str(path), "weight": "weight"}):
        with pytest.raises(
            GraphError, match=r"1 of 3 edges lack the weight attribute 'weight' \(e\.g\. 2-3\)"
        ):
            build_graph(spec)
    res = invoke("validate", _config(tmp_path, f"{{kind: {kind}, path: {path.name}}}"))
    assert_one_line(res, "1 of 3 edges lack the weight attribute 'weight'")


def test_unit_weights_when_no_edge_has_a_weight_and_none_was_named(tmp_path):
    g = build_graph({"kind": "graphml", "path": str(_graphml(tmp_path, [None, None, None]))})
    assert [w for *_, w in g.edges(data="weight")] == [1.0, 1.0, 1.0]
    res = invoke("validate", _config(tmp_path, "{kind: graphml, path: g.graphml, weight: weight}"))
    assert_one_line(res, "no edge of this GraphML file has")


def test_a_graphml_default_is_the_weight_of_an_edge_without_its_own(tmp_path):
    """GraphML's rule: a key's <default> is the value of every element without <data> for it
    (networkx keeps it aside in G.graph['edge_default']; it was read as 1)."""
    g = build_graph({"kind": "graphml", "path": str(_graphml(tmp_path, [4, None, None], default=2.5))})
    assert omega_matrix(g)[0, 1] == 4.0 and omega_matrix(g)[1, 2] == 2.5 and omega_matrix(g)[2, 3] == 2.5


@pytest.mark.parametrize(
    ("weights", "needle"),
    [
        ([0, 1, 1], "positive finite"),
        ([-1, 1, 1], "positive finite"),
        (["NaN", 1, 1], "cannot read it as GML"),
        (['"x"', 1, 1], "positive finite"),
    ],
)
def test_odd_gml_weights_are_one_line(tmp_path, weights, needle):
    res = invoke("validate", _config(tmp_path, f"{{kind: gml, path: {_gml(tmp_path, weights).name}}}"))
    assert_one_line(res, needle)


# ---- 2. a closed stdout --------------------------------------------------------------------
@pytest.fixture(scope="module")
def exact_file(tmp_path_factory):
    """A karate-club file of exact measures only (no integration): 156 records, ~250 kB of
    JSON, more than a pipe holds."""
    folder = tmp_path_factory.mktemp("exact")
    cfg = folder / "karate.yaml"
    cfg.write_text("graph: {kind: networkx, generator: karate_club_graph}\nmeasures: [xi2]\n")
    res = invoke("run", cfg, "--out", folder / "karate.h5", "-q")
    assert res.exit_code == 0, res.output
    return folder / "karate.h5"


@pytest.mark.parametrize("args", [("summary", "-f", "json"), ("summary",), ("summary", "-f", "csv")])
def test_summary_into_a_pipe_closed_after_one_line_ends_quietly(exact_file, args):
    p = _cli(args[0], exact_file, *args[1:], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout.readline()
    p.stdout.close()
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait(timeout=60) == 0, err
    assert "error" not in err.lower() and "Traceback" not in err, err


@pytest.mark.parametrize("command", ["summary", "validate"])
def test_a_pipe_closed_before_anything_is_written_ends_quietly(exact_file, command):
    target = exact_file if command == "summary" else exact_file.with_suffix(".yaml")
    r, w = os.pipe()
    os.close(r)  # the reader is gone before the command starts
    p = _cli(command, target, stdout=w, stderr=subprocess.PIPE)
    os.close(w)
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait(timeout=60) == 0, err
    assert "error" not in err.lower() and "Exception ignored" not in err, err


# ---- 3. the writer lock --------------------------------------------------------------------
def test_a_second_run_on_an_output_being_written_names_its_writer(tmp_path, exact_file):
    """The writer holds the lock while the output and its journal exist (a checkpoint written,
    chunks saved): a second run is told who writes it, not to --resume."""
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1']\nbetas: []\n")
    out = tmp_path / "busy.h5"
    out.write_bytes(exact_file.read_bytes())  # the writer's last checkpoint
    store = ResultStore(out)
    with store.lock():
        store.journal.mkdir()
        for extra in ([], ["--resume"], ["--overwrite"]):
            p = _cli("run", cfg, "--out", out, "-q", *extra, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            stdout, stderr = (s.decode() for s in p.communicate(timeout=120))
            assert p.returncode == 2, stderr
            (line,) = stderr.strip().splitlines()
            assert f"is being written by another antisync process (pid {os.getpid()} on " in line, line
            assert "started " in line and "--resume" not in line, line
    assert out.read_bytes() == exact_file.read_bytes()


# ---- 4. the sum rule's rounding ------------------------------------------------------------
def _sum_view(offset: float, nb: int = 50) -> JobView:
    """One node ``a`` with three out-links whose per-realization values sum to 0 exactly but
    for one ulp of rounding (in float, in every block, on the same side) plus ``offset``."""
    rng = np.random.default_rng(1)
    lam = np.zeros((nb, 3, 10))
    lam[:, :, 0] = 1  # one realization per block: the block mean is the value itself
    x, y = rng.normal(0.4, 0.3, nb), rng.normal(-0.1, 0.3, nb)
    z = np.nextafter(-(x + y), -np.inf)  # the float sum of x, y, z: one ulp below 0
    lam[:, 0, 3], lam[:, 1, 3], lam[:, 2, 3] = x, y, z + offset
    lam[:, :, 4] = lam[:, :, 3] ** 2
    lam[:, :, 8], lam[:, :, 9] = 0.0, 100.0
    return JobView(
        graph="g", edges=["a->x", "a->y", "a->z"], betas=(), dbeta=0.01, variant_edge=np.zeros(0),
        variant_beta=np.zeros(0), rec=np.zeros((nb, 0, 7)), rec0=np.zeros((nb, 5)), done=np.ones(nb, bool),
        tail=np.zeros((0, 1)), realizations=nb, lam_rec=lam,
    )  # fmt: skip


def test_a_rounding_level_sum_is_consistent_with_the_rule():
    from antisync.stats.sum_rule import ROUNDING_ULPS

    (row,) = node_sums(_sum_view(0.0))
    assert row["high"] < 0 and abs(row["sum"]) < 1e-15  # resolved from 0 by its interval alone
    assert row["rounding"] == pytest.approx(ROUNDING_ULPS * np.finfo(float).eps * 3 * 0.4, rel=0.5)
    assert not row["resolved"] and row["rounding_only"]
    note = sum_rule_note([row], "derivative")
    assert "every sum consistent with 0" in note and "not derivatives" not in note
    assert "within floating-point rounding of 0: |sum| <= 2^20 eps" in note


@pytest.mark.parametrize("offset", [1e-6, 1e-3, 0.05])
def test_a_real_violation_is_still_flagged(offset):
    (row,) = node_sums(_sum_view(offset))
    assert row["resolved"] and not row.get("rounding_only")
    assert "not derivatives within their errors" in sum_rule_note([row], "derivative")


# ---- 5. a mean outside its own interval on the figures -------------------------------------
def _records(n: int = 30) -> list[dict]:
    recs = []
    for i in range(n):
        v = 0.1 * (i - n / 2) / (n / 2)
        recs.append(
            {"graph": "g", "edge": f"{i}->{i + 1}", "lambda_km": v, "lambda_km_se": 0.02,
             "lambda_km_ci_low": v - 0.04, "lambda_km_ci_high": v + 0.04}
        )  # fmt: skip
    recs[3].update(lambda_km=0.56, lambda_km_ci_low=-0.23, lambda_km_ci_high=0.20)  # 3->4
    return recs


def _marked(ax) -> tuple[list, list]:
    rings = [line for line in ax.lines if line.get_gid() == "outside interval"]
    notes = [t.get_text().replace("\n", " ") for t in ax.texts if t.get_gid() == "outside note"]
    return rings, notes


@pytest.mark.parametrize("plot", [plot_top_intervals, plot_sorted])
def test_a_mean_outside_its_interval_is_marked_and_explained(plot):
    import matplotlib.pyplot as plt

    from antisync.report.links import OUTSIDE_LABEL
    from antisync.stats.summary import OUTSIDE_WHY

    fig, ax = plt.subplots()
    plot(_records(), "lambda_km", ax, **({"k": 10} if plot is plot_top_intervals else {}))
    (ring,), (note,) = _marked(ax)
    assert list(ring.get_xdata() if plot is plot_top_intervals else ring.get_ydata()) == [0.56]
    assert OUTSIDE_LABEL in [t.get_text() for t in ax.get_legend().get_texts()]
    assert OUTSIDE_WHY in note and "(1 link)" in note
    plt.close(fig)
    # no mark where every mean is inside its interval
    fig, ax = plt.subplots()
    plot(_records()[4:], "lambda_km", ax)
    assert _marked(ax) == ([], [])
    plt.close(fig)


def test_the_top_links_figure_of_a_large_graph_carries_the_mark():
    """Through :func:`link_figures`, what ``antisync report`` draws for a graph of many links."""
    from antisync.stats.summary import OUTSIDE_WHY

    g = nx.path_graph(31)
    recs = _records()
    view = JobView(
        graph="g", edges=[r["edge"] for r in recs], betas=(), dbeta=0.01, variant_edge=np.zeros(0),
        variant_beta=np.zeros(0), rec=np.zeros((1, 0, 7)), rec0=np.zeros((1, 5)), done=np.ones(1, bool),
        tail=np.zeros((0, 1)), realizations=64, omega=nx.to_numpy_array(g, nodelist=range(31)),
        nodes=list(range(31)),
    )  # fmt: skip
    figures = dict((suffix, fig) for fig, suffix in link_figures(view, recs, k=10))
    for suffix in ("top_links", "lambda_sorted"):
        notes = [n for ax in figures[suffix].axes for n in _marked(ax)[1]]
        assert len(notes) == 1 and OUTSIDE_WHY in notes[0], suffix
    import matplotlib.pyplot as plt

    for fig in figures.values():
        plt.close(fig)


# ---- 6. one name for the summary and the figures -------------------------------------------
def test_the_summary_calls_a_generated_graph_by_the_configs_name(tmp_path):
    cfg = tmp_path / "small world.yaml"
    cfg.write_text(
        "name: ws24\n"
        "graph: {kind: networkx, generator: connected_watts_strogatz_graph,\n"
        "        args: {n: 24, k: 4, p: 0.2, seed: 3}}\n"
        "measures: [xi2]\n"
    )
    out = tmp_path / "ws.h5"
    assert invoke("run", cfg, "--out", out, "-q").exit_code == 0
    res = invoke("summary", out)
    assert res.exit_code == 0, res.output
    assert "ws24" in res.stdout and "connected_watts_strogatz_graph" not in res.stdout, res.stdout
    # CSV and JSON, read by programs, keep the job's name (its HDF5 group's) and agree
    csv_rows = invoke("summary", out, "--format", "csv").stdout.splitlines()[1:]
    json_recs = json.loads(invoke("summary", out, "--format", "json").stdout)["records"]
    assert {row.split(",")[0] for row in csv_rows} == {r["graph"] for r in json_recs}
    assert {r["graph"] for r in json_recs} == {"connected_watts_strogatz_graph"}
    res = invoke("report", out, "--out", tmp_path / "figs", "-q")
    assert res.exit_code == 0, res.output
    names = {p.name for p in (tmp_path / "figs").iterdir()}
    assert "ws24_lambda_sorted.png" in names, names
    assert "connected_watts_strogatz_graph" not in (tmp_path / "figs" / "index.md").read_text()


def test_summary_json_records_parse(exact_file):
    """The JSON of a run file still parses whole (the pipe handling changes nothing else)."""
    res = invoke("summary", exact_file, "--format", "json")
    assert res.exit_code == 0 and len(json.loads(res.stdout)["records"]) == 156


def test_a_writer_with_its_own_journal_is_refused_naming_the_holder(tmp_path):
    """:func:`antisync.store.lock.writer_lock`, for ``grid --removal --out X.json``: a second
    writer (another process) is refused naming the first, before it looks at the journal."""
    from antisync.store.lock import writer_lock

    out = tmp_path / "table.json"
    code = (
        "import sys\nfrom antisync.errors import StoreError\nfrom antisync.store.lock import writer_lock\n"
        "try:\n    with writer_lock(sys.argv[1]):\n        print('held')\n"
        "except StoreError as exc:\n    print(exc)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    with writer_lock(out) as held:
        assert held
        (tmp_path / "table.json.partial").mkdir()  # the first writer's journal
        second = subprocess.run(
            [sys.executable, "-c", code, str(out)], capture_output=True, text=True, env=env
        )
        assert f"being written by another antisync process (pid {os.getpid()} on " in second.stdout, second
    # released: the next writer takes it
    again = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True, text=True, env=env)
    assert again.stdout.strip() == "held", again


def test_the_link_table_marks_a_mean_outside_its_interval(monkeypatch):
    """The Markdown table that replaces Fig. 1a's labels on a graph of many links."""
    from antisync.report import figures
    from antisync.stats.summary import OUTSIDE_WHY

    monkeypatch.setattr(figures, "_lambdas", lambda view: ("lambda_km", _records()))
    lines = figures.link_table(None)
    (row,) = [line for line in lines if line.startswith("| 3->4 ")]
    assert "+0.56 \u25c7" in row
    assert lines[-1].endswith(OUTSIDE_WHY) and "(1)" in lines[-1]
    assert sum("\u25c7" in line for line in lines) == 2  # the one row and the note


def test_a_second_grid_removal_on_a_table_being_written_names_its_writer(tmp_path):
    """``antisync grid --removal --out X.json`` holds X.json's writer lock before it looks at
    X.json.partial: a second one is told who writes it (pid), not to ``--resume`` the first
    one's journal, and the journal is left as it is."""
    from antisync.store.lock import writer_lock

    cfg = tmp_path / "ring.yaml"
    cfg.write_text(
        "name: ring\ngraph: {kind: inline, links: [[0, 1, 2.0], [1, 2, 2.0], [2, 3, 2.0], [3, 0, 2.0]]}\n"
        "model: {frequencies: [1.0, -1.0, 0.5, -0.5], inertia: 1.0, damping: 1.0}\n"
        "sync: {criterion: frequency, tolerance: 0.001}\n"
        "dynamics: {coupling: raw, integrator: rk4, dt: 0.02, t_max: 20}\nrealizations: 4\noutput: r.h5\n"
    )
    out = tmp_path / "table.json"
    journal = tmp_path / "table.json.partial"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    with writer_lock(out):
        journal.mkdir()  # the first writer's journal
        (journal / "task_0_0_4_1.npz").write_bytes(b"the first writer's work")
        second = subprocess.run(
            [sys.executable, "-m", "antisync", "grid", str(cfg), "--removal", "--out", str(out), "--resume"],
            capture_output=True,
            text=True,
            env=env,
        )
    assert second.returncode == 2, second
    assert f"being written by another antisync process (pid {os.getpid()} on " in second.stderr, second
    assert "Traceback" not in second.stderr
    assert (journal / "task_0_0_4_1.npz").read_bytes() == b"the first writer's work"


def test_a_run_output_inside_another_runs_journal_folder_is_refused(tmp_path):
    """``antisync run --out X.h5.partial/y.h5`` would write into another run's unfinished
    work and make it unresumable: refused in one line, the journal left as it is."""
    journal = tmp_path / "x.h5.partial"
    journal.mkdir()
    cfg = tmp_path / "c.yaml"
    cfg.write_text("graph: {kind: lollipop, nodes: 4, path: 1}\nrealizations: 8\noutput: c.h5\n")
    res = runner.invoke(app, ["run", str(cfg), "--out", str(journal / "y.h5")])
    assert_one_line(res, "x.h5.partial, where antisync keeps an unfinished run's work")
    assert list(journal.iterdir()) == []


def test_an_integer_weight_beyond_floats_range_is_one_line():
    """A weight of 10**400 (an int no float holds; hypothesis found it) is refused as a weight
    that is not a positive finite number, not an OverflowError."""
    from antisync.errors import AntisyncError
    from antisync.measures import for_graph

    for weight in (10**400, 10**5000):  # 5,000 digits: beyond what str() of an int allows
        g = nx.path_graph(3)
        g.edges[0, 1]["weight"] = weight
        with pytest.raises(AntisyncError, match="weights must be positive finite numbers") as err:
            for_graph(g, which=["xi2"])
        assert "\n" not in str(err.value)
