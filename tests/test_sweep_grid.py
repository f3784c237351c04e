"""Grid sweeps over any config key (issue 30): schema, jobs, resume, summary and the figure."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from helpers import CrashAfter, assert_one_line, comparable, sweep_cli
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError, StoreError
from antisync.sweeps import family_graphs, load_sweep, load_sweep_text, main_jobs, run_sweep, sweep_summary

REPO = Path(__file__).resolve().parent.parent

# the paper's lollipop (path 1-2-3, bridge 3-4, triangle 4-5-6), phase lag x threshold
GRID = """
name: grid
graph: {kind: lollipop, nodes: 6, path: 3}
sweep:
  grid: {model.phase_lag: [0, 0.3], dynamics.threshold: [0.9, 0.99]}
betas: []
realizations: 64
block_size: 16
seed: 2
dynamics: {dt: 0.05, integrator: rk4, t_max: 100}
screen: {realizations: 16, t_max: 100}
"""


# ---- schema ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("sweep", "message"),
    [
        (
            "{grid: {model.phaselag: [0, 0.1]}}",
            "unknown key 'model.phaselag' (did you mean 'model.phase_lag'?)",
        ),
        ("{grid: {model.phase_lag: []}}", "sweep.grid.model.phase_lag must be a non-empty list"),
        ("{grid: {model.phase_lag: 0.1}}", "sweep.grid.model.phase_lag must be a non-empty list"),
        ("{zip: {model.phase_lag: [0, 0.1], model.inertia: [1]}}", "must have equal lengths"),
        ("{grid: {model.phase_lag: [0, 2]}}", "sweep point model.phase_lag=2: model.phase_lag must be"),
        ("{grid: {model.phase_lag: [0]}, zip: {model.phase_lag: [0.1]}}", "in both sweep.grid and sweep.zip"),
        ("{grid: {graph: [1, 2]}}", "graph cannot be swept"),
        ("{grid: {sweep: [1, 2]}}", "sweep cannot be swept"),
        ("{grid: {output: [a.h5, b.h5]}}", "output cannot be swept"),
        ("{grid: {model.phase_lag: [0.1, 0.1]}}", "lists a value twice"),
        ("{grid: {model.phase_lag: [0]}, family: atlas, nodes: 4}", "has no 'graph' key"),
        ("{}", "needs sweep.grid or sweep.zip"),
        ("{grid: {dynamics.dt: [0.01, -1]}}", "sweep point dynamics.dt=-1"),
    ],
)
def test_grid_errors_name_the_key(sweep, message):
    text = f"graph: {{kind: lollipop, nodes: 6, path: 3}}\nsweep: {sweep}\n"
    with pytest.raises(ConfigError) as exc:
        load_sweep_text(text)
    assert message in str(exc.value)
    assert "\n" not in str(exc.value)


def test_grid_refuses_what_it_cannot_combine():
    base = "sweep: {family: atlas, nodes: 4, grid: {dynamics.threshold: [0.9, 0.99]}}\n"
    with pytest.raises(ConfigError, match=r"either thresholds: \[...\] or a grid over dynamics.threshold"):
        load_sweep_text(base + "thresholds: [0.9]")
    with pytest.raises(ConfigError, match="top.graphs"):
        load_sweep_text(base + "top: {graphs: 2}")
    with pytest.raises(ConfigError, match=r"stop: with top.graphs > 0"):
        load_sweep_text(
            base.replace("grid: {dynamics.threshold: [0.9, 0.99]}", "") + "top: {graphs: 2}\n"
            "stop: {when: signs-resolved}"
        )
    with pytest.raises(ConfigError, match=r"stop.when cannot be swept \(stop: is one rule"):
        load_sweep_text(base.replace("dynamics.threshold", "stop.when"))
    with pytest.raises(ConfigError, match="--grid expects KEY=V1,V2"):
        load_sweep_text("graph: {kind: lollipop, nodes: 6, path: 3}", grid=["model.phase_lag"])


def test_grid_points_jobs_and_key():
    sw = load_sweep_text(
        "sweep: {family: lollipop, nodes: [5, 6], path: 2}\nbetas: []\nrealizations: 32\n",
        grid=["model.phase_lag=0,0.2"],
        zip_=["model.inertia=0.5,1", "model.damping=2,1"],
    )
    assert [p.as_dict() for p in sw.points] == [
        {"model.phase_lag": 0, "model.inertia": 0.5, "model.damping": 2},
        {"model.phase_lag": 0, "model.inertia": 1, "model.damping": 1},
        {"model.phase_lag": 0.2, "model.inertia": 0.5, "model.damping": 2},
        {"model.phase_lag": 0.2, "model.inertia": 1, "model.damping": 1},
    ]
    assert sw.points[3].config.model.inertia == 1.0 and sw.points[3].config.model.phase_lag == 0.2
    assert sw.thresholds == (0.99,)
    jobs, meta = main_jobs(sw, family_graphs(sw))
    assert len(jobs) == 2 * 4
    assert meta[0]["job"] == "lollipop_5_2_phase_lag0_inertia0.5_damping2"
    assert meta[-1]["point"] == {"model.phase_lag": 0.2, "model.inertia": 1, "model.damping": 1}
    assert jobs[-1].config.model.damping == 1.0 and jobs[-1].config.model.inertia == 1.0
    assert sw.key()["sweep"]["grid"] == {"model.phase_lag": [0, 0.2]}
    assert sw.key()["sweep"]["zip"] == {"model.inertia": [0.5, 1], "model.damping": [2, 1]}
    # a grid over the threshold is the sweep's thresholds, one job per point
    sw = load_sweep_text(GRID)
    assert sw.thresholds == (0.9, 0.99)
    _, meta = main_jobs(sw, family_graphs(sw))
    assert [m["job"] for m in meta] == [
        "lollipop_6_3_phase_lag0_r0.9",
        "lollipop_6_3_phase_lag0_r0.99",
        "lollipop_6_3_phase_lag0.3_r0.9",
        "lollipop_6_3_phase_lag0.3_r0.99",
    ]
    assert [m["threshold"] for m in meta] == [0.9, 0.99, 0.9, 0.99]
    # the stored config (provenance, `antisync validate`) loads back to the same sweep
    assert load_sweep_text(sw.to_yaml()).key() == sw.key()


def test_a_sweep_without_a_grid_keeps_its_key_and_jobs():
    """Files of sweeps written before grids existed resume: no grid, no new key."""
    sw = load_sweep(REPO / "configs" / "threshold.yaml")
    assert sw.points == () and "grid" not in sw.key()["sweep"] and "zip" not in sw.key()["sweep"]


def test_grid_on_a_run_config_and_nested_frequency_keys():
    """``--grid`` on a run config (graph:, no sweep:) sweeps its graph; a key inside a mapping
    value (the spread of drawn frequencies) is set inside it."""
    sw = load_sweep(REPO / "configs" / "lollipop6.yaml", grid=["model.phase_lag=0,0.1"])
    assert sw.family["graphs"] == [{"kind": "lollipop", "nodes": 6, "path": 3}]
    assert sw.name == "lollipop6" and len(sw.points) == 2
    with pytest.raises(
        ConfigError, match=r"sweep point model.frequencies.sd=0.05: model.frequencies must be"
    ):
        load_sweep(REPO / "configs" / "lollipop6.yaml", grid=["model.frequencies.sd=0.05,0.1"])
    text = (
        "graph: {kind: lollipop, nodes: 6, path: 3}\nmodel: {frequencies: {distribution: normal, sd: 0.1}}\n"
    )
    sw = load_sweep_text(text, grid=["model.frequencies.sd=0.05,0.2"])
    assert [p.config.model.frequencies["sd"] for p in sw.points] == [0.05, 0.2]
    assert all(p.config.model.frequencies["distribution"] == "normal" for p in sw.points)


# ---- running, resuming, summary, report ----------------------------------------------------
@pytest.fixture(scope="module")
def grid_reference(tmp_path_factory):
    """The grid sweep run uninterrupted through the CLI."""
    cfg, out = sweep_cli(tmp_path_factory.mktemp("grid"), "grid", GRID)
    return cfg, out, comparable(sweep_summary(out))


def test_grid_sweep_file_holds_every_point(grid_reference):
    _, out, ref = grid_reference
    assert ref["complete"]
    points = {r["point"] for r in ref["records"]}
    assert points == {
        "model.phase_lag=0, dynamics.threshold=0.9",
        "model.phase_lag=0, dynamics.threshold=0.99",
        "model.phase_lag=0.3, dynamics.threshold=0.9",
        "model.phase_lag=0.3, dynamics.threshold=0.99",
    }
    for r in ref["records"]:
        assert math.isclose(r["threshold"], r["grid"]["dynamics.threshold"])
    summary = sweep_summary(out)
    assert [a["keys"] for a in summary["grid"]] == [["model.phase_lag"], ["dynamics.threshold"]]
    # the lag changes the numbers: the two lags' tau0 differ at one threshold
    tau0 = {r["point"]: r["tau0_mean"] for r in ref["records"]}
    assert (
        tau0["model.phase_lag=0, dynamics.threshold=0.99"]
        != tau0["model.phase_lag=0.3, dynamics.threshold=0.99"]
    )


def test_killed_grid_sweep_resumes_to_the_same_file(grid_reference, tmp_path):
    """Killed in the main stage, then finished with `antisync sweep --resume`: the numbers of
    the uninterrupted run."""
    cfg, _, ref = grid_reference
    out = tmp_path / "grid.h5"
    with pytest.raises(RuntimeError, match="killed"):
        run_sweep(load_sweep(cfg), output=out, progress=False, chunk_realizations=16, executor=CrashAfter(5))
    assert (tmp_path / "grid.h5.partial").exists()  # the kill left its journal, unfinished
    res = CliRunner().invoke(app, ["sweep", str(cfg), "--out", str(out), "--resume", "--quiet"])
    assert res.exit_code == 0, res.output
    assert comparable(sweep_summary(out)) == ref


def test_resume_with_another_grid_is_refused(grid_reference, tmp_path):
    cfg, out, _ = grid_reference
    with pytest.raises(StoreError, match="different config"):
        run_sweep(load_sweep(cfg, grid=["model.phase_lag=0,0.2"]), output=out, resume=True, progress=False)
    res = CliRunner().invoke(
        app, ["sweep", str(cfg), "--out", str(out), "--resume", "--grid", "model.phase_lag=0,0.2", "-q"]
    )
    assert_one_line(res, "different config")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--grid", "model.lag=0,0.1"], "unknown key 'model.lag'"),
        (["--grid", "model.phase_lag="], "--grid expects KEY=V1,V2"),
        (["--zip", "model.inertia=1,2", "--zip", "model.damping=1"], "equal lengths"),
        (["--grid", "model.phase_lag=0,9"], "model.phase_lag must be"),
    ],
)
def test_cli_grid_errors_are_one_line_and_touch_nothing(tmp_path, options, message):
    cfg = tmp_path / "g.yaml"
    cfg.write_text(
        GRID.replace("sweep:\n  grid: {model.phase_lag: [0, 0.3], dynamics.threshold: [0.9, 0.99]}\n", "")
    )
    out = tmp_path / "g.h5"
    res = CliRunner().invoke(app, ["sweep", str(cfg), "--out", str(out), *options])
    assert_one_line(res, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.yaml"]


def test_summary_and_report_of_a_grid_sweep(grid_reference, tmp_path):
    _, out, _ = grid_reference
    runner = CliRunner()
    res = runner.invoke(app, ["summary", str(out)])
    assert res.exit_code == 0, res.output
    assert "== grid point model.phase_lag=0.3, dynamics.threshold=0.9" in res.output
    res = runner.invoke(app, ["summary", str(out), "--format", "csv"])
    assert res.exit_code == 0, res.output
    assert {"model.phase_lag", "dynamics.threshold", "point"} <= set(res.output.splitlines()[0].split(","))
    res = runner.invoke(app, ["summary", str(out), "--format", "json"])
    data = json.loads(res.output)
    assert data["grid"][0]["keys"] == ["model.phase_lag"]
    # each (point, link) is its own link for the sign calls: 4 points x 9 orbits' edges
    assert len({(r["point"], r["edge"]) for r in data["records"]}) == 4 * 12
    res = runner.invoke(app, ["report", str(out), "--out", str(tmp_path / "rep"), "--quiet"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "rep" / "grid_lambda.png").stat().st_size > 0
    index = (tmp_path / "rep" / "index.md").read_text()
    assert "grid_lambda.png" in index and "grid: model.phase_lag = 0, 0.3" in index
    assert not (tmp_path / "rep" / "fig2a_F_beta.png").exists()
    table = (tmp_path / "rep" / "grid_lambda.md").read_text()
    assert "## dynamics.threshold=0.99" in table and "model.phase_lag=0.3" in table


# ---- the figure's data ------------------------------------------------------------------
def _record(edge, lag, t, lam, lo, hi):
    point = {"model.phase_lag": lag, "dynamics.threshold": t}
    return {
        "graph": "g",
        "edge": edge,
        "representative": edge,
        "orbit_size": 1,
        "threshold": t,
        "repeat": 0,
        "grid": point,
        "point": f"model.phase_lag={lag:g}, dynamics.threshold={t:g}",
        "lambda_km": lam,
        "lambda_km_se": (hi - lo) / 4,
        "lambda_km_ci_low": lo,
        "lambda_km_ci_high": hi,
        "lambda_km_ci_level": 0.95,
    }


def test_grid_curves_mark_resolved_sign_flips_only():
    from antisync.report.grid_sweep import flip_lines, grid_curves, grid_table

    lags, t = [0.0, 0.2, 0.4, 0.6, 0.8], 0.99
    # resolved +, +, unresolved, resolved -, -: the sign flips between 0.2 and 0.6
    a = [(0.3, 0.2, 0.4), (0.1, 0.05, 0.15), (0.0, -0.1, 0.1), (-0.2, -0.3, -0.1), (-0.3, -0.4, -0.2)]
    b = [(0.05, -0.1, 0.2), (-0.05, -0.2, 0.1), (0.02, -0.1, 0.1), (-0.01, -0.1, 0.1), (0, -0.1, 0.1)]
    recs = [_record("1->2", x, t, *v) for x, v in zip(lags, a, strict=True)]
    recs += [_record("2->1", x, t, *v) for x, v in zip(lags, b, strict=True)]
    summary = {
        "records": recs,
        "grid": [
            {"keys": ["model.phase_lag"], "values": [[x] for x in lags], "zip": False},
            {"keys": ["dynamics.threshold"], "values": [[t]], "zip": False},
        ],
    }
    curves = grid_curves(summary, top=1)
    assert curves["links"] == [("g", "1->2")] and curves["n_links"] == 2
    (panel,) = curves["panels"]
    (curve,) = panel["curves"]
    np.testing.assert_allclose(curve["x"], lags)
    assert list(curve["sign"]) == [1, 1, 0, -1, -1]
    assert curve["flips"] == [(pytest.approx(0.2), pytest.approx(0.6))]
    assert flip_lines(curves) == [
        "1->2: antifragile to fragile between model.phase_lag = 0.2 and 0.6 (dynamics.threshold=0.99)"
    ]
    curves = grid_curves(summary)
    unresolved = next(c for c in curves["panels"][0]["curves"] if c["edge"] == "2->1")
    assert list(unresolved["sign"]) == [0] * 5 and unresolved["flips"] == []
    assert "(?)" in grid_table(curves)


def test_grid_sweep_on_dask_gives_the_local_numbers(grid_reference, tmp_path):
    """A grid point is just more jobs: a two-process LocalCluster gives the CLI's numbers."""
    pytest.importorskip("distributed")
    from helpers import local_cluster_client

    from antisync.execution.executors.dask import DaskExecutor

    cfg, _, ref = grid_reference
    out = tmp_path / "grid.h5"
    with local_cluster_client() as client:
        with DaskExecutor(client, "cpu") as ex:
            run_sweep(load_sweep(cfg), output=out, progress=False, executor=ex, chunk_realizations=32)
    assert comparable(sweep_summary(out)) == ref


def test_grid_figure_of_a_zip_axis_with_names(tmp_path):
    """A zip axis whose first key is not a number is drawn at positions 0, 1, ... labelled
    with every zipped value; a second graph's links are named with their graph."""
    from antisync.report.grid_sweep import grid_curves, plot_grid

    recs = []
    for k, (integrator, dt) in enumerate([("euler", 0.01), ("rk4", 0.05)]):
        for graph in ("g", "h"):
            r = _record("1->2", 0.0, 0.99, 0.1 * (k + 1), 0.05, 0.3)
            r.update(graph=graph, grid={"dynamics.integrator": integrator, "dynamics.dt": dt})
            r["point"] = f"dynamics.integrator={integrator}, dynamics.dt={dt:g}"
            recs.append(r)
    summary = {
        "records": recs,
        "grid": [
            {
                "keys": ["dynamics.integrator", "dynamics.dt"],
                "values": [["euler", 0.01], ["rk4", 0.05]],
                "zip": True,
            }
        ],
    }
    curves = grid_curves(summary)
    assert not curves["numeric"] and list(curves["x"]) == [0.0, 1.0]
    assert curves["x_labels"] == ["euler, 0.01", "rk4, 0.05"]
    assert curves["graphs"] == ["g", "h"] and len(curves["panels"]) == 1
    np.testing.assert_allclose(curves["panels"][0]["curves"][0]["lambda"], [0.1, 0.2])
    fig = plot_grid(curves)
    fig.savefig(tmp_path / "zip.png")
    assert (tmp_path / "zip.png").stat().st_size > 0
