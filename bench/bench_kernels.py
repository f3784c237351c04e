"""Lambda^KM for all 12 directed edges of the paper's lollipop: speed and time to precision.

Run with ``make bench`` (or ``python bench/bench_kernels.py [--realizations M]``). Everything is
measured in one run on the same machine, against a baseline written the obvious way:

(a) baseline: the paper's procedure (tau0 and tau(dbeta) integrated anew for every edge,
    Euler dt = 0.001, grid crossing) with the kernel a competent Numba user writes:
    ``fastmath``, one ``sin`` per undirected edge (``sin(theta_j - theta_i)`` serves both
    ends), r compared squared, realizations in parallel with ``prange`` (issue 17);
(a') the plainer kernel earlier versions of this bench used as the baseline (one ``sin`` per
    directed edge, no fastmath), for continuity;
(b) antisync finite difference (Euler dt = 0.001, lanes, tau0 shared by all edges);
(c) antisync pathwise (forward tangents for all edges along one trajectory);
(d) antisync hybrid (pathwise, secants where |value| > 2);
(e) antisync finite difference with RK4 (dt = 0.04, Hermite crossing).

For each: realizations/s, trajectory-steps/s (Euler or RK4 steps of any trajectory; tangents
ride along), the worst standard error over the edges at the benchmark size (batch means), and
the projected wall time to standard error 0.005 on every edge: t_per_realization * M_needed
with M_needed = M * (worst_se / 0.005)^2. The baseline computes exactly the estimator of (b)
(grid crossing times), so it shares (b)'s standard error and only its speed is timed.
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
from numba import njit, prange

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync.execution.compute import compute_chunk  # noqa: E402
from antisync.physics.phases import phase  # noqa: E402
from antisync.plan.config import load_config_text  # noqa: E402
from antisync.plan.jobs import Chunk, make_job  # noqa: E402
from antisync.stats import estimators  # noqa: E402

TARGET_SE = 0.005


@njit(inline="always")
def _tau_theta(theta0, src, dst, w, n, dt, target, max_steps):
    theta = theta0.copy()
    vel = np.empty(n)
    for step in range(1, max_steps + 1):
        vel[:] = 0.0
        for p in range(src.size):
            vel[src[p]] += w[p] * np.sin(theta[dst[p]] - theta[src[p]])
        for i in range(n):
            theta[i] += dt * vel[i]
        c = 0.0
        s = 0.0
        for i in range(n):
            c += np.cos(theta[i])
            s += np.sin(theta[i])
        if np.sqrt(c * c + s * s) / n >= target:
            return step
    return -1


@njit(parallel=True)
def baseline(seed, m, n, src, dst, w0, w_edges, dt, target, max_steps, out):
    """out[r, e] = tau0/tau(dbeta) - 1 for edge e, tau0 re-integrated for every edge."""
    for r in prange(m):
        theta0 = np.empty(n)
        for i in range(n):
            theta0[i] = phase(seed, r, i)
        for e in range(w_edges.shape[0]):
            k0 = _tau_theta(theta0, src, dst, w0, n, dt, target, max_steps)
            k1 = _tau_theta(theta0, src, dst, w_edges[e], n, dt, target, max_steps)
            out[r, e] = k0 / k1 - 1.0 if k0 > 0 and k1 > 0 else np.nan


@njit(fastmath=True, inline="always")
def _tau_competent(theta0, a, b, wab, wba, n, dt, target2, max_steps):
    theta = theta0.copy()
    vel = np.empty(n)
    for step in range(1, max_steps + 1):
        vel[:] = 0.0
        for p in range(a.size):  # one sin per undirected edge
            s = np.sin(theta[b[p]] - theta[a[p]])
            vel[a[p]] += wab[p] * s
            vel[b[p]] -= wba[p] * s
        c = 0.0
        sn = 0.0
        for i in range(n):
            theta[i] += dt * vel[i]
            c += np.cos(theta[i])
            sn += np.sin(theta[i])
        if c * c + sn * sn >= target2:
            return step
    return -1


@njit(parallel=True, fastmath=True)
def competent(seed, m, n, a, b, wab0, wba0, wab, wba, dt, target, max_steps, out):
    """``baseline`` as a competent user writes it (undirected edge arrays ``a < b`` with the
    weights of both directions; ``wab[e]``/``wba[e]`` those of variant ``e``)."""
    target2 = (target * n) ** 2
    for r in prange(m):
        theta0 = np.empty(n)
        for i in range(n):
            theta0[i] = phase(seed, r, i)
        for e in range(wab.shape[0]):
            k0 = _tau_competent(theta0, a, b, wab0, wba0, n, dt, target2, max_steps)
            k1 = _tau_competent(theta0, a, b, wab[e], wba[e], n, dt, target2, max_steps)
            out[r, e] = k0 / k1 - 1.0 if k0 > 0 and k1 > 0 else np.nan


def undirected(rows, cols, weights):
    """Undirected edge arrays ``(a, b)`` with ``a < b`` and the weights of ``a <- b`` and
    ``b <- a`` taken from directed CSR entries ``weights[..., p]`` (rows receive)."""
    where = {(int(i), int(j)): p for p, (i, j) in enumerate(zip(rows, cols, strict=True))}
    pairs = sorted((i, j) for i, j in where if i < j)
    a = np.array([i for i, _ in pairs], dtype=np.int64)
    b = np.array([j for _, j in pairs], dtype=np.int64)
    ab = [where[(i, j)] for i, j in pairs]
    ba = [where[(j, i)] for i, j in pairs]
    w = np.asarray(weights)
    return a, b, w[..., ab].copy(), w[..., ba].copy()


def _config(method: str, integrator: str = "euler", dt: float = 0.001, m: int = 1000, precision="float64"):
    return load_config_text(f"""
graph: {{kind: lollipop, nodes: 6, path: 3}}
edges: all
betas: []
lambda: {{method: {method}, dbeta: 0.01}}
dynamics: {{integrator: {integrator}, dt: {dt}, precision: {precision}}}
realizations: {m}
block_size: {max(1, m // 100)}
""")


def run_antisync(method, integrator, dt, m, precision="float64"):
    job = make_job(_config(method, integrator, dt, m, precision))
    compute_chunk(job, Chunk(0, 1))  # compile
    t = time.perf_counter()
    res = compute_chunk(job, Chunk(0, job.n_blocks))
    seconds = time.perf_counter() - t
    steps = _trajectory_steps(job, m, method, integrator, dt)
    worst = 0.0
    tails = []
    for e in range(len(job.edges)):
        s = estimators.summarize_lambda(res.lam_rec[:, e])
        if s["n"]:
            worst = max(worst, s["lambda"].se)
            tails.append(estimators.tail_share(res.lam_tail[e]))
    lam = [estimators.summarize_lambda(res.lam_rec[:, e])["lambda"].mean for e in range(len(job.edges))]
    return seconds, steps, worst, max(tails), dict(zip(job.edge_labels, lam, strict=True))


def _trajectory_steps(job, m, method, integrator, dt):
    """Steps of every trajectory integrated (recomputed cheaply from a small sample's ratio)."""
    from antisync.execution.compute import simulate_job

    sim = simulate_job(job, 0, min(m, 300))
    scale = m / min(m, 300)
    base = sim.steps0[sim.status0 == 0].sum()
    if method == "finite-difference":
        var = sim.steps[sim.status == 0].sum()
        return float((base + var) * scale)
    return float(base * scale)  # pathwise/hybrid: one trajectory (secants add < 2%)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=4000)
    ap.add_argument("--baseline-realizations", type=int, default=300)
    args = ap.parse_args()
    m = args.realizations
    print(f"# bench_kernels: lollipop(6,3), 12 directed edges, dbeta = 0.01, M = {m}")
    print(
        f"# machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"numba {numba.__version__}, {numba.get_num_threads()} threads, python {platform.python_version()}"
    )

    # (a) baseline
    job = make_job(_config("finite-difference"))
    rows = np.repeat(np.arange(6), np.diff(job.csr.indptr))
    v = [job.variant(e, 0.01) for e in range(12)]
    w_edges = job.variant_weights[v]
    mb = args.baseline_realizations
    out = np.empty((mb, 12))
    a, b, wab0, wba0 = undirected(rows, job.csr.indices, job.csr.weights)
    _, _, wab, wba = undirected(rows, job.csr.indices, w_edges)
    graph = (6, a, b, wab0, wba0, wab, wba, 0.001, 0.99, 200_000)
    competent(np.uint64(1), 4, *graph, out[:4])
    t = time.perf_counter()
    competent(np.uint64(1), mb, *graph, out)
    base_s = time.perf_counter() - t
    fd_check = np.nanmean(out, axis=0) / 0.01
    # (a') the plain kernel, on the same realizations
    plain = np.empty((mb, 12))
    graph = (6, rows, job.csr.indices, job.csr.weights, w_edges, 0.001, 0.99, 200_000)
    baseline(np.uint64(1), 4, *graph, plain[:4])
    t = time.perf_counter()
    baseline(np.uint64(1), mb, *graph, plain)
    plain_s = time.perf_counter() - t
    same = float(np.mean(np.isclose(plain, out, equal_nan=True)))

    results = {}
    cases = (
        ("(b) finite difference, Euler", "finite-difference", "euler", 0.001, "float64"),
        ("(b32) finite difference, Euler, float32 lanes", "finite-difference", "euler", 0.001, "float32"),
        ("(c) pathwise, Euler", "pathwise", "euler", 0.001, "float64"),
        ("(d) hybrid, Euler", "hybrid", "euler", 0.001, "float64"),
        ("(e) finite difference, RK4 dt=0.04", "finite-difference", "rk4", 0.04, "float64"),
    )
    for label, method, integrator, dt, precision in cases:
        results[label] = run_antisync(method, integrator, dt, m, precision)
    fd_s, fd_steps, fd_se, _, fd_lam = results["(b) finite difference, Euler"]
    # the baseline integrates tau0 once per edge: 24 trajectories per realization vs 13 in (b)
    base_steps = fd_steps / m * mb * 24 / 13
    base_rate = mb / base_s
    base_time = (m * (fd_se / TARGET_SE) ** 2) / base_rate
    print(
        f"# baseline check: its Lambda on 2->1 from {mb} realizations = {fd_check[1]:.3f} "
        f"(antisync FD, M={m}: {fd_lam['2->1']:.3f}); the plain kernel gives the same "
        f"(tau0/tau - 1) on {same:.1%} of (realization, edge) pairs (fastmath reorders sums)"
    )
    print()
    print(
        "| estimator | realizations/s | traj-steps/s | ns/step/thread | worst se (M) | tail share | "
        "time to se 0.005 | vs (a): real/s | steps/s | time to precision |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    threads = numba.get_num_threads()
    print(
        f"| (a) competent baseline (paper's procedure) | {base_rate:,.0f} | {base_steps / base_s:.3g} | "
        f"{threads * base_s / base_steps * 1e9:.1f} | {fd_se:.4f} (as b) | - | {base_time:,.0f} s | "
        "1 | 1 | 1 |"
    )
    print(
        f"| (a') plain baseline (before issue 17) | {mb / plain_s:,.0f} | {base_steps / plain_s:.3g} | "
        f"{threads * plain_s / base_steps * 1e9:.1f} | {fd_se:.4f} (as b) | - | "
        f"{base_time * plain_s / base_s:,.0f} s | {base_s / plain_s:.2f}x | "
        f"{base_s / plain_s:.2f}x | {base_s / plain_s:.2f}x |"
    )
    for label, (sec, steps, se, tail, _) in results.items():
        rate = m / sec
        ttp = m * (se / TARGET_SE) ** 2 / rate
        print(
            f"| {label} | {rate:,.0f} | {steps / sec:.3g} | {threads * sec / steps * 1e9:.1f} | {se:.4f} | "
            f"{tail:.2f} | {ttp:,.0f} s | "
            f"{rate / base_rate:.1f}x | {(steps / sec) / (base_steps / base_s):.1f}x | "
            f"{base_time / ttp:.0f}x |"
        )
    print()
    print(f"Lambda per edge (M = {m}):")
    edges = list(fd_lam)
    print("| estimator | " + " | ".join(edges) + " |")
    print("|---|" + "---|" * len(edges))
    for label, (*_, lam) in results.items():
        print(f"| {label} | " + " | ".join(f"{lam[e]:+.3f}" for e in edges) + " |")


if __name__ == "__main__":
    main()
