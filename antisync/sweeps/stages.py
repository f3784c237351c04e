"""Running a sweep: screening, the main stage and the top stage, into one result file.

:func:`run_sweep` locks the output once, screens every graph of the family (cached per graph
in the journal and in the file), runs one job per (kept graph, threshold, repeat) on the
representative edges (:func:`main_jobs`), then the top stage on the most antifragile edge of
the best-ranked graphs (:func:`top_jobs`). The sweep's metadata (screening, orbits, jobs) is
written at every checkpoint (:func:`antisync.store.write_sweep_meta`), so a sweep killed at
any moment and rerun with ``resume=True`` ends with the same numbers as an uninterrupted one.
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

from tqdm import tqdm

from antisync.errors import ConfigError, StoreError
from antisync.kernels.backends import resolve_backend
from antisync.physics import graphs as graphs_mod
from antisync.plan.config import Config
from antisync.plan.jobs import make_job
from antisync.sweeps.analysis import ranking
from antisync.sweeps.families import GraphEntry, family_graphs
from antisync.sweeps.points import GridPoint, number_name, point_label, point_suffix
from antisync.sweeps.results import sweep_summary
from antisync.sweeps.schema import Sweep

__all__ = ["check_sweep", "main_jobs", "run_sweep", "top_jobs"]


def _job_name(graph: str, threshold: float, repeat: int, sweep: Sweep, point: GridPoint | None = None) -> str:
    name = graph
    if point is not None:
        name += point_suffix(point, sweep.axes)
    if len(sweep.thresholds) > 1 and (point is None or point.threshold is None):
        name += f"_r{number_name(threshold)}"  # 0.99 and 0.9900001 are two names
    if sweep.repeats > 1:
        name += f"_rep{repeat}"
    return name


def _job_config(
    sweep: Sweep,
    entry: GraphEntry,
    edges: list,
    *,
    threshold: float,
    seed: int,
    betas: tuple,
    realizations: int | None = None,
    name: str,
    point: GridPoint | None = None,
) -> Config:
    base = sweep.base if point is None else point.config
    return replace(
        base,
        name=name,
        graph=entry.spec,
        edges=[graphs_mod.edge_label(*e) for e in edges],
        betas=tuple(betas),
        seed=base.seed + seed - sweep.base.seed,
        realizations=realizations or base.realizations,
        dynamics=replace(base.dynamics, threshold=threshold),
    )


def main_jobs(sweep: Sweep, entries: list[GraphEntry], *, progress: bool = False) -> tuple[list, list[dict]]:
    """Jobs of the main stage (representative edges only) and their descriptions.

    One job per (graph, grid point, threshold, repeat); a point that sets the threshold has
    only its own. The description of a grid's job has its ``point`` (``{key: value}``).
    ``progress``: a bar while the jobs are built (their coupling arrays take a few
    milliseconds each: seconds for a grid of thousands of points).

    Raises
    ------
    ConfigError
        Two jobs would have the same name (:func:`_refuse_shared_names`), before any is built.
    """
    plan = []
    for entry in entries:
        for point in sweep.points or (None,):
            thresholds = sweep.thresholds if point is None or point.threshold is None else (point.threshold,)
            for t in thresholds:
                for k in range(sweep.repeats):
                    name = _job_name(entry.name, t, k, sweep, point)
                    desc = {"job": name, "graph": entry.name, "threshold": t, "repeat": k, "stage": "main"}
                    if point is not None:
                        desc["point"] = point.as_dict()
                    plan.append((entry, point, desc))
    _refuse_shared_names([desc for _, _, desc in plan], sweep)
    jobs, meta = [], []
    bar = tqdm(
        total=len(plan),
        unit="job",
        desc="planning",
        disable=not progress or len(plan) < 500,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    for entry, point, desc in plan:
        k = desc["repeat"]
        cfg = _job_config(
            sweep,
            entry,
            entry.representatives,
            threshold=desc["threshold"],
            seed=sweep.base.seed + k,
            betas=sweep.base.betas if k == 0 else (),
            name=desc["job"],
            point=point,
        )
        jobs.append(make_job(cfg, graph=entry.graph, name=desc["job"], command="sweep"))
        meta.append(desc)
        bar.update(1)
    bar.close()
    return jobs, meta


def _describe(desc: dict, sweep: Sweep) -> str:
    """A main-stage job in words: its graph, point, threshold and repeat where they vary."""
    parts = [f"graph {desc['graph']}" + (" (top stage)" if desc.get("stage") == "top" else "")]
    if "point" in desc:
        parts.append(f"grid point {point_label(desc['point'])}")
    elif len(sweep.thresholds) > 1 and desc.get("stage") != "top":
        parts.append(f"threshold {desc['threshold']!r}")
    if sweep.repeats > 1 and desc.get("stage") != "top":
        parts.append(f"repeat {desc['repeat']}")
    return " ".join(parts)


def _refuse_shared_names(descs: list[dict], sweep: Sweep) -> None:
    """Refuse two jobs of one name: the file keeps one group per name, so one of them would
    be shown with the other's numbers. Point names are injective on the values
    (:func:`~antisync.sweeps.points.point_suffix`); this is the guard for anything else (a
    graph named ``g_top`` beside the top-stage job of a graph ``g``, say)."""
    clash = _first_shared_name(descs)
    if clash is not None:
        other, desc = clash
        raise ConfigError(
            f"{_describe(other, sweep)} and {_describe(desc, sweep)} would both be job "
            f"{desc['job']!r} (one would show the other's numbers): give the graphs other "
            "name: keys, or use other grid values"
        )


def _first_shared_name(descs: list[dict]) -> tuple[dict, dict] | None:
    """The first two of ``descs`` (in order) with one job name, or None when the names differ."""
    seen: dict[str, dict] = {}
    for desc in descs:
        other = seen.setdefault(desc["job"], desc)
        if other is not desc:
            return other, desc
    return None


def _refuse_renamed_jobs(path: Path, stored: dict, meta: list[dict]) -> None:
    """Refuse to resume a file whose jobs this version names otherwise (or that holds two
    points under one name), before anything is computed.

    Its stored jobs (``stored["jobs"]``) and the sweep's (``meta``) are matched by (graph,
    point, threshold, repeat); a different name means the file was written by an antisync
    that named grid values with six significant digits (``1e+06`` for seed 1000001): its
    groups would not be found (computed again, the old ones kept beside them) or, where two
    points shared a name, one point holds the other's numbers.
    """

    def where(desc: dict) -> str:
        point = json.dumps(desc.get("point"), sort_keys=True, default=str)
        return json.dumps([desc["graph"], point, float(desc["threshold"]), desc["repeat"]])

    old = [d for d in stored.get("jobs", []) if d.get("stage") == "main"]
    clash = _first_shared_name(old)
    if clash is not None:
        first, second = (point_label(d.get("point") or {}) for d in clash)
        raise StoreError(
            f"{path} holds grid points {first} and {second} under one job {clash[0]['job']!r} "
            "(written by an antisync that named values with 6 digits); one shows the other's "
            "numbers: run the sweep again with --overwrite"
        )
    ours = {where(d): d["job"] for d in meta}
    for d in old:
        new = ours.get(where(d))
        if new is not None and new != d["job"]:
            raise StoreError(
                f"{path} names the job of {point_label(d.get('point') or {})} {d['job']!r}, this "
                f"antisync {new!r} (job names now tell apart values such as 0.1 and 0.1000001): "
                "finish it with the antisync that started it, or start again with --overwrite"
            )


def top_jobs(sweep: Sweep, entries: list[GraphEntry], records: list[dict]) -> tuple[list, list[dict]]:
    """Top-stage jobs: the most antifragile edge of each of the first ``top.graphs`` graphs."""
    if sweep.top.graphs <= 0:
        return [], []
    by_name = {e.name: e for e in entries}
    t = sweep.ranking_threshold()
    jobs, meta = [], []
    for row in ranking(records, t)[: sweep.top.graphs]:
        entry = by_name[row["graph"]]
        edge = graphs_mod.parse_edge(row["max_representative"], entry.graph)
        jobs.append(_top_job(sweep, entry, edge))
        meta.append(
            {
                "job": jobs[-1].name,
                "graph": entry.name,
                "threshold": t,
                "repeat": 0,
                "stage": "top",
                "rank": row["rank"],
                "edge": row["max_edge"],
            }
        )
    return jobs, meta


def run_sweep(
    sweep: Sweep,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool | None = None,
    executor=None,
    log=None,
    chunk_realizations: int | None = None,
    checkpoint_seconds: float = 30.0,
) -> Path:
    """Screen, run the main stage and the top stage of ``sweep`` into one HDF5 file.

    Parameters are those of :func:`antisync.execution.runner.run_jobs`. Returns the file's path.

    The output is locked once for the whole sweep, before ``overwrite`` deletes anything (the
    ``run_jobs`` call of each stage takes the same lock again). A given ``executor`` is used
    by every stage and left open. ``resume`` on a complete sweep file leaves it untouched.
    A failure before anything was finished removes what the sweep created.
    """
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.store import ResultStore

    store = ResultStore(output or sweep.output)
    entries = family_graphs(sweep)
    show = sys.stderr.isatty() if progress is None else bool(progress)
    # every refusal before the output or its journal is touched; its jobs are the main stage's
    planned = check_sweep(sweep, entries, progress=show)
    with store.lock(read_only_ok=resume) as writable:
        store.prepare(resume=resume, overwrite=overwrite)
        try:
            return _run_sweep_locked(
                sweep,
                entries,
                planned,
                store,
                writable,
                resume=resume,
                progress=progress,
                executor=executor,
                log=log,
                chunk_realizations=chunk_realizations,
                checkpoint_seconds=checkpoint_seconds,
            )
        except BaseException as exc:
            if writable:
                store.discard_unfinished(refused=isinstance(exc, ConfigError))
            raise


def _run_sweep_locked(
    sweep: Sweep,
    entries: list[GraphEntry],
    planned: tuple[list, list[dict]],
    store,
    writable: bool,
    *,
    resume: bool,
    progress,
    executor,
    log,
    chunk_realizations,
    checkpoint_seconds,
) -> Path:
    """The body of :func:`run_sweep`, with ``store`` locked and prepared; ``planned``: the
    main stage's jobs of every graph (:func:`check_sweep`)."""
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.execution.runner import run_jobs
    from antisync.execution.stopping import already_stopped
    from antisync.store import read_sweep_meta, write_sweep_meta
    from antisync.sweeps.screening import ScreenResult, screen_graph

    say = log or (lambda msg: None)
    path = store.path
    key = sweep.key()
    if resume:
        store.load_states([], key)  # a file or journal of another sweep is an error, now
    # while an --overwrite replaces the file, the sweep's own checkpoints are in store.current
    stored = read_sweep_meta(store.current) if resume and store.current.exists() else None
    if stored is not None:
        _refuse_renamed_jobs(path, stored, planned[1])
    if resume and stored is not None and stored.get("complete") and store.file_complete():
        # every stage finished with this key: the file stays exactly as it is
        if writable:
            store.drop_journal()  # left by a kill after the last checkpoint
        stopped = store.stopped_early(key)  # its groups hold fewer realizations than the budget
        say(already_stopped(path, stopped) if stopped else f"{path} is already complete; nothing to do")
        return path
    if not writable:
        raise StoreError(
            f"cannot write to folder {path.parent} to finish {path}; "
            "make it writable or use --out for a new file"
        )
    store.start_journal(key)
    grid = f", {len(sweep.points)} grid point(s)" if sweep.points else ""
    say(
        f"sweep {sweep.name}: {len(entries)} graph(s) of family {sweep.family['family']}{grid}, "
        f"{len(sweep.thresholds)} threshold(s), {sweep.repeats} repeat(s)"
    )
    generalized = sweep.base.generalized or any(p.config.generalized for p in sweep.points)
    if sweep.screen.enabled and generalized:
        # the screening's classifier rests on the gradient flow of identical first-order
        # oscillators (docs/sweeps.md); it has no verdict on another model or criterion
        say(
            "warning: the screening integrates the paper's identical first-order oscillators with "
            "the order-parameter criterion, not this sweep's model:/sync: (no graph is excluded "
            "for how the model behaves); read each record's n_not_synced, or set "
            "screen.enabled: false"
        )

    # -- 1. screening, cached per graph in the journal and in the file ------------------------
    screens: dict[str, ScreenResult] = {}
    if stored:
        for gm in stored["graphs"]:
            if gm.get("screen"):
                screens[gm["graph"]] = ScreenResult.from_dict(gm["screen"])
    for d in store.load_screens():  # one cut off by a crash is not there: screened again
        screens.setdefault(d["graph"], ScreenResult.from_dict(d))
    show = sys.stderr.isatty() if progress is None else progress
    todo = [e for e in entries if sweep.screen.enabled and e.name not in screens]
    dyn = sweep.base.dynamics
    bar = tqdm(
        total=len(entries),
        initial=len(entries) - len(todo),
        unit="graph",
        desc="screening",
        disable=not show or not todo,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    for entry in todo:
        res = screen_graph(
            graphs_mod.omega_matrix(entry.graph),
            graph=entry.name,
            seed=sweep.base.seed,
            realizations=sweep.screen.realizations,
            t_max=sweep.screen.t_max,
            dt=dyn.dt,
            threshold=max(sweep.thresholds),
            coupling_kind=dyn.coupling,
            exclude_fraction=sweep.screen.exclude_fraction,
            threads=sweep.base.threads,
        )
        screens[entry.name] = res
        store.save_screen(entry.name, res.to_dict())
        bar.update(1)
    bar.close()
    excluded = {n for n, s in screens.items() if s.excluded}
    kept = [e for e in entries if e.name not in excluded]
    for e in entries:
        if e.name in excluded:
            say(f"excluded {e.name}: {screens[e.name].reason}")
    if not kept:
        raise ConfigError(f"sweep {sweep.name}: every graph was excluded by the screening")

    # -- 2. main stage ---------------------------------------------------------------------
    kept_names = {e.name for e in kept}  # the planned jobs of the graphs the screening kept
    jobs = [j for j, m in zip(*planned, strict=True) if m["graph"] in kept_names]
    jobs_meta = [m for m in planned[1] if m["graph"] in kept_names]
    saved = _symmetry(sweep, kept, jobs)
    say(
        f"symmetry: {saved['directed_edges']} directed edges in {saved['representatives']} orbits; "
        f"integrating representatives saves {saved['integrations_saved']:,} of "
        f"{saved['integrations_without_symmetry']:,} integrations ({saved['fraction_saved']:.0%})"
    )
    state = {"jobs_meta": list(jobs_meta), "final": sweep.top.graphs == 0}

    def write_meta(f, states) -> None:
        meta = _meta(sweep, entries, screens, excluded, state["jobs_meta"], saved)
        meta["complete"] = bool(state["final"] and all(st.complete for st in states.values()))
        write_sweep_meta(f, meta)  # also the root's complete, as for a run file

    common = dict(
        progress=progress,
        executor=executor,
        log=log,
        chunk_realizations=chunk_realizations,
        checkpoint_seconds=checkpoint_seconds,
        key=key,
        provenance={"config_yaml": sweep.to_yaml(), "sweep": sweep.name},
        extra=write_meta,
    )
    main_done = False
    if stored is not None:
        states = store.load_states(jobs, key)
        main_done = all(st.complete for st in states.values())
    if not main_done:
        run_jobs(jobs, sweep.base, output=path, resume=True, **common)
    if sweep.top.graphs == 0:
        if main_done:
            # done, but the file did not say complete (a complete one returned above): rewrite
            # it so that its metadata is current
            run_jobs(jobs, sweep.base, output=path, resume=True, **common)
        return path

    # -- 3. top stage ----------------------------------------------------------------------
    records = sweep_summary(store.current)["records"]
    tjobs, tmeta = top_jobs(sweep, kept, records)
    state["jobs_meta"] = jobs_meta + tmeta
    state["final"] = True
    if tjobs:
        say(
            f"top stage: {len(tjobs)} graph(s), edge of largest Lambda, betas "
            f"{list(sweep.top.betas)}, {tjobs[0].config.realizations:,} realizations"
        )
    run_jobs(jobs + tjobs, sweep.base, output=path, resume=True, **common)
    return path


def _top_job(sweep: Sweep, entry: GraphEntry, edge):
    """The top stage's job of ``entry`` on ``edge``: the top stage's betas and realizations at
    the ranking threshold, no per-realization pairs."""
    name = f"{entry.name}_top"
    cfg = _job_config(
        sweep,
        entry,
        [edge],
        threshold=sweep.ranking_threshold(),
        seed=sweep.base.seed,
        betas=sweep.top.betas,
        realizations=sweep.top.realizations,
        name=name,
    )
    return make_job(replace(cfg, keep_pairs=0), graph=entry.graph, name=name, command="sweep")


def check_sweep(
    sweep: Sweep, entries: list[GraphEntry], backend: str | None = None, *, progress: bool = False
) -> tuple[list, list[dict]]:
    """Refuse, before anything is written, every job the sweep could run; returns the main
    stage's jobs of every graph and their descriptions (:func:`main_jobs`, ``progress`` its bar).

    The main stage's jobs of every graph (screening may exclude some, never add one) and, for
    the top stage, each graph's job on its first representative edge with the top stage's
    betas and realizations (the stage's options; its edge is chosen by the ranking later) go
    through the same checks :func:`antisync.execution.runner.run_jobs` makes
    (:func:`~antisync.execution.compute.check_job`), so a bad option, edge, frequency list or step
    fails the command before the output or its journal exists, not after the screening.
    ``backend``: the one to check for (default: the config's, resolved on this machine;
    ``antisync validate`` passes the configured one, so a cuda sweep validates on a laptop).
    """
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.execution.compute import check_job
    from antisync.measures.pipeline import with_nnc

    if backend is None:
        backend, _ = resolve_backend(sweep.base.backend)
    _check_backend(sweep, entries, backend)
    main, meta = main_jobs(sweep, entries, progress=progress)
    jobs = list(main)
    if sweep.top.graphs > 0:
        jobs += [_top_job(sweep, entry, entry.representatives[0]) for entry in entries]
        top = [{"job": f"{e.name}_top", "graph": e.name, "stage": "top"} for e in entries]
        _refuse_shared_names(meta + top, sweep)
    for job in with_nnc(jobs):
        check_job(job, backend)
    return main, meta


def _check_backend(sweep: Sweep, entries: list[GraphEntry], backend: str) -> None:
    """Refuse, before anything is written, what the sweep's backend cannot run: its options
    (:func:`~antisync.execution.compute.check_backend`) and, on cuda, a graph with more nodes than
    the kernels hold (the stages' ``run_jobs`` would refuse it only after the screening)."""
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.execution.compute import check_backend

    check_backend(sweep.base, backend)
    if backend == "cuda":
        # lazy: numba-cuda, only for a cuda sweep
        from antisync.kernels.cuda import MAX_NODES

        for e in entries:
            if e.graph.number_of_nodes() > MAX_NODES:
                raise ConfigError(
                    f"graph {e.name} has {e.graph.number_of_nodes()} nodes; the cuda backend runs "
                    f"at most {MAX_NODES}: use --backend cpu"
                )


def _symmetry(sweep: Sweep, kept: list[GraphEntry], jobs) -> dict:
    n_dir = sum(len(e.edges) for e in kept)
    n_rep = sum(len(e.representatives) for e in kept)
    with_sym = without = 0
    by_graph = {e.name: e for e in kept}
    for job in jobs:
        entry = by_graph[job.graph.graph["name"]]
        # the betas and dbeta of one edge (orbit: plus the +-dbeta pair)
        per_edge = (job.integrations_per_realization - 1) // len(job.edges)
        m = job.config.realizations
        with_sym += (1 + per_edge * len(entry.representatives)) * m
        without += (1 + per_edge * len(entry.edges)) * m
    return {
        "directed_edges": n_dir,
        "representatives": n_rep,
        "integrations": with_sym,
        "integrations_without_symmetry": without,
        "integrations_saved": without - with_sym,
        "fraction_saved": (without - with_sym) / without if without else 0.0,
    }


def _meta(sweep, entries, screens, excluded, jobs_meta, saved) -> dict:
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.store import SWEEP_FORMAT, SWEEP_FORMAT_VERSION

    graphs = []
    for e in entries:
        s = screens.get(e.name)
        graphs.append(
            {
                "graph": e.name,
                "spec": e.spec,
                "nodes": [_jsonable(v) for v in graphs_mod.node_order(e.graph)],
                "undirected_edges": [[_jsonable(u), _jsonable(v)] for u, v in e.graph.edges],
                "orbits": e.orbit_labels(),
                "excluded": e.name in excluded,
                "screen": s.to_dict() if s is not None else None,
            }
        )
    meta = {
        "format": SWEEP_FORMAT,
        "format_version": SWEEP_FORMAT_VERSION,
        "name": sweep.name,
        "family": sweep.family,
        "thresholds": list(sweep.thresholds),
        "repeats": sweep.repeats,
        "ranking_threshold": sweep.ranking_threshold(),
        "top": asdict(sweep.top) | {"betas": list(sweep.top.betas)},
        "screen": asdict(sweep.screen),
        "graphs": graphs,
        "jobs": jobs_meta,
        "symmetry": saved,
        "coupling": sweep.base.dynamics.coupling,
        "dbeta": sweep.base.lambda_.dbeta,
        "betas": list(sweep.base.betas),
    }
    if sweep.axes:  # the grid's axes in their order: keys moving together, their values
        meta["grid"] = [
            {"keys": list(a.keys), "values": [list(v) for v in a.values], "zip": a.zipped} for a in sweep.axes
        ]
    return meta


def _jsonable(v):
    return v if isinstance(v, int | float | str) else str(v)
