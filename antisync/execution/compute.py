"""One chunk of work: integrate its realizations on a backend and reduce them to mergeable
partial statistics. Executors (local, Dask) only decide *where* :func:`compute_chunk` runs.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from antisync.errors import ConfigError
from antisync.plan.jobs import Chunk, Job
from antisync.stats import estimators
from antisync.status import NOT_SYNCED, SYNCED
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


def _kernel(backend: str):
    if backend == "cuda":
        from antisync.kernels import cuda as kernel
    else:
        from antisync.kernels import cpu as kernel
    return kernel


def check_backend(config, backend: str) -> None:
    """Refuse options the resolved ``backend`` does not implement (before any file is written).

    The CUDA backend integrates the paper's procedure: Euler steps and grid crossing times, in
    float64 or float32; the derivative methods' Lambda pass (float64) runs on the CPU lanes
    beside it (:func:`host_part`). The CPU backend runs everything in float64, and the Euler
    finite difference in float32 as well.

    Raises
    ------
    ConfigError
        Naming the key, the value and what would work.
    """
    dyn = config.dynamics
    if config.generalized:
        # the model kernels run Euler or RK4 with either crossing on both backends, float64 only
        if dyn.precision != "float64":
            raise ConfigError(
                "the model:/sync: sections (docs/models.md) run in dynamics.precision float64 only"
            )
        return
    if dyn.precision != "float64" and backend != "cuda" and dyn.integrator != "euler":
        # the CPU lanes run float32 for the Euler step with Taylor rotations only
        raise ConfigError(
            f"dynamics.precision {dyn.precision} runs dynamics.integrator euler only "
            f"(got {dyn.integrator}); use precision float64 or integrator euler"
        )
    if dyn.precision != "float64" and config.lambda_.method != "finite-difference":
        # the derivative passes are float64; their tau0 would not be the float32 run's
        raise ConfigError(
            f"dynamics.precision {dyn.precision} runs lambda.method finite-difference only "
            f"(got {config.lambda_.method}); use precision float64 or method finite-difference"
        )
    if backend != "cuda":
        return
    if dyn.integrator != "euler":
        raise ConfigError(
            f"dynamics.integrator {dyn.integrator} runs on the cpu backend only; "
            "use --backend cpu or integrator euler"
        )
    if dyn.interpolate:
        raise ConfigError(
            "dynamics.crossing interpolated runs on the cpu backend only (the CUDA kernels "
            "return grid crossing times); use --backend cpu or crossing grid"
        )


def host_part(config, backend: str) -> str | None:
    """What of a run on ``backend`` runs on the CPU all the same, or None: the CUDA kernel
    integrates the undamaged and damaged trajectories of the ``betas`` (tau0, tau(beta), F),
    while the Lambda pass of every method but ``finite-difference`` (the forward tangents, the
    adjoint, the secants, the orbit and central-difference rows) runs on the CPU lanes."""
    if backend == "cuda" and config.lambda_.method != "finite-difference":
        model = " of a model" if config.generalized else ""
        return f"lambda.method {config.lambda_.method}{model} runs its Lambda pass on the CPU"
    return None


def check_job(job: Job, backend: str) -> None:
    """:func:`check_backend` for ``job``'s config, plus what depends on its graph (the CUDA
    kernels keep a trajectory's state in fixed-size per-thread arrays of ``MAX_NODES``; a
    float32 state resolves ``r`` to about ``N`` float32 roundings, :func:`check_float32_threshold`)."""
    check_backend(job.config, backend)
    dyn = job.config.dynamics
    if dyn.precision == "float32":
        check_float32_threshold(dyn.threshold, len(job.nodes))
    if backend != "cuda" and dyn.precision == "float32" and job.model is None:
        from antisync.kernels.core import TAYLOR_MAX_ANGLE
        from antisync.kernels.cpu import rotation_angle_bound

        bound = rotation_angle_bound(dyn.dt, job.csr.indptr, job.csr.weights, job.variant_weights)
        if bound > TAYLOR_MAX_ANGLE:
            raise ConfigError(
                f"dynamics.precision float32 on the cpu backend needs every rotation angle "
                f"dt * sum_j |w_ij| <= {TAYLOR_MAX_ANGLE}; graph {job.name} at dt {dyn.dt} reaches "
                f"{bound:.4g}: use a smaller dynamics.dt or precision float64"
            )
    if backend == "cuda":
        from antisync.kernels.cuda import MAX_NODES

        if len(job.nodes) > MAX_NODES:
            raise ConfigError(
                f"graph {job.name} has {len(job.nodes)} nodes; the cuda backend runs at most "
                f"{MAX_NODES}: use --backend cpu"
            )


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
    (only the items marked by ``todo``, see :func:`antisync.kernels.cpu.simulate`).

    A generalized model's ``variant_weights`` other than the job's own variants or
    :attr:`~antisync.plan.jobs.Job.orbit_weights` need their ``variant_targets`` (the criterion's
    target of each row: the relative criterion's moves with the weights)."""
    dyn = job.config.dynamics
    check_backend(job.config, backend)
    if job.model is not None:
        if todo is not None and backend == "cuda":
            raise ValueError("the CUDA model kernel integrates every item (no todo)")
        return _simulate_model(
            job, first, count, backend, threads, variant_weights, realizations, todo, variant_targets
        )
    kwargs = {"precision": dyn.precision}
    if backend != "cuda":
        kwargs["threads"] = threads
    if realizations is not None:
        kwargs["realizations"] = realizations
    if todo is not None:
        kwargs["todo"] = todo
    weights = job.variant_weights if variant_weights is None else variant_weights
    if dyn.integrator != "euler":
        kwargs["integrator"] = dyn.integrator
    return _kernel(backend).simulate(
        job.config.seed,
        first,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        weights,
        dt=dyn.dt,
        threshold=dyn.threshold,
        max_steps=dyn.max_steps,
        **kwargs,
    )


def model_params(setup, model, seed: int, ks: np.ndarray, n: int, targets: np.ndarray):
    """The model kernels' :class:`~antisync.kernels.model_steps.ModelParams` for realizations
    ``ks`` of ``n`` nodes (``setup``: :class:`~antisync.plan.model.ModelSetup`; ``model``: the config's
    model section): fixed frequencies (one row), drawn ones (a row per realization, in the
    rotating frame of docs/models.md, the distribution's mean never added) or none."""
    from antisync.kernels.model_steps import ModelParams
    from antisync.plan.model import drawn_frequencies

    if model.drawn:
        freqs = drawn_frequencies(model, seed, ks, n)
    else:
        freqs = (np.zeros(n) if setup.freqs is None else setup.freqs)[None, :]
    return ModelParams(
        freqs, setup.cos_lag, setup.sin_lag, setup.inertia, setup.damping, setup.criterion, targets
    )


def _model_params(job: Job, ks: np.ndarray, targets: np.ndarray):
    """:func:`model_params` of ``job``."""
    return model_params(job.model, job.config.model, job.config.seed, ks, len(job.nodes), targets)


def _simulate_model(
    job, first, count, backend, threads, variant_weights, realizations, todo=None, variant_targets=None
):
    """:func:`simulate_job` for a generalized model (docs/models.md)."""
    from antisync.kernels import cpu

    if backend == "cuda":
        from antisync.kernels.cuda import simulate_model
    else:
        simulate_model = functools.partial(cpu.simulate_model, threads=threads)

    setup = job.model
    targets = setup.targets
    if variant_weights is None:
        variant_weights = job.variant_weights
    elif variant_weights is job.orbit_weights:
        # the +-dbeta rows of central-difference / orbit, each with its own target (relative)
        targets = np.concatenate([setup.targets[:1], setup.orbit_targets])
    elif variant_targets is not None and len(variant_targets) == len(variant_weights):
        targets = np.concatenate([setup.targets[:1], variant_targets])
    else:
        raise ValueError("other weights for a generalized model need their variant_targets")
    ks = cpu._realization_ids(first, count, realizations)
    params = _model_params(job, ks, targets)
    dyn = job.config.dynamics
    return simulate_model(
        job.config.seed,
        0,
        0,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        variant_weights,
        params,
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        integrator=dyn.integrator,
        realizations=ks,
        **({} if todo is None else {"todo": todo}),
    )


def lambda_values(
    job: Job, sim, first: int, count: int, threads: int | None = None, *, with_tau: bool = False
):
    """Per-realization Lambda^KM estimates for every edge of ``job`` by ``lambda.method``.

    Returns ``(values, code, flagged, base)`` with ``values``/``code``/``flagged`` of shape
    ``(count, E)`` (see :func:`antisync.stats.estimators.lambda_block_records`) and ``base`` the
    undamaged outcome when the pathwise, adjoint or orbit pass produced it (else None). With
    ``with_tau``, also ``slope`` and ``tau0`` ``(count, E)``: the same estimator's slope of
    ``tau(beta)`` at 0 (time per unit beta: the forward secant ``(tau(dbeta) - tau0)/dbeta``,
    the central one, or the derivative ``d tau0/d beta``) and ``tau0``, for Lambda^tau.
    """
    spec = job.config.lambda_
    dyn = job.config.dynamics
    n_edges = len(job.edges)
    if spec.method == "finite-difference":
        v = _fd_variants(job)
        t0, t = estimators.crossing_times(sim, dyn.interpolate)
        t = t[:, v]
        ok = (sim.status0[:, None] == SYNCED) & (sim.status[:, v] == SYNCED)
        code = np.where(ok, SYNCED, np.maximum(sim.status0[:, None], sim.status[:, v])).astype(np.int8)
        values = np.where(ok, (t0[:, None] / np.where(ok, t, 1.0) - 1.0) / job.dbeta, 0.0)
        out = (values, code, np.zeros_like(ok), None)
        if with_tau:
            # the order of the CUDA reducer's operations, so the two give the same bits
            slope = np.where(ok, (t - t0[:, None]) * dyn.dt / job.dbeta, 0.0)
            out += (slope, np.broadcast_to((t0 * dyn.dt)[:, None], ok.shape))
        return out

    if spec.method in ("orbit", "central-difference"):
        out = _orbit_values(job, sim, first, count, threads)
        return out if with_tau else out[:4]

    pw = _derivative_pass(job, first, count, threads)
    tau0 = (pw.steps0 - 1 + pw.frac0) * dyn.dt
    ok0 = pw.status0 == SYNCED
    values = np.where(ok0[:, None], -pw.dtau / np.where(ok0, tau0, 1.0)[:, None], 0.0)
    slope = np.where(ok0[:, None], pw.dtau, 0.0)
    code = np.repeat(pw.status0[:, None], n_edges, axis=1).astype(np.int8)
    flagged = np.zeros((count, n_edges), dtype=bool)
    if spec.method in ("hybrid", "adjoint-hybrid"):
        flagged = ok0[:, None] & (np.abs(values) > spec.hybrid_cut)
        _secants(job, values, code, flagged, tau0, first, threads, slope)
    out = (values, code, flagged, pw)
    return out + (slope, np.broadcast_to(tau0[:, None], values.shape)) if with_tau else out


def _secants(job: Job, values, code, flagged, tau0, first: int, threads: int | None, slope=None) -> None:
    """Replace the flagged values by central secants ``tau0 (1/tau(+dbeta) - 1/tau(-dbeta)) /
    (2 dbeta)`` of interpolated times, in place (``hybrid``, ``adjoint-hybrid``).

    Central, not forward: a flagged realization passes near a saddle, where tau(beta) has a
    logarithmic singularity close to beta = 0, and a one-sided secant there carries a bias of
    its side that no usable dbeta removes (docs/equations.md, "Lambda near saddle passages");
    the central one estimates the same derivative d<F>/dbeta as the pathwise bulk.

    One integration call for every flagged (realization, link) pair and nothing else (the
    lane driver's ``todo``): its lanes are refilled from the flagged pairs only, so the extra
    cost is the flagged pairs' two trajectories, however they scatter over realizations and
    links. Each secant is the same trajectory whatever shares the call.
    """
    rows = np.flatnonzero(flagged.any(axis=1))
    if rows.size == 0:
        return
    links = np.flatnonzero(flagged.any(axis=0))
    pairs = flagged[np.ix_(rows, links)]
    todo = np.concatenate([np.zeros((rows.size, 1), dtype=bool), pairs, pairs], axis=1)
    index = np.concatenate([links, links + len(job.edges)])
    targets = None if job.model is None else job.model.secant_targets[index]
    sec = simulate_job(
        job, 0, 0, "cpu", threads, job.secant_weights[index], first + rows, todo, variant_targets=targets
    )
    tau = (sec.steps - 1 + sec.frac) * job.config.dynamics.dt
    plus, minus = tau[:, : links.size], tau[:, links.size :]
    s_plus, s_minus = sec.status[:, : links.size], sec.status[:, links.size :]
    good = pairs & (s_plus == SYNCED) & (s_minus == SYNCED)
    bad = pairs & ~good
    r, e = np.broadcast_arrays(rows[:, None], links[None, :])
    t0 = tau0[r[good]]
    values[r[good], e[good]] = t0 * (1.0 / plus[good] - 1.0 / minus[good]) / (2.0 * job.dbeta)
    if slope is not None:  # Lambda^tau's slope of tau, by the same central secant
        slope[r[good], e[good]] = (plus[good] - minus[good]) / (2.0 * job.dbeta)
    code[r[bad], e[bad]] = np.where(s_plus[bad] != SYNCED, s_plus[bad], s_minus[bad])


def _derivative_pass(job: Job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of every edge along the undamaged trajectories: forward tangents
    (``pathwise``, ``hybrid``) or one adjoint pass (``adjoint``, ``adjoint-hybrid``)."""
    dyn = job.config.dynamics
    kw = dict(dt=dyn.dt, threshold=dyn.threshold, max_steps=dyn.max_steps, threads=threads)
    edge_a, edge_b, rho, mu = job.tangent
    if job.model is not None:
        return _model_adjoint_pass(job, first, count, threads)
    if job.config.lambda_.method in ("adjoint", "adjoint-hybrid"):
        from antisync.kernels.adjoint import link_derivatives, simulate_adjoint

        edges = list(zip(edge_a.tolist(), edge_b.tolist(), strict=True))
        deriv = link_derivatives(job.omega, job.csr, edges, dyn.coupling)
        return simulate_adjoint(
            job.config.seed,
            first,
            count,
            job.csr.indptr,
            job.csr.indices,
            job.csr.weights,
            deriv,
            integrator=dyn.integrator,
            **kw,
        )
    from antisync.kernels.cpu import simulate_pathwise

    return simulate_pathwise(
        job.config.seed,
        first,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        edge_a,
        edge_b,
        rho,
        mu,
        **kw,
    )


def _model_adjoint_pass(job: Job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of a generalized model by the adjoint of its step and of its
    dense-output crossing (:mod:`antisync.kernels.model_adjoint`)."""
    from antisync.kernels.adjoint import link_derivatives
    from antisync.kernels.cpu import _realization_ids
    from antisync.kernels.model_adjoint import simulate_model_adjoint

    dyn = job.config.dynamics
    setup = job.model
    params = _model_params(job, _realization_ids(first, count, None), setup.targets[:1])
    edge_a, edge_b, _, _ = job.tangent
    edges = list(zip(edge_a.tolist(), edge_b.tolist(), strict=True))
    return simulate_model_adjoint(
        job.config.seed,
        first,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        link_derivatives(job.omega, job.csr, edges, dyn.coupling),
        params,
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        integrator=dyn.integrator,
        dtarget=setup.dtarget,
        threads=threads,
    )


def _orbit_values(job: Job, sim, first: int, count: int, threads: int | None):
    """Central differences along each edge's orbit (``lambda.method: orbit``; a link alone
    for ``central-difference``).

    One pass integrates tau0 and the ``+dbeta``/``-dbeta`` variants of every orbit; its
    undamaged outcome is returned as ``base`` (equal to ``sim``'s when both exist).
    """
    dyn = job.config.dynamics
    osim = simulate_job(job, first, count, "cpu", threads, job.orbit_weights)
    t0, t = estimators.crossing_times(osim, dyn.interpolate)
    plus, minus = t[:, 0::2], t[:, 1::2]
    s_plus, s_minus = osim.status[:, 0::2], osim.status[:, 1::2]
    ok = (osim.status0[:, None] == SYNCED) & (s_plus == SYNCED) & (s_minus == SYNCED)
    code = np.where(ok, SYNCED, np.maximum(osim.status0[:, None], np.maximum(s_plus, s_minus)))
    inv = np.where(ok, 1.0 / np.where(ok, plus, 1.0) - 1.0 / np.where(ok, minus, 1.0), 0.0)
    values = t0[:, None] * inv / (2.0 * job.dbeta * job.orbit_sizes[None, :])
    values = np.where(ok, values, 0.0)
    slope = np.where(ok, (plus - minus) * dyn.dt / (2.0 * job.dbeta * job.orbit_sizes[None, :]), 0.0)
    tau0 = np.broadcast_to((t0 * dyn.dt)[:, None], ok.shape)
    return values, code.astype(np.int8), np.zeros_like(ok), osim, slope, tau0


def _sync_flips(job: Job, sim) -> np.ndarray:
    """Per (realization, edge) of a finite difference: ``-1`` where tau0 synchronized and
    tau(dbeta) did not, ``+1`` for the reverse, else 0 (the synchronized fraction's response)."""
    s0 = sim.status0[:, None]
    s = sim.status[:, _fd_variants(job)]
    lost = (s0 == SYNCED) & (s == NOT_SYNCED)
    gained = (s0 == NOT_SYNCED) & (s == SYNCED)
    return (gained.astype(np.int8) - lost.astype(np.int8)).astype(np.int8)


def _fd_variants(job: Job) -> np.ndarray:
    """The variant at ``dbeta`` of every edge: the finite difference of Lambda^KM."""
    return np.array([job.variant(e, job.dbeta) for e in range(len(job.edges))], dtype=np.int64)


def _compute_on_device(job: Job, chunk: Chunk, first: int, count: int, start: float) -> ChunkResult:
    """A chunk reduced on the GPU: only block records and histograms come back."""
    from antisync.kernels.cuda import simulate_reduced

    dyn = job.config.dynamics
    hcfg = job.config.histogram
    red = simulate_reduced(
        job.config.seed,
        first,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        job.variant_weights,
        dt=dyn.dt,
        threshold=dyn.threshold,
        max_steps=dyn.max_steps,
        block=job.block_size,
        hist_variants=job.hist_variants,
        bins=hcfg.bins,
        tau_max=hcfg.tau_max,
        lambda_variants=_fd_variants(job),
        dbeta=job.dbeta,
        precision=dyn.precision,
    )
    return ChunkResult(
        chunk,
        red.rec,
        red.rec0,
        red.tail,
        red.hist,
        red.lam_rec,
        red.lam_tail,
        None,
        first,
        count,
        time.perf_counter() - start,
        "cuda",
    )


def compute_chunk(job: Job, chunk: Chunk, backend: str = "cpu", threads: int | None = None) -> ChunkResult:
    """Integrate and reduce one chunk (pure: no files, no progress bars).

    On backend cuda a chunk that keeps no per-realization pairs (it lies beyond
    ``keep_pairs``) is reduced on the GPU (:func:`antisync.kernels.cuda.simulate_reduced`,
    records identical to the host's), so only block records and histograms cross the bus.
    """
    start = time.perf_counter()
    first, count = chunk.realizations(job.block_size, job.config.realizations)
    derivative = job.config.lambda_.method != "finite-difference"
    if backend == "cuda" and job.config.keep_pairs <= first and job.model is None and not derivative:
        check_backend(job.config, backend)
        return _compute_on_device(job, chunk, first, count, start)
    if derivative and len(job.variant_edge) == 0:
        sim = None  # Lambda only: the Lambda pass integrates the undamaged network itself
    else:
        sim = simulate_job(job, first, count, backend, threads)
    values, code, flagged, base, slope, tau0 = lambda_values(job, sim, first, count, threads, with_tau=True)
    if sim is None:
        from antisync.kernels.cpu import SimResult

        empty = np.empty((count, 0))
        sim = SimResult(
            base.status0, base.steps0, empty.astype(np.int8), empty.astype(np.int64), base.frac0, empty
        )
    dyn = job.config.dynamics
    interpolate = dyn.interpolate
    dt = dyn.dt
    rec, rec0, tail = estimators.block_records(sim, dt, job.block_size, interpolate)
    flip = _sync_flips(job, sim) if not derivative else None
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
