"""Which functions compute a chunk: one table over (model, ``lambda.method``, integrator,
backend, precision).

Every combination is a cell of :data:`TABLE`: a :class:`Row` where it runs, holding the
integration :class:`Driver` (the kernels' entry point for the model kind on the backend) and the
:class:`LambdaPass` (the estimator's values from the integrated trajectories, or from the
trajectories it integrates itself); a :class:`Refusal` where it does not, holding the one-line
message the run gets. :mod:`antisync.execution.compute` looks a chunk's row up once and calls
what it holds; :mod:`antisync.execution.capabilities` prints the same cells (docs/models.md).

Adding an integrator or a precision is a value of :mod:`antisync.types` the drivers accept
(the refusals say where it does not run); adding an estimator is a row of :data:`PASSES` and its
declaration in :data:`antisync.types.LAMBDA_ROWS` (the rows it needs built); adding
a backend is a row of :data:`DRIVERS` per model kind. A cell with neither a row nor a refusal is
an error when this module is imported, so the table cannot leave a combination unexplained.

The kernels are imported inside the functions: numba's import (and numba-cuda's, which needs
a driver) stays out of the table, which ``antisync capabilities`` and ``antisync validate``
read without integrating anything.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from antisync.errors import ConfigError
from antisync.kernels import cpu, implicit
from antisync.kernels.adjoint import link_derivatives, simulate_adjoint
from antisync.kernels.core import TAYLOR_MAX_ANGLE
from antisync.kernels.model_adjoint import simulate_model_adjoint
from antisync.kernels.model_steps import ModelParams
from antisync.kernels.shared import realization_ids, rotation_angle_bound
from antisync.plan.model import drawn_frequencies, law_targets, start_phases
from antisync.stats import estimators
from antisync.status import NOT_SYNCED, SYNCED
from antisync.store.state import ChunkResult
from antisync.types import BACKENDS, INTEGRATORS, LAMBDA_METHODS, PRECISIONS

__all__ = [
    "DESIGN_REFUSALS",
    "DRIVERS",
    "MODEL_KINDS",
    "PASSES",
    "REFUSALS",
    "TABLE",
    "TRIP_ROWS",
    "DesignDrivers",
    "Driver",
    "Key",
    "LambdaPass",
    "Refusal",
    "Row",
    "design_drivers",
    "fd_variants",
    "job_model_params",
    "key_of",
    "lambda_pass",
    "law_params",
    "law_simulator",
    "lookup",
    "model_params",
    "model_kind",
    "model_simulator",
    "trip_simulator",
    "sync_flips",
]

#: the model kinds: Eq. 2's identical first-order oscillators, a generalized model (a
#: ``model:`` or ``sync:`` section, docs/models.md), integrated by the model kernels, and a
#: user's law (``model.law``), integrated by its generated kernels (:mod:`antisync.kernels.law`)
MODEL_KINDS = ("identical", "model", "law")


def model_kind(config) -> str:
    """The model kind (:data:`MODEL_KINDS`) of ``config``."""
    if config.model.law is not None:
        return "law"
    return "model" if config.generalized else "identical"


class Key(NamedTuple):
    """A cell of the table: what a run's config and backend choose."""

    model: str
    method: str
    integrator: str
    backend: str
    precision: str


def key_of(config, backend: str) -> Key:
    """The cell of ``config`` (a :class:`~antisync.plan.config.Config`) run on ``backend``."""
    dyn = config.dynamics
    return Key(model_kind(config), config.lambda_.method, dyn.integrator, backend, dyn.precision)


# -- the integration drivers ------------------------------------------------------------------


def model_params(setup, model, seed: int, ks: np.ndarray, n: int, targets: np.ndarray):
    """The model kernels' :class:`~antisync.kernels.model_steps.ModelParams` for realizations
    ``ks`` of ``n`` nodes (``setup``: :class:`~antisync.plan.model.ModelSetup`; ``model``: the config's
    model section): fixed frequencies (one row), drawn ones (a row per realization, in the
    rotating frame of docs/models.md, the distribution's mean never added) or none; with
    ``model.start`` each realization's start around the locked state."""

    if model.drawn:
        freqs = drawn_frequencies(model, seed, ks, n)
    else:
        freqs = (np.zeros(n) if setup.freqs is None else setup.freqs)[None, :]
    starts = None if setup.start is None else start_phases(setup.start, model.start["width"], seed, ks)
    return ModelParams(
        freqs, setup.cos_lag, setup.sin_lag, setup.inertia, setup.damping, setup.criterion, targets, starts
    )


def job_model_params(job, ks: np.ndarray, targets: np.ndarray):
    """:func:`model_params` of ``job``."""
    return model_params(job.model, job.config.model, job.config.seed, ks, len(job.nodes), targets)


def _network(job, first: int, count: int) -> tuple:
    """The arguments every kernel entry point starts with: ``(seed, first, count, indptr,
    indices, weights)`` of ``job``'s realizations ``first .. first + count`` on its network."""
    csr = job.csr
    return job.config.seed, first, count, csr.indptr, csr.indices, csr.weights


def _clock(dyn, *, threshold: bool = True) -> dict:
    """The step settings of ``dyn`` (a :class:`~antisync.plan.config.Dynamics`) as the kernels'
    keywords: ``dt``, ``max_steps`` and, for Eq. 2's threshold criterion, ``threshold`` (a
    generalized model's criterion travels in its targets)."""
    clock = {"dt": dyn.dt, "max_steps": dyn.max_steps}
    if threshold:
        clock["threshold"] = dyn.threshold
    return clock


def _identical(simulate, job, first, count, variant_weights, realizations, todo, **kwargs):
    """Eq. 2's identical oscillators by ``simulate`` (a backend's ``simulate``), ``kwargs`` the
    backend's own (the CPU lanes' ``threads``)."""
    dyn = job.config.dynamics
    kwargs["precision"] = dyn.precision
    if realizations is not None:
        kwargs["realizations"] = realizations
    if todo is not None:
        kwargs["todo"] = todo
    weights = job.variant_weights if variant_weights is None else variant_weights
    if dyn.integrator != "euler":
        kwargs["integrator"] = dyn.integrator
    return simulate(
        *_network(job, first, count),
        weights,
        **_clock(dyn),
        **kwargs,
    )


def _identical_lanes(job, first, count, threads, variant_weights, realizations, todo, variant_targets):
    """:func:`antisync.kernels.cpu.simulate` (float64 Euler or RK4, float32 Euler)."""

    return _identical(cpu.simulate, job, first, count, variant_weights, realizations, todo, threads=threads)


def _identical_cuda(job, first, count, threads, variant_weights, realizations, todo, variant_targets):
    """:func:`antisync.kernels.cuda.simulate` (Euler, grid crossings, float64 or float32)."""
    # lazy: numba-cuda is optional; the CUDA kernels load only for a cuda row
    from antisync.kernels.cuda import simulate

    return _identical(simulate, job, first, count, variant_weights, realizations, todo)


def _model(simulate_model, job, first, count, variant_weights, realizations, todo, variant_targets):
    """A generalized model (docs/models.md) by ``simulate_model`` (a backend's)."""

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
    ks = realization_ids(first, count, realizations)
    params = job_model_params(job, ks, targets)
    dyn = job.config.dynamics
    return simulate_model(
        *_network(job, 0, 0),
        variant_weights,
        params,
        **_clock(dyn, threshold=False),
        realizations=ks,
        **({} if todo is None else {"todo": todo}),
    )


#: The integrators of a line trip (``antisync grid --trip``: the swing equation, or a user's law,
#: from the operating point, with a fault and the trip; :mod:`antisync.kernels.trip`, the law's
#: generated ``law_one_trip_rk4`` and ``law_one_trip_rodas4``), by model kind (``model`` or ``law``), and
#: why the others do not run one.
TRIP_ROWS: dict[tuple[str, str], str | None] = {
    ("model", "euler"): (
        "a line trip integrates by rk4 or rodas4 (Euler's first-order step under-resolves the swing)"
    ),
    ("model", "rk4"): None,
    ("model", "rodas4"): None,
    ("law", "euler"): (
        "a law's line trip integrates by rk4 or rodas4 (Euler's first-order step under-resolves the swing)"
    ),
    ("law", "rk4"): None,
    ("law", "rodas4"): None,
}


def trip_simulator(integrator: str, law: bool = False) -> Callable:
    """The trip kernels' driver with ``integrator`` bound (:func:`antisync.kernels.trip.integrate_trips`;
    with ``law`` :func:`antisync.kernels.law.integrate_law_trips`), or the row's one-line refusal
    (:data:`TRIP_ROWS`) as a :class:`~antisync.errors.ConfigError`."""
    kind = "law" if law else "model"
    why = TRIP_ROWS.get((kind, integrator), f"a line trip integrates by rk4 or rodas4, not {integrator}")
    if why is not None:
        raise ConfigError(why)
    if law:
        from antisync.kernels.law import integrate_law_trips

        return functools.partial(integrate_law_trips, integrator=integrator)
    from antisync.kernels.trip import integrate_trips

    return functools.partial(integrate_trips, integrator=integrator)


#: Where a design (``antisync design``, :mod:`antisync.optimize`) cannot run, by the config value
#: that rules it out: it differentiates the explicit steps, on the CPU.
DESIGN_REFUSALS: dict[str, str] = {
    "rodas4": "a design differentiates dynamics.integrator euler or rk4, not rodas4 (the adjoint is "
    "written for the explicit steps)",
    "cuda": "a design runs on the CPU: set backend: cpu (or leave it out)",
    "relative": "a design cannot use sync.criterion relative (its target r* moves with every weight "
    "and has no derivative here): use order-parameter or frequency",
    "model.start": "a design cannot use model.start (its starts lie around the locked state of the "
    "weights being designed, which moves with every step and has no derivative here): drop "
    "model.start (uniform phases)",
}


def _design_keys(config) -> tuple:
    """What of ``config`` :data:`DESIGN_REFUSALS` is keyed by: the integrator, the backend, the
    criterion, a given start."""
    return (
        config.dynamics.integrator,
        config.backend,
        config.sync.criterion,
        "model.start" if config.model.start is not None else None,
    )


class DesignDrivers(NamedTuple):
    """A design's two kernels for a config (:func:`design_drivers`), one signature whatever the
    model kind (``params``: the model's :class:`~antisync.kernels.model_steps.ModelParams`, a
    law's :class:`~antisync.kernels.law.LawParams`, None for Eq. 2's identical oscillators):

    - ``forward(seed, indptr, indices, base_w, var_w, params, ks, threads, todo)``: the times of
      the base weights and of every row of ``var_w`` on the starts ``ks`` (a
      :class:`~antisync.kernels.shared.SimResult`);
    - ``adjoint(seed, indptr, indices, weights, deriv, params, ks, threads)``: each start's
      ``d tau0 / d x`` along ``deriv`` (a :class:`~antisync.kernels.shared.PathwiseResult`).
    """

    forward: Callable
    adjoint: Callable


def design_drivers(config) -> DesignDrivers:
    """The kernels of a design of ``config`` (a :class:`~antisync.plan.config.Config`), or the
    one-line :class:`~antisync.errors.ConfigError` of :data:`DESIGN_REFUSALS`."""
    dyn = config.dynamics
    for value in _design_keys(config):
        if value in DESIGN_REFUSALS:
            raise ConfigError(DESIGN_REFUSALS[value])
    clock = {"dt": dyn.dt, "max_steps": dyn.max_steps}
    if config.generalized:
        if model_kind(config) == "law":
            from antisync.kernels.law import simulate_law, simulate_law_adjoint

            # RK4 on the angles: the steps the adjoint runs backwards, so the gradient is the
            # derivative of the forward's tau (the circle form differs by the method's error)
            simulate = functools.partial(simulate_law, integrator=dyn.integrator, circle=False)
            backward = simulate_law_adjoint
        else:
            simulate = model_simulator(dyn)
            backward = simulate_model_adjoint

        def forward(seed, indptr, indices, base_w, var_w, params, ks, threads, todo):
            return simulate(
                seed,
                0,
                0,
                indptr,
                indices,
                base_w,
                var_w,
                params,
                **clock,
                threads=threads,
                realizations=ks,
                todo=todo,
            )

        def adjoint(seed, indptr, indices, weights, deriv, params, ks, threads):
            return backward(
                seed,
                0,
                0,
                indptr,
                indices,
                weights,
                deriv,
                params,
                **clock,
                integrator=dyn.integrator,
                threads=threads,
                realizations=ks,
            )

        return DesignDrivers(forward, adjoint)
    clock["threshold"] = dyn.threshold

    def forward_identical(seed, indptr, indices, base_w, var_w, params, ks, threads, todo):
        return cpu.simulate(
            seed,
            0,
            0,
            indptr,
            indices,
            base_w,
            var_w,
            **clock,
            threads=threads,
            realizations=ks,
            integrator=dyn.integrator,
            todo=todo,
        )

    def adjoint_identical(seed, indptr, indices, weights, deriv, params, ks, threads):
        return simulate_adjoint(
            seed,
            0,
            0,
            indptr,
            indices,
            weights,
            deriv,
            **clock,
            threads=threads,
            realizations=ks,
            integrator=dyn.integrator,
        )

    return DesignDrivers(forward_identical, adjoint_identical)


def model_simulator(dynamics, give_up: tuple[float, float] | None = None) -> Callable:
    """The CPU model driver of ``dynamics.integrator`` (a config's
    :class:`~antisync.plan.config.Dynamics`) with its settings bound: the lanes of
    :func:`antisync.kernels.cpu.simulate_model` (Euler, RK4) or
    :func:`antisync.kernels.implicit.simulate_model` (Rodas4 at ``dynamics.rtol``/``atol``, and
    ``give_up``: ``sync.give_up_rule``, which the config allows with rodas4 only)."""
    rtol, atol = dynamics.tolerances
    if give_up is not None and dynamics.integrator != "rodas4":
        raise ValueError(f"give_up stops rodas4 early; integrator {dynamics.integrator} has no such stop")
    return {
        "euler": functools.partial(cpu.simulate_model, integrator="euler"),
        "rk4": functools.partial(cpu.simulate_model, integrator="rk4"),
        "rodas4": functools.partial(implicit.simulate_model, rtol=rtol, atol=atol, give_up=give_up),
    }[dynamics.integrator]


def law_simulator(dynamics) -> Callable:
    """A user's law's CPU driver with ``dynamics.integrator`` bound
    (:func:`antisync.kernels.law.simulate_law`: Euler, RK4 or Rodas4; its tolerances are in the
    :class:`~antisync.kernels.law.LawParams` of :func:`law_params`): :func:`model_simulator`'s
    counterpart for ``model.law``."""
    from antisync.kernels.law import simulate_law

    return functools.partial(simulate_law, integrator=dynamics.integrator)


def base_network_times(
    job, ks: np.ndarray, dt: float, max_steps: int, threads=None, tolerances: tuple | None = None
) -> tuple:
    """``(status, tau)`` of ``job``'s undamaged network on realizations ``ks`` at step ``dt``
    (``tau`` in the model's units, NaN unless SYNCED) by the CPU driver of its model kind: what
    the step check (:mod:`antisync.execution.step_check`) compares at ``dt`` and ``dt / 2``, or
    (``tolerances``: Rodas4's ``(rtol, atol)`` in place of the config's) at two tolerances."""
    csr = job.csr
    dynamics = job.config.dynamics
    if tolerances is not None:
        dynamics = dataclasses.replace(dynamics, rtol=float(tolerances[0]), atol=float(tolerances[1]))
    common = (job.config.seed, 0, 0, csr.indptr, csr.indices, csr.weights, np.zeros((0, csr.weights.size)))
    clock = {"dt": dt, "max_steps": int(max_steps), "threads": threads, "realizations": ks}
    if model_kind(job.config) == "law":
        sim = law_simulator(dynamics)(*common, law_params(job.law, dynamics, 1), **clock)
    else:
        params = job_model_params(job, ks, job.model.targets[:1])
        sim = model_simulator(dynamics)(*common, params, **clock)
    t0, _ = estimators.crossing_times(sim, dynamics.interpolate)
    return sim.status0, np.where(sim.status0 == SYNCED, t0 * dt, np.nan)


def _law_lanes(job, first, count, threads, variant_weights, realizations, todo, variant_targets):
    """A user's law by its generated kernels (:func:`antisync.kernels.law.simulate_law`; Euler,
    RK4 or Rodas4, one trajectory per item). Every network has the job's one target, or with the
    relative criterion its own (:func:`_law_params`: ``variant_targets`` is the built-in
    model's)."""
    weights = job.variant_weights if variant_weights is None else variant_weights
    dyn = job.config.dynamics
    return law_simulator(dyn)(
        *_network(job, first, count),
        weights,
        _law_params(job, weights),
        **_clock(dyn, threshold=False),
        threads=threads,
        realizations=realizations,
        todo=todo,
    )


def _law_step(job) -> None:
    """A law checked finite at its start, and its explicit step on its own Jacobian
    (:func:`antisync.kernels.law.check_step`)."""
    if job.kuramoto:
        from antisync.kernels.law import check_step

        check_step(job.law, job.config.seed, job.csr, job.config.dynamics)


def _model_lanes(job, first, count, threads, variant_weights, realizations, todo, variant_targets):
    """:func:`model_simulator`'s driver (Euler or RK4 lanes, Rodas4; float64)."""

    simulate = functools.partial(model_simulator(job.config.dynamics), threads=threads)
    return _model(simulate, job, first, count, variant_weights, realizations, todo, variant_targets)


def _model_cuda(job, first, count, threads, variant_weights, realizations, todo, variant_targets):
    """:func:`antisync.kernels.cuda.simulate_model` (Euler or RK4, float64; every item)."""
    if todo is not None:
        raise ValueError("the CUDA model kernel integrates every item (no todo)")
    # lazy: numba-cuda is optional; the CUDA kernels load only for a cuda row
    from antisync.kernels.cuda import simulate_model

    simulate = functools.partial(simulate_model, integrator=job.config.dynamics.integrator)
    return _model(simulate, job, first, count, variant_weights, realizations, todo, variant_targets)


def _reduce_on_device(job, chunk, first: int, count: int, start: float) -> ChunkResult:
    """A finite-difference chunk reduced on the GPU: only block records and histograms come back
    (:func:`antisync.kernels.cuda.simulate_reduced`, records identical to the host's)."""
    # lazy: numba-cuda is optional; the CUDA kernels load only for a cuda row
    from antisync.kernels.cuda import simulate_reduced

    dyn = job.config.dynamics
    hcfg = job.config.histogram
    red = simulate_reduced(
        *_network(job, first, count),
        job.variant_weights,
        **_clock(dyn),
        block=job.block_size,
        hist_variants=job.hist_variants,
        bins=hcfg.bins,
        tau_max=hcfg.tau_max,
        lambda_variants=fd_variants(job),
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


def _rotation_angles(job) -> None:
    """The CPU's float32 lanes rotate by Taylor polynomials: refuse a step whose rotation angle
    ``dt * sum_j |w_ij|`` they do not resolve (float64 runs any)."""
    dyn = job.config.dynamics
    if dyn.precision != "float32":
        return

    bound = rotation_angle_bound(dyn.dt, job.csr.indptr, job.csr.weights, job.variant_weights)
    if bound > TAYLOR_MAX_ANGLE:
        raise ConfigError(
            f"dynamics.precision float32 on the cpu backend needs every rotation angle "
            f"dt * sum_j |w_ij| <= {TAYLOR_MAX_ANGLE}; graph {job.name} at dt {dyn.dt} reaches "
            f"{bound:.4g}: use a smaller dynamics.dt or precision float64"
        )


def _cuda_nodes(job) -> None:
    """The CUDA kernels keep a trajectory's state in fixed-size per-thread arrays of ``MAX_NODES``."""
    # lazy: numba-cuda is optional; the CUDA kernels load only for a cuda row
    from antisync.kernels.cuda import MAX_NODES

    if len(job.nodes) > MAX_NODES:
        raise ConfigError(
            f"graph {job.name} has {len(job.nodes)} nodes; the cuda backend runs at most "
            f"{MAX_NODES}: use --backend cpu"
        )


def _no_check(job) -> None:
    """Nothing of the graph limits the driver."""


#: the fixed-step integrators (Euler, RK4); the CPU model driver also runs ``rodas4``
_EXPLICIT = ("euler", "rk4")


@dataclass(frozen=True)
class Driver:
    """How one model kind's trajectories are integrated on one backend.

    Attributes
    ----------
    model, backend : str
        The model kind (:data:`MODEL_KINDS`) and the backend.
    simulate : callable
        ``simulate(job, first, count, threads, variant_weights, realizations, todo,
        variant_targets)`` -> :class:`~antisync.kernels.shared.SimResult`: tau0 and the variants
        (``None`` arguments: the job's own), see :func:`antisync.execution.compute.simulate_job`.
    check_job : callable
        ``check_job(job)``: what depends on the graph rather than on the cell (raises
        :class:`~antisync.errors.ConfigError`).
    device : bool
        Integrates on an accelerator: a Lambda pass that integrates trajectories of its own runs
        on the CPU lanes beside it (:attr:`Row.host_part`).
    reduce : callable or None
        ``reduce(job, chunk, first, count, start)`` -> :class:`~antisync.store.state.ChunkResult`:
        a chunk that keeps no per-realization pairs reduced where it was integrated, for the
        method ``reduces``.
    reduces : str or None
        The ``lambda.method`` whose Lambda ``reduce`` computes.
    no_interpolation : str or None
        Why ``dynamics.crossing interpolated`` does not run here (None: it does).
    integrators : tuple of str
        The ``dynamics.integrator`` values it integrates.
    """

    model: str
    backend: str
    simulate: Callable
    check_job: Callable = _no_check
    device: bool = False
    reduce: Callable | None = None
    reduces: str | None = None
    no_interpolation: str | None = None
    integrators: tuple[str, ...] = _EXPLICIT


#: (model kind, integrator, backend) -> the driver integrating it there
DRIVERS: dict[tuple[str, str, str], Driver] = {
    (d.model, integrator, d.backend): d
    for d in (
        Driver("identical", "cpu", _identical_lanes, check_job=_rotation_angles),
        Driver(
            "identical",
            "cuda",
            _identical_cuda,
            check_job=_cuda_nodes,
            device=True,
            reduce=_reduce_on_device,
            reduces="finite-difference",
            no_interpolation=(
                "dynamics.crossing interpolated runs on the cpu backend only (the CUDA kernels "
                "return grid crossing times); use --backend cpu or crossing grid"
            ),
        ),
        Driver("model", "cpu", _model_lanes, integrators=(*_EXPLICIT, "rodas4")),
        Driver("model", "cuda", _model_cuda, check_job=_cuda_nodes, device=True),
        Driver("law", "cpu", _law_lanes, check_job=_law_step, integrators=(*_EXPLICIT, "rodas4")),
    )
    for integrator in d.integrators
}


def _lanes(job) -> Driver:
    """The CPU driver of ``job``'s model kind and integrator: where every Lambda pass integrates."""
    kind = "law" if job.law is not None else "identical" if job.model is None else "model"
    return DRIVERS[kind, job.config.dynamics.integrator, "cpu"]


# -- the Lambda passes ------------------------------------------------------------------------


def fd_variants(job) -> np.ndarray:
    """The variant at ``dbeta`` of every edge: the finite difference of Lambda^KM."""
    return np.array([job.variant(e, job.dbeta) for e in range(len(job.edges))], dtype=np.int64)


def sync_flips(job, sim) -> np.ndarray:
    """Per (realization, edge) of a finite difference: ``-1`` where tau0 synchronized and
    tau(dbeta) did not, ``+1`` for the reverse, else 0 (the synchronized fraction's response)."""
    s0 = sim.status0[:, None]
    s = sim.status[:, fd_variants(job)]
    lost = (s0 == SYNCED) & (s == NOT_SYNCED)
    gained = (s0 == NOT_SYNCED) & (s == SYNCED)
    return (gained.astype(np.int8) - lost.astype(np.int8)).astype(np.int8)


def _forward_secants(job, sim, first: int, count: int, threads: int | None):
    """``finite-difference``: the paper's forward secant ``(tau0 / tau(dbeta) - 1) / dbeta`` of
    every edge, from the chunk's integrated variants (no trajectory of its own)."""
    dyn = job.config.dynamics
    v = fd_variants(job)
    t0, t = estimators.crossing_times(sim, dyn.interpolate)
    t = t[:, v]
    ok = (sim.status0[:, None] == SYNCED) & (sim.status[:, v] == SYNCED)
    code = np.where(ok, SYNCED, np.maximum(sim.status0[:, None], sim.status[:, v])).astype(np.int8)
    values = np.where(ok, (t0[:, None] / np.where(ok, t, 1.0) - 1.0) / job.dbeta, 0.0)
    # the order of the CUDA reducer's operations, so the two give the same bits
    slope = np.where(ok, (t - t0[:, None]) * dyn.dt / job.dbeta, 0.0)
    return values, code, np.zeros_like(ok), None, slope, np.broadcast_to((t0 * dyn.dt)[:, None], ok.shape)


def _orbit_differences(job, sim, first: int, count: int, threads: int | None):
    """Central differences along each edge's orbit (``lambda.method: orbit``; a link alone
    for ``central-difference``).

    One pass integrates tau0 and the ``+dbeta``/``-dbeta`` variants of every orbit; its
    undamaged outcome is returned as ``base`` (equal to ``sim``'s when both exist).
    """
    dyn = job.config.dynamics
    osim = _lanes(job).simulate(job, first, count, threads, job.orbit_weights, None, None, None)
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


def _tangent_pass(job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of every edge by forward tangents along the undamaged trajectories
    (:func:`antisync.kernels.cpu.simulate_pathwise`)."""

    dyn = job.config.dynamics
    edge_a, edge_b, rho, mu = job.tangent
    return cpu.simulate_pathwise(
        *_network(job, first, count),
        edge_a,
        edge_b,
        rho,
        mu,
        **_clock(dyn),
        threads=threads,
    )


def _job_link_derivatives(job):
    """:func:`~antisync.kernels.adjoint.link_derivatives` of ``job``'s tangent edges (what the
    adjoint passes seed their backward sweeps with)."""
    edge_a, edge_b, _, _ = job.tangent
    edges = list(zip(edge_a.tolist(), edge_b.tolist(), strict=True))
    return link_derivatives(job.omega, job.csr, edges, job.config.dynamics.coupling)


def _adjoint_pass(job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of every edge by one adjoint pass per trajectory
    (:func:`antisync.kernels.adjoint.simulate_adjoint`)."""

    dyn = job.config.dynamics
    return simulate_adjoint(
        *_network(job, first, count),
        _job_link_derivatives(job),
        integrator=dyn.integrator,
        **_clock(dyn),
        threads=threads,
    )


def _model_adjoint_pass(job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of a generalized model by the adjoint of its step and of its
    dense-output crossing (:mod:`antisync.kernels.model_adjoint`)."""

    dyn = job.config.dynamics
    setup = job.model
    params = job_model_params(job, realization_ids(first, count, None), setup.targets[:1])
    return simulate_model_adjoint(
        *_network(job, first, count),
        _job_link_derivatives(job),
        params,
        **_clock(dyn, threshold=False),
        integrator=dyn.integrator,
        dtarget=setup.dtarget,
        threads=threads,
    )


def law_params(setup, dynamics, kinds: int, targets: np.ndarray | None = None):
    """The :class:`~antisync.kernels.law.LawParams` of a :class:`~antisync.plan.model.LawSetup`
    for ``kinds`` networks (every one the same target, or ``targets``), Rodas4's tolerances from
    ``dynamics``."""
    from antisync.kernels.law import LawParams

    if setup.fraction is not None and setup.r_star is None:  # a NaN target: never synchronized
        raise ValueError("law_params: the relative criterion's r* is not found yet (with_law_r_star)")
    if setup.start_width is not None and setup.start is None:  # else: the paper's phases, silently
        raise ValueError("law_params: model.start's locked phases are not found yet (with_law_start)")
    rtol, atol = dynamics.tolerances
    targets = np.full(kinds, setup.target) if targets is None else np.asarray(targets, dtype=np.float64)
    return LawParams(
        setup.law, setup.values, targets, rtol, atol, setup.criterion, setup.drawn, setup.edges, setup.start
    )


def _law_params(job, weights=None):
    """A law job's :class:`~antisync.kernels.law.LawParams` for its undamaged network and the
    networks ``weights`` (rows; none by default): with the relative criterion each its own
    target (:func:`antisync.plan.model.law_targets`; the variants' ``r*`` from the job)."""
    setup = job.law
    if weights is None or not len(weights):
        return law_params(setup, job.config.dynamics, 1)
    if setup.fraction is not None and weights is job.variant_weights:
        targets = setup.relative_target(setup.r_star)
    else:
        targets = law_targets(setup, job.csr.indptr, job.csr.indices, weights)
    return law_params(setup, job.config.dynamics, len(weights) + 1, targets)


def _law_adjoint_pass(job, first: int, count: int, threads: int | None):
    """``d tau0 / d beta_e`` of a law by the adjoint of its generated steps and of its crossing
    (:func:`antisync.kernels.law.simulate_law_adjoint`)."""
    from antisync.kernels.law import simulate_law_adjoint

    dyn = job.config.dynamics
    return simulate_law_adjoint(
        *_network(job, first, count),
        _job_link_derivatives(job),
        _law_params(job),
        **_clock(dyn, threshold=False),
        integrator=dyn.integrator,
        dtarget=job.law.dtarget,
        threads=threads,
    )


def _derivatives(job, sim, first: int, count: int, threads: int | None, *, derivative, secants: bool):
    """``-d tau0/d beta / tau0`` of every edge from ``derivative(job, first, count, threads)``
    (the pass along the undamaged trajectories); with ``secants`` (the hybrids) the values beyond
    ``lambda.hybrid_cut`` are replaced by central secants (:func:`_secants`)."""
    spec = job.config.lambda_
    dyn = job.config.dynamics
    n_edges = len(job.edges)
    pw = derivative(job, first, count, threads)
    tau0 = (pw.steps0 - 1 + pw.frac0) * dyn.dt
    ok0 = pw.status0 == SYNCED
    values = np.where(ok0[:, None], -pw.dtau / np.where(ok0, tau0, 1.0)[:, None], 0.0)
    slope = np.where(ok0[:, None], pw.dtau, 0.0)
    code = np.repeat(pw.status0[:, None], n_edges, axis=1).astype(np.int8)
    flagged = np.zeros((count, n_edges), dtype=bool)
    if secants:
        flagged = ok0[:, None] & (np.abs(values) > spec.hybrid_cut)
        _secants(job, values, code, flagged, tau0, first, threads, slope)
    return values, code, flagged, pw, slope, np.broadcast_to(tau0[:, None], values.shape)


def _secants(job, values, code, flagged, tau0, first: int, threads: int | None, slope=None) -> None:
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
    targets = None if job.model is None else job.model.secant_targets[index]  # a law's are its own
    sec = _lanes(job).simulate(job, 0, 0, threads, job.secant_weights[index], first + rows, todo, targets)
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


@dataclass(frozen=True)
class LambdaPass:
    """An estimator of Lambda^KM (``lambda.method``) for one model kind.

    Attributes
    ----------
    model, method : str
        The model kind (:data:`MODEL_KINDS`) and the ``lambda.method``.
    values : callable
        ``values(job, sim, first, count, threads)`` -> ``(values, code, flagged, base, slope,
        tau0)``, see :func:`antisync.execution.compute.lambda_values`.
    integrates : bool
        Integrates trajectories of its own on the CPU lanes (tangents, adjoint, secants, orbit
        rows): ``sim`` may be None where the job has no ``betas``, and on an accelerator this
        part stays on the CPU. False: the values come from the chunk's variants.
    sync_response : callable or None
        ``sync_response(job, sim)``: per (realization, edge) ``-1``/``0``/``+1``, the
        synchronized fraction's response that the estimator also records (else None).
    """

    model: str
    method: str
    values: Callable
    integrates: bool = True
    sync_response: Callable | None = None


def _derivative_values(derivative: Callable, secants: bool = False) -> Callable:
    """The ``values`` of a derivative estimator: :func:`_derivatives` of ``derivative``."""
    return functools.partial(_derivatives, derivative=derivative, secants=secants)


_FD = {"integrates": False, "sync_response": sync_flips}

#: (model kind, lambda.method) -> the pass computing its values, one row per estimator that
#: runs for the model kind (the forward tangents are written for the identical oscillators'
#: Euler step only: :data:`REFUSALS` says so for the models)
PASSES: dict[tuple[str, str], LambdaPass] = {
    (p.model, p.method): p
    for p in (
        LambdaPass("identical", "finite-difference", _forward_secants, **_FD),
        LambdaPass("identical", "central-difference", _orbit_differences),
        LambdaPass("identical", "orbit", _orbit_differences),
        LambdaPass("identical", "pathwise", _derivative_values(_tangent_pass)),
        LambdaPass("identical", "hybrid", _derivative_values(_tangent_pass, secants=True)),
        LambdaPass("identical", "adjoint", _derivative_values(_adjoint_pass)),
        LambdaPass("identical", "adjoint-hybrid", _derivative_values(_adjoint_pass, secants=True)),
        LambdaPass("model", "finite-difference", _forward_secants, **_FD),
        LambdaPass("model", "central-difference", _orbit_differences),
        LambdaPass("model", "orbit", _orbit_differences),
        LambdaPass("model", "adjoint", _derivative_values(_model_adjoint_pass)),
        LambdaPass("model", "adjoint-hybrid", _derivative_values(_model_adjoint_pass, secants=True)),
        LambdaPass("law", "finite-difference", _forward_secants, **_FD),
        LambdaPass("law", "central-difference", _orbit_differences),
        LambdaPass("law", "orbit", _orbit_differences),
        LambdaPass("law", "adjoint", _derivative_values(_law_adjoint_pass)),
        LambdaPass("law", "adjoint-hybrid", _derivative_values(_law_adjoint_pass, secants=True)),
    )
}


# -- the refusals -----------------------------------------------------------------------------

#: the backends a run resolves to (``auto`` is one of them, :mod:`antisync.kernels.backends`)
RESOLVED_BACKENDS = tuple(b for b in BACKENDS if b != "auto")


def _but(choices: tuple[str, ...], *values: str) -> tuple[str, ...]:
    """``choices`` other than ``values`` (so a new choice is refused until a row runs it)."""
    return tuple(c for c in choices if c not in values)


@dataclass(frozen=True)
class Refusal:
    """A check a run makes: the cells it refuses (every field's values; all of a field by
    default) and the one-line message, a template over :class:`Key`'s fields.

    ``by`` names who makes the check: ``config`` (:class:`~antisync.plan.config.Config` on
    load, with the message repeated here so the table can print it) or ``backend``
    (:func:`antisync.execution.compute.check_backend`, from here).
    """

    by: str
    message: str
    model: tuple[str, ...] = MODEL_KINDS
    method: tuple[str, ...] = LAMBDA_METHODS
    integrator: tuple[str, ...] = INTEGRATORS
    backend: tuple[str, ...] = RESOLVED_BACKENDS
    precision: tuple[str, ...] = PRECISIONS

    def refuses(self, key: Key) -> bool:
        """Whether the check refuses the cell ``key``."""
        return all(value in getattr(self, field) for field, value in key._asdict().items())

    def why(self, key: Key) -> str:
        """The message the run of cell ``key`` gets."""
        return self.message.format(**key._asdict())


_TANGENTS = ("pathwise", "hybrid")
_IMPLICIT = ("rodas4",)
_FLOAT64 = ("float64",)

#: the checks in the order a run meets them (the config's on load, then the backend's), so a
#: cell that several refuse gets the first one's message, as the run does
REFUSALS: tuple[Refusal, ...] = (
    Refusal(
        "config",
        "lambda.method {method} needs dynamics.integrator euler (the tangent is written for the "
        "Euler step); use adjoint, finite-difference or orbit with rk4",
        method=_TANGENTS,
        integrator=_but(INTEGRATORS, "euler"),
    ),
    Refusal(
        "config",
        "lambda.method {method}: its forward tangents are written for the Euler step of identical "
        "first-order oscillators; with this model/sync section use adjoint or adjoint-hybrid (the "
        "same derivative, every link in one backward pass), central-difference (the derivative "
        "d<F>/dbeta) or finite-difference (the paper's forward secant)",
        model=("model",),
        method=_TANGENTS,
    ),
    Refusal(
        "config",
        "lambda.method {method}: its forward tangents are written for the Euler step of identical "
        "first-order oscillators; with a law (model.law) use central-difference (the derivative "
        "d<F>/dbeta), finite-difference (the paper's forward secant) or orbit",
        model=("law",),
        method=_TANGENTS,
    ),
    Refusal(
        "backend",
        "a law (model.law) runs on the cpu backend only: its kernels are generated for the CPU (no "
        "CUDA twin yet); use --backend cpu",
        model=("law",),
        backend=_but(RESOLVED_BACKENDS, "cpu"),
    ),
    Refusal(
        "backend",
        "a law (model.law) runs in dynamics.precision float64 only",
        model=("law",),
        precision=_but(PRECISIONS, *_FLOAT64),
    ),
    # the model kernels run Euler or RK4 with either crossing on both backends, float64 only
    Refusal(
        "backend",
        "the model:/sync: sections (docs/models.md) run in dynamics.precision float64 only",
        model=("model",),
        precision=_but(PRECISIONS, *_FLOAT64),
    ),
    # the CPU lanes run float32 for the Euler step with Taylor rotations only
    Refusal(
        "backend",
        "dynamics.precision {precision} runs dynamics.integrator euler only (got {integrator}); "
        "use precision float64 or integrator euler",
        model=("identical",),
        backend=("cpu",),
        precision=_but(PRECISIONS, *_FLOAT64),
        integrator=_but(INTEGRATORS, "euler"),
    ),
    # the derivative passes are float64; their tau0 would not be the float32 run's
    Refusal(
        "backend",
        "dynamics.precision {precision} runs lambda.method finite-difference only (got {method}); "
        "use precision float64 or method finite-difference",
        model=("identical",),
        precision=_but(PRECISIONS, *_FLOAT64),
        method=_but(LAMBDA_METHODS, "finite-difference"),
    ),
    Refusal(
        "backend",
        "dynamics.integrator {integrator} runs on the cpu backend only; use --backend cpu or "
        "integrator euler",
        model=("identical",),
        backend=("cuda",),
        integrator=("rk4",),
    ),
    # the implicit step: for stiff models, forward only, on the CPU
    Refusal(
        "backend",
        "dynamics.integrator rodas4 integrates the model:/sync: sections (stiff networks such as "
        "power grids, docs/models.md); the identical oscillators with normalized coupling are not "
        "stiff (their Laplacian's eigenvalues are at most 2): use euler or rk4",
        model=("identical",),
        integrator=_IMPLICIT,
    ),
    Refusal(
        "backend",
        "lambda.method {method} differentiates the integrator's discrete steps backwards; rodas4's "
        "steps are chosen adaptively from the state (accepted or rejected by its error estimate), "
        "so tau is not a smooth function of the weights through them and no discrete adjoint is "
        "written: use finite-difference or central-difference with rodas4, or {method} with rk4",
        model=("model", "law"),
        method=("adjoint", "adjoint-hybrid"),
        integrator=_IMPLICIT,
    ),
    Refusal(
        "backend",
        "dynamics.integrator rodas4 runs on the cpu backend only: each trajectory factors a sparse "
        "matrix with its fill-in, which the CUDA kernels' fixed per-thread arrays do not hold; use "
        "--backend cpu",
        model=("model",),
        backend=("cuda",),
        integrator=_IMPLICIT,
    ),
)


# -- the table --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """A cell that runs: its driver and its Lambda pass."""

    key: Key
    driver: Driver
    lambda_pass: LambdaPass

    @property
    def reduce(self) -> Callable | None:
        """The driver's reduction of a whole chunk where it computes this method's Lambda."""
        return self.driver.reduce if self.driver.reduces == self.key.method else None

    @property
    def host_part(self) -> str | None:
        """What of the run stays on the CPU on an accelerator, or None."""
        if not (self.driver.device and self.lambda_pass.integrates):
            return None
        model = " of a model" if self.key.model == "model" else ""
        return f"lambda.method {self.key.method}{model} runs its Lambda pass on the CPU"


def _cell(key: Key) -> Row | str:
    """The row of ``key``, or the message of the first check that refuses it."""
    for refusal in REFUSALS:
        if refusal.refuses(key):
            return refusal.why(key)
    driver = DRIVERS.get((key.model, key.integrator, key.backend))
    lambda_pass = PASSES.get((key.model, key.method))
    if driver is None or lambda_pass is None:
        raise RuntimeError(f"{key} has no driver or Lambda pass and no refusal says why")
    return Row(key, driver, lambda_pass)


#: every cell: a :class:`Row` where it runs, else the one-line message that refuses it
TABLE: dict[Key, Row | str] = {
    key: _cell(key)
    for key in itertools.starmap(
        Key, itertools.product(MODEL_KINDS, LAMBDA_METHODS, INTEGRATORS, RESOLVED_BACKENDS, PRECISIONS)
    )
}


def lookup(config, backend: str) -> Row:
    """The row of ``config`` run on ``backend`` (``cpu`` or ``cuda``, ``auto`` resolved).

    Raises
    ------
    ConfigError
        The cell's one-line message where it does not run.
    """
    if backend not in RESOLVED_BACKENDS:
        raise ValueError(
            f"backend must be one of {', '.join(RESOLVED_BACKENDS)} (auto resolved): {backend!r}"
        )
    cell = TABLE[key_of(config, backend)]
    if isinstance(cell, str):
        raise ConfigError(cell)
    return cell


def lambda_pass(job) -> LambdaPass:
    """The Lambda pass of ``job``'s model kind and ``lambda.method`` (on any backend)."""
    return PASSES[model_kind(job.config), job.config.lambda_.method]
