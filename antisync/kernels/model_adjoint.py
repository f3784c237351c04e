"""Adjoint sensitivities of tau0 for the generalized models: ``lambda.method: adjoint`` beyond Eq. 2.

The model kernels (:func:`antisync.kernels.core.make_model_kernels`) integrate ``y = (c, s,
nu)`` (``c_i, s_i = cos, sin theta_i``, ``nu_i = theta_i'`` at nodes with inertia) by Euler (a
rotation of ``(c_i, s_i)`` by ``dt theta_i'``) or RK4 (projected back to the unit circle after
each step), and locate the crossing on the dense output (docs/models.md). This module
differentiates exactly that computation: the crossing time ``tau0 = dt (k - 1 + x)`` of the
discrete trajectory, ``x`` the crossing inside the last step, with respect to every entry
``w_p`` of the coupling ``W``, by one backward pass of the discrete step's adjoint (vector-
Jacobian products). ``d tau0 / d beta_e`` is the contraction with ``dW/dbeta_e``
(:func:`antisync.kernels.adjoint.link_derivatives`), plus, for the relative criterion, the
term of the target's own dependence on the damage (``r*`` moves with ``W``).

The crossing's derivative, by criterion (``H`` the interpolant at the crossing ``x*``):

- order parameter / relative: ``H(x*; R_{k-1}, dt R'_{k-1}, R_k, dt R'_k) = T`` (cubic Hermite for
  RK4, linear for Euler) gives ``dx = (dT - sum_a H_a da) / H_x``, ``a`` the four end values,
  each a function of the state at its end (``R' = 2 (C dC/dt + S dS/dt)`` through ``theta'``);
- frequency: the first ``x`` where every deviation is inside the band is where the *active*
  deviation (the one at ``+-tolerance`` there: node ``i*``, ``theta'`` or ``g`` row) enters it, so
  ``x`` is differentiated through that one interpolant, its end values ``theta_i' - mean`` and
  rates ``d/dt`` of it (``nu_i'`` at a node with inertia, ``d coupling_i/dt / gamma_i`` elsewhere:
  second derivatives of the phases, differentiated here too). A max over nodes is piecewise
  smooth: where two deviations reach the band edge together the derivative jumps, and such
  realizations are a set of measure zero.

Memory as in :mod:`antisync.kernels.adjoint`: the forward pass keeps every ``every``-th state,
the backward pass recomputes each segment from its checkpoint (bit for bit the same states) and
walks it backwards. The RK4 forward pass is the driver's ``sync_steps`` run in pieces of
``every`` steps, storing each piece's start (:func:`_forward`); Euler's renormalization counts
steps from the call's start, so its forward pass runs twice (once to find ``k``, once to store
the checkpoints). The replay of an RK4 segment keeps each step's stage states and phase rates
(:func:`_rk4_record`, the driver's step with the same operations), so the step's adjoint
(:func:`_rk4_vjp`) evaluates no right-hand side: per step, the forward pass makes 5 passes
over the edges (4 stages and the frequency criterion's rates), the replay 4 and the backward pass
4, each gathering and scattering in one pass (IEEE 14 swing: 2.4-2.5 ms per
realization, from 4.4-4.9 with the second forward pass and the backward stages' right-hand
sides; bench/RESULTS.md). ``every`` never changes the results.

Tests (tests/test_model_adjoint.py): per realization, for each model (frequencies, lag,
inertia, mixed inertia) and criterion, Euler and RK4, ``d tau0 / d beta_e`` equals a central
difference of the interpolated crossing of the same discrete integrator.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import loops
from antisync.kernels.core import (
    CRIT_FREQUENCY,
    DEV_ROW,
    RENORM_EVERY,
    WORK_ROWS,
)
from antisync.kernels.model_steps import MK
from antisync.kernels.precision import K64
from antisync.kernels.shared import (
    PathwiseResult,
    Threads,
    batch_starts,
    copy_into,
    doubled,
    has_inertia,
    per_node,
    realization_ids,
)
from antisync.physics.phases import start_phase
from antisync.status import NOT_SYNCED, SYNCED

__all__ = ["simulate_model_adjoint"]

_rhs = MK.rhs
_rk4_step = MK.rk4_step
_euler_step = MK.euler_step
_sync = MK.sync_steps
_measure = MK.measure
_deviations = MK.deviations
_renormalize = K64.renormalize
_rotation = K64.rotation


# ---- the vector-Jacobian products of the right-hand side ----------------------------------


@njit(inline="always")
def _coupling_vjp(c, s, b_k, indptr, indices, w, cl, sl, bc, bs, g):
    """Add ``(d K / d (c, s, w))^T b_k`` to ``bc``, ``bs``, ``g``, where ``K_i = cl (c_i S_i - s_i
    C_i) - sl (c_i C_i + s_i S_i)`` and ``C_i = sum_p w_p c_j``, ``S_i = sum_p w_p s_j``.

    One pass over each row: the cotangents of ``C_i``, ``S_i`` do not depend on the sums, so
    the sums (for node ``i``'s own cotangent) are gathered in the same pass that scatters."""
    n = c.shape[0]
    for i in range(n):
        if b_k[i] == 0.0:
            continue
        b_sc = b_k[i] * (-cl * s[i] - sl * c[i])
        b_ss = b_k[i] * (cl * c[i] - sl * s[i])
        sc = 0.0
        ss = 0.0
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            cj = c[j]
            sj = s[j]
            sc += w[q] * cj
            ss += w[q] * sj
            bc[j] += w[q] * b_sc
            bs[j] += w[q] * b_ss
            g[q] += b_sc * cj + b_ss * sj
        bc[i] += b_k[i] * (cl * ss - sl * sc)
        bs[i] += b_k[i] * (-cl * sc - sl * ss)


@njit(inline="always")
def _rate_cotangents(b_th, b_dnu, mass, gamma, second):
    """``(b_k, b_nu)``: one node's cotangents of its coupling ``K`` and of ``nu`` from those of
    its rates ``theta'`` (``b_th``) and ``nu'`` (``b_dnu``) in ``rhs``."""
    if not second:
        return b_th, 0.0
    if mass > 0.0:
        # theta' = nu, nu' = (P + K - gamma nu) / m
        return b_dnu / mass, b_th - gamma / mass * b_dnu
    return b_th / gamma, 0.0


@njit(inline="always")
def _rates_vjp(c, s, b_th, b_dnu, eq, second, bc, bs, bnu, g, b_k):
    """Add the cotangents of ``(c, s, nu, w)`` from those of the rates ``theta'`` (``b_th``)
    and ``nu'`` (``b_dnu``) of :func:`~antisync.kernels.core.make_model_kernels`' ``rhs``;
    ``b_k`` is scratch."""
    _, w, indptr, indices, cl, sl, mass, gamma = eq
    n = c.shape[0]
    for i in range(n):
        b_k[i], b_nu = _rate_cotangents(b_th[i], b_dnu[i], mass[i], gamma[i], second)
        bnu[i] += b_nu
    _coupling_vjp(c, s, b_k, indptr, indices, w, cl, sl, bc, bs, g)


@njit(cache=True)
def _kdot_vjp(c, s, th, b_kd, indptr, indices, w, cl, sl, bc, bs, b_th, g):
    """Add the cotangents of ``(c, s, theta', w)`` from those of ``Kd_i = sum_p w_p cos(theta_j -
    theta_i - alpha) (theta_j' - theta_i')``."""
    n = c.shape[0]
    for i in range(n):
        if b_kd[i] == 0.0:
            continue
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            ca = cl * (c[j] * c[i] + s[j] * s[i]) + sl * (s[j] * c[i] - c[j] * s[i])
            dth = th[j] - th[i]
            g[q] += b_kd[i] * ca * dth
            b_ca = b_kd[i] * w[q] * dth
            b_th[j] += b_kd[i] * w[q] * ca
            b_th[i] -= b_kd[i] * w[q] * ca
            bc[j] += b_ca * (cl * c[i] - sl * s[i])
            bs[j] += b_ca * (cl * s[i] + sl * c[i])
            bc[i] += b_ca * (cl * c[j] + sl * s[j])
            bs[i] += b_ca * (cl * s[j] - sl * c[j])


# ---- the vector-Jacobian products of one step ---------------------------------------------


@njit(inline="always")
def _rk4_record(y, st, sth, k, th, dnu, eq, second, dt):
    """One step of :func:`~antisync.kernels.core.make_model_kernels`' ``rk4_step`` from ``y``
    (rows c, s, nu; ``th``/``dnu`` its rates on entry), with the same operations in the same
    order (so bit for bit the same next state), keeping what the step's adjoint needs: the stage
    states ``st`` (4, 3, n) and their phase rates ``sth`` (4, n). ``k`` (3, 4, n) is scratch for
    the stage fields. On exit ``y`` is the next state and ``th``/``dnu`` its rates."""
    n = th.shape[0]
    for i in range(n):
        st[0, 0, i] = y[0, i]
        st[0, 1, i] = y[1, i]
        st[0, 2, i] = y[2, i]
        sth[0, i] = th[i]
        k[0, 0, i] = -y[1, i] * th[i]
        k[1, 0, i] = y[0, i] * th[i]
        k[2, 0, i] = dnu[i] if second else 0.0
    for stage in range(1, 4):
        h = 0.5 * dt if stage < 3 else dt
        for i in range(n):
            st[stage, 0, i] = y[0, i] + h * k[0, stage - 1, i]
            st[stage, 1, i] = y[1, i] + h * k[1, stage - 1, i]
            st[stage, 2, i] = y[2, i] + h * k[2, stage - 1, i]
        _rhs(st[stage, 0], st[stage, 1], st[stage, 2], eq, second, th, dnu)
        for i in range(n):
            sth[stage, i] = th[i]
            k[0, stage, i] = -st[stage, 1, i] * th[i]
            k[1, stage, i] = st[stage, 0, i] * th[i]
            k[2, stage, i] = dnu[i] if second else 0.0
    for i in range(n):
        cn = y[0, i] + dt / 6.0 * (k[0, 0, i] + 2.0 * k[0, 1, i] + 2.0 * k[0, 2, i] + k[0, 3, i])
        sn = y[1, i] + dt / 6.0 * (k[1, 0, i] + 2.0 * k[1, 1, i] + 2.0 * k[1, 2, i] + k[1, 3, i])
        inv = 1.0 / math.sqrt(cn * cn + sn * sn)
        y[0, i] = cn * inv
        y[1, i] = sn * inv
        if second:
            y[2, i] += dt / 6.0 * (k[2, 0, i] + 2.0 * k[2, 1, i] + 2.0 * k[2, 2, i] + k[2, 3, i])
    _rhs(y[0], y[1], y[2], eq, second, th, dnu)


@njit(cache=True)
def _rk4_vjp(st, sth, lam, out, ak, by, b_k, eq, second, dt, g):
    """``out = (d step / d y)^T lam`` and ``g += (d step / d w)^T lam`` for the RK4 step whose
    stage states ``st`` (4, 3, n) and phase rates ``sth`` (4, n) :func:`_rk4_record` kept:
    no right-hand side is evaluated again. ``ak`` (4, 3, n), ``by`` (3, n), ``b_k`` (n): scratch."""
    _, w, indptr, indices, cl, sl, mass, gamma = eq
    n = sth.shape[1]
    # the projection of (c, s) after the step: c' = z_c / rho, s' = z_s / rho, with
    # z = y + dt/6 (K1 + 2 K2 + 2 K3 + K4) and K = (-s theta', c theta') at each stage
    for i in range(n):
        zc = st[0, 0, i] + dt / 6.0 * (
            -st[0, 1, i] * sth[0, i]
            + 2.0 * -st[1, 1, i] * sth[1, i]
            + 2.0 * -st[2, 1, i] * sth[2, i]
            - st[3, 1, i] * sth[3, i]
        )
        zs = st[0, 1, i] + dt / 6.0 * (
            st[0, 0, i] * sth[0, i]
            + 2.0 * st[1, 0, i] * sth[1, i]
            + 2.0 * st[2, 0, i] * sth[2, i]
            + st[3, 0, i] * sth[3, i]
        )
        rho = math.sqrt(zc * zc + zs * zs)
        cn = zc / rho
        sn = zs / rho
        dot = cn * lam[0, i] + sn * lam[1, i]
        # the cotangents of the stage fields: b_K = (1, 2, 2, 1) dt/6 b_z
        bzc = (lam[0, i] - cn * dot) / rho
        bzs = (lam[1, i] - sn * dot) / rho
        bzn = lam[2, i] if second else 0.0
        out[0, i] = bzc
        out[1, i] = bzs
        out[2, i] = bzn
        for stage in range(4):
            f = dt / 6.0 * (1.0 if stage == 0 or stage == 3 else 2.0)
            ak[stage, 0, i] = f * bzc
            ak[stage, 1, i] = f * bzs
            ak[stage, 2, i] = f * bzn
    # backwards through the stages: Y_{s+1} = y + h_s K_s with K_s = f(Y_s) = (-s theta',
    # c theta', nu') at Y_s; the cotangent of the rates and of K in one pass over the nodes
    for stage in range(3, -1, -1):
        y = st[stage]
        a = ak[stage]
        th = sth[stage]
        for i in range(n):
            by[0, i] = th[i] * a[1, i]
            by[1, i] = -(th[i] * a[0, i])
            b_th = -y[1, i] * a[0, i] + y[0, i] * a[1, i]
            b_k[i], by[2, i] = _rate_cotangents(b_th, a[2, i], mass[i], gamma[i], second)
        _coupling_vjp(y[0], y[1], b_k, indptr, indices, w, cl, sl, by[0], by[1], g)
        # by: the cotangent of Y_stage; Y_stage = y + h K_{stage-1} (stage >= 1)
        for i in range(n):
            out[0, i] += by[0, i]
            out[1, i] += by[1, i]
            out[2, i] += by[2, i]
        if stage > 0:
            h = 0.5 * dt if stage < 3 else dt
            prev = ak[stage - 1]
            for i in range(n):
                prev[0, i] += h * by[0, i]
                prev[1, i] += h * by[1, i]
                prev[2, i] += h * by[2, i]


@njit(cache=True)
def _euler_vjp(y, th, lam, out, b_th, b_dnu, b_k, eq, second, dt, g):
    """``out = (d step / d y)^T lam`` (and ``g``) for the Euler step from ``y`` with phase
    rates ``th`` (kept by the replay): a rotation of ``(c_i, s_i)`` by ``a_i = dt theta_i'`` and
    ``nu += dt nu'`` (renormalization: a projection that moves the state by rounding only, taken
    as the identity)."""
    n = th.shape[0]
    for i in range(n):
        ca, sa = _rotation(dt * th[i])
        cn = y[0, i] * ca - y[1, i] * sa
        sn = y[1, i] * ca + y[0, i] * sa
        out[0, i] = ca * lam[0, i] + sa * lam[1, i]
        out[1, i] = -sa * lam[0, i] + ca * lam[1, i]
        out[2, i] = lam[2, i] if second else 0.0
        b_th[i] = dt * (-sn * lam[0, i] + cn * lam[1, i])
        b_dnu[i] = dt * lam[2, i] if second else 0.0
    _rates_vjp(y[0], y[1], b_th, b_dnu, eq, second, out[0], out[1], out[2], g, b_k)


# ---- seeds: the crossing's dependence on the states at both ends of the last step ---------


@njit(cache=True)
def _order_seed(y, coef_r, coef_d, th, b_th, b_dnu, b_k, eq, second, lam, g):
    """``lam += coef_r dR/dy + coef_d d(dR/dt)/dy`` (and ``g``) at ``y`` with rates ``th``."""
    n = th.shape[0]
    tc = 0.0
    ts = 0.0
    dc = 0.0
    ds = 0.0
    for i in range(n):
        tc += y[0, i]
        ts += y[1, i]
        dc -= y[1, i] * th[i]
        ds += y[0, i] * th[i]
    for i in range(n):
        lam[0, i] += coef_r * 2.0 * tc + coef_d * (2.0 * dc + 2.0 * ts * th[i])
        lam[1, i] += coef_r * 2.0 * ts + coef_d * (2.0 * ds - 2.0 * tc * th[i])
        b_th[i] = coef_d * 2.0 * (-tc * y[1, i] + ts * y[0, i])
        b_dnu[i] = 0.0
    if coef_d != 0.0:
        _rates_vjp(y[0], y[1], b_th, b_dnu, eq, second, lam[0], lam[1], lam[2], g, b_k)


@njit(cache=True)
def _deviation_seed(y, node, row, coef_v, coef_r, th, dnu, b_th, b_dnu, b_k, b_kd, eq, second, lam, g):
    """``lam += coef_v d(dev)/dy + coef_r d(rate of dev)/dy`` (and ``g``) for deviation ``row``
    (0: ``theta'_i - mean``, 1: ``g_i - mean``, ``g = (P + K) / gamma``) of node ``node``."""
    _, w, indptr, indices, cl, sl, mass, gamma = eq
    n = th.shape[0]
    for i in range(n):
        sigma = (1.0 if i == node else 0.0) - 1.0 / n
        b_th[i] = 0.0
        b_dnu[i] = 0.0
        b_kd[i] = 0.0
        if row == 0:
            b_th[i] = coef_v * sigma
            # the rate of theta_i': nu_i' with inertia, d K_i/dt / gamma_i without
            if second and mass[i] > 0.0:
                b_dnu[i] = coef_r * sigma
            else:
                b_kd[i] = coef_r * sigma / (gamma[i] if second else 1.0)
        else:
            b_k[i] = coef_v * sigma / gamma[i]
            b_kd[i] = coef_r * sigma / gamma[i]
    if row == 1:
        _coupling_vjp(y[0], y[1], b_k, indptr, indices, w, cl, sl, lam[0], lam[1], g)
    # d K/dt depends on theta' as well: its cotangent joins b_th before the rates' VJP
    _kdot_vjp(y[0], y[1], th, b_kd, indptr, indices, w, cl, sl, lam[0], lam[1], b_th, g)
    _rates_vjp(y[0], y[1], b_th, b_dnu, eq, second, lam[0], lam[1], lam[2], g, b_k)


@njit(inline="always")
def _hermite_basis(x):
    x2 = x * x
    x3 = x2 * x
    return 2 * x3 - 3 * x2 + 1, x3 - 2 * x2 + x, -2 * x3 + 3 * x2, x3 - x2


@njit(inline="always")
def _hermite_slope(x):
    return 6 * x * x - 6 * x, 3 * x * x - 4 * x + 1, -6 * x * x + 6 * x, 3 * x * x - 2 * x


@njit(inline="always")
def _seed_coefficients(f, x, dt, rk4):
    """``-f dH/d(y0, rate0, y1, rate1)`` of the interpolant at ``x`` (Hermite for RK4, whose
    end slopes are dt times the rates; the straight line for Euler): the seeds of the crossing
    ``x`` with ``f = dt / H_x``."""
    if rk4:
        h00, h10, h01, h11 = _hermite_basis(x)
        return -f * h00, -f * h10 * dt, -f * h01, -f * h11 * dt
    return -f * (1.0 - x), 0.0, -f * x, 0.0


# ---- one trajectory ---------------------------------------------------------------------


@njit(cache=True)
def _advance(y, th, dnu, work, eq, second, dt, rk4, step):
    """One step of :func:`~antisync.kernels.core.make_model_kernels`' ``sync_steps`` (the same
    operations: the states are bit for bit the driver's); ``th``/``dnu`` current on entry and exit."""
    if rk4:
        _rk4_step(y[0], y[1], y[2], th, dnu, work, eq, second, dt)
    else:
        _euler_step(y[0], y[1], y[2], th, dnu, dt, second)
        if step % RENORM_EVERY == 0:
            _renormalize(y[0], y[1])
    _rhs(y[0], y[1], y[2], eq, second, th, dnu)


@njit(cache=True)
def _forward(y, th, dnu, work, eq, second, dt, rk4, criterion, target, max_steps, every):
    """``(status, steps, x, ck)``: :func:`~antisync.kernels.core.make_model_kernels`'
    ``sync_steps`` from ``y`` (bit for bit), with ``ck[c]`` the state after ``c every`` steps
    for every ``c every < steps`` (``y`` ends at the last state reached).

    RK4 runs ``sync_steps`` in pieces of ``every`` steps, each from the state where the last one
    stopped: a call recomputes at its start exactly the rates, ``R`` and deviations that the
    step before computed at its end, so the pieces are the one call's operations, and the
    states are stored on the way. (A piece cannot find its start already in the band: the
    piece before would have found the crossing at ``x <= 1`` of its last step.) Euler counts its
    renormalizations from the call's start, so it integrates once to find ``steps`` and once
    more to store the states."""
    n = th.shape[0]
    y0 = y.copy()  # Euler's second pass starts here again
    length = every if rk4 else max_steps  # Euler: one piece
    ck = np.empty((16 if rk4 else 0, 3, n))
    done = 0
    while True:
        if rk4:
            c = done // every
            if c == ck.shape[0]:
                ck = doubled(ck)
            for row in range(3):
                for i in range(n):
                    ck[c, row, i] = y[row, i]
        piece = min(length, max_steps - done)
        st, k, x = _sync(y[0], y[1], y[2], th, dnu, work, eq, dt, rk4, criterion, target, piece)
        # SYNCED, ALREADY_SYNCED (at done = 0 only), or NOT_SYNCED at the step cap
        if st != NOT_SYNCED or done + piece >= max_steps:
            break
        done += piece
    k += done
    if rk4 or st != SYNCED:
        return st, k, x, ck
    ck = np.empty(((k - 1) // every + 1, 3, n))
    copy_into(y, y0)
    _rhs(y[0], y[1], y[2], eq, second, th, dnu)
    for step in range(k):
        if step % every == 0:
            copy_into(ck[step // every], y)
        if step < k - 1:
            _advance(y, th, dnu, work, eq, second, dt, rk4, step + 1)
    return st, k, x, ck


@njit(cache=True)
def _model_adjoint(y0, eq, dt, rk4, criterion, target, max_steps, every, g):
    """``(status, steps, x, coef_target)`` of one trajectory from ``y0`` and, when it synchronizes,
    ``g[p] = d tau0 / d w_p``; ``coef_target = d tau0 / d target`` (for the relative criterion).
    ``eq``: the equations' constants ``(p, w, indptr, indices, cl, sl, mass, gamma)`` of
    :func:`~antisync.kernels.core.make_model_kernels`."""
    mass, gamma = eq[6], eq[7]
    n = y0.shape[1]
    second = has_inertia(mass)
    freq = criterion == CRIT_FREQUENCY
    y = y0.copy()
    th = np.empty(n)
    dnu = np.zeros(n)
    work = np.empty((WORK_ROWS, n))
    st, k, x, ck = _forward(y, th, dnu, work, eq, second, dt, rk4, criterion, target, max_steps, every)
    for q in range(g.shape[0]):
        g[q] = 0.0
    if st != SYNCED:
        return st, k, x, 0.0
    n_ck = (k - 1) // every + 1
    # y: state k - 1 (from its checkpoint); y1: state k
    copy_into(y, ck[n_ck - 1])
    _rhs(y[0], y[1], y[2], eq, second, th, dnu)
    for step in range((n_ck - 1) * every, k - 1):
        _advance(y, th, dnu, work, eq, second, dt, rk4, step + 1)
    y1 = y.copy()
    th1 = np.empty(n)
    dnu1 = np.zeros(n)
    copy_into(th1, th)
    copy_into(dnu1, dnu)
    _advance(y1, th1, dnu1, work, eq, second, dt, rk4, k)
    lam = np.zeros((3, n))  # the cotangent of state k
    lam0 = np.zeros((3, n))  # the seed at state k - 1
    b_th = np.empty(n)
    b_dnu = np.empty(n)
    b_k = np.empty(n)
    b_kd = np.empty(n)
    coef_target = 0.0
    if not freq:
        r0 = 0.0
        r1 = 0.0
        tc0 = 0.0
        ts0 = 0.0
        tc1 = 0.0
        ts1 = 0.0
        for i in range(n):
            tc0 += y[0, i]
            ts0 += y[1, i]
            tc1 += y1[0, i]
            ts1 += y1[1, i]
        r0 = tc0 * tc0 + ts0 * ts0
        r1 = tc1 * tc1 + ts1 * ts1
        if rk4:
            d0, _ = _measure(y[0], y[1], th, dnu, mass, gamma, second)
            d1, _ = _measure(y1[0], y1[1], th1, dnu1, mass, gamma, second)
            s00, s10, s01, s11 = _hermite_slope(x)
            hx = s00 * r0 + s10 * dt * d0 + s01 * r1 + s11 * dt * d1
            # tau = dt (k - 1 + x): d tau = dt (dT - sum H_a da) / H_x
            f = dt / hx
        else:
            f = dt / (r1 - r0)
        c0, d0c, c1, d1c = _seed_coefficients(f, x, dt, rk4)
        _order_seed(y, c0, d0c, th, b_th, b_dnu, b_k, eq, second, lam0, g)
        _order_seed(y1, c1, d1c, th1, b_th, b_dnu, b_k, eq, second, lam, g)
        coef_target = f
    else:
        # the active deviation at x: the one nearest the band's edge
        w0 = np.empty((WORK_ROWS, n))
        _deviations(y[0], y[1], th, dnu, eq, second, w0)
        _deviations(y1[0], y1[1], th1, dnu1, eq, second, work)
        h00, h10, h01, h11 = _hermite_basis(x)
        s00, s10, s01, s11 = _hermite_slope(x)
        best = -1.0
        node = np.int64(0)  # not 0: see antisync.kernels.shared.has_inertia
        row = np.int64(0)
        slope = 0.0
        rows = 2 if second else 1
        for rr in range(rows):
            for i in range(n):
                a0 = w0[DEV_ROW + 2 * rr, i]
                a1 = work[DEV_ROW + 2 * rr, i]
                if rk4:
                    m0 = dt * w0[DEV_ROW + 2 * rr + 1, i]
                    m1 = dt * work[DEV_ROW + 2 * rr + 1, i]
                    v = h00 * a0 + h10 * m0 + h01 * a1 + h11 * m1
                    sl_ = s00 * a0 + s10 * m0 + s01 * a1 + s11 * m1
                else:
                    v = (1.0 - x) * a0 + x * a1
                    sl_ = a1 - a0
                if abs(v) > best:
                    best = abs(v)
                    node = i
                    row = rr
                    slope = sl_
        c0, d0c, c1, d1c = _seed_coefficients(dt / slope, x, dt, rk4)
        _deviation_seed(y, node, row, c0, d0c, th, dnu, b_th, b_dnu, b_k, b_kd, eq, second, lam0, g)
        _deviation_seed(y1, node, row, c1, d1c, th1, dnu1, b_th, b_dnu, b_k, b_kd, eq, second, lam, g)
    # backwards over the steps k .. 1, segment by segment from the checkpoints: each segment is
    # replayed forward keeping what its steps' adjoints need (RK4: the stage states and rates,
    # Euler: the states and rates), then walked backwards
    seg = np.empty((0 if rk4 else every, 3, n))
    seg_th = np.empty((0 if rk4 else every, n))
    rec_st = np.empty((every if rk4 else 0, 4, 3, n))
    rec_th = np.empty((every if rk4 else 0, 4, n))
    kst = np.empty((3, 4, n))
    out = np.empty((3, n))
    ak = np.empty((4, 3, n))
    by = np.empty((3, n))
    first_seed = True
    for c_idx in range(n_ck - 1, -1, -1):
        lo = c_idx * every
        hi = min(k, lo + every)  # steps lo+1 .. hi start from states lo .. hi-1
        copy_into(y, ck[c_idx])
        _rhs(y[0], y[1], y[2], eq, second, th, dnu)
        for j in range(lo, hi):
            if rk4:
                _rk4_record(y, rec_st[j - lo], rec_th[j - lo], kst, th, dnu, eq, second, dt)
            else:
                copy_into(seg[j - lo], y)
                copy_into(seg_th[j - lo], th)
                if j < hi - 1:
                    _advance(y, th, dnu, work, eq, second, dt, rk4, j + 1)
        for j in range(hi - 1, lo - 1, -1):
            # the step j -> j + 1
            if rk4:
                _rk4_vjp(rec_st[j - lo], rec_th[j - lo], lam, out, ak, by, b_k, eq, second, dt, g)
            else:
                _euler_vjp(seg[j - lo], seg_th[j - lo], lam, out, b_th, b_dnu, b_k, eq, second, dt, g)
            copy_into(lam, out)
            if first_seed:  # state k - 1: add the crossing's seed there
                first_seed = False
                lam += lam0
    return st, k, x, coef_target


@njit(cache=True)
def _adjoint_item(ks, seed, graph, model, dt, rk4, criterion, target, max_steps, every, out, r):
    """:func:`_model_adjoint` of realization ``r``: ``graph`` ``(indptr, indices, w)``, ``model``
    ``(freqs, starts, cl, sl, mass, gamma)`` (a row of ``freqs`` each, or one for all; ``starts``
    as :func:`~antisync.physics.phases.start_phase` takes them), results into ``out``
    ``(status0, steps0, frac0, grad, coef_t)``; every realization in parallel by
    :func:`_adjoint_items`."""
    indptr, indices, w = graph
    freqs, starts, cl, sl, mass, gamma = model
    status0, steps0, frac0, grad, coef_t = out
    n = indptr.shape[0] - 1
    y0 = np.zeros((3, n))
    for i in range(n):
        theta = start_phase(starts, seed, ks[r], r, i)
        y0[0, i] = np.cos(theta)
        y0[1, i] = np.sin(theta)
    p = freqs[r] if freqs.shape[0] > 1 else freqs[0]
    eq = (p, w, indptr, indices, cl, sl, mass, gamma)
    st, k, x, ct = _model_adjoint(y0, eq, dt, rk4, criterion, target, max_steps, every, grad[r])
    status0[r] = st
    steps0[r] = k
    frac0[r] = x
    coef_t[r] = ct


def _adjoint_items(item, ks, seed, graph, model, dt, rk4, criterion, target, max_steps, every, out):
    """``item`` (:func:`_adjoint_item`) of every realization, in parallel (compiled by
    :func:`antisync.kernels.loops.run`)."""
    for r in prange(ks.shape[0]):
        item(ks, seed, graph, model, dt, rk4, criterion, target, max_steps, every, out, np.int64(r))


def simulate_model_adjoint(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    weights: np.ndarray,
    deriv,
    params,
    *,
    dt: float,
    max_steps: int,
    integrator: str = "rk4",
    dtarget: np.ndarray | None = None,
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    every: int = 64,
) -> PathwiseResult:
    """Undamaged trajectories of a generalized model and ``d tau0 / d beta_e`` for every link.

    Parameters
    ----------
    seed, first, count, realizations, threads
        As in :func:`antisync.kernels.cpu.simulate_model`.
    indptr, indices, weights
        CSR form of the undamaged ``W``.
    deriv : LinkDerivatives
        ``dW/dbeta_e`` of each link (:func:`antisync.kernels.adjoint.link_derivatives`).
    params : ModelParams
        The model (:class:`antisync.kernels.model_steps.ModelParams`); ``params.targets[0]`` is
        the undamaged network's target.
    dtarget : array (E,), optional
        ``d target / d beta_e`` (the relative criterion's ``(fraction r* N)^2`` moves with the
        damage); ``None``: targets that do not depend on ``W``.
    every : int
        Steps between checkpoints (memory only, never the results).

    Returns
    -------
    PathwiseResult
        ``status0``, ``steps0``, ``frac0`` as the model driver's (bit for bit) and ``dtau``
        ``(m, E)``, 0 where the trajectory did not synchronize.
    """
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    ks = realization_ids(first, count, realizations)
    m = ks.size
    n = indptr.size - 1
    w = np.ascontiguousarray(weights, dtype=np.float64)
    freqs = np.ascontiguousarray(params.freqs, dtype=np.float64)
    starts = batch_starts(params, m, n)
    status0 = np.empty(m, dtype=np.int8)
    steps0 = np.empty(m, dtype=np.int64)
    frac0 = np.empty(m)
    grad = np.zeros((m, w.size))
    coef_t = np.zeros(m)
    with Threads(threads):
        loops.run(
            _adjoint_items,
            _adjoint_item,
            ks,
            np.uint64(seed),
            (indptr.astype(np.int64), indices.astype(np.int64), w),
            (
                freqs,
                starts,
                float(params.cos_lag),
                float(params.sin_lag),
                per_node(params.inertia, n),
                per_node(params.damping, n),
            ),
            float(dt),
            integrator == "rk4",
            int(params.criterion),
            float(params.targets[0]),
            int(max_steps),
            int(every),
            (status0, steps0, frac0, grad, coef_t),
        )
    n_edges = deriv.indptr.size - 1
    dtau = np.zeros((m, n_edges))
    for e in range(n_edges):
        lo, hi = deriv.indptr[e], deriv.indptr[e + 1]
        dtau[:, e] = grad[:, deriv.position[lo:hi]] @ deriv.value[lo:hi]
        if dtarget is not None:
            dtau[:, e] += coef_t * dtarget[e]
    dtau[status0 != SYNCED] = 0.0
    return PathwiseResult(status0, steps0, frac0, dtau)
