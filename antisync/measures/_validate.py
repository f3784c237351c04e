"""Input checks shared by the measures: one-line errors a user can act on.

Each raises :class:`~antisync.errors.MeasureError`, an :class:`~antisync.errors.AntisyncError`
that is also a ``ValueError`` (callers that caught ValueError still do).
"""

from __future__ import annotations

import numpy as np

from antisync.errors import MeasureError
from antisync.physics.coupling import COUPLINGS


def check_coupling(coupling: str) -> None:
    """Raise :class:`MeasureError` unless ``coupling`` is in :data:`antisync.physics.coupling.COUPLINGS`."""
    if coupling not in COUPLINGS:
        raise MeasureError(f"coupling must be one of {COUPLINGS}, got {coupling!r}")


def as_omega(omega, *, symmetric: bool = False, name: str = "omega") -> np.ndarray:
    """Return ``omega`` as a float64 ``(N, N)`` array of a strongly connected weighted graph.

    Raises ``ValueError`` for a non-square, non-finite or negative matrix, a nonzero diagonal,
    a disconnected graph, or (with ``symmetric=True``) an asymmetric one.
    """
    omega = np.asarray(omega, dtype=np.float64)
    if omega.ndim != 2 or omega.shape[0] != omega.shape[1] or omega.shape[0] < 2:
        raise MeasureError(f"{name} must be a square (N, N) matrix with N >= 2, got shape {omega.shape}")
    if not np.all(np.isfinite(omega)) or np.any(omega < 0):
        raise MeasureError(f"{name} must have finite, non-negative weights")
    if np.any(np.diag(omega) != 0):
        raise MeasureError(f"{name} must have a zero diagonal (no self-loops)")
    if symmetric and np.any(np.abs(omega - omega.T) > 1e-12 * np.abs(omega).max()):
        raise MeasureError(
            f"{name} must be symmetric (an undamaged, undirected network); "
            "derivatives at beta=0 are taken around an undirected Omega"
        )
    if not _strongly_connected(omega > 0):
        raise MeasureError(
            f"{name} describes a disconnected graph (not every node reaches every other); "
            "the measures need a connected network"
        )
    return omega


def check_edge(omega: np.ndarray, a: int, b: int) -> tuple[int, int]:
    """Return ``(a, b)`` as ints after checking ``a -> b`` is a link of ``omega`` (0-based)."""
    n = omega.shape[0]
    a, b = int(a), int(b)
    if not (0 <= a < n and 0 <= b < n):
        raise MeasureError(f"edge ({a}, {b}) is out of range for {n} nodes (indices are 0-based)")
    if omega[a, b] <= 0:
        raise MeasureError(f"there is no link {a}->{b} to damage (Omega[{a}, {b}] = 0)")
    return a, b


def _strongly_connected(adj: np.ndarray) -> bool:
    """Whether every node reaches node 0 and is reached from it (breadth-first, both ways)."""
    for step in (adj, adj.T):
        seen = np.zeros(adj.shape[0], dtype=bool)
        seen[0] = True
        frontier = seen.copy()
        while frontier.any():
            frontier = step[frontier].any(axis=0) & ~seen
            seen |= frontier
        if not seen.all():
            return False
    return True
