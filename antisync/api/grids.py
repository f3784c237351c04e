"""The grid wing's Python face, ``antisync.grid``: a power grid's lines in three questions.

- :func:`static`: the locked state after each line's removal (or weakening): its largest load,
  stability margin and lambda2, the static Braess and troublemaker lines;
- :func:`removal`: the dynamic N-1 by random starts: each line removed on the same starts as the
  intact grid, ``P_sync`` lost or gained with exact intervals, the change of tau;
- :func:`trip`: the engineer's N-1: each line (or each row of a contingency table,
  :func:`contingencies`) tripped from the operating point, after a fault of ``t_clear`` s if
  asked, with the critical clearing times if asked.

Each takes a config as :func:`antisync.run` does (a YAML path, a mapping of config keys, an
:class:`~antisync.plan.config.Config`, or a networkx graph standing for ``{"graph": G}``),
with keyword overrides merged by the same rules (``model={"damping": 2}``), and returns a
:class:`GridResult`: ``records`` (one dict per line, what the CLI's table shows), ``table`` (the
full object) and ``to_pandas()``::

    import antisync

    res = antisync.grid.static("configs/ieee39_grid.yaml")
    res.records[0]["d_margin"]; res.to_pandas()
    antisync.grid.removal("configs/ieee39_grid.yaml", lines="16-17", realizations=200,
                          output="ieee39_removal.json")
    antisync.grid.trip("configs/ieee14_grid.yaml", lines="1-2", t_clear=0.1, cct=True)

These functions and ``antisync grid static|removal|trip CONFIG`` are two faces of the same
work: the output policy (an existing file replaced only with ``overwrite`` and only when it is a
table of the same kind, never a file the config reads), the one-writer lock and the journal that
resumes an interrupted run live once, in :mod:`antisync.grids.runner`. Every bad argument is a one-line
:class:`~antisync.grids.errors.GridError` (or :class:`~antisync.errors.ConfigError`) before any
file is made.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from antisync.errors import AntisyncError, ConfigError
from antisync.grids.errors import GridError
from antisync.grids.lines import parse_lines
from antisync.grids.load import grid_from_config
from antisync.grids.removal_config import check_beta, resolve_config
from antisync.grids.removal_file import (
    plain,
    table_document,
)
from antisync.grids.runner import run_removal, run_trip, trip_times
from antisync.grids.static import format_table, static_table
from antisync.grids.trip import (
    format_trips,
    read_contingencies,
)
from antisync.plan.config import Config
from antisync.plan.sources import flag, shown
from antisync.report.grid_tables import read_table, removal_markdown
from antisync.report.removal import (
    removal_figure,
    trip_figure,
)

__all__ = ["GridResult", "contingencies", "load_table", "removal", "static", "trip"]

#: What each kind of result's ``records`` are: one row per line, as the CLI's table shows them.
KINDS = ("static", "removal", "trip")


@dataclass(frozen=True)
class GridResult:
    """What :func:`static`, :func:`removal` and :func:`trip` return.

    Attributes
    ----------
    kind : {"static", "removal", "trip"}
    records : list of dict
        One per line (per contingency for a trip table): the static indicators
        (:class:`~antisync.grids.static.LineIndicators`), the paired removal response
        (:class:`~antisync.grids.removal_table.LineRemoval`) or the trip's outcome (settles,
        the time to settle after the trip, the largest frequency and angle, the CCT). The same
        rows as the JSON file's (``rows`` of a removal table, ``lines`` of a trip table).
    table : object
        The whole result: a :class:`~antisync.grids.static.LineTable`, a
        :class:`~antisync.grids.removal_table.RemovalTable` (or, for a finished file returned
        by ``resume=True``, its JSON document) or the trip report (a dict, what the JSON file
        holds).
    path : Path or None
        The JSON file written (``output``), else None.
    kept : bool
        ``resume=True`` found ``output`` finished: it was checked against the arguments and
        left as it is, and ``table`` is its JSON document.
    """

    kind: str
    records: list[dict]
    table: Any = field(repr=False)
    path: Path | None = None
    kept: bool = False

    def to_pandas(self):
        """The records as a :class:`pandas.DataFrame` (needs pandas: ``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            raise AntisyncError(
                "GridResult.to_pandas needs pandas (pip install pandas); "
                "GridResult.records holds the same data as dicts"
            ) from None
        return pd.DataFrame.from_records(self.records)

    def to_markdown(self, top: int | None = None) -> str:
        """The table the CLI prints (``top``: the first rows of the ranking only; a static or
        removal table)."""
        if self.kind == "static":
            return format_table(self.table, top=top)
        if self.kind == "trip":
            return format_trips(self.table)
        if isinstance(self.table, Mapping):  # read back from its file
            return removal_markdown(self.table)
        return self.table.to_markdown(top=top)

    def __repr__(self) -> str:
        where = f" {str(self.path)!r}" if self.path is not None else ""
        return f"GridResult({self.kind}{where}, {len(self.records)} lines)"


def static(
    config: str | os.PathLike | Mapping | Config | Any,
    /,
    *,
    lines=None,
    beta: float = 1.0,
    progress: bool = False,
    **overrides: Any,
) -> GridResult:
    """The static indicators of each line's removal (or weakening by ``beta``): the locked
    state from the intact one (:func:`antisync.grids.static.static_table`).

    Parameters
    ----------
    config : path, mapping, Config or networkx graph
        As :func:`antisync.run` takes it; ``model.frequencies`` are the injections.
    lines : str, list of (u, v) or None
        ``"4-5,2-3"``, a list of label pairs, or None: every line, the bridges skipped (a
        bridge named here is refused at ``beta = 1``).
    beta : float
        ``Omega_ij -> (1 - beta) Omega_ij``, in ``(0, 1]``.
    progress : bool
        A bar of the lines done on stderr.
    **overrides
        Config keys, merged as :func:`antisync.run` merges them.
    """
    progress = flag("antisync.grid.static: progress", progress)
    cfg = _config("antisync.grid.static", config, overrides)
    beta = check_beta(beta)
    g = grid_from_config(cfg)
    picked = _lines(lines, g.labels)
    hint = "leave it out of lines (without lines every bridge is skipped)"
    table = static_table(
        g, beta=beta, lines=picked, skip_bridges=picked is None, bridge_hint=hint, progress=progress
    )
    return GridResult("static", table.to_dicts(), table)


def removal(
    config: str | os.PathLike | Mapping | Config | Any,
    /,
    *,
    lines=None,
    beta: float = 1.0,
    islanding: bool = False,
    output: str | os.PathLike | None = None,
    resume: bool = False,
    overwrite: bool = False,
    figure: str | os.PathLike | None = None,
    by: str = "speedup",
    client=None,
    threads: int | None = None,
    log: Callable[[str], None] | None = None,
    source: str | os.PathLike | None = None,
    **overrides: Any,
) -> GridResult:
    """The dynamic N-1 by random starts (:func:`antisync.grids.removal.line_removal`): each
    line removed (or weakened by ``beta``) and integrated from the intact grid's starts.

    Parameters
    ----------
    config, lines, beta, **overrides
        As :func:`static` (``realizations=200``, ``seed=1`` are overrides too).
    islanding : bool
        Remove bridges too, their rows marked ``islanding``.
    output : path, optional
        The table as JSON (``.json``), written atomically; its journal ``OUTPUT.partial`` keeps
        every finished task until then, so a killed run finishes with ``resume=True``. One
        writer at a time: a second is refused naming the holder.
    resume, overwrite : bool
        Finish an interrupted ``output`` (a finished one is checked against the arguments and
        returned as it is), or replace it; they exclude each other.
    figure : path, optional
        The grid drawn with its lines coloured by the response (``by``: ``"speedup"``, F_1 - 1,
        or ``"psync"``, d P_sync); ``.png``, ``.pdf`` or ``.svg``.
    client : distributed.Client, optional
        Integrate on this Dask cluster (the table is the same, array for array).
    threads : int, optional
        CPU threads (default: all cores; on Dask, per task: 1).
    log : callable, optional
        Receives one-line progress messages.
    source : path, optional
        The YAML file a :class:`~antisync.plan.config.Config` given as ``config`` was read from
        (``antisync grid`` passes it): like every file the config reads, never replaced by an
        output (a ``config`` path is its own source).
    """
    where = "antisync.grid.removal"
    resume, overwrite, islanding = (
        flag(f"{where}: {k}", v)
        for k, v in (("resume", resume), ("overwrite", overwrite), ("islanding", islanding))
    )
    _check_files(where, resume, overwrite, output, log)
    out = None if output is None else Path(output)
    cfg = _config(where, config, overrides)
    done = run_removal(
        cfg,
        lines=_lines(lines, None),  # a string is read against the grid's labels by the removal
        beta=beta,
        islanding=islanding,
        out=out,
        source=_source(config, source),
        resume=resume,
        overwrite=overwrite,
        threads=threads,
        client=client,
        log=log,
        figure=figure,
    )
    if done.kept:
        return dataclasses.replace(load_table(out), kept=True)
    table, out = done.table, done.path
    if figure is not None:
        drawn = removal_figure(table, done.config, figure, by=by, overwrite=overwrite)
        if log is not None:
            log(f"wrote {drawn}")
    return GridResult("removal", table_document(table)["rows"], table, out)


def trip(
    config: str | os.PathLike | Mapping | Config | Any,
    /,
    *,
    lines=None,
    contingencies: str | os.PathLike | None = None,
    t_clear: float | None = None,
    cct: bool = False,
    cct_max: float = 1.0,
    cct_scan: float | None = None,
    t_max: float = 20.0,
    output: str | os.PathLike | None = None,
    resume: bool = False,
    overwrite: bool = False,
    figure: str | os.PathLike | None = None,
    client=None,
    threads: int | None = None,
    progress: bool | None = False,
    log: Callable[[str], None] | None = None,
    source: str | os.PathLike | None = None,
    **overrides: Any,
) -> GridResult:
    """The engineer's N-1 (:func:`antisync.grids.trip.trip_report`): each line tripped from the
    operating point, after a bolted fault of ``t_clear`` s at its first bus (None: no fault),
    integrated by the config's integrator for ``t_max`` s after the trip. The table's first
    trips are integrated again at a finer setting (:mod:`antisync.grids.trip_check`): its
    ``accuracy_check``, a warning through ``log`` (or :func:`warnings.warn`) where it fails.

    Parameters
    ----------
    config, lines, **overrides
        As :func:`static`.
    contingencies : path, optional
        The trips of a contingency table (:func:`contingencies`) instead of every line;
        ``lines`` keeps the rows on the lines it names.
    t_clear : float, optional
        The fault's duration before the trip (s).
    cct : bool
        Each line's critical clearing time: the longest fault with every shorter one survived,
        by a scan every ``cct_scan`` s (default 0.01) up to ``cct_max`` s, then every 1 ms in the
        first failing interval.
    t_max : float
        How long the grid runs after the trip (s).
    output, resume, overwrite, figure, client, threads, log, source
        As :func:`removal` (the figure colours lines by the CCT or the frequency swing).
    progress : bool or None
        A bar of the trips done on stderr (None: when stderr is a terminal).
    """
    where = "antisync.grid.trip"
    resume, overwrite, cct = (
        flag(f"{where}: {k}", v) for k, v in (("resume", resume), ("overwrite", overwrite), ("cct", cct))
    )
    if progress is not None:
        progress = flag(f"{where}: progress", progress)
    _check_files(where, resume, overwrite, output, log)
    out = None if output is None else Path(output)
    cct_max, cct_scan, t_max = trip_times(cct, cct_max, cct_scan, t_max)
    done = run_trip(
        _config(where, config, overrides),
        lines=_lines(lines, None),
        contingencies=contingencies,
        t_clear=t_clear,
        cct=cct,
        cct_max=cct_max,
        cct_scan=cct_scan,
        t_max=t_max,
        out=out,
        source=_source(config, source),
        resume=resume,
        overwrite=overwrite,
        threads=threads,
        client=client,
        progress=progress,
        log=log,
        figure=figure,
    )
    if done.kept:
        return dataclasses.replace(load_table(out), kept=True)
    report, out = done.table, done.path
    if figure is not None:
        drawn = trip_figure(report, done.grid, figure, overwrite=overwrite)
        if log is not None:
            log(f"wrote {drawn}")
    return GridResult("trip", plain(report["lines"]), report, out)


def contingencies(
    config: str | os.PathLike | Mapping | Config | Any, path, /, **overrides: Any
) -> list[dict]:
    """The rows of a contingency table (``label from to share`` per line of text, as
    ``configs/activsg2000_grid_contingencies.txt``) checked against the grid of ``config``: one
    dict per row (``label``, ``line`` as a label pair, ``share``: the part of the line's
    coupling it opens); a row naming no line of the grid is a one-line GridError."""
    g = grid_from_config(_config("antisync.grid.contingencies", config, overrides), law=True)
    return [
        {"label": label, "line": [g.labels[a], g.labels[b]], "share": float(share)}
        for label, (a, b), share in read_contingencies(path, g)
    ]


def load_table(path: str | os.PathLike) -> GridResult:
    """A removal or trip table's file (JSON, or HDF5 with ``.h5``) as the :class:`GridResult`
    its run returned: ``records`` its rows (``nan`` as None), ``table`` its document
    (:func:`antisync.report.grid_tables.read_table`). ``antisync.load`` reads these files too."""
    path = Path(path)
    kind, doc = read_table(path)
    rows = doc["rows"] if kind == "removal" else doc["lines"]
    return GridResult(kind, plain(rows), doc, path)


def _config(where: str, config, overrides: Mapping) -> Config:
    """The validated config of ``config`` (a networkx graph stands for ``{"graph": G}``) with
    ``overrides``; a config that is none of the valid kinds is one line naming them."""
    nx = __import__("sys").modules.get("networkx")
    if nx is not None and isinstance(config, nx.Graph):
        config = {"graph": config}
    if not isinstance(config, str | os.PathLike | Mapping | Config):
        raise ConfigError(
            f"{where}: config must be a YAML file path, a mapping of config keys, an "
            f"antisync.plan.config.Config or a networkx graph, got {shown(config)}"
        )
    return resolve_config(config, overrides)


def _source(config, source):
    """The config file an output must never replace: ``config`` itself when it is a path."""
    if source is not None and not isinstance(source, str | os.PathLike):
        raise ConfigError(f"source must be None or the path of the config's YAML file, got {shown(source)}")
    return config if isinstance(config, str | os.PathLike) else source


def _lines(lines, labels):
    """``lines`` as label pairs: a string (``"4-5,2-3"`` or a YAML list) read against the
    grid's ``labels`` (kept as it is when ``labels`` is None); a list of pairs; None for every
    line."""
    if lines is None or (isinstance(lines, str) and labels is None):
        return lines
    if isinstance(lines, str):
        return parse_lines(lines, labels)
    if not isinstance(lines, list | tuple):
        raise GridError(
            f'lines must be None, a string ("4-5,2-3") or a list of (u, v) pairs, got {shown(lines)}'
        )
    return [tuple(p) if isinstance(p, list) else p for p in lines]


def _check_files(where: str, resume: bool, overwrite: bool, output, log) -> None:
    if resume and overwrite:
        raise GridError(f"{where}: resume finishes the interrupted run and overwrite starts over: give one")
    if resume and output is None:
        raise GridError(f"{where}: resume finishes an interrupted run with an output file: give its output")
    if output is not None and not isinstance(output, str | os.PathLike):
        raise ConfigError(f"{where}: output must be a path of a .json file, got {shown(output)}")
    if log is not None and not callable(log):
        raise ConfigError(
            f"{where}: log must be None or a callable taking one string (e.g. print), got {shown(log)}"
        )
