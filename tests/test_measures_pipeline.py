"""The response measures inside a run: config -> runner -> HDF5 -> summary -> report.

``measures: [km, linear, xi2, rw, km_nnc]`` must give, per directed edge, exactly what the
measure functions give when called by hand with the run's phases and settings, store it once,
join the raw-coupling twin's Lambda, and draw Figs. 5 and 7e.
"""

import json

import h5py
import networkx as nx
import numpy as np
import pytest
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError, MeasureError
from antisync.execution.runner import run_config
from antisync.measures import lambda_linear, lambda_rw, lambda_xi2_all
from antisync.measures import linear as linear_mod
from antisync.measures.pipeline import compute_measures, nnc_job, with_nnc
from antisync.physics import graphs
from antisync.physics.phases import initial_phases
from antisync.plan.config import LINEAR_METHODS, load_config_text
from antisync.plan.jobs import make_job
from antisync.stats.summary import RECORD_KEYS

runner = CliRunner()

SEED, M_LINEAR = 4, 120
CONFIG = f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
betas: [0.5]
realizations: 300
block_size: 30
seed: {SEED}
measures: [km, linear, xi2, rw, km_nnc]
linear: {{realizations: {M_LINEAR}, method: exact}}
lambda: {{method: finite-difference, dbeta: 0.01}}
dynamics: {{dt: 0.002, t_max: 60}}
histogram: {{bins: 20}}
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One CLI run with every measure, its JSON summary and its report folder."""
    tmp = tmp_path_factory.mktemp("measures")
    cfg = tmp / "lolli.yaml"
    cfg.write_text(CONFIG)
    out = tmp / "lolli.h5"
    res = invoke("run", cfg, "--out", out, "--quiet")
    assert res.exit_code == 0, res.output
    res = invoke("summary", out, "--format", "json")
    assert res.exit_code == 0, res.output
    recs = json.loads(res.stdout)["records"]
    res = invoke("report", out, "--out", tmp / "fig", "--quiet")
    assert res.exit_code == 0, res.output
    return {"cfg": cfg, "out": out, "recs": recs, "fig": tmp / "fig"}


def _by_edge(recs, graph):
    return {r["edge"]: r for r in recs if r["graph"] == graph}


def test_summary_values_equal_direct_calls(run):
    recs = _by_edge(run["recs"], "lollipop_6_3")
    omega = graphs.omega_matrix(graphs.lollipop(6, 3))
    labels = list(recs)
    pairs = [(int(a) - 1, int(b) - 1) for a, b in (e.split("->") for e in labels)]
    assert len(pairs) == 12
    xi2 = lambda_xi2_all(omega, pairs, "normalized")
    theta0 = initial_phases(SEED, 0, M_LINEAR, 6)  # realizations 0..M-1 of the run's seed
    for label, (a, b), x in zip(labels, pairs, xi2, strict=True):
        r = recs[label]
        assert set(RECORD_KEYS) <= set(r)
        assert r["lambda_xi2"] == pytest.approx(x, rel=1e-12, abs=1e-15)
        assert r["lambda_rw"] == pytest.approx(lambda_rw(omega, a, b), rel=1e-12, abs=1e-15)
        lin = lambda_linear(omega, a, b, theta0, 0.99, "normalized", 0.01, "exact", dt=0.002, t_max=60)
        assert r["lambda_linear"] == pytest.approx(lin.lambda_, rel=1e-12, abs=1e-15)
        assert r["lambda_linear_se"] == pytest.approx(lin.se, rel=1e-12, abs=1e-15)
        assert (r["lambda_linear_n"], r["lambda_linear_n_excluded"]) == (lin.n, lin.n_excluded)


def test_km_nnc_is_joined_from_the_raw_coupling_twin(run):
    recs, twin = _by_edge(run["recs"], "lollipop_6_3"), _by_edge(run["recs"], "lollipop_6_3_nnc")
    assert set(twin) == set(recs)
    for edge, r in recs.items():
        assert r["lambda_km_nnc"] == twin[edge]["lambda_km"]
        assert r["lambda_km_nnc_se"] == twin[edge]["lambda_km_se"]
    # the twin's own records carry its KM run and no measures
    assert all(twin[e][k] is None for e in twin for k in RECORD_KEYS)
    # raw coupling, same seed: realization k's tau0 is the raw-coupled Kuramoto time from the
    # same initial phases (checked against a direct integration)
    from antisync.execution.compute import simulate_job

    cfg = load_config_text(CONFIG)
    sim = simulate_job(nnc_job(make_job(cfg)), 0, 25)
    with h5py.File(run["out"], "r") as f:
        g = f["jobs/lollipop_6_3_nnc"]
        assert g.attrs["coupling"] == "raw" and g.attrs["nnc_of"] == "lollipop_6_3"
        assert g.attrs["seed"] == SEED and "measures" not in g
        np.testing.assert_array_equal(g["kept/steps0"][:25], sim.steps0)
        assert f["jobs/lollipop_6_3"].attrs["coupling"] == "normalized"
    # the normalized tau0 differ: the twin really is another model
    assert recs["2->1"]["tau0_mean"] != twin["2->1"]["tau0_mean"]


def test_lambda_is_exactly_zero_on_the_leaf_edge(run):
    r = _by_edge(run["recs"], "lollipop_6_3")["1->2"]
    for key in ("lambda_km", "lambda_linear", "lambda_xi2", "lambda_rw"):
        assert r[key] == 0.0, key
    # ...but not in the raw-coupling model, where damage weakens node 1's only coupling
    assert r["lambda_km_nnc"] < 0


def test_hdf5_measures_group(run):
    with h5py.File(run["out"], "r") as f:
        g = f["jobs/lollipop_6_3"]
        edges = json.loads(g.attrs["edges"])
        m = g["measures"]
        assert json.loads(m.attrs["measures"]) == ["linear", "xi2", "rw"]
        assert m.attrs["linear_method"] == "exact" and m.attrs["linear_realizations"] == M_LINEAR
        assert m.attrs["linear_seed"] == SEED and m.attrs["linear_dbeta"] == 0.01
        for key in (
            "lambda_xi2",
            "lambda_rw",
            "lambda_linear",
            "lambda_linear_se",
            "lambda_linear_n",
            "lambda_linear_n_excluded",
        ):
            assert m[key].shape == (len(edges),), key
        i = edges.index("2->1")
        recs = _by_edge(run["recs"], "lollipop_6_3")
        assert m["lambda_xi2"][i] == recs["2->1"]["lambda_xi2"]


def test_report_draws_fig5_and_fig7e(run):
    pngs = {p.name for p in run["fig"].glob("*.png")}
    assert {"fig5_measures.png", "lolli_fig7e_km_nnc.png"} <= pngs  # named after lolli.yaml
    assert "lolli_nnc_graph.png" in pngs  # the twin's own Fig. 7a


def test_summary_table_shows_measure_columns(run):
    res = invoke("summary", run["out"])
    assert res.exit_code == 0
    header = res.stdout.splitlines()[0]
    for col in ("Lambda_lin", "Lambda_xi2", "Lambda_RW", "Lambda_NNC"):
        assert col in header


def test_records_without_measures_have_null_keys(tmp_path, small_config_text):
    cfg = tmp_path / "small.yaml"
    cfg.write_text(small_config_text)
    out = tmp_path / "r.h5"
    assert invoke("run", cfg, "--out", out, "--quiet").exit_code == 0
    recs = json.loads(invoke("summary", out, "--format", "json").stdout)["records"]
    assert all(r[k] is None for r in recs for k in RECORD_KEYS)
    res = invoke("report", out, "--out", tmp_path / "fig", "--quiet")
    assert res.exit_code == 0
    assert not list((tmp_path / "fig").glob("fig5*"))


# --- bad input ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("override", "expect"),
    [
        (
            "measures=[km, xi_2]",
            "measures must be one of km, linear, xi2, rw, km_nnc, got 'xi_2' (did you mean 'xi2'?)",
        ),
        ("measures=[xi2, km_nnc]", "measures: km_nnc is a raw-coupling twin of the km run; add km"),
        ("measures=[]", "measures must list at least one measure"),
        ("measures=[km, rw, rw]", "measures lists rw twice"),
        (
            "linear.method=eular",
            "linear.method must be one of exact, euler, derivative, got 'eular' (did you mean 'euler'?)",
        ),
        ("linear.realizations=1", "linear.realizations must be an integer in 2..10**15"),
        ("linear.runs=5", "unknown key 'linear.runs'"),
    ],
)
def test_bad_measure_config_is_one_line_exit_2(tmp_path, override, expect):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIG)
    res = invoke("run", cfg, "--out", tmp_path / "x.h5", "--set", override, "--quiet")
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error:")
    assert expect in lines[0]
    assert not (tmp_path / "x.h5").exists()


def test_km_nnc_needs_a_normalized_run():
    with pytest.raises(ConfigError, match="km_nnc .* needs dynamics.coupling: normalized"):
        load_config_text(CONFIG, ["dynamics.coupling=raw"])
    assert load_config_text(CONFIG, ["dynamics.coupling=raw", "measures=[km, xi2]"])


def test_measures_on_a_disconnected_graph_fail_before_anything_is_written(tmp_path):
    two = nx.disjoint_union(nx.complete_graph(3), nx.complete_graph(3))
    nx.set_edge_attributes(two, 1.0, "weight")
    cfg = load_config_text(CONFIG, ["measures=[km, rw]", f"output={tmp_path / 'd.h5'}"])
    job = make_job(cfg, graph=two, name="two_triangles")
    with pytest.raises(MeasureError, match=r"^graph two_triangles: measure rw: .*disconnected"):
        compute_measures(job)
    from antisync.execution.runner import run_jobs

    with pytest.raises(MeasureError):
        run_jobs([job], cfg, progress=False)
    assert not list(tmp_path.iterdir())


def test_config_schema():
    cfg = load_config_text(CONFIG)
    assert cfg.measures == ("km", "linear", "xi2", "rw", "km_nnc")
    assert cfg.to_dict()["linear"] == {"realizations": M_LINEAR, "method": "exact"}
    default = load_config_text("graph: {kind: lollipop, nodes: 6, path: 3}")
    assert default.measures == ("km",) and default.linear.method == "exact"
    assert LINEAR_METHODS == linear_mod.LINEAR_METHODS
    assert load_config_text(CONFIG, ["measures=km"]).measures == ("km",)


def test_with_nnc_adds_one_twin_per_job():
    job = make_job(load_config_text(CONFIG))
    jobs = with_nnc([job])
    assert [j.name for j in jobs] == ["lollipop_6_3", "lollipop_6_3_nnc"]
    assert [j.name for j in with_nnc(jobs)] == ["lollipop_6_3", "lollipop_6_3_nnc"]  # idempotent
    twin = jobs[1]
    assert twin.nnc_of == job.name and twin.config.dynamics.coupling == "raw"
    assert twin.config.measures == ("km",) and twin.edge_labels == job.edge_labels
    # raw coupling: W = Omega, so the twin's undamaged weights are the adjacency itself
    np.testing.assert_array_equal(twin.csr.weights, np.ones_like(twin.csr.weights))


def test_linear_exact_and_euler_agree_with_common_phases():
    """Through the pipeline: the same KM initial phases, Lambda^(linear) by the exact solution
    and by Euler (dt = 0.001) agree within their standard errors on the lollipop."""
    text = CONFIG.replace("dt: 0.002", "dt: 0.001")
    edges = ["2->1", "2->3", "4->5"]
    common = ["measures=[km, linear]", f"edges={json.dumps(edges)}", "linear.realizations=100"]
    exact = compute_measures(make_job(load_config_text(text, common + ["linear.method=exact"])))
    euler = compute_measures(make_job(load_config_text(text, common + ["linear.method=euler"])))
    np.testing.assert_array_equal(exact["lambda_linear_n"], euler["lambda_linear_n"])
    assert np.all(exact["lambda_linear_n"] == 100)
    diff = np.abs(exact["lambda_linear"] - euler["lambda_linear"])
    se = np.hypot(exact["lambda_linear_se"], euler["lambda_linear_se"])
    assert np.all(diff <= 3 * se), (diff, se)
    # with common phases they agree far better than independent estimates would
    assert np.all(diff <= 0.1 * se), (diff, se)


def test_measures_are_computed_once_and_survive_checkpoints_and_resume(tmp_path, monkeypatch):
    import antisync.execution.runner as runner_mod
    from antisync.store import records

    calls = []

    def counting(job, config=None):
        calls.append(job.name)
        return compute_measures(job, config)

    monkeypatch.setattr(runner_mod, "compute_measures", counting)
    cfg = load_config_text(
        CONFIG,
        [
            "measures=[km, xi2, km_nnc]",
            "realizations=60",
            "block_size=10",
            'edges=["2->1"]',
            f"output={tmp_path / 'r.h5'}",
        ],
    )
    # many chunks, a checkpoint after each: the measures are still computed once
    path = run_config(cfg, progress=False, chunk_realizations=10, checkpoint_seconds=0.0)
    assert calls == ["lollipop_6_3"]  # the twin has no measures of its own
    first = records(path)
    run_config(cfg, progress=False, resume=True)
    assert calls == ["lollipop_6_3"]  # read back from the file on --resume
    assert records(path) == first
    assert first[0]["lambda_xi2"] is not None and first[0]["lambda_km_nnc"] is not None


# --- Sec. 3.4: Lambda^(KM-NNC) against Lambda^KM on the lollipop ----------------------------------

SLOW_CONFIG = """
graph: {kind: lollipop, nodes: 6, path: 3}
betas: []
realizations: 100000
seed: 1
measures: [km, km_nnc]
lambda: {method: finite-difference, dbeta: 0.01}
dynamics: {dt: 0.001, threshold: 0.99, t_max: 200}
keep_pairs: 0
"""
# 4->5 and 4->6 (one edge up to the 5<->6 symmetry): KM - NNC is about +0.007 +- 0.004 from
# 120k realizations (this seed's 100k plus 20k of seed 12), i.e. well under 2 standard errors
# here; resolving it at 3 se would take about 1e6 realizations, far beyond a test's budget.
UNRESOLVED = ("4->5", "4->6")


@pytest.mark.slow
def test_km_nnc_below_km_except_3to4(tmp_path):
    """Sec. 3.4, Fig. 7e: Lambda^(KM-NNC) < Lambda^KM on every lollipop edge but 3->4.

    1e5 realizations of each model (same seed, hence the same initial phases), dt = 0.001,
    dbeta = 0.01; about 380 CPU-seconds (3 minutes on two free cores). The margin of an edge
    is (Lambda^KM - Lambda^NNC) / sqrt(se_KM^2 + se_NNC^2); with the two runs almost
    uncorrelated per realization (|corr| < 0.2 in a 20k run), this combined se is the se of
    the difference. Observed with this seed: 3->4 -5.5; 5->6 +7.7, 6->5 +9.3, 5->4 and 6->4
    +13.6, 4->3 +14.2, 2->1 +17.5, 2->3 +18.1, 3->2 +26.0, 1->2 +92; 4->5 +1.4 and 4->6
    +0.1, the two the test cannot resolve (see UNRESOLVED): for them it asserts only that
    the data do not contradict the paper (margin > -2).
    """
    from antisync.store import records

    cfg = load_config_text(SLOW_CONFIG, [f"output={tmp_path / 'nnc.h5'}"])
    recs = [r for r in records(run_config(cfg, progress=False)) if r["graph"] == "lollipop_6_3"]
    margins = {}
    for r in recs:
        diff = r["lambda_km"] - r["lambda_km_nnc"]
        margins[r["edge"]] = diff / np.hypot(r["lambda_km_se"], r["lambda_km_nnc_se"])
        print(
            f"{r['edge']}: KM {r['lambda_km']:+.4f} +- {r['lambda_km_se']:.4f}, "
            f"NNC {r['lambda_km_nnc']:+.4f} +- {r['lambda_km_nnc_se']:.4f}, "
            f"margin {margins[r['edge']]:+.1f}"
        )
    assert len(margins) == 12
    assert margins.pop("3->4") < -3  # the paper's one exception: NNC above KM
    for edge in UNRESOLVED:
        assert margins.pop(edge) > -2, edge
    assert all(m > 3 for m in margins.values()), margins
