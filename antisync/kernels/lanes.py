"""The lane driver: every model's realizations in lanes of trajectories, with refill.

Each thread steps ``LANES`` trajectories together in a ``[node, lane]`` layout; a finished lane
is refilled with the next (realization, variant) item of the thread's queue, and the driver
keeps one step clock and looks at the lanes only when one may have met its criterion or reaches
the step cap. One source serves every model: :func:`make_lane_driver` compiles it for a
:class:`LaneFeatures`, whose terms are compile-time constants. The identical first-order
oscillators of the paper are every term off (``model=None``), which numba compiles without any
of the models' code: their Euler step with Taylor rotations and their RK4 step run on explicit
machine vectors (``euler_step_vec``, ``rk4_step_vec`` of :mod:`.core`, the lane count rounded up
to a multiple of ``2 VEC``), the others on the lane loops of :mod:`.core`. A generalized model
(natural frequencies, phase lag, inertia, the frequency criterion; docs/models.md) adds its
per-lane frequencies and targets and the step functions of :mod:`.model_steps`.

With tangents switched on, the driver integrates the undamaged network with forward
sensitivities for every damaged edge at once (the tangent of the Euler step, exact for the
discretized dynamics): the pathwise estimator.

:func:`integrate_lanes` is called by the CPU backend's entry points (:mod:`.cpu`) and by the
adjoint's ordering pass (:mod:`.adjoint`); :func:`item_of` is the work-queue bookkeeping that
the one-trajectory drivers of :mod:`.cpu` and :mod:`.implicit` share with it (with
:mod:`.shared`'s ``record``, ``record_item`` and ``share_base``).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import model_steps as ms
from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER, DEV_PREV_ROW, DEV_ROW, VEC, WORK_ROWS
from antisync.kernels.precision import K64, order2, renormalize, rk4_vec, step_lanes, step_vec
from antisync.kernels.shared import Graph, Model, Outputs, has_inertia, record, record_item, share_base
from antisync.physics.phases import phase, start_phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = [
    "LaneFeatures",
    "Lanes",
    "ModelLanes",
    "Queue",
    "group_rows",
    "integrate_lanes",
    "item_of",
    "make_lane_driver",
    "next_item",
]

_tangent_lanes = K64.tangent_step_lanes
_hermite = K64.hermite_crossing
# the generalized models' one-trajectory functions (make_model_kernels, float64)
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


class Lanes(NamedTuple):
    """A thread's lanes, as a model's loader gets them: the state and weights in the ``[node, lane]``
    layout and the item each lane holds.

    The driver builds these groups inside its ``prange`` body and hands them to functions that
    are not inlined: an array reached through a named tuple and written in a parallel loop's
    own body loses the writes (numba issues #5872, #7135, #10338), one written in a called
    function keeps them.
    """

    c: np.ndarray
    """(N, width), the run's precision: ``cos theta``."""
    s: np.ndarray
    """(N, width): ``sin theta``."""
    lw: np.ndarray
    """(nnz, width): the CSR weights of the lane's network."""
    r2: np.ndarray
    """(width,): ``R = |sum_j e^{i theta_j}|^2`` now."""
    dr2: np.ndarray
    """float64 (width,): ``dR/dt`` now (RK4 and the models)."""
    item_r: np.ndarray
    """int64 (width,): the lane's realization row (-1: empty)."""
    item_v: np.ndarray
    """int64 (width,): the lane's variant (-1: the undamaged network)."""
    t0: np.ndarray
    """int64 (width,): the clock's step when the lane was filled."""
    target: np.ndarray
    """float64 (width,): the criterion's target of the lane's network (a model)."""


class ModelLanes(NamedTuple):
    """A generalized model's lane arrays beside :class:`Lanes` (each (N, width), float64)."""

    nu: np.ndarray
    """Frequencies ``nu = theta'`` of the inertial nodes."""
    th: np.ndarray
    """The rates ``theta'``."""
    dnu: np.ndarray
    """The rates ``nu'``."""
    p: np.ndarray
    """Natural frequencies of the lane's realization."""
    work: np.ndarray
    """(WORK_ROWS, N, width): the frequency criterion's deviations, now and one step back."""


@njit(inline="always")
def next_item(r, v, r_hi, var_is_base):
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
def _start_state(seed, k, ci, si, r2_target):
    """Initial (cos, sin) of realization k (computed in double, stored in the state's precision);
    returns True when r(0) already reaches the threshold."""
    for i in range(ci.shape[0]):
        th = phase(seed, k, i)
        ci[i] = np.cos(th)
        si[i] = np.sin(th)
    return order2(ci, si) >= r2_target


class Queue(NamedTuple):
    """What :func:`_load_lane` reads of a thread's work queue (built inside the driver's
    ``prange`` body at the call, as :class:`Lanes` is; nothing in it is written)."""

    seed: int
    """The run's seed (:func:`~antisync.physics.phases.phase`)."""
    ks: np.ndarray
    """uint64 (m,): the realization ids."""
    r_hi: int
    """The end of the thread's realization range."""
    r2_target: float
    """``R`` at the threshold: ``(N threshold)^2``."""


#: What :func:`_load_lane` did: the queue was empty, a lane was filled, or the item it took was
#: synchronized at t = 0 (the caller records it and asks again).
EMPTY, FILLED, MET = 0, 1, 2


@njit(inline="always")
def _load_lane(q, qr, qv, t, net, queue, c, s, lw, ci, si, start, lane_r, lane_v, lane_t0):
    """Put the next queued item that needs integrating into lane ``q``: ``net`` a
    :class:`~.shared.Graph`, ``queue`` a :class:`Queue`, the lane arrays one by one.

    The identical model's loader is inlined into the driver's ``prange`` body, so it writes only
    to arrays passed one by one (writes through a named tuple there are lost; see
    :class:`Lanes`) and leaves the outputs to the caller: as a non-inlined function taking
    :class:`Lanes` and the other groups (as :func:`_model_load` does), it made the identical
    model's Euler and RK4 lanes 10-16% slower (bench/bench_kernels.py, lollipop(6,3)): the
    arrays passed to a call escape, and the step loops lose what the compiler knew about them.

    Returns the advanced cursor, what happened (:data:`EMPTY`, :data:`FILLED` or :data:`MET`)
    and the item ``(r, v)`` taken: an item synchronized at t = 0 is the caller's to record.
    """
    n = c.shape[0]
    while qr < queue.r_hi:
        r, v = qr, qv
        qr, qv = next_item(qr, qv, queue.r_hi, net.var_is_base)
        if net.todo.shape[0] > 0 and not net.todo[r, v + 1]:
            continue
        if start[0] != r:
            # the realization's initial state, kept in (ci, si) for its variants that follow
            start[0] = r
            start[1] = _start_state(queue.seed, queue.ks[r], ci, si, queue.r2_target)
        if start[1]:
            return qr, qv, MET, r, v
        for i in range(n):
            c[i, q] = ci[i]
            s[i, q] = si[i]
        for p in range(lw.shape[0]):
            lw[p, q] = net.base_w[p] if v < 0 else net.var_w[v, p]
        lane_r[q] = r
        lane_v[q] = v
        lane_t0[q] = t
        return qr, qv, FILLED, r, v
    return qr, qv, EMPTY, -1, -1


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
def group_rows(group, n_groups, m):
    """The realizations ``r_lo <= r < r_hi`` of ``group`` when ``m`` are dealt to ``n_groups``
    in contiguous runs of ``ceil(m / n_groups)`` (the last groups may get fewer, or none)."""
    per = (m + n_groups - 1) // n_groups
    r_lo = group * per
    return r_lo, min(m, r_lo + per)


@njit(inline="always")
def item_of(item, per, var_is_base, todo):
    """``(r, v, run)`` of flat item ``item`` of a one-trajectory-per-item driver (``per`` items
    a realization: the undamaged network ``v = -1``, then each variant): ``run`` is False for a
    variant equal to the base (copied by :func:`share_base`) or an item ``todo`` leaves out."""
    r = item // per
    v = item % per - 1
    if v >= 0 and var_is_base[v]:
        return r, v, False
    if todo.shape[0] > 0 and not todo[r, v + 1]:
        return r, v, False  # not asked for: left at -1 / NaN
    return r, v, True


@njit(cache=True)  # not inlined: numba's inline pass fails on it ("closure with *args")
def _model_load(q, qr, qv, t, queue, graph, model, second, lanes, extra, out):
    """Put the next queued item that needs integrating into lane ``q`` (the one-trajectory
    ``sync_steps``' start on the lane's column; ``queue`` a :class:`Queue` (its ``r2_target``
    unused: a model's targets are per variant), ``graph`` a :class:`~.shared.Graph`, ``model`` a
    :class:`~.shared.Model`, ``second`` whether any node has inertia, ``lanes`` the thread's
    :class:`Lanes`, ``extra`` its :class:`ModelLanes`, ``out`` the :class:`~.shared.Outputs`);
    items met at t = 0 are recorded on the spot. Returns the advanced cursor and 1 if the lane
    was filled, 0 if the queue is empty."""
    indptr = graph.indptr
    indices = graph.indices
    freqs, cl, sl, mass, gamma = model[:5]
    freq = model.criterion == CRIT_FREQUENCY
    c = lanes.c
    s = lanes.s
    lw = lanes.lw
    r2 = lanes.r2
    nu = extra.nu
    th = extra.th
    dnu = extra.dnu
    p = extra.p
    r_hi = queue.r_hi
    n = c.shape[0]
    while qr < r_hi:
        r, v = qr, qv
        qr, qv = next_item(qr, qv, r_hi, graph.var_is_base)
        if graph.todo.shape[0] > 0 and not graph.todo[r, v + 1]:
            continue
        row = r if freqs.shape[0] > 1 else 0
        for i in range(n):
            theta = start_phase(model.starts, queue.seed, queue.ks[r], r, i)
            c[i, q] = np.cos(theta)
            s[i, q] = np.sin(theta)
            nu[i, q] = 0.0
            dnu[i, q] = 0.0
            p[i, q] = freqs[row, i]
        for e in range(lw.shape[0]):
            lw[e, q] = graph.base_w[e] if v < 0 else graph.var_w[v, e]
        target = model.targets[v + 1]
        cq, sq, thq, dnuq = c[:, q], s[:, q], th[:, q], dnu[:, q]
        eq = (p[:, q], lw[:, q], indptr, indices, cl, sl, mass, gamma)
        _model_rhs(cq, sq, nu[:, q], eq, second, thq, dnuq)
        r2[q] = order2(cq, sq)
        d, dev = _model_measure(cq, sq, thq, dnuq, mass, gamma, second)
        lanes.dr2[q] = d
        if freq:
            met = dev < target
            if not met:
                _model_deviations(cq, sq, thq, dnuq, eq, second, extra.work[:, :, q])
        else:
            met = r2[q] >= target
        if met:
            record_item(out, r, v, np.int64(ALREADY_SYNCED), np.int64(0), 0.0)
            continue
        lanes.item_r[q] = r
        lanes.item_v[q] = v
        lanes.t0[q] = t
        lanes.target[q] = target
        return qr, qv, 1
    return qr, qv, 0


class LaneFeatures(NamedTuple):
    """The model terms a lane driver is compiled with: compile-time constants of
    :func:`make_lane_driver`. The identical first-order oscillators of the paper are every term
    off."""

    model: bool = False
    """A generalized model (docs/models.md): natural frequencies, a phase lag, inertia with
    first-order buses and the frequency criterion, their values the data of a
    :class:`~.shared.Model`, stepped by :mod:`.model_steps`. Off: the identical oscillators'
    steps of :mod:`.core` (machine vectors, Taylor rotations, tangents)."""
    rk4: bool = False
    """Classical RK4 (the run's ``rk4``); off: Euler, whose driver holds the Euler steps with
    and without forward tangents (the tangents as a feature of their own made the pathwise
    lanes 30% slower: bench/RESULTS.md)."""


@functools.cache
def make_lane_driver(features: LaneFeatures):
    """The lane driver compiled for ``features`` (its arguments: :func:`integrate_lanes`).

    The features are constants of the closure: numba prunes every branch on them before
    typing, so the identical model's driver holds none of a model's code and compiles to the
    operations it always had, in the same order, and a model's driver none of the identical
    model's vector steps; an Euler driver holds no RK4 step, and so on. One
    source, one driver per feature set (cached on disk like any ``cache=True`` function, keyed
    by the constants): a run compiles only the steps of its integrator (fresh cache, one session:
    the identical model's float64 Euler driver in 49 s and its RK4 driver in 36 s, instead of
    82 s for the driver of both).

    Two rules keep numba's parallel pass right here, both learnt the hard way: every name is
    bound on both sides of a branch on a feature (a lane array bound in a pruned branch only
    once arrived as another array of shape (0, 0)), and ``model`` itself is not used inside the
    ``prange`` body (an expression on it there made the model's Euler step twice as slow; a
    plain function per task, instead of the ``prange`` body, made it four times as slow: its
    inlined step functions kept their reference counting in the vector loops).
    """
    identical = not features.model
    rk4 = features.rk4

    @njit(parallel=True, cache=True)
    def drive(ks, graph, run, model, out, tangents, n_groups):
        # every field as a local before the prange: a parallel loop that writes to an array
        # reached through a named tuple loses the writes (numba issues #5872, #7135, #10338)
        indptr, indices, base_w, var_w, var_is_base, todo = graph
        seed, dt, r2_target, max_steps, taylor, _, lanes, renorm, block = run
        status0 = out.status0
        steps0 = out.steps0
        frac0 = out.frac0
        status = out.status
        steps = out.steps
        frac = out.frac
        dtau = out.dtau
        edge_a, edge_b, rho, mu = tangents
        n = indptr.shape[0] - 1
        nnz = base_w.shape[0]
        n_var = var_w.shape[0]
        n_edges = edge_a.shape[0]
        tangent = n_edges > 0
        # every name is bound on both sides of a branch on `identical` (numba prunes the branch
        # before typing; a name bound on one side only confused its parallel pass)
        if identical:
            freqs = np.zeros((1, 0))
            starts = np.zeros((0, 0))
            cl = 1.0
            sl = 0.0
            mass = np.zeros(0)
            gamma = np.zeros(0)
            targets = np.zeros(0)
            criterion = CRIT_ORDER
            freq = False
            second = has_inertia(mass)
            # the Euler step with Taylor rotations and the RK4 step run on pairs of machine vectors
            fused = taylor and not rk4 and not tangent
            wide = fused or rk4
        else:
            freqs, cl, sl, mass, gamma, criterion, targets, starts = model
            freq = criterion == CRIT_FREQUENCY
            second = has_inertia(mass)
            # Euler with an order criterion needs no rates after the step: the step is fused
            fused = not rk4 and not freq
            wide = True
        # the vector steps take `block` lanes at a time: the arrays are `width` lanes wide, lanes
        # >= `lanes` stay empty (state (1, 0), weights 0)
        width = (lanes + block - 1) // block * block if wide else lanes
        # every lane integrates the undamaged network: its weights can be broadcast
        shared = n_var == 0
        # the scratch of the default model's steps (ni rows) and of a model's (nm rows)
        ni = n if identical else 0
        nm = n - ni
        m = ks.shape[0]
        for group in prange(n_groups):
            r_lo, r_hi = group_rows(group, n_groups, m)
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
            # the right-hand side's constants, once per task (read only: see Lanes)
            terms = ms.Terms(lane_p, lw, indptr, indices, cl, sl, mass, gamma, second)
            # RK4: the stage states in turn and the sum k1 + 2 k2 + 2 k3 (rows c, s, nu)
            ya = np.zeros((3, nm if rk4 else 0, width))
            yb = np.zeros((3, nm if rk4 else 0, width))
            kacc = np.zeros((3, nm if rk4 else 0, width))
            m4 = np.zeros((4, width))
            lane_target = np.zeros(width)
            qr, qv = r_lo, np.int64(-1)  # typed, not literal: see has_inertia
            active = 0
            t = np.int64(0)
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
                            if identical:
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
                                        dtau[r, e] = (
                                            -dt * ((1.0 - x) * dr2t_prev[e, q] + x * dr2t[e, q]) / span
                                        )
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
                            record(status0, steps0, frac0, status, steps, frac, r, lane_v[q], st, k, x)
                            lane_r[q] = -1
                            active -= 1
                        if q >= lanes:
                            continue  # padding of the vector width: never filled
                        # the groups built at the call, inside the body (see Lanes)
                        net = Graph(indptr, indices, base_w, var_w, var_is_base, todo)
                        queue = Queue(seed, ks, r_hi, r2_target)
                        if identical:
                            got = MET
                            while got == MET:
                                qr, qv, got, r, v = _load_lane(
                                    q, qr, qv, t, net, queue, c, s, lw, ci, si, start, lane_r, lane_v, lane_t0
                                )
                                if got == MET:
                                    record(
                                        status0,
                                        steps0,
                                        frac0,
                                        status,
                                        steps,
                                        frac,
                                        r,
                                        v,
                                        ALREADY_SYNCED,
                                        0,
                                        0.0,
                                    )
                            filled = 1 if got == FILLED else 0
                            if filled:
                                _lane_initial(c, s, kv, lw, indptr, indices, rk4, q, r2, dr2, u, dr2t)
                        else:
                            consts = Model(freqs, cl, sl, mass, gamma, criterion, targets, starts)
                            lane = Lanes(c, s, lw, r2, dr2, lane_r, lane_v, lane_t0, lane_target)
                            extra = ModelLanes(nu, th, dnu, lane_p, work)
                            res = Outputs(status0, steps0, frac0, status, steps, frac, dtau)
                            qr, qv, filled = _model_load(
                                q, qr, qv, t, queue, net, consts, second, lane, extra, res
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
                if identical:
                    dr2t, dr2t_prev = dr2t_prev, dr2t
                    # rk4 first: a feature, so numba compiles only its step (fused implies
                    # neither rk4 nor tangent)
                    if rk4:
                        rk4_vec(c, s, kv, yc, ys, ybc, ybs, lw, base_w, shared, indptr, indices, dt, r2, dr2)
                    elif tangent:
                        _tangent_lanes(
                            c,
                            s,
                            acc,
                            sum_c,
                            sum_s,
                            tot_c,
                            tot_s,
                            (lw, indptr, indices),
                            dt,
                            r2,
                            taylor,
                            u,
                            (du, cu, su),
                            (edge_a, edge_b, rho, mu),
                            dr2t,
                        )
                    elif fused:
                        step_vec(c, s, cn, sn, lw, base_w, shared, indptr, indices, dt, r2)
                        c, cn = cn, c
                        s, sn = sn, s
                    else:
                        step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor)
                else:
                    if freq:
                        # the deviations one step back, for the crossing inside the step
                        for row in range(4):
                            for i in range(n):
                                for q in range(width):
                                    work[DEV_PREV_ROW + row, i, q] = work[DEV_ROW + row, i, q]
                    if rk4:
                        _model_rk4_vec(c, s, nu, th, dnu, ya, yb, kacc, terms, dt, not freq, r2, dr2)
                    elif fused:
                        _model_euler_vec(c, s, cn, sn, nu, terms, dt, taylor, r2, spare)
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
                            renormalize(c[:, q], s[:, q])
                        next_renorm = min(next_renorm, t + renorm - k % renorm)
                if identical:
                    hits = 0
                    for q in range(width):
                        hits += (r2[q] >= r2_target) & (lane_r[q] >= 0)
                else:
                    if freq and not rk4:
                        _model_rhs_vec(c, s, nu, terms, th, dnu)
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
                share_base(var_is_base, r, out)
                if status0[r] == ALREADY_SYNCED:
                    for e in range(n_edges):
                        dtau[r, e] = 0.0

    return drive


def integrate_lanes(ks, graph, run, model, out, tangents, n_groups) -> None:
    """Lanes of trajectories with refill: realizations ``ks`` (split into ``n_groups`` ranges,
    one per parallel task) of ``graph`` (a :class:`~.shared.Graph`) with the constants ``run``
    (a :class:`~.shared.Run`), results into ``out`` (:class:`~.shared.Outputs`). With
    ``tangents.edge_a`` non-empty (and no variants) every trajectory also carries forward
    sensitivities and ``out.dtau[r, e]`` receives d tau0/d beta_e.

    ``model`` (a :class:`~.shared.Model`) adds natural frequencies, a phase lag, inertia and the
    other criteria (:mod:`antisync.kernels.model_steps`); ``None`` is the identical first-order
    model. Each runs the driver of its :class:`LaneFeatures` (:func:`make_lane_driver`).
    """
    features = LaneFeatures(model=model is not None, rk4=bool(run.rk4))
    drive = make_lane_driver(features)
    drive(ks, graph, run, model, out, tangents, n_groups)
