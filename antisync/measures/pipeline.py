"""The response measures inside a run: what ``measures: [km, linear, xi2, rw, km_nnc]`` does.

- :func:`compute_measures`: ``Lambda^(xi2)``, ``Lambda^(RW)`` and ``Lambda^(linear)`` for every
  damaged edge of a :class:`~antisync.plan.jobs.Job`, once per job (the runner stores them with
  the job's statistics; checkpoints rewrite them, never recompute them).
- :func:`nnc_job` / :func:`with_nnc`: ``km_nnc`` runs the same experiment a second time with
  raw coupling (Sec. 3.4, Eqs. 20-22), same seed and so the same initial phases, as a second
  job ``<name>_nnc`` of the same file.
- The ``measures`` subgroup of a job in HDF5 is written and read by
  :mod:`antisync.store.layout` (``write_measures`` / ``read_measures``).
- :func:`measure_fields` / :func:`join_nnc`: the summary keys ``lambda_linear``,
  ``lambda_linear_se``, ``lambda_linear_n``, ``lambda_linear_n_excluded``, ``lambda_xi2``,
  ``lambda_rw``, ``lambda_km_nnc`` and ``lambda_km_nnc_se``. Every record carries all of
  them; a measure that was not computed is ``None`` (``null`` in JSON, empty in CSV), so
  tables of mixed files keep one set of columns.

Conventions: ``Lambda^(linear)`` uses realizations ``0 .. linear.realizations - 1`` of the
run's seed (the Kuramoto runs' own initial phases), the run's threshold, coupling, ``dbeta``
(``lambda.dbeta``), ``dt`` and ``t_max``. ``Lambda^(xi2)`` uses the run's coupling (for raw
coupling, the Laplacian of ``Omega``). ``Lambda^(RW)`` is always the normalized walk
``W(Omega)`` of the Appendix, whatever the Kuramoto coupling.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from antisync.errors import ConfigError, MeasureError
from antisync.measures.linear import lambda_linear, tau_linear_euler, tau_linear_exact
from antisync.measures.randomwalk import lambda_rw_all
from antisync.measures.spectral import lambda_xi2_all
from antisync.physics.phases import initial_phases
from antisync.plan.jobs import Job, make_job

__all__ = [
    "COMPUTED",
    "NNC_SUFFIX",
    "compute_measures",
    "nnc_job",
    "wants_measures",
    "with_nnc",
]

#: Measures computed by :func:`compute_measures` (``km`` and ``km_nnc`` are Kuramoto runs).
COMPUTED = ("linear", "xi2", "rw")
NNC_SUFFIX = "_nnc"


def wants_measures(job: Job) -> bool:
    """Whether ``job``'s config asks for any of ``linear``, ``xi2``, ``rw``."""
    return any(m in COMPUTED for m in job.config.measures)


def compute_measures(job: Job, config=None) -> dict[str, np.ndarray]:
    """The non-simulation measures of every damaged edge of ``job``.

    Parameters
    ----------
    job : Job
        A job from :func:`~antisync.plan.jobs.make_job`; ``job.edges`` fixes the order.
    config : Config, optional
        Which measures and how; default ``job.config``.

    Returns
    -------
    dict of str to ndarray, each of shape ``(len(job.edges),)``
        ``lambda_xi2`` (Eq. 16, exact) if ``xi2`` is requested; ``lambda_rw`` (Eq. 25, exact)
        if ``rw``; ``lambda_linear``, ``lambda_linear_se``, ``lambda_linear_n``,
        ``lambda_linear_n_excluded``, ``lambda_linear_n_already_synced`` (Eq. 14, see
        :class:`~antisync.measures.linear.LinearResult`) if ``linear``.

    Raises
    ------
    MeasureError
        One line naming the graph, the measure (and edge) and the reason, e.g. a
        disconnected graph.
    """
    cfg = config or job.config
    wanted = set(cfg.measures)
    index = {v: i for i, v in enumerate(job.nodes)}
    pairs = [(index[a], index[b]) for a, b in job.edges]
    dyn = cfg.dynamics
    omega = job.omega
    out: dict[str, np.ndarray] = {}

    if "xi2" in wanted:
        with _naming(job, "xi2"):
            out["lambda_xi2"] = np.asarray(lambda_xi2_all(omega, pairs, dyn.coupling), dtype=float)
    if "rw" in wanted:
        with _naming(job, "rw"):  # every link from one factorization
            out["lambda_rw"] = np.asarray(lambda_rw_all(omega, pairs), dtype=float)
    if "linear" in wanted:
        spec = cfg.linear
        theta0 = initial_phases(cfg.seed, 0, spec.realizations, len(job.nodes))
        with _naming(job, "linear"):
            # tau_0 is the same for every edge: compute it once, as lambda_linear would
            if spec.method == "euler":
                tau0 = tau_linear_euler(omega, theta0, dyn.threshold, dyn.coupling, dyn.dt, dyn.t_max)
            else:
                tau0 = tau_linear_exact(omega, theta0, dyn.threshold, dyn.coupling, dyn.t_max)
        results = []
        for (a, b), label in zip(pairs, job.edge_labels, strict=True):
            with _naming(job, "linear", label):
                results.append(
                    lambda_linear(
                        omega,
                        a,
                        b,
                        theta0,
                        dyn.threshold,
                        dyn.coupling,
                        job.dbeta,
                        spec.method,
                        dt=dyn.dt,
                        t_max=dyn.t_max,
                        tau0=tau0,
                    )
                )
        out["lambda_linear"] = np.array([r.lambda_ for r in results], dtype=float)
        out["lambda_linear_se"] = np.array([r.se for r in results], dtype=float)
        out["lambda_linear_n"] = np.array([r.n for r in results], dtype=np.int64)
        out["lambda_linear_n_excluded"] = np.array([r.n_excluded for r in results], dtype=np.int64)
        out["lambda_linear_n_already_synced"] = np.array(
            [r.n_already_synced for r in results], dtype=np.int64
        )
    return out


class _naming:
    """Turn a measure's ``ValueError`` into a one-line :class:`MeasureError` naming the case."""

    def __init__(self, job: Job, measure: str, edge: str | None = None):
        self.where = f"graph {job.name}: measure {measure}" + (f", edge {edge}" if edge else "")

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is not None and issubclass(kind, ValueError | np.linalg.LinAlgError):
            raise MeasureError(f"{self.where}: {str(exc).splitlines()[0]}") from exc
        return False


# --- KM-NNC: the raw-coupling twin of a run --------------------------------------------------


def nnc_job(job: Job) -> Job:
    """The raw-coupling twin of ``job`` (Eqs. 20-22): same graph, edges, betas, seed, dynamics.

    Its config keeps only ``km`` (the twin is a Kuramoto run, nothing else), its name is
    ``job.name + "_nnc"`` and ``nnc_of`` names ``job``.
    """
    cfg = job.config
    twin = replace(cfg, dynamics=replace(cfg.dynamics, coupling="raw"), measures=("km",))
    return replace(make_job(twin, graph=job.graph, name=job.name + NNC_SUFFIX), nnc_of=job.name)


def with_nnc(jobs: list[Job]) -> list[Job]:
    """``jobs``, each followed by its raw-coupling twin when its config lists ``km_nnc``."""
    names = {job.name for job in jobs}
    out = []
    for job in jobs:
        out.append(job)
        if "km_nnc" in job.config.measures and not job.nnc_of:
            twin_name = job.name + NNC_SUFFIX
            if twin_name in names:
                if any(j.nnc_of == job.name for j in jobs):
                    continue  # already expanded
                raise ConfigError(
                    f"km_nnc needs a job named {twin_name!r} for the raw-coupling run of "
                    f"{job.name!r}, but that name is already taken"
                )
            out.append(nnc_job(job))
            names.add(twin_name)
    return out
