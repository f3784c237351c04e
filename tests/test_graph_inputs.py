"""Getting a network into antisync (issue 30): every input form of one weighted graph builds
the same Omega; a graph object runs through the API and its result file needs no object
afterwards; every bad input is one line; ``antisync --version``."""

import csv
import json
import re
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
import yaml
from helpers import assert_one_line
from networkx.algorithms import bipartite
from typer.testing import CliRunner

import antisync
from antisync._version import __version__
from antisync.cli.app import app
from antisync.errors import AntisyncError
from antisync.physics.graphs import (
    GraphError,
    build_graph,
    from_edgelist,
    graph_spec,
    node_order,
    omega_matrix,
)
from antisync.plan.config import load_config

runner = CliRunner()
REPO = Path(__file__).resolve().parent.parent


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def davis():
    """The Southern Women: 18 women linked by the number of events they attended together
    (names with spaces, weights 1 to 7)."""
    b = nx.davis_southern_women_graph()
    g = bipartite.weighted_projected_graph(b, b.graph["top"])
    return nx.Graph((u, v, {"weight": float(w)}) for u, v, w in g.edges(data="weight"))


def _quoted(text: str) -> str:
    return '"' + text.replace('"', '""') + '"'


def _write_forms(g: nx.Graph, folder) -> dict[str, str]:
    """Each file form of ``g`` in ``folder``: ``{form: the config's graph: line}``, paths
    relative to the config file."""
    forms = {}
    # whitespace columns, names in double quotes, a comment, a blank line, a trailing comment
    lines = ["# the Southern Women, co-attendance counts", ""]
    lines += [f"{_quoted(u)}  {_quoted(v)}\t{w:g}  # link" for u, v, w in g.edges(data="weight")]
    (folder / "quoted.edges").write_text("\n".join(lines) + "\n")
    forms["quoted whitespace"] = "{kind: edgelist, path: quoted.edges}"
    # tab-separated, as networkx writes it: .tsv by its name, another name by graph.delimiter
    nx.write_weighted_edgelist(g, folder / "women.tsv", delimiter="\t")
    forms["tsv"] = "{kind: edgelist, path: women.tsv}"
    nx.write_weighted_edgelist(g, folder / "women_tab.txt", delimiter="\t")
    forms["tab delimiter"] = "{kind: edgelist, path: women_tab.txt, delimiter: tab}"
    # CSV with a header line, as a spreadsheet writes it
    with open(folder / "women.csv", "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["Source", "Target", "Weight"])
        out.writerows(g.edges(data="weight"))
    forms["csv with header"] = "{kind: edgelist, path: women.csv}"
    # commas in a file without .csv: graph.delimiter
    nx.write_weighted_edgelist(g, folder / "women_comma.txt", delimiter=",")
    forms["comma delimiter"] = "{kind: edgelist, path: women_comma.txt, delimiter: ','}"
    nx.write_graphml(g, folder / "women.graphml")
    forms["graphml"] = "{kind: graphml, path: women.graphml}"
    nx.write_gml(g, folder / "women.gml")
    forms["gml"] = "{kind: gml, path: women.gml}"
    forms["inline"] = json.dumps(graph_spec(g))
    return forms


def test_every_input_form_builds_the_same_graph(tmp_path, davis):
    folder = tmp_path / "data"
    folder.mkdir()
    forms = _write_forms(davis, folder)
    ref_nodes, ref_omega = node_order(davis), omega_matrix(davis)
    assert len(ref_nodes) == 18 and set(np.unique(ref_omega)) > {1.0, 6.0}
    for form, graph in forms.items():
        cfg_path = folder / f"{form.replace(' ', '_')}.yaml"
        cfg_path.write_text(f"graph: {graph}\n")
        cfg = load_config(cfg_path)  # as `antisync run` reads it: paths relative to the config
        g = build_graph(cfg.graph, seed=cfg.seed)
        assert node_order(g) == ref_nodes, form
        assert np.array_equal(omega_matrix(g), ref_omega), form


def test_a_graph_object_runs_through_the_api_and_its_file_needs_no_object(tmp_path, davis):
    u, v, _ = max(davis.edges(data="weight"), key=lambda e: e[2])
    config = {
        "graph": davis,
        "name": "women",
        "edges": [f"{u}->{v}", f"{v}->{u}"],
        "betas": [0.5],
        "realizations": 64,
        "block_size": 16,
        "seed": 3,
        "dynamics": {"dt": 0.002, "t_max": 60},
    }
    out = tmp_path / "women.h5"
    res = antisync.run(config, output=out)
    assert res.complete and {r["graph"] for r in res.records} == {"women"}
    assert [r["edge"] for r in res.records] == [f"{u}->{v}", f"{v}->{u}"]
    assert config["graph"] is davis  # the caller's mapping is left as it is
    # the file holds the graph: the stored config rebuilds it without the object
    stored = yaml.safe_load(res.config_yaml)
    assert stored["graph"]["kind"] == "inline"
    g = build_graph(stored["graph"])
    assert node_order(g) == node_order(davis)
    assert np.array_equal(omega_matrix(g), omega_matrix(davis))
    # resume from the stored config alone: the same run, left as it is
    again = antisync.run(stored, output=out, resume=True)
    assert again.records == res.records
    # and the same object again is the same run (same simulation key)
    assert antisync.run({**config, "graph": davis.copy()}, output=out, resume=True).records == res.records
    summary = invoke("summary", out, "--format", "json")
    assert summary.exit_code == 0, summary.output
    assert {r["graph"] for r in json.loads(summary.stdout)["records"]} == {"women"}


def test_graph_objects_in_a_sweep_are_named_by_place(tmp_path):
    path = nx.relabel_nodes(nx.path_graph(4), {i: f"p {i}" for i in range(4)})
    star = nx.star_graph(3)
    nx.set_edge_attributes(star, 2.0, "weight")
    res = antisync.sweep(
        {"sweep": {"family": "graphs", "graphs": [path, star]}, "betas": [], "screen": {"enabled": False}},
        realizations=64,
        lambda_={"method": "orbit"},
        dynamics={"integrator": "rk4", "dt": 0.04},
        output=tmp_path / "sweep.h5",
    )
    assert res.complete and {r["graph"] for r in res.records} == {"graph1", "graph2"}
    assert "p 0->p 1" in {r["edge"] for r in res.records}


def test_header_detection(tmp_path):
    p = tmp_path / "g.txt"
    # 'u v' names the columns ...
    p.write_text("u v weight\n1 2 2\n2 3\n")
    assert sorted(from_edgelist(p).edges(data="weight")) == [(1, 2, 2.0), (2, 3, 1.0)]
    # ... unless u or v is a node of another line: then it is a link
    p.write_text("u v\nv w\n")
    assert sorted(from_edgelist(p).edges) == [("u", "v"), ("v", "w")]
    assert sorted(from_edgelist(p, header=True).edges) == [("v", "w")]
    # a first line with a number third is a link whatever its names
    p.write_text("source target 2\ntarget x\n")
    assert from_edgelist(p).number_of_edges() == 2
    # other names are a header when the config says so
    p.write_text("name1;name2;strength\na;b;2\n")
    assert list(from_edgelist(p, ";", header=True).edges(data="weight")) == [("a", "b", 2.0)]
    with pytest.raises(GraphError, match="a header line[?] give graph.header: true"):
        from_edgelist(p, ";")
    # header: false reads every line as a link
    p.write_text("u v weight\na b 1\n")
    with pytest.raises(GraphError, match="weight 'weight' is not a number") as info:
        from_edgelist(p, header=False)
    assert "graph.header" not in str(info.value)


def test_quotes_and_separators_inside_names(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text('"Smith, John",Doe # not a comment,1.5\n  # a comment\nDoe # not a comment, "x""y"\n')
    g = from_edgelist(p)
    assert sorted(g.edges(data="weight")) == [
        ("Doe # not a comment", 'x"y', 1.0),
        ("Smith, John", "Doe # not a comment", 1.5),
    ]
    p = tmp_path / "g.edges"
    p.write_text('"Smith, John" "a;b" 2 # comment\n"a;b" c\n')
    assert sorted(from_edgelist(p).edges) == [("Smith, John", "a;b"), ("a;b", "c")]


FILES = {
    "women.txt": "Evelyn Jefferson Brenda Rogers 6\n",
    "tabs.txt": "Evelyn Jefferson\tBrenda Rogers\t6\n",
    "open.edges": '"Evelyn Jefferson Brenda 6\n',
    "glued.edges": '"Evelyn"Jefferson Brenda 6\n',
    "semi.csv": "a;b;1\nb;c;2\n",
    "names.csv": "name1,name2,strength\na,b,2\n",
    "commas.txt": "Evelyn,Brenda,6\n",
    "csvquote.csv": 'a,"b c,3\n',
    "empty.csv": "a,,3\n",
    "bad.graphml": "<graphml><graph>",
    "nograph.graphml": '<graphml xmlns="http://graphml.graphdrawing.org/xmlns"></graphml>',
    "directed.graphml": "\n".join(nx.generate_graphml(nx.DiGraph([(1, 2), (2, 3)]))),
    "text.graphml": "\n".join(nx.generate_graphml(nx.Graph([(1, 2, {"weight": "heavy"}), (2, 3)]))),
    "bad.gml": "graph [ node [ id 0 ",
    "directed.gml": "\n".join(nx.generate_gml(nx.DiGraph([(1, 2), (2, 3)]))),
    "twins.gml": 'graph [ node [ id 0 label "a" ] node [ id 1 label "a" ] edge [ source 0 target 1 ] ]',
    "g.graphml": "\n".join(nx.generate_graphml(nx.path_graph(3))),
}

BAD_GRAPHS = [
    ("{kind: edgelist, path: women.txt}", 'needs double quotes ("Evelyn Jefferson")'),
    ("{kind: edgelist, path: tabs.txt}", "give graph.delimiter: tab"),
    ("{kind: edgelist, path: open.edges}", 'a quote " is not closed'),
    ("{kind: edgelist, path: glued.edges}", "text right after a closing quote"),
    ("{kind: edgelist, path: semi.csv}", "give graph.delimiter: ';'"),
    ("{kind: edgelist, path: names.csv}", "a header line? give graph.header: true"),
    ("{kind: edgelist, path: commas.txt}", "give graph.delimiter: ','"),
    ("{kind: edgelist, path: csvquote.csv}", "unexpected end of data"),
    ("{kind: edgelist, path: empty.csv}", "a node label is empty"),
    ("{kind: edgelist, path: names.csv, delimiter: x}", "graph.delimiter must be whitespace"),
    ("{kind: edgelist, path: names.csv, header: maybe}", "graph.header must be true"),
    ("{kind: edgelist, path: g.graphml}", "give graph: {kind: graphml, path: g.graphml}"),
    ("{kind: edgelist, path: names.csv, weight: w}", "unknown key 'graph.weight'"),
    ("{kind: graphml, path: bad.graphml}", "is not well-formed XML"),
    ("{kind: graphml, path: missing.graphml}", "cannot read GraphML file"),
    ("{kind: graphml, path: nograph.graphml}", "no <graph> element"),
    ("{kind: graphml, path: directed.graphml}", "the GraphML graph is directed"),
    ("{kind: graphml, path: text.graphml}", "has weight 'heavy'"),
    ("{kind: graphml, path: g.graphml, weight: 3}", "graph.weight must name the edge attribute"),
    ("{kind: gml, path: bad.gml}", "networkx cannot read it as GML"),
    ("{kind: gml, path: directed.gml}", "the GML graph is directed"),
    ("{kind: gml, path: twins.gml}", "the same label 'a'"),
    ("{kind: gml, path: missing.gml}", "cannot read GML file"),
    ("{kind: inline, links: [[1, 2], [2, 1]]}", "graph.links[1]: link 2-1 is listed twice"),
    ("{kind: inline, links: [[1, 2, -1]]}", "graph.links[0]: weight must be a positive"),
    ("{kind: inline, links: [[1, 2.5]]}", "must be an integer or a non-empty name"),
    ("{kind: inline, links: [[1, 2], [3, 4]]}", "disconnected"),
    ("{kind: inline, links: [[1, 2]], nodes: [1, 2, 3]}", "disconnected"),
    ("{kind: inline, links: 5}", "graph.links must be a non-empty list"),
]


@pytest.mark.parametrize("graph,message", BAD_GRAPHS)
def test_bad_graph_inputs_are_one_line(tmp_path, graph, message):
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"graph: {graph}\nrealizations: 20\n")
    out = tmp_path / "o.h5"
    assert_one_line(invoke("validate", cfg), message)
    assert_one_line(invoke("run", cfg, "--out", out, "-q"), message)
    assert not out.exists()


@pytest.mark.parametrize(
    "graph,words",
    [
        (nx.DiGraph([(1, 2), (2, 3)]), ["graph", "undirected", "DiGraph"]),
        (nx.grid_2d_graph(2, 2), ["graph", "(0, 0)", "tuple", "convert_node_labels_to_integers"]),
        (nx.Graph([(1, 2, {"weight": 0})]), ["graph", "edge 1-2", "weight 0"]),
        (nx.Graph([(1, "1"), ("1", 2)]), ["print alike"]),
        (nx.Graph([("a->b", "c")]), ["'a->b'", "'->'"]),
    ],
)
def test_bad_graph_objects_are_one_line(tmp_path, graph, words):
    with pytest.raises(AntisyncError) as info:
        antisync.run({"graph": graph}, output=tmp_path / "x.h5")
    text = str(info.value)
    assert "\n" not in text and all(w in text for w in words), text
    assert not (tmp_path / "x.h5").exists()


def test_graph_objects_with_mixed_or_lonely_nodes_keep_them(davis):
    mixed = nx.Graph([(1, "a"), ("a", 2)])
    spec = graph_spec(mixed)
    assert spec["nodes"] == [1, "a", 2]  # unsortable: the insertion order is the node order
    assert node_order(build_graph(spec)) == node_order(mixed) == [1, "a", 2]
    lonely = nx.Graph([(1, 2)])
    lonely.add_node(3)
    with pytest.raises(GraphError, match="disconnected"):
        build_graph(graph_spec(lonely))
    multi = nx.MultiGraph([(1, 2, {"weight": 2.0}), (1, 2, {"weight": 0.5}), (2, 3)])
    assert graph_spec(multi)["links"] == [[1, 2, 2.5], [2, 3]]  # parallel links add up
    assert "nodes" not in graph_spec(davis)


def test_graph_files_are_relative_to_the_config_file(tmp_path, monkeypatch):
    from antisync.sweeps import load_sweep

    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "p.edges").write_text("1 2\n2 3\n")
    monkeypatch.chdir(tmp_path)  # not the config's folder
    expected = str(tmp_path / "sub" / "p.edges")
    sweep = tmp_path / "sub" / "s.yaml"
    sweep.write_text("sweep: {family: graphs, graphs: [{kind: edgelist, path: p.edges, name: p}]}\n")
    assert load_sweep(sweep).family["graphs"][0]["path"] == expected
    cfg = tmp_path / "sub" / "c.yaml"
    cfg.write_text("graph: {kind: gml, path: elsewhere.gml}\n")
    # --set graph.path (and the API's graph=) apply before the paths are resolved
    assert load_config(cfg, ["graph={kind: edgelist, path: p.edges}"]).graph["path"] == expected
    assert load_config(cfg, values={"graph.path": "p.edges"}).graph["path"] == expected


def test_version():
    res = invoke("--version")
    assert res.exit_code == 0 and res.stdout.strip() == f"antisync {__version__}"


def test_docs_example_runs_as_written(tmp_path, monkeypatch):
    """The ```python block of docs/graphs.md, in an empty folder."""
    (code,) = re.findall(r"```python\n(.*?)```", (REPO / "docs" / "graphs.md").read_text(), flags=re.S)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "docs/graphs.md", "exec"), {})  # noqa: S102 -- our own docs
    assert antisync.load(tmp_path / "women.h5").complete
    res = invoke("validate", tmp_path / "data" / "women.yaml")
    assert res.exit_code == 0 and "# ok: graph women with 18 nodes" in res.stdout, res.output
