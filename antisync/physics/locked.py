"""Phase-locked states of the generalized Kuramoto model, by Newton's method (docs/models.md).

A phase-locked state rotates rigidly, ``theta_i(t) = phi_i + Omega t``. Inserted into
``m theta_i'' + gamma theta_i' = P_i + sum_j w_ij sin(theta_j - theta_i - alpha)`` (first order:
``m = 0, gamma = 1``) it solves, with ``nu = gamma Omega``,

    F_i(phi, nu) = P_i - nu + sum_j w_ij sin(phi_j - phi_i - alpha) = 0,   i = 1..N,

``N`` equations for ``N - 1`` phase differences (``phi_0 = 0`` fixes the rotation) and ``nu``.
The state does not depend on ``m``; its stability does. Newton's method is continued from the
in-phase state of ``P = 0, alpha = 0`` along ``P -> s P, alpha -> s alpha`` for ``s`` from 0 to
1, so the state found is the one connected to ordinary synchrony (other stable states, such
as twisted states of rings, are not looked for).

Stability: the first-order Jacobian ``J_ik = dF_i/dphi_k`` (``w_ik cos(phi_k - phi_i - alpha)``
off the diagonal, minus the row sum on it) must have every eigenvalue but the one zero of the
global rotation in the open left half-plane; for ``m > 0`` the same for the ``2N x 2N`` matrix
``[[0, I], [J/m, -gamma/m I]]``, and with per-node ``m_i`` (some 0) and ``gamma_i`` for
:func:`linearization`'s matrix. Per-node damping weighs the common frequency, ``F_i = P_i - g_i
nu + ...`` with ``g_i = gamma_i / mean gamma`` (:func:`residual`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = [
    "LockedState",
    "jacobian",
    "linearization",
    "locked_state",
    "residual",
    "rightmost",
    "rounding_floor",
    "vouched_bound",
]

#: Newton stops when every |F_i| is below this (the residual of an exact state in float64).
TOL = 1e-13
#: Newton's last test, where its steps end at the floor of rounding above ``TOL``: every ``|F_i|``
#: below ``10 TOL`` or below ``FLOOR_ULPS`` roundings of the largest row sum of ``|w|``, whichever
#: is larger (:func:`rounding_floor`). ``F_i`` carries the rounding of each ``phi_j - phi_i``
#: times ``w_ij``: a line of ``K = 1e5`` (ACTIVSg10k's stiffest) leaves ``|F_i|`` near 1e-11
#: whatever the iteration does, and an absolute ``10 TOL`` reported no locked state there.
FLOOR_ULPS = 10
#: An eigenvalue counts as stable when its real part is below ``-STABLE_MARGIN``.
STABLE_MARGIN = 1e-9
#: From this many nodes on, Newton's steps and the stability margin work on sparse matrices
#: (a grid of thousands of buses: a dense eigenvalue problem of ``N + generators`` takes tens of
#: seconds there, per line of a table); below it, the dense ones (exact, and fast at that size).
SPARSE_FROM = 500
#: The sparse margin: this many eigenvalues nearest a small positive shift (shift-invert
#: Arnoldi, ARPACK), the rightmost of those other than the rotation's zero (:func:`rightmost`).
SPARSE_EIGS = 16


@dataclass(frozen=True)
class LockedState:
    """A phase-locked state: ``phi`` (``phi[0] = 0``), ``nu = gamma Omega``, ``r`` the order
    parameter ``|mean_j exp(i phi_j)|``, ``stable`` and the largest real part of the
    Jacobian's eigenvalues other than the rotation's zero."""

    phi: np.ndarray
    nu: float
    r: float
    stable: bool
    max_real: float


def residual(phi: np.ndarray, nu: float, w: np.ndarray, p: np.ndarray, lag: float, g=1.0) -> np.ndarray:
    """``F_i = P_i - g_i nu + sum_j w_ij sin(phi_j - phi_i - lag)`` (module docstring; ``g_i =
    gamma_i / mean gamma``, 1 for a uniform damping)."""
    d = phi[None, :] - phi[:, None] - lag
    return p - g * nu + (w * np.sin(d)).sum(axis=1)


def jacobian(phi: np.ndarray, w: np.ndarray, lag: float, sparse: bool = False):
    """``dF_i/dphi_k`` of :func:`residual` (the first-order model's Jacobian); a
    ``scipy.sparse`` matrix with ``sparse``."""
    if sparse:
        return _jacobian_sparse(phi, _coo(w), lag)
    g = w * np.cos(phi[None, :] - phi[:, None] - lag)
    return g - np.diag(g.sum(axis=1))


def rounding_floor(row_sums: np.ndarray) -> float:
    """The residual Newton's method accepts after its last step (:data:`FLOOR_ULPS`):
    ``max(10 TOL, FLOOR_ULPS eps max_i sum_j |w_ij|)`` from the row sums of ``|w|``."""
    scale = float(np.max(row_sums)) if row_sums.size else 0.0
    return max(10 * TOL, FLOOR_ULPS * float(np.finfo(np.float64).eps) * scale)


def _newton(phi, nu, f_of, solve, max_iter=50, floor=10 * TOL):
    """Newton's method on the unknowns ``phi_1..phi_{N-1}`` and ``nu`` (``phi_0 = 0``):
    ``f_of(phi, nu)`` is the residual, ``solve(phi, f)`` the step for it through the Jacobian
    with column 0 made ``dF/dnu = -g`` (None where that matrix is singular). Converged: every
    ``|F_i|`` below ``TOL``, or below ``floor`` (:func:`rounding_floor`) after ``max_iter``
    steps."""
    for _ in range(max_iter):
        f = f_of(phi, nu)
        if np.max(np.abs(f)) < TOL:
            return phi, nu, True
        step = solve(phi, f)
        if step is None or not np.isfinite(step).all():
            return phi, nu, False
        phi = phi.copy()
        phi[1:] += step[1:]
        nu = nu + step[0]
        if phi.size and np.max(np.abs(step)) > 1e3:
            return phi, nu, False
    return phi, nu, bool(np.max(np.abs(f_of(phi, nu))) < floor)


def _dense_step(phi, f, w, lag, g):
    a = jacobian(phi, w, lag)
    a[:, 0] = -g
    try:
        return np.linalg.solve(a, -f)
    except np.linalg.LinAlgError:
        return None


def linearization(jac, inertia, damping):
    """The matrix of ``m_i u_i'' + gamma_i u_i' = (jac u)_i`` as a first-order system.

    State: ``u`` of every node, then ``v_i = u_i'`` of the nodes with ``m_i > 0``; a node with
    ``m_i = 0`` is first order, ``u_i' = (jac u)_i / gamma_i``. Without inertia anywhere it is
    ``jac`` (the first-order model, its damping unused). ``inertia`` and ``damping`` are numbers
    or per-node arrays. A ``scipy.sparse`` ``jac`` gives a sparse matrix (CSC).
    """
    n = jac.shape[0]
    m = np.broadcast_to(np.asarray(inertia, dtype=np.float64), (n,))
    gamma = np.broadcast_to(np.asarray(damping, dtype=np.float64), (n,))
    gen = np.flatnonzero(m > 0)
    if not gen.size:
        return jac
    k = gen.size
    if sp.issparse(jac):
        top = sp.diags(np.where(m == 0, 1.0 / gamma, 0.0)) @ jac  # the first-order rows
        pick = sp.csr_matrix((np.ones(k), (gen, np.arange(k))), shape=(n, k))  # u_gen' = v
        lower = sp.diags(1.0 / m[gen]) @ jac[gen]  # v' = (jac u)/m - gamma/m v
        return sp.bmat([[top, pick], [lower, sp.diags(-gamma[gen] / m[gen])]], format="csc")
    big = np.zeros((n + k, n + k))
    load = np.flatnonzero(m == 0)
    big[load, :n] = jac[load] / gamma[load, None]
    big[gen, n + np.arange(k)] = 1.0
    big[n + np.arange(k), :n] = jac[gen] / m[gen, None]
    big[n + np.arange(k), n + np.arange(k)] = -gamma[gen] / m[gen]
    return big


def _max_real(phi, w, lag, inertia, damping) -> float:
    ev = np.linalg.eigvals(linearization(jacobian(phi, w, lag), inertia, damping))
    # drop the rotation's zero eigenvalue (the one closest to 0)
    ev = np.delete(ev, np.argmin(np.abs(ev)))
    return float(np.max(ev.real)) if ev.size else -np.inf


def _coo(w: np.ndarray):
    """Rows, columns and weights of ``w``'s nonzero entries."""
    r, c = np.nonzero(w)
    return r, c, w[r, c]


def _residual_sparse(phi, nu, coo, p, lag, g=1.0):
    r, c, v = coo
    return p - g * nu + np.bincount(r, v * np.sin(phi[c] - phi[r] - lag), minlength=phi.size)


def _jacobian_sparse(phi, coo, lag) -> sp.csr_matrix:
    """:func:`jacobian` as a sparse matrix."""
    r, c, v = coo
    n = phi.size
    g = v * np.cos(phi[c] - phi[r] - lag)
    diag = -np.bincount(r, g, minlength=n)
    at = np.arange(n)
    rows, cols = np.concatenate([r, at]), np.concatenate([c, at])
    return sp.csr_matrix((np.concatenate([g, diag]), (rows, cols)), shape=(n, n))


def _sparse_step(phi, f, coo, lag, g):
    """:func:`_dense_step` with the Jacobian sparse and its LU by SuperLU: the Jacobian's first
    column replaced by ``-g`` (the unknown ``nu`` in place of ``phi_0``), built as such."""
    r, c, v = coo
    n = phi.size
    w = v * np.cos(phi[c] - phi[r] - lag)
    diag = -np.bincount(r, w, minlength=n)
    at = np.arange(1, n)
    keep = c != 0
    rows = np.concatenate([r[keep], at, np.arange(n)])
    cols = np.concatenate([c[keep], at, np.zeros(n, dtype=at.dtype)])
    vals = np.concatenate([w[keep], diag[1:], -np.broadcast_to(g, (n,))])
    a = sp.csc_matrix((vals, (rows, cols)), shape=(n, n))
    try:
        return spla.splu(a).solve(-f)
    except RuntimeError:  # singular
        return None


def rightmost(a, k: int = SPARSE_EIGS, *, missed_below: float | None = None) -> float:
    """The largest real part of the eigenvalues of the square matrix ``a`` other than the
    rotation's zero (the one closest to 0), ``-inf`` for a 1 x 1 matrix.

    Every eigenvalue (dense) below :data:`SPARSE_FROM` rows, or where ``missed_below`` is
    None. Otherwise the ``k`` nearest a small positive shift by shift-invert Arnoldi (ARPACK),
    which the caller vouches for with ``missed_below``: every eigenvalue with a larger real part
    is real and not positive. Then an eigenvalue that was not found is either real and below the
    found ones (it is farther from the shift) or has a real part below ``missed_below``, so the
    found rightmost is exact when it is above ``missed_below``; when it is not, every
    eigenvalue, dense."""
    n = a.shape[0]
    if n >= SPARSE_FROM and missed_below is not None:
        a = sp.csc_matrix(a)
        scale = float(abs(a).sum(axis=1).max()) or 1.0
        start = np.random.default_rng(0).random(n)  # a fixed start vector: reproducible digits
        ev = spla.eigs(
            a, k=min(k, n - 2), sigma=1e-6 * scale, which="LM", return_eigenvectors=False, tol=1e-12, v0=start
        )
        ev = np.delete(ev, np.argmin(np.abs(ev)))
        found = float(np.max(ev.real))
        if found > missed_below:
            return found
    ev = np.linalg.eigvals(a.toarray() if sp.issparse(a) else a)
    ev = np.delete(ev, np.argmin(np.abs(ev)))
    return float(np.max(ev.real)) if ev.size else -np.inf


def vouched_bound(phi: np.ndarray, w: np.ndarray, lag: float, inertia=None, damping=None) -> float | None:
    """What :func:`rightmost` may take as ``missed_below`` for the Jacobian at ``phi`` (no
    ``inertia``) or the linearization with ``inertia`` and ``damping``; None where nothing can be
    vouched for. With no phase lag, ``w`` symmetric and ``cos(phi_j - phi_i) >= 0`` on every
    line, the Jacobian is a negative weighted Laplacian: symmetric, no eigenvalue above 0, all
    real (``-inf``: nothing is missed above any bound). Then an eigenvalue ``lambda`` of the
    linearization, ``lambda^2 m u + lambda D u = J u`` (``m = 0`` at first-order nodes), times
    ``u*``, gives ``lambda^2 a + lambda b + c = 0`` with ``a = sum m |u|^2``, ``b = sum D |u|^2``
    and ``c = -u* J u >= 0``: it is real and not positive, or complex with real part ``-b / 2a
    <= -min(D_i / m_i) / 2`` over the nodes with inertia."""
    if lag != 0.0 or not np.array_equal(w, w.T):
        return None
    r, c = np.nonzero(w)
    if np.any(np.cos(phi[c] - phi[r]) < 0):
        return None
    if inertia is None:
        return -np.inf
    n = phi.size
    m = np.broadcast_to(np.asarray(inertia, dtype=np.float64), (n,))
    gamma = np.broadcast_to(np.asarray(damping, dtype=np.float64), (n,))
    gen = m > 0
    return -float(np.min(gamma[gen] / m[gen])) / 2 if gen.any() else -np.inf


def locked_state(
    w: np.ndarray, p: np.ndarray, lag: float = 0.0, inertia=0.0, damping=1.0
) -> LockedState | None:
    """The phase-locked state connected to synchrony (module docstring), or ``None`` when the
    continuation from ``s = 0`` fails to reach ``s = 1`` (no locked state on that branch:
    typically frequencies too spread for the coupling).

    Parameters
    ----------
    w : ndarray (N, N)
        Coupling matrix ``W`` (rows: the receiving node, as in Eq. 2).
    p : ndarray (N,)
        Natural frequencies (mean removed or not: it only shifts ``nu``).
    lag : float
        ``alpha``.
    inertia, damping : float or ndarray (N,)
        ``m`` and ``gamma``, one value or per node (:func:`linearization`). A locked state
        rotates at one frequency ``nu``, so ``gamma_i nu = P_i + coupling_i``: with a uniform
        ``gamma`` the phases are those of the first-order model; per-node ``gamma_i`` weighs
        ``nu`` per node.

    Notes
    -----
    From :data:`SPARSE_FROM` nodes on, Newton's steps are sparse (SuperLU), and so is the
    margin where :func:`vouched_bound` makes the nearest eigenvalues enough (:func:`rightmost`);
    else every eigenvalue, dense.
    """
    w = np.asarray(w, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    n = p.size
    phi = np.zeros(n)
    nu = 0.0
    gamma = np.broadcast_to(np.asarray(damping, dtype=np.float64), (n,))
    m = np.broadcast_to(np.asarray(inertia, dtype=np.float64), (n,))
    # the weights of nu: 1 for a uniform damping (or none: first order), so nu = gamma Omega
    g = 1.0 if not (m > 0).any() or np.all(gamma == gamma[0]) else gamma / gamma.mean()
    sparse = n >= SPARSE_FROM
    coo = _coo(w) if sparse else None
    if sparse:
        floor = rounding_floor(np.bincount(coo[0], np.abs(coo[2]), minlength=n))
    else:
        floor = rounding_floor(np.abs(w).sum(axis=1))

    def newton(phi, nu, p_s, lag_s):
        if sparse:
            return _newton(
                phi,
                nu,
                lambda ph, v: _residual_sparse(ph, v, coo, p_s, lag_s, g),
                lambda ph, f: _sparse_step(ph, f, coo, lag_s, g),
                floor=floor,
            )
        return _newton(
            phi,
            nu,
            lambda ph, v: residual(ph, v, w, p_s, lag_s, g),
            lambda ph, f: _dense_step(ph, f, w, lag_s, g),
            floor=floor,
        )

    s, ds = 0.0, 0.125
    phi, nu, ok = newton(phi, nu, 0.0 * p, 0.0)
    while s < 1.0:
        s_next = min(1.0, s + ds)
        phi_t, nu_t, ok = newton(phi, nu, s_next * p, s_next * lag)
        if ok:
            phi, nu, s = phi_t, nu_t, s_next
            ds = min(0.25, 2 * ds)
        else:
            ds /= 4
            if ds < 1e-6:
                return None
    phi = phi - phi[0]
    r = float(np.abs(np.exp(1j * phi).mean()))
    if sparse:
        bound = vouched_bound(phi, w, lag, inertia, damping)
        jac = _jacobian_sparse(phi, coo, lag)
        max_real = rightmost(linearization(jac, inertia, damping), missed_below=bound)
    else:
        max_real = _max_real(phi, w, lag, inertia, damping)
    return LockedState(phi, float(nu), r, bool(max_real < -STABLE_MARGIN), max_real)
