"""The static table of a large grid: today's continuation from P = 0 against the warm start from
the intact grid's locked state, the same lines, the same run.

    python bench/bench_static.py [--config configs/activsg2000_grid.yaml] [--old-lines 100]
                                 [--blas-threads 1]

:func:`antisync.grids.static.static_table` of the config's grid (bridges skipped, every line
removed):

- ``old``: ``warm=False``, each line's locked state by Newton continuation from ``P = 0`` and its
  margins by shift-invert Arnoldi from scratch (the path before the warm start), on
  ``--old-lines`` lines spread evenly over the table (0: every line; ACTIVSg2000's 2,210 take
  about 10 minutes on one thread);
- ``new``: the default, Newton from the intact state (:mod:`antisync.physics.warm`), on every line,
  and on the old path's lines alone (the same lines' ratio).

Printed as markdown: the machine (CPU model, cores, load average), seconds per line, the ratio,
the old path's projection to every line, the lines that fell back to the continuation, and the
largest difference of each indicator between the two paths on their common lines (relative for
the state's indicators, ``d_*`` relative to the indicator they change). numpy's BLAS runs on
``--blas-threads`` threads (set before numpy is imported).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KEYS = ("margin", "max_flow", "max_load", "r", "lambda2")


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            return next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def differences(old, new) -> dict:
    """The largest difference of each indicator over the rows both tables have (by line)."""
    rows = {r.line: r for r in new}
    worst = {}
    for a in old:
        b = rows[a.line]
        assert (a.exists, a.stable) == (b.exists, b.stable), a.line
        for key in KEYS:
            x, y = getattr(a, key), getattr(b, key)
            if math.isfinite(x) and math.isfinite(y):
                worst[key] = max(worst.get(key, 0.0), abs(x - y) / abs(x) if x != y else 0.0)
            dx, dy = getattr(a, f"d_{key}"), getattr(b, f"d_{key}")
            if math.isfinite(dx) and math.isfinite(dy):
                worst[f"d_{key}"] = max(worst.get(f"d_{key}", 0.0), abs(dx - dy) / abs(x))
    return worst


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "activsg2000_grid.yaml"))
    ap.add_argument("--old-lines", type=int, default=100, help="lines for the old path (0: all)")
    ap.add_argument("--blas-threads", type=int, default=1)
    ap.add_argument(
        "--dense-lines", type=int, default=0, help="lines checked by dense eigenvalues (about 20 s each)"
    )
    args = ap.parse_args(argv)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(args.blas_threads)  # before numpy is imported
    sys.path.insert(0, str(ROOT))
    import numpy as np
    import scipy

    from antisync.grids.lines import grid_bridges, lines_of
    from antisync.grids.load import load_grid_config
    from antisync.grids.static import static_table

    grid = load_grid_config(Path(args.config))
    bridges = grid_bridges(grid.omega)
    every = [ab for ab in lines_of(grid.omega, grid.labels, None) if ab not in bridges]
    labels = grid.labels
    step = 1 if args.old_lines <= 0 else max(1, len(every) // args.old_lines)
    sample = every[::step][: args.old_lines or None]
    sample_lines = [(labels[a], labels[b]) for a, b in sample]
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(
        f"{cpu_model()}, os.cpu_count() = {os.cpu_count()}, {cores} usable, load average "
        f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}; python {platform.python_version()}, "
        f"numpy {np.__version__}, scipy {scipy.__version__}, BLAS threads {args.blas_threads}"
    )
    removed = f"{len(every)} lines removed ({len(bridges)} bridges skipped)"
    print(f"\n{grid.name}: {len(labels)} buses, {removed}\n")
    print("| path | lines | seconds | s / line | CPU s | fell back |")
    print("|---|---|---|---|---|---|")

    def run(name, lines, **kw):
        t, c = time.perf_counter(), time.process_time()
        table = static_table(grid, lines=lines, **kw)
        t, c = time.perf_counter() - t, time.process_time() - c
        fell = "-" if kw.get("warm") is False else len(table.continued)
        print(f"| {name} | {len(table)} | {t:.2f} | {t / len(table):.4f} | {c:.2f} | {fell} |")
        return table, t

    old, t_old = run("old (continuation)", sample_lines, warm=False)
    same, t_same = run("new, old's lines", sample_lines)
    first, t_new = run("new", None)
    per_old = t_old / len(old)
    print(f"\nold path projected to all {len(every)} lines: {per_old * len(every):.0f} s")
    print(f"same lines: {t_old / t_same:.1f}x")
    print(f"all lines, new: {t_new:.1f} s, {per_old * len(every) / t_new:.1f}x the projection")
    if first.continued:
        print(f"fell back to the continuation: {', '.join(f'{u}-{v}' for u, v in first.continued)}")
    for name, table in (("new, old's lines", same), ("new, all lines", first)):
        worst = differences(old, table)
        print(f"\nlargest differences, old vs {name}, {len(old)} lines:")
        print("; ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    worst = sorted(first, key=lambda r: r.d_margin if math.isfinite(r.d_margin) else math.inf)[:4]
    print("\nlargest margin drops: " + ", ".join(f"{r.label} ({r.d_margin:+.4f})" for r in worst))
    if args.dense_lines > 0:
        dense_check(grid, [r.nodes for r in worst[:1]] + sample[: args.dense_lines - 1], first)
    return 0


def dense_check(grid, lines, table) -> None:
    """The warm state of each line, its margin and lambda2 from every eigenvalue (numpy's dense
    eigvals of the linearization and the Jacobian), against the table's."""
    import numpy as np

    from antisync.physics.locked import jacobian, linearization, locked_state
    from antisync.physics.warm import LineChanges

    w = grid.omega
    intact = locked_state(w, grid.p, 0.0, grid.inertia, grid.damping)
    changes = LineChanges(w, grid.p, intact, 0.0, grid.inertia, grid.damping)
    rows = {r.nodes: r for r in table}
    print("\n| line | margin, dense | rel. diff | lambda2, dense | rel. diff | residual |")
    print("|---|---|---|---|---|---|")
    for a, b in lines:
        st = changes.state(a, b, 0.0).state
        cut = w.copy()
        cut[a, b] = cut[b, a] = 0.0
        jac = jacobian(st.phi, cut, 0.0)
        residual = np.abs(
            grid.p - st.nu + (cut * np.sin(st.phi[None, :] - st.phi[:, None])).sum(axis=1)
        ).max()
        out = []
        for mat in (linearization(jac, grid.inertia, grid.damping), jac):
            ev = np.linalg.eigvals(mat)
            ev = np.delete(ev, np.argmin(np.abs(ev)))
            out.append(-float(np.max(ev.real)))
        row = rows[(a, b)]
        print(
            f"| {row.label} | {out[0]:.12f} | {abs(row.margin - out[0]) / out[0]:.1e} | {out[1]:.12f} "
            f"| {abs(row.lambda2 - out[1]) / out[1]:.1e} | {residual:.1e} |"
        )


if __name__ == "__main__":
    raise SystemExit(main())
