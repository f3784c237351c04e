"""The step functions of the lane state's precision, chosen at compile time.

The CPU drivers are compiled once per argument types: a float32 state (``c``, ``s`` and the
weights) picks the float32 step functions of :func:`~antisync.kernels.core.make_kernels` here, a
float64 state the float64 ones. The float32 drivers run the Euler step with Taylor rotations
only, but numba types every branch: the float64-only steps get an empty float32 body. It is
never reached, because :func:`antisync.kernels.cpu.simulate` refuses float32 with RK4 or without
Taylor rotations; it cannot raise instead, since a raise inside a driver's ``prange`` body would
make numba run the loop serially.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import overload

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels.core import make_kernels

__all__ = ["K32", "K64", "order2", "renormalize", "rk4_vec", "step_lanes", "step_vec", "sync_steps"]

_jit = lambda f: njit(f, inline="always", cache=True)  # noqa: E731
K64 = make_kernels(_jit)
"""The float64 step functions (inlined where they are called)."""
K32 = make_kernels(_jit, np.float32)
"""The float32 step functions."""
_sync64, _sync32 = K64.sync_steps, K32.sync_steps
_step_vec64, _step_vec32 = K64.euler_step_vec, K32.euler_step_vec
_renorm64, _renorm32 = K64.renormalize, K32.renormalize
_order2_64, _order2_32 = K64.order2, K32.order2
_step_lanes64 = K64.euler_step_lanes
_rk4_vec64 = K64.rk4_step_vec


def sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
    """The one-trajectory Euler integration of ``c``'s precision (``Kernels.sync_steps``)."""


@overload(sync_steps)
def _sync_steps_impl(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
    if c.dtype == types.float32:
        return lambda c, s, acc, indptr, indices, weights, dt, r2_target, max_steps: _sync32(
            c, s, acc, indptr, indices, weights, dt, r2_target, max_steps
        )
    return lambda c, s, acc, indptr, indices, weights, dt, r2_target, max_steps: _sync64(
        c, s, acc, indptr, indices, weights, dt, r2_target, max_steps
    )


def step_vec(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2):
    """``Kernels.euler_step_vec`` of ``c``'s precision."""


@overload(step_vec, inline="always")
def _step_vec_impl(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2):
    if c.dtype == types.float32:
        return lambda c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2: _step_vec32(
            c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2
        )
    return lambda c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2: _step_vec64(
        c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2
    )


def renormalize(c, s):
    """``Kernels.renormalize`` of ``c``'s precision."""


@overload(renormalize, inline="always")
def _renormalize_impl(c, s):
    if c.dtype == types.float32:
        return lambda c, s: _renorm32(c, s)
    return lambda c, s: _renorm64(c, s)


def order2(c, s):
    """``Kernels.order2`` of ``c``'s precision."""


@overload(order2)
def _order2_impl(c, s):
    if c.dtype == types.float32:
        return lambda c, s: _order2_32(c, s)
    return lambda c, s: _order2_64(c, s)


def step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
    """``Kernels.euler_step_lanes`` (float64 only)."""


@overload(step_lanes, inline="always")
def _step_lanes_impl(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
    if c.dtype == types.float32:

        def unavailable(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
            pass  # never called (see the module docstring)

        return unavailable
    return lambda c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor: _step_lanes64(
        c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor
    )


def rk4_vec(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
    """``Kernels.rk4_step_vec`` (float64 only)."""


@overload(rk4_vec, inline="always")
def _rk4_vec_impl(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
    if c.dtype == types.float32:

        def unavailable(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
            pass  # never called (see the module docstring)

        return unavailable
    return lambda c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2: _rk4_vec64(
        c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2
    )
