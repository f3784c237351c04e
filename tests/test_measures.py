"""Tests of the non-simulation measures: Lambda^(xi2), Lambda^(RW), Lambda^(linear).

Closed forms (complete graph, star, path), a hand-derived Lambda^(xi2) on the path P_4,
exact derivatives against finite differences on random graphs, and two independent routes
(exact solution and Euler) for the linear dynamics.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
import scipy.linalg

from antisync.measures import (
    LinearResult,
    f_rw,
    f_xi2,
    lambda_linear,
    lambda_rw,
    lambda_xi2,
    lambda_xi2_all,
    order_parameter,
    tau_linear_euler,
    tau_linear_exact,
    tau_rw,
    xi2,
)
from antisync.measures import linear as linear_mod
from antisync.physics.coupling import coupling_derivative, coupling_matrix, damaged_omega, laplacian
from antisync.physics.graphs import all_directed_edges, lollipop, omega_matrix

# --- helpers -------------------------------------------------------------------------------


def omega_of(g: nx.Graph) -> np.ndarray:
    return nx.to_numpy_array(g, nodelist=sorted(g), dtype=np.float64)


def directed_edges(omega: np.ndarray) -> list[tuple[int, int]]:
    return [(int(a), int(b)) for a, b in zip(*np.nonzero(omega), strict=True)]


def scaled(omega: np.ndarray, a: int, b: int, factor: float) -> np.ndarray:
    """``Omega`` with ``Omega_ab`` times ``factor = 1 - beta`` (``factor > 1``: beta < 0)."""
    out = omega.copy()
    out[a, b] *= factor
    return out


def random_connected_graphs(n_graphs: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n_graphs:
        n = int(rng.integers(5, 10))
        g = nx.gnp_random_graph(n, float(rng.uniform(0.3, 0.7)), seed=int(rng.integers(2**31)))
        if nx.is_connected(g):
            out.append(omega_of(g))
    return out


def degenerate_graphs() -> list[np.ndarray]:
    cycle_chord = nx.cycle_graph(6)
    cycle_chord.add_edge(0, 3)
    return [
        omega_of(nx.complete_graph(5)),
        omega_of(nx.star_graph(5)),
        omega_of(cycle_chord),
        omega_of(nx.cycle_graph(7)),
        omega_of(nx.complete_bipartite_graph(2, 3)),
        omega_matrix(lollipop(6, 3)),
    ]


def xi2_cluster_size(omega: np.ndarray, coupling: str) -> int:
    ev = np.sort(np.linalg.eigvals(laplacian(omega, coupling)).real)
    return int(np.sum(np.abs(ev[1:] - ev[1]) <= 1e-9 * ev[-1]))


# the 12 directed edges of the paper's lollipop as 0-based (a, b): label k is index k - 1
LOLLIPOP_EDGES = [(u - 1, v - 1) for u, v in all_directed_edges(lollipop(6, 3))]


# --- closed-form spectra ---------------------------------------------------------------------


@pytest.mark.parametrize("n", [3, 5, 8])
def test_complete_graph_spectrum(n):
    omega = omega_of(nx.complete_graph(n))
    # normalized: L = I - (J - I)/(n-1) -> 0 and n/(n-1) (multiplicity n-1)
    ev = np.sort(np.linalg.eigvals(laplacian(omega)).real)
    np.testing.assert_allclose(ev, [0.0] + [n / (n - 1)] * (n - 1), atol=1e-12)
    assert xi2(omega) == pytest.approx(n / (n - 1), rel=1e-12)
    # raw: combinatorial Laplacian nI - J -> 0 and n (multiplicity n-1)
    assert xi2(omega, "raw") == pytest.approx(n, rel=1e-12)


@pytest.mark.parametrize("n", [3, 4, 7])
def test_star_spectrum(n):
    omega = omega_of(nx.star_graph(n - 1))  # n nodes: one hub, n-1 leaves
    ev = np.sort(np.linalg.eigvals(laplacian(omega)).real)
    np.testing.assert_allclose(ev, [0.0] + [1.0] * (n - 2) + [2.0], atol=1e-12)
    assert xi2(omega) == pytest.approx(1.0, rel=1e-12)
    assert xi2(omega, "raw") == pytest.approx(1.0, rel=1e-12)  # raw: 0, 1 (n-2 times), n


@pytest.mark.parametrize("n", [2, 4, 9])
def test_path_spectrum(n):
    omega = omega_of(nx.path_graph(n))
    ev = np.sort(np.linalg.eigvals(laplacian(omega)).real)
    np.testing.assert_allclose(ev, 1 - np.cos(np.pi * np.arange(n) / (n - 1)), atol=1e-12)
    assert xi2(omega) == pytest.approx(1 - np.cos(np.pi / (n - 1)), rel=1e-12)
    assert xi2(omega, "raw") == pytest.approx(2 - 2 * np.cos(np.pi / n), rel=1e-12)


def test_xi2_of_damaged_network_is_real_part():
    omega = omega_matrix(lollipop(6, 3))
    star = damaged_omega(omega, 3, 4, 0.7)
    ev = np.linalg.eigvals(laplacian(star))
    ev = ev[np.argsort(np.abs(ev))][1:]
    assert xi2(star) == pytest.approx(ev.real.min(), rel=1e-12)


# --- random walk -----------------------------------------------------------------------------


@pytest.mark.parametrize("n", [3, 5, 10])
def test_tau_rw_complete_graph(n):
    """K_N: W = (J - I)/(N-1) has lambda_l = -1/(N-1) for l >= 2 and pi_j = 1/N, so Eq. (23)
    gives tau_j = N * (N-1)/N * (1 - 1/N) = (N-1)^2/N: the mean first-passage time N-1 from
    any other node, times the probability (N-1)/N of not starting at j."""
    assert tau_rw(omega_of(nx.complete_graph(n))) == pytest.approx((n - 1) ** 2 / n, rel=1e-12)


def eq23_tau_rw(omega: np.ndarray) -> float | None:
    """Eq. (23) literally: biorthogonal eigenvectors of W, sum over l >= 2.

    ``None`` when W is (numerically) not diagonalizable, where Eq. (23) is undefined.
    """
    w = coupling_matrix(omega, "normalized")
    lam, q = np.linalg.eig(w)
    if np.linalg.cond(q) > 1e8:
        return None
    qinv = np.linalg.inv(q)  # rows: left eigenvectors with <phibar_l|phi_m> = delta_lm
    one = np.argmin(np.abs(lam - 1.0))
    taus = []
    for j in range(len(lam)):
        total = sum(q[j, l] * qinv[l, j] / (1 - lam[l]) for l in range(len(lam)) if l != one)
        taus.append(total / (q[j, one] * qinv[one, j]))
    tau = np.mean(taus)
    assert abs(tau.imag) < 1e-9
    return float(tau.real)


def mfpt_tau_rw(omega: np.ndarray) -> float:
    """tau_j as the mean first-passage time to j from the stationary start, by linear solves:
    m_i = 1 + sum_{k != j} w_ik m_k for i != j, tau_j = sum_{i != j} pi_i m_i."""
    w = coupling_matrix(omega, "normalized")
    n = len(w)
    lam, vecs = np.linalg.eig(w.T)
    pi = vecs[:, np.argmin(np.abs(lam - 1))].real
    pi /= pi.sum()
    taus = []
    for j in range(n):
        rest = [i for i in range(n) if i != j]
        m = np.linalg.solve(np.eye(n - 1) - w[np.ix_(rest, rest)], np.ones(n - 1))
        taus.append(pi[rest] @ m)
    return float(np.mean(taus))


def test_tau_rw_equals_eigenvector_sum_of_eq23():
    graphs = random_connected_graphs(8, seed=11) + [omega_matrix(lollipop(6, 3))]
    rng = np.random.default_rng(12)
    n_complex = n_defective = n_checked = 0
    for omega in graphs:
        assert tau_rw(omega) == pytest.approx(eq23_tau_rw(omega), rel=1e-10)
        assert tau_rw(omega) == pytest.approx(mfpt_tau_rw(omega), rel=1e-10)
        # damaged, non-symmetric W (possibly complex eigenvalues)
        edges = directed_edges(omega)
        for k in rng.choice(len(edges), size=4, replace=False):
            a, b = edges[k]
            star = damaged_omega(omega, a, b, float(rng.uniform(0.2, 0.9)))
            assert not np.allclose(coupling_matrix(star), coupling_matrix(star).T)
            n_complex += bool(np.any(np.abs(np.linalg.eigvals(coupling_matrix(star)).imag) > 1e-8))
            assert tau_rw(star) == pytest.approx(mfpt_tau_rw(star), rel=1e-10)
            reference = eq23_tau_rw(star)
            if reference is None:  # defective W: only the fundamental-matrix form is defined
                n_defective += 1
                continue
            assert tau_rw(star) == pytest.approx(reference, rel=1e-10)
            n_checked += 1
    assert n_checked >= 30 and n_defective <= 3 and n_complex >= 1


def test_rw_disconnected_graph_raises():
    omega = omega_of(nx.disjoint_union(nx.path_graph(3), nx.path_graph(3)))
    with pytest.raises(ValueError, match="disconnected"):
        tau_rw(omega)
    with pytest.raises(ValueError, match="disconnected"):
        lambda_rw(omega, 0, 1)


# --- Lambda = 0 on a leaf's only edge ----------------------------------------------------------


def test_lambda_zero_on_edge_leaving_degree_one_node():
    """Lollipop 1 -> 2 (indices (0, 1)): node 1 has one neighbor; its row of W stays (0, 1, 0..)."""
    omega = omega_matrix(lollipop(6, 3))
    rng = np.random.default_rng(3)
    theta0 = rng.uniform(0, 2 * np.pi, (50, 6))
    assert abs(lambda_xi2(omega, 0, 1)) <= 1e-12
    assert abs(lambda_rw(omega, 0, 1)) <= 1e-12
    assert abs(f_xi2(omega, 0, 1, 0.5) - 1) <= 1e-12
    assert abs(f_rw(omega, 0, 1, 0.5) - 1) <= 1e-12
    for method in ("exact", "euler", "derivative"):
        res = lambda_linear(omega, 0, 1, theta0, method=method)
        assert res.n == 50 and abs(res.lambda_) <= 1e-12, method
    # the same on the path's other end
    path = omega_of(nx.path_graph(5))
    assert abs(lambda_xi2(path, 4, 3)) <= 1e-12 and abs(lambda_rw(path, 4, 3)) <= 1e-12


# --- Lambda^(xi2) on P_4 by hand ---------------------------------------------------------------


def test_lambda_xi2_path4_hand_derivation():
    """P_4 = 0-1-2-3, normalized coupling.

    Spectrum 1 - cos(pi k/3): xi_2 = 1/2. W = D^-1 A has the right eigenvector for W-eigenvalue
    1/2 (L-eigenvalue 1/2) v_j = cos(pi j/3) = (1, 1/2, -1/2, -1) (check: (Wv)_0 = v_1 = 1/2,
    (Wv)_1 = (v_0 + v_2)/2 = 1/4), and the left one u = D v = (1, 1, -1, -1), u^T v = 3.
    At beta = 0, d w_aj/dbeta = 1/k_a^2 for the other neighbors j and -(k_a - 1)/k_a^2 for j = b
    (Eq. 4), and dL = -dW, so dxi_2 = -u_a (dW_a . v) / 3 and Lambda = dxi_2 / (1/2).

    - 0->1 and 3->2: k_a = 1, dW = 0, Lambda = 0.
    - 1->0: dW_1 = (-1/4, 0, 1/4, 0), dW_1 . v = -1/4 - 1/8 = -3/8, Lambda = -2(1)(-3/8)/3 = +1/4.
    - 1->2: dW_1 = (1/4, 0, -1/4, 0), dW_1 . v = 1/4 + 1/8 = 3/8, Lambda = -1/4.
    - 2->3, 2->1: by the mirror symmetry j -> 3 - j, +1/4 and -1/4.
    """
    omega = omega_of(nx.path_graph(4))
    expected = {(0, 1): 0.0, (1, 0): 0.25, (1, 2): -0.25, (2, 1): -0.25, (2, 3): 0.25, (3, 2): 0.0}
    for (a, b), value in expected.items():
        assert lambda_xi2(omega, a, b) == pytest.approx(value, abs=1e-12)
    # confirmation only: a central difference of Eq. (15)
    h = 1e-6
    fd = (xi2(scaled(omega, 1, 0, 1 - h)) - xi2(scaled(omega, 1, 0, 1 + h))) / (2 * h) / 0.5
    assert fd == pytest.approx(0.25, abs=1e-8)


def test_lambda_xi2_all_matches_single_edges():
    omega = omega_matrix(lollipop(6, 3))
    many = lambda_xi2_all(omega, LOLLIPOP_EDGES)
    single = [lambda_xi2(omega, a, b) for a, b in LOLLIPOP_EDGES]
    np.testing.assert_allclose(many, single, rtol=0, atol=1e-15)
    # sign pattern the paper reports for Lambda^(KM) (Fig. 1): 2->1 and 5->6 antifragile,
    # 2->3 and 6->4 fragile; 2->1 the largest, 2->3 the smallest
    i21, i23, i56, i64 = (LOLLIPOP_EDGES.index(e) for e in [(1, 0), (1, 2), (4, 5), (5, 3)])
    assert many[i21] > 0 and many[i56] > 0 and many[i23] < 0 and many[i64] < 0
    assert np.argmax(many) == i21 and np.argmin(many) == i23


# --- exact derivatives against finite differences ------------------------------------------------


def central_difference(f, h):
    """Fourth-order central difference of f at 0 (truncation O(h^4), rounding ~ eps/h)."""
    return (8 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12 * h)


def check_derivatives(omega, coupling, report):
    h = 1e-5
    x0 = xi2(omega, coupling)
    degenerate = xi2_cluster_size(omega, coupling) > 1
    report["degenerate"] += degenerate
    lam_all = lambda_xi2_all(omega, directed_edges(omega), coupling)
    for (a, b), lam in zip(directed_edges(omega), lam_all, strict=True):
        if degenerate:
            # one-sided: the smallest real part has a kink at beta = 0
            fd = (xi2(scaled(omega, a, b, 1 - 1e-6), coupling) / x0 - 1) / 1e-6
            assert lam == pytest.approx(fd, rel=1e-4, abs=1e-4), (a, b)
        else:
            fd = central_difference(
                lambda beta, a=a, b=b: xi2(scaled(omega, a, b, 1 - beta), coupling) / x0, h
            )
            assert lam == pytest.approx(fd, rel=1e-6, abs=1e-9), (a, b)
        report["edges"] += 1
    if coupling == "normalized":
        t0 = tau_rw(omega)
        for a, b in directed_edges(omega):
            fd = central_difference(lambda beta, a=a, b=b: t0 / tau_rw(scaled(omega, a, b, 1 - beta)), h)
            assert lambda_rw(omega, a, b) == pytest.approx(fd, rel=1e-6, abs=1e-9), (a, b)


@pytest.mark.parametrize("coupling", ["normalized", "raw"])
def test_exact_derivatives_match_finite_differences(coupling):
    report = {"degenerate": 0, "edges": 0}
    for omega in random_connected_graphs(50, seed=2024) + degenerate_graphs():
        check_derivatives(omega, coupling, report)
    assert report["degenerate"] >= 4  # K_5, star, cycle + chord, C_7, K_{2,3} at least
    assert report["edges"] > 1000


def test_degenerate_xi2_one_sided_derivative_is_min_of_split():
    """K_5: xi_2 = 5/4 is 4-fold. Damaging a->b keeps 2 eigenvalues at 5/4 exactly (vectors with
    v_a = v_b = 0, sum 0) and moves the rest, so Lambda = min(0, ...) must be <= 0."""
    omega = omega_of(nx.complete_graph(5))
    lam = lambda_xi2(omega, 0, 1)
    assert lam <= 0
    h = 1e-7
    assert lam == pytest.approx((f_xi2(omega, 0, 1, h) - 1) / h, abs=1e-5)


# --- linear dynamics -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def lollipop_phases():
    rng = np.random.default_rng(20240601)
    return omega_matrix(lollipop(6, 3)), rng.uniform(0, 2 * np.pi, (300, 6))


def naive_tau(omega, theta0, threshold, coupling, dt_grid, t_max):
    """Slow reference: exp(-dt L) repeatedly on a fine grid; the index of the first r >= thr."""
    prop = scipy.linalg.expm(-dt_grid * laplacian(omega, coupling))
    theta = theta0.copy()
    k_first = np.full(theta0.shape[0], -1)
    for k in range(int(t_max / dt_grid) + 1):
        hit = (order_parameter(theta) >= threshold) & (k_first < 0)
        k_first[hit] = k
        if np.all(k_first >= 0):
            break
        theta = theta @ prop.T
    return k_first


@pytest.mark.parametrize(
    "coupling, damage",
    [
        ("normalized", None),
        ("normalized", (3, 4, 0.6)),  # 4->5: eigenvalue 3/2 becomes a Jordan block (Taylor route)
        ("normalized", (1, 0, 0.6)),  # 2->1: diagonalizable, eigendecomposition route
        ("raw", (1, 2, 0.5)),
    ],
)
def test_tau_linear_exact_against_fine_grid(lollipop_phases, coupling, damage):
    omega, theta0 = lollipop_phases
    if damage is not None:
        omega = damaged_omega(omega, *damage)
    theta0 = theta0[:40]
    dt_grid = 2e-3
    tau = tau_linear_exact(omega, theta0, 0.99, coupling)
    k = naive_tau(omega, theta0, 0.99, coupling, dt_grid, 60.0)
    assert np.all(k > 0)
    # the crossing lies in ((k-1) dt, k dt]
    assert np.all(tau > (k - 1) * dt_grid - 1e-9) and np.all(tau <= k * dt_grid + 1e-9)


def test_tau_linear_exact_finds_first_crossing_of_nonmonotone_r():
    """Phases near 0 and near 2 pi are nearly synchronized mod 2 pi, but the unwrapped linear
    dynamics pulls them apart first: r rises above the threshold briefly, drops, rises again.
    A grid of spacing 3 must still return the first crossing (the curvature-bound bisection)."""
    omega = omega_matrix(lollipop(6, 3))
    rng = np.random.default_rng(7)
    theta0 = rng.normal(0, 0.15, (400, 6)) + 2 * np.pi * rng.integers(0, 2, (400, 6))
    fine = tau_linear_exact(omega, theta0, 0.99)
    coarse = tau_linear_exact(omega, theta0, 0.99, grid_dt=3.0)
    np.testing.assert_allclose(coarse, fine, rtol=1e-9, atol=1e-12)
    # the test means something: some realizations drop below the threshold after crossing
    props = scipy.linalg.expm(-np.multiply.outer(np.linspace(0.05, 20, 40), laplacian(omega)))
    ok = np.isfinite(fine) & (fine > 0)
    dips = 0
    for t, th in zip(fine[ok], theta0[ok], strict=True):
        at_tau = scipy.linalg.expm(-t * laplacian(omega)) @ th
        dips += order_parameter(props @ at_tau).min() < 0.99
    assert ok.sum() > 100 and dips >= 10
    assert np.sum(fine == 0.0) > 0  # and some start above the threshold: tau = 0


def test_flow_routes_agree_with_scipy_expm(lollipop_phases, monkeypatch):
    omega, theta0 = lollipop_phases
    defective = laplacian(damaged_omega(omega, 3, 4, 0.6))
    assert np.linalg.cond(np.linalg.eig(defective)[1]) > 1e8  # really the Taylor route
    star = damaged_omega(omega, 4, 5, 0.5)  # non-symmetric but diagonalizable
    for lap in (defective, laplacian(star)):
        flow = linear_mod._Flow(lap, symmetric=False, coupling="normalized", omega=None)
        for s in (0.003, 0.05, 0.7, 4.0):
            np.testing.assert_allclose(
                flow.advance(theta0[0], s), scipy.linalg.expm(-s * lap) @ theta0[0], rtol=1e-12
            )
        np.testing.assert_allclose(
            flow.stack(0.05, 40)[-1], scipy.linalg.expm(-2.0 * lap), rtol=1e-11, atol=1e-14
        )
    tau_eig = tau_linear_exact(star, theta0[:30])
    monkeypatch.setattr(linear_mod, "_MAX_EIG_COND", 0.0)  # force the Taylor route
    tau_taylor = tau_linear_exact(star, theta0[:30])
    np.testing.assert_allclose(tau_taylor, tau_eig, rtol=1e-9)


def test_modal_sensitivity_matches_expm_frechet(lollipop_phases):
    """dtheta/dbeta by Daleckii-Krein (vectorized) against scipy.linalg.expm_frechet."""
    omega, theta0 = lollipop_phases
    t = np.linspace(0.5, 30, 20)
    for coupling in ("normalized", "raw"):
        lap = laplacian(omega, coupling)
        for a, b in [(1, 0), (3, 4), (4, 5)]:
            dw = coupling_derivative(omega, a, b, coupling)
            dlap = np.diag(dw.sum(axis=1)) - dw
            args = (omega, lap, dlap, theta0[:20], t, coupling)
            modal = linear_mod._sensitivity(*args, route="modal")
            frechet = linear_mod._sensitivity(*args, route="frechet")
            for x, y in zip(modal, frechet, strict=True):
                np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-11)


def test_tau_linear_not_reached_by_t_max(lollipop_phases):
    omega, theta0 = lollipop_phases
    tau = tau_linear_exact(omega, theta0[:20], t_max=3.0)
    full = tau_linear_exact(omega, theta0[:20])
    np.testing.assert_array_equal(np.isinf(tau), full > 3.0)
    np.testing.assert_allclose(tau[full <= 3.0], full[full <= 3.0], rtol=1e-12)
    euler = tau_linear_euler(omega, theta0[:20], t_max=3.0)
    assert np.all(np.isinf(euler[full > 3.0 + 0.01]))


def test_tau_linear_exact_vs_euler(lollipop_phases):
    """Euler solves dtheta/dt = -L_eff theta with L_eff = -log(I - dt L)/dt = L + dt L^2/2 + ...,
    i.e. each mode xi decays as if time ran faster by 1 + dt xi/2 <= 1 + dt xi_N/2; reporting the
    first grid step adds at most dt. So -dt xi_N tau/2 - O(dt^2) <= tau_E - tau <= dt (+ the
    same rescaling, which only makes Euler earlier); assert |diff| <= dt (1 + xi_N tau/2)."""
    omega, theta0 = lollipop_phases
    dt = 1e-3
    tau = tau_linear_exact(omega, theta0)
    tau_e = tau_linear_euler(omega, theta0, 0.99, "normalized", dt)
    xi_n = np.max(np.linalg.eigvals(laplacian(omega)).real)
    diff = tau_e - tau
    assert np.all(np.isfinite(tau)) and np.all(np.isfinite(tau_e))
    assert np.all(np.abs(diff) <= dt * (1 + xi_n * tau / 2) + 1e-9)
    assert np.mean(np.abs(diff)) < 2 * dt
    # Lambda^(linear) from both routes with common phases
    for a, b in [(1, 0), (1, 2), (4, 5)]:
        ex = lambda_linear(omega, a, b, theta0, method="exact")
        eu = lambda_linear(omega, a, b, theta0, method="euler", dt=dt)
        assert ex.n == eu.n == 300
        assert abs(ex.lambda_ - eu.lambda_) <= 3 * np.hypot(ex.se, eu.se)


def test_lambda_linear_finite_difference_converges_to_derivative(lollipop_phases):
    omega, theta0 = lollipop_phases
    theta0 = theta0[:100]
    deriv = lambda_linear(omega, 1, 0, theta0, method="derivative")
    errors = [
        abs(lambda_linear(omega, 1, 0, theta0, dbeta=d).lambda_ - deriv.lambda_) for d in (1e-2, 1e-3, 1e-4)
    ]
    assert errors[1] < errors[0] / 5 and errors[2] < errors[1] / 5
    assert errors[2] < 1e-4 * max(1.0, abs(deriv.lambda_))
    assert deriv.lambda_ > 0.1  # 2->1 is antifragile in the linear model too


def test_linear_result_counts_excluded(lollipop_phases):
    omega, theta0 = lollipop_phases
    synced = np.zeros((5, 6))  # r(0) = 1: already synchronized
    res = lambda_linear(omega, 1, 0, np.vstack([theta0[:20], synced]), t_max=1e3)
    assert (res.n, res.n_excluded, res.n_already_synced) == (20, 5, 5)
    assert np.isfinite(res.lambda_) and res.se > 0
    short = lambda_linear(omega, 1, 0, theta0[:20], t_max=0.5)
    assert short.n == 0 and short.n_excluded == 20 and np.isnan(short.lambda_)
    with pytest.raises(ValueError, match="n_already_synced"):
        LinearResult(0.0, 0.0, 3, 1, 2)


# --- bad input -----------------------------------------------------------------------------------


def test_bad_input_messages():
    omega = omega_matrix(lollipop(6, 3))
    theta0 = np.zeros((2, 6))
    for call in (
        lambda: xi2(omega, "normalised"),
        lambda: lambda_xi2(omega, 1, 0, "normalised"),
        lambda: f_xi2(omega, 1, 0, 0.1, "normalised"),
        lambda: tau_linear_exact(omega, theta0, coupling="normalised"),
        lambda: tau_linear_euler(omega, theta0, coupling="normalised"),
        lambda: lambda_linear(omega, 1, 0, theta0, coupling="normalised"),
    ):
        with pytest.raises(ValueError, match=r"coupling must be one of .*'normalised'"):
            call()
    with pytest.raises(ValueError, match="method must be one of"):
        lambda_linear(omega, 1, 0, theta0, method="rk4")
    with pytest.raises(ValueError, match="no link 0->3"):
        lambda_xi2(omega, 0, 3)
    with pytest.raises(ValueError, match="symmetric"):
        lambda_xi2(damaged_omega(omega, 1, 0, 0.5), 1, 2)
    with pytest.raises(ValueError, match="disconnected"):
        xi2(omega_of(nx.disjoint_union(nx.path_graph(2), nx.path_graph(3))))
    with pytest.raises(ValueError, match=r"theta0 must have shape \(M, 6\)"):
        tau_linear_exact(omega, np.zeros((3, 5)))


def test_lambda_rw_all_equals_link_by_link():
    """One factorization for every link (O(deg N) per link) gives lambda_rw's values."""
    import networkx as nx

    from antisync.measures.randomwalk import lambda_rw_all

    rng = np.random.default_rng(5)
    for seed in range(6):
        g = nx.connected_watts_strogatz_graph(14, 4, 0.3, seed=seed)
        for u, v in g.edges:
            g[u][v]["weight"] = 0.5 + rng.random()
        omega = nx.to_numpy_array(g, nodelist=sorted(g))
        edges = [(u, v) for u, v in g.edges] + [(v, u) for u, v in g.edges]
        one = np.array([lambda_rw(omega, a, b) for a, b in edges])
        np.testing.assert_allclose(lambda_rw_all(omega, edges), one, rtol=1e-10, atol=1e-14)


def test_measures_of_a_1000_node_graph_fit_in_memory():
    """Every link of a 1000-node graph: no N x N matrix per link (that took 32 GB)."""
    import networkx as nx

    import antisync

    g = nx.barabasi_albert_graph(1000, 2, seed=1)
    rows = antisync.measures.for_graph(g)
    assert len(rows) == 2 * g.number_of_edges() == 3992
    assert all(np.isfinite(r["lambda_xi2"]) and np.isfinite(r["lambda_rw"]) for r in rows)
