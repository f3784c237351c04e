"""`antisync report RESULTS.h5`: the paper's figures from a result file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync_cli.cli.common import DebugOpt, QuietOpt, ResultArg, info, user_errors


@user_errors
def report(
    results: ResultArg,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Folder for figures (default: next to the file).")
    ] = None,
    pdf: Annotated[bool, typer.Option("--pdf", help="Also write PDF versions.")] = False,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Write Fig. 1-style figures: graph coloured by Lambda^KM, <F_beta> vs beta, (tau0, tau) histograms."""
    from antisync_cli.report.figures import write_report
    from antisync_cli.summary import read_views

    views = read_views(results)
    folder = out or results.with_suffix("").with_name(results.stem + "_figures")
    paths = write_report(views, folder, pdf=pdf)
    for p in paths:
        info(f"wrote {p}", quiet)
