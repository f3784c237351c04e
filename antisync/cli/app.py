"""The `antisync` command: one Typer app, one module per subcommand."""

from __future__ import annotations

import typer

from antisync.cli.paper import paper
from antisync.cli.report import report
from antisync.cli.run import run
from antisync.cli.summary import summary
from antisync.cli.sweep import sweep
from antisync.cli.validate import validate

app = typer.Typer(
    name="antisync",
    help="Antifragility of Kuramoto synchronization to link damage (tau0, F_beta, Lambda).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.command()(run)
app.command()(sweep)
app.command()(summary)
app.command()(report)
app.command()(validate)
app.command()(paper)


def main() -> None:
    app()
