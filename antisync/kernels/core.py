"""Step functions written once, compiled for every backend.

:func:`make_kernels` takes a numba decorator (``njit`` for the CPU, ``cuda.jit(device=True)``
for CUDA) and returns the compiled step and sync-time functions, so the mathematics of the
integrator exists in one place (STYLE habit 3).

The state is kept as ``(c_i, s_i) = (cos theta_i, sin theta_i)``. With
``sin(theta_j - theta_i) = s_j c_i - c_j s_i`` the Kuramoto right-hand side (paper Eq. 2)
is ``omega_i = c_i sum_j w_ij s_j - s_i sum_j w_ij c_j``, and the explicit Euler step
``theta_i <- theta_i + dt omega_i`` is exactly a rotation of ``(c_i, s_i)`` by the angle
``alpha_i = dt omega_i``. The rotation's ``cos``/``sin`` are Taylor polynomials, exact to
rounding for ``|alpha| <= 0.05`` (truncation below 1e-16 relative); larger angles fall back to
``math.cos``/``math.sin``. The order parameter ``r = |sum_j (c_j, s_j)| / N`` (Eq. 3) is then
read off without any transcendental call. Every ``RENORM_EVERY`` steps ``(c, s)`` is projected
back to the unit circle so rounding cannot drift.

In single precision (``make_kernels(jit, np.float32)``, the CUDA backend's ``precision:
float32``) the drift is not only random: for ``|alpha| < 2.4e-4`` the Taylor cosine rounds to
exactly 1 in float32, so each rotation lengthens ``(c_i, s_i)`` by ``alpha^2 / 2``, ``r`` reads
high, and over 1024 steps that made float32 cross the threshold one step early in ~12% of
trajectories (lollipop(6,3), dt = 0.001). float32 therefore renormalizes every
``RENORM_EVERY_FLOAT32`` steps, which removes that bias (docs/cuda.md).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, overload, register_model

from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = [
    "CRIT_FREQUENCY",
    "CRIT_ORDER",
    "DENSE_POINTS",
    "RENORM_EVERY",
    "RENORM_EVERY_FLOAT32",
    "TAYLOR_MAX_ANGLE",
    "VEC",
    "WORK_ROWS",
    "F64Vec",
    "Kernels",
    "ModelKernels",
    "lanes_per_vector",
    "make_kernels",
    "make_model_kernels",
    "renorm_interval",
    "vload",
    "vsplat",
    "vsqrt",
    "vstore",
]

RENORM_EVERY = 1024
RENORM_EVERY_FLOAT32 = 64


def renorm_interval(dtype) -> int:
    """Steps between projections of the state back to the unit circle, for ``dtype``."""
    return RENORM_EVERY if dtype == np.float64 else RENORM_EVERY_FLOAT32


TAYLOR_MAX_ANGLE = 0.05


# --- CPU lane vectors -------------------------------------------------------------------
# The lane kernels step VEC trajectories per machine vector. Written as plain loops over the
# lanes, LLVM cannot prove that the state, the weights and the accumulators do not overlap, so
# it either keeps the accumulators in memory behind runtime overlap checks on every edge or
# (with the lane loop unrolled) leaves them scalar (bench/roofline.py, bench/RESULTS.md issue
# 17). ``F64Vec`` is an LLVM ``<VEC x double>`` value: ``vload``/``vstore`` move VEC
# consecutive doubles of a C-contiguous array, ``+ - *`` (with vectors or scalars) are
# lane-wise IEEE operations, so every lane performs exactly the scalar operations of the
# one-trajectory step, in the same order (no fused multiply-add, no reassociation).

VEC = 8
"""Doubles per lane vector (one AVX-512 register, two AVX2 registers); a float32 lane vector
holds the same bytes, ``2 VEC`` floats."""


class _LaneVec(types.Type):
    """Numba type of one machine vector of lanes (an LLVM ``<lanes x element>`` value)."""

    def __init__(self, dtype, lanes, ir_type):
        self.dtype = dtype
        self.lanes = lanes
        self.ir_type = ir_type
        super().__init__(name=f"LaneVec({dtype}, {lanes})")


class F64Vec(_LaneVec):
    """``VEC`` float64 lanes."""

    def __init__(self):
        super().__init__(types.float64, VEC, ir.VectorType(ir.DoubleType(), VEC))


class F32Vec(_LaneVec):
    """``2 VEC`` float32 lanes (the bytes of one :class:`F64Vec`)."""

    def __init__(self):
        super().__init__(types.float32, 2 * VEC, ir.VectorType(ir.FloatType(), 2 * VEC))


f64vec = F64Vec()
f32vec = F32Vec()
_VEC_OF = {types.float64: f64vec, types.float32: f32vec}


def lanes_per_vector(dtype) -> int:
    """Lanes of ``dtype`` (float64 or float32) in one lane vector."""
    return VEC if dtype == np.float64 else 2 * VEC


@register_model(F64Vec)
@register_model(F32Vec)
class _LaneVecModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, fe_type.ir_type)


def _vec_of_array(arr):
    """The lane vector type of a C-contiguous float64/float32 array, else None."""
    if isinstance(arr, types.Array) and arr.layout == "C":
        return _VEC_OF.get(arr.dtype)
    return None


def _vec_pointer(context, builder, arrty, arr, offset, vt):
    data = context.make_array(arrty)(context, builder, arr).data
    return builder.bitcast(builder.gep(data, [offset]), vt.ir_type.as_pointer())


@intrinsic
def vload(typingctx, arr, offset):
    """``arr.flat[offset : offset + lanes]`` as a lane vector (no bounds check)."""
    vt = _vec_of_array(arr)
    if vt is None or not isinstance(offset, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        return builder.load(
            _vec_pointer(context, builder, sig.args[0], args[0], args[1], vt), align=vt.dtype.bitwidth // 8
        )

    return vt(arr, offset), codegen


@intrinsic
def vstore(typingctx, arr, offset, value):
    """``arr.flat[offset : offset + lanes] = value`` (no bounds check)."""
    vt = _vec_of_array(arr)
    if vt is None or not isinstance(offset, types.Integer) or value != vt:
        return None

    def codegen(context, builder, sig, args):
        builder.store(
            args[2],
            _vec_pointer(context, builder, sig.args[0], args[0], args[1], vt),
            align=vt.dtype.bitwidth // 8,
        )
        return context.get_dummy_value()

    return types.none(arr, offset, value), codegen


def _splat(context, builder, x, fromty, vt):
    x = context.cast(builder, x, fromty, vt.dtype)
    one = builder.insert_element(ir.Constant(vt.ir_type, ir.Undefined), x, ir.Constant(ir.IntType(32), 0))
    mask = ir.Constant(ir.VectorType(ir.IntType(32), vt.lanes), [0] * vt.lanes)
    return builder.shuffle_vector(one, ir.Constant(vt.ir_type, ir.Undefined), mask)


@intrinsic
def vsplat(typingctx, x):
    """The scalar ``x`` in every lane: a float32 vector for a float32 ``x``, else float64."""
    if not isinstance(x, (types.Float, types.Integer)):
        return None
    vt = f32vec if x == types.float32 else f64vec

    def codegen(context, builder, sig, args):
        return _splat(context, builder, args[0], sig.args[0], vt)

    return vt(x), codegen


def _vec_binop(instruction):
    @intrinsic
    def binop(typingctx, a, b):
        # a vector and a vector, or a vector and a scalar (converted to the vector's type)
        vt = a if isinstance(a, _LaneVec) else b
        if not isinstance(vt, _LaneVec):
            return None
        for x in (a, b):
            if x != vt and not isinstance(x, (types.Float, types.Integer)):
                return None

        def codegen(context, builder, sig, args):
            x, y = (
                arg if ty == vt else _splat(context, builder, arg, ty, vt)
                for arg, ty in zip(args, sig.args, strict=True)
            )
            return getattr(builder, instruction)(x, y)

        return vt(a, b), codegen

    return binop


def _overload_vec_operator(op, binop):
    @overload(op)
    def _vec_operator(a, b):
        if isinstance(a, _LaneVec) or isinstance(b, _LaneVec):
            return lambda a, b: binop(a, b)
        return None


for _op, _instruction in (
    (operator.add, "fadd"),
    (operator.sub, "fsub"),
    (operator.mul, "fmul"),
    (operator.truediv, "fdiv"),
    (operator.iadd, "fadd"),
    (operator.isub, "fsub"),
    (operator.imul, "fmul"),
):
    _overload_vec_operator(_op, _vec_binop(_instruction))


@intrinsic
def _vneg(typingctx, a):
    if not isinstance(a, _LaneVec):
        return None

    def codegen(context, builder, sig, args):
        return builder.fneg(args[0])

    return a(a), codegen


@overload(operator.neg)
def _vec_neg(a):
    if isinstance(a, _LaneVec):
        return lambda a: _vneg(a)
    return None


def _llvm_vec_fn(builder, vt, name: str):
    """LLVM's lane-wise intrinsic ``llvm.<name>`` (``sqrt``, ``fabs``) for the lane vector
    type ``vt``: one vector in, one out."""
    fnty = ir.FunctionType(vt.ir_type, [vt.ir_type])
    suffix = "f64" if vt.dtype == types.float64 else "f32"
    return cgutils.get_or_insert_function(builder.module, fnty, f"llvm.{name}.v{vt.lanes}{suffix}")


@intrinsic
def vsqrt(typingctx, a):
    """Lane-wise square root (correctly rounded, as ``math.sqrt``)."""
    if not isinstance(a, _LaneVec):
        return None

    def codegen(context, builder, sig, args):
        return builder.call(_llvm_vec_fn(builder, sig.args[0], "sqrt"), args)

    return a(a), codegen


@intrinsic
def vany_outside(typingctx, a, bound):
    """Whether some lane has ``|a| > bound`` or is NaN: the lanes for which ``abs(x) <= bound``
    is False (the Taylor rotation's range test, for a whole vector)."""
    if not isinstance(a, _LaneVec) or not isinstance(bound, (types.Float, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        vt = sig.args[0]
        fabs = _llvm_vec_fn(builder, vt, "fabs")
        outside = builder.fcmp_unordered(
            ">", builder.call(fabs, [args[0]]), _splat(context, builder, args[1], sig.args[1], vt)
        )
        bits = builder.bitcast(outside, ir.IntType(vt.lanes))
        return builder.icmp_unsigned("!=", bits, ir.Constant(ir.IntType(vt.lanes), 0))

    return types.boolean(a, bound), codegen


class Kernels(NamedTuple):
    """The compiled functions of :func:`make_kernels`, by name (see there for each signature).

    Jitted drivers call them as module-level names bound once (``_sync_steps =
    _K.sync_steps``): numba resolves a driver's callees among its module's globals.
    """

    rotation: Callable
    taylor_rotation: Callable
    rotate_by_vec: Callable
    euler_step: Callable
    euler_step_lanes: Callable
    euler_step_vec: Callable
    edge_vec: Callable
    node_sums_vec: Callable
    tangent_step_lanes: Callable
    rk4_step_lanes: Callable
    rk4_step_vec: Callable
    lane_velocity: Callable
    hermite_crossing: Callable
    sync_steps: Callable
    order2: Callable
    renormalize: Callable


def make_kernels(jit, dtype=np.float64) -> Kernels:
    """Compile the integrator's building blocks with ``jit``.

    Parameters
    ----------
    jit : callable
        A numba decorator (``njit(...)`` or ``cuda.jit(device=True)``).
    dtype : numpy floating type, default ``np.float64``
        Type of the state arithmetic of the one-trajectory functions (``rotation``,
        ``euler_step``, ``renormalize``, ``order2``, ``sync_steps``): their literals are
        constants of this type, so with ``np.float32`` (and float32 arrays, ``dt`` and
        ``r2_target``) numba types the step in single precision instead of promoting it to
        double. With ``np.float64`` the constants are the same doubles the literals were, so
        results do not change. ``euler_step_vec`` takes either precision (with float32,
        ``2 VEC`` lanes per machine vector); the other lane, tangent and RK4 functions are for
        float64 only.

    Returns
    -------
    Kernels
        A named tuple of the compiled functions:
        ``rotation(a) -> (cos a, sin a)`` (Taylor polynomials for ``|a| <= 0.05``);
        ``euler_step(c, s, acc, indptr, indices, weights, dt) -> R`` advances one state in
        place and returns ``R = |sum_j e^{i theta_j}|^2``;
        ``sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps)
        -> (status, steps)`` integrates until ``R >= r2_target``;
        ``euler_step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2,
        taylor)`` advances
        ``L`` independent states stored as ``[node, lane]`` (weights ``lw[nnz, lane]``), the
        lane loop innermost so the compiler vectorizes across lanes; ``taylor=True`` promises
        ``|alpha| <= 0.05`` for every node and lane (then results equal ``euler_step``'s bit
        for bit, since the same operations run in the same order);
        ``euler_step_vec(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2)`` is that step
        for ``taylor=True`` on machine vectors (:data:`VEC` float64 or ``2 VEC`` float32 lanes,
        the lane count a multiple of two vectors), fused, the new state written to
        ``(cn, sn)``; the same bits (CPU only);
        ``tangent_step_lanes(...)`` does the same step and its forward sensitivities;
        ``renormalize(c, s)`` projects every ``(c_i, s_i)`` back to the unit circle (the lane
        drivers pass one lane's column, ``renormalize(c[:, q], s[:, q])``).
    """

    # typed constants: closure values are frozen by numba with their numpy type
    zero = dtype(0.0)
    one = dtype(1.0)
    half = dtype(0.5)
    c4 = dtype(1.0 / 24.0)
    c6 = dtype(1.0 / 720.0)
    c8 = dtype(1.0 / 40320.0)
    s3 = dtype(1.0 / 6.0)
    s5 = dtype(1.0 / 120.0)
    s7 = dtype(1.0 / 5040.0)
    s9 = dtype(1.0 / 362880.0)
    max_angle = dtype(TAYLOR_MAX_ANGLE)
    vw = lanes_per_vector(dtype)
    renorm_every = renorm_interval(dtype)

    def taylor_rotation(a):
        a2 = a * a
        # reciprocal factorials multiply (a division costs ~10 multiplications' throughput)
        ca = one - a2 * (half - a2 * (c4 - a2 * (c6 - a2 * c8)))
        sa = a * (one - a2 * (s3 - a2 * (s5 - a2 * (s7 - a2 * s9))))
        return ca, sa

    taylor_rotation = jit(taylor_rotation)

    def rotation(a):
        if abs(a) <= max_angle:
            return taylor_rotation(a)
        return math.cos(a), math.sin(a)

    rotation = jit(rotation)

    def euler_step(c, s, acc, indptr, indices, weights, dt):
        n = c.shape[0]
        for i in range(n):
            sc = zero
            ss = zero
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                w = weights[p]
                sc += w * c[j]
                ss += w * s[j]
            # Eq. (2) in (cos, sin) form: omega_i = c_i sum_j w_ij s_j - s_i sum_j w_ij c_j
            acc[i] = dt * (c[i] * ss - s[i] * sc)
        sum_c = zero
        sum_s = zero
        for i in range(n):
            ca, sa = rotation(acc[i])
            ci = c[i]
            si = s[i]
            c[i] = ci * ca - si * sa
            s[i] = si * ca + ci * sa
            sum_c += c[i]
            sum_s += s[i]
        return sum_c * sum_c + sum_s * sum_s

    euler_step = jit(euler_step)

    def lane_sums(c, s, sum_c, sum_s, acc, lw, indptr, indices, dt):
        """Coupling sums ``sum_j w_ij c_j``, ``sum_j w_ij s_j`` and rotation angles, per lane."""
        n, lanes = c.shape
        for i in range(n):
            for q in range(lanes):
                sum_c[i, q] = 0.0
                sum_s[i, q] = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                for q in range(lanes):
                    w = lw[p, q]
                    sum_c[i, q] += w * c[j, q]
                    sum_s[i, q] += w * s[j, q]
            for q in range(lanes):
                acc[i, q] = dt * (c[i, q] * sum_s[i, q] - s[i, q] * sum_c[i, q])

    lane_sums = jit(lane_sums)

    def lane_rotate(c, s, acc, tot_c, tot_s, r2, taylor):
        """Rotate every ``(c_i, s_i)`` by its angle; ``r2 = |sum_j e^{i theta_j}|^2`` per lane."""
        n, lanes = c.shape
        for q in range(lanes):
            tot_c[q] = 0.0
            tot_s[q] = 0.0
        for i in range(n):
            for q in range(lanes):
                if taylor:
                    ca, sa = taylor_rotation(acc[i, q])
                else:
                    ca, sa = rotation(acc[i, q])
                ci = c[i, q]
                si = s[i, q]
                c[i, q] = ci * ca - si * sa
                s[i, q] = si * ca + ci * sa
                tot_c[q] += c[i, q]
                tot_s[q] += s[i, q]
        for q in range(lanes):
            r2[q] = tot_c[q] * tot_c[q] + tot_s[q] * tot_s[q]

    lane_rotate = jit(lane_rotate)

    def euler_step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, taylor):
        lane_sums(c, s, sum_c, sum_s, acc, lw, indptr, indices, dt)
        lane_rotate(c, s, acc, tot_c, tot_s, r2, taylor)

    euler_step_lanes = jit(euler_step_lanes)

    def rotate_by_vec(ci, si, cn, sn, o, angle):
        """Store ``(ci, si)`` rotated by ``angle`` (Taylor rotation, every lane within its range)
        at ``(cn, sn)[o : o + VEC]``; returns the rotated pair."""
        ca, sa = taylor_rotation(angle)
        x = ci * ca - si * sa
        y = si * ca + ci * sa
        vstore(cn, o, x)
        vstore(sn, o, y)
        return x, y

    rotate_by_vec = jit(rotate_by_vec)

    def rotate_vec(c, s, cn, sn, o, sc, ss, dt):
        """Rotate the lane vector ``(c, s)[o : o + VEC]`` by ``dt (c ss - s sc)`` into ``(cn, sn)``."""
        ci = vload(c, o)
        si = vload(s, o)
        return rotate_by_vec(ci, si, cn, sn, o, dt * (ci * ss - si * sc))

    rotate_vec = jit(rotate_vec)

    def edge_vec(c, s, lw, w, shared, indices, p, qa, sca, ssa, scb, ssb):
        """Add CSR entry ``p``'s ``w c_j``, ``w s_j`` to the coupling sums of the lane vectors at
        ``qa`` and ``qa + VEC``. (Loop-free: an inlined helper with a loop over array
        arguments leaves numba's reference counting calls in the loop around it.)"""
        lanes = c.shape[1]
        o = indices[p] * lanes
        if shared:
            wa = vsplat(w[p])
            wb = wa
        else:
            wa = vload(lw, p * lanes + qa)
            wb = vload(lw, p * lanes + qa + vw)
        sca = sca + wa * vload(c, o + qa)
        ssa = ssa + wa * vload(s, o + qa)
        scb = scb + wb * vload(c, o + qa + vw)
        ssb = ssb + wb * vload(s, o + qa + vw)
        return sca, ssa, scb, ssb

    edge_vec = jit(edge_vec)

    def node_sums_vec(c, s, lw, w, shared, indptr, indices, i, qa):
        """Node ``i``'s coupling sums ``(sc, ss)`` of the lane vectors at ``qa`` and ``qa + VEC``,
        kept in registers over its edges (``edge_vec``)."""
        sca, ssa, scb, ssb = vsplat(zero), vsplat(zero), vsplat(zero), vsplat(zero)
        for p in range(indptr[i], indptr[i + 1]):
            sca, ssa, scb, ssb = edge_vec(c, s, lw, w, shared, indices, p, qa, sca, ssa, scb, ssb)
        return sca, ssa, scb, ssb

    node_sums_vec = jit(node_sums_vec)

    def euler_step_vec(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2):
        """``euler_step_lanes`` with ``taylor=True`` on machine vectors, fused.

        The lane count ``c.shape[1]`` must be a multiple of two machine vectors (``2 VEC``
        float64 or ``4 VEC`` float32 lanes): two vectors are stepped together (independent
        work for the out-of-order core).
        For each node their coupling sums stay in registers over the node's edges and the
        rotated state goes to ``(cn, sn)`` (the caller swaps the buffers), so no sum, angle or
        running total is stored. ``shared=True`` promises every lane has the weights ``w``
        (CSR, 1-D), which are then broadcast instead of loading ``lw[p, lane]``. Per lane the
        operations and their order are those of ``euler_step``: the same bits.
        """
        n, lanes = c.shape
        for qa in range(0, lanes, 2 * vw):
            qb = qa + vw
            tca = vsplat(zero)
            tsa = vsplat(zero)
            tcb = vsplat(zero)
            tsb = vsplat(zero)
            for i in range(n):
                sca, ssa, scb, ssb = node_sums_vec(c, s, lw, w, shared, indptr, indices, i, qa)
                xa, ya = rotate_vec(c, s, cn, sn, i * lanes + qa, sca, ssa, dt)
                xb, yb = rotate_vec(c, s, cn, sn, i * lanes + qb, scb, ssb, dt)
                tca = tca + xa
                tsa = tsa + ya
                tcb = tcb + xb
                tsb = tsb + yb
            vstore(r2, qa, tca * tca + tsa * tsa)
            vstore(r2, qb, tcb * tcb + tsb * tsb)

    euler_step_vec = jit(euler_step_vec)

    def tangent_step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, net, dt, r2, taylor, u, work, damage, dr2):
        """Euler step plus its tangents ``u[e] = dtheta/dbeta_e`` for damage on each edge ``e``.

        The tangent of ``theta <- theta + dt f(theta, W(beta))`` is
        ``u <- u + dt (J u + df/dbeta)``, with ``(J u)_i = sum_j w_ij cos(theta_j - theta_i)
        (u_j - u_i)`` and, for damage on ``a -> b``, ``df_a/dbeta = rho omega_a + mu
        sin(theta_b - theta_a)`` (``dw_aj/dbeta = rho w_aj + mu [j = b]``; see
        :func:`antisync.physics.coupling.coupling_derivative`). Afterwards
        ``dr2[e] = d|sum_j e^{i theta_j}|^2 / dbeta_e``.

        The arguments of ``euler_step_lanes``, the network as ``net = (lw, indptr, indices)``,
        then the tangents ``u[e, node, lane]``, their scratch ``work = (du, cu, su)`` (each
        ``[node, lane]``), the damage ``(edge_a, edge_b, rho, mu)`` per edge and ``dr2[e, lane]``.
        """
        lw, indptr, indices = net
        du, cu, su = work
        edge_a, edge_b, rho, mu = damage
        n, lanes = c.shape
        lane_sums(c, s, sum_c, sum_s, acc, lw, indptr, indices, dt)
        for e in range(u.shape[0]):
            for j in range(n):
                for q in range(lanes):
                    cu[j, q] = c[j, q] * u[e, j, q]
                    su[j, q] = s[j, q] * u[e, j, q]
            for i in range(n):
                for q in range(lanes):
                    du[i, q] = 0.0
                for p in range(indptr[i], indptr[i + 1]):
                    j = indices[p]
                    for q in range(lanes):
                        du[i, q] += lw[p, q] * (c[i, q] * cu[j, q] + s[i, q] * su[j, q])
                for q in range(lanes):
                    diag = c[i, q] * sum_c[i, q] + s[i, q] * sum_s[i, q]
                    du[i, q] = dt * (du[i, q] - u[e, i, q] * diag)
            a = edge_a[e]
            b = edge_b[e]
            for q in range(lanes):
                sin_ba = s[b, q] * c[a, q] - c[b, q] * s[a, q]
                du[a, q] += rho[e] * acc[a, q] + dt * mu[e] * sin_ba
            for i in range(n):
                for q in range(lanes):
                    u[e, i, q] += du[i, q]
        lane_rotate(c, s, acc, tot_c, tot_s, r2, taylor)
        for e in range(u.shape[0]):
            for q in range(lanes):
                dr2[e, q] = 0.0
            for i in range(n):
                for q in range(lanes):
                    dr2[e, q] += 2.0 * (tot_s[q] * c[i, q] - tot_c[q] * s[i, q]) * u[e, i, q]

    tangent_step_lanes = jit(tangent_step_lanes)

    def lane_velocity(c, s, dc, ds, dtot, omega, sum_c, sum_s, lw, indptr, indices):
        """``(dc, ds) = (-s omega, c omega)`` per node and ``dR/dt`` per lane (RK4 stages)."""
        n, lanes = c.shape
        lane_sums(c, s, sum_c, sum_s, omega, lw, indptr, indices, 1.0)
        for q in range(lanes):
            dtot[0, q] = 0.0  # d(sum c)/dt
            dtot[1, q] = 0.0  # d(sum s)/dt
            dtot[2, q] = 0.0  # sum c
            dtot[3, q] = 0.0  # sum s
        for i in range(n):
            for q in range(lanes):
                dc[i, q] = -s[i, q] * omega[i, q]
                ds[i, q] = c[i, q] * omega[i, q]
                dtot[0, q] += dc[i, q]
                dtot[1, q] += ds[i, q]
                dtot[2, q] += c[i, q]
                dtot[3, q] += s[i, q]

    lane_velocity = jit(lane_velocity)

    def rk4_step_lanes(c, s, k, yc, ys, dtot, omega, sum_c, sum_s, lw, indptr, indices, dt, r2, dr2):
        """Classical RK4 on ``dc/dt = -s omega, ds/dt = c omega`` (Eq. 2 in (cos, sin) form).

        ``k[0], k[1]`` must hold the velocity at the current state on entry (stage 1); on exit
        they hold it at the new state, so each step costs four right-hand sides. The state is
        projected back to the unit circle after every step. ``r2`` and ``dr2 = dR/dt`` are
        returned per lane for the Hermite crossing.
        """
        n, lanes = c.shape
        for stage in range(1, 4):
            h = 0.5 * dt if stage < 3 else dt
            src = 2 * (stage - 1)
            for i in range(n):
                for q in range(lanes):
                    yc[i, q] = c[i, q] + h * k[src, i, q]
                    ys[i, q] = s[i, q] + h * k[src + 1, i, q]
            lane_velocity(
                yc, ys, k[2 * stage], k[2 * stage + 1], dtot, omega, sum_c, sum_s, lw, indptr, indices
            )
        for i in range(n):
            for q in range(lanes):
                cn = c[i, q] + dt / 6.0 * (k[0, i, q] + 2.0 * k[2, i, q] + 2.0 * k[4, i, q] + k[6, i, q])
                sn = s[i, q] + dt / 6.0 * (k[1, i, q] + 2.0 * k[3, i, q] + 2.0 * k[5, i, q] + k[7, i, q])
                inv = 1.0 / math.sqrt(cn * cn + sn * sn)
                c[i, q] = cn * inv
                s[i, q] = sn * inv
        lane_velocity(c, s, k[0], k[1], dtot, omega, sum_c, sum_s, lw, indptr, indices)
        for q in range(lanes):
            r2[q] = dtot[2, q] * dtot[2, q] + dtot[3, q] * dtot[3, q]
            dr2[q] = 2.0 * (dtot[2, q] * dtot[0, q] + dtot[3, q] * dtot[1, q])

    rk4_step_lanes = jit(rk4_step_lanes)

    def velocity_vec(yc, ys, o, sc, ss):
        """``(c, s, dc, ds)`` with ``(dc, ds) = (-s omega, c omega)`` for the lane vector at ``o``
        of the state ``(yc, ys)`` with coupling sums ``sc, ss`` (as ``lane_velocity``)."""
        c = vload(yc, o)
        s = vload(ys, o)
        omega = c * ss - s * sc
        return c, s, -s * omega, c * omega

    velocity_vec = jit(velocity_vec)

    def rk4_stage_vec(c, s, k, kc, src_c, src_s, dst_c, dst_s, o, sc, ss, h):
        """One lane vector of an inner RK4 stage: the velocity at ``src`` into ``k`` (flat offset
        ``kc`` of the ``dc`` row, the ``ds`` row one state further) and ``dst = (c, s) + h k``."""
        size = c.size
        _, _, dc, ds = velocity_vec(src_c, src_s, o, sc, ss)
        vstore(k, kc + o, dc)
        vstore(k, kc + size + o, ds)
        vstore(dst_c, o, vload(c, o) + h * dc)
        vstore(dst_s, o, vload(s, o) + h * ds)

    rk4_stage_vec = jit(rk4_stage_vec)

    def rk4_final_vec(c, s, k, ya_c, ya_s, o, sc, ss, sixth):
        """One lane vector of the last RK4 stage, the update and the projection to the circle."""
        size = c.size
        _, _, dc, ds = velocity_vec(ya_c, ya_s, o, sc, ss)
        vstore(k, 6 * size + o, dc)
        vstore(k, 7 * size + o, ds)
        two = vsplat(2.0)
        cn = vload(c, o) + sixth * (
            vload(k, o) + two * vload(k, 2 * size + o) + two * vload(k, 4 * size + o) + dc
        )
        sn = vload(s, o) + sixth * (
            vload(k, size + o) + two * vload(k, 3 * size + o) + two * vload(k, 5 * size + o) + ds
        )
        inv = 1.0 / vsqrt(cn * cn + sn * sn)
        vstore(c, o, cn * inv)
        vstore(s, o, sn * inv)

    rk4_final_vec = jit(rk4_final_vec)

    def rk4_step_vec(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2):
        """``rk4_step_lanes`` on machine vectors (the lane count a multiple of ``2 VEC``), the same
        bits. ``k`` as there (``k[0], k[1]`` the velocity at the state on entry and on exit);
        ``ya``, ``yb`` hold the stage states in turn. ``w``, ``shared`` as in ``euler_step_vec``.

        Every block of ``2 VEC`` lanes runs its whole step before the next block, and each
        pass over the nodes fuses what the stage needs per node: the velocity with the next
        stage's state, the last stage's velocity with the RK4 update and the projection to the
        unit circle, the new velocity with ``R`` and ``dR/dt``.
        """
        n, lanes = c.shape
        hh = 0.5 * dt
        sixth = dt / 6.0
        size = n * lanes
        for qa in range(0, lanes, 2 * VEC):
            qb = qa + VEC
            for i in range(n):
                for v in range(2):
                    o = i * lanes + qa + v * VEC
                    vstore(ya_c, o, vload(c, o) + hh * vload(k, o))
                    vstore(ya_s, o, vload(s, o) + hh * vload(k, size + o))
            for i in range(n):
                sca, ssa, scb, ssb = node_sums_vec(ya_c, ya_s, lw, w, shared, indptr, indices, i, qa)
                rk4_stage_vec(c, s, k, 2 * size, ya_c, ya_s, yb_c, yb_s, i * lanes + qa, sca, ssa, hh)
                rk4_stage_vec(c, s, k, 2 * size, ya_c, ya_s, yb_c, yb_s, i * lanes + qb, scb, ssb, hh)
            for i in range(n):
                sca, ssa, scb, ssb = node_sums_vec(yb_c, yb_s, lw, w, shared, indptr, indices, i, qa)
                rk4_stage_vec(c, s, k, 4 * size, yb_c, yb_s, ya_c, ya_s, i * lanes + qa, sca, ssa, dt)
                rk4_stage_vec(c, s, k, 4 * size, yb_c, yb_s, ya_c, ya_s, i * lanes + qb, scb, ssb, dt)
            for i in range(n):
                sca, ssa, scb, ssb = node_sums_vec(ya_c, ya_s, lw, w, shared, indptr, indices, i, qa)
                rk4_final_vec(c, s, k, ya_c, ya_s, i * lanes + qa, sca, ssa, sixth)
                rk4_final_vec(c, s, k, ya_c, ya_s, i * lanes + qb, scb, ssb, sixth)
            # the velocity at the new state (stage 1 of the next step), R and dR/dt
            d0a = vsplat(zero)
            d1a = vsplat(zero)
            d2a = vsplat(zero)
            d3a = vsplat(zero)
            d0b = vsplat(zero)
            d1b = vsplat(zero)
            d2b = vsplat(zero)
            d3b = vsplat(zero)
            for i in range(n):
                sca, ssa, scb, ssb = node_sums_vec(c, s, lw, w, shared, indptr, indices, i, qa)
                o = i * lanes + qa
                ci, si, dc, ds = velocity_vec(c, s, o, sca, ssa)
                vstore(k, o, dc)
                vstore(k, size + o, ds)
                d0a = d0a + dc
                d1a = d1a + ds
                d2a = d2a + ci
                d3a = d3a + si
                o = i * lanes + qb
                ci, si, dc, ds = velocity_vec(c, s, o, scb, ssb)
                vstore(k, o, dc)
                vstore(k, size + o, ds)
                d0b = d0b + dc
                d1b = d1b + ds
                d2b = d2b + ci
                d3b = d3b + si
            vstore(r2, qa, d2a * d2a + d3a * d3a)
            vstore(dr2, qa, 2.0 * (d2a * d0a + d3a * d1a))
            vstore(r2, qb, d2b * d2b + d3b * d3b)
            vstore(dr2, qb, 2.0 * (d2b * d0b + d3b * d1b))

    rk4_step_vec = jit(rk4_step_vec)

    def hermite_crossing(r0, d0, r1, d1, dt, target):
        """Fraction ``x`` in (0, 1] of a step where the cubic Hermite interpolant of ``R``
        (values ``r0, r1``, time derivatives ``d0, d1``) first reaches ``target``
        (``r0 < target <= r1``), by bisection to rounding."""
        lo = 0.0
        hi = 1.0
        for _ in range(60):
            x = 0.5 * (lo + hi)
            x2 = x * x
            x3 = x2 * x
            p = (
                (2 * x3 - 3 * x2 + 1) * r0
                + (x3 - 2 * x2 + x) * dt * d0
                + (-2 * x3 + 3 * x2) * r1
                + (x3 - x2) * dt * d1
            )
            if p >= target:
                hi = x
            else:
                lo = x
        return hi

    hermite_crossing = jit(hermite_crossing)

    def renormalize(c, s):
        """``(c_i, s_i) /= |(c_i, s_i)|`` for every node (``c``, ``s`` may be strided views)."""
        for i in range(c.shape[0]):
            inv = one / math.sqrt(c[i] * c[i] + s[i] * s[i])
            c[i] *= inv
            s[i] *= inv

    renormalize = jit(renormalize)

    def order2(c, s):
        sum_c = zero
        sum_s = zero
        for i in range(c.shape[0]):
            sum_c += c[i]
            sum_s += s[i]
        return sum_c * sum_c + sum_s * sum_s

    order2 = jit(order2)

    def sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
        if order2(c, s) >= r2_target:
            return ALREADY_SYNCED, 0
        for step in range(1, max_steps + 1):
            r2 = euler_step(c, s, acc, indptr, indices, weights, dt)
            if r2 >= r2_target:
                return SYNCED, step
            if step % renorm_every == 0:
                renormalize(c, s)
        return NOT_SYNCED, max_steps

    sync_steps = jit(sync_steps)
    return Kernels(
        rotation=rotation,
        taylor_rotation=taylor_rotation,
        rotate_by_vec=rotate_by_vec,
        euler_step=euler_step,
        euler_step_lanes=euler_step_lanes,
        euler_step_vec=euler_step_vec,
        edge_vec=edge_vec,
        node_sums_vec=node_sums_vec,
        tangent_step_lanes=tangent_step_lanes,
        rk4_step_lanes=rk4_step_lanes,
        rk4_step_vec=rk4_step_vec,
        lane_velocity=lane_velocity,
        hermite_crossing=hermite_crossing,
        sync_steps=sync_steps,
        order2=order2,
        renormalize=renormalize,
    )


#: Criterion codes of :func:`make_model_kernels`' ``sync_steps``: ``R >= r2_target`` (the
#: order-parameter and relative criteria differ only in the target), or every
#: ``|theta_i' - mean theta'| < tolerance``.
CRIT_ORDER = 0
CRIT_FREQUENCY = 1

#: Rows of the model kernels' scratch array ``work`` (shape ``(WORK_ROWS, N)``): 0-14 the RK4
#: stages, 15-18 the frequency deviations and their rates now, 19-22 one step back.
WORK_ROWS = 23
DEV_ROW = 15
DEV_PREV_ROW = 19
_DEV = DEV_ROW
_DEV_PREV = DEV_PREV_ROW

#: Points per step at which :func:`make_model_kernels`' dense output looks for the first time
#: the criterion holds, once a cheap bound says it may hold inside the step; the crossing is then
#: located by bisection between the last point before and the first point after.
DENSE_POINTS = 32


class ModelKernels(NamedTuple):
    """The compiled functions of :func:`make_model_kernels`, by name."""

    rhs: Callable
    euler_step: Callable
    rk4_step: Callable
    sync_steps: Callable
    measure: Callable
    deviations: Callable
    order_crossing: Callable
    frequency_crossing: Callable
    largest_deviation: Callable
    hermite: Callable
    hermite_range: Callable
    copy_rows: Callable


def make_model_kernels(jit, base: Kernels) -> ModelKernels:
    """Compile the generalized model's step functions with ``jit`` (docs/models.md).

    The model is ``m_i theta_i'' + gamma_i theta_i' = P_i + sum_j w_ij sin(theta_j - theta_i -
    alpha)``; a node with ``m_i = 0`` is first order, ``gamma_i theta_i' = P_i + ...`` (the
    structure-preserving power-grid model: generators with inertia beside load buses), and a
    model with every ``m_i = 0`` is ``theta_i' = P_i + ...`` (its damping unused; the caller
    passes ``gamma = 1``). With ``sin(a - alpha) = sin a cos alpha - cos a sin alpha`` the coupling
    is ``cos alpha (c_i S_i - s_i C_i) - sin alpha (c_i C_i + s_i S_i)`` from the same sums ``C_i =
    sum_j w_ij c_j``, ``S_i = sum_j w_ij s_j`` as Eq. 2's, at no extra transcendental cost. The
    state is ``(c_i, s_i)`` as in :func:`make_kernels` plus ``nu_i = theta_i'`` for ``m_i > 0``.

    With ``P = 0``, ``alpha = 0`` (``cos alpha = 1``, ``sin alpha = 0``) and ``m = 0`` the Euler
    step performs exactly the default step's operations (``0 + 1 x - 0 y = x`` in floating
    point) and renormalizes at the same steps, so it reproduces :func:`make_kernels`'
    ``sync_steps`` bit for bit (tests/test_models.py).

    **Where the criterion is met.** Each criterion is checked on the integrator's dense output,
    not only at grid points: for RK4 the cubic Hermite interpolant of each tested quantity from
    its values and time derivatives at both ends of the step (fourth order, like the step), for
    Euler the straight line between them (Euler's own dense output). The quantities are ``R =
    |sum_j e^{i theta_j}|^2`` for the order-parameter criteria, and for the frequency criterion
    every deviation ``theta_i' - mean theta'`` (and, with inertia, ``g_i - mean g``, ``g_i =
    (P_i + coupling_i) / gamma_i``), whose rates come from ``d coupling_i / dt = sum_j w_ij
    cos(theta_j - theta_i - alpha) (theta_j' - theta_i')``. A step is scanned only when a bound
    (the exact range of every interpolant over the step) says the criterion can hold in it; the
    first of :data:`DENSE_POINTS` points where it holds is then refined by bisection. A
    deviation that dips below the tolerance between two grid points is thus found (at RK4 dt 0.02
    on the IEEE 14 grid, grid-point checks moved ~3% of crossings by 0.05 to 1.3, biasing
    ``<tau0>`` by about dt); only a dip shorter than ``dt / DENSE_POINTS`` can be missed.

    Parameters
    ----------
    jit : callable
        A numba decorator (``njit(...)`` or ``cuda.jit(device=True)``).
    base : Kernels
        :func:`make_kernels` compiled with the same ``jit`` (its rotation and renormalization).

    Returns
    -------
    ModelKernels
        The equations' constants travel as one tuple, ``eq = (p, weights, indptr, indices, cl,
        sl, mass, gamma)``: the natural frequencies ``P_i``, ``W`` in CSR form, ``cos alpha``,
        ``sin alpha`` and the per-node ``m_i``, ``gamma_i`` (the lane kernels'
        :class:`~antisync.kernels.model_steps.Terms` in the same order, without ``second``).
        ``rhs(c, s, nu, eq, second, th, dnu)`` fills ``th = theta'`` and, for ``second`` (some
        ``m_i > 0``), ``dnu = nu'``;
        ``euler_step(c, s, nu, th, dnu, dt, second) -> R`` advances one explicit Euler step
        from the rates in ``th``/``dnu`` (a rotation of ``(c_i, s_i)`` by ``dt theta_i'``);
        ``rk4_step(c, s, nu, th, dnu, work, eq, second, dt)`` classical RK4 on ``(c, s, nu)``
        (``th``/``dnu`` at the current state on entry), projecting ``(c_i, s_i)`` back to the
        unit circle after the step;
        ``sync_steps(c, s, nu, th, dnu, work, eq, dt, rk4, criterion, target, max_steps) ->
        (status, steps, frac)``
        integrates until the criterion holds (``target``: ``R`` for :data:`CRIT_ORDER`, the
        tolerance for :data:`CRIT_FREQUENCY`; ``work`` has :data:`WORK_ROWS` rows); ``frac`` in
        ``(0, 1]`` locates the first crossing inside the last step on the dense output.
    """
    rotation = base.rotation
    renormalize = base.renormalize
    order2 = base.order2

    def rhs(c, s, nu, eq, second, th, dnu):
        p, weights, indptr, indices, cl, sl, mass, gamma = eq
        n = c.shape[0]
        lagged = sl != 0.0 or cl != 1.0
        for i in range(n):
            sc = 0.0
            ss = 0.0
            for q in range(indptr[i], indptr[i + 1]):
                j = indices[q]
                w = weights[q]
                sc += w * c[j]
                ss += w * s[j]
            # sum_j w_ij sin(theta_j - theta_i - alpha), from the sums of Eq. 2
            k = c[i] * ss - s[i] * sc
            if lagged:
                k = cl * k - sl * (c[i] * sc + s[i] * ss)
            if not second:
                th[i] = p[i] + k
            elif mass[i] > 0.0:
                th[i] = nu[i]
                dnu[i] = (p[i] + k - gamma[i] * nu[i]) / mass[i]
            else:
                # a first-order node of a second-order network
                th[i] = (p[i] + k) / gamma[i]
                dnu[i] = 0.0

    rhs = jit(rhs)

    def euler_step(c, s, nu, th, dnu, dt, second):
        n = c.shape[0]
        sum_c = 0.0
        sum_s = 0.0
        for i in range(n):
            ca, sa = rotation(dt * th[i])
            ci = c[i]
            si = s[i]
            c[i] = ci * ca - si * sa
            s[i] = si * ca + ci * sa
            sum_c += c[i]
            sum_s += s[i]
            if second:
                nu[i] += dt * dnu[i]
        return sum_c * sum_c + sum_s * sum_s

    euler_step = jit(euler_step)

    def rk4_step(c, s, nu, th, dnu, work, eq, second, dt):
        # work rows: 0-3 dc of the stages, 4-7 ds, 8-11 dnu, 12-14 the stage state (c, s, nu)
        n = c.shape[0]
        for i in range(n):
            work[0, i] = -s[i] * th[i]
            work[4, i] = c[i] * th[i]
            work[8, i] = dnu[i] if second else 0.0
        for stage in range(1, 4):
            h = 0.5 * dt if stage < 3 else dt
            for i in range(n):
                work[12, i] = c[i] + h * work[stage - 1, i]
                work[13, i] = s[i] + h * work[stage + 3, i]
                work[14, i] = nu[i] + h * work[stage + 7, i]
            # rows cut to n: on CUDA ``work`` is a (WORK_ROWS, MAX_NODES) local array
            rhs(work[12, :n], work[13, :n], work[14, :n], eq, second, th, dnu)
            for i in range(n):
                work[stage, i] = -work[13, i] * th[i]
                work[stage + 4, i] = work[12, i] * th[i]
                work[stage + 8, i] = dnu[i] if second else 0.0
        for i in range(n):
            cn = c[i] + dt / 6.0 * (work[0, i] + 2.0 * work[1, i] + 2.0 * work[2, i] + work[3, i])
            sn = s[i] + dt / 6.0 * (work[4, i] + 2.0 * work[5, i] + 2.0 * work[6, i] + work[7, i])
            norm2 = cn * cn + sn * sn
            # a diverged state (a step beyond its stability bound) can reach 0 here: NaN, whose
            # deviation never meets the criterion, not a ZeroDivisionError
            inv = 1.0 / math.sqrt(norm2) if norm2 > 0.0 else math.nan
            c[i] = cn * inv
            s[i] = sn * inv
            if second:
                nu[i] += dt / 6.0 * (work[8, i] + 2.0 * work[9, i] + 2.0 * work[10, i] + work[11, i])

    rk4_step = jit(rk4_step)

    def worse(dev, d):
        """``max(dev, d)`` that keeps a NaN: numba's ``max(0.0, nan)`` is ``0.0``, so a diverged
        state (an explicit step beyond its stability bound) had the deviation 0, "synchronized".
        Equal to ``max`` for numbers, bit for bit."""
        if d <= dev or dev != dev:
            return dev
        return d

    worse = jit(worse)

    def measure(c, s, th, dnu, mass, gamma, second):
        """``(dR/dt, deviation)`` of the current state: the largest ``|theta_i' - mean|``, and
        for a second-order network also the largest deviation of ``g_i = theta_i' + (m_i /
        gamma_i) nu_i' = (P_i + coupling_i) / gamma_i``, the frequency node ``i`` relaxes to
        (else ``theta' = 0`` at ``t = 0`` would count as locked)."""
        n = c.shape[0]
        tc = 0.0
        ts = 0.0
        dc = 0.0
        ds = 0.0
        mean = 0.0
        mean2 = 0.0
        for i in range(n):
            tc += c[i]
            ts += s[i]
            dc -= s[i] * th[i]
            ds += c[i] * th[i]
            mean += th[i]
            if second:
                mean2 += th[i] + mass[i] / gamma[i] * dnu[i]
        mean /= n
        mean2 /= n
        dev = 0.0
        for i in range(n):
            dev = worse(dev, abs(th[i] - mean))
            if second:
                dev = worse(dev, abs(th[i] + mass[i] / gamma[i] * dnu[i] - mean2))
        return 2.0 * (tc * dc + ts * ds), dev

    measure = jit(measure)

    def deviations(c, s, th, dnu, eq, second, work):
        """Rows ``_DEV.._DEV+3`` of ``work``: ``theta_i' - mean``, its rate, ``g_i - mean``
        (second order) and its rate, from ``d coupling_i / dt = sum_j w_ij cos(theta_j -
        theta_i - alpha) (theta_j' - theta_i')``."""
        _, weights, indptr, indices, cl, sl, mass, gamma = eq
        n = c.shape[0]
        m0 = 0.0
        m1 = 0.0
        m2 = 0.0
        m3 = 0.0
        for i in range(n):
            kd = 0.0
            for q in range(indptr[i], indptr[i + 1]):
                j = indices[q]
                # cos(theta_j - theta_i - alpha)
                ca = cl * (c[j] * c[i] + s[j] * s[i]) + sl * (s[j] * c[i] - c[j] * s[i])
                kd += weights[q] * ca * (th[j] - th[i])
            work[_DEV, i] = th[i]
            if not second:
                work[_DEV + 1, i] = kd
            else:
                work[_DEV + 1, i] = dnu[i] if mass[i] > 0.0 else kd / gamma[i]
                work[_DEV + 2, i] = th[i] + mass[i] / gamma[i] * dnu[i]
                work[_DEV + 3, i] = kd / gamma[i]
                m2 += work[_DEV + 2, i]
                m3 += work[_DEV + 3, i]
            m0 += work[_DEV, i]
            m1 += work[_DEV + 1, i]
        for i in range(n):
            work[_DEV, i] -= m0 / n
            work[_DEV + 1, i] -= m1 / n
            if second:
                work[_DEV + 2, i] -= m2 / n
                work[_DEV + 3, i] -= m3 / n

    deviations = jit(deviations)

    def copy_rows(work, dst, src, count):
        """``work[dst + k] = work[src + k]`` for ``k < count``: the deviations kept as the step
        before's (``dst = DEV_PREV_ROW``, ``src = DEV_ROW``) or put back (the reverse)."""
        for k in range(count):
            for i in range(work.shape[1]):
                work[dst + k, i] = work[src + k, i]

    copy_rows = jit(copy_rows)

    def hermite(y0, m0, y1, m1, x):
        """The cubic Hermite interpolant at ``x`` in [0, 1] (``m0``, ``m1``: rates times dt)."""
        x2 = x * x
        x3 = x2 * x
        return (2 * x3 - 3 * x2 + 1) * y0 + (x3 - 2 * x2 + x) * m0 + (-2 * x3 + 3 * x2) * y1 + (x3 - x2) * m1

    hermite = jit(hermite)

    def hermite_range(y0, m0, y1, m1):
        """``(min, max)`` of the cubic Hermite interpolant over [0, 1]: its ends and the zeros of
        its derivative ``m0 + 2 a2 x + 3 a3 x^2`` inside."""
        a2 = -3.0 * y0 - 2.0 * m0 + 3.0 * y1 - m1
        a3 = 2.0 * y0 + m0 - 2.0 * y1 + m1
        lo = min(y0, y1)
        hi = max(y0, y1)
        for k in range(2):
            x = -1.0
            if a3 != 0.0:
                disc = a2 * a2 - 3.0 * a3 * m0
                if disc >= 0.0:
                    root = math.sqrt(disc)
                    x = (-a2 + root) / (3.0 * a3) if k == 0 else (-a2 - root) / (3.0 * a3)
            elif a2 != 0.0 and k == 0:
                x = -m0 / (2.0 * a2)
            if 0.0 < x < 1.0:
                y = ((a3 * x + a2) * x + m0) * x + y0
                lo = min(lo, y)
                hi = max(hi, y)
        return lo, hi

    hermite_range = jit(hermite_range)

    def ends(work, row, i, dt, rk4):
        """``(y0, m0, y1, m1)`` of deviation row ``row`` at node ``i`` over the last step: RK4's
        Hermite data, or Euler's straight line (both rates the secant)."""
        y0 = work[row + _DEV_PREV - _DEV, i]
        y1 = work[row, i]
        if rk4:
            return y0, dt * work[row + _DEV_PREV - _DEV + 1, i], y1, dt * work[row + 1, i]
        return y0, y1 - y0, y1, y1 - y0

    ends = jit(ends)

    def largest_deviation(work, n, rows, dt, rk4, x):
        """The largest ``|deviation|`` of the tested rows (``rows``: 2 with inertia) at ``x`` of
        the last step's interpolants (``x = 1``: the step's end, exactly)."""
        dev = 0.0
        for i in range(n):
            for k in range(rows):
                y0, m0, y1, m1 = ends(work, _DEV + 2 * k, i, dt, rk4)
                dev = worse(dev, abs(hermite(y0, m0, y1, m1, x)))
        return dev

    largest_deviation = jit(largest_deviation)

    def frequency_crossing(work, n, second, dt, rk4, target):
        """First ``x`` in (0, 1] of the last step where every interpolated deviation is below
        ``target``, or -1 (none found)."""
        rows = 2 if second else 1
        for i in range(n):
            for k in range(rows):
                y0, m0, y1, m1 = ends(work, _DEV + 2 * k, i, dt, rk4)
                lo, hi = hermite_range(y0, m0, y1, m1)
                if lo >= target or hi <= -target:
                    return -1.0  # this deviation stays out of the band for the whole step
        a = 0.0
        for point in range(1, DENSE_POINTS + 1):
            b = point / DENSE_POINTS
            if largest_deviation(work, n, rows, dt, rk4, b) < target:
                for _ in range(60):
                    x = 0.5 * (a + b)
                    if largest_deviation(work, n, rows, dt, rk4, x) < target:
                        b = x
                    else:
                        a = x
                return b
            a = b
        return -1.0

    frequency_crossing = jit(frequency_crossing)

    def order_crossing(r0, d0, r1, d1, dt, rk4, target):
        """First ``x`` in (0, 1] of the last step where the interpolated ``R`` reaches
        ``target`` (Hermite for RK4, straight line for Euler), or -1."""
        if not rk4:
            return (target - r0) / (r1 - r0) if r1 >= target else -1.0
        m0 = dt * d0
        m1 = dt * d1
        if r1 < target:
            lo, hi = hermite_range(r0, m0, r1, m1)
            if hi < target:
                return -1.0
        a = 0.0
        for point in range(1, DENSE_POINTS + 1):
            b = point / DENSE_POINTS
            if hermite(r0, m0, r1, m1, b) >= target:
                for _ in range(60):
                    x = 0.5 * (a + b)
                    if hermite(r0, m0, r1, m1, x) >= target:
                        b = x
                    else:
                        a = x
                return b
            a = b
        return -1.0

    order_crossing = jit(order_crossing)

    def sync_steps(c, s, nu, th, dnu, work, eq, dt, rk4, criterion, target, max_steps):
        mass, gamma = eq[6], eq[7]
        n = c.shape[0]
        second = False
        for i in range(n):
            second |= mass[i] > 0.0
        freq = criterion == CRIT_FREQUENCY
        rhs(c, s, nu, eq, second, th, dnu)
        r2 = order2(c, s)
        dr2, dev = measure(c, s, th, dnu, mass, gamma, second)
        if freq:
            if dev < target:
                return ALREADY_SYNCED, 0, 0.0
            deviations(c, s, th, dnu, eq, second, work)
        elif r2 >= target:
            return ALREADY_SYNCED, 0, 0.0
        for step in range(1, max_steps + 1):
            r2_prev = r2
            dr2_prev = dr2
            if freq:
                copy_rows(work, _DEV_PREV, _DEV, 4)
            if rk4:
                rk4_step(c, s, nu, th, dnu, work, eq, second, dt)
                r2 = order2(c, s)
            else:
                r2 = euler_step(c, s, nu, th, dnu, dt, second)
                if step % RENORM_EVERY == 0:
                    renormalize(c, s)
            rhs(c, s, nu, eq, second, th, dnu)
            if freq:
                deviations(c, s, th, dnu, eq, second, work)
                x = frequency_crossing(work, n, second, dt, rk4, target)
            else:
                if rk4:
                    dr2, dev = measure(c, s, th, dnu, mass, gamma, second)
                x = order_crossing(r2_prev, dr2_prev, r2, dr2, dt, rk4, target)
            if x >= 0.0:
                return SYNCED, step, x
        return NOT_SYNCED, max_steps, 0.0

    sync_steps = jit(sync_steps)
    return ModelKernels(
        rhs=rhs,
        euler_step=euler_step,
        rk4_step=rk4_step,
        sync_steps=sync_steps,
        measure=measure,
        deviations=deviations,
        order_crossing=order_crossing,
        frequency_crossing=frequency_crossing,
        largest_deviation=largest_deviation,
        hermite=hermite,
        hermite_range=hermite_range,
        copy_rows=copy_rows,
    )
