"""What the generated kernels of a user's law (:mod:`antisync.kernels.law`) use of antisync:
the paper's phases, the crossing on the step's cubic interpolant (its range and points), the
item bookkeeping of the one-trajectory drivers and Rodas4's coefficients, sparse LU and
step-size controller, under one module so a generated file imports one name; and the parallel
loops that run a generated module's item functions, one compiled loop for every law."""

from __future__ import annotations

import numpy as np
from numba import prange

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
from antisync.kernels.shared import record, share_rows, trip_weights
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
    "each_trip",
    "item_of",
    "phase",
    "record",
    "rotation",
    "share_rows",
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
