"""`antisync grid removal CONFIG`: the dynamic N-1 by random starts."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import (
    DebugOpt,
    QuietOpt,
    SetOpt,
    dask_executor,
    info,
    typed_values,
    user_errors,
)
from antisync.cli.grid.options import (
    BetaOpt,
    ByOpt,
    GridConfigArg,
    IslandingOpt,
    LinesOpt,
    OutOpt,
    OverwriteOpt,
    RealizationsOpt,
    ResumeOpt,
    SchedulerOpt,
    SeedOpt,
    ThreadsOpt,
    TopOpt,
    WorkersOpt,
    check_files,
    check_top,
    interrupted,
)


@user_errors
def removal(
    config: GridConfigArg,
    lines: LinesOpt = None,
    beta: BetaOpt = None,
    realizations: RealizationsOpt = None,
    seed: SeedOpt = None,
    islanding: IslandingOpt = False,
    threads: ThreadsOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    top: TopOpt = None,
    out: OutOpt = None,
    figure: Annotated[
        Path | None,
        typer.Option(
            "--figure", help="Draw the grid, lines coloured by the removal response (.png, .pdf, .svg)."
        ),
    ] = None,
    by: ByOpt = None,
    overwrite: OverwriteOpt = False,
    resume: ResumeOpt = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """The dynamic N-1: each line removed on the same random starts, P_sync lost/gained, change of tau."""
    from antisync.grids.runner import run_removal
    from antisync.plan.config import load_config
    from antisync.report.removal import removal_figure

    check_top(top)
    check_files(resume, overwrite, out, "--removal")
    # the config, --set and the typed options read and refused exactly as `antisync run` does
    values = typed_values(realizations=realizations, seed=seed, threads=threads)
    cfg = load_config(config, list(set_ or []), values)
    say = None if quiet else (lambda m: info(f"antisync grid: {m}"))
    with dask_executor(cfg, workers=workers, scheduler=scheduler, quiet=quiet) as ex:
        try:
            done = run_removal(
                cfg,
                lines=lines,
                beta=1.0 if beta is None else beta,
                islanding=islanding,
                out=out,
                source=config,
                resume=resume,
                overwrite=overwrite,
                client=None if ex is None else ex.client,
                log=say,
                figure=figure,
            )
        except KeyboardInterrupt:
            interrupted(out)
    if done.kept:  # a finished file asked to resume is left as it is
        return
    if figure is not None:
        drawn = removal_figure(done.table, done.config, figure, by=by or "speedup", overwrite=overwrite)
        info(f"antisync grid: wrote {drawn}", quiet)
    typer.echo(done.table.to_markdown(top=top))
