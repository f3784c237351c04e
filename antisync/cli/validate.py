"""`antisync validate CONFIG`: check a config (and build its graph) without running it."""

from __future__ import annotations

import typer

from antisync.cli.common import ConfigArg, DebugOpt, SetOpt, user_errors


@user_errors
def validate(config: ConfigArg, set_: SetOpt = None, debug: DebugOpt = False) -> None:
    """Check CONFIG: keys, values, graph, edges. Prints the resolved config on success."""
    from antisync.plan.config import load_config
    from antisync.plan.jobs import make_job, stiffness_note

    keys = _top_keys(config)
    if "design" in keys:
        from antisync.optimize.config import load_design_config

        cfg, spec = load_design_config(config, list(set_ or []))
        problem = spec.problem(cfg)
        typer.echo(cfg.resolved().to_yaml().rstrip())
        typer.echo(f"design: {spec.to_dict()}")
        typer.echo(
            f"# ok: design of {len(problem.links)} link weight(s) of {problem.n_nodes} nodes "
            f"({int(problem.candidate.sum())} candidate(s)), budget {problem.budget.total:g}, "
            f"objective {spec.objective}, into {spec.output}"
        )
        return
    if "sweep" in keys:
        from antisync.sweeps import family_graphs, load_sweep
        from antisync.sweeps.stages import check_sweep

        sw = load_sweep(config, list(set_ or []))
        entries = family_graphs(sw)  # builds every graph, selects edges, finds orbits
        backend = preflight(sw.base, [])
        check_sweep(sw, entries, backend)  # every job's checks, as `antisync sweep` makes them first
        typer.echo(sw.to_yaml().rstrip())
        typer.echo(
            f"# ok: sweep of {len(entries)} graph(s), {sum(len(e.edges) for e in entries)} directed "
            f"edge(s) in {sum(len(e.representatives) for e in entries)} orbit(s), "
            f"{len(sw.thresholds)} threshold(s), {sw.repeats} repeat(s)"
            + (f", {len(sw.points)} grid point(s)" if sw.points else "")
            + (f", {_budget(sw.base)}" if sw.base.stop.active else "")
            + "; screening not run"
        )
        return
    cfg = load_config(config, list(set_ or []))
    if cfg.sync.give_up is not None:
        # sync.give_up is for `antisync grid --removal` only: checked as that command checks it
        from antisync.grids.removal_config import planned_lines

        lines = planned_lines(cfg, None, 1.0, False)
        typer.echo(cfg.resolved().to_yaml().rstrip())
        rule = cfg.sync.give_up
        typer.echo(
            f"# ok: a config for antisync grid --removal ({len(lines)} non-bridge lines; sync.give_up "
            f"after {rule['after']:g} s, band {rule['band']:g}; antisync run and sweep refuse give_up)"
        )
        return
    job = make_job(cfg)
    preflight(cfg, [job])
    typer.echo(cfg.resolved().to_yaml().rstrip())
    run = (
        f"{job.integrations_per_realization - 1} damaged variant(s), {_budget(cfg)}"
        if job.kuramoto
        else f"no Kuramoto integration (measures: {', '.join(cfg.measures)})"
    )
    typer.echo(
        f"# ok: graph {job.name} with {len(job.nodes)} nodes, {len(job.edges)} directed edge(s), {run}"
    )
    note = stiffness_note(job)
    if note is not None:
        typer.echo(f"# note: {note}")


def _budget(cfg) -> str:
    """``N realizations``, or with a stopping rule the budget and its looks."""
    if not cfg.stop.active:
        return f"{cfg.realizations:,} realizations"
    looks = ", ".join(f"{n:,}" for n in cfg.stop_looks)
    return f"up to {cfg.realizations:,} realizations (stop {cfg.stop.when}: looks at {looks})"


def preflight(cfg, jobs) -> str:
    """The checks ``antisync run`` makes before it writes anything: the km_nnc twins and what
    the backend implements (cuda: options and node counts), for the backend the config asks
    for. Whether this machine has a GPU is a note, not an error: a config for the cluster is
    valid on a laptop. Returns the backend checked."""
    from antisync.errors import AntisyncError
    from antisync.execution.compute import check_backend, check_job
    from antisync.kernels.backends import resolve_backend
    from antisync.measures.pipeline import with_nnc

    backend = cfg.backend
    try:
        backend, _ = resolve_backend(cfg.backend)
    except AntisyncError as exc:
        typer.echo(f"# note: {exc}")
    check_backend(cfg, backend)
    for job in with_nnc(jobs):
        check_job(job, backend)
    return backend


def _top_keys(path) -> set:
    """The YAML file's top-level keys (``sweep:``, ``design:`` choose the loader; errors are
    left to the loaders)."""
    import yaml

    from antisync.errors import AntisyncError
    from antisync.plan.config import read_config_text

    try:
        # the config reader: a FIFO, a device or a huge file is refused, never read
        raw = yaml.safe_load(read_config_text(path))
    except (AntisyncError, OSError, yaml.YAMLError):
        return set()
    return set(raw) if isinstance(raw, dict) else set()
