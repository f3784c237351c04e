"""How one realization's synchronization time ended (STYLE habit 5: status codes, not NaN)."""

from __future__ import annotations

from enum import IntEnum

__all__ = ["Status"]


class Status(IntEnum):
    """Outcome of one integration; the integer values are what kernels and HDF5 files store."""

    SYNCED = 0
    """r(t) reached the threshold at some t > 0: tau is finite and positive."""
    ALREADY_SYNCED = 1
    """r(0) >= threshold: tau = 0 and F = tau0 / tau is undefined, so excluded and counted."""
    NOT_SYNCED = 2
    """r(t) had not reached the threshold by t_max: excluded from F and counted."""

    @property
    def message(self) -> str:
        return {
            Status.SYNCED: "synchronized",
            Status.ALREADY_SYNCED: "r(0) >= threshold (tau = 0); excluded from F",
            Status.NOT_SYNCED: "not synchronized by t_max; excluded from F (increase t_max?)",
        }[self]
