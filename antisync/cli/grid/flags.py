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

from antisync.cli.common import DebugOpt, QuietOpt, SetOpt, one_of, user_errors
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
        Path | None,
        typer.Option(
            "--out", "-o", help="Write the removal or trip table atomically, as X.json or X.h5 (HDF5)."
        ),
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
