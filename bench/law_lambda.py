"""Every link's Lambda^KM of the lollipop under three models, side by side: the paper's
Kuramoto model (the built-in kernels), Stuart-Landau oscillators and Kuramoto with a second
harmonic (laws, docs/laws.md); writes docs/figures/law_lambda.png and prints the table.

    python bench/law_lambda.py [--realizations 4000] [--out docs/figures/law_lambda.png]

Each run: central-difference (the derivative d<F>/dbeta, dbeta 0.02), RK4 at dt 0.01, the same
seed, so the three models start from the same random phases (Stuart-Landau from the unit circle
at those phases).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import antisync  # noqa: E402

MODELS = {
    "Kuramoto (the paper's)": None,
    "Stuart-Landau": {"law": "stuart-landau"},
    "second harmonic (a = 0.25)": {"law": "second-harmonic"},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=4000)
    ap.add_argument("--out", default="docs/figures/law_lambda.png")
    args = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, model in MODELS.items():
            config = {
                "graph": {"kind": "lollipop", "nodes": 6, "path": 3},
                "betas": [],
                "realizations": args.realizations,
                "lambda": {"method": "central-difference", "dbeta": 0.02},
                "dynamics": {"integrator": "rk4", "dt": 0.01},
                **({"model": model} if model else {}),
            }
            t = time.perf_counter()
            res = antisync.run(config, output=Path(folder) / f"{len(rows)}.h5")
            recs = [r for r in res.records if r.get("lambda_km") is not None]
            rows[name] = {r["edge"]: (r["lambda_km"], r["lambda_km_se"]) for r in recs}
            print(f"{name}: {time.perf_counter() - t:.1f} s")
    edges = list(next(iter(rows.values())))
    print("| link | " + " | ".join(rows) + " |")
    print("|---|" + "---|" * len(rows))
    for e in edges:
        print(f"| {e} | " + " | ".join(f"{rows[m][e][0]:+.3f} +- {rows[m][e][1]:.3f}" for m in rows) + " |")
    fig, ax = plt.subplots(figsize=(8, 3.6))
    x = np.arange(len(edges))
    width = 0.8 / len(rows)
    for k, (name, vals) in enumerate(rows.items()):
        lam = [vals[e][0] for e in edges]
        se = [2 * vals[e][1] for e in edges]
        ax.bar(x + (k - 1) * width, lam, width, yerr=se, label=name, capsize=2)
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xticks(x, edges, rotation=45)
    ax.set_ylabel(r"$\Lambda^{KM}$ (bars: 2 s.e.)")
    ax.set_title(f"lollipop N = 6: every link, three oscillator models ({args.realizations} realizations)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
