"""Synchronization screening: does a graph synchronize from random initial phases?

Eqs. (5)-(6) of the paper need ``tau0`` and ``tau(beta)`` to be finite, so the paper analyses
only graphs that "fully synchronize from random initial conditions" (Sec. 3.3: of the 112
connected graphs with six nodes, the 6-ring and the 5-ring with one or two more edges are left
out). Identical Kuramoto oscillators with ``W = S^-1 Omega`` follow a gradient flow
(``S_i dtheta_i/dt = -dV/dtheta_i`` with ``V = -1/2 sum_ij Omega_ij cos(theta_j - theta_i)``),
so every trajectory ends at an equilibrium. An unsynchronized realization is therefore one of

- **stuck**: it converged to a *stable* equilibrium with ``r < threshold`` (a twisted state):
  it will never synchronize, whatever ``t_max``;
- **saddle**: it is at rest near an *unstable* equilibrium: a slow transient that leaves;
- **slow**: still moving at ``t_max``.

:func:`screen_graph` integrates realizations of the undamaged network with the same Euler step
as the main kernels (same trajectory, same step counts), stops a realization when its phase
velocities have all fallen below ``v_tol`` while ``r < threshold``, and classifies the state it
stopped at from the eigenvalues of the Jacobian. Only *stuck* realizations say that a graph has
a stable non-synchronized state; rare slow transients near saddles do not exclude a graph.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numba
import numpy as np
from numba import njit, prange

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.kernels.core import RENORM_EVERY, make_kernels
from antisync.physics import coupling
from antisync.physics.phases import phase
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED

__all__ = ["STATIONARY", "ScreenResult", "classify_state", "jacobian", "screen_graph", "screen_realizations"]

_K = make_kernels(lambda f: njit(f, inline="never", cache=True))
_euler_step = _K.euler_step
_order2 = _K.order2
_renormalize = _K.renormalize

#: internal outcome of the screening kernel: at rest (all |dtheta/dt| < v_tol) with r < threshold
STATIONARY = 3


@njit(parallel=True, cache=True)
def _screen_batch(
    seed,
    first,
    indptr,
    indices,
    weights,
    dt,
    r2_target,
    max_steps,
    check_every,
    v_tol,
    status,
    steps,
    vmax,
    theta_end,
):
    m = status.shape[0]
    n = indptr.shape[0] - 1
    for r in prange(m):
        c = np.empty(n)
        s = np.empty(n)
        acc = np.zeros(n)
        for i in range(n):
            th = phase(seed, first + r, i)
            c[i] = np.cos(th)
            s[i] = np.sin(th)
        st = NOT_SYNCED
        k = max_steps
        if _order2(c, s) >= r2_target:
            st = ALREADY_SYNCED
            k = 0
        else:
            for step in range(1, max_steps + 1):
                r2 = _euler_step(c, s, acc, indptr, indices, weights, dt)
                if r2 >= r2_target:
                    st = SYNCED
                    k = step
                    break
                if step % RENORM_EVERY == 0:
                    _renormalize(c, s)
                if step % check_every == 0:
                    top = 0.0
                    for i in range(n):
                        top = max(top, abs(acc[i]))
                    if top < v_tol * dt:
                        st = STATIONARY
                        k = step
                        break
        top = 0.0
        for i in range(n):
            top = max(top, abs(acc[i]))
            theta_end[r, i] = math.atan2(s[i], c[i])
        status[r] = st
        steps[r] = k
        vmax[r] = top / dt


def jacobian(theta: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Jacobian of ``dtheta_i/dt = sum_j w_ij sin(theta_j - theta_i)`` (Eq. 2) at ``theta``."""
    diff = np.cos(theta[None, :] - theta[:, None])
    j = w * diff
    np.fill_diagonal(j, 0.0)
    j[np.diag_indices_from(j)] = -j.sum(axis=1)
    return j


def classify_state(theta: np.ndarray, w: np.ndarray, tol: float = 1e-7) -> str:
    """``"stable"``, ``"unstable"`` or ``"marginal"``: the equilibrium near ``theta``.

    The Jacobian always has the eigenvalue 0 (a common phase shift); the state is stable
    when every other eigenvalue has a negative real part below ``-tol`` (relative to the
    largest modulus), unstable when one is above ``+tol``.
    """
    ev = np.linalg.eigvals(jacobian(theta, w)).real
    scale = max(float(np.max(np.abs(ev))), 1e-300)
    if np.any(ev > tol * scale):
        return "unstable"
    if np.sum(np.abs(ev) <= tol * scale) > 1:
        return "marginal"
    return "stable"


@dataclass(frozen=True)
class ScreenResult:
    """Outcome of screening one graph (counts over ``realizations`` random starts).

    Attributes
    ----------
    n_synced, n_already : int
        Reached ``r >= threshold`` at ``t > 0`` / already at ``t = 0``.
    n_stuck : int
        Converged to a stable non-synchronized equilibrium (twisted state).
    n_saddle : int
        At rest near an unstable (or marginal) equilibrium when stopped: slow transients.
    n_slow : int
        Not synchronized and still moving at ``t_max``.
    tau_max : float
        The slowest synchronization time among the synchronized realizations.
    r_stuck : float
        Order parameter of the first stuck state (``nan`` if none).
    """

    graph: str
    realizations: int
    n_synced: int
    n_already: int
    n_stuck: int
    n_saddle: int
    n_slow: int
    tau_max: float
    tau_mean: float
    r_stuck: float
    excluded: bool
    reason: str
    seconds: float = 0.0

    @property
    def n_not_synced(self) -> int:
        return self.n_stuck + self.n_saddle + self.n_slow

    @property
    def fraction_not_synced(self) -> float:
        return self.n_not_synced / self.realizations

    @property
    def fraction_stuck(self) -> float:
        return self.n_stuck / self.realizations

    def to_dict(self) -> dict:
        d = asdict(self)
        d["fraction_not_synced"] = self.fraction_not_synced
        d["fraction_stuck"] = self.fraction_stuck
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}

    @classmethod
    def from_dict(cls, d: dict) -> ScreenResult:
        fields = set(cls.__dataclass_fields__)
        return cls(
            **{
                k: (math.nan if v is None and k in ("tau_max", "tau_mean", "r_stuck") else v)
                for k, v in d.items()
                if k in fields
            }
        )


def screen_realizations(
    omega: np.ndarray,
    *,
    seed: int = 1,
    realizations: int = 200,
    t_max: float = 200.0,
    dt: float = 0.001,
    threshold: float = 0.99,
    coupling_kind: str = "normalized",
    v_tol: float = 1e-6,
    check_every: int = 250,
    threads: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-realization outcome of the screening integration (see :func:`screen_graph`).

    Returns
    -------
    status : int8 (m,)
        :class:`~antisync.status.Status` code, or :data:`STATIONARY` (at rest, ``r < threshold``).
    steps : int64 (m,)
        Steps taken; for SYNCED realizations exactly the kernels' ``steps0``.
    vmax : float (m,)
        Largest ``|dtheta_i/dt|`` at the end.
    theta : float (m, N)
        Final phases.
    """
    csr = coupling.coupling_csr(omega, coupling_kind)
    n = csr.n_nodes
    max_steps = int(math.ceil(t_max / dt - 1e-9))
    status = np.empty(realizations, dtype=np.int8)
    steps = np.empty(realizations, dtype=np.int64)
    vmax = np.empty(realizations)
    theta = np.empty((realizations, n))
    previous = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        _screen_batch(
            np.uint64(seed),
            np.uint64(0),
            csr.indptr,
            csr.indices,
            csr.weights,
            float(dt),
            (threshold * n) ** 2,
            max_steps,
            int(check_every),
            float(v_tol),
            status,
            steps,
            vmax,
            theta,
        )
    finally:
        numba.set_num_threads(previous)
    return status, steps, vmax, theta


def screen_graph(
    omega: np.ndarray,
    *,
    graph: str = "",
    seed: int = 1,
    realizations: int = 200,
    t_max: float = 200.0,
    dt: float = 0.001,
    threshold: float = 0.99,
    coupling_kind: str = "normalized",
    exclude_fraction: float = 0.0,
    v_tol: float = 1e-6,
    slow_v_tol: float = 1e-3,
    check_every: int = 250,
    threads: int | None = None,
) -> ScreenResult:
    """Screen the undamaged network ``omega`` for realizations that never synchronize.

    Parameters
    ----------
    omega : ndarray (N, N)
        Weights of the undamaged network.
    seed, realizations : int
        Realization ``k`` starts from :func:`antisync.physics.phases.phase` ``(seed, k, node)``,
        the same phases the main run uses, ``k = 0 .. realizations - 1``.
    t_max, dt, threshold
        Integration limit, Euler step and order-parameter threshold ``r``.
    exclude_fraction : float
        The graph is excluded when the fraction of *stuck* realizations exceeds this
        (default 0: any realization converging to a stable unsynchronized state excludes it).
    v_tol : float
        A realization whose phase velocities are all below ``v_tol`` is at rest.
    slow_v_tol : float
        A realization not at rest at ``t_max`` whose velocities are below ``slow_v_tol`` and
        that sits next to a stable equilibrium is stuck as well.

    Returns
    -------
    ScreenResult
    """
    start = time.perf_counter()
    w = coupling.coupling_matrix(omega, coupling_kind)
    status, steps, vmax, theta = screen_realizations(
        omega,
        seed=seed,
        realizations=realizations,
        t_max=t_max,
        dt=dt,
        threshold=threshold,
        coupling_kind=coupling_kind,
        v_tol=v_tol,
        check_every=check_every,
        threads=threads,
    )
    n_stuck = n_saddle = n_slow = 0
    r_stuck = math.nan
    for r in np.flatnonzero(status >= NOT_SYNCED):
        # still creeping at t_max counts as stuck too when it sits next to a stable
        # equilibrium: twisted states contract at rates down to ~0.09 on six nodes, so coming
        # to rest can take longer than t_max, and a gradient flow cannot leave that basin
        at_rest = status[r] == STATIONARY or vmax[r] < slow_v_tol
        kind = classify_state(theta[r], w) if at_rest else "moving"
        if kind == "stable":
            n_stuck += 1
            if math.isnan(r_stuck):
                r_stuck = float(abs(np.exp(1j * theta[r]).mean()))
        elif status[r] == STATIONARY:
            n_saddle += 1
        else:
            n_slow += 1
    synced = status == SYNCED
    taus = steps[synced] * dt
    frac = n_stuck / realizations
    excluded = n_stuck > 0 and frac > exclude_fraction
    reason = ""
    if excluded:
        reason = (
            f"stable non-synchronized state (twisted, r = {r_stuck:.3f}) reached from "
            f"{n_stuck} of {realizations} random starts"
        )
    return ScreenResult(
        graph=graph,
        realizations=realizations,
        n_synced=int(synced.sum()),
        n_already=int((status == ALREADY_SYNCED).sum()),
        n_stuck=n_stuck,
        n_saddle=n_saddle,
        n_slow=n_slow,
        tau_max=float(taus.max()) if taus.size else math.nan,
        tau_mean=float(taus.mean()) if taus.size else math.nan,
        r_stuck=r_stuck,
        excluded=bool(excluded),
        reason=reason,
        seconds=time.perf_counter() - start,
    )
