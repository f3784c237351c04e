"""The `antisync` command: one Typer app, one module per subcommand."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Annotated

import typer
from typer.core import TyperGroup

from antisync._version import __version__
from antisync.cli.capabilities import capabilities
from antisync.cli.common import fail, flush_stdout
from antisync.cli.design import design
from antisync.cli.grid.flags import grid
from antisync.cli.grid.removal import removal as grid_removal
from antisync.cli.grid.static import static as grid_static
from antisync.cli.grid.trip import trip as grid_trip
from antisync.cli.paper import paper
from antisync.cli.report import report
from antisync.cli.run import run
from antisync.cli.summary import summary
from antisync.cli.sweep import sweep
from antisync.cli.validate import validate

#: click's UsageError (BadParameter, NoSuchOption, MissingParameter, "No such command" ...),
#: found from typer's public BadParameter: recent typer carries its own copy of click, older
#: typer uses click itself, and either way BadParameter is a UsageError
UsageError = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


class OneLineUsageGroup(TyperGroup):
    """The app's command group: a bad option value, an unknown option or command, a missing
    argument is the CLI's one line (``antisync: error: run: invalid value for
    '--realizations': ... (see antisync run --help)``, exit 2) like every other error of the
    CLI, instead of click's multi-line usage box.

    Click raises a ``UsageError`` while it parses the command line: the group's own options
    in :meth:`make_context`, the command's name and options in :meth:`invoke`.
    """

    def make_context(self, info_name, args, parent=None, **extra):
        with usage_errors_as_one_line():
            return super().make_context(info_name, args, parent=parent, **extra)

    def invoke(self, ctx):
        # click names the subcommand once it is resolved; some errors of its options (a
        # missing value: "Option '--threads' requires an argument") carry no context of their own
        with usage_errors_as_one_line(lambda: ctx.invoked_subcommand):
            return super().invoke(ctx)


@contextlib.contextmanager
def usage_errors_as_one_line(subcommand: Callable[[], str | None] = lambda: None):
    """Turn a click ``UsageError`` raised inside into the CLI's one line, exit 2."""
    try:
        yield
    except UsageError as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":  # bare `antisync`: the help is the answer
            raise
        fail(usage_message(exc, subcommand()))


#: The hidden subcommand of ``antisync grid`` that reads the one-command form
#: (``antisync grid CONFIG --removal``; :mod:`antisync.cli.grid.flags`).
GRID_FLAGS = "flags"


class GridGroup(OneLineUsageGroup):
    """``antisync grid``: the subcommands ``static``, ``removal`` and ``trip``; a command line
    that starts with anything else (a config path, an option) is the one-command form of
    before them, read by the hidden ``flags`` subcommand."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ctx.help_option_names:
            args = [GRID_FLAGS, *args]
        return super().parse_args(ctx, args)


def usage_message(exc: Exception, subcommand: str | None = None) -> str:
    """``run: invalid value for '--threads': ... (see antisync run --help)``: the subcommand,
    click's message with a lower-case start, and the help that lists what is valid."""
    names = []
    ctx = getattr(exc, "ctx", None)
    while ctx is not None and ctx.parent is not None:  # the root's name is the program's name
        if ctx.info_name != GRID_FLAGS:  # the one-command form reads as `antisync grid`
            names.append(ctx.info_name)
        ctx = ctx.parent
    command = " ".join(reversed(names)) or subcommand or ""
    message = " ".join(exc.format_message().splitlines()).strip().rstrip(".")
    message = message[:1].lower() + message[1:]
    if not command:
        return f"{message} (see antisync --help)"
    return f"{command}: {message} (see antisync {command} --help)"


app = typer.Typer(
    name="antisync",
    help="Antifragility of Kuramoto synchronization to link damage (tau0, F_beta, Lambda).",
    cls=OneLineUsageGroup,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _print_version(value: bool) -> None:
    """``--version``: print ``antisync <version>`` and exit 0, before any command runs."""
    if value:
        typer.echo(f"antisync {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    """The options of ``antisync`` itself (before a command)."""


app.command()(run)
app.command()(sweep)
app.command()(summary)
app.command()(report)
app.command()(validate)
app.command()(paper)
grid_app = typer.Typer(
    name="grid",
    help="A power grid's lines: static indicators, the dynamic N-1 by random starts, or the "
    "engineer's N-1 with faults and critical clearing times (docs/power_grids.md).",
    cls=GridGroup,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
grid_app.command("static")(grid_static)
grid_app.command("removal")(grid_removal)
grid_app.command("trip")(grid_trip)
grid_app.command(GRID_FLAGS, hidden=True)(grid)
app.add_typer(grid_app)
app.command()(capabilities)
app.command()(design)


def main() -> None:
    """The ``antisync`` program. Whatever ends it, standard output is flushed here, where a
    reader that went away (``antisync summary f | head -1``) ends it quietly rather than
    with Python's "Exception ignored ... BrokenPipeError" (see :func:`flush_stdout`)."""
    try:
        app()
    finally:
        flush_stdout()
