"""How one realization's synchronization time ended (STYLE habit 5: status codes, not NaN)."""

from __future__ import annotations

from enum import IntEnum

__all__ = ["ALREADY_SYNCED", "GAVE_UP", "NOT_SYNCED", "SYNCED", "Status"]


class Status(IntEnum):
    """Outcome of one integration; the integer values are what kernels and HDF5 files store."""

    SYNCED = 0
    """r(t) reached the threshold at some t > 0: tau is finite and positive."""
    ALREADY_SYNCED = 1
    """r(0) >= threshold: tau = 0 and F = tau0 / tau is undefined, so excluded and counted."""
    NOT_SYNCED = 2
    """r(t) had not reached the threshold by t_max: excluded from F and counted."""
    GAVE_UP = 3
    """Stopped early by ``sync.give_up``: every frequency deviation had stayed above its band
    until its time (a machine still slipping), so presumed not synchronized by t_max; counted
    as not synchronized, and apart (``antisync grid --removal`` only, docs/power_grids.md)."""

    @property
    def message(self) -> str:
        return {
            Status.SYNCED: "synchronized",
            Status.ALREADY_SYNCED: "r(0) >= threshold (tau = 0); excluded from F",
            Status.NOT_SYNCED: "not synchronized by t_max; excluded from F (increase t_max?)",
            Status.GAVE_UP: "still slipping at sync.give_up.after; counted as not synchronized",
        }[self]


# The codes as plain ints: the constants for numba-jitted code (CPU and CUDA kernels freeze
# module globals at compile time; plain ints type as integers there, with no enum member
# types involved). Python code can use either: Status.SYNCED == SYNCED.
SYNCED: int = int(Status.SYNCED)
""":attr:`Status.SYNCED` as an int, for jitted code."""
ALREADY_SYNCED: int = int(Status.ALREADY_SYNCED)
""":attr:`Status.ALREADY_SYNCED` as an int, for jitted code."""
NOT_SYNCED: int = int(Status.NOT_SYNCED)
""":attr:`Status.NOT_SYNCED` as an int, for jitted code."""
GAVE_UP: int = int(Status.GAVE_UP)
""":attr:`Status.GAVE_UP` as an int, for jitted code."""
