"""An adaptive embedded Runge-Kutta pair against the package's fixed-step RK4 lanes (issue 17, item 3).

Run from the repository root::

    NUMBA_NUM_THREADS=2 python bench/bench_adaptive.py [--realizations M] [--threads 2]

What it measures, on the paper's lollipop (6 nodes, path 3), all 12 directed links, finite
difference ``dbeta = 0.01`` (``Lambda = (tau0 / tau(dbeta) - 1) / dbeta`` per realization), every
method on the same realizations ``0 .. M-1`` with the package's initial phases
``phase(seed, k, node)``:

- the package's finite difference with RK4 and the cubic Hermite crossing (the lane kernel that
  ``antisync run`` uses, timed through :func:`antisync.execution.compute.compute_chunk` as
  ``bench/bench_kernels.py`` does) at ``dt = 0.04`` (the baseline) and larger steps
  (``--rk4-dts``), for a comparison at equal accuracy;
- Dormand-Prince 5(4) (the pair of scipy's ``RK45`` and Hairer's ``DOPRI5``) with Hairer's PI
  step-size controller and the pair's own 4th-order dense output, one trajectory at a time per
  realization, realizations in parallel (``prange``), at several tolerances;
- a reference: the same adaptive solver at ``rtol = atol = 1e-12``, itself checked against
  scipy's ``solve_ivp(DOP853, rtol = atol = 1e-13)`` in the phases theta with a terminal event
  on a few realizations.

It prints, as markdown: per-realization agreement of tau0 and of the damaged tau with the
reference; Lambda per link with standard errors and the paired difference to the reference;
time to precision (as in ``bench_kernels.py``: ``seconds * (worst_se / 0.005)^2``, the package's
batch-means standard error for every method); steps and right-hand-side evaluations per
realization.

The adaptive solver integrates the same ``(c_i, s_i) = (cos theta_i, sin theta_i)`` form as the
package's kernels (``dc_i/dt = -s_i omega_i``, ``ds_i/dt = c_i omega_i``, ``omega_i = c_i sum_j
w_ij s_j - s_i sum_j w_ij c_j``): no transcendental function in the right-hand side, and
``R = r^2 N^2 = (sum c)^2 + (sum s)^2`` is a polynomial in the state. It does not project back
to the unit circle (the drift is part of the controlled local error).
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync.execution.compute import compute_chunk, lambda_values, simulate_job  # noqa: E402
from antisync.physics.phases import initial_phases, phase  # noqa: E402
from antisync.plan.config import load_config_text  # noqa: E402
from antisync.plan.jobs import Chunk, make_job  # noqa: E402
from antisync.stats import estimators  # noqa: E402
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED  # noqa: E402

TARGET_SE = 0.005
DBETA = 0.01
RK4_DT = 0.04
REF_TOL = 1e-12
SCIPY_TOL = 1e-13

# --- Dormand-Prince 5(4) ------------------------------------------------------------------
# Tableau, error weights and dense-output matrix as in scipy.integrate RK45 (Dormand & Prince
# 1980; Hairer, Norsett & Wanner, Solving ODEs I, II.5; the dense output with Shampine's
# optimal c_6). Module-level floats are frozen into the compiled code as constants.
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84  # B2 = B7 = 0 (FSAL)
# error estimate h sum_k E_k K_k (the 7th stage is the derivative at the new state)
E1, E3, E4, E5, E6, E7 = -71 / 57600, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40
# dense output: y(t + x h) = y + h sum_m (sum_k K_k P[k, m]) x^(m + 1), m = 0..3
P = np.array(
    [
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)
# Hairer's DOPRI5 controller: h_new = h / fac with fac = err^0.17 / err_prev^0.04 / 0.9,
# clamped so that 0.2 h <= h_new <= 10 h (PI control, Gustafsson's stabilization, beta 0.04)
PI_BETA = 0.04
PI_EXPO = 0.2 - 0.75 * PI_BETA
SAFE = 0.9
FAC_MIN = 0.2
FAC_MAX = 10.0


@njit(fastmath=True, inline="always")
def _rhs(c, s, indptr, indices, w, dc, ds):
    """``(dc, ds) = (-s omega, c omega)``: Eq. 2 in (cos, sin) form, no transcendental call."""
    for i in range(c.shape[0]):
        sc = 0.0
        ss = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            sc += w[p] * c[j]
            ss += w[p] * s[j]
        om = c[i] * ss - s[i] * sc
        dc[i] = -s[i] * om
        ds[i] = c[i] * om


@njit(fastmath=True, inline="always")
def _scaled_norm(ec, es, c0, s0, c1, s1, rtol, atol):
    """RMS of ``(ec, es) / (atol + rtol max(|y0|, |y1|))`` over all 2N components (Hairer)."""
    acc = 0.0
    for i in range(c0.shape[0]):
        sc = atol + rtol * max(abs(c0[i]), abs(c1[i]))
        ss = atol + rtol * max(abs(s0[i]), abs(s1[i]))
        acc += (ec[i] / sc) ** 2 + (es[i] / ss) ** 2
    return math.sqrt(acc / (2 * c0.shape[0]))


@njit(fastmath=True, inline="always")
def _dense_crossing(c_sum, s_sum, kc_sum, ks_sum, h, target):
    """Fraction ``x`` in (0, 1] of an accepted step where the dense output of ``R`` first reaches
    ``target``, by bisection to rounding.

    The interpolant is linear in the stages, so ``C(x) = sum_i c_i(x)`` and ``S(x)`` are quartics
    built from the node sums of the stages (``kc_sum[k] = sum_i kc[k, i]``): the root search costs
    a few flops per iteration, whatever N is.
    """
    qc = np.zeros(4)
    qs = np.zeros(4)
    for k in range(7):
        for m in range(4):
            qc[m] += kc_sum[k] * P[k, m]
            qs[m] += ks_sum[k] * P[k, m]
    lo = 0.0
    hi = 1.0
    for _ in range(60):
        x = 0.5 * (lo + hi)
        cx = c_sum + h * x * (qc[0] + x * (qc[1] + x * (qc[2] + x * qc[3])))
        sx = s_sum + h * x * (qs[0] + x * (qs[1] + x * (qs[2] + x * qs[3])))
        if cx * cx + sx * sx >= target:
            hi = x
        else:
            lo = x
    return hi


@njit(fastmath=True)
def sync_time(c, s, indptr, indices, w, rtol, atol, target, t_max, kc, ks, yc, ys):
    """First time ``R = (sum c)^2 + (sum s)^2`` reaches ``target``, by Dormand-Prince 5(4).

    Parameters
    ----------
    c, s : float64 (N,)
        Initial state ``(cos theta, sin theta)``; overwritten (the state at the end).
    indptr, indices, w : CSR form of ``W``.
    rtol, atol : float
        Tolerances of the local error of the 4th-order embedded solution, per component.
    target : float
        ``(threshold N)^2``.
    t_max : float
        Give up at this time (NOT_SYNCED), as the package's ``dynamics.t_max``.
    kc, ks : float64 (7, N)
        Stage derivatives (scratch); ``yc, ys``: float64 (2, N), stage and new state (scratch).

    Returns
    -------
    status, tau, accepted, rejected, nfev
        Crossing time from the dense output inside the first accepted step whose end point
        reaches the target (a crossing and return inside one step is not seen, as in the
        package's RK4); step counts and right-hand-side evaluations.
    """
    n = c.shape[0]
    c_sum = 0.0
    s_sum = 0.0
    for i in range(n):
        c_sum += c[i]
        s_sum += s[i]
    if c_sum * c_sum + s_sum * s_sum >= target:
        return ALREADY_SYNCED, 0.0, 0, 0, 0
    _rhs(c, s, indptr, indices, w, kc[0], ks[0])
    # initial step: Hairer's heuristic as in scipy's select_initial_step (error order 4)
    d0 = 0.0
    d1 = 0.0
    for i in range(n):
        sc = atol + rtol * abs(c[i])
        ss = atol + rtol * abs(s[i])
        d0 += (c[i] / sc) ** 2 + (s[i] / ss) ** 2
        d1 += (kc[0, i] / sc) ** 2 + (ks[0, i] / ss) ** 2
    d0 = math.sqrt(d0 / (2 * n))
    d1 = math.sqrt(d1 / (2 * n))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    for i in range(n):
        yc[0, i] = c[i] + h0 * kc[0, i]
        ys[0, i] = s[i] + h0 * ks[0, i]
    _rhs(yc[0], ys[0], indptr, indices, w, kc[1], ks[1])
    d2 = 0.0
    for i in range(n):
        sc = atol + rtol * abs(c[i])
        ss = atol + rtol * abs(s[i])
        d2 += ((kc[1, i] - kc[0, i]) / sc) ** 2 + ((ks[1, i] - ks[0, i]) / ss) ** 2
    d2 = math.sqrt(d2 / (2 * n)) / h0
    if max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** 0.2
    h = min(100.0 * h0, h1, t_max)
    nfev = 2
    accepted = 0
    rejected = 0
    t = 0.0
    # err_prev^0.04 of the last accepted step (one pow per step instead of two)
    fac_prev = 1e-4**PI_BETA
    last_rejected = False
    yc1 = yc[1]
    ys1 = ys[1]
    yc0 = yc[0]
    ys0 = ys[0]
    while True:
        if t + h > t_max:
            h = t_max - t
        # stages 2..6 (stage 1 is the derivative at the current state: FSAL)
        for i in range(n):
            yc0[i] = c[i] + h * (A21 * kc[0, i])
            ys0[i] = s[i] + h * (A21 * ks[0, i])
        _rhs(yc0, ys0, indptr, indices, w, kc[1], ks[1])
        for i in range(n):
            yc0[i] = c[i] + h * (A31 * kc[0, i] + A32 * kc[1, i])
            ys0[i] = s[i] + h * (A31 * ks[0, i] + A32 * ks[1, i])
        _rhs(yc0, ys0, indptr, indices, w, kc[2], ks[2])
        for i in range(n):
            yc0[i] = c[i] + h * (A41 * kc[0, i] + A42 * kc[1, i] + A43 * kc[2, i])
            ys0[i] = s[i] + h * (A41 * ks[0, i] + A42 * ks[1, i] + A43 * ks[2, i])
        _rhs(yc0, ys0, indptr, indices, w, kc[3], ks[3])
        for i in range(n):
            yc0[i] = c[i] + h * (A51 * kc[0, i] + A52 * kc[1, i] + A53 * kc[2, i] + A54 * kc[3, i])
            ys0[i] = s[i] + h * (A51 * ks[0, i] + A52 * ks[1, i] + A53 * ks[2, i] + A54 * ks[3, i])
        _rhs(yc0, ys0, indptr, indices, w, kc[4], ks[4])
        for i in range(n):
            yc0[i] = c[i] + h * (
                A61 * kc[0, i] + A62 * kc[1, i] + A63 * kc[2, i] + A64 * kc[3, i] + A65 * kc[4, i]
            )
            ys0[i] = s[i] + h * (
                A61 * ks[0, i] + A62 * ks[1, i] + A63 * ks[2, i] + A64 * ks[3, i] + A65 * ks[4, i]
            )
        _rhs(yc0, ys0, indptr, indices, w, kc[5], ks[5])
        # 5th-order solution, then stage 7 = its derivative (the next step's stage 1)
        for i in range(n):
            yc1[i] = c[i] + h * (
                B1 * kc[0, i] + B3 * kc[2, i] + B4 * kc[3, i] + B5 * kc[4, i] + B6 * kc[5, i]
            )
            ys1[i] = s[i] + h * (
                B1 * ks[0, i] + B3 * ks[2, i] + B4 * ks[3, i] + B5 * ks[4, i] + B6 * ks[5, i]
            )
        _rhs(yc1, ys1, indptr, indices, w, kc[6], ks[6])
        nfev += 6
        # the error estimate, reusing the stage-state rows (stage 6's state is no longer needed)
        for i in range(n):
            yc0[i] = h * (
                E1 * kc[0, i] + E3 * kc[2, i] + E4 * kc[3, i] + E5 * kc[4, i] + E6 * kc[5, i] + E7 * kc[6, i]
            )
            ys0[i] = h * (
                E1 * ks[0, i] + E3 * ks[2, i] + E4 * ks[3, i] + E5 * ks[4, i] + E6 * ks[5, i] + E7 * ks[6, i]
            )
        err = _scaled_norm(yc0, ys0, c, s, yc1, ys1, rtol, atol)
        fac_err = err**PI_EXPO
        if err <= 1.0:
            accepted += 1
            c_new = 0.0
            s_new = 0.0
            for i in range(n):
                c_new += yc1[i]
                s_new += ys1[i]
            if c_new * c_new + s_new * s_new >= target:
                kc_sum = np.zeros(7)
                ks_sum = np.zeros(7)
                for k in range(7):
                    for i in range(n):
                        kc_sum[k] += kc[k, i]
                        ks_sum[k] += ks[k, i]
                x = _dense_crossing(c_sum, s_sum, kc_sum, ks_sum, h, target)
                return SYNCED, t + x * h, accepted, rejected, nfev
            t += h
            for i in range(n):
                c[i] = yc1[i]
                s[i] = ys1[i]
                kc[0, i] = kc[6, i]
                ks[0, i] = ks[6, i]
            c_sum = c_new
            s_sum = s_new
            if t >= t_max:
                return NOT_SYNCED, t_max, accepted, rejected, nfev
            fac = fac_err / fac_prev / SAFE
            fac = max(1.0 / FAC_MAX, min(1.0 / FAC_MIN, fac))
            h_new = h / fac
            if last_rejected:
                h_new = min(h_new, h)
            fac_prev = max(err, 1e-4) ** PI_BETA
            last_rejected = False
        else:
            rejected += 1
            h_new = h / min(1.0 / FAC_MIN, fac_err / SAFE)
            last_rejected = True
        h = h_new


@njit(parallel=True, fastmath=True)
def adaptive_fd(seed, ks, indptr, indices, base_w, var_w, var_is_base, rtol, atol, target, t_max, out):
    """tau0 and tau of every variant for realizations ``ks``, in parallel over realizations.

    ``out`` is a tuple of arrays filled per realization ``r``: ``status0[r]``, ``tau0[r]``,
    ``status[r, v]``, ``tau[r, v]``, and the totals over its trajectories ``steps[r, 0]``
    (accepted), ``steps[r, 1]`` (rejected), ``steps[r, 2]`` (right-hand-side evaluations). A
    variant whose weights equal the base (``var_is_base``) copies tau0, as the package does.
    """
    status0, tau0, status, tau, steps = out
    n = indptr.shape[0] - 1
    for r in prange(ks.shape[0]):
        theta = np.empty(n)
        c = np.empty(n)
        s = np.empty(n)
        kc = np.empty((7, n))
        kss = np.empty((7, n))
        yc = np.empty((2, n))
        ys = np.empty((2, n))
        for i in range(n):
            theta[i] = phase(seed, ks[r], i)
            c[i] = math.cos(theta[i])
            s[i] = math.sin(theta[i])
        st, t0, acc, rej, nfev = sync_time(
            c, s, indptr, indices, base_w, rtol, atol, target, t_max, kc, kss, yc, ys
        )
        status0[r] = st
        tau0[r] = t0
        steps[r, 0] = acc
        steps[r, 1] = rej
        steps[r, 2] = nfev
        for v in range(var_w.shape[0]):
            if var_is_base[v]:
                status[r, v] = st
                tau[r, v] = t0
                continue
            for i in range(n):
                c[i] = math.cos(theta[i])
                s[i] = math.sin(theta[i])
            st, tv, acc, rej, nfev = sync_time(
                c, s, indptr, indices, var_w[v], rtol, atol, target, t_max, kc, kss, yc, ys
            )
            status[r, v] = st
            tau[r, v] = tv
            steps[r, 0] += acc
            steps[r, 1] += rej
            steps[r, 2] += nfev


class Outcome:
    """Per-realization results of one method: ``status0, tau0`` (M,), ``status, tau`` (M, 12)."""

    def __init__(self, status0, tau0, status, tau):
        self.status0 = status0
        self.tau0 = tau0
        self.status = status
        self.tau = tau

    def lambda_values(self):
        """``(values, code)`` as :func:`antisync.execution.compute.lambda_values` forms them."""
        ok = (self.status0[:, None] == SYNCED) & (self.status == SYNCED)
        code = np.where(ok, SYNCED, np.maximum(self.status0[:, None], self.status)).astype(np.int8)
        values = np.where(ok, (self.tau0[:, None] / np.where(ok, self.tau, 1.0) - 1.0) / DBETA, 0.0)
        return values, code


def _config(m: int, dt: float = RK4_DT):
    return load_config_text(f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
edges: all
betas: []
lambda: {{method: finite-difference, dbeta: {DBETA}}}
dynamics: {{integrator: rk4, dt: {dt}}}
realizations: {m}
block_size: {max(1, m // 100)}
keep_pairs: {m}
""")


class Problem:
    """The lollipop's CSR arrays and the 12 finite-difference variants, from the package."""

    def __init__(self, m: int):
        self.job = make_job(_config(m))
        job = self.job
        self.m = m
        self.n = len(job.nodes)
        self.labels = list(job.edge_labels)
        self.variants = np.array([job.variant(e, DBETA) for e in range(len(job.edges))])
        self.var_w = np.ascontiguousarray(job.variant_weights[self.variants])
        self.var_is_base = np.array([np.array_equal(w, job.csr.weights) for w in self.var_w])
        self.seed = np.uint64(job.config.seed)
        dyn = job.config.dynamics
        self.target = (dyn.threshold * self.n) ** 2
        self.t_max = float(dyn.t_max)

    def adaptive(self, rtol: float, atol: float, m: int | None = None):
        """Run :func:`adaptive_fd`; returns ``(Outcome, steps (M, 3), seconds)``."""
        m = self.m if m is None else m
        ks = np.arange(m, dtype=np.uint64)
        v = self.var_w.shape[0]
        out = (
            np.empty(m, np.int8),
            np.empty(m),
            np.empty((m, v), np.int8),
            np.empty((m, v)),
            np.empty((m, 3), np.int64),
        )
        csr = self.job.csr
        t = time.perf_counter()
        adaptive_fd(
            self.seed,
            ks,
            csr.indptr,
            csr.indices,
            csr.weights,
            self.var_w,
            self.var_is_base,
            rtol,
            atol,
            self.target,
            self.t_max,
            out,
        )
        seconds = time.perf_counter() - t
        return Outcome(*out[:4]), out[4], seconds

    def rk4_job(self, dt: float):
        """The package's job for RK4 with step ``dt`` (same graph, variants, seed, realizations)."""
        return make_job(_config(self.m, dt))

    def rk4_timed(self, job, threads: int):
        """The package's finite difference as ``antisync run`` computes it; returns the chunk
        result (block records, kept per-realization Lambda) and its wall time."""
        t = time.perf_counter()
        res = compute_chunk(job, Chunk(0, job.n_blocks), threads=threads)
        return res, time.perf_counter() - t

    def rk4_outcome(self, job, threads: int):
        """Per-realization results of the package's RK4 lanes (the timed kernel, run again):
        ``(Outcome, (values, code), steps per realization, trajectories per realization)`` with
        ``tau = (steps - 1 + frac) dt`` and the Lambda values of
        :func:`antisync.execution.compute.lambda_values`."""
        sim = simulate_job(job, 0, self.m, threads=threads)
        values, code, _, _ = lambda_values(job, sim, 0, self.m, threads)
        dt = job.config.dynamics.dt
        tau0 = (sim.steps0 - 1 + sim.frac0) * dt
        tau = (sim.steps - 1 + sim.frac) * dt
        v = self.variants
        # the lane driver steps every variant whose weights differ from the base network
        distinct = np.flatnonzero(
            ~np.array([np.array_equal(w, job.csr.weights) for w in job.variant_weights])
        )
        steps = sim.steps0 + sim.steps[:, distinct].sum(axis=1)
        out = Outcome(sim.status0, tau0, sim.status[:, v], tau[:, v])
        return out, (values, code), steps, len(distinct) + 1


def link_estimates(values, code, block: int):
    """``[(Lambda, se)]`` per link by the package's estimator (block records, batch-means se)."""
    rec, _ = estimators.lambda_block_records(values, code, np.zeros(values.shape, bool), block)
    out = []
    for e in range(values.shape[1]):
        s = estimators.summarize_lambda(rec[:, e])
        out.append((s["lambda"].mean, s["lambda"].se))
    return out


def scipy_reference(problem: Problem, m: int, tol: float):
    """tau0 and the damaged tau of realizations ``0 .. m-1`` by scipy's DOP853 in the phases
    ``theta`` (a different state, method and code path from :func:`sync_time`), with a terminal
    event on ``R - target`` (scipy locates it on DOP853's 7th-order dense output by brentq)."""
    from scipy.integrate import solve_ivp

    csr = problem.job.csr
    rows = np.repeat(np.arange(problem.n), np.diff(csr.indptr))
    cols = csr.indices
    target = problem.target
    theta0 = initial_phases(int(problem.seed), 0, m, problem.n)

    def tau_of(th0, w):
        def f(_t, th):
            return np.bincount(rows, w * np.sin(th[cols] - th[rows]), minlength=problem.n)

        def ev(_t, th):
            return np.cos(th).sum() ** 2 + np.sin(th).sum() ** 2 - target

        ev.terminal = True
        ev.direction = 1
        sol = solve_ivp(f, (0.0, problem.t_max), th0, method="DOP853", rtol=tol, atol=tol, events=ev)
        return sol.t_events[0][0] if sol.t_events[0].size else np.nan

    tau0 = np.array([tau_of(th, csr.weights) for th in theta0])
    tau = np.array(
        [
            [
                tau_of(th, w) if not same else np.nan
                for w, same in zip(problem.var_w, problem.var_is_base, strict=True)
            ]
            for th in theta0
        ]
    )
    tau[:, problem.var_is_base] = tau0[:, None]
    return tau0, tau


def _agreement_row(label, out: Outcome, ref: Outcome, mask, damaged):
    d0 = np.abs(out.tau0 - ref.tau0)[mask]
    dv = np.abs(out.tau - ref.tau)[mask][:, damaged].ravel()
    rel0 = d0 / ref.tau0[mask]
    lam, _ = out.lambda_values()
    lam_ref, _ = ref.lambda_values()
    dl = np.abs(lam - lam_ref)[mask][:, damaged].ravel()

    def q(x):
        return f"{np.median(x):.1e} / {np.quantile(x, 0.99):.1e} / {x.max():.1e}"

    return f"| {label} | {q(d0)} | {q(rel0)} | {q(dv)} | {q(dl)} |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=20000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--tols", type=float, nargs="+", default=[1e-4, 1e-6, 1e-8])
    ap.add_argument(
        "--rk4-dts", type=float, nargs="+", default=[RK4_DT, 0.1, 0.2], help="the first is the baseline"
    )
    ap.add_argument("--repeats", type=int, default=3, help="interleaved timing repeats (median kept)")
    ap.add_argument("--scipy-realizations", type=int, default=30)
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    m = args.realizations
    prob = Problem(m)
    damaged = ~prob.var_is_base
    print(
        f"# bench_adaptive: lollipop(6,3), 12 directed links, dbeta = {DBETA}, M = {m}, "
        f"{args.threads} threads, numba {numba.__version__}, python {platform.python_version()}"
    )

    # compile both before timing (the package's kernels are cached; ours compile here)
    jobs = {dt: prob.rk4_job(dt) for dt in args.rk4_dts}
    for job in jobs.values():
        compute_chunk(job, Chunk(0, 1), threads=args.threads)
    prob.adaptive(1e-6, 1e-6, m=8)

    # the reference, and its check against scipy on a few realizations
    ref, ref_steps, ref_s = prob.adaptive(REF_TOL, REF_TOL)
    ms = min(args.scipy_realizations, m)
    t = time.perf_counter()
    sp0, sp = scipy_reference(prob, ms, SCIPY_TOL)
    sp_s = time.perf_counter() - t
    gap0 = np.nanmax(np.abs(sp0 - ref.tau0[:ms]))
    gap = np.nanmax(np.abs(sp - ref.tau[:ms]))
    print(
        f"# reference: Dormand-Prince rtol = atol = {REF_TOL:g} ({ref_s:.1f} s, "
        f"{ref_steps[:, 0].mean() + ref_steps[:, 1].mean():,.0f} steps per realization); against "
        f"scipy DOP853 rtol = atol = {SCIPY_TOL:g} with events on {ms} realizations ({sp_s:.0f} s): "
        f"max |dtau0| = {gap0:.1e}, max |dtau(dbeta)| = {gap:.1e}"
    )

    # timing: the package's runs and the adaptive solver at every tolerance, interleaved
    times = {("rk4", dt): [] for dt in args.rk4_dts} | {("dp5", tol): [] for tol in args.tols}
    kept = {}
    adaptive = {}
    for _ in range(args.repeats):
        for dt, job in jobs.items():
            res, sec = prob.rk4_timed(job, args.threads)
            times[("rk4", dt)].append(sec)
            kept[dt] = res.kept["lambda"]
        for tol in args.tols:
            out, steps, sec = prob.adaptive(tol, tol)
            times[("dp5", tol)].append(sec)
            adaptive[tol] = (out, steps)
    med = {k: float(np.median(v)) for k, v in times.items()}

    # every method's per-realization results: (label, Outcome, (values, code), steps, rhs evals)
    methods = []
    for dt, job in jobs.items():
        out, (vals, code), steps, traj = prob.rk4_outcome(job, args.threads)
        if not np.array_equal(vals, kept[dt]):
            raise RuntimeError("simulate_job + lambda_values differ from compute_chunk's kept pairs")
        # RK4: four right-hand sides per step and one for every trajectory's initial velocity
        methods.append((f"package RK4 dt {dt:g}", ("rk4", dt), out, (vals, code), steps, 4 * steps + traj))
    for tol, (out, steps) in adaptive.items():
        methods.append(
            (
                f"DP5 rtol = atol = {tol:g}",
                ("dp5", tol),
                out,
                out.lambda_values(),
                steps[:, 0] + steps[:, 1],
                steps[:, 2],
            )
        )
    print(
        "# the package's per-realization Lambda (simulate_job + lambda_values) equals "
        "compute_chunk's kept pairs"
    )

    mask = (ref.status0 == SYNCED) & (ref.status == SYNCED).all(axis=1)
    for _, _, out, *_ in methods:
        mask &= (out.status0 == SYNCED) & (out.status == SYNCED).all(axis=1)
    print(
        f"# realizations with every trajectory synchronized in every method: {mask.sum()} of {m} "
        f"(reference NOT_SYNCED trajectories: {(ref.status0 == NOT_SYNCED).sum()} tau0, "
        f"{(ref.status == NOT_SYNCED).sum()} damaged)"
    )
    print()
    print("## Per-realization agreement with the reference (median / 99th percentile / max)")
    print()
    print(
        "| method | abs tau0 error | rel tau0 error | abs tau(dbeta) error (11 damaged links) | "
        "abs Lambda error per realization |"
    )
    print("|---|---|---|---|---|")
    for label, _, out, *_ in methods:
        print(_agreement_row(label, out, ref, mask, damaged))

    # Lambda per link: every method with its batch-means se, and paired differences to the reference
    block = prob.job.block_size
    ref_vals, ref_code = ref.lambda_values()
    summaries = {"reference": link_estimates(ref_vals, ref_code, block)}
    for label, _, _, (vals, code), *_ in methods:
        summaries[label] = link_estimates(vals, code, block)
    print()
    print(f"## Lambda per link (M = {m}, +- batch-means se as the package reports it)")
    print()
    print("| link | " + " | ".join(summaries) + " |")
    print("|---|" + "---|" * len(summaries))
    for e, lab in enumerate(prob.labels):
        print(
            f"| {lab} | " + " | ".join(f"{s[e][0]:+.4f} +- {s[e][1]:.4f}" for s in summaries.values()) + " |"
        )
    print()
    print(f"## Paired difference of Lambda to the reference, mean +- se (the same {mask.sum()} realizations)")
    print()
    print("| link | " + " | ".join(label for label, *_ in methods) + " |")
    print("|---|" + "---|" * len(methods))
    for e, lab in enumerate(prob.labels):
        cells = []
        for _, _, _, (vals, _), *_ in methods:
            d = (vals[:, e] - ref_vals[:, e])[mask]
            cells.append(f"{d.mean():+.1e} +- {d.std(ddof=1) / math.sqrt(d.size):.1e}")
        print(f"| {lab} | " + " | ".join(cells) + " |")

    # time to precision, steps
    print()
    print(
        f"## Time to precision ({args.threads} threads, median of {args.repeats} interleaved runs, M = {m})"
    )
    print()
    print(
        "| method | seconds (M) | realizations/s | worst se (M) | time to se 0.005 | vs RK4 dt "
        f"{args.rk4_dts[0]:g} | steps / realization (acc + rej) | rejected | RHS evals / realization | "
        "ns per RHS eval per thread |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    base_ttp = None
    for label, key, _, _, steps, rhs in methods:
        se = max(se for _, se in summaries[label])
        ttp = med[key] * (se / TARGET_SE) ** 2
        base_ttp = ttp if base_ttp is None else base_ttp
        rejected = f"{adaptive[key[1]][1][:, 1].mean():.1f}" if key[0] == "dp5" else "0"
        print(
            f"| {label} | {med[key]:.2f} | {m / med[key]:,.0f} | {se:.4f} | {ttp:.2f} s | "
            f"{ttp / base_ttp:.2f} | {steps.mean():,.0f} | {rejected} | {rhs.mean():,.0f} | "
            f"{med[key] * args.threads / (m * rhs.mean()) * 1e9:.1f} |"
        )
    print()
    print(
        "raw seconds per repeat: "
        + "; ".join(f"{k[0]} {k[1]:g}: {', '.join(f'{x:.2f}' for x in v)}" for k, v in times.items())
    )


if __name__ == "__main__":
    main()
