"""Every link of a real network (issue 14, items 4 and 5): exact measures without a Kuramoto
run, summaries that sort and flag hundreds of links, CSV, and the large-graph report.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import antisync
from antisync.cli.app import app
from antisync.errors import AntisyncError
from antisync.physics.graphs import GraphError, build_graph
from antisync.report.links import compare, is_large
from antisync.stats.records import flag_signs, primary_measure, sort_records
from antisync.stats.summary import sign_resolved
from antisync.store import read_views

runner = CliRunner()

BA = {"kind": "networkx", "generator": "barabasi_albert_graph", "args": {"n": 200, "m": 2, "seed": 5}}
EXACT = f"""
name: ba200
graph: {json.dumps(BA)}
measures: [xi2, rw]
betas: [0.5]              # ignored without km: nothing is integrated
realizations: 2000
"""
# 34 nodes: a large graph for the report, four links so that the Kuramoto run is short
KARATE = """
name: karate4
graph: {kind: networkx, generator: karate_club_graph}
edges: ["0->31", "31->0", "33->32", "32->33"]
betas: []
measures: [km, xi2, rw]
realizations: 120
block_size: 10
seed: 2
dynamics: {dt: 0.002, t_max: 60}
"""
SMALL = """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3"]
betas: [0.5]
measures: [km, xi2]
realizations: 120
block_size: 20
seed: 3
dynamics: {dt: 0.002, t_max: 60}
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def assert_one_line(res, message: str) -> None:
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert "Traceback" not in res.output, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
    assert message in lines[0], (message, lines[0])


def _run(tmp, name: str, text: str):
    cfg = tmp / f"{name}.yaml"
    cfg.write_text(text)
    out = tmp / f"{name}.h5"
    res = invoke("run", cfg, "--out", out, "--quiet")
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def exact(tmp_path_factory):
    """A 200-node Barabasi-Albert graph, measures [xi2, rw], through the CLI."""
    return _run(tmp_path_factory.mktemp("exact"), "ba200", EXACT)


@pytest.fixture(scope="module")
def karate(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("karate"), "karate4", KARATE)


def _json_records(path, *args):
    res = invoke("summary", path, "--format", "json", *args)
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)["records"]


# ---- exact measures without a Kuramoto run ---------------------------------------------------
def test_exact_only_run_stores_for_graph_values(exact):
    expected = antisync.measures.for_graph(BA)
    recs = antisync.load(exact).records
    assert len(recs) == len(expected) == 2 * 2 * (200 - 2)  # m (n - m) undirected edges
    assert [r["edge"] for r in recs] == [e["edge"] for e in expected]
    for r, e in zip(recs, expected, strict=True):
        assert r["lambda_xi2"] == e["lambda_xi2"] and r["lambda_rw"] == e["lambda_rw"]
        assert r["lambda_km"] is None and r["lambda_km_ci_low"] is None and r["F_mean"] is None
        assert r["beta"] is None and r["n"] == 0 and r["realizations"] == 0 and r["complete"]


def test_exact_only_run_integrates_nothing(exact):
    with h5py.File(exact, "r") as f:
        assert yaml.safe_load(f.attrs["config_yaml"])["measures"] == ["xi2", "rw"]
        (g,) = f["jobs"].values()
        assert not g.attrs["kuramoto"]
        assert g.attrs["realizations"] == g.attrs["realizations_done"] == 0
        assert g.attrs["seconds"] == 0.0  # time spent integrating
        assert g["blocks_done"].shape == (0,) and g["block_records"].shape[0] == 0
        assert g["variant_edge"].shape == (0,) and g["kept/status0"].shape == (0,)
        assert sorted(g["measures"]) == ["lambda_rw", "lambda_xi2"]
        assert json.loads(g["measures"].attrs["measures"]) == ["xi2", "rw"]
    assert not exact.with_name(exact.name + ".partial").exists()
    s = antisync.api.summarize(exact)
    assert s["kind"] == "run" and s["complete"]
    again = invoke("run", exact.with_name("ba200.yaml"), "--out", exact, "--resume")
    assert again.exit_code == 0 and "already complete" in again.output


def test_summary_table_of_an_exact_only_file(exact):
    res = invoke("summary", exact)
    assert res.exit_code == 0, res.output
    header = res.stdout.splitlines()[0].split()
    assert header == ["graph", "edge", "Lambda_xi2", "Lambda_RW"]
    assert "warning" not in res.stdout


# ---- summary: sort, sign flags, CSV ---------------------------------------------------------
def _parse(text: str, like):
    """A CSV cell back to the JSON value ``like`` holds."""
    if like is None:
        assert text == ""
        return None
    if isinstance(like, bool):
        return text == "True"
    return type(like)(text)


@pytest.mark.parametrize("by", ["xi2", "rw", "lambda"])
def test_sorted_csv_equals_sorted_json(exact, by):
    recs = _json_records(exact, "--sort", by)
    key = {"lambda": "lambda_xi2"}.get(by, f"lambda_{by}")
    values = [r[key] for r in recs]
    assert values == sorted(values, reverse=True)
    assert all(r["sign_resolved"] is None for r in recs)  # no Lambda^KM to resolve
    res = invoke("summary", exact, "--sort", by, "--format", "csv")
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(io.StringIO(res.stdout)))
    assert len(rows) == len(recs) and list(rows[0]) == list(recs[0])
    for row, rec in zip(rows, recs, strict=True):
        assert {k: _parse(row[k], v) for k, v in rec.items()} == rec


def test_kuramoto_records_are_flagged_and_sorted(karate):
    recs = _json_records(karate, "--sort", "km")
    assert [r["lambda_km"] for r in recs] == sorted((r["lambda_km"] for r in recs), reverse=True)
    for r in recs:
        assert r["sign_resolved"] == sign_resolved(r) in (-1, 0, 1)
    plain = antisync.load(karate).records
    assert sort_records(plain, "lambda") == sort_records(plain, "km")
    assert [r["edge"] for r in flag_signs(sort_records(plain, "km"))] == [r["edge"] for r in recs]
    table = invoke("summary", karate, "--sort", "km").stdout.splitlines()
    assert "sign" in table[0].split() and "Lambda_KM" in table[0].split()


def test_sort_keeps_records_without_the_value_last():
    recs = [
        {"edge": "a", "lambda_rw": None},
        {"edge": "b", "lambda_rw": -1.0},
        {"edge": "c", "lambda_rw": 2.0},
    ]
    assert [r["edge"] for r in sort_records(recs, "rw")] == ["c", "b", "a"]
    assert primary_measure(recs) == "lambda_rw"
    with pytest.raises(AntisyncError, match="no record has lambda_xi2; these records have rw"):
        sort_records(recs, "xi2")


# ---- report ------------------------------------------------------------------------------------
def _valid(path) -> bool:
    head = path.read_bytes()[:8]
    return head.startswith(b"\x89PNG\r\n\x1a\n") if path.suffix == ".png" else head.startswith(b"%PDF")


def test_report_of_an_exact_only_large_graph(exact, tmp_path):
    res = invoke("report", exact, "--out", tmp_path, "--pdf", "--top", "5", "--quiet")
    assert res.exit_code == 0, res.output
    (view,) = read_views(exact)
    assert is_large(view)
    names = {p.name for p in tmp_path.iterdir()}
    for stem in ("lambda_sorted", "top_links", "measure_pairs"):
        for ext in ("png", "pdf"):
            p = tmp_path / f"ba200_{stem}.{ext}"  # the config's name
            assert p.name in names and _valid(p), p
    assert "ba200_graph.png" not in names  # Fig. 1a's labels: small graphs only


def test_report_of_a_kuramoto_large_graph(karate, tmp_path):
    res = invoke("report", karate, "--out", tmp_path, "--quiet")
    assert res.exit_code == 0, res.output
    (view,) = read_views(karate)
    for stem in ("lambda_sorted", "top_links", "measure_pairs"):
        assert _valid(tmp_path / f"karate4_{stem}.png")
    recs = antisync.load(karate).records
    resolved = [r for r in recs if sign_resolved(r) != 0]
    for key in ("lambda_xi2", "lambda_rw"):
        c = compare(recs, "lambda_km", key)
        # only links whose Kuramoto sign is resolved count for the sign agreement
        assert c["total"] == len(resolved) and c["links"] == len(recs)
        agree = sum(np.sign(r[key]) == sign_resolved(r) for r in resolved)
        assert c["agree"] == agree


def test_report_of_a_small_graph_keeps_fig1(tmp_path):
    out = _run(tmp_path, "small", SMALL)
    res = invoke("report", out, "--out", tmp_path / "fig", "--quiet")
    assert res.exit_code == 0, res.output
    names = {p.name for p in (tmp_path / "fig").iterdir()}
    assert {"small_graph.png", "small_F_beta.png", "small_histograms.png", "index.md"} <= names
    assert not any("lambda_sorted" in n or "top_links" in n or "measure_pairs" in n for n in names)
    assert all(_valid(tmp_path / "fig" / n) for n in names if n != "index.md")


# ---- real networks -------------------------------------------------------------------------
def test_lesmis_keeps_its_co_appearance_weights():
    import networkx as nx

    g = build_graph({"kind": "networkx", "generator": "les_miserables_graph", "weighted": True})
    ref = nx.les_miserables_graph()
    assert g.number_of_edges() == 254
    assert all(g.edges[u, v]["weight"] == ref.edges[u, v]["weight"] for u, v in ref.edges)
    unit = build_graph({"kind": "networkx", "generator": "les_miserables_graph"})
    assert {d["weight"] for *_, d in unit.edges(data=True)} == {1.0}
    with pytest.raises(GraphError, match="graph.weighted must be true or false"):
        build_graph({"kind": "networkx", "generator": "les_miserables_graph", "weighted": "yes"})


def test_ieee118_topology_is_the_case_files():
    """configs/ieee118.edges: the 179 distinct lines of PYPOWER's case118 (186 branches less 7
    parallel circuits) on buses 1..118, connected; the config damages all 358 directed links."""
    import networkx as nx

    from antisync.plan.config import load_config
    from antisync.plan.jobs import make_job

    configs = Path(__file__).resolve().parents[1] / "configs"
    job = make_job(load_config(configs / "ieee118.yaml"))
    g = build_graph({"kind": "edgelist", "path": str(configs / "ieee118.edges")})
    assert (g.number_of_nodes(), g.number_of_edges()) == (118, 179) and nx.is_connected(g)
    assert sorted(g.nodes) == list(range(1, 119))
    assert len(job.edges) == 358
    # a few lines as the case file lists them, and a parallel pair stored once
    assert {(1, 2), (5, 8), (68, 116), (42, 49)} <= {tuple(sorted(e)) for e in g.edges}


# ---- bad input ---------------------------------------------------------------------------------
def test_bad_input_is_one_line(exact, tmp_path):
    assert_one_line(invoke("summary", exact, "--sort", "lambda_km"), "--sort must be one of lambda, km, xi2")
    assert_one_line(invoke("summary", exact, "--sort", "km"), "cannot sort by km: no record has lambda_km")
    assert_one_line(invoke("summary", exact, "--format", "xlsx"), "--format must be one of table, json, csv")
    assert_one_line(invoke("report", exact, "--top", "0"), "--top must be a positive number")
    cfg = exact.with_name("ba200.yaml")
    out = tmp_path / "x.h5"
    for override, message in [
        ("measures=[xi2, rws]", "measures must be one of km, linear, xi2, rw, km_nnc, got 'rws'"),
        ("measures=[rw, km_nnc]", "km_nnc is a raw-coupling twin of the km run; add km"),
        ("graph.weighted=1", "graph.weighted must be true or false"),
    ]:
        assert_one_line(invoke("run", cfg, "--out", out, "--set", override, "-q"), message)
    assert not out.exists()
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("sweep: {family: lollipop, nodes: [4], path: 1}\nmeasures: [xi2, rw]\n")
    assert_one_line(invoke("validate", sweep), "a sweep screens and ranks its graphs by Lambda^KM")
