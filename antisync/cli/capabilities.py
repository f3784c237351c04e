"""`antisync capabilities`: what runs where, the dispatch table that runs the chunks."""

from __future__ import annotations

import typer


def capabilities() -> None:
    """Print what runs where: every model, lambda.method, integrator, backend and precision.

    A markdown table (docs/models.md, "What runs where"): "runs", or a footnote with the
    one-line message a run of a refused combination gets, or what of a CUDA run stays on the CPU.
    """
    from antisync.execution.capabilities import table

    typer.echo(table(), nl=False)
