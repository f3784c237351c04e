"""The engineer's N-1 on a stiff grid: a trip by Rodas4 against RK4 at the stability-bound step,
the same contingencies, the same fault.

    python bench/bench_trip.py [--config configs/activsg2000_grid.yaml] [--rows 32]
                               [--t-clear 0.1] [--rtol 1e-4 1e-6] [--threads 2]

The first ``--rows`` rows of the config's official contingency table (``<prefix>_contingencies.txt``,
rows that open a bridge whole skipped) from the intact grid's operating point
(:func:`antisync.grids.trip.operating_point`), a bolted fault of ``--t-clear`` seconds at each
line's first bus, then the trip, for 20 s (the CLI's default ``--t-max``):

- ``rk4``: :func:`antisync.grids.trip.trip_lines` at the config's ``dt`` (0.0005 s on
  ACTIVSg2000: the largest Laplacian eigenvalue of K is 4,983), the trips one per thread;
- ``rodas4``: the same with ``integrator="rodas4"`` at each ``--rtol`` (``atol`` the same).

Each is timed after a warm-up call (compilation excluded), on ``--threads`` threads; the post-trip
static states are left out (they are the same work for both). Accuracy against RK4, per trip:
equal settling verdicts, the largest differences of the maximum frequency deviation, the
maximum angle difference and the time to settle.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from antisync.grids.load import load_grid_config
from antisync.grids.trip import _integrate, operating_point, plan_trips, read_contingencies
from antisync.plan.config import load_config


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/activsg2000_grid.yaml")
    ap.add_argument("--rows", type=int, default=32)
    ap.add_argument("--t-clear", type=float, default=0.1)
    ap.add_argument("--rtol", type=float, nargs="+", default=[1e-4, 1e-6])
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()
    config = Path(args.config)
    grid = load_grid_config(config)
    table = read_contingencies(config.with_name(config.stem + "_contingencies.txt"), grid)
    lines, _, shares, _ = plan_trips(grid, None, table[: args.rows])
    theta0 = operating_point(grid)
    common = dict(
        t_max=20.0,
        dt=float(load_config(config).dynamics.dt),
        tolerance=1e-3,
        theta0=theta0,
        threads=args.threads,
    )
    methods = {"rk4": {"integrator": "rk4"}}
    methods.update({f"rodas4 rtol {r:g}": {"integrator": "rodas4", "rtol": r, "atol": r} for r in args.rtol})
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores; {grid.name}: "
        f"{len(grid.labels)} buses, {len(lines)} trips, fault {args.t_clear:g} s, dt {common['dt']:g}"
    )
    out = {}
    seconds = {}
    for name, kw in methods.items():
        _integrate(grid, lines[:2], args.t_clear, shares[:2], **common, **kw)  # compile
        cpu0, t0 = time.process_time(), time.perf_counter()
        out[name], _, _ = _integrate(grid, lines, args.t_clear, shares, **common, **kw)
        seconds[name] = (time.perf_counter() - t0, time.process_time() - cpu0)
    rk = out["rk4"]
    print(
        "| integrator | wall (s) | CPU (s) | CPU per trip (s) | RK4 / it (CPU) | verdicts equal "
        "| max d max-freq (rad/s) | max d max-angle (rad) | max d settle (s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, rows in out.items():
        wall, cpu = seconds[name]
        same = int((np.isfinite(rows[:, 0]) == np.isfinite(rk[:, 0])).sum())
        both = np.isfinite(rows[:, 0]) & np.isfinite(rk[:, 0])
        d = np.abs(rows - rk)
        settle = float(d[both, 0].max()) if both.any() else float("nan")
        print(
            f"| {name} | {wall:.1f} | {cpu:.1f} | {cpu / len(lines):.3f} | {seconds['rk4'][1] / cpu:.1f}x "
            f"| {same}/{len(lines)} | {d[:, 1].max():.2e} | {d[:, 2].max():.2e} | {settle:.3f} |"
        )


if __name__ == "__main__":
    main()
