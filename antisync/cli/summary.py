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

    JSON is one object for run and sweep files alike: {"kind": "run" | "sweep", "file",
    "complete", "records": [...], "config_yaml", and for sweeps "excluded", "top", "screen",
    "symmetry", "thresholds", ...} (see antisync.api.summarize). CSV holds the records only;
    the table ends with warnings and, for a sweep, the excluded graphs.
    """
    import json

    from antisync.api import summarize
    from antisync.report.tables import format_records, format_sweep
    from antisync.store import is_sweep_file, records
    from antisync.sweeps import sweep_summary

    if format == "json":
        typer.echo(json.dumps(summarize(results), indent=2))
    elif is_sweep_file(results):
        typer.echo(format_sweep(sweep_summary(results), format))
    else:
        typer.echo(format_records(records(results), format))
