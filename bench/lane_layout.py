"""The lane driver's layout on small and large batches: ns per trajectory-step of the built-in
RK4 lanes (the model kernels and the identical oscillators), two threads, a target out of reach
(every item runs all its steps). ``python bench/lane_layout.py`` (about a minute).

A batch is cut into ``4 x threads`` groups of realizations, each stepping 32 lanes until its last
lane is done; ``antisync.kernels.cpu._layout`` narrows the lanes and the groups of a batch too
small to fill them (bench/RESULTS.md, "The lane layout of small batches").
"""

from __future__ import annotations

import functools
import time

import networkx as nx
import numpy as np
from bench_laws import unit_network

from antisync.kernels import cpu
from antisync.kernels.model_steps import ModelParams

#: (graph, N, realizations, variants, steps)
CASES = (
    ("3-regular", lambda: nx.random_regular_graph(3, 1000, seed=1), 32, 0, 300),
    ("3-regular", lambda: nx.random_regular_graph(3, 1000, seed=1), 256, 0, 100),
    ("karate", nx.karate_club_graph, 64, 0, 2000),
    ("karate", nx.karate_club_graph, 256, 3, 1000),
    ("karate", nx.karate_club_graph, 4096, 0, 200),
)


def best_of(f, repeat: int = 3) -> float:
    f()  # compile or load
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    for name, make, m, v, steps in CASES:
        csr, n, never = unit_network(make())
        params = ModelParams(np.zeros((1, n)), 1.0, 0.0, 0.0, 1.0, 0, np.full(1 + v, never[0]))
        vw = np.repeat(csr.weights[None] * 0.999, v, axis=0)
        common = (5, 0, m, csr.indptr, csr.indices, csr.weights, vw)
        clock = {"dt": 0.01, "max_steps": steps, "threads": 2, "integrator": "rk4"}
        kinds = {
            "model": functools.partial(cpu.simulate_model, *common, params, **clock),
            "identical": functools.partial(cpu.simulate, *common, threshold=2.0, **clock),
        }
        for kind, f in kinds.items():
            ns = best_of(f) / (m * (1 + v) * steps) * 1e9
            print(f"{name} N={n} m={m} V={v} {kind}: {ns:8.1f} ns per trajectory-step", flush=True)


if __name__ == "__main__":
    main()
