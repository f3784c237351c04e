"""`antisync summary RESULTS.h5`: per-(edge, beta) estimates as a table, JSON or CSV."""

from __future__ import annotations

from typing import Annotated, Literal

import typer

from antisync.cli.common import DebugOpt, ResultArg, user_errors

Format = Literal["table", "json", "csv"]


@user_errors
def summary(
    results: ResultArg,
    format: Annotated[Format, typer.Option("--format", "-f", help="table, json or csv.")] = "table",
    debug: DebugOpt = False,
) -> None:
    """Print <F_beta>, Lambda^KM, <tau0> with standard errors and status counts.

    For a sweep file, JSON is an object {"records": [...], "excluded": [...], "top": [...],
    "screen": [...], "symmetry": {...}} (a run file gives a plain list of records); CSV
    holds the records only; the table ends with the excluded graphs.
    """
    from antisync.report.tables import format_records, format_sweep
    from antisync.store import is_sweep_file, records
    from antisync.sweeps import sweep_summary

    if is_sweep_file(results):
        typer.echo(format_sweep(sweep_summary(results), format))
    else:
        typer.echo(format_records(records(results), format))
