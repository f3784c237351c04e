"""Reverse-mode (adjoint) sensitivities of tau0 to every coupling weight: ``lambda.method: adjoint``.

The pathwise estimator (:func:`antisync.kernels.cpu.simulate_pathwise`) carries one forward
tangent ``d theta / d beta_e`` per damaged link, ``O(E N)`` work per step. Here one forward pass
integrates the undamaged trajectory and one backward pass of the *discrete* integrator's
adjoint gives ``g_p = d tau0 / d w_p`` for every entry ``p = (i, j)`` of ``W`` at once, ``O(N +
nnz)`` work per step whatever the number of links; ``d tau0 / d beta_e`` is then the contraction
of ``g`` with the one nonzero row of ``dW/dbeta_e``
(:func:`antisync.physics.coupling.coupling_derivative_row`, see :func:`link_derivatives`). The result is
the derivative of the same function of the weights that the pathwise tangents differentiate
(the interpolated crossing time of the same discrete trajectory), so both give the same values
to rounding (docs/equations.md, "The adjoint of the Euler step", Eqs. A1-A4).

Memory: the backward pass needs the trajectory in reverse. The forward pass keeps every
``checkpoint_every``-th state (``K``); the backward pass recomputes each segment of ``K`` steps
forward from its checkpoint (with the same step function, so bit for bit the same states)
and then walks it backwards. For a trajectory of ``k`` steps on ``N`` nodes a thread holds
``(ceil(k / K) + K) 2 N`` doubles (``K = 64``, ``k = 20,000``, ``N = 1,000``: 6.0 MB; the lane
path ``LANES = 16`` times that) and recomputes ``k (K - 1) / K`` steps, about one extra forward
pass, for any ``K``; ``K = 1`` stores every state and recomputes nothing. ``K`` never changes
the results (bit for bit). The default 64 keeps a lane group's segment (``16 K 2 N`` doubles,
557 KB on the karate club) in a core's L2 cache, where 256 did not (karate: 1.5x slower).

Integrators: ``euler`` (the rotation step of :mod:`antisync.kernels.core`, in the phases:
``theta <- theta + dt f(theta)``, linear crossing in ``R = |sum_j e^{i theta_j}|^2``) and
``rk4`` (the lane RK4 step run with one lane, in ``(c, s)`` with its per-step projection onto the
unit circle, cubic Hermite crossing differentiated through the interpolant).

Layers as in :mod:`antisync.kernels.cpu`: ``_euler_adjoint`` / ``_rk4_adjoint`` (one
trajectory), ``_adjoint_batch`` (``prange`` over groups of realizations, one trajectory at a
time per thread: the reference), the Euler lane path (``_euler_forward_lanes``,
``_euler_backward_lanes``, ``_adjoint_lanes_batch``: :data:`LANES` realizations per group on
machine vectors, the same bits; see "lanes of trajectories" below), the RK4 lane path
(``_rk4_forward_lanes``, ``_rk4_backward_lanes``) and the public :func:`simulate_adjoint`.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import loops
from antisync.kernels.core import (
    RENORM_EVERY,
    TAYLOR_MAX_ANGLE,
    VEC,
    vload,
    vsplat,
    vsqrt,
    vstore,
)
from antisync.kernels.lanes import group_rows, integrate_lanes
from antisync.kernels.precision import K64
from antisync.kernels.shared import (
    NO_TANGENTS,
    Graph,
    Outputs,
    PathwiseResult,
    Threads,
    copy_into,
    csr_mv2,
    doubled,
    realization_ids,
    row_sum_bound,
)
from antisync.kernels.shared import Run as LaneRun
from antisync.physics.coupling import CouplingCSR, coupling_derivative_row
from antisync.physics.phases import phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED
from antisync.types import Coupling, Integrator

__all__ = ["CHECKPOINT_EVERY", "LANES", "LinkDerivatives", "link_derivatives", "simulate_adjoint"]

_euler_step = K64.euler_step
_euler_vec = K64.euler_step_vec
_rk4_vec = K64.rk4_step_vec
_renormalize = K64.renormalize
_order2 = K64.order2
_rk4_lanes = K64.rk4_step_lanes
_lane_velocity = K64.lane_velocity
_hermite = K64.hermite_crossing

CHECKPOINT_EVERY = 64
"""Default ``K``: steps between stored states of the forward pass (memory, not results)."""

PREDICT_DT = 0.2
"""RK4 step (times the largest row sum of ``|w|``) of the pass that predicts each realization's
crossing time to group the lanes (:func:`_lane_order`; speed only, never a result)."""


class LinkDerivatives(NamedTuple):
    """``dW/dbeta_e`` of each damaged link ``e`` on the CSR pattern of ``W``, itself in CSR form.

    Damage on ``a -> b`` changes row ``a`` of ``W`` only, so link ``e`` has the entries
    ``value[q]`` at CSR positions ``position[q]`` for ``q`` in ``indptr[e] .. indptr[e + 1] - 1``
    (the positions of row ``a``).
    """

    indptr: np.ndarray
    """int64 (E + 1,)"""
    position: np.ndarray
    """int64 (nnz_d,): index into the CSR weights of ``W``."""
    value: np.ndarray
    """float64 (nnz_d,): ``d w_p / d beta_e`` at ``beta = 0``."""


def link_derivatives(
    omega: np.ndarray, csr: CouplingCSR, edges, coupling_kind: Coupling = "normalized"
) -> LinkDerivatives:
    """:class:`LinkDerivatives` of the directed links ``edges`` (0-based ``(a, b)`` pairs).

    Each row is :func:`antisync.physics.coupling.coupling_derivative_row` restricted to the pattern of
    row ``a`` of ``csr`` (it is zero off the pattern: damage rescales existing links only).
    """
    indptr = np.zeros(len(edges) + 1, dtype=np.int64)
    position = []
    value = []
    for e, (a, b) in enumerate(edges):
        row = coupling_derivative_row(omega, a, b, coupling_kind)
        lo, hi = int(csr.indptr[a]), int(csr.indptr[a + 1])
        cols = csr.indices[lo:hi]
        off = np.ones(row.size, dtype=bool)
        off[cols] = False
        if np.any(row[off] != 0.0):
            raise ValueError(f"dW/dbeta of link {a}->{b} is nonzero outside the pattern of W")
        position.append(np.arange(lo, hi, dtype=np.int64))
        value.append(row[cols])
        indptr[e + 1] = indptr[e] + (hi - lo)
    if not edges:
        return LinkDerivatives(indptr, np.zeros(0, dtype=np.int64), np.zeros(0))
    return LinkDerivatives(indptr, np.concatenate(position), np.concatenate(value))


class _Run(NamedTuple):
    """The constants of one batch."""

    seed: np.uint64
    dt: float
    r2_target: float
    max_steps: int
    every: int
    """``K``: steps between checkpoints."""
    rk4: bool


# ---- one trajectory ------------------------------------------------------------------------


@njit(cache=True)
def _store(ck, idx, c, s):
    """``ck[idx] = (c, s)``, doubling ``ck`` when full; returns the (possibly new) array. The
    states are ``[node]`` (one trajectory) or ``[node, lane]`` (the lanes)."""
    if idx >= ck.shape[0]:
        ck = doubled(ck)
    copy_into(ck[idx, 0], c)
    copy_into(ck[idx, 1], s)
    return ck


@njit(inline="always")
def _euler_vjp(c, s, lam, lam_new, g, indptr, indices, w, dt):
    """One step of the Euler adjoint at state ``(c, s)`` (Eqs. A2, A3).

    ``lam = d tau / d theta_{n+1}`` in; ``lam_new = d tau / d theta_n`` (through this step) out;
    ``g_p += dt lam_i sin(theta_j - theta_i)`` (``d tau / d w_p`` of this step).
    """
    n = c.shape[0]
    for i in range(n):
        lam_new[i] = lam[i]
    for i in range(n):
        li = dt * lam[i]
        ci = c[i]
        si = s[i]
        diag = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            g[p] += li * (s[j] * ci - c[j] * si)  # sin(theta_j - theta_i)
            t = li * w[p] * (c[j] * ci + s[j] * si)  # cos(theta_j - theta_i)
            lam_new[j] += t
            diag += t
        lam_new[i] -= diag


@njit(inline="always")
def _r2_gradient(c, s, coef, lam):
    """``lam += coef dR/dtheta`` with ``R = |sum_j e^{i theta_j}|^2``:
    ``dR/dtheta_i = 2 (S c_i - C s_i)``."""
    tc = 0.0
    ts = 0.0
    for i in range(c.shape[0]):
        tc += c[i]
        ts += s[i]
    for i in range(c.shape[0]):
        lam[i] += coef * 2.0 * (ts * c[i] - tc * s[i])


@njit(cache=True)
def _euler_adjoint(c, s, acc, ck, seg, lam, lam_new, g, indptr, indices, w, dt, r2_target, max_steps, every):
    """Euler trajectory from ``(c, s)``, then its adjoint: ``g_p = d tau0 / d w_p``.

    Returns ``(status, steps, x, ck)`` with the interpolated ``tau0 = dt (steps - 1 + x)``
    (``g`` is meaningful only for SYNCED).
    """
    n = c.shape[0]
    for p in range(g.shape[0]):
        g[p] = 0.0
    r2_prev = _order2(c, s)
    if r2_prev >= r2_target:
        return ALREADY_SYNCED, 0, 0.0, ck
    ck = _store(ck, np.int64(0), c, s)
    k = 0
    r2 = r2_prev
    for step in range(1, max_steps + 1):
        r2 = _euler_step(c, s, acc, indptr, indices, w, dt)
        if r2 >= r2_target:
            k = step
            break
        if step % RENORM_EVERY == 0:
            _renormalize(c, s)
        if step % every == 0:
            ck = _store(ck, step // every, c, s)
        r2_prev = r2
    if k == 0:
        return NOT_SYNCED, max_steps, 0.0, ck
    # tau = dt (k - 1 + x), x = (R* - R_{k-1}) / (R_k - R_{k-1})  (Eq. A4)
    span = r2 - r2_prev
    x = (r2_target - r2_prev) / span
    for i in range(n):
        lam[i] = 0.0
    _r2_gradient(c, s, -dt * x / span, lam)
    for sg in range((k - 1) // every, -1, -1):
        j0 = sg * every
        j1 = min(j0 + every, k)
        # states j0 .. j1 - 1 again, exactly as the forward pass made them
        for i in range(n):
            seg[0, 0, i] = ck[sg, 0, i]
            seg[0, 1, i] = ck[sg, 1, i]
        for j in range(j0 + 1, j1):
            row = j - j0
            for i in range(n):
                seg[row, 0, i] = seg[row - 1, 0, i]
                seg[row, 1, i] = seg[row - 1, 1, i]
            _euler_step(seg[row, 0], seg[row, 1], acc, indptr, indices, w, dt)
            if j % RENORM_EVERY == 0:
                _renormalize(seg[row, 0], seg[row, 1])
        for j in range(j1 - 1, j0 - 1, -1):
            cj = seg[j - j0, 0]
            sj = seg[j - j0, 1]
            _euler_vjp(cj, sj, lam, lam_new, g, indptr, indices, w, dt)
            lam, lam_new = lam_new, lam
            if j == k - 1 and j > 0:
                _r2_gradient(cj, sj, -dt * (1.0 - x) / span, lam)
    return SYNCED, k, x, ck


@njit(inline="always")
def _velocity(c, s, om, sc, ss, fc, fs, indptr, indices, w):
    """``(fc, fs) = (-s omega, c omega)``, ``omega_i = c_i ss_i - s_i sc_i`` with ``sc_i = sum_j
    w_ij c_j``, ``ss_i = sum_j w_ij s_j`` (Eq. 2 in (cos, sin) form); keeps the intermediates."""
    csr_mv2(indptr, indices, w, c, s, sc, ss)
    for i in range(c.shape[0]):
        om[i] = c[i] * ss[i] - s[i] * sc[i]
        fc[i] = -s[i] * om[i]
        fs[i] = c[i] * om[i]


@njit(inline="always")
def _velocity_vjp(c, s, om, sc, ss, gc, gs, bc, bs, g, indptr, indices, w):
    """``(bc, bs) += (gc, gs)^T d(fc, fs)/d(c, s)`` and ``g += (gc, gs)^T d(fc, fs)/dw`` at the
    state whose intermediates :func:`_velocity` left in ``om, sc, ss``."""
    for i in range(c.shape[0]):
        ob = c[i] * gs[i] - s[i] * gc[i]  # cotangent of omega_i
        bc[i] += om[i] * gs[i] + ob * ss[i]
        bs[i] += -om[i] * gc[i] - ob * sc[i]
        bss = ob * c[i]  # cotangent of ss_i
        bsc = -ob * s[i]  # cotangent of sc_i
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            bs[j] += w[p] * bss
            bc[j] += w[p] * bsc
            g[p] += bss * s[j] + bsc * c[j]


@njit(inline="always")
def _stages(yc, ys, st, indptr, indices, w, dt):
    """The four RK4 stages from ``y``: ``st[q] = (c, s, omega, sc, ss, fc, fs)`` of stage ``q``."""
    for i in range(yc.shape[0]):
        st[0, 0, i] = yc[i]
        st[0, 1, i] = ys[i]
    for q in range(4):
        if q > 0:
            h = 0.5 * dt if q < 3 else dt
            for i in range(yc.shape[0]):
                st[q, 0, i] = yc[i] + h * st[q - 1, 5, i]
                st[q, 1, i] = ys[i] + h * st[q - 1, 6, i]
        _velocity(st[q, 0], st[q, 1], st[q, 2], st[q, 3], st[q, 4], st[q, 5], st[q, 6], indptr, indices, w)


@njit(inline="always")
def _rk4_vjp(yc, ys, st, ac, as_, work, g, net, dt):
    """One step of the RK4 adjoint at ``y_n = (yc, ys)`` (Eq. A5): ``(ac, as_)`` holds
    ``d tau / d y_{n+1}`` in and ``d tau / d y_n`` out; ``g`` gets this step's ``d tau / d w``.
    ``work = (zc, zs, tc, ts, kc, ks)``: scratch, one value per node each; ``net = (indptr,
    indices, w)``: the CSR weights."""
    zc, zs, tc, ts, kc, ks = work
    indptr, indices, w = net
    n = yc.shape[0]
    h = 0.5 * dt
    _stages(yc, ys, st, indptr, indices, w, dt)
    # projection y_{n+1} = z / |z| per node: zbar = (ybar - y (y . ybar)) / |z|
    for i in range(n):
        zci = yc[i] + dt / 6.0 * (st[0, 5, i] + 2.0 * st[1, 5, i] + 2.0 * st[2, 5, i] + st[3, 5, i])
        zsi = ys[i] + dt / 6.0 * (st[0, 6, i] + 2.0 * st[1, 6, i] + 2.0 * st[2, 6, i] + st[3, 6, i])
        norm = np.sqrt(zci * zci + zsi * zsi)
        uc = zci / norm
        us = zsi / norm
        dot = uc * ac[i] + us * as_[i]
        zc[i] = (ac[i] - uc * dot) / norm
        zs[i] = (as_[i] - us * dot) / norm
        ac[i] = zc[i]
        as_[i] = zs[i]
    # z = y + dt/6 (k1 + 2 k2 + 2 k3 + k4); y4 = y + dt k3, y3 = y + h k2, y2 = y + h k1
    weight = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)
    for q in range(3, -1, -1):
        for i in range(n):
            if q == 3:
                kc[i] = dt * weight[q] * zc[i]
                ks[i] = dt * weight[q] * zs[i]
            else:
                hq = dt if q == 2 else h
                kc[i] = dt * weight[q] * zc[i] + hq * tc[i]
                ks[i] = dt * weight[q] * zs[i] + hq * ts[i]
            tc[i] = 0.0
            ts[i] = 0.0
        if q == 0:
            _velocity_vjp(
                st[0, 0], st[0, 1], st[0, 2], st[0, 3], st[0, 4], kc, ks, ac, as_, g, indptr, indices, w
            )
        else:
            _velocity_vjp(
                st[q, 0], st[q, 1], st[q, 2], st[q, 3], st[q, 4], kc, ks, tc, ts, g, indptr, indices, w
            )
            for i in range(n):
                ac[i] += tc[i]
                as_[i] += ts[i]


@njit(inline="always")
def _crossing_seed(yc, ys, st, coef_r, coef_d, ac, as_, kc, ks, g, indptr, indices, w):
    """``(ac, as_, g) += coef_r dR + coef_d dD`` at ``y``, with ``R = C^2 + S^2`` (``C = sum c``,
    ``S = sum s``) and ``D = dR/dt = 2 (C sum fc + S sum fs)``, which depends on ``w`` too."""
    n = yc.shape[0]
    for i in range(n):
        st[0, 0, i] = yc[i]
        st[0, 1, i] = ys[i]
    _velocity(st[0, 0], st[0, 1], st[0, 2], st[0, 3], st[0, 4], st[0, 5], st[0, 6], indptr, indices, w)
    tc = 0.0
    ts = 0.0
    vc = 0.0
    vs = 0.0
    for i in range(n):
        tc += yc[i]
        ts += ys[i]
        vc += st[0, 5, i]
        vs += st[0, 6, i]
    for i in range(n):
        ac[i] += 2.0 * (coef_r * tc + coef_d * vc)
        as_[i] += 2.0 * (coef_r * ts + coef_d * vs)
        kc[i] = 2.0 * coef_d * tc
        ks[i] = 2.0 * coef_d * ts
    _velocity_vjp(st[0, 0], st[0, 1], st[0, 2], st[0, 3], st[0, 4], kc, ks, ac, as_, g, indptr, indices, w)


@njit(inline="always")
def _hermite_seed_weights(r2_prev, dr2_prev, r2, dr2, dt, x):
    """``d tau / d (R_k, D_k, R_{k-1}, D_{k-1})`` for ``tau = dt (k - 1 + x)``, where the
    Hermite cubic through ``(R, D)`` at steps ``k - 1`` and ``k`` meets the target at ``x``."""
    x2 = x * x
    x3 = x2 * x
    slope = (
        (6.0 * x2 - 6.0 * x) * r2_prev
        + (3.0 * x2 - 4.0 * x + 1.0) * dt * dr2_prev
        + (-6.0 * x2 + 6.0 * x) * r2
        + (3.0 * x2 - 2.0 * x) * dt * dr2
    )
    scale = -dt / slope
    return (
        scale * (-2.0 * x3 + 3.0 * x2),
        scale * dt * (x3 - x2),
        scale * (2.0 * x3 - 3.0 * x2 + 1.0),
        scale * dt * (x3 - 2.0 * x2 + x),
    )


@njit(inline="always")
def _start_lane(q, r2_0, r2_target, max_steps, code, k_lane):
    """Lane ``q``'s status before its first step (``r2_0``: its R at t = 0); 1 if it is live."""
    if r2_0 >= r2_target:
        code[q] = ALREADY_SYNCED
        k_lane[q] = 0
        return 0
    code[q] = NOT_SYNCED
    k_lane[q] = max_steps + 1
    return 1


@njit(inline="always")
def _last_crossing(code, k_lane):
    """The largest crossing step of the group's SYNCED lanes (-1 if none)."""
    top = -1
    for q in range(code.shape[0]):
        if code[q] == SYNCED:
            top = max(top, k_lane[q])
    return top


@njit(cache=True)
def _rk4_adjoint(c, s, ck, seg, g, indptr, indices, w, dt, r2_target, max_steps, every):
    """RK4 trajectory from ``(c, s)`` (the lane step of :mod:`.core`, one lane), then its adjoint:
    ``g_p = d tau0 / d w_p`` with the Hermite-interpolated ``tau0``. Returns as
    :func:`_euler_adjoint`."""
    n = c.shape[0]
    nnz = w.shape[0]
    for p in range(nnz):
        g[p] = 0.0
    if _order2(c, s) >= r2_target:
        return ALREADY_SYNCED, 0, 0.0, ck
    # one-lane scratch of the lane step
    cl = np.empty((n, 1))
    sl = np.empty((n, 1))
    kv = np.zeros((8, n, 1))
    yc = np.empty((n, 1))
    ys = np.empty((n, 1))
    dtot = np.zeros((4, 1))
    om = np.empty((n, 1))
    sum_c = np.empty((n, 1))
    sum_s = np.empty((n, 1))
    lw = np.empty((nnz, 1))
    r2 = np.zeros(1)
    dr2 = np.zeros(1)
    for p in range(nnz):
        lw[p, 0] = w[p]
    for i in range(n):
        cl[i, 0] = c[i]
        sl[i, 0] = s[i]
    _lane_velocity(cl, sl, kv[0], kv[1], dtot, om, sum_c, sum_s, lw, indptr, indices)
    r2[0] = dtot[2, 0] ** 2 + dtot[3, 0] ** 2
    dr2[0] = 2.0 * (dtot[2, 0] * dtot[0, 0] + dtot[3, 0] * dtot[1, 0])
    ck = _store(ck, np.int64(0), c, s)
    k = 0
    x = 0.0
    for step in range(1, max_steps + 1):
        r2_prev = r2[0]
        dr2_prev = dr2[0]
        _rk4_lanes(cl, sl, kv, yc, ys, dtot, om, sum_c, sum_s, lw, indptr, indices, dt, r2, dr2)
        if r2[0] >= r2_target:
            k = step
            x = _hermite(r2_prev, dr2_prev, r2[0], dr2[0], dt, r2_target)
            break
        if step % every == 0:
            ck = _store(ck, step // every, cl.ravel(), sl.ravel())  # (n, 1): C views, one _store
    if k == 0:
        return NOT_SYNCED, max_steps, 0.0, ck
    # tau = dt (k - 1 + x), P(x) = target for the Hermite cubic P through (R, D) at k - 1 and k
    w_r, w_d, w_r_prev, w_d_prev = _hermite_seed_weights(r2_prev, dr2_prev, r2[0], dr2[0], dt, x)
    st = np.empty((4, 7, n))
    ac = np.zeros(n)
    as_ = np.zeros(n)
    zc = np.empty(n)
    zs = np.empty(n)
    tc = np.zeros(n)
    ts = np.zeros(n)
    kc = np.empty(n)
    ks = np.empty(n)
    work = (zc, zs, tc, ts, kc, ks)
    net = (indptr, indices, w)
    yk_c = cl[:, 0].copy()
    yk_s = sl[:, 0].copy()
    _crossing_seed(yk_c, yk_s, st, w_r, w_d, ac, as_, kc, ks, g, indptr, indices, w)
    for sg in range((k - 1) // every, -1, -1):
        j0 = sg * every
        j1 = min(j0 + every, k)
        for i in range(n):
            cl[i, 0] = ck[sg, 0, i]
            sl[i, 0] = ck[sg, 1, i]
            seg[0, 0, i] = cl[i, 0]
            seg[0, 1, i] = sl[i, 0]
        _lane_velocity(cl, sl, kv[0], kv[1], dtot, om, sum_c, sum_s, lw, indptr, indices)
        for j in range(j0 + 1, j1):
            _rk4_lanes(cl, sl, kv, yc, ys, dtot, om, sum_c, sum_s, lw, indptr, indices, dt, r2, dr2)
            for i in range(n):
                seg[j - j0, 0, i] = cl[i, 0]
                seg[j - j0, 1, i] = sl[i, 0]
        for j in range(j1 - 1, j0 - 1, -1):
            cj = seg[j - j0, 0]
            sj = seg[j - j0, 1]
            _rk4_vjp(cj, sj, st, ac, as_, work, g, net, dt)
            if j == k - 1:
                # R and D at the step before the crossing (D depends on w even at j = 0)
                _crossing_seed(cj, sj, st, w_r_prev, w_d_prev, ac, as_, kc, ks, g, indptr, indices, w)
    return SYNCED, k, x, ck


# ---- lanes of trajectories (Euler with Taylor rotations; RK4 below) -------------------------
#
# ``LANES`` realizations side by side in ``[node, lane]`` arrays, as the forward lane driver of
# :mod:`.cpu` holds them: the forward pass and the segment recompute are ``euler_step_vec``
# (bit for bit ``euler_step`` per lane when every rotation angle is within the Taylor range), and
# the backward pass is :func:`_euler_vjp` on machine vectors (:func:`_euler_vjp_vec`, the same
# operations in the same order per lane). The lanes of a group start together and end at their
# own crossing steps ``k_q``; the group's clock runs forward until every lane has crossed (or
# hit the step cap) and backward from the largest ``k_q`` to 0. A lane's adjoint state is
# exactly zero for ``j >= k_q`` until its seed at ``j = k_q``, so the steps past its crossing
# add exact zeros to its ``lam`` and ``g`` (``+0.0``: the same bits as not adding). A lane is
# renormalized at step ``j`` when ``j % RENORM_EVERY == 0`` and ``j < k_q``, as the
# one-trajectory pass renormalizes (never at or after its crossing).

LANES = 16
"""Realizations per lane group of the vector adjoint (a multiple of ``2 VEC``)."""


@njit(inline="always")
def _vjp_edges(c, s, lam_new, g, w, indices, p, lanes, qa, node_a, node_b, da, db):
    """CSR entry ``p`` of :func:`_euler_vjp` for the lane vectors at ``qa`` and ``qa + VEC``
    (loop-free, as ``edge_vec``): ``node_a = (c_i, s_i, dt lam_i)`` of the first vector,
    ``node_b`` of the second, ``da``, ``db`` their running diagonal sums."""
    cia, sia, lia = node_a
    cib, sib, lib = node_b
    oa = indices[p] * lanes + qa
    ob = oa + VEC
    ga = p * lanes + qa
    gb = ga + VEC
    cja = vload(c, oa)
    sja = vload(s, oa)
    cjb = vload(c, ob)
    sjb = vload(s, ob)
    vstore(g, ga, vload(g, ga) + lia * (sja * cia - cja * sia))
    vstore(g, gb, vload(g, gb) + lib * (sjb * cib - cjb * sib))
    ta = lia * w[p] * (cja * cia + sja * sia)
    tb = lib * w[p] * (cjb * cib + sjb * sib)
    vstore(lam_new, oa, vload(lam_new, oa) + ta)
    vstore(lam_new, ob, vload(lam_new, ob) + tb)
    return da + ta, db + tb


@njit(cache=True)
def _euler_vjp_vec(c, s, lam, lam_new, g, indptr, indices, w, dt):
    """:func:`_euler_vjp` for every lane of ``[node, lane]`` arrays (``g`` is ``[nnz, lane]``),
    on machine vectors; per lane the same operations in the same order."""
    n, lanes = c.shape
    for o in range(0, n * lanes, VEC):
        vstore(lam_new, o, vload(lam, o))
    for qa in range(0, lanes, 2 * VEC):
        for i in range(n):
            oa = i * lanes + qa
            ob = oa + VEC
            lia = dt * vload(lam, oa)
            lib = dt * vload(lam, ob)
            cia = vload(c, oa)
            sia = vload(s, oa)
            cib = vload(c, ob)
            sib = vload(s, ob)
            node_a = (cia, sia, lia)
            node_b = (cib, sib, lib)
            da = vsplat(0.0)
            db = vsplat(0.0)
            for p in range(indptr[i], indptr[i + 1]):
                da, db = _vjp_edges(c, s, lam_new, g, w, indices, p, lanes, qa, node_a, node_b, da, db)
            vstore(lam_new, oa, vload(lam_new, oa) - da)
            vstore(lam_new, ob, vload(lam_new, ob) - db)


@njit(cache=True)
def _euler_forward_lanes(c, s, cn, sn, lw, ck, k_lane, x_lane, span_lane, code, indptr, indices, w, run):
    """The group's forward pass from the states in ``(c, s)``: per lane its status ``code``,
    crossing step ``k_lane`` (``max_steps + 1`` if none: renormalized to the end) and
    crossing ``x_lane``, ``span_lane = R_k - R_{k-1}``; checkpoints into ``ck`` (returned)."""
    n, lanes = c.shape
    _, dt, r2_target, max_steps, every, _ = run
    r2 = np.empty(lanes)
    r2_prev = np.empty(lanes)
    live = 0
    for q in range(lanes):
        r2[q] = _order2(c[:, q], s[:, q])
        x_lane[q] = 0.0
        span_lane[q] = 1.0
        live += _start_lane(q, r2[q], r2_target, max_steps, code, k_lane)
    ck = _store(ck, np.int64(0), c, s)
    t = 0
    while live > 0 and t < max_steps:
        r2, r2_prev = r2_prev, r2
        t += 1
        _euler_vec(c, s, cn, sn, lw, w, True, indptr, indices, dt, r2)
        c, cn = cn, c
        s, sn = sn, s
        for q in range(lanes):
            if k_lane[q] > t and r2[q] >= r2_target:
                code[q] = SYNCED
                k_lane[q] = t
                span_lane[q] = r2[q] - r2_prev[q]
                x_lane[q] = (r2_target - r2_prev[q]) / span_lane[q]
                live -= 1
        if t % RENORM_EVERY == 0:
            for q in range(lanes):
                if t < k_lane[q]:
                    _renormalize(c[:, q], s[:, q])
        if t % every == 0:
            ck = _store(ck, t // every, c, s)
    return ck


@njit(cache=True)
def _euler_backward_lanes(
    ck, seg_c, seg_s, lw, lam, lam_new, g, k_lane, x_lane, span_lane, code, indptr, indices, w, run
):
    """The group's backward pass: ``g[p, q] = d tau0 / d w_p`` of every SYNCED lane ``q``."""
    n, lanes = lam.shape
    dt = run.dt
    every = run.every
    g[:] = 0.0
    lam[:] = 0.0
    r2 = np.empty(lanes)  # the recompute's R, not needed
    top = _last_crossing(code, k_lane)
    if top < 0:
        return
    for sg in range(top // every, -1, -1):
        j0 = sg * every
        j1 = min(j0 + every, top + 1)
        # states j0 .. j1 - 1 again, exactly as the forward pass made them
        copy_into(seg_c[0], ck[sg, 0])
        copy_into(seg_s[0], ck[sg, 1])
        for j in range(j0 + 1, j1):
            row = j - j0
            _euler_vec(
                seg_c[row - 1], seg_s[row - 1], seg_c[row], seg_s[row], lw, w, True, indptr, indices, dt, r2
            )
            if j % RENORM_EVERY == 0:
                for q in range(lanes):
                    if j < k_lane[q]:
                        _renormalize(seg_c[row][:, q], seg_s[row][:, q])
        for j in range(j1 - 1, j0 - 1, -1):
            cj = seg_c[j - j0]
            sj = seg_s[j - j0]
            _euler_vjp_vec(cj, sj, lam, lam_new, g, indptr, indices, w, dt)
            lam, lam_new = lam_new, lam
            for q in range(lanes):
                if code[q] != SYNCED:
                    continue
                if j == k_lane[q]:
                    # tau = dt (k - 1 + x), x = (R* - R_{k-1}) / (R_k - R_{k-1})  (Eq. A4)
                    _r2_gradient(cj[:, q], sj[:, q], -dt * x_lane[q] / span_lane[q], lam[:, q])
                elif j == k_lane[q] - 1 and j > 0:
                    _r2_gradient(cj[:, q], sj[:, q], -dt * (1.0 - x_lane[q]) / span_lane[q], lam[:, q])


# ---- lanes of RK4 trajectories --------------------------------------------------------------
#
# The forward pass and the recompute are ``rk4_step_vec`` (bit for bit the one-lane
# ``rk4_step_lanes`` the reference runs); the backward pass is :func:`_rk4_vjp` with every
# operation repeated over the ``LANES`` lanes in an innermost loop of constant length (the same
# operations in the same order per lane). An RK4 adjoint state of zero stays exactly ``+0.0``
# through :func:`_rk4_vjp` (every product with it is a signed zero, every sum starts at
# ``+0.0``), so the steps past a lane's crossing leave its adjoint and ``g`` as they were.


class _Transpose(NamedTuple):
    """The CSR pattern of ``W`` by columns: for column ``j``, ``row[t]`` and ``position[t]`` (the
    CSR index ``p`` of ``(i, j)``) for ``t`` in ``indptr[j] .. indptr[j + 1] - 1``, rows
    ascending; ``split[j]`` is the first ``t`` of the column with ``row[t] >= j``."""

    indptr: np.ndarray
    row: np.ndarray
    position: np.ndarray
    split: np.ndarray


def _transpose(indptr: np.ndarray, indices: np.ndarray) -> _Transpose:
    """:class:`_Transpose` of the CSR pattern ``indptr, indices``."""
    n = indptr.size - 1
    row = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    position = np.lexsort((row, indices)).astype(np.int64)  # by column, then row
    col = indices[position]
    tptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(col, minlength=n), out=tptr[1:])
    split = np.searchsorted(col * n + row[position], np.arange(n, dtype=np.int64) * (n + 1))
    return _Transpose(tptr, row[position], position, split.astype(np.int64))


@njit(inline="always")
def _column_link(trow, tpos, w, g, bss, bsc, t, node_j, lanes, qa, aca, asa, acb, asb):
    """Entry ``t`` of column ``j`` of the transposed pattern in :func:`_rk4_vjp_vec`, for the
    lane vectors at ``qa`` and ``qa + VEC`` (``node_j = (c_j, s_j)`` of the first, then of the
    second): row ``i``'s ``w_ij (bsc_i, bss_i)`` into the column's sums and ``g[p] += bss_i s_j
    + bsc_i c_j`` (loop-free, as ``edge_vec``)."""
    cja, sja, cjb, sjb = node_j
    oa = trow[t] * lanes + qa
    ob = oa + VEC
    p = tpos[t]
    ga = p * lanes + qa
    gb = ga + VEC
    wp = w[p]
    bsa = vload(bss, oa)
    bca = vload(bsc, oa)
    bsb = vload(bss, ob)
    bcb = vload(bsc, ob)
    vstore(g, ga, vload(g, ga) + (bsa * sja + bca * cja))
    vstore(g, gb, vload(g, gb) + (bsb * sjb + bcb * cjb))
    return aca + wp * bca, asa + wp * bsa, acb + wp * bcb, asb + wp * bsb


@njit(inline="always")
def _stage_link(st, base, size, w, indices, p, lanes, qa, aa, ba, ab, bb):
    """CSR entry ``p``'s ``w c_j``, ``w s_j`` of the stage state ``st[base ...]`` into the
    coupling sums of the lane vectors at ``qa`` and ``qa + VEC`` (the order of :func:`_velocity`)."""
    oja = indices[p] * lanes + qa
    ojb = oja + VEC
    return (
        aa + w[p] * vload(st, base + oja),
        ba + w[p] * vload(st, base + size + oja),
        ab + w[p] * vload(st, base + ojb),
        bb + w[p] * vload(st, base + size + ojb),
    )


@njit(inline="always")
def _stage_velocity(st, base, size, o, a, b):
    """Stage quantities ``(omega, sc, ss, fc, fs)`` of the lane vector at ``o`` (:func:`_velocity`)."""
    ci = vload(st, base + o)
    si = vload(st, base + size + o)
    om = ci * b - si * a
    vstore(st, base + 2 * size + o, om)
    vstore(st, base + 3 * size + o, a)
    vstore(st, base + 4 * size + o, b)
    vstore(st, base + 5 * size + o, -si * om)
    vstore(st, base + 6 * size + o, ci * om)


@njit(inline="always")
def _project_vjp(yc, ys, st, ac, as_, zc, zs, size, sixth, o):
    """The projection's adjoint for the lane vector at ``o``: ``zbar = (ybar - u (u . ybar)) / |z|``."""
    two = vsplat(2.0)
    zci = vload(yc, o) + sixth * (
        vload(st, 5 * size + o)
        + two * vload(st, 7 * size + 5 * size + o)
        + two * vload(st, 14 * size + 5 * size + o)
        + vload(st, 21 * size + 5 * size + o)
    )
    zsi = vload(ys, o) + sixth * (
        vload(st, 6 * size + o)
        + two * vload(st, 7 * size + 6 * size + o)
        + two * vload(st, 14 * size + 6 * size + o)
        + vload(st, 21 * size + 6 * size + o)
    )
    norm = vsqrt(zci * zci + zsi * zsi)
    uc = zci / norm
    us = zsi / norm
    aci = vload(ac, o)
    asi = vload(as_, o)
    dot = uc * aci + us * asi
    zcv = (aci - uc * dot) / norm
    zsv = (asi - us * dot) / norm
    vstore(zc, o, zcv)
    vstore(zs, o, zsv)
    vstore(ac, o, zcv)
    vstore(as_, o, zsv)


@njit(inline="always")
def _node_cotangents(st, base, size, kc, ks, bss, bsc, own_c, own_s, o):
    """Per node of :func:`_velocity_vjp` at a stage: ``omega``'s cotangent ``ob`` gives the
    node's own term ``(om gs + ob ss, -om gc - ob sc)`` and ``(bss, bsc) = (ob c, -ob s)``."""
    ci = vload(st, base + o)
    si = vload(st, base + size + o)
    om = vload(st, base + 2 * size + o)
    gc = vload(kc, o)
    gs = vload(ks, o)
    ob = ci * gs - si * gc
    vstore(own_c, o, om * gs + ob * vload(st, base + 4 * size + o))
    vstore(own_s, o, -om * gc - ob * vload(st, base + 3 * size + o))
    vstore(bss, o, ob * ci)
    vstore(bsc, o, -ob * si)


@njit(cache=True)
def _rk4_vjp_vec(yc, ys, st, ac, as_, work, g, net, dt, tr, scratch):
    """:func:`_rk4_vjp` (with :func:`_stages`, :func:`_velocity`, :func:`_velocity_vjp`) for
    every lane of ``[node, lane]`` arrays on machine vectors, two vectors of :data:`VEC` lanes at
    a time (whole cache lines of the 16 lanes, and independent chains for the out-of-order
    core): ``st`` is ``[stage, quantity, node, lane]``, ``g`` ``[nnz, lane]``. Per lane the same
    operations in the same order as the reference, so the same bits.

    The scatter of :func:`_velocity_vjp` (``bs_j += w_ij bss_i`` along row ``i``) runs as a
    gather down column ``j`` of the transposed pattern ``tr`` (:class:`_Transpose`): the
    per-node cotangents first, into ``scratch`` (``[4, node * lane]``), then for each ``j`` a
    register sum of what the scatter adds into ``(bc_j, bs_j)`` in its order (the rows
    ``i < j`` ascending, ``j``'s own term, the rows ``i >= j``). ``work`` and ``net`` as in
    :func:`_rk4_vjp`, each array ``[node, lane]``."""
    zc, zs, tc, ts, kc, ks = work
    indptr, indices, w = net
    n, lanes = yc.shape
    size = n * lanes
    h = 0.5 * dt
    sixth = dt / 6.0
    tptr, trow, tpos, tsplit = tr.indptr, tr.row, tr.position, tr.split
    bss = scratch[0]
    bsc = scratch[1]
    own_c = scratch[2]
    own_s = scratch[3]
    for qa in range(0, lanes, 2 * VEC):
        # the four stages: state, omega, coupling sums and velocity (_stages)
        for sq in range(4):
            base = sq * 7 * size
            if sq == 0:
                for o in range(qa, size, lanes):
                    for v in range(2):
                        vstore(st, base + o + v * VEC, vload(yc, o + v * VEC))
                        vstore(st, base + size + o + v * VEC, vload(ys, o + v * VEC))
            else:
                hq = 0.5 * dt if sq < 3 else dt
                prev = (sq - 1) * 7 * size
                for o in range(qa, size, lanes):
                    for v in range(2):
                        ov = o + v * VEC
                        vstore(st, base + ov, vload(yc, ov) + hq * vload(st, prev + 5 * size + ov))
                        vstore(st, base + size + ov, vload(ys, ov) + hq * vload(st, prev + 6 * size + ov))
            for i in range(n):
                aa, ba, ab, bb = vsplat(0.0), vsplat(0.0), vsplat(0.0), vsplat(0.0)
                for p in range(indptr[i], indptr[i + 1]):
                    aa, ba, ab, bb = _stage_link(st, base, size, w, indices, p, lanes, qa, aa, ba, ab, bb)
                _stage_velocity(st, base, size, i * lanes + qa, aa, ba)
                _stage_velocity(st, base, size, i * lanes + qa + VEC, ab, bb)
        # projection y_{n+1} = z / |z| per node
        for o in range(qa, size, lanes):
            _project_vjp(yc, ys, st, ac, as_, zc, zs, size, sixth, o)
            _project_vjp(yc, ys, st, ac, as_, zc, zs, size, sixth, o + VEC)
        # z = y + dt/6 (k1 + 2 k2 + 2 k3 + k4); y4 = y + dt k3, y3 = y + h k2, y2 = y + h k1
        for sq in range(3, -1, -1):
            base = sq * 7 * size
            wq = 1.0 / 6.0 if (sq == 0 or sq == 3) else 1.0 / 3.0
            for o in range(qa, size, lanes):
                for v in range(2):
                    ov = o + v * VEC
                    if sq == 3:
                        vstore(kc, ov, dt * wq * vload(zc, ov))
                        vstore(ks, ov, dt * wq * vload(zs, ov))
                    else:
                        hq = dt if sq == 2 else h
                        vstore(kc, ov, dt * wq * vload(zc, ov) + hq * vload(tc, ov))
                        vstore(ks, ov, dt * wq * vload(zs, ov) + hq * vload(ts, ov))
                    vstore(tc, ov, vsplat(0.0))
                    vstore(ts, ov, vsplat(0.0))
            # _velocity_vjp at stage sq into (bc, bs) = (ac, as_) for the first stage, else into
            # (tc, ts) and then added to (ac, as_)
            for o in range(qa, size, lanes):
                _node_cotangents(st, base, size, kc, ks, bss, bsc, own_c, own_s, o)
                _node_cotangents(st, base, size, kc, ks, bss, bsc, own_c, own_s, o + VEC)
            for j in range(n):
                oa = j * lanes + qa
                ob = oa + VEC
                cja = vload(st, base + oa)
                sja = vload(st, base + size + oa)
                cjb = vload(st, base + ob)
                sjb = vload(st, base + size + ob)
                node_j = (cja, sja, cjb, sjb)
                if sq == 0:
                    aca, asa, acb, asb = vload(ac, oa), vload(as_, oa), vload(ac, ob), vload(as_, ob)
                else:
                    aca, asa, acb, asb = vload(tc, oa), vload(ts, oa), vload(tc, ob), vload(ts, ob)
                for t in range(tptr[j], tsplit[j]):
                    aca, asa, acb, asb = _column_link(
                        trow, tpos, w, g, bss, bsc, t, node_j, lanes, qa, aca, asa, acb, asb
                    )
                aca = aca + vload(own_c, oa)
                asa = asa + vload(own_s, oa)
                acb = acb + vload(own_c, ob)
                asb = asb + vload(own_s, ob)
                for t in range(tsplit[j], tptr[j + 1]):
                    aca, asa, acb, asb = _column_link(
                        trow, tpos, w, g, bss, bsc, t, node_j, lanes, qa, aca, asa, acb, asb
                    )
                if sq > 0:
                    vstore(tc, oa, aca)  # the next stage's kc, ks read them
                    vstore(ts, oa, asa)
                    vstore(tc, ob, acb)
                    vstore(ts, ob, asb)
                    aca = vload(ac, oa) + aca
                    asa = vload(as_, oa) + asa
                    acb = vload(ac, ob) + acb
                    asb = vload(as_, ob) + asb
                vstore(ac, oa, aca)
                vstore(as_, oa, asa)
                vstore(ac, ob, acb)
                vstore(as_, ob, asb)


@njit(cache=True)
def _rk4_forward_lanes(c, s, step_bufs, ck, crossing, net, run):
    """The group's RK4 forward pass from the states in ``(c, s)``; into ``crossing = (k_lane,
    x_lane, coef, code)`` per lane ``code``, ``k_lane``, ``x_lane`` and the Hermite seed
    coefficients ``coef[:, q] = (R_k, D_k, R_{k-1}, D_{k-1})`` weights (as :func:`_rk4_adjoint`
    forms them); checkpoints into ``ck`` (returned). ``step_bufs = (kv, yc, ys, ybc, ybs, lw)``:
    the buffers and per-lane weights of the lane RK4 step; ``net = (indptr, indices, w)``."""
    kv, yc, ys, ybc, ybs, lw = step_bufs
    k_lane, x_lane, coef, code = crossing
    indptr, indices, w = net
    n, lanes = c.shape
    _, dt, r2_target, max_steps, every, _ = run
    r2 = np.empty(lanes)
    dr2 = np.empty(lanes)
    r2_prev = np.empty(lanes)
    dr2_prev = np.empty(lanes)
    live = 0
    dtot = np.empty((4, lanes))
    om = np.empty((n, lanes))
    sum_c = np.empty((n, lanes))
    sum_s = np.empty((n, lanes))
    _lane_velocity(c, s, kv[0], kv[1], dtot, om, sum_c, sum_s, lw, indptr, indices)
    for q in range(lanes):
        r2[q] = dtot[2, q] ** 2 + dtot[3, q] ** 2
        dr2[q] = 2.0 * (dtot[2, q] * dtot[0, q] + dtot[3, q] * dtot[1, q])
        x_lane[q] = 0.0
        # the reference asks _order2 (sums in the same order as d2, d3 here)
        live += _start_lane(q, _order2(c[:, q], s[:, q]), r2_target, max_steps, code, k_lane)
    ck = _store(ck, np.int64(0), c, s)
    t = 0
    while live > 0 and t < max_steps:
        r2, r2_prev = r2_prev, r2
        dr2, dr2_prev = dr2_prev, dr2
        t += 1
        _rk4_vec(c, s, kv, yc, ys, ybc, ybs, lw, w, True, indptr, indices, dt, r2, dr2)
        for q in range(lanes):
            if k_lane[q] > t and r2[q] >= r2_target:
                code[q] = SYNCED
                k_lane[q] = t
                x = _hermite(r2_prev[q], dr2_prev[q], r2[q], dr2[q], dt, r2_target)
                x_lane[q] = x
                coef[0, q], coef[1, q], coef[2, q], coef[3, q] = _hermite_seed_weights(
                    r2_prev[q], dr2_prev[q], r2[q], dr2[q], dt, x
                )
                live -= 1
        if t % every == 0:
            ck = _store(ck, t // every, c, s)
    return ck


@njit(cache=True)
def _rk4_backward_lanes(ck, seg_c, seg_s, c, s, step_bufs, g, crossing, net, tr, run):
    """The group's RK4 backward pass: ``g[p, q] = d tau0 / d w_p`` of every SYNCED lane
    (``step_bufs``, ``crossing`` and ``net`` as :func:`_rk4_forward_lanes` left them)."""
    kv, yc, ys, ybc, ybs, lw = step_bufs
    k_lane, _, coef, code = crossing
    indptr, indices, w = net
    n, lanes = ck.shape[2], ck.shape[3]
    dt = run.dt
    every = run.every
    g[:] = 0.0
    top = _last_crossing(code, k_lane)
    if top < 0:
        return
    st = np.empty((4, 7, n, lanes))
    scratch = np.empty((4, n * lanes))  # _rk4_vjp_vec's per-node cotangents
    ac = np.zeros((n, lanes))
    as_ = np.zeros((n, lanes))
    zc = np.empty((n, lanes))
    zs = np.empty((n, lanes))
    tc = np.zeros((n, lanes))
    ts = np.zeros((n, lanes))
    kc = np.empty((n, lanes))
    ks = np.empty((n, lanes))
    work = (zc, zs, tc, ts, kc, ks)
    r2 = np.empty(lanes)
    dr2 = np.empty(lanes)
    # one-lane scratch of the seeds (the reference's own buffers)
    st1 = np.empty((4, 7, n))
    kc1 = np.empty(n)
    ks1 = np.empty(n)
    dtot = np.empty((4, lanes))
    om = np.empty((n, lanes))
    sum_c = np.empty((n, lanes))
    sum_s = np.empty((n, lanes))
    for sg in range(top // every, -1, -1):
        j0 = sg * every
        j1 = min(j0 + every, top + 1)
        # states j0 .. j1 - 1 again, exactly as the forward pass made them
        copy_into(c, ck[sg, 0])
        copy_into(s, ck[sg, 1])
        copy_into(seg_c[0], c)
        copy_into(seg_s[0], s)
        _lane_velocity(c, s, kv[0], kv[1], dtot, om, sum_c, sum_s, lw, indptr, indices)
        for j in range(j0 + 1, j1):
            _rk4_vec(c, s, kv, yc, ys, ybc, ybs, lw, w, True, indptr, indices, dt, r2, dr2)
            copy_into(seg_c[j - j0], c)
            copy_into(seg_s[j - j0], s)
        for j in range(j1 - 1, j0 - 1, -1):
            cj = seg_c[j - j0]
            sj = seg_s[j - j0]
            _rk4_vjp_vec(cj, sj, st, ac, as_, work, g, net, dt, tr, scratch)
            for q in range(lanes):
                if code[q] != SYNCED:
                    continue
                if j == k_lane[q]:
                    cr, cd = coef[0, q], coef[1, q]
                elif j == k_lane[q] - 1:
                    # R and D at the step before the crossing (D depends on w even at j = 0)
                    cr, cd = coef[2, q], coef[3, q]
                else:
                    continue
                _crossing_seed(
                    cj[:, q],
                    sj[:, q],
                    st1,
                    cr,
                    cd,
                    ac[:, q],
                    as_[:, q],
                    kc1,
                    ks1,
                    g[:, q],
                    indptr,
                    indices,
                    w,
                )


# ---- the batch drivers -----------------------------------------------------------------------


@njit(inline="always")
def _start_state(c, s, seed, k):
    """``(c, s) = (cos theta, sin theta)`` of realization ``k``'s initial phases."""
    for i in range(c.shape[0]):
        th = phase(seed, k, i)
        c[i] = np.cos(th)
        s[i] = np.sin(th)


@njit(inline="always")
def _link_values(dtau, r, g, synced, d_ptr, d_pos, d_val):
    """``dtau[r, e] = sum_p (dW/dbeta_e)_p g_p`` for every link ``e`` (:class:`LinkDerivatives`
    ``d_ptr, d_pos, d_val``), or 0 unless ``synced``."""
    for e in range(d_ptr.shape[0] - 1):
        total = 0.0
        if synced:
            for p in range(d_ptr[e], d_ptr[e + 1]):
                total += d_val[p] * g[d_pos[p]]
        dtau[r, e] = total


@njit(cache=True)
def _adjoint_lanes_group(ks, indptr, indices, w, tr, deriv, run, status0, steps0, frac0, dtau, group):
    """Group ``group`` of ``LANES`` realizations of ``ks``, stepped together (every group in
    parallel, one per task: :func:`_adjoint_lanes_batch`)."""
    d_ptr, d_pos, d_val = deriv
    seed, _, _, max_steps, every, rk4 = run
    m = ks.shape[0]
    n = indptr.shape[0] - 1
    nnz = w.shape[0]
    lanes = LANES
    r_lo = group * lanes
    r_hi = min(m, r_lo + lanes)
    # empty lanes hold the synchronized state (1, 0): ALREADY_SYNCED, never looked at
    c = np.ones((n, lanes))
    s = np.zeros((n, lanes))
    for r in range(r_lo, r_hi):
        _start_state(c[:, r - r_lo], s[:, r - r_lo], seed, ks[r])
    cn = np.empty((n, lanes))
    sn = np.empty((n, lanes))
    ck = np.empty((16, 2, n, lanes))
    k_lane = np.empty(lanes, dtype=np.int64)
    x_lane = np.empty(lanes)
    span_lane = np.empty(lanes)
    coef = np.empty((4, lanes))
    code = np.empty(lanes, dtype=np.int8)
    seg_len = min(every, max_steps + 1)
    seg_c = np.empty((seg_len, n, lanes))
    seg_s = np.empty((seg_len, n, lanes))
    g = np.empty((nnz, lanes))
    if rk4:
        lw = np.empty((nnz, lanes))  # per-lane weights of lane_velocity
        for p in range(nnz):
            lw[p] = w[p]
        kv = np.zeros((8, n, lanes))
        yc = np.empty((n, lanes))
        ys = np.empty((n, lanes))
        step_bufs = (kv, yc, ys, cn, sn, lw)
        crossing = (k_lane, x_lane, coef, code)
        net = (indptr, indices, w)
        ck = _rk4_forward_lanes(c, s, step_bufs, ck, crossing, net, run)
        _rk4_backward_lanes(ck, seg_c, seg_s, c, s, step_bufs, g, crossing, net, tr, run)
    else:
        lw = np.empty((1, lanes))  # unused: every lane has the weights w
        ck = _euler_forward_lanes(
            c, s, cn, sn, lw, ck, k_lane, x_lane, span_lane, code, indptr, indices, w, run
        )
        lam = np.empty((n, lanes))
        lam_new = np.empty((n, lanes))
        _euler_backward_lanes(
            ck,
            seg_c,
            seg_s,
            lw,
            lam,
            lam_new,
            g,
            k_lane,
            x_lane,
            span_lane,
            code,
            indptr,
            indices,
            w,
            run,
        )
    for r in range(r_lo, r_hi):
        q = r - r_lo
        st = code[q]
        status0[r] = st
        steps0[r] = k_lane[q] if st == SYNCED else (0 if st == ALREADY_SYNCED else max_steps)
        frac0[r] = x_lane[q]
        _link_values(dtau, r, g[:, q], st == SYNCED, d_ptr, d_pos, d_val)


def _adjoint_lanes_batch(item, ks, indptr, indices, w, tr, deriv, run, status0, steps0, frac0, dtau):
    """``item`` (:func:`_adjoint_lanes_group`) of every group of ``LANES`` realizations, one per
    parallel task (compiled by :func:`antisync.kernels.loops.run`)."""
    for group in prange((ks.shape[0] + LANES - 1) // LANES):
        item(ks, indptr, indices, w, tr, deriv, run, status0, steps0, frac0, dtau, np.int64(group))


@njit(cache=True)
def _adjoint_group(ks, indptr, indices, w, deriv, run, n_groups, status0, steps0, frac0, dtau, group):
    """Range ``group`` of realizations ``ks`` split into ``n_groups`` ranges, its realizations
    one at a time with the group's buffers (every group in parallel: :func:`_adjoint_batch`)."""
    d_ptr, d_pos, d_val = deriv
    seed, dt, r2_target, max_steps, every, rk4 = run
    m = ks.shape[0]
    n = indptr.shape[0] - 1
    nnz = w.shape[0]
    r_lo, r_hi = group_rows(group, n_groups, m)
    if r_lo >= r_hi:
        return
    c = np.empty(n)
    s = np.empty(n)
    acc = np.empty(n)
    ck = np.empty((16, 2, n))
    seg = np.empty((min(every, max_steps), 2, n))  # a segment never outgrows the trajectory
    lam = np.empty(n)
    lam_new = np.empty(n)
    g = np.zeros(nnz)
    for r in range(r_lo, r_hi):
        _start_state(c, s, seed, ks[r])
        if rk4:
            st, k, x, ck = _rk4_adjoint(c, s, ck, seg, g, indptr, indices, w, dt, r2_target, max_steps, every)
        else:
            st, k, x, ck = _euler_adjoint(
                c, s, acc, ck, seg, lam, lam_new, g, indptr, indices, w, dt, r2_target, max_steps, every
            )
        status0[r] = st
        steps0[r] = k
        frac0[r] = x
        _link_values(dtau, r, g, st == SYNCED, d_ptr, d_pos, d_val)


def _adjoint_batch(item, ks, indptr, indices, w, deriv, run, n_groups, status0, steps0, frac0, dtau):
    """``item`` (:func:`_adjoint_group`) of every group, one per parallel task (compiled by
    :func:`antisync.kernels.loops.run`)."""
    for group in prange(n_groups):
        item(ks, indptr, indices, w, deriv, run, n_groups, status0, steps0, frac0, dtau, np.int64(group))


def _lane_order(ks, indptr, indices, w, run: _Run) -> np.ndarray:
    """The order in which :func:`_adjoint_lanes_batch` takes the realizations ``ks``.

    A lane group's clock runs until its slowest lane has crossed, so realizations are grouped
    by their crossing time, predicted by the forward lane driver (:mod:`.cpu`, with refill)
    with RK4 at a step of :data:`PREDICT_DT` (over the largest row sum of ``|w|``) when that is
    coarser than ``run.dt``: the order needs times close to the run's, not its bits, and the
    coarse pass costs a small part of a forward pass (at ``run.dt`` it cost 10-25% of the
    whole adjoint). The groups are then dealt round-robin to the threads' contiguous shares of
    the parallel loop, so that each thread gets short and long ones. Only the speed depends on
    the order, never a result.
    """
    m = ks.size
    if m <= LANES:
        return np.arange(m)
    graph = Graph(indptr, indices, w, np.empty((0, w.size)), np.zeros(0, dtype=np.bool_))
    dt = PREDICT_DT / max(row_sum_bound(indptr, w, []), 1e-300)
    if dt > run.dt:
        steps = int(np.ceil(run.max_steps * run.dt / dt))
        lane_run = LaneRun(run.seed, dt, run.r2_target, steps, False, True, LANES)
    else:
        lane_run = LaneRun(run.seed, run.dt, run.r2_target, run.max_steps, not run.rk4, run.rk4, LANES)
    out = Outputs(
        np.empty(m, dtype=np.int8),
        np.empty(m, dtype=np.int64),
        np.empty(m),
        np.empty((m, 0), dtype=np.int8),
        np.empty((m, 0), dtype=np.int64),
        np.empty((m, 0)),
        np.empty((m, 0)),
    )
    threads = numba.get_num_threads()
    integrate_lanes(ks, graph, lane_run, None, out, NO_TANGENTS, threads)
    by_steps = np.argsort(out.steps0, kind="stable")
    n_groups = (m + LANES - 1) // LANES
    groups = [by_steps[g * LANES : (g + 1) * LANES] for g in range(n_groups)]
    dealt = [g for t in range(threads) for g in range(t, n_groups, threads)]
    # the last group may be short: keep it last, so every other group is full
    if n_groups - 1 in dealt:
        dealt.remove(n_groups - 1)
        dealt.append(n_groups - 1)
    return np.concatenate([groups[g] for g in dealt])


def simulate_adjoint(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    derivatives: LinkDerivatives,
    *,
    dt: float,
    threshold: float,
    max_steps: int,
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    integrator: Integrator = "euler",
    checkpoint_every: int = CHECKPOINT_EVERY,
    lanes: bool = True,
) -> PathwiseResult:
    """Undamaged trajectories and ``d tau0 / d beta_e`` for every link ``e`` of ``derivatives``.

    The same numbers as :func:`antisync.kernels.cpu.simulate_pathwise` (Euler) to rounding,
    from one forward and one backward pass per realization, whatever the number of links.

    Parameters
    ----------
    seed, first, count, realizations
        As in :func:`antisync.kernels.cpu.simulate`.
    indptr, indices, base_weights : arrays
        CSR form of the undamaged ``W(Omega)``.
    derivatives : LinkDerivatives
        ``dW/dbeta_e`` of each link (:func:`link_derivatives`).
    dt, threshold, max_steps, threads
        As in :func:`antisync.kernels.cpu.simulate`.
    integrator : {"euler", "rk4"}
        Euler (linear crossing in ``R``) or RK4 (cubic Hermite crossing).
    checkpoint_every : int
        ``K``, steps between stored states (see the module docstring); never changes results.
    lanes : bool
        Run :data:`LANES` trajectories at a time on machine vectors (RK4 always; Euler when
        every rotation angle is within the Taylor range, ``dt sum_j |w_ij| <= 0.05``); ``False``
        runs one trajectory at a time (the reference). The results are the same bits either way.

    Returns
    -------
    PathwiseResult
        ``status0``, ``steps0``, ``frac0`` of the undamaged network (interpolated ``tau0 =
        (steps0 - 1 + frac0) dt``) and ``dtau[r, e] = d tau0 / d beta_e`` (0 unless SYNCED).
    """
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    every = checkpoint_every
    if isinstance(every, bool) or not isinstance(every, int | np.integer) or every < 1:
        raise ValueError(f"checkpoint_every must be a positive integer, got {checkpoint_every!r}")
    ks = realization_ids(first, count, realizations)
    n = indptr.size - 1
    m = ks.size
    deriv = LinkDerivatives(
        np.ascontiguousarray(derivatives.indptr, dtype=np.int64),
        np.ascontiguousarray(derivatives.position, dtype=np.int64),
        np.ascontiguousarray(derivatives.value, dtype=np.float64),
    )
    status0 = np.empty(m, dtype=np.int8)
    steps0 = np.empty(m, dtype=np.int64)
    frac0 = np.empty(m)
    dtau = np.empty((m, deriv.indptr.size - 1))
    run = _Run(
        np.uint64(seed),
        float(dt),
        (threshold * n) ** 2,
        int(max_steps),
        int(checkpoint_every),
        integrator == "rk4",
    )
    indptr = np.ascontiguousarray(indptr, dtype=np.int64)
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    taylor = float(dt) * row_sum_bound(indptr, base_weights, []) <= TAYLOR_MAX_ANGLE
    if lanes and (taylor or integrator == "rk4"):
        with Threads(threads):
            order = _lane_order(ks, indptr, indices, base_weights, run)
            out = (np.empty_like(status0), np.empty_like(steps0), np.empty_like(frac0), np.empty_like(dtau))
            tr = _transpose(indptr, indices)
            args = (ks[order], indptr, indices, base_weights, tr, deriv, run, *out)
            loops.run(_adjoint_lanes_batch, _adjoint_lanes_group, *args)
        for target, got in zip((status0, steps0, frac0, dtau), out, strict=True):
            target[order] = got
        return PathwiseResult(status0, steps0, frac0, dtau)
    with Threads(threads) as groups:
        loops.run(
            _adjoint_batch,
            _adjoint_group,
            ks,
            np.ascontiguousarray(indptr, dtype=np.int64),
            np.ascontiguousarray(indices, dtype=np.int64),
            np.ascontiguousarray(base_weights, dtype=np.float64),
            deriv,
            run,
            groups,
            status0,
            steps0,
            frac0,
            dtau,
        )
    return PathwiseResult(status0, steps0, frac0, dtau)
