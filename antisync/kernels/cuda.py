"""CUDA backend: grid-stride kernels around the shared step functions, plus device reductions.

Layers (as in stumpy's ``gpu_stump``): the step/sync functions of
:mod:`antisync.kernels.core` and the phase hash of :mod:`antisync.physics.phases`, compiled with
``cuda.jit(device=True)``, integrate one trajectory; private kernels run one trajectory per
thread; host wrappers move arrays with ``to_device`` / ``copy_to_host``; :func:`simulate` and
:func:`simulate_reduced` are the public, validated entry points.

Each batch takes two launches: ``tau0`` (one thread per realization) and the damaged variants
(one thread per (realization, variant) pair, after the first launch so that a variant whose
weights equal the base copies ``tau0`` instead of integrating). Every thread draws its own
initial phases from ``(seed, k, node)``, so the pairs of one realization share them.

Agreement with the CPU backend
------------------------------
Under the numba CUDA simulator the kernels run the same double-precision operations as the
CPU backend and the steps are identical, realization by realization (tests/test_cuda_sim.py).
On a real GPU two things can differ at the level of one rounding: NVVM contracts
``a * b + c`` into a fused multiply-add (one rounding instead of two) in the Euler step, and
CUDA's ``cos``/``sin`` (used for the initial phases and for rotation angles above 0.05) are
not always correctly rounded. The trajectories then differ by ~1e-16 relative, which changes
the step at which ``r`` crosses the threshold only when ``r^2`` lands within that distance of
the target (a rare one-step flip, ``|delta tau| = dt``) or, rarer still, when a trajectory
passing near a saddle state amplifies the difference (docs/cuda.md). The device reductions
avoid contraction (``libdevice.dmul_rn``) so, given the same steps, block and Lambda records
equal :func:`antisync.stats.estimators.block_records` and ``lambda_block_records`` exactly.

The module imports without numba-cuda, a GPU or the simulator; only calling it then raises
:class:`~antisync.errors.AntisyncError`.
"""

from __future__ import annotations

import functools
import math
import warnings
from typing import NamedTuple

import numpy as np

from antisync.errors import AntisyncError
from antisync.kernels.core import WORK_ROWS, make_kernels, make_model_kernels
from antisync.kernels.shared import SimResult, model_inputs, per_node, record
from antisync.physics.phases import make_phase
from antisync.stats.estimators import (
    BLOCK_FIELDS,
    LAMBDA_FIELDS,
    LAMBDA_TAIL_BINS,
    TAIL_BINS,
    TAIL_EDGES,
    TAU0_FIELDS,
)
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED
from antisync.types import PRECISIONS, Precision

try:  # numba-cuda is an optional dependency
    import numba
    from numba import cuda
except ImportError:  # pragma: no cover - depends on the installation
    cuda = None

__all__ = ["MAX_NODES", "PRECISIONS", "Reduced", "simulate", "simulate_model", "simulate_reduced"]

MAX_NODES = 64
"""Largest graph the kernels accept: the per-thread state lives in local arrays of this size."""

THREADS_PER_BLOCK = 128
SIMULATOR_THREADS_PER_BLOCK = 8
"""Threads per block under ``NUMBA_ENABLE_CUDASIM``: the simulator runs a block's threads as
Python threads that take a per-module lock on every device-function call, and with 128 of them
it can fall into a lock convoy (a 10 s check once ran for over 15 minutes). Every kernel here
is a grid-stride loop without shared memory or barriers, so the block size never changes a
result."""
BATCH_PAIRS = 1 << 24
"""Trajectories per device batch in :func:`simulate_reduced` (~150 MB of per-pair results)."""

_MAX_GRID = 1 << 20


def _simulated() -> bool:
    return bool(numba.config.ENABLE_CUDASIM)


def _require_cuda() -> None:
    from antisync.kernels.backends import cuda_usable

    ok, why = cuda_usable()
    if not ok:
        raise AntisyncError(f"the CUDA backend cannot run here: {why}; use backend cpu")


@functools.cache
def _kernels(precision: Precision):
    """Compile (once per process and precision) the device functions and kernels."""
    ftype = np.float32 if precision == "float32" else np.float64
    nbtype = numba.float32 if precision == "float32" else numba.float64
    device = cuda.jit(device=True)
    sync_steps = make_kernels(device, ftype).sync_steps
    phase = make_phase(device)

    @cuda.jit(device=True)
    def start_state(seed, k, n, c, s):
        # phases and their cos/sin in double, rounded once to the state type
        for i in range(n):
            th = phase(seed, k, i)
            c[i] = math.cos(th)
            s[i] = math.sin(th)

    @cuda.jit
    def tau0_kernel(seed, first, count, indptr, indices, weights, dt, r2_target, max_steps, status0, steps0):
        n = indptr.shape[0] - 1
        c = cuda.local.array(MAX_NODES, nbtype)[:n]
        s = cuda.local.array(MAX_NODES, nbtype)[:n]
        acc = cuda.local.array(MAX_NODES, nbtype)[:n]
        for r in range(cuda.grid(1), count, cuda.gridsize(1)):
            start_state(seed, first + r, n, c, s)
            st, k = sync_steps(c, s, acc, indptr, indices, weights, dt, r2_target, max_steps)
            status0[r] = st
            steps0[r] = k

    @cuda.jit
    def variant_kernel(
        seed,
        first,
        count,
        indptr,
        indices,
        var_w,
        var_is_base,
        dt,
        r2_target,
        max_steps,
        status0,
        steps0,
        status,
        steps,
    ):
        n = indptr.shape[0] - 1
        n_var = var_w.shape[0]
        c = cuda.local.array(MAX_NODES, nbtype)[:n]
        s = cuda.local.array(MAX_NODES, nbtype)[:n]
        acc = cuda.local.array(MAX_NODES, nbtype)[:n]
        for p in range(cuda.grid(1), count * n_var, cuda.gridsize(1)):
            r = p // n_var
            v = p - r * n_var
            if var_is_base[v]:
                # this damage leaves W unchanged (e.g. a link leaving a degree-1 node)
                status[r, v] = status0[r]
                steps[r, v] = steps0[r]
                continue
            start_state(seed, first + r, n, c, s)
            st, k = sync_steps(c, s, acc, indptr, indices, var_w[v], dt, r2_target, max_steps)
            status[r, v] = st
            steps[r, v] = k

    return tau0_kernel, variant_kernel


@functools.cache
def _reducers():
    """Kernels for block records, the tail histogram and the (tau0, tau(beta)) histograms."""
    if _simulated():

        def mul(x, y):
            return x * y
    else:
        from numba.cuda import libdevice

        # a product that NVVM never fuses with the following addition (no FMA), so the
        # sums round exactly as estimators._reduce_blocks does on the CPU
        mul = libdevice.dmul_rn

    @cuda.jit(device=True)
    def tail_bin(edges, x):
        # np.searchsorted(edges, x, side="right"): the number of edges <= x
        lo = 0
        hi = edges.shape[0]
        while lo < hi:
            mid = (lo + hi) // 2
            if edges[mid] <= x:
                lo = mid + 1
            else:
                hi = mid
        return lo

    @cuda.jit
    def block_kernel(status0, steps0, status, steps, dt, block, edges, rec, rec0, tail):
        # one thread per (block, column); column 0 is tau0, column v + 1 is variant v.
        # Each sums its block in realization order, as estimators._reduce_blocks does.
        m = status0.shape[0]
        n_var = status.shape[1]
        n_blocks = rec0.shape[0]
        for p in range(cuda.grid(1), n_blocks * (n_var + 1), cuda.gridsize(1)):
            bl = p // (n_var + 1)
            v = p - bl * (n_var + 1) - 1
            lo = bl * block
            hi = min(lo + block, m)
            n_ok = 0.0
            n_already = 0.0
            n_not = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            s4 = 0.0
            for r in range(lo, hi):
                st0 = status0[r]
                if v < 0:
                    if st0 == SYNCED:
                        t0 = mul(steps0[r], dt)
                        n_ok += 1
                        s1 += t0
                        s2 += mul(t0, t0)
                    elif st0 == ALREADY_SYNCED:
                        n_already += 1
                    else:
                        n_not += 1
                    continue
                st = status[r, v]
                if st0 == SYNCED and st == SYNCED:
                    d = steps0[r] / steps[r, v] - 1.0
                    t = mul(steps[r, v], dt)
                    n_ok += 1
                    s1 += d
                    s2 += mul(d, d)
                    s3 += t
                    s4 += mul(t, t)
                    cuda.atomic.add(tail, (v, tail_bin(edges, abs(d))), 1)
                elif st0 == NOT_SYNCED or st == NOT_SYNCED:
                    n_not += 1
                else:
                    n_already += 1
            if v < 0:
                rec0[bl, 0] = n_ok
                rec0[bl, 1] = n_already
                rec0[bl, 2] = n_not
                rec0[bl, 3] = s1
                rec0[bl, 4] = s2
            else:
                rec[bl, v, 0] = n_ok
                rec[bl, v, 1] = n_already
                rec[bl, v, 2] = n_not
                rec[bl, v, 3] = s1
                rec[bl, v, 4] = s2
                rec[bl, v, 5] = s3
                rec[bl, v, 6] = s4

    @cuda.jit
    def lambda_kernel(status0, steps0, status, steps, lam_v, dbeta, dt, block, edges, rec, tail):
        # one thread per (block, edge): the finite difference (tau0/tau(dbeta) - 1)/dbeta of
        # variant lam_v[e], summed in realization order as estimators._reduce_lambda does
        m = status0.shape[0]
        n_edges = lam_v.shape[0]
        n_blocks = rec.shape[0]
        for p in range(cuda.grid(1), n_blocks * n_edges, cuda.gridsize(1)):
            bl = p // n_edges
            e = p - bl * n_edges
            v = lam_v[e]
            n_ok = 0.0
            n_already = 0.0
            n_not = 0.0
            n_lost = 0.0
            n_gained = 0.0
            s1 = 0.0
            s2 = 0.0
            s_slope = 0.0
            s_tau0 = 0.0
            for r in range(bl * block, min(bl * block + block, m)):
                st0 = status0[r]
                st = status[r, v]
                if st0 == SYNCED and st == NOT_SYNCED:
                    n_lost += 1
                elif st0 == NOT_SYNCED and st == SYNCED:
                    n_gained += 1
                if st0 == SYNCED and st == SYNCED:
                    x = (steps0[r] / steps[r, v] - 1.0) / dbeta
                    n_ok += 1
                    s1 += x
                    s2 += mul(x, x)
                    # Lambda^tau's sums: the forward secant of tau and tau0, as compute does
                    s_slope += mul(steps[r, v] - steps0[r], dt) / dbeta
                    s_tau0 += mul(steps0[r], dt)
                    # the signed histogram of estimators._reduce_lambda
                    b = tail_bin(edges, abs(x)) + (edges.shape[0] + 1 if x < 0 else 0)
                    cuda.atomic.add(tail, (e, b), 1)
                elif st0 == NOT_SYNCED or st == NOT_SYNCED:
                    n_not += 1
                else:
                    n_already += 1
            rec[bl, e, 0] = n_ok
            rec[bl, e, 1] = n_already
            rec[bl, e, 2] = n_not
            rec[bl, e, 3] = s1
            rec[bl, e, 4] = s2
            rec[bl, e, 5] = 0.0  # n_flagged: the finite difference flags nothing
            rec[bl, e, 6] = n_lost
            rec[bl, e, 7] = n_gained
            rec[bl, e, 8] = s_slope
            rec[bl, e, 9] = s_tau0

    @cuda.jit
    def hist_kernel(status0, steps0, status, steps, variants, scale, hist):
        # one thread per (realization, histogram) pair; as estimators.histogram2d
        m = status0.shape[0]
        n_h = variants.shape[0]
        bins = hist.shape[1]
        for p in range(cuda.grid(1), m * n_h, cuda.gridsize(1)):
            r = p // n_h
            k = p - r * n_h
            v = variants[k]
            if status0[r] == SYNCED and status[r, v] == SYNCED:
                i0 = min(int(steps0[r] * scale), bins - 1)
                i1 = min(int(steps[r, v] * scale), bins - 1)
                cuda.atomic.add(hist, (k, i0, i1), 1)

    return block_kernel, lambda_kernel, hist_kernel


def threads_per_block() -> int:
    """Threads per block of every launch: :data:`THREADS_PER_BLOCK` on a GPU,
    :data:`SIMULATOR_THREADS_PER_BLOCK` under the simulator."""
    return SIMULATOR_THREADS_PER_BLOCK if _simulated() else THREADS_PER_BLOCK


def _grid(total: int) -> int:
    return max(1, min(-(-total // threads_per_block()), _MAX_GRID))


def _prepare(
    seed,
    first,
    count,
    indptr,
    indices,
    base_weights,
    variant_weights,
    dt,
    threshold,
    max_steps,
    precision: Precision,
):
    """Validate the public arguments; return the device-ready host arrays and scalars."""
    if precision not in PRECISIONS:
        raise AntisyncError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    if seed < 0 or first < 0 or count < 0:
        raise ValueError("seed, first and count must be non-negative")
    n = int(indptr.size) - 1
    if n > MAX_NODES:
        raise AntisyncError(
            f"the graph has {n} nodes but the CUDA backend supports at most {MAX_NODES} "
            "(antisync.kernels.cuda.MAX_NODES); use backend cpu"
        )
    if not dt > 0 or not 0 < threshold < 1 or max_steps < 1:
        raise ValueError(
            f"need dt > 0, 0 < threshold < 1, max_steps >= 1; got {dt}, {threshold}, {max_steps}"
        )
    base = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base.size)
    if indices.size != base.size:
        raise ValueError(f"indices ({indices.size}) and weights ({base.size}) differ in length")
    _require_cuda()
    # decided in double precision, exactly as the CPU backend decides it
    var_is_base = np.array([np.array_equal(w, base) for w in var_w], dtype=np.bool_)
    ftype = np.float32 if precision == "float32" else np.float64
    return {
        "seed": np.uint64(seed),
        "first": np.int64(first),
        "indptr": np.ascontiguousarray(indptr, dtype=np.int64),
        "indices": np.ascontiguousarray(indices, dtype=np.int64),
        "base": base.astype(ftype),
        "var_w": var_w.astype(ftype),
        "var_is_base": var_is_base,
        "dt": ftype(dt),
        "r2_target": ftype((threshold * n) ** 2),
        "max_steps": np.int64(max_steps),
    }


class _quiet_simulator:
    """Silence numpy's uint64 overflow warnings from the phase hash under the simulator
    (the wrap-around is intended; compiled code never warns)."""

    def __enter__(self):
        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.filterwarnings("ignore", message="overflow encountered", category=RuntimeWarning)

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


def _integrate(a, first, count, precision):
    """Launch tau0 and the variants for realizations ``first .. first+count-1``; device arrays."""
    tau0_kernel, variant_kernel = _kernels(precision)
    n_var = a["var_w"].shape[0]
    indptr = cuda.to_device(a["indptr"])
    indices = cuda.to_device(a["indices"])
    status0 = cuda.device_array(count, dtype=np.int8)
    steps0 = cuda.device_array(count, dtype=np.int64)
    status = steps = None  # no variants: nothing to allocate (empty device arrays are avoided)
    if n_var:
        status = cuda.device_array((count, n_var), dtype=np.int8)
        steps = cuda.device_array((count, n_var), dtype=np.int64)
    with _quiet_simulator():
        tau0_kernel[_grid(count), threads_per_block()](
            a["seed"],
            np.int64(first),
            np.int64(count),
            indptr,
            indices,
            cuda.to_device(a["base"]),
            a["dt"],
            a["r2_target"],
            a["max_steps"],
            status0,
            steps0,
        )
        if n_var:
            variant_kernel[_grid(count * n_var), threads_per_block()](
                a["seed"],
                np.int64(first),
                np.int64(count),
                indptr,
                indices,
                cuda.to_device(a["var_w"]),
                cuda.to_device(a["var_is_base"]),
                a["dt"],
                a["r2_target"],
                a["max_steps"],
                status0,
                steps0,
                status,
                steps,
            )
    return status0, steps0, status, steps


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
    precision: Precision = "float64",
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` for the base network and every variant.

    The CUDA twin of :func:`antisync.kernels.cpu.simulate` (same arguments except
    ``threads``, same :class:`~antisync.kernels.cpu.SimResult`).

    Parameters
    ----------
    seed, first, count : int
        Realization ``k`` starts from :func:`antisync.physics.phases.phase` ``(seed, k, node)``.
    indptr, indices, base_weights : arrays
        CSR form of ``W(Omega)`` (see :class:`antisync.physics.coupling.CouplingCSR`); at most
        :data:`MAX_NODES` nodes.
    variant_weights : array, shape (V, nnz)
        CSR weights of each damaged ``W(Omega*)`` on the same pattern.
    dt, threshold, max_steps
        Euler step, order-parameter threshold ``r`` and the step cap (``t_max / dt``).
    precision : {"float64", "float32"}
        Arithmetic of the state ``(cos theta, sin theta)``; initial phases are always drawn in
        double and rounded once. ``float32`` changes some ``tau`` by a few steps (docs/cuda.md).

    Raises
    ------
    AntisyncError
        No usable GPU (or simulator), more than ``MAX_NODES`` nodes, or an unknown precision.
    """
    a = _prepare(
        seed,
        first,
        count,
        indptr,
        indices,
        base_weights,
        variant_weights,
        dt,
        threshold,
        max_steps,
        precision,
    )
    n_var = a["var_w"].shape[0]
    if count == 0:
        return SimResult(
            np.empty(0, np.int8),
            np.empty(0, np.int64),
            np.empty((0, n_var), np.int8),
            np.empty((0, n_var), np.int64),
        )
    status0, steps0, status, steps = _integrate(a, first, count, precision)
    if not n_var:
        status, steps = np.empty((count, 0), np.int8), np.empty((count, 0), np.int64)
    else:
        status, steps = status.copy_to_host(), steps.copy_to_host()
    return SimResult(status0.copy_to_host(), steps0.copy_to_host(), status, steps)


class Reduced(NamedTuple):
    """Statistics of a batch reduced on the device (see :func:`simulate_reduced`).

    Attributes
    ----------
    rec, rec0, tail
        As returned by :func:`antisync.stats.estimators.block_records`.
    hist
        As returned by :func:`antisync.stats.estimators.histogram2d`.
    lam_rec, lam_tail
        As returned by :func:`antisync.stats.estimators.lambda_block_records` for the
        finite-difference Lambda^KM of each edge (no edges: shapes ``(n_blocks, 0, 6)``, ``(0, B)``).
    """

    rec: np.ndarray
    rec0: np.ndarray
    tail: np.ndarray
    hist: np.ndarray
    lam_rec: np.ndarray
    lam_tail: np.ndarray


def simulate_reduced(
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
    block: int,
    hist_variants: np.ndarray,
    bins: int,
    tau_max: float,
    lambda_variants: np.ndarray | None = None,
    dbeta: float | None = None,
    precision: Precision = "float64",
    batch_pairs: int = BATCH_PAIRS,
) -> Reduced:
    """Integrate and reduce on the device: only block records and histograms come back.

    Equivalent to ``sim = simulate(...)`` followed by
    :func:`antisync.stats.estimators.block_records` ``(sim, dt, block)``,
    :func:`antisync.stats.estimators.histogram2d` ``(sim, hist_variants, dt, bins, tau_max)`` and
    :func:`antisync.stats.estimators.lambda_block_records` of the finite differences
    ``(tau0/tau(dbeta) - 1)/dbeta`` (as :func:`antisync.execution.compute.lambda_values` computes
    them), with identical results, but per-realization outcomes never leave the GPU.
    Realizations are processed in batches of whole blocks of about ``batch_pairs``
    trajectories, so device memory stays bounded whatever ``count`` is.

    Parameters
    ----------
    first : int
        Must lie on a block boundary of the run (as chunks do); blocks are counted from it.
    block : int
        Block size ``B`` of the statistics records.
    hist_variants, bins, tau_max
        As in :func:`antisync.stats.estimators.histogram2d`.
    lambda_variants : int array (E,), optional
        The variant damaging edge ``e`` by ``dbeta``, for each edge whose Lambda^KM records
        are wanted.
    dbeta : float
        The damage of those variants (needed with ``lambda_variants``).

    Returns
    -------
    Reduced
        ``(rec, rec0, tail, hist, lam_rec, lam_tail)``.
    """
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    a = _prepare(
        seed,
        first,
        count,
        indptr,
        indices,
        base_weights,
        variant_weights,
        dt,
        threshold,
        max_steps,
        precision,
    )
    n_var = a["var_w"].shape[0]
    if n_var == 0:
        raise ValueError("simulate_reduced needs at least one variant (use simulate for tau0 alone)")
    variants = _variant_indices(hist_variants, n_var, "hist_variants")
    lam_v = _variant_indices(lambda_variants if lambda_variants is not None else [], n_var, "lambda_variants")
    if lam_v.size and not (dbeta is not None and 0.0 < dbeta < 1.0):
        raise ValueError(f"lambda_variants need the damage dbeta in (0, 1), got {dbeta!r}")
    block_kernel, lambda_kernel, hist_kernel = _reducers()
    n_blocks = -(-count // block)
    out = Reduced(
        np.zeros((n_blocks, n_var, len(BLOCK_FIELDS))),
        np.zeros((n_blocks, len(TAU0_FIELDS))),
        np.zeros((n_var, TAIL_BINS), dtype=np.int64),
        np.zeros((variants.size, bins, bins), dtype=np.int64),
        np.zeros((n_blocks, lam_v.size, len(LAMBDA_FIELDS))),
        np.zeros((lam_v.size, LAMBDA_TAIL_BINS), dtype=np.int64),
    )
    if count == 0:
        return out
    # device accumulators; empty index arrays get a dummy slot (no zero-size device arrays)
    tail = cuda.to_device(out.tail)
    hist = cuda.to_device(np.zeros((max(variants.size, 1), bins, bins), dtype=np.int64))
    lam_tail = cuda.to_device(np.zeros((max(lam_v.size, 1), LAMBDA_TAIL_BINS), dtype=np.int64))
    edges = cuda.to_device(TAIL_EDGES)
    variants_d = cuda.to_device(variants if variants.size else np.zeros(1, np.int64))
    lam_v_d = cuda.to_device(lam_v if lam_v.size else np.zeros(1, np.int64))
    scale = bins / (tau_max / dt)  # the same double as estimators.histogram2d
    per = max(1, batch_pairs // ((1 + n_var) * block)) * block
    for lo in range(0, count, per):
        m = min(per, count - lo)
        status0, steps0, status, steps = _integrate(a, first + lo, m, precision)
        nb = -(-m // block)
        b0 = lo // block
        rec_d = cuda.device_array((nb, n_var, len(BLOCK_FIELDS)))
        rec0_d = cuda.device_array((nb, len(TAU0_FIELDS)))
        block_kernel[_grid(nb * (n_var + 1)), threads_per_block()](
            status0,
            steps0,
            status,
            steps,
            float(dt),
            np.int64(block),
            edges,
            rec_d,
            rec0_d,
            tail,
        )
        out.rec[b0 : b0 + nb] = rec_d.copy_to_host()
        out.rec0[b0 : b0 + nb] = rec0_d.copy_to_host()
        if lam_v.size:
            lam_d = cuda.device_array((nb, lam_v.size, len(LAMBDA_FIELDS)))
            lambda_kernel[_grid(nb * lam_v.size), threads_per_block()](
                status0,
                steps0,
                status,
                steps,
                lam_v_d,
                float(dbeta),
                float(dt),
                np.int64(block),
                edges,
                lam_d,
                lam_tail,
            )
            out.lam_rec[b0 : b0 + nb] = lam_d.copy_to_host()
        if variants.size:
            hist_kernel[_grid(m * variants.size), threads_per_block()](
                status0,
                steps0,
                status,
                steps,
                variants_d,
                scale,
                hist,
            )
    out.tail[...] = tail.copy_to_host()
    out.hist[...] = hist.copy_to_host()[: variants.size]
    out.lam_tail[...] = lam_tail.copy_to_host()[: lam_v.size]
    return out


def _variant_indices(values, n_var: int, name: str) -> np.ndarray:
    idx = np.ascontiguousarray(values, dtype=np.int64).reshape(-1)
    if idx.size and (idx.min() < 0 or idx.max() >= n_var):
        raise ValueError(f"{name} must index the {n_var} variants, got {idx}")
    return idx


# --- the generalized models (natural frequencies, phase lag, inertia; docs/models.md) -------


@functools.cache
def _model_kernel():
    """Compile (once per process) the generalized models' kernel: one thread per (realization,
    variant) item, ``make_model_kernels``' ``sync_steps`` (float64)."""
    device = cuda.jit(device=True)
    sync = make_model_kernels(device, make_kernels(device)).sync_steps
    phase = make_phase(device)
    store = device(record.py_func)
    f64 = numba.float64

    @cuda.jit
    def model_kernel(seed, ks, graph, model, dt, rk4, max_steps, out):
        """``graph`` ``(indptr, indices, base_w, var_w, var_is_base)``, ``model`` ``(freqs,
        starts, cl, sl, inertia, damping, criterion, targets)`` and ``out`` ``(status0, steps0,
        frac0, status, steps, frac)``: the fields of :class:`~.shared.Graph`,
        :class:`~.shared.Model` and :class:`~.shared.Outputs`."""
        indptr, indices, base_w, var_w, var_is_base = graph
        freqs, starts, cl, sl, inertia, damping, criterion, targets = model
        status0, steps0, frac0, status, steps, frac = out
        n = indptr.shape[0] - 1
        m = ks.shape[0]
        n_var = var_w.shape[0]
        per = n_var + 1
        c = cuda.local.array(MAX_NODES, f64)[:n]
        s = cuda.local.array(MAX_NODES, f64)[:n]
        nu = cuda.local.array(MAX_NODES, f64)[:n]
        th = cuda.local.array(MAX_NODES, f64)[:n]
        dnu = cuda.local.array(MAX_NODES, f64)[:n]
        work = cuda.local.array((WORK_ROWS, MAX_NODES), f64)
        for item in range(cuda.grid(1), m * per, cuda.gridsize(1)):
            r = item // per
            v = item - r * per - 1
            if v >= 0 and var_is_base[v]:
                continue  # copied from the undamaged result on the host
            for i in range(n):
                # model.start's phases when the batch carries them (physics.phases.start_phase)
                theta = starts[r, i] if starts.shape[0] > 0 else phase(seed, ks[r], i)
                c[i] = math.cos(theta)
                s[i] = math.sin(theta)
                nu[i] = 0.0
                dnu[i] = 0.0
            row = r if freqs.shape[0] > 1 else 0
            w = base_w if v < 0 else var_w[v]
            eq = (freqs[row], w, indptr, indices, cl, sl, inertia, damping)
            st, k, x = sync(c, s, nu, th, dnu, work, eq, dt, rk4, criterion, targets[v + 1], max_steps)
            store(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)

    return model_kernel


def simulate_model(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    params,
    *,
    dt: float,
    max_steps: int,
    integrator: str = "euler",
    realizations: np.ndarray | None = None,
) -> SimResult:
    """A generalized model on the GPU: the CUDA twin of :func:`antisync.kernels.cpu.simulate_model`
    (same arguments but ``threads``, ``todo`` and ``lanes``; same result). One thread per
    (realization, variant) item in a grid-stride loop, each integrated by the CPU driver's
    ``make_model_kernels`` step functions (compiled with ``cuda.jit(device=True)``) from the same
    counter-based phases and natural frequencies: under the numba CUDA simulator statuses, steps
    and crossing fractions equal the CPU driver's (tests/test_models_cuda_sim.py); on an H100 it
    gave the CPU driver's statuses and steps on all 128,000 trajectories of
    ``bench/gpu_models_check.py`` (bench/RESULTS.md). float64 only.

    Raises
    ------
    AntisyncError
        No usable GPU (or simulator), or more than ``MAX_NODES`` nodes.
    """
    ks, base, var_w, var_is_base, freqs, targets, starts = model_inputs(
        first, count, realizations, indptr, base_weights, variant_weights, params, integrator
    )
    m = ks.size
    n_var = var_w.shape[0]
    n = int(indptr.size) - 1
    if n > MAX_NODES:
        raise AntisyncError(
            f"the graph has {n} nodes but the CUDA backend supports at most {MAX_NODES} "
            "(antisync.kernels.cuda.MAX_NODES); use backend cpu"
        )
    _require_cuda()
    out = {
        "status0": np.zeros(m, np.int8),
        "steps0": np.zeros(m, np.int64),
        "frac0": np.zeros(m),
        "status": np.zeros((m, n_var), np.int8),
        "steps": np.zeros((m, n_var), np.int64),
        "frac": np.zeros((m, n_var)),
    }
    if m:
        dev = {k: cuda.to_device(v) for k, v in out.items()}
        items = m * (n_var + 1)
        threads = threads_per_block()
        blocks = min(_MAX_GRID, -(-items // threads))
        with _quiet_simulator():
            graph = (
                cuda.to_device(np.ascontiguousarray(indptr, dtype=np.int64)),
                cuda.to_device(np.ascontiguousarray(indices, dtype=np.int64)),
                cuda.to_device(base),
                cuda.to_device(var_w if n_var else np.zeros((0, base.size))),
                cuda.to_device(var_is_base if n_var else np.zeros(0, np.bool_)),
            )
            model = (
                cuda.to_device(freqs),
                cuda.to_device(starts),
                float(params.cos_lag),
                float(params.sin_lag),
                cuda.to_device(per_node(params.inertia, n)),
                cuda.to_device(per_node(params.damping, n)),
                int(params.criterion),
                cuda.to_device(targets),
            )
            _model_kernel()[blocks, threads](
                np.uint64(seed),
                cuda.to_device(ks),
                graph,
                model,
                float(dt),
                integrator == "rk4",
                np.int64(max_steps),
                tuple(dev.values()),
            )
        out = {k: v.copy_to_host() for k, v in dev.items()}
    for v in np.flatnonzero(var_is_base):
        out["status"][:, v] = out["status0"]
        out["steps"][:, v] = out["steps0"]
        out["frac"][:, v] = out["frac0"]
    return SimResult(out["status0"], out["steps0"], out["status"], out["steps"], out["frac0"], out["frac"])
