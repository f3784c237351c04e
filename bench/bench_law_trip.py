"""The engineer's N-1 of a user's law against the built-in swing equation's: the same grid, the
same faults and trips, the same step; what the law's generated trip kernels cost and how close
their table is.

    python bench/bench_law_trip.py [--config configs/ieee39_grid.yaml] [--t-clear 0.1]
                                   [--threads 2] [--repeat 3] [--cct 6-7,23-24] [--dt DT]

The config's grid (:func:`antisync.grids.load.load_grid_config`) and the same grid written as
the law ``power-grid`` (generators with inertia beside first-order buses, tests/test_laws.py's
``POWER_GRID``: ``theta' = nu`` at a generator, ``(P + u) / gamma`` at a load bus): every line
that is not a bridge tripped after a bolted fault of ``--t-clear`` s at its first bus, RK4 at
the config's ``dt``, 20 s after the trip (:func:`antisync.grids.trip._integrate`, each timed
after a warm-up call, the best of ``--repeat``); then the critical clearing times of the
``--cct`` lines by both. The built-in model's operating point pins bus 1's angle; the law's
(found by integration from the in-phase state) is the same up to one angle.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from antisync.grids.lines import grid_bridges, lines_of, parse_lines
from antisync.grids.load import load_grid_config
from antisync.grids.trip import _integrate, critical_clearing, operating_point
from antisync.kernels.core import CRIT_FREQUENCY
from antisync.kernels.shared import per_node
from antisync.laws import Law
from antisync.plan.model import LawSetup

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_laws import POWER_GRID  # noqa: E402  (the tests' law, not copied here)


def law_grid(grid):
    """``grid`` with its dynamics written as the law ``power-grid``."""
    import dataclasses

    n = len(grid.labels)
    mass, damping = per_node(grid.inertia, n), per_node(grid.damping, n)
    generator = (mass > 0).astype(float)
    values = np.vstack([grid.p, np.where(mass > 0, mass, 1.0), damping, generator])
    setup = LawSetup(Law.from_mapping(POWER_GRID), values, 1e-3, CRIT_FREQUENCY, lock_t_max=1000.0)
    return dataclasses.replace(grid, law=setup)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/ieee39_grid.yaml")
    ap.add_argument("--t-clear", type=float, default=0.1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cct", default="6-7,23-24", help="lines whose critical clearing times both find")
    ap.add_argument("--dt", type=float, default=None, help="the RK4 step (default: the config's)")
    args = ap.parse_args()
    from antisync.plan.config import load_config

    dt = args.dt or load_config(args.config).dynamics.dt
    builtin = load_grid_config(args.config)
    law = law_grid(builtin)
    bridges = grid_bridges(builtin.omega)
    lines = [ln for ln in lines_of(builtin.omega, builtin.labels, None) if ln not in bridges]
    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, {os.cpu_count()} cores; {args.threads} threads")
    print(f"{args.config}: {len(builtin.labels)} buses, {len(lines)} lines tripped, RK4 at dt {dt:g}")
    rows, times = {}, {}
    for name, grid in (("built-in", builtin), ("law", law)):
        t = time.perf_counter()
        y0 = operating_point(grid)
        start = time.perf_counter() - t
        kw = dict(t_max=20.0, dt=dt, tolerance=1e-3, theta0=y0, threads=args.threads)
        _integrate(grid, lines[:2], args.t_clear, None, **kw)  # compile
        best = np.inf
        for _ in range(args.repeat):
            t = time.perf_counter()
            rows[name] = _integrate(grid, lines, args.t_clear, None, **kw)[0]
            best = min(best, time.perf_counter() - t)
        times[name] = best
        trips = f"{len(lines)} trips {best:6.2f} s (best of {args.repeat})"
        print(f"{name:9s} operating point {start:6.2f} s; {trips}")
    a, b = rows["built-in"], rows["law"]
    same = np.isfinite(a[:, 0]) == np.isfinite(b[:, 0])
    print(f"law / built-in time: {times['law'] / times['built-in']:.2f}x")
    settle = int(np.isfinite(a[:, 0]).sum())
    print(f"settling verdicts equal: {int(same.sum())} of {len(lines)} ({settle} settle)")
    for k, what in enumerate(("settle time", "max frequency", "max angle")):
        ok = np.isfinite(a[:, k]) & np.isfinite(b[:, k])
        gap = np.abs(a[ok, k] - b[ok, k]) / np.maximum(np.abs(a[ok, k]), 1e-300)
        print(f"  {what}: largest relative gap {gap.max():.2e}")
    picked = parse_lines(args.cct, builtin.labels)
    picked = [lines_of(builtin.omega, builtin.labels, [ln])[0] for ln in picked]
    for name, grid in (("built-in", builtin), ("law", law)):
        t = time.perf_counter()
        cct, again = critical_clearing(grid, picked, cct_max=1.0, t_max=20.0, dt=dt, threads=args.threads)
        found = ", ".join(f"{c:.3f}" for c in cct)
        later = ", ".join("-" if np.isnan(x) else f"{x:.3f}" for x in again)
        print(f"{name:9s} CCT of {args.cct}: {found} s; again at {later} ({time.perf_counter() - t:.1f} s)")


if __name__ == "__main__":
    main()
