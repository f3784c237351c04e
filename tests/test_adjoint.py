"""lambda.method adjoint: one reverse-mode pass gives d tau0 / d beta of every link.

Checked against the forward tangents of ``pathwise`` (Euler: the same derivative of the same
discrete trajectory, so equal to rounding), against central finite differences of the
Hermite-interpolated crossing (RK4, where no pathwise exists), through ``antisync.run``, and for
independence of the checkpoint interval (bit for bit).
"""

from dataclasses import replace

import networkx as nx
import numpy as np
import pytest

import antisync
from antisync.errors import ConfigError
from antisync.execution.compute import check_backend, host_part
from antisync.kernels.adjoint import link_derivatives, simulate_adjoint
from antisync.kernels.cpu import simulate, simulate_pathwise
from antisync.physics import coupling, graphs
from antisync.plan.config import load_config_text
from antisync.status import SYNCED

EULER = dict(dt=0.002, threshold=0.99, max_steps=50_000)
RK4 = dict(dt=0.04, threshold=0.99, max_steps=5_000)


def _random_omega():
    """A connected 10-node graph with 22 links and weights in [0.5, 2]."""
    g = nx.gnm_random_graph(10, 22, seed=4)
    assert nx.is_connected(g)
    rng = np.random.default_rng(4)
    omega = np.zeros((10, 10))
    for i, j in g.edges:
        omega[i, j] = omega[j, i] = rng.uniform(0.5, 2.0)
    return omega


GRAPHS = {
    "lollipop": lambda: graphs.omega_matrix(graphs.lollipop(6, 3)),
    "random": _random_omega,
}


def _network(name, kind):
    omega = GRAPHS[name]()
    csr = coupling.to_csr(coupling.coupling_matrix(omega, kind), pattern=omega > 0)
    edges = [(int(a), int(b)) for a, b in zip(*np.nonzero(omega), strict=True)]  # every link
    return omega, csr, edges


@pytest.mark.parametrize("kind", ["normalized", "raw"])
@pytest.mark.parametrize("name", ["lollipop", "random"])
def test_adjoint_equals_pathwise_for_every_link(name, kind):
    omega, csr, edges = _network(name, kind)
    a, b, rho, mu = coupling.tangent_coefficients(omega, edges, kind)
    m = 24
    pw = simulate_pathwise(11, 0, m, csr.indptr, csr.indices, csr.weights, a, b, rho, mu, **EULER)
    deriv = link_derivatives(omega, csr, edges, kind)
    ad = simulate_adjoint(11, 0, m, csr.indptr, csr.indices, csr.weights, deriv, **EULER)
    # the forward pass is the same step function: the same trajectory, bit for bit
    assert np.array_equal(ad.status0, pw.status0) and np.array_equal(ad.steps0, pw.steps0)
    assert np.array_equal(ad.frac0, pw.frac0)
    assert (ad.status0 == SYNCED).sum() >= m - 1
    # per-realization Lambda = -tau0'/tau0, as compute.lambda_values forms it
    tau0 = (pw.steps0 - 1 + pw.frac0) * EULER["dt"]
    ok = pw.status0 == SYNCED
    lam_pw = -pw.dtau[ok] / tau0[ok, None]
    lam_ad = -ad.dtau[ok] / tau0[ok, None]
    scale = np.abs(lam_pw).max()
    assert scale > 0.1
    np.testing.assert_allclose(lam_ad, lam_pw, rtol=1e-9, atol=1e-12 * scale)
    assert np.all(ad.dtau[~ok] == 0.0)


def _minus(omega, csr, edges, kind, h):
    """CSR weights with each link reinforced by ``h`` (beta = -h), one row per link."""
    out = []
    for i, j in edges:
        o = omega.copy()
        o[i, j] *= 1.0 + h
        out.append(coupling.to_csr(coupling.coupling_matrix(o, kind), pattern=omega > 0).weights)
    return np.array(out)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
@pytest.mark.parametrize("name", ["lollipop", "random"])
def test_rk4_adjoint_matches_central_differences_of_the_hermite_crossing(name, kind):
    omega, csr, edges = _network(name, kind)
    m = 16
    deriv = link_derivatives(omega, csr, edges, kind)
    ad = simulate_adjoint(3, 0, m, csr.indptr, csr.indices, csr.weights, deriv, integrator="rk4", **RK4)
    h = 1e-6
    plus = coupling.variant_weights(omega, csr, [(i, j, h) for i, j in edges], kind)
    args = (3, 0, m, csr.indptr, csr.indices, csr.weights)
    fp = simulate(*args, plus, integrator="rk4", **RK4)
    fm = simulate(*args, _minus(omega, csr, edges, kind, h), integrator="rk4", **RK4)
    # the forward pass is the lane driver's RK4 step: the same tau0, bit for bit
    assert np.array_equal(ad.steps0, fp.steps0) and np.array_equal(ad.frac0, fp.frac0)
    tau = lambda sim: (sim.steps - 1 + sim.frac) * RK4["dt"]  # noqa: E731
    numeric = (tau(fp) - tau(fm)) / (2 * h)
    # a derivative, not a jump: both neighbours cross in the same step as tau0
    k0 = ad.steps0[:, None]
    same = (ad.status0[:, None] == SYNCED) & (fp.steps == k0) & (fm.steps == k0)
    assert same.mean() > 0.9
    err = np.abs(numeric - ad.dtau)[same] / (np.abs(ad.dtau[same]) + 1e-3)
    assert np.median(err) < 1e-7 and err.max() < 1e-5, (np.median(err), err.max())


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_checkpoint_interval_changes_nothing(integrator):
    """Segments are recomputed by the forward step itself: any K gives the same bits."""
    omega, csr, edges = _network("random", "normalized")
    deriv = link_derivatives(omega, csr, edges, "normalized")
    kw = EULER if integrator == "euler" else RK4
    runs = [
        simulate_adjoint(
            5,
            0,
            8,
            csr.indptr,
            csr.indices,
            csr.weights,
            deriv,
            integrator=integrator,
            checkpoint_every=k,
            **kw,
        )
        for k in (1, 7, 256, 100_000)
    ]
    for other in runs[1:]:
        assert np.array_equal(other.dtau, runs[0].dtau)
        assert np.array_equal(other.frac0, runs[0].frac0)
    with pytest.raises(ValueError, match="checkpoint_every"):
        simulate_adjoint(5, 0, 1, csr.indptr, csr.indices, csr.weights, deriv, checkpoint_every=0, **kw)


def test_a_grown_checkpoint_store_keeps_every_checkpoint():
    """The adjoints' checkpoint stores double by an element loop (shared.doubled): the first
    half is the old store bit for bit, at the ranks of the one-trajectory and the lanes' stores."""
    from numba import njit

    from antisync.kernels.shared import copy_into, doubled

    copy = njit(lambda dst, src: copy_into(dst, src))
    rng = np.random.default_rng(0)
    for shape in [(3, 2, 4), (3, 2, 4, 5)]:
        ck = rng.random(shape)
        big = doubled(ck)
        assert big.shape == (6, *shape[1:]) and np.array_equal(big[:3], ck)
        copy(big[4], ck[1])  # C-contiguous: as flat vectors
        assert np.array_equal(big[4], ck[1])
        copy(big[5, :, 1:], ck[2, :, :-1])  # strided: index by index
        assert np.array_equal(big[5, :, 1:], ck[2, :, :-1])
        # a shape mismatch raises, never copies out of bounds (both layouts, and in Python)
        mismatched = [(big[4], ck[1, :1]), (big[5, :, 1:], ck[2, :, :-2]), (big[4].copy(), ck[1].T.copy())]
        for dst, src in mismatched:
            with pytest.raises(ValueError, match="differ in shape"):
                copy(dst, src)
            with pytest.raises(ValueError, match="differ in shape"):
                copy_into(dst, src)


def test_link_derivatives_are_the_coupling_derivative_rows():
    omega, csr, edges = _network("random", "normalized")
    deriv = link_derivatives(omega, csr, edges, "normalized")
    rows = np.repeat(np.arange(csr.n_nodes), np.diff(csr.indptr))
    for e, (a, b) in enumerate(edges):
        dense = np.zeros(omega.shape)
        q = slice(deriv.indptr[e], deriv.indptr[e + 1])
        dense[rows[deriv.position[q]], csr.indices[deriv.position[q]]] = deriv.value[q]
        assert np.array_equal(dense, coupling.coupling_derivative(omega, a, b, "normalized"))


def _lollipop(method, tmp_path, realizations=300):
    return antisync.run(
        {
            "graph": {"kind": "lollipop", "nodes": 6, "path": 3},
            "edges": "all",
            "betas": [],
            "lambda": {"method": method, "hybrid_cut": 1.0},
            "dynamics": {"dt": 0.002, "t_max": 100},
            "seed": 13,
        },
        realizations=realizations,
        output=tmp_path / f"{method}.h5",
    )


def test_run_adjoint_equals_pathwise(tmp_path):
    res = {m: _lollipop(m, tmp_path) for m in ("pathwise", "adjoint", "hybrid", "adjoint-hybrid")}
    for ref, new in (("pathwise", "adjoint"), ("hybrid", "adjoint-hybrid")):
        assert len(res[new].records) == len(res[ref].records) == 12
        for r_ref, r_new in zip(res[ref].records, res[new].records, strict=True):
            assert r_new["edge"] == r_ref["edge"]
            assert r_new["lambda_km"] == pytest.approx(r_ref["lambda_km"], rel=1e-9, abs=1e-12)
            assert r_new["lambda_km_se"] == pytest.approx(r_ref["lambda_km_se"], rel=1e-9, abs=1e-12)
            assert r_new["lambda_n_flagged"] == r_ref["lambda_n_flagged"]
            assert (r_new["lambda_n"], r_new["n_excluded"]) == (r_ref["lambda_n"], r_ref["n_excluded"])
    assert sum(r["lambda_n_flagged"] for r in res["adjoint-hybrid"].records) > 0
    assert all(r["lambda_n_flagged"] == 0 for r in res["adjoint"].records)


def test_adjoint_runs_rk4_on_the_cpu_and_euler_beside_the_gpu(tmp_path):
    text = """
graph: {kind: lollipop, nodes: 6, path: 3}
lambda: {method: adjoint}
dynamics: {integrator: rk4, dt: 0.04}
"""
    cfg = load_config_text(text)
    check_backend(cfg, "cpu")
    with pytest.raises(ConfigError, match="dynamics.integrator rk4 runs on the cpu backend only"):
        check_backend(cfg, "cuda")
    euler = load_config_text(text.replace("integrator: rk4, dt: 0.04", "integrator: euler"))
    check_backend(euler, "cuda")
    assert host_part(euler, "cuda") == "lambda.method adjoint runs its Lambda pass on the CPU"
    with pytest.raises(ConfigError, match="needs dynamics.integrator euler"):
        load_config_text(text.replace("method: adjoint", "method: pathwise"))


def test_adjoint_hybrid_secants_in_one_call_are_the_single_secants():
    """The flagged pairs, scattered over realizations and links, run in one call that
    integrates only them (the lane driver's ``todo``); each must be the secant of that
    (realization, link) pair on its own."""
    from antisync.execution.compute import lambda_values
    from antisync.plan.jobs import make_job

    job = make_job(
        load_config_text("""
graph: {kind: networkx, generator: gnm_random_graph, args: {n: 10, m: 22, seed: 4}}
betas: []
lambda: {method: adjoint-hybrid, hybrid_cut: 0.1}
dynamics: {dt: 0.002, t_max: 100}
realizations: 12
seed: 2
""")
    )
    values, code, flagged, base = lambda_values(job, None, 0, 12)
    # scattered: far from the full (flagged realizations) x (flagged links) block
    assert flagged.sum() < flagged.any(axis=0).sum() * flagged.any(axis=1).sum() / 2
    tau0 = (base.steps0 - 1 + base.frac0) * 0.002
    csr = job.csr
    n_edges = len(job.edges)
    for r, e in zip(*np.nonzero(flagged), strict=True):
        one = simulate(
            2,
            0,
            0,
            csr.indptr,
            csr.indices,
            csr.weights,
            job.secant_weights[[e, n_edges + e]],  # the link at +dbeta and at -dbeta
            realizations=np.array([r]),
            dt=0.002,
            threshold=0.99,
            max_steps=job.config.dynamics.max_steps,
        )
        assert (one.status[0] == SYNCED).all() and code[r, e] == SYNCED
        plus, minus = (one.steps[0] - 1 + one.frac[0]) * 0.002
        assert values[r, e] == tau0[r] * (1.0 / plus - 1.0 / minus) / (2 * 0.01)
    plain = replace(job.config, lambda_=replace(job.config.lambda_, method="adjoint"))
    adjoint, _, _, _ = lambda_values(make_job(plain), None, 0, 12)
    assert np.array_equal(values[~flagged], adjoint[~flagged])
