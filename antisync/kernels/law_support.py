"""What the generated kernels of a user's law (:mod:`antisync.kernels.law`) use of antisync:
the paper's phases, the crossing on the step's cubic interpolant (its range and points), the
item bookkeeping of the one-trajectory drivers and Rodas4's coefficients, sparse LU and
step-size controller, under one module so a generated file imports one name."""

from __future__ import annotations

import functools

import numba
import numpy as np
from numba import njit, prange, types

from antisync.kernels import implicit
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
from antisync.kernels.shared import record, share_row, trip_weights
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
    "item_of",
    "in_parallel",
    "share_rows",
    "phase",
    "record",
    "rotation",
    "share_row",
    "taylor_rotation",
    "trip_weights",
    "vany_outside",
    "vload",
    "vsplat",
    "vsqrt",
    "vstore",
]

order_crossing = MK.order_crossing
rotation = K64.rotation
taylor_rotation = K64.taylor_rotation
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


# -- the parallel loops, one for every law --------------------------------------------------------
#
# Each runs a generated module's function for one item (a trajectory, a group of lanes, a
# realization's adjoint, a line trip) on the numba threads, the item's index its last argument.
# The function comes in as a first-class function (numba's ``FunctionType``), so that a loop is
# compiled once per argument types for every law, and cached on disk with antisync's kernels,
# instead of once per law and kind inside the generated module (there each loop was a compile of
# its own, 2-6 s cold, re-optimizing the whole integration linked into it). The call through the
# function pointer is once per item, never per step. The arguments come in groups: a tuple in a
# tuple cannot enter a parallel loop (numba's gufunc wrapper refuses it), so the groups that are
# flat tuples are spread into the call and the tuples the function takes whole (a clock, a
# factorization plan, tolerances) come as groups of their own.


def _each(fn, args, count):
    for i in prange(count):
        fn(*args, np.int64(i))


def _each_item(fn, inputs, clock, plan, jperm, outputs, count):
    for i in prange(count):
        fn(*inputs, clock, plan, jperm, *outputs, np.int64(i))


def _each_group(fn, inputs, clock, outputs, sizes, count):
    for i in prange(count):
        fn(*inputs, clock, *outputs, *sizes, np.int64(i))


def _each_trip(fn, inputs, tols, plan, jperm, out, count):
    for i in prange(count):
        fn(*inputs, tols, plan, jperm, out, np.int64(i))


#: each loop: its function, and which of its groups are spread into the call
_LOOPS = {
    "items": (_each_item, (0, 4)),
    "groups": (_each_group, (0, 2, 3)),
    "flat": (_each, (0,)),
    "trips": (_each_trip, (0,)),
}


@functools.cache
def _loop(kind: str, group_types: tuple):
    py_func, spread = _LOOPS[kind]
    call = []
    for k, t in enumerate(group_types):
        call += list(t.types) if k in spread else [t]
    fn = types.FunctionType(types.void(*call, types.int64))
    return njit(types.void(fn, *group_types, types.int64), parallel=True, cache=True, error_model="numpy")(
        py_func
    )


def in_parallel(kind: str, fn, count: int, *groups) -> None:
    """``fn(..., i)`` for ``i`` in ``0 .. count - 1`` on the numba threads, by the loop ``kind``
    (``items``: a trajectory per item, ``groups``: a lane group per item, ``flat``: a flat
    argument list, such as an adjoint's realization, ``trips``: a line trip per item), ``fn``'s
    arguments before the index given as the loop's groups (the ``kind``'s signature in
    :data:`_LOOPS`). The loop is compiled for the groups' types (``numba.typeof``), and ``fn`` for
    its arguments' when it is first passed."""
    _loop(kind, tuple(numba.typeof(g) for g in groups))(fn, *groups, count)


def share_rows(var_is_base: np.ndarray, out) -> None:
    """The variants that leave the weights unchanged get the undamaged result (``out`` an
    :class:`~antisync.kernels.shared.Outputs`), as ``share_row`` gives them in a kernel."""
    out.status[:, var_is_base] = out.status0[:, None]
    out.steps[:, var_is_base] = out.steps0[:, None]
    out.frac[:, var_is_base] = out.frac0[:, None]
