"""Validators of config values: each refuses a bad value with a one-line :class:`ConfigError`.

Shared by :mod:`antisync.plan.config`, :mod:`antisync.plan.model`, :mod:`antisync.physics.graphs` and
:mod:`antisync.sweeps`. Every message names the key at fault (``dynamics.dt must be a positive
number, got 0``), so the CLI can print it as it is.

One number parser reads every numeric value, whatever wrote it (YAML, ``--set``, the CLI's
typed options, a Python caller, a file): :func:`parse_number` and :func:`parse_integer`. They
take Python and numpy numbers (never bools), and text in one grammar, :data:`DECIMAL`: ASCII
decimal digits with an optional sign, fraction and exponent (``1e-3``, ``-2.5E+3``, ``.5``).
Everything else is refused with one line, never read as something else: ``1,5`` (a decimal
comma), ``0x10``, ``1_000``, ``010`` (octal in YAML 1.1, ten in YAML 1.2), a unicode minus,
non-breaking spaces, trailing characters. A value too large for a float (a 400-digit integer)
is refused, not an ``OverflowError``.

:func:`read_input_bytes` / :func:`read_input_text` are the one reader of every file a config
names (the config itself, edge lists, frequency files): regular files only (a FIFO would
hang, ``/dev/zero`` never ends), at most :data:`MAX_INPUT_BYTES`, UTF-8 (a byte-order mark
read as such; UTF-16/32 with a byte-order mark decoded), no NUL or other control characters.

Example
-------
>>> choice("executor", "ray", ("local", "dask"))
Traceback (most recent call last):
...
antisync.errors.ConfigError: executor must be one of local, dask, got 'ray'
>>> parse_number("dynamics.dt", "1e-3")
0.001
"""

from __future__ import annotations

import codecs
import difflib
import math
import numbers
import os
import re
import stat
from collections.abc import Iterable
from pathlib import Path

from antisync.errors import AntisyncError, ConfigError

__all__ = [
    "DECIMAL",
    "MAX_INPUT_BYTES",
    "beta",
    "choice",
    "fraction",
    "integer",
    "number",
    "number_text",
    "parse_integer",
    "parse_number",
    "positive",
    "read_input_bytes",
    "read_input_text",
    "show",
    "suggest",
    "unknown_keys",
    "whole",
]

#: The text of a number: ASCII digits, an optional sign, fraction and exponent. The integer
#: part has no leading zeros (``010`` is 8 in YAML 1.1 and 10 in YAML 1.2: refused, not guessed).
DECIMAL = re.compile(r"[-+]?(?:(?:0|[1-9][0-9]*)(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\Z")
_INTEGER_TEXT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)\Z")
# non-finite spellings (YAML's and Python's); the validators refuse them where they mean nothing
_SPECIAL = {"nan": math.nan, "inf": math.inf, "infinity": math.inf}
#: Largest file antisync reads as input (a config, an edge list, a frequency file). 64 MiB is
#: an edge list of ~3 million links, beyond what the dense N x N matrices of a run hold.
MAX_INPUT_BYTES = 64 * 2**20
#: Integers up to this are exact in float64 (realization counts written as ``1e6``).
_EXACT = 2**53


def show(value) -> str:
    """``repr(value)``, shortened: a 400-digit integer is ``1000...000 (401 digits)``."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        sign = "-" if value < 0 else ""
        try:
            digits = str(abs(int(value)))
        except ValueError:  # beyond Python's limit on int -> str (4300 digits)
            about = int(abs(int(value)).bit_length() * math.log10(2)) + 1
            return f"{sign}an integer of about {about} digits"
        if len(digits) > 24:
            return f"{sign}{digits[:4]}...{digits[-3:]} ({len(digits)} digits)"
    text = repr(value)
    return text if len(text) <= 80 else text[:60] + "..." + text[-10:]


def _hint(text: str) -> str:
    """Why a text that looks like a number is not one (appended to the error)."""
    if "," in text:
        return " (a decimal comma? write 1.5, not 1,5)"
    if not text.isascii():
        return " (write numbers in ASCII: digits, '.', 'e' and '-', no unicode minus or spaces)"
    if "_" in text or text.lower().startswith(("0x", "0o", "0b", "-0x", "+0x")) or ":" in text:
        return " (write decimal digits such as 1000 or 1e3)"
    if re.fullmatch(r"[-+]?0[0-9]+", text):
        return " (leading zeros: write the number without them)"
    return ""


def number_text(text: str) -> float | None:
    """The float written as ``text`` in the grammar :data:`DECIMAL` (or ``nan``/``inf``,
    YAML's ``.nan``/``.inf``, any case, optional sign), surrounding ASCII whitespace ignored;
    ``None`` for anything else. Huge exponents give ``inf`` (``1e400``)."""
    t = text.strip(" \t\r\n")
    if DECIMAL.match(t):
        return float(t)
    sign = -1.0 if t[:1] == "-" else 1.0
    name = t.lstrip("+-").lstrip(".").lower() if t[:1] in "+-." or t[:1].isalpha() else ""
    if name in _SPECIAL and t.lstrip("+-").lower() in (name, "." + name):
        return sign * _SPECIAL[name]
    return None


def parse_number(key: str, value, must: str = "a number", finite: bool = True) -> float:
    """``value`` as a float, or a one-line :class:`ConfigError` naming ``key``.

    Parameters
    ----------
    key : str
        The key, for the message (``dynamics.dt``).
    value
        A Python or numpy number (not a bool), or text in :data:`DECIMAL` (``"1e-3"``: YAML
        1.1 reads an exponent without a dot as a string).
    must : str
        What a valid value is, for the message: ``KEY must be MUST, got VALUE``.
    finite : bool
        Refuse ``nan`` and ``inf`` (no config key has a use for them).

    Raises
    ------
    ConfigError
        A bool, a non-number, text in another grammar (with a hint: decimal comma, unicode
        minus, ...), an integer too large for a float, or a non-finite value.
    """
    x = None
    hint = ""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        pass  # true/false are not 1/0 here
    elif isinstance(value, numbers.Integral):
        try:
            x = float(value)
        except OverflowError:
            raise ConfigError(f"{key} must be {must}, got {show(value)} (too large)") from None
    elif isinstance(value, numbers.Real):
        x = float(value)
    elif isinstance(value, str):
        x = number_text(value)
        if x is None:
            hint = _hint(value.strip(" \t\r\n"))
    if x is None or (finite and not math.isfinite(x)):
        raise ConfigError(f"{key} must be {must}, got {show(value)}{hint}")
    return x


def parse_integer(key: str, value, lo: int, hi: int, valid: str) -> int:
    """``value`` as an int in ``lo..hi``, or a one-line :class:`ConfigError` naming ``key``.

    Integers (Python or numpy), integer-valued floats up to 2**53 (``1e6``, ``2.0e3``: exact in
    float64) and their text; not bools, not 3.7, not ``1e23`` (not exact as a float).

    Parameters
    ----------
    valid : str
        The range as the message writes it (``"1..10**15"``).

    Raises
    ------
    ConfigError
        ``KEY must be an integer in VALID, got VALUE``.
    """
    n = _as_int(value)
    if n is None or not lo <= n <= hi:
        hint = _hint(value.strip(" \t\r\n")) if isinstance(value, str) else ""
        raise ConfigError(f"{key} must be an integer in {valid}, got {show(value)}{hint}")
    return n


def _as_int(value) -> int | None:
    """The integer ``value`` stands for (rules of :func:`parse_integer`), else ``None``."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return None
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, str):
        t = value.strip(" \t\r\n")
        if _INTEGER_TEXT.match(t):
            return int(t)
        x = number_text(t)
    elif isinstance(value, numbers.Real):
        x = float(value)
    else:
        return None
    if x is None or not math.isfinite(x) or x != math.floor(x) or abs(x) > _EXACT:
        return None
    return int(x)


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
    if not isinstance(value, str) or value not in valid:
        raise ConfigError(
            f"{key} must be one of {', '.join(valid)}, got {show(value)}" + suggest(str(value), valid)
        )


def positive(key: str, value) -> float:
    """``value`` as a finite float ``> 0`` (:func:`parse_number`).

    Raises
    ------
    ConfigError
    """
    x = parse_number(key, value, "a positive number")
    if not x > 0:
        raise ConfigError(f"{key} must be a positive number, got {show(value)}")
    return x


def fraction(key: str, value) -> float:
    """``value`` as a float strictly between 0 and 1 (thresholds, dbeta).

    Raises
    ------
    ConfigError
    """
    x = parse_number(key, value, "in (0, 1)")
    if not 0.0 < x < 1.0:
        raise ConfigError(f"{key} must be in (0, 1), got {show(value)}")
    return x


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
    if isinstance(value, str) and number_text(value) is None:
        hint = _hint(value.strip(" \t\r\n"))
        raise ConfigError(f"{key} must be a number in [0, 1), got {show(value)}{hint}")
    try:
        x = parse_number(key, value)
    except ConfigError:
        x = math.nan
    if not 0.0 <= x < 1.0:
        raise ConfigError(f"{key} must lie in [0, 1) (e.g. [0.1, 0.5]), got {show(value)}")
    return x


#: the schemas' name for :func:`parse_integer` (not a bool, not a float such as 3.7 or 1e23)
integer = parse_integer


def number(key: str, value, default):
    """``value`` as a float where ``default`` is a float and ``value`` a number or a numeric
    string (YAML reads ``1e-3``, without a dot, as a string); anything else unchanged, for the
    validators to judge (they name the valid range).

    Raises
    ------
    ConfigError
        For a string that is not a number where a float is expected.
    """
    if not isinstance(default, float):
        return value
    if isinstance(value, str):
        return parse_number(key, value, "a number", finite=False)
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and type(value).__name__ != "bool_":
        try:
            return float(value)
        except OverflowError:
            return value  # too large for a float: the validator refuses it with its range
    return value


def whole(key: str, value):
    """``1e6`` (which YAML 1.1 reads as a string) or ``1.0e6`` as the integer 1000000; other
    values are returned unchanged, for the validators, which name what is wrong.

    ``key`` is unused (kept so every validator takes the key first).
    """
    n = _as_int(value)
    return value if n is None else n


# ---- input files ------------------------------------------------------------------------
_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)
# C0 controls other than tab, newline, vertical tab, form feed and carriage return, and DEL
_CONTROL = re.compile(r"[\x00-\x08\x0e-\x1f\x7f]")


def read_input_bytes(path: str | Path, what: str, error: type[AntisyncError] = ConfigError) -> bytes:
    """The bytes of an input file, or one line: it must be a regular file of at most
    :data:`MAX_INPUT_BYTES` (a FIFO or a terminal would block, ``/dev/zero`` never ends).

    Parameters
    ----------
    path : str or Path
    what : str
        The file's role in messages (``edge list``, ``model.frequencies.file``).
    error : AntisyncError subclass
        Raised for every problem (``GraphError`` for graph files).
    """
    path = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO for reading must not wait for a writer; fstat then
        # refuses it before a single byte is read
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise error(f"cannot read {what} {path}: it does not exist") from None
    except IsADirectoryError:
        raise error(f"{what} {path} is a folder; give a text file") from None
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = next((name for test, name in _KINDS if test(info.st_mode)), "not a regular file")
            raise error(f"{what} {path} is {kind}; give a regular text file")
        if info.st_size > MAX_INPUT_BYTES:
            raise error(
                f"{what} {path} is {info.st_size / 2**20:,.0f} MiB; antisync reads input files of "
                f"at most {MAX_INPUT_BYTES // 2**20} MiB"
            )
        if hasattr(os, "O_NONBLOCK"):
            os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=True) as fh:
            fd = -1
            data = fh.read(MAX_INPUT_BYTES + 1)  # a file that grows while read stops here
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    finally:
        if fd >= 0:
            os.close(fd)
    if len(data) > MAX_INPUT_BYTES:
        raise error(f"{what} {path} is larger than {MAX_INPUT_BYTES // 2**20} MiB; antisync reads no more")
    return data


def read_input_text(path: str | Path, what: str, error: type[AntisyncError] = ConfigError) -> str:
    """The text of an input file (:func:`read_input_bytes`), decoded: UTF-8, a byte-order mark
    dropped; UTF-16 or UTF-32 with a byte-order mark decoded as such. Refused with one line:
    other encodings (a UTF-16 file without a mark, Latin-1 bytes) and NUL or other control
    characters, which would otherwise become parts of node labels or numbers."""
    path = Path(path)
    data = read_input_bytes(path, what, error)
    encoding = next((enc for bom, enc in _BOMS if data.startswith(bom)), "utf-8")
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise error(
            f"{what} {path} is not {encoding.upper().replace('-SIG', '')} text (byte {exc.start}); "
            "save it as UTF-8"
        ) from None
    bad = _CONTROL.search(text)
    if bad:
        line = text.count("\n", 0, bad.start()) + 1
        what_char = (
            "NUL characters (UTF-16 text without a byte-order mark?)"
            if bad.group() == "\0"
            else (f"the control character U+{ord(bad.group()):04X}")
        )
        raise error(f"{what} {path}:{line} contains {what_char}; save it as UTF-8 text")
    return text
