"""Cost of locating the crossing on the dense output (docs/models.md), one core.

    python bench/bench_crossings.py

The IEEE 14 swing-equation config (RK4, dt 0.02), undamaged trajectories only: steps per
second under the frequency criterion (every node's frequency deviation and its rate each step,
the exact range of each Hermite interpolant, a scan only where the tolerance can be met) against
the order-parameter criterion (R and dR/dt, the Hermite range of R) on the same starts. Their
ratio is what the frequency criterion's dense check costs per step.
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

import numpy as np

from antisync.kernels import cpu
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "ieee14_grid.yaml"


def _rate(overrides: list[str], count: int) -> tuple[float, float]:
    job = make_job(load_config(CONFIG, ["edges=['1->2']", "realizations=10", *overrides]))
    s = job.model
    params = cpu.ModelParams(
        s.freqs[None, :], s.cos_lag, s.sin_lag, s.inertia, s.damping, s.criterion, s.targets[:1]
    )
    args = (
        1,
        0,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        np.zeros((0, job.csr.weights.size)),
    )
    kw = dict(dt=0.02, max_steps=10000, integrator="rk4", threads=1)
    cpu.simulate_model(*args[:2], 8, *args[3:], params, **kw)  # compile or load the cache
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        sim = cpu.simulate_model(*args, params, **kw)
        best = min(best, time.perf_counter() - t)
    steps = float(sim.steps0.sum())
    return steps / best, steps / count


def main() -> None:
    print(f"{platform.processor() or platform.machine()}, python {platform.python_version()}, 1 thread")
    freq, n_freq = _rate([], 1000)
    order, n_order = _rate(["sync.criterion=order-parameter", "dynamics.threshold=0.9"], 1000)
    print(f"frequency criterion:       {freq / 1e6:.3f} M steps/s ({n_freq:.0f} steps per trajectory)")
    print(f"order-parameter criterion: {order / 1e6:.3f} M steps/s ({n_order:.0f} steps per trajectory)")
    print(
        f"per-step cost of the frequency criterion's dense check: {order / freq:.2f}x the order parameter's"
    )


if __name__ == "__main__":
    main()
