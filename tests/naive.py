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
    """Eq. (3): r = |mean_j exp(i theta_j)|."""
    return float(np.abs(np.exp(1j * theta).mean()))


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
