"""Time to find every directed edge's automorphism orbit: ``graphs.edge_orbits`` against the
pairwise search it replaced, on the same graphs in the same run.

    python bench/bench_edge_orbits.py [--baseline-up-to 65]

The baseline is the earlier ``edge_orbits``: each edge against every representative with the
same degree invariants, one VF2 search per pair with the two ends pinned (what a user of
networkx would write without enumerating the group). It runs only on graphs of at most
``--baseline-up-to`` nodes (a 129-node path took it 94 s). Both give the same
``{edge: representative}`` where both run (checked here); tests/test_sweeps.py checks the orbits
against enumerated automorphisms.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import networkx as nx
from networkx.algorithms.isomorphism import GraphMatcher, categorical_node_match

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from antisync.physics.graphs import all_directed_edges, edge_orbits  # noqa: E402


def _invariant(g: nx.Graph, e: tuple) -> tuple:
    a, b = e
    return (g.degree(a), g.degree(b), *(tuple(sorted(g.degree(x) for x in g[v])) for v in e))


def _maps_onto(g: nx.Graph, e: tuple, f: tuple) -> bool:
    g1, g2 = nx.Graph(g), nx.Graph(g)
    for h, (a, b) in ((g1, e), (g2, f)):
        nx.set_node_attributes(h, 0, "pin")
        h.nodes[a]["pin"], h.nodes[b]["pin"] = 1, 2
    same_weight = lambda x, y: x.get("weight", 1.0) == y.get("weight", 1.0)  # noqa: E731
    return GraphMatcher(g1, g2, categorical_node_match("pin", 0), same_weight).is_isomorphic()


def pairwise_orbits(g: nx.Graph) -> dict:
    """The baseline: one pinned VF2 search per pair (edge, representative) of equal invariants."""
    reps: list[tuple] = []
    out = {}
    for e in all_directed_edges(g):
        inv = _invariant(g, e)
        out[e] = next((r for r in reps if _invariant(g, r) == inv and _maps_onto(g, r, e)), e)
        if out[e] == e:
            reps.append(e)
    return out


GRAPHS = {
    "path 33": lambda: nx.path_graph(33),
    "path 65": lambda: nx.path_graph(65),
    "ring 64": lambda: nx.cycle_graph(64),
    "binary tree, 63 nodes": lambda: nx.balanced_tree(2, 5),
    "grid 6 x 6": lambda: nx.grid_2d_graph(6, 6),
    "karate club": nx.karate_club_graph,
    "path 1,025": lambda: nx.path_graph(1025),
    "ring 1,000": lambda: nx.cycle_graph(1000),
    "grid 20 x 20": lambda: nx.grid_2d_graph(20, 20),
    "binary tree, 511 nodes": lambda: nx.balanced_tree(2, 8),
    "random 3-regular, 200 nodes": lambda: nx.random_regular_graph(3, 200, seed=1),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline-up-to", type=int, default=65, help="largest graph for the baseline")
    args = parser.parse_args()
    print("| graph | directed edges | orbits | edge_orbits | pairwise VF2 (the baseline) |")
    print("|---|---|---|---|---|")
    for name, make in GRAPHS.items():
        g = make()
        t = time.perf_counter()
        orbits = edge_orbits(g)
        new = time.perf_counter() - t
        old = "not run"
        if g.number_of_nodes() <= args.baseline_up_to:
            t = time.perf_counter()
            want = pairwise_orbits(g)
            old = f"{time.perf_counter() - t:.2f} s"
            assert want == orbits, name  # the same representatives
        print(f"| {name} | {len(orbits)} | {len(set(orbits.values()))} | {new:.2f} s | {old} |")


if __name__ == "__main__":
    main()
