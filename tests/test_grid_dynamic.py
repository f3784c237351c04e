"""Dynamic line removal (antisync/grids/removal.py, docs/power_grids.md): paired on the same starts as
the ordinary run, exact intervals, the Braess example in the dynamic indicator, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers import assert_one_line, local_cluster_client
from scipy.stats import binomtest
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.grids.errors import GridError
from antisync.grids.lines import parse_lines
from antisync.grids.removal import line_removal
from antisync.grids.removal_file import write_table
from antisync.plan.config import config_from_mapping
from antisync.stats.exact import clopper_pearson, mcnemar_exact
from antisync.status import SYNCED

runner = CliRunner()

# The Braess construction of tests/test_grid_static.py: the line 0-1-2-3-4 at capacity K,
# generators at 0 and 4, the consumer at 3; closing the ring with a line 0-4 at capacity K
# destroys the stable locked state (Witthaut and Timme, New J. Phys. 14, 083036 (2012)).
K = 1.12
P_BRAESS = [1.0, 0.0, 0.0, -2.0, 1.0]


def braess_config(kappa: float, realizations: int = 48, inertia: float = 0.0, **dyn) -> dict:
    links = [[a, a + 1, K] for a in range(4)] + ([[0, 4, kappa]] if kappa > 0 else [])
    return {
        "name": "braess",
        "graph": {"kind": "inline", "links": links, "nodes": [0, 1, 2, 3, 4]},
        "model": {"frequencies": P_BRAESS, "inertia": inertia},
        "sync": {"criterion": "frequency", "tolerance": 1e-3},
        "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.02, "t_max": 100.0, **dyn},
        "realizations": realizations,
        "seed": 7,
    }


def ring_config(realizations: int = 32) -> dict:
    """A six-bus ring with a chord, second order, comfortably above the critical coupling."""
    links = [[i, (i + 1) % 6, 2.0] for i in range(6)] + [[0, 3, 1.0]]
    return {
        "name": "ring6",
        "graph": {"kind": "inline", "links": links},
        "model": {"frequencies": [1.0, -1.0, 0.5, -0.5, 0.8, -0.8], "inertia": 1.0, "damping": 1.0},
        "sync": {"criterion": "frequency", "tolerance": 1e-3},
        "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.02, "t_max": 80.0},
        "realizations": realizations,
        "seed": 11,
    }


# --- exact intervals ---------------------------------------------------------------------------


@pytest.mark.parametrize(("k", "n"), [(0, 10), (1, 10), (5, 10), (10, 10), (3, 97), (96, 97), (40, 400)])
@pytest.mark.parametrize("level", [0.95, 0.99])
def test_clopper_pearson_is_scipys_exact_interval(k, n, level):
    ci = binomtest(k, n).proportion_ci(confidence_level=level, method="exact")
    assert clopper_pearson(k, n, level) == pytest.approx((ci.low, ci.high), abs=1e-12)


def test_mcnemar_is_the_exact_binomial_test_on_the_discordant_pairs():
    p, lo, hi = mcnemar_exact(lost=2, gained=11, n=200)
    assert p == pytest.approx(binomtest(11, 13, 0.5).pvalue)
    ci = binomtest(11, 13).proportion_ci(method="exact")
    assert (lo, hi) == pytest.approx((13 / 200 * (2 * ci.low - 1), 13 / 200 * (2 * ci.high - 1)))
    assert lo < 9 / 200 < hi and lo > 0  # resolved: the interval excludes no change
    # symmetric in lost and gained; no discordant pair: no evidence, no change
    p2, lo2, hi2 = mcnemar_exact(lost=11, gained=2, n=200)
    assert p2 == pytest.approx(p) and (lo2, hi2) == pytest.approx((-hi, -lo))
    assert mcnemar_exact(0, 0, 50) == (1.0, 0.0, 0.0)
    assert math.isnan(clopper_pearson(0, 0)[0])


# --- paired on the same starts as the ordinary run -----------------------------------------------


def test_intact_tau_is_the_ordinary_runs_tau0_and_removal_is_the_grid_without_the_line():
    """The intact grid of a removal table is the job machinery's undamaged run of the same
    config and seed, realization by realization; removing a line (beta = 1) is integrating the
    grid without it, and beta -> 1 approaches it."""
    from antisync.execution.compute import simulate_job
    from antisync.plan.jobs import make_job
    from antisync.stats.estimators import crossing_times

    cfg = ring_config()
    table = line_removal(cfg, lines=[(0, 3), (1, 2)])
    job = make_job(config_from_mapping(cfg))
    none = np.empty((0, job.csr.weights.size))  # the undamaged network only
    sim = simulate_job(job, 0, cfg["realizations"], variant_weights=none, variant_targets=np.empty(0))
    t0, _ = crossing_times(sim, job.config.dynamics.interpolate)
    tau0 = np.where(sim.status0 == SYNCED, t0 * job.config.dynamics.dt, np.nan)
    np.testing.assert_array_equal(table.status0, sim.status0)
    np.testing.assert_array_equal(table.tau0, tau0)
    assert table.synced0 == cfg["realizations"]  # every start locks: a fair check of tau0

    # removing the chord 0-3 = the ring without it, start by start
    ring = {**cfg, "graph": {"kind": "inline", "links": cfg["graph"]["links"][:6]}}
    without = line_removal(ring, lines=[(1, 2)])
    np.testing.assert_array_equal(table.status[:, 0], without.status0)
    np.testing.assert_allclose(table.tau[:, 0], without.tau0, rtol=1e-12)
    near = line_removal(cfg, lines=[(0, 3)], beta=1 - 1e-9)
    np.testing.assert_array_equal(near.status[:, 0], table.status[:, 0])
    np.testing.assert_allclose(near.tau[:, 0], table.tau[:, 0], rtol=1e-6)
    row = table.row(3, 0)
    assert row.both == cfg["realizations"] and row.lost == row.gained == 0
    assert row.d_tau == pytest.approx(np.mean(table.tau[:, 0] - table.tau0))
    assert row.ratio == pytest.approx(np.nanmean(table.tau0 / table.tau[:, 0]))


@pytest.mark.parametrize("kind", ["raw", "normalized"])
@pytest.mark.parametrize("beta", [1.0, 0.3])
def test_a_lines_weights_are_the_whole_damaged_matrix_s_bit_for_bit(kind, beta):
    """The one builder of damaged weights (``coupling.variant_weights``, ``both_ways``: a line's
    two links) against the slow obvious reference: the whole ``Omega`` copied, the line scaled
    both ways, ``W`` of the copy compressed on the intact pattern."""
    import networkx as nx

    from antisync.physics import coupling, graphs

    g = nx.gnm_random_graph(40, 120, seed=3)
    for u, v in g.edges:
        g.edges[u, v]["weight"] = 0.5 + (u * 7 + v * 3) % 5 / 4
    omega = graphs.omega_matrix(g)
    csr = coupling.to_csr(coupling.coupling_matrix(omega, kind), pattern=omega > 0)
    lines = [(u, v) for u, v in g.edges if g.degree(u) > 1 and g.degree(v) > 1][:30]
    fast = coupling.variant_weights(omega, csr, [(a, b, beta) for a, b in lines], kind, both_ways=True)
    for v, (a, b) in enumerate(lines):
        changed = omega.copy()
        changed[a, b] *= 1.0 - beta
        changed[b, a] *= 1.0 - beta
        slow = coupling.to_csr(coupling.coupling_matrix(changed, kind), pattern=omega > 0).weights
        np.testing.assert_array_equal(fast[v], slow)


def test_a_removal_plan_is_built_once_and_refuses_arguments_beside_it():
    """``plan_removal`` resolves the lines and the grid once; ``line_removal`` of the plan is the
    removal of its config and lines, and refuses lines, overrides or another beta beside it."""
    from antisync.grids.removal_config import plan_removal

    cfg = config_from_mapping(ring_config(4))
    plan = plan_removal(cfg, [(0, 3)], 1.0, False)
    assert plan.asked == {("0", "3"): False}
    a, b = line_removal(plan), line_removal(ring_config(4), lines=[(0, 3)])
    np.testing.assert_array_equal(a.tau, b.tau)
    np.testing.assert_array_equal(a.status0, b.status0)
    for kwargs, words in (({"lines": [(1, 2)]}, "drop lines"), ({"beta": 0.5}, "drop beta")):
        with pytest.raises(GridError, match=words):
            line_removal(plan, **kwargs)
    with pytest.raises(GridError, match="drop realizations"):
        line_removal(plan, realizations=8)


def test_braess_line_removal_restores_synchrony_in_the_dynamics():
    """Witthaut and Timme's Braess paradox in the dynamic indicator: with the line 0-4 the ring
    has no stable locked state and no start frequency-locks (P_sync = 0); removing 0-4 (or
    weakening it to 5% of K) gains exactly the starts that lock on the tree itself, resolved by
    McNemar's exact test, and it is the only dynamic Braess line. Removing any other line
    leaves no locked state (test_grid_static.py): P_sync stays 0."""
    ring = braess_config(K)
    table = line_removal(ring)
    tree = line_removal(braess_config(0.0), lines=[(0, 1)], beta=0.5)  # its intact run
    assert table.synced0 == 0
    assert tree.synced0 > ring["realizations"] // 2  # first order, the tree locks from (almost) every start
    row = table.row(0, 4)
    assert row.lost == 0 and row.gained == tree.synced0 and row.p_after == tree.p_sync
    np.testing.assert_array_equal(table.status[:, table.rows.index(row)], tree.status0)
    assert row.line in table.sync_called() and row.d_psync_ci[0] > 0
    assert [r.line for r in table.braess_lines()] == [(0, 4)]
    assert all(r.synced_after == 0 for r in table.rows if r.line != (0, 4))
    assert table.troublemakers() == []
    weak = line_removal(ring, lines=[(0, 4)], beta=0.95)
    assert weak[0].gained > 0 and weak[0].lost == 0
    # the other way round: on the tree, every line is a bridge (refused unless islanding), and
    # with islanding no island is balanced, so every start is lost
    with pytest.raises(GridError, match="bridge"):
        line_removal(braess_config(0.0), lines=[(2, 3)])
    isl = line_removal(braess_config(0.0), lines=[(2, 3)], islanding=True)
    assert isl[0].islanding and isl[0].synced_after == 0 and isl[0].lost == tree.synced0
    assert isl.troublemakers()[0].line == (2, 3)


# --- bad input -----------------------------------------------------------------------------------


def test_bad_requests_are_one_line_grid_errors():
    cfg = ring_config(4)
    for kwargs, message in (
        ({"lines": [(0, 2)]}, "line 0-2 is not a line of the grid"),
        ({"lines": [(0, 9)]}, "no such node"),
        ({"beta": 0.0}, "beta must be a number in (0, 1]"),
        ({"beta": 1.5}, "beta must be a number in (0, 1]"),
        ({"model": {"inertia": [1.0, 1.0]}}, "model.inertia has 2 values"),
    ):
        with pytest.raises(GridError) as err:
            line_removal(cfg, **kwargs)
        assert message in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(GridError, match="not u-v"):
        parse_lines("0-1,0:2", [0, 1, 2])


def _grid_files(tmp_path, inertia_lines: int = 5):
    """A five-bus config with per-node files, no bridge (a ring 0-1-2-3-4 with the chord 1-3)."""
    (tmp_path / "g.edges").write_text("0 1 2\n1 2 2\n2 3 2\n3 4 2\n0 4 2\n1 3 2\n")
    (tmp_path / "p.txt").write_text("1\n0\n0\n-2\n1\n")
    (tmp_path / "m.txt").write_text("1\n" * inertia_lines)
    cfg = tmp_path / "g.yaml"
    cfg.write_text(
        "name: g\ngraph: {kind: edgelist, path: g.edges}\n"
        "model: {frequencies: {file: p.txt}, inertia: {file: m.txt}, damping: 1.0}\n"
        "sync: {criterion: frequency, tolerance: 0.001}\n"
        "dynamics: {coupling: raw, integrator: rk4, dt: 0.02, t_max: 60}\nrealizations: 8\n"
    )
    return cfg


def test_cli_refuses_bad_input_with_one_line_and_leaves_the_file(tmp_path):
    cfg = _grid_files(tmp_path)
    out = tmp_path / "out.json"
    out.write_text("keep me")
    for args, message in (
        (["--lines", "0-2", "--overwrite"], "line 0-2 is not a line of the grid"),
        (["--lines", "0-9", "--overwrite"], "not u-v with two nodes of the grid"),
        (["--lines", "0-1", "--beta", "2", "--overwrite"], "beta must be a number in (0, 1]"),
        (
            ["--lines", "0-1", "--overwrite", "--out", str(tmp_path / "x.csv")],
            "written as JSON or HDF5; name it *.json or *.h5",
        ),
        (["--lines", "0-1"], "exists; pass --overwrite"),
    ):
        res = runner.invoke(app, ["grid", str(cfg), "--removal", "--out", str(out), *args])
        assert_one_line(res, message)
        assert out.read_text() == "keep me"
    bad = _grid_files(tmp_path, inertia_lines=4)
    args = ["grid", str(bad), "--removal", "--lines", "0-1", "--out", str(out), "--overwrite"]
    res = runner.invoke(app, args)
    assert_one_line(res, "m.txt has 4 values; the graph has 5 nodes")
    assert out.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.edges", "g.yaml", "m.txt", "out.json", "p.txt"]


def test_cli_writes_the_table_atomically(tmp_path):
    cfg = _grid_files(tmp_path)
    out = tmp_path / "out.json"
    res = runner.invoke(app, ["grid", str(cfg), "--removal", "--lines", "0-4,1-3", "--out", str(out), "-q"])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["format"] == "antisync-line-removal" and doc["summary"]["realizations"] == 8
    assert [r["label"] for r in doc["rows"]] == ["0-4", "1-3"]
    assert "| 0-4 |" in res.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.edges", "g.yaml", "m.txt", "out.json", "p.txt"]
    res = runner.invoke(app, ["grid", str(cfg)])  # the static table
    assert res.exit_code == 0 and "| line | state | margin" in res.stdout


def test_write_table_refuses_an_existing_file(tmp_path):
    table = line_removal(ring_config(4), lines="0-3")
    path = write_table(table, tmp_path / "t.json")
    with pytest.raises(GridError, match="exists"):
        write_table(table, path)
    assert json.loads(path.read_text())["rows"][0]["label"] == "0-3"


# --- the report: the grid drawn with each line's response (antisync/report/removal.py) --------

PNG = b"\x89PNG\r\n\x1a\n"


def test_removal_figure_is_drawn_from_a_table_or_its_json(tmp_path):
    from antisync.report.removal import removal_doc, removal_figure, resolved

    table = line_removal(ring_config(4), lines="0-3,0-1")
    path = removal_figure(table, ring_config(4), tmp_path / "speedup.png")
    assert path.read_bytes().startswith(PNG)
    saved = write_table(table, tmp_path / "t.json")
    # from the JSON file, its stored config, coloured by d P_sync
    path = removal_figure(saved, None, tmp_path / "psync.png", by="psync")
    assert path.read_bytes().startswith(PNG)
    assert removal_doc(saved)["rows"] == removal_doc(table)["rows"]
    assert set(resolved(removal_doc(table))) == {"troublemakers", "braess", "faster", "slower"}
    with pytest.raises(GridError, match="exists; pass --overwrite"):
        removal_figure(saved, None, path)
    with pytest.raises(GridError, match="by must be one of speedup, psync"):
        removal_figure(saved, None, tmp_path / "x.png", by="tau")
    (tmp_path / "other.json").write_text('{"rows": []}')
    with pytest.raises(GridError, match="not a removal table"):
        removal_figure(tmp_path / "other.json", None, tmp_path / "y.png")
    with pytest.raises(GridError, match="cannot read the removal table"):
        removal_figure(tmp_path / "psync.png", None, tmp_path / "y.png")
    with pytest.raises(GridError, match="lines that are not in this grid"):
        removal_figure(saved, braess_config(0.0), tmp_path / "z.png")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["other.json", "psync.png", "speedup.png", "t.json"]


def test_report_draws_a_removal_table_from_its_json(tmp_path):
    """``antisync report R.json`` of a removal table: the grid by speedup and by d P_sync from
    the config the table keeps, and index.md with the ranked rows."""
    table = line_removal(ring_config(4), lines="0-3,0-1")
    saved = write_table(table, tmp_path / "r.json")
    res = CliRunner().invoke(app, ["report", str(saved), "--out", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    name = table.name
    for stem in (f"{name}_removal", f"{name}_removal_psync"):
        assert (tmp_path / "rep" / f"{stem}.png").read_bytes().startswith(PNG)
    index = (tmp_path / "rep" / "index.md").read_text()
    assert "| 0-3 |" in index and "| 0-1 |" in index and f"{table.n} realizations" in index


def test_cli_figure_is_written_and_never_overwritten_without_overwrite(tmp_path):
    cfg = _grid_files(tmp_path)
    fig = tmp_path / "g.png"
    args = ["grid", str(cfg), "--removal", "--lines", "0-4,1-3", "--figure", str(fig), "-q"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    first = fig.read_bytes()
    assert first.startswith(PNG)
    res = runner.invoke(app, args)
    assert_one_line(res, "g.png exists; pass --overwrite")
    assert fig.read_bytes() == first
    res = runner.invoke(app, [*args, "--overwrite", "--by", "psync"])
    assert res.exit_code == 0, res.output
    for extra, message in (
        (["--figure", str(tmp_path / "no" / "f.png")], "does not exist"),
        (["--figure", str(tmp_path / "f.txt")], "name it *.png"),
        (["--figure", str(tmp_path / "f.png"), "--by", "tau"], "--by must be one of speedup, psync"),
    ):
        res = runner.invoke(app, ["grid", str(cfg), "--removal", "--lines", "0-4", *extra])
        assert_one_line(res, message)
    res = runner.invoke(app, ["grid", str(cfg), "--figure", str(tmp_path / "f.png")])
    assert_one_line(res, "--figure is for the dynamic removal table: add --removal")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.edges", "g.png", "g.yaml", "m.txt", "p.txt"]


# --- Dask --------------------------------------------------------------------------------------


def test_a_rodas4_removal_is_the_rodas4_run_of_the_grid_and_near_rk4():
    """With ``dynamics.integrator: rodas4`` the intact grid of a removal table is the job
    machinery's Rodas4 run, realization by realization, and every start's status and tau match
    RK4's table within 1e-4 of tau (same starts)."""
    from antisync.execution.compute import simulate_job
    from antisync.plan.jobs import make_job
    from antisync.stats.estimators import crossing_times

    cfg = ring_config()
    stiff = {**cfg, "dynamics": {**cfg["dynamics"], "integrator": "rodas4"}}
    table = line_removal(stiff, lines=[(0, 3), (1, 2)])
    job = make_job(config_from_mapping(stiff))
    none = np.empty((0, job.csr.weights.size))
    sim = simulate_job(job, 0, cfg["realizations"], variant_weights=none, variant_targets=np.empty(0))
    t0, _ = crossing_times(sim, job.config.dynamics.interpolate)
    np.testing.assert_array_equal(table.status0, sim.status0)
    np.testing.assert_array_equal(
        table.tau0, np.where(sim.status0 == SYNCED, t0 * job.config.dynamics.dt, np.nan)
    )
    explicit = line_removal(cfg, lines=[(0, 3), (1, 2)])
    np.testing.assert_array_equal(table.status, explicit.status)
    np.testing.assert_allclose(table.tau0, explicit.tau0, rtol=1e-4)
    np.testing.assert_allclose(table.tau, explicit.tau, rtol=1e-4)


@pytest.fixture(scope="module")
def client():
    with local_cluster_client() as c:
        yield c


@pytest.mark.parametrize("integrator", ["rk4", "rodas4"])
def test_removal_on_a_dask_cluster_equals_the_local_table(client, integrator):
    """Tasks of realizations x groups of lines on two worker processes (the intact grid in one
    group only) give the local table, array for array and row for row, for the explicit and
    the stiff integrator."""
    from antisync.grids import removal

    cfg = ring_config(realizations=removal.CHUNK + 8)  # two chunks of realizations
    cfg["dynamics"]["integrator"] = integrator
    here = line_removal(cfg)
    tasks = removal._plan(cfg["realizations"], np.zeros((7, 1)), np.ones(1), removal._groups(client, 264))
    assert len({t[1].tobytes() for t in tasks}) > 1  # the lines are split over tasks
    there = line_removal(cfg, client=client)
    for name in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(getattr(there, name), getattr(here, name), err_msg=name)
    assert there.rows == here.rows


def test_removal_from_starts_around_the_operating_point_on_dask_equals_the_local_table(client):
    """The random-start N-1 from perturbations of the operating point (``model.start``): the
    intact ring starts within 1 rad of its locked state and every start locks; the Dask table
    equals the local one array for array, and the starts are not the paper's (other times)."""
    cfg = ring_config(realizations=24)
    near = {**cfg, "model": {**cfg["model"], "start": {"around": "locked", "width": 1.0}}}
    here = line_removal(near, lines=[(0, 3), (1, 2)])
    assert (here.status0 == SYNCED).all()
    there = line_removal(near, lines=[(0, 3), (1, 2)], client=client)
    for name in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(getattr(there, name), getattr(here, name), err_msg=name)
    assert there.rows == here.rows
    uniform = line_removal(cfg, lines=[(0, 3)])
    assert not np.array_equal(uniform.tau0, here.tau0)


def test_a_laws_removal_on_a_dask_cluster_equals_the_local_table(client):
    """A user's law (the swing law, tests/test_laws.py) through the same tasks: its setup travels
    to the workers as data, its kernels compile (or load) there, and the table equals the local
    one array for array."""
    cfg = ring_config(realizations=16)
    p = cfg["model"]["frequencies"]
    cfg["model"] = {"law": "swing", "params": {"P": p, "m": 1.0, "gamma": 1.0}}
    here = line_removal(cfg, lines=[(0, 3), (1, 2)])
    there = line_removal(cfg, lines=[(0, 3), (1, 2)], client=client)
    for name in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(getattr(there, name), getattr(here, name), err_msg=name)
    assert there.rows == here.rows and (here.status0 == SYNCED).all()


def test_cli_removal_with_workers_equals_the_local_run(tmp_path):
    cfg = _grid_files(tmp_path)
    out = {}
    for name, extra in (("local", []), ("dask", ["--workers", "2"])):
        path = tmp_path / f"{name}.json"
        res = runner.invoke(app, ["grid", str(cfg), "--removal", "--out", str(path), *extra])
        assert res.exit_code == 0, res.output
        out[name] = json.loads(path.read_text())
    assert "LocalCluster of 2" in res.stderr
    assert out["dask"]["rows"] == out["local"]["rows"]
    res = runner.invoke(app, ["grid", str(cfg), "--workers", "2"])
    assert_one_line(res, "--workers is for the dynamic removal table: add --removal")


# --- an interrupted removal resumes --------------------------------------------------------------


class _StopAfter:
    """A ``log`` that interrupts the run (as Ctrl-C would) after ``n`` progress messages."""

    def __init__(self, n: int):
        self.n, self.seen = n, []

    def __call__(self, message: str) -> None:
        self.seen.append(message)
        if len(self.seen) >= self.n:
            raise KeyboardInterrupt


def test_an_interrupted_removal_resumes_from_its_journal_and_redoes_nothing(tmp_path):
    from antisync.grids import removal

    cfg = ring_config(realizations=removal.CHUNK + 8)  # two chunks: 256 and 8 realizations
    # x two groups of the ring's seven lines: four tasks, the intact grid in each chunk's first
    tasks = removal._plan(cfg["realizations"], np.zeros((7, 1)), np.ones(1), -(-7 // removal.LINES_PER_TASK))
    assert len(tasks) == 4
    first_ks, first_group, first_intact = tasks[0]
    whole = line_removal(cfg)
    journal = tmp_path / "t.json.partial"
    with pytest.raises(KeyboardInterrupt):
        line_removal(cfg, journal=journal, log=_StopAfter(1))
    assert len(list(journal.glob("task_*.npz"))) == 1
    # another work's journal is refused in one line and left as it is
    before = sorted(p.name for p in journal.iterdir())
    with pytest.raises(GridError, match="holds the unfinished work of another removal run"):
        line_removal({**cfg, "seed": 12}, journal=journal)
    assert sorted(p.name for p in journal.iterdir()) == before
    seen = []
    resumed = line_removal(cfg, journal=journal, log=seen.append)
    assert seen[0].startswith(f"resumed: {first_ks.size * (first_group.size + first_intact)} trajectories")
    assert len(seen) == len(tasks)  # only the three missing tasks ran
    assert seen[-1].endswith("~0 s left") and "7/7 lines done" in seen[-1]
    for name in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(whole, name), err_msg=name)
    assert resumed.rows == whole.rows


def test_cli_resume_finishes_and_removes_the_journal(tmp_path):
    from antisync.grids.removal_journal import journal_folder
    from antisync.plan.config import load_config

    cfg = _grid_files(tmp_path)
    out = tmp_path / "r.json"
    journal = journal_folder(out)
    with pytest.raises(KeyboardInterrupt):  # a first run killed after its first task
        line_removal(load_config(cfg), lines="0-4,1-3", journal=journal, log=_StopAfter(1))
    args = ["grid", str(cfg), "--removal", "--lines", "0-4,1-3", "--out", str(out)]
    res = runner.invoke(app, args)
    assert_one_line(res, "an interrupted removal run left")
    assert not out.exists() and journal.exists()
    res = runner.invoke(app, [*args, "--resume"])
    assert res.exit_code == 0, res.output
    assert out.exists() and not journal.exists()
    res = runner.invoke(app, [*args, "--resume"])
    assert res.exit_code == 0 and "is complete: nothing to resume" in res.stderr
    reference = tmp_path / "ref.json"
    res = runner.invoke(app, ["grid", str(cfg), "--removal", "--lines", "0-4,1-3", "--out", str(reference)])
    assert json.loads(out.read_text())["rows"] == json.loads(reference.read_text())["rows"]


def test_parts_split_by_lines_merge_into_the_one_run_table():
    """Two parts with disjoint lines (as on two machines) merge into the table of one run over
    all the lines: the same rows, and the calls made again over the union."""
    from antisync.grids.removal_file import table_document
    from antisync.report.removal import merge_docs

    cfg = ring_config(realizations=24)
    one = table_document(line_removal(cfg))
    a = table_document(line_removal(cfg, lines=[(0, 1), (1, 2), (2, 3)]))
    b = table_document(line_removal(cfg, lines=[(3, 4), (4, 5), (0, 5), (0, 3)]))
    merged = merge_docs([a, b])
    by_label = lambda doc: {r["label"]: r for r in doc["rows"]}  # noqa: E731
    assert by_label(merged) == by_label(one)
    for key in ("sync_called", "tau_called", "troublemakers", "braess_lines"):
        assert sorted(merged[key]) == sorted(one[key]), key
    assert merged["summary"]["lines"] == 7 and len(merged["merged_from"]) == 2
    # a part run elsewhere: other threads, output and a folder of its own for the same files
    elsewhere = {**b["config"], "threads": 8, "output": "/scratch/x.h5"}
    elsewhere["model"] = {**elsewhere["model"], "inertia": {"file": "/scratch/antisync/m.txt"}}
    here = {**a["config"], "model": {**a["config"]["model"], "inertia": {"file": "/home/m.txt"}}}
    assert merge_docs([{**a, "config": here}, {**b, "config": elsewhere}])["rows"] == merged["rows"]
    with pytest.raises(GridError, match="line 0-1 is in two parts"):
        merge_docs([a, a])
    other = table_document(line_removal({**cfg, "seed": 12}, lines=[(3, 4)]))
    with pytest.raises(GridError, match="merge only parts run with the same config, seed"):
        merge_docs([a, other])


def test_a_large_grids_figure_names_only_the_resolved_the_moved_and_the_largest_lines():
    from antisync.report.removal import NAMED_LINES, _named_lines

    rows = {k: {"label": f"{k}-{k + 1}", "gained": int(k == 3), "lost": 0, "v": k / 100} for k in range(40)}
    marks = {"troublemakers": {"0-1"}, "braess": set(), "faster": set(), "slower": {"5-6"}}
    value = lambda r: r["v"]  # noqa: E731
    named = _named_lines(rows, marks, value, small=False)
    largest = {f"{k}-{k + 1}" for k in range(40 - NAMED_LINES, 40)}
    assert named == {"0-1", "5-6", "3-4"} | largest
    assert len(_named_lines(rows, marks, value, small=True)) == 40


@pytest.mark.parametrize(
    ("damage", "says"),
    [
        ({"gave_up0": "three"}, "summary.gave_up0 is 'three', not a count"),
        ({"gave_up": -1}, "summary.gave_up is -1, not a count"),
        ({"give_up_audit": {"sampled": "x"}}, "summary.give_up_audit is not sync.give_up's audit"),
    ],
)
def test_report_refuses_a_removal_table_with_bad_give_up_counts_in_one_line(tmp_path, damage, says):
    """A removal table whose ``sync.give_up`` counts are of the wrong kind: one line, exit 2, no
    empty figures folder left behind."""
    table = line_removal(ring_config(4), lines="0-3")
    saved = write_table(table, tmp_path / "r.json")
    doc = json.loads(saved.read_text())
    doc["summary"].update(damage)
    saved.write_text(json.dumps(doc))
    res = CliRunner().invoke(app, ["report", str(saved)])
    assert_one_line(res, says)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_report_index_of_a_removal_table_names_the_given_up_counts(tmp_path):
    """``antisync report`` of a removal table run with ``sync.give_up``: its index says how many
    trajectories the rule stopped and what its audit checked."""
    table = line_removal(ring_config(4), lines="0-3")
    saved = write_table(table, tmp_path / "r.json")
    doc = json.loads(saved.read_text())
    audit = {"pilot": "p", "sampled": 4, "locked": 0, "rerun": 4, "bound95": 0.75}
    doc["summary"].update(gave_up0=2, gave_up=3, give_up_audit=audit)
    saved.write_text(json.dumps(doc))
    res = CliRunner().invoke(app, ["report", str(saved), "--out", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    index = (tmp_path / "rep" / "index.md").read_text()
    assert "Stopped by sync.give_up (counted as not synchronized): 2 intact, 3 after" in index
    assert "audit integrated 4 given-up trajectories" in index


# --- the step check of an explicit integrator ------------------------------------------------------


def test_the_step_check_flags_a_stable_but_coarse_step(tmp_path):
    """IEEE 39 at RK4 dt 0.0025 (stable, but its load buses' fast modes damped 10x too slowly):
    start 4 locks there and at no smaller step, so the check, which integrates the first starts
    of the intact grid again at dt / 2, warns and the table says so; at the shipped dt 0.00125
    it passes. A Rodas4 removal checks its tolerances instead (ten times finer)."""
    from pathlib import Path

    from antisync.report.removal import removal_doc

    config = Path(__file__).resolve().parent.parent / "configs" / "ieee39_grid.yaml"
    run = {"lines": "22-23", "realizations": 6, "seed": 1}
    warning = "1 changed status .first: start 4.*run again at dynamics.dt = 0.00125"
    with pytest.warns(UserWarning, match=warning):
        coarse = line_removal(config, dynamics={"dt": 0.0025}, **run)
    check = coarse.step_check
    assert check["changed"] == 1 and check["first_changed"] == 4 and not check["passed"]
    assert "these numbers depend on the step" in coarse.to_markdown().splitlines()[0]
    fine = line_removal(config, **run)
    assert fine.step_check["passed"] and fine.step_check["dt"] == 0.00125
    assert fine.step_check["largest_dtau"] < 1e-3
    out = tmp_path / "t.json"
    write_table(coarse, out)
    doc = removal_doc(out)
    assert doc["summary"]["step_check"] == check
    rodas4 = line_removal(config, dynamics={"integrator": "rodas4"}, **run).step_check
    assert rodas4["passed"] and (rodas4["rtol"], rodas4["atol"]) == (1e-6, 1e-6)


def test_a_run_checks_its_explicit_step_too():
    """``antisync run`` of a generalized model (and of a law) checks Euler's or RK4's step on its
    undamaged network's first starts (:func:`antisync.execution.step_check.job_step_check`); the
    paper's identical oscillators, whose step defines tau, are not checked; Rodas4 checks its
    tolerances: at rtol = atol = 1e-4 on IEEE 39 six of eight times move by more than 1% (up to
    0.3 s) at 1e-5, a warning naming the finer tolerances; at the default 1e-6 it passes."""
    from pathlib import Path

    from antisync.execution.step_check import job_step_check, step_check_line
    from antisync.plan.config import load_config
    from antisync.plan.jobs import make_job

    config = Path(__file__).resolve().parent.parent / "configs" / "ieee39_grid.yaml"
    coarse = job_step_check(make_job(load_config(config, ["realizations=8", "dynamics.dt=0.0025"])))
    assert coarse["changed"] == 1 and coarse["first_changed"] == 4 and not coarse["passed"]
    fine = job_step_check(make_job(load_config(config, ["realizations=8"])))
    assert fine["passed"] and fine["starts"] == 8 and fine["largest_dtau"] < 1e-3
    rodas4 = load_config(config, ["realizations=8", "dynamics.integrator=rodas4"])
    assert job_step_check(make_job(rodas4))["passed"]
    coarse = ["realizations=8", "dynamics.integrator=rodas4", "dynamics.rtol=1e-4", "dynamics.atol=1e-4"]
    loose = job_step_check(make_job(load_config(config, coarse)))
    assert not loose["passed"] and loose["jumped"] >= 4 and loose["changed"] == 0
    line = step_check_line(loose)
    assert line.startswith("tolerances checked: the first 8 starts again at rtol = 1e-05, atol = 1e-05")
    assert line.endswith("run again at dynamics.rtol = 1e-05, dynamics.atol = 1e-05")
    lollipop = {"graph": {"kind": "lollipop", "nodes": 6, "path": 3}, "realizations": 8}
    assert job_step_check(make_job(config_from_mapping(lollipop))) is None
    law = config_from_mapping({**lollipop, "model": {"law": "kuramoto"}})
    assert job_step_check(make_job(law))["passed"]


def test_the_step_check_forgives_a_start_that_grazes_and_only_that():
    """:func:`check_step_accuracy` on given outcomes (start: status, time by step): start 1 is
    the coarse step's error (it moves from dt to dt / 2, then stays), start 2 grazes (it moves
    again at dt / 4). Only the first fails the check; the second is counted as grazing."""
    from antisync.execution.step_check import check_step_accuracy, step_check_line

    times = {  # dt -> time of starts 0..3 (start 3 never synchronizes)
        0.1: [10.0, 14.0, 12.0, np.nan],
        0.05: [10.001, 12.0, 13.5, np.nan],
        0.025: [10.0011, 12.0001, 12.0, np.nan],
    }

    def run(flagged_only_moves):
        def run_at(dt, ks):
            t = np.array(times[dt])[ks]
            if not flagged_only_moves and dt == 0.025:
                t = np.array(times[0.05])[ks]
            return np.where(np.isnan(t), 2, SYNCED).astype(np.int8), t

        return run_at

    ks = np.arange(4)
    record = check_step_accuracy(run(True), 0.1, ks)
    assert record["jumped"] == 2 and record["grazing"] == 1 and not record["passed"]
    assert "1 of these moved again at dt / 4" in step_check_line(record)
    times[0.05][1] = 14.0  # start 1 now agrees at dt and dt / 2: only the grazing start is flagged
    record = check_step_accuracy(run(True), 0.1, ks)
    assert record["jumped"] == 1 and record["grazing"] == 1 and record["passed"]
    record = check_step_accuracy(run(False), 0.1, ks)  # the grazing start settles at dt / 4
    assert record["grazing"] == 0 and not record["passed"]
