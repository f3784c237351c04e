"""CPU backend: numba batch drivers around the shared step functions of :mod:`.core`.

Layers (as in stumpy): the step functions of :mod:`antisync.kernels.core` advance a state;
the private drivers here run batches of realizations in parallel threads; :func:`simulate` and
:func:`simulate_pathwise` are the public, validated entry points.

Two drivers give identical results, bit for bit:

- ``_integrate_batch``: one trajectory at a time per thread (the plain reference path,
  the same loop structure as the CUDA kernel);
- ``_integrate_lanes`` (default): each thread steps ``LANES`` trajectories together in a
  ``[node, lane]`` layout; a finished lane is refilled with the next (realization, variant)
  item of the thread's queue. The Euler step with Taylor rotations and the RK4 step run on
  explicit machine vectors (``euler_step_vec``, ``rk4_step_vec`` of :mod:`.core`, the lane
  count rounded up to a multiple of ``2 VEC``); the others on the lane loops of :mod:`.core`.
  The driver keeps one step clock and looks at the lanes only when one crosses the
  threshold, must be renormalized or reaches the step cap.

Both drivers are compiled per state precision: ``precision="float32"`` runs the Euler step
with Taylor rotations on float32 lanes (twice as many per machine vector), bit for bit the
one-trajectory float32 driver.

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
from antisync.kernels.core import (
    RENORM_EVERY,
    TAYLOR_MAX_ANGLE,
    VEC,
    lanes_per_vector,
    make_kernels,
    renorm_interval,
)
from antisync.phases import phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED
from antisync.types import Integrator

__all__ = [
    "LANES",
    "PRECISIONS",
    "PathwiseResult",
    "SimResult",
    "rotation_angle_bound",
    "simulate",
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


@njit(parallel=True, cache=True)
def _integrate_lanes(ks, graph, run, out, tangents, n_groups):
    """Lanes of trajectories with refill: realizations ``ks`` (split into ``n_groups`` ranges,
    one per parallel task) of ``graph`` (a :class:`_Graph`) with the constants ``run`` (a
    :class:`_Run`), results into ``out`` (:class:`_Outputs`). With ``tangents.edge_a`` non-empty
    (and no variants) every trajectory also carries forward sensitivities and ``out.dtau[r, e]``
    receives d tau0/d beta_e."""
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
    m = status0.shape[0]
    n = indptr.shape[0] - 1
    nnz = base_w.shape[0]
    n_var = var_w.shape[0]
    n_edges = edge_a.shape[0]
    tangent = n_edges > 0
    # the Euler step with Taylor rotations and the RK4 step run on pairs of machine vectors of
    # VEC lanes: the arrays are `width` lanes wide, lanes >= `lanes` stay empty (state (1, 0),
    # weights 0)
    vec = taylor and not rk4 and not tangent
    block = run.block
    width = (lanes + block - 1) // block * block if vec or rk4 else lanes
    # every lane integrates the undamaged network: its weights can be broadcast
    shared = n_var == 0
    # a lane's step count is `t - lane_t0`; between events (a crossing, a renormalization or
    # the step cap of some lane) no lane needs looking at
    renorm = run.renorm if not rk4 else max_steps + 1
    per = (m + n_groups - 1) // n_groups
    for group in prange(n_groups):
        r_lo = group * per
        r_hi = min(m, r_lo + per)
        if r_lo >= r_hi:
            continue
        # the state and weights in the run's precision (float32 or float64)
        c = np.ones((n, width), base_w.dtype)
        s = np.zeros((n, width), base_w.dtype)
        cn = np.empty((n, width) if vec else (0, width), base_w.dtype)
        sn = np.empty((n, width) if vec else (0, width), base_w.dtype)
        acc = np.empty((n, width))
        sum_c = np.empty((n, width))
        sum_s = np.empty((n, width))
        lw = np.zeros((nnz, width), base_w.dtype)
        tot_c = np.empty(width)
        tot_s = np.empty(width)
        r2 = np.zeros(width, base_w.dtype)
        r2_prev = np.zeros(width, base_w.dtype)
        dr2 = np.zeros(width)
        dr2_prev = np.zeros(width)
        # RK4 scratch: stage velocities kv[2 * stage + (0 for c, 1 for s)], two stage states
        kv = np.zeros((8 if rk4 else 2, n, width))
        yc = np.empty((n, width))
        ys = np.empty((n, width))
        ybc = np.empty((n, width) if rk4 else (0, width))
        ybs = np.empty((n, width) if rk4 else (0, width))
        # tangent scratch: u[e] = d theta / d beta_e, and d R / d beta_e now and one step back
        u = np.zeros((n_edges, n, width))
        du = np.empty((n, width))
        cu = np.empty((n, width))
        su = np.empty((n, width))
        dr2t = np.zeros((n_edges, width))
        dr2t_prev = np.zeros((n_edges, width))
        lane_r = np.full(width, -1, dtype=np.int64)
        lane_v = np.zeros(width, dtype=np.int64)
        lane_t0 = np.zeros(width, dtype=np.int64)
        ci = np.empty(n, base_w.dtype)
        si = np.empty(n, base_w.dtype)
        start = np.full(2, -1, dtype=np.int64)  # realization in (ci, si), synchronized at t = 0
        qr, qv = r_lo, -1
        active = 0
        t = 0
        for q in range(lanes):
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
            active += filled
            if filled:
                _lane_initial(c, s, kv, lw, indptr, indices, rk4, q, r2, dr2, u, dr2t)
        next_event = t + min(renorm, max_steps)
        while active > 0:
            # the step writes r2 (dr2, dr2t) afresh for every lane: swap instead of copying
            r2, r2_prev = r2_prev, r2
            dr2, dr2_prev = dr2_prev, dr2
            dr2t, dr2t_prev = dr2t_prev, dr2t
            t += 1
            if vec:
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
            crossed = False
            for q in range(width):
                crossed |= (r2[q] >= r2_target) & (lane_r[q] >= 0)
            if not crossed and t < next_event:
                continue
            next_event = t + min(renorm, max_steps)
            for q in range(width):
                if lane_r[q] < 0:
                    continue
                k = t - lane_t0[q]
                r = lane_r[q]
                if r2[q] >= r2_target:
                    st = SYNCED
                    span = r2[q] - r2_prev[q]
                    if rk4:
                        x = _hermite(r2_prev[q], dr2_prev[q], r2[q], dr2[q], dt, r2_target)
                    else:
                        # where inside the last step a straight line through R crosses the target
                        x = (r2_target - r2_prev[q]) / span
                    # tau = dt (k - 1 + x), x linear in R between the two steps:
                    # dx/dbeta = -((1 - x) dR_{k-1} + x dR_k) / (R_k - R_{k-1})
                    for e in range(n_edges):
                        dtau[r, e] = -dt * ((1.0 - x) * dr2t_prev[e, q] + x * dr2t[e, q]) / span
                elif k >= max_steps:
                    st = NOT_SYNCED
                    x = 0.0
                    for e in range(n_edges):
                        dtau[r, e] = 0.0
                else:
                    if k % renorm == 0:
                        _renormalize(c[:, q], s[:, q])
                    # this lane's next renormalization or step cap
                    next_event = min(next_event, t + min(renorm - k % renorm, max_steps - k))
                    continue
                v = lane_v[q]
                _record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)
                lane_r[q] = -1
                active -= 1
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
                active += filled
                if filled:
                    _lane_initial(c, s, kv, lw, indptr, indices, rk4, q, r2, dr2, u, dr2t)
        for r in range(r_lo, r_hi):
            # variants that leave W unchanged share the undamaged result
            for v in range(n_var):
                if var_is_base[v]:
                    status[r, v] = status0[r]
                    steps[r, v] = steps0[r]
                    frac[r, v] = frac0[r]
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
        Realization ``k`` starts from :func:`antisync.phases.phase` ``(seed, k, node)``.
    indptr, indices, base_weights : arrays
        CSR form of ``W(Omega)`` (see :class:`antisync.coupling.CouplingCSR`).
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
    with _Threads(threads) as groups:
        if not lanes:
            _integrate_batch(ks, graph, run, status0, steps0, status, steps)
            return SimResult(status0, steps0, status, steps)
        frac0 = np.empty(m) if todo is None else np.full(m, np.nan)
        frac = np.empty((m, var_w.shape[0])) if todo is None else np.full((m, var_w.shape[0]), np.nan)
        out = _Outputs(status0, steps0, frac0, status, steps, frac, np.empty((m, 0)))
        if todo is not None:
            # few scattered items: no more groups (row ranges) than it takes to fill the lanes
            groups = min(groups, max(1, -(-int(todo.sum()) // max(1, int(lanes)))))
        _integrate_lanes(ks, graph, run, out, _NO_TANGENTS, groups)
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
    :func:`antisync.coupling.tangent_coefficients`).
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
        _integrate_lanes(ks, graph, run, out, tangents, groups)
    return PathwiseResult(out.status0, out.steps0, out.frac0, out.dtau)
