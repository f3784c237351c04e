"""CPU driver of the generalized models (natural frequencies, phase lag, inertia; docs/models.md).

Lanes of trajectories (:func:`simulate_model`, ``lanes=LANES``): each parallel task steps 32
(realization, variant) items together on the default path's ``[node, lane]`` layout and machine
vectors, refilling a lane when its item ends; every lane follows
:func:`antisync.kernels.core.make_model_kernels`' ``sync_steps`` from the realization's
counter-based phases (and natural frequencies) bit for bit. ``lanes=0`` runs that one-trajectory
function per item (:func:`_integrate_items`), the slow obvious reference the tests hold the
lanes to. The identical first-order model never comes here: it keeps the default lane driver of
:mod:`antisync.kernels.cpu`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels.core import (
    CRIT_FREQUENCY,
    CRIT_ORDER,
    DEV_PREV_ROW,
    DEV_ROW,
    RENORM_EVERY,
    TAYLOR_MAX_ANGLE,
    VEC,
    WORK_ROWS,
    make_kernels,
    make_model_kernels,
    vany_outside,
    vload,
    vsplat,
    vsqrt,
    vstore,
)
from antisync.kernels.cpu import (
    LANES,
    SimResult,
    _next_item,
    _realization_ids,
    _record,
    _row_sum_bound,
    _Threads,
)
from antisync.phases import make_uniform, phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = ["ModelParams", "draw_frequencies", "simulate_model"]

#: Counter streams of :func:`antisync.phases.make_uniform` used by the natural frequencies (the
#: initial phases are the separate hash :func:`antisync.phases.phase`).
STREAM_FREQ_A = 1
STREAM_FREQ_B = 2

_jit = lambda f: njit(f, inline="always", cache=True)  # noqa: E731
_K = make_kernels(_jit)
_MK = make_model_kernels(_jit, _K)
_model_sync = _MK.sync_steps
_model_rhs = _MK.rhs
_model_measure = _MK.measure
_model_deviations = _MK.deviations
_order_crossing = _MK.order_crossing
_frequency_crossing = _MK.frequency_crossing
_rotation = _K.rotation
_edge_vec = _K.edge_vec
_rotate_by_vec = _K.rotate_by_vec
_taylor = _K.taylor_rotation
_order2 = _K.order2
_renormalize = _K.renormalize


class ModelParams(NamedTuple):
    """The model's constants for a kernel (see :class:`antisync.model.Model`).

    ``freqs`` has one row (the same frequencies for every realization) or one row per
    realization of the batch, mean already removed; ``inertia`` and ``damping`` one number or
    one per node (``damping`` must be 1 where no node has inertia); ``targets[0]`` is the undamaged network's
    and ``targets[1 + v]`` variant ``v``'s: ``R = (r N)^2`` at the order-parameter or relative
    threshold, or the frequency tolerance.
    """

    freqs: np.ndarray
    cos_lag: float
    sin_lag: float
    inertia: float | np.ndarray
    damping: float | np.ndarray
    criterion: int
    targets: np.ndarray


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
    freqs,
    cl,
    sl,
    inertia,
    damping,
    dt,
    rk4,
    criterion,
    targets,
    max_steps,
    todo,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
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


# --- the lane driver ---------------------------------------------------------------------------
# The step functions of make_model_kernels on a [node, lane] state, on machine vectors of VEC
# lanes (two vectors at a time; the lane count a multiple of 2 VEC): per lane every function
# performs exactly the one-trajectory function's operations in the same order, so a lane's
# trajectory is the one-trajectory driver's, bit for bit. The refill path (one fresh lane) calls
# the one-trajectory functions on the lane's column.


@njit(inline="always")
def _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sc, ss, i):
    """``rhs``' node ``i`` for the lane vector at flat offset ``o`` of the state ``(c, s, nu)``
    from its coupling sums ``sc, ss``: ``(c_i, s_i, theta_i', nu_i')`` (``nu_i' = 0`` where the
    node or the model is first order)."""
    ci = vload(c, o)
    si = vload(s, o)
    k = (ci * ss - si * sc) * cl - (ci * sc + si * ss) * sl
    dnu = vsplat(0.0)
    if not second:
        th = vload(p, o) + k
    elif mass[i] > 0.0:
        v = vload(nu, o)
        th = v
        dnu = (vload(p, o) + k - v * gamma[i]) / mass[i]
    else:
        th = (vload(p, o) + k) / gamma[i]
    return ci, si, th, dnu


@njit(inline="always")
def _rhs_vec(c, s, nu, p, lw, indptr, indices, cl, sl, mass, gamma, second, th, dnu):
    """make_model_kernels' ``rhs`` for every lane: the coupling sums of each node kept in
    registers over its edges (``edge_vec``), then the rates into ``th``, ``dnu``."""
    n, lanes = c.shape
    zero = vsplat(0.0)
    for qa in range(0, lanes, 2 * VEC):
        for i in range(n):
            sca, ssa, scb, ssb = zero, zero, zero, zero
            for e in range(indptr[i], indptr[i + 1]):
                sca, ssa, scb, ssb = _edge_vec(c, s, lw, gamma, False, indices, e, qa, sca, ssa, scb, ssb)
            o = i * lanes + qa
            _, _, ta, da = _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sca, ssa, i)
            _, _, tb, db = _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o + VEC, scb, ssb, i)
            vstore(th, o, ta)
            vstore(th, o + VEC, tb)
            if second:
                vstore(dnu, o, da)
                vstore(dnu, o + VEC, db)


@njit(inline="always")
def _euler_vec(c, s, cn, sn, nu, p, lw, indptr, indices, cl, sl, mass, gamma, second, dt, taylor, r2, spare):
    """One Euler step of every lane, fused as the identical model's ``euler_step_vec``: per node
    the coupling sums over its edges (in registers), ``rhs``' rates at the current state, the
    rotation of ``(c_i, s_i)`` by ``dt theta_i'`` into ``(cn, sn)`` (the caller swaps the
    buffers) and ``nu_i += dt nu_i'``; ``r2`` gets each lane's ``R``. The rates are not kept
    (the order criteria with Euler need only ``R``). ``taylor`` promises every angle is within
    the Taylor range (else each vector is tested); ``spare`` (VEC floats) is scratch for a
    vector with an angle outside it."""
    n, lanes = c.shape
    zero = vsplat(0.0)
    for qa in range(0, lanes, 2 * VEC):
        qb = qa + VEC
        tca, tsa, tcb, tsb = zero, zero, zero, zero
        for i in range(n):
            sca, ssa, scb, ssb = zero, zero, zero, zero
            for e in range(indptr[i], indptr[i + 1]):
                sca, ssa, scb, ssb = _edge_vec(c, s, lw, gamma, False, indices, e, qa, sca, ssa, scb, ssb)
            o = i * lanes
            xa, ya = _euler_node_vec(
                c, s, cn, sn, nu, p, cl, sl, mass, gamma, second, dt, taylor, o + qa, sca, ssa, i, spare
            )
            xb, yb = _euler_node_vec(
                c, s, cn, sn, nu, p, cl, sl, mass, gamma, second, dt, taylor, o + qb, scb, ssb, i, spare
            )
            tca = tca + xa
            tsa = tsa + ya
            tcb = tcb + xb
            tsb = tsb + yb
        vstore(r2, qa, tca * tca + tsa * tsa)
        vstore(r2, qb, tcb * tcb + tsb * tsb)


@njit(cache=True)  # not inlined: the rare path stays out of the vector loop's registers
def _rotate_each(c, s, cn, sn, angles, o):
    """Some lane's angle is outside the Taylor range: ``rotation()`` lane by lane for the lane
    vector at flat offset ``o`` (angles in ``angles``)."""
    lanes = c.shape[1]
    row = o // lanes
    q0 = o - row * lanes
    for q in range(VEC):
        ca, sa = _rotation(angles[q])
        ci = c[row, q0 + q]
        si = s[row, q0 + q]
        cn[row, q0 + q] = ci * ca - si * sa
        sn[row, q0 + q] = si * ca + ci * sa


@njit(inline="always")
def _euler_node_vec(c, s, cn, sn, nu, p, cl, sl, mass, gamma, second, dt, taylor, o, sc, ss, i, spare):
    """Node ``i`` of :func:`_euler_vec` for the lane vector at flat offset ``o``."""
    ci, si, th, dnu = _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sc, ss, i)
    a = th * dt
    if taylor or not vany_outside(a, TAYLOR_MAX_ANGLE):
        x, y = _rotate_by_vec(ci, si, cn, sn, o, a)
    else:
        vstore(spare, 0, a)
        _rotate_each(c, s, cn, sn, spare, o)
        x = vload(cn, o)
        y = vload(sn, o)
    if second:
        vstore(nu, o, vload(nu, o) + dnu * dt)
    return x, y


@njit(inline="always")
def _euler_lanes(c, s, nu, th, dnu, dt, second):
    """make_model_kernels' ``euler_step`` for every lane from the rates in ``th``, ``dnu`` (the
    frequency criterion needs the rates of every step, so this step is not fused; ``R`` is not
    computed: that criterion does not use it)."""
    n, lanes = c.shape
    for i in range(n):
        # rotation() is the Taylor polynomial wherever |angle| <= TAYLOR_MAX_ANGLE: when every
        # lane's angle is, the branch-free loop computes the same numbers on machine vectors
        big = 0
        for q in range(lanes):
            big += abs(dt * th[i, q]) > TAYLOR_MAX_ANGLE  # an integer sum: vectorizes
        if big == 0:
            for q in range(lanes):
                ca, sa = _taylor(dt * th[i, q])
                ci = c[i, q]
                si = s[i, q]
                c[i, q] = ci * ca - si * sa
                s[i, q] = si * ca + ci * sa
        else:
            for q in range(lanes):
                ca, sa = _rotation(dt * th[i, q])
                ci = c[i, q]
                si = s[i, q]
                c[i, q] = ci * ca - si * sa
                s[i, q] = si * ca + ci * sa
        if second:
            for q in range(lanes):
                nu[i, q] += dt * dnu[i, q]


@njit(inline="always")
def _rk4_inner_vec(c, s, nu, src, dst, acc, p, lw, indptr, indices, cl, sl, mass, gamma, second, h, qa):
    """An inner RK4 stage of the lane vectors at ``qa`` and ``qa + VEC``: per node the rates at
    the stage state ``src`` (rows c, s, nu), ``acc += 2 k`` and ``dst = (c, s, nu) + h k``."""
    n, lanes = c.shape
    size = n * lanes
    zero = vsplat(0.0)
    two = vsplat(2.0)
    src_c, src_s, src_nu = src[0], src[1], src[2]
    for i in range(n):
        sca, ssa, scb, ssb = zero, zero, zero, zero
        for e in range(indptr[i], indptr[i + 1]):
            sca, ssa, scb, ssb = _edge_vec(src_c, src_s, lw, gamma, False, indices, e, qa, sca, ssa, scb, ssb)
        for v in range(2):
            o = i * lanes + qa + v * VEC
            sc = sca if v == 0 else scb
            ss = ssa if v == 0 else ssb
            ci, si, th, dnu = _rates_vec(src_c, src_s, src_nu, p, cl, sl, mass, gamma, second, o, sc, ss, i)
            kc = -si * th
            ks = ci * th
            vstore(acc, o, vload(acc, o) + two * kc)
            vstore(acc, size + o, vload(acc, size + o) + two * ks)
            vstore(dst, o, vload(c, o) + h * kc)
            vstore(dst, size + o, vload(s, o) + h * ks)
            if second:
                vstore(acc, 2 * size + o, vload(acc, 2 * size + o) + two * dnu)
                vstore(dst, 2 * size + o, vload(nu, o) + h * dnu)


@njit(inline="always")
def _rk4_vec(
    c, s, nu, th, dnu, ya, yb, acc, p, lw, indptr, indices, cl, sl, mass, gamma, second, dt, order, r2, dr2
):
    """make_model_kernels' ``rk4_step`` for every lane, then ``rhs`` at the new state (into
    ``th``, ``dnu``) and, for ``order``, ``R`` and ``dR/dt`` (``measure``'s sums) into ``r2``,
    ``dr2``. Each block of ``2 VEC`` lanes runs its whole step before the next; ``acc`` (rows
    c, s, nu) sums ``k1 + 2 k2 + 2 k3`` in ``rk4_step``'s order of additions, ``ya``, ``yb``
    hold the stage states in turn. ``th``, ``dnu`` on entry: the rates at the current state."""
    n, lanes = c.shape
    size = n * lanes
    hh = 0.5 * dt
    sixth = dt / 6.0
    zero = vsplat(0.0)
    ya_c, ya_s, ya_nu = ya[0], ya[1], ya[2]
    for qa in range(0, lanes, 2 * VEC):
        qb = qa + VEC
        # stage 1 from the rates on entry
        for i in range(n):
            for v in range(2):
                o = i * lanes + qa + v * VEC
                t = vload(th, o)
                kc = -vload(s, o) * t
                ks = vload(c, o) * t
                vstore(acc, o, kc)
                vstore(acc, size + o, ks)
                vstore(ya_c, o, vload(c, o) + hh * kc)
                vstore(ya_s, o, vload(s, o) + hh * ks)
                if second:
                    kn = vload(dnu, o)
                    vstore(acc, 2 * size + o, kn)
                    vstore(ya_nu, o, vload(nu, o) + hh * kn)
        _rk4_inner_vec(c, s, nu, ya, yb, acc, p, lw, indptr, indices, cl, sl, mass, gamma, second, hh, qa)
        _rk4_inner_vec(c, s, nu, yb, ya, acc, p, lw, indptr, indices, cl, sl, mass, gamma, second, dt, qa)
        # stage 4, the update and the projection of (c_i, s_i) to the unit circle
        for i in range(n):
            sca, ssa, scb, ssb = zero, zero, zero, zero
            for e in range(indptr[i], indptr[i + 1]):
                sca, ssa, scb, ssb = _edge_vec(
                    ya_c, ya_s, lw, gamma, False, indices, e, qa, sca, ssa, scb, ssb
                )
            for v in range(2):
                o = i * lanes + qa + v * VEC
                sc = sca if v == 0 else scb
                ss = ssa if v == 0 else ssb
                ci, si, t, dn = _rates_vec(ya_c, ya_s, ya_nu, p, cl, sl, mass, gamma, second, o, sc, ss, i)
                cn = vload(c, o) + sixth * (vload(acc, o) + -si * t)
                sn = vload(s, o) + sixth * (vload(acc, size + o) + ci * t)
                inv = 1.0 / vsqrt(cn * cn + sn * sn)
                vstore(c, o, cn * inv)
                vstore(s, o, sn * inv)
                if second:
                    vstore(nu, o, vload(nu, o) + sixth * (vload(acc, 2 * size + o) + dn))
        # the rates at the new state (stage 1 of the next step), R and dR/dt
        tca, tsa, dca, dsa = zero, zero, zero, zero
        tcb, tsb, dcb, dsb = zero, zero, zero, zero
        for i in range(n):
            sca, ssa, scb, ssb = zero, zero, zero, zero
            for e in range(indptr[i], indptr[i + 1]):
                sca, ssa, scb, ssb = _edge_vec(c, s, lw, gamma, False, indices, e, qa, sca, ssa, scb, ssb)
            o = i * lanes + qa
            ca, sa, ta, da = _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sca, ssa, i)
            cb, sb, tb, db = _rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o + VEC, scb, ssb, i)
            vstore(th, o, ta)
            vstore(th, o + VEC, tb)
            if second:
                vstore(dnu, o, da)
                vstore(dnu, o + VEC, db)
            if order:
                tca = tca + ca
                tsa = tsa + sa
                dca = dca - sa * ta
                dsa = dsa + ca * ta
                tcb = tcb + cb
                tsb = tsb + sb
                dcb = dcb - sb * tb
                dsb = dsb + cb * tb
        if order:
            vstore(r2, qa, tca * tca + tsa * tsa)
            vstore(dr2, qa, 2.0 * (tca * dca + tsa * dsa))
            vstore(r2, qb, tcb * tcb + tsb * tsb)
            vstore(dr2, qb, 2.0 * (tcb * dcb + tsb * dsb))


@njit(inline="always")
def _deviations_lanes(c, s, th, dnu, lw, indptr, indices, cl, sl, mass, gamma, second, work, m4):
    """make_model_kernels' ``deviations`` for every lane (rows DEV_ROW.. of ``work``)."""
    n, lanes = c.shape
    d = DEV_ROW
    for k in range(4):
        for q in range(lanes):
            m4[k, q] = 0.0
    for i in range(n):
        for q in range(lanes):
            work[d + 1, i, q] = 0.0  # kd
        for e in range(indptr[i], indptr[i + 1]):
            j = indices[e]
            for q in range(lanes):
                ca = cl * (c[j, q] * c[i, q] + s[j, q] * s[i, q]) + sl * (
                    s[j, q] * c[i, q] - c[j, q] * s[i, q]
                )
                work[d + 1, i, q] += lw[e, q] * ca * (th[j, q] - th[i, q])
        for q in range(lanes):
            kd = work[d + 1, i, q]
            work[d, i, q] = th[i, q]
            if not second:
                work[d + 1, i, q] = kd
            else:
                work[d + 1, i, q] = dnu[i, q] if mass[i] > 0.0 else kd / gamma[i]
                work[d + 2, i, q] = th[i, q] + mass[i] / gamma[i] * dnu[i, q]
                work[d + 3, i, q] = kd / gamma[i]
                m4[2, q] += work[d + 2, i, q]
                m4[3, q] += work[d + 3, i, q]
            m4[0, q] += work[d, i, q]
            m4[1, q] += work[d + 1, i, q]
    for i in range(n):
        for q in range(lanes):
            work[d, i, q] -= m4[0, q] / n
            work[d + 1, i, q] -= m4[1, q] / n
            if second:
                work[d + 2, i, q] -= m4[2, q] / n
                work[d + 3, i, q] -= m4[3, q] / n


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
def _integrate_model_lanes(
    ks,
    seed,
    indptr,
    indices,
    base_w,
    var_w,
    var_is_base,
    freqs,
    cl,
    sl,
    mass,
    gamma,
    dt,
    rk4,
    criterion,
    targets,
    max_steps,
    todo,
    lanes,
    taylor,
    n_groups,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
    """Lanes of trajectories with refill (as :func:`antisync.kernels.cpu._integrate_lanes`):
    each parallel task steps ``lanes`` items of its range of realizations together and refills
    a lane when its item is done. Same results as :func:`_integrate_items`, bit for bit."""
    m = ks.shape[0]
    n = indptr.shape[0] - 1
    nnz = base_w.shape[0]
    second = False
    for i in range(n):
        second |= mass[i] > 0.0
    freq = criterion == CRIT_FREQUENCY
    # Euler with an order criterion needs no rates after the step: the step is fused
    fused = not rk4 and not freq
    d = DEV_ROW
    dp = DEV_PREV_ROW
    per = (m + n_groups - 1) // n_groups
    width = (lanes + 2 * VEC - 1) // (2 * VEC) * (2 * VEC)
    for group in prange(n_groups):
        r_lo = group * per
        r_hi = min(m, r_lo + per)
        if r_lo >= r_hi:
            continue
        # the vector step needs a multiple of 2 VEC lanes: lanes past `lanes` stay empty
        # (phases 0, weights 0)
        c = np.ones((n, width))
        s = np.zeros((n, width))
        cn = np.ones((n, width) if fused else (0, width))
        sn = np.zeros((n, width) if fused else (0, width))
        spare = np.empty(VEC)
        nu = np.zeros((n, width))
        th = np.zeros((n, width))
        dnu = np.zeros((n, width))
        p = np.zeros((n, width))
        lw = np.zeros((nnz, width))
        work = np.zeros((WORK_ROWS, n, width))
        # RK4: the stage states in turn and the sum k1 + 2 k2 + 2 k3 (rows c, s, nu)
        ya = np.zeros((3, n if rk4 else 0, width))
        yb = np.zeros((3, n if rk4 else 0, width))
        kacc = np.zeros((3, n if rk4 else 0, width))
        r2 = np.zeros(width)
        dr2 = np.zeros(width)
        r2_prev = np.zeros(width)
        dr2_prev = np.zeros(width)
        acc = np.zeros((4, width))
        lane_r = np.full(width, -1, dtype=np.int64)
        lane_v = np.zeros(width, dtype=np.int64)
        lane_t0 = np.zeros(width, dtype=np.int64)
        lane_target = np.zeros(width)
        qr, qv = r_lo, -1
        active = 0
        t = 0
        # a lane's step count is t - lane_t0; the per-lane pass below runs only when some lane
        # may have met the criterion (a vectorized test) or reaches the step cap (and at t = 0,
        # to fill the lanes): it records what ended and refills the lane from the queue. Lanes
        # are renormalized (Euler) only at their own multiples of RENORM_EVERY, as in sync_steps
        next_cap = t + max_steps
        next_renorm = t + RENORM_EVERY
        event = True
        while True:
            if event:
                next_cap = t + max_steps
                for q in range(width):
                    if lane_r[q] >= 0:
                        k = t - lane_t0[q]
                        if freq:
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
                        r = lane_r[q]
                        v = lane_v[q]
                        _record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)
                        lane_r[q] = -1
                        active -= 1
                    if q >= lanes:
                        continue  # padding of the vector width: never filled
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
                    )
                    active += filled
            if active == 0:
                break
            t += 1
            r2, r2_prev = r2_prev, r2
            dr2, dr2_prev = dr2_prev, dr2
            if freq:
                for k in range(4):
                    for i in range(n):
                        for q in range(width):
                            work[dp + k, i, q] = work[d + k, i, q]
            if rk4:
                _rk4_vec(
                    c,
                    s,
                    nu,
                    th,
                    dnu,
                    ya,
                    yb,
                    kacc,
                    p,
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
            else:
                if fused:
                    _euler_vec(
                        c,
                        s,
                        cn,
                        sn,
                        nu,
                        p,
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
                    _euler_lanes(c, s, nu, th, dnu, dt, second)
                if t >= next_renorm:
                    next_renorm = t + RENORM_EVERY
                    for q in range(width):
                        if lane_r[q] < 0:
                            continue
                        k = t - lane_t0[q]
                        if k % RENORM_EVERY == 0:
                            _renormalize(c[:, q], s[:, q])
                        next_renorm = min(next_renorm, t + RENORM_EVERY - k % RENORM_EVERY)
            if freq and not rk4:
                _rhs_vec(c, s, nu, p, lw, indptr, indices, cl, sl, mass, gamma, second, th, dnu)
            if freq:
                _deviations_lanes(c, s, th, dnu, lw, indptr, indices, cl, sl, mass, gamma, second, work, acc)
                hits = 1  # the criterion's own bound test, per lane, below
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
            _share_base(var_is_base, r, status0, steps0, frac0, status, steps, frac)


def _per_node(value, n: int) -> np.ndarray:
    """Inertia or damping as the kernels' per-node array (a number is every node's)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))


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
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    if params.criterion not in (CRIT_ORDER, CRIT_FREQUENCY):
        raise ValueError(f"unknown criterion code {params.criterion}")
    if lanes < 0:
        raise ValueError(f"lanes must be >= 0, got {lanes}")
    ks = _realization_ids(first, count, realizations)
    m = ks.size
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base_weights.size)
    n_var = var_w.shape[0]
    var_is_base = np.array([np.array_equal(w, base_weights) for w in var_w], dtype=np.bool_)
    if todo is None:
        todo = np.zeros((0, 0), dtype=np.bool_)
    else:
        todo = np.ascontiguousarray(todo, dtype=np.bool_)
        if todo.shape != (m, n_var + 1):
            raise ValueError(f"todo must have shape {(m, n_var + 1)}, got {todo.shape}")
        # a variant equal to the base is integrated, not copied from a base that may not run
        var_is_base[:] = False
    freqs = np.ascontiguousarray(params.freqs, dtype=np.float64)
    n = indptr.size - 1
    if freqs.ndim != 2 or freqs.shape[1] != n or freqs.shape[0] not in (1, m):
        raise ValueError(f"freqs must have shape (1, {n}) or ({m}, {n}), got {freqs.shape}")
    targets = np.ascontiguousarray(params.targets, dtype=np.float64)
    if targets.shape != (n_var + 1,):
        raise ValueError(f"targets must have shape ({n_var + 1},), got {targets.shape}")
    status0 = np.full(m, -1, dtype=np.int8)
    steps0 = np.full(m, -1, dtype=np.int64)
    frac0 = np.full(m, np.nan)
    status = np.full((m, n_var), -1, dtype=np.int8)
    steps = np.full((m, n_var), -1, dtype=np.int64)
    frac = np.full((m, n_var), np.nan)
    args = (
        ks,
        np.uint64(seed),
        indptr.astype(np.int64),
        indices.astype(np.int64),
        base_weights,
        var_w,
        var_is_base,
        freqs,
        float(params.cos_lag),
        float(params.sin_lag),
        _per_node(params.inertia, n),
        _per_node(params.damping, n),
        float(dt),
        integrator == "rk4",
        int(params.criterion),
        targets,
        int(max_steps),
        todo,
    )
    outputs = (status0, steps0, frac0, status, steps, frac)
    taylor = _taylor_everywhere(dt, indptr, base_weights, var_w, freqs, params, n)
    with _Threads(threads) as groups:
        if not lanes:
            _integrate_items(*args, *outputs)
        else:
            if todo.shape[0] > 0:
                # few scattered items: no more groups (row ranges) than it takes to fill the lanes
                groups = min(groups, max(1, -(-int(todo.sum()) // int(lanes))))
            _integrate_model_lanes(*args, int(lanes), taylor, groups, *outputs)
    return SimResult(status0, steps0, status, steps, frac0, frac)


def _taylor_everywhere(dt, indptr, base_w, var_w, freqs, params: ModelParams, n: int) -> bool:
    """Whether every Euler rotation angle ``dt theta_i'`` of a first-order model is within
    :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`: ``|theta_i'| <= max |P| + (|cos alpha| +
    |sin alpha|) max_i sum_j |w_ij|`` (a margin of 1e-9 for rounding). Never for inertia
    (``theta_i' = nu_i`` has no such bound)."""
    if (_per_node(params.inertia, n) > 0.0).any():
        return False
    coupling = abs(params.cos_lag) + abs(params.sin_lag)
    rate = float(np.abs(freqs).max(initial=0.0)) + coupling * _row_sum_bound(indptr, base_w, var_w)
    return float(dt) * rate * (1.0 + 1e-9) <= TAYLOR_MAX_ANGLE


def lag_terms(phase_lag: float) -> tuple[float, float]:
    """``(cos alpha, sin alpha)``; exactly ``(1.0, 0.0)`` for ``alpha = 0``."""
    return math.cos(phase_lag), math.sin(phase_lag)


_uniform = make_uniform(lambda f: njit(f, inline="always"))


@njit(cache=True)
def _fill_frequencies(seed, ks, n, normal, mean, scale, out):
    for r in range(ks.shape[0]):
        for i in range(n):
            u1 = _uniform(seed, ks[r], i, STREAM_FREQ_A)
            if normal:
                # Box-Muller: 1 - u1 in (0, 1], so the logarithm is finite
                u2 = _uniform(seed, ks[r], i, STREAM_FREQ_B)
                z = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
                out[r, i] = mean + scale * z
            else:
                out[r, i] = mean + scale * (2.0 * u1 - 1.0)


def draw_frequencies(spec: dict, seed: int, ks: np.ndarray, n: int) -> np.ndarray:
    """Natural frequencies of realizations ``ks`` (shape ``(len(ks), n)``), mean not removed.

    ``normal``: ``mean + sd z`` with ``z`` from Box-Muller on two counter streams;
    ``uniform``: ``mean + width (2 u - 1)``. Keyed by ``(seed, k, node)`` like the phases, so
    chunks, threads and backends cannot change them.
    """
    ks = np.ascontiguousarray(ks, dtype=np.uint64)
    out = np.empty((ks.size, n))
    normal = spec["distribution"] == "normal"
    scale = spec["sd"] if normal else spec["width"]
    _fill_frequencies(np.uint64(seed), ks, n, normal, float(spec.get("mean", 0.0)), float(scale), out)
    return out
