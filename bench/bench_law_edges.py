"""A law's edge parameter against the same value as a constant, per trajectory-step.

    python bench/bench_law_edges.py [--threads 2] [--repeat 3] [--steps 400] [--integrator rk4]

Kuramoto-Sakaguchi with its lag ``alpha`` written two ways: ``kuramoto-sakaguchi`` (the lag a
constant, 0.3) and ``sakaguchi-links`` (the lag an edge parameter, ``model.edge_params``, 0.3
on every link here), on the karate club (N = 34) and a random 3-regular graph of N = 1,000, at
dt 0.01 for a fixed number of steps (the target out of reach). Timed back to back in the same
round:

- ``edge``: the lag per link on lane vectors (what a run takes by default), ``cos(alpha)`` and
  ``sin(alpha)`` computed once per link (:func:`antisync.kernels.law.with_derived`);
- ``constant lanes``: the constant on lane vectors, its sine and cosine folded into the code:
  the same layout;
- ``constant one``: the constant, one trajectory per item (``lanes=0``).

Prints the fastest of ``--repeat`` rounds per kind and the median of each round's ratio.
"""

from __future__ import annotations

import argparse
import functools
import os
import platform

import networkx as nx
import numpy as np
from bench_laws import time_rounds, unit_network  # bench/ is the script's folder, first on sys.path

from antisync.kernels.law import LawParams, simulate_law
from antisync.laws import read_law

GRAPHS = {
    "karate N=34": (nx.karate_club_graph, 512),
    "3-regular N=1000": (lambda: nx.random_regular_graph(3, 1000, seed=1), 32),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--integrator", choices=("euler", "rk4", "rodas4"), default="rk4")
    args = ap.parse_args()
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, threads {args.threads}")
    constant = read_law("kuramoto-sakaguchi")
    text = constant.as_dict()
    text.update(name="sakaguchi-links", constants={}, edge_params={"alpha": 0.3})
    edge = read_law(text)
    for name, (make, m) in GRAPHS.items():
        csr, n, never = unit_network(make())
        common = (5, 0, m, csr.indptr, csr.indices, csr.weights, np.zeros((0, csr.weights.size)))
        clock = {"dt": 0.01, "max_steps": args.steps, "threads": args.threads, "integrator": args.integrator}
        values = np.zeros((1, n))
        lags = np.full((1, csr.weights.size), 0.3)
        kinds = {
            "edge": functools.partial(
                simulate_law, *common, LawParams(edge, values, never, edges=lags), **clock
            ),
            "constant one": functools.partial(
                simulate_law, *common, LawParams(constant, values, never), lanes=0, **clock
            ),
            "constant lanes": functools.partial(
                simulate_law, *common, LawParams(constant, values, never), **clock
            ),
        }
        best, ratios = time_rounds(kinds, "edge", args.repeat, m * args.steps)
        for k in kinds:
            print(
                f"{name:18s} {args.integrator:6s} {k:15s} {best[k]:10.1f} ns/trajectory-step   "
                f"edge / this: {np.median(ratios[k]):.2f} (rounds {min(ratios[k]):.2f}-{max(ratios[k]):.2f})"
            )


if __name__ == "__main__":
    main()
