"""One chunk of work: integrate its realizations on a backend and reduce them to mergeable
partial statistics. Executors (local, Dask) only decide *where* :func:`compute_chunk` runs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from antisync_cli import estimators
from antisync_cli.jobs import Chunk, Job

__all__ = ["ChunkResult", "compute_chunk", "simulate_job"]


@dataclass
class ChunkResult:
    """Partial statistics of one chunk; every field merges by addition or by block position.

    Attributes
    ----------
    rec, rec0 : block records (see :func:`antisync_cli.estimators.block_records`)
    tail : int64 (V, TAIL_BINS)
    hist : int64 (len(job.hist_variants), bins, bins)
    kept : dict of arrays or None
        Per-realization steps and status for realizations below ``keep_pairs``.
    """

    chunk: Chunk
    rec: np.ndarray
    rec0: np.ndarray
    tail: np.ndarray
    hist: np.ndarray
    kept: dict | None
    first: int
    count: int
    seconds: float
    backend: str


def simulate_job(job: Job, first: int, count: int, backend: str = "cpu", threads: int | None = None):
    """Integrate realizations ``first .. first+count-1`` of ``job`` on ``backend``."""
    dyn = job.config.dynamics
    if backend == "cuda":
        from antisync_cli.kernels.cuda import simulate
    else:
        from antisync_cli.kernels.cpu import simulate
    kwargs = {"threads": threads} if backend != "cuda" else {}
    return simulate(
        job.config.seed, first, count, job.csr.indptr, job.csr.indices, job.csr.weights,
        job.variant_weights, dt=dyn.dt, threshold=dyn.threshold, max_steps=dyn.max_steps,
        **kwargs,
    )


def compute_chunk(job: Job, chunk: Chunk, backend: str = "cpu", threads: int | None = None) -> ChunkResult:
    """Integrate and reduce one chunk (pure: no files, no progress bars)."""
    start = time.perf_counter()
    first, count = chunk.realizations(job.block_size, job.config.realizations)
    sim = simulate_job(job, first, count, backend, threads)
    dt = job.config.dynamics.dt
    rec, rec0, tail = estimators.block_records(sim, dt, job.block_size)
    hcfg = job.config.histogram
    hist = estimators.histogram2d(sim, job.hist_variants, dt, hcfg.bins, hcfg.tau_max)
    keep = max(0, min(job.config.keep_pairs - first, count))
    kept = None
    if keep:
        kept = {
            "status0": sim.status0[:keep].copy(),
            "steps0": sim.steps0[:keep].copy(),
            "status": sim.status[:keep].copy(),
            "steps": sim.steps[:keep].copy(),
        }
    return ChunkResult(chunk, rec, rec0, tail, hist, kept, first, count,
                       time.perf_counter() - start, backend)
