"""Slow, obvious references that every fast path must match.

Written straight from the paper's equations with numpy, in the phase variables theta, with no
tricks: Eq. (2) right-hand side as ``W @ sin(theta_j - theta_i)``, Eq. (3) for r(t), explicit
Euler, tau = first grid time with r >= threshold.
"""

from __future__ import annotations

import numpy as np

from antisync.status import Status


def kuramoto_rhs(theta: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Eq. (2): dtheta_i/dt = sum_j w_ij sin(theta_j - theta_i)."""
    return (w * np.sin(theta[None, :] - theta[:, None])).sum(axis=1)


def order_parameter(theta: np.ndarray) -> float:
    """Eq. (3): r = |mean_j exp(i theta_j)|. (The sum over N is ``mean``'s own arithmetic,
    without its Python-level overhead: the Euler reference calls this every step.)"""
    return float(np.abs(np.exp(1j * theta).sum() / theta.size))


def sync_steps(theta0: np.ndarray, w: np.ndarray, dt: float, threshold: float, max_steps: int):
    """Explicit Euler on theta; returns (Status, steps) with tau = steps * dt."""
    theta = np.array(theta0, dtype=np.float64)
    if order_parameter(theta) >= threshold:
        return Status.ALREADY_SYNCED, 0
    for step in range(1, max_steps + 1):
        theta = theta + dt * kuramoto_rhs(theta, w)
        if order_parameter(theta) >= threshold:
            return Status.SYNCED, step
    return Status.NOT_SYNCED, max_steps


def two_oscillator_tau(phi0: float, threshold: float, coupling: float = 1.0) -> float:
    """Exact tau for N=2 with w_12 = w_21 = coupling: dphi/dt = -2 k sin(phi), phi = theta2 - theta1.

    tan(phi/2) = tan(phi0/2) exp(-2 k t) and r = |cos(phi/2)|, so r reaches the threshold when
    tan(phi/2) = tan(arccos(threshold)), i.e. tau = ln(tan(phi0/2) / tan(arccos r)) / (2 k).
    """
    return float(np.log(np.tan(abs(phi0) / 2) / np.tan(np.arccos(threshold))) / (2 * coupling))


# ---- generalized models (docs/models.md) ------------------------------------------------


def model_rates(theta, nu, w, p, lag, inertia, damping):
    """``(theta', nu')`` of ``m theta'' + gamma theta' = P + sum_j w_ij sin(theta_j - theta_i -
    lag)``; first order (``inertia == 0``): ``theta' = P + coupling``, ``nu' = 0``. Per-node
    ``inertia``/``damping`` arrays: a node with ``m_i = 0`` has ``gamma_i theta_i' = P_i +
    coupling_i`` (when some other node has inertia)."""
    return _Model(w, p, lag, inertia, damping, theta.size).rates(theta, nu)


def frequency_deviation(theta, nu, w, p, lag, inertia, damping):
    """Largest ``|theta_i' - mean theta'|``; for ``m > 0`` also of ``(P_i + coupling_i) /
    gamma``, the frequency each node relaxes to (docs/models.md)."""
    return _Model(w, p, lag, inertia, damping, theta.size).deviation(theta, nu)


class _Model:
    """:func:`model_rates` and :func:`frequency_deviation` of one model, its per-node arrays
    made once (an integration calls them tens of thousands of times)."""

    def __init__(self, w, p, lag, inertia, damping, n):
        self.w, self.p, self.lag = w, p, lag
        m = np.broadcast_to(np.asarray(inertia, dtype=float), (n,))
        g = np.broadcast_to(np.asarray(damping, dtype=float), (n,))
        self.second = bool((m > 0).any())
        self.gen = m > 0
        self.g = g
        self.m = np.where(self.gen, m, 1.0)  # divides the generators' rows only
        if self.second:
            self.relax = np.asarray(inertia) / np.asarray(damping)

    def rates(self, theta, nu):
        k = (self.w * np.sin(theta[None, :] - theta[:, None] - self.lag)).sum(axis=1)
        if not self.second:
            return self.p + k, np.zeros_like(theta)
        th = np.where(self.gen, nu, (self.p + k) / self.g)
        dnu = np.where(self.gen, (self.p + k - self.g * nu) / self.m, 0.0)
        return th, dnu

    def deviation(self, theta, nu):
        th, dnu = self.rates(theta, nu)
        dev = np.max(np.abs(th - th.mean()))
        if self.second:
            relax = th + self.relax * dnu
            dev = max(dev, np.max(np.abs(relax - relax.mean())))
        return float(dev)


def model_tau(
    theta0, w, p, lag, inertia, damping, criterion, target, t_max, rtol=1e-11, atol=1e-12, max_step=0.01
):
    """tau of a generalized model by ``scipy.integrate.solve_ivp`` (DOP853) with an event.

    ``criterion`` ``"r"``: first time ``r(t) >= target``; ``"frequency"``: first time the
    :func:`frequency_deviation` falls below ``target``. Initial frequencies are zero. Returns
    ``(Status, tau)``.
    """
    from scipy.integrate import solve_ivp

    n = theta0.size
    model = _Model(w, p, lag, inertia, damping, n)
    second = model.second

    def split(y):
        return y[:n], (y[n:] if second else np.zeros(n))

    def rhs(t, y):
        th, dnu = model.rates(*split(y))
        return np.concatenate([th, dnu]) if second else th

    def gap(t, y):
        theta, nu = split(y)
        if criterion == "r":
            return order_parameter(theta) - target
        return target - model.deviation(theta, nu)

    gap.terminal = True
    gap.direction = 1.0
    y0 = np.concatenate([theta0, np.zeros(n)]) if second else np.array(theta0, dtype=float)
    if gap(0.0, y0) >= 0 if criterion == "r" else gap(0.0, y0) > 0:
        return Status.ALREADY_SYNCED, 0.0
    # events are searched between the solver's steps: short ones keep it from stepping over a dip
    sol = solve_ivp(
        rhs, (0.0, t_max), y0, method="DOP853", rtol=rtol, atol=atol, events=gap, max_step=max_step
    )
    if sol.t_events[0].size:
        return Status.SYNCED, float(sol.t_events[0][0])
    return Status.NOT_SYNCED, t_max


def model_euler_steps(theta0, w, p, lag, inertia, damping, criterion, target, dt, max_steps):
    """Explicit Euler on ``(theta, nu)``; ``(Status, steps)`` with the criterion checked on the
    grid (as :func:`sync_steps` does for Eq. 2)."""
    theta = np.array(theta0, dtype=np.float64)
    nu = np.zeros_like(theta)
    model = _Model(w, p, lag, inertia, damping, theta.size)

    def met(theta, nu):
        if criterion == "r":
            return order_parameter(theta) >= target
        return model.deviation(theta, nu) < target

    if met(theta, nu):
        return Status.ALREADY_SYNCED, 0
    for step in range(1, max_steps + 1):
        th, dnu = model.rates(theta, nu)
        theta = theta + dt * th
        nu = nu + dt * dnu
        if met(theta, nu):
            return Status.SYNCED, step
    return Status.NOT_SYNCED, max_steps
