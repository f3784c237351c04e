"""Lambda estimators: pathwise tangents against finite differences, closed-form symmetries,
the hybrid's secants, orbit differences, and agreement between methods on the paper's lollipop."""

import numpy as np
import pytest

from antisync.execution.runner import run_config
from antisync.kernels.cpu import simulate, simulate_pathwise
from antisync.physics import coupling, graphs
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.store import records

DT = 0.002
KW = dict(dt=DT, threshold=0.99, max_steps=50_000)


def _setup(kind, edges):
    omega = graphs.omega_matrix(graphs.lollipop(6, 3))
    csr = coupling.to_csr(coupling.coupling_matrix(omega, kind), pattern=omega > 0)
    return omega, csr, coupling.tangent_coefficients(omega, edges, kind)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_tangent_coefficients_reproduce_coupling_derivative(kind):
    omega = graphs.omega_matrix(graphs.lollipop(7, 2)) * 1.5
    edges = [(1, 0), (3, 4), (2, 3), (0, 1)]
    a, b, rho, mu = coupling.tangent_coefficients(omega, edges, kind)
    w = coupling.coupling_matrix(omega, kind)
    for e, (i, j) in enumerate(edges):
        expected = coupling.coupling_derivative(omega, i, j, kind)[i]
        got = rho[e] * w[i]
        got[j] += mu[e]
        assert np.allclose(got, expected, atol=1e-14)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_pathwise_tangent_matches_finite_difference_of_interpolated_tau(kind):
    edges = [(1, 0), (4, 5), (1, 2), (2, 3)]
    omega, csr, (a, b, rho, mu) = _setup(kind, edges)
    m = 30
    pw = simulate_pathwise(3, 0, m, csr.indptr, csr.indices, csr.weights, a, b, rho, mu, **KW)
    h = 1e-6
    vw = coupling.variant_weights(omega, csr, [(i, j, h) for i, j in edges], kind)
    fd = simulate(3, 0, m, csr.indptr, csr.indices, csr.weights, vw, **KW)
    assert np.array_equal(fd.steps0, pw.steps0) and np.allclose(fd.frac0, pw.frac0, rtol=0, atol=1e-15)
    tau0 = (pw.steps0 - 1 + pw.frac0) * DT
    numeric = ((fd.steps - 1 + fd.frac) * DT - tau0[:, None]) / h
    err = np.abs(numeric - pw.dtau) / (np.abs(pw.dtau) + 1e-3)
    assert np.median(err) < 1e-5 and err.max() < 5e-3


def test_degree_two_and_degree_one_nodes():
    """Node 2 has degree 2: damaging 2->1 and 2->3 changes row 2 in exactly opposite ways, so the
    derivative estimators give opposite values realization by realization; 1->2 gives 0."""
    edges = [(1, 0), (1, 2), (0, 1)]
    omega, csr, (a, b, rho, mu) = _setup("normalized", edges)
    pw = simulate_pathwise(8, 0, 64, csr.indptr, csr.indices, csr.weights, a, b, rho, mu, **KW)
    # equal up to rounding: the forcing rho*omega_a + mu*sin is not computed as a negation
    assert np.allclose(pw.dtau[:, 0], -pw.dtau[:, 1], rtol=1e-9, atol=1e-12)
    assert np.all(pw.dtau[:, 2] == 0.0)


def _job(method, extra=""):
    return make_job(
        load_config_text(f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
edges: ["2->1", "2->3", "5->6", "1->2"]
betas: []
lambda: {{method: {method}, hybrid_cut: 1.0}}
dynamics: {{dt: {DT}, t_max: 100}}
realizations: 400
seed: 5
{extra}""")
    )


def test_hybrid_uses_central_secants_of_interpolated_times_where_flagged():
    """Flagged values (near a saddle passage) are central secants: a forward one would carry
    the one-sided bias that makes the sum rule fail."""
    from antisync.execution.compute import lambda_values

    hybrid = _job("hybrid")
    values, code, flagged, base = lambda_values(hybrid, None, 0, 400)
    pathwise_values, _, _, _ = lambda_values(_job("pathwise"), None, 0, 400)
    assert flagged.any() and flagged.mean() < 0.2
    assert np.array_equal(values[~flagged], pathwise_values[~flagged])
    tau0 = (base.steps0 - 1 + base.frac0) * DT
    for r, e in zip(*np.nonzero(flagged), strict=True):
        sec = simulate(
            5,
            0,
            0,
            hybrid.csr.indptr,
            hybrid.csr.indices,
            hybrid.csr.weights,
            hybrid.secant_weights[[e, len(hybrid.edges) + e]],
            realizations=np.array([r]),
            **KW,
        )
        plus, minus = (sec.steps[0] - 1 + sec.frac[0]) * DT
        assert values[r, e] == pytest.approx(tau0[r] * (1 / plus - 1 / minus) / (2 * 0.01), rel=1e-12)


def test_methods_agree_on_the_lollipop(tmp_path):
    out = {}
    for method in ("finite-difference", "pathwise", "hybrid", "orbit"):
        cfg = load_config_text(f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
edges: ["2->1", "2->3", "5->6", "1->2"]
betas: []
lambda: {{method: {method}}}
realizations: 1500
seed: 21
output: {tmp_path / method}.h5
""")
        run_config(cfg, progress=False)
        out[method] = {r["edge"]: r for r in records(cfg.output)}
    for edge in ("2->1", "2->3", "5->6"):
        ref = out["finite-difference"][edge]
        for method in ("pathwise", "hybrid", "orbit"):
            r = out[method][edge]
            gap = abs(r["lambda_km"] - ref["lambda_km"])
            assert gap < 4 * np.hypot(r["lambda_km_se"], ref["lambda_km_se"]), (edge, method, r, ref)
    for method in out:
        assert out[method]["1->2"]["lambda_km"] == 0.0
    assert out["pathwise"]["2->1"]["lambda_km"] == pytest.approx(
        -out["pathwise"]["2->3"]["lambda_km"], rel=1e-9
    )


# ---- lambda.method: orbit ------------------------------------------------------------------


def _orbit_job(graph, edges, coupling_kind="normalized", m=400, crossing="grid"):
    return make_job(
        load_config_text(f"""
graph: {graph}
edges: {edges}
betas: []
lambda: {{method: orbit}}
dynamics: {{dt: {DT}, t_max: 100, coupling: {coupling_kind}, crossing: {crossing}}}
realizations: {m}
seed: 5
""")
    )


def test_orbit_of_a_single_link_is_the_central_difference():
    """On lollipop(6, 3) the orbit of 2->1 is {2->1}: the estimate is the plain central difference
    of that link, realization by realization; the orbit of 5->6 is {5->6, 6->5}."""
    from antisync.execution.compute import lambda_values

    job = _orbit_job("{kind: lollipop, nodes: 6, path: 3}", '["2->1", "5->6"]')
    assert job.orbit_sizes.tolist() == [1, 2]
    (a, b), h = (1, 0), 0.01
    plus = coupling.variant_weights(job.omega, job.csr, [(a, b, h)])[0]
    assert np.array_equal(job.orbit_weights[0], plus)
    damaged = job.omega.copy()
    damaged[a, b] *= 1 + h
    minus = coupling.to_csr(coupling.coupling_matrix(damaged), pattern=job.omega > 0).weights
    assert np.array_equal(job.orbit_weights[1], minus)
    values, code, _, base = lambda_values(job, None, 0, 400)
    ref = simulate(5, 0, 400, job.csr.indptr, job.csr.indices, job.csr.weights, np.stack([plus, minus]), **KW)
    ok = (ref.status0 == 0) & (ref.status == 0).all(axis=1)
    assert np.array_equal(code[:, 0] == 0, ok) and ok.mean() > 0.99
    t0, t = ref.steps0[ok] * DT, ref.steps[ok] * DT
    expected = t0 * (1 / t[:, 0] - 1 / t[:, 1]) / (2 * h)
    assert np.allclose(values[ok, 0], expected, rtol=1e-12, atol=0)
    assert np.array_equal(base.steps0, ref.steps0)


def test_orbit_of_an_arc_transitive_graph_closed_forms():
    """K5: every directed link is in one orbit. Normalized coupling: damaging them all leaves W
    unchanged, so Lambda = 0 on every link. Raw coupling: it scales W by 1 - beta, so
    tau(beta) = tau0 / (1 - beta) up to the Euler error and Lambda = -1 / 20 on every link."""
    from antisync.execution.compute import lambda_values

    norm = _orbit_job("{kind: networkx, generator: complete_graph, args: {n: 5}}", '["0->1", "3->2"]')
    assert norm.orbit_sizes.tolist() == [20, 20]
    assert np.allclose(norm.orbit_weights, norm.csr.weights[None, :], rtol=1e-15, atol=0)
    values, code, _, _ = lambda_values(norm, None, 0, 200)
    assert (code == 0).all() and np.abs(values).max() < 1e-9

    raw = _orbit_job(
        "{kind: networkx, generator: complete_graph, args: {n: 5}}",
        '["0->1"]',
        "raw",
        crossing="interpolated",
    )
    values, code, _, _ = lambda_values(raw, None, 0, 200)
    assert (code == 0).all()
    assert values.mean() == pytest.approx(-1 / 20, rel=2e-3)
    assert values.std() < 2e-3


def test_orbit_directions_of_one_node_cancel():
    """Lollipop L = 1, N = 7: from a clique node a away from the bridge, the derivative summed over
    all out-links of a is zero (normalized rows sum to 1), so Lambda(fig. 2 link) =
    -Lambda(a -> bridge) / (N - 3). The two orbit estimates use different damage directions
    and agree realization by realization up to O(dbeta^2)."""
    from antisync.execution.compute import lambda_values

    job = _orbit_job("{kind: lollipop, nodes: 7, path: 1}", '["6->7", "7->2"]', m=300)
    assert job.orbit_sizes.tolist() == [20, 5]
    values, code, _, _ = lambda_values(job, None, 0, 300)
    ok = (code == 0).all(axis=1)
    left, right = values[ok, 0], -values[ok, 1] / 4
    assert np.median(np.abs(left - right)) < 0.02 * np.median(np.abs(left))
    assert abs(left.mean() - right.mean()) < 0.05 * left.std() / np.sqrt(ok.sum())
