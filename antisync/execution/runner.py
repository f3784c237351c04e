"""Run jobs: pending chunks -> executor -> journal -> checkpoints -> final HDF5 file.

This is the only place that ties computation to files and progress bars; the CLI calls
:func:`run_config`, and a notebook can too.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

from tqdm import tqdm

from antisync.errors import StoreError
from antisync.execution import stopping
from antisync.execution.compute import check_job, host_part
from antisync.execution.executors import Executor
from antisync.execution.executors.local import LocalExecutor
from antisync.execution.step_check import job_step_check, step_check_notes
from antisync.kernels.backends import resolve_backend
from antisync.measures.pipeline import COMPUTED, compute_measures, wants_measures, with_nnc
from antisync.plan.config import Config
from antisync.plan.jobs import Chunk, Job, make_job, stiffness_note
from antisync.store import JobState, ResultStore, chunk_tag, command_line, git_revision

__all__ = ["Interrupted", "run_config", "run_jobs"]

# Trajectories (realizations x (1 + variants)) per chunk on a GPU: enough threads to fill it
# many times over, one device batch of antisync.kernels.cuda.simulate_reduced.
GPU_CHUNK_TRAJECTORIES = 1 << 24


class Interrupted(Exception):
    """The run was interrupted; everything finished so far is saved and ``--resume`` continues."""


def run_config(config: Config, **kwargs) -> Path:
    """Run one config (one graph) and return the path of its HDF5 file. See :func:`run_jobs`."""
    return run_jobs([make_job(config)], config, **kwargs)


def run_jobs(
    jobs: list[Job],
    config: Config,
    *,
    output: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool | None = None,
    executor: Executor | None = None,
    chunk_realizations: int | None = None,
    checkpoint_seconds: float = 30.0,
    log: Callable[[str], None] | None = None,
    key: dict | None = None,
    provenance: dict | None = None,
    extra: Callable | None = None,
) -> Path:
    """Run ``jobs`` to completion into ``output`` (default ``config.output``).

    Parameters
    ----------
    resume : bool
        Continue an interrupted run in ``output``; done blocks are neither redone nor recounted.
    overwrite : bool
        Replace an existing ``output``: only an antisync result file (a run's or a sweep's) is
        replaced, anything else is refused. Without ``resume`` or ``overwrite`` an existing
        file is an error and is left untouched.
    progress : bool, optional
        Show a progress bar on stderr; default: only when stderr is a terminal.
    executor : object, optional
        Something with ``run(work)`` yielding ``(job, ChunkResult)``, ``describe()`` and
        ``close()``. Default: a local executor, made here and closed here. A given executor is
        left open (whoever makes an executor closes it): a sweep hands the same one to each of
        its stages.
    key : dict, optional
        What must match for ``resume`` (default ``config.simulation_key()``); a sweep passes
        the key of the whole sweep.
    provenance : dict, optional
        Extra or replacement root attributes (a sweep stores its own ``config_yaml``).
    extra : callable, optional
        ``extra(h5file, states)``, called at every checkpoint to write more groups.

    Notes
    -----
    The output is locked for the whole call (see :meth:`ResultStore.lock`): a second writer
    is refused before anything is deleted or modified. ``resume`` on a complete file with
    the same key leaves it untouched (also when it or its folder is read-only). A failure
    before any chunk finished removes what this call created (a journal with nothing in it,
    temporary files), so the same command can simply be run again.

    With a stopping rule (``config.stop``, docs/stopping.md) the realizations are integrated
    look by look (:attr:`~antisync.plan.config.Config.stop_looks`); the run ends at the first look
    where :func:`antisync.execution.stopping.take_look` finds every sign known, and the file then holds
    exactly a plain run of that many realizations.
    """
    say = log or (lambda msg: None)
    jobs = with_nnc(jobs)  # measures: km_nnc adds each job's raw-coupling twin
    store = ResultStore(output or config.output)
    backend, note = resolve_backend(config.backend)
    for job in jobs:  # the options and the graph: refused before any file or folder exists
        check_job(job, backend)
    for job in jobs:
        stiff = stiffness_note(job)
        if stiff is not None:
            say(f"note: {job.name}: {stiff}")
    host = host_part(config, backend)
    note = note if host is None else f"{note} ({host})"
    key = config.simulation_key() if key is None else key
    with store.lock(read_only_ok=resume) as writable:
        store.prepare(resume=resume, overwrite=overwrite)
        stopped = store.stopped_early(key) if resume else None
        if stopped is not None:
            # the stopping rule ended this run: its groups hold fewer realizations than the budget
            if writable:
                store.drop_journal()
            say(stopping.already_stopped(store.path, stopped))
            return store.path
        states = store.load_states(jobs, key) if resume else {job.name: JobState(job) for job in jobs}
        if resume and store.file_complete() and all(st.complete for st in states.values()):
            # nothing to compute: the file stays exactly as it is (inode, mtime, mode)
            if writable:
                store.drop_journal()  # left by a kill after the last checkpoint
            done = sum(st.realizations_done for st in states.values())
            say(f"{store.path} is already complete; nothing to do ({done:,} already done)")
            return store.path
        if not writable:
            raise StoreError(
                f"cannot write to folder {store.path.parent} to finish {store.path}; "
                "make it writable or use --out for a new file"
            )
        # Euler's or RK4's step, checked again at dt / 2: a note (one line for many jobs), never a refusal
        checks = {job.name: job_step_check(job, config.threads) for job in jobs}
        checked = {name: c for name, c in checks.items() if c is not None}
        for line in step_check_notes(checked):
            say(line)
        own_executor = executor is None
        if own_executor:
            executor = LocalExecutor(backend, config.threads)
        try:
            _execute(
                store,
                jobs,
                states,
                executor,
                config=config,
                key=key,
                backend=backend,
                note=note,
                say=say,
                progress=progress,
                chunk_realizations=chunk_realizations,
                checkpoint_seconds=checkpoint_seconds,
                provenance={**(provenance or {}), **_step_check_attr(checked)},
                extra=extra,
            )
        except BaseException:
            store.discard_unfinished()
            raise
        finally:
            if own_executor:
                executor.close()
    return store.path


def _step_check_attr(checked: dict) -> dict:
    """The run file's root attribute ``step_check_json`` (each checked job's
    :func:`~antisync.execution.step_check.step_record`), or nothing when no job was checked."""
    if not checked:
        return {}
    return {"step_check_json": json.dumps(checked, sort_keys=True)}


def _execute(
    store: ResultStore,
    jobs: list[Job],
    states: dict,
    executor,
    *,
    config: Config,
    key: dict,
    backend: str,
    note: str,
    say,
    progress,
    chunk_realizations,
    checkpoint_seconds: float,
    provenance,
    extra,
) -> None:
    """Compute the pending chunks of ``jobs`` into ``store`` (locked and prepared)."""
    # before anything is written: a graph a measure rejects leaves no file behind
    measured = _compute_measures(jobs, states, say)
    store.start_journal(key)
    provenance_extra = provenance
    provenance = {
        "command": command_line(),
        "config_yaml": config.resolved().to_yaml(),
        "git_revision": git_revision(),
        "simulation_key": _json(key),
    }
    provenance.update(provenance_extra or {})
    if measured:
        store.checkpoint(states, provenance, extra=extra)  # so --resume never computes them again
    if chunk_realizations is None and config.chunk_size != "auto":
        chunk_realizations = int(config.chunk_size)
    chunks = {job.name: job.chunks(_chunk_size(job, backend, chunk_realizations)) for job in jobs}
    # every journal chunk carries its run's tag: --resume never merges another run's chunks
    tags = {job.name: chunk_tag(job, key) for job in jobs}
    done_already = sum(st.realizations_done for st in states.values())
    total = sum(job.realizations for job in jobs)  # 0 for a job without km: nothing integrated
    # the bar counts integrations (tau0 plus one per damage variant, orbit differences
    # included): with many jobs of different sizes (a sweep) its rate and ETA stay meaningful
    cost = {job.name: job.integrations_per_realization for job in jobs}
    looks = config.stop_looks  # [realizations] without a stopping rule
    if not config.stop.active:
        # every job to its own count: a sweep's top stage may ask for more than `config`'s
        looks = [max([config.realizations, *(job.realizations for job in jobs)])]
    level = stopping.look_level(len(looks))
    say(
        f"{note}; {executor.describe()}; {len(jobs)} job(s), "
        f"{sum(cost.values()) - len(jobs)} damaged variant(s), "
        + (
            f"up to {total:,} realizations (stop: {config.stop.when}, looks at "
            f"{', '.join(f'{n:,}' for n in looks)}; intervals at {level:.2%})"
            if config.stop.active
            else f"{total:,} realizations in all"
        )
        + (f" ({done_already:,} already done)" if done_already else "")
    )
    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(
        total=sum(job.realizations * cost[job.name] for job in jobs),
        initial=sum(states[j.name].realizations_done * cost[j.name] for j in jobs),
        unit="integ",
        unit_scale=True,
        delay=1.0,
        disable=not show,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    last = time.monotonic()
    try:
        for n in looks:
            # the realizations up to this look, in chunks that end at it
            work = [
                (job, c)
                for job in jobs
                for c in states[job.name].pending(_clip(chunks[job.name], -(-n // job.block_size)))
            ]
            for job, res in executor.run(work):
                store.save_chunk(job.name, res, tags[job.name])
                states[job.name].add(res)
                bar.update(res.count * cost[job.name])
                if len(jobs) > 1:
                    done_jobs = sum(st.complete for st in states.values())
                    bar.set_description(f"{job.name} ({done_jobs}/{len(jobs)} jobs)", refresh=False)
                if time.monotonic() - last > checkpoint_seconds:
                    store.checkpoint(states, provenance, extra=extra)
                    last = time.monotonic()
            if config.stop.active and _stop_here(states, n, looks, level, config, provenance, say):
                break
    except KeyboardInterrupt:
        bar.close()
        store.checkpoint(states, provenance, extra=extra)
        raise Interrupted(
            f"interrupted; finished chunks are saved in {store.path}: "
            "rerun the same command with --resume to finish"
        ) from None
    finally:
        bar.close()
    store.checkpoint(states, provenance, final=True, extra=extra)


def _clip(chunks: list[Chunk], blocks: int) -> list[Chunk]:
    """``chunks`` cut to the first ``blocks`` blocks (chunk boundaries never change results)."""
    out = []
    for c in chunks:
        end = min(c.first_block + c.n_blocks, blocks)
        if end > c.first_block:
            out.append(Chunk(c.first_block, end - c.first_block))
    return out


def _stop_here(states: dict, n: int, looks: list[int], level: float, config: Config, provenance, say) -> bool:
    """The stopping rule's look after ``n`` realizations; when it stops (or the budget is
    spent), ``states`` are cut to ``n`` and ``provenance["stop_json"]`` says what happened."""
    if n < looks[-1] and any(st.done[-(-n // st.job.block_size) :].any() for st in states.values()):
        return False  # a resumed run already went past this look: it said go on then
    look = stopping.take_look(states, n, level, config.stop.tolerance)
    say(look.describe(looks[-1]))
    if not look.all_known and n < looks[-1]:
        return False
    if n < looks[-1]:
        for name, st in states.items():
            states[name] = st.truncated(n)
    provenance["stop_json"] = _json(
        {
            "when": config.stop.when,
            "tolerance": config.stop.tolerance,
            "looks": looks,
            "level": level,
            "budget": looks[-1],
            "stopped_at": n,
            "stopped_early": n < looks[-1],
            "last_look": look.to_dict(),
        }
    )
    return True


def _compute_measures(jobs: list[Job], states: dict, say) -> bool:
    """Lambda^(linear), Lambda^(xi2), Lambda^(RW) once per job, before any chunk (a graph they
    reject fails the run at once); states loaded with their measures are left alone."""
    computed = False
    for job in jobs:
        st = states[job.name]
        if st.measures is None and wants_measures(job):
            start = time.perf_counter()
            st.measures = compute_measures(job)
            st.measures_seconds = time.perf_counter() - start
            names = ", ".join(m for m in job.config.measures if m in COMPUTED)
            say(f"{job.name}: measures {names} in {st.measures_seconds:.1f} s")
            computed = True
    return computed


def _chunk_size(job: Job, backend: str, requested: int | None) -> int | None:
    """Realizations per chunk: as requested, else the job's default (CPU) or a GPU-sized one."""
    if requested is not None or backend != "cuda":
        return requested
    return max(job.block_size, GPU_CHUNK_TRAJECTORIES // (1 + len(job.variant_edge)))


def _json(obj) -> str:
    return json.dumps(obj)
