"""What the backends share: the drivers' argument groups, their results and the host-side checks.

The CPU drivers (:mod:`.cpu`, the lane driver of :mod:`.lanes`), the CUDA twins (:mod:`.cuda`)
and the adjoints (:mod:`.adjoint`, :mod:`.model_adjoint`) all import from here, never from one
another's private names (as stumpy's backends import only its ``core.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from numba.extending import overload

from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER, RENORM_EVERY, VEC

__all__ = [
    "NO_TANGENTS",
    "Graph",
    "Model",
    "Outputs",
    "PathwiseResult",
    "Run",
    "SimResult",
    "Tangents",
    "Threads",
    "batch_starts",
    "check_collapsed",
    "csr_mv2",
    "has_inertia",
    "model_batch",
    "model_inputs",
    "per_node",
    "realization_ids",
    "record",
    "record_item",
    "rotation_angle_bound",
    "row_sum_bound",
    "share_base",
    "share_rows",
    "todo_mask",
    "trip_weights",
    "unset_outputs",
]


class Graph(NamedTuple):
    """The drivers' network: ``W`` in CSR form and the CSR weights of every damage variant."""

    indptr: np.ndarray
    """int64 (N + 1,)"""
    indices: np.ndarray
    """int64 (nnz,)"""
    base_w: np.ndarray
    """float64 (nnz,): the undamaged ``W``."""
    var_w: np.ndarray
    """float64 (V, nnz): each damaged ``W(Omega*)``."""
    var_is_base: np.ndarray
    """bool (V,): variant ``v`` leaves ``W`` unchanged (its result is copied from tau0)."""
    todo: np.ndarray = np.ones((0, 0), dtype=np.bool_)
    """bool (m, V + 1): the lane driver integrates only the marked (realization, network)
    items, column 0 the undamaged network; shape (0, 0): every item."""


class Run(NamedTuple):
    """The constants of one batch."""

    seed: np.uint64
    dt: float
    r2_target: float
    """``(threshold N)^2``: ``R = |sum_j e^{i theta_j}|^2`` at the threshold."""
    max_steps: int
    taylor: bool
    """Every rotation angle is within the Taylor polynomials' range (lane driver)."""
    rk4: bool
    """RK4 with Hermite crossing instead of Euler (lane driver)."""
    lanes: int
    """Trajectories stepped together per thread (lane driver)."""
    renorm: int = RENORM_EVERY
    """Euler steps between projections of the state back to the unit circle."""
    block: int = 2 * VEC
    """Lanes the vector kernels step together (two machine vectors of the state's precision):
    the lane arrays are a multiple of it wide."""


class Outputs(NamedTuple):
    """Arrays the lane driver fills, one row per realization."""

    status0: np.ndarray
    """int8 (m,)"""
    steps0: np.ndarray
    """int64 (m,)"""
    frac0: np.ndarray
    """float64 (m,)"""
    status: np.ndarray
    """int8 (m, V)"""
    steps: np.ndarray
    """int64 (m, V)"""
    frac: np.ndarray
    """float64 (m, V)"""
    dtau: np.ndarray
    """float64 (m, E): d tau0 / d beta_e (E = 0 without tangents)."""


class Tangents(NamedTuple):
    """The damaged edges whose forward sensitivities ride along (all empty: none).

    Damage on edge ``e = a -> b`` changes row ``a`` of ``W`` as ``dw_aj/dbeta = rho[e] w_aj +
    mu[e] [j = b]``.
    """

    edge_a: np.ndarray
    """int64 (E,)"""
    edge_b: np.ndarray
    """int64 (E,)"""
    rho: np.ndarray
    """float64 (E,)"""
    mu: np.ndarray
    """float64 (E,)"""


NO_TANGENTS = Tangents(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))


class Model(NamedTuple):
    """A generalized model's constants for the lane driver
    (:class:`~antisync.kernels.model_steps.ModelParams` as arrays); the driver takes ``None`` for
    the identical first-order oscillators."""

    freqs: np.ndarray
    """float64 (1 or m, N): natural frequencies, one row for all realizations or one each."""
    cos_lag: float
    sin_lag: float
    mass: np.ndarray
    """float64 (N,): inertia m_i (0: a first-order node)."""
    gamma: np.ndarray
    """float64 (N,): damping."""
    criterion: int
    """CRIT_ORDER or CRIT_FREQUENCY."""
    targets: np.ndarray
    """float64 (V + 1,): the criterion's target of the undamaged network, then of each variant."""
    starts: np.ndarray
    """float64 (m, N): each realization's initial phases (``model.start``), or (0, N): the
    paper's, drawn in the kernel (:func:`start_phase`)."""


@dataclass(frozen=True)
class SimResult:
    """Per-realization outcome of a batch (integration steps; ``tau = steps * dt``).

    Attributes
    ----------
    status0, steps0 : arrays, shape (m,)
        :class:`~antisync.status.Status` code and steps of the undamaged network.
    status, steps : arrays, shape (m, V)
        The same for each damage variant ``v``.
    frac0, frac : arrays or None
        Where inside the crossing step the threshold is met, ``x`` in ``(0, 1]``, from a
        straight line through ``R = |sum_j e^{i theta_j}|^2`` at the two grid points: the
        interpolated crossing time is ``(steps - 1 + x) dt`` (None from the plain driver).
    """

    status0: np.ndarray
    steps0: np.ndarray
    status: np.ndarray
    steps: np.ndarray
    frac0: np.ndarray | None = None
    frac: np.ndarray | None = None


@dataclass(frozen=True)
class PathwiseResult:
    """Undamaged trajectories with their sensitivities.

    Attributes
    ----------
    status0, steps0, frac0 : arrays, shape (m,)
        As in :class:`SimResult`; the interpolated ``tau0 = (steps0 - 1 + frac0) dt``.
    dtau : array, shape (m, E)
        ``d tau0 / d beta_e`` at ``beta = 0`` for damage on edge ``e`` (0 unless SYNCED).
    """

    status0: np.ndarray
    steps0: np.ndarray
    frac0: np.ndarray
    dtau: np.ndarray


def rotation_angle_bound(dt: float, indptr, base_w, var_w) -> float:
    """The largest rotation angle an Euler step can take, ``dt max_i sum_j |w_ij|`` over the base
    weights and every variant's (the lane kernels need it within
    :data:`~antisync.kernels.core.TAYLOR_MAX_ANGLE`)."""
    return float(dt) * row_sum_bound(indptr, base_w, var_w)


def row_sum_bound(indptr, base_w, var_w) -> float:
    """Largest sum_j |w_ij| over rows of the base and every variant (bounds |omega_i|)."""
    rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
    best = 0.0
    for w in (base_w, *var_w):
        best = max(best, float(np.bincount(rows, np.abs(w), minlength=indptr.size - 1).max()))
    return best


def realization_ids(first: int, count: int, realizations) -> np.ndarray:
    """The realization indices of a batch (uint64): ``realizations`` as given, else ``first ..
    first+count-1``."""
    if realizations is not None:
        ks = np.asarray(realizations, dtype=np.uint64)
        if ks.ndim != 1:
            raise ValueError("realizations must be a 1-D array of realization indices")
        return ks
    if first < 0 or count < 0:
        raise ValueError("first and count must be non-negative")
    return np.arange(first, first + count, dtype=np.uint64)


class Threads:
    """Temporarily set numba's thread count (results never depend on it)."""

    def __init__(self, threads):
        self.threads = threads

    def __enter__(self):
        self.previous = numba.get_num_threads()
        if self.threads is not None:
            numba.set_num_threads(max(1, min(int(self.threads), numba.config.NUMBA_NUM_THREADS)))
        return 4 * numba.get_num_threads()

    def __exit__(self, *exc):
        numba.set_num_threads(self.previous)


def model_inputs(first, count, realizations, indptr, base_weights, variant_weights, params, integrator):
    """A model run's arguments checked and in the kernels' types, for the CPU and CUDA drivers:
    ``(ks, base_weights, var_w, var_is_base, freqs, targets, starts)`` (``starts`` ``(0, N)``:
    the kernels draw the paper's phases); ``ValueError`` names what is wrong (the integrator, the
    criterion code, the shapes of ``freqs``, ``targets`` and ``starts``)."""
    if integrator not in ("euler", "rk4", "rodas4"):
        raise ValueError(f"integrator must be 'euler', 'rk4' or 'rodas4', got {integrator!r}")
    if params.criterion not in (CRIT_ORDER, CRIT_FREQUENCY):
        raise ValueError(f"unknown criterion code {params.criterion}")
    ks = realization_ids(first, count, realizations)
    m = ks.size
    n = indptr.size - 1
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
    return ks, base, var_w, var_is_base, freqs, targets, batch_starts(params, m, n)


def batch_starts(params, m: int, n: int) -> np.ndarray:
    """``params.starts`` (a :class:`~.model_steps.ModelParams`') for a batch of ``m`` realizations
    of ``n`` nodes as the kernels take it: ``(m, n)``, or ``(0, n)`` for the paper's phases."""
    if params.starts is None:
        return np.zeros((0, n))
    starts = np.ascontiguousarray(params.starts, dtype=np.float64)
    if starts.shape != (m, n):
        raise ValueError(f"starts must have shape ({m}, {n}) or be None, got {starts.shape}")
    return starts


def per_node(value, n: int) -> np.ndarray:
    """Inertia or damping as the kernels' per-node array (a number is every node's): always a
    fresh, writable copy. (``np.broadcast_to`` of a per-node array is a read-only view, and numba
    compiles every kernel again for a read-only argument: a second lane driver, ~1 min.)"""
    return np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))


def model_batch(
    first, count, realizations, indptr, indices, base_weights, variant_weights, params, integrator, todo
):
    """A CPU model run's kernel arguments, checked: ``(ks, graph, model, out)`` with
    :func:`model_inputs`' checks, ``todo`` (bool ``(m, V + 1)`` or None: every item; given, a
    variant equal to the base is integrated rather than copied from a base that may not run)
    and the :class:`Outputs` at ``-1`` / NaN for the items not integrated."""
    ks, base_weights, var_w, var_is_base, freqs, targets, starts = model_inputs(
        first, count, realizations, indptr, base_weights, variant_weights, params, integrator
    )
    m = ks.size
    n_var = var_w.shape[0]
    n = indptr.size - 1
    todo = todo_mask(todo, m, n_var, var_is_base)
    graph = Graph(indptr.astype(np.int64), indices.astype(np.int64), base_weights, var_w, var_is_base, todo)
    model = Model(
        freqs,
        float(params.cos_lag),
        float(params.sin_lag),
        per_node(params.inertia, n),
        per_node(params.damping, n),
        int(params.criterion),
        targets,
        starts,
    )
    return ks, graph, model, unset_outputs(m, n_var)


def todo_mask(todo, m: int, n_var: int, var_is_base: np.ndarray) -> np.ndarray:
    """The kernels' ``todo``: ``(0, 0)`` for every item, else the bool ``(m, n_var + 1)`` mask
    checked; given, a variant equal to the base is integrated rather than copied from a base
    that may not run (``var_is_base`` cleared in place)."""
    if todo is None:
        return np.zeros((0, 0), dtype=np.bool_)
    todo = np.ascontiguousarray(todo, dtype=np.bool_)
    if todo.shape != (m, n_var + 1):
        raise ValueError(f"todo must have shape {(m, n_var + 1)}, got {todo.shape}")
    var_is_base[:] = False
    return todo


def unset_outputs(m: int, n_var: int) -> Outputs:
    """:class:`Outputs` of ``m`` realizations and ``n_var`` variants, every item at ``-1`` /
    NaN (not integrated) until a driver records it; no tangents."""
    return Outputs(
        np.full(m, -1, dtype=np.int8),
        np.full(m, -1, dtype=np.int64),
        np.full(m, np.nan),
        np.full((m, n_var), -1, dtype=np.int8),
        np.full((m, n_var), -1, dtype=np.int64),
        np.full((m, n_var), np.nan),
        np.empty((m, 0)),
    )


def check_collapsed(failed: np.ndarray, ks: np.ndarray, what: str = "") -> None:
    """Rodas4's step-size collapse, never a status: ``FloatingPointError`` naming how many
    trajectories of ``failed`` (``(m, 1 + V)``, column 0 the undamaged network) collapsed and the
    first (``what``: words after "trajectories", e.g. " of law kuramoto")."""
    if not failed.any():
        return
    r, v = np.argwhere(failed)[0]
    which = "the undamaged network" if v == 0 else f"variant {v - 1}"
    raise FloatingPointError(
        f"rodas4: the step size collapsed on {int(failed.sum())} trajectories{what} (first: "
        f"realization {int(ks[r])}, {which}); loosen dynamics.rtol/atol or use integrator rk4"
    )


@numba.njit(inline="always")
def record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x):
    """Store item ``(r, v)``'s status, steps and crossing fraction: the undamaged network's for
    ``v < 0``, else variant ``v``'s. (The arrays one by one: outputs passed in a tuple lose
    their writes inside a parallel loop.)"""
    if v < 0:
        status0[r] = st
        steps0[r] = k
        frac0[r] = x
    else:
        status[r, v] = st
        steps[r, v] = k
        frac[r, v] = x


# One specialization per kernel: a variable that starts as a constant and is refined in a loop
# (``second = False`` then ``second |= mass[i] > 0``; ``node = 0`` then ``node = i``) is typed
# ``Literal[bool](False)`` or ``Literal[int](0)`` in numba's first inference pass, and every
# jitted function it reaches is compiled for the literal and again for ``bool``/``int64``, which
# doubled the compile time of the largest kernels (bench/specializations.py lists the kernels
# compiled more than once). Such variables start from a call instead: :func:`has_inertia`,
# ``np.int64(0)``, ``np.bool_(False)``.
@numba.njit(cache=True)
def has_inertia(mass):
    """Whether any node has inertia (``mass[i] > 0``: a second-order model), typed ``bool``."""
    for i in range(mass.shape[0]):
        if mass[i] > 0.0:
            return True
    return False


# Called, not inlined, from a prange body: an array reached through a named tuple keeps its
# writes there only inside a called function (see antisync.kernels.lanes.Lanes).
@numba.njit(cache=True)
def record_item(out, r, v, st, k, x):
    """:func:`record` into ``out`` (an :class:`Outputs`), once per trajectory."""
    record(out.status0, out.steps0, out.frac0, out.status, out.steps, out.frac, r, v, st, k, x)


def share_rows(var_is_base: np.ndarray, out) -> None:
    """:func:`share_base` of every realization, from Python (after a loop of
    :mod:`antisync.kernels.loops`, whose items record only what they integrate)."""
    out.status[:, var_is_base] = out.status0[:, None]
    out.steps[:, var_is_base] = out.steps0[:, None]
    out.frac[:, var_is_base] = out.frac0[:, None]


@numba.njit(cache=True)
def doubled(ck):
    """A C-contiguous ``ck`` with twice its rows: the first half a copy, the rest unset (the
    checkpoint stores of the adjoints grow by it). An element loop: numba's broadcasting slice
    assignment (``bigger[:rows] = ck``) took about 3 s of a fresh compile at each rank."""
    bigger = np.empty((2 * ck.shape[0],) + ck.shape[1:], ck.dtype)
    copy_into(bigger[: ck.shape[0]], ck)
    return bigger


def copy_into(dst, src):
    """``dst[...] = src`` for two arrays of one shape, inside a kernel element by element: the
    same bits as the slice assignment, without compiling numba's broadcasting checks (see
    :func:`doubled`). Two C-contiguous arrays are copied as flat vectors, others index by index.
    Arrays of different shapes raise ValueError, as the slice assignment does (a message without
    their shapes: formatting them was the broadcasting check's cost), never a copy out of bounds."""
    if dst.shape != src.shape:
        raise ValueError("copy_into: the two arrays differ in shape")
    dst[...] = src


@overload(copy_into)
def _copy_into(dst, src):
    if dst.layout == "C" and src.layout == "C":

        def flat(dst, src):
            if dst.shape != src.shape:
                raise ValueError("copy_into: the two arrays differ in shape")
            a, b = dst.reshape(-1), src.reshape(-1)
            for j in range(b.size):
                a[j] = b[j]

        return flat

    def each(dst, src):
        if dst.shape != src.shape:
            raise ValueError("copy_into: the two arrays differ in shape")
        for idx in np.ndindex(src.shape):
            dst[idx] = src[idx]

    return each


@numba.njit(cache=True)
def share_base(var_is_base, r, out):
    """Realization ``r``'s variants that leave the weights unchanged get the undamaged result
    (in ``out``, an :class:`Outputs`)."""
    for v in range(var_is_base.shape[0]):
        if var_is_base[v]:
            out.status[r, v] = out.status0[r]
            out.steps[r, v] = out.steps0[r]
            out.frac[r, v] = out.frac0[r]


@numba.njit(inline="always")
def csr_mv2(indptr, indices, w, a, b, out_a, out_b):
    """``out_a = W a`` and ``out_b = W b`` for ``W`` in CSR (``w`` its values): the coupling
    sums ``sum_j w_ij a_j`` in row order, the same order wherever they are taken."""
    for i in range(indptr.shape[0] - 1):
        acc_a = 0.0
        acc_b = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            acc_a += w[p] * a[j]
            acc_b += w[p] * b[j]
        out_a[i] = acc_a
        out_b[i] = acc_b


@numba.njit(cache=True)
def trip_weights(k, indptr, indices, a, b, keep):
    """The fault's weights (bus ``a``'s lines at 0) and the post-trip weights (``a-b`` at
    ``keep`` of its ``K``) of one trip, on the CSR pattern of ``k``."""
    w_fault = k.copy()
    w_post = k.copy()
    for i in range(indptr.shape[0] - 1):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            if i == a or j == a:
                w_fault[q] = 0.0
            if (i == a and j == b) or (i == b and j == a):
                w_post[q] = keep * k[q]
    return w_fault, w_post
