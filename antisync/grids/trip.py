"""The engineer's N-1: a line trip from the operating point, with an optional fault before it,
and each line's critical clearing time (docs/power_grids.md).

The grid runs in its stable locked state ``theta*`` (:func:`antisync.physics.locked.locked_state`
of the intact grid; ``theta' = 0``: the injections' mean is removed, so the operating point is
stationary in the frame of the nominal frequency). A grid without a stable operating point is
refused. For the line ``a-b``:

1. **Fault** (``t_clear > 0``): at ``t = 0`` a bolted three-phase fault at bus ``a``, the
   line's first end, brings that bus's voltage to zero, so none of its lines carries power:
   ``K_aj = K_ja = 0`` for every ``j`` while it lasts (the classical fault-on model of
   transient stability: P. Kundur, *Power System Stability and Control*, McGraw-Hill 1994,
   Sec. 13.1; P. Sauer and M. Pai, *Power System Dynamics and Stability*, Prentice Hall 1998,
   Ch. 9). The bus's own injection ``P_a`` still acts on it.
2. **Trip** at ``t_clear`` (0: the line simply opens): the protection opens ``a-b`` and the
   fault is gone; the grid runs on without the line for ``t_max`` seconds **after the trip**. A
   contingency of an official table that opens one circuit of several in parallel
   (:func:`read_contingencies`) takes that circuit's ``share`` of the line's ``K``: the line
   stays at ``(1 - share) K``.

The swing equation is the one every antisync grid integrates, ``m_i theta_i'' + D_i theta_i' =
P_i + sum_j K_ij sin(theta_j - theta_i)`` (a bus with ``m_i = 0`` first order), integrated by
the model kernels (:mod:`antisync.kernels.trip`): their classical RK4 at a fixed step, or on a
stiff grid Rodas4 with adaptive steps (``integrator="rodas4"``, what ``antisync grid --trip``
uses for a config whose integrator is ``rodas4``), which follows the first swing with short
steps and the settled grid with long ones.

Per line (:class:`Trip`): whether the grid **settles** (the frequency criterion of ``sync:
{criterion: frequency}``, as ``antisync run`` and ``--removal`` judge it: every ``|theta_i' -
mean theta'|`` and, with inertia, every ``|g_i - mean g|``, ``g_i = (P_i + coupling_i) / D_i``,
below ``tolerance`` from some time on until ``t_max`` after the trip), that **time to settle**
(counted from the trip), the **maximum frequency deviation** ``max_t max_i |theta_i'|`` (from
the nominal frequency) and the **maximum line angle difference** ``max_t max_(ij) |theta_i -
theta_j|`` over the lines in service (the first swing), beside whether the post-trip grid has a
stable locked state (the static indicator). The **critical clearing time** is the longest fault
such that every shorter fault is survived, found by a scan (:func:`critical_clearing`) that is
sound where the verdicts switch more than once near the boundary.
"""

from __future__ import annotations

import hashlib
import math
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from antisync._version import __version__
from antisync.errors import ConfigError
from antisync.execution.dispatch import trip_simulator
from antisync.execution.executors.dask import TaskLostError, client_threads
from antisync.execution.executors.tasks import map_tasks
from antisync.grids.errors import GridError
from antisync.grids.lines import grid_bridges, lines_of, split_bridges
from antisync.grids.load import Grid
from antisync.grids.removal_file import read_document
from antisync.grids.removal_journal import TripJournal, key_changes
from antisync.grids.trip_check import check_trips, trip_check_line
from antisync.kernels.shared import per_node
from antisync.physics.coupling import to_csr
from antisync.physics.locked import locked_state
from antisync.plan.config import MIN_TOLERANCE
from antisync.plan.jobs import check_step
from antisync.plan.model import check_second_order_step
from antisync.store.provenance import git_revision, now
from antisync.types import RODAS4_ATOL, RODAS4_RTOL

FORMAT = "antisync-trip"
"""The ``format`` of a trip table's JSON (``antisync grid CONFIG --trip --out X.json``)."""

CLOCK = "t_max and settle_time count from the trip (the fault's end)"
"""What a trip table's times mean (its ``clock``; tables without it counted from the fault's start)."""

CRITERION = (
    "frequency locking: every |theta_i' - mean| and, with inertia, every |g_i - mean g| "
    "(g_i = (P_i + coupling_i) / D_i) below the tolerance"
)
"""The settling criterion of a trip table (its ``criterion``), ``sync: {criterion: frequency}``'s."""

LAW_CRITERION = (
    "frequency locking: every one of the law's frequency quantities within the tolerance of its mean; "
    "max_frequency is the largest |first quantity| and max_angle the largest difference of the law's phases"
)
"""A law's trip table's ``criterion`` (:attr:`antisync.laws.spec.Law.frequency`)."""

__all__ = [
    "CCT_TOL",
    "COLUMNS",
    "TRIPS_PER_TASK",
    "Trip",
    "check_explicit_step",
    "check_finished_trips",
    "critical_clearing",
    "format_trips",
    "integration_record",
    "network_record",
    "operating_point",
    "plan_trips",
    "provenance",
    "read_contingencies",
    "trip_lines",
    "trip_report",
]


@dataclass(frozen=True)
class Trip:
    """One line's contingency from the operating point."""

    line: tuple
    """``(a, b)`` in the grid's bus labels; the fault (if any) is at ``a``."""
    t_clear: float
    settles: bool
    settle_time: float
    """The time after the trip from which the frequency criterion holds until ``t_max`` after it
    (0 if it holds from the trip on; ``nan`` if it does not hold at the end)."""
    max_frequency: float
    """``max_t max_i |theta_i'|`` (rad/s from the nominal frequency)."""
    max_angle: float
    """``max_t`` of the largest ``|theta_i - theta_j|`` over the lines in service (rad)."""
    post_locked: bool
    """Whether the grid without the line has a stable locked state (static)."""
    share: float = 1.0
    """The share of the line's ``K`` that the trip takes (1: the whole line)."""
    label: str | None = None
    """The contingency's label in its table (:func:`read_contingencies`), or None."""

    def as_dict(self) -> dict:
        out = asdict(self)
        out["line"] = [str(v) for v in self.line]
        return out


def operating_point(grid: Grid) -> np.ndarray:
    """The intact grid's stable locked phases (a law's: its flat state, :func:`_law_operating_point`);
    one-line :class:`GridError` when it has none."""
    if grid.law is not None:
        return _law_operating_point(grid)
    state = locked_state(grid.omega, grid.p, grid.lag, grid.inertia, grid.damping)
    if state is None or not state.stable:
        why = (
            "no locked state"
            if state is None
            else f"an unstable one (largest real part {state.max_real:.3g})"
        )
        raise GridError(
            f"{grid.name}: the intact grid has {why}, so there is no operating point to trip a line "
            "from; lower the injections or raise the capacities (antisync grid CONFIG shows the static state)"
        )
    return state.phi.copy()


def _law_operating_point(grid: Grid, weights: np.ndarray | None = None) -> np.ndarray | None:
    """A law's operating point: the locked state its network reaches from the in-phase state
    (:func:`antisync.kernels.law_locked.locked_state`, a stable one: it attracts), the flat
    state of its kernels. ``weights``: other weights on the grid's CSR pattern (the law's edge
    parameters are in its order: a line out keeps its place, weight 0), whose locked state is
    returned, or None where there is none."""
    from antisync.kernels.law_locked import locked_state as law_locked_state

    setup, csr = grid.law, to_csr(grid.omega)
    w = csr.weights if weights is None else weights
    state = law_locked_state(
        setup.law, setup.values, setup.edges, csr.indptr, csr.indices, w, t_max=setup.lock_t_max
    )
    if weights is not None:
        return None if state is None else state.y
    if state is None:
        raise GridError(
            f"{grid.name}: law {setup.law.name} does not lock from its in-phase state within "
            f"{setup.lock_t_max:g} time units, so there is no operating point to trip a line from; lower "
            "the injections or raise the capacities"
        )
    return state.y.copy()


def _arrays(grid: Grid):
    """The grid's CSR coupling (:func:`antisync.physics.coupling.to_csr`), injections, inertia
    and damping per bus, as the kernels take them. A grid without inertia is the first-order
    model ``theta_i' = P_i / D_i + sum_j (K_ij / D_i) sin(...)``: its injections and each bus's
    row of ``K`` divided by its damping, which is then 1 (the model kernels' first order)."""
    n = len(grid.labels)
    csr = to_csr(grid.omega)
    p = np.asarray(grid.p, dtype=np.float64).copy()
    mass, damping = per_node(grid.inertia, n), per_node(grid.damping, n)
    if np.any(mass[damping <= 0] == 0) or np.any(damping < 0):
        raise GridError("every bus needs damping > 0 where it has no inertia, and damping >= 0")
    k = csr.weights.copy()
    if not np.any(mass > 0):
        k /= np.repeat(damping, np.diff(csr.indptr))
        p /= damping
        damping = np.ones(n)
    return csr.indptr, csr.indices, k, p, mass, damping


def check_explicit_step(config, grid: Grid) -> None:
    """Refuse, as ``antisync run`` does for the same config, a ``dynamics.dt`` at which the
    explicit step makes the operating point's neighbourhood unstable (the second-order model's
    check with inertia, else the first-order one): a one-line
    :class:`~antisync.errors.ConfigError` naming the largest stable ``dt``. A trip by Rodas4 has
    no such limit."""
    if grid.law is not None:  # checked on the law's own Jacobian, as antisync run checks it
        from antisync.kernels.law import check_step as check_law_step

        try:
            check_law_step(grid.law, config.seed, to_csr(grid.omega), config.dynamics)
        except ConfigError as exc:
            raise GridError(str(exc)) from None
        return
    n = len(grid.labels)
    mass, gamma = per_node(grid.inertia, n), per_node(grid.damping, n)
    if (mass > 0).any():
        csr = to_csr(grid.omega)
        check_second_order_step(config, csr.indptr, csr.indices, csr.weights, mass, gamma)
    else:
        check_step(grid.omega, config)


def _check(grid: Grid, t_clear, t_max: float, dt: float) -> None:
    if grid.coupling != "raw" or grid.lag != 0.0:
        raise GridError("a line trip integrates the swing equation: dynamics.coupling raw and no phase lag")
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(t_max) and t_max > dt):
        raise GridError(
            f"--t-max ({t_max:g}) must be a finite time above the step dt ({dt:g}), both positive"
        )
    if t_max / dt > MAX_STEPS:
        raise GridError(
            f"--t-max {t_max:g} s is {t_max / dt:.3g} steps of dynamics.dt = {dt:g}: at most "
            f"{MAX_STEPS:.0e} (a trip that has not settled by then is not told apart by a longer window)"
        )
    for t in np.atleast_1d(t_clear):
        if not (0 <= t < math.inf):
            raise GridError(f"--t-clear must be a finite fault duration >= 0 s, got {t:g}")
        if t / dt > MAX_STEPS:
            raise GridError(
                f"a fault of {t:g} s is {t / dt:.3g} steps of dynamics.dt = {dt:g}: at most {MAX_STEPS:.0e}"
            )


def _integrate(
    grid: Grid,
    lines,
    t_clear,
    shares,
    *,
    t_max,
    dt,
    tolerance,
    theta0,
    threads,
    integrator="rk4",
    rtol=RODAS4_RTOL,
    atol=RODAS4_ATOL,
):
    """Per line ``[settle_time, max_frequency, max_angle]`` (settle time from the trip, ``nan``:
    it does not settle within ``t_max`` after the trip) and the clearing times and shares as
    arrays; what :func:`trip_lines` reports and all :func:`critical_clearing` needs (no static
    post-trip state: it does not depend on the fault). The kernels are
    :func:`antisync.kernels.trip.trip_item`'s: ``rk4`` at the fixed step ``dt``, or ``rodas4``
    under ``rtol``, ``atol`` from the first step ``dt``."""
    _check(grid, t_clear, t_max, dt)
    if integrator == "rodas4" and not (MIN_TOLERANCE <= min(rtol, atol) and max(rtol, atol) < 1):
        raise GridError(
            f"rodas4's rtol and atol must be in [{MIN_TOLERANCE:g}, 1), got {rtol:g} and {atol:g}"
        )
    try:
        simulate = trip_simulator(integrator, law=grid.law is not None)
    except ConfigError as exc:
        raise GridError(str(exc)) from None
    if theta0 is None:
        theta0 = operating_point(grid)
    ta = np.array([a for a, _ in lines], dtype=np.int64)
    tb = np.array([b for _, b in lines], dtype=np.int64)
    clear = np.ascontiguousarray(np.broadcast_to(np.asarray(t_clear, dtype=np.float64), (len(lines),)))
    share = np.ones(len(lines)) if shares is None else np.asarray(shares, dtype=np.float64)
    if share.shape != (len(lines),) or not np.all((share > 0) & (share <= 1)):
        raise GridError("a trip's share of its line must be in (0, 1], one per line")
    keep = np.ascontiguousarray(1.0 - share)
    trips = (ta, tb, keep, clear)
    tols = (float(tolerance), float(rtol), float(atol))
    if grid.law is not None:  # the law's generated trip kernels
        from antisync.kernels.law import with_edges

        setup, csr = grid.law, to_csr(grid.omega)
        params = with_edges(setup.values, setup.law, setup.edges)
        network = (setup.law, theta0, params, csr.indptr, csr.indices, csr.weights)
        out = simulate(*network, trips, t_max, dt, tols, threads=threads)
    else:
        indptr, indices, k, p, mass, damping = _arrays(grid)
        grid_arrays = (p, indptr, indices, mass, damping)
        out = simulate(theta0, grid_arrays, k, trips, t_max, dt, tols, threads=threads)
    if out[:, 3].any():
        a, b = lines[int(np.flatnonzero(out[:, 3])[0])]
        count, first = int(out[:, 3].sum()), f"{grid.labels[a]}-{grid.labels[b]}"
        if integrator == "rodas4":
            raise GridError(
                f"rodas4: the step size collapsed on {count} trips (first: line {first}); loosen "
                "dynamics.rtol/atol towards 1e-4 or use integrator rk4"
            )
        raise GridError(
            f"rk4: dynamics.dt = {dt:g} is unstable on {count} trips (first: line {first}): the state "
            "overflowed; lower dynamics.dt or use integrator rodas4"
        )
    out[:, 0] = np.maximum(out[:, 0] - clear, 0.0)  # from the trip
    return out[:, :3], clear, share


def trip_lines(
    grid: Grid,
    lines: list[tuple[int, int]],
    *,
    t_clear: float | np.ndarray = 0.0,
    t_max: float = 20.0,
    dt: float = 0.0025,
    tolerance: float = 1e-3,
    theta0: np.ndarray | None = None,
    threads: int | None = None,
    shares: np.ndarray | None = None,
    labels: list[str] | None = None,
    integrator: str = "rk4",
    rtol: float = RODAS4_RTOL,
    atol: float = RODAS4_ATOL,
) -> list[Trip]:
    """Every line of ``lines`` (0-based ``(a, b)``; the fault at ``a``) tripped from the
    operating point after a fault of ``t_clear`` seconds (one value, or one per line).
    ``shares``: the part of each line's ``K`` the trip takes (default 1, the whole line; a
    contingency table's circuit of several in parallel takes less); ``labels`` name the trips.

    ``dt`` is the RK4 step (the step that holds the fault's end is split there), or with
    ``integrator="rodas4"`` the first step of Rodas4 under ``rtol`` and ``atol``
    (:func:`antisync.kernels.implicit.rodas4_trip`: the stiff grids' integrator); ``tolerance``
    the frequency band of settling (rad/s). Bridges are the caller's to refuse (the islands of a
    tripped bridge cannot share a frequency unless each is balanced). The post-trip grid's
    static state is found once per distinct (line, share).
    """
    settings = {"t_max": t_max, "dt": dt, "tolerance": tolerance, "theta0": theta0, "threads": threads}
    settings.update(integrator=integrator, rtol=rtol, atol=atol)
    clear = np.broadcast_to(np.asarray(t_clear, dtype=np.float64), (len(lines),))
    share = np.ones(len(lines)) if shares is None else np.asarray(shares, dtype=np.float64)
    rows = _trip_task(grid, lines, clear, share, None, settings)
    return _trips(grid, lines, clear, share, labels, rows)


#: The critical clearing time's resolution (s): the fine scan's step inside the first failing
#: interval of the coarse scan (:func:`critical_clearing`), unless a caller gives another.
CCT_TOL = 1e-3

#: The coarse scan's step (s) of the fault durations a critical clearing time is searched on.
CCT_SCAN = 0.01

#: Coarse scan points integrated per line at a time (a line stops at its first failure).
_SCAN_CHUNK = 8

#: The most faults of a CCT's coarse scan (``cct_max / cct_scan``) and of its fine scan of the
#: first failing interval (``cct_scan / cct_tol``).
MAX_SCAN = 1e5
MAX_FINE = 1000

#: The most steps of ``dt`` a trip's window after the trip may hold (``--t-max / dt``).
MAX_STEPS = 1e7

#: Trips per task: the unit of the progress bar, of the journal (``--out``'s ``.partial``
#: folder) and of a Dask task (fewer on a cluster: :data:`TASKS_PER_THREAD`).
TRIPS_PER_TASK = 16
#: On a Dask cluster a task holds fewer trips when that gives each worker thread about this
#: many tasks (four trips on two workers: four tasks of one, not one task of four that one
#: worker runs alone). Each trip's row is its own whatever shares its task (tested).
TASKS_PER_THREAD = 4

#: The columns of a task's rows (:func:`_trip_task`).
COLUMNS = ("settle_time", "max_frequency", "max_angle", "post_locked", "cct", "cct_again", "peak_error")

#: RK4 trips whose largest phase advance in one step (``dt max |theta_i'|``) exceeds this (rad) are
#: integrated again at ``dt / 2`` to estimate how well their frequency peak is resolved.
STEP_ANGLE = 0.1


def _post_locked(grid: Grid, a: int, b: int, share: float) -> bool:
    """Whether the grid with ``share`` of line ``a-b``'s ``K`` taken has a stable locked state
    (a law's: whether it locks from its in-phase state, :func:`_law_operating_point`)."""
    if grid.law is not None:
        csr = to_csr(grid.omega)
        rows = np.repeat(np.arange(csr.indptr.size - 1), np.diff(csr.indptr))
        line = ((rows == a) & (csr.indices == b)) | ((rows == b) & (csr.indices == a))
        return (
            _law_operating_point(grid, np.where(line, (1.0 - share) * csr.weights, csr.weights)) is not None
        )
    post = grid.omega.copy()
    post[a, b] *= 1.0 - share
    post[b, a] *= 1.0 - share
    state = locked_state(post, grid.p, grid.lag, grid.inertia, grid.damping)
    return bool(state is not None and state.stable)


def _trip_task(grid: Grid, lines, t_clear, shares, cct: dict | None, settings: dict) -> np.ndarray:
    """The rows (:data:`COLUMNS`) of consecutive trips: the kernel's integration, the post-trip
    static state (once per distinct line and share) and, with ``cct`` (``cct_max``,
    ``cct_tol``), the critical clearing times (``nan`` without). A pure function of its
    arguments: a task here or on a Dask worker."""
    out, _, share = _integrate(grid, lines, t_clear, shares, **settings)
    rows = np.full((len(lines), len(COLUMNS)), np.nan)
    rows[:, :3] = out
    rows[:, 6] = _peak_error(grid, lines, t_clear, share, out[:, 1], settings)
    post = {}
    for e, (a, b) in enumerate(lines):
        key = (a, b, float(share[e]))
        if key not in post:
            post[key] = _post_locked(grid, a, b, share[e])
        rows[e, 3] = post[key]
    if cct is not None:
        rows[:, 4], rows[:, 5] = critical_clearing(grid, lines, **cct, **settings, shares=share)
    return rows


def _peak_error(grid: Grid, lines, t_clear, share, peak, settings: dict) -> np.ndarray:
    """RK4's check of the fault's transients: each trip whose largest phase advance in one step
    ``dt max |theta_i'|`` exceeds :data:`STEP_ANGLE` is integrated again at ``dt / 2``, and the
    error of its frequency peak at ``dt`` estimated as ``16/15 |peak(dt) - peak(dt/2)|``
    (Richardson, order 4; on IEEE 39 line 16-17 after a 1 s fault: 2.8 rad/s estimated against
    2.9 measured, of 336.7). 0 where the step is short enough or the integrator is Rodas4
    (adaptive: its error control resolves the swing)."""
    error = np.zeros(len(lines))
    if settings.get("integrator", "rk4") != "rk4":
        return error
    dt = settings["dt"]
    coarse = np.flatnonzero(dt * peak > STEP_ANGLE)
    if coarse.size:
        clear = np.broadcast_to(np.asarray(t_clear, dtype=np.float64), (len(lines),))[coarse]
        fine = _integrate(
            grid, [lines[e] for e in coarse], clear, share[coarse], **{**settings, "dt": 0.5 * dt}
        )[0][:, 1]
        error[coarse] = 16.0 / 15.0 * np.abs(peak[coarse] - fine)
    return error


def _trips(grid: Grid, lines, clear, share, labels, rows) -> list[Trip]:
    """The :class:`Trip` of each row of :func:`_trip_task`."""
    return [
        Trip(
            line=(grid.labels[a], grid.labels[b]),
            t_clear=float(clear[e]),
            settles=bool(np.isfinite(rows[e, 0])),
            settle_time=float(rows[e, 0]),
            max_frequency=float(rows[e, 1]),
            max_angle=float(rows[e, 2]),
            post_locked=bool(rows[e, 3]),
            share=float(share[e]),
            label=None if labels is None else labels[e],
        )
        for e, (a, b) in enumerate(lines)
    ]


def _grid_digest(grid: Grid) -> str:
    """SHA-256 of what a trip integrates: the grid's couplings, injections, inertia and damping
    (a journal's task files are for this grid as built, not only for its config's name)."""
    h = hashlib.sha256()
    n = len(grid.labels)
    for name, value in (
        ("omega", grid.omega),
        ("p", grid.p),
        ("inertia", per_node(grid.inertia, n)),
        ("damping", per_node(grid.damping, n)),
    ):
        value = np.ascontiguousarray(value, dtype=np.float64)
        h.update(f"{name}{value.shape}".encode())
        h.update(value.tobytes())
    h.update(f"{grid.coupling} {grid.lag!r}".encode())
    if grid.law is not None:  # the law's text and its values per node and per link
        setup = grid.law
        h.update(setup.law.text.encode())
        for value in (setup.values, setup.edges):
            if value is not None:
                value = np.ascontiguousarray(value, dtype=np.float64)
                h.update(f"{value.shape}".encode())
                h.update(value.tobytes())
    return h.hexdigest()


def critical_clearing(
    grid: Grid,
    lines: list[tuple[int, int]],
    *,
    cct_max: float = 1.0,
    cct_tol: float = CCT_TOL,
    cct_scan: float = CCT_SCAN,
    t_max: float = 20.0,
    dt: float = 0.0025,
    tolerance: float = 1e-3,
    threads: int | None = None,
    theta0: np.ndarray | None = None,
    shares: np.ndarray | None = None,
    integrator: str = "rk4",
    rtol: float = RODAS4_RTOL,
    atol: float = RODAS4_ATOL,
) -> tuple[np.ndarray, np.ndarray]:
    """Each line's critical clearing time: the longest fault at its first bus such that every
    shorter fault is survived (the grid settles within ``t_max`` after the trip), on a scan:

    1. the **coarse scan**, the faults ``k cct_scan`` (``k = 1, 2, ...``, and ``cct_max``) in
       increasing order, until the first one the grid does not survive;
    2. the **fine scan** of that failing interval ``(lo, hi)``, the faults ``lo + i cct_tol``
       below ``hi``; the CCT is the last fault survived before the first one that is not.

    A verdict that switches more than once near the boundary (settles, does not, settles again)
    cannot move the result: it is the first failure, and the scan points do not depend on
    ``cct_max``. What it guarantees: every scanned fault up to the CCT was survived, at
    ``cct_scan`` spacing and at ``cct_tol`` in the last interval; a window of failure narrower
    than ``cct_scan`` between two survived scan points is not seen.

    Returns ``(cct, again)`` per line: ``cct`` 0 where even an instant trip does not settle,
    ``cct_max`` where every scanned fault up to it is survived (no CCT up to ``cct_max``);
    ``again`` the shortest scanned fault longer than the CCT that the grid survives again (the
    verdicts switch back: a second window), ``nan`` where no scanned one does (only the points
    integrated are known: the fine scan's and the coarse chunk's holding the first failure).
    Every line's scan advances together: one parallel batch of every active line's next
    :data:`_SCAN_CHUNK` points. ``theta0``: the operating point when the caller has it;
    ``integrator``, ``rtol``, ``atol`` as in :func:`trip_lines`."""
    if not (
        0 < cct_tol <= cct_scan and 0 < cct_max and all(map(math.isfinite, (cct_tol, cct_scan, cct_max)))
    ):
        raise GridError(
            f"need 0 < cct_tol ({cct_tol:g}) <= cct_scan ({cct_scan:g}) and a finite "
            f"cct_max > 0 ({cct_max:g})"
        )
    if cct_scan > MAX_FINE * cct_tol or cct_max > MAX_SCAN * cct_scan:
        raise GridError(
            f"the CCT scan would hold {cct_max / cct_scan:.3g} faults of {cct_scan:g} s and "
            f"{cct_scan / cct_tol:.3g} of {cct_tol:g} s in its last interval (at most {MAX_SCAN:.0e} and "
            f"{MAX_FINE:g}): choose --cct-scan in [{cct_max / MAX_SCAN:.3g}, {MAX_FINE * cct_tol:g}] s "
            "or a shorter --cct-max"
        )
    _check(grid, cct_max, t_max, dt)
    if theta0 is None:
        theta0 = operating_point(grid)
    kw = {"t_max": t_max, "dt": dt, "tolerance": tolerance, "theta0": theta0, "threads": threads}
    kw.update(integrator=integrator, rtol=rtol, atol=atol)
    share = np.ones(len(lines)) if shares is None else np.asarray(shares, dtype=np.float64)

    def survives(items):
        """The verdicts of ``(line index, fault duration)`` items, in one batch."""
        if not items:
            return np.zeros(0, dtype=bool)
        picked = [lines[e] for e, _ in items]
        clear = np.array([t for _, t in items])
        rows = _integrate(grid, picked, clear, share[[e for e, _ in items]], **kw)[0]
        return np.isfinite(rows[:, 0])

    n = len(lines)
    ok0 = survives([(e, 0.0) for e in range(n)])
    coarse = cct_scan * np.arange(1, int(math.floor(cct_max / cct_scan + 1e-9)) + 1)
    if coarse.size == 0 or coarse[-1] < cct_max * (1 - 1e-12):
        coarse = np.append(coarse, cct_max)
    cct = np.where(ok0, cct_max, 0.0)
    again = np.full(n, np.nan)
    first_fail = np.full(n, -1)  # the coarse index of each line's first failure
    done = np.zeros(n, dtype=int)  # coarse points integrated per line
    active = list(np.flatnonzero(ok0))
    while active:
        items = [(e, float(t)) for e in active for t in coarse[done[e] : done[e] + _SCAN_CHUNK]]
        verdicts = iter(survives(items))
        still = []
        for e in active:
            chunk = coarse[done[e] : done[e] + _SCAN_CHUNK]
            ok = np.array([next(verdicts) for _ in chunk], dtype=bool)
            if ok.all():
                done[e] += chunk.size
                if done[e] < coarse.size:
                    still.append(e)
                continue
            j = int(np.argmin(ok))
            first_fail[e] = done[e] + j
            later = np.flatnonzero(ok[j + 1 :])
            if later.size:
                again[e] = chunk[j + 1 + later[0]]
        active = still
    # the fine scan of each failing interval
    failing = np.flatnonzero(first_fail >= 0)
    fine = {}
    for e in failing:
        lo = 0.0 if first_fail[e] == 0 else coarse[first_fail[e] - 1]
        hi = coarse[first_fail[e]]
        count = int(math.ceil((hi - lo) / cct_tol - 1e-9)) - 1
        fine[e] = (lo, lo + cct_tol * np.arange(1, max(count, 0) + 1), hi)
    verdicts = iter(survives([(e, float(t)) for e in failing for t in fine[e][1]]))
    for e in failing:
        lo, points, hi = fine[e]
        ok = np.array([next(verdicts) for _ in points], dtype=bool)
        j = int(np.argmin(ok)) if not ok.all() else points.size
        cct[e] = lo if j == 0 else points[j - 1]
        later = np.flatnonzero(ok[j + 1 :]) if j < points.size else np.zeros(0, dtype=int)
        if later.size:
            again[e] = points[j + 1 + later[0]]
    return cct, again


def read_contingencies(path, grid: Grid) -> list[tuple[str, tuple[int, int], float]]:
    """A grid's contingency table (``<prefix>_contingencies.txt``, written by
    tools/grid_case.py from an official N-1 table): one row per contingency, ``label from to
    share`` (``#`` starts a comment), the line by the grid's bus labels and the share of its
    ``K`` the outage takes, in ``(0, 1]``. Returns ``(label, (a, b), share)`` with 0-based ``a <
    b``; a file that cannot be read, a malformed row or a line not in the grid is a one-line
    :class:`GridError` naming the row."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise GridError(f"--contingencies {path}: cannot read it ({exc.__class__.__name__})") from None
    labels = grid.labels
    index = {str(lab): k for k, lab in enumerate(labels)}
    out, seen = [], set()
    for number, row in enumerate(text.splitlines(), start=1):
        fields = row.split("#", 1)[0].split()
        if not fields:
            continue
        where = f"--contingencies {path}, line {number}"
        if len(fields) != 4:
            raise GridError(f"{where}: expected 'label from to share', got {row.strip()!r}")
        label, u, v, share = fields
        try:
            share = float(share)
        except ValueError:
            share = math.nan
        if not 0 < share <= 1:
            raise GridError(f"{where}: the share must be a number in (0, 1], got {fields[3]!r}")
        a, b = sorted((index.get(u, -1), index.get(v, -1)))
        if a < 0 or a == b or not grid.omega[a, b] > 0:
            raise GridError(f"{where}: {u}-{v} is not a line of the grid (buses {labels[0]}..{labels[-1]})")
        if label in seen:
            raise GridError(f"{where}: the label {label!r} is used twice")
        seen.add(label)
        out.append((label, (a, b), share))
    if not out:
        raise GridError(f"--contingencies {path} lists no contingency")
    return out


def plan_trips(grid: Grid, lines=None, contingencies=None):
    """The trips :func:`trip_report` runs: ``(lines, labels, shares, skipped)`` with 0-based
    line pairs, the contingency labels (None without a table), each trip's share of its line
    and the bridges skipped (label pairs). Refuses a line not in the grid, a bridge named in
    ``lines`` and a table none of whose rows is on ``lines``."""
    bridges = grid_bridges(grid.omega)
    if contingencies is None:
        todo = lines_of(grid.omega, grid.labels, lines)
        hint = "leave it out of --lines (without --lines every bridge is skipped)"
        todo, skipped = split_bridges(
            grid.omega, grid.labels, todo, bridges, refuse=lines is not None, hint=hint
        )
        names, shares = None, np.ones(len(todo))
    else:
        rows = contingencies
        if lines is not None:
            wanted = set(lines_of(grid.omega, grid.labels, lines))
            rows = [row for row in rows if row[1] in wanted]
            if not rows:
                raise GridError("no contingency of the table is on a line of --lines")
        whole_bridge = [row for row in rows if row[1] in bridges and row[2] == 1.0]
        skipped = [(grid.labels[a], grid.labels[b]) for _, (a, b), _ in whole_bridge]
        rows = [row for row in rows if row not in whole_bridge]
        if not rows:
            names = ", ".join(
                f"{label} ({u}-{v})" for (label, _, _), (u, v) in zip(whole_bridge, skipped, strict=True)
            )
            raise GridError(
                f"every contingency asked for opens a bridge whole ({names}): the islands could not share "
                "a frequency, so there is no trip to integrate"
            )
        names = [label for label, _, _ in rows]
        todo = [line for _, line, _ in rows]
        shares = np.array([share for _, _, share in rows])
    return todo, names, shares, skipped


def integration_record(integrator: str, rtol: float, atol: float) -> dict:
    """The integrator of a trip table as its file and journal record it (``rtol``, ``atol``:
    None for RK4, whose step is ``dt``)."""
    rodas4 = integrator == "rodas4"
    return {"integrator": integrator, "rtol": rtol if rodas4 else None, "atol": atol if rodas4 else None}


def check_finished_trips(path, grid: Grid, plan, settings: dict) -> None:
    """Refuse (one line naming what differs) a ``--resume`` whose finished trip table ``path``
    holds other work than ``plan`` (:func:`plan_trips`) with ``settings`` (the report's
    ``t_clear``, ``t_max``, ``dt``, ``tolerance``, ``integrator``, ``rtol``, ``atol``, ``cct_max``,
    ``cct_tol``)."""
    try:
        doc = read_document(path, "trip table")
    except GridError as exc:
        raise GridError(f"--resume: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("lines"), list):
        raise GridError(f"--resume: {path} is not a trip table (format {FORMAT!r})")
    todo, names, shares, _ = plan
    asked = [
        [None if names is None else names[e], [str(grid.labels[a]), str(grid.labels[b])], float(shares[e])]
        for e, (a, b) in enumerate(todo)
    ]
    rows = [r if isinstance(r, dict) else {} for r in doc["lines"]]
    stored = [[r.get("label"), r.get("line"), r.get("share")] for r in rows]
    theirs = {k: doc.get(k) for k in ("grid", *settings)}
    changes = key_changes(theirs, {"grid": grid.name, **settings})
    changes = [] if changes == "no key differs" else [changes]
    if doc.get("work") != _grid_digest(grid):
        changes.append("the grid's data (its couplings, injections, inertia or damping as built)")
    if stored != asked:
        changes.append(f"trips: {len(stored)} in the table, {len(asked)} asked, not the same")
    if changes:
        raise GridError(
            f"--resume: {path} is the finished table of another trip run ({'; '.join(changes)}): give "
            "the arguments it was run with, --overwrite to replace it, or another --out (it is left as it is)"
        )


def trip_report(
    grid: Grid,
    lines=None,
    *,
    contingencies: list[tuple[str, tuple[int, int], float]] | None = None,
    t_clear: float | None = None,
    cct: bool = False,
    cct_max: float = 1.0,
    cct_tol: float = CCT_TOL,
    cct_scan: float = CCT_SCAN,
    t_max: float = 20.0,
    dt: float = 0.0025,
    tolerance: float = 1e-3,
    integrator: str = "rk4",
    rtol: float = RODAS4_RTOL,
    atol: float = RODAS4_ATOL,
    threads: int | None = None,
    client=None,
    journal: str | Path | None = None,
    progress: bool | None = False,
) -> dict:
    """What ``antisync grid CONFIG --trip`` prints and writes: every line of ``lines`` (label
    pairs, as :func:`antisync.grids.lines.parse_lines` gives them; ``None``: every line that is
    not a bridge) tripped from the operating point, after a fault of ``t_clear`` seconds at its
    first bus in node order (``None``: no fault), with its critical clearing time if ``cct``,
    each integrated by ``integrator`` (:func:`trip_lines`).
    With ``contingencies`` (:func:`read_contingencies`) the trips are the table's rows instead,
    ``lines`` (if given) keeping those on the lines it names; a row that opens a bridge whole
    is skipped and listed.

    The trips run in tasks of :data:`TRIPS_PER_TASK` (fewer on a cluster,
    :data:`TASKS_PER_THREAD`; :func:`_trip_task`, each with its own critical clearing scan):
    here on ``threads`` kernel threads, or on the Dask cluster of ``client`` (an open
    ``distributed.Client``; one kernel thread per task unless ``threads`` says otherwise) through
    :func:`antisync.execution.executors.tasks.map_tasks`, with the same
    rows either way. ``journal`` (a folder: :class:`~antisync.grids.removal_journal.TripJournal`)
    keeps every finished task at once, and a call with the same arguments and journal reads
    them back and runs only the rest. ``progress``: a bar of the trips done and the time left
    on stderr (None: when stderr is a terminal). The table's first trips are then integrated
    again at a finer setting (:mod:`antisync.grids.trip_check`): the report's
    ``accuracy_check``.

    Every refusal comes before any integration: a line not in the grid, a bridge named in
    ``lines``, a clearing time that is not in ``(0, t_max)``, a grid without a stable
    operating point, a journal of other work."""
    if t_clear is not None and not 0 < t_clear < math.inf:
        raise GridError(f"--t-clear must be a finite fault duration > 0 seconds, got {t_clear:g}")
    todo, names, shares, skipped = plan_trips(grid, lines, contingencies)
    clear = 0.0 if t_clear is None else t_clear
    _check(grid, clear, t_max, dt)
    theta0 = operating_point(grid)
    # on Dask one kernel thread per task: the cluster already runs a task per worker thread
    settings = {"t_max": t_max, "dt": dt, "tolerance": tolerance, "theta0": theta0}
    settings.update(integrator=integrator, rtol=rtol, atol=atol)
    settings["threads"] = threads if client is None else threads or 1
    spec = {"cct_max": cct_max, "cct_tol": cct_tol, "cct_scan": cct_scan} if cct else None
    values = np.full((len(todo), len(COLUMNS)), np.nan)
    book = None
    if journal is not None:
        key = {
            "grid": grid.name,
            "trips": [
                [name, str(grid.labels[a]), str(grid.labels[b]), float(sh)]
                for name, (a, b), sh in zip(names or [None] * len(todo), todo, shares, strict=True)
            ],
            "t_clear": t_clear,
            "clock": CLOCK,
            "cct": spec,
            "t_max": t_max,
            "dt": dt,
            "tolerance": tolerance,
            **integration_record(integrator, rtol, atol),
        }
        book = TripJournal(journal, key, work=_grid_digest(grid))
    have = np.zeros(len(todo), dtype=bool) if book is None else book.load(values)
    per = TRIPS_PER_TASK if client is None else _trips_per_task(len(todo), client)
    tasks = [
        (lo, min(lo + per, len(todo)))
        for lo in range(0, len(todo), per)
        if not have[lo : min(lo + per, len(todo))].all()
    ]
    calls = ((grid, todo[lo:hi], clear, shares[lo:hi], spec, settings) for lo, hi in tasks)
    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(
        total=len(todo),
        initial=int(have.sum()),
        unit="trip",
        desc="trips",
        delay=1.0,
        disable=not show,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    try:
        for i, rows in map_tasks(_trip_task, calls, client=client):
            lo, hi = tasks[i]
            values[lo:hi] = rows
            if book is not None:
                book.save(lo, rows)
            bar.update(int((~have[lo:hi]).sum()))
            have[lo:hi] = True
    except TaskLostError as exc:
        lost = f"{type(exc.cause).__name__}: {exc.cause}"
        raise GridError(
            f"the Dask cluster lost a trip task ({lost}); with --out, the finished tasks are kept: "
            "run the same command with --resume"
        ) from None
    finally:
        bar.close()
    if show and len(todo):  # a few more trips, at a finer setting: minutes on a large grid
        print("trips: the first ones again at a finer setting (the table's accuracy check)", file=sys.stderr)
    check = check_trips(_integrate, grid, todo, clear, shares, values, settings, spec, client)
    trips = _trips(grid, todo, np.full(len(todo), float(clear)), shares, names, values)
    rows = [t.as_dict() for t in trips]
    for row, error in zip(rows, values[:, 6], strict=True):
        row["max_frequency_error"] = float(error)
    if cct:
        for row, value, again in zip(rows, values[:, 4], values[:, 5], strict=True):
            row["cct"] = float(value)
            row["cct_again"] = None if np.isnan(again) else float(again)
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "grid": grid.name,
        "fault": "none (the line opens)"
        if t_clear is None
        else "bolted three-phase fault at the line's first bus",
        "t_clear": t_clear,
        "t_max": t_max,
        "clock": CLOCK,
        "criterion": CRITERION if grid.law is None else LAW_CRITERION,
        **({} if grid.law is None else {"law": grid.law.law.name}),
        "dt": dt,
        "tolerance": tolerance,
        **integration_record(integrator, rtol, atol),
        "cct_max": cct_max if cct else None,
        "cct_tol": cct_tol if cct else None,
        "cct_scan": cct_scan if cct else None,
        "contingencies": contingencies is not None,
        "bridges_skipped": [list(map(str, b)) for b in skipped],
        "accuracy_check": check,
        "work": _grid_digest(grid),
        "lines": rows,
        "network": network_record(grid),
    }


def _trips_per_task(trips: int, client) -> int:
    """Trips per task on ``client``'s cluster: about :data:`TASKS_PER_THREAD` tasks per worker
    thread, at most :data:`TRIPS_PER_TASK` trips each."""
    threads = client_threads(client) or 1
    return max(1, min(TRIPS_PER_TASK, -(-trips // (TASKS_PER_THREAD * threads))))


#: The trip table's format version: 2 since its times count from the trip, its criterion has
#: the g_i condition and its CCT is the scan's (1: tables before, read as they are).
FORMAT_VERSION = 2


def provenance(command: str = "") -> dict:
    """What a trip table's file records of where it came from, as the other results do: the
    format version, antisync's version, the git revision, the command and the time."""
    return {
        "format_version": FORMAT_VERSION,
        "version": __version__,
        "git_revision": git_revision(),
        "command": command,
        "written": now(),
    }


def network_record(grid: Grid) -> dict:
    """What a trip table keeps of its grid for its figure (``antisync report``): the buses'
    labels, every line as ``[u, v, K]`` and each bus's inertia."""
    n = len(grid.labels)
    rows, cols = np.nonzero(np.triu(grid.omega > 0))
    return {
        "nodes": [str(v) for v in grid.labels],
        "links": [
            [str(grid.labels[i]), str(grid.labels[j]), float(grid.omega[i, j])]
            for i, j in zip(rows, cols, strict=True)
        ],
        "inertia": [float(m) for m in per_node(grid.inertia, n)],
    }


def format_trips(report: dict) -> str:
    """The trip table as Markdown, lines that do not settle first (with a contingency table,
    each row's label and the share of its line it opens). The time to settle counts from the
    trip; with critical clearing times, "again" is the shortest scanned fault above the CCT
    that the grid survives again (the verdicts switch back), and a note under the table counts
    those lines and says what the scan resolved."""
    cct = report["cct_max"] is not None
    table = report.get("contingencies", False)
    head = "| contingency | share " if table else ""
    head += (
        "| line | settles | time to settle after the trip (s) | max |freq| (rad/s) | max angle (rad) "
        "| post-trip locked |"
    )
    head += " CCT (s) | survives again at (s) |" if cct else ""
    out = [head, "|" + "---|" * (6 + 2 * cct + 2 * table)]
    for r in sorted(report["lines"], key=lambda r: (r["settles"], -r["max_frequency"])):
        row = f"| {r['label']} | {r['share']:.3g} " if table else ""
        row += (
            f"| {'-'.join(r['line'])} | {'yes' if r['settles'] else 'NO'} | {r['settle_time']:.3f} | "
            f"{r['max_frequency']:.4g} | {r['max_angle']:.3f} | {'yes' if r['post_locked'] else 'no'} |"
        )
        if cct:
            again = r.get("cct_again")
            row += f" {r['cct']:.4f} | {'-' if again is None else f'{again:.4f}'} |"
        out.append(row)
    coarse = [r for r in report["lines"] if r.get("max_frequency_error", 0.0) > 0.01 * r["max_frequency"]]
    if coarse:
        worst = max(coarse, key=lambda r: r["max_frequency_error"] / r["max_frequency"])
        out.append("")
        out.append(
            f"RK4 at dt = {report['dt']:g}: the frequency peak of {len(coarse)} trip(s) is resolved worse "
            f"than 1% (worst: line {'-'.join(worst['line'])}, {worst['max_frequency']:.4g} rad/s, "
            f"estimated error {worst['max_frequency_error']:.2g} by step doubling): use a smaller "
            "dynamics.dt or rodas4"
        )
    if "accuracy_check" in report:  # tables before the check lack it
        out.append("")
        out.append(trip_check_line(report["accuracy_check"], report.get("integrator", "rk4")) + ".")
    if cct:
        windows = sum(r.get("cct_again") is not None for r in report["lines"])
        top = sum(r["cct"] >= report["cct_max"] for r in report["lines"])
        out.append("")
        out.append(
            f"CCT: the longest fault with every shorter scanned fault survived (scan every "
            f"{report.get('cct_scan') or CCT_SCAN:g} s, then every {report['cct_tol']:g} s in the first "
            f"failing interval); {top} line(s) survive every fault up to --cct-max {report['cct_max']:g} s; "
            f"{windows} line(s) survive again a longer fault than their CCT (second window). "
            f"Settling within --t-max {report['t_max']:g} s after the trip."
        )
    return "\n".join(out)
