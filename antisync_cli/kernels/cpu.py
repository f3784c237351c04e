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
from antisync_cli.phases import phase

__all__ = ["SimResult", "simulate"]

_K = make_kernels(lambda f: njit(f, inline="never", fastmath=False, cache=True))
_sync_steps = _K["sync_steps"]


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
    try:
        _integrate_batch(
            np.uint64(seed), np.uint64(first), indptr.astype(np.int64), indices.astype(np.int64),
            base_weights.astype(np.float64), var_w, var_is_base, float(dt), r2_target,
            int(max_steps), status0, steps0, status, steps,
        )
    finally:
        numba.set_num_threads(previous)
    return SimResult(status0, steps0, status, steps)
