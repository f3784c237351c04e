"""Lambda^KM of every link of a graph: adjoint against pathwise and finite differences.

``python bench/bench_adjoint.py [--realizations M] [--large-links K]`` times, on one thread
(``NUMBA_NUM_THREADS=1``), the seconds per realization each estimator needs for *all* directed
links of

- the karate club graph (``networkx.karate_club_graph``, 34 nodes, 156 directed links,
  interaction-count weights): every estimator on every link, measured;
- a 200-node Barabasi-Albert graph (``barabasi_albert_graph(200, 2, seed=1)``, 792 directed
  links): adjoint on every link, measured; pathwise and finite differences on ``K`` and ``4 K``
  links, then extrapolated linearly in the number of links (their cost is ``a + b E``: one
  tangent, or one damaged trajectory, per link); the fit is printed with the measurements.

All three estimators run the paper's Euler step (dt = 0.001, threshold 0.99, normalized
coupling) from the same initial phases. Pathwise steps 32 trajectories together (its lane
driver), so it is timed on a multiple of 32 realizations; the finite difference also uses
the lane driver; the adjoint runs 16 realizations side by side (its lane path, ordered by
crossing step; ``kernels.adjoint.LANES``). The adjoint's per-realization
values are checked against pathwise on the links both computed (the largest relative
difference is printed). ``--hybrid`` instead prints the flagged fraction of ``adjoint-hybrid``
(``hybrid_cut`` 2, the default) on both graphs and the paper's lollipop.
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
from antisync.plan.config import load_config_text  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402

GRAPHS = {
    "karate": "{kind: networkx, generator: karate_club_graph}",
    "ba200": "{kind: networkx, generator: barabasi_albert_graph, args: {n: 200, m: 2, seed: 1}}",
}


def job_for(graph: str, method: str, edges="all", m: int = 32):
    edges_yaml = "all" if edges == "all" else "[" + ", ".join(f'"{e}"' for e in edges) + "]"
    return make_job(
        load_config_text(f"""
graph: {graph}
edges: {edges_yaml}
betas: []
lambda: {{method: {method}, dbeta: 0.01, hybrid_cut: 2.0}}
dynamics: {{dt: 0.001, t_max: 200}}
realizations: {m}
seed: 3
""")
    )


def seconds_per_realization(job, m: int):
    """(seconds per realization, per-realization values, codes) of ``lambda_values`` over
    realizations ``0 .. m-1`` (compiled on a first tiny call)."""
    fd = job.config.lambda_.method == "finite-difference"
    lambda_values(job, simulate_job(job, 0, 1, threads=1) if fd else None, 0, 1, threads=1)
    start = time.perf_counter()
    sim = simulate_job(job, 0, m, threads=1) if fd else None
    values, code, flagged, _ = lambda_values(job, sim, 0, m, threads=1)
    return (time.perf_counter() - start) / m, values, code, flagged


def flagged_fraction(m: int) -> None:
    """Share of (realization, link) values that ``adjoint-hybrid`` replaces by a secant."""
    cases = {"lollipop(6, 3)": "{kind: lollipop, nodes: 6, path: 3}", **GRAPHS}
    for name, graph in cases.items():
        job = job_for(graph, "adjoint-hybrid", m=m)
        t, _, code, flagged = seconds_per_realization(job, m)
        ok = code == 0
        print(
            f"{name} adjoint-hybrid (cut 2): {flagged.sum()} of {ok.sum()} (realization, link) "
            f"values flagged = {flagged.sum() / ok.sum():.3%}; links with any: "
            f"{int(flagged.any(axis=0).sum())} of {flagged.shape[1]}; {t:.3f} s per realization",
            flush=True,
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=32, help="per timing (a multiple of 32)")
    ap.add_argument("--large-links", type=int, default=4, help="K: links timed on the large graph")
    ap.add_argument("--hybrid", action="store_true", help="only the flagged fraction of adjoint-hybrid")
    ap.add_argument("--hybrid-realizations", type=int, default=200)
    args = ap.parse_args()
    m = args.realizations
    if args.hybrid:
        flagged_fraction(args.hybrid_realizations)
        return
    rows = []

    # karate: every estimator on every link
    times = {}
    vals = {}
    for method in ("adjoint", "pathwise", "finite-difference"):
        job = job_for(GRAPHS["karate"], method, m=m)
        t, v, code, _ = seconds_per_realization(job, m)
        times[method], vals[method] = t, (v, code)
        print(f"karate {method}: {t:.4f} s per realization, {len(job.edges)} links", flush=True)
    (va, ca), (vp, _) = vals["adjoint"], vals["pathwise"]
    ok = ca == 0
    rel = np.abs(va[ok] - vp[ok]).max() / np.abs(vp[ok]).max()
    print(f"karate adjoint vs pathwise: max |difference| / max |value| = {rel:.2e}")
    rows.append(("karate club (N=34, 156 links)", times, "measured", "measured"))

    # BA(200, 2): adjoint on all links; pathwise and FD on K and 4K links, linear in E
    big = job_for(GRAPHS["ba200"], "adjoint", m=m)
    n_links = len(big.edges)
    m_adj = max(4, m // 4)
    t_adj, va, ca, _ = seconds_per_realization(big, m_adj)
    print(f"ba200 adjoint: {t_adj:.4f} s per realization, {n_links} links (M = {m_adj})", flush=True)
    times = {"adjoint": t_adj}
    k = args.large_links
    for method in ("pathwise", "finite-difference"):
        pts = []
        for count in (k, 4 * k):
            sub = big.edge_labels[:: max(1, n_links // count)][:count]
            job = job_for(GRAPHS["ba200"], method, sub, m=m)
            t, v, code, _ = seconds_per_realization(job, m)
            pts.append((count, t))
            print(f"ba200 {method}: {t:.4f} s per realization on {count} links", flush=True)
            if method == "pathwise":
                # the same realizations 0 .. m_adj - 1, these links
                idx = [big.edge_labels.index(e) for e in sub]
                pv, av = v[:m_adj], va[:, idx]
                both = (code[:m_adj] == 0) & (ca[:, idx] == 0)
                d = np.abs(pv[both] - av[both]).max() / np.abs(pv[both]).max()
                print(f"  adjoint vs pathwise on these links: max |difference| / max |value| = {d:.2e}")
        (e1, t1), (e2, t2) = pts
        slope = (t2 - t1) / (e2 - e1)
        times[method] = t1 + slope * (n_links - e1)
        print(
            f"  fit: {t1 - slope * e1:.4f} + {slope:.5f} E s -> {times[method]:.2f} s for {n_links} links",
            flush=True,
        )
    rows.append(
        ("Barabasi-Albert N=200 m=2 (792 links)", times, "measured", f"extrapolated from {k}, {4 * k} links")
    )

    print()
    print(
        "| graph | adjoint (s/real.) | pathwise (s/real.) | finite difference (s/real.) "
        "| pathwise / adjoint | FD / adjoint | |"
    )
    print("|---|---:|---:|---:|---:|---:|---|")
    for name, t, how_adj, how_other in rows:
        print(
            f"| {name} | {t['adjoint']:.4f} | {t['pathwise']:.3f} | {t['finite-difference']:.3f} | "
            f"{t['pathwise'] / t['adjoint']:.0f}x | {t['finite-difference'] / t['adjoint']:.0f}x | "
            f"adjoint {how_adj}; others {how_other} |"
        )


if __name__ == "__main__":
    main()
