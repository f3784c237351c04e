"""Shared CLI plumbing: option aliases, typed overrides, executors, and user errors as one line."""

from __future__ import annotations

import contextlib
import functools
import os
import select
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, get_args

import typer

from antisync.errors import ConfigError
from antisync.types import Backend, Executor
from antisync.validation import choice

EXIT_USAGE = 2

ConfigArg = Annotated[Path, typer.Argument(help="YAML config file (see configs/).", show_default=False)]
ResultArg = Annotated[
    Path,
    typer.Argument(
        help="HDF5 result file written by `antisync run` (or sweep, design), or a table of "
        "`antisync grid removal|trip --out`.",
        show_default=False,
    ),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="Override a config key, value parsed as YAML: --set realizations=5000 "
        "--set dynamics.dt=0.0005. Repeatable.",
    ),
]
DebugOpt = Annotated[bool, typer.Option("--debug", help="Show tracebacks for errors.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar or messages.")]


def one_of(option: str, literal: Any) -> Callable[[str], str]:
    """A Typer ``parser`` admitting the values of the ``Literal`` type ``literal``.

    Typer lists the choices in ``--help`` from the annotation; a value outside them is refused
    here as the CLI's one line (``antisync: error: --executor must be one of local, dask,
    got 'ray'``, exit 2) instead of Typer's multi-line usage box.
    """
    valid = get_args(literal)

    def parse(value: str) -> str:
        try:
            choice(option, value, valid)
        except ConfigError as exc:
            fail(str(exc))
        return value

    return parse


def backend_option(help_text: str) -> Any:
    """``--backend``, one of :data:`antisync.types.BACKENDS`."""
    return typer.Option(parser=one_of("--backend", Backend), help=help_text)


BackendOpt = Annotated[
    Backend | None, backend_option("Override `backend` (auto: cuda when a GPU is usable).")
]
ExecutorOpt = Annotated[
    Executor | None, typer.Option(parser=one_of("--executor", Executor), help="Override `executor`.")
]


def fail(message: str) -> None:
    typer.echo(f"antisync: error: {message}", err=True)
    raise typer.Exit(EXIT_USAGE)


def user_errors(func):
    """Print an AntisyncError (or an OSError: disk full, permission denied) as one line and
    exit 2; a traceback only with --debug."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from antisync.errors import AntisyncError

        debug = kwargs.get("debug", False)
        try:
            return func(*args, **kwargs)
        except AntisyncError as exc:
            if debug:
                raise
            # one line, always: a value quoted from the user's input may hold a newline
            fail(" ".join(str(exc).split("\n")).strip() or type(exc).__name__)
        except BrokenPipeError as exc:
            if stdout_closed():  # `antisync summary f | head -1`: the reader has what it wanted
                quiet_exit()
            if debug:
                raise
            fail(os_message(exc))
        except OSError as exc:  # the machine refused: a full disk, a read-only folder
            if debug:
                raise
            fail(os_message(exc))
        except KeyboardInterrupt:
            typer.echo("antisync: interrupted", err=True)
            raise typer.Exit(130) from None

    return wrapper


def stdout_closed() -> bool:
    """Whether standard output is a pipe whose reader has gone (``| head -1`` exited).

    A BrokenPipeError is then the reader's choice, not a failure; one from anything else (a
    pipe to another process) is not. On a pipe, ``poll`` reports POLLERR once no reader is
    left; where it cannot tell (no ``poll``), a broken pipe is taken to be standard output's.
    """
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):  # replaced by a test runner, or closed
        return False
    if not hasattr(select, "poll"):  # pragma: no cover - Windows
        return True
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(events & select.POLLERR for _, events in poller.poll(0))


def quiet_exit() -> None:
    """End quietly after standard output's reader went away: exit 0, no message.

    Everything the reader asked for was delivered (the commands that print write no files
    after their output). Standard output is pointed at the null device first, so that
    Python's final flush of what is still buffered cannot print "Exception ignored ...
    BrokenPipeError" on the way out.
    """
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    raise typer.Exit(0)


def flush_stdout() -> None:
    """Flush standard output at the program's end, quietly when its reader has gone (a pipe
    closed after the last write a command made: the buffer is flushed only at exit)."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        with contextlib.suppress(typer.Exit):
            quiet_exit()
    except (OSError, ValueError, AttributeError):
        pass


def os_message(exc: OSError) -> str:
    """``cannot write results/x.h5: No space left on device`` from an OSError."""
    what = exc.strerror or str(exc) or type(exc).__name__
    name = exc.filename
    return f"{name}: {what}" if name else what


def typed_values(**options) -> dict:
    """The CLI's typed options as config values, set as they are (never parsed as YAML):
    ``--out '#x.h5'`` is the file ``#x.h5`` and ``--out null`` the file ``null``."""
    return {
        key: (str(value) if isinstance(value, Path) else value)
        for key, value in options.items()
        if value is not None
    }


@contextlib.contextmanager
def dask_executor(cfg, *, workers: int | None, scheduler: str | None, quiet: bool):
    """A Dask executor when the options or ``cfg.executor`` ask for one (else ``None``),
    closed on exit: whoever creates an executor closes it."""
    from antisync.errors import AntisyncError

    if cfg.executor != "dask" and workers is None and scheduler is None:
        yield None
        return
    try:
        from antisync.execution.executors.dask import DaskExecutor
    except ImportError as exc:
        raise AntisyncError(
            f"the dask executor is not available here ({exc}); "
            "install antisync with its dependencies (pip install -e .)"
        ) from None
    ex = DaskExecutor.from_options(cfg, workers=workers, scheduler=scheduler, log=lambda m: info(m, quiet))
    try:
        yield ex
    finally:
        ex.close()


@contextlib.contextmanager
def writing(output: str):
    """What ``run`` and ``sweep`` do when the work stops early: Ctrl-C exits 130 saying how to
    resume; an OSError (a full disk, a file size limit, a folder turned read-only) is one line
    naming the output."""
    from antisync.errors import AntisyncError
    from antisync.execution.runner import Interrupted

    try:
        yield
    except Interrupted as exc:
        info(f"antisync: {exc}")
        raise typer.Exit(130) from None
    except OSError as exc:
        raise AntisyncError(
            f"cannot write {output}: {os_message(exc)}; finished chunks are kept: make room and "
            "rerun the same command with --resume"
        ) from None


def info(message: str, quiet: bool = False) -> None:
    if not quiet:
        print(message, file=sys.stderr)
