"""One chunk of work: integrate its realizations on a backend and reduce them to mergeable
partial statistics. Executors (local, Dask) only decide *where* :func:`compute_chunk` runs;
which functions integrate and estimate is the chunk's row of the dispatch table
(:mod:`antisync.execution.dispatch`), looked up once.
"""

from __future__ import annotations

import time

import numpy as np

from antisync.errors import ConfigError
from antisync.execution import dispatch
from antisync.kernels.shared import SimResult
from antisync.plan.jobs import Chunk, Job
from antisync.stats import estimators
from antisync.store.state import ChunkResult

__all__ = [
    "ChunkResult",
    "check_backend",
    "check_float32_threshold",
    "check_job",
    "compute_chunk",
    "lambda_values",
    "simulate_job",
]


def check_backend(config, backend: str) -> dispatch.Row:
    """Refuse options the resolved ``backend`` does not implement (before any file is written).

    The CUDA backend integrates the paper's procedure: Euler steps and grid crossing times, in
    float64 or float32; the derivative methods' Lambda pass (float64) runs on the CPU lanes
    beside it (:func:`host_part`). The CPU backend runs everything in float64, and the Euler
    finite difference in float32 as well. The cells and their messages are the dispatch table's
    (:data:`antisync.execution.dispatch.TABLE`); the crossing is checked against the row's driver.

    Returns
    -------
    Row
        The cell's :class:`~antisync.execution.dispatch.Row`: the functions that run it.

    Raises
    ------
    ConfigError
        Naming the key, the value and what would work.
    """
    row = dispatch.lookup(config, backend)
    if config.dynamics.interpolate and row.driver.no_interpolation is not None:
        raise ConfigError(row.driver.no_interpolation)
    return row


def host_part(config, backend: str) -> str | None:
    """What of a run on ``backend`` runs on the CPU all the same, or None: the CUDA kernel
    integrates the undamaged and damaged trajectories of the ``betas`` (tau0, tau(beta), F),
    while the Lambda pass of every method but ``finite-difference`` (the forward tangents, the
    adjoint, the secants, the orbit and central-difference rows) runs on the CPU lanes."""
    return dispatch.lookup(config, backend).host_part


def check_job(job: Job, backend: str) -> None:
    """:func:`check_backend` for ``job``'s config, plus what depends on its graph (the CUDA
    kernels keep a trajectory's state in fixed-size per-thread arrays of ``MAX_NODES``; a
    float32 state resolves ``r`` to about ``N`` float32 roundings, :func:`check_float32_threshold`;
    the CPU's float32 lanes a bounded rotation angle): the row's ``driver.check_job``."""
    row = check_backend(job.config, backend)
    dyn = job.config.dynamics
    if dyn.precision == "float32":
        check_float32_threshold(dyn.threshold, len(job.nodes))
    row.driver.check_job(job)


#: ``1 - threshold >= FLOAT32_MARGIN * N * eps32`` for a float32 state (:func:`check_float32_threshold`).
FLOAT32_MARGIN = 100


def check_float32_threshold(threshold: float, n_nodes: int) -> None:
    """Refuse a ``dynamics.threshold`` too close to 1 for a float32 state of ``n_nodes`` nodes.

    A float32 state is ``N`` unit vectors ``(c_j, s_j)`` in float32, renormalized every few
    dozen steps, and ``R = |sum_j (c_j, s_j)|^2`` is summed in float32 (on the CUDA backend too,
    whose target ``(threshold N)^2`` is itself a float32), so ``r`` carries an error of about
    ``N eps32`` (``eps32 = 2**-23``) and ``1 - r`` below that is noise. The bound is
    ``1 - threshold >= FLOAT32_MARGIN N eps32``: threshold 0.99993 for N = 6, 0.99964 for
    N = 30, 0.9988 for N = 100, and the paper's 0.99 up to N = 838.

    Measured against float64 (CPU backend, Euler finite-difference lanes, seed 1; lollipop
    graphs with a path of 3 and a clique of N - 3; ``ratio = (1 - threshold) / (N eps32)``;
    ``mean``: ``|<tau0_32> / <tau0_64> - 1|``, ``max``: the largest per-realization
    ``|tau0_32 / tau0_64 - 1|``)::

        N    dt     real.  1-threshold  ratio    mean     max
        6    0.001  200    1e-2         14000    4.8e-6   4.9e-4
        6    0.001  200    1e-4         140      2.5e-5   1.5e-3
        6    0.001  200    1e-5         14       2.3e-3   1.8e-2
        6    0.001  200    1e-6         1.4      2.7e-2   1.1e-1
        6    0.001  200    1e-7         0.14     1.2e-1   3.6e-1
        6    0.01   200    1e-4         140      6.1e-5   1.6e-3
        6    0.01   200    1e-5         14       7.7e-4   4.7e-3
        6    0.01   200    1e-6         1.4      1.1e-2   4.5e-2   (the issue's 1%)
        6    0.01   200    1e-7         0.14     7.8e-2   1.8e-1   (the issue's 7.6%)
        30   0.01   100    1e-2         2800     7.6e-6   8.8e-4
        30   0.01   100    1e-3         280      4.8e-6   6.3e-4
        30   0.01   100    1e-4         28       1.5e-4   2.1e-3
        30   0.01   100    1e-5         2.8      2.7e-3   2.0e-2
        30   0.01   100    1e-6         0.28     3.0e-2   1.0e-1
        100  0.01   50     1e-3         84       4.2e-5   6.0e-4
        100  0.01   50     1e-4         8.4      2.5e-4   3.8e-3
        100  0.01   50     1e-5         0.84     2.2e-4   1.3e-2
        100  0.01   50     1e-6         0.084    2.2e-2   7.6e-1   (2% never synchronized)

    At a fixed ``1 - threshold`` the error grows with N (3x from N = 6 to 30), and at a fixed
    ratio it is about the same for every N: the ratio is the variable. Above ratio ~100 tau0
    moves as little as at the paper's 0.99 (per-realization max ~1e-3); below it the error
    grows about tenfold per decade. ``FLOAT32_MARGIN = 100`` is that edge.

    Raises
    ------
    ConfigError
        Naming the threshold, N and the largest threshold float32 resolves.
    """
    eps32 = float(np.finfo(np.float32).eps)
    floor = FLOAT32_MARGIN * n_nodes * eps32
    if not 1.0 - threshold >= floor:  # NaN-safe
        raise ConfigError(
            f"dynamics.threshold {threshold:.12g} is too close to 1 for dynamics.precision float32 "
            f"with {n_nodes} nodes: float32 resolves r to ~N x 1.2e-7, so the largest threshold is "
            f"{1.0 - floor:.8g} (1 - {FLOAT32_MARGIN} N eps32); use precision float64 or a lower threshold"
        )


def simulate_job(
    job: Job,
    first: int,
    count: int,
    backend: str = "cpu",
    threads: int | None = None,
    variant_weights: np.ndarray | None = None,
    realizations: np.ndarray | None = None,
    todo: np.ndarray | None = None,
    variant_targets: np.ndarray | None = None,
):
    """Integrate realizations ``first .. first+count-1`` (or ``realizations``) of ``job``
    (only the items marked by ``todo``, see :func:`antisync.kernels.cpu.simulate`) by the
    driver of its row.

    A generalized model's ``variant_weights`` other than the job's own variants or
    :attr:`~antisync.plan.jobs.Job.orbit_weights` need their ``variant_targets`` (the criterion's
    target of each row: the relative criterion's moves with the weights)."""
    row = check_backend(job.config, backend)
    return row.driver.simulate(
        job, first, count, threads, variant_weights, realizations, todo, variant_targets
    )


def lambda_values(
    job: Job, sim, first: int, count: int, threads: int | None = None, *, with_tau: bool = False
):
    """Per-realization Lambda^KM estimates for every edge of ``job`` by ``lambda.method``
    (the job's :class:`~antisync.execution.dispatch.LambdaPass`).

    Returns ``(values, code, flagged, base)`` with ``values``/``code``/``flagged`` of shape
    ``(count, E)`` (see :func:`antisync.stats.estimators.lambda_block_records`) and ``base`` the
    undamaged outcome when the pathwise, adjoint or orbit pass produced it (else None). With
    ``with_tau``, also ``slope`` and ``tau0`` ``(count, E)``: the same estimator's slope of
    ``tau(beta)`` at 0 (time per unit beta: the forward secant ``(tau(dbeta) - tau0)/dbeta``,
    the central one, or the derivative ``d tau0/d beta``) and ``tau0``, for Lambda^tau.
    """
    out = dispatch.lambda_pass(job).values(job, sim, first, count, threads)
    return out if with_tau else out[:4]


def compute_chunk(job: Job, chunk: Chunk, backend: str = "cpu", threads: int | None = None) -> ChunkResult:
    """Integrate and reduce one chunk (pure: no files, no progress bars).

    The chunk's row of the dispatch table (:func:`check_backend`) holds what runs it: its
    driver integrates tau0 and the variants, its Lambda pass estimates Lambda. Where the row
    has a ``reduce`` (backend cuda, finite-difference) a chunk that keeps no per-realization
    pairs (it lies beyond ``keep_pairs``) is reduced on the GPU
    (:func:`antisync.kernels.cuda.simulate_reduced`, records identical to the host's), so only
    block records and histograms cross the bus.
    """
    start = time.perf_counter()
    first, count = chunk.realizations(job.block_size, job.config.realizations)
    row = check_backend(job.config, backend)
    if row.reduce is not None and job.config.keep_pairs <= first:
        return row.reduce(job, chunk, first, count, start)
    estimator = row.lambda_pass
    if estimator.integrates and len(job.variant_edge) == 0:
        sim = None  # Lambda only: the Lambda pass integrates the undamaged network itself
    else:
        sim = row.driver.simulate(job, first, count, threads, None, None, None, None)
    values, code, flagged, base, slope, tau0 = estimator.values(job, sim, first, count, threads)
    if sim is None:
        empty = np.empty((count, 0))
        sim = SimResult(
            base.status0, base.steps0, empty.astype(np.int8), empty.astype(np.int64), base.frac0, empty
        )
    dyn = job.config.dynamics
    interpolate = dyn.interpolate
    dt = dyn.dt
    rec, rec0, tail = estimators.block_records(sim, dt, job.block_size, interpolate)
    flip = None if estimator.sync_response is None else estimator.sync_response(job, sim)
    lam_rec, lam_tail = estimators.lambda_block_records(
        values, code, flagged, job.block_size, flip, slope, tau0
    )
    hcfg = job.config.histogram
    hist = estimators.histogram2d(sim, job.hist_variants, dt, hcfg.bins, hcfg.tau_max, interpolate)
    keep = max(0, min(job.config.keep_pairs - first, count))
    kept = None
    if keep:
        kept = {
            "status0": sim.status0[:keep].copy(),
            "steps0": sim.steps0[:keep].copy(),
            "status": sim.status[:keep].copy(),
            "steps": sim.steps[:keep].copy(),
            "lambda": values[:keep].copy(),
        }
    return ChunkResult(
        chunk,
        rec,
        rec0,
        tail,
        hist,
        lam_rec,
        lam_tail,
        kept,
        first,
        count,
        time.perf_counter() - start,
        backend,
    )
