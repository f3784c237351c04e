"""What each Lambda^KM estimator estimates, near saddle passages.

Two quantities share the name Lambda^KM: the paper's forward secant (<F(dbeta)> - 1)/dbeta of
Eq. 17 at a stated dbeta, and the derivative d<F>/dbeta at 0. Near saddle passages tau(beta)
has logarithmic singularities close to beta = 0, so the one-sided secants keep a bias of their
side at every usable dbeta while central differences do not. The sum rule (normalized coupling:
the out-links of a node sum to 0 for the derivative) tells them apart. Every comparison here is
paired, on common initial phases, with fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

from antisync.execution.compute import lambda_values, simulate_job
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.status import SYNCED

LOLLIPOP = "{kind: lollipop, nodes: 6, path: 3}"
K5 = "{kind: networkx, generator: complete_graph, args: {n: 5}}"


def _job(graph: str, edges: list[str], method: str, *, dt: float = 0.04, dbeta: float = 0.01, seed: int = 11):
    return make_job(
        load_config_text(f"""
graph: {graph}
edges: {edges}
betas: []
realizations: 1
seed: {seed}
lambda: {{method: {method}, dbeta: {dbeta}}}
dynamics: {{integrator: rk4, dt: {dt}, crossing: interpolated, t_max: 400}}
""")
    )


def _values(job, count: int, chunk: int = 100_000):
    """Per-realization values and their 'synchronized' mask of every link, in realization order."""
    vals, oks = [], []
    for first in range(0, count, chunk):
        n = min(chunk, count - first)
        sim = simulate_job(job, first, n) if job.config.lambda_.method == "finite-difference" else None
        v, code, _, _ = lambda_values(job, sim, first, n)
        vals.append(v)
        oks.append(code == SYNCED)
    return np.concatenate(vals), np.concatenate(oks)


def _mean_se(x: np.ndarray, block: int = 1000) -> tuple[float, float]:
    """Mean and batch-means standard error of a per-realization series."""
    nb = x.size // block
    means = x[: nb * block].reshape(nb, block).mean(axis=1)
    return float(x.mean()), float(means.std(ddof=1) / np.sqrt(nb))


@pytest.mark.parametrize(
    ("graph", "node_edges"), [(LOLLIPOP, ["2->1", "2->3"]), (K5, ["0->1", "0->2", "0->3", "0->4"])]
)
def test_the_adjoint_obeys_the_sum_rule_per_realization(graph, node_edges):
    """Damaging every out-link of a node alike leaves W unchanged: the per-realization
    derivatives of a node's out-links add up to 0, to rounding."""
    values, ok = _values(_job(graph, node_edges, "adjoint"), 2000)
    assert ok.all()
    scale = np.abs(values).max(axis=1)
    assert np.all(np.abs(values.sum(axis=1)) <= 1e-9 * np.maximum(scale, 1.0))


#: The two tests of :func:`lollipop_secants` (800,000 integrations, 16.5 s of a fresh clone's
#: `make test`) run in `make test-slow`. Their power, from one run of the fixture (seed 11): the
#: forward secants' sum over node 2's out-links is +0.01095 +- 0.00236 (z = 4.6) against a
#: threshold of 3 standard errors, power about 0.95; 2->1's forward-minus-central gap is
#: +0.00673 +- 0.00118 (z = 5.7), power about 0.997; the central sum, +0.00017 +- 0.00009, sits
#: well inside its bound of 4 standard errors + 1e-4.
@pytest.fixture(scope="module")
def lollipop_secants():
    """Forward secants (the paper's Eq. 17) and central differences of node 2's two out-links,
    400,000 realizations on the same phases (RK4 dt 0.04, interpolated crossings)."""
    edges = ["2->1", "2->3"]
    fwd, ok_f = _values(_job(LOLLIPOP, edges, "finite-difference"), 400_000)
    cen, ok_c = _values(_job(LOLLIPOP, edges, "central-difference"), 400_000)
    both = (ok_f & ok_c).all(axis=1)
    return fwd[both], cen[both]


@pytest.mark.slow
def test_central_differences_obey_the_sum_rule_and_forward_secants_do_not(lollipop_secants):
    fwd, cen = lollipop_secants
    c_sum, c_se = _mean_se(cen.sum(axis=1))
    f_sum, f_se = _mean_se(fwd.sum(axis=1))
    gap, gap_se = _mean_se(fwd.sum(axis=1) - cen.sum(axis=1))
    assert abs(c_sum) < 4 * c_se + 1e-4, (c_sum, c_se)
    # measured: forward sum +0.0120 +- 0.0024 at dbeta 0.01 (bench/saddle_secants.py)
    assert f_sum > 3 * f_se, (f_sum, f_se)
    assert gap > 3 * gap_se, (gap, gap_se)


@pytest.mark.slow
def test_the_paper_headline_link_is_a_forward_value(lollipop_secants):
    """2->1: the forward secant sits above the central difference on the same phases (the
    paper's 0.2653 is a forward value; the derivative is about 0.257)."""
    fwd, cen = lollipop_secants
    gap, gap_se = _mean_se(fwd[:, 0] - cen[:, 0])
    assert gap > 3 * gap_se, (gap, gap_se)
    value, se = _mean_se(cen[:, 0])
    assert 0.245 < value < 0.27 and se < 0.003


@pytest.mark.parametrize("dt", [0.04, 0.02])
def test_the_derivative_estimators_agree_paired(dt):
    """Central differences, the adjoint-hybrid (adjoint bulk, central secants where flagged) and
    orbit estimate one quantity: their per-realization differences average to 0 on common
    phases, at two step sizes."""
    edges = ["2->1", "2->3", "5->6", "6->4"]
    cen, ok_c = _values(_job(LOLLIPOP, edges, "central-difference", dt=dt), 20_000)
    adh, ok_a = _values(_job(LOLLIPOP, edges, "adjoint-hybrid", dt=dt), 20_000)
    both = ok_c & ok_a
    for e in range(len(edges)):
        d = (adh[:, e] - cen[:, e])[both[:, e]]
        gap, se = _mean_se(d)
        assert abs(gap) < 4 * se + 2e-4, (edges[e], gap, se)
    orb, ok_o = _values(_job(LOLLIPOP, ["2->1"], "orbit", dt=dt), 20_000)
    # 2->1 is alone in its orbit: orbit is the central difference itself
    assert np.array_equal(orb[:, 0], cen[:, 0]) and np.array_equal(ok_o[:, 0], ok_c[:, 0])


def test_the_complete_graph_derivative_is_zero():
    """K5: symmetry and the sum rule make every link's derivative 0; its central difference on
    one link is consistent with 0."""
    cen, ok = _values(_job(K5, ["0->1"], "central-difference"), 100_000)
    value, se = _mean_se(cen[ok[:, 0], 0])
    assert abs(value) < 4 * se, (value, se)


# ---- what the summary says ---------------------------------------------------------------
def _run(
    tmp_path,
    method: str,
    extra: str = "",
    dynamics: str = "{integrator: rk4, dt: 0.04, crossing: interpolated}",
):
    from antisync.execution.runner import run_config

    cfg = load_config_text(f"""
graph: {LOLLIPOP}
edges: all
betas: []
realizations: 2000
seed: 3
lambda: {{method: {method}}}
dynamics: {dynamics}
{extra}""")
    return run_config(cfg, output=tmp_path / f"{method}.h5")


@pytest.mark.parametrize(
    ("method", "quantity"), [("finite-difference", "forward-secant"), ("central-difference", "derivative")]
)
def test_every_record_names_its_quantity_and_the_summary_checks_the_sum_rule(tmp_path, method, quantity):
    from antisync.api import summarize

    s = summarize(_run(tmp_path, method))
    assert {r["lambda_quantity"] for r in s["records"]} == {quantity}
    rows = {r["node"]: r for r in s["sum_rule"]}
    assert set(rows) == {"2", "3", "4", "5", "6"}  # node 1 has a single out-link
    for node, row in rows.items():
        links = [r for r in s["records"] if r["edge"].split("->")[0] == node]
        assert row["links"] == [r["edge"] for r in links]
        assert row["sum"] == pytest.approx(sum(r["lambda_km"] for r in links), abs=1e-12)
        assert row["low"] < row["sum"] < row["high"]


def test_the_summary_table_says_how_signs_were_called_and_the_sum_rule(tmp_path):
    from typer.testing import CliRunner

    from antisync.cli.app import app

    out = _run(tmp_path, "finite-difference")
    res = CliRunner().invoke(app, ["summary", str(out)])
    assert res.exit_code == 0, res.output
    assert "false discovery rate 0.05" in res.output
    assert "sum rule (normalized coupling" in res.output and "5 node(s) checked" in res.output


def test_raw_coupling_has_no_sum_rule(tmp_path):
    """Without the normalization a node's out-links do not compensate each other: no rule."""
    from antisync.api import summarize
    from antisync.execution.runner import run_config

    raw = load_config_text(f"graph: {LOLLIPOP}\nbetas: []\nrealizations: 200\ndynamics: {{coupling: raw}}\n")
    assert summarize(run_config(raw, output=tmp_path / "raw.h5"))["sum_rule"] == []


def test_a_hybrid_file_from_before_central_secants_says_so(tmp_path):
    """Files whose job group has no lambda_quantity were written before the hybrids' flagged
    values became central secants: their hybrid records are labelled as the mixture they are."""
    import h5py

    from antisync.api import summarize
    from antisync.execution.runner import run_config
    from antisync.stats.estimators import MIXED_QUANTITY

    cfg = load_config_text(
        f"graph: {LOLLIPOP}\nedges: ['2->1']\nbetas: []\nrealizations: 200\n"
        "lambda: {method: hybrid}\ndynamics: {dt: 0.01}\n"
    )
    out = run_config(cfg, output=tmp_path / "h.h5")
    assert summarize(out)["records"][0]["lambda_quantity"] == "derivative"
    with h5py.File(out, "r+") as f:
        for g in f["jobs"].values():
            del g.attrs["lambda_quantity"]
    assert summarize(out)["records"][0]["lambda_quantity"] == MIXED_QUANTITY


# ---- the additive response Lambda^tau = -d ln<tau(beta)>/dbeta ----------------------------
def test_lambda_tau_is_the_ratio_of_the_paired_means(tmp_path):
    """The record's Lambda^tau is -(<tau(dbeta)> - <tau0>)/(dbeta <tau0>) over the realizations
    that give a Lambda value, computed from the kept per-realization times."""
    import h5py

    from antisync.api import summarize

    # grid crossings: the kept pairs hold the steps (an interpolated run's fractions are not kept)
    out = _run(
        tmp_path, "finite-difference", "keep_pairs: 2000", "{integrator: euler, dt: 0.01, crossing: grid}"
    )
    recs = {r["edge"]: r for r in summarize(out)["records"]}
    with h5py.File(out, "r") as f:
        (g,) = f["jobs"].values()
        edges = __import__("json").loads(g.attrs["edges"])
        steps0, steps = g["kept/steps0"][...], g["kept/steps"][...]
        status0, status = g["kept/status0"][...], g["kept/status"][...]
        variant_edge, variant_beta = g["variant_edge"][...], g["variant_beta"][...]
    dt = 0.01
    t0 = steps0 * dt
    for e, label in enumerate(edges):
        v = int(np.flatnonzero((variant_edge == e) & np.isclose(variant_beta, 0.01))[0])
        t = steps[:, v] * dt
        ok = (status0 == SYNCED) & (status[:, v] == SYNCED)
        direct = -np.sum((t[ok] - t0[ok]) / 0.01) / np.sum(t0[ok])
        assert recs[label]["lambda_tau"] == pytest.approx(direct, rel=1e-9, abs=1e-12), label


def test_lambda_tau_interval_uses_the_batches_degrees_of_freedom():
    """R +- t se with Student's t on n_batches - 1 degrees of freedom (a normal quantile covered
    0.940 at 20 batches, bench/RESULTS.md); at many batches it is the normal interval."""
    from scipy.stats import t as student

    from antisync.stats.estimators import Z95, Estimate, lambda_tau_interval

    low, high = lambda_tau_interval(Estimate(0.3, 0.01, float("nan"), 0.01, 2000, 20))
    q = student.ppf(0.975, 19)
    assert q == pytest.approx(2.093, abs=1e-3)
    assert (low, high) == pytest.approx((0.3 - q * 0.01, 0.3 + q * 0.01), rel=1e-12)
    low, high = lambda_tau_interval(Estimate(0.3, 0.01, float("nan"), 0.01, 10**6, 10**5))
    assert high - 0.3 == pytest.approx(Z95 * 0.01, rel=1e-4)
    assert np.isnan(lambda_tau_interval(Estimate(0.3, float("nan"), float("nan"), float("nan"), 5, 1))).all()


def test_lambda_tau_obeys_the_sum_rule_with_forward_secants(tmp_path):
    """Unlike <F>'s forward secant, Lambda^tau's forward secant keeps node 2's sum within its
    interval (measured +0.0023 +- 0.0031 at 400,000 realizations, bench/RESULTS.md)."""
    from antisync.api import summarize
    from antisync.execution.runner import run_config

    cfg = load_config_text(f"""
graph: {LOLLIPOP}
edges: ["2->1", "2->3"]
betas: []
realizations: 100000
seed: 11
dynamics: {{integrator: rk4, dt: 0.04, crossing: interpolated}}
""")
    s = summarize(run_config(cfg, output=tmp_path / "t.h5"))
    (row,) = [r for r in s["sum_rule"] if r["node"] == "2"]
    assert row["tau_low"] < 0 < row["tau_high"], row
    assert row["tau_high"] - row["tau_low"] < 0.05


def test_a_format_3_file_reads_and_resumes_without_lambda_tau(tmp_path):
    """A file from before Lambda^tau (8 Lambda fields) is summarized with lambda_tau None and
    resumed: the new blocks cannot make up for the old ones, so it stays None."""
    import h5py

    from antisync.api import summarize
    from antisync.execution.runner import run_config

    text = f"graph: {LOLLIPOP}\nedges: ['2->1']\nbetas: []\nrealizations: 400\nblock_size: 100\n"
    text += "dynamics: {integrator: rk4, dt: 0.04}\n"
    out = run_config(load_config_text(text, ["realizations=200"]), output=tmp_path / "old.h5")
    with h5py.File(out, "r+") as f:
        f.attrs["format_version"] = 3
        (g,) = f["jobs"].values()
        old = g["lambda_records"][...][..., :8]
        del g["lambda_records"]
        g["lambda_records"] = old
    assert summarize(out)["records"][0]["lambda_tau"] is None
    # the same config with more realizations is another run; the same one resumes
    res = run_config(load_config_text(text, ["realizations=200"]), output=out, resume=True)
    assert summarize(res)["records"][0]["lambda_km"] is not None


def _sum_rule_view(nodes: int, offset_in_se: float):
    """A job whose every node has two out-links; node 1's sum sits ``offset_in_se`` standard
    errors from 0, the others' at 0 (per-block sums alternate around their mean)."""
    from antisync.stats.summary import JobView

    nb, delta = 50, 0.1
    se = delta * np.sqrt(nb / (nb - 1)) / np.sqrt(nb)
    edges = [f"{a}->{b}" for a in range(1, nodes + 1) for b in ("x", "y")]
    lam = np.zeros((nb, len(edges), 10))
    lam[:, :, 0] = 100
    swing = delta * (-1.0) ** np.arange(nb)
    for k in range(nodes):
        mean = offset_in_se * se if k == 0 else 0.0
        lam[:, 2 * k, 3] = 100 * (mean + swing)  # the node's sum per block is the first link's
    lam[:, :, 8], lam[:, :, 9] = 0.0, 100.0
    empty = np.zeros((nb, 0, 7))
    return JobView(
        graph="g", edges=edges, betas=(), dbeta=0.01, variant_edge=np.zeros(0), variant_beta=np.zeros(0),
        rec=empty, rec0=np.zeros((nb, 5)), done=np.ones(nb, bool), tail=np.zeros((0, 1)),
        realizations=nb * 100, lam_rec=lam,
    )  # fmt: skip


def test_the_sum_rule_decides_over_all_the_nodes_it_checks():
    """A sum 2.3 standard errors from 0 is resolved when it is the only node checked (95%) but
    not among five (Bonferroni, 99%): checking many nodes finds no broken rule by chance."""
    from antisync.stats.sum_rule import node_sums

    (alone,) = node_sums(_sum_rule_view(1, 2.3))
    assert alone["resolved"] and alone["low"] > 0
    among = node_sums(_sum_rule_view(5, 2.3))
    assert len(among) == 5 and among[0]["low"] > 0 and not any(r["resolved"] for r in among)
    assert node_sums(_sum_rule_view(5, 3.0))[0]["resolved"]
