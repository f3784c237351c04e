"""What the generated kernels of a user's law (:mod:`antisync.kernels.law`) use of antisync:
the paper's phases, the crossing on the step's cubic interpolant (its range and points), the
item bookkeeping of the one-trajectory drivers and Rodas4's coefficients, sparse LU and
step-size controller, under one module so a generated file imports one name; the frequency
criterion's crossing and a line trip's settling clock on a law's deviations; and the parallel
loops that run a generated module's item functions. What is here compiles once for every law."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from antisync.kernels import implicit, loops
from antisync.kernels.core import (
    DENSE_POINTS,
    RENORM_EVERY,
    TAYLOR_MAX_ANGLE,
    VEC,
    vany_outside,
    vload,
    vsplat,
    vsqrt,
    vstore,
)
from antisync.kernels.lanes import item_of
from antisync.kernels.model_steps import MK
from antisync.kernels.precision import K64
from antisync.kernels.shared import copy_into, record, share_rows, trip_weights
from antisync.physics.phases import phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = [
    "ALREADY_SYNCED",
    "DENSE_POINTS",
    "NOT_SYNCED",
    "RENORM_EVERY",
    "SYNCED",
    "TAYLOR_MAX_ANGLE",
    "VEC",
    "each_group",
    "each_item",
    "each_realization",
    "dev_ends",
    "each_trip",
    "frequency_crossing",
    "hermite",
    "item_of",
    "law_binding",
    "law_crossing_weights",
    "law_deviation",
    "near_step",
    "phase",
    "record",
    "rotation",
    "share_rows",
    "taylor_rotation",
    "trip_clock",
    "trip_keep",
    "trip_weights",
    "vany_outside",
    "vload",
    "vsplat",
    "vsqrt",
    "vstore",
]

rotation = K64.rotation
taylor_rotation = K64.taylor_rotation
hermite = MK.hermite
hermite_range = MK.hermite_range
factor = implicit._factor
solve = implicit._solve
on_the_grid = implicit._on_the_grid
shrunk = implicit._shrunk
trip_swing = implicit.trip_swing
RA = implicit._A
RC = implicit._C
RGAMMA = implicit._GAMMA
H_FLOOR = implicit._H_FLOOR
MAX_REJECTS = implicit._MAX_REJECTS
SHRINK = implicit._SHRINK
SAFETY = implicit._SAFETY
GROW = implicit._GROW
BETA1 = implicit._BETA1
BETA2 = implicit._BETA2
CROSSING_RTOL = implicit._CROSSING_RTOL
REFINE = implicit._REFINE
NEAR = implicit._NEAR
BAND = implicit._BAND


@njit(cache=True, error_model="numpy")
def order_crossing(r0, d0, r1, d1, dt, rk4, target):
    """The built-in kernels' ``order_crossing`` (inlined here), compiled once for every law: the
    generated modules call it, where each of its call sites in a module inlined it again."""
    return MK.order_crossing(r0, d0, r1, d1, dt, rk4, target)


# -- the frequency criterion's crossing and a trip's settling clock, one compile for every law ---
#
# The law's frequency quantities are rows 2 k of D (k < D.shape[0] // 2, the law's KF), their rates
# rows 2 k + 1: nothing here depends on the law but that count, so these are compiled once for
# every law (in a generated module each was a compile of its own per law and per literal flag).


@njit(cache=True, error_model="numpy")
def dev_ends(D, Dp, row, i, dt, rk4):
    """(y0, m0, y1, m1) of deviation row at node i over the last step: RK4's Hermite data, or
    Euler's straight line."""
    y0 = Dp[row, i]
    y1 = D[row, i]
    if rk4:
        return y0, dt * Dp[row + 1, i], y1, dt * D[row + 1, i]
    return y0, y1 - y0, y1, y1 - y0


@njit(cache=True, error_model="numpy")
def law_deviation(D, Dp, n, dt, rk4, x):
    """The largest |deviation| of the frequency criterion's quantities at x of the last step's
    interpolants (x = 1: the step's end, exactly; a NaN kept: never synchronized)."""
    dev = 0.0
    for i in range(n):
        for k in range(D.shape[0] // 2):
            y0, m0, y1, m1 = dev_ends(D, Dp, 2 * k, i, dt, rk4)
            d = abs(hermite(y0, m0, y1, m1, x))
            if not (d <= dev or dev != dev):
                dev = d
    return dev


@njit(cache=True, error_model="numpy")
def frequency_crossing(D, Dp, n, dt, rk4, target):
    """First x in (0, 1] of the last step where every interpolated deviation is below target,
    or -1 (the built-in kernels' frequency_crossing on the law's quantities)."""
    for i in range(n):
        for k in range(D.shape[0] // 2):
            y0, m0, y1, m1 = dev_ends(D, Dp, 2 * k, i, dt, rk4)
            lo, hi = hermite_range(y0, m0, y1, m1)
            if lo >= target or hi <= -target:
                return -1.0  # this deviation stays out of the band for the whole step
    a = 0.0
    for point in range(1, DENSE_POINTS + 1):
        b = point / DENSE_POINTS
        if law_deviation(D, Dp, n, dt, rk4, b) < target:
            for _ in range(60):
                x = 0.5 * (a + b)
                if law_deviation(D, Dp, n, dt, rk4, x) < target:
                    b = x
                else:
                    a = x
            return b
        a = b
    return -1.0


@njit(cache=True, error_model="numpy")
def near_step(D, n, target):
    """The longest step once every deviation is within BAND times the tolerance: NEAR of the
    tolerance over the fastest deviation's rate (inf while one is farther)."""
    fastest = 0.0
    for k in range(D.shape[0] // 2):
        for i in range(n):
            if abs(D[2 * k, i]) > BAND * target:
                return np.inf
            fastest = max(fastest, abs(D[2 * k + 1, i]))
    return NEAR * target / fastest if fastest > 0.0 else np.inf


@njit(cache=True, error_model="numpy")
def law_binding(D, Dp, n, dt, rk4, x):
    """(k, i) of the deviation whose interpolant is farthest from 0 at x (the one that sets
    the frequency criterion's crossing there)."""
    best, bk, bi = -1.0, 0, 0
    for i in range(n):
        for k in range(D.shape[0] // 2):
            y0, m0, y1, m1 = dev_ends(D, Dp, 2 * k, i, dt, rk4)
            d = abs(hermite(y0, m0, y1, m1, x))
            if d > best:
                best, bk, bi = d, k, i
    return bk, bi


@njit(cache=True, error_model="numpy")
def law_crossing_weights(r0, d0, r1, d1, dt, rk4, x):
    """d tau / d(H's data) of the crossing H(x) = target on the last step (tau = (steps - 1 + x)
    dt), H the cubic Hermite interpolant of (r0, dt d0, r1, dt d1), or Euler's straight line:
    the weights of r0, d0, r1 and d1, and d tau / d target."""
    if rk4:
        m0 = dt * d0
        m1 = dt * d1
        x2 = x * x
        x3 = x2 * x
        h_r0 = 2 * x3 - 3 * x2 + 1
        h_m0 = x3 - 2 * x2 + x
        h_r1 = -2 * x3 + 3 * x2
        h_m1 = x3 - x2
        h_x = (6 * x2 - 6 * x) * r0 + (3 * x2 - 4 * x + 1) * m0
        h_x += (-6 * x2 + 6 * x) * r1 + (3 * x2 - 2 * x) * m1
    else:
        h_r0 = 1.0 - x
        h_m0 = 0.0
        h_r1 = x
        h_m1 = 0.0
        h_x = r1 - r0
    c = -dt / h_x
    return c * h_r0, c * h_m0 * dt, c * h_r1, c * h_m1 * dt, -c


@njit(cache=True, error_model="numpy")
def trip_clock(D, Dp, n, t_prev, step, tol, settle, start):
    """The settling clock of a line trip (antisync.kernels.implicit's trip_switch and trip_band
    on the law's deviations). With start, at the first state of a configuration (D): nan when a
    deviation is out of the band, else the time from which they have all been in it. After a
    step: nan when one is out of the band at its end, else the time the interpolants entered it
    (located in the step) or, after an excursion out of it inside the step, the step's end."""
    if start:
        dev = law_deviation(D, D, n, step, False, 1.0)
        if not dev < tol:
            return np.nan
        return t_prev if settle != settle else settle
    dev = law_deviation(D, Dp, n, step, True, 1.0)
    if not dev < tol:
        return np.nan
    if settle != settle:
        x = frequency_crossing(D, Dp, n, step, True, tol)
        return t_prev + (x if x >= 0.0 else 1.0) * step
    for i in range(n):
        for k in range(D.shape[0] // 2):
            y0, m0, y1, m1 = dev_ends(D, Dp, 2 * k, i, step, True)
            lo, hi = hermite_range(y0, m0, y1, m1)
            if hi >= tol or lo <= -tol:
                return t_prev + step
    return settle


@njit(cache=True, error_model="numpy")
def trip_keep(T):
    """T's values at the step's start kept (before the step's end is evaluated into T)."""
    D, Dp, Q, Qp, ph, dph, u, p_ph, p_dph, p_u = T
    copy_into(Dp, D)
    copy_into(Qp, Q)
    copy_into(p_u, u)
    copy_into(p_ph, ph)
    copy_into(p_dph, dph)


# -- the parallel loops, one for every law (antisync.kernels.loops) ------------------------------
#
# Each runs a generated module's function for one item on the numba threads, the item's index its
# last argument: the loop is compiled once per argument types for every law, not once per law
# and kind inside the generated module (there each loop was a compile of its own, 2-6 s cold).


def _items(fn, inputs, clock, plan, jperm, outputs):
    count = inputs[0].shape[0] * (inputs[5].shape[0] + 1)  # realizations x (variants + base)
    for i in prange(count):
        fn(*inputs, clock, plan, jperm, *outputs, np.int64(i))


def _groups(fn, inputs, clock, outputs, sizes):
    for i in prange(sizes[0]):
        fn(*inputs, clock, *outputs, *sizes, np.int64(i))


def _realizations(fn, args):
    for i in prange(args[0].shape[0]):
        fn(*args, np.int64(i))


def _trips(fn, inputs, tols, plan, jperm, out):
    for i in prange(inputs[5].shape[0]):
        fn(*inputs, tols, plan, jperm, out, np.int64(i))


def each_item(fn, inputs, clock, plan, jperm, outputs) -> None:
    """``law_item_<kind>`` (``fn``) on every item of a batch: ``inputs`` ``(ks, seed, indptr,
    indices, base_w, var_w, var_is_base, todo, PR, targets)``, ``outputs`` ``(status0, steps0,
    frac0, status, steps, frac, collapsed)``."""
    loops.run(_items, fn, inputs, clock, plan, jperm, outputs, spread=(0, 4))


def each_group(fn, inputs, clock, outputs, sizes) -> None:
    """A lane driver (``law_items_lanes...``, ``fn``) on every group: ``inputs`` as
    :func:`each_item`'s, ``outputs`` without ``collapsed``, ``sizes`` ``(n_groups, L)``."""
    loops.run(_groups, fn, inputs, clock, outputs, sizes, spread=(0, 2, 3))


def each_realization(fn, args) -> None:
    """``law_adjoint_item`` or its frequency twin (``fn``) on every realization of ``args``
    (its arguments but the index; ``args[0]`` the realizations ``ks``)."""
    loops.run(_realizations, fn, args, spread=(0,))


def each_trip(fn, inputs, tols, plan, jperm, out) -> None:
    """``law_one_trip_<kind>`` (``fn``) on every trip: ``inputs`` ``(y0, indptr, indices, P, k,
    ta, tb, keep, t_clear, t_after, dt)``."""
    loops.run(_trips, fn, inputs, tols, plan, jperm, out, spread=(0,))
