"""Rodas4 per trajectory on a large grid against scipy's Radau with the analytic sparse
Jacobian, on the same starts (issue 62: 2,000 to 10,000 buses).

    python bench/bench_rodas_large.py [--config configs/activsg2000_grid.yaml] [--starts 4]
                                      [--radau-starts 2] [--width 1.0]
    python bench/bench_rodas_large.py --accuracy [--starts 2]

The config's undamaged grid from starts ``0 .. starts-1`` within ``--width`` rad of its operating
point (``model.start: {around: locked, width: W}``, as the random-start removal of
docs/power_grids.md), until every frequency deviation is below the config's tolerance or
``t_max``. Rodas4 (the config's ``rtol``/``atol``) times each start alone on one thread; Radau
(:func:`bench_implicit._radau`: ``solve_ivp(method="Radau")``, the sparse Jacobian, the criterion
as an event, ``rtol = atol = 1e-6``) runs the first ``--radau-starts`` starts in this process.
Printed: the CPU seconds per trajectory of each and their ratio on the same starts, and the
agreement of statuses and tau. RK4 is not run: its stable step on these grids is 1e-5 s or less
(docs/power_grids.md).

``--accuracy``: the two at equal accuracy rather than at equal tolerance (a tolerance is not an
error: each method's error constant is its own). Each start's tau by Rodas4 at ``rtol = atol =
1e-9`` is the reference; Rodas4 at ``1e-5, 1e-6, 1e-7`` and Radau at ``1e-6, 1e-7, 1e-8`` are
timed (CPU seconds, one thread) and their tau's error against it printed, start by start.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from bench_implicit import _radau

from antisync.execution.dispatch import job_model_params
from antisync.kernels import implicit
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job
from antisync.status import SYNCED

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "activsg2000_grid.yaml")
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--radau-starts", type=int, default=2)
    ap.add_argument("--width", type=float, default=1.0)
    ap.add_argument("--accuracy", action="store_true", help="work against tau's error (module docstring)")
    args = ap.parse_args()

    cfg = load_config(args.config, [f"model.start={{around: locked, width: {args.width}}}"])
    job = make_job(cfg)
    dyn = cfg.dynamics
    rtol, atol = dyn.tolerances
    plan = implicit.factor_plan(job.csr.indptr, job.csr.indices)
    empty = np.zeros((0, job.csr.weights.size))
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, {args.config.name}, "
        f"N = {len(job.nodes)}, {args.starts} starts within {args.width} rad, "
        f"rodas4 rtol {rtol} atol {atol}, t_max {dyn.t_max}"
    )

    def one(k, tols=(rtol, atol)):
        ks = np.array([k], dtype=np.uint64)
        params = job_model_params(job, ks, job.model.targets[:1])
        net = (cfg.seed, 0, 1, job.csr.indptr, job.csr.indices, job.csr.weights, empty, params)
        return implicit.simulate_model(
            *net,
            dt=dyn.dt,
            max_steps=dyn.max_steps,
            rtol=tols[0],
            atol=tols[1],
            threads=1,
            plan=plan,
            realizations=ks,
        )

    one(0)  # compile (or load the cache)
    if args.accuracy:
        _accuracy(job, cfg, one, args.starts)
        return
    rod_t, rod_status, rod_tau = [], [], []
    for k in range(args.starts):
        c0 = time.process_time()
        res = one(k)
        rod_t.append(time.process_time() - c0)
        rod_status.append(int(res.status0[0]))
        rod_tau.append(float((res.steps0[0] - 1 + res.frac0[0]) * dyn.dt))
    rod_t = np.array(rod_t)
    print(f"rodas4: CPU s per trajectory {rod_t.mean():.2f} (min {rod_t.min():.2f}, max {rod_t.max():.2f})")
    print(f"  statuses {rod_status}, tau {[round(t, 4) for t in rod_tau]}")
    if not args.radau_starts:
        return
    ks = np.arange(args.radau_starts, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets[:1])
    rad = _radau(job, params, ks, cfg.seed, dyn.dt, dyn.t_max, 1e-6, 1e-6)
    rad_t = np.array([r[3] for r in rad])
    same = sum(r[0] == s for r, s in zip(rad, rod_status, strict=False))
    both = [(r[1], t) for r, s, t in zip(rad, rod_status, rod_tau, strict=False) if r[0] == s == SYNCED]
    worst = max((abs(a - b) / b for a, b in both), default=float("nan"))
    print(f"radau: CPU s per trajectory {rad_t.mean():.2f}, steps {[r[2] for r in rad]}")
    print(f"  statuses equal to rodas4 {same}/{len(rad)}, largest relative tau difference {worst:.3g}")
    ratio = rad_t.mean() / rod_t[: len(rad)].mean()
    print(f"radau / rodas4 CPU per trajectory on starts 0..{len(rad) - 1}: {ratio:.1f}x")


def _accuracy(job, cfg, one, starts: int) -> None:
    """Rodas4 and Radau at equal accuracy (module docstring): a row per method, tolerance and
    start."""
    dyn = cfg.dynamics

    def rodas(k, tol):
        c0 = time.process_time()
        res = one(k, (tol, tol))
        cpu = time.process_time() - c0
        return int(res.status0[0]), float((res.steps0[0] - 1 + res.frac0[0]) * dyn.dt), cpu

    print("| start | method | rtol = atol | tau (s) | tau's error (s) | CPU s |")
    print("|---|---|---|---|---|---|")
    for k in range(starts):
        status, ref, cpu = rodas(k, 1e-9)
        print(f"| {k} | rodas4 (reference) | 1e-09 | {ref:.4f} | | {cpu:.2f} |")
        if status != SYNCED:
            continue
        for tol in (1e-5, 1e-6, 1e-7):
            _, tau, cpu = rodas(k, tol)
            print(f"| {k} | rodas4 | {tol:g} | {tau:.4f} | {abs(tau - ref):.3g} | {cpu:.2f} |")
        ks = np.array([k], dtype=np.uint64)
        params = job_model_params(job, ks, job.model.targets[:1])
        for tol in (1e-6, 1e-7, 1e-8):
            ((_, tau, _, cpu),) = _radau(job, params, ks, cfg.seed, dyn.dt, dyn.t_max, tol, tol)
            print(f"| {k} | radau | {tol:g} | {tau:.4f} | {abs(tau - ref):.3g} | {cpu:.2f} |")


if __name__ == "__main__":
    main()
