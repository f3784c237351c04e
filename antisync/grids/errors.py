"""The grids stage's error: a grid or line request that cannot be evaluated."""

from __future__ import annotations

from antisync.errors import AntisyncError

__all__ = ["GridError"]


class GridError(AntisyncError, ValueError):
    """A grid or line request that cannot be evaluated: the message names the line or file."""
