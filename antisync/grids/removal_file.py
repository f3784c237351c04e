"""The file of a dynamic line removal: a :class:`~antisync.grids.removal_table.RemovalTable` as
JSON or HDF5 (:func:`table_document`, :func:`write_table`; ``.h5``: :mod:`antisync.store.grid_file`,
the same document and every start's outcome), the one reader of a grid table's file of either
kind (:func:`read_document`), antisync's output policy for it and for the removal's figure
(:func:`check_output`, :func:`check_new_file`), and the atomic replacement every one of them is
written by.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from antisync._version import __version__
from antisync.errors import StoreError
from antisync.grids.errors import GridError
from antisync.grids.removal_table import RemovalTable
from antisync.stats.multiplicity import FDR_LEVEL
from antisync.store.grid_file import SUFFIXES as HDF5_SUFFIXES
from antisync.store.grid_file import grid_table_kind, read_grid_table, write_grid_table
from antisync.store.outputs import check_output_path, config_inputs, image_problem, json_format_problem
from antisync.store.provenance import git_revision, now

__all__ = [
    "FIGURE_SUFFIXES",
    "FORMAT",
    "FORMAT_VERSION",
    "check_figure",
    "check_new_file",
    "check_output",
    "plain",
    "read_document",
    "replace_atomically",
    "table_document",
    "write_table",
]

#: The ``format`` of a JSON file written by :func:`write_table`.
FORMAT = "antisync-line-removal"
FORMAT_VERSION = 1


def check_output(
    path: str | Path, overwrite: bool = False, protect=(), *, table: str = "removal", fmt: str = FORMAT
) -> Path:
    """The JSON output ``path`` of a grid table, checked before any work
    (:func:`check_new_file`): an existing file is replaced (``overwrite``) only when it is a
    table of the same kind (``table``, whose JSON ``format`` is ``fmt``: the removal table's by
    default, the trip table's for ``antisync grid --trip``); ``protect``: the run's inputs
    (:func:`antisync.store.outputs.config_inputs`), never replaced."""
    return check_new_file(
        path,
        overwrite,
        "--out",
        (".json", *HDF5_SUFFIXES),
        f"the {table} table is written as JSON or HDF5; name it *.json or *.h5",
        replaceable=lambda p: _table_problem(p, table, fmt),
        kind=f"an antisync {table} table (JSON of format {fmt!r}, or an HDF5 grid table)",
        protect=protect,
    )


def _table_problem(path: Path, table: str, fmt: str) -> str | None:
    """What ``path`` is when it is not a ``table`` table (JSON of format ``fmt``, or HDF5)."""
    if Path(path).suffix.lower() in HDF5_SUFFIXES:
        return None if grid_table_kind(path) == table else f"not an HDF5 {table} table"
    return json_format_problem(path, fmt)


def is_hdf5_table(path: str | Path) -> bool:
    """Whether ``path`` names an HDF5 grid table's file (by its suffix)."""
    return Path(path).suffix.lower() in HDF5_SUFFIXES


def read_document(path: str | Path, what: str = "grid table"):
    """The document of a grid table's file, JSON (``.json`` or any other suffix) or HDF5
    (``.h5``, :func:`antisync.store.grid_file.read_grid_table`), as parsed; one-line GridError
    when it cannot be read (the caller checks its ``format``)."""
    path = Path(path)
    if is_hdf5_table(path):
        try:
            return read_grid_table(path)
        except StoreError as exc:
            raise GridError(str(exc)) from None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise GridError(f"{path}: cannot read the {what} ({type(exc).__name__}: {exc})") from None


def check_new_file(
    path: str | Path,
    overwrite: bool,
    option: str,
    suffixes: tuple[str, ...],
    hint: str,
    *,
    replaceable,
    kind: str,
    protect=(),
) -> Path:
    """An output ``path`` checked before any work by antisync's one output policy
    (:func:`antisync.store.outputs.check_output_path`): its suffix one of ``suffixes`` (else
    ``hint``), its folder existing, no link, no input of the run (``protect``), nothing inside
    a journal folder, and an existing file replaced only with ``overwrite`` and only when
    ``replaceable`` accepts it (``kind``); one-line GridErrors that name ``option``."""
    return check_output_path(
        path,
        option=option,
        suffixes=suffixes,
        hint=hint,
        overwrite=overwrite,
        replaceable=replaceable,
        kind=kind,
        protect=protect,
        error=GridError,
    )


def plain(x):
    """``x`` as plain JSON data: mapping keys as strings, tuples as lists, numpy integers as
    ints, and a float that is not finite as ``None``."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [plain(v) for v in x]
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, float | np.floating):
        return None if not math.isfinite(x) else float(x)
    return x


def table_document(table: RemovalTable, command: str = "") -> dict:
    """``table`` as the plain mapping :func:`write_table` writes (the summary, every row, the
    troublemaker and Braess lists, the resolved calls, the resolved config and provenance;
    ``nan`` as ``None``)."""
    sync, tau = table.sync_called(), table.tau_called()
    doc = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "version": __version__,
        "git_revision": git_revision(),
        "command": command,
        "written": now(),
        "summary": table.summary(),
        "troublemakers": [r.label for r in table.troublemakers(None)],
        "braess_lines": [r.label for r in table.braess_lines()],
        # the resolved changes (Benjamini-Hochberg, false discovery rate FDR_LEVEL over the lines)
        "fdr_level": FDR_LEVEL,
        "sync_called": [r.label for r in table.rows if r.line in sync],
        "tau_called": [r.label for r in table.rows if r.line in tau],
        "rows": table.to_dicts(),
        "config": table.config,
    }
    return plain(doc)


def write_table(table: RemovalTable, path: str | Path, overwrite: bool = False, command: str = "") -> Path:
    """Write ``table`` as JSON (:func:`table_document`), or with an ``.h5`` suffix as HDF5 (the
    same document and every start's outcome: :func:`antisync.store.grid_file.write_grid_table`),
    atomically, so an existing result is never half-written. ``nan`` is written as ``null``. An existing
    ``path`` is replaced (``overwrite``) only when it is a removal table, and never when it is a
    file the table's config reads (:func:`check_output`)."""
    path = check_output(path, overwrite, protect=config_inputs(table.config))
    if is_hdf5_table(path):
        outcomes = {"status0": table.status0, "tau0": table.tau0, "status": table.status, "tau": table.tau}
        return write_grid_table(path, table_document(table, command), outcomes)
    text = json.dumps(table_document(table, command), indent=1, default=str)

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
            fh.flush()
            os.fsync(fh.fileno())

    return replace_atomically(path, write)


def replace_atomically(path: Path, write) -> Path:
    """Call ``write(tmp)`` on a temporary file in ``path``'s folder, then rename it over
    ``path``: a reader sees the old file or the whole new one, never half of it; on an error the
    temporary file is removed and ``path`` is left as it was."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # mkstemp's 0600, as an ordinary new file would be
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


#: The file types a grid command's ``--figure`` writes (matplotlib picks the format from the suffix).
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def check_figure(path, overwrite: bool = False, protect=()) -> Path:
    """The figure's ``path``, checked before any work by antisync's one output policy
    (:func:`antisync.grids.removal_file.check_new_file`): a ``.png``, ``.pdf`` or ``.svg`` file in an
    existing folder, and an existing file replaced only with ``overwrite`` and only when it is
    an image of that kind (by its first bytes), never one of ``protect`` (the run's inputs);
    else a one-line GridError."""
    return check_new_file(
        path,
        overwrite,
        "--figure",
        FIGURE_SUFFIXES,
        "name it *.png, *.pdf or *.svg",
        replaceable=image_problem,
        kind="an image of the kind its suffix names (PNG, PDF or SVG, by its first bytes)",
        protect=protect,
    )
