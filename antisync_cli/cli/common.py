"""Shared CLI plumbing: option aliases and turning user errors into one line + exit code 2."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Annotated

import typer

EXIT_USAGE = 2

ConfigArg = Annotated[Path, typer.Argument(help="YAML config file (see configs/).", show_default=False)]
ResultArg = Annotated[
    Path, typer.Argument(help="HDF5 result file written by `antisync run`.", show_default=False)
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option("--set", help="Override a config key, value parsed as YAML: --set realizations=5000 "
                 "--set dynamics.dt=0.0005. Repeatable."),
]
DebugOpt = Annotated[bool, typer.Option("--debug", help="Show tracebacks for errors.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar or messages.")]


def fail(message: str) -> None:
    typer.echo(f"antisync: error: {message}", err=True)
    raise typer.Exit(EXIT_USAGE)


def user_errors(func):
    """Print an AntisyncError as one line and exit 2 (a traceback only with --debug)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from antisync_cli.errors import AntisyncError

        debug = kwargs.get("debug", False)
        try:
            return func(*args, **kwargs)
        except AntisyncError as exc:
            if debug:
                raise
            fail(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        except KeyboardInterrupt:
            typer.echo("antisync: interrupted", err=True)
            raise typer.Exit(130) from None

    return wrapper


def info(message: str, quiet: bool = False) -> None:
    if not quiet:
        print(message, file=sys.stderr)
