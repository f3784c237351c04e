"""Per-step cost of every pass that runs on the step kernels: forward, adjoint (VJP), tangent.

    python bench/bench_passes.py [--seconds 0.3] [--tangent-limit 2000]

One thread, 16 lanes (the adjoint's group), each kernel alone in a loop, best of three, in ns
per trajectory-step (a tangent step per tangent). Columns, on the graphs of bench_sizes.py:

- Euler forward: ``euler_step_vec`` (what the forward drivers and the adjoint's forward pass
  and segment recompute run, Euler dt 0.01 here so that every rotation stays in the Taylor
  range of the vector path);
- Euler VJP: ``adjoint._euler_vjp_vec`` (the backward step of the Euler adjoint); one backward
  step of the adjoint costs a recompute step (a forward step) plus this;
- RK4 forward: ``rk4_step_vec``; RK4 VJP: ``adjoint._rk4_vjp_vec`` (stages recomputed inside);
- tangent: ``tangent_step_lanes`` with E tangents (the pathwise / hybrid estimators, one per
  damaged link), ``(t_step - t_forward) / E`` per tangent-step: the per-link price that the
  adjoint pays once for every link.

The adjoint's whole cost per realization is then about ``forward + recompute + VJP`` per step
(plus the grouping pre-pass, another forward), the pathwise one ``forward + E tangent``.
Adjoint states are reset every 64 steps (a segment), so that no denormal slows a loop.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sizes import csr, graphs_to_bench  # noqa: E402

from antisync.kernels.adjoint import _euler_vjp_vec, _rk4_vjp_vec, _transpose  # noqa: E402
from antisync.kernels.precision import K64 as _K  # noqa: E402

LANES = 16
DT_EULER = 0.01
DT_RK4 = 0.04
RESET = 64

_step_vec = _K.euler_step_vec
_step_rk4 = _K.rk4_step_vec
_step_tangent = _K.tangent_step_lanes


@njit
def _run_euler(c, s, cn, sn, lw, w, indptr, indices, dt, r2, nsteps):
    for _ in range(nsteps):
        _step_vec(c, s, cn, sn, lw, w, True, indptr, indices, dt, r2)
        c, cn = cn, c
        s, sn = sn, s


@njit
def _run_euler_vjp(c, s, lam, lam_new, g, indptr, indices, w, dt, nsteps):
    for k in range(nsteps):
        if k % RESET == 0:
            lam[:] = 1.0
        _euler_vjp_vec(c, s, lam, lam_new, g, indptr, indices, w, dt)
        lam, lam_new = lam_new, lam


@njit
def _run_rk4(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, indptr, indices, dt, r2, dr2, nsteps):
    for _ in range(nsteps):
        _step_rk4(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, True, indptr, indices, dt, r2, dr2)


@njit
def _run_rk4_vjp(args, ac, as_, nsteps):
    """``nsteps`` of ``_rk4_vjp_vec(*args)``, whose adjoint state ``(ac, as_)`` is in ``args``."""
    for k in range(nsteps):
        if k % RESET == 0:
            ac[:] = 1.0
            as_[:] = 1.0
        _rk4_vjp_vec(*args)


@njit
def _run_tangent(head, tail, nsteps):
    """``nsteps`` of ``tangent_step_lanes(*head, True, *tail)`` (``tail[0]`` the tangents)."""
    for k in range(nsteps):
        if k % RESET == 0:
            tail[0][:] = 0.0
        c, s, ac, sc, ss, tc, ts, lw, ip, ix, dt, r2 = head
        u, du, cu, su, a, b, rho, mu, dr2 = tail
        _step_tangent(c, s, ac, sc, ss, tc, ts, lw, ip, ix, dt, r2, True, u, du, cu, su, a, b, rho, mu, dr2)


def _best(run, seconds: float, nsteps: int) -> float:
    """ns per call of ``run(nsteps)`` (a fresh state each time), best of three."""
    run(2)
    best = np.inf
    for _ in range(3):
        sec = run(nsteps)
        while sec < seconds / 3:
            nsteps *= 2
            sec = run(nsteps)
        best = min(best, sec / nsteps * 1e9)
    return best


def time_passes(indptr, indices, weights, seconds: float, tangents: int) -> dict[str, float]:
    """ns per trajectory-step of each pass on one graph (see the module docstring)."""
    rng = np.random.default_rng(0)
    n, nnz = indptr.size - 1, indices.size
    indptr = indptr.astype(np.int64)
    indices = indices.astype(np.int64)
    theta = rng.uniform(0.0, 2.0 * np.pi, (n, LANES))
    c0, s0 = np.cos(theta), np.sin(theta)
    lw = np.ascontiguousarray(np.repeat(weights[:, None], LANES, axis=1))
    r2, dr2 = np.empty(LANES), np.empty(LANES)
    e = np.empty((n, LANES))

    def timed(fn, *args):
        def run(nsteps):
            t = time.perf_counter()
            fn(*args, nsteps)
            return time.perf_counter() - t

        return run

    base = max(10, int(2e6 / (nnz + 3 * n)))
    out = {}
    c, s = c0.copy(), s0.copy()
    out["euler"] = _best(
        timed(_run_euler, c, s, e.copy(), e.copy(), lw, weights, indptr, indices, DT_EULER, r2), seconds, base
    )
    g = np.zeros((nnz, LANES))
    out["euler_vjp"] = _best(
        timed(_run_euler_vjp, c0, s0, e.copy(), e.copy(), g, indptr, indices, weights, DT_EULER),
        seconds,
        base,
    )
    k = np.zeros((8, n, LANES))
    # k[0:2] must hold the velocity at the state on entry: a few steps from any k settle it
    c, s = c0.copy(), s0.copy()
    out["rk4"] = _best(
        timed(
            _run_rk4,
            c,
            s,
            k,
            e.copy(),
            e.copy(),
            e.copy(),
            e.copy(),
            lw,
            weights,
            indptr,
            indices,
            DT_RK4,
            r2,
            dr2,
        ),
        seconds,
        base // 4,
    )
    st = np.empty((4, 7, n, LANES))
    ac, as_, *bufs = [np.zeros((n, LANES)) for _ in range(8)]
    tr = _transpose(indptr, indices)
    scratch = np.empty((4, n * LANES))
    args = (c0, s0, st, ac, as_, *bufs, g, indptr, indices, weights, DT_RK4, tr, scratch)
    out["rk4_vjp"] = _best(timed(_run_rk4_vjp, args, ac, as_), seconds, base // 8)
    # tangents: every directed link up to ``tangents`` of them (a -> b = CSR entry p)
    rows = np.repeat(np.arange(n), np.diff(indptr))
    m = min(tangents, nnz)
    pick = np.linspace(0, nnz - 1, m).astype(np.int64)
    a = rows[pick].astype(np.int64)
    b = indices[pick]
    rho = np.full(m, -0.1)
    mu = -weights[pick]
    u = np.zeros((m, n, LANES))
    sums = [np.empty((n, LANES)) for _ in range(5)]
    tot = [np.empty(LANES) for _ in range(2)]
    c, s = c0.copy(), s0.copy()
    head = (c, s, *sums[:3], *tot, lw, indptr, indices, DT_EULER, r2)
    tail = (u, sums[3], sums[4], e.copy(), a, b, rho, mu, np.empty((m, LANES)))
    t_tan = _best(timed(_run_tangent, head, tail), seconds, max(2, base // (4 * m)))
    out["tangent_step"] = t_tan
    out["tangents"] = m
    return {key: (v / LANES if key != "tangents" else v) for key, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=0.3, help="minimum time per measurement")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--tangent-limit", type=int, default=2000, help="at most this many tangents per graph")
    args = ap.parse_args()
    numba.set_num_threads(1)
    print(
        f"# bench_passes: {LANES} lanes, one thread, Euler dt {DT_EULER}, RK4 dt {DT_RK4}; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(
        "\n| graph | N | nnz | Euler forward ns | Euler VJP ns (x forward) | adjoint backward step "
        "(recompute + VJP, x forward) | RK4 forward ns (x Euler) | RK4 VJP ns (x RK4 forward) | "
        "tangent step, E tangents | ns per tangent-step (x Euler forward) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, g in graphs_to_bench(args.seed):
        indptr, indices, weights = csr(g)
        t = time_passes(indptr, indices, weights, args.seconds, args.tangent_limit)
        per_tangent = (t["tangent_step"] - t["euler"]) / t["tangents"]
        print(
            f"| {label} | {indptr.size - 1} | {indices.size} | {t['euler']:.2f} | "
            f"{t['euler_vjp']:.2f} ({t['euler_vjp'] / t['euler']:.1f}) | "
            f"Euler {1 + t['euler_vjp'] / t['euler']:.1f}, RK4 {1 + t['rk4_vjp'] / t['rk4']:.1f} | "
            f"{t['rk4']:.1f} ({t['rk4'] / t['euler']:.1f}) | "
            f"{t['rk4_vjp']:.1f} ({t['rk4_vjp'] / t['rk4']:.1f}) | "
            f"{t['tangent_step']:.0f}, E = {t['tangents']} | "
            f"{per_tangent:.2f} ({per_tangent / t['euler']:.2f}) |",
            flush=True,
        )


if __name__ == "__main__":
    main()
