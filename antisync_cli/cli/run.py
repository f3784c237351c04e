"""`antisync run CONFIG`: run one config into an HDF5 file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync_cli.cli.common import ConfigArg, DebugOpt, QuietOpt, SetOpt, info, user_errors


@user_errors
def run(
    config: ConfigArg,
    realizations: Annotated[int | None, typer.Option(help="Override `realizations`.")] = None,
    seed: Annotated[int | None, typer.Option(help="Override `seed`.")] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Override `output` (HDF5 path).")] = None,
    backend: Annotated[str | None, typer.Option(help="cpu, cuda or auto.")] = None,
    executor: Annotated[str | None, typer.Option(help="local or dask.")] = None,
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
    from antisync_cli.config import load_config
    from antisync_cli.errors import AntisyncError
    from antisync_cli.runner import Interrupted, run_config

    overrides = list(set_ or [])
    for key, value in (("realizations", realizations), ("seed", seed), ("output", out),
                       ("backend", backend), ("executor", executor), ("threads", threads)):
        if value is not None:
            overrides.append(f"{key}={value}")
    cfg = load_config(config, overrides)
    if resume and overwrite:
        raise AntisyncError("--resume and --overwrite exclude each other: choose one")
    dask_executor = None
    if cfg.executor == "dask" or workers is not None or scheduler is not None:
        from antisync_cli.executors.dask import DaskExecutor

        dask_executor = DaskExecutor.from_options(cfg, workers=workers, scheduler=scheduler,
                                                  log=lambda m: info(m, quiet))
    try:
        path = run_config(cfg, resume=resume, overwrite=overwrite, progress=None if not quiet else False,
                          executor=dask_executor, log=lambda m: info(m, quiet))
    except Interrupted as exc:
        info(f"antisync: {exc}")
        raise typer.Exit(130) from None
    finally:
        # run_jobs closes its executor, but not when it fails before starting (output exists)
        if dask_executor is not None:
            dask_executor.close()
    info(f"wrote {path}  (next: antisync summary {path}; antisync report {path})", quiet)
