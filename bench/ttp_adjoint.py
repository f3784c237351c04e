"""Time to a given worst-link standard error, every link: adjoint-hybrid against finite difference.

``--baseline central-difference`` times it against the finite difference of the same quantity,
the derivative (central differences on the same starts); the default, the paper's forward
secant, is another quantity near saddle passages (docs/equations.md), kept for the earlier
figures of bench/RESULTS.md.

``python bench/ttp_adjoint.py --graph lesmis --integrator euler --realizations 32`` runs, on one
thread (``NUMBA_NUM_THREADS=1``), ``lambda_values`` of both estimators on the same realizations
(same seed: the same initial phases) for every directed link, and prints each one's seconds per
realization and per-link variance of the per-realization values (synchronized realizations).
The time to reach a standard error ``se`` on every link is ``t max_e var_e / se^2`` (``t`` the
seconds per realization), so the ratio of the two estimators' times is
``(t_FD max_e var_FD) / (t_AH max_e var_AH)``, whatever ``se``; the median link's ratio is
printed beside it. Graphs: ``karate`` (156 links) and ``lesmis`` (Les Miserables, weighted,
508 links, as configs/lesmis.yaml); integrators: ``euler`` (dt 0.001) or ``rk4`` (dt 0.04,
the configs' choice). ``--config configs/ieee14_grid.yaml`` (or any config) takes the graph,
model and dynamics from a config instead (a generalized model's adjoint and secants run on the
model kernels, antisync/kernels/model_adjoint.py).

The two are timed interleaved, so that a change in the machine's load falls on both: the finite
difference runs in pieces of ``--piece`` realizations, and after each piece the adjoint-hybrid
runs on all M realizations (the same numbers every time); its seconds per realization are the
mean over those repeats. (Timed one after the other, the ratio moved by 20% between two runs on
a shared machine.) The adjoint-hybrid always runs all M at once: its 16-lane groups, sorted by
predicted crossing, need many realizations to leave few lanes idle, as in a run's chunks of at
least ``ADJOINT_MIN_CHUNK``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ["NUMBA_NUM_THREADS"] = "1"  # before numba is imported
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from antisync.execution.compute import lambda_values, simulate_job  # noqa: E402
from antisync.plan.config import load_config, load_config_text  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402
from antisync.status import SYNCED  # noqa: E402

GRAPHS = {
    "karate": "{kind: networkx, generator: karate_club_graph}",
    "lesmis": "{kind: networkx, generator: les_miserables_graph, weighted: true}",
}
STEPS = {"euler": 0.001, "rk4": 0.04}


def job_for(graph: str, method: str, integrator: str, m: int, config: str | None = None):
    if config is not None:
        sets = [
            f"lambda.method={method}",
            "lambda.dbeta=0.01",
            "lambda.hybrid_cut=2.0",
            f"realizations={m}",
            "seed=3",
        ]
        return make_job(load_config(config, sets + ["betas=[]", "edges=all"]))
    return make_job(
        load_config_text(f"""
graph: {GRAPHS[graph]}
edges: all
betas: []
lambda: {{method: {method}, dbeta: 0.01, hybrid_cut: 2.0}}
dynamics: {{integrator: {integrator}, dt: {STEPS[integrator]}, threshold: 0.99, t_max: 200}}
realizations: {m}
seed: 3
""")
    )


def fd_piece(job, first: int, count: int):
    # the forward difference reads the run's own integration; central differences integrate
    # their +-dbeta pairs themselves
    forward = job.config.lambda_.method == "finite-difference"
    sim = simulate_job(job, first, count, threads=1) if forward else None
    return lambda_values(job, sim, first, count, threads=1)[:3]


def interleaved(fd_job, ah_job, m: int, piece: int):
    """Finite difference in pieces, the adjoint-hybrid on all ``m`` after each piece: seconds per
    realization of each (the adjoint-hybrid's the mean of its repeats) and both outcomes."""
    fd_piece(fd_job, 0, 1)  # compile
    lambda_values(ah_job, None, 0, 1, threads=1)
    fd_seconds, ah_seconds, parts = 0.0, [], []
    for first in range(0, m, piece):
        start = time.perf_counter()
        parts.append(fd_piece(fd_job, first, min(piece, m - first)))
        fd_seconds += time.perf_counter() - start
        start = time.perf_counter()
        ah = lambda_values(ah_job, None, 0, m, threads=1)[:3]
        ah_seconds.append(time.perf_counter() - start)
    fd = tuple(np.concatenate(x) for x in zip(*parts, strict=True))
    return {
        fd_job.config.lambda_.method: (fd_seconds / m, *fd),
        "adjoint-hybrid": (np.mean(ah_seconds) / m, *ah),
    }, ah_seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graph", choices=sorted(GRAPHS), default="lesmis")
    ap.add_argument("--integrator", choices=sorted(STEPS), default="euler")
    ap.add_argument("--realizations", type=int, default=32)
    ap.add_argument(
        "--piece", type=int, default=32, help="finite-difference realizations between adjoint repeats"
    )
    ap.add_argument(
        "--baseline",
        choices=("finite-difference", "central-difference"),
        default="finite-difference",
        help="the finite difference to time against: the paper's forward secant (another quantity) "
        "or central differences (the derivative adjoint-hybrid estimates; issue 28)",
    )
    ap.add_argument("--config", help="take graph, model and dynamics from this config file")
    args = ap.parse_args()
    m = args.realizations
    methods = (args.baseline, "adjoint-hybrid")
    fd_job, ah_job = (job_for(args.graph, method, args.integrator, m, args.config) for method in methods)
    if args.config:
        args.graph, args.integrator = fd_job.name, fd_job.config.dynamics.integrator
    out, ah_seconds = interleaved(fd_job, ah_job, m, args.piece)
    spread = np.array(ah_seconds) / m
    print(
        f"adjoint-hybrid repeats: {len(spread)}, seconds per realization min {spread.min():.4f}, "
        f"mean {spread.mean():.4f}, max {spread.max():.4f}"
    )
    res = {}
    for method, (t, values, code, flagged) in out.items():
        ok = code == SYNCED
        var = np.array([values[ok[:, e], e].var(ddof=1) for e in range(values.shape[1])])
        res[method] = (t, var)
        print(
            f"{args.graph} {args.integrator} {method}: {t:.4f} s per realization, {values.shape[1]} links, "
            f"{ok.all(axis=1).sum()} of {m} realizations synchronized on every link; "
            f"per-link variance max {var.max():.4g}, median {np.median(var):.4g}; "
            f"flagged {flagged.sum()} values",
            flush=True,
        )
    (t_fd, v_fd), (t_ah, v_ah) = res[args.baseline], res["adjoint-hybrid"]
    live = (v_fd > 0) & (v_ah > 0)  # a link whose damage leaves W unchanged has Lambda = 0 exactly
    print(
        f"{args.graph} {args.integrator} against {args.baseline}: seconds FD / AH = {t_fd / t_ah:.1f}x; "
        f"worst-link time to precision FD / AH = {t_fd * v_fd.max() / (t_ah * v_ah.max()):.1f}x "
        f"(variance ratio of the worst links {v_fd.max() / v_ah.max():.2f}); "
        f"median link: {np.median(t_fd * v_fd[live] / (t_ah * v_ah[live])):.1f}x "
        f"({live.sum()} links with nonzero variance)"
    )


if __name__ == "__main__":
    main()
