"""`antisync paper`: every figure and table of the paper at reduced realizations, with a README."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, backend_option, info, user_errors
from antisync.types import Backend


@user_errors
def paper(
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for files, figures and README.md.")] = Path(
        "results/paper"
    ),
    scale: Annotated[
        float, typer.Option(help="Multiply every step's realizations (1: ~30 min on 2 cores).")
    ] = 1.0,
    only: Annotated[list[str] | None, typer.Option(help="Run only this step (repeatable).")] = None,
    threads: Annotated[int | None, typer.Option(help="CPU threads (default: all cores).")] = None,
    backend: Annotated[
        Backend, backend_option("Backend of every step (auto: cuda when a GPU is usable).")
    ] = "cpu",
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Start again instead of resuming.")] = False,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="Print the plan and its time estimate.")] = False,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run the paper's experiments (Figs. 1-4, 5b, 6, 7, Table 1) and write OUT/README.md.

    Finished steps are kept and interrupted ones resumed, so rerunning is cheap.
    """
    from antisync.errors import AntisyncError
    from antisync.paper.make import STEPS, make_paper, plan

    if not scale > 0:
        raise AntisyncError(f"--scale must be positive, got {scale}")
    names = [s.name for s in STEPS]
    for name in only or []:
        if name not in names:
            raise AntisyncError(f"--only {name!r}: steps are {', '.join(names)}")
    if dry_run:
        typer.echo(plan(scale))
        return
    make_paper(
        out,
        scale=scale,
        overwrite=overwrite,
        threads=threads,
        backend=backend,
        only=tuple(only or ()),
        progress=None if not quiet else False,
        log=lambda m: info(m, quiet),
    )
