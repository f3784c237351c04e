"""The public Python API and the CLI's parser under hostile arguments.

Every bad argument of ``antisync.run``, ``antisync.sweep``, ``antisync.load``,
``antisync.summarize`` and ``antisync.measures.for_graph`` ends in an
:class:`~antisync.errors.AntisyncError` whose one line names the argument, before any file or
folder exists; never in a TypeError, a yaml RepresenterError or a networkx ValueError. numpy
scalars are the Python numbers they hold. A mapping given to a section merges into it. A bad
option on the command line is the CLI's one line, not click's usage box.
"""

import contextlib
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import antisync
from antisync.cli.app import app
from antisync.errors import AntisyncError, ConfigError, StoreError
from antisync.physics.graphs import GraphError
from antisync.plan.config import Config
from antisync.plan.sources import resolve_config as _config
from antisync.plan.sources import sections as _sections

REPO = Path(__file__).resolve().parent.parent
# a tiny run: 4 nodes, one link, no beta grid, 8 realizations of a short trajectory
TINY = {
    "graph": {"kind": "lollipop", "nodes": 4, "path": 1},
    "edges": ["2->1"],
    "betas": [],
    "realizations": 8,
    "dynamics": {"dt": 0.01, "t_max": 50.0},
}
TINY_SWEEP = {
    "sweep": {"family": "lollipop", "nodes": [4], "path": 1},
    "betas": [],
    "realizations": 8,
    "screen": {"enabled": False, "realizations": 50},
    "top": {"graphs": 0, "betas": [0.5]},
    "dynamics": {"dt": 0.01, "t_max": 50.0},
}


def snapshot(folder: Path) -> dict:
    """Every path below ``folder`` with its size and mtime: 'no file touched' is equality."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) if p.is_file() else None
        for p in sorted(folder.rglob("*"))
    }


def assert_one_line_error(exc: BaseException, *names: str) -> None:
    """An AntisyncError whose message is one line naming each of ``names``."""
    assert isinstance(exc, AntisyncError), repr(exc)
    message = str(exc)
    assert message and "\n" not in message, message
    for name in names:
        assert name in message, (name, message)


@contextlib.contextmanager
def empty_folder():
    """A fresh empty folder as the working directory (hypothesis examples cannot share
    pytest's tmp_path: each must start from nothing to show that nothing was made)."""
    with tempfile.TemporaryDirectory() as folder, contextlib.chdir(folder):
        yield Path(folder)


# ---- sections merge ---------------------------------------------------------------------
def test_sections_are_read_from_the_schema():
    """The API's sections are the schema's: config.py's table of sections, and a sweep's
    screen and top; a new section added to Config cannot be forgotten by the API."""
    from antisync.plan.config import _SECTIONS as CONFIG_SECTIONS
    from antisync.sweeps import Sweep

    assert _sections() == set(CONFIG_SECTIONS)
    assert _sections(Sweep) == set(CONFIG_SECTIONS) | {"screen", "top"}
    assert "graph" not in _sections(Sweep) and "sweep" not in _sections(Sweep)


# (section, what the config sets, what the keyword sets): every section of the schema
SECTION_CASES = {
    "dynamics": ({"t_max": 40.0, "dt": 0.01}, {"dt": 0.02}),
    "lambda": ({"dbeta": 0.02}, {"method": "pathwise"}),
    "histogram": ({"bins": 50, "tau_max": 20.0}, {"bins": 60}),
    "linear": ({"realizations": 100}, {"method": "euler"}),
    "model": ({"inertia": 1.0, "damping": 1.5}, {"damping": 2.0}),
    "sync": ({"criterion": "frequency", "tolerance": 0.001}, {"tolerance": 0.01}),
    "stop": ({"when": "signs-resolved", "first_look": 4}, {"tolerance": 0.1}),
}


def test_every_section_has_a_merge_case():
    assert set(SECTION_CASES) == _sections()


@pytest.mark.parametrize("form", ["mapping", "file", "Config"])
@pytest.mark.parametrize("section", sorted(SECTION_CASES))
def test_a_section_keyword_merges_into_the_config(tmp_path, section, form):
    """``model={"damping": 2}`` used to replace the whole model section (frequencies and
    inertia gone: another model ran). Now the keyword's keys replace those keys only, and
    nothing else of the config changes, whatever form the config has."""
    given_, override = SECTION_CASES[section]
    raw = {**TINY, section: given_}
    if form == "file":
        config = tmp_path / "c.yaml"
        config.write_text(yaml.safe_dump(raw))
    elif form == "Config":
        config = _config(raw, {}, None)
    else:
        config = raw
    before = _config(config, {}, None).to_dict()
    after = _config(config, {"lambda_" if section == "lambda" else section: override}, None).to_dict()
    assert after[section] == {**before[section], **override}
    assert {k: v for k, v in after.items() if k != section} == {
        k: v for k, v in before.items() if k != section
    }


def test_ieee14_model_and_sync_keywords_keep_the_rest_of_their_section():
    """The issue's case: the IEEE 14-bus grid keeps its frequencies, inertia and criterion."""
    path = REPO / "configs" / "ieee14_grid.yaml"
    base = _config(path, {}, None)
    damped = _config(path, {"model": {"damping": 2}}, None)
    assert damped.model.frequencies == base.model.frequencies and damped.model.frequencies
    assert (damped.model.inertia, damped.model.damping) == (base.model.inertia, 2.0)
    assert damped.sync == base.sync
    looser = _config(path, {"sync": {"tolerance": 0.01}}, None)
    assert looser.sync.criterion == base.sync.criterion == "frequency"
    assert looser.sync.tolerance == 0.01 and looser.model == base.model


def test_none_resets_a_section_and_graph_is_replaced_whole():
    cfg = _config({**TINY, "model": {"inertia": 1.0}}, {"model": None}, None)
    assert cfg.model == Config(graph=TINY["graph"], output="c.h5").model
    barbell = _config(TINY, {"graph": {"kind": "barbell", "m1": 3}, "edges": "all"}, None)
    assert barbell.graph == {"kind": "barbell", "m1": 3}  # not merged with nodes/path


def test_sweep_section_keywords_merge(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = antisync.sweep(
        TINY_SWEEP,
        output="s.h5",
        screen={"realizations": 20},
        top={"realizations": 4},
        dynamics={"dt": 0.02},
    )
    stored = yaml.safe_load(res.config_yaml)
    assert stored["screen"]["enabled"] is False and stored["screen"]["realizations"] == 20
    assert stored["top"]["betas"] == [0.5] and stored["top"]["realizations"] == 4
    assert (stored["dynamics"]["dt"], stored["dynamics"]["t_max"]) == (0.02, 50.0)


# ---- numpy values are numbers -------------------------------------------------------------
def test_numpy_scalars_and_arrays_are_the_numbers_they_hold(tmp_path, monkeypatch):
    """``np.int64(8)`` used to be refused as no integer, an ``np.float64`` inside a section
    passed validation and then failed in yaml's representer after the run had begun."""
    monkeypatch.chdir(tmp_path)
    res = antisync.run(
        {**TINY, "graph": {"kind": "lollipop", "nodes": np.int64(4), "path": np.int32(1)}},
        output=tmp_path / "np.h5",
        realizations=np.int64(8),
        seed=np.uint16(3),
        betas=np.array([0.5]),
        edges=np.array(["2->1"]),
        dynamics={"t_max": np.float32(40.0), "dt": np.float64(0.01)},
        resume=np.bool_(False),
    )
    stored = yaml.safe_load(res.config_yaml)
    assert (stored["realizations"], stored["seed"], stored["betas"]) == (8, 3, [0.5])
    assert stored["dynamics"]["t_max"] == 40.0 and stored["graph"]["nodes"] == 4
    rows = antisync.measures.for_graph({"kind": "lollipop", "nodes": np.int64(6), "path": np.int8(3)})
    assert len(rows) == 2 * nx.number_of_edges(nx.lollipop_graph(3, 3))


def test_an_executor_object_and_a_log_callable_are_taken(tmp_path):
    from antisync.execution.executors.local import LocalExecutor

    said: list[str] = []
    ex = LocalExecutor("cpu", None)
    try:
        res = antisync.run(TINY, output=tmp_path / "r.h5", executor=ex, log=said.append)
        assert res.complete and said
        again = antisync.run(TINY, output=tmp_path / "r2.h5", executor=ex)  # left open: usable
        assert again.records == res.records
    finally:
        ex.close()


# ---- every bad argument: one line naming it, nothing made ----------------------------------
class NotAnExecutor:
    def run(self, work):  # no describe, no close
        return iter(())


def _bad_calls():
    from antisync.execution.executors.local import LocalExecutor

    run, sweep = antisync.run, antisync.sweep
    cases = [
        # (call, args, kwargs, error, words the message must hold)
        (run, (None,), {}, ConfigError, ["config", "None"]),
        (run, (123,), {}, ConfigError, ["config", "123"]),
        (run, (b"c.yaml",), {}, ConfigError, ["config", "b'c.yaml'"]),
        (run, (["c.yaml"],), {}, ConfigError, ["config"]),
        (run, ("",), {}, ConfigError, ["config"]),
        (run, ("c\0.yaml",), {}, ConfigError, ["config", "NUL"]),
        (run, (TINY,), {"output": 123}, ConfigError, ["output", "123"]),
        (run, (TINY,), {"output": b"o.h5"}, ConfigError, ["output"]),
        (run, (TINY,), {"output": ""}, ConfigError, ["output"]),
        (run, (TINY,), {"output": "o\0.h5"}, ConfigError, ["output", "NUL"]),
        (run, (TINY,), {"output": "d/" + "a" * 300 + ".h5"}, ConfigError, ["output", "too long"]),
        (run, (TINY,), {"output": "\ud800.h5"}, ConfigError, ["output"]),
        (run, (TINY,), {"resume": "yes"}, ConfigError, ["resume", "True or False", "'yes'"]),
        (run, (TINY,), {"resume": 1}, ConfigError, ["resume"]),
        (run, (TINY,), {"overwrite": None}, ConfigError, ["overwrite"]),
        (run, (TINY,), {"progress": "no"}, ConfigError, ["progress"]),
        (run, (TINY,), {"resume": True, "overwrite": True}, ConfigError, ["exclude each other"]),
        (run, (TINY,), {"log": "print"}, ConfigError, ["log", "callable", "'print'"]),
        (run, (TINY,), {"log": 3}, ConfigError, ["log"]),
        (run, (TINY,), {"executor": "dask"}, ConfigError, ["executor", "'dask'"]),
        (run, (TINY,), {"executor": object()}, ConfigError, ["executor"]),
        (run, (TINY,), {"executor": NotAnExecutor()}, ConfigError, ["executor"]),
        (run, (TINY,), {"executor": LocalExecutor}, ConfigError, ["executor"]),
        (run, (TINY,), {"realizations": object()}, ConfigError, ["realizations", "plain YAML data"]),
        (run, (TINY,), {"dynamics": {"dt": {0.1}}}, ConfigError, ["dynamics.dt"]),
        (run, (TINY,), {"name": b"x"}, ConfigError, ["name"]),
        (run, (TINY,), {"seed": np.datetime64("2024-01-01")}, ConfigError, ["seed"]),
        (run, (TINY,), {"betas": [0.5, 1j]}, ConfigError, ["betas[1]"]),
        (run, (TINY,), {"model": {1: 2}}, ConfigError, ["model", "string keys"]),
        (run, ({**TINY, "seed": object()},), {}, ConfigError, ["config.seed"]),
        (sweep, (None,), {}, ConfigError, ["config"]),
        (sweep, (Config(graph=TINY["graph"], output="c.h5"),), {}, ConfigError, ["config", "sweep"]),
        (sweep, (TINY_SWEEP,), {"output": 1.5}, ConfigError, ["output"]),
        (sweep, (TINY_SWEEP,), {"resume": True, "overwrite": True}, ConfigError, ["exclude each other"]),
        (sweep, (TINY_SWEEP,), {"log": "print"}, ConfigError, ["log"]),
        (sweep, (TINY_SWEEP,), {"executor": "local"}, ConfigError, ["executor"]),
        (sweep, (TINY_SWEEP,), {"screen": {"realizations": object()}}, ConfigError, ["screen.realizations"]),
        (sweep, ({**TINY_SWEEP, "top": {"betas": {0.5}}},), {}, ConfigError, ["config.top.betas"]),
        (antisync.load, (None,), {}, StoreError, ["path", "None"]),
        (antisync.load, (123,), {}, StoreError, ["path", "123"]),
        (antisync.load, (b"r.h5",), {}, StoreError, ["path"]),
        (antisync.load, ("r\0.h5",), {}, StoreError, ["path"]),
        (antisync.load, ("a" * 5000,), {}, StoreError, ["path", "too long"]),
        (antisync.api.summarize, (3.5,), {}, StoreError, ["path", "3.5"]),
    ]
    return [pytest.param(*c, id=f"{c[0].__name__}-{i}") for i, c in enumerate(cases)]


@pytest.mark.parametrize("call,args,kwargs,error,words", _bad_calls())
def test_bad_argument_is_one_line_naming_it_and_nothing_is_made(
    tmp_path, monkeypatch, call, args, kwargs, error, words
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(TINY))
    before = snapshot(tmp_path)
    with pytest.raises(error) as info:
        call(*args, **kwargs)
    assert_one_line_error(info.value, *words)
    assert snapshot(tmp_path) == before  # no results/ folder, no journal, no lock file


def test_resume_with_overwrite_leaves_an_existing_file_alone(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    antisync.run(TINY, output="r.h5")
    before = snapshot(tmp_path)
    with pytest.raises(ConfigError, match="resume and overwrite exclude each other: choose one"):
        antisync.run(TINY, output="r.h5", resume=True, overwrite=True)
    assert snapshot(tmp_path) == before


# ---- for_graph ---------------------------------------------------------------------------
def _path4():
    return nx.path_graph(4)


@pytest.mark.parametrize(
    "graph,kwargs,words",
    [
        (None, {}, ["graph", "None"]),
        (42, {}, ["graph", "42"]),
        ("karate_club_graph", {}, ["graph"]),
        (nx.DiGraph([(0, 1), (1, 0)]), {}, ["undirected", "DiGraph"]),
        (nx.MultiDiGraph([(0, 1), (1, 0)]), {}, ["undirected", "MultiDiGraph"]),
        (nx.Graph([(0, 1, {"weight": "2"}), (1, 2)]), {}, ["0-1", "weight", "'2'"]),
        (nx.Graph([(0, 1, {"weight": -1.0}), (1, 2)]), {}, ["0-1", "weight"]),
        (nx.Graph([(0, 1, {"weight": float("nan")}), (1, 2)]), {}, ["weight", "nan"]),
        (nx.Graph([(0, 1, {"weight": True}), (1, 2)]), {}, ["weight", "True"]),
        (nx.Graph([(0, 1, {"weight": None}), (1, 2)]), {}, ["weight", "None"]),
        (nx.Graph([(0, 1, {"weight": 1e300}), (1, 2)]), {}, ["weights sum"]),
        (nx.Graph([(0, 1), (1, 1), (1, 2)]), {}, ["self-loop"]),
        (nx.Graph([(1, "1"), ("1", 2)]), {}, ["print alike"]),
        (nx.Graph([(0, 1), (2, 3)]), {}, ["connected"]),
        (nx.Graph(), {}, ["connected"]),
        ({"kind": "lollipop", "nodes": 4.5, "path": 1}, {}, ["graph.nodes"]),
        ({"kind": "nope"}, {}, ["graph.kind"]),
        (_path4(), {"which": "km"}, ["which", "'km'"]),
        (_path4(), {"which": []}, ["which"]),
        (_path4(), {"which": None}, ["which"]),
        (_path4(), {"which": [3]}, ["which"]),
        (_path4(), {"edges": "0->1"}, ["edges", "'0->1'"]),
        (_path4(), {"edges": [0]}, ["edges"]),
        (_path4(), {"edges": []}, ["edges"]),
        (_path4(), {"edges": None}, ["edges"]),
        (_path4(), {"edges": ["0->2"]}, ["0->2"]),
        (_path4(), {"coupling": None}, ["coupling", "None"]),
        (_path4(), {"coupling": ["raw"]}, ["coupling"]),
        (_path4(), {"coupling": "raw"}, ["normalized"]),  # rw needs the normalized walk
    ],
)
def test_for_graph_bad_arguments_are_one_line(graph, kwargs, words):
    with pytest.raises(AntisyncError) as info:
        antisync.measures.for_graph(graph, **kwargs)
    assert_one_line_error(info.value, *words)


def test_directed_graphs_are_refused_as_graph_errors():
    with pytest.raises(GraphError, match="undirected"):
        antisync.measures.for_graph(nx.DiGraph(nx.complete_graph(3)))


weights = st.floats(0.25, 4.0)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    edges=st.lists(
        st.tuples(st.integers(0, 4), st.integers(0, 4), weights).filter(lambda e: e[0] != e[1]),
        min_size=4,
        max_size=12,
    )
)
def test_parallel_links_of_a_multigraph_add_up(edges):
    """Omega_ij is the total weight between i and j: a multigraph's measures are those of the
    simple graph whose weights are the sums of the parallel links (it used to keep the last)."""
    multi = nx.MultiGraph()
    simple = nx.Graph()
    for u, v, w in edges:
        multi.add_edge(u, v, weight=w)
        old = simple.edges[u, v]["weight"] if simple.has_edge(u, v) else 0.0
        simple.add_edge(u, v, weight=old + w)
    if not nx.is_connected(simple):
        with pytest.raises(GraphError, match="connected"):
            antisync.measures.for_graph(multi)
        return
    got = antisync.measures.for_graph(multi)
    want = antisync.measures.for_graph(simple)
    assert [r["edge"] for r in got] == [r["edge"] for r in want]
    for a, b in zip(got, want, strict=True):
        assert math.isclose(a["lambda_xi2"], b["lambda_xi2"], rel_tol=1e-9, abs_tol=1e-12)
        assert math.isclose(a["lambda_rw"], b["lambda_rw"], rel_tol=1e-9, abs_tol=1e-12)


# ---- fuzz: success or an AntisyncError, nothing else, nothing made on error -----------------
class Opaque:
    """An object yaml cannot store and no argument accepts."""


# paths stay inside the working folder: no "/" (a fuzzed output must never name /etc/...)
names = st.text(alphabet=st.sampled_from(list("ab.h5_- \n\t\0é") + ["\ud800", "\\", "~"]), max_size=12)
hostile = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.sampled_from([10**5000, -(10**5000)]),  # Python will not even print these
    st.floats(),
    names,
    st.binary(max_size=6),
    st.sampled_from(
        [
            np.int64(3),
            np.int8(-1),
            np.uint64(2**63),
            np.float32("nan"),
            np.float64("inf"),
            np.bool_(True),
            np.bool_(False),
            np.str_("x.h5"),
            np.array([1, 2]),
            np.array(0.5),
            np.datetime64("2024-01-01"),
            np.complex128(1j),
            Opaque(),
            object(),
            {1, 2},
            frozenset(),
            (),
            [],
            {},
            {"a": 1},
            [None],
            Path("p.h5"),
            Path(""),
            1j,
            Ellipsis,
            NotAnExecutor(),
        ]
    ),
)
hostile = st.one_of(hostile, st.lists(hostile, max_size=3), st.dictionaries(names, hostile, max_size=2))
RUN_ARGS = ["config", "output", "resume", "overwrite", "progress", "executor", "log"]
FUZZ = settings(
    max_examples=50, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)


def _call_in_empty_folder(call, *args, **kwargs):
    """``call(*args, **kwargs)`` in a fresh folder: success, or an AntisyncError after which
    the folder is still empty."""
    with empty_folder() as folder:
        try:
            call(*args, **kwargs)
        except AntisyncError as exc:
            assert_one_line_error(exc)
            assert snapshot(folder) == {}, (str(exc), snapshot(folder))
        finally:
            sys.stderr.flush()


@FUZZ
@given(arg=st.sampled_from(RUN_ARGS), value=hostile)
def test_fuzz_run_arguments(arg, value):
    args = {"config": TINY, "output": "r.h5", "resume": False, "overwrite": False, "progress": False}
    args[arg] = value
    config = args.pop("config")
    _call_in_empty_folder(antisync.run, config, **args)


@FUZZ
@given(arg=st.sampled_from(RUN_ARGS), value=hostile)
def test_fuzz_sweep_arguments(arg, value):
    args = {"config": TINY_SWEEP, "output": "s.h5"}
    args[arg] = value
    config = args.pop("config")
    _call_in_empty_folder(antisync.sweep, config, **args)


@FUZZ
@given(path=hostile, which=st.sampled_from([antisync.load, antisync.api.summarize]))
def test_fuzz_load_and_summarize(path, which):
    _call_in_empty_folder(which, path)


OVERRIDE_KEYS = [
    "realizations",
    "seed",
    "name",
    "betas",
    "edges",
    "measures",
    "threads",
    "graph",
    "dynamics",
    "lambda_",
    "histogram",
    "linear",
    "model",
    "sync",
    "stop",
]
# the plumbing of override values: numpy numbers at any depth, things yaml cannot store; small
# magnitudes (huge numbers are config.py's to refuse), so that a valid one stays quick
plumbing = st.one_of(
    st.sampled_from([np.int64(5), np.uint8(2), np.float64(0.5), np.float32(0.25), np.bool_(True)]),
    st.sampled_from([np.array([0.5]), np.array(["2->1"]), np.array([[1, 2]]), np.array([], dtype=float)]),
    st.sampled_from([Opaque(), {0.5}, b"x", 1j, np.datetime64("2024"), Path("x.h5"), ("2->1",)]),
    st.integers(-5, 10),
    st.floats(-10, 10),
    st.sampled_from([math.nan, math.inf, -math.inf]),
    names,
)
plumbing = st.one_of(
    plumbing,
    st.lists(plumbing, max_size=3),
    st.dictionaries(st.sampled_from(["dt", "t_max", "damping", "method", "when", "bins", "kind"]), plumbing),
)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(key=st.sampled_from(OVERRIDE_KEYS), value=plumbing)
def test_fuzz_override_values_are_stored_or_refused(key, value):
    """An override is a validated config whose YAML and resume key can be written, or a
    ConfigError naming it; the RepresenterError after the run had begun is gone."""
    try:
        cfg = _config(TINY, {key: value}, None)
    except AntisyncError as exc:
        assert_one_line_error(exc)
        return
    assert yaml.safe_load(cfg.to_yaml())["graph"] == cfg.graph
    json.dumps(cfg.simulation_key())


@settings(max_examples=30, deadline=None, derandomize=True)
@given(key=st.sampled_from(["realizations", "seed", "betas", "edges", "name", "dynamics"]), value=plumbing)
def test_fuzz_override_values_through_a_real_run(key, value):
    _call_in_empty_folder(antisync.run, TINY, output="r.h5", **{key: value})


def _graphs_with(weight):
    g = nx.path_graph(3)
    g[0][1]["weight"] = weight
    m = nx.MultiGraph(nx.path_graph(3))
    m.add_edge(0, 1, weight=weight)
    return st.sampled_from([g, m])


graph_args = st.one_of(
    hostile,
    hostile.flatmap(_graphs_with),
    st.sampled_from([nx.path_graph(3), nx.DiGraph(nx.path_graph(3)), nx.MultiDiGraph(nx.path_graph(3))]),
    st.fixed_dictionaries({"kind": st.sampled_from(["lollipop", "atlas", "barbell"]), "nodes": hostile}),
)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(
    graph=graph_args,
    which=st.one_of(st.just(("xi2", "rw")), hostile),
    edges=st.one_of(st.just("all"), st.just(["0->1"]), hostile),
    coupling=st.one_of(st.just("normalized"), hostile),
)
def test_fuzz_for_graph(graph, which, edges, coupling):
    with empty_folder() as folder:
        try:
            rows = antisync.measures.for_graph(graph, which=which, edges=edges, coupling=coupling)
        except AntisyncError as exc:
            assert_one_line_error(exc)
        else:
            assert all(math.isfinite(v) for r in rows for k, v in r.items() if k != "edge")
        assert snapshot(folder) == {}


# ---- the CLI's parser: one line, not the usage box ----------------------------------------
runner = CliRunner()


@pytest.mark.parametrize(
    "args,words",
    [
        (["run", "{cfg}", "--realizations", "abc"], ["run", "--realizations"]),
        (["run", "{cfg}", "--threads", "-x"], ["run", "--threads"]),
        (["run", "{cfg}", "--seed", "1.5"], ["run", "--seed"]),
        (["run", "{cfg}", "--bogus"], ["run", "--bogus"]),
        (["run", "{cfg}", "--threads"], ["run", "--threads", "requires an argument"]),
        (["run", "{cfg}", "--quiet=3"], ["run", "--quiet"]),
        (["run", "{cfg}", "extra"], ["run", "extra"]),
        (["run"], ["run", "missing argument", "config"]),
        (["sweep", "{cfg}", "--realizations", "many"], ["sweep", "--realizations"]),
        (["sweep", "{cfg}", "--workers", "x"], ["sweep", "--workers"]),
        (["sweep", "{cfg}", "--nope"], ["sweep", "--nope"]),
        (["sweep"], ["sweep", "missing argument"]),
        (["summary", "{h5}", "--bogus"], ["summary", "--bogus"]),
        (["summary", "{h5}", "--format"], ["summary", "--format"]),
        (["summary"], ["summary", "missing argument"]),
        (["report", "{h5}", "--top", "abc"], ["report", "--top"]),
        (["report", "{h5}", "--pdf=yes"], ["report", "--pdf"]),
        (["report"], ["report", "missing argument"]),
        (["validate", "{cfg}", "--nope"], ["validate", "--nope"]),
        (["validate", "{cfg}", "--set"], ["validate", "--set"]),
        (["validate"], ["validate", "missing argument"]),
        (["rn", "{cfg}"], ["no such command", "'rn'"]),
        (["--bogus"], ["--bogus"]),
    ],
)
def test_bad_command_line_is_one_line(tmp_path, args, words):
    """Click's usage box (Usage: ... Try 'antisync run --help' ... a framed Error) was printed
    for any option it could not parse; every other error of the CLI is one line, exit 2."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(TINY))
    args = [a.format(cfg=cfg, h5=tmp_path / "r.h5") for a in args]
    before = snapshot(tmp_path)
    res = runner.invoke(app, args)
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert "Traceback" not in res.output and not res.stdout, res.output
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
    assert not set(lines[0]) & set("╭╮╰╯│─"), lines[0]
    assert "Usage:" not in lines[0] and "--help" in lines[0]
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert snapshot(tmp_path) == before


def test_bad_option_through_the_installed_command(tmp_path):
    """The same line from a real process (``python -m antisync``: the console script's main)."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(TINY))
    res = subprocess.run(
        [sys.executable, "-m", "antisync", "run", str(cfg), "--realizations", "abc"],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "60"},
        check=False,
    )
    assert res.returncode == 2 and not res.stdout
    assert res.stderr.splitlines() == [
        "antisync: error: run: invalid value for '--realizations': "
        + res.stderr.split("'--realizations': ", 1)[1].strip()
    ]
    assert res.stderr.strip().endswith("(see antisync run --help)")


def test_help_is_still_help():
    assert runner.invoke(app, ["run", "--help"]).exit_code == 0
    res = runner.invoke(app, [])
    assert "Usage" in res.output and "run" in res.output


@pytest.mark.parametrize(
    "call",
    [
        lambda m: m.lambda_xi2(np.ones((1, 1)), 0, 0),
        lambda m: m.lambda_xi2(np.array([[0.0, 1.0], [1.0, 0.0]]), 0, 0),
        lambda m: m.lambda_xi2(np.array([[0.0, 1.0], [1.0, 0.0]]), 0, 1, coupling="weird"),
        lambda m: m.lambda_rw(np.array([[0.0, 1.0], [1.0, 0.0]]), 0, 0),
        lambda m: m.f_xi2(np.array([[0.0, -1.0], [-1.0, 0.0]]), 0, 1, 0.1),
    ],
)
def test_the_exported_measures_raise_antisync_errors(call):
    """antisync.measures' functions on bad weights or links raise MeasureError (an
    AntisyncError and a ValueError), never a bare ValueError."""
    import antisync.measures as m
    from antisync.errors import AntisyncError

    with pytest.raises(AntisyncError):
        call(m)
