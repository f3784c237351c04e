"""The HDF5 file of a grid table (``antisync grid removal|trip --out X.h5``): the table's document,
its rows as columns, and a removal's per-start outcomes.

A grid table is a JSON document (:func:`antisync.grids.removal_file.table_document` for a removal,
the trip report for a trip); written with a ``.json`` suffix it is that text, with ``.h5`` this
file, which holds the same document whole and adds what JSON cannot hold compactly: a removal's
paired outcomes of every start (the status and tau of the intact grid and after each line's
change), so a table can be analysed again without integrating anything. Reading gives back the
document exactly (:func:`read_grid_table`), so every reader of grid tables (``antisync report``,
``antisync summary``, ``antisync.load``, ``--resume``) reads either file.

Layout::

    /            attrs: format "antisync-grid-table", version, kind ("removal" | "trip"),
                 written, command, antisync_version, git_revision (the document's provenance)
    /document    the table's JSON document, one string (rows, summary, config, provenance)
    /rows        one dataset per column of the rows whose values are numbers, booleans or
                 strings (a number column's null as nan), for h5py and pandas readers
    /outcomes    a removal's status0 (M,), tau0 (M,), status (M, L), tau (M, L) (L: the rows
                 in order; tau nan unless SYNCED)

The file is written whole into ``<file>.tmp`` and renamed over the target (a kill leaves the
old file or the new one, never half of one).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import h5py
import numpy as np

from antisync.errors import StoreError

__all__ = ["FORMAT", "KINDS", "grid_table_kind", "read_grid_table", "read_outcomes", "write_grid_table"]

FORMAT = "antisync-grid-table"
VERSION = 1
#: The tables a grid file holds, by the ``format`` of their document.
KINDS = {"antisync-line-removal": "removal", "antisync-trip": "trip"}
#: The suffixes of an HDF5 grid table (any other output of ``antisync grid`` is JSON).
SUFFIXES = (".h5", ".hdf5")
OUTCOMES = ("status0", "tau0", "status", "tau")


def grid_table_kind(path: str | Path) -> str | None:
    """``"removal"`` or ``"trip"`` for an HDF5 grid table, None for any other file (or none)."""
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != FORMAT:
                return None
            kind = f.attrs.get("kind")
    except (OSError, ValueError):
        return None
    return kind if kind in KINDS.values() else None


def write_grid_table(path: str | Path, doc: dict, outcomes: dict | None = None) -> Path:
    """Write the table document ``doc`` (plain JSON data, its ``format`` one of :data:`KINDS`)
    and, for a removal, its ``outcomes`` (arrays named by :data:`OUTCOMES`) atomically."""
    path = Path(path)
    kind = KINDS.get(doc.get("format"))
    if kind is None:
        raise StoreError(
            f"a grid table's document has format {doc.get('format')!r}, not one of {sorted(KINDS)}"
        )
    text = json.dumps(doc, indent=None, allow_nan=False, default=str)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["version"] = VERSION
            f.attrs["kind"] = kind
            for key, attr in (
                ("written", "written"),
                ("command", "command"),
                ("git_revision", "git_revision"),
            ):
                f.attrs[attr] = str(doc.get(key) or "")
            f.attrs["antisync_version"] = str(doc.get("version") or "")
            f.create_dataset("document", data=text, dtype=h5py.string_dtype())
            rows = doc.get("rows" if kind == "removal" else "lines") or []
            _write_columns(f.create_group("rows"), rows)
            if outcomes is not None:
                g = f.create_group("outcomes")
                for key in OUTCOMES:
                    g.create_dataset(key, data=np.asarray(outcomes[key]), compression="gzip")
            f.flush()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _write_columns(group, rows: list[dict]) -> None:
    """Each key every row holds as a column: numbers (null as nan), booleans, strings, and
    pairs of either (a line's two labels, an interval); other values only in the document."""
    if not rows:
        return
    keys = [k for k in rows[0] if all(k in r for r in rows)]
    for key in keys:
        values = [r[key] for r in rows]
        column = _column(values)
        if column is not None:
            group.create_dataset(key, data=column)


def _column(values: list):
    """``values`` as one array (numbers, booleans or strings, or pairs of them), else None."""
    flat = [x for v in values for x in (v if isinstance(v, list | tuple) else (v,))]
    pairs = all(isinstance(v, list | tuple) and len(v) == 2 for v in values)
    if not pairs and any(isinstance(v, list | tuple | dict) for v in values):
        return None
    shape = (len(values), 2) if pairs else (len(values),)
    if all(isinstance(x, bool) for x in flat):
        return np.array(flat, dtype=bool).reshape(shape)
    if all(x is None or (isinstance(x, int | float) and not isinstance(x, bool)) for x in flat):
        return np.array([math.nan if x is None else x for x in flat], dtype=float).reshape(shape)
    if all(isinstance(x, str) for x in flat):
        return np.array(flat, dtype=h5py.string_dtype()).reshape(shape)
    return None


def read_grid_table(path: str | Path) -> dict:
    """The document :func:`write_grid_table` wrote, exactly; a one-line :class:`StoreError` for
    a file that is not a readable grid table."""
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError) as exc:
        raise StoreError(f"{path} is not a readable HDF5 file ({exc}); give a grid table") from None
    with f:
        if f.attrs.get("format") != FORMAT:
            raise StoreError(f"{path} is not a grid table (written by antisync grid removal|trip --out X.h5)")
        if f.attrs.get("version", 0) > VERSION:
            raise StoreError(
                f"{path} is a grid table of format version {f.attrs['version']}, newer than this antisync "
                f"reads ({VERSION}): upgrade antisync"
            )
        try:
            text = f["document"][()]
            doc = json.loads(text.decode("utf-8") if isinstance(text, bytes) else text)
        except (KeyError, ValueError, UnicodeDecodeError, TypeError) as exc:
            raise StoreError(
                f"{path}: its document is damaged ({type(exc).__name__}); write the table again"
            ) from None
    if not isinstance(doc, dict) or doc.get("format") not in KINDS:
        raise StoreError(f"{path}: its document is not a grid table; write the table again")
    return doc


def read_outcomes(path: str | Path) -> dict[str, np.ndarray] | None:
    """A removal file's per-start outcomes (:data:`OUTCOMES`), None for a trip table."""
    read_grid_table(path)  # refuses anything else in one line
    with h5py.File(path, "r") as f:
        if "outcomes" not in f:
            return None
        return {key: f["outcomes"][key][()] for key in OUTCOMES}
