"""Sweeps: schema, families, screening, automorphism orbits, fan-out, resume, Table 1."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import networkx as nx
import numpy as np
import pytest
from helpers import CrashAfter, comparable

from antisync.errors import ConfigError
from antisync.physics import graphs
from antisync.sweeps import (
    edge_orbits,
    expand_records,
    family_graphs,
    load_sweep,
    load_sweep_text,
    ranking,
    run_sweep,
    sweep_summary,
)

REPO = Path(__file__).resolve().parent.parent

TINY = """
name: tiny
sweep:
  family: graphs
  graphs:
    - {kind: networkx, generator: path_graph, args: {n: 3}}
    - {kind: lollipop, nodes: 4, path: 1}
    - {kind: atlas, index: 18}     # K4
    - {kind: networkx, generator: cycle_graph, args: {n: 5}, name: C5}
betas: [0.5]
measures: [km, xi2]
realizations: 120
block_size: 20
seed: 3
dynamics: {dt: 0.002, t_max: 60}
screen: {realizations: 60, t_max: 60}
top: {graphs: 2, realizations: 80}
"""


# ---- schema ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("sweep: {family: atlas, nodes: 6}\nsweeps: 1", "unknown key 'sweeps'"),
        ("sweep: {family: atlsa, nodes: 6}", "sweep.family must be one of"),
        ("sweep: {family: atlas, nodes: 9}", "sweep.nodes values must be integers in 2..7"),
        ("sweep: {family: atlas, node: 6}", "unknown key 'sweep.node'"),
        ("sweep: {family: lollipop, nodes: 6}", "needs key(s) sweep.path"),
        ("sweep: {family: lollipop, nodes: '9..4', path: 1}", "sweep.nodes range '9..4' is empty"),
        (
            "sweep: {family: atlas, nodes: 6}\nthresholds: [0.9]\ndynamics: {threshold: 0.9}",
            "either thresholds",
        ),
        ("sweep: {family: atlas, nodes: 6}\nthresholds: [0.9, 1.5]", "thresholds must lie in (0, 1)"),
        ("sweep: {family: atlas, nodes: 6}\nrepeats: 0", "repeats must be an integer >= 1"),
        ("sweep: {family: atlas, nodes: 6}\nscreen: {realisations: 5}", "unknown key 'screen.realisations'"),
        ("sweep: {family: atlas, nodes: 6}\ntop: {graphs: -1}", "top.graphs must be an integer >= 0"),
        ("sweep: {family: atlas, nodes: 6}\nedges: fig2", "edges: fig2"),
        ("sweep: {family: atlas, nodes: 6}\ngraph: {kind: atlas, index: 3}", "has no 'graph' key"),
        ("graph: {kind: atlas, index: 3}", "missing key 'sweep'"),
        ("sweep: {family: atlas, nodes: 6}\nrealizations: 0", "realizations must be an integer in 1..10**15"),
        ("sweep: {family: graphs, graphs: [{kind: atlas, index: 3}, {kind: atlas, index: 3}]}", "used twice"),
    ],
)
def test_schema_errors_name_the_key(text, message):
    with pytest.raises(ConfigError) as exc:
        load_sweep_text(text)
    assert message in str(exc.value)
    assert "\n" not in str(exc.value)


def test_run_config_loader_points_sweeps_to_antisync_sweep():
    from antisync.plan.config import load_config_text

    with pytest.raises(ConfigError, match="antisync sweep"):
        load_config_text("sweep: {family: atlas, nodes: 6}")


SHIPPED = sorted(p.stem for p in (REPO / "configs").glob("*.yaml"))


def test_every_config_is_shipped_and_checked():
    shipped = {"atlas6", "lollipop_L1", "threshold", "lollipop6", "karate", "lesmis"}
    grids = {
        "ieee39_grid",
        "ieee118_grid",
        "ieee118_uniform",
        "ieee300_grid",
        "activsg2000_grid",
        "activsg10k_grid",
    }
    assert shipped | grids <= set(SHIPPED)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_configs_are_valid(name):
    """Every shipped config loads, and builds its graph and damaged links (a run's) or its
    family (a sweep's), as `antisync validate` does."""
    import yaml

    from antisync.plan.config import load_config
    from antisync.plan.jobs import make_job

    path = REPO / "configs" / f"{name}.yaml"
    raw = yaml.safe_load(path.read_text())
    if "design" in raw:  # a design config (docs/design.md): its run config and its design section
        from antisync.optimize.config import load_design_config

        cfg, spec = load_design_config(path)  # the graphs: tests/test_optimize.py
        assert name.startswith(cfg.name) and spec.output.endswith(f"{cfg.name}_design.h5")
    elif "sweep" in raw:
        sw = load_sweep(path)
        assert sw.name == name
        assert sw.key() == load_sweep(path).key()
    else:
        cfg = load_config(path)
        assert cfg.name == name
        job = make_job(cfg)
        assert job.edges and job.kuramoto == ("km" in cfg.measures)


def test_overrides_and_ranges():
    sw = load_sweep_text(
        "sweep: {family: lollipop, nodes: '4..20', path: 1}\nedges: fig2",
        overrides=["realizations=77", "sweep.path=[1, 2]", "repeats=3"],
    )
    assert sw.base.realizations == 77 and sw.repeats == 3
    assert sw.family["nodes"] == list(range(4, 21)) and sw.family["path"] == [1, 2]
    assert sw.base.keep_pairs == 0  # sweep default


# ---- families ----------------------------------------------------------------------------
def test_atlas_family_counts():
    from antisync.sweeps.families import family_specs

    counts = {n: len(family_specs({"family": "atlas", "nodes": [n]})) for n in range(2, 8)}
    assert counts == {2: 1, 3: 2, 4: 6, 5: 21, 6: 112, 7: 853}
    names = [name for name, _ in family_specs({"family": "atlas", "nodes": [6]})]
    assert names[-1] == "G208" and "G105" in names  # K6 last; the 6-ring is G105


def test_fig2_edge_is_the_clique_edge_away_from_the_bridge():
    sw = load_sweep_text("sweep: {family: lollipop, nodes: '4..6', path: 1}\nedges: fig2")
    entries = family_graphs(sw)
    assert [e.labels for e in entries] == [["3->4"], ["3->4"], ["3->4"]]
    for e in entries:
        a, b = e.edges[0]
        assert e.graph.has_edge(a, b) and not e.graph.has_edge(a, 1) and not e.graph.has_edge(b, 1)


# ---- symmetry ----------------------------------------------------------------------------
def _partition(orbits: dict) -> set:
    groups: dict = {}
    for e, r in orbits.items():
        groups.setdefault(r, set()).add(graphs.edge_label(*e))
    return {frozenset(g) for g in groups.values()}


def test_orbits_lollipop_6_3():
    parts = _partition(edge_orbits(graphs.lollipop(6, 3)))
    assert frozenset({"4->5", "4->6"}) in parts
    assert frozenset({"5->6", "6->5"}) in parts
    assert frozenset({"5->4", "6->4"}) in parts
    for single in ("1->2", "2->1", "2->3", "3->2", "3->4", "4->3"):
        assert frozenset({single}) in parts
    assert len(parts) == 9


def test_orbits_complete_graph_is_one_orbit():
    orbits = edge_orbits(nx.complete_graph(4))
    assert len(orbits) == 12 and len(set(orbits.values())) == 1


@pytest.mark.parametrize("index", [60, 96, 104, 127, 150, 208])
def test_orbits_match_enumerated_automorphisms(index):
    from networkx.algorithms.isomorphism import GraphMatcher

    g = graphs.atlas(index)
    autos = list(GraphMatcher(g, g).isomorphisms_iter())
    orbits = edge_orbits(g)
    for e in graphs.all_directed_edges(g):
        expected = {(s[e[0]], s[e[1]]) for s in autos}
        assert {f for f in orbits if orbits[f] == orbits[e]} == expected


def _enumerated_orbits_agree(g, match=None) -> None:
    from networkx.algorithms.isomorphism import GraphMatcher

    autos = list(GraphMatcher(g, g, edge_match=match).isomorphisms_iter())
    orbits = edge_orbits(g)
    for e in graphs.all_directed_edges(g):
        assert {f for f in orbits if orbits[f] == orbits[e]} == {(s[e[0]], s[e[1]]) for s in autos}, e


def test_orbits_of_every_connected_six_node_graph_match_enumerated_automorphisms():
    """The paper's 112 connected graphs on six nodes, each directed edge's orbit against the
    one the enumerated automorphisms give."""
    from networkx.generators.atlas import graph_atlas_g

    six = [g for g in graph_atlas_g() if g.number_of_nodes() == 6 and nx.is_connected(g)]
    assert len(six) == 112
    for g in six:
        _enumerated_orbits_agree(g)


@pytest.mark.parametrize(
    "g",
    [
        nx.balanced_tree(2, 3),  # a tree: branches swapped at every level
        nx.cycle_graph(9),  # one orbit, joined by the automorphisms found, not by searches
        nx.grid_2d_graph(3, 4),
        nx.petersen_graph(),
        # regular, not edge-transitive: one class before any search, two orbits of edges
        nx.circular_ladder_graph(5),
    ],
    ids=["tree", "ring", "grid", "petersen", "prism"],
)
def test_orbits_match_enumerated_automorphisms_beyond_the_atlas(g):
    _enumerated_orbits_agree(g)


def test_weighted_orbits_keep_the_weights():
    """A ring whose weights alternate 1, 2: only rotations by two steps and the reflections that
    keep the weights; the orbits are the enumerated ones of the weight-preserving relabellings."""
    g = nx.cycle_graph(8)
    for k, (a, b) in enumerate(g.edges):
        g[a][b]["weight"] = 1.0 + k % 2
    _enumerated_orbits_agree(g, match=lambda x, y: x["weight"] == y["weight"])


def test_a_long_paths_orbits_are_its_mirror_pairs():
    """A path of 401 nodes (every pair of edges a search before: hours at this size): each
    directed edge's orbit is itself and its mirror image, and refinement alone gives each node
    its distance to the nearer end."""
    n = 401
    g = nx.path_graph(n)
    colors = graphs.refined_colors(g)
    assert len(set(colors.values())) == (n + 1) // 2
    assert all(colors[i] == colors[n - 1 - i] for i in range(n))
    orbits = edge_orbits(g)
    for a, b in graphs.all_directed_edges(g):
        mirror = (n - 1 - a, n - 1 - b)
        assert {f for f in orbits if orbits[f] == orbits[a, b]} == {(a, b), mirror}
        assert orbits[a, b] == min((a, b), mirror, key=list(orbits).index)  # the first edge


def test_expand_records_fans_out_to_every_orbit_member():
    recs = [
        {"graph": "g", "edge": "0->1", "beta": 0.5, "lambda_km": 0.2},
        {"graph": "g", "edge": "1->0", "beta": 0.5, "lambda_km": -0.1},
    ]
    orbits = {"0->1": "0->1", "1->0": "1->0", "2->1": "0->1", "0->2": "0->1"}
    out = expand_records(recs, orbits)
    assert [r["edge"] for r in out] == ["0->1", "1->0", "2->1", "0->2"]
    assert [r["lambda_km"] for r in out] == [0.2, -0.1, 0.2, 0.2]
    assert [r["orbit_size"] for r in out] == [3, 1, 3, 3]
    assert all(r["representative"] == orbits[r["edge"]] for r in out)
    assert recs[0]["edge"] == "0->1"  # inputs untouched


def test_ranking_sums_positive_lambdas():
    def rec(g, e, lam, rep=0):
        return {
            "graph": g,
            "edge": e,
            "lambda_km": lam,
            "lambda_km_se": 0.01,
            "threshold": 0.99,
            "repeat": rep,
            "beta": None,
            "tau0_mean": 1.0,
            "tau0_se": 0.1,
        }

    recs = [
        rec("A", "0->1", 0.3),
        rec("A", "1->0", -0.5),
        rec("B", "0->1", 0.2),
        rec("B", "1->0", 0.15),
        rec("B", "0->1", 0.4, rep=1),
        rec("B", "1->0", 0.15, rep=1),
    ]
    rows = ranking(recs, 0.99)
    assert [r["graph"] for r in rows] == ["B", "A"]
    assert math.isclose(rows[0]["score"], 0.3 + 0.15) and rows[0]["max_edge"] == "0->1"
    assert math.isclose(rows[1]["lambda_max"], 0.3)


# ---- screening ---------------------------------------------------------------------------
def _c5_plus(extra: list) -> nx.Graph:
    g = nx.cycle_graph(5)
    g.add_edges_from(extra)
    return g


EXPECTED_EXCLUDED = {
    "6-ring": nx.cycle_graph(6),
    "5-ring + pendant": _c5_plus([(0, 5)]),
    "5-ring + node on two neighbours": _c5_plus([(0, 5), (1, 5)]),
}


def _which(g: nx.Graph) -> str | None:
    return next((k for k, h in EXPECTED_EXCLUDED.items() if nx.is_isomorphic(g, h)), None)


def test_screening_excludes_the_rings_and_keeps_slow_graphs():
    """The three non-synchronizing 6-node graphs and the slowest synchronizing ones (G96 has a
    4-cycle whose degenerate twisted state gives the longest transients of the atlas)."""
    from antisync.sweeps.screening import screen_graph

    candidates = [
        g for g in range(53, 209) if nx.is_connected(graphs.atlas(g)) and _which(graphs.atlas(g)) is not None
    ]
    assert len(candidates) == 3
    for index in candidates + [96, 126, 150, 208]:
        g = graphs.atlas(index)
        res = screen_graph(graphs.omega_matrix(g), graph=f"G{index}", realizations=200, t_max=200)
        assert res.excluded == (_which(g) is not None), (index, res)
        if res.excluded:
            assert res.fraction_stuck > 0.02 and res.r_stuck < 0.3
        else:
            assert res.n_stuck == 0 and res.n_synced == 200


def test_screening_steps_equal_the_kernel_steps():
    from antisync.execution.compute import simulate_job
    from antisync.plan.config import load_config_text
    from antisync.plan.jobs import make_job
    from antisync.sweeps.screening import screen_realizations

    cfg = load_config_text('graph: {kind: atlas, index: 127}\nedges: ["0->2"]\nbetas: []\nseed: 5')
    job = make_job(cfg)
    sim = simulate_job(job, 0, 60)
    status, steps, _, _ = screen_realizations(job.omega, seed=5, realizations=60, t_max=200)
    ok = status == 0
    assert ok.sum() > 50
    np.testing.assert_array_equal(sim.steps0[ok], steps[ok])
    np.testing.assert_array_equal(sim.status0[ok], 0)


def test_stability_classification_of_twisted_and_synchronized_states():
    from antisync.physics.coupling import coupling_matrix
    from antisync.sweeps.screening import classify_state

    w = coupling_matrix(graphs.omega_matrix(graphs.from_networkx("cycle_graph", {"n": 6})))
    twisted = 2 * np.pi * np.arange(6) / 6
    assert classify_state(twisted, w) == "stable"  # q = 1 on C6: |q| < N/4
    assert classify_state(np.zeros(6), w) == "stable"
    w4 = coupling_matrix(graphs.omega_matrix(graphs.from_networkx("cycle_graph", {"n": 4})))
    assert classify_state(np.pi / 2 * np.arange(4), w4) != "stable"  # q = 1 on C4: degenerate
    assert classify_state(np.array([0, np.pi, 0, np.pi]), w4) == "unstable"


@pytest.mark.slow
def test_screening_of_the_whole_atlas_excludes_exactly_three():
    sw = load_sweep_text("sweep: {family: atlas, nodes: 6}")
    from antisync.sweeps.screening import screen_graph

    excluded = []
    for entry in family_graphs(sw, symmetry=False):
        res = screen_graph(graphs.omega_matrix(entry.graph), graph=entry.name, realizations=200)
        if res.excluded:
            excluded.append(entry.graph)
        else:
            assert res.n_stuck == 0
    assert sorted(_which(g) for g in excluded) == sorted(EXPECTED_EXCLUDED)


# ---- running and resuming ----------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny_reference(tmp_path_factory):
    sw = load_sweep_text(TINY)
    path = tmp_path_factory.mktemp("ref") / "tiny.h5"
    run_sweep(sw, output=path, progress=False, chunk_realizations=20)
    return sw, path, comparable(sweep_summary(path))


def test_tiny_sweep_contents(tiny_reference):
    _, path, ref = tiny_reference
    assert [e["graph"] for e in ref["excluded"]] == ["C5"]
    assert ref["excluded"][0]["fraction_not_synced"] > 0
    assert ref["complete"]
    recs = ref["records"]
    assert {r["graph"] for r in recs} == {"path_graph", "lollipop_4_1", "G18"}
    k4 = [r for r in recs if r["graph"] == "G18"]
    assert len(k4) == 12 and len({r["lambda_km"] for r in k4}) == 1  # one orbit, fanned out
    assert ref["symmetry"]["representatives"] < ref["symmetry"]["directed_edges"]
    assert len(ref["top"]) == 2 and all(r["beta"] == 0.5 for r in ref["top"])
    assert [r["rank"] for r in ref["top"]] == [1, 2]


def test_top_stage_runs_its_own_realizations_when_more_than_the_main_stage(tmp_path):
    """top.realizations above the main stage's: every top job runs all of them (they were cut
    to the main stage's count, and the file left incomplete, with nothing said)."""
    text = TINY.replace("top: {graphs: 2, realizations: 80}", "top: {graphs: 1, realizations: 200}")
    sw = load_sweep_text(text.replace("measures: [km, xi2]", "measures: [km]"))
    path = run_sweep(sw, output=tmp_path / "t.h5", progress=False, chunk_realizations=40)
    summary = sweep_summary(path)
    assert summary["complete"]
    (top,) = summary["top"]
    assert top["n"] + top["n_excluded"] == 200
    assert {r["n"] + r["n_excluded"] for r in summary["records"]} == {120}


def test_fanned_out_records_match_direct_xi2(tiny_reference):
    """Lambda^(xi2), computed for representatives only and fanned out, equals a direct
    computation on every orbit member: an independent check of the orbits."""
    from antisync.measures.spectral import lambda_xi2

    _, _, ref = tiny_reference
    built = {"path_graph": nx.path_graph(3), "lollipop_4_1": graphs.lollipop(4, 1), "G18": graphs.atlas(18)}
    for r in ref["records"]:
        g = built[r["graph"]]
        nodes = graphs.node_order(g)
        a, b = graphs.parse_edge(r["edge"], g)
        direct = lambda_xi2(graphs.omega_matrix(g), nodes.index(a), nodes.index(b))
        assert math.isclose(r["lambda_xi2"], direct, rel_tol=1e-7, abs_tol=1e-8), r["edge"]


@pytest.mark.parametrize(
    ("crash_after", "exc", "stage"),
    [
        (0, RuntimeError, "main"),
        (7, RuntimeError, "main"),
        (9, KeyboardInterrupt, "main"),
        (19, RuntimeError, "top"),
    ],
)
def test_interrupted_sweep_resumes_to_the_same_file(tiny_reference, tmp_path, crash_after, exc, stage):
    """Killed right after screening, in the main stage (3 graphs x 6 chunks of 20) or in the top
    stage, or interrupted with Ctrl-C, then resumed: the same numbers as uninterrupted."""
    from antisync.execution.runner import Interrupted

    sw, _, ref = tiny_reference
    path = tmp_path / "tiny.h5"
    with pytest.raises(Interrupted if exc is KeyboardInterrupt else RuntimeError):
        run_sweep(
            sw, output=path, progress=False, chunk_realizations=20, executor=CrashAfter(crash_after, exc)
        )
    if stage == "main":  # screening results wait in the journal until the first checkpoint
        assert len(list((tmp_path / "tiny.h5.partial" / "screen").glob("*.json"))) == 4
    if exc is KeyboardInterrupt:  # the checkpoint already holds the screening
        assert len(sweep_summary(path)["excluded"]) == 1 and not sweep_summary(path)["complete"]
    elif stage == "top":
        assert path.exists()  # the main stage ended with a checkpoint
    if path.exists():  # every checkpoint (also the one after the measures) holds the screening
        s = sweep_summary(path)
        assert len(s["excluded"]) == 1 and not s["complete"]
        with h5py.File(path, "r") as f:  # the file says so too, also between the stages
            assert not f.attrs["complete"]
    run_sweep(sw, output=path, resume=True, progress=False, chunk_realizations=40)
    assert comparable(sweep_summary(path)) == ref
    assert not (tmp_path / "tiny.h5.partial").exists()
    with h5py.File(path, "r") as f:
        assert f.attrs["complete"]


def test_resume_refuses_another_sweep(tiny_reference, tmp_path):
    from antisync.errors import StoreError

    sw, path, _ = tiny_reference
    other = load_sweep_text(TINY, overrides=["seed=4"])
    with pytest.raises(StoreError, match="different config"):
        run_sweep(other, output=path, resume=True, progress=False)


def test_screening_is_resumed_not_redone(tiny_reference, tmp_path, monkeypatch):
    import antisync.sweeps.screening as screening

    sw, _, ref = tiny_reference
    path = tmp_path / "tiny.h5"
    calls = []
    real = screening.screen_graph

    def flaky(*args, **kwargs):
        calls.append(kwargs["graph"])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(screening, "screen_graph", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(sw, output=path, progress=False)
    run_sweep(sw, output=path, resume=True, progress=False, chunk_realizations=20)
    assert calls == ["path_graph", "lollipop_4_1", "G18", "G18", "C5"]
    assert comparable(sweep_summary(path)) == ref


# ---- CLI -----------------------------------------------------------------------------------
def test_cli_sweep_summary_and_report(tmp_path):
    from typer.testing import CliRunner

    from antisync.cli.app import app

    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(TINY.replace("top: {graphs: 2, realizations: 80}", "top: {graphs: 1, realizations: 40}"))
    out = tmp_path / "tiny.h5"
    runner = CliRunner()
    res = runner.invoke(
        app,
        [
            "sweep",
            str(cfg),
            "--out",
            str(out),
            "--quiet",
            "--realizations",
            "40",
            "--set",
            "screen.realizations=40",
        ],
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["summary", str(out), "--format", "json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert {"records", "excluded"} <= set(data)
    assert data["excluded"][0]["graph"] == "C5"
    assert {"graph", "reason", "fraction_not_synced"} <= set(data["excluded"][0])
    assert all("graph" in r and "edge" in r for r in data["records"])
    res = runner.invoke(app, ["summary", str(out)])
    assert res.exit_code == 0 and "excluded C5" in res.output
    res = runner.invoke(app, ["report", str(out), "--out", str(tmp_path / "fig"), "--quiet"])
    assert res.exit_code == 0, res.output
    for name in (
        "fig3_ranking.png",
        "table1.md",
        "table1.csv",
        "table1.tex",
        "fig4_histograms.png",
        "fig5_measures.png",
        "index.md",
    ):
        assert (tmp_path / "fig" / name).exists(), name
    res = runner.invoke(app, ["sweep", str(cfg), "--out", str(out), "--quiet"])
    assert res.exit_code == 2 and "already exists" in res.output
    res = runner.invoke(app, ["run", str(cfg)])
    assert res.exit_code == 2 and "antisync sweep" in res.output


# ---- Table 1 -------------------------------------------------------------------------------
def test_table1_formats():
    from antisync.report.tables import fmt_pm, format_table1

    assert fmt_pm(9.31254, 0.0123) == ("9.313", "0.012")
    assert fmt_pm(0.1321, 0.0021) == ("0.1321", "0.0021")
    assert fmt_pm(1.08234, None) == ("1.082", "-")
    rows = [
        {
            "rank": 1,
            "graph": "G171",
            "edge": "2->1",
            "tau0_mean": 9.3125,
            "tau0_se": 0.0031,
            "lambda_km": 0.1321,
            "lambda_km_se": 0.0042,
            "F_mean": 1.0823,
            "F_se": 0.00051,
            "beta": 0.5,
            "n_tau0": 1000,
            "n_F": 1000,
        },
        {
            "rank": 2,
            "graph": "lollipop_6_3",
            "edge": "2->1",
            "tau0_mean": 9.5614,
            "tau0_se": 0.01,
            "lambda_km": 0.2653,
            "lambda_km_se": 0.005,
            "F_mean": None,
            "F_se": None,
            "beta": None,
            "n_tau0": None,
            "n_F": None,
        },
    ]
    md = format_table1(rows, "markdown").splitlines()
    assert md[0].startswith("| rank | graph | <tau0> |") and "<F_0.5>" in md[0]
    assert md[2] == "| 1 | G171 | 9.3125 ± 0.0031 | 2->1 | 0.1321 ± 0.0042 | 1.08230 ± 0.00051 |"
    assert md[3].endswith("| - |")
    csv_lines = format_table1(rows, "csv").splitlines()
    assert csv_lines[0].startswith("rank,graph,tau0_mean,tau0_se,edge,lambda_km")
    assert csv_lines[1].startswith("1,G171,9.3125,0.0031,2->1,0.1321,0.0042,1.0823")
    tex = format_table1(rows, "latex")
    assert r"$9.3125 \pm 0.0031$" in tex and r"lollipop\_6\_3" in tex and r"$2\to1$" in tex
    assert tex.startswith(r"\begin{tabular}") and tex.endswith(r"\end{tabular}")


def test_fit_gamma_recovers_a_line():
    from antisync.report.sweep import fit_gamma

    x = np.linspace(-0.4, 0.4, 50)
    fit = fit_gamma(x, 0.7 * x + 0.003)
    assert math.isclose(fit["gamma"], 0.7, abs_tol=1e-12) and math.isclose(fit["C"], 0.003, abs_tol=1e-12)


def test_paper_plan_fits_the_budget_and_readme_tolerates_missing_steps(tmp_path):
    from antisync.paper.make import STEPS, _readme, plan

    assert sum(s.cpu_seconds() for s in STEPS) / 2 < 0.6 * 3600  # 2 cores, margin for slower CPUs
    assert "total" in plan(0.5)
    text = _readme(tmp_path, 1.0, {}, {})
    assert "## Fig. 3" in text and "not produced" in text
    assert "## Paper precision" in text and "--realizations 1000000000" in text


def test_make_paper_step_reruns_as_a_no_op_and_keeps_its_time(tmp_path):
    """One real step of ``antisync paper`` at 100 realizations: the README shows it with its
    minutes; a rerun finds the step finished, computes nothing and keeps the first time."""
    from antisync.paper.make import make_paper

    out, logs = tmp_path / "paper", []
    readme = make_paper(out, scale=0.01, only=("lollipop6",), progress=False, log=logs.append)
    text = readme.read_text()
    assert "| lollipop6 | 100 | Fig. 1 |" in text and "| 2->1 | 1." in text
    assert "## Paper precision" in text and "not produced" in text  # the other steps
    first = json.loads((out / "timings.json").read_text())
    make_paper(out, scale=0.01, only=("lollipop6",), progress=False, log=logs.append)
    assert json.loads((out / "timings.json").read_text()) == first
    assert any("(already finished)" in str(line) for line in logs)
    assert any("(100 already done)" in str(line) for line in logs)


def test_paper_precision_commands_are_valid_configs():
    """Every command printed under "Paper precision" in results/paper/README.md validates:
    its config exists and every --set, --realizations, --backend, --out is accepted."""
    import shlex

    from typer.testing import CliRunner

    from antisync.cli.app import app
    from antisync.paper.make import PAPER_PRECISION

    commands = [c for c in PAPER_PRECISION.replace("\\\n", " ").splitlines() if c.startswith("antisync ")]
    assert len(commands) == 6
    as_set = {"--realizations": "realizations", "--backend": "backend", "--out": "output"}
    for command in commands:
        words = shlex.split(command)[2:]
        args = ["validate", str(REPO / words[0])]
        for flag, value in zip(words[1::2], words[2::2], strict=True):
            assert flag in ("--set", *as_set), command
            args += ["--set", value if flag == "--set" else f"{as_set[flag]}={value}"]
        res = CliRunner().invoke(app, args)
        assert res.exit_code == 0, (command, res.output)


def test_validate_accepts_sweep_configs():
    from typer.testing import CliRunner

    from antisync.cli.app import app

    res = CliRunner().invoke(app, ["validate", str(REPO / "configs" / "atlas6.yaml")])
    assert res.exit_code == 0, res.output
    assert "# ok: sweep of 112 graph(s), 1902 directed edge(s) in 848 orbit(s)" in res.output


# ---- Fig. 2b: Lambda of the L = 1 lollipop link against N -------------------------------------


def _fig2b(tmp_path, nodes: str, realizations: int) -> tuple[list[dict], dict]:
    from antisync.report.sweep import plot_fig2
    from antisync.sweeps import trend_in_n

    sw = load_sweep(
        REPO / "configs" / "lollipop_L1.yaml",
        [
            f"sweep.nodes={nodes}",
            "betas=[]",
            "repeats=1",
            "lambda.method=orbit",
            "dynamics.integrator=rk4",
            "dynamics.dt=0.04",
            f"realizations={realizations}",
            "screen.realizations=50",
        ],
    )
    path = tmp_path / "fig2b.h5"
    run_sweep(sw, output=path, progress=False)
    summary = sweep_summary(path)
    _, _, rows = plot_fig2(summary)
    return rows, trend_in_n(rows)


def test_fig2b_lambda_positive_and_decreasing_small_n(tmp_path):
    """N = 4..7 at 4000 realizations with the orbit estimator and RK4 at dt = 0.04 (seeded; the
    same values as Euler at dt = 0.001 within errors, ten times faster): every Lambda is positive
    by more than 4 standard errors, no step increases, and 4->5, 5->6 decrease resolvedly.
    (The measured values for N = 4..20 at 50,000 realizations are in docs/sweeps.md.)"""
    rows, trend = _fig2b(tmp_path, "4..7", 4000)
    assert [r["N"] for r in rows] == [4, 5, 6, 7]
    assert trend["positive"] == [4, 5, 6, 7], rows
    assert trend["increases"] == [] and {(4, 5), (5, 6)} <= set(trend["decreases"]), (rows, trend)
    assert all(a["lambda_km"] > b["lambda_km"] for a, b in zip(rows, rows[1:], strict=False))


@pytest.mark.slow
def test_fig2b_lambda_positive_and_decreasing_all_n(tmp_path):
    """The whole of Fig. 2b, N = 4..20, at 200,000 realizations per N (about 7 minutes on two
    cores): positive everywhere by 4 standard errors, no resolved increase."""
    rows, trend = _fig2b(tmp_path, "4..20", 200_000)
    assert trend["positive"] == list(range(4, 21)), rows
    assert trend["increases"] == [], trend


def test_trend_in_n_counts_resolved_steps_and_the_gap():
    from antisync.sweeps import trend_in_n

    rows = [
        {"N": n, "lambda_km": v, "lambda_km_se": 1.0}
        for n, v in zip(range(4, 9), [30.0, 20.0, 18.0, 19.0, 3.0], strict=True)
    ]
    tr = trend_in_n(rows, z=4.0)
    assert tr["positive"] == [4, 5, 6, 7] and tr["not_positive"] == [8]  # 3 < 4 se
    assert tr["decreases"] == [(4, 5), (7, 8)] and tr["unresolved"] == [(5, 6), (6, 7)]
    assert tr["increases"] == [] and tr["gap"] == 3  # 5 -> 7 drops only 1: gap 2 is not enough
    rows[2]["lambda_km"] = 40.0
    assert trend_in_n(rows)["increases"] == [(5, 6)]


def test_fixed_frequencies_turn_the_orbit_reduction_off():
    """Automorphic edges are equal only when the dynamics is: fixed per-node frequencies break
    the symmetry (every edge integrated), drawn ones keep it (in distribution)."""
    text = """
sweep: {family: lollipop, path: 1, nodes: 5}
edges: all
betas: [0.5]
realizations: 100
model: MODEL
"""
    drawn = load_sweep_text(text.replace("MODEL", "{frequencies: {distribution: normal, sd: 0.1}}"))
    fixed = load_sweep_text(text.replace("MODEL", "{frequencies: [0.1, -0.1, 0.0, 0.2, -0.2]}"))
    (e_drawn,) = family_graphs(drawn)
    (e_fixed,) = family_graphs(fixed)
    assert len(set(e_drawn.rep.values())) < len(e_drawn.edges)
    assert e_fixed.rep == {e: e for e in e_fixed.edges}


# ---- issue 26: the sweep honours sync.threshold, and says what its screening cannot see ----
def test_sync_threshold_is_the_swept_threshold():
    """``sync.threshold`` is another spelling of ``dynamics.threshold``: a sweep that gives it
    sweeps it (it used to store [0.99] when 0.9 was asked)."""
    sw = load_sweep_text("sweep: {family: atlas, nodes: 4}\nsync: {threshold: 0.9}")
    assert sw.thresholds == (0.9,) and sw.base.dynamics.threshold == 0.9
    assert load_sweep_text("sweep: {family: atlas, nodes: 4}\ndynamics: {threshold: 0.9}").thresholds == (
        0.9,
    )
    with pytest.raises(ConfigError, match=r"either thresholds: \[...\] or sync.threshold"):
        load_sweep_text("sweep: {family: atlas, nodes: 4}\nthresholds: [0.9]\nsync: {threshold: 0.9}")
    with pytest.raises(ConfigError, match="disagree"):
        load_sweep_text(
            "sweep: {family: atlas, nodes: 4}\nsync: {threshold: 0.9}\ndynamics: {threshold: 0.99}"
        )


def test_a_sweep_with_a_model_says_its_screening_ignores_the_model(tmp_path):
    text = TINY + "model: {phase_lag: 0.1}\n"
    said = []
    run_sweep(
        load_sweep_text(text, ["realizations=20", "screen.realizations=5", "top.graphs=0"]),
        output=tmp_path / "m.h5",
        progress=False,
        log=said.append,
    )
    assert any("screening integrates the paper's identical" in m for m in said), said
