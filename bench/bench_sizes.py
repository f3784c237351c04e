"""The Euler lane kernel at every network size, against the machine's peak and NumPy (issue 17).

For each graph (lollipop N = 6, a lollipop N = 20, karate N = 34, Les Miserables N = 77, a
sparse random graph N = 118 of mean degree ~3, a random 4-regular graph N = 500) it times
``antisync.kernels.cpu.simulate`` on the undamaged network only (tau0 of M realizations, Euler,
dt = 0.01, normalized coupling; lanes are refilled as trajectories finish, so M must be
large against 32 lanes x threads) and reports:

- ns per trajectory-step per thread, and per directed edge (``nnz`` of W);
- the flops of one step as the lane kernel does them, ``4 nnz + 30 N`` (two multiply-adds per
  directed edge for the sums of w c and w s; per node the rotation angle, Taylor cos/sin,
  the rotation and the order parameter's sums), and the GFLOP/s that makes;
- the same integration written as a competent vectorized NumPy Euler (all M trajectories as
  rows of a (M, N) array, ``np.add.reduceat`` over the CSR rows, trajectories dropped once
  synchronized), in ns per trajectory-step, and antisync's speed-up over it;
- the machine's peak: ``bench/roofline.py``'s register-resident FMA loop (it reaches the core's
  peak; the earlier L1 streaming loop here was only a lower bound), per thread x threads.

Usage: ``python bench/bench_sizes.py [--realizations 64]``. Results: bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import networkx as nx
import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from antisync.kernels.cpu import simulate  # noqa: E402
from antisync.physics import graphs  # noqa: E402
from antisync.physics.coupling import coupling_matrix, to_csr  # noqa: E402
from antisync.physics.phases import phase  # noqa: E402

DT = 0.01
THRESHOLD = 0.99
T_MAX = 400.0


def peak_gflops(threads: int) -> float:
    """The cores' FMA peak: ``bench/roofline.py``'s register-resident FMA loop (12 independent
    8-wide accumulators, ``vfmadd...pd``), per thread times the threads."""
    from roofline import limits  # roofline imports this module: import on use

    return limits(0.2)["fma"] * threads / 1e9


def csr(g: nx.Graph):
    """Normalized coupling W (paper Eq. 2) of ``g`` in CSR form: indptr, indices, weights."""
    c = to_csr(coupling_matrix(nx.to_numpy_array(g, nodelist=list(g.nodes)), "normalized"))
    return c.indptr, c.indices, c.weights


def numpy_euler(indptr, indices, weights, m: int, seed: int, max_steps: int) -> tuple[float, int]:
    """``(seconds, trajectory-steps)`` of a vectorized NumPy Euler of ``m`` trajectories."""
    n = indptr.size - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    theta = np.array([[phase(seed, r, i) for i in range(n)] for r in range(m)])
    alive = np.ones(m, dtype=bool)
    steps = 0
    t = time.perf_counter()
    for _ in range(max_steps):
        th = theta[alive]
        s = weights * np.sin(th[:, indices] - th[:, rows])
        vel = np.add.reduceat(s, indptr[:-1], axis=1)
        th += DT * vel
        theta[alive] = th
        steps += th.shape[0]
        r = np.abs(np.exp(1j * th).mean(axis=1))
        done = r >= THRESHOLD
        if done.any():
            idx = np.flatnonzero(alive)[done]
            alive[idx] = False
        if not alive.any():
            break
    return time.perf_counter() - t, steps


def graphs_to_bench(seed: int):
    rng = np.random.default_rng(seed)
    out = [
        ("lollipop N=6", graphs.lollipop(6, 3)),
        ("lollipop N=20", graphs.lollipop(20, 10)),
        ("karate N=34", nx.karate_club_graph()),
        ("les miserables N=77", nx.Graph(nx.les_miserables_graph().edges())),
    ]
    # a connected sparse random graph of mean degree ~3 (118 nodes, as the IEEE 118-bus grid)
    while True:
        g = nx.gnm_random_graph(118, 179, seed=int(rng.integers(1 << 31)))
        if nx.is_connected(g):
            out.append(("random N=118 (deg 3)", g))
            break
    out.append(("random 4-regular N=500", nx.random_regular_graph(4, 500, seed=seed)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=1024)
    ap.add_argument("--numpy-realizations", type=int, default=256)
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    threads = numba.get_num_threads()
    print(
        f"# bench_sizes: Euler dt {DT}, tau0 only, M = {args.realizations}; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {threads} threads, "
        f"numba {numba.__version__}"
    )
    peak = peak_gflops(threads)
    print(
        f"# peak: {peak:.1f} GFLOP/s over {threads} threads (register FMA loop, bench/roofline.py), "
        f"{peak / threads:.1f} per thread\n"
    )
    print(
        "| graph | N | nnz | ns/step/thread | ns/step/thread/nnz | flops/step | GFLOP/s (share of peak) | "
        "NumPy ns/step | speed-up | synced |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    max_steps = int(round(T_MAX / DT))
    for label, g in graphs_to_bench(args.seed):
        indptr, indices, weights = csr(g)
        n, nnz = indptr.size - 1, indices.size
        none = np.empty((0, nnz))
        kw = {"dt": DT, "threshold": THRESHOLD, "max_steps": max_steps}
        simulate(1, 0, 32, indptr, indices, weights, none, **kw)  # compile
        t = time.perf_counter()
        sim = simulate(1, 0, args.realizations, indptr, indices, weights, none, **kw)
        sec = time.perf_counter() - t
        synced = sim.status0 == 0
        steps = float(np.where(synced, sim.steps0, max_steps).sum())
        ns = sec * threads / steps * 1e9
        flops = 4 * nnz + 30 * n
        gflops = flops * steps / sec / 1e9
        np_sec, np_steps = numpy_euler(indptr, indices, weights, args.numpy_realizations, 1, max_steps)
        np_ns = np_sec / np_steps * 1e9  # NumPy runs on one thread (plus BLAS-free ufuncs)
        print(
            f"| {label} | {n} | {nnz} | {ns:.1f} | {ns / nnz:.2f} | {flops} | {gflops:.1f} "
            f"({gflops / peak:.0%}) | {np_ns:,.0f} | {np_ns / (ns / threads):.0f}x | "
            f"{synced.mean():.0%} |",
            flush=True,
        )
    print(
        "\nspeed-up: NumPy's wall time per trajectory-step over antisync's (all threads); "
        f"antisync's ns/step/thread over {threads} threads"
    )


if __name__ == "__main__":
    main()
