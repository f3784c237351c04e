"""`antisync validate CONFIG`: check a config (and build its graph) without running it."""

from __future__ import annotations

import typer

from antisync_cli.cli.common import ConfigArg, DebugOpt, SetOpt, user_errors


@user_errors
def validate(config: ConfigArg, set_: SetOpt = None, debug: DebugOpt = False) -> None:
    """Check CONFIG: keys, values, graph, edges. Prints the resolved config on success."""
    from antisync_cli.config import load_config
    from antisync_cli.jobs import make_job

    cfg = load_config(config, list(set_ or []))
    job = make_job(cfg)
    typer.echo(cfg.resolved().to_yaml().rstrip())
    typer.echo(
        f"# ok: graph {job.name} with {len(job.nodes)} nodes, {len(job.edges)} directed edge(s), "
        f"{len(job.variant_edge)} damaged variant(s), {cfg.realizations:,} realizations"
    )
