"""The generalized models' terms on the lanes (natural frequencies, phase lag, inertia;
docs/models.md): their constants and their step functions on the ``[node, lane]`` layout.

The lane driver :func:`antisync.kernels.lanes.integrate_lanes` runs the identical first-order
oscillators and these models alike; with a model it calls the functions here, which perform per
lane exactly the operations of :func:`antisync.kernels.core.make_model_kernels`' one-trajectory
functions in the same order, on machine vectors of ``VEC`` lanes (two vectors at a time; the
lane count a multiple of ``2 VEC``), so a lane's trajectory is the one-trajectory driver's, bit
for bit. Without a model the driver is compiled without any of them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels.core import (
    DEV_ROW,
    TAYLOR_MAX_ANGLE,
    VEC,
    make_model_kernels,
    vany_outside,
    vload,
    vsplat,
    vsqrt,
    vstore,
)
from antisync.kernels.precision import K64
from antisync.physics.phases import make_uniform

__all__ = ["ModelParams", "Terms", "draw_frequencies", "lag_terms"]

#: Counter streams of :func:`antisync.physics.phases.make_uniform` used by the natural frequencies (the
#: initial phases are the separate hash :func:`antisync.physics.phases.phase`).
STREAM_FREQ_A = 1
STREAM_FREQ_B = 2

MK = make_model_kernels(lambda f: njit(f, inline="always", cache=True), K64)
"""The one-trajectory model functions (``sync_steps``, ``rhs``, ``measure``, ...), inlined."""
_rotation = K64.rotation
_node_sums_vec = K64.node_sums_vec  # its w (unused: lw per lane) filled with gamma
_rotate_by_vec = K64.rotate_by_vec
_taylor = K64.taylor_rotation


class ModelParams(NamedTuple):
    """The model's constants for a kernel (see :class:`antisync.plan.model.Model`).

    ``freqs`` has one row (the same frequencies for every realization) or one row per
    realization of the batch, mean already removed; ``inertia`` and ``damping`` one number or
    one per node (``damping`` must be 1 where no node has inertia); ``targets[0]`` is the undamaged network's
    and ``targets[1 + v]`` variant ``v``'s: ``R = (r N)^2`` at the order-parameter or relative
    threshold, or the frequency tolerance. ``starts`` holds one row of initial phases per
    realization of the batch (``model.start``), or is ``None``: the paper's phases, drawn by
    the kernels (:func:`antisync.physics.phases.phase`).
    """

    freqs: np.ndarray
    cos_lag: float
    sin_lag: float
    inertia: float | np.ndarray
    damping: float | np.ndarray
    criterion: int
    targets: np.ndarray
    starts: np.ndarray | None = None


class Terms(NamedTuple):
    """The constants of the model's right-hand side on the lanes (``rhs``' other arguments), as
    the step functions take them. Each unpacks them once at its top, outside its loops, and
    hands the arrays themselves to the helpers it calls per node (``rates_vec``, ``node_sums_vec``):
    see the note at :func:`rk4_vec`'s ``k1`` on arrays and inlined helpers in the loop."""

    p: np.ndarray
    """(N, width): the natural frequencies of each lane's realization."""
    lw: np.ndarray
    """(nnz, width): the CSR weights of each lane's network."""
    indptr: np.ndarray
    """The CSR row pointers."""
    indices: np.ndarray
    """The CSR column indices."""
    cl: float
    """``cos alpha`` of the phase lag."""
    sl: float
    """``sin alpha``."""
    mass: np.ndarray
    """(N,): the inertia of each node (0: first order)."""
    gamma: np.ndarray
    """(N,): the damping of each node."""
    second: bool
    """Whether any node has inertia (the state's ``nu`` rows)."""


@njit(inline="always")
def rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sc, ss, i):
    """``rhs``' node ``i`` for the lane vector at flat offset ``o`` of the state ``(c, s, nu)``
    from its coupling sums ``sc, ss``: ``(c_i, s_i, theta_i', nu_i')`` (``nu_i' = 0`` where the
    node or the model is first order)."""
    ci = vload(c, o)
    si = vload(s, o)
    k = ci * ss - si * sc
    if sl != 0.0 or cl != 1.0:
        k = k * cl - (ci * sc + si * ss) * sl
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
def rhs_vec(c, s, nu, terms, th, dnu):
    """make_model_kernels' ``rhs`` for every lane (constants ``terms``, a :class:`Terms`): the
    coupling sums of each node kept in registers over its edges (``edge_vec``), then the rates
    into ``th``, ``dnu``."""
    p, lw, indptr, indices, cl, sl, mass, gamma, second = terms
    n, lanes = c.shape
    for qa in range(0, lanes, 2 * VEC):
        for i in range(n):
            sca, ssa, scb, ssb = _node_sums_vec(c, s, lw, gamma, False, indptr, indices, i, qa)
            o = i * lanes + qa
            _, _, ta, da = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sca, ssa, i)
            _, _, tb, db = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o + VEC, scb, ssb, i)
            vstore(th, o, ta)
            vstore(th, o + VEC, tb)
            if second:
                vstore(dnu, o, da)
                vstore(dnu, o + VEC, db)


@njit(inline="always")
def euler_vec(c, s, cn, sn, nu, terms, dt, taylor, r2, spare):
    """One Euler step of every lane (constants ``terms``, a :class:`Terms`), fused as the
    identical model's ``euler_step_vec``: per node the coupling sums over its edges (in
    registers), ``rhs``' rates at the current state, the rotation of ``(c_i, s_i)`` by
    ``dt theta_i'`` into ``(cn, sn)`` (the caller swaps the buffers) and ``nu_i += dt nu_i'``;
    ``r2`` gets each lane's ``R``. The rates are not kept
    (the order criteria with Euler need only ``R``). ``taylor`` promises every angle is within
    the Taylor range (else each vector is tested); ``spare`` (VEC floats) is scratch for a
    vector with an angle outside it."""
    p, lw, indptr, indices, cl, sl, mass, gamma, second = terms
    n, lanes = c.shape
    zero = vsplat(0.0)
    for qa in range(0, lanes, 2 * VEC):
        qb = qa + VEC
        tca, tsa, tcb, tsb = zero, zero, zero, zero
        for i in range(n):
            sca, ssa, scb, ssb = _node_sums_vec(c, s, lw, gamma, False, indptr, indices, i, qa)
            oa = i * lanes + qa
            ca, sa, ta, da = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, oa, sca, ssa, i)
            xa, ya = _euler_node_vec(c, s, cn, sn, nu, ca, sa, ta, da, dt, taylor, second, oa, spare)
            cb, sb, tb, db = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, oa + VEC, scb, ssb, i)
            xb, yb = _euler_node_vec(c, s, cn, sn, nu, cb, sb, tb, db, dt, taylor, second, oa + VEC, spare)
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
def _euler_node_vec(c, s, cn, sn, nu, ci, si, th, dnu, dt, taylor, second, o, spare):
    """A node of :func:`euler_vec` for the lane vector at flat offset ``o`` from its
    ``rates_vec`` ``(ci, si, th, dnu)``: ``(c_i, s_i)`` rotated into ``(cn, sn)`` (returned) and
    ``nu_i`` advanced."""
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
def euler_lanes(c, s, nu, th, dnu, dt, second):
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
def _rk4_inner_vec(c, s, nu, src, dst, acc, terms, h, qa):
    """An inner RK4 stage of the lane vectors at ``qa`` and ``qa + VEC``: per node the rates
    (constants ``terms``) at the stage state ``src`` (rows c, s, nu), ``acc += 2 k`` and
    ``dst = (c, s, nu) + h k``."""
    p, lw, indptr, indices, cl, sl, mass, gamma, second = terms
    n, lanes = c.shape
    size = n * lanes
    two = vsplat(2.0)
    src_c, src_s, src_nu = src[0], src[1], src[2]
    for i in range(n):
        sca, ssa, scb, ssb = _node_sums_vec(src_c, src_s, lw, gamma, False, indptr, indices, i, qa)
        for v in range(2):
            o = i * lanes + qa + v * VEC
            sc = sca if v == 0 else scb
            ss = ssa if v == 0 else ssb
            ci, si, th, dnu = rates_vec(src_c, src_s, src_nu, p, cl, sl, mass, gamma, second, o, sc, ss, i)
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
def rk4_vec(c, s, nu, th, dnu, ya, yb, acc, terms, dt, order, r2, dr2):
    """make_model_kernels' ``rk4_step`` for every lane (constants ``terms``, a :class:`Terms`),
    then ``rhs`` at the new state and, for ``order``, ``R`` and ``dR/dt`` (``measure``'s sums)
    into ``r2``, ``dr2``. Each block of ``2 VEC`` lanes runs its whole step before the next;
    ``acc`` (rows c, s, nu) sums ``k1 + 2 k2 + 2 k3`` in ``rk4_step``'s order of additions,
    ``ya``, ``yb`` hold the stage states in turn.

    The first stage of a step is the rates at its state, so the pass that computes them at the
    end of a step also writes the next step's ``k1`` (into ``acc``) and its first stage state
    (into ``ya``): on entry ``acc`` and ``ya`` hold them (:func:`rk4_start` for a lane just
    loaded). The rates themselves go to ``th``, ``dnu`` only without ``order`` (the frequency
    criterion's deviations read them); the order criteria need ``R`` and ``dR/dt`` alone."""
    p, lw, indptr, indices, cl, sl, mass, gamma, second = terms
    n, lanes = c.shape
    size = n * lanes
    hh = 0.5 * dt
    sixth = dt / 6.0
    zero = vsplat(0.0)
    ya_c, ya_s, ya_nu = ya[0], ya[1], ya[2]
    for qa in range(0, lanes, 2 * VEC):
        qb = qa + VEC
        _rk4_inner_vec(c, s, nu, ya, yb, acc, terms, hh, qa)
        _rk4_inner_vec(c, s, nu, yb, ya, acc, terms, dt, qa)
        # stage 4, the update and the projection of (c_i, s_i) to the unit circle
        for i in range(n):
            sca, ssa, scb, ssb = _node_sums_vec(ya_c, ya_s, lw, gamma, False, indptr, indices, i, qa)
            for v in range(2):
                o = i * lanes + qa + v * VEC
                sc = sca if v == 0 else scb
                ss = ssa if v == 0 else ssb
                ci, si, t, dn = rates_vec(ya_c, ya_s, ya_nu, p, cl, sl, mass, gamma, second, o, sc, ss, i)
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
            sca, ssa, scb, ssb = _node_sums_vec(c, s, lw, gamma, False, indptr, indices, i, qa)
            o = i * lanes + qa
            ca, sa, ta, da = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o, sca, ssa, i)
            cb, sb, tb, db = rates_vec(c, s, nu, p, cl, sl, mass, gamma, second, o + VEC, scb, ssb, i)
            if not order:
                vstore(th, o, ta)
                vstore(th, o + VEC, tb)
                if second:
                    vstore(dnu, o, da)
                    vstore(dnu, o + VEC, db)
            # k1 and the first stage state of the next step (written out here: as an inlined
            # helper taking the arrays it ran 1.8x slower, numba's reference counting in the loop)
            kca = -sa * ta
            ksa = ca * ta
            kcb = -sb * tb
            ksb = cb * tb
            vstore(acc, o, kca)
            vstore(acc, o + VEC, kcb)
            vstore(acc, size + o, ksa)
            vstore(acc, size + o + VEC, ksb)
            vstore(ya, o, ca + hh * kca)
            vstore(ya, o + VEC, cb + hh * kcb)
            vstore(ya, size + o, sa + hh * ksa)
            vstore(ya, size + o + VEC, sb + hh * ksb)
            if second:
                vstore(acc, 2 * size + o, da)
                vstore(acc, 2 * size + o + VEC, db)
                vstore(ya, 2 * size + o, vload(nu, o) + hh * da)
                vstore(ya, 2 * size + o + VEC, vload(nu, o + VEC) + hh * db)
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


@njit(cache=True)  # not inlined: it runs when a lane is loaded, outside the vector loop
def rk4_start(c, s, nu, th, dnu, acc, ya, q, hh, second):
    """:func:`rk4_vec`'s entry state for lane ``q`` just loaded (its rates in ``th``, ``dnu``):
    ``k1`` into ``acc`` and the first stage state into ``ya``, as the step writes them."""
    for i in range(c.shape[0]):
        kc = -s[i, q] * th[i, q]
        ks = c[i, q] * th[i, q]
        acc[0, i, q] = kc
        acc[1, i, q] = ks
        ya[0, i, q] = c[i, q] + hh * kc
        ya[1, i, q] = s[i, q] + hh * ks
        if second:
            acc[2, i, q] = dnu[i, q]
            ya[2, i, q] = nu[i, q] + hh * dnu[i, q]


@njit(inline="always")
def deviations_lanes(c, s, th, dnu, lw, indptr, indices, cl, sl, mass, gamma, second, work, m4):
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


def lag_terms(phase_lag: float) -> tuple[float, float]:
    """``(cos alpha, sin alpha)``; exactly ``(1.0, 0.0)`` for ``alpha = 0``."""
    return math.cos(phase_lag), math.sin(phase_lag)


_uniform = make_uniform(lambda f: njit(f, inline="always"))


@njit(cache=True)
def _fill_frequencies(seed, ks, n, normal, mean, scale, out, stream_a, stream_b):
    for r in range(ks.shape[0]):
        for i in range(n):
            u1 = _uniform(seed, ks[r], i, stream_a)
            if normal:
                # Box-Muller: 1 - u1 in (0, 1], so the logarithm is finite
                u2 = _uniform(seed, ks[r], i, stream_b)
                z = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
                out[r, i] = mean + scale * z
            else:
                out[r, i] = mean + scale * (2.0 * u1 - 1.0)


def draw_frequencies(
    spec: dict, seed: int, ks: np.ndarray, n: int, streams: tuple[int, int] = (STREAM_FREQ_A, STREAM_FREQ_B)
) -> np.ndarray:
    """Natural frequencies of realizations ``ks`` (shape ``(len(ks), n)``), mean not removed.

    ``normal``: ``mean + sd z`` with ``z`` from Box-Muller on two counter streams;
    ``uniform``: ``mean + width (2 u - 1)``. Keyed by ``(seed, k, node)`` like the phases, so
    chunks, threads and backends cannot change them. ``streams``: the two counter streams (a
    user law's ``k``-th parameter draws on ``1 + 2 k`` and ``2 + 2 k``: its first, the built-in
    frequencies' streams).
    """
    ks = np.ascontiguousarray(ks, dtype=np.uint64)
    out = np.empty((ks.size, n))
    normal = spec["distribution"] == "normal"
    scale = spec["sd"] if normal else spec["width"]
    mean = float(spec.get("mean", 0.0))
    a, b = (np.uint64(x) for x in streams)
    _fill_frequencies(np.uint64(seed), ks, n, normal, mean, float(scale), out, a, b)
    return out
