"""`antisync sweep CONFIG`: screen, symmetry-reduce and run a family of graphs into one HDF5 file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from antisync_cli.cli.common import ConfigArg, DebugOpt, QuietOpt, SetOpt, info, user_errors


@user_errors
def sweep(
    config: ConfigArg,
    realizations: Annotated[int | None, typer.Option(help="Override `realizations` (main stage).")] = None,
    out: Annotated[Path | None, typer.Option("--out", "-o", help="Override `output` (HDF5 path).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Finish an interrupted sweep in the same file.")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing output file.")] = False,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Run the sweep of CONFIG (a config with a `sweep:` section, see configs/atlas6.yaml).

    Every graph is screened first: graphs whose realizations end in a stable non-synchronized
    state are excluded (and listed by `antisync summary`). Directed edges equivalent under
    a graph automorphism are integrated once. Killed at any moment, `--resume` finishes it.
    """
    from antisync_cli.errors import AntisyncError
    from antisync_cli.runner import Interrupted
    from antisync_cli.sweeps import load_sweep, run_sweep

    overrides = list(set_ or [])
    for key, value in (("realizations", realizations), ("output", out)):
        if value is not None:
            overrides.append(f"{key}={value}")
    sw = load_sweep(config, overrides)
    if resume and overwrite:
        raise AntisyncError("--resume and --overwrite exclude each other: choose one")
    try:
        path = run_sweep(sw, resume=resume, overwrite=overwrite,
                         progress=None if not quiet else False, log=lambda m: info(m, quiet))
    except Interrupted as exc:
        info(f"antisync: {exc}")
        raise typer.Exit(130) from None
    info(f"wrote {path}  (next: antisync summary {path}; antisync report {path})", quiet)
