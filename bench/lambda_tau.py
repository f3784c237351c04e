"""Lambda^tau = -d ln<tau(beta)>/dbeta at 0: time to a worst-link interval per estimator, and the
coverage of its reported interval (issue 28).

Lambda^tau is a ratio of means, ``R = -sum slope_r / sum tau0_r`` over the realizations that
give a value (``slope_r`` the estimator's slope of ``tau(beta)`` at 0: the forward secant, the
central one, or the adjoint's derivative). Its variance is that of the linearized ratio,
``u_r = -(slope_r + R tau0_r) / mean(tau0)``: ``se^2 = var(u) / n``, so the time to a given
worst-link standard error is ``t max_e var_e(u)`` (``t`` seconds per realization).

``ttp``: every estimator on the same starts, one thread, interleaved in pieces (a change in the
machine's load falls on all), prints seconds per realization, the worst and median link's
``var(u)`` and the ratios against the finite difference of the same quantity: the derivative's
is ``central-difference``; the forward secant's only estimator is the finite difference itself::

    python bench/lambda_tau.py ttp --graph karate --realizations 512

``coverage``: one pool of per-realization ``(slope, tau0)`` (cached as
``bench/.cache/<name>_tau.npz``), runs of ``n`` drawn from it with replacement, each reduced by
the package's own block records and :func:`antisync.stats.estimators.summarize_lambda_tau` (the
interval ``antisync summary`` reports, :func:`antisync.stats.estimators.lambda_tau_interval`, ``R +- t
se``, beside the normal quantile's ``R +- 1.96 se``); coverage of the pool's ratio per link::

    python bench/lambda_tau.py coverage lollipop --method central-difference --realizations 400000

Results: bench/RESULTS.md, "Lambda^tau: time to precision and coverage".
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # before numba is imported
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from antisync.execution.compute import lambda_values, simulate_job  # noqa: E402
from antisync.plan.config import load_config_text  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402
from antisync.stats import estimators  # noqa: E402
from antisync.status import SYNCED  # noqa: E402

GRAPHS = {
    "lollipop": "{kind: lollipop, nodes: 6, path: 3}",
    "k5": "{kind: networkx, generator: complete_graph, args: {n: 5}}",
    "karate": "{kind: networkx, generator: karate_club_graph}",
    "lesmis": "{kind: networkx, generator: les_miserables_graph, weighted: true}",
}
# the quantity each estimator's slope of tau estimates, and the finite difference of that quantity
QUANTITY = {
    "finite-difference": "forward secant",
    "central-difference": "derivative",
    "adjoint-hybrid": "derivative",
    "adjoint": "derivative",
}
BASELINE = {"forward secant": "finite-difference", "derivative": "central-difference"}


def job_for(graph: str, method: str, m: int, seed: int, dt: float):
    return make_job(
        load_config_text(f"""
graph: {GRAPHS.get(graph, graph)}
edges: all
betas: []
lambda: {{method: {method}, dbeta: 0.01, hybrid_cut: 2.0}}
dynamics: {{integrator: rk4, dt: {dt}, threshold: 0.99, t_max: 400}}
realizations: {m}
seed: {seed}
""")
    )


def slopes(job, first: int, count: int, threads: int = 1):
    """``(ok, slope, tau0)``, each ``(count, E)``: the realizations that give a value and their
    slope of tau at 0 and tau0, as the run's reducer sums them."""
    forward = job.config.lambda_.method == "finite-difference"
    sim = simulate_job(job, first, count, threads=threads) if forward else None
    _, code, _, _, slope, tau0 = lambda_values(job, sim, first, count, threads, with_tau=True)
    return code == SYNCED, np.asarray(slope), np.asarray(tau0)


def linearized_variance(ok, slope, tau0) -> np.ndarray:
    """Per link, ``var(u)`` of the linearized ratio (``se^2 = var(u) / n``)."""
    out = np.empty(ok.shape[1])
    for e in range(ok.shape[1]):
        s, t = slope[ok[:, e], e], tau0[ok[:, e], e]
        ratio = -s.sum() / t.sum()
        out[e] = np.var(-(s + ratio * t) / t.mean(), ddof=1)
    return out


def ttp(args) -> None:
    methods = args.methods
    jobs = {m: job_for(args.graph, m, args.realizations, args.seed, args.dt) for m in methods}
    for job in jobs.values():  # compile
        slopes(job, 0, 1)
    seconds = dict.fromkeys(methods, 0.0)
    parts: dict[str, list] = {m: [] for m in methods}
    for first in range(0, args.realizations, args.piece):
        count = min(args.piece, args.realizations - first)
        for m, job in jobs.items():
            start = time.perf_counter()
            parts[m].append(slopes(job, first, count))
            seconds[m] += time.perf_counter() - start
    rows = {}
    for m in methods:
        ok, slope, tau0 = (np.concatenate(x) for x in zip(*parts[m], strict=True))
        var = linearized_variance(ok, slope, tau0)
        ratio = -np.array([slope[ok[:, e], e].sum() / tau0[ok[:, e], e].sum() for e in range(ok.shape[1])])
        rows[m] = (seconds[m] / args.realizations, var, ratio)
        print(
            f"{args.graph} {m} ({QUANTITY[m]}): {rows[m][0]:.4f} s per realization, {ok.shape[1]} links; "
            f"var(u) worst {var.max():.4g}, median {np.median(var):.4g}; "
            f"Lambda^tau range [{ratio.min():+.4f}, {ratio.max():+.4f}]",
            flush=True,
        )
    print(
        "\n| estimator | quantity | s per realization | worst var(u) "
        "| worst-link time to precision, against the FD of the quantity | median link |"
    )
    print("|---|---|---:|---:|---:|---:|")
    for m, (t, var, _) in rows.items():
        base = BASELINE[QUANTITY[m]]
        if base in rows:
            tb, vb, _ = rows[base]
            live = (var > 0) & (vb > 0)
            worst = f"{tb * vb.max() / (t * var.max()):.1f}x"
            median = f"{np.median(tb * vb[live] / (t * var[live])):.1f}x"
        else:
            worst = median = "(baseline not run)"
        print(f"| {m} | {QUANTITY[m]} | {t:.4f} | {var.max():.4g} | {worst} | {median} |")


def pool(args):
    path = Path(args.cache) / f"{args.name}_tau.npz"
    if not path.exists():
        job = job_for(args.graph, args.method, args.realizations, args.seed, args.dt)
        start, parts = time.perf_counter(), []
        for first in range(0, args.realizations, 20_000):
            parts.append(slopes(job, first, min(20_000, args.realizations - first), threads=args.threads))
            print(f"# pool {first + len(parts[-1][0]):,} / {args.realizations:,}", flush=True)
        ok, slope, tau0 = (np.concatenate(x) for x in zip(*parts, strict=True))
        keep = ok.all(axis=1)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, slope=slope[keep], tau0=tau0[keep], edges=np.array(job.edge_labels, dtype=object))
        print(f"# pool {args.name}: {keep.sum():,} realizations in {time.perf_counter() - start:.0f} s")
    d = np.load(path, allow_pickle=True)
    return list(d["edges"]), d["slope"], d["tau0"]


def coverage(args) -> None:
    edges, slope, tau0 = pool(args)
    live = ~np.all(slope == 0, axis=0)
    truth = -slope.sum(axis=0) / tau0.sum(axis=0)
    print(f"# {args.name} ({args.graph}): pool of {len(slope):,}, {args.method}, rk4 dt {args.dt}")
    rng = np.random.default_rng(args.draw_seed)
    for n in args.sizes:
        block = max(100, -(-n // 1000))  # the config's automatic block size
        hits = {"normal": np.zeros(slope.shape[1]), "reported": np.zeros(slope.shape[1])}
        widths = np.zeros(slope.shape[1])
        start = time.perf_counter()
        for _ in range(args.runs):
            k = rng.integers(0, len(slope), n)
            ones = np.ones((n, slope.shape[1]))
            rec, _ = estimators.lambda_block_records(
                ones,
                np.zeros(ones.shape, np.int8),
                np.zeros(ones.shape, bool),
                block,
                slope=slope[k],
                tau0=tau0[k],
            )
            for e in range(slope.shape[1]):
                est = estimators.summarize_lambda_tau(rec[:, e, :])
                lo, hi = est.mean - estimators.Z95 * est.se, est.mean + estimators.Z95 * est.se
                hits["normal"][e] += lo <= truth[e] <= hi
                lo, hi = estimators.lambda_tau_interval(est)
                hits["reported"][e] += lo <= truth[e] <= hi
                widths[e] += hi - lo
        cov = {name: h / args.runs for name, h in hits.items()}
        print(f"\n## runs of {n:,} realizations ({args.runs} runs, {time.perf_counter() - start:.0f} s)\n")
        print(
            "| link | Lambda^tau (pool) | mean width (reported) "
            "| coverage, normal quantile | reported (Student t) |"
        )
        print("|---|---:|---:|---:|---:|")
        for e, label in enumerate(edges):
            if live[e]:
                cells = " | ".join(f"{c[e]:.3f}" for c in cov.values())
                print(f"| {label} | {truth[e]:+.4f} | {widths[e] / args.runs:.4f} | {cells} |")
        cells = " | ".join(
            f"{c[live].mean():.3f} ({c[live].min():.3f}-{c[live].max():.3f})" for c in cov.values()
        )
        print(f"| all (range) | | | {cells} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("ttp", help="time to a worst-link interval per estimator")
    t.add_argument(
        "--methods", nargs="+", default=["finite-difference", "central-difference", "adjoint-hybrid"]
    )
    t.add_argument("--realizations", type=int, default=512)
    t.add_argument("--piece", type=int, default=64)
    c = sub.add_parser("coverage", help="coverage of the reported interval")
    c.add_argument("name", help="pool name (cache file <cache>/<name>_tau.npz)")
    c.add_argument("--method", default="central-difference", choices=sorted(QUANTITY))
    c.add_argument("--realizations", type=int, default=400_000, help="pool size")
    c.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000])
    c.add_argument("--runs", type=int, default=400)
    c.add_argument("--draw-seed", type=int, default=7)
    c.add_argument("--threads", type=int, default=1)
    c.add_argument("--cache", default=str(Path(__file__).resolve().parent / ".cache"))
    for q in (t, c):
        q.add_argument("--graph", default="lollipop", help=f"{', '.join(GRAPHS)} or a graph spec (YAML)")
        q.add_argument("--seed", type=int, default=3)
        q.add_argument("--dt", type=float, default=0.04)
    args = p.parse_args()
    ttp(args) if args.command == "ttp" else coverage(args)


if __name__ == "__main__":
    main()
