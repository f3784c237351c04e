"""`antisync grid CONFIG`: a grid's lines, static indicators or dynamic removal (docs/power_grids.md)."""

from __future__ import annotations

import contextlib
import math
from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, SetOpt, dask_executor, info, one_of, user_errors
from antisync.types import RemovalBy


@user_errors
def grid(
    config: Annotated[
        Path, typer.Argument(help="YAML config of a grid (configs/ieee39_grid.yaml).", show_default=False)
    ],
    removal: Annotated[
        bool,
        typer.Option("--removal", help="Integrate each line's removal on the same starts (dynamic N-1)."),
    ] = False,
    trip: Annotated[
        bool,
        typer.Option(
            "--trip",
            help="The engineer's N-1: each line tripped from the operating point (optionally after "
            "a fault of --t-clear s at its first bus); --cct adds critical clearing times.",
        ),
    ] = False,
    t_clear: Annotated[
        float | None, typer.Option("--t-clear", help="--trip: the fault's duration before the trip (s).")
    ] = None,
    cct: Annotated[
        bool,
        typer.Option(
            "--cct",
            help="--trip: each line's critical clearing time, the longest fault with every shorter "
            "one survived (a scan every --cct-scan s, then every 1 ms in the first failing interval).",
        ),
    ] = False,
    cct_max: Annotated[
        float | None, typer.Option("--cct-max", help="--cct: the longest fault tried (s) [default: 1].")
    ] = None,
    cct_scan: Annotated[
        float | None,
        typer.Option(
            "--cct-scan", help="--cct: the coarse scan's step of fault durations (s) [default: 0.01]."
        ),
    ] = None,
    contingencies: Annotated[
        Path | None,
        typer.Option(
            "--contingencies",
            help="--trip: the trips of a contingency table (label from to share per row; "
            "configs/activsg2000_grid_contingencies.txt is the case's official N-1) instead of "
            "every line; --lines keeps the rows on the lines it names.",
        ),
    ] = None,
    t_max: Annotated[
        float | None,
        typer.Option("--t-max", help="--trip: how long the grid runs after the trip (s) [default: 20]."),
    ] = None,
    lines: Annotated[
        str | None,
        typer.Option(
            help='Lines to change, "4-5,2-3" (a label may hold a dash: "a-b-c" is read when one split '
            "gives two nodes), or a YAML list of pairs for any label: '[[a-b, c], [\"x,y\", -2]]' "
            "(default: every line, bridges skipped)."
        ),
    ] = None,
    beta: Annotated[
        float | None, typer.Option(help="Weaken each line by beta in (0, 1]; 1 removes it [default: 1].")
    ] = None,
    realizations: Annotated[int | None, typer.Option(help="Override `realizations` (--removal).")] = None,
    seed: Annotated[int | None, typer.Option(help="Override `seed` (--removal).")] = None,
    islanding: Annotated[
        bool, typer.Option("--islanding", help="Remove bridges too, marking the rows (default: refused).")
    ] = False,
    threads: Annotated[
        int | None, typer.Option(help="CPU threads (default: all cores; with Dask, per task: 1).")
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            help="--removal or --trip on a local Dask cluster of this many single-threaded workers."
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="--removal or --trip on the Dask cluster at this address (tcp://host:8786)."),
    ] = None,
    top: Annotated[int | None, typer.Option(help="Print only the first TOP rows of the ranking.")] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the removal or trip table as JSON (atomically).")
    ] = None,
    figure: Annotated[
        Path | None,
        typer.Option(
            "--figure",
            help="Draw the grid, lines coloured by the removal response (--removal) or by the "
            "critical clearing time or frequency swing (--trip) (.png, .pdf, .svg).",
        ),
    ] = None,
    by: Annotated[
        RemovalBy | None,
        typer.Option(
            "--by",
            parser=one_of("--by", RemovalBy),
            help="--removal --figure's colour: F_1 - 1 (speedup) or d P_sync [default: speedup].",
        ),
    ] = None,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace an existing --out or --figure file.")
    ] = False,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Finish an interrupted --removal or --trip --out run from its OUT.partial folder.",
        ),
    ] = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Rank CONFIG's lines: the static indicators of the locked state after each line's removal
    (default), or with --removal the paired dynamic response (P_sync lost/gained with exact
    intervals, the change of tau), troublemaker and Braess lines marked; --figure draws it."""
    import dataclasses

    from antisync.cli.common import typed_values
    from antisync.grids.errors import GridError
    from antisync.grids.lines import parse_lines
    from antisync.grids.load import grid_from_config
    from antisync.grids.removal import line_removal
    from antisync.grids.removal_config import check_beta, planned_lines
    from antisync.grids.removal_file import check_output, write_table
    from antisync.grids.removal_journal import journal_folder, remove_journal
    from antisync.grids.static import format_table, static_table
    from antisync.plan.config import load_config
    from antisync.report.removal import check_figure, check_finished_table, removal_figure
    from antisync.store.lock import writer_lock
    from antisync.store.outputs import config_inputs
    from antisync.store.provenance import command_line

    if trip:
        removal_only = {
            "--removal": removal or None,
            "--beta": beta,
            "--realizations": realizations,
            "--seed": seed,
            "--top": top,
            "--islanding": islanding or None,
            "--by": by,
        }
        for name, value in removal_only.items():
            if value is not None:
                raise GridError(
                    f"{name} is not an option of --trip (the line trips from the operating point)"
                )
        for name, value in (("--cct-max", cct_max), ("--cct-scan", cct_scan)):
            if value is not None and not cct:
                raise GridError(f"{name} sets the critical clearing times' search: add --cct")
        cct_max = 1.0 if cct_max is None else cct_max
        t_max = 20.0 if t_max is None else t_max
        if cct_scan is None:
            cct_scan = 0.01 if not 0.001 <= cct_max < 0.01 else cct_max
        where = {"threads": threads, "workers": workers, "scheduler": scheduler}
        files = {"out": out, "figure": figure, "overwrite": overwrite, "resume": resume}
        cct_spec = {"cct": cct, "cct_max": cct_max, "cct_scan": cct_scan}
        _trip(config, set_, lines, contingencies, t_clear, cct_spec, t_max, where, files, quiet)
        return
    beta = 1.0 if beta is None else beta
    by = "speedup" if by is None else by
    trip_only = (
        ("--t-clear", t_clear),
        ("--t-max", t_max),
        ("--cct", cct or None),
        ("--cct-max", cct_max),
        ("--cct-scan", cct_scan),
    )
    for name, value in (*trip_only, ("--contingencies", contingencies)):
        if value is not None:
            raise GridError(f"{name} is for the line trips from the operating point: add --trip")
    beta = check_beta(beta)
    removal_only = {
        "--out": out,
        "--figure": figure,
        "--workers": workers,
        "--scheduler": scheduler,
        "--realizations": realizations,
        "--seed": seed,
    }
    for name, value in removal_only.items():
        if value is not None and not removal:
            raise GridError(f"{name} is for the dynamic removal table: add --removal")
    if top is not None and top < 1:
        raise GridError(f"--top must be an integer >= 1 (the number of rows printed), got {top}")
    if resume and overwrite:
        raise GridError("--resume finishes the interrupted run and --overwrite starts over: give one")
    if resume and out is None:
        raise GridError("--resume finishes an interrupted --removal --out X.json run: give its --out")
    # the config, --set and the typed options read and refused exactly as `antisync run` does
    values = typed_values(realizations=realizations, seed=seed, threads=threads)
    cfg = load_config(config, list(set_ or []), values)
    # threads only say where the work runs: kept out of the config a journal and a table store
    threads, cfg = cfg.threads, dataclasses.replace(cfg, threads=None)
    if not removal:
        g = grid_from_config(cfg)
        picked = parse_lines(lines, g.labels)
        hint = "leave it out of --lines (without --lines every bridge is skipped)"
        table = static_table(
            g, beta=beta, lines=picked, skip_bridges=picked is None, bridge_hint=hint, progress=not quiet
        )
        typer.echo(format_table(table, top=top))
        return
    # the work's own refusals (a line not in the grid, a bridge, a per-node file of the wrong
    # length) come before any about the output files, as they did before the files were checked
    asked = planned_lines(cfg, lines, beta, islanding)
    inputs = config_inputs(cfg, config)
    journal = None if out is None else journal_folder(out)
    # one writer at a time, taken before the journal or the output is looked at: a second
    # writer is told who holds it (pid, host, start, command), not to --resume
    with writer_lock(out) if out is not None else contextlib.nullcontext():
        if journal is not None:
            _check_journal(journal, "removal", resume=resume, overwrite=overwrite)
        if resume and out.exists() and not journal.exists():
            # nothing is written: only the arguments are compared with the table's
            check_finished_table(out, cfg, asked, beta)
            info(f"{out} is complete: nothing to resume (it is left as it is)", quiet)
            return
        if out is not None:
            check_output(out, overwrite or (resume and journal.exists()), protect=inputs)
        if figure is not None:
            check_figure(figure, overwrite, protect=inputs)
        try:
            with dask_executor(cfg, workers=workers, scheduler=scheduler, quiet=quiet) as ex:
                table = line_removal(
                    cfg,
                    lines=lines,
                    beta=beta,
                    islanding=islanding,
                    threads=threads,
                    log=None if quiet else (lambda m: info(f"antisync grid: {m}")),
                    client=None if ex is None else ex.client,
                    journal=journal,
                    restart=overwrite,
                )
        except KeyboardInterrupt:
            _interrupted(journal)
        typer.echo(table.to_markdown(top=top))
        if out is not None:
            path = write_table(table, out, overwrite=overwrite or resume, command=command_line())
            remove_journal(journal)
            info(f"wrote {path}", quiet)
        if figure is not None:
            path = removal_figure(table, cfg, figure, by=by, overwrite=overwrite)
            info(f"wrote {path}", quiet)


def _trip(config, set_, lines, contingencies, t_clear, cct_spec, t_max, where, files, quiet) -> None:
    """``--trip``: the engineer's N-1 table (antisync/grids/trip.py), printed, as JSON with
    ``--out`` and drawn with ``--figure`` (both written atomically; an existing file only with
    ``--overwrite``). ``where``: threads, workers, scheduler (here or on Dask, as a removal);
    with ``--out`` every finished task is kept in ``OUT.partial`` until the table is written,
    and ``--resume`` finishes an interrupted run from it."""
    import json

    from antisync.cli.common import typed_values
    from antisync.grids.errors import GridError
    from antisync.grids.lines import parse_lines
    from antisync.grids.load import grid_from_config
    from antisync.grids.removal_file import check_output, plain, replace_atomically
    from antisync.grids.removal_journal import journal_folder, remove_journal
    from antisync.grids.trip import (
        CCT_TOL,
        CLOCK,
        FORMAT,
        check_explicit_step,
        check_finished_trips,
        format_trips,
        integration_record,
        plan_trips,
        provenance,
        read_contingencies,
        trip_report,
    )
    from antisync.plan.config import load_config
    from antisync.report.removal import check_figure, trip_figure
    from antisync.store.lock import writer_lock
    from antisync.store.outputs import config_inputs
    from antisync.store.provenance import command_line

    out, figure, overwrite, resume = files["out"], files["figure"], files["overwrite"], files["resume"]
    cfg = load_config(config, list(set_ or []), typed_values(threads=where["threads"]))
    if cfg.sync.give_up is not None:
        raise GridError(
            "sync.give_up stops random starts that keep slipping (--removal); a trip runs from the "
            "operating point for --t-max: remove give_up"
        )
    cct, cct_max, cct_scan = cct_spec["cct"], cct_spec["cct_max"], cct_spec["cct_scan"]
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
    if resume and overwrite:
        raise GridError("--resume finishes the interrupted run and --overwrite starts over: give one")
    if resume and out is None:
        raise GridError("--resume finishes an interrupted --trip --out X.json run: give its --out")
    g = grid_from_config(cfg)
    if cfg.dynamics.integrator != "rodas4":
        check_explicit_step(cfg, g)  # the trip's RK4 at dt, checked as `antisync run` checks it
    table = None if contingencies is None else read_contingencies(contingencies, g)
    tolerance = cfg.sync.tolerance if cfg.sync.criterion == "frequency" else 1e-3
    # the config's integrator: rk4 at dt, or rodas4 (a stiff grid's) with its tolerances; the
    # dispatch table's trip row refuses euler
    dyn = cfg.dynamics
    rtol, atol = dyn.tolerances
    integration = {
        "integrator": dyn.integrator,
        "rtol": rtol,
        "atol": atol,
    }
    journal = None if out is None else journal_folder(out)
    with writer_lock(out) if out is not None else contextlib.nullcontext():
        if journal is not None:
            _check_journal(journal, "trip", resume=resume, overwrite=overwrite)
            if resume and out.exists() and not journal.exists():
                # nothing is written: only the arguments are compared with the table's
                settings = {"t_clear": t_clear, "t_max": t_max, "dt": cfg.dynamics.dt, "tolerance": tolerance}
                settings.update(integration_record(**integration))
                settings.update(cct_max=cct_max if cct else None, cct_tol=CCT_TOL if cct else None)
                settings.update(cct_scan=cct_scan if cct else None, clock=CLOCK)
                check_finished_trips(out, g, plan_trips(g, parse_lines(lines, g.labels), table), settings)
                info(f"{out} is complete: nothing to resume (it is left as it is)", quiet)
                return
            out = check_output(
                out,
                overwrite or (resume and journal.exists()),
                protect=config_inputs(cfg, config),
                table="trip",
                fmt=FORMAT,
            )
            if overwrite:
                remove_journal(journal)
        if figure is not None:
            check_figure(figure, overwrite, protect=config_inputs(cfg, config))
        try:
            with dask_executor(
                cfg, workers=where["workers"], scheduler=where["scheduler"], quiet=quiet
            ) as ex:
                report = trip_report(
                    g,
                    parse_lines(lines, g.labels),
                    contingencies=table,
                    t_clear=t_clear,
                    cct=cct,
                    cct_max=cct_max,
                    cct_scan=cct_scan,
                    t_max=t_max,
                    dt=cfg.dynamics.dt,
                    tolerance=tolerance,
                    **integration,
                    threads=cfg.threads,
                    client=None if ex is None else ex.client,
                    journal=journal,
                    progress=False if quiet else None,
                )
        except KeyboardInterrupt:
            _interrupted(journal)
        typer.echo(format_trips(report))
        if report["bridges_skipped"]:
            skipped = ", ".join("-".join(b) for b in report["bridges_skipped"])
            info(
                f"skipped {len(report['bridges_skipped'])} trip(s) that open a bridge whole: {skipped}", quiet
            )
        if out is not None:
            doc = plain({**report, **provenance(command_line()), "config": cfg.to_dict()})
            text = json.dumps(doc, indent=1, allow_nan=False) + "\n"  # strict JSON: nan as null
            replace_atomically(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
            remove_journal(journal)
            info(f"wrote {out}", quiet)
        if figure is not None:
            info(f"wrote {trip_figure(report, g, figure, overwrite=overwrite)}", quiet)


def _interrupted(journal: Path | None) -> None:
    """Ctrl-C during --removal or --trip: say what was kept and exit 130."""
    kept = f"finished tasks are in {journal}; the same command with --resume finishes it"
    typer.echo(f"antisync grid: interrupted; {kept if journal else 'nothing was saved (no --out)'}", err=True)
    raise typer.Exit(130) from None


def _check_journal(journal: Path, kind: str, *, resume: bool, overwrite: bool) -> None:
    """Refuse a journal path that is a link or a file, and an interrupted run's journal that
    neither --resume nor --overwrite addresses (``kind``: removal or trip)."""
    from antisync.grids.errors import GridError

    if journal.is_symlink():
        raise GridError(f"{journal} is a symbolic link, not a {kind} journal (a folder); move it away")
    if journal.exists() and not journal.is_dir():
        raise GridError(f"{journal} is a file, not a {kind} journal (a folder); move it away")
    if journal.exists() and not (resume or overwrite):
        raise GridError(
            f"an interrupted {kind} run left {journal}: pass --resume to finish it (same arguments) "
            "or --overwrite to start over"
        )
