"""Validators of config values: each refuses a bad value with a one-line :class:`ConfigError`.

Shared by :mod:`antisync.config` and :mod:`antisync.sweeps`. Every message names the key at
fault (``dynamics.dt must be a positive number, got 0``), so the CLI can print it as it is.

Example
-------
>>> choice("executor", "ray", ("local", "dask"))
Traceback (most recent call last):
...
antisync.errors.ConfigError: executor must be one of local, dask, got 'ray'
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable

from antisync.errors import ConfigError

__all__ = [
    "beta",
    "choice",
    "fraction",
    "integer",
    "number",
    "positive",
    "suggest",
    "unknown_keys",
    "whole",
]


def unknown_keys(mapping: dict, valid: set, prefix: str) -> None:
    """Refuse the first key of ``mapping`` that is not in ``valid``.

    Parameters
    ----------
    mapping : dict
        The keys given (a config section).
    valid : set
        The keys allowed.
    prefix : str
        Written before every key in the message (``"dynamics."``).

    Raises
    ------
    ConfigError
        Naming the key, the nearest valid one and all valid keys.
    """
    for key in mapping:
        if key not in valid:
            raise ConfigError(
                f"unknown key {prefix + str(key)!r}"
                + suggest(str(key), valid, prefix)
                + f"; valid keys: {', '.join(sorted(prefix + v for v in valid))}"
            )


def suggest(word: str, valid: Iterable, prefix: str = "") -> str:
    """`` (did you mean 'PREFIXclosest'?)`` for the valid name closest to ``word``, or ``""``.

    Parameters
    ----------
    word : str
        What was given.
    valid : iterable
        The names allowed.
    prefix : str, optional
        Written before the suggested name.
    """
    close = difflib.get_close_matches(word, [str(v) for v in valid], n=1, cutoff=0.5)
    return f" (did you mean '{prefix}{close[0]}'?)" if close else ""


def choice(key: str, value, valid: Iterable[str]) -> None:
    """Refuse ``value`` unless it is one of ``valid`` (a tuple from :mod:`antisync.types`).

    Raises
    ------
    ConfigError
        ``KEY must be one of a, b, got 'x'``, with the nearest valid value if one is close.
    """
    if value not in valid:
        raise ConfigError(
            f"{key} must be one of {', '.join(valid)}, got {value!r}" + suggest(str(value), valid)
        )


def positive(key: str, value) -> None:
    """Refuse ``value`` unless it is a finite number ``> 0`` (not a bool).

    Raises
    ------
    ConfigError
    """
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (value > 0 and math.isfinite(value))
    ):
        raise ConfigError(f"{key} must be a positive number, got {value!r}")


def fraction(key: str, value) -> None:
    """Refuse ``value`` unless it is a number strictly between 0 and 1 (thresholds, dbeta).

    Raises
    ------
    ConfigError
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 < value < 1.0:
        raise ConfigError(f"{key} must be in (0, 1), got {value!r}")


def beta(key: str, value) -> float:
    """A damage in ``[0, 1)`` as a float (a numeric string such as ``"1e-1"`` is read first).

    Returns
    -------
    float

    Raises
    ------
    ConfigError
        For anything that is not a number in ``[0, 1)``.
    """
    if isinstance(value, str):
        value = number(key, value, 0.0)
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value < 1.0:
        raise ConfigError(f"{key} must lie in [0, 1) (e.g. [0.1, 0.5]), got {value!r}")
    return float(value)


def integer(key: str, value, lo: int, hi: int, valid: str) -> None:
    """Refuse ``value`` unless it is an integer in ``lo..hi`` (not a bool, not a float such as
    3.7 or 1e23).

    Parameters
    ----------
    valid : str
        The range as the message writes it (``"1..10**15"``).

    Raises
    ------
    ConfigError
    """
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ConfigError(f"{key} must be an integer in {valid}, got {value!r}")


def number(key: str, value, default):
    """``value`` as a float where ``default`` is a float and ``value`` a YAML int or a numeric
    string (YAML reads ``1e-3``, without a dot, as a string); anything else unchanged, for the
    validators to judge.

    Raises
    ------
    ConfigError
        For a string that is not a number where a float is expected.
    """
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, float) and isinstance(value, str):
        try:
            return float(value)  # YAML reads 1e-3 (no dot) as a string
        except ValueError:
            raise ConfigError(f"{key} must be a number, got {value!r}") from None
    return value


def whole(key: str, value):
    """``1e6`` (which YAML reads as a string) or ``1.0e6`` as the integer 1000000; other values
    are returned unchanged, for the validators, which name what is wrong.

    ``key`` is unused (kept so every validator takes the key first).
    """
    if isinstance(value, str | float) and not isinstance(value, bool):
        try:
            x = float(value)
        except ValueError:
            return value
        if math.isfinite(x) and x == int(x) and abs(x) <= 2**53:  # exact in float64
            return int(x)
    return value
