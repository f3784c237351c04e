"""How a config's times depend on its explicit step: the intact network's starts at ``dt``,
``dt / 2`` and ``dt / 4``, each level against the next.

    python bench/step_convergence.py configs/ieee39_grid.yaml [--dt 0.0025] [--realizations 400]

For each pair of levels: the starts whose status changes, and the quantiles of ``|tau(dt) -
tau(dt / 2)|`` over the starts synchronized at both (a converged RK4 step shrinks the median
16x a halving; a start whose frequency deviation grazes the tolerance jumps at any step, a step
that is too coarse moves many). The removal's step check (``antisync.grids.removal``) is the
first pair on its first 64 starts.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from antisync.execution.dispatch import job_model_params, model_simulator
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job
from antisync.status import SYNCED


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--dt", type=float, default=None, help="the coarsest step (default: the config's)")
    ap.add_argument("--realizations", type=int, default=400)
    ap.add_argument("--levels", type=int, default=3)
    args = ap.parse_args()
    cfg = load_config(args.config)
    job = make_job(cfg)
    csr, m = job.csr, args.realizations
    params = job_model_params(job, np.arange(m), job.model.targets[:1])
    simulate = model_simulator(cfg.dynamics)
    dt0 = args.dt or cfg.dynamics.dt
    machine = platform.processor() or platform.machine()
    print(f"# {machine}, {os.cpu_count()} cores; {args.config}, {m} starts")
    levels = []
    for level in range(args.levels):
        dt = dt0 / 2**level
        t0 = time.perf_counter()
        sim = simulate(
            cfg.seed, 0, m, csr.indptr, csr.indices, csr.weights, np.zeros((0, csr.weights.size)), params,
            dt=dt, max_steps=int(round(cfg.dynamics.t_max / dt)),
        )  # fmt: skip
        tau = np.where(sim.status0 == SYNCED, (sim.steps0 - 1 + sim.frac0) * dt, np.nan)
        levels.append((dt, sim.status0, tau))
        synced = int((sim.status0 == SYNCED).sum())
        print(f"dt {dt:g}: {synced} of {m} synchronized, {time.perf_counter() - t0:.1f} s")
    for (a, sa, ta), (b, sb, tb) in zip(levels[:-1], levels[1:], strict=True):
        d = np.abs(ta - tb)
        d = d[np.isfinite(d)]
        q50, q90, q99, top = np.quantile(d, [0.5, 0.9, 0.99, 1.0])
        changed = np.flatnonzero(sa != sb)
        jumped = int((d > 0.01 * np.median(tb[np.isfinite(tb)])).sum())
        print(
            f"dt {a:g} against {b:g}: {changed.size} changed status {changed[:8].tolist()}; |d tau| median "
            f"{q50:.2g} s, 90% {q90:.2g}, 99% {q99:.2g}, largest {top:.2g}; "
            f"{jumped} of {d.size} moved by more than 1% of the median"
        )


if __name__ == "__main__":
    main()
