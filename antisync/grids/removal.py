"""Dynamic line removal (dynamic N-1) of a power grid: does the grid still synchronize, and
how fast, when one line is removed or weakened (docs/power_grids.md)?

For every line ``i-j`` both directions are weakened, ``Omega_ij, Omega_ji -> (1 - beta)
Omega_ij`` (``beta = 1`` removes the line), and the damaged grid is integrated from the **same**
initial conditions as the intact one: realization ``k`` starts from the counter-based phases
``theta_i(0) = 2 pi u(seed, k, i)`` of :mod:`antisync.physics.phases` (``theta_i'(0) = 0``), whatever
line, chunk or thread. The integration is the config's compiled CPU model driver
(:func:`antisync.execution.dispatch.model_simulator`: the RK4 or Euler lanes, or Rodas4 for a
stiff grid; the intact grid as the base network, one
variant per line on the same CSR pattern, a removed line's weights 0), so an intact run's
``tau0`` is the ordinary ``antisync run``'s ``tau0`` of the same seed, realization by
realization (tested).

Per line (:class:`~antisync.grids.removal_table.LineRemoval`), from the paired outcomes of ``M`` realizations:

- ``P_sync`` before and after (synchronized: the criterion of ``sync:`` met by ``t_max``),
  each with its exact Clopper-Pearson interval; the basin-stability change (Menck et al.,
  Nat. Phys. 9, 89 (2013)) is ``d_psync = P_after - P_before``;
- ``lost`` (synchronized intact, not after) and ``gained`` (the reverse), with Clopper-Pearson
  intervals of ``lost / M`` and ``gained / M``; ``d_psync = (gained - lost) / M``. The paired
  test is McNemar's exact one: conditional on the ``d = lost + gained`` discordant pairs,
  ``gained ~ Binomial(d, q)`` with ``q = 1/2`` under no change (``p_value``, two-sided), and
  the interval of ``d_psync`` is ``(d / M)(2 q - 1)`` at the ends of ``q``'s Clopper-Pearson
  interval (conditional on ``d``; ``[0, 0]`` when no pair is discordant: then ``lost_ci`` and
  ``gained_ci`` bound the change);
- on the pairs that synchronize both times (status SYNCED both), the mean of ``d_tau = tau -
  tau0`` with its standard error, and the mean ratio ``tau0 / tau`` (the paper's ``F``) with its
  standard error.

Rankings (:class:`~antisync.grids.removal_table.RemovalTable`): **troublemaker lines** (removal
costs the most synchrony: largest ``lost - gained``) and **dynamic Braess lines** (removal or
weakening raises ``P_sync`` or speeds synchronization, ``d_tau < 0``). A change is *resolved*
when the Benjamini-Hochberg procedure at false discovery rate 0.05 over the table's lines calls
it (McNemar's exact p-values for ``P_sync``, normal ones of ``d_tau / se`` for tau;
:mod:`antisync.stats.multiplicity`, as the sign calls of ``antisync summary``): a per-line 5%
test would call about one line in twenty of an unaffected grid.

A bridge (a line whose removal islands the grid) at ``beta = 1`` is refused with a one-line
:class:`~antisync.grids.errors.GridError`; ``islanding=True`` integrates it anyway and marks the row
``islanding`` (the islands cannot share one frequency unless each is balanced, so with the
frequency criterion such a row normally loses every realization).

This module is the orchestrator: it builds the work (:mod:`antisync.grids.removal_config`), cuts
it into tasks of realizations x lines, integrates them here or on a Dask client
(:func:`antisync.execution.executors.tasks.map_tasks`), saves each finished task in its journal
(:mod:`antisync.grids.removal_journal`) and summarizes the paired outcomes
(:mod:`antisync.grids.removal_table`; the exact tests: :mod:`antisync.stats.exact`).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path

import numpy as np

from antisync.errors import AntisyncError
from antisync.execution.dispatch import law_params, law_simulator, model_params, model_simulator
from antisync.execution.executors.dask import TaskLostError, check_client, client_threads
from antisync.execution.executors.tasks import map_tasks
from antisync.execution.step_check import (
    STEP_CHECK_STARTS,
    check_step_accuracy,
    check_tolerance_accuracy,
    step_check_line,
)
from antisync.grids.errors import GridError
from antisync.grids.removal_config import RemovalPlan, check_beta, plan_removal, resolve_config, work_config
from antisync.grids.removal_journal import RemovalJournal, remove_journal, work_digest
from antisync.grids.removal_table import RemovalTable, line_rows
from antisync.physics import coupling
from antisync.plan.model import law_on_network, model_setup
from antisync.stats.estimators import crossing_times
from antisync.status import ALREADY_SYNCED, GAVE_UP, SYNCED

__all__ = ["CHUNK", "CLIENT_HINT", "TASKS_PER_WORKER", "line_removal"]

#: Realizations integrated per call of the compiled driver (progress and memory).
CHUNK = 256
#: Lines per task of a run on this machine (with ``client=None``): the unit of the progress
#: lines and of the journal, so that an interrupted run of a large grid keeps all but a few
#: lines' worth of work (on ACTIVSg2000 a task of 4 lines x 100 starts is ~5 minutes).
LINES_PER_TASK = 4
#: ``sync.give_up``'s checks (docs/power_grids.md): the **pilot** integrates every start of the
#: intact grid without the rule and with ``after / PILOT_MARGIN``, and refuses the run if any
#: start that locks would be stopped; the **audit** integrates, in every task, at least
#: ``AUDIT_MIN`` and ``AUDIT_FRACTION`` of its given-up trajectories without the rule, and if one
#: of them locks, every given-up trajectory of the task again without it.
PILOT_MARGIN = 1.25
AUDIT_FRACTION = 0.01
AUDIT_MIN = 2

#: Tasks per Dask worker thread that :func:`line_removal` aims for (lines are grouped so that a
#: few realizations x many lines still spread over the cluster).
TASKS_PER_WORKER = 4


#: What :func:`line_removal` says to a ``client`` that is not a ``distributed.Client``.
CLIENT_HINT = (
    "to use a scheduler address, open Client('tcp://...') yourself or use `antisync grid --scheduler`"
)


def line_removal(
    grid_or_config,
    *,
    lines=None,
    beta: float = 1.0,
    realizations: int | None = None,
    seed: int | None = None,
    islanding: bool = False,
    threads: int | None = None,
    level: float = 0.95,
    log=None,
    client=None,
    journal: str | Path | None = None,
    restart: bool = False,
    **overrides,
) -> RemovalTable:
    """Paired dynamic removal (or weakening) of grid lines, module docstring.

    Parameters
    ----------
    grid_or_config : path, mapping, Config, Grid or RemovalPlan
        A config with a ``model:`` (``configs/ieee39_grid.yaml``), the same keys as a mapping,
        an :class:`antisync.plan.config.Config`, or a :class:`antisync.grids.load.Grid` (integrated with
        rk4, ``dt = 0.01``, ``t_max = 400`` and frequency locking to 1e-3 unless ``overrides``
        say otherwise); or the :class:`~antisync.grids.removal_config.RemovalPlan` of
        :func:`~antisync.grids.removal_config.plan_removal`, which holds the config, the grid
        as built and the lines (a command builds its graph once: ``lines``, ``islanding`` and
        overrides are refused beside a plan, and ``beta`` must be the plan's).
    lines : list of (u, v), str or None
        The lines (node labels, or ``"4-5,2-3"``); default every line, the bridges left out
        (at ``beta = 1``) and listed in ``skipped``. A bridge named here is refused.
    beta : float
        ``Omega_ij, Omega_ji -> (1 - beta) Omega_ij``, in ``(0, 1]``; 1 removes the line.
    realizations, seed : int, optional
        Override the config's (realization ``k`` starts from ``phase(seed, k, i)``).
    islanding : bool
        Integrate a bridge's removal too, its row marked ``islanding``.
    threads : int, optional
        CPU threads of the compiled driver (default: all cores; on Dask, per task: 1).
    client : distributed.Client, optional
        Integrate on this Dask cluster's workers: tasks of up to :data:`CHUNK` realizations x a
        group of lines (the intact grid in the first group), about :data:`TASKS_PER_WORKER` per
        worker thread. Every trajectory is a function of ``(seed, k, weights)`` alone, so the
        table equals the local one, array for array (tests/test_grid_dynamic.py). The caller
        owns the cluster: anything but an open ``distributed.Client`` (a scheduler address
        included) is refused before any work.
    journal : path, optional
        A folder (``<out>.partial`` for ``antisync grid --out``) where every finished task is
        saved at once: a run killed at any moment and started again with the same journal and
        arguments integrates only what is missing
        (:class:`~antisync.grids.removal_journal.RemovalJournal`). A journal of other work
        (another config, seed, realization count, line set or beta) is refused in one line
        naming what differs; a task file in it that is damaged or not of this work (its tag) is
        deleted and its work done again, never merged.
    restart : bool
        Discard what ``journal`` holds (once the arguments are checked) and start over.
    level : float
        Confidence level of the exact intervals.
    log : callable, optional
        Receives one-line progress messages.
    **overrides
        Config keys, as :func:`antisync.run` takes them (``dynamics={"t_max": 200}``).

    Returns
    -------
    RemovalTable

    Raises
    ------
    antisync.grids.errors.GridError
        A line not in the grid, a bridge at ``beta = 1``, ``beta`` outside ``(0, 1]``, a config
        value that is not valid (per-node files of the wrong length included), a ``client`` that
        is not an open ``distributed.Client``, or a ``journal`` of other work: one line.
    """
    t_start = time.perf_counter()
    check_client(client, hint=CLIENT_HINT, error=GridError)
    beta = check_beta(beta)
    if not 0 < level < 1:
        raise GridError(f"level must lie in (0, 1), got {level}")
    if realizations is not None:
        overrides["realizations"] = realizations
    if seed is not None:
        overrides["seed"] = seed
    if isinstance(grid_or_config, RemovalPlan):
        given = {"lines": lines, "islanding": islanding or None, **overrides}
        if beta != grid_or_config.beta or any(v is not None for v in given.values()):
            named = ", ".join(k for k, v in given.items() if v is not None) or "beta"
            raise GridError(f"a RemovalPlan holds its lines, beta and config: drop {named}")
        plan = grid_or_config
    else:
        plan = plan_removal(resolve_config(grid_or_config, overrides), lines, beta, islanding)
    cfg, labels, todo, bridges, skipped = plan.config, plan.labels, plan.todo, plan.bridges, plan.skipped
    islanding, omega, kind = plan.islanding, plan.omega, cfg.dynamics.coupling
    try:
        csr = coupling.coupling_csr(omega, kind)
        damages = [(a, b, beta) for a, b in todo]
        variants = coupling.variant_weights(omega, csr, damages, kind, both_ways=True)
        names = [f"line {labels[a]}-{labels[b]} beta {beta:g}" for a, b in todo]
        if cfg.model.law is None:
            setup, law = model_setup(cfg, csr.indptr, csr.indices, [csr.weights, *variants], names)[0], None
            targets = setup.targets
        else:
            setup, (law, targets) = None, _law_work(plan, csr, variants, names)
    except AntisyncError as exc:
        if isinstance(exc, GridError):
            raise
        raise GridError(str(exc)) from None
    except ValueError as exc:  # a normalized coupling left with an isolated node
        raise GridError(f"cannot weaken the lines: {exc}") from None

    dyn = cfg.dynamics
    m = int(cfg.realizations)
    status0 = np.empty(m, dtype=np.int8)
    status = np.empty((m, len(todo)), dtype=np.int8)
    tau0 = np.full(m, np.nan)
    tau = np.full((m, len(todo)), np.nan)
    fixed = dict(
        seed=int(cfg.seed),
        indptr=csr.indptr,
        indices=csr.indices,
        base=csr.weights,
        setup=setup,
        law=law,
        all_targets=targets,
        model=cfg.model,
        n_nodes=len(labels),
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        dynamics=dyn,
        give_up=cfg.stop_rule("removal"),
        interpolate=dyn.interpolate,
    )
    if fixed["give_up"] is not None:
        _pilot(fixed, variants, m, threads, log)
    step_check = _step_check(fixed, variants, m, threads, log)
    # with sync.give_up the tasks are the same on every executor: the audit samples each task's
    # given-up trajectories, so a cluster's other grouping would audit others (another table)
    local = client is None or fixed["give_up"] is not None
    groups = -(-len(todo) // LINES_PER_TASK) if local else _groups(client, m)
    tasks = _plan(m, variants, base=csr.weights, groups=groups)
    done = 0
    have = np.zeros((m, 1 + len(todo)), dtype=bool)  # the trajectories held: intact, then each line
    audit = np.zeros(3, dtype=np.int64)  # sync.give_up's audit: sampled, of them locking, rerun
    book = None
    if journal is not None:
        key = {
            "config": work_config(cfg.to_dict()),
            "lines": [[str(labels[a]), str(labels[b])] for a, b in todo],
        }
        if restart:
            remove_journal(journal)
        key = {**key, "beta": beta, "islanding": bool(islanding)}
        book = RemovalJournal(journal, key, work=work_digest(fixed, variants))
        have = book.load(status0, tau0, status, tau, audit)
        tasks = _unfinished(tasks, have)
        done = int(have.sum())
        if done and log is not None:
            log(f"resumed: {done} trajectories read from {book.folder}")
    # on Dask one kernel thread per task: the cluster already runs a task per worker thread
    task_threads = threads if client is None else threads or 1
    calls = (_task_call(task, variants, fixed, task_threads) for task in tasks)
    grids = len(todo) + 1
    done_before = done
    try:
        for i, part in map_tasks(_removal_task, calls, client=client):
            ks, group, intact = tasks[i]
            span = slice(ks[0], ks[-1] + 1)
            if intact:
                status0[span], tau0[span] = part[0], part[1]
            status[span, group], tau[span, group] = part[2], part[3]
            audit += part[4]
            if book is not None:
                book.save(ks, group, intact, part)
            have[span, 0] |= intact
            have[span, 1 + group] = True
            done += ks.size * (group.size + intact)
            if log is not None:
                took = time.perf_counter() - t_start
                left = (m * grids - done) * took / max(done - done_before, 1)
                log(
                    f"{done}/{m * grids} trajectories ({m} realizations x {grids} grids), "
                    f"{int(have[:, 1:].all(axis=0).sum())}/{len(todo)} lines done, "
                    f"{took:.1f} s, ~{left:.0f} s left"
                )
    except TaskLostError as exc:
        lost = f"{type(exc.cause).__name__}: {exc.cause}"
        raise GridError(
            f"the Dask cluster lost a removal task ({lost}); with --out, the finished tasks are kept: "
            "run the same command with --resume"
        ) from None

    rows = line_rows(todo, labels, bridges, beta, status0, tau0, status, tau, level)

    return RemovalTable(
        name=cfg.name,
        beta=beta,
        seed=int(cfg.seed),
        rows=tuple(rows),
        status0=status0,
        tau0=tau0,
        status=status,
        tau=tau,
        seconds=time.perf_counter() - t_start,
        skipped=tuple(skipped),
        config=cfg.to_dict(),
        level=level,
        audit=None if fixed["give_up"] is None else _audit_record(audit),
        step_check=step_check,
    )


# --- the work: tasks of realizations x lines, run here or on Dask ----------------------------


def _plan(m: int, variants: np.ndarray, base: np.ndarray, groups: int) -> list[tuple]:
    """Tasks ``(realizations, line indices, with the intact grid)``: chunks of :data:`CHUNK`
    realizations x ``groups`` groups of lines; the first group of a chunk integrates the intact
    grid too, and so does any group holding a line whose change leaves the weights as they are
    (the driver copies such a line's result from the intact one)."""
    same = np.array([np.array_equal(w, base) for w in variants], dtype=bool)
    parts = [g for g in np.array_split(np.arange(variants.shape[0]), max(1, groups)) if g.size]
    out = []
    for first in range(0, m, CHUNK):
        ks = np.arange(first, min(m, first + CHUNK), dtype=np.int64)
        out += [(ks, g, j == 0 or bool(same[g].any())) for j, g in enumerate(parts)]
    return out


def _groups(client, m: int) -> int:
    """Groups of lines per chunk of realizations: about :data:`TASKS_PER_WORKER` tasks per
    worker thread of ``client``'s cluster."""
    threads = client_threads(client) or 1
    chunks = -(-m // CHUNK)
    return max(1, -(-TASKS_PER_WORKER * threads // chunks))


def _law_work(plan: RemovalPlan, csr, variants: np.ndarray, names: list) -> tuple:
    """A law's removal: its :class:`~antisync.plan.model.LawSetup` on the grid (edge parameters
    read onto the grid as built; with the relative criterion ``r*`` of the intact grid and of
    every line's; with ``model.start`` the intact grid's locked phases), checked finite at its
    start and its explicit step on its own Jacobian (:func:`antisync.kernels.law.check_step`),
    and the target of the intact grid and of each line's."""
    from antisync.kernels.law import check_step

    cfg = plan.config

    def check(setup):
        check_step(setup, cfg.seed, csr, cfg.dynamics)

    law = law_on_network(cfg, plan.labels, plan.graph, csr, variants, names, check)
    if law.fraction is None:
        return law, np.full(1 + len(names), law.target)
    return law, law.relative_target(law.r_star)


def _simulate(ks, variants, fixed: dict, threads, todo, give_up):
    """The model driver, or the law's, on realizations ``ks`` of the intact grid and
    ``variants`` (``todo``: bool ``(ks, 1 + variants)`` or None, every item) with the stop rule
    ``give_up`` (the built-in model's Rodas4 only)."""
    if fixed["law"] is not None:
        dyn = fixed["dynamics"]
        params = law_params(fixed["law"], dyn, 1 + variants.shape[0], fixed["targets"])
        simulate = law_simulator(dyn)
    else:
        params = model_params(
            fixed["setup"], fixed["model"], fixed["seed"], ks, fixed["n_nodes"], fixed["targets"]
        )
        simulate = model_simulator(fixed["dynamics"], give_up)
    return simulate(
        fixed["seed"],
        0,
        0,
        fixed["indptr"],
        fixed["indices"],
        fixed["base"],
        variants,
        params,
        dt=fixed["dt"],
        max_steps=fixed["max_steps"],
        threads=threads,
        realizations=ks,
        todo=todo,
    )


def _removal_task(ks, variants, intact: bool, fixed: dict, threads):
    """Integrate realizations ``ks`` of the intact grid (if ``intact``) and of ``variants``:
    ``(status0, tau0, status, tau, audit)``, times in the model's units (NaN where not
    SYNCED); ``audit``: ``sync.give_up``'s audit of this task (:func:`_audited`)."""
    todo = np.ones((ks.size, variants.shape[0] + 1), dtype=np.bool_)
    todo[:, 0] = intact
    sim = _simulate(ks, variants, fixed, threads, None if intact else todo, fixed["give_up"])
    st = np.concatenate([sim.status0[:, None], sim.status], axis=1)
    t0, t = crossing_times(sim, fixed["interpolate"])
    tau = np.concatenate([t0[:, None], t], axis=1) * fixed["dt"]
    audit = np.zeros(3, dtype=np.int64)
    if fixed["give_up"] is not None:
        audit = _audited(ks, variants, fixed, threads, st, tau, todo)
    tau = np.where(st == SYNCED, tau, np.nan)
    return st[:, 0], tau[:, 0], st[:, 1:], tau[:, 1:], audit


def _audited(ks, variants, fixed: dict, threads, st, tau, todo) -> np.ndarray:
    """``sync.give_up``'s audit of a task, in place on its statuses ``st`` and times ``tau``
    (``(ks, 1 + variants)``): a sample of its GAVE_UP trajectories (at least :data:`AUDIT_MIN`
    and :data:`AUDIT_FRACTION` of them, drawn from the run's seed and the task's first realization
    and line: the same on every executor, whose tasks are the same with the rule) integrated to
    ``t_max``
    without the rule; if one of them locks, every GAVE_UP trajectory of the task is. What is
    integrated again takes its rule-free outcome. Returns ``[sampled, of them locking,
    integrated again]``."""
    given = (st == GAVE_UP) & todo
    rows, cols = np.nonzero(given)
    if rows.size == 0:
        return np.zeros(3, dtype=np.int64)
    size = min(rows.size, max(AUDIT_MIN, int(np.ceil(AUDIT_FRACTION * rows.size))))
    first = int(fixed["group"][0]) + 1 if fixed["group"].size else 0
    rng = np.random.default_rng([fixed["seed"], int(ks[0]), first, int(todo[0, 0])])
    pick = np.zeros(rows.size, dtype=bool)
    pick[rng.choice(rows.size, size=size, replace=False)] = True

    def again(mask):
        want = np.zeros_like(todo)
        want[rows[mask], cols[mask]] = True
        sim = _simulate(ks, variants, fixed, threads, want, None)
        free = np.concatenate([sim.status0[:, None], sim.status], axis=1)
        t0, t = crossing_times(sim, fixed["interpolate"])
        times = np.concatenate([t0[:, None], t], axis=1) * fixed["dt"]
        st[want], tau[want] = free[want], times[want]
        return free[rows[mask], cols[mask]]

    locked = int(np.isin(again(pick), (SYNCED, ALREADY_SYNCED)).sum())
    rerun = size
    if locked:
        again(~pick)
        rerun = rows.size
    return np.array([size, locked, rerun], dtype=np.int64)


def _pilot(fixed: dict, variants, m: int, threads, log) -> None:
    """``sync.give_up``'s pilot: every start of the intact grid integrated without the rule and
    with ``after / PILOT_MARGIN``; a start that locks without the rule but is stopped by the
    tightened one means the rule is not trusted on this grid: one line, before any task."""
    after, band = fixed["give_up"]
    ks = np.arange(m, dtype=np.int64)
    todo = np.zeros((m, 2), dtype=np.bool_)
    todo[:, 0] = True
    pilot = {**fixed, "targets": fixed["all_targets"][:2]}
    free = _simulate(ks, variants[:1], pilot, threads, todo, None).status0
    tight = _simulate(ks, variants[:1], pilot, threads, todo, (after / PILOT_MARGIN, band)).status0
    locks = np.isin(free, (SYNCED, ALREADY_SYNCED))
    stopped = locks & (tight == GAVE_UP)
    if stopped.any():
        raise GridError(
            f"sync.give_up is not trusted on this grid: {int(stopped.sum())} of the {int(locks.sum())} "
            f"starts of the intact grid that lock by t_max were still outside the band {band:g} at "
            f"after / {PILOT_MARGIN:g} = {after / PILOT_MARGIN:g} s (first: realization "
            f"{int(np.flatnonzero(stopped)[0])}); raise sync.give_up.after or remove give_up"
        )
    if log is not None:
        log(
            f"sync.give_up pilot: {int(locks.sum())} of {m} intact starts lock, none outside the band at "
            f"{after / PILOT_MARGIN:g} s (after / {PILOT_MARGIN:g})"
        )


def _step_check(fixed: dict, variants, m: int, threads, log) -> dict | None:
    """The step check of Euler or RK4, or Rodas4's of its tolerances
    (:mod:`antisync.execution.step_check`), on the intact grid's first starts (without
    ``sync.give_up``), before any task: its record for the table, and a warning through ``log``
    (or :func:`warnings.warn`) when it did not pass."""
    ks = np.arange(min(STEP_CHECK_STARTS, m), dtype=np.int64)
    dyn = fixed["dynamics"]

    def run_at(dt, starts, dynamics=dyn):
        todo = np.zeros((starts.size, 2), dtype=np.bool_)
        todo[:, 0] = True
        run = {
            **fixed,
            "dynamics": dynamics,
            "targets": fixed["all_targets"][:2],
            "dt": dt,
            "max_steps": round(fixed["max_steps"] * fixed["dt"] / dt),
        }
        sim = _simulate(starts, variants[:1], run, threads, todo, None)
        t0, _ = crossing_times(sim, fixed["interpolate"])
        return sim.status0, np.where(sim.status0 == SYNCED, t0 * dt, np.nan)

    if dyn.integrator == "rodas4":
        rtol, atol = dyn.tolerances

        def at_tolerances(r, a, starts):
            return run_at(fixed["dt"], starts, dataclasses.replace(dyn, rtol=float(r), atol=float(a)))

        record = check_tolerance_accuracy(at_tolerances, fixed["dt"], rtol, atol, ks)
    else:
        record = check_step_accuracy(run_at, fixed["dt"], ks)
    if record is not None and not record["passed"]:  # a pass is said in the table's first line
        text = f"WARNING: {step_check_line(record)}"
        if log is not None:
            log(text)
        else:
            warnings.warn(text, stacklevel=3)
    return record


def _audit_record(audit: np.ndarray) -> dict:
    """What a removal table says of ``sync.give_up``'s checks (its ``audit``)."""
    sampled, locked, rerun = (int(v) for v in audit)
    bound = None if locked or not sampled else min(1.0, 3.0 / sampled)
    return {
        "pilot": f"every intact start that locks was inside the band by after / {PILOT_MARGIN:g}",
        "sampled": sampled,
        "locked": locked,
        "rerun": rerun,
        "fraction": AUDIT_FRACTION,
        "minimum": AUDIT_MIN,
        "bound95": bound,
    }


def _task_call(task: tuple, variants: np.ndarray, fixed: dict, threads) -> tuple:
    """The arguments of :func:`_removal_task` for ``task`` (its ``targets`` cut to its own lines)."""
    ks, group, intact = task
    targets = fixed["all_targets"]
    targets = np.concatenate([targets[:1], targets[1:][group]])
    return ks, variants[group], intact, {**fixed, "targets": targets, "group": group}, threads


def _unfinished(tasks: list[tuple], have: np.ndarray) -> list[tuple]:
    """``tasks`` less what ``have`` (bool ``(m, 1 + lines)``: column 0 the intact grid) holds."""
    out = []
    for ks, group, intact in tasks:
        intact = intact and not have[ks, 0].all()
        group = group[~have[ks][:, 1 + group].all(axis=0)]
        if intact or group.size:
            out.append((ks, group, intact))
    return out
