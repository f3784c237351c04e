"""Time to precision of ``lambda.method: orbit`` against the paper's finite difference.

``python bench/bench_orbit.py [--realizations M] [--nodes 5,8,12,20]`` runs, for the Fig. 2 link
of lollipops with L = 1 (and the links 5->6, 2->1 of the Fig. 1 lollipop), the same M
realizations (same initial phases) with both estimators on one thread, and prints the
per-realization standard deviation, the seconds per realization and the ratio of the CPU time
each needs for a given standard error, ``(sd_fd^2 t_fd) / (sd_orbit^2 t_orbit)``. Both columns
are measured in the same run, so the ratio is what to quote on a noisy machine.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync.execution.compute import lambda_values, simulate_job  # noqa: E402
from antisync.plan.config import load_config_text  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402


def measure(graph: str, edge: str, method: str, m: int) -> tuple[np.ndarray, float, int]:
    job = make_job(
        load_config_text(f"""
graph: {graph}
edges: ["{edge}"]
betas: []
lambda: {{method: {method}}}
realizations: {m}
seed: 11
""")
    )
    lambda_values(
        job, simulate_job(job, 0, 2, threads=1) if method != "orbit" else None, 0, 2, threads=1
    )  # compile
    start = time.perf_counter()
    sim = simulate_job(job, 0, m, threads=1) if method != "orbit" else None
    values, code, _, _ = lambda_values(job, sim, 0, m, threads=1)
    seconds = (time.perf_counter() - start) / m
    size = 1 if job.orbit_sizes is None else int(job.orbit_sizes[0])
    return values[code[:, 0] == 0, 0], seconds, size


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=4000)
    ap.add_argument("--nodes", default="5,8,12,20")
    args = ap.parse_args()
    m = args.realizations
    cases = [
        ("{kind: lollipop, nodes: 6, path: 3}", "5->6", "lollipop N=6 L=3"),
        ("{kind: lollipop, nodes: 6, path: 3}", "2->1", "lollipop N=6 L=3"),
    ]
    for n in (int(x) for x in args.nodes.split(",")):
        cases.append((f"{{kind: lollipop, nodes: {n}, path: 1}}", f"{n - 1}->{n}", f"lollipop N={n} L=1"))
    print(f"# bench_orbit: M = {m} realizations, one thread, Euler dt = 0.001, grid crossing")
    print(
        "| graph | link | orbit size | Lambda FD 0.01 | Lambda orbit | sd FD | sd orbit | "
        "ms/real FD | ms/real orbit | time-to-precision ratio |"
    )
    print("|:---|:---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for graph, edge, label in cases:
        fd, t_fd, _ = measure(graph, edge, "finite-difference", m)
        orb, t_orb, size = measure(graph, edge, "orbit", m)
        se = lambda x: x.std() / np.sqrt(x.size)  # noqa: E731
        ratio = (fd.var() * t_fd) / (orb.var() * t_orb)
        print(
            f"| {label} | {edge} | {size} | {fd.mean():+.5f} ± {se(fd):.5f} | "
            f"{orb.mean():+.5f} ± {se(orb):.5f} | {fd.std():.4f} | {orb.std():.4f} | "
            f"{1e3 * t_fd:.3f} | {1e3 * t_orb:.3f} | {ratio:,.1f}x |",
            flush=True,
        )


if __name__ == "__main__":
    main()
