"""The options the grid subcommands share (one help text each)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import one_of
from antisync.types import RemovalBy

GridConfigArg = Annotated[
    Path, typer.Argument(help="YAML config of a grid (configs/ieee39_grid.yaml).", show_default=False)
]
LinesOpt = Annotated[
    str | None,
    typer.Option(
        help='Lines to change, "4-5,2-3" (a label may hold a dash: "a-b-c" is read when one split '
        "gives two nodes), or a YAML list of pairs for any label: '\\[\\[a-b, c], \\[\"x,y\", -2]]' "
        "(default: every line, bridges skipped)."
    ),
]
BetaOpt = Annotated[
    float | None, typer.Option(help="Weaken each line by beta in (0, 1]; 1 removes it (default 1).")
]
ThreadsOpt = Annotated[
    int | None, typer.Option(help="CPU threads (default: all cores; with Dask, per task: 1).")
]
WorkersOpt = Annotated[
    int | None, typer.Option(help="Run on a local Dask cluster of this many single-threaded workers.")
]
SchedulerOpt = Annotated[
    str | None, typer.Option(help="Run on the Dask cluster at this address (tcp://host:8786).")
]
OutOpt = Annotated[
    Path | None,
    typer.Option(
        "--out",
        "-o",
        help="Write the table atomically: X.json, or X.h5 (HDF5: the same document, its rows as "
        "columns and a removal's every start); antisync summary, report and antisync.load read both.",
    ),
]
OverwriteOpt = Annotated[
    bool, typer.Option("--overwrite", help="Replace an existing --out or --figure file.")
]
ResumeOpt = Annotated[
    bool,
    typer.Option("--resume", help="Finish an interrupted --out run from its OUT.partial folder."),
]
TopOpt = Annotated[int | None, typer.Option(help="Print only the first TOP rows of the ranking.")]


def check_top(top: int | None) -> None:
    """``--top``: an integer >= 1, else one line."""
    from antisync.grids.errors import GridError

    if top is not None and top < 1:
        raise GridError(f"--top must be an integer >= 1 (the number of rows printed), got {top}")


def check_files(resume: bool, overwrite: bool, out: Path | None, what: str) -> None:
    """``--resume`` and ``--overwrite`` exclude each other, and ``--resume`` needs ``--out``
    (``what``: ``--removal`` or ``--trip``, for the message)."""
    from antisync.grids.errors import GridError

    if resume and overwrite:
        raise GridError("--resume finishes the interrupted run and --overwrite starts over: give one")
    if resume and out is None:
        raise GridError(f"--resume finishes an interrupted {what} --out X.json run: give its --out")


def interrupted(out: Path | None) -> None:
    """Ctrl-C during a removal or trip: say what was kept and exit 130."""
    from antisync.grids.removal_journal import journal_folder

    journal = None if out is None else journal_folder(out)
    kept = f"finished tasks are in {journal}; the same command with --resume finishes it"
    typer.echo(f"antisync grid: interrupted; {kept if journal else 'nothing was saved (no --out)'}", err=True)
    raise typer.Exit(130) from None


# ---- the removal's options ----

RealizationsOpt = Annotated[int | None, typer.Option(help="Override `realizations`.")]
SeedOpt = Annotated[int | None, typer.Option(help="Override `seed`.")]
IslandingOpt = Annotated[
    bool, typer.Option("--islanding", help="Remove bridges too, marking the rows (default: refused).")
]
ByOpt = Annotated[
    RemovalBy | None,
    typer.Option(
        "--by", parser=one_of("--by", RemovalBy), help="The figure's colour: F_1 - 1 (speedup) or d P_sync."
    ),
]

# ---- the trip's options ----

TClearOpt = Annotated[
    float | None, typer.Option("--t-clear", help="The fault's duration before the trip (s).")
]
CctOpt = Annotated[
    bool,
    typer.Option(
        "--cct",
        help="Each line's critical clearing time, the longest fault with every shorter one survived "
        "(a scan every --cct-scan s, then every 1 ms in the first failing interval).",
    ),
]
CctMaxOpt = Annotated[
    float | None, typer.Option("--cct-max", help="--cct: the longest fault tried (s) (default 1).")
]
CctScanOpt = Annotated[
    float | None,
    typer.Option("--cct-scan", help="--cct: the coarse scan's step of fault durations (s) (default 0.01)."),
]
ContingenciesOpt = Annotated[
    Path | None,
    typer.Option(
        "--contingencies",
        help="The trips of a contingency table (label from to share per row; "
        "configs/activsg2000_grid_contingencies.txt is the case's official N-1) instead of "
        "every line; --lines keeps the rows on the lines it names.",
    ),
]
TMaxOpt = Annotated[
    float | None, typer.Option("--t-max", help="How long the grid runs after the trip (s) (default 20).")
]
