"""A line trip from the operating point (the engineer's N-1, :mod:`antisync.grids.trip`): the
kernels that integrate it, RK4 at a fixed step and Rodas4 with adaptive steps, both with the model
kernels' steps and frequency criterion.

A trip is the swing equation (:func:`~antisync.kernels.core.make_model_kernels`' model without
phase lag) on the weights ``w_fault`` (a bolted fault at the line's first bus: its lines carry
nothing) until ``t_clear``, then on ``w_post`` (the line out, or the share of it a contingency
opens) until ``t_end``, from the operating point at rest. Each kernel gives ``out = [settle_time,
max_frequency, max_angle, failed]``:

- ``settle_time``: the time (from ``t = 0``, the fault's start) from which the frequency criterion
  of ``sync: {criterion: frequency}`` has held until ``t_end``: every ``|theta_i' - mean|`` and,
  with inertia, every ``|g_i - mean g|`` (``g_i = (P_i + coupling_i) / gamma_i``, the frequency
  node ``i`` relaxes to) below the tolerance, on the steps' cubic Hermite interpolants
  (:func:`~antisync.kernels.implicit.trip_band`); ``nan`` where it does not hold at ``t_end``;
- ``max_frequency``, ``max_angle``: the largest ``|theta_i'|`` and line angle difference over the
  interpolants (:func:`~antisync.kernels.implicit.trip_swing`), the first swing;
- ``failed``: 1 where the integration broke down (Rodas4's step size collapsed; RK4's state stopped
  being finite).

:func:`integrate_trips` runs one trip per item (a line, its share and its clearing time) on
the numba threads, :func:`trip_item` for each.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import loops
from antisync.kernels.core import DEV_PREV_ROW, DEV_ROW, WORK_ROWS
from antisync.kernels.implicit import (
    plan_of_pattern,
    rodas4_trip,
    trip_band,
    trip_rates,
    trip_swing,
    trip_switch,
)
from antisync.kernels.model_steps import MK
from antisync.kernels.shared import Threads, has_inertia, trip_weights

__all__ = ["INTEGRATORS", "integrate_trips", "rk4_trip", "trip_item"]

#: The integrators a trip runs on (the dispatch table's ``trip`` row; ``euler`` is refused
#: there: a first-order step would under-resolve the first swing).
INTEGRATORS = ("rk4", "rodas4")

_rhs = MK.rhs
_rk4_step = MK.rk4_step
_copy_rows = MK.copy_rows


@njit(cache=True)
def rk4_trip(th0, grid, w_fault, w_post, t_clear, t_end, dt, tol, line, out):
    """A contingency (module docstring) by the model kernels' classical RK4 on ``(cos, sin,
    nu)`` (:func:`~antisync.kernels.core.make_model_kernels`' ``rk4_step``) at the step ``dt``:
    ``ceil(t_clear / dt)`` steps with the fault, the last one ending at ``t_clear``, then
    ``ceil((t_end - t_clear) / dt)`` without, the last one ending at ``t_end``. The phases are
    followed unwrapped (each step's rotation of ``(cos, sin)``, well below pi per step at any
    stable ``dt``) for the line angle differences. ``grid``: ``(p, indptr, indices, mass,
    gamma)``; ``line``: ``(a, b, keep)``."""
    p, indptr, indices, mass, gamma = grid
    n = th0.shape[0]
    second = has_inertia(mass)
    c = np.cos(th0)
    s = np.sin(th0)
    nu = np.zeros(n)
    th = np.empty(n)
    dnu = np.zeros(n)
    u = th0.copy()  # the unwrapped phases
    acc = np.empty(n)
    p_u = np.empty(n)  # the phases, speeds, their rates, cos and sin at the step's start
    p_f = np.empty(n)
    p_acc = np.empty(n)
    p_c = np.empty(n)
    p_s = np.empty(n)
    work = np.zeros((WORK_ROWS, n))
    fault = t_clear > 0.0
    settle = np.nan
    max_f = 0.0
    max_a = 0.0
    t = 0.0
    failed = 0.0
    for phase in range(2):
        if phase == 0 and not fault:
            continue
        w = w_fault if phase == 0 else w_post
        eq = (p, w, indptr, indices, 1.0, 0.0, mass, gamma)
        # the rates at this state in the configuration that holds from it on
        _rhs(c, s, nu, eq, second, th, dnu)
        trip_rates(c, s, th, dnu, eq, second, gamma, acc, work)
        settle = trip_switch(work, n, second, tol, t, settle)
        t0 = t
        length = t_clear if phase == 0 else t_end - t_clear
        steps = max(1, int(math.ceil(length / dt - 1e-9)))
        for k in range(steps):
            h = dt if k < steps - 1 else length - (steps - 1) * dt
            for i in range(n):
                p_u[i] = u[i]
                p_f[i] = th[i]
                p_acc[i] = acc[i]
                p_c[i] = c[i]
                p_s[i] = s[i]
            _copy_rows(work, DEV_PREV_ROW, DEV_ROW, 4)
            _rk4_step(c, s, nu, th, dnu, work, eq, second, h)
            for i in range(n):
                u[i] += math.atan2(s[i] * p_c[i] - c[i] * p_s[i], c[i] * p_c[i] + s[i] * p_s[i])
            t_prev = t
            t = t0 + (k + 1) * dt if k < steps - 1 else t0 + length
            _rhs(c, s, nu, eq, second, th, dnu)
            trip_rates(c, s, th, dnu, eq, second, gamma, acc, work)
            max_f, max_a = trip_swing(
                p_u, p_f, p_f, p_acc, u, th, th, acc, t - t_prev, indptr, indices, line, max_f, max_a
            )
            settle = trip_band(work, n, second, t_prev, t - t_prev, tol, settle)
            total = 0.0
            for i in range(n):
                total += c[i] + nu[i]
            if not math.isfinite(total):
                failed = 1.0  # the step is unstable for this grid
                break
        if failed:
            break
    out[0] = settle if not failed else np.nan
    out[1] = max_f
    out[2] = max_a
    out[3] = failed


@njit(cache=True)
def trip_item(theta0, graph, k, trips, t_after, h0, tols, plan, rodas4, out, e):
    """Trip ``e`` of ``trips = (ta, tb, keep, t_clear)`` (the line ``ta-tb``, the share ``1 -
    keep`` of its ``K`` the trip takes, the fault's duration) from ``theta0``, for ``t_after``
    seconds after its trip: :func:`rk4_trip` at the step ``h0`` or, with ``rodas4``,
    :func:`~antisync.kernels.implicit.rodas4_trip` from the first step ``h0``; ``graph = (p,
    indptr, indices, mass, gamma)``, ``tols = (band, rtol, atol)``; ``out`` one row of four per
    trip (module docstring). Every trip in parallel: :func:`integrate_trips`."""
    _, indptr, indices, _, _ = graph
    ta, tb, keep, t_clear = trips
    w_fault, w_post = trip_weights(k, indptr, indices, ta[e], tb[e], keep[e])
    line = (ta[e], tb[e], keep[e])
    t_end = t_clear[e] + t_after
    if rodas4:
        rodas4_trip(theta0, graph, w_fault, w_post, t_clear[e], t_end, h0, tols, plan, line, out[e])
    else:
        rk4_trip(theta0, graph, w_fault, w_post, t_clear[e], t_end, h0, tols[0], line, out[e])


def _trips(item, theta0, graph, k, trips, t_after, h0, tols, plan, rodas4, out):
    """``item`` (:func:`trip_item`) of every trip, in parallel (compiled by
    :func:`antisync.kernels.loops.run`)."""
    for e in prange(out.shape[0]):
        item(theta0, graph, k, trips, t_after, h0, tols, plan, rodas4, out, np.int64(e))


def integrate_trips(theta0, grid, k, trips, t_after, h0, tols, integrator, threads=None):
    """:func:`trip_item` of every trip on ``threads`` numba threads, one at a time per thread (a trip
    that does not settle takes many more steps than one that does): the ``(items, 4)`` rows.
    ``grid = (p, indptr, indices, mass, gamma)``, ``k`` the CSR weights, ``trips = (ta, tb,
    keep, t_clear)``, ``integrator`` one of :data:`INTEGRATORS`."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"a trip integrates by {' or '.join(INTEGRATORS)}, not {integrator}")
    _, indptr, indices, _, _ = grid
    plan = plan_of_pattern(indptr, indices)
    # writable C arrays of one type whatever the caller built (a broadcast, a read-only column):
    # one compiled trip_item
    types = (np.int64, np.int64, np.float64, np.float64)
    trips = tuple(np.array(a, dtype=t) for a, t in zip(trips, types, strict=True))
    out = np.empty((trips[0].size, 4))
    with Threads(threads), numba.parallel_chunksize(1):
        args = (theta0, grid, k, trips, float(t_after), float(h0), tols, plan, integrator == "rodas4", out)
        loops.run(_trips, trip_item, *args)
    return out
