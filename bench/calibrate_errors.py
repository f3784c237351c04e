"""Calibration harness for Lambda's error bars (issue 18): do the reported 95% intervals cover?

A *pool* is one long run that keeps every realization's Lambda estimate (``keep_pairs``),
cached as ``<cache>/<name>.npz``. Runs of ``n`` realizations are drawn from the pool with
replacement, so the truth each interval must hold is exactly the pool's mean, and as many runs
as wanted can be drawn (a pool of 2,000,000 holds the rare values that carry the variance,
|Lambda| > 50 at probability ~1e-4, a few hundred times). Each run is reduced to block records
and signed tail counts by the package's own functions, and its interval computed as the
summary computes it:

- ``batch-means``: ``mean +- 1.96 se`` with ``se = max(naive, batch-means)`` (before issue 18);
- ``reported``: what ``antisync summary`` reports now, ``estimators.lambda_ci`` (a Pareto model
  of the tail pooled over the job's links, united with the batch-means interval).

Coverage per link is the fraction of runs whose interval holds the pool mean (its sd is
``sqrt(0.95 * 0.05 / runs)``, 0.011 at 400 runs). Links whose every value is 0 are skipped.

Usage::

    python bench/calibrate_errors.py lollipop --realizations 2000000 --sizes 2000 20000
    python bench/calibrate_errors.py barbell --graph "{kind: barbell, m1: 3}" --realizations 1000000
    python bench/calibrate_errors.py swing --method adjoint-hybrid --realizations 200000 \
        --model "{frequencies: [0.3, -0.1, -0.15, 0.2, -0.1, -0.15], inertia: [1, 0, 0, 0.5, 0, 2]}" \
        --sync "{criterion: frequency, tolerance: 0.002}"

Results and the chosen method: bench/RESULTS.md ("Calibration of Lambda's error bars").
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync.stats import estimators  # noqa: E402

Z95 = estimators.Z95
LOLLIPOP = "{kind: lollipop, nodes: 6, path: 3}"


def kept_lambdas(
    graph: str,
    realizations: int,
    seed: int,
    method: str,
    integrator: str,
    dt: float,
    model: str = "",
    sync: str = "",
):
    """Every realization's Lambda estimate per link: ``(edges, values (m, E))`` for the
    realizations whose tau0 and every tau(beta) synchronized."""
    import h5py
    import yaml

    import antisync

    out = Path(tempfile.mkdtemp()) / "calibrate.h5"
    cfg = {
        "graph": yaml.safe_load(graph),
        "edges": "all",
        "betas": [],
        "seed": seed,
        "keep_pairs": realizations,
        "lambda": {"method": method},
        "dynamics": {"integrator": integrator, "dt": dt, "t_max": 400.0},
    }
    if model:
        cfg["model"] = yaml.safe_load(model)
    if sync:
        cfg["sync"] = yaml.safe_load(sync)
    antisync.run(cfg, realizations=realizations, output=out, progress=True)
    with h5py.File(out, "r") as f:
        (g,) = f["jobs"].values()
        edges = json.loads(g.attrs["edges"])
        lam = g["kept/lambda"][...]
        ok = (g["kept/status0"][...] == 0)[:, None] & np.isfinite(lam)
    return edges, lam[ok.all(axis=1)]


def pool(args) -> tuple[list[str], np.ndarray, float]:
    """The cached pool ``(edges, values, dbeta)``, made on first use."""
    path = Path(args.cache) / f"{args.name}.npz"
    if not path.exists():
        t = time.perf_counter()
        edges, values = kept_lambdas(
            args.graph,
            args.realizations,
            args.seed,
            args.method,
            args.integrator,
            args.dt,
            args.model,
            args.sync,
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, edges=np.array(edges, dtype=object), lam=values, ok=np.ones(values.shape, bool))
        print(
            f"# pool {args.name}: {len(values):,} realizations in {time.perf_counter() - t:.0f} s", flush=True
        )
    d = np.load(path, allow_pickle=True)
    values = d["lam"][d["ok"].all(axis=1)]
    keep = ~np.all(values == 0, axis=0)
    return list(d["edges"][keep]), values[:, keep], 0.01


def intervals(run: np.ndarray, dbeta: float, estimator: str) -> dict[str, np.ndarray]:
    """``{method: (E, 2) array of (low, high)}`` for one run, computed as the summary does."""
    n = run.shape[0]
    block = max(100, -(-n // 1000))  # the config's automatic block size
    rec, tail = estimators.lambda_block_records(
        run, np.zeros(run.shape, np.int8), np.zeros(run.shape, bool), block
    )
    pooled, links = estimators.pooled_tail(tail)
    out = {"batch-means": np.empty((run.shape[1], 2)), "reported": np.empty((run.shape[1], 2))}
    for e in range(run.shape[1]):
        est = estimators.summarize_lambda(rec[:, e, :])["lambda"]
        low, high, _, _ = estimators.lambda_ci(
            est, rec[:, e, :], tail[e], pooled, dbeta, estimator=estimator, links=links
        )
        out["batch-means"][e] = est.mean - Z95 * est.se, est.mean + Z95 * est.se
        out["reported"][e] = low, high
    return out


def coverage(
    values: np.ndarray, dbeta: float, n: int, runs: int, seed: int, estimator: str = "finite-difference"
) -> dict[str, np.ndarray]:
    """Per method, per link: the fraction of ``runs`` runs of ``n`` whose interval holds the pool mean."""
    truth = values.mean(axis=0)
    rng = np.random.default_rng(seed)
    hits: dict[str, np.ndarray] = {}
    for _ in range(runs):
        run = values[rng.integers(0, values.shape[0], n)]
        for name, iv in intervals(run, dbeta, estimator).items():
            hits.setdefault(name, np.zeros(values.shape[1]))
            hits[name] += (iv[:, 0] <= truth) & (truth <= iv[:, 1])
    return {k: v / runs for k, v in hits.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name", help="pool name (cache file <cache>/<name>.npz)")
    p.add_argument("--graph", default=LOLLIPOP)
    p.add_argument("--realizations", type=int, default=2_000_000, help="pool size")
    p.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000])
    p.add_argument("--runs", type=int, default=400)
    p.add_argument("--seed", type=int, default=1001, help="pool seed")
    p.add_argument("--draw-seed", type=int, default=7, help="seed of the runs drawn from the pool")
    p.add_argument("--method", default="finite-difference")
    p.add_argument("--integrator", default="rk4")
    p.add_argument("--dt", type=float, default=0.04)
    p.add_argument("--model", default="", help="a model: section (YAML), docs/models.md")
    p.add_argument("--sync", default="", help="a sync: section (YAML)")
    p.add_argument("--cache", default=str(Path(__file__).resolve().parent / ".cache"))
    args = p.parse_args()
    edges, values, dbeta = pool(args)
    print(
        f"# {args.name} ({args.graph}): pool of {len(values):,}, "
        f"{args.method}, {args.integrator} dt {args.dt}"
    )
    for n in args.sizes:
        t = time.perf_counter()
        cov = coverage(values, dbeta, n, args.runs, args.draw_seed, args.method)
        print(f"\n## runs of {n:,} realizations ({args.runs} runs, {time.perf_counter() - t:.0f} s)\n")
        print("| link | " + " | ".join(cov) + " |")
        print("|---|" + "---:|" * len(cov))
        for e, label in enumerate(edges):
            print(f"| {label} | " + " | ".join(f"{c[e]:.3f}" for c in cov.values()) + " |")
        print("| all | " + " | ".join(f"{c.mean():.3f}" for c in cov.values()) + " |")
        print(
            "| range | " + " | ".join(f"{c.min():.3f}-{c.max():.3f}" for c in cov.values()) + " |", flush=True
        )


if __name__ == "__main__":
    main()
