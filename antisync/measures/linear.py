"""The linearized Kuramoto dynamics and Lambda^(linear): Eqs. (7)-(14) of the paper.

The phases follow ``dtheta/dt = -L theta`` (Eq. 9) with ``L = diag(W 1) - W`` (Eq. 8 for
normalized coupling), starting from raw phases ``theta0`` in ``[0, 2 pi)`` that are never
wrapped. ``tau^(linear)`` is the first time the order parameter ``r(t) = |mean_j exp(i
theta_j)|`` (Eq. 3) reaches the threshold; ``F^(linear)_beta = tau_0 / tau(beta)`` (Eq. 13)
and ``Lambda^(linear)`` is the derivative of its mean at ``beta = 0`` (Eq. 14).

Two independent routes give ``tau``: :func:`tau_linear_exact` uses the exact solution
``theta(t) = exp(-t L) theta0`` (Eqs. 10-12) and root finding, :func:`tau_linear_euler` the
explicit Euler scheme with the discrete convention of the Kuramoto kernels.

A fact used throughout: ``-L`` has non-negative off-diagonal entries and zero row sums, so
``max_i theta_i(t)`` never increases and ``min_i theta_i(t)`` never decreases (maximum
principle). ``dtheta/dt`` and ``d2theta/dt2`` solve the same equation, so ``max_i |dtheta_i/dt|``
and ``max_i |d2theta_i/dt2|`` never increase either. These give the bounds on ``dr/dt`` and
``d2r/dt2`` that make the crossing search of :func:`tau_linear_exact` rigorous.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg
from numba import njit
from scipy.optimize import brentq

from antisync.measures._validate import as_omega, check_coupling, check_edge
from antisync.physics.coupling import Coupling, coupling_derivative, damaged_omega, laplacian

__all__ = [
    "LinearResult",
    "lambda_linear",
    "order_parameter",
    "tau_linear_euler",
    "tau_linear_exact",
]

LinearMethod = Literal["exact", "euler", "derivative"]
LINEAR_METHODS: tuple[str, ...] = ("exact", "euler", "derivative")

# Grid intervals are searched recursively until they are this short (then declared crossing-free:
# an excursion above the threshold shorter than this is below any meaningful resolution).
_MIN_INTERVAL = 1e-10
# Above this condition number of the eigenvector matrix, exp(-tL) comes from scipy's expm.
_MAX_EIG_COND = 1e8
_BLOCK = 128
# Taylor steps of exp(-sL) (the expm route inside a grid interval) satisfy ||s L||_inf <= 0.1;
# 15 terms then leave a remainder below 0.1^16 / 16! ~ 5e-30.
_TAYLOR_NORM = 0.1
_TAYLOR_TERMS = 15


@dataclass(frozen=True)
class LinearResult:
    """``Lambda^(linear)`` estimated over realizations of the initial phases (Eq. 14).

    Attributes
    ----------
    lambda_ : float
        Mean over the ``n`` used realizations (``nan`` when ``n == 0``).
    se : float
        Standard error of that mean (``nan`` when ``n < 2``).
    n : int
        Realizations used: both ``tau_0`` and ``tau(beta)`` finite and positive.
    n_excluded : int
        Realizations left out: already synchronized at ``t = 0`` (``r(0) >= r``), not
        synchronized by ``t_max`` in one of the two processes, or (``method="derivative"``)
        a crossing with ``dr/dt = 0`` where ``tau`` is not differentiable.
    n_already_synced : int
        The part of ``n_excluded`` with ``r(0) >= r``.
    """

    lambda_: float
    se: float
    n: int
    n_excluded: int
    n_already_synced: int = 0

    def __post_init__(self):
        if self.n < 0 or self.n_excluded < 0 or not 0 <= self.n_already_synced <= self.n_excluded:
            raise ValueError(
                "LinearResult needs n >= 0 and 0 <= n_already_synced <= n_excluded, got "
                f"n={self.n}, n_excluded={self.n_excluded}, "
                f"n_already_synced={self.n_already_synced}"
            )


def order_parameter(theta: np.ndarray) -> np.ndarray:
    """Kuramoto order parameter ``r = |mean_j exp(i theta_j)|`` over the last axis, Eq. (3)."""
    theta = np.asarray(theta, dtype=np.float64)
    return np.hypot(np.cos(theta).mean(axis=-1), np.sin(theta).mean(axis=-1))


def tau_linear_exact(
    omega: np.ndarray,
    theta0: np.ndarray,
    threshold: float = 0.99,
    coupling: Coupling = "normalized",
    t_max: float = 200.0,
    *,
    grid_dt: float | None = None,
) -> np.ndarray:
    """Synchronization times of the linear dynamics from its exact solution, Eqs. (9)-(12).

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of a connected network (may be a damaged, asymmetric ``Omega*``).
    theta0 : ndarray, shape (M, N) or (N,)
        Initial phases of ``M`` realizations, raw values (not wrapped during the evolution).
    threshold : float
        The synchronization threshold ``r`` of the order parameter, ``0 < r <= 1``.
    coupling : {"normalized", "raw"}
    t_max : float
        Times beyond ``t_max`` count as not synchronized.
    grid_dt : float, optional
        Spacing of the scanning grid; default ``0.1 / max|xi|``. It affects speed only.

    Returns
    -------
    ndarray, shape (M,)
        The first time with ``r(t) >= threshold``; ``0.0`` where ``r(0) >= threshold`` and
        ``inf`` where the threshold is not reached by ``t_max``.

    Notes
    -----
    ``theta(t) = Q exp(-t Xi) Q^-1 theta0`` with the eigendecomposition ``L = Q Xi Q^-1``
    (complex pairs allowed; the phases are its real part), or products of short truncated
    Taylor series of ``exp(-sL)`` when ``Q`` is ill-conditioned (a nearly defective ``L``).
    ``r`` is evaluated on a grid (vectorized over realizations) and the
    first grid interval ``[t_k, t_k + h]`` with ``r(t_k) < r <= r(t_k + h)`` is handed to
    ``brentq``. A crossing and recrossing *inside* an interval cannot be missed: with
    ``A1 = max_i |(L theta(t_k))_i|`` and ``A2 = max_i |(L^2 theta(t_k))_i|``, the maximum
    principle (module docstring) gives ``|dr/dt| <= A1`` and
    ``|d2r/dt2| <= C2 = A2 + A1^2 (1 + 1/r_min)`` on the interval, so
    ``r <= min((r_k + r_{k+1} + A1 h)/2, max(r_k, r_{k+1}) + C2 h^2/8)`` there. Intervals where
    this bound reaches the threshold are bisected (the quadratic margin shrinks 4x per halving)
    until the bound clears or a point above the threshold brackets the crossing; intervals
    shorter than 1e-10 are declared crossing-free.
    """
    check_coupling(coupling)
    omega = as_omega(omega)
    theta0 = _as_theta0(theta0, omega.shape[0])
    _check_threshold(threshold)
    lap = laplacian(omega, coupling)
    flow = _Flow(lap, symmetric=np.array_equal(omega, omega.T), coupling=coupling, omega=omega)
    h = float(grid_dt) if grid_dt is not None else 0.1 / flow.spectral_radius
    return _scan(flow, theta0, threshold, t_max, h)


def tau_linear_euler(
    omega: np.ndarray,
    theta0: np.ndarray,
    threshold: float = 0.99,
    coupling: Coupling = "normalized",
    dt: float = 0.001,
    t_max: float = 200.0,
) -> np.ndarray:
    """Synchronization times of the linear dynamics by explicit Euler: ``theta -= dt L theta``.

    Parameters
    ----------
    omega, theta0, threshold, coupling, t_max
        As in :func:`tau_linear_exact`.
    dt : float
        Time step.

    Returns
    -------
    ndarray, shape (M,)
        ``n dt`` for the first step ``n >= 0`` with ``r >= threshold`` (``r`` is checked at
        ``t = 0`` too, as in the Kuramoto Euler kernels); ``inf`` if no step up to
        ``round(t_max / dt)`` reaches it. The first-order scheme has an ``O(dt)`` error.
    """
    check_coupling(coupling)
    omega = as_omega(omega)
    theta0 = _as_theta0(theta0, omega.shape[0])
    _check_threshold(threshold)
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    out = np.empty(theta0.shape[0])
    _euler_kernel(
        laplacian(omega, coupling), theta0, float(threshold), float(dt), int(round(t_max / dt)), out
    )
    return out


def lambda_linear(
    omega: np.ndarray,
    a: int,
    b: int,
    theta0: np.ndarray,
    threshold: float = 0.99,
    coupling: Coupling = "normalized",
    dbeta: float = 0.01,
    method: LinearMethod = "exact",
    *,
    dt: float = 0.001,
    t_max: float = 200.0,
    tau0: np.ndarray | None = None,
) -> LinearResult:
    """``Lambda^(linear)`` of the directed link ``a -> b``, Eq. (14) of the paper.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of the undamaged connected network.
    a, b : int
        0-based indices of the damaged directed link ``a -> b``.
    theta0 : ndarray, shape (M, N)
        Initial phases; the same for ``tau_0`` and ``tau(dbeta)`` of each realization.
    threshold : float
        Synchronization threshold ``r``.
    coupling : {"normalized", "raw"}
    dbeta : float
        Damage of the finite difference ``(<tau_0 / tau(dbeta)> - 1) / dbeta`` (Eq. 14
        evaluated numerically: the paper's Eq. 18, with ``dbeta = 0.01``).
    method : {"exact", "euler", "derivative"}
        ``"exact"``: both times from :func:`tau_linear_exact`; ``"euler"``: both from
        :func:`tau_linear_euler` with step ``dt``; ``"derivative"``: no finite difference but the
        exact per-realization derivative ``-tau'(0) / tau_0`` by implicit differentiation of
        ``r(tau(beta), beta) = threshold`` (``dbeta`` is then unused), see Notes.
    dt : float
        Euler step for ``method="euler"``.
    t_max : float
        As in :func:`tau_linear_exact`.
    tau0 : ndarray, shape (M,), optional
        ``tau_0`` of ``theta0`` on the undamaged ``omega``, computed as this function would
        (:func:`tau_linear_euler` with the same ``dt`` for ``"euler"``, else
        :func:`tau_linear_exact`), so that many edges of one network share it. The result is
        then identical to a call without it.

    Returns
    -------
    LinearResult

    Notes
    -----
    For ``method="derivative"``: ``dtau/dbeta = -(dr/dbeta) / (dr/dt)`` at ``t = tau_0``, with
    ``dtheta/dt = -L theta`` and ``dtheta/dbeta = D exp(-t L)[-t dL] theta0`` the Frechet
    derivative of the matrix exponential, ``dL = dL/dbeta``; ``dr = Re(conj(z) dz) / r`` with
    ``dz = mean_j(i dtheta_j exp(i theta_j))``. For symmetric ``omega`` the Frechet derivative
    is evaluated in the eigenbasis (Daleckii-Krein, vectorized over realizations), otherwise by
    ``scipy.linalg.expm_frechet``. This is the derivative of the mean; the finite difference
    also sees rare jumps of ``tau`` where ``r`` touches the threshold tangentially.
    """
    check_coupling(coupling)
    if method not in LINEAR_METHODS:
        raise ValueError(f"method must be one of {LINEAR_METHODS}, got {method!r}")
    omega = as_omega(omega)
    a, b = check_edge(omega, a, b)
    theta0 = _as_theta0(theta0, omega.shape[0])
    if method != "derivative" and not 0 < dbeta < 1:
        raise ValueError(f"dbeta must satisfy 0 < dbeta < 1, got {dbeta}")

    if tau0 is not None:
        tau0 = np.asarray(tau0, dtype=np.float64)
        if tau0.shape != (theta0.shape[0],):
            raise ValueError(f"tau0 must have shape ({theta0.shape[0]},), got {tau0.shape}")
    elif method == "euler":
        tau0 = tau_linear_euler(omega, theta0, threshold, coupling, dt, t_max)
    else:
        tau0 = tau_linear_exact(omega, theta0, threshold, coupling, t_max)
    already = tau0 == 0.0

    if method == "derivative":
        per_real = _lambda_derivative(omega, a, b, theta0, tau0, coupling)
    else:
        omega_star = damaged_omega(omega, a, b, dbeta)
        if np.array_equal(laplacian(omega_star, coupling), laplacian(omega, coupling)):
            # the damage leaves the coupling unchanged (normalized coupling, the only link of
            # a leaf): the same dynamics, tau(beta) = tau_0 exactly. Without this shortcut the
            # asymmetric Omega* would take another eigen-route and differ by rounding.
            tau_b = tau0
        elif method == "euler":
            tau_b = tau_linear_euler(omega_star, theta0, threshold, coupling, dt, t_max)
        else:
            tau_b = tau_linear_exact(omega_star, theta0, threshold, coupling, t_max)
        ok = np.isfinite(tau0) & np.isfinite(tau_b) & (tau0 > 0) & (tau_b > 0)
        per_real = np.full(tau0.shape, np.nan)
        per_real[ok] = (tau0[ok] / tau_b[ok] - 1.0) / dbeta

    used = per_real[np.isfinite(per_real)]
    n = used.size
    mean = float(used.mean()) if n else float("nan")
    se = float(used.std(ddof=1) / np.sqrt(n)) if n > 1 else float("nan")
    return LinearResult(mean, se, n, tau0.size - n, int(already.sum()))


# --- the exact flow ------------------------------------------------------------------------


class _Flow:
    """``theta -> exp(-s L) theta``: eigendecomposition, or Taylor steps where that is unsafe.

    The eigendecomposition route is Eq. (11), ``exp(-sL) = Q exp(-s Xi) Q^-1``. When ``Q`` is
    ill-conditioned (a nearly defective ``L``, e.g. lollipop(6, 3) damaged on 4->5, whose
    eigenvalue 3/2 becomes a Jordan block), ``exp(-sL)`` is a product of truncated Taylor
    series of steps with ``||step L||_inf <= 0.1`` instead (remainder < 0.1^16/16! per step).
    """

    def __init__(self, lap: np.ndarray, *, symmetric: bool, coupling: str, omega: np.ndarray):
        self.lap = lap
        self.lap2 = lap @ lap
        if symmetric:
            # L = D^-1 Ls D with Ls symmetric: Q = D^-1 X, Q^-1 = X^T D, exactly well-conditioned
            d = np.sqrt(omega.sum(axis=1)) if coupling == "normalized" else np.ones(len(lap))
            xi, x = np.linalg.eigh(d[:, None] * lap / d[None, :])
            self.xi, self.q, self.qinv = xi, x / d[:, None], x.T * d[None, :]
            self.use_eig = True
        else:
            xi, q = np.linalg.eig(lap)
            self.use_eig = np.linalg.cond(q) < _MAX_EIG_COND
            if self.use_eig:
                self.xi, self.q, self.qinv = xi, q, np.linalg.inv(q)
            else:
                self.xi = xi
                self.lap_norm = float(np.abs(lap).sum(axis=1).max())
                powers = np.empty((_TAYLOR_TERMS, *lap.shape))
                powers[0] = np.eye(lap.shape[0])
                for k in range(1, _TAYLOR_TERMS):
                    powers[k] = powers[k - 1] @ lap / k  # L^k / k!
                self.powers = powers.reshape(_TAYLOR_TERMS, -1)
        self.spectral_radius = float(np.max(np.abs(self.xi)))

    def stack(self, h: float, count: int) -> np.ndarray:
        """Propagators ``exp(-k h L)`` for ``k = 1..count``, shape ``(count, N, N)``."""
        if self.use_eig:
            e = np.exp(-np.multiply.outer(h * np.arange(1, count + 1), self.xi))
            return np.einsum("il,tl,lj->tij", self.q, e, self.qinv).real
        out = np.empty((count, *self.lap.shape))
        out[0] = self.propagator(h)
        for k in range(1, count):
            out[k] = out[0] @ out[k - 1]
        return out

    def propagator(self, s: float) -> np.ndarray:
        """``exp(-s L)`` as a product of Taylor steps (the route for an ill-conditioned ``Q``)."""
        n_sub = max(1, int(np.ceil(s * self.lap_norm / _TAYLOR_NORM)))
        step = s / n_sub
        prop = ((-step) ** np.arange(_TAYLOR_TERMS) @ self.powers).reshape(self.lap.shape)
        return np.linalg.matrix_power(prop, n_sub)

    def advance(self, theta: np.ndarray, s: float) -> np.ndarray:
        """``exp(-s L) theta`` for one state ``theta`` of shape ``(N,)``."""
        if self.use_eig:
            return (self.q @ (np.exp(-s * self.xi) * (self.qinv @ theta))).real
        return self.propagator(s) @ theta


def _r1(theta: np.ndarray) -> float:
    """Order parameter of one state, without the overhead of :func:`order_parameter`."""
    return abs(np.exp(1j * theta).sum()) / theta.size


def _upper_bound(r_l, r_r, a1, a2, h):
    """Upper bound of ``r`` on an interval of length ``h`` (see :func:`tau_linear_exact`)."""
    lipschitz = 0.5 * (r_l + r_r + a1 * h)
    r_min = 0.5 * (r_l + r_r - a1 * h)
    with np.errstate(divide="ignore", invalid="ignore"):
        c2 = a2 + a1**2 * (1.0 + 1.0 / r_min)
        quad = np.where(r_min > 0, np.maximum(r_l, r_r) + c2 * h**2 / 8.0, np.inf)
    return np.minimum(lipschitz, quad)


def _scan(flow: _Flow, theta0: np.ndarray, thr: float, t_max: float, h: float) -> np.ndarray:
    r0 = order_parameter(theta0)
    tau = np.full(theta0.shape[0], np.inf)
    tau[r0 >= thr] = 0.0
    active = np.flatnonzero(r0 < thr)
    props = flow.stack(h, _BLOCK)  # (B, N, N)
    theta = theta0[active]
    t_start = 0.0
    while active.size and t_start < t_max:
        block = np.einsum("bij,mj->mbi", props, theta)
        grid = np.concatenate([theta[:, None, :], block], axis=1)  # (m, B+1, N)
        r = order_parameter(grid)
        # einsum, not matmul: a tall-skinny BLAS call would be threaded for no gain
        a1 = np.abs(np.einsum("mbj,ij->mbi", grid, flow.lap)).max(axis=-1)
        a2 = np.abs(np.einsum("mbj,ij->mbi", grid, flow.lap2)).max(axis=-1)
        r_l, r_r = r[:, :-1], r[:, 1:]
        bracket = r_r >= thr
        suspect = ~bracket & (_upper_bound(r_l, r_r, a1[:, :-1], a2[:, :-1], h) >= thr)
        done = np.zeros(active.size, dtype=bool)
        for row in np.flatnonzero((bracket | suspect).any(axis=1)):
            for k in np.flatnonzero(bracket[row] | suspect[row]):
                t_k = t_start + k * h
                if t_k >= t_max:  # not synchronized by t_max: tau stays inf
                    done[row] = True
                    break
                if bracket[row, k]:
                    t_cross = _root(flow, grid[row, k], t_k, 0.0, h, thr)
                else:
                    t_cross = _refine(
                        flow, grid[row, k], r_l[row, k], grid[row, k + 1], r_r[row, k], t_k, h, thr
                    )
                if t_cross is not None:
                    tau[active[row]] = t_cross if t_cross <= t_max else np.inf
                    done[row] = True
                    break
        active, theta = active[~done], block[~done, -1]
        t_start += _BLOCK * h
    return tau


def _root(flow, theta_k, t_k, s_lo, s_hi, thr):
    """``t_k + s`` with ``r(exp(-s L) theta_k) = thr`` for ``s`` in ``[s_lo, s_hi]`` (a bracket)."""

    def f(s):
        return _r1(flow.advance(theta_k, s)) - thr

    return t_k + brentq(f, s_lo, s_hi, xtol=1e-13, rtol=4 * np.finfo(float).eps)


def _refine(flow, th_l, r_l, th_r, r_r, t_k, h, thr):
    """Bisect a suspect interval; the crossing time in it, or ``None`` if there is none."""
    # depth-first, left half first, so the first crossing is found first
    stack = [(0.0, h, th_l, r_l, th_r, r_r)]
    while stack:
        s_l, s_r, th_a, r_a, th_b, r_b = stack.pop()
        s_m = 0.5 * (s_l + s_r)
        th_m = flow.advance(th_a, s_m - s_l)
        r_m = _r1(th_m)
        if r_m >= thr:
            return _root(flow, th_a, t_k + s_l, 0.0, s_m - s_l, thr)
        if s_r - s_l <= 2 * _MIN_INTERVAL:
            continue
        halves = []
        for lo, hi, th_lo, r_lo, r_hi, th_hi in (
            (s_l, s_m, th_a, r_a, r_m, th_m),
            (s_m, s_r, th_m, r_m, r_b, th_b),
        ):
            a1 = np.abs(flow.lap @ th_lo).max()
            a2 = np.abs(flow.lap2 @ th_lo).max()
            if _upper_bound(r_lo, r_hi, a1, a2, hi - lo) >= thr:
                halves.append((lo, hi, th_lo, r_lo, th_hi, r_hi))
        stack.extend(reversed(halves))
    return None


def _lambda_derivative(omega, a, b, theta0, tau0, coupling):
    """Per-realization ``-tau'(0) / tau_0`` (``nan`` where it is not defined)."""
    lap = laplacian(omega, coupling)
    dw = coupling_derivative(omega, a, b, coupling)
    dlap = np.diag(dw.sum(axis=1)) - dw
    out = np.full(tau0.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(tau0) & (tau0 > 0))
    if ok.size == 0:
        return out
    route = "modal" if np.array_equal(omega, omega.T) else "frechet"
    theta, dtheta_db = _sensitivity(omega, lap, dlap, theta0[ok], tau0[ok], coupling, route)
    e = np.exp(1j * theta)
    z = e.mean(axis=1)
    dz_dt = np.mean(1j * (-theta @ lap.T) * e, axis=1)
    dz_db = np.mean(1j * dtheta_db * e, axis=1)
    dr_dt = (np.conj(z) * dz_dt).real  # both times |z|, which cancels in the ratio
    dr_db = (np.conj(z) * dz_db).real
    with np.errstate(divide="ignore", invalid="ignore"):
        # -tau'/tau0 with tau' = -dr_db/dr_dt; a tangential crossing (dr/dt = 0) stays nan
        out[ok] = np.where(dr_dt > 0, dr_db / dr_dt / tau0[ok], np.nan)
    return out


def _sensitivity(omega, lap, dlap, theta0, t, coupling, route="modal"):
    """``theta(t)`` and ``dtheta(t)/dbeta = D exp(-t L)[-t dL] theta0`` for each realization.

    ``route="modal"`` (symmetric ``omega``): Daleckii-Krein, ``Q (G o (Q^-1 dL Q)) Q^-1`` with
    ``G_ij`` the divided difference of ``x -> exp(-t x)`` at ``xi_i, xi_j``, vectorized over
    realizations. ``route="frechet"``: ``scipy.linalg.expm_frechet`` per realization.
    """
    if route == "frechet":
        theta = np.empty_like(theta0)
        dtheta = np.empty_like(theta0)
        for m, (tm, th0) in enumerate(zip(t, theta0, strict=True)):
            expm_tl, frechet = scipy.linalg.expm_frechet(-tm * lap, -tm * dlap)
            theta[m], dtheta[m] = expm_tl @ th0, frechet @ th0
        return theta, dtheta
    d = np.sqrt(omega.sum(axis=1)) if coupling == "normalized" else np.ones(len(lap))
    xi, x = np.linalg.eigh(d[:, None] * lap / d[None, :])
    q, qinv = x / d[:, None], x.T * d[None, :]
    c = theta0 @ qinv.T  # modal coordinates, (M, N)
    decay = np.exp(-np.multiply.outer(t, xi))  # (M, N)
    # G_ij = (e^{-t xi_i} - e^{-t xi_j}) / (xi_i - xi_j) = -t e^{-t xi_j} expm1(y)/y,
    # y = -t (xi_i - xi_j): no cancellation for close eigenvalues, -t e^{-t xi} when equal
    y = -t[:, None, None] * (xi[:, None] - xi[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(y == 0, 1.0, np.expm1(y) / y)
    g = -t[:, None, None] * decay[:, None, :] * ratio
    theta = (decay * c) @ q.T
    dtheta = np.einsum("il,mlk,mk->mi", q, g * (qinv @ dlap @ q), c)
    return theta, dtheta


# --- Euler ---------------------------------------------------------------------------------


@njit(cache=False)
def _euler_kernel(lap, theta0, thr, dt, n_max, out):  # pragma: no cover - compiled
    m_real, n = theta0.shape
    theta = np.empty(n)
    nxt = np.empty(n)
    for m in range(m_real):
        for i in range(n):
            theta[i] = theta0[m, i]
        out[m] = np.inf
        for step in range(n_max + 1):
            c = 0.0
            s = 0.0
            for j in range(n):
                c += np.cos(theta[j])
                s += np.sin(theta[j])
            if np.sqrt(c * c + s * s) / n >= thr:
                out[m] = step * dt
                break
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += lap[i, j] * theta[j]
                nxt[i] = theta[i] - dt * acc
            for i in range(n):
                theta[i] = nxt[i]


# --- input checks --------------------------------------------------------------------------


def _as_theta0(theta0, n: int) -> np.ndarray:
    theta0 = np.asarray(theta0, dtype=np.float64)
    if theta0.ndim == 1:
        theta0 = theta0[None, :]
    if theta0.ndim != 2 or theta0.shape[1] != n:
        raise ValueError(f"theta0 must have shape (M, {n}) for this {n}-node network, got {theta0.shape}")
    if not np.all(np.isfinite(theta0)):
        raise ValueError("theta0 must be finite")
    return np.ascontiguousarray(theta0)


def _check_threshold(threshold: float) -> None:
    if not 0 < threshold <= 1:
        raise ValueError(f"threshold must satisfy 0 < threshold <= 1, got {threshold}")
