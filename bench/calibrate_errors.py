"""Calibration harness for Lambda's error bars (issue 18): do the reported 95% intervals cover?

One long run keeps every realization's Lambda estimate (``keep_pairs``); it is cut into ``R``
disjoint runs of ``n`` realizations (independent: realization ``k``'s phases depend only on
``(seed, k, node)``). Each run's interval is computed by each candidate method and compared
with the mean of all the *other* runs (leave-one-out, so a run is never judged against
itself). Coverage per link is the fraction of runs whose interval holds that reference.

Methods:

- ``summary``: what ``antisync summary`` reports today, ``mean +- 1.96 lambda_km_se`` with
  ``lambda_km_se = max(naive, batch-means)`` computed from the run's block records exactly
  as the summary computes it;
- ``pooled-tail`` (prototype): the variance with the sample's tail replaced by a Pareto tail,
  the tail index fitted once per run by Hill's estimator on the top 1% of ``|Lambda|`` pooled
  over all links of the graph (the grazing crossings that make the tail are shared by every
  link), extrapolated up to the run's largest ``|Lambda|``; never below the naive error.

Usage::

    python bench/calibrate_errors.py --realizations 200000 --sizes 2000
    python bench/calibrate_errors.py --graph "{kind: barbell, m1: 3}" --realizations 400000

Findings so far are in bench/RESULTS.md ("Calibration of Lambda's error bars").
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync import estimators  # noqa: E402

METHODS = ("summary", "pooled-tail")
Z95 = 1.959964


def kept_lambdas(
    graph: str, realizations: int, seed: int, method: str, integrator: str, dt: float, threads: int | None
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Every realization's Lambda estimate per link: ``(edges, values (m, E), ok (m, E))``."""
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
        "threads": threads,
    }
    antisync.run(cfg, realizations=realizations, output=out, progress=True)
    with h5py.File(out, "r") as f:
        (g,) = f["jobs"].values()
        edges = json.loads(g.attrs["edges"])
        lam = g["kept/lambda"][...]
        ok = (g["kept/status0"][...] == 0)[:, None] & np.isfinite(lam)
    return edges, lam, ok


def summary_se(x: np.ndarray, block: int) -> float:
    """``lambda_km_se`` of a run whose per-realization values are ``x``, as the summary has it."""
    n = x.size
    rec, _ = estimators.lambda_block_records(
        x[:, None], np.zeros((n, 1), np.int8), np.zeros((n, 1), bool), block
    )
    return estimators.summarize_lambda(rec[:, 0, :])["lambda"].se


def pooled_tail_se(x: np.ndarray, run: np.ndarray, top: float = 0.01) -> float:
    """Prototype: the naive variance with the tail beyond ``u`` (the pooled top ``top``
    quantile of ``|Lambda|`` over every link of the run) replaced by a Pareto tail whose index
    is fitted by Hill's estimator on the pooled values, cut at the run's largest value."""
    pooled = np.abs(run).ravel()
    pooled = pooled[pooled > 0]
    u = np.quantile(pooled, 1 - top)
    above = pooled[pooled > u]
    alpha = above.size / np.sum(np.log(above / u))
    cap = pooled.max()
    ax = np.abs(x)
    p = np.mean(ax > u)
    body = np.mean(np.where(ax <= u, x * x, 0.0))
    if abs(alpha - 2.0) < 1e-9:
        tail = p * u * u * (1.0 + 2.0 * math.log(cap / u))
    else:
        tail = p * (u * u + u**alpha * alpha / (2.0 - alpha) * (cap ** (2.0 - alpha) - u ** (2.0 - alpha)))
    var = max(body + tail - x.mean() ** 2, 0.0)
    naive = x.std(ddof=1)
    return max(math.sqrt(var), naive) / math.sqrt(x.size)


def coverage(values: np.ndarray, ok: np.ndarray, n: int) -> dict:
    """Per link and method: coverage of the leave-one-out mean by runs of ``n`` realizations,
    and the spread (sd) of the run means over the median standard error."""
    usable = ok.all(axis=1)  # realizations whose tau0 synchronized (all links share it)
    v = values[usable]
    runs = v.shape[0] // n
    v = v[: runs * n].reshape(runs, n, -1)
    block = max(100, -(-n // 1000))
    means = v.mean(axis=1)
    loo = (means.sum(axis=0) - means) / (runs - 1)
    out: dict = {}
    for e in range(v.shape[2]):
        if np.all(v[:, :, e] == 0):
            continue  # an exactly neutral link (Lambda = 0 in every realization)
        for name in METHODS:
            se = np.array(
                [
                    summary_se(v[r, :, e], block) if name == "summary" else pooled_tail_se(v[r, :, e], v[r])
                    for r in range(runs)
                ]
            )
            hit = np.abs(means[:, e] - loo[:, e]) <= Z95 * se
            out.setdefault(e, {})[name] = {
                "coverage": float(hit.mean()),
                "runs": runs,
                "spread_over_se": float(np.std(means[:, e], ddof=1) / np.median(se)),
            }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--graph", default="{kind: lollipop, nodes: 6, path: 3}")
    p.add_argument("--realizations", type=int, default=200_000)
    p.add_argument("--sizes", type=int, nargs="+", default=[2000])
    p.add_argument("--seed", type=int, default=1001)
    p.add_argument("--method", default="finite-difference")
    p.add_argument("--integrator", default="rk4")
    p.add_argument("--dt", type=float, default=0.04)
    p.add_argument("--threads", type=int, default=None)
    args = p.parse_args()
    t = time.perf_counter()
    edges, lam, ok = kept_lambdas(
        args.graph, args.realizations, args.seed, args.method, args.integrator, args.dt, args.threads
    )
    print(
        f"# {args.graph}: {args.realizations:,} realizations, {args.method}, {args.integrator} "
        f"dt {args.dt}, {time.perf_counter() - t:.0f} s",
        flush=True,
    )
    for n in args.sizes:
        cov = coverage(lam, ok, n)
        runs = next(iter(cov.values()))[METHODS[0]]["runs"]
        print(f"\n## runs of {n:,} realizations ({runs} runs)\n")
        print(
            "| link | "
            + " | ".join(f"{m} coverage" for m in METHODS)
            + " | sd of means / median summary se |"
        )
        print("|---|" + "---:|" * (len(METHODS) + 1))
        for e, c in cov.items():
            print(
                f"| {edges[e]} | "
                + " | ".join(f"{c[m]['coverage']:.3f}" for m in METHODS)
                + f" | {c['summary']['spread_over_se']:.2f} |"
            )
        mean = {m: np.mean([c[m]["coverage"] for c in cov.values()]) for m in METHODS}
        print("| all | " + " | ".join(f"{mean[m]:.3f}" for m in METHODS) + " | |", flush=True)


if __name__ == "__main__":
    main()
