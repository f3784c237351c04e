"""What the generated kernels of a user's law (:mod:`antisync.kernels.law`) use of antisync:
the paper's phases, the crossing on the step's cubic interpolant (its range and points), the
item bookkeeping of the one-trajectory drivers and Rodas4's coefficients, sparse LU and
step-size controller, under one module so a generated file imports one name."""

from __future__ import annotations

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
