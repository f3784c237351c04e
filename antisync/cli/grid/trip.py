"""`antisync grid trip CONFIG`: the engineer's N-1 from the operating point."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, SetOpt, dask_executor, info, typed_values, user_errors
from antisync.cli.grid.options import (
    CctMaxOpt,
    CctOpt,
    CctScanOpt,
    ContingenciesOpt,
    GridConfigArg,
    LinesOpt,
    OutOpt,
    OverwriteOpt,
    ResumeOpt,
    SchedulerOpt,
    TClearOpt,
    ThreadsOpt,
    TMaxOpt,
    WorkersOpt,
    check_files,
    interrupted,
)


@user_errors
def trip(
    config: GridConfigArg,
    t_clear: TClearOpt = None,
    cct: CctOpt = False,
    cct_max: CctMaxOpt = None,
    cct_scan: CctScanOpt = None,
    contingencies: ContingenciesOpt = None,
    t_max: TMaxOpt = None,
    lines: LinesOpt = None,
    threads: ThreadsOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    out: OutOpt = None,
    figure: Annotated[
        Path | None,
        typer.Option(
            "--figure",
            help="Draw the grid, lines coloured by the critical clearing time or the frequency swing "
            "(.png, .pdf, .svg).",
        ),
    ] = None,
    overwrite: OverwriteOpt = False,
    resume: ResumeOpt = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """The engineer's N-1: each line tripped from the operating point, after a fault, with CCTs.

    The first four trips run again at a finer setting: the line under the table says if they held.
    """
    from antisync.grids.errors import GridError
    from antisync.grids.runner import run_trip, trip_times
    from antisync.grids.trip import format_trips
    from antisync.plan.config import load_config
    from antisync.report.removal import trip_figure

    for name, value in (("--cct-max", cct_max), ("--cct-scan", cct_scan)):
        if value is not None and not cct:
            raise GridError(f"{name} sets the critical clearing times' search: add --cct")
    check_files(resume, overwrite, out, "--trip")
    cct_max, cct_scan, t_max = trip_times(
        cct, 1.0 if cct_max is None else cct_max, cct_scan, 20.0 if t_max is None else t_max
    )
    cfg = load_config(config, list(set_ or []), typed_values(threads=threads))
    with dask_executor(cfg, workers=workers, scheduler=scheduler, quiet=quiet) as ex:
        try:
            done = run_trip(
                cfg,
                lines=lines,
                contingencies=contingencies,
                t_clear=t_clear,
                cct=cct,
                cct_max=cct_max,
                cct_scan=cct_scan,
                t_max=t_max,
                out=out,
                source=config,
                resume=resume,
                overwrite=overwrite,
                client=None if ex is None else ex.client,
                progress=False if quiet else None,
                log=None if quiet else info,
                figure=figure,
            )
        except KeyboardInterrupt:
            interrupted(out)
    if done.kept:
        return  # a finished file asked to resume: left as it is
    if figure is not None:
        info(f"wrote {trip_figure(done.table, done.grid, figure, overwrite=overwrite)}", quiet)
    typer.echo(format_trips(done.table))
    skipped = ", ".join("-".join(b) for b in done.table["bridges_skipped"])
    if skipped:
        n = len(done.table["bridges_skipped"])
        info(f"skipped {n} trip(s) that open a bridge whole: {skipped}", quiet)
