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

__all__ = ["LockedState", "jacobian", "linearization", "locked_state", "residual"]

#: Newton stops when every |F_i| is below this (the residual of an exact state in float64).
TOL = 1e-13
#: An eigenvalue counts as stable when its real part is below ``-STABLE_MARGIN``.
STABLE_MARGIN = 1e-9


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


def jacobian(phi: np.ndarray, w: np.ndarray, lag: float) -> np.ndarray:
    """``dF_i/dphi_k`` of :func:`residual` (the first-order model's Jacobian)."""
    g = w * np.cos(phi[None, :] - phi[:, None] - lag)
    return g - np.diag(g.sum(axis=1))


def _newton(phi, nu, w, p, lag, g=1.0, max_iter=50):
    n = phi.size
    for _ in range(max_iter):
        f = residual(phi, nu, w, p, lag, g)
        if np.max(np.abs(f)) < TOL:
            return phi, nu, True
        jac = jacobian(phi, w, lag)
        # unknowns: phi_1..phi_{N-1} and nu (phi_0 = 0): column 0 becomes dF/dnu = -g
        a = jac.copy()
        a[:, 0] = -g
        try:
            step = np.linalg.solve(a, -f)
        except np.linalg.LinAlgError:
            return phi, nu, False
        if not np.isfinite(step).all():
            return phi, nu, False
        phi = phi.copy()
        phi[1:] += step[1:]
        nu = nu + step[0]
        if n and np.max(np.abs(step)) > 1e3:
            return phi, nu, False
    f = residual(phi, nu, w, p, lag, g)
    return phi, nu, bool(np.max(np.abs(f)) < 10 * TOL)


def linearization(jac: np.ndarray, inertia, damping) -> np.ndarray:
    """The matrix of ``m_i u_i'' + gamma_i u_i' = (jac u)_i`` as a first-order system.

    State: ``u`` of every node, then ``v_i = u_i'`` of the nodes with ``m_i > 0``; a node with
    ``m_i = 0`` is first order, ``u_i' = (jac u)_i / gamma_i``. Without inertia anywhere it is
    ``jac`` (the first-order model, its damping unused). ``inertia`` and ``damping`` are numbers
    or per-node arrays.
    """
    n = jac.shape[0]
    m = np.broadcast_to(np.asarray(inertia, dtype=np.float64), (n,))
    gamma = np.broadcast_to(np.asarray(damping, dtype=np.float64), (n,))
    gen = np.flatnonzero(m > 0)
    if not gen.size:
        return jac
    big = np.zeros((n + gen.size, n + gen.size))
    load = np.flatnonzero(m == 0)
    big[load, :n] = jac[load] / gamma[load, None]
    big[gen, n + np.arange(gen.size)] = 1.0
    big[n + np.arange(gen.size), :n] = jac[gen] / m[gen, None]
    big[n + np.arange(gen.size), n + np.arange(gen.size)] = -gamma[gen] / m[gen]
    return big


def _max_real(phi, w, lag, inertia, damping) -> float:
    ev = np.linalg.eigvals(linearization(jacobian(phi, w, lag), inertia, damping))
    # drop the rotation's zero eigenvalue (the one closest to 0)
    ev = np.delete(ev, np.argmin(np.abs(ev)))
    return float(np.max(ev.real)) if ev.size else -np.inf


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
    s, ds = 0.0, 0.125
    phi, nu, ok = _newton(phi, nu, w, 0.0 * p, 0.0, g)
    while s < 1.0:
        s_next = min(1.0, s + ds)
        phi_t, nu_t, ok = _newton(phi, nu, w, s_next * p, s_next * lag, g)
        if ok:
            phi, nu, s = phi_t, nu_t, s_next
            ds = min(0.25, 2 * ds)
        else:
            ds /= 4
            if ds < 1e-6:
                return None
    phi = phi - phi[0]
    r = float(np.abs(np.exp(1j * phi).mean()))
    max_real = _max_real(phi, w, lag, inertia, damping)
    return LockedState(phi, float(nu), r, bool(max_real < -STABLE_MARGIN), max_real)
