"""The generalized models on a stiff network: Rodas4, an L-stable Rosenbrock method with adaptive
steps, one trajectory per thread.

A power grid is stiff: its Jacobian's eigenvalues span ``-4,576`` to ``-0.071`` per second on
IEEE 300, so an explicit step is bound by the fastest mode while the synchronization time is set
by the slowest. ``dynamics.integrator: rodas4`` integrates the models of
:func:`antisync.kernels.core.make_model_kernels` (natural frequencies, phase lag, inertia,
per-node inertia beside first-order buses) with Hairer and Wanner's RODAS (*Solving Ordinary
Differential Equations II*, Sec. IV.7; the coefficients of their ``rodas.f``, the set named
RODAS4 in OrdinaryDiffEq.jl): six stages, order 4 with an embedded order-3 error estimate,
L-stable and stiffly accurate. Each step solves six linear systems with one matrix
``(h gamma)^-1 I - J``; the step size follows the error estimate under ``dynamics.rtol`` and
``dynamics.atol`` (the weighted RMS norm of Hairer and Wanner). Each trajectory has its own
step sizes: no trajectory waits for another.

**The linear algebra.** The state is ``theta`` (every node) and ``nu = theta'`` (the nodes with
inertia). Eliminating ``nu`` leaves an ``N x N`` system per stage,

    (D + L(theta)) x = b,   D_i = g (m_i g + gamma_i),   g = 1 / (h gamma),

with ``L`` the Laplacian of the weights ``w_ij cos(theta_j - theta_i - alpha)`` on the coupling's
sparsity pattern (``m_i = 0`` at a first-order node; ``gamma_i = 1`` in a model without
inertia). Every trajectory of a job shares that pattern, so :func:`factor_plan` orders it once
(minimum degree) and does the symbolic factorization once: the fill-in, and the numeric LU as
a flat list of operations, which each step replays on the trajectory's values (no pivoting; a
pivot that is not resolved rejects the step with a quarter of the step size). No dense matrix
is formed.

**Where the criterion is met** is found exactly as for RK4 (the same functions of
:func:`~antisync.kernels.core.make_model_kernels`): each tested quantity's cubic Hermite
interpolant over the accepted step from its values and rates at both ends, scanned and
bisected; the statuses are the same. The crossing time ``tau`` is stored on the grid of
``dynamics.dt`` as the explicit drivers store theirs, ``tau = (steps - 1 + frac) dt`` with
``frac`` in ``(0, 1]``: ``dt`` is the first step and the unit of the stored times, and ``t_max
= max_steps dt``.
"""

from __future__ import annotations

import functools
import heapq
import math
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels import loops
from antisync.kernels import model_steps as ms
from antisync.kernels.core import CRIT_FREQUENCY, DEV_PREV_ROW, DEV_ROW, WORK_ROWS
from antisync.kernels.lanes import item_of
from antisync.kernels.model_steps import ModelParams
from antisync.kernels.precision import K64
from antisync.kernels.shared import (
    SimResult,
    Threads,
    check_collapsed,
    copy_into,
    has_inertia,
    model_batch,
    record_item,
    share_rows,
)
from antisync.physics.phases import start_phase
from antisync.status import ALREADY_SYNCED, GAVE_UP, NOT_SYNCED, SYNCED
from antisync.types import RODAS4_ATOL, RODAS4_RTOL

__all__ = [
    "DEFAULT_ATOL",
    "DEFAULT_RTOL",
    "FactorPlan",
    "RODAS4",
    "StepStats",
    "factor_plan",
    "plan_of_pattern",
    "rodas4_trip",
    "simulate_model",
    "speed_rates",
    "trip_band",
    "trip_rates",
    "trip_swing",
    "trip_switch",
]

#: The default tolerances of ``dynamics.rtol`` / ``dynamics.atol``.
DEFAULT_RTOL = RODAS4_RTOL
DEFAULT_ATOL = RODAS4_ATOL

_rhs = ms.MK.rhs
_measure = ms.MK.measure
_deviations = ms.MK.deviations
_frequency_crossing = ms.MK.frequency_crossing
_largest_deviation = ms.MK.largest_deviation
_hermite_range = ms.MK.hermite_range
_order_crossing = ms.MK.order_crossing
_copy_rows = ms.MK.copy_rows
_rotation = K64.rotation
_order2 = K64.order2


class _Rodas4(NamedTuple):
    """RODAS (order 4(3)) in the form with ``u_i = h k_i`` (Hairer and Wanner, IV.7 (7.25)):
    ``(I / (h gamma) - J) u_i = f(y0 + sum_j a_ij u_j) + sum_j c_ij u_j / h``; the stage-5
    input plus ``u5`` is the stage-6 input, that plus ``u6`` the new state, ``u6`` the error."""

    gamma: float
    a: tuple
    c: tuple


RODAS4 = _Rodas4(
    0.25,
    (
        (1.544,),
        (0.9466785280815826, 0.2557011698983284),
        (3.314825187068521, 2.896124015972201, 0.9986419139977817),
        (1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950),
    ),
    (
        (-5.6688,),
        (-2.430093356833875, -0.2063599157091915),
        (-0.1073529058151375, -9.594562251023355, -20.47028614809616),
        (7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160),
        (8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136, -6.058818238834054),
    ),
)
"""The coefficients of Hairer's ``rodas.f`` (``METH = 1``)."""

_GAMMA = RODAS4.gamma

#: step-size controller (PI, Gustafsson): ``h_new = h clip(SAFETY err^-BETA1 err_prev^BETA2,
#: SHRINK, GROW)`` after an accepted step, ``h clip(SAFETY err^(-1/4), SHRINK, 1)`` after a
#: rejected one
_SAFETY = 0.9
_SHRINK = 0.2
_GROW = 6.0
#: the PI controller's exponents (0.7 and 0.4 over the error estimate's order plus one)
_BETA1 = 0.7 / 4
_BETA2 = 0.4 / 4
#: a step size below this fraction of ``t_max`` is a failure (reported, never a silent status)
_H_FLOOR = 1e-13
#: a crossing is located on the cubic interpolant of a step where the straight line between
#: the step's ends puts it within this fraction of its time; else the step is redone at
#: ``_REFINE`` of its size (the interpolant is only as good as the step is short)
_CROSSING_RTOL = 1e-5
_REFINE = 0.25
#: within ``_BAND`` tolerances of the frequency band (or for ``R``, of the headroom above its
#: target), a step moves each tested quantity by at most ``_NEAR`` of the tolerance: a dip into
#: the band between two steps is then one the cubic interpolant of its ends sees
_BAND = 10.0
_NEAR = 0.5
#: rejected steps in a row after which the trajectory is reported as failed
_MAX_REJECTS = 60

#: the coefficients as arrays: stage ``s`` (0-based) reads ``_A[s, :s]`` and ``_C[s, :s]``
_A = np.zeros((6, 5))
_C = np.zeros((6, 5))
for _s, _row in enumerate(RODAS4.a, start=1):
    _A[_s, : len(_row)] = _row
for _s, _row in enumerate(RODAS4.c, start=1):
    _C[_s, : len(_row)] = _row


class FactorPlan(NamedTuple):
    """The sparse LU of ``D + L`` on the coupling's pattern, planned once per job.

    ``perm[k]`` is the node eliminated ``k``-th (``inv[perm[k]] = k``); the filled matrix is
    stored by rows in elimination order (``ptr``, ``col``; ``diag[k]`` its diagonal's position);
    ``entry[q]`` is where the network's CSR entry ``q`` lands. The numeric factorization is, for
    each pivot ``k`` in order: the pivot replaced by its reciprocal, the column below it
    (``val[div_pos[div_ptr[k]:div_ptr[k+1]]]``) scaled by it, then ``val[upd_ij] -= val[upd_ik] *
    val[upd_kj]`` over ``upd_ptr[k]:upd_ptr[k+1]``.
    """

    perm: np.ndarray
    inv: np.ndarray
    ptr: np.ndarray
    col: np.ndarray
    diag: np.ndarray
    entry: np.ndarray
    div_ptr: np.ndarray
    div_pos: np.ndarray
    upd_ptr: np.ndarray
    upd_ij: np.ndarray
    upd_ik: np.ndarray
    upd_kj: np.ndarray


def _minimum_degree(n: int, neighbours: list[set]) -> list[int]:
    """A minimum-degree elimination order of the graph ``neighbours`` (ties: the lowest node),
    eliminating on the graph itself (each eliminated node's neighbours become a clique)."""
    adj = [set(a) for a in neighbours]
    heap = [(len(a), i) for i, a in enumerate(adj)]
    heapq.heapify(heap)
    done = np.zeros(n, dtype=bool)
    order = []
    while heap:
        deg, k = heapq.heappop(heap)
        if done[k] or deg != len(adj[k]):
            continue  # stale entry
        done[k] = True
        order.append(k)
        nbrs = adj[k]
        for u in nbrs:
            adj[u].discard(k)
            adj[u] |= nbrs - {u}
            heapq.heappush(heap, (len(adj[u]), u))
        adj[k] = set()
    return order


def factor_plan(indptr: np.ndarray, indices: np.ndarray) -> FactorPlan:
    """Order the pattern of ``W + W^T`` (CSR ``indptr``, ``indices``) by minimum degree and plan
    its LU: the fill-in and the flat list of numeric operations (:class:`FactorPlan`)."""
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    n = indptr.size - 1
    neighbours = [set() for _ in range(n)]
    for i in range(n):
        for j in indices[indptr[i] : indptr[i + 1]]:
            if j != i:
                neighbours[i].add(int(j))
                neighbours[int(j)].add(i)
    perm = _minimum_degree(n, neighbours)
    inv = np.empty(n, dtype=np.int64)
    inv[np.asarray(perm, dtype=np.int64)] = np.arange(n)
    # symbolic elimination in the new numbering: the filled pattern and each pivot's clique
    adj = [{int(inv[j]) for j in neighbours[perm[k]]} for k in range(n)]
    rows = [{k} for k in range(n)]
    cliques = []
    for k in range(n):
        later = sorted(j for j in adj[k] if j > k)
        cliques.append(later)
        for i in later:
            rows[i].add(k)
            rows[k].add(i)
            adj[i] |= set(later) - {i}
    ptr = np.zeros(n + 1, dtype=np.int64)
    cols = [sorted(r) for r in rows]
    for k in range(n):
        ptr[k + 1] = ptr[k] + len(cols[k])
    col = np.fromiter((j for r in cols for j in r), dtype=np.int64, count=int(ptr[-1]))
    pos = {}
    for k in range(n):
        for q in range(ptr[k], ptr[k + 1]):
            pos[k, int(col[q])] = q
    diag = np.array([pos[k, k] for k in range(n)], dtype=np.int64)
    entry = np.empty(indices.size, dtype=np.int64)
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            entry[q] = pos[int(inv[i]), int(inv[indices[q]])]
    div_ptr = np.zeros(n + 1, dtype=np.int64)
    upd_ptr = np.zeros(n + 1, dtype=np.int64)
    div_pos, upd_ij, upd_ik, upd_kj = [], [], [], []
    for k in range(n):
        for i in cliques[k]:
            div_pos.append(pos[i, k])
        for i in cliques[k]:
            for j in cliques[k]:
                upd_ij.append(pos[i, j])
                upd_ik.append(pos[i, k])
                upd_kj.append(pos[k, j])
        div_ptr[k + 1] = len(div_pos)
        upd_ptr[k + 1] = len(upd_ij)
    as_index = lambda x: np.asarray(x, dtype=np.int64)  # noqa: E731
    return FactorPlan(
        np.asarray(perm, dtype=np.int64),
        inv,
        ptr,
        col,
        diag,
        entry,
        div_ptr,
        as_index(div_pos),
        upd_ptr,
        as_index(upd_ij),
        as_index(upd_ik),
        as_index(upd_kj),
    )


def plan_of_pattern(indptr: np.ndarray, indices: np.ndarray) -> FactorPlan:
    """:func:`factor_plan` once per pattern in a process (every chunk of a job, every halving
    of a critical clearing time's bisection shares it)."""
    return _plan_of_pattern(
        np.ascontiguousarray(indptr, dtype=np.int64).tobytes(),
        np.ascontiguousarray(indices, dtype=np.int64).tobytes(),
    )


@functools.lru_cache(maxsize=16)
def _plan_of_pattern(indptr: bytes, indices: bytes) -> FactorPlan:
    return factor_plan(np.frombuffer(indptr, dtype=np.int64), np.frombuffer(indices, dtype=np.int64))


class StepStats(NamedTuple):
    """Per item of a run (``(m,)`` for tau0, ``(m, V)`` for the variants): accepted and rejected
    steps (``-1``: not integrated, or copied from tau0)."""

    accepted0: np.ndarray
    rejected0: np.ndarray
    accepted: np.ndarray
    rejected: np.ndarray


@njit(cache=True, inline="always")
def _assemble(val, c, s, indptr, indices, w, cl, sl, dd, fp_entry, fp_diag, fp_inv):
    """``val`` = the filled matrix ``D + L(theta)`` (``dd``: the diagonal ``D``; fill entries 0)."""
    val[:] = 0.0
    n = c.shape[0]
    for i in range(n):
        di = dd[i]
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            # w_ij cos(theta_j - theta_i - alpha)
            a = w[q] * (cl * (c[j] * c[i] + s[j] * s[i]) + sl * (s[j] * c[i] - c[j] * s[i]))
            val[fp_entry[q]] -= a
            di += a
        val[fp_diag[fp_inv[i]]] += di


@njit(cache=True, inline="always")
def _factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, scale):
    """The numeric LU in place, each pivot stored as its reciprocal; False where a pivot is
    below ``1e-12 scale`` (not resolved)."""
    n = fp_diag.shape[0]
    for k in range(n):
        piv = val[fp_diag[k]]
        if not abs(piv) > 1e-12 * scale:
            return False
        inv_piv = 1.0 / piv
        val[fp_diag[k]] = inv_piv
        for e in range(div_ptr[k], div_ptr[k + 1]):
            val[div_pos[e]] *= inv_piv
        for e in range(upd_ptr[k], upd_ptr[k + 1]):
            val[upd_ij[e]] -= val[upd_ik[e]] * val[upd_kj[e]]
    return True


@njit(cache=True, inline="always")
def _solve(val, ptr, col, fp_diag, fp_perm, b, x, xp):
    """``x`` (node order) from the factors and ``b`` (node order), through ``xp`` (elimination
    order); ``x`` may be ``b``."""
    n = fp_diag.shape[0]
    for k in range(n):
        xp[k] = b[fp_perm[k]]
    for k in range(n):
        acc = xp[k]
        for q in range(ptr[k], fp_diag[k]):
            acc -= val[q] * xp[col[q]]
        xp[k] = acc
    for k in range(n - 1, -1, -1):
        acc = xp[k]
        for q in range(fp_diag[k] + 1, ptr[k + 1]):
            acc -= val[q] * xp[col[q]]
        xp[k] = acc * val[fp_diag[k]]
    for k in range(n):
        x[fp_perm[k]] = xp[k]


@njit(cache=True, inline="always")
def _near_step(work, n, second, target):
    """The longest step once every frequency deviation is within ``_BAND`` times the tolerance:
    ``_NEAR`` of the tolerance over the fastest deviation's rate (inf while one is farther)."""
    rows = 2 if second else 1
    fastest = 0.0
    for k in range(rows):
        for i in range(n):
            if abs(work[DEV_ROW + 2 * k, i]) > _BAND * target:
                return np.inf
            fastest = max(fastest, abs(work[DEV_ROW + 2 * k + 1, i]))
    return _NEAR * target / fastest if fastest > 0.0 else np.inf


@njit(cache=True, inline="always")
def _eval(th_state, nu_state, c, s, eq, second, f_th, f_nu):
    """``(f_th, f_nu)`` = the model's rates at ``(theta, nu)`` (``c``, ``s`` filled on the way;
    ``eq`` the equations' constants of :func:`~antisync.kernels.core.make_model_kernels`)."""
    n = th_state.shape[0]
    for i in range(n):
        c[i] = math.cos(th_state[i])
        s[i] = math.sin(th_state[i])
    _rhs(c, s, nu_state, eq, second, f_th, f_nu)


@njit(cache=True, inline="always")
def _orders(mass, gamma):
    """``(second, gamma_eff)``: whether any node has inertia, and the damping of each node's
    ``theta'`` (1 everywhere in a first-order model, whose damping is unused)."""
    n = mass.shape[0]
    second = has_inertia(mass)
    gamma_eff = np.empty(n)
    for i in range(n):
        gamma_eff[i] = gamma[i] if second else 1.0
    return second, gamma_eff


@njit(cache=True, inline="always")
def _row_scale(indptr, w):
    """The network's scale for the pivot test: the largest row sum of ``|w|``."""
    scale = 0.0
    for i in range(indptr.shape[0] - 1):
        row = 0.0
        for q in range(indptr[i], indptr[i + 1]):
            row += abs(w[q])
        scale = max(scale, row)
    return max(scale, 1e-300)


@njit(cache=True, inline="always")
def _scratch(n, plan):
    """The arrays of :func:`_attempt`: ``u_th``, ``u_nu`` (the stages, row by stage), ``d_th``,
    ``z_nu`` (a stage's input ``y_th + d_th``, ``z_nu``), ``f_th``, ``f_nu`` (the rates there),
    ``r_th``, ``b``, ``x``, ``xp``, ``c``, ``s``, ``dd`` and the factors ``val``."""
    return (
        np.zeros((6, n)),
        np.zeros((6, n)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.zeros(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(plan.col.shape[0]),
    )


@njit(cache=True, inline="always")
def _attempt(y_th, y_nu, cy, sy, f0_th, f0_nu, h, net, plan, scratch, scale, rtol, atol):
    """One attempted Rodas4 step of size ``h`` from ``(y_th, y_nu)`` (``cy``, ``sy``: the cosines
    and sines of ``y_th``; ``f0_th``, ``f0_nu``: the rates there) on the model ``net = (eq,
    gamma_eff, second)`` (``eq`` as :func:`rodas4_sync` takes it), the LU on ``plan``. Leaves the
    stages in ``scratch`` (``u_th, u_nu, d_th, z_nu, ...``: the new state is ``y_th + d_th +
    u_th[5]``, ``z_nu + u_nu[5]``) and returns the weighted RMS error estimate, or -1 where a
    pivot is not resolved."""
    eq, gamma_eff, second = net
    p, w, indptr, indices, cl, sl, mass, gamma = eq
    fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry = plan[:6]
    div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj = plan[6:]
    u_th, u_nu, d_th, z_nu, f_th, f_nu, r_th, b, x, xp, c, s, dd, val = scratch
    n = y_th.shape[0]
    g = 1.0 / (h * _GAMMA)
    inv_h = 1.0 / h
    for i in range(n):
        dd[i] = g * (mass[i] * g + gamma_eff[i]) if second else g
    # the matrix at the step's start
    _assemble(val, cy, sy, indptr, indices, w, cl, sl, dd, fp_entry, fp_diag, fp_inv)
    if not _factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, scale * (g + 1.0)):
        return -1.0
    for stage in range(6):
        if stage == 0:
            for i in range(n):
                f_th[i] = f0_th[i]
                f_nu[i] = f0_nu[i]
        else:
            if stage < 5:
                for i in range(n):
                    dt_i = 0.0
                    dn_i = y_nu[i]
                    for j in range(stage):
                        dt_i += _A[stage, j] * u_th[j, i]
                        dn_i += _A[stage, j] * u_nu[j, i]
                    d_th[i] = dt_i
                    z_nu[i] = dn_i
            else:
                # stage 6: the stage-5 input plus u5
                for i in range(n):
                    d_th[i] += u_th[4, i]
                    z_nu[i] += u_nu[4, i]
            # cos, sin of y_th + d_th by rotating those of y_th (Taylor for small angles)
            for i in range(n):
                ca, sa = _rotation(d_th[i])
                c[i] = cy[i] * ca - sy[i] * sa
                s[i] = sy[i] * ca + cy[i] * sa
            _rhs(c, s, z_nu, eq, second, f_th, f_nu)
        for i in range(n):
            rt = f_th[i]
            rn = f_nu[i]
            for j in range(stage):
                cj = _C[stage, j] * inv_h
                rt += cj * u_th[j, i]
                rn += cj * u_nu[j, i]
            r_th[i] = rt
            b[i] = mass[i] * rn + (mass[i] * g + gamma_eff[i]) * rt if second else rt
        _solve(val, fp_ptr, fp_col, fp_diag, fp_perm, b, x, xp)
        for i in range(n):
            u_th[stage, i] = x[i]
            u_nu[stage, i] = g * x[i] - r_th[i] if (second and mass[i] > 0.0) else 0.0
    # the new state is the stage-6 input plus u6; u6 is the error estimate
    err = 0.0
    count = 0
    for i in range(n):
        yn = y_th[i] + d_th[i] + u_th[5, i]
        e = u_th[5, i] / (atol + rtol * max(abs(y_th[i]), abs(yn)))
        err += e * e
        count += 1
        if second and mass[i] > 0.0:
            yn = z_nu[i] + u_nu[5, i]
            e = u_nu[5, i] / (atol + rtol * max(abs(y_nu[i]), abs(yn)))
            err += e * e
            count += 1
    err = math.sqrt(err / count)
    return err


@njit(cache=True, inline="always")
def _shrunk(h, err):
    """The step size to retry a rejected step with (never larger): a quarter where
    :func:`_attempt` did not resolve a pivot (``err = -1``), a fifth for a NaN, else the
    error's fourth root with a safety factor, at most five times smaller."""
    if err < 0.0:
        return h * 0.25
    return h * max(_SHRINK, min(1.0, _SAFETY * err**-0.25 if err == err else _SHRINK))


@njit(cache=True)
def rodas4_sync(th0, nu0, eq, criterion, target, t_max, h0, rtol, atol, plan, fixed, after, band):
    """One trajectory from ``(th0, nu0)`` of the model ``eq`` (the equations' constants ``(p,
    w, indptr, indices, cl, sl, mass, gamma)`` of
    :func:`~antisync.kernels.core.make_model_kernels`) until the criterion holds or ``t_max``,
    the LU on ``plan`` (a :class:`FactorPlan`): ``(status, tau, accepted, rejected, failed)``
    (``failed``: the step size fell below ``1e-13 t_max`` or kept being rejected, ``tau`` the
    time reached). ``fixed``: every step ``h0``, accepted whatever its error estimate, the
    crossing on the step's cubic interpolant (the order tests). ``after``, ``band`` (frequency
    criterion): a trajectory whose largest deviation of the criterion (the one it must bring
    below ``target``) has not been below ``band`` at any accepted step by time ``after`` ends
    there with status ``GAVE_UP`` (``sync.give_up``; ``after = inf``: never)."""
    p, w, indptr, indices, cl, sl, mass, gamma = eq
    fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry = plan[:6]
    div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj = plan[6:]
    n = th0.shape[0]
    second, gamma_eff = _orders(mass, gamma)
    freq = criterion == CRIT_FREQUENCY
    # u_1..u_6 for theta and nu, row by stage
    u_th = np.zeros((6, n))
    u_nu = np.zeros((6, n))
    # the state at the step's start: theta, nu, cos and sin of theta, the rates of theta and nu
    state = np.zeros((6, n))
    y_th, y_nu, cy, sy, f0_th, f0_nu = state[0], state[1], state[2], state[3], state[4], state[5]
    copy_into(y_th, th0)
    copy_into(y_nu, nu0)
    kept = np.empty((6, n))  # the state one accepted step back, to redo a step shorter
    d_th = np.empty(n)  # a stage's input: y_th + d_th, z_nu
    z_nu = np.empty(n)
    f_th = np.empty(n)  # rates at the stage input
    f_nu = np.zeros(n)
    r_th = np.empty(n)
    b = np.empty(n)
    x = np.empty(n)
    xp = np.empty(n)
    c = np.empty(n)
    s = np.empty(n)
    dd = np.empty(n)
    val = np.empty(fp_col.shape[0])
    work = np.empty((WORK_ROWS, n))

    _eval(y_th, y_nu, cy, sy, eq, second, f0_th, f0_nu)
    dr2, dev = _measure(cy, sy, f0_th, f0_nu, mass, gamma, second)
    r2 = _order2(cy, sy)
    if freq:
        if dev < target:
            return ALREADY_SYNCED, 0.0, 0, 0, False
        _deviations(cy, sy, f0_th, f0_nu, eq, second, work)
    elif r2 >= target:
        return ALREADY_SYNCED, 0.0, 0, 0, False
    scale = _row_scale(indptr, w)

    # sync.give_up: watched until the largest frequency deviation first falls below band
    watch = freq and after < t_max
    t = 0.0
    h = min(h0, t_max)
    h_cap = t_max  # the step size cap up to ``cap_until``, the end of an unresolved crossing's step
    cap_until = 0.0
    refined = 0
    err_prev = 1.0
    accepted = 0
    rejected = 0
    rejects_in_row = 0
    while t < t_max:
        if h < _H_FLOOR * t_max or rejects_in_row > _MAX_REJECTS:
            return NOT_SYNCED, t, accepted, rejected, True
        last = False
        if t + h >= t_max:
            h = t_max - t
            last = True
        # _attempt's step written out: calling it here (inlined or not) cost this loop 3-5% on
        # IEEE 300 (bench/ab_groups.py, same bits; bench/RESULTS.md, "One kernel family
        # instance, the backends' shared bookkeeping")
        g = 1.0 / (h * _GAMMA)
        inv_h = 1.0 / h
        for i in range(n):
            dd[i] = g * (mass[i] * g + gamma_eff[i]) if second else g
        # the matrix at the step's start
        _assemble(val, cy, sy, indptr, indices, w, cl, sl, dd, fp_entry, fp_diag, fp_inv)
        if not _factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, scale * (g + 1.0)):
            h = _shrunk(h, -1.0)  # a pivot not resolved, as _attempt's -1
            rejected += 1
            rejects_in_row += 1
            continue
        for stage in range(6):
            if stage == 0:
                for i in range(n):
                    f_th[i] = f0_th[i]
                    f_nu[i] = f0_nu[i]
            else:
                if stage < 5:
                    for i in range(n):
                        dt_i = 0.0
                        dn_i = y_nu[i]
                        for j in range(stage):
                            dt_i += _A[stage, j] * u_th[j, i]
                            dn_i += _A[stage, j] * u_nu[j, i]
                        d_th[i] = dt_i
                        z_nu[i] = dn_i
                else:
                    # stage 6: the stage-5 input plus u5
                    for i in range(n):
                        d_th[i] += u_th[4, i]
                        z_nu[i] += u_nu[4, i]
                # cos, sin of y_th + d_th by rotating those of y_th (Taylor for small angles)
                for i in range(n):
                    ca, sa = _rotation(d_th[i])
                    c[i] = cy[i] * ca - sy[i] * sa
                    s[i] = sy[i] * ca + cy[i] * sa
                _rhs(c, s, z_nu, eq, second, f_th, f_nu)
            for i in range(n):
                rt = f_th[i]
                rn = f_nu[i]
                for j in range(stage):
                    cj = _C[stage, j] * inv_h
                    rt += cj * u_th[j, i]
                    rn += cj * u_nu[j, i]
                r_th[i] = rt
                b[i] = mass[i] * rn + (mass[i] * g + gamma_eff[i]) * rt if second else rt
            _solve(val, fp_ptr, fp_col, fp_diag, fp_perm, b, x, xp)
            for i in range(n):
                u_th[stage, i] = x[i]
                u_nu[stage, i] = g * x[i] - r_th[i] if (second and mass[i] > 0.0) else 0.0
        # the new state is the stage-6 input plus u6; u6 is the error estimate
        err = 0.0
        count = 0
        for i in range(n):
            yn = y_th[i] + d_th[i] + u_th[5, i]
            e = u_th[5, i] / (atol + rtol * max(abs(y_th[i]), abs(yn)))
            err += e * e
            count += 1
            if second and mass[i] > 0.0:
                yn = z_nu[i] + u_nu[5, i]
                e = u_nu[5, i] / (atol + rtol * max(abs(y_nu[i]), abs(yn)))
                err += e * e
                count += 1
        err = math.sqrt(err / count)
        if fixed:
            err = 0.0 if err == err else err
        if not err <= 1.0:  # rejected (a NaN too)
            h = _shrunk(h, err)
            rejected += 1
            rejects_in_row += 1
            continue
        rejects_in_row = 0
        accepted += 1
        copy_into(kept, state)
        for i in range(n):
            y_th[i] += d_th[i] + u_th[5, i]
            y_nu[i] = z_nu[i] + u_nu[5, i] if (second and mass[i] > 0.0) else 0.0
        t_prev = t
        t = t_max if last else t + h
        # the criterion on the accepted step (rates at the new state: the next step's stage 1)
        r2_prev = r2
        dr2_prev = dr2
        if freq:
            _copy_rows(work, DEV_PREV_ROW, DEV_ROW, 4)
        _eval(y_th, y_nu, cy, sy, eq, second, f0_th, f0_nu)
        if freq:
            _deviations(cy, sy, f0_th, f0_nu, eq, second, work)
            xc = _frequency_crossing(work, n, second, t - t_prev, True, target)
        else:
            r2 = _order2(cy, sy)
            dr2, dev = _measure(cy, sy, f0_th, f0_nu, mass, gamma, second)
            xc = _order_crossing(r2_prev, dr2_prev, r2, dr2, t - t_prev, True, target)
        if xc >= 0.0:
            # the cubic interpolant is trusted where the straight line agrees with it to
            # _CROSSING_RTOL of the time; else the step is redone shorter, up to the crossing
            if freq:
                xl = _frequency_crossing(work, n, second, t - t_prev, False, target)
            else:
                xl = _order_crossing(r2_prev, dr2_prev, r2, dr2, t - t_prev, False, target)
            tau = t_prev + xc * (t - t_prev)
            if (
                xl >= 0.0 and abs(xc - xl) * (t - t_prev) <= _CROSSING_RTOL * tau
            ) or t - t_prev <= _H_FLOOR * 1e3 * t_max:
                return SYNCED, tau, accepted, rejected, False
            copy_into(state, kept)
            if freq:
                _copy_rows(work, DEV_ROW, DEV_PREV_ROW, 4)
            r2 = r2_prev
            dr2 = dr2_prev
            h_cap = _REFINE * (t - t_prev)
            cap_until = t
            h = h_cap
            t = t_prev
            accepted -= 1
            refined += 1
            continue
        if watch:
            # the criterion's own deviations (with inertia also g_i's) at the step's end
            if _largest_deviation(work, n, 2 if second else 1, 0.0, False, 1.0) < band:
                watch = False
            elif t >= after:
                return GAVE_UP, t, accepted, rejected, False
        # a PI controller (Gustafsson): the error now and one step back
        err = max(err, 1e-10)
        fac = _SAFETY * err**-_BETA1 * err_prev**_BETA2
        err_prev = err
        if t >= cap_until:
            h_cap = t_max  # past the step whose crossing was not resolved
        if not fixed:
            h = min(h * max(_SHRINK, min(_GROW, fac)), h_cap)
            # near the criterion, a step may move a tested quantity by at most _NEAR of the
            # band it must cross, so that the cubic interpolant sees a short dip into it
            if freq:
                h = min(h, _near_step(work, n, second, target))
            elif dr2 != 0.0:
                h = min(h, _NEAR * max(target - r2, n * n - target) / abs(dr2))
    return NOT_SYNCED, t_max, accepted, rejected, False


@njit(cache=True, inline="always")
def speed_rates(cy, sy, f_th, f_nu, indptr, indices, w, mass, gamma, acc):
    """``acc`` = the rates of the speeds ``theta_i'``: ``nu_i'`` with inertia, else ``sum_j w_ij
    cos(theta_j - theta_i) (theta_j' - theta_i') / gamma_i`` (no phase lag; ``gamma_i`` 1 in a
    first-order model): the slopes of a trip's speed interpolants (its largest ``|theta_i'|``)."""
    n = cy.shape[0]
    for i in range(n):
        if mass[i] > 0.0:
            acc[i] = f_nu[i]
        else:
            kd = 0.0
            for q in range(indptr[i], indptr[i + 1]):
                j = indices[q]
                kd += w[q] * (cy[j] * cy[i] + sy[j] * sy[i]) * (f_th[j] - f_th[i])
            acc[i] = kd / gamma[i]


@njit(cache=True, inline="always")
def trip_swing(p_th, p_d, p_f, p_acc, th, d, f, acc, step, indptr, indices, line, max_f, max_a):
    """The largest ``|f_i|`` (``theta_i'``) and line angle difference ``|theta_i - theta_j|`` over
    one step of a trip, on the cubic Hermite interpolants from the values and rates at both ends
    (``p_``: the step's start; ``d`` the phases' rates, ``acc`` the frequencies'; the built-in
    model's ``d`` is its ``f``, a law's frequency quantity need not be its phase's rate);
    ``line = (a, b, keep)``: the tripped line is left out when ``keep`` is 0. Returns the
    running maxima ``(max_f, max_a)``."""
    ta, tb, keep = line
    for i in range(th.shape[0]):
        lo, hi = _hermite_range(p_f[i], step * p_acc[i], f[i], step * acc[i])
        max_f = max(max_f, -lo, hi)
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            if j > i and not (keep == 0.0 and ((i == ta and j == tb) or (i == tb and j == ta))):
                lo, hi = _hermite_range(
                    p_th[i] - p_th[j], step * (p_d[i] - p_d[j]), th[i] - th[j], step * (d[i] - d[j])
                )
                max_a = max(max_a, -lo, hi)
    return max_f, max_a


@njit(cache=True, inline="always")
def trip_rates(cy, sy, f_th, f_nu, eq, second, gamma, acc, work):
    """At a trip's state (``cy``, ``sy`` its cosines and sines, ``f_th``, ``f_nu`` its rates on
    the weights of ``eq``): the frequency criterion's deviations into ``work``
    (:func:`~antisync.kernels.core.make_model_kernels`' ``deviations``) and the speeds' rates
    into ``acc`` (:func:`speed_rates`; ``gamma`` 1 in a first-order model)."""
    _, w, indptr, indices, _, _, mass, _ = eq
    _deviations(cy, sy, f_th, f_nu, eq, second, work)
    speed_rates(cy, sy, f_th, f_nu, indptr, indices, w, mass, gamma, acc)


@njit(cache=True, inline="always")
def trip_switch(work, n, second, tol, t, settle):
    """The settling clock where a trip's configuration starts (the fault at ``t = 0``, the trip
    at its clearing time), from the deviations of the state at ``t`` on the new weights: ``nan``
    when one is out of the band, else the time from which they have been in it."""
    if _largest_deviation(work, n, 2 if second else 1, 0.0, False, 1.0) >= tol:
        return np.nan
    return t if settle != settle else settle


@njit(cache=True, inline="always")
def trip_band(work, n, second, t_prev, step, tol, settle):
    """The settling clock of a trip after one step: the frequency criterion of ``sync: {criterion:
    frequency}`` (every ``theta_i' - mean`` and, with inertia, every ``g_i - mean g`` within
    ``tol``; :func:`~antisync.kernels.core.make_model_kernels`' deviations, in ``work``'s rows
    now and one step back) on the step's interpolants. Returns the time from which every
    deviation has stayed in the band (``nan``: out of it at the step's end): entered inside the
    step (located on the interpolants), or an excursion out of it between two in-band ends
    (the step's end)."""
    rows = 2 if second else 1
    if _largest_deviation(work, n, rows, step, True, 1.0) >= tol:
        return np.nan
    if settle != settle:
        x = _frequency_crossing(work, n, second, step, True, tol)
        return t_prev + (x if x >= 0.0 else 1.0) * step
    for i in range(n):
        for k in range(rows):
            row = DEV_ROW + 2 * k
            lo, hi = _hermite_range(
                work[DEV_PREV_ROW + 2 * k, i],
                step * work[DEV_PREV_ROW + 2 * k + 1, i],
                work[row, i],
                step * work[row + 1, i],
            )
            if hi >= tol or lo <= -tol:
                return t_prev + step
    return settle


@njit(cache=True)
def rodas4_trip(th0, grid, w_fault, w_post, t_clear, t_end, h0, tols, plan, line, out):
    """A contingency from the state ``th0`` at rest: the swing equation (no phase lag) on the
    weights ``w_fault`` until ``t_clear`` (none when 0), then on ``w_post`` until ``t_end``, by
    Rodas4 with adaptive steps; the step that would pass ``t_clear`` ends there and the next
    starts afresh at ``h0``. ``grid``: ``(p, indptr, indices, mass, gamma)``; ``tols``: the
    frequency band, ``rtol`` and ``atol``; ``line``: ``(a, b, keep)``, the tripped line, left
    out of the angle differences when ``keep`` is 0.

    ``out`` = ``[settle_time, max_frequency, max_angle, failed]`` on the integrator's dense
    output (each accepted step's cubic Hermite interpolants, :func:`trip_swing` and
    :func:`trip_band`): the largest ``|theta_i'|`` and ``|theta_i - theta_j|`` over the
    interpolants, and the time (from ``t = 0``, the fault's start) from which the frequency
    criterion has held until ``t_end`` (``nan`` if it does not hold there). ``failed`` (1): the
    step size collapsed (the other values are those reached). The RK4 twin is
    :func:`antisync.kernels.trip.rk4_trip`."""
    p, indptr, indices, mass, gamma = grid
    tol, rtol, atol = tols
    n = th0.shape[0]
    second, gamma_eff = _orders(mass, gamma)
    scratch = _scratch(n, plan)
    u_th, u_nu, d_th, z_nu = scratch[:4]
    y_th = th0.copy()
    y_nu = np.zeros(n)
    cy = np.empty(n)
    sy = np.empty(n)
    f0_th = np.empty(n)
    f0_nu = np.zeros(n)
    acc = np.empty(n)
    p_th = np.empty(n)  # the state, speeds and their rates at the accepted step's start
    p_f = np.empty(n)
    p_acc = np.empty(n)
    work = np.zeros((WORK_ROWS, n))
    fault = t_clear > 0.0
    w = w_fault if fault else w_post
    eq = (p, w, indptr, indices, 1.0, 0.0, mass, gamma)
    net = (eq, gamma_eff, second)
    _eval(y_th, y_nu, cy, sy, eq, second, f0_th, f0_nu)
    trip_rates(cy, sy, f0_th, f0_nu, eq, second, gamma_eff, acc, work)
    settle = trip_switch(work, n, second, tol, 0.0, np.nan)
    max_f = 0.0  # over the accepted steps' interpolants, which hold their ends
    max_a = 0.0
    scale = _row_scale(indptr, w_post)
    t = 0.0
    end = t_clear if fault else t_end  # the end of the current configuration
    h = min(h0, end)
    err_prev = 1.0
    rejects_in_row = 0
    failed = 0.0
    while t < t_end:
        if h < _H_FLOOR * t_end or rejects_in_row > _MAX_REJECTS:
            failed = 1.0
            break
        last = False
        if t + h >= end:
            h = end - t
            last = True
        err = _attempt(y_th, y_nu, cy, sy, f0_th, f0_nu, h, net, plan, scratch, scale, rtol, atol)
        if not 0.0 <= err <= 1.0:
            h = _shrunk(h, err)
            rejects_in_row += 1
            continue
        rejects_in_row = 0
        for i in range(n):
            p_th[i] = y_th[i]
            p_f[i] = f0_th[i]
            p_acc[i] = acc[i]
            y_th[i] += d_th[i] + u_th[5, i]
            y_nu[i] = z_nu[i] + u_nu[5, i] if (second and mass[i] > 0.0) else 0.0
        t_prev = t
        t = end if last else t + h
        step = t - t_prev
        _copy_rows(work, DEV_PREV_ROW, DEV_ROW, 4)
        _eval(y_th, y_nu, cy, sy, eq, second, f0_th, f0_nu)
        trip_rates(cy, sy, f0_th, f0_nu, eq, second, gamma_eff, acc, work)
        max_f, max_a = trip_swing(
            p_th, p_f, p_f, p_acc, y_th, f0_th, f0_th, acc, step, indptr, indices, line, max_f, max_a
        )
        settle = trip_band(work, n, second, t_prev, step, tol, settle)
        # a PI controller (Gustafsson), and within the band's reach at most half of it per step
        err = max(err, 1e-10)
        fac = _SAFETY * err**-_BETA1 * err_prev**_BETA2
        err_prev = err
        h = h * max(_SHRINK, min(_GROW, fac))
        if last and t < t_end:
            # the fault clears: the grid without the line from this state on
            w = w_post
            eq = (p, w, indptr, indices, 1.0, 0.0, mass, gamma)
            net = (eq, gamma_eff, second)
            end = t_end
            _eval(y_th, y_nu, cy, sy, eq, second, f0_th, f0_nu)
            trip_rates(cy, sy, f0_th, f0_nu, eq, second, gamma_eff, acc, work)
            settle = trip_switch(work, n, second, tol, t, settle)
            h = h0
            err_prev = 1.0
        h = min(h, _near_step(work, n, second, tol))
    out[0] = settle
    out[1] = max_f
    out[2] = max_a
    out[3] = failed


@njit(cache=True)
def _integrate_item(ks, seed, graph, model, fp, dt, t_max, tols, max_steps, out, counts, item):
    """Item ``item`` of a batch, a (realization, network) pair, with its own step sizes (every
    item in parallel, one per thread iteration: :func:`_integrate_items`); ``counts`` ``(acc0,
    rej0, acc, rej, failed)`` gets its accepted and rejected steps and whether the step size
    failed; ``tols``: ``(rtol, atol, after, band)`` (:func:`rodas4_sync`)."""
    acc0, rej0, acc, rej, failed = counts
    indptr, indices, base_w, var_w, var_is_base, todo = graph
    freqs, cl, sl, inertia, damping, criterion, targets, starts = model
    rtol, atol, after, band = tols
    n = indptr.shape[0] - 1
    r, v, run = item_of(item, var_w.shape[0] + 1, var_is_base, todo)
    if not run:
        return
    th = np.empty(n)
    nu = np.zeros(n)
    for i in range(n):
        th[i] = start_phase(starts, seed, ks[r], r, i)
    p = freqs[r] if freqs.shape[0] > 1 else freqs[0]
    w = base_w if v < 0 else var_w[v]
    eq = (p, w, indptr, indices, cl, sl, inertia, damping)
    st, tau, n_acc, n_rej, bad = rodas4_sync(
        th, nu, eq, criterion, targets[v + 1], t_max, dt, rtol, atol, fp, np.bool_(False), after, band
    )
    k, x = _on_the_grid(st, tau, dt, max_steps)
    record_item(out, r, v, st, k, x)
    if v < 0:
        acc0[r] = n_acc
        rej0[r] = n_rej
    else:
        acc[r, v] = n_acc
        rej[r, v] = n_rej
    if bad:
        failed[r, v + 1] = True


def _integrate_items(item, ks, seed, graph, model, fp, dt, t_max, tols, max_steps, out, counts):
    """``item`` (:func:`_integrate_item`) of every (realization, network) pair, in parallel (the
    layout of :func:`antisync.kernels.cpu._integrate_items`; compiled by
    :func:`antisync.kernels.loops.run`)."""
    for i in prange(ks.shape[0] * (graph.var_w.shape[0] + 1)):
        item(ks, seed, graph, model, fp, dt, t_max, tols, max_steps, out, counts, np.int64(i))


@njit(cache=True)
def _on_the_grid(st, tau, dt, max_steps):
    """``(steps, frac)`` with ``tau = (steps - 1 + frac) dt``, ``frac`` in ``(0, 1]``, as the
    explicit drivers store a crossing; ``(0, 0)`` already synchronized, ``(max_steps, 0)`` not."""
    if st == ALREADY_SYNCED:
        return 0, 0.0
    if st != SYNCED:
        return max_steps, 0.0
    u = tau / dt
    k = int(math.ceil(u))
    if k < 1:
        k = 1
    if k > max_steps:
        return max_steps, 1.0
    x = u - (k - 1)
    return k, min(1.0, max(x, 1e-300))


def simulate_model(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    params: ModelParams,
    *,
    dt: float,
    max_steps: int,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    todo: np.ndarray | None = None,
    plan: FactorPlan | None = None,
    stats: bool = False,
    give_up: tuple[float, float] | None = None,
) -> SimResult | tuple[SimResult, StepStats]:
    """Integrate realizations ``first .. first+count-1`` of a generalized model by Rodas4 for
    the base network and every variant: the arguments of
    :func:`antisync.kernels.cpu.simulate_model` (``dt`` the first step and the unit of the
    stored times, ``t_max = max_steps dt``) plus the tolerances ``rtol``, ``atol`` and the
    pattern's :func:`factor_plan` (made once per pattern in a process when None); ``give_up``:
    ``(after, band)`` of ``sync.give_up`` (frequency criterion), None: every trajectory runs to
    its criterion or ``t_max``.

    Returns a :class:`~antisync.kernels.shared.SimResult` (``tau = (steps - 1 + frac) dt``),
    and with ``stats`` also the :class:`StepStats`. A trajectory whose step size collapses (a
    pivot or an error estimate never resolved) raises ``FloatingPointError`` naming it, never a
    status.
    """
    if not (rtol > 0 and atol > 0):
        raise ValueError(f"rtol and atol must be positive, got {rtol}, {atol}")
    ks, graph, model, out = model_batch(
        first, count, realizations, indptr, indices, base_weights, variant_weights, params, "rodas4", todo
    )
    if give_up is not None and not (model.criterion == CRIT_FREQUENCY and give_up[0] > 0 and give_up[1] > 0):
        raise ValueError(
            f"give_up (after, band) needs the frequency criterion and positive values, got {give_up}"
        )
    m = ks.size
    n_var = graph.var_w.shape[0]
    if plan is None:
        plan = plan_of_pattern(indptr, indices)
    after, band = (math.inf, 0.0) if give_up is None else (float(give_up[0]), float(give_up[1]))
    acc0 = np.full(m, -1, dtype=np.int64)
    rej0 = np.full(m, -1, dtype=np.int64)
    acc = np.full((m, n_var), -1, dtype=np.int64)
    rej = np.full((m, n_var), -1, dtype=np.int64)
    failed = np.zeros((m, n_var + 1), dtype=np.bool_)
    t_max = float(dt) * int(max_steps)
    # one item at a time per thread: a start that never locks runs ~6x the steps of one that does
    with Threads(threads), numba.parallel_chunksize(1):
        loops.run(
            _integrate_items,
            _integrate_item,
            ks,
            np.uint64(seed),
            graph,
            model,
            plan,
            float(dt),
            t_max,
            (float(rtol), float(atol), after, band),
            int(max_steps),
            out,
            (acc0, rej0, acc, rej, failed),
        )
    share_rows(graph.var_is_base, out)
    check_collapsed(failed, ks)
    result = SimResult(out.status0, out.steps0, out.status, out.steps, out.frac0, out.frac)
    return (result, StepStats(acc0, rej0, acc, rej)) if stats else result
