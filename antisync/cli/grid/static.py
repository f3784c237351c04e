"""`antisync grid static CONFIG`: the static indicators of each line's removal."""

from __future__ import annotations

from typing import Annotated

import typer

from antisync.cli.common import DebugOpt, QuietOpt, SetOpt, typed_values, user_errors
from antisync.cli.grid.options import BetaOpt, GridConfigArg, LinesOpt, TopOpt, check_top


@user_errors
def static(
    config: GridConfigArg,
    lines: LinesOpt = None,
    beta: BetaOpt = None,
    top: TopOpt = None,
    threads: Annotated[
        int | None,
        typer.Option(hidden=True, help="Checked as `antisync run` checks it; the table runs on one core."),
    ] = None,
    set_: SetOpt = None,
    quiet: QuietOpt = False,
    debug: DebugOpt = False,
) -> None:
    """Rank the lines by the locked state after each one's removal: margin, lambda2, largest load."""
    from antisync.api.grids import static as static_table
    from antisync.plan.config import load_config

    check_top(top)
    cfg = load_config(config, list(set_ or []), typed_values(threads=threads))
    res = static_table(cfg, lines=lines, beta=1.0 if beta is None else beta, progress=not quiet)
    typer.echo(res.to_markdown(top=top))
