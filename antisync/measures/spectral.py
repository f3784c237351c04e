"""The spectral measure Lambda^(xi2): Eqs. (15)-(16) of the paper.

``xi2`` is the eigenvalue of the Laplacian ``L = diag(W 1) - W`` with the smallest nonzero real
part; ``F^(xi2)_beta = Re xi2(L(Omega*)) / xi2(L(Omega))`` (Eq. 15) and ``Lambda^(xi2)`` is its
derivative at ``beta = 0`` (Eq. 16), computed here exactly by first-order eigenvalue
perturbation rather than by a finite difference.

At ``beta = 0`` ``Omega`` is symmetric, so ``L`` is similar to a symmetric matrix:
``Ls = D L D^-1`` with ``D = diag(sqrt(S_i))`` for normalized coupling (``Ls = I - S^-1/2 Omega
S^-1/2``) and ``D = I`` for raw coupling (``L`` is already symmetric). With ``Ls x = xi x`` and
``x`` orthonormal, the right and left eigenvectors of ``L`` are ``v = D^-1 x`` and ``u = D x``
with ``u^T v = 1``, so ``dxi = u^T dL v`` (``dL = dL/dbeta``).
"""

from __future__ import annotations

import numpy as np

from antisync.measures._validate import as_omega, check_coupling, check_edge
from antisync.physics.coupling import (
    Coupling,
    coupling_derivative,
    coupling_derivative_row,
    damaged_omega,
    laplacian,
    symmetrized_laplacian,
)

__all__ = ["f_xi2", "lambda_xi2", "lambda_xi2_all", "xi2"]

#: Eigenvalues closer than this (relative to the largest one) count as one degenerate xi2.
DEGENERACY_RTOL = 1e-9


def xi2(omega: np.ndarray, coupling: Coupling = "normalized") -> float:
    """Real part of the second eigenvalue ``xi_2`` of the Laplacian of ``W(Omega)``.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of a connected network; may be asymmetric (a damaged ``Omega*``).
    coupling : {"normalized", "raw"}
        ``W = S^-1 Omega`` (Eq. 1) or ``W = Omega`` (the model of Eq. 20).

    Returns
    -------
    float
        ``Re xi_2``: the smallest real part among the eigenvalues other than ``xi_1 = 0``
        (Sec. "Linear approximation of the Kuramoto model"; ``tau^(xi2) = 1 / Re xi_2``).

    Raises
    ------
    ValueError
        For an unknown coupling or a disconnected graph.
    """
    check_coupling(coupling)
    omega = as_omega(omega)
    if np.array_equal(omega, omega.T):
        return float(_symmetrized_spectrum(omega, coupling)[0][1])
    eig = np.linalg.eigvals(laplacian(omega, coupling))
    # L 1 = 0 exactly, so xi_1 = 0 is the eigenvalue of smallest modulus; drop it.
    rest = np.delete(eig, np.argmin(np.abs(eig)))
    return float(rest.real.min())


def f_xi2(omega: np.ndarray, a: int, b: int, beta: float, coupling: Coupling = "normalized") -> float:
    """Functionality ``F^(xi2)_beta = Re xi2(Omega*) / xi2(Omega)``, Eq. (15) of the paper.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Undamaged weights.
    a, b : int
        0-based indices of the damaged directed link ``a -> b``.
    beta : float
        Damage, ``0 <= beta < 1``.
    coupling : {"normalized", "raw"}
    """
    omega = as_omega(omega)
    a, b = check_edge(omega, a, b)
    return xi2(damaged_omega(omega, a, b, beta), coupling) / xi2(omega, coupling)


def lambda_xi2(
    omega: np.ndarray,
    a: int,
    b: int,
    coupling: Coupling = "normalized",
    degeneracy_rtol: float = DEGENERACY_RTOL,
) -> float:
    """Exact ``Lambda^(xi2) = dF^(xi2)_beta / dbeta`` at ``beta = 0``, Eq. (16) of the paper.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Symmetric weights of the undamaged connected network.
    a, b : int
        0-based indices of the damaged directed link ``a -> b``.
    coupling : {"normalized", "raw"}
    degeneracy_rtol : float
        Eigenvalues within this tolerance (relative to the spectral radius of ``L``) of
        ``xi_2`` are treated as one degenerate eigenvalue.

    Returns
    -------
    float
        ``Re(dxi_2/dbeta) / xi_2``. See :func:`lambda_xi2_all` for the method.
    """
    return float(lambda_xi2_all(omega, [(a, b)], coupling, degeneracy_rtol)[0])


def lambda_xi2_all(
    omega: np.ndarray,
    edges,
    coupling: Coupling = "normalized",
    degeneracy_rtol: float = DEGENERACY_RTOL,
) -> np.ndarray:
    """``Lambda^(xi2)`` (Eq. 16) for many directed edges of one network, from one eigensolve.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Symmetric weights of the undamaged connected network.
    edges : sequence of (int, int)
        0-based directed links ``(a, b)``.
    coupling : {"normalized", "raw"}
    degeneracy_rtol : float
        See :func:`lambda_xi2`.

    Returns
    -------
    ndarray, shape (len(edges),)

    Notes
    -----
    Let ``X`` (``N x m``) hold the orthonormal eigenvectors of the symmetrized Laplacian
    ``Ls`` for the ``m``-fold eigenvalue ``xi_2``, ``V = D^-1 X`` and ``U = D X`` the right and
    left eigenvectors of ``L`` (``U^T V = I``). For ``m = 1`` the derivative is
    ``dxi_2 = U^T dL V``. For ``m > 1`` the ``m`` eigenvalues split to first order as
    ``xi_2 + beta mu_k``, with ``mu_k`` the eigenvalues of ``M = U^T dL V``; the one-sided
    (``beta -> 0+``) derivative of the smallest real part is ``min Re mu_k``. Since damage
    changes only row ``a`` of ``L``, ``M`` has rank one and ``min Re mu_k = min(0, tr M)``,
    but ``M`` is diagonalized here in general.
    """
    check_coupling(coupling)
    omega = as_omega(omega, symmetric=True)
    edges = [check_edge(omega, a, b) for a, b in edges]
    evals, x, d = _symmetrized_spectrum(omega, coupling)
    xi_2 = evals[1]
    cluster = np.abs(evals - xi_2) <= degeneracy_rtol * max(abs(evals[-1]), 1e-300)
    cluster[0] = False  # xi_1 = 0 never belongs to the xi_2 cluster of a connected graph
    x2 = x[:, cluster]
    v = x2 / d[:, None]  # right eigenvectors of L
    u = x2 * d[:, None]  # left eigenvectors of L, u^T v = I
    if not edges:
        return np.empty(0)
    # dL = e_a l^T has one nonzero row, so M = u_a (l^T v) needs O(N) per link, never an
    # N x N matrix per link (a 1000-node graph's 4000 links would need 32 GB stacked)
    rows = np.stack([_laplacian_derivative_row(omega, a, b, coupling) for a, b in edges])
    heads = np.array([a for a, _ in edges])
    m = u[heads][:, :, None] * (rows @ v)[:, None, :]
    dxi = np.linalg.eigvals(m).real.min(axis=1)
    return dxi / xi_2


def _symmetrized_spectrum(omega: np.ndarray, coupling: Coupling) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigenpairs of ``Ls = D L D^-1`` for symmetric ``omega``, and the diagonal ``d`` of ``D``.

    Raises ``ValueError`` when ``xi_2`` is (numerically) zero: the graph is disconnected.
    """
    ls, d = symmetrized_laplacian(omega, coupling)
    evals, x = np.linalg.eigh(ls)
    if evals[1] <= 1e-12 * abs(evals[-1]):
        raise ValueError("xi_2 is zero: the graph is disconnected; the measures need a connected network")
    return evals, x, d


def _laplacian_derivative(omega: np.ndarray, a: int, b: int, coupling: Coupling) -> np.ndarray:
    """``dL/dbeta`` at ``beta = 0`` for damage on ``a -> b``: ``diag(dW 1) - dW``."""
    dw = coupling_derivative(omega, a, b, coupling)
    return np.diag(dw.sum(axis=1)) - dw


def _laplacian_derivative_row(omega: np.ndarray, a: int, b: int, coupling: Coupling) -> np.ndarray:
    """Row ``a`` of ``dL/dbeta`` (:func:`_laplacian_derivative`; every other row is zero)."""
    dw_row = coupling_derivative_row(omega, a, b, coupling)
    row = -dw_row
    row[a] += dw_row.sum()
    return row
