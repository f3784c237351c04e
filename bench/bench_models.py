"""Model kernels (docs/models.md) against the default lane driver, one core.

    python bench/bench_models.py

The model kernel runs with ``P = 0, alpha = 0, m = 0``, so both integrate the same
trajectories (identical steps, checked) and the ratio is the cost of the one-trajectory-per-
thread driver and the general step.
"""

from __future__ import annotations

import time

import numpy as np

from antisync.config import load_config_text
from antisync.jobs import make_job
from antisync.kernels import cpu, model_cpu


def main() -> None:
    job = make_job(
        load_config_text(
            "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1', '5->6']\nbetas: [0.5]\n"
        )
    )
    n = len(job.nodes)
    v = job.variant_weights.shape[0]
    args = (1, 0, 400, job.csr.indptr, job.csr.indices, job.csr.weights, job.variant_weights)
    params = model_cpu.ModelParams(np.zeros((1, n)), 1.0, 0.0, 0.0, 1.0, 0, np.full(v + 1, (0.99 * n) ** 2))
    for _ in range(2):  # the first round compiles (or loads the cache)
        t = time.perf_counter()
        ref = cpu.simulate(*args, dt=0.001, threshold=0.99, max_steps=200000, threads=1)
        lanes = time.perf_counter() - t
        t = time.perf_counter()
        got = model_cpu.simulate_model(*args, params, dt=0.001, max_steps=200000, threads=1)
        model = time.perf_counter() - t
        t = time.perf_counter()
        model_cpu.simulate_model(*args, params, dt=0.04, max_steps=5000, threads=1, integrator="rk4")
        model_rk4 = time.perf_counter() - t
        t = time.perf_counter()
        cpu.simulate(*args, dt=0.04, threshold=0.99, max_steps=5000, threads=1, integrator="rk4")
        lanes_rk4 = time.perf_counter() - t
    same = np.array_equal(ref.steps, got.steps) and np.array_equal(ref.steps0, got.steps0)
    steps = int(ref.steps0.sum() + ref.steps.sum())
    print(f"{400 * (v + 1)} trajectories, {steps} Euler steps (dt = 0.001), identical: {same}")
    print(
        f"euler: lanes {lanes:.2f} s ({steps / lanes / 1e6:.1f} M steps/s), model {model:.2f} s "
        f"({steps / model / 1e6:.1f} M steps/s), ratio {model / lanes:.1f}"
    )
    print(f"rk4 dt = 0.04: lanes {lanes_rk4:.3f} s, model {model_rk4:.3f} s")


if __name__ == "__main__":
    main()
