"""`antisync design CONFIG`: weights under a budget that make a network synchronize fastest."""

from __future__ import annotations

from typing import Annotated

import typer

from antisync.cli.common import (
    ConfigArg,
    DebugOpt,
    QuietOpt,
    SetOpt,
    info,
    typed_values,
    user_errors,
    writing,
)


@user_errors
def design(
    config: ConfigArg,
    seed: Annotated[int | None, typer.Option(help="Override `seed` (the training stream's).")] = None,
    threads: Annotated[int | None, typer.Option(help="CPU threads (default: all cores).")] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Continue an interrupted design in the same file.")
    ] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing design file.")] = False,
    figures: Annotated[bool, typer.Option(help="Draw the design's figures next to its file.")] = True,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Design the link weights of CONFIG's network under its `design:` budget (docs/design.md):
    every iterate, the baselines and a paired comparison on fresh starts into an HDF5 file."""
    from antisync.errors import AntisyncError
    from antisync.optimize.config import load_design_config
    from antisync.optimize.run import run_design
    from antisync.report.design import draw_design

    if resume and overwrite:
        raise AntisyncError("--resume and --overwrite exclude each other: choose one")
    cfg, spec = load_design_config(config, list(set_ or []), typed_values(seed=seed, threads=threads))
    with writing(spec.output):
        path = run_design(
            cfg,
            spec,
            resume=resume,
            overwrite=overwrite,
            progress=False if quiet else None,
            threads=cfg.threads,
            log=lambda m: info(m, quiet),
        )
    if figures:
        for out in draw_design(path):
            info(f"wrote {out}", quiet)
    info(f"wrote {path}  (next: antisync report {path})", quiet)
