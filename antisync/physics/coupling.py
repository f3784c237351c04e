"""Weights, damage and coupling matrices: the paper's Eqs. (1), (4) and (20) in one place.

Every backend and every measure consumes what this module produces, so the direction
convention is fixed here once: damaging the directed link ``a -> b`` multiplies
``Omega[a, b]`` (and only that entry) by ``1 - beta``; with normalized coupling this changes
row ``a`` of ``W`` only (Eq. 4).

Conventions
-----------
- ``omega`` is a dense ``(N, N)`` float array of non-negative weights, zero diagonal.
- ``coupling="normalized"``: ``w_ij = Omega_ij / S_i`` with ``S_i = sum_l Omega_il`` (Eq. 1).
- ``coupling="raw"``: ``w_ij = Omega_ij`` (the non-normalized model of Eq. 20).
- The (generalized) Laplacian is ``L = diag(sum_j w_ij) - W``; for normalized coupling
  this is ``I - W`` (Eq. 8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from antisync.types import COUPLINGS, Coupling

__all__ = [
    "COUPLINGS",
    "Coupling",
    "CouplingCSR",
    "coupling_derivative",
    "coupling_derivative_row",
    "coupling_matrix",
    "damaged_omega",
    "laplacian",
    "symmetrized_laplacian",
    "orbit_variant_weights",
    "tangent_coefficients",
    "to_csr",
    "variant_weights",
]


def _check_coupling(coupling: str) -> None:
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")


def damaged_omega(omega: np.ndarray, a: int, b: int, beta: float, *, removal: bool = False) -> np.ndarray:
    """Return ``Omega*``: a copy of ``omega`` with ``Omega*_ab = (1 - beta) Omega_ab``.

    Parameters
    ----------
    omega : ndarray, shape (N, N)
        Weights of the undamaged network.
    a, b : int
        0-based indices of the directed link ``a -> b``; ``omega[a, b]`` must be positive.
    beta : float
        Damage, ``-1 < beta < 1``: a negative beta reinforces the link (the ``-dbeta`` side of
        a central difference).
    removal : bool
        Allow ``beta = 1`` too (a line removed: its link's weight 0).
    """
    if not (-1.0 < beta < 1.0 or (removal and beta == 1.0)):
        raise ValueError(f"beta must satisfy -1 < beta < {'= ' if removal else ''}1, got {beta}")
    if omega[a, b] <= 0:
        raise ValueError(f"there is no link {a}->{b} to damage (Omega[{a}, {b}] = 0)")
    out = np.array(omega, dtype=np.float64, copy=True)
    out[a, b] *= 1.0 - beta
    return out


def coupling_matrix(omega: np.ndarray, coupling: Coupling = "normalized") -> np.ndarray:
    """Coupling matrix ``W(Omega)``: Eq. (1) for ``normalized``, ``Omega`` itself for ``raw``."""
    _check_coupling(coupling)
    omega = np.asarray(omega, dtype=np.float64)
    if coupling == "raw":
        return omega.copy()
    strength = omega.sum(axis=1)
    if np.any(strength <= 0):
        isolated = np.flatnonzero(strength <= 0).tolist()
        raise ValueError(f"nodes with zero strength cannot be normalized: indices {isolated}")
    return omega / strength[:, None]


def laplacian(omega: np.ndarray, coupling: Coupling = "normalized") -> np.ndarray:
    """Laplacian ``L = diag(W 1) - W`` of the linearized dynamics ``dtheta/dt = -L theta``."""
    w = coupling_matrix(omega, coupling)
    return np.diag(w.sum(axis=1)) - w


def symmetrized_laplacian(omega: np.ndarray, coupling: Coupling = "normalized"):
    """``(Ls, d)``: the symmetric matrix ``Ls = D L D^-1`` similar to :func:`laplacian` for a
    symmetric ``omega`` (``D = diag(d)``, ``d = sqrt(S)`` for normalized coupling, ones for raw),
    so ``eigh(Ls)`` gives ``L``'s real spectrum."""
    strength = omega.sum(axis=1)
    if coupling == "normalized":
        d = np.sqrt(strength)
        return np.eye(omega.shape[0]) - omega / np.outer(d, d), d
    return np.diag(strength) - omega, np.ones(omega.shape[0])


def coupling_derivative(
    omega: np.ndarray, a: int, b: int, coupling: Coupling = "normalized", beta: float = 0.0
) -> np.ndarray:
    """``dW(Omega*)/dbeta`` for damage on ``a -> b`` at damage ``beta`` (only row ``a`` is nonzero).

    For normalized coupling, with ``S(beta) = S_a - beta Omega_ab`` (Eq. 4):
    ``d w_aj / dbeta = Omega_aj Omega_ab / S(beta)^2`` for ``j != b`` and
    ``d w_ab / dbeta = -Omega_ab (S_a - Omega_ab) / S(beta)^2``.
    For raw coupling, ``d Omega*_ab / dbeta = -Omega_ab``.
    """
    omega = np.asarray(omega, dtype=np.float64)
    d = np.zeros(omega.shape)
    d[a] = coupling_derivative_row(omega, a, b, coupling, beta)
    return d


def coupling_derivative_row(
    omega: np.ndarray, a: int, b: int, coupling: Coupling = "normalized", beta: float = 0.0
) -> np.ndarray:
    """Row ``a`` of :func:`coupling_derivative`, the only nonzero one (``O(N)``, for many links)."""
    _check_coupling(coupling)
    omega = np.asarray(omega, dtype=np.float64)
    wab = omega[a, b]
    if coupling == "raw":
        row = np.zeros(omega.shape[0])
        row[b] = -wab
        return row
    s_a = omega[a].sum()
    s_beta = s_a - beta * wab
    row = omega[a] * wab / s_beta**2
    row[b] = -wab * (s_a - wab) / s_beta**2
    return row


@dataclass(frozen=True)
class CouplingCSR:
    """Sparsity pattern of ``W`` in compressed-row form, shared by all damage variants.

    Attributes
    ----------
    indptr : int64 array, shape (N + 1,)
    indices : int64 array, shape (nnz,)
        Column indices; row ``i`` holds ``indices[indptr[i]:indptr[i+1]]``.
    weights : float64 array, shape (nnz,)
        ``w_ij`` of the undamaged network.
    """

    indptr: np.ndarray
    indices: np.ndarray
    weights: np.ndarray

    @property
    def n_nodes(self) -> int:
        return self.indptr.size - 1

    def position(self, i: int, j: int) -> int:
        """Index into ``weights`` of entry ``(i, j)``; ``KeyError`` if it is not in the pattern."""
        row = self.indices[self.indptr[i] : self.indptr[i + 1]]
        hit = np.flatnonzero(row == j)
        if hit.size == 0:
            raise KeyError((i, j))
        return int(self.indptr[i] + hit[0])


def to_csr(w: np.ndarray, pattern: np.ndarray | None = None) -> CouplingCSR:
    """Compress ``w`` to CSR over ``pattern`` (default: the nonzeros of ``w``)."""
    w = np.asarray(w, dtype=np.float64)
    mask = (w != 0) if pattern is None else np.asarray(pattern, dtype=bool)
    rows, cols = np.nonzero(mask)  # row-major order
    indptr = np.zeros(w.shape[0] + 1, dtype=np.int64)
    np.add.at(indptr, rows + 1, 1)
    indptr = np.cumsum(indptr)
    return CouplingCSR(indptr, cols.astype(np.int64), w[rows, cols].copy())


def coupling_csr(omega: np.ndarray, coupling: Coupling = "normalized") -> CouplingCSR:
    """``W(Omega)`` in CSR over ``Omega``'s links: the pattern every damaged variant of the
    network shares (:func:`variant_weights`; a removed line keeps its place, weight 0)."""
    omega = np.asarray(omega, dtype=np.float64)
    return to_csr(coupling_matrix(omega, coupling), pattern=omega > 0)


def variant_weights(
    omega: np.ndarray,
    csr: CouplingCSR,
    damages: list[tuple[int, int, float]],
    coupling: Coupling = "normalized",
    *,
    both_ways: bool = False,
) -> np.ndarray:
    """CSR weights of ``W(Omega*)`` for each damage ``(a, b, beta)``, on the pattern of ``csr``:
    the one builder of damaged networks' weights (a run's variants and secants, a line removal).

    Parameters
    ----------
    both_ways : bool
        Each damage is a line's: ``Omega*_ab`` and ``Omega*_ba`` both scaled by ``1 - beta``,
        ``beta`` in ``(-1, 1]`` (1 removes the line). Else the directed link ``a -> b`` alone,
        ``-1 < beta < 1``.

    Returns
    -------
    ndarray, shape (len(damages), nnz)
        Row ``v`` equals ``csr.weights`` except on row ``a`` of damage ``v`` (and row ``b``
        with ``both_ways``).
    """
    _check_coupling(coupling)
    omega = np.asarray(omega, dtype=np.float64)
    mask = np.zeros(omega.shape, dtype=bool)
    mask[np.repeat(np.arange(csr.n_nodes), np.diff(csr.indptr)), csr.indices] = True
    base = to_csr(coupling_matrix(omega, coupling), pattern=mask).weights
    out = np.empty((len(damages), base.size))
    for v, (a, b, beta) in enumerate(damages):
        out[v] = base
        for i, j in ((a, b), (b, a)) if both_ways else ((a, b),):
            # only row i changes: W*_i = Omega*_i (raw) or Omega*_i / sum(Omega*_i) (normalized),
            # the same operations on the same row as coupling_matrix of the whole damaged Omega,
            # without copying an N x N matrix per variant (ACTIVSg2000: 5,334 variants, 263 s)
            row = damaged_omega(omega[i : i + 1], 0, j, beta, removal=both_ways)[0]
            if coupling == "normalized":
                if row.sum() <= 0:
                    raise ValueError(f"nodes with zero strength cannot be normalized: indices [{i}]")
                row = row / row.sum()
            lo, hi = csr.indptr[i], csr.indptr[i + 1]
            out[v, lo:hi] = row[csr.indices[lo:hi]]
    return out


def orbit_variant_weights(
    omega: np.ndarray,
    csr: CouplingCSR,
    orbits: list[list[tuple[int, int]]],
    h: float,
    coupling: Coupling = "normalized",
) -> np.ndarray:
    """CSR weights of ``W`` with every directed link of an orbit scaled by ``1 - h`` and ``1 + h``.

    Parameters
    ----------
    orbits : list of lists of (a, b)
        0-based directed links; each list is damaged (``1 - h``) and reinforced (``1 + h``) at once.
    h : float
        Step of the central difference, ``0 < h < 1``.

    Returns
    -------
    ndarray, shape (2 * len(orbits), nnz)
        Row ``2 k`` is orbit ``k`` at ``beta = +h``, row ``2 k + 1`` at ``beta = -h``.
    """
    if not 0.0 < h < 1.0:
        raise ValueError(f"h must satisfy 0 < h < 1, got {h}")
    out = np.empty((2 * len(orbits), csr.weights.size))
    mask = np.zeros(omega.shape, dtype=bool)
    mask[np.repeat(np.arange(csr.n_nodes), np.diff(csr.indptr)), csr.indices] = True
    for k, links in enumerate(orbits):
        rows, cols = np.array(links, dtype=np.int64).reshape(-1, 2).T
        if np.any(omega[rows, cols] <= 0):
            raise ValueError(f"orbit {links} contains a pair that is not a link")
        for j, beta in enumerate((h, -h)):
            damaged = np.array(omega, dtype=np.float64, copy=True)
            damaged[rows, cols] *= 1.0 - beta
            out[2 * k + j] = to_csr(coupling_matrix(damaged, coupling), pattern=mask).weights
    return out


def tangent_coefficients(omega: np.ndarray, edges: list[tuple[int, int]], coupling: str):
    """``(edge_a, edge_b, rho, mu)`` with ``dw_aj/dbeta = rho w_aj + mu [j = b]`` at beta = 0.

    Normalized coupling: ``rho = Omega_ab / S_a``, ``mu = -Omega_ab / S_a``; raw coupling:
    ``rho = 0``, ``mu = -Omega_ab``. (Checked against
    :func:`coupling_derivative` in the tests.)
    """
    a = np.array([e[0] for e in edges], dtype=np.int64)
    b = np.array([e[1] for e in edges], dtype=np.int64)
    wab = omega[a, b]
    if coupling == "raw":
        return a, b, np.zeros(len(edges)), -wab
    strength = omega.sum(axis=1)[a]
    return a, b, wab / strength, -wab / strength
