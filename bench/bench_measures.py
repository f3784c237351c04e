"""Timing of Lambda^(xi2) over the 6-node atlas, and the three measures on the paper's lollipop.

Run: ``PYTHONPATH=. python bench/bench_measures.py [--realizations 2000] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import time

import networkx as nx
import numpy as np

from antisync.measures import lambda_linear, lambda_rw, lambda_xi2_all
from antisync.physics.graphs import all_directed_edges, edge_label, lollipop, omega_matrix


def atlas_timing(repeats: int = 5) -> tuple[int, int, float]:
    graphs = [g for g in nx.graph_atlas_g() if len(g) == 6 and nx.is_connected(g)]
    prepared = []
    for g in graphs:
        omega = omega_matrix(g)
        prepared.append((omega, [(int(a), int(b)) for a, b in zip(*np.nonzero(omega), strict=True)]))
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        n_edges = sum(len(lambda_xi2_all(omega, edges)) for omega, edges in prepared)
        best = min(best, time.perf_counter() - start)
    return len(graphs), n_edges, best


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--realizations", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    n_graphs, n_edges, seconds = atlas_timing()
    print(
        f"Lambda^(xi2), all directed edges of the {n_graphs} connected 6-node atlas graphs "
        f"({n_edges} edges): {seconds * 1e3:.1f} ms (best of 5)"
    )

    g = lollipop(6, 3)
    omega = omega_matrix(g)
    theta0 = np.random.default_rng(args.seed).uniform(0, 2 * np.pi, (args.realizations, 6))
    edges = [(u, v) for u, v in all_directed_edges(g)]
    lam_xi2 = lambda_xi2_all(omega, [(u - 1, v - 1) for u, v in edges])
    print(
        f"\nlollipop(6, 3), r = 0.99, {args.realizations} realizations (seed {args.seed}), "
        "Lambda^(linear) with dbeta = 0.01"
    )
    print(f"{'edge':>5} {'xi2':>8} {'RW':>8} {'linear (FD)':>17} {'linear (deriv)':>17} {'n':>5}")
    start = time.perf_counter()
    for (u, v), lx in zip(edges, lam_xi2, strict=True):
        fd = lambda_linear(omega, u - 1, v - 1, theta0)
        dv = lambda_linear(omega, u - 1, v - 1, theta0, method="derivative")
        print(
            f"{edge_label(u, v):>5} {lx:8.4f} {lambda_rw(omega, u - 1, v - 1):8.4f} "
            f"{fd.lambda_:8.4f} ± {fd.se:.4f} {dv.lambda_:8.4f} ± {dv.se:.4f} {fd.n:5d}"
        )
    print(f"(linear: {time.perf_counter() - start:.1f} s for 12 edges x 2 methods)")


if __name__ == "__main__":
    main()
