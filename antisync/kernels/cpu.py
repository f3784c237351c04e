"""CPU backend: numba batch drivers around the shared step functions of :mod:`.core`.

Layers (as in stumpy): the step functions of :mod:`antisync.kernels.core` advance a state;
the private drivers here run batches of realizations in parallel threads; :func:`simulate`,
:func:`simulate_model` and :func:`simulate_pathwise` are the public, validated entry points.

One lane driver, ``_integrate_lanes``, runs every model: each thread steps ``LANES``
trajectories together in a ``[node, lane]`` layout; a finished lane is refilled with the next
(realization, variant) item of the thread's queue, and the driver keeps one step clock and looks
at the lanes only when one may have met its criterion or reaches the step cap. The identical
first-order oscillators of the paper are the case without a model (``model=None``), which numba
compiles without any of the models' code: their Euler step with Taylor rotations and their RK4
step run on explicit machine vectors (``euler_step_vec``, ``rk4_step_vec`` of :mod:`.core`, the
lane count rounded up to a multiple of ``2 VEC``), the others on the lane loops of
:mod:`.core`. A generalized model (natural frequencies, phase lag, inertia, the frequency
criterion; docs/models.md) adds its per-lane frequencies and targets and the step functions of
:mod:`.model_steps`.

Beside it, the plain one-trajectory-per-thread references that the lanes match bit for bit:
``_integrate_batch`` (identical oscillators; the loop structure of the CUDA kernel) and
``_integrate_items`` (a model; ``make_model_kernels``' ``sync_steps``), selected by ``lanes=0``.

The identical model's drivers are compiled per state precision: ``precision="float32"`` runs
the Euler step with Taylor rotations on float32 lanes (twice as many per machine vector), bit
for bit the one-trajectory float32 driver.

With tangents switched on, the lane driver integrates the undamaged network with forward
sensitivities for every damaged edge at once (the tangent of the Euler step, exact for the
discretized dynamics): the pathwise estimator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import model_steps as ms
from antisync.kernels.core import (
    CRIT_FREQUENCY,
    CRIT_ORDER,
    DEV_PREV_ROW,
    DEV_ROW,
    RENORM_EVERY,
    TAYLOR_MAX_ANGLE,
    VEC,
    WORK_ROWS,
    lanes_per_vector,
    make_kernels,
    renorm_interval,
)
from antisync.kernels.model_steps import ModelParams, per_node
from antisync.physics.phases import phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED
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

_jit = lambda f: njit(f, inline="always", cache=True)  # noqa: E731
_K = make_kernels(_jit)
_K32 = make_kernels(_jit, np.float32)
_tangent_lanes = _K.tangent_step_lanes
_hermite = _K.hermite_crossing
_sync64, _sync32 = _K.sync_steps, _K32.sync_steps
_step_vec64, _step_vec32 = _K.euler_step_vec, _K32.euler_step_vec
_renorm64, _renorm32 = _K.renormalize, _K32.renormalize
_order2_64, _order2_32 = _K.order2, _K32.order2
_step_lanes64 = _K.euler_step_lanes
_rk4_vec64 = _K.rk4_step_vec
# the generalized models' one-trajectory functions (make_model_kernels, float64)
_model_sync = ms.MK.sync_steps
_model_rhs = ms.MK.rhs
_model_measure = ms.MK.measure
_model_deviations = ms.MK.deviations
_order_crossing = ms.MK.order_crossing
_frequency_crossing = ms.MK.frequency_crossing
_model_euler_vec = ms.euler_vec
_model_rk4_vec = ms.rk4_vec
_model_rk4_start = ms.rk4_start
_model_euler_lanes = ms.euler_lanes
_model_rhs_vec = ms.rhs_vec
_model_deviations_lanes = ms.deviations_lanes

PRECISIONS = ("float64", "float32")
"""Arithmetic of the lane state. float32 runs the Euler step with Taylor rotations only
(twice the lanes per machine vector); everything else is float64."""


# --- the step functions of the state's precision ---------------------------------------------
# The drivers below are compiled once per argument types: a float32 state (c, s and the
# weights) picks the float32 step functions here, a float64 state the float64 ones. The float32
# drivers run the Euler step with Taylor rotations only, but numba types every branch: the
# float64-only steps get an empty float32 body. It is never reached, because simulate()
# refuses float32 with RK4 or without Taylor rotations; it cannot raise instead, since a raise
# inside the driver's prange body would make numba run the loop serially.


def _sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
    """The one-trajectory Euler integration of ``c``'s precision (``Kernels.sync_steps``)."""


@overload(_sync_steps)
def _sync_steps_impl(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
    if c.dtype == types.float32:
        return lambda c, s, acc, indptr, indices, weights, dt, r2_target, max_steps: _sync32(
            c, s, acc, indptr, indices, weights, dt, r2_target, max_steps
        )
    return lambda c, s, acc, indptr, indices, weights, dt, r2_target, max_steps: _sync64(
        c, s, acc, indptr, indices, weights, dt, r2_target, max_steps
    )


def _step_vec(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2):
    """``Kernels.euler_step_vec`` of ``c``'s precision."""


@overload(_step_vec, inline="always")
def _step_vec_impl(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2):
    if c.dtype == types.float32:
        return lambda c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2: _step_vec32(
            c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2
        )
    return lambda c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2: _step_vec64(
        c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2
    )


def _renormalize(c, s):
    """``Kernels.renormalize`` of ``c``'s precision."""


@overload(_renormalize, inline="always")
def _renormalize_impl(c, s):
    if c.dtype == types.float32:
        return lambda c, s: _renorm32(c, s)
    return lambda c, s: _renorm64(c, s)


def _order2(c, s):
    """``Kernels.order2`` of ``c``'s precision."""


@overload(_order2)
def _order2_impl(c, s):
    if c.dtype == types.float32:
        return lambda c, s: _order2_32(c, s)
    return lambda c, s: _order2_64(c, s)


def _step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
    """``Kernels.euler_step_lanes`` (float64 only)."""


@overload(_step_lanes, inline="always")
def _step_lanes_impl(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
    if c.dtype == types.float32:

        def unavailable(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
            pass  # never called (see above)

        return unavailable
    return lambda c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor: _step_lanes64(
        c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor
    )


def _rk4_vec(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
    """``Kernels.rk4_step_vec`` (float64 only)."""


@overload(_rk4_vec, inline="always")
def _rk4_vec_impl(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
    if c.dtype == types.float32:

        def unavailable(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
            pass  # never called (see above)

        return unavailable
    return lambda c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2: _rk4_vec64(
        c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2
    )


LANES = 32
"""Trajectories stepped together per thread (the inner width of the ``[node, lane]`` layout)."""


class _Graph(NamedTuple):
    """The drivers' network: ``W`` in CSR form and the CSR weights of every damage variant."""

    indptr: np.ndarray
    """int64 (N + 1,)"""
    indices: np.ndarray
    """int64 (nnz,)"""
    base_w: np.ndarray
    """float64 (nnz,): the undamaged ``W``."""
    var_w: np.ndarray
    """float64 (V, nnz): each damaged ``W(Omega*)``."""
    var_is_base: np.ndarray
    """bool (V,): variant ``v`` leaves ``W`` unchanged (its result is copied from tau0)."""
    todo: np.ndarray = np.ones((0, 0), dtype=np.bool_)
    """bool (m, V + 1): the lane driver integrates only the marked (realization, network)
    items, column 0 the undamaged network; shape (0, 0): every item."""


class _Run(NamedTuple):
    """The constants of one batch."""

    seed: np.uint64
    dt: float
    r2_target: float
    """``(threshold N)^2``: ``R = |sum_j e^{i theta_j}|^2`` at the threshold."""
    max_steps: int
    taylor: bool
    """Every rotation angle is within the Taylor polynomials' range (lane driver)."""
    rk4: bool
    """RK4 with Hermite crossing instead of Euler (lane driver)."""
    lanes: int
    """Trajectories stepped together per thread (lane driver)."""
    renorm: int = RENORM_EVERY
    """Euler steps between projections of the state back to the unit circle."""
    block: int = 2 * VEC
    """Lanes the vector kernels step together (two machine vectors of the state's precision):
    the lane arrays are a multiple of it wide."""


class _Outputs(NamedTuple):
    """Arrays the lane driver fills, one row per realization."""

    status0: np.ndarray
    """int8 (m,)"""
    steps0: np.ndarray
    """int64 (m,)"""
    frac0: np.ndarray
    """float64 (m,)"""
    status: np.ndarray
    """int8 (m, V)"""
    steps: np.ndarray
    """int64 (m, V)"""
    frac: np.ndarray
    """float64 (m, V)"""
    dtau: np.ndarray
    """float64 (m, E): d tau0 / d beta_e (E = 0 without tangents)."""


class _Tangents(NamedTuple):
    """The damaged edges whose forward sensitivities ride along (all empty: none).

    Damage on edge ``e = a -> b`` changes row ``a`` of ``W`` as ``dw_aj/dbeta = rho[e] w_aj +
    mu[e] [j = b]``.
    """

    edge_a: np.ndarray
    """int64 (E,)"""
    edge_b: np.ndarray
    """int64 (E,)"""
    rho: np.ndarray
    """float64 (E,)"""
    mu: np.ndarray
    """float64 (E,)"""


_NO_TANGENTS = _Tangents(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))


class _Model(NamedTuple):
    """A generalized model's constants for the lane driver (:class:`ModelParams` as arrays);
    the driver takes ``None`` for the identical first-order oscillators."""

    freqs: np.ndarray
    """float64 (1 or m, N): natural frequencies, one row for all realizations or one each."""
    cos_lag: float
    sin_lag: float
    mass: np.ndarray
    """float64 (N,): inertia m_i (0: a first-order node)."""
    gamma: np.ndarray
    """float64 (N,): damping."""
    criterion: int
    """CRIT_ORDER or CRIT_FREQUENCY."""
    targets: np.ndarray
    """float64 (V + 1,): the criterion's target of the undamaged network, then of each variant."""


@njit(parallel=True, cache=True)
def _integrate_batch(ks, graph, run, status0, steps0, status, steps):
    # fields as locals before the prange (see _integrate_lanes)
    indptr = graph.indptr
    indices = graph.indices
    base_w = graph.base_w
    var_w = graph.var_w
    var_is_base = graph.var_is_base
    seed = run.seed
    dt = run.dt
    r2_target = run.r2_target
    max_steps = run.max_steps
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
        st, k = _sync_steps(c, s, acc, indptr, indices, base_w, dt, r2_target, max_steps)
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
            st_v, k_v = _sync_steps(c, s, acc, indptr, indices, var_w[v], dt, r2_target, max_steps)
            status[r, v] = st_v
            steps[r, v] = k_v


@njit(inline="always")
def _next_item(r, v, r_hi, var_is_base):
    """Advance the work cursor (realization r, variant v; v = -1 is the undamaged network),
    skipping variants whose weights equal the base (their result is copied afterwards)."""
    n_var = var_is_base.shape[0]
    while True:
        v += 1
        if v == n_var:
            v = -1
            r += 1
        if r >= r_hi or v < 0 or not var_is_base[v]:
            return r, v


@njit(inline="always")
def _record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x):
    """Store item ``(r, v)``'s status, steps and crossing fraction: the undamaged network's for
    ``v < 0``, else variant ``v``'s. (The arrays one by one: outputs passed in a tuple lose
    their writes inside a parallel loop.)"""
    if v < 0:
        status0[r] = st
        steps0[r] = k
        frac0[r] = x
    else:
        status[r, v] = st
        steps[r, v] = k
        frac[r, v] = x


@njit(inline="always")
def _start_state(seed, k, ci, si, r2_target):
    """Initial (cos, sin) of realization k (computed in double, stored in the state's precision);
    returns True when r(0) already reaches the threshold."""
    for i in range(ci.shape[0]):
        th = phase(seed, k, i)
        ci[i] = np.cos(th)
        si[i] = np.sin(th)
    return _order2(ci, si) >= r2_target


@njit(inline="always")
def _load_lane(
    q,
    qr,
    qv,
    r_hi,
    seed,
    ks,
    base_w,
    var_w,
    var_is_base,
    todo,
    r2_target,
    c,
    s,
    lw,
    ci,
    si,
    start,
    lane_r,
    lane_v,
    lane_t0,
    t,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
    """Put the next queued item that needs integrating into lane ``q``.

    Items already synchronized at t = 0 are recorded on the spot. Returns the advanced cursor
    and 1 if the lane was filled, 0 if the queue is empty.
    """
    n = c.shape[0]
    while qr < r_hi:
        r, v = qr, qv
        qr, qv = _next_item(qr, qv, r_hi, var_is_base)
        if todo.shape[0] > 0 and not todo[r, v + 1]:
            continue
        if start[0] != r:
            # the realization's initial state, kept in (ci, si) for its variants that follow
            start[0] = r
            start[1] = _start_state(seed, ks[r], ci, si, r2_target)
        if start[1]:
            _record(status0, steps0, frac0, status, steps, frac, r, v, ALREADY_SYNCED, 0, 0.0)
            continue
        for i in range(n):
            c[i, q] = ci[i]
            s[i, q] = si[i]
        for p in range(lw.shape[0]):
            lw[p, q] = base_w[p] if v < 0 else var_w[v, p]
        lane_r[q] = r
        lane_v[q] = v
        lane_t0[q] = t
        return qr, qv, 1
    return qr, qv, 0


@njit(inline="always")
def _lane_initial(c, s, kv, lw, indptr, indices, rk4, q, r2, dr2, u, dr2t):
    """Order parameter (and, for RK4, stage-1 velocity) of a freshly loaded lane ``q``: the
    operations of ``lane_velocity`` for this lane only."""
    if rk4:
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        d3 = 0.0
        for i in range(c.shape[0]):
            sc = 0.0
            ss = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                sc += lw[p, q] * c[j, q]
                ss += lw[p, q] * s[j, q]
            omega = c[i, q] * ss - s[i, q] * sc
            kv[0, i, q] = -s[i, q] * omega
            kv[1, i, q] = c[i, q] * omega
            d0 += kv[0, i, q]
            d1 += kv[1, i, q]
            d2 += c[i, q]
            d3 += s[i, q]
        r2[q] = d2**2 + d3**2
        dr2[q] = 2.0 * (d2 * d0 + d3 * d1)
    else:
        r2[q] = c[:, q].sum() ** 2 + s[:, q].sum() ** 2
    for e in range(u.shape[0]):
        dr2t[e, q] = 0.0
        for i in range(u.shape[1]):
            u[e, i, q] = 0.0


@njit(inline="always")
def _share_base(var_is_base, r, status0, steps0, frac0, status, steps, frac):
    """Realization ``r``'s variants that leave the weights unchanged get the undamaged result."""
    for v in range(var_is_base.shape[0]):
        if var_is_base[v]:
            status[r, v] = status0[r]
            steps[r, v] = steps0[r]
            frac[r, v] = frac0[r]


@njit(parallel=True, cache=True)
def _integrate_items(
    ks,
    seed,
    indptr,
    indices,
    base_w,
    var_w,
    var_is_base,
    todo,
    freqs,
    cl,
    sl,
    inertia,
    damping,
    criterion,
    targets,
    dt,
    rk4,
    max_steps,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
    """A generalized model one trajectory per item (the fields of :class:`_Graph` and
    :class:`_Model` one by one): ``make_model_kernels``' ``sync_steps`` from the realization's
    phases, the plain reference that the lane driver matches bit for bit."""
    m = ks.shape[0]
    n = indptr.shape[0] - 1
    n_var = var_w.shape[0]
    per = n_var + 1
    for item in prange(m * per):
        r = item // per
        v = item % per - 1
        if v >= 0 and var_is_base[v]:
            continue  # copied from the undamaged result below
        if todo.shape[0] > 0 and not todo[r, v + 1]:
            continue  # not asked for: left at -1 / NaN
        c = np.empty(n)
        s = np.empty(n)
        nu = np.zeros(n)
        th = np.empty(n)
        dnu = np.zeros(n)
        work = np.empty((WORK_ROWS, n))
        for i in range(n):
            theta = phase(seed, ks[r], i)
            c[i] = np.cos(theta)
            s[i] = np.sin(theta)
        p = freqs[r] if freqs.shape[0] > 1 else freqs[0]
        w = base_w if v < 0 else var_w[v]
        st, k, x = _model_sync(
            c,
            s,
            nu,
            th,
            dnu,
            work,
            p,
            indptr,
            indices,
            w,
            cl,
            sl,
            inertia,
            damping,
            dt,
            rk4,
            criterion,
            targets[v + 1],
            max_steps,
        )
        _record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)
    for r in prange(m):
        _share_base(var_is_base, r, status0, steps0, frac0, status, steps, frac)


@njit(cache=True)  # not inlined: numba's inline pass fails on it ("closure with *args")
def _model_load(
    q,
    qr,
    qv,
    r_hi,
    seed,
    ks,
    base_w,
    var_w,
    var_is_base,
    todo,
    freqs,
    targets,
    cl,
    sl,
    mass,
    gamma,
    second,
    freq,
    indptr,
    indices,
    c,
    s,
    nu,
    th,
    dnu,
    p,
    lw,
    work,
    r2,
    dr2,
    lane_r,
    lane_v,
    lane_t0,
    lane_target,
    t,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
    """Put the next queued item that needs integrating into lane ``q`` (the one-trajectory
    ``sync_steps``' start on the lane's column); items met at t = 0 are recorded on the spot.
    Returns the advanced cursor and 1 if the lane was filled, 0 if the queue is empty."""
    n = c.shape[0]
    while qr < r_hi:
        r, v = qr, qv
        qr, qv = _next_item(qr, qv, r_hi, var_is_base)
        if todo.shape[0] > 0 and not todo[r, v + 1]:
            continue
        row = r if freqs.shape[0] > 1 else 0
        for i in range(n):
            theta = phase(seed, ks[r], i)
            c[i, q] = np.cos(theta)
            s[i, q] = np.sin(theta)
            nu[i, q] = 0.0
            dnu[i, q] = 0.0
            p[i, q] = freqs[row, i]
        for e in range(lw.shape[0]):
            lw[e, q] = base_w[e] if v < 0 else var_w[v, e]
        target = targets[v + 1]
        cq, sq, thq, dnuq = c[:, q], s[:, q], th[:, q], dnu[:, q]
        _model_rhs(
            cq, sq, nu[:, q], p[:, q], indptr, indices, lw[:, q], cl, sl, mass, gamma, second, thq, dnuq
        )
        r2[q] = _order2(cq, sq)
        d, dev = _model_measure(cq, sq, thq, dnuq, mass, gamma, second)
        dr2[q] = d
        if freq:
            met = dev < target
            if not met:
                _model_deviations(
                    cq, sq, thq, dnuq, indptr, indices, lw[:, q], cl, sl, mass, gamma, second, work[:, :, q]
                )
        else:
            met = r2[q] >= target
        if met:
            _record(status0, steps0, frac0, status, steps, frac, r, v, ALREADY_SYNCED, 0, 0.0)
            continue
        lane_r[q] = r
        lane_v[q] = v
        lane_t0[q] = t
        lane_target[q] = target
        return qr, qv, 1
    return qr, qv, 0


@njit(parallel=True, cache=True)
def _integrate_lanes(ks, graph, run, model, out, tangents, n_groups):
    """Lanes of trajectories with refill: realizations ``ks`` (split into ``n_groups`` ranges,
    one per parallel task) of ``graph`` (a :class:`_Graph`) with the constants ``run`` (a
    :class:`_Run`), results into ``out`` (:class:`_Outputs`). With ``tangents.edge_a`` non-empty
    (and no variants) every trajectory also carries forward sensitivities and ``out.dtau[r, e]``
    receives d tau0/d beta_e.

    ``model`` (a :class:`_Model`) adds natural frequencies, a phase lag, inertia and the other
    criteria (:mod:`antisync.kernels.model_steps`); ``None`` is the identical first-order
    model, and numba compiles that case without any of the model's terms (the branches on
    ``model is None`` are pruned before typing), so its code is the default path's alone.

    Two rules keep numba's parallel pass right here, both learnt the hard way: every name is
    bound whatever ``model`` is (a lane array bound in a pruned branch only once arrived as
    another array of shape (0, 0)), and ``model`` itself is not used inside the ``prange`` body
    (an expression on it there made the model's Euler step twice as slow; a plain function per
    task, instead of the ``prange`` body, made it four times as slow: its inlined step functions
    kept their reference counting in the vector loops).
    """
    # every field as a local before the prange: a parallel loop that writes to an array
    # reached through a named tuple loses the writes (numba issues #5872, #7135, #10338)
    indptr = graph.indptr
    indices = graph.indices
    base_w = graph.base_w
    var_w = graph.var_w
    var_is_base = graph.var_is_base
    todo = graph.todo
    seed = run.seed
    dt = run.dt
    r2_target = run.r2_target
    max_steps = run.max_steps
    taylor = run.taylor
    rk4 = run.rk4
    lanes = run.lanes
    renorm = run.renorm
    block = run.block
    status0 = out.status0
    steps0 = out.steps0
    frac0 = out.frac0
    status = out.status
    steps = out.steps
    frac = out.frac
    dtau = out.dtau
    edge_a = tangents.edge_a
    edge_b = tangents.edge_b
    rho = tangents.rho
    mu = tangents.mu
    n = indptr.shape[0] - 1
    nnz = base_w.shape[0]
    n_var = var_w.shape[0]
    n_edges = edge_a.shape[0]
    tangent = n_edges > 0
    # every name is bound on both sides of a branch on `model is None` (numba prunes the
    # branch before typing; a name bound on one side only confused its parallel pass)
    if model is None:
        freqs = np.zeros((1, 0))
        cl = 1.0
        sl = 0.0
        mass = np.zeros(0)
        gamma = np.zeros(0)
        targets = np.zeros(0)
        freq = False
        second = False
        # the Euler step with Taylor rotations and the RK4 step run on pairs of machine vectors
        fused = taylor and not rk4 and not tangent
        wide = fused or rk4
    else:
        freqs = model.freqs
        cl = model.cos_lag
        sl = model.sin_lag
        mass = model.mass
        gamma = model.gamma
        targets = model.targets
        freq = model.criterion == CRIT_FREQUENCY
        second = False
        for i in range(n):
            second |= mass[i] > 0.0
        # Euler with an order criterion needs no rates after the step: the step is fused
        fused = not rk4 and not freq
        wide = True
    # the vector steps take `block` lanes at a time: the arrays are `width` lanes wide, lanes
    # >= `lanes` stay empty (state (1, 0), weights 0)
    width = (lanes + block - 1) // block * block if wide else lanes
    # every lane integrates the undamaged network: its weights can be broadcast
    shared = n_var == 0
    # the scratch of the default model's steps (ni rows) and of a model's (nm rows)
    ni = n if model is None else 0
    nm = n - ni
    m = ks.shape[0]
    per = (m + n_groups - 1) // n_groups
    for group in prange(n_groups):
        r_lo = group * per
        r_hi = min(m, r_lo + per)
        if r_lo >= r_hi:
            continue
        # the state and weights in the run's precision (float32 or float64)
        c = np.ones((n, width), base_w.dtype)
        s = np.zeros((n, width), base_w.dtype)
        cn = np.ones((n, width) if fused else (0, width), base_w.dtype)
        sn = np.zeros((n, width) if fused else (0, width), base_w.dtype)
        lw = np.zeros((nnz, width), base_w.dtype)
        r2 = np.zeros(width, base_w.dtype)
        r2_prev = np.zeros(width, base_w.dtype)
        dr2 = np.zeros(width)
        dr2_prev = np.zeros(width)
        lane_r = np.full(width, -1, dtype=np.int64)
        lane_v = np.zeros(width, dtype=np.int64)
        lane_t0 = np.zeros(width, dtype=np.int64)
        # the default model's scratch (empty with a model) ...
        acc = np.empty((ni, width))
        sum_c = np.empty((ni, width))
        sum_s = np.empty((ni, width))
        tot_c = np.empty(width)
        tot_s = np.empty(width)
        # RK4 scratch: stage velocities kv[2 * stage + (0 for c, 1 for s)], two stage states
        kv = np.zeros((8 if rk4 else 2, ni, width))
        yc = np.empty((ni, width))
        ys = np.empty((ni, width))
        ybc = np.empty((ni if rk4 else 0, width))
        ybs = np.empty((ni if rk4 else 0, width))
        # tangent scratch: u[e] = d theta / d beta_e, and d R / d beta_e now and one step back
        u = np.zeros((n_edges, n, width))
        du = np.empty((n, width))
        cu = np.empty((n, width))
        su = np.empty((n, width))
        dr2t = np.zeros((n_edges, width))
        dr2t_prev = np.zeros((n_edges, width))
        ci = np.empty(n, base_w.dtype)
        si = np.empty(n, base_w.dtype)
        start = np.full(2, -1, dtype=np.int64)  # realization in (ci, si), synchronized at t = 0
        # ... and a model's (empty without one)
        spare = np.empty(VEC)
        nu = np.zeros((nm, width))
        th = np.zeros((nm, width))
        dnu = np.zeros((nm, width))
        lane_p = np.zeros((nm, width))
        work = np.zeros((WORK_ROWS, nm, width))
        # RK4: the stage states in turn and the sum k1 + 2 k2 + 2 k3 (rows c, s, nu)
        ya = np.zeros((3, nm if rk4 else 0, width))
        yb = np.zeros((3, nm if rk4 else 0, width))
        kacc = np.zeros((3, nm if rk4 else 0, width))
        m4 = np.zeros((4, width))
        lane_target = np.zeros(width)
        qr, qv = r_lo, -1
        active = 0
        t = 0
        # a lane's step count is t - lane_t0; the per-lane pass below runs only when some lane
        # may have met the criterion (a vectorized test) or reaches the step cap (and at t = 0,
        # to fill the lanes): it records what ended and refills the lane from the queue. Euler
        # lanes are renormalized at their own multiples of `renorm` steps, as in sync_steps
        next_cap = t + max_steps
        next_renorm = t + renorm
        event = True
        while True:
            if event:
                next_cap = t + max_steps
                for q in range(width):
                    if lane_r[q] >= 0:
                        k = t - lane_t0[q]
                        r = lane_r[q]
                        if model is None:
                            x = -1.0
                            if r2[q] >= r2_target:
                                span = r2[q] - r2_prev[q]
                                if rk4:
                                    x = _hermite(r2_prev[q], dr2_prev[q], r2[q], dr2[q], dt, r2_target)
                                else:
                                    # where a straight line through R crosses the target
                                    x = (r2_target - r2_prev[q]) / span
                                # tau = dt (k - 1 + x), x linear in R between the two steps:
                                # dx/dbeta = -((1 - x) dR_{k-1} + x dR_k) / (R_k - R_{k-1})
                                for e in range(n_edges):
                                    dtau[r, e] = -dt * ((1.0 - x) * dr2t_prev[e, q] + x * dr2t[e, q]) / span
                            elif k >= max_steps:
                                for e in range(n_edges):
                                    dtau[r, e] = 0.0
                        elif freq:
                            x = _frequency_crossing(work[:, :, q], n, second, dt, rk4, lane_target[q])
                        else:
                            x = _order_crossing(
                                r2_prev[q], dr2_prev[q], r2[q], dr2[q], dt, rk4, lane_target[q]
                            )
                        if x >= 0.0:
                            st = SYNCED
                        elif k >= max_steps:
                            st = NOT_SYNCED
                            x = 0.0
                        else:
                            next_cap = min(next_cap, lane_t0[q] + max_steps)
                            continue
                        _record(status0, steps0, frac0, status, steps, frac, r, lane_v[q], st, k, x)
                        lane_r[q] = -1
                        active -= 1
                    if q >= lanes:
                        continue  # padding of the vector width: never filled
                    if model is None:
                        qr, qv, filled = _load_lane(
                            q,
                            qr,
                            qv,
                            r_hi,
                            seed,
                            ks,
                            base_w,
                            var_w,
                            var_is_base,
                            todo,
                            r2_target,
                            c,
                            s,
                            lw,
                            ci,
                            si,
                            start,
                            lane_r,
                            lane_v,
                            lane_t0,
                            t,
                            status0,
                            steps0,
                            frac0,
                            status,
                            steps,
                            frac,
                        )
                        if filled:
                            _lane_initial(c, s, kv, lw, indptr, indices, rk4, q, r2, dr2, u, dr2t)
                    else:
                        qr, qv, filled = _model_load(
                            q,
                            qr,
                            qv,
                            r_hi,
                            seed,
                            ks,
                            base_w,
                            var_w,
                            var_is_base,
                            todo,
                            freqs,
                            targets,
                            cl,
                            sl,
                            mass,
                            gamma,
                            second,
                            freq,
                            indptr,
                            indices,
                            c,
                            s,
                            nu,
                            th,
                            dnu,
                            lane_p,
                            lw,
                            work,
                            r2,
                            dr2,
                            lane_r,
                            lane_v,
                            lane_t0,
                            lane_target,
                            t,
                            status0,
                            steps0,
                            frac0,
                            status,
                            steps,
                            frac,
                        )
                        if filled and rk4:
                            _model_rk4_start(c, s, nu, th, dnu, kacc, ya, q, 0.5 * dt, second)
                    active += filled
            if active == 0:
                break
            # the step writes r2 (dr2, dr2t) afresh for every lane: swap instead of copying
            t += 1
            r2, r2_prev = r2_prev, r2
            dr2, dr2_prev = dr2_prev, dr2
            if model is None:
                dr2t, dr2t_prev = dr2t_prev, dr2t
                if fused:
                    _step_vec(c, s, cn, sn, lw, base_w, shared, indptr, indices, dt, r2)
                    c, cn = cn, c
                    s, sn = sn, s
                elif rk4:
                    _rk4_vec(c, s, kv, yc, ys, ybc, ybs, lw, base_w, shared, indptr, indices, dt, r2, dr2)
                elif tangent:
                    _tangent_lanes(
                        c,
                        s,
                        acc,
                        sum_c,
                        sum_s,
                        tot_c,
                        tot_s,
                        lw,
                        indptr,
                        indices,
                        dt,
                        r2,
                        taylor,
                        u,
                        du,
                        cu,
                        su,
                        edge_a,
                        edge_b,
                        rho,
                        mu,
                        dr2t,
                    )
                else:
                    _step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor)
            else:
                if freq:
                    # the deviations one step back, for the crossing inside the step
                    for row in range(4):
                        for i in range(n):
                            for q in range(width):
                                work[DEV_PREV_ROW + row, i, q] = work[DEV_ROW + row, i, q]
                if rk4:
                    _model_rk4_vec(
                        c,
                        s,
                        nu,
                        th,
                        dnu,
                        ya,
                        yb,
                        kacc,
                        lane_p,
                        lw,
                        indptr,
                        indices,
                        cl,
                        sl,
                        mass,
                        gamma,
                        second,
                        dt,
                        not freq,
                        r2,
                        dr2,
                    )
                elif fused:
                    _model_euler_vec(
                        c,
                        s,
                        cn,
                        sn,
                        nu,
                        lane_p,
                        lw,
                        indptr,
                        indices,
                        cl,
                        sl,
                        mass,
                        gamma,
                        second,
                        dt,
                        taylor,
                        r2,
                        spare,
                    )
                    c, cn = cn, c
                    s, sn = sn, s
                else:
                    _model_euler_lanes(c, s, nu, th, dnu, dt, second)
            if not rk4 and t >= next_renorm:
                next_renorm = t + renorm
                for q in range(width):
                    if lane_r[q] < 0:
                        continue
                    k = t - lane_t0[q]
                    if k % renorm == 0:
                        _renormalize(c[:, q], s[:, q])
                    next_renorm = min(next_renorm, t + renorm - k % renorm)
            if model is None:
                hits = 0
                for q in range(width):
                    hits += (r2[q] >= r2_target) & (lane_r[q] >= 0)
            else:
                if freq and not rk4:
                    _model_rhs_vec(
                        c, s, nu, lane_p, lw, indptr, indices, cl, sl, mass, gamma, second, th, dnu
                    )
                if freq:
                    _model_deviations_lanes(
                        c, s, th, dnu, lw, indptr, indices, cl, sl, mass, gamma, second, work, m4
                    )
                    hits = 1  # the criterion's own bound test, per lane, in the pass above
                elif rk4:
                    # the Hermite interpolant of R over the step stays below max(R_0, R_1) +
                    # 4/27 (|m0| + |m1|) (its slope basis functions peak at 4/27): a lane below
                    # that bound, widened for rounding, cannot cross in this step
                    hits = 0
                    for q in range(width):
                        top = max(r2_prev[q], r2[q]) * (1.0 + 1e-12) + 0.15 * dt * (
                            abs(dr2_prev[q]) + abs(dr2[q])
                        )
                        hits += (top >= lane_target[q]) & (lane_r[q] >= 0)
                else:
                    hits = 0
                    for q in range(width):
                        hits += (r2[q] >= lane_target[q]) & (lane_r[q] >= 0)
            event = hits > 0 or t >= next_cap
        for r in range(r_lo, r_hi):
            # variants that leave W unchanged share the undamaged result
            _share_base(var_is_base, r, status0, steps0, frac0, status, steps, frac)
            if status0[r] == ALREADY_SYNCED:
                for e in range(n_edges):
                    dtau[r, e] = 0.0


@dataclass(frozen=True)
class SimResult:
    """Per-realization outcome of a batch (integration steps; ``tau = steps * dt``).

    Attributes
    ----------
    status0, steps0 : arrays, shape (m,)
        :class:`~antisync.status.Status` code and steps of the undamaged network.
    status, steps : arrays, shape (m, V)
        The same for each damage variant ``v``.
    frac0, frac : arrays or None
        Where inside the crossing step the threshold is met, ``x`` in ``(0, 1]``, from a
        straight line through ``R = |sum_j e^{i theta_j}|^2`` at the two grid points: the
        interpolated crossing time is ``(steps - 1 + x) dt`` (None from the plain driver).
    """

    status0: np.ndarray
    steps0: np.ndarray
    status: np.ndarray
    steps: np.ndarray
    frac0: np.ndarray | None = None
    frac: np.ndarray | None = None


@dataclass(frozen=True)
class PathwiseResult:
    """Undamaged trajectories with their sensitivities.

    Attributes
    ----------
    status0, steps0, frac0 : arrays, shape (m,)
        As in :class:`SimResult`; the interpolated ``tau0 = (steps0 - 1 + frac0) dt``.
    dtau : array, shape (m, E)
        ``d tau0 / d beta_e`` at ``beta = 0`` for damage on edge ``e`` (0 unless SYNCED).
    """

    status0: np.ndarray
    steps0: np.ndarray
    frac0: np.ndarray
    dtau: np.ndarray


def rotation_angle_bound(dt: float, indptr, base_w, var_w) -> float:
    """The largest rotation angle an Euler step can take, ``dt max_i sum_j |w_ij|`` over the base
    weights and every variant's (the lane kernels need it within
    :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`)."""
    return float(dt) * _row_sum_bound(indptr, base_w, var_w)


def _row_sum_bound(indptr, base_w, var_w) -> float:
    """Largest sum_j |w_ij| over rows of the base and every variant (bounds |omega_i|)."""
    rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
    best = 0.0
    for w in (base_w, *var_w):
        best = max(best, float(np.bincount(rows, np.abs(w), minlength=indptr.size - 1).max()))
    return best


def _realization_ids(first: int, count: int, realizations) -> np.ndarray:
    if realizations is not None:
        ks = np.asarray(realizations, dtype=np.uint64)
        if ks.ndim != 1:
            raise ValueError("realizations must be a 1-D array of realization indices")
        return ks
    if first < 0 or count < 0:
        raise ValueError("first and count must be non-negative")
    return np.arange(first, first + count, dtype=np.uint64)


class _Threads:
    """Temporarily set numba's thread count (results never depend on it)."""

    def __init__(self, threads):
        self.threads = threads

    def __enter__(self):
        self.previous = numba.get_num_threads()
        if self.threads is not None:
            numba.set_num_threads(max(1, min(int(self.threads), numba.config.NUMBA_NUM_THREADS)))
        return 4 * numba.get_num_threads()

    def __exit__(self, *exc):
        numba.set_num_threads(self.previous)


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
    ks = _realization_ids(first, count, realizations)
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
    graph = _Graph(indptr.astype(np.int64), indices.astype(np.int64), base_weights, var_w, var_is_base)
    if todo is not None:
        todo = np.ascontiguousarray(todo, dtype=np.bool_)
        if todo.shape != (m, var_w.shape[0] + 1):
            raise ValueError(f"todo must have shape {(m, var_w.shape[0] + 1)}, got {todo.shape}")
        for a in (status0, steps0, status, steps):
            a.fill(-1)
        # a variant equal to the base is integrated, not copied from a base that may not run
        graph = graph._replace(var_is_base=np.zeros_like(var_is_base), todo=todo)
    with _Threads(threads) as groups:
        if todo is not None and lanes:
            groups, lanes = _scattered_layout(int(todo.sum()), groups, int(lanes))
        run = _Run(
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
        out = _Outputs(status0, steps0, frac0, status, steps, frac, np.empty((m, 0)))
        _integrate_lanes(ks, graph, run, None, out, _NO_TANGENTS, groups)
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
    ks = _realization_ids(first, count, realizations)
    n = indptr.size - 1
    m = ks.size
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    out = _Outputs(
        np.empty(m, dtype=np.int8),
        np.empty(m, dtype=np.int64),
        np.empty(m),
        np.empty((m, 0), dtype=np.int8),
        np.empty((m, 0), dtype=np.int64),
        np.empty((m, 0)),
        np.empty((m, len(edge_a))),
    )
    graph = _Graph(
        indptr.astype(np.int64),
        indices.astype(np.int64),
        base_weights,
        np.empty((0, base_weights.size)),
        np.zeros(0, dtype=np.bool_),
    )
    taylor = rotation_angle_bound(dt, indptr, base_weights, []) <= TAYLOR_MAX_ANGLE
    run = _Run(np.uint64(seed), float(dt), (threshold * n) ** 2, int(max_steps), taylor, False, int(lanes))
    tangents = _Tangents(
        np.asarray(edge_a, dtype=np.int64),
        np.asarray(edge_b, dtype=np.int64),
        np.asarray(rho, dtype=np.float64),
        np.asarray(mu, dtype=np.float64),
    )
    with _Threads(threads) as groups:
        _integrate_lanes(ks, graph, run, None, out, tangents, groups)
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
    ks, base_weights, var_w, var_is_base, freqs, targets = model_inputs(
        first, count, realizations, indptr, base_weights, variant_weights, params, integrator
    )
    m = ks.size
    n_var = var_w.shape[0]
    n = indptr.size - 1
    if todo is None:
        todo = np.zeros((0, 0), dtype=np.bool_)
    else:
        todo = np.ascontiguousarray(todo, dtype=np.bool_)
        if todo.shape != (m, n_var + 1):
            raise ValueError(f"todo must have shape {(m, n_var + 1)}, got {todo.shape}")
        # a variant equal to the base is integrated, not copied from a base that may not run
        var_is_base[:] = False
    status0 = np.full(m, -1, dtype=np.int8)
    steps0 = np.full(m, -1, dtype=np.int64)
    frac0 = np.full(m, np.nan)
    status = np.full((m, n_var), -1, dtype=np.int8)
    steps = np.full((m, n_var), -1, dtype=np.int64)
    frac = np.full((m, n_var), np.nan)
    graph = _Graph(indptr.astype(np.int64), indices.astype(np.int64), base_weights, var_w, var_is_base, todo)
    model = _Model(
        freqs,
        float(params.cos_lag),
        float(params.sin_lag),
        per_node(params.inertia, n),
        per_node(params.damping, n),
        int(params.criterion),
        targets,
    )
    rk4 = integrator == "rk4"
    outputs = (status0, steps0, frac0, status, steps, frac)
    with _Threads(threads) as groups:
        if not lanes:
            _integrate_items(ks, np.uint64(seed), *graph, *model, float(dt), rk4, int(max_steps), *outputs)
        else:
            if todo.shape[0] > 0:
                groups, lanes = _scattered_layout(int(todo.sum()), groups, int(lanes))
            taylor = _taylor_everywhere(dt, indptr, base_weights, var_w, freqs, params, n)
            run = _Run(np.uint64(seed), float(dt), 0.0, int(max_steps), taylor, rk4, int(lanes))
            out = _Outputs(*outputs, np.empty((m, 0)))
            _integrate_lanes(ks, graph, run, model, out, _NO_TANGENTS, groups)
    return SimResult(status0, steps0, status, steps, frac0, frac)


def _scattered_layout(items: int, groups: int, lanes: int) -> tuple[int, int]:
    """``(groups, lanes)`` for a run of ``items`` scattered items (``todo``): half the lanes,
    down to 16, while a group would get fewer than eight items a lane, then no more groups (row
    ranges) than it takes to fill the lanes. A group steps until its last lane is done, so a
    few items, long ones among them (the hybrid's secants pass near saddles), leave most of 32
    lanes idle. Either gives the same results, bit for bit. Measured, one thread, the secants of
    ``adjoint-hybrid`` (ms per realization, 32 against 16 lanes): IEEE 118 swing, 46 items, 24
    against 16; karate, 242 items, 0.23-0.28 against 0.16-0.18; les miserables, 56 items,
    0.43-0.50 against 0.26-0.29 (bench/RESULTS.md)."""
    while lanes > 16 and items < 8 * lanes * groups:
        lanes //= 2
    return min(groups, max(1, -(-items // lanes))), lanes


def model_inputs(first, count, realizations, indptr, base_weights, variant_weights, params, integrator):
    """A model run's arguments checked and in the kernels' types, for the CPU and CUDA drivers:
    ``(ks, base_weights, var_w, var_is_base, freqs, targets)``; ``ValueError`` names what is
    wrong (the integrator, the criterion code, the shapes of ``freqs`` and ``targets``)."""
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    if params.criterion not in (CRIT_ORDER, CRIT_FREQUENCY):
        raise ValueError(f"unknown criterion code {params.criterion}")
    ks = _realization_ids(first, count, realizations)
    m = ks.size
    n = indptr.size - 1
    base = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base.size)
    n_var = var_w.shape[0]
    var_is_base = np.array([np.array_equal(w, base) for w in var_w], dtype=np.bool_)
    freqs = np.ascontiguousarray(params.freqs, dtype=np.float64)
    if freqs.ndim != 2 or freqs.shape[1] != n or freqs.shape[0] not in (1, m):
        raise ValueError(f"freqs must have shape (1, {n}) or ({m}, {n}), got {freqs.shape}")
    targets = np.ascontiguousarray(params.targets, dtype=np.float64)
    if targets.shape != (n_var + 1,):
        raise ValueError(f"targets must have shape ({n_var + 1},), got {targets.shape}")
    return ks, base, var_w, var_is_base, freqs, targets


def _taylor_everywhere(dt, indptr, base_w, var_w, freqs, params: ModelParams, n: int) -> bool:
    """Whether every Euler rotation angle ``dt theta_i'`` of a first-order model is within
    :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`: ``|theta_i'| <= max |P| + (|cos alpha| +
    |sin alpha|) max_i sum_j |w_ij|`` (a margin of 1e-9 for rounding). Never for inertia
    (``theta_i' = nu_i`` has no such bound)."""
    if (per_node(params.inertia, n) > 0.0).any():
        return False
    coupling = abs(params.cos_lag) + abs(params.sin_lag)
    rate = float(np.abs(freqs).max(initial=0.0)) + coupling * _row_sum_bound(indptr, base_w, var_w)
    return float(dt) * rate * (1.0 + 1e-9) <= TAYLOR_MAX_ANGLE
