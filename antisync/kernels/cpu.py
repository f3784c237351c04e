"""CPU backend: numba batch drivers around the shared step functions of :mod:`.core`.

Layers (as in stumpy): the step functions of :mod:`antisync.kernels.core` advance a state;
the drivers run batches of realizations in parallel threads; :func:`simulate`,
:func:`simulate_model` and :func:`simulate_pathwise` are the public, validated entry points.

One lane driver, :func:`antisync.kernels.lanes.integrate_lanes`, runs every model (lanes of
trajectories with refill, the pathwise tangents included). Beside it, here, the plain
one-trajectory-per-thread references that the lanes match bit for bit: ``_integrate_batch``
(identical oscillators; the loop structure of the CUDA kernel) and ``_integrate_items`` (a
model; ``make_model_kernels``' ``sync_steps``), selected by ``lanes=0``.

The identical model's drivers are compiled per state precision (:mod:`.precision`):
``precision="float32"`` runs the Euler step with Taylor rotations on float32 lanes (twice as many
per machine vector), bit for bit the one-trajectory float32 driver.

The argument groups, results and host-side checks that the backends share live in
:mod:`.shared`; the ones the entry points return are re-exported here.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import loops
from antisync.kernels import model_steps as ms
from antisync.kernels.core import TAYLOR_MAX_ANGLE, WORK_ROWS, lanes_per_vector, renorm_interval
from antisync.kernels.lanes import integrate_lanes, item_of
from antisync.kernels.model_steps import ModelParams
from antisync.kernels.precision import sync_steps
from antisync.kernels.shared import (
    NO_TANGENTS,
    Graph,
    Outputs,
    PathwiseResult,
    Run,
    SimResult,
    Tangents,
    Threads,
    model_batch,
    per_node,
    realization_ids,
    record_item,
    rotation_angle_bound,
    row_sum_bound,
    share_rows,
)
from antisync.physics.phases import phase, start_phase
from antisync.types import Integrator

__all__ = [
    "LANES",
    "PRECISIONS",
    "PathwiseResult",
    "SimResult",
    "ModelParams",
    "rotation_angle_bound",
    "simulate",
    "simulate_model",
    "simulate_pathwise",
]

# the name antisync.execution imports (the realization indices of a chunk)
_realization_ids = realization_ids
_model_sync = ms.MK.sync_steps


PRECISIONS = ("float64", "float32")
"""Arithmetic of the lane state. float32 runs the Euler step with Taylor rotations only
(twice the lanes per machine vector); everything else is float64."""


LANES = 32
"""Trajectories stepped together per thread (the inner width of the ``[node, lane]`` layout)."""


@njit(parallel=True, cache=True)
def _integrate_batch(ks, graph, run, status0, steps0, status, steps):
    # fields as locals before the prange (see antisync.kernels.lanes.integrate_lanes)
    indptr, indices, base_w, var_w, var_is_base = graph[:5]
    seed, dt, r2_target, max_steps = run[:4]
    m = status0.shape[0]
    n = indptr.shape[0] - 1
    n_var = var_w.shape[0]
    for r in prange(m):
        theta = np.empty(n)
        c = np.empty(n, base_w.dtype)
        s = np.empty(n, base_w.dtype)
        acc = np.empty(n, base_w.dtype)
        for i in range(n):
            theta[i] = phase(seed, ks[r], i)
            c[i] = np.cos(theta[i])
            s[i] = np.sin(theta[i])
        st, k = sync_steps(c, s, acc, indptr, indices, base_w, dt, r2_target, max_steps)
        status0[r] = st
        steps0[r] = k
        for v in range(n_var):
            if var_is_base[v]:
                # this damage leaves W unchanged (e.g. a link leaving a degree-1 node)
                status[r, v] = st
                steps[r, v] = k
                continue
            for i in range(n):
                c[i] = np.cos(theta[i])
                s[i] = np.sin(theta[i])
            st_v, k_v = sync_steps(c, s, acc, indptr, indices, var_w[v], dt, r2_target, max_steps)
            status[r, v] = st_v
            steps[r, v] = k_v


def _integrate_items(item, ks, seed, graph, model, dt, rk4, max_steps, out):
    """A generalized model one trajectory per item (``graph`` a :class:`~.shared.Graph`,
    ``model`` a :class:`~.shared.Model`, results into ``out``, an :class:`~.shared.Outputs`):
    ``make_model_kernels``' ``sync_steps`` from the realization's phases, the plain reference
    that the lane driver matches bit for bit. The parallel loop only calls ``item``
    (:func:`_one_item`), a first-class function: the loop is compiled by
    :func:`antisync.kernels.loops.run` without linking the integration into it."""
    per = graph.var_w.shape[0] + 1
    for i in prange(ks.shape[0] * per):
        item(ks, seed, graph, model, dt, rk4, max_steps, out, np.int64(i))


@njit(cache=True)
def _one_item(ks, seed, graph, model, dt, rk4, max_steps, out, item):
    """Item ``item`` of :func:`_integrate_items`."""
    indptr, indices, base_w, var_w, var_is_base, todo = graph
    freqs, cl, sl, inertia, damping, criterion, targets, starts = model
    n = indptr.shape[0] - 1
    r, v, run = item_of(item, var_w.shape[0] + 1, var_is_base, todo)
    if not run:
        return
    c = np.empty(n)
    s = np.empty(n)
    nu = np.zeros(n)
    th = np.empty(n)
    dnu = np.zeros(n)
    work = np.empty((WORK_ROWS, n))
    for i in range(n):
        theta = start_phase(starts, seed, ks[r], r, i)
        c[i] = np.cos(theta)
        s[i] = np.sin(theta)
    p = freqs[r] if freqs.shape[0] > 1 else freqs[0]
    w = base_w if v < 0 else var_w[v]
    eq = (p, w, indptr, indices, cl, sl, inertia, damping)
    st, k, x = _model_sync(c, s, nu, th, dnu, work, eq, dt, rk4, criterion, targets[v + 1], max_steps)
    record_item(out, r, v, st, k, x)


def simulate(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    *,
    dt: float,
    threshold: float,
    max_steps: int,
    threads: int | None = None,
    lanes: int = LANES,
    realizations: np.ndarray | None = None,
    integrator: Integrator = "euler",
    todo: np.ndarray | None = None,
    precision: str = "float64",
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` for the base network and every variant.

    Parameters
    ----------
    seed, first, count : int
        Realization ``k`` starts from :func:`antisync.physics.phases.phase` ``(seed, k, node)``.
    indptr, indices, base_weights : arrays
        CSR form of ``W(Omega)`` (see :class:`antisync.physics.coupling.CouplingCSR`).
    variant_weights : array, shape (V, nnz)
        CSR weights of each damaged ``W(Omega*)`` on the same pattern.
    dt, threshold, max_steps
        Euler step, order-parameter threshold ``r`` and the step cap (``t_max / dt``).
    threads : int, optional
        Numba threads for this call (results do not depend on it).
    lanes : int
        Trajectories stepped together per thread; ``0`` selects the plain one-trajectory-at-a-
        time driver. Results are identical either way (same operations in the same order).
    realizations : array of int, optional
        Explicit realization indices instead of ``first .. first+count-1``.
    integrator : {"euler", "rk4"}
        Explicit Euler (the paper's) or classical RK4 (lane driver only; crossing times by
        cubic Hermite interpolation, see ``frac``).
    todo : bool array, shape (m, V + 1), optional
        Integrate only the marked items: ``todo[r, 0]`` the undamaged network of realization
        ``r``, ``todo[r, 1 + v]`` its variant ``v`` (lane driver only). The lanes are refilled
        from the marked items alone, so a few scattered items cost what they integrate. Items
        left out get status and steps ``-1`` and ``frac`` NaN.
    precision : {"float64", "float32"}
        Arithmetic of the state and the weights. float32 (Euler only; the lane driver also
        needs every rotation angle within the Taylor range, ``dt max_i sum_j |w_ij| <=``
        :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`) steps twice as many lanes per machine
        vector and renormalizes every ``RENORM_EVERY_FLOAT32`` steps; the initial phases are
        computed in double and rounded once. Both drivers give the same bits in either
        precision.
    """
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    f32 = precision == "float32"
    if f32 and integrator != "euler":
        raise ValueError("precision float32 runs the euler integrator only")
    if integrator == "rk4" and not lanes:
        raise ValueError("the rk4 integrator runs in the lane driver (lanes >= 1)")
    if todo is not None and not lanes:
        raise ValueError("todo runs in the lane driver (lanes >= 1)")
    ks = realization_ids(first, count, realizations)
    n = indptr.size - 1
    m = ks.size
    ftype = np.float32 if f32 else np.float64
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base_weights.size)
    # |alpha_i| = dt |omega_i| <= dt sum_j |w_ij|: then the Taylor rotation is always valid
    angle = rotation_angle_bound(dt, indptr, base_weights, var_w)
    taylor = angle <= TAYLOR_MAX_ANGLE
    if f32 and lanes and not taylor:
        raise ValueError(
            f"precision float32 in the lane driver needs dt * max_i sum_j |w_ij| <= {TAYLOR_MAX_ANGLE} "
            f"(got {angle:.4g}): use a smaller dt, precision float64 or lanes=0"
        )
    base_weights = base_weights.astype(ftype)
    var_w = var_w.astype(ftype)
    var_is_base = np.array([np.array_equal(w, base_weights) for w in var_w], dtype=np.bool_)
    status0 = np.empty(m, dtype=np.int8)
    steps0 = np.empty(m, dtype=np.int64)
    status = np.empty((m, var_w.shape[0]), dtype=np.int8)
    steps = np.empty((m, var_w.shape[0]), dtype=np.int64)
    graph = Graph(indptr.astype(np.int64), indices.astype(np.int64), base_weights, var_w, var_is_base)
    if todo is not None:
        todo = np.ascontiguousarray(todo, dtype=np.bool_)
        if todo.shape != (m, var_w.shape[0] + 1):
            raise ValueError(f"todo must have shape {(m, var_w.shape[0] + 1)}, got {todo.shape}")
        for a in (status0, steps0, status, steps):
            a.fill(-1)
        # a variant equal to the base is integrated, not copied from a base that may not run
        graph = graph._replace(var_is_base=np.zeros_like(var_is_base), todo=todo)
    with Threads(threads) as groups:
        if lanes:
            items = m * (1 + var_w.shape[0]) if todo is None else int(todo.sum())
            groups, lanes = _layout(items, groups, int(lanes))
        run = Run(
            np.uint64(seed),
            ftype(dt),
            ftype((threshold * n) ** 2),
            int(max_steps),
            taylor,
            integrator == "rk4",
            int(lanes),
            renorm_interval(ftype),
            2 * lanes_per_vector(ftype),
        )
        if not lanes:
            _integrate_batch(ks, graph, run, status0, steps0, status, steps)
            return SimResult(status0, steps0, status, steps)
        frac0 = np.empty(m) if todo is None else np.full(m, np.nan)
        frac = np.empty((m, var_w.shape[0])) if todo is None else np.full((m, var_w.shape[0]), np.nan)
        out = Outputs(status0, steps0, frac0, status, steps, frac, np.empty((m, 0)))
        integrate_lanes(ks, graph, run, None, out, NO_TANGENTS, groups)
    return SimResult(status0, steps0, status, steps, frac0, frac)


def simulate_pathwise(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    edge_a: np.ndarray,
    edge_b: np.ndarray,
    rho: np.ndarray,
    mu: np.ndarray,
    *,
    dt: float,
    threshold: float,
    max_steps: int,
    threads: int | None = None,
    lanes: int = LANES,
    realizations: np.ndarray | None = None,
) -> PathwiseResult:
    """Undamaged trajectories and ``d tau0 / d beta_e`` for damage on every edge ``e`` at once.

    Damage on edge ``e = a -> b`` changes row ``a`` of ``W`` as
    ``dw_aj/dbeta = rho[e] w_aj + mu[e] [j = b]`` (see
    :func:`antisync.physics.coupling.tangent_coefficients`).
    """
    ks = realization_ids(first, count, realizations)
    n = indptr.size - 1
    m = ks.size
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    out = Outputs(
        np.empty(m, dtype=np.int8),
        np.empty(m, dtype=np.int64),
        np.empty(m),
        np.empty((m, 0), dtype=np.int8),
        np.empty((m, 0), dtype=np.int64),
        np.empty((m, 0)),
        np.empty((m, len(edge_a))),
    )
    graph = Graph(
        indptr.astype(np.int64),
        indices.astype(np.int64),
        base_weights,
        np.empty((0, base_weights.size)),
        np.zeros(0, dtype=np.bool_),
    )
    taylor = rotation_angle_bound(dt, indptr, base_weights, []) <= TAYLOR_MAX_ANGLE
    run = Run(np.uint64(seed), float(dt), (threshold * n) ** 2, int(max_steps), taylor, False, int(lanes))
    tangents = Tangents(
        np.asarray(edge_a, dtype=np.int64),
        np.asarray(edge_b, dtype=np.int64),
        np.asarray(rho, dtype=np.float64),
        np.asarray(mu, dtype=np.float64),
    )
    with Threads(threads) as groups:
        integrate_lanes(ks, graph, run, None, out, tangents, groups)
    return PathwiseResult(out.status0, out.steps0, out.frac0, out.dtau)


def simulate_model(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    params: ModelParams,
    *,
    dt: float,
    max_steps: int,
    integrator: str = "euler",
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    todo: np.ndarray | None = None,
    lanes: int = LANES,
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` of a generalized model for the base
    network and every variant (same arguments as :func:`antisync.kernels.cpu.simulate`, plus
    the model's ``params``; ``threshold`` is in ``params.targets``). ``todo`` (bool, ``(m, V +
    1)``) integrates only the marked items, as in :func:`antisync.kernels.cpu.simulate`: the
    others get status and steps ``-1`` and ``frac`` NaN. ``lanes`` trajectories are stepped
    together per thread (the lane driver); ``lanes=0`` runs one trajectory per thread (the plain
    reference driver). Both give the same results, bit for bit.

    Returns a :class:`~antisync.kernels.cpu.SimResult` with ``frac0``/``frac`` (where inside
    the last step the criterion is met).
    """
    if lanes < 0:
        raise ValueError(f"lanes must be >= 0, got {lanes}")
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    ks, graph, model, out = model_batch(
        first, count, realizations, indptr, indices, base_weights, variant_weights, params, integrator, todo
    )
    n = indptr.size - 1
    rk4 = integrator == "rk4"
    with Threads(threads) as groups:
        if not lanes:
            args = (ks, np.uint64(seed), graph, model, float(dt), rk4, int(max_steps), out)
            loops.run(_integrate_items, _one_item, *args)
            share_rows(graph.var_is_base, out)
        else:
            every = ks.size * (1 + graph.var_w.shape[0])
            groups, lanes = _layout(
                int(graph.todo.sum()) if graph.todo.shape[0] else every, groups, int(lanes)
            )
            taylor = _taylor_everywhere(dt, indptr, graph.base_w, graph.var_w, model.freqs, params, n)
            run = Run(np.uint64(seed), float(dt), 0.0, int(max_steps), taylor, rk4, int(lanes))
            integrate_lanes(ks, graph, run, model, out, NO_TANGENTS, groups)
    return SimResult(out.status0, out.steps0, out.status, out.steps, out.frac0, out.frac)


def _layout(items: int, groups: int, lanes: int) -> tuple[int, int]:
    """``(groups, lanes)`` for a run of ``items`` items (every realization of every network, or
    the ``todo`` ones): half the lanes, down to 16, while a group would get fewer than eight
    items a lane, then no more groups (row ranges) than it takes to fill the lanes. A group
    steps until its last lane is done, so a few items, long ones among them (the hybrid's
    secants pass near saddles), leave most of 32 lanes idle; and a small batch cut into
    ``4 x threads`` groups steps mostly empty lanes (32 realizations at N = 1,000: 8 groups of
    4). Either gives the same results, bit for bit. Measured, one thread, the secants of
    ``adjoint-hybrid`` (ms per realization, 32 against 16 lanes): IEEE 118 swing, 46 items, 24
    against 16; karate, 242 items, 0.23-0.28 against 0.16-0.18; les miserables, 56 items,
    0.43-0.50 against 0.26-0.29 (bench/RESULTS.md)."""
    while lanes > 16 and items < 8 * lanes * groups:
        lanes //= 2
    return min(groups, max(1, -(-items // lanes))), lanes


def _taylor_everywhere(dt, indptr, base_w, var_w, freqs, params: ModelParams, n: int) -> bool:
    """Whether every Euler rotation angle ``dt theta_i'`` of a first-order model is within
    :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`: ``|theta_i'| <= max |P| + (|cos alpha| +
    |sin alpha|) max_i sum_j |w_ij|`` (a margin of 1e-9 for rounding). Never for inertia
    (``theta_i' = nu_i`` has no such bound)."""
    if (per_node(params.inertia, n) > 0.0).any():
        return False
    coupling = abs(params.cos_lag) + abs(params.sin_lag)
    rate = float(np.abs(freqs).max(initial=0.0)) + coupling * row_sum_bound(indptr, base_w, var_w)
    return float(dt) * rate * (1.0 + 1e-9) <= TAYLOR_MAX_ANGLE
