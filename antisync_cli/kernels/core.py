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
"""

from __future__ import annotations

import math

from antisync_cli.status import Status

__all__ = ["RENORM_EVERY", "TAYLOR_MAX_ANGLE", "make_kernels"]

RENORM_EVERY = 1024
_SYNCED = int(Status.SYNCED)
_ALREADY = int(Status.ALREADY_SYNCED)
_NOT_SYNCED = int(Status.NOT_SYNCED)


TAYLOR_MAX_ANGLE = 0.05


def make_kernels(jit):
    """Compile the integrator's building blocks with ``jit``.

    Returns
    -------
    dict
        ``rotation(a) -> (cos a, sin a)`` (Taylor polynomials for ``|a| <= 0.05``);
        ``euler_step(c, s, acc, indptr, indices, weights, dt) -> R`` advances one state in
        place and returns ``R = |sum_j e^{i theta_j}|^2``;
        ``sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps)
        -> (status, steps)`` integrates until ``R >= r2_target``;
        ``euler_step_lanes(c, s, acc, sc, ss, lw, indptr, indices, dt, r2, taylor)`` advances
        ``L`` independent states stored as ``[node, lane]`` (weights ``lw[nnz, lane]``), the
        lane loop innermost so the compiler vectorizes across lanes; ``taylor=True`` promises
        ``|alpha| <= 0.05`` for every node and lane (then results equal ``euler_step``'s bit
        for bit, since the same operations run in the same order).
    """

    def taylor_rotation(a):
        a2 = a * a
        ca = 1.0 - a2 * (0.5 - a2 * (1.0 / 24.0 - a2 * (1.0 / 720.0 - a2 / 40320.0)))
        sa = a * (1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0 - a2 * (1.0 / 5040.0 - a2 / 362880.0))))
        return ca, sa

    taylor_rotation = jit(taylor_rotation)

    def rotation(a):
        if abs(a) <= TAYLOR_MAX_ANGLE:
            return taylor_rotation(a)
        return math.cos(a), math.sin(a)

    rotation = jit(rotation)

    def euler_step(c, s, acc, indptr, indices, weights, dt):
        n = c.shape[0]
        for i in range(n):
            sc = 0.0
            ss = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                w = weights[p]
                sc += w * c[j]
                ss += w * s[j]
            # Eq. (2) in (cos, sin) form: omega_i = c_i sum_j w_ij s_j - s_i sum_j w_ij c_j
            acc[i] = dt * (c[i] * ss - s[i] * sc)
        sum_c = 0.0
        sum_s = 0.0
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

    def euler_step_lanes(c, s, acc, sc, ss, lw, indptr, indices, dt, r2, taylor):
        n, lanes = c.shape
        for i in range(n):
            for q in range(lanes):
                sc[q] = 0.0
                ss[q] = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                for q in range(lanes):
                    w = lw[p, q]
                    sc[q] += w * c[j, q]
                    ss[q] += w * s[j, q]
            for q in range(lanes):
                acc[i, q] = dt * (c[i, q] * ss[q] - s[i, q] * sc[q])
        for q in range(lanes):
            sc[q] = 0.0
            ss[q] = 0.0
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
                sc[q] += c[i, q]
                ss[q] += s[i, q]
        for q in range(lanes):
            r2[q] = sc[q] * sc[q] + ss[q] * ss[q]

    euler_step_lanes = jit(euler_step_lanes)

    def renormalize(c, s):
        for i in range(c.shape[0]):
            inv = 1.0 / math.sqrt(c[i] * c[i] + s[i] * s[i])
            c[i] *= inv
            s[i] *= inv

    renormalize = jit(renormalize)

    def order2(c, s):
        sum_c = 0.0
        sum_s = 0.0
        for i in range(c.shape[0]):
            sum_c += c[i]
            sum_s += s[i]
        return sum_c * sum_c + sum_s * sum_s

    order2 = jit(order2)

    def sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps):
        if order2(c, s) >= r2_target:
            return _ALREADY, 0
        for step in range(1, max_steps + 1):
            r2 = euler_step(c, s, acc, indptr, indices, weights, dt)
            if r2 >= r2_target:
                return _SYNCED, step
            if step % RENORM_EVERY == 0:
                renormalize(c, s)
        return _NOT_SYNCED, max_steps

    sync_steps = jit(sync_steps)
    return {
        "rotation": rotation,
        "euler_step": euler_step,
        "euler_step_lanes": euler_step_lanes,
        "sync_steps": sync_steps,
        "order2": order2,
        "renormalize": renormalize,
    }
