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
    grid: Annotated[
        list[str] | None,
        typer.Option(
            "--grid",
            help="Sweep a config key over values, every combination with the other --grid keys: "
            "--grid model.phase_lag=0,0.1,0.2 (sets sweep.grid.KEY, replacing the config's list; "
            "values parsed as YAML). Repeatable, once per key; at most 10,000 jobs. On a run "
            "config (graph:, no sweep:) it sweeps that graph.",
        ),
    ] = None,
    zip_: Annotated[
        list[str] | None,
        typer.Option(
            "--zip",
            help="Like --grid, but every --zip key moves together (equal lengths): "
            "--zip model.inertia=0.5,1,2 --zip model.damping=1,0.5,0.25. Repeatable, once per key.",
        ),
    ] = None,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run the sweep of CONFIG (a config with a `sweep:` section, see configs/atlas6.yaml,
    or a grid over config keys, see configs/lollipop_grid.yaml and docs/sweeps.md).

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
    sw = load_sweep(config, list(set_ or []), values, grid=list(grid or []), zip_=list(zip_ or []))
    for note in sw.notes:  # an option that replaced the config's list of a key
        info(note, quiet)
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
