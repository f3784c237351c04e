"""The choices antisync accepts, each declared once as a ``Literal`` type.

Config fields (:mod:`antisync.plan.config`) and CLI options (:mod:`antisync.cli`) are annotated with
these types; the tuples of valid values that the validators and ``click`` check against are
derived from them with :func:`typing.get_args`, so a new choice is added in one place.

Example
-------
>>> BACKENDS
('cpu', 'cuda', 'auto')
"""

from __future__ import annotations

from typing import Literal, NamedTuple, get_args

__all__ = [
    "BACKENDS",
    "COUPLINGS",
    "CROSSINGS",
    "EXECUTORS",
    "INTEGRATORS",
    "LAMBDA_ROWS",
    "RODAS4_ATOL",
    "RODAS4_RTOL",
    "LAMBDA_METHODS",
    "LINEAR_METHODS",
    "MEASURES",
    "PRECISIONS",
    "REMOVAL_BY",
    "STOP_RULES",
    "Backend",
    "Coupling",
    "Crossing",
    "Executor",
    "Integrator",
    "LambdaMethod",
    "LambdaRows",
    "LinearMethod",
    "Measure",
    "Precision",
    "RemovalBy",
    "StopRule",
]

Backend = Literal["cpu", "cuda", "auto"]
"""Where chunks are integrated; ``auto`` is CUDA when a GPU is usable (:mod:`antisync.kernels.backends`)."""
Executor = Literal["local", "dask"]
"""Who runs the chunks: this process or a Dask cluster."""
Integrator = Literal["euler", "rk4", "rodas4"]
"""The time step: explicit Euler or classical RK4 at ``dynamics.dt``, or Rodas4 (L-stable
Rosenbrock, adaptive steps under ``dynamics.rtol``/``atol``) for stiff models
(:mod:`antisync.kernels.implicit`)."""
Crossing = Literal["auto", "grid", "interpolated"]
"""How tau is read off the step grid (see :class:`antisync.plan.config.Dynamics`)."""
LambdaMethod = Literal[
    "finite-difference", "central-difference", "pathwise", "hybrid", "adjoint", "adjoint-hybrid", "orbit"
]
"""Estimator of Lambda^KM (see :class:`antisync.plan.config.LambdaSpec`)."""
Measure = Literal["km", "linear", "xi2", "rw", "km_nnc"]
"""km: Lambda^KM from the run (Eq. 6); linear, xi2, rw: the measures of Secs. 2.3 and 3.3
(Eqs. 14, 16, 25); km_nnc: the same run with raw coupling (Sec. 3.4, Eqs. 20-22)."""
LinearMethod = Literal["exact", "euler", "derivative"]
"""How Lambda^(linear) is computed (see :class:`antisync.plan.config.LinearSpec`)."""
Precision = Literal["float64", "float32"]
"""Arithmetic of the integrated state (float32 on backend cuda only)."""
StopRule = Literal["never", "signs-resolved"]
"""When a run may end before its ``realizations`` (see :class:`antisync.plan.config.Stop`)."""
Coupling = Literal["normalized", "raw"]
"""``W = S^-1 Omega`` (Eq. 1) or ``W = Omega`` (Eq. 20), see :mod:`antisync.physics.coupling`."""
RemovalBy = Literal["speedup", "psync"]
"""What colours a line in :func:`antisync.report.removal.removal_figure`: ``F_1 - 1`` (the mean
``tau0 / tau - 1`` without the line, > 0: faster) or ``d P_sync`` (> 0: more starts lock)."""

BACKENDS: tuple[Backend, ...] = get_args(Backend)
EXECUTORS: tuple[Executor, ...] = get_args(Executor)
INTEGRATORS: tuple[Integrator, ...] = get_args(Integrator)
#: rodas4's default tolerances, ``dynamics.rtol`` and ``dynamics.atol`` (docs/models.md gives
#: the measurements that chose them)
RODAS4_RTOL = 1e-6
RODAS4_ATOL = 1e-6
CROSSINGS: tuple[Crossing, ...] = get_args(Crossing)
STOP_RULES: tuple[StopRule, ...] = get_args(StopRule)
LAMBDA_METHODS: tuple[LambdaMethod, ...] = get_args(LambdaMethod)
MEASURES: tuple[Measure, ...] = get_args(Measure)
LINEAR_METHODS: tuple[LinearMethod, ...] = get_args(LinearMethod)
PRECISIONS: tuple[Precision, ...] = get_args(Precision)
COUPLINGS: tuple[Coupling, ...] = get_args(Coupling)
REMOVAL_BY: tuple[RemovalBy, ...] = get_args(RemovalBy)


class LambdaRows(NamedTuple):
    """What a ``lambda.method`` needs of a job besides the undamaged trajectories: the rows of
    damaged weights :func:`antisync.plan.jobs.make_job` builds for it and the passes it adds per
    realization. Each estimator declares its needs here, once (:data:`LAMBDA_ROWS`); the job
    builder reads the declaration instead of testing method names, and the dispatch table's
    :class:`~antisync.execution.dispatch.LambdaPass` of the method is what consumes the rows."""

    dbeta_variant: bool = False
    """A variant at ``beta = dbeta`` per edge (the paper's forward secant, Eq. 17)."""
    orbit: Literal["edge", "automorphism"] | None = None
    """Rows at ``+-dbeta`` per edge (``edge``: central differences) or per automorphism orbit."""
    secants: bool = False
    """Every edge at ``+-dbeta`` for the central secants that replace the flagged values."""
    passes: Literal["tangents", "backward"] | None = None
    """A derivative pass along the undamaged trajectories: forward tangents (one per link) or
    the adjoint's backward sweep (about four trajectories; the relative criterion adds its
    target's rows)."""


#: Every estimator's needs (:class:`LambdaRows`), by ``lambda.method``.
LAMBDA_ROWS: dict[LambdaMethod, LambdaRows] = {
    "finite-difference": LambdaRows(dbeta_variant=True),
    "central-difference": LambdaRows(orbit="edge"),
    "orbit": LambdaRows(orbit="automorphism"),
    "pathwise": LambdaRows(passes="tangents"),
    "hybrid": LambdaRows(passes="tangents", secants=True),
    "adjoint": LambdaRows(passes="backward"),
    "adjoint-hybrid": LambdaRows(passes="backward", secants=True),
}
