"""CPU driver of the generalized models (natural frequencies, phase lag, inertia; docs/models.md).

One trajectory per thread: a parallel loop over (realization, variant) items, each integrated
by :func:`antisync.kernels.core.make_model_kernels`' ``sync_steps`` from the realization's
counter-based phases (and natural frequencies). The identical first-order model never comes
here: it keeps the default lane driver of :mod:`antisync.kernels.cpu`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER, WORK_ROWS, make_kernels, make_model_kernels
from antisync.kernels.cpu import SimResult, _realization_ids, _Threads
from antisync.phases import make_uniform, phase

__all__ = ["ModelParams", "draw_frequencies", "simulate_model"]

#: Counter streams of :func:`antisync.phases.make_uniform` used by the natural frequencies (the
#: initial phases are the separate hash :func:`antisync.phases.phase`).
STREAM_FREQ_A = 1
STREAM_FREQ_B = 2

_jit = lambda f: njit(f, inline="always", cache=True)  # noqa: E731
_MK = make_model_kernels(_jit, make_kernels(_jit))
_model_sync = _MK.sync_steps


class ModelParams(NamedTuple):
    """The model's constants for a kernel (see :class:`antisync.model.Model`).

    ``freqs`` has one row (the same frequencies for every realization) or one row per
    realization of the batch, mean already removed; ``inertia`` and ``damping`` one number or
    one per node (``damping`` must be 1 where no node has inertia); ``targets[0]`` is the undamaged network's
    and ``targets[1 + v]`` variant ``v``'s: ``R = (r N)^2`` at the order-parameter or relative
    threshold, or the frequency tolerance.
    """

    freqs: np.ndarray
    cos_lag: float
    sin_lag: float
    inertia: float | np.ndarray
    damping: float | np.ndarray
    criterion: int
    targets: np.ndarray


@njit(parallel=True, cache=True)
def _integrate_items(
    ks,
    seed,
    indptr,
    indices,
    base_w,
    var_w,
    var_is_base,
    freqs,
    cl,
    sl,
    inertia,
    damping,
    dt,
    rk4,
    criterion,
    targets,
    max_steps,
    todo,
    status0,
    steps0,
    frac0,
    status,
    steps,
    frac,
):
    m = ks.shape[0]
    n = indptr.shape[0] - 1
    n_var = var_w.shape[0]
    per = n_var + 1
    for item in prange(m * per):
        r = item // per
        v = item % per - 1
        if v >= 0 and var_is_base[v]:
            continue  # copied from the undamaged result below
        if todo.shape[0] > 0 and not todo[r, v + 1]:
            continue  # not asked for: left at -1 / NaN
        c = np.empty(n)
        s = np.empty(n)
        nu = np.zeros(n)
        th = np.empty(n)
        dnu = np.zeros(n)
        work = np.empty((WORK_ROWS, n))
        for i in range(n):
            theta = phase(seed, ks[r], i)
            c[i] = np.cos(theta)
            s[i] = np.sin(theta)
        p = freqs[r] if freqs.shape[0] > 1 else freqs[0]
        w = base_w if v < 0 else var_w[v]
        st, k, x = _model_sync(
            c,
            s,
            nu,
            th,
            dnu,
            work,
            p,
            indptr,
            indices,
            w,
            cl,
            sl,
            inertia,
            damping,
            dt,
            rk4,
            criterion,
            targets[v + 1],
            max_steps,
        )
        if v < 0:
            status0[r] = st
            steps0[r] = k
            frac0[r] = x
        else:
            status[r, v] = st
            steps[r, v] = k
            frac[r, v] = x
    for r in prange(m):
        for v in range(n_var):
            if var_is_base[v]:
                status[r, v] = status0[r]
                steps[r, v] = steps0[r]
                frac[r, v] = frac0[r]


def _per_node(value, n: int) -> np.ndarray:
    """Inertia or damping as the kernels' per-node array (a number is every node's)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))


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
    integrator: str = "euler",
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    todo: np.ndarray | None = None,
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` of a generalized model for the base
    network and every variant (same arguments as :func:`antisync.kernels.cpu.simulate`, plus
    the model's ``params``; ``threshold`` is in ``params.targets``). ``todo`` (bool, ``(m, V +
    1)``) integrates only the marked items, as in :func:`antisync.kernels.cpu.simulate`: the
    others get status and steps ``-1`` and ``frac`` NaN.

    Returns a :class:`~antisync.kernels.cpu.SimResult` with ``frac0``/``frac`` (where inside
    the last step the criterion is met).
    """
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    if params.criterion not in (CRIT_ORDER, CRIT_FREQUENCY):
        raise ValueError(f"unknown criterion code {params.criterion}")
    ks = _realization_ids(first, count, realizations)
    m = ks.size
    base_weights = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base_weights.size)
    n_var = var_w.shape[0]
    var_is_base = np.array([np.array_equal(w, base_weights) for w in var_w], dtype=np.bool_)
    if todo is None:
        todo = np.zeros((0, 0), dtype=np.bool_)
    else:
        todo = np.ascontiguousarray(todo, dtype=np.bool_)
        if todo.shape != (m, n_var + 1):
            raise ValueError(f"todo must have shape {(m, n_var + 1)}, got {todo.shape}")
        # a variant equal to the base is integrated, not copied from a base that may not run
        var_is_base[:] = False
    freqs = np.ascontiguousarray(params.freqs, dtype=np.float64)
    n = indptr.size - 1
    if freqs.ndim != 2 or freqs.shape[1] != n or freqs.shape[0] not in (1, m):
        raise ValueError(f"freqs must have shape (1, {n}) or ({m}, {n}), got {freqs.shape}")
    targets = np.ascontiguousarray(params.targets, dtype=np.float64)
    if targets.shape != (n_var + 1,):
        raise ValueError(f"targets must have shape ({n_var + 1},), got {targets.shape}")
    status0 = np.full(m, -1, dtype=np.int8)
    steps0 = np.full(m, -1, dtype=np.int64)
    frac0 = np.full(m, np.nan)
    status = np.full((m, n_var), -1, dtype=np.int8)
    steps = np.full((m, n_var), -1, dtype=np.int64)
    frac = np.full((m, n_var), np.nan)
    with _Threads(threads):
        _integrate_items(
            ks,
            np.uint64(seed),
            indptr.astype(np.int64),
            indices.astype(np.int64),
            base_weights,
            var_w,
            var_is_base,
            freqs,
            float(params.cos_lag),
            float(params.sin_lag),
            _per_node(params.inertia, n),
            _per_node(params.damping, n),
            float(dt),
            integrator == "rk4",
            int(params.criterion),
            targets,
            int(max_steps),
            todo,
            status0,
            steps0,
            frac0,
            status,
            steps,
            frac,
        )
    return SimResult(status0, steps0, status, steps, frac0, frac)


def lag_terms(phase_lag: float) -> tuple[float, float]:
    """``(cos alpha, sin alpha)``; exactly ``(1.0, 0.0)`` for ``alpha = 0``."""
    return math.cos(phase_lag), math.sin(phase_lag)


_uniform = make_uniform(lambda f: njit(f, inline="always"))


@njit(cache=True)
def _fill_frequencies(seed, ks, n, normal, mean, scale, out):
    for r in range(ks.shape[0]):
        for i in range(n):
            u1 = _uniform(seed, ks[r], i, STREAM_FREQ_A)
            if normal:
                # Box-Muller: 1 - u1 in (0, 1], so the logarithm is finite
                u2 = _uniform(seed, ks[r], i, STREAM_FREQ_B)
                z = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
                out[r, i] = mean + scale * z
            else:
                out[r, i] = mean + scale * (2.0 * u1 - 1.0)


def draw_frequencies(spec: dict, seed: int, ks: np.ndarray, n: int) -> np.ndarray:
    """Natural frequencies of realizations ``ks`` (shape ``(len(ks), n)``), mean not removed.

    ``normal``: ``mean + sd z`` with ``z`` from Box-Muller on two counter streams;
    ``uniform``: ``mean + width (2 u - 1)``. Keyed by ``(seed, k, node)`` like the phases, so
    chunks, threads and backends cannot change them.
    """
    ks = np.ascontiguousarray(ks, dtype=np.uint64)
    out = np.empty((ks.size, n))
    normal = spec["distribution"] == "normal"
    scale = spec["sd"] if normal else spec["width"]
    _fill_frequencies(np.uint64(seed), ks, n, normal, float(spec.get("mean", 0.0)), float(scale), out)
    return out
