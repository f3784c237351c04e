"""A grid table from its resolved work to its file, as :mod:`antisync.execution.runner` does for
runs: the output policy (an existing file replaced only with ``overwrite``, only by a table of
the same kind, never a file the config reads), the one-writer lock, the journal that resumes an
interrupted run, and a finished file checked against the arguments on ``resume``.

``antisync grid removal|trip`` and the Python face (:mod:`antisync.api.grids`, which adds the
figures and the result object) both call :func:`run_removal` and :func:`run_trip`; the work
itself is :func:`antisync.grids.removal.line_removal` and :func:`antisync.grids.trip.trip_report`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from antisync.errors import ConfigError
from antisync.execution.dispatch import trip_simulator
from antisync.grids.errors import GridError
from antisync.grids.load import Grid, grid_from_config
from antisync.grids.removal import line_removal
from antisync.grids.removal_config import check_beta, plan_removal, work_config
from antisync.grids.removal_file import (
    FORMAT,
    check_figure,
    check_output,
    is_hdf5_table,
    plain,
    read_document,
    replace_atomically,
    write_table,
)
from antisync.grids.removal_journal import journal_folder, key_changes, remove_journal
from antisync.grids.trip import (
    CCT_SCAN,
    CCT_TOL,
    CLOCK,
    check_explicit_step,
    check_finished_trips,
    integration_record,
    plan_trips,
    provenance,
    read_contingencies,
    trip_report,
)
from antisync.grids.trip import FORMAT as TRIP_FORMAT
from antisync.grids.trip_check import trip_check_line
from antisync.plan.config import Config
from antisync.store.grid_file import write_grid_table
from antisync.store.lock import writer_lock
from antisync.store.outputs import config_inputs
from antisync.store.provenance import command_line

__all__ = [
    "TripPlan",
    "Written",
    "check_finished_table",
    "plan_trip",
    "run_removal",
    "run_trip",
    "trip_times",
]


@dataclass(frozen=True)
class Written:
    """What :func:`run_removal` and :func:`run_trip` did: ``table`` the work's result (a
    :class:`~antisync.grids.removal_table.RemovalTable`, or a trip report's dict), ``path`` the
    file written (None without an output); ``kept``: ``resume`` found the file finished, checked
    it against the arguments and left it as it is (``table`` is None then). ``config``: the
    config the work ran (the removal's without ``threads``); ``grid``: the trip's grid as built."""

    table: Any
    path: Path | None
    kept: bool = False
    config: Config | None = None
    grid: Grid | None = None


def run_removal(
    cfg: Config,
    *,
    lines=None,
    beta: float = 1.0,
    islanding: bool = False,
    out: Path | None = None,
    source: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    threads: int | None = None,
    client=None,
    log: Callable[[str], None] | None = None,
    figure: Path | None = None,
) -> Written:
    """The removal of ``lines`` of ``cfg``'s grid (:func:`~antisync.grids.removal.line_removal`)
    into ``out`` (JSON, or HDF5 with ``.h5``; None: nothing written).

    The work's refusals come first (:func:`~antisync.grids.removal_config.plan_removal`: the
    graph built once), then the files' (``inputs``: the files the config reads, ``source`` its
    YAML file; ``figure``: the path the caller will draw the table to, checked here): one
    writer at a time (a second is refused naming the holder), an interrupted run's journal
    ``OUT.partial`` finished only with ``resume``, a finished ``out`` given ``resume`` checked
    against the arguments and kept, an existing ``out`` replaced only with ``overwrite``, never
    one of ``inputs``. The journal keeps every finished task until the table is written."""
    beta = check_beta(beta)
    if threads is None:
        threads = cfg.threads
    # threads only say where the work runs: kept out of the config a journal and a table store
    cfg = dataclasses.replace(cfg, threads=None)
    plan = plan_removal(cfg, lines, beta, islanding)
    inputs = _inputs(cfg, source, figure, overwrite)
    journal = None if out is None else journal_folder(out)
    say = log or (lambda m: None)
    with writer_lock(out) if out is not None else contextlib.nullcontext():
        if journal is not None:

            def finished():  # only the arguments are compared with the table's
                check_finished_table(out, cfg, plan.asked, beta)

            if _kept(out, journal, "removal", resume, overwrite, finished, say):
                return Written(None, out, kept=True)
            check_output(out, overwrite or (resume and journal.exists()), protect=inputs)
        table = line_removal(
            plan, beta=beta, threads=threads, log=log, client=client, journal=journal, restart=overwrite
        )
        if out is not None:
            out = write_table(table, out, overwrite=overwrite or resume, command=command_line())
            remove_journal(journal)
            say(f"wrote {out}")
    return Written(table, out, config=cfg)


@dataclass(frozen=True)
class TripPlan:
    """A trip run's work, resolved once (:func:`plan_trip`): the config, the grid as built from
    it, the lines (label pairs, or None: every line) and the contingency table's rows."""

    config: Config
    grid: Grid
    lines: Any
    contingencies: Any


def plan_trip(cfg: Config, lines, contingencies) -> TripPlan:
    """The :class:`TripPlan` of ``cfg``: its stop rule ruled on (a trip takes none), the grid
    built once, its explicit step checked, the contingency table read; one line for each
    refusal."""
    try:
        cfg.stop_rule("trip")
    except ConfigError as exc:
        raise GridError(str(exc)) from None
    try:  # the dispatch table's trip row for this model kind and integrator
        trip_simulator(cfg.dynamics.integrator, law=cfg.model.law is not None)
    except ConfigError as exc:
        raise GridError(str(exc)) from None
    g = grid_from_config(cfg, law=True)
    if cfg.dynamics.integrator != "rodas4":
        check_explicit_step(cfg, g)  # the trip's RK4 at dt, checked as `antisync run` checks it
    table = None if contingencies is None else read_contingencies(contingencies, g)
    if isinstance(lines, str):
        from antisync.grids.lines import parse_lines

        lines = parse_lines(lines, g.labels)
    return TripPlan(cfg, g, lines, table)


def run_trip(
    cfg: Config,
    *,
    lines=None,
    contingencies=None,
    t_clear: float | None,
    cct: bool,
    cct_max: float,
    cct_scan: float,
    t_max: float,
    out: Path | None = None,
    source: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    threads: int | None = None,
    client=None,
    progress: bool | None = False,
    log: Callable[[str], None] | None = None,
    figure: Path | None = None,
) -> Written:
    """The trips of ``cfg``'s grid (:func:`plan_trip`, :func:`~antisync.grids.trip.trip_report`)
    into ``out``, with the order of refusals, the file policy, lock and journal of
    :func:`run_removal`."""
    plan = plan_trip(cfg, lines, contingencies)
    inputs = _inputs(cfg, source, figure, overwrite)
    cfg, g = plan.config, plan.grid
    tolerance = cfg.sync.tolerance if cfg.sync.criterion == "frequency" else 1e-3
    # the config's integrator: rk4 at dt, or rodas4 (a stiff grid's) with its tolerances; the
    # dispatch table's trip row refuses euler
    rtol, atol = cfg.dynamics.tolerances
    integration = {"integrator": cfg.dynamics.integrator, "rtol": rtol, "atol": atol}
    journal = None if out is None else journal_folder(out)
    say = log or (lambda m: None)
    with writer_lock(out) if out is not None else contextlib.nullcontext():
        if journal is not None:

            def finished():  # nothing is written: only the arguments are compared with the table's
                settings = {"t_clear": t_clear, "t_max": t_max, "dt": cfg.dynamics.dt, "tolerance": tolerance}
                settings.update(integration_record(**integration))
                settings.update(cct_max=cct_max if cct else None, cct_tol=CCT_TOL if cct else None)
                settings.update(cct_scan=cct_scan if cct else None, clock=CLOCK)
                check_finished_trips(out, g, plan_trips(g, plan.lines, plan.contingencies), settings)

            if _kept(out, journal, "trip", resume, overwrite, finished, say):
                return Written(None, out, kept=True)
            again = overwrite or (resume and journal.exists())
            out = check_output(out, again, protect=inputs, table="trip", fmt=TRIP_FORMAT)
            if overwrite:
                remove_journal(journal)
        report = trip_report(
            g,
            plan.lines,
            contingencies=plan.contingencies,
            t_clear=t_clear,
            cct=cct,
            cct_max=cct_max,
            cct_scan=cct_scan,
            t_max=t_max,
            dt=cfg.dynamics.dt,
            tolerance=tolerance,
            **integration,
            threads=cfg.threads if threads is None else threads,
            client=client,
            journal=journal,
            progress=progress,
        )
        check = report["accuracy_check"]
        if check is not None and not check["passed"]:
            text = trip_check_line(check, report["integrator"])
            if log is not None:
                log(text)
            else:
                warnings.warn(text, stacklevel=2)
        if out is not None:
            doc = plain({**report, **provenance(command_line()), "config": cfg.to_dict()})
            if is_hdf5_table(out):
                write_grid_table(out, doc)
            else:
                text = json.dumps(doc, indent=1, allow_nan=False) + "\n"  # strict JSON: nan as null
                replace_atomically(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
            remove_journal(journal)
            say(f"wrote {out}")
    return Written(report, out, config=cfg, grid=g)


def trip_times(cct: bool, cct_max, cct_scan, t_max) -> tuple[float, float, float]:
    """``(cct_max, cct_scan, t_max)`` checked; ``cct_scan`` None: 0.01 s (``cct_max`` itself for
    a ``cct_max`` under 0.01 s)."""
    if cct_scan is None:
        cct_scan = CCT_SCAN if not CCT_TOL <= cct_max < CCT_SCAN else cct_max
    if not 0 < t_max < math.inf:
        raise GridError(f"--t-max must be a finite positive number of seconds, got {t_max:g}")
    if cct and not CCT_TOL <= cct_max < math.inf:
        raise GridError(
            f"--cct-max must be a finite fault duration of at least {CCT_TOL:g} s, got {cct_max:g}"
        )
    if cct and not CCT_TOL <= cct_scan <= cct_max:
        raise GridError(
            f"--cct-scan must be in [{CCT_TOL:g}, --cct-max = {cct_max:g}] seconds, got {cct_scan:g}"
        )
    return float(cct_max), float(cct_scan), float(t_max)


def check_finished_table(out: Path, cfg, asked: dict, beta: float) -> None:
    """Refuse (one line naming what differs) a ``resume`` whose finished removal table ``out``
    holds another run than the one asked for: its stored config (seed, realizations, model ...),
    lines (``asked``: :attr:`~antisync.grids.removal_config.RemovalPlan.asked`), beta or
    islanding rows."""
    doc = read_document(out, "removal table")
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise GridError(f"{out}: not a removal table (written by antisync grid --removal --out)")
    rows = [r for r in doc.get("rows") or [] if isinstance(r, dict)]
    stored = {}
    for r in rows:
        line = r.get("line")
        if isinstance(line, list) and len(line) == 2:
            stored[(str(line[0]), str(line[1]))] = bool(r.get("islanding"))

    changes = []
    summary = doc.get("summary") if isinstance(doc.get("summary"), dict) else {}
    if summary.get("beta") != beta:
        changes.append(f"beta: {summary.get('beta')} -> {beta:g}")
    config_diff = key_changes(work_config(doc.get("config")), work_config(cfg.to_dict()))
    if config_diff != "no key differs":
        changes.append(config_diff)
    gone = [f"{u}-{v}" for u, v in stored if (u, v) not in asked and (v, u) not in asked]
    new = [f"{u}-{v}" for u, v in asked if (u, v) not in stored and (v, u) not in stored]
    if gone or new:
        parts = [f"{len(gone)} in the table not asked ({_few(gone)})"] if gone else []
        parts += [f"{len(new)} asked not in the table ({_few(new)})"] if new else []
        changes.append("lines: " + ", ".join(parts))
    else:
        flips = [f"{u}-{v}" for (u, v), isl in asked.items() if stored.get((u, v), stored.get((v, u))) != isl]
        if flips:
            changes.append(f"islanding: the bridge(s) {', '.join(flips[:3])} removed in one run only")
    if changes:
        raise GridError(
            f"--resume: {out} is the finished table of another run ({'; '.join(changes)}): give the "
            "arguments it was run with, --overwrite to replace it, or another --out (it is left as it is)"
        )


def _few(names: list[str], most: int = 3) -> str:
    """The first ``most`` names and a count of the rest."""
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def _inputs(cfg, source, figure, overwrite: bool) -> list:
    """The files the config reads (``source``: its YAML file), never replaced by an output, and
    ``figure`` checked against them (drawn by the caller, :mod:`antisync.report`, once the table
    is made)."""
    inputs = config_inputs(cfg, source)
    if figure is not None:
        check_figure(figure, overwrite, protect=inputs)
    return inputs


def _kept(out: Path, journal: Path, kind: str, resume: bool, overwrite: bool, finished, say) -> bool:
    """The journal checked (:func:`_check_journal`); True when ``resume`` finds ``out``
    finished (no journal beside it): ``finished()`` compares its arguments and it is kept."""
    _check_journal(journal, kind, resume=resume, overwrite=overwrite)
    if not (resume and out.exists() and not journal.exists()):
        return False
    finished()
    say(f"{out} is complete: nothing to resume (it is left as it is)")
    return True


def _check_journal(journal: Path, kind: str, *, resume: bool, overwrite: bool) -> None:
    """Refuse a journal path that is a link or a file, and an interrupted run's journal that
    neither ``resume`` nor ``overwrite`` addresses (``kind``: removal or trip)."""
    if journal.is_symlink():
        raise GridError(f"{journal} is a symbolic link, not a {kind} journal (a folder); move it away")
    if journal.exists() and not journal.is_dir():
        raise GridError(f"{journal} is a file, not a {kind} journal (a folder); move it away")
    if journal.exists() and not (resume or overwrite):
        raise GridError(
            f"an interrupted {kind} run left {journal}: pass --resume to finish it (same arguments) "
            "or --overwrite to start over"
        )
