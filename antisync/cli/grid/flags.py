"""`antisync grid CONFIG [--removal | --trip]`: the one-command form of the grid subcommands.

Command lines written before `antisync grid static|removal|trip` still run: the group
(:class:`antisync.cli.app.GridGroup`) sends a line that does not start with a subcommand here.
This module only refuses the options that belong to another table and hands the rest to
:mod:`antisync.cli.grid.static`, :mod:`~antisync.cli.grid.removal` or :mod:`~antisync.cli.grid.trip`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, SetOpt, user_errors
from antisync.cli.grid.options import (
    BetaOpt,
    ByOpt,
    CctMaxOpt,
    CctOpt,
    CctScanOpt,
    ContingenciesOpt,
    GridConfigArg,
    IslandingOpt,
    LinesOpt,
    OutOpt,
    OverwriteOpt,
    RealizationsOpt,
    ResumeOpt,
    SchedulerOpt,
    SeedOpt,
    TClearOpt,
    ThreadsOpt,
    TMaxOpt,
    TopOpt,
    WorkersOpt,
)


@user_errors
def grid(
    config: GridConfigArg,
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
    t_clear: TClearOpt = None,
    cct: CctOpt = False,
    cct_max: CctMaxOpt = None,
    cct_scan: CctScanOpt = None,
    contingencies: ContingenciesOpt = None,
    t_max: TMaxOpt = None,
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
            "--figure",
            help="Draw the grid, lines coloured by the removal response (--removal) or by the "
            "critical clearing time or frequency swing (--trip) (.png, .pdf, .svg).",
        ),
    ] = None,
    by: ByOpt = None,
    overwrite: OverwriteOpt = False,
    resume: ResumeOpt = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Rank CONFIG's lines: the static indicators of the locked state after each line's removal
    (default), or with --removal the paired dynamic response (P_sync lost/gained with exact
    intervals, the change of tau), troublemaker and Braess lines marked; --figure draws it."""
    from antisync.cli.grid.options import check_files
    from antisync.cli.grid.removal import removal as removal_command
    from antisync.cli.grid.static import static as static_command
    from antisync.cli.grid.trip import trip as trip_command
    from antisync.grids.errors import GridError

    common = {"config": config, "lines": lines, "set_": set_, "quiet": quiet, "debug": debug}
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
        trip_command(
            **common,
            t_clear=t_clear,
            cct=cct,
            cct_max=cct_max,
            cct_scan=cct_scan,
            contingencies=contingencies,
            t_max=t_max,
            threads=threads,
            workers=workers,
            scheduler=scheduler,
            out=out,
            figure=figure,
            overwrite=overwrite,
            resume=resume,
        )
        return
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
    removal_only = {
        "--out": out,
        "--figure": figure,
        "--workers": workers,
        "--scheduler": scheduler,
        "--realizations": realizations,
        "--seed": seed,
    }
    if removal:
        removal_command(
            **common,
            beta=beta,
            realizations=realizations,
            seed=seed,
            islanding=islanding,
            threads=threads,
            workers=workers,
            scheduler=scheduler,
            top=top,
            out=out,
            figure=figure,
            by=by,
            overwrite=overwrite,
            resume=resume,
        )
        return
    for name, value in removal_only.items():
        if value is not None:
            raise GridError(f"{name} is for the dynamic removal table: add --removal")
    check_files(resume, overwrite, None, "--removal")
    static_command(**common, beta=beta, top=top, threads=threads)
