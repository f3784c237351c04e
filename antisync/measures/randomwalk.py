"""The random-walk measure Lambda^(RW) of the paper's Appendix (Eqs. 23-25).

A walker hops with the transition matrix ``W(Omega)`` (always normalized, Eq. 1). Its global
time is ``tau_RW = (1/N) sum_j tau_j(0)`` with ``tau_j(0)`` the spectral sum of Eq. (23).
Writing ``pi`` for the stationary distribution and ``Z = (I - W + 1 pi^T)^-1`` for the
fundamental matrix, ``sum_{l>=2} |phi_l><phibar_l| / (1 - lambda_l) = Z - 1 pi^T`` and
``<j|phi_1><phibar_1|j> = pi_j``, so Eq. (23) reads ``tau_j(0) = (Z_jj - pi_j) / pi_j``: the
mean first-passage time to ``j`` from the stationary distribution. This form needs no
eigenvectors and is differentiated exactly below.
"""

from __future__ import annotations

import numpy as np

from antisync.measures._validate import as_omega, check_edge
from antisync.physics.coupling import coupling_derivative, coupling_matrix, damaged_omega

__all__ = ["f_rw", "lambda_rw", "lambda_rw_all", "stationary_and_fundamental", "tau_rw"]


def stationary_and_fundamental(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stationary distribution ``pi`` and fundamental matrix ``Z`` of a stochastic matrix.

    Parameters
    ----------
    w : ndarray, shape (N, N)
        Row-stochastic transition matrix of an irreducible chain.

    Returns
    -------
    pi : ndarray, shape (N,)
        ``pi^T W = pi^T``, ``sum(pi) = 1``.
    z : ndarray, shape (N, N)
        ``Z = (I - W + 1 pi^T)^-1``.

    Raises
    ------
    ValueError
        If ``W`` has no unique stationary distribution (a reducible chain).
    """
    w = np.asarray(w, dtype=np.float64)
    n = w.shape[0]
    eye = np.eye(n)
    # pi^T (I - W + 1 1^T) = 1^T has a unique solution iff the chain has one recurrent class
    # (then pi^T 1 = 1 follows from (I - W) 1 = 0).
    a = eye - w + 1.0
    if np.linalg.cond(a) > 1e12:
        raise ValueError(
            "the transition matrix has no unique stationary distribution "
            "(the graph is disconnected or the walk is reducible)"
        )
    pi = np.linalg.solve(a.T, np.ones(n))
    z = np.linalg.inv(eye - w + np.outer(np.ones(n), pi))
    return pi, z


def tau_rw(omega: np.ndarray) -> float:
    """Global time ``tau_RW = (1/N) sum_j tau_j(0)`` of the random walk on ``W(Omega)``, Eq. (23).

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of a connected network (may be a damaged, asymmetric ``Omega*``).

    Returns
    -------
    float
        ``mean_j (Z_jj - pi_j) / pi_j`` (module docstring shows this equals Eq. 23).

    Raises
    ------
    ValueError
        If the graph is disconnected.
    """
    omega = as_omega(omega)
    pi, z = stationary_and_fundamental(coupling_matrix(omega, "normalized"))
    return float(np.mean(np.diag(z) / pi - 1.0))


def f_rw(omega: np.ndarray, a: int, b: int, beta: float) -> float:
    """``F^(RW)_beta = tau_RW(Omega) / tau_RW(Omega*)``, Eq. (24) of the paper.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Undamaged weights.
    a, b : int
        0-based indices of the damaged directed link ``a -> b``.
    beta : float
        Damage, ``0 <= beta < 1``.
    """
    omega = as_omega(omega)
    a, b = check_edge(omega, a, b)
    return tau_rw(omega) / tau_rw(damaged_omega(omega, a, b, beta))


def lambda_rw(omega: np.ndarray, a: int, b: int) -> float:
    """Exact ``Lambda^(RW) = dF^(RW)_beta / dbeta`` at ``beta = 0``, Eq. (25) of the paper.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of the undamaged connected network.
    a, b : int
        0-based indices of the damaged directed link ``a -> b``.

    Returns
    -------
    float
        ``-(dtau_RW/dbeta) / tau_RW``.

    Notes
    -----
    With ``dW = dW/dbeta`` (only row ``a`` nonzero), differentiating ``pi^T (I - W) = 0``,
    ``pi^T 1 = 1`` and ``Z (I - W + 1 pi^T) = I`` (using ``Z 1 = 1``, ``pi^T Z = pi^T``) gives

    - ``dpi^T = pi^T dW Z``,
    - ``dZ = Z dW Z - 1 dpi^T Z``,
    - ``dtau_j = dZ_jj / pi_j - Z_jj dpi_j / pi_j^2``.
    """
    omega = as_omega(omega)
    a, b = check_edge(omega, a, b)
    pi, z = stationary_and_fundamental(coupling_matrix(omega, "normalized"))
    dw = coupling_derivative(omega, a, b, "normalized")
    dpi = pi @ dw @ z
    dz_diag = np.diag(z @ dw @ z) - dpi @ z
    zd = np.diag(z)
    tau0 = np.mean(zd / pi - 1.0)
    dtau = np.mean(dz_diag / pi - zd * dpi / pi**2)
    return float(-dtau / tau0)


def lambda_rw_all(omega: np.ndarray, edges) -> np.ndarray:
    """``Lambda^(RW)`` (Eq. 25) of many directed links of one network, from one factorization.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of the undamaged connected network.
    edges : sequence of (int, int)
        0-based directed links ``(a, b)``.

    Returns
    -------
    ndarray, shape (len(edges),)
        The values :func:`lambda_rw` gives, link by link.

    Notes
    -----
    Damage on ``a -> b`` changes row ``a`` of ``W`` only: ``dW = e_a r^T`` with
    ``r = w_ab (W_a - e_b)`` (Eq. 4 differentiated). The identities of :func:`lambda_rw` then
    need no ``N x N`` product per link: with ``q^T = r^T Z`` and ``Z2 = Z Z`` computed once,
    ``dpi = pi_a q``, ``diag(Z dW Z) = Z[:, a] * q`` and ``dpi^T Z = pi_a r^T Z2``, so a link
    costs ``O(deg(a) N)`` after one ``O(N^3)`` factorization (instead of ``O(N^3)`` each).
    """
    omega = as_omega(omega)
    pairs = [check_edge(omega, a, b) for a, b in edges]
    w = coupling_matrix(omega, "normalized")
    pi, z = stationary_and_fundamental(w)
    z2 = z @ z
    zd = np.diag(z)
    tau0 = np.mean(zd / pi - 1.0)
    out = np.empty(len(pairs))
    for k, (a, b) in enumerate(pairs):
        cols = np.flatnonzero(w[a])  # r is zero off a's neighbours
        r = w[a, b] * w[a, cols]
        r[cols == b] -= w[a, b]
        q = r @ z[cols]
        dpi = pi[a] * q
        dz_diag = z[:, a] * q - pi[a] * (r @ z2[cols])
        dtau = np.mean(dz_diag / pi - zd * dpi / pi**2)
        out[k] = -dtau / tau0
    return out
