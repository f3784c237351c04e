"""Static indicators of every line of the shipped power grids (antisync/grids/static.py,
docs/power_grids.md): what removing (or weakening) one line does to the locked state.

``python bench/grid_static.py`` prints, as markdown, for configs/ieee14_grid.yaml (K = 2.5 per
line, inertia 1, damping 1; bus i is node i) and configs/ieee118_uniform.yaml (K = 10 per line in
the edge list, inertia 1 at the 54 generator buses and 0 at the load buses, damping 1):

- the intact grid's margin, lambda2, largest load and r*, and the wall time of the table;
- every line (IEEE 14) or the ``--top`` lines (IEEE 118) ranked by the change of the margin,
  most harmful first (ties, within 1e-9, by the rise of the largest relative load);
- the static Braess candidates and the troublemakers, by the margin and by lambda2.

Bridges (lines whose removal islands the grid) are skipped with ``--beta 1`` and listed.
numpy's BLAS runs on one thread unless ``--blas-threads`` says otherwise: the matrices are small
(at most 172 x 172) and a threaded BLAS on a busy two-core machine (load average 5) was measured
about 150 times slower per line (2.8 s against 0.015 s for one IEEE 118 locked state).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--beta", type=float, default=1.0, help="1 removes each line (default)")
    ap.add_argument("--top", type=int, default=10, help="IEEE 118 rows to print (default 10)")
    ap.add_argument("--blas-threads", type=int, default=1, help="BLAS threads (default 1)")
    args = ap.parse_args(argv)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(args.blas_threads)  # before numpy is imported
    sys.path.insert(0, str(ROOT))
    from antisync.grids.load import load_grid_config
    from antisync.grids.static import format_table, static_table

    for cfg, top in (("ieee14_grid.yaml", None), ("ieee118_uniform.yaml", args.top)):
        grid = load_grid_config(ROOT / "configs" / cfg)
        table = static_table(grid, beta=args.beta)
        print(f"## {grid.name}: {len(grid.labels)} buses, beta = {args.beta:g}\n")
        print(format_table(table, top=top, by="d_margin"))
        print()
        if top is None:  # the margin of IEEE 14 saturates (docs/power_grids.md): lambda2 too
            print(format_table(table, top=5, by="d_lambda2").split("\n", 2)[2])
            print()
        for by in ("d_margin", "d_lambda2"):
            braess = ", ".join(r.label for r in table.braess_lines(margin=by)) or "none"
            worst = table.troublemakers(5, by=by)
            trouble = ", ".join(f"{r.label} ({getattr(r, by):+.4f})" for r in worst) or "none"
            print(f"- by {by}: static Braess candidates: {braess}")
            print(f"- by {by}: troublemakers: {trouble}")
        print(f"- wall time of the table: {table.seconds:.2f} s\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
