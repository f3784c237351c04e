"""`antisync report FILE`: the paper's figures from a result file, a sweep's and a design's, and
the figures of `antisync grid`'s JSON tables (a line removal, the engineer's N-1)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, info, user_errors

ReportArg = Annotated[
    Path,
    typer.Argument(
        help="HDF5 result file (antisync run, sweep, design) or JSON table (antisync grid "
        "--removal/--trip --out).",
        show_default=False,
    ),
]


@user_errors
def report(
    results: ReportArg,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Folder for figures (default: next to the file).")
    ] = None,
    pdf: Annotated[bool, typer.Option("--pdf", help="Also write PDF versions.")] = False,
    top: Annotated[
        int,
        typer.Option(
            "--top",
            help="Graphs of more than 20 nodes or 40 links: draw the TOP most antifragile and TOP "
            "most fragile links strong.",
        ),
    ] = 10,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Write Fig. 1-style figures: graph coloured by Lambda^KM, <F_beta> vs beta, (tau0, tau) histograms.

    Files are named after the config's `name:` (NAME_graph.png, NAME_F_beta.png,
    NAME_histograms.png, ...); index.md lists them with the question each answers.

    For a graph of more than 20 nodes or 40 links, instead of the per-link labels of Fig. 1a:
    every link's Lambda sorted with its 95% interval, the network with the --top most
    antifragile and most fragile links strong, and Lambda^KM against Lambda^xi2 and Lambda^RW
    (Spearman rho, sign agreement over resolved links).

    For a sweep file: the Fig. 3 ranking, Table 1 (Markdown, CSV, LaTeX), Fig. 4 histograms,
    Fig. 2 for lollipop sweeps and Fig. 6 for threshold sweeps, with an index.md.

    For a JSON table of `antisync grid`: a line removal's grid coloured by each line's speedup
    and by its change of P_sync, or the engineer's N-1 coloured by critical clearing time (or
    frequency swing), with the table in index.md.
    """
    from antisync.errors import AntisyncError
    from antisync.report.figures import write_file_report
    from antisync.report.grid_tables import table_kind, write_table_report
    from antisync.store import is_sweep_file
    from antisync.store.design_file import is_design_file

    if top < 1:
        raise AntisyncError(f"--top must be a positive number of links, got {top}")
    folder = out or results.with_suffix("").with_name(results.stem + "_figures")
    if folder.exists() and not folder.is_dir():
        raise AntisyncError(f"report folder {folder} is a file; give --out a folder (new or existing)")
    kind = table_kind(results)  # None: an HDF5 file
    if kind is not None:
        paths = write_table_report(results, folder, pdf=pdf, kind=kind)
    elif is_design_file(results):
        from antisync.report.design import draw_design

        paths = draw_design(results, folder)
    elif is_sweep_file(results):
        # a sweep: Fig. 3 ranking, Table 1, Fig. 4, Fig. 2 (lollipops), Fig. 6 (thresholds)
        from antisync.report.sweep import write_sweep_report

        paths = write_sweep_report(results, folder, pdf=pdf)
    else:
        paths = write_file_report(results, folder, pdf=pdf, top=top)
    for p in paths:
        info(f"wrote {p}", quiet)
