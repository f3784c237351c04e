"""IEEE 39 side by side (docs/power_grids.md): every line's dynamic removal response, its
small-damage Lambda and the static indicators, their rank correlations and sign agreement, and
a drawing of the grid with the lines coloured by the removal response.

    antisync grid configs/ieee39_grid.yaml --removal --realizations 400 --seed 1 \\
        --out results/ieee39_removal.json                     # the dynamic table
    antisync run configs/ieee39_grid.yaml --realizations 200  # Lambda of every directed line
    python bench/grid_removal.py results/ieee39_removal.json --lambda results/ieee39_grid.h5 \\
        --figure docs/figures/ieee39_removal.png --overwrite

Per line ``i-j``: the removal's ``d P_sync`` (McNemar's exact p), ``d tau`` on the pairs that
synchronize both times and the mean ratio ``F_1 = tau0 / tau`` (``> 1``: faster after the
removal); ``Lambda_line = Lambda_{i->j} + Lambda_{j->i}`` (the first-order response of ``F`` to
damaging both directions, ``> 0``: antifragile), and the static ``d margin``, ``d lambda2``,
``d max load`` of the locked state (antisync/grids/static.py). Spearman's rank correlations between
them, and the share of lines whose signs agree, where both are resolved from zero. The table and
the figure are the package's (antisync/report/removal.py: ``side_by_side_report``,
``removal_figure``); ``antisync grid CONFIG --removal --figure X.png`` draws the same figure.
Several JSON files are parts of one run split by ``--lines`` (same config, seed, realizations
and beta): they are merged first, the calls made again over all their lines (``merge_docs``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# one BLAS thread, before numpy is imported: the static table's small eigenproblems ran ~40x
# slower with two threads on this busy two-core machine (bench/grid_static.py says the same)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "removal",
        type=Path,
        nargs="+",
        help="JSON of antisync grid --removal; several: parts with disjoint --lines, merged (merge_docs)",
    )
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "ieee39_grid.yaml")
    ap.add_argument("--lambda", dest="lam", type=Path, help="HDF5 of antisync run (Lambda per directed line)")
    ap.add_argument("--figure", type=Path, help="PNG of the grid coloured by the removal response")
    ap.add_argument("--by", default="speedup", choices=("speedup", "psync"), help="the figure's colour")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --figure")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import antisync
    from antisync.errors import AntisyncError
    from antisync.grids.load import load_grid_config
    from antisync.grids.static import static_table
    from antisync.report.removal import (
        lambda_by_line,
        merge_docs,
        removal_doc,
        removal_figure,
        side_by_side_report,
    )

    try:
        doc = removal_doc(args.removal[0]) if len(args.removal) == 1 else merge_docs(args.removal)
        t0 = time.perf_counter()
        table = static_table(load_grid_config(args.config), beta=float(doc["summary"]["beta"]))
        t_static = time.perf_counter() - t0
        lam = lambda_by_line(antisync.load(args.lam).records) if args.lam else None
        print(side_by_side_report(doc, table, lam, seconds_static=t_static))
        if args.figure:
            path = removal_figure(doc, args.config, args.figure, by=args.by, overwrite=args.overwrite)
            print(f"wrote {path}")
    except AntisyncError as exc:  # parts that do not merge, a bad file: one line, as antisync's CLI
        print(f"grid_removal.py: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
