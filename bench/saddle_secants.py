"""Forward, backward and central differences of <F> on common phases, and the sum rule (issue 28).

For every out-link ``a -> b`` of one node ``a`` this integrates, from the same initial phases,
the undamaged network and the link at ``beta = +dbeta`` and ``-dbeta``, and reports per link
the paper's forward secant ``(<F(dbeta)> - 1)/dbeta`` (Eq. 17), the backward secant
``(1 - <F(-dbeta)>)/dbeta`` and the central difference (their mean), then the node's sum over
its out-links, which is 0 for the derivative d<F>/dbeta with normalized coupling (damaging all
out-links of a node alike leaves W unchanged). Errors are batch means over blocks of 1,000
realizations, paired (each difference is formed per realization first).

Usage::

    python bench/saddle_secants.py --graph lollipop --node 2 --realizations 400000 --dbeta 0.01
    python bench/saddle_secants.py --graph K5 --node 0 --realizations 1600000 --dbeta 0.002
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from antisync.execution.compute import simulate_job
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.status import SYNCED

GRAPHS = {
    "lollipop": "{kind: lollipop, nodes: 6, path: 3}",
    "K5": "{kind: networkx, generator: complete_graph, args: {n: 5}}",
}


def job_for(graph: str, node, dbeta: float, integrator: str, dt: float, seed: int):
    g = make_job(load_config_text(f"graph: {GRAPHS[graph]}\nbetas: []\nrealizations: 1\n"))
    edges = [f"{node}->{b}" for b in sorted(g.graph.neighbors(int(node)))]
    text = f"""
graph: {GRAPHS[graph]}
edges: {edges}
betas: []
realizations: 1
seed: {seed}
lambda: {{method: central-difference, dbeta: {dbeta}}}
dynamics: {{integrator: {integrator}, dt: {dt}, crossing: interpolated, t_max: 400}}
"""
    return make_job(load_config_text(text))


def per_realization(job, first: int, count: int):
    """Per realization and link: forward, backward and central secants (NaN where any of the
    three trajectories did not synchronize)."""
    dt = job.config.dynamics.dt
    sim = simulate_job(job, first, count, "cpu", None, job.orbit_weights)
    t0 = (sim.steps0 - 1 + sim.frac0) * dt
    t = (sim.steps - 1 + sim.frac) * dt
    plus, minus = t[:, 0::2], t[:, 1::2]
    ok = (sim.status0[:, None] == SYNCED) & (sim.status[:, 0::2] == SYNCED) & (sim.status[:, 1::2] == SYNCED)
    h = job.dbeta
    fwd = np.where(ok, (t0[:, None] / plus - 1.0) / h, np.nan)
    bwd = np.where(ok, (1.0 - t0[:, None] / minus) / h, np.nan)
    taus = np.stack(
        [np.where(ok, t0[:, None], np.nan), np.where(ok, plus, np.nan), np.where(ok, minus, np.nan)]
    )
    return fwd, bwd, 0.5 * (fwd + bwd), taus


def scan(job, realization: int, edge: int, betas: np.ndarray) -> np.ndarray:
    """tau(beta) of one realization with one link damaged by each of ``betas`` (RK4, Hermite
    crossing): the shape of tau near a singular damage beta_s."""
    from antisync.physics import coupling

    a, b = (job.nodes.index(v) for v in job.edges[edge])
    weights = coupling.variant_weights(job.omega, job.csr, [(a, b, float(x)) for x in betas])
    sim = simulate_job(job, realization, 1, "cpu", None, weights)
    return np.where(
        sim.status[0] == SYNCED, (sim.steps[0] - 1 + sim.frac[0]) * job.config.dynamics.dt, np.nan
    )


def batch_mean(x: np.ndarray, block: int = 1000):
    """Mean over realizations (NaN rows dropped per column) and its batch-means standard error."""
    x = x[~np.isnan(x).any(axis=1)]
    nb = x.shape[0] // block
    means = x[: nb * block].reshape(nb, block, -1).mean(axis=1)
    return x.mean(axis=0), means.std(axis=0, ddof=1) / np.sqrt(nb)


def lambda_tau(taus: np.ndarray, h: float, labels, block: int = 1000) -> None:
    """Lambda^tau = -d ln<tau(beta)>/dbeta at 0, a ratio of means on the same starts: forward
    -(<tau(h)>/<tau0> - 1)/h, backward -(1 - <tau(-h)>/<tau0>)/h and central, per link and
    summed over the node's links, with batch-means errors of the per-block ratios."""
    t0, plus, minus = taus  # (M, E) each, NaN where a trajectory did not synchronize
    keep = ~np.isnan(t0).any(axis=1)
    t0, plus, minus = t0[keep], plus[keep], minus[keep]
    nb = t0.shape[0] // block

    def blocks(x):
        return x[: nb * block].reshape(nb, block, -1).mean(axis=1)

    b0, bp, bm = blocks(t0), blocks(plus), blocks(minus)
    ests = {
        "forward": (-(bp / b0 - 1.0) / h, -(plus.mean(0) / t0.mean(0) - 1.0) / h),
        "backward": (-(1.0 - bm / b0) / h, -(1.0 - minus.mean(0) / t0.mean(0)) / h),
        "central": (-(bp - bm) / (2 * h * b0), -(plus.mean(0) - minus.mean(0)) / (2 * h * t0.mean(0))),
    }
    print(f"{'Lambda^tau':>10} " + " ".join(f"{k:>18}" for k in ests) + f" {'fwd - bwd':>18}")
    for e, label in enumerate(list(labels) + ["sum"]):
        cells = []
        for per_block, total in [*ests.values(), (ests["forward"][0] - ests["backward"][0], None)]:
            col = per_block.sum(axis=1) if label == "sum" else per_block[:, e]
            value = col.mean() if total is None else (total.sum() if label == "sum" else total[e])
            cells.append(f"{value:+.5f} +- {col.std(ddof=1) / np.sqrt(nb):.5f}")
        print(f"{label:>10} " + " ".join(cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graph", choices=sorted(GRAPHS), default="lollipop")
    ap.add_argument("--node", default="2")
    ap.add_argument("--realizations", type=int, default=400_000)
    ap.add_argument("--dbeta", type=float, nargs="+", default=[0.01, 0.002])
    ap.add_argument("--integrator", default="rk4")
    ap.add_argument("--dt", type=float, default=0.04)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--chunk", type=int, default=100_000)
    ap.add_argument(
        "--scan",
        type=int,
        default=0,
        help="print tau(beta) of the K realizations whose one-sided secants differ most",
    )
    args = ap.parse_args()
    for h in args.dbeta:
        job = job_for(args.graph, args.node, h, args.integrator, args.dt, args.seed)
        start = time.perf_counter()
        parts = [
            per_realization(job, f, min(args.chunk, args.realizations - f))
            for f in range(0, args.realizations, args.chunk)
        ]
        fwd, bwd, cen = (np.concatenate([p[i] for p in parts]) for i in range(3))
        taus = np.concatenate([p[3] for p in parts], axis=1)
        seconds = time.perf_counter() - start
        print(
            f"\n{args.graph}, node {args.node}, dbeta {h}, {args.integrator} dt {args.dt} interpolated, "
            f"{args.realizations:,} realizations, seed {args.seed} ({seconds:.0f} s)"
        )
        print(f"{'link':>8} {'forward':>18} {'backward':>18} {'central':>18} {'fwd - central':>18}")
        rows = {"forward": fwd, "backward": bwd, "central": cen, "fwd - central": fwd - cen}
        stats = {k: batch_mean(v) for k, v in rows.items()}
        for e, label in enumerate(job.edge_labels):
            cells = " ".join(f"{stats[k][0][e]:+.5f} +- {stats[k][1][e]:.5f}" for k in rows)
            print(f"{label:>8} {cells}")
        sums = {k: batch_mean(v.sum(axis=1, keepdims=True)) for k, v in rows.items()}
        cells = " ".join(f"{sums[k][0][0]:+.5f} +- {sums[k][1][0]:.5f}" for k in rows)
        print(f"{'sum':>8} {cells}")
        lambda_tau(taus, h, job.edge_labels)
        if args.scan:
            # the realizations whose forward and backward secants of the first link differ most
            gap = np.nan_to_num(np.abs(fwd[:, 0] - bwd[:, 0]))
            grid = np.concatenate([-np.geomspace(h, 1e-6, 6), [0.0], np.geomspace(1e-6, h, 6)])
            for r in np.argsort(gap)[::-1][: args.scan]:
                taus = scan(job, int(r), 0, grid)
                label = job.edge_labels[0]
                print(f"realization {r}, link {label}: forward {fwd[r, 0]:+.2f}, backward {bwd[r, 0]:+.2f}")
                print("  beta " + " ".join(f"{x:+.0e}" for x in grid))
                print("  tau  " + " ".join(f"{t:6.3f}" for t in taus))


if __name__ == "__main__":
    main()
