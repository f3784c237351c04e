"""`antisync summary RESULTS.h5`: per-(edge, beta) estimates as a table, JSON or CSV."""

from __future__ import annotations

from typing import Annotated, Literal

import typer

from antisync_cli.cli.common import DebugOpt, ResultArg, user_errors

Format = Literal["table", "json", "csv"]


@user_errors
def summary(
    results: ResultArg,
    format: Annotated[Format, typer.Option("--format", "-f", help="table, json or csv.")] = "table",
    debug: DebugOpt = False,
) -> None:
    """Print <F_beta>, Lambda^KM, <tau0> with standard errors and status counts."""
    from antisync_cli.report.tables import format_records
    from antisync_cli.summary import records

    typer.echo(format_records(records(results), format))
