"""A design at its defaults against the shipped config: the karate club's spectral baseline and
tau design at ``lower: 0`` (no key but the objective and budget) beside
``configs/karate_design.yaml`` (``lower: 0.05``, ``t_max: 400``), on the same fresh starts.

    python bench/design_defaults.py [--evaluate 20000] [--threads 2]

1. the normalized-Laplacian lambda_2 of the ``lambda2`` baseline at ``lower: 0`` and ``0.05``
   (:func:`antisync.optimize.spectral.design_normalized_lambda2`);
2. ``antisync.design`` of the mapping a new user writes (docs/design.md: ``objective: tau``,
   ``budget: 78``, RK4 ``dt = 0.04``, nothing else) and of ``configs/karate_design.yaml``;
3. both designed weights integrated on the same ``--evaluate`` fresh starts of the shipped
   config's problem (its seed's ``fresh`` stream, ``t_max = 400``), paired: the mean tau of each
   and the difference with its standard error.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

import antisync
from antisync.optimize.config import load_design_config
from antisync.optimize.descent import stream_seed
from antisync.optimize.ensemble import evaluate
from antisync.optimize.spectral import design_normalized_lambda2, normalized_lambda2
from antisync.status import SYNCED

ROOT = Path(__file__).resolve().parent.parent
NEW_USER = {
    "name": "k",
    "graph": {"kind": "networkx", "generator": "karate_club_graph"},
    "design": {"objective": "tau", "budget": 78},
    "dynamics": {"integrator": "rk4", "dt": 0.04},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--evaluate", type=int, default=20000)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    args = ap.parse_args()
    cfg, spec = load_design_config(ROOT / "configs" / "karate_design.yaml")
    problem = spec.problem(cfg)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, threads {args.threads}")
    n, links = problem.n_nodes, np.asarray(problem.links)
    for lower in (0.0, 0.05):
        budget = type(problem.budget).of(78, len(links), lo=lower)
        t0 = time.perf_counter()
        result = design_normalized_lambda2(n, links, budget)
        uniform = normalized_lambda2(n, links, budget.uniform())[0]
        print(
            f"lambda2 baseline, lower {lower:g}: normalized lambda_2 {result.value:.4f} (uniform "
            f"{uniform:.4f}), smallest weight {result.x.min():.3g}, {time.perf_counter() - t0:.1f} s"
        )
    designed = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, source in (
            ("defaults (lower 0)", NEW_USER),
            ("karate_design.yaml", ROOT / "configs" / "karate_design.yaml"),
        ):
            t0 = time.perf_counter()
            rec = antisync.design(source, output=Path(tmp) / f"{len(designed)}.h5", log=lambda _: None)
            rows = {r["design"]: r for r in rec["verification"]["rows"]}
            designed[name] = rec["baselines"]["designed"]
            print(
                f"{name}: {time.perf_counter() - t0:.1f} s, its own verification: designed "
                f"{rows['designed']['mean_tau']:.3f} +- {rows['designed']['se']:.3f}, lambda2 "
                f"{rows['lambda2']['mean_tau']:.3f}, uniform {rows['uniform']['mean_tau']:.3f} "
                f"({rec['reason']})"
            )
    ks = np.arange(args.evaluate, dtype=np.uint64)
    names = list(designed)
    tau, status = evaluate(
        problem, [designed[k] for k in names], stream_seed(cfg.seed, "fresh"), ks, args.threads
    )
    for i, name in enumerate(names):
        ok = status[i] == SYNCED
        print(
            f"on the same {args.evaluate} fresh starts: {name} <tau> {tau[i].mean():.3f} +- "
            f"{tau[i].std(ddof=1) / np.sqrt(tau.shape[1]):.3f} ({ok.mean():.4f} synchronized)"
        )
    diff = tau[0] - tau[1]
    se = diff.std(ddof=1) / np.sqrt(diff.size)
    print(f"defaults minus karate_design.yaml: {diff.mean():+.4f} +- {se:.4f} ({diff.mean() / se:+.1f} SE)")


if __name__ == "__main__":
    main()
