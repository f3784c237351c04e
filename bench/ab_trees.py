"""Two source trees against each other on the identical model's lane driver, alternating whole
processes (this machine's speed moves by up to 20% between processes with the same code, see
bench/RESULTS.md, "The models' RK4 step one pass shorter").

    git worktree add /tmp/old <commit>
    python bench/ab_trees.py /tmp/old . --network karate --integrator rk4 --pairs 8

Each process imports antisync from its tree (PYTHONPATH), times ``cpu.simulate`` on one thread
(the fastest of 5 runs after one that compiles or loads the cache) and prints ns per
trajectory-step; the processes alternate old, new, old, ... Printed: both trees' values, their
medians, and the median and range of the paired ratios new/old.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

NETWORKS = {
    "lollipop": ("graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1', '3->4', '5->6']\n", 4000),
    "karate": (
        "graph: {kind: networkx, generator: karate_club_graph}\nedges: ['0->1', '0->31', '33->32']\n",
        400,
    ),
    "ieee118": (
        "graph: {kind: edgelist, path: configs/ieee118.edges}\nedges: ['1->2', '49->69', '100->103']\n",
        200,
    ),
}

CHILD = """
import sys, time
import numpy as np
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.kernels import cpu
text, m, integ = sys.argv[1], int(sys.argv[2]), sys.argv[3]
job = make_job(load_config_text(text + "betas: [0.5]\\n"))
dt = {"euler": 0.01, "rk4": 0.04}[integ]
args = (1, 0, m, job.csr.indptr, job.csr.indices, job.csr.weights, job.variant_weights)
kw = dict(dt=dt, max_steps=int(round(200 / dt)), integrator=integ, threads=1, threshold=0.99)
best = np.inf
for r in range(6):
    t = time.perf_counter()
    sim = cpu.simulate(*args, **kw)
    el = time.perf_counter() - t
    steps = int(np.maximum(sim.steps0, 0).sum() + np.maximum(sim.steps, 0).sum())
    if r:
        best = min(best, el / steps * 1e9)
print(best)
"""


def _time(tree: Path, text: str, m: int, integ: str) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree), "NUMBA_NUM_THREADS": "1"}
    # the tree's own folder: configs/ieee118.edges is read relative to it
    out = subprocess.run(
        [sys.executable, "-c", CHILD, text, str(m), integ], cwd=tree, env=env, check=True, capture_output=True
    )
    return float(out.stdout.split()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--network", choices=NETWORKS, default="karate")
    ap.add_argument("--integrator", choices=("euler", "rk4"), default="rk4")
    ap.add_argument("--pairs", type=int, default=8)
    a = ap.parse_args()
    text, m = NETWORKS[a.network]
    old, new = [], []
    for i in range(a.pairs):
        old.append(_time(a.old.resolve(), text, m, a.integrator))
        new.append(_time(a.new.resolve(), text, m, a.integrator))
        print(f"pair {i + 1}: old {old[-1]:.1f} new {new[-1]:.1f} ns / trajectory-step", flush=True)
    ratio = np.array(new) / np.array(old)
    print(f"| tree | ns per trajectory-step, {a.pairs} processes (sorted) | median |")
    print("|---|---|---|")
    for name, v in (("old", old), ("new", new)):
        print(f"| {name} | " + ", ".join(f"{x:.1f}" for x in sorted(v)) + f" | {np.median(v):.1f} |")
    print(f"paired new/old: median {np.median(ratio):.2f}, range {ratio.min():.2f}-{ratio.max():.2f}")


if __name__ == "__main__":
    main()
