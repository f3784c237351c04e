"""CPU backend: a ``prange`` batch driver over realizations around the shared step functions.

Layers (as in stumpy): the step/sync functions of :mod:`antisync_cli.kernels.core` integrate
one trajectory; :func:`_integrate_batch` runs a batch of realizations in parallel, each
realization integrating the undamaged network once (``tau0``) and then every damage variant
from the same initial phases; :func:`simulate` is the public, validated entry point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from antisync_cli.kernels.core import make_kernels
from antisync_cli.kernels.core import RENORM_EVERY, TAYLOR_MAX_ANGLE
from antisync_cli.phases import phase
from antisync_cli.status import Status

__all__ = ["SimResult", "simulate"]

_K = make_kernels(lambda f: njit(f, inline="always", cache=True))
_sync_steps = _K["sync_steps"]
_step_lanes = _K["euler_step_lanes"]
_renormalize = _K["renormalize"]

LANES = 32
"""Realizations stepped together by one thread (the ``[node, lane]`` layout's inner width)."""
_SYNCED = int(Status.SYNCED)
_ALREADY = int(Status.ALREADY_SYNCED)
_NOT_SYNCED = int(Status.NOT_SYNCED)


@njit(parallel=True, cache=True)
def _integrate_batch(
    seed, first, indptr, indices, base_w, var_w, var_is_base, dt, r2_target, max_steps,
    status0, steps0, status, steps,
):
    m = status0.shape[0]
    n = indptr.shape[0] - 1
    n_var = var_w.shape[0]
    for r in prange(m):
        theta = np.empty(n)
        c = np.empty(n)
        s = np.empty(n)
        acc = np.empty(n)
        for i in range(n):
            theta[i] = phase(seed, first + r, i)
            c[i] = np.cos(theta[i])
            s[i] = np.sin(theta[i])
        st, k = _sync_steps(c, s, acc, indptr, indices, base_w, dt, r2_target, max_steps)
        status0[r] = st
        steps0[r] = k
        for v in range(n_var):
            if var_is_base[v]:
                # this damage leaves W unchanged (e.g. a link leaving a degree-1 node)
                status[r, v] = st
                steps[r, v] = k
                continue
            for i in range(n):
                c[i] = np.cos(theta[i])
                s[i] = np.sin(theta[i])
            st_v, k_v = _sync_steps(c, s, acc, indptr, indices, var_w[v], dt, r2_target, max_steps)
            status[r, v] = st_v
            steps[r, v] = k_v


@njit(inline="always")
def _next_item(r, v, r_hi, var_is_base):
    """Advance the work cursor (realization r, variant v; v = -1 is the undamaged network),
    skipping variants whose weights equal the base (their result is copied afterwards)."""
    n_var = var_is_base.shape[0]
    while True:
        v += 1
        if v == n_var:
            v = -1
            r += 1
        if r >= r_hi or v < 0 or not var_is_base[v]:
            return r, v


@njit(inline="always")
def _load_lane(q, qr, qv, r_hi, seed, first, base_w, var_w, var_is_base, r2_target, c, s, lw,
               ci, si, lane_r, lane_v, lane_k, status0, steps0, status, steps):
    """Put the next queued item that needs integrating into lane ``q``.

    Items already synchronized at t = 0 are recorded on the spot. Returns the advanced cursor
    and 1 if the lane was filled, 0 if the queue is empty.
    """
    n = c.shape[0]
    while qr < r_hi:
        r, v = qr, qv
        qr, qv = _next_item(qr, qv, r_hi, var_is_base)
        sum_c = 0.0
        sum_s = 0.0
        for i in range(n):
            th = phase(seed, first + r, i)
            ci[i] = np.cos(th)
            si[i] = np.sin(th)
            sum_c += ci[i]
            sum_s += si[i]
        if sum_c * sum_c + sum_s * sum_s >= r2_target:
            if v < 0:
                status0[r] = _ALREADY
                steps0[r] = 0
            else:
                status[r, v] = _ALREADY
                steps[r, v] = 0
            continue
        for i in range(n):
            c[i, q] = ci[i]
            s[i, q] = si[i]
        for p in range(lw.shape[0]):
            lw[p, q] = base_w[p] if v < 0 else var_w[v, p]
        lane_r[q] = r
        lane_v[q] = v
        lane_k[q] = 0
        return qr, qv, 1
    return qr, qv, 0


@njit(parallel=True, cache=True)
def _integrate_lanes(
    seed, first, indptr, indices, base_w, var_w, var_is_base, dt, r2_target, max_steps, taylor,
    lanes, n_groups, status0, steps0, status, steps,
):
    m = status0.shape[0]
    n = indptr.shape[0] - 1
    nnz = base_w.shape[0]
    n_var = var_w.shape[0]
    per = (m + n_groups - 1) // n_groups
    for group in prange(n_groups):
        r_lo = group * per
        r_hi = min(m, r_lo + per)
        if r_lo >= r_hi:
            continue
        c = np.empty((n, lanes))
        s = np.empty((n, lanes))
        acc = np.empty((n, lanes))
        lw = np.empty((nnz, lanes))
        sc = np.empty(lanes)
        ss = np.empty(lanes)
        r2 = np.empty(lanes)
        lane_r = np.full(lanes, -1, dtype=np.int64)
        lane_v = np.zeros(lanes, dtype=np.int64)
        lane_k = np.zeros(lanes, dtype=np.int64)
        ci = np.empty(n)
        si = np.empty(n)
        qr, qv = r_lo, -1
        active = 0
        for q in range(lanes):
            qr, qv, filled = _load_lane(q, qr, qv, r_hi, seed, first, base_w, var_w, var_is_base,
                                        r2_target, c, s, lw, ci, si, lane_r, lane_v, lane_k,
                                        status0, steps0, status, steps)
            active += filled
        while active > 0:
            _step_lanes(c, s, acc, sc, ss, lw, indptr, indices, dt, r2, taylor)
            for q in range(lanes):
                if lane_r[q] < 0:
                    continue
                lane_k[q] += 1
                k = lane_k[q]
                if r2[q] >= r2_target:
                    st = _SYNCED
                elif k >= max_steps:
                    st = _NOT_SYNCED
                else:
                    if k % RENORM_EVERY == 0:
                        for i in range(n):
                            inv = 1.0 / np.sqrt(c[i, q] * c[i, q] + s[i, q] * s[i, q])
                            c[i, q] *= inv
                            s[i, q] *= inv
                    continue
                r = lane_r[q]
                v = lane_v[q]
                if v < 0:
                    status0[r] = st
                    steps0[r] = k
                else:
                    status[r, v] = st
                    steps[r, v] = k
                lane_r[q] = -1
                active -= 1
                qr, qv, filled = _load_lane(q, qr, qv, r_hi, seed, first, base_w, var_w, var_is_base,
                                            r2_target, c, s, lw, ci, si, lane_r, lane_v, lane_k,
                                            status0, steps0, status, steps)
                active += filled
        # variants that leave W unchanged share the undamaged result
        for r in range(r_lo, r_hi):
            for v in range(n_var):
                if var_is_base[v]:
                    status[r, v] = status0[r]
                    steps[r, v] = steps0[r]


@dataclass(frozen=True)
class SimResult:
    """Per-realization outcome of a batch (integration steps; ``tau = steps * dt``).

    Attributes
    ----------
    status0, steps0 : arrays, shape (m,)
        :class:`~antisync_cli.status.Status` code and steps of the undamaged network.
    status, steps : arrays, shape (m, V)
        The same for each damage variant ``v``.
    """

    status0: np.ndarray
    steps0: np.ndarray
    status: np.ndarray
    steps: np.ndarray


def _row_sum_bound(indptr, base_w, var_w) -> float:
    """Largest sum_j |w_ij| over rows of the base and every variant (bounds |omega_i|)."""
    rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
    best = 0.0
    for w in (base_w, *var_w):
        best = max(best, float(np.bincount(rows, np.abs(w), minlength=indptr.size - 1).max()))
    return best


def simulate(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    *,
    dt: float,
    threshold: float,
    max_steps: int,
    threads: int | None = None,
    lanes: int = LANES,
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` for the base network and every variant.

    Parameters
    ----------
    seed, first, count : int
        Realization ``k`` starts from :func:`antisync_cli.phases.phase` ``(seed, k, node)``.
    indptr, indices, base_weights : arrays
        CSR form of ``W(Omega)`` (see :class:`antisync_cli.coupling.CouplingCSR`).
    variant_weights : array, shape (V, nnz)
        CSR weights of each damaged ``W(Omega*)`` on the same pattern.
    dt, threshold, max_steps
        Euler step, order-parameter threshold ``r`` and the step cap (``t_max / dt``).
    threads : int, optional
        Numba threads for this call (results do not depend on it).
    lanes : int
        Trajectories stepped together per thread; ``0`` selects the plain one-trajectory-at-a-
        time driver. Results are identical either way (same operations in the same order).
    """
    n = indptr.size - 1
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base_weights.size)
    var_is_base = np.array([np.array_equal(w, base_weights) for w in var_w], dtype=np.bool_)
    status0 = np.empty(count, dtype=np.int8)
    steps0 = np.empty(count, dtype=np.int64)
    status = np.empty((count, var_w.shape[0]), dtype=np.int8)
    steps = np.empty((count, var_w.shape[0]), dtype=np.int64)
    r2_target = (threshold * n) ** 2
    previous = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    args = (np.uint64(seed), np.uint64(first), indptr.astype(np.int64), indices.astype(np.int64),
            base_weights.astype(np.float64), var_w, var_is_base, float(dt), r2_target, int(max_steps))
    try:
        if lanes:
            # |alpha_i| = dt |omega_i| <= dt sum_j |w_ij|: the Taylor rotation is always valid
            bound = float(dt) * _row_sum_bound(indptr, base_weights, var_w)
            groups = 4 * numba.get_num_threads()
            _integrate_lanes(*args, bound <= TAYLOR_MAX_ANGLE, int(lanes), groups,
                             status0, steps0, status, steps)
        else:
            _integrate_batch(*args, status0, steps0, status, steps)
    finally:
        numba.set_num_threads(previous)
    return SimResult(status0, steps0, status, steps)
