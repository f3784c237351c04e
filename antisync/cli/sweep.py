"""`antisync sweep CONFIG`: screen, symmetry-reduce and run a family of graphs into one HDF5 file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import (
    ConfigArg,
    DebugOpt,
    QuietOpt,
    SetOpt,
    backend_option,
    dask_executor,
    info,
    typed_values,
    user_errors,
    writing,
)
from antisync.types import Backend


@user_errors
def sweep(
    config: ConfigArg,
    realizations: Annotated[int | None, typer.Option(help="Override `realizations` (main stage).")] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Override `output` (HDF5 path).")] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Finish an interrupted sweep in the same file.")
    ] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing output file.")] = False,
    backend: Annotated[
        Backend | None,
        backend_option("Override `backend` (auto: cuda when a GPU is usable; screening is always cpu)."),
    ] = None,
    threads: Annotated[int | None, typer.Option(help="CPU threads (default: all cores).")] = None,
    workers: Annotated[
        int | None, typer.Option(help="Dask: start a LocalCluster with this many workers.")
    ] = None,
    scheduler: Annotated[str | None, typer.Option(help="Dask: address of an existing scheduler.")] = None,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run the sweep of CONFIG (a config with a `sweep:` section, see configs/atlas6.yaml).

    Graphs whose realizations end in a stable non-synchronized state are excluded by a
    screening (listed by `antisync summary`).

    Directed edges mapped onto each other by a graph automorphism are integrated once.

    Killed at any moment, the same command with --resume finishes it.
    """
    from antisync.errors import AntisyncError
    from antisync.sweeps import load_sweep, run_sweep

    if resume and overwrite:
        raise AntisyncError("--resume and --overwrite exclude each other: choose one")
    values = typed_values(realizations=realizations, output=out, backend=backend, threads=threads)
    sw = load_sweep(config, list(set_ or []), values)
    with dask_executor(sw.base, workers=workers, scheduler=scheduler, quiet=quiet) as ex:
        with writing(sw.output):
            path = run_sweep(
                sw,
                resume=resume,
                overwrite=overwrite,
                executor=ex,
                progress=None if not quiet else False,
                log=lambda m: info(m, quiet),
            )
    info(f"wrote {path}  (next: antisync summary {path}; antisync report {path})", quiet)
