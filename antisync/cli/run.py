"""`antisync run CONFIG`: run one config into an HDF5 file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync.cli.common import (
    BackendOpt,
    ConfigArg,
    DebugOpt,
    ExecutorOpt,
    QuietOpt,
    SetOpt,
    dask_executor,
    info,
    typed_values,
    user_errors,
    writing,
)


@user_errors
def run(
    config: ConfigArg,
    realizations: Annotated[int | None, typer.Option(help="Override `realizations`.")] = None,
    seed: Annotated[int | None, typer.Option(help="Override `seed`.")] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Override `output` (HDF5 path).")] = None,
    backend: BackendOpt = None,
    executor: ExecutorOpt = None,
    workers: Annotated[
        int | None, typer.Option(help="Dask: start a LocalCluster with this many workers.")
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="Dask: address of an existing scheduler (tcp://host:8786).")
    ] = None,
    threads: Annotated[int | None, typer.Option(help="CPU threads (default: all cores).")] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Finish an interrupted run in the same output file.")
    ] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing output file.")] = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run the experiment of CONFIG and write tau0/tau(beta) statistics, Lambda and histograms to HDF5."""
    from antisync.errors import AntisyncError
    from antisync.execution.runner import run_config
    from antisync.plan.config import load_config

    if resume and overwrite:
        raise AntisyncError("--resume and --overwrite exclude each other: choose one")
    values = typed_values(
        realizations=realizations, seed=seed, output=out, backend=backend, executor=executor, threads=threads
    )
    cfg = load_config(config, list(set_ or []), values)
    with dask_executor(cfg, workers=workers, scheduler=scheduler, quiet=quiet) as ex:
        with writing(cfg.output):
            path = run_config(
                cfg,
                resume=resume,
                overwrite=overwrite,
                progress=None if not quiet else False,
                executor=ex,
                log=lambda m: info(m, quiet),
            )
    info(f"wrote {path}  (next: antisync summary {path}; antisync report {path})", quiet)
