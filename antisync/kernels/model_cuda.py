"""CUDA twin of :mod:`antisync.kernels.model_cpu` (generalized models, docs/models.md).

One thread per (realization, variant) item in a grid-stride loop, each integrated by the same
``make_model_kernels`` step functions as the CPU driver (compiled with
``cuda.jit(device=True)``), from the same counter-based phases and natural frequencies, so under
the numba CUDA simulator statuses, steps and crossing fractions equal the CPU driver's
(tests/test_models_cuda_sim.py). float64 only; at most :data:`antisync.kernels.cuda.MAX_NODES`
nodes. On an H100 it gave the CPU driver's statuses and steps on all 128,000 trajectories of
``bench/gpu_models_check.py`` (bench/RESULTS.md).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from antisync.errors import AntisyncError
from antisync.kernels.core import WORK_ROWS, make_kernels, make_model_kernels
from antisync.kernels.cpu import SimResult, _realization_ids
from antisync.kernels.cuda import _MAX_GRID, MAX_NODES, _quiet_simulator, _require_cuda, threads_per_block
from antisync.kernels.model_cpu import _per_node
from antisync.phases import make_phase

try:  # numba-cuda is an optional dependency
    import numba
    from numba import cuda
except ImportError:  # pragma: no cover - depends on the installation
    cuda = None

__all__ = ["simulate_model"]


@functools.cache
def _kernel():
    device = cuda.jit(device=True)
    sync = make_model_kernels(device, make_kernels(device)).sync_steps
    phase = make_phase(device)
    f64 = numba.float64

    @cuda.jit
    def model_kernel(
        seed,
        ks,
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
        status0,
        steps0,
        frac0,
        status,
        steps,
        frac,
    ):
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
                theta = phase(seed, ks[r], i)
                c[i] = math.cos(theta)
                s[i] = math.sin(theta)
                nu[i] = 0.0
                dnu[i] = 0.0
            row = r if freqs.shape[0] > 1 else 0
            p = freqs[row]
            w = base_w if v < 0 else var_w[v]
            st, k, x = sync(
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
    """The CUDA twin of :func:`antisync.kernels.model_cpu.simulate_model` (same arguments but
    ``threads``, same result).

    Raises
    ------
    AntisyncError
        No usable GPU (or simulator), or more than ``MAX_NODES`` nodes.
    """
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"integrator must be 'euler' or 'rk4', got {integrator!r}")
    n = int(indptr.size) - 1
    if n > MAX_NODES:
        raise AntisyncError(
            f"the graph has {n} nodes but the CUDA backend supports at most {MAX_NODES} "
            "(antisync.kernels.cuda.MAX_NODES); use backend cpu"
        )
    _require_cuda()
    ks = _realization_ids(first, count, realizations)
    m = ks.size
    base = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base.size)
    n_var = var_w.shape[0]
    var_is_base = np.array([np.array_equal(w, base) for w in var_w], dtype=np.bool_)
    freqs = np.ascontiguousarray(params.freqs, dtype=np.float64)
    if freqs.ndim != 2 or freqs.shape[1] != n or freqs.shape[0] not in (1, m):
        raise ValueError(f"freqs must have shape (1, {n}) or ({m}, {n}), got {freqs.shape}")
    targets = np.ascontiguousarray(params.targets, dtype=np.float64)
    if targets.shape != (n_var + 1,):
        raise ValueError(f"targets must have shape ({n_var + 1},), got {targets.shape}")
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
            _kernel()[blocks, threads](
                np.uint64(seed),
                cuda.to_device(ks),
                cuda.to_device(np.ascontiguousarray(indptr, dtype=np.int64)),
                cuda.to_device(np.ascontiguousarray(indices, dtype=np.int64)),
                cuda.to_device(base),
                cuda.to_device(var_w if n_var else np.zeros((0, base.size))),
                cuda.to_device(var_is_base if n_var else np.zeros(0, np.bool_)),
                cuda.to_device(freqs),
                float(params.cos_lag),
                float(params.sin_lag),
                cuda.to_device(_per_node(params.inertia, n)),
                cuda.to_device(_per_node(params.damping, n)),
                float(dt),
                integrator == "rk4",
                int(params.criterion),
                cuda.to_device(targets),
                np.int64(max_steps),
                *dev.values(),
            )
        out = {k: v.copy_to_host() for k, v in dev.items()}
    for v in np.flatnonzero(var_is_base):
        out["status"][:, v] = out["status0"]
        out["steps"][:, v] = out["steps0"]
        out["frac"][:, v] = out["frac0"]
    return SimResult(out["status0"], out["steps0"], out["status"], out["steps"], out["frac0"], out["frac"])
