"""Graph families of a sweep: which graphs, which of their directed edges, and their orbits.

- ``atlas``: every connected graph of :func:`networkx.graph_atlas_g` with the given node
  counts, named ``G<index>``;
- ``lollipop``: lollipops ``lollipop_<N>_<L>`` with the paper's labels;
- ``graphs``: a list of graph specs as in a run config.

:func:`family_graphs` builds them, selects their edges (``all``, ``fig2`` or a list) and
groups the edges into automorphism orbits (:func:`~antisync.physics.graphs.edge_orbits`): one
representative per orbit is integrated.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx

from antisync.errors import ConfigError
from antisync.physics import graphs as graphs_mod
from antisync.physics.graphs import edge_orbits
from antisync.plan.config import check_graph, graph_name
from antisync.plan.jobs import check_step

__all__ = ["FAMILIES", "GraphEntry", "family_graphs", "family_specs", "fig2_edge"]

FAMILIES = ("atlas", "lollipop", "graphs")


def family_specs(family: dict) -> list[tuple[str, dict]]:
    """``(name, graph spec)`` of every graph of the family (a validated ``sweep:`` section),
    before building any graph."""
    fam = family["family"]
    if fam == "atlas":
        wanted = set(family["nodes"])
        out = []
        for index, g in enumerate(nx.graph_atlas_g()):
            if g.number_of_nodes() in wanted and nx.is_connected(g):
                out.append((f"G{index}", {"kind": "atlas", "index": index}))
        return out
    if fam == "lollipop":
        out = []
        for n in family["nodes"]:
            for path in family["path"]:
                if n - path >= 2:
                    out.append((f"lollipop_{n}_{path}", {"kind": "lollipop", "nodes": n, "path": path}))
        if not out:
            raise ConfigError("sweep.nodes and sweep.path give no lollipop with nodes - path >= 2")
        return out
    out, seen = [], set()
    for k, spec in enumerate(family["graphs"]):
        spec = dict(spec)
        name = spec.pop("name", None)
        try:
            check_graph(spec)
        except ConfigError as exc:
            raise ConfigError(f"sweep.graphs[{k}]: {exc}") from None
        name = str(name or graph_name(spec))
        if name in seen:
            raise ConfigError(
                f"sweep.graphs[{k}]: graph name {name!r} is used twice; give the graphs distinct name: keys"
            )
        seen.add(name)
        out.append((name, spec))
    return out


@dataclass
class GraphEntry:
    """One graph of a sweep: its selected directed edges and their automorphism orbits."""

    name: str
    spec: dict
    graph: nx.Graph
    edges: list  # selected directed edges, (u, v) node labels
    rep: dict  # edge -> representative edge (both (u, v))

    @property
    def labels(self) -> list[str]:
        return [graphs_mod.edge_label(*e) for e in self.edges]

    @property
    def representatives(self) -> list:
        return [e for e in self.edges if self.rep[e] == e]

    def orbit_labels(self) -> dict[str, str]:
        return {graphs_mod.edge_label(*e): graphs_mod.edge_label(*self.rep[e]) for e in self.edges}


def family_graphs(sweep, *, symmetry: bool = True) -> list[GraphEntry]:
    """Build every graph of ``sweep`` with its selected edges and their orbits.

    Parameters
    ----------
    sweep : Sweep
        A :class:`~antisync.sweeps.schema.Sweep`: its ``family``, ``edges`` and ``base``
        (the seed of random generators and the step checked on each graph) are used.
    symmetry : bool
        Group the edges into automorphism orbits; otherwise each edge is its own orbit. Off
        whatever is asked when the model has fixed per-node frequencies (an automorphism
        does not map them onto themselves); frequencies drawn independently per node, a
        phase lag or inertia keep every orbit's edges equal in distribution. With a grid,
        every point's model counts.
    """
    configs = [sweep.base] + [p.config for p in sweep.points]
    for cfg in configs:
        if cfg.model.frequencies is not None and not cfg.model.drawn:
            # fixed per-node frequencies tell automorphic edges apart: integrate every edge
            symmetry = False
    out = []
    for name, spec in family_specs(sweep.family):
        g = graphs_mod.build_graph(spec, seed=sweep.base.seed)
        g.graph["name"] = name
        omega = graphs_mod.omega_matrix(g)
        for cfg in configs:
            try:  # before the screening spends time on a step that cannot synchronize
                check_step(omega, cfg)
            except ConfigError as exc:
                raise ConfigError(f"graph {name}: {exc}") from None
        edges = _select_edges(sweep, spec, g, name)
        rep = edge_orbits(g, edges) if symmetry else {e: e for e in edges}
        out.append(GraphEntry(name, spec, g, edges, rep))
    return out


def fig2_edge(n_nodes: int, path: int) -> tuple[int, int]:
    """The edge of the paper's Fig. 2 in ``lollipop(N, L)``: a clique edge ``a -> b`` not touching
    the bridge node ``L + 1``, here ``(L + 2) -> (L + 3)`` (all such edges are one orbit)."""
    if n_nodes - path < 3:
        raise ConfigError(
            f"edges: fig2 needs a clique of at least 3 nodes; lollipop N={n_nodes}, "
            f"L={path} has {n_nodes - path}"
        )
    return (path + 2, path + 3)


def _select_edges(sweep, spec: dict, g: nx.Graph, name: str) -> list:
    if sweep.edges == "all":
        return graphs_mod.all_directed_edges(g)
    if sweep.edges == "fig2":
        return [fig2_edge(int(spec["nodes"]), int(spec["path"]))]
    out = []
    for text in sweep.edges:
        try:
            e = graphs_mod.parse_edge(text, g)
        except graphs_mod.GraphError as exc:
            raise ConfigError(f"edges: graph {name}: {exc}") from None
        if e not in out:
            out.append(e)
    return out
