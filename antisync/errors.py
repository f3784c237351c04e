"""Errors a user can act on. The CLI prints them as one line and exits with code 2."""

from __future__ import annotations

__all__ = ["AntisyncError", "ConfigError", "MeasureError", "StoreError"]


class AntisyncError(Exception):
    """Base class for problems with the user's input (config, graph, arguments, files)."""


class ConfigError(AntisyncError, ValueError):
    """A config file or override that is not valid: the message names the key and what is valid."""


class StoreError(AntisyncError):
    """A result file that cannot be used (unreadable, foreign, or from a different config)."""


class MeasureError(AntisyncError, ValueError):
    """A response measure that cannot be computed for a run's graph (e.g. a disconnected one)."""
