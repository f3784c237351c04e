"""Exact per-link measures of a whole graph in one call: Lambda^(xi2) and Lambda^(RW).

No integration and no result file: the measures that need no realizations, for every
directed link (or a chosen few) of a networkx graph or a config graph spec.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["for_graph"]


def for_graph(
    graph: nx.Graph | Mapping,
    *,
    which: tuple[str, ...] = ("xi2", "rw"),
    edges: str | list[str] = "all",
    coupling: str = "normalized",
) -> list[dict]:
    """Exact ``Lambda^(xi2)`` (Eq. 16) and ``Lambda^(RW)`` (Eq. 25) of directed links, no
    integration.

    Parameters
    ----------
    graph : networkx.Graph or mapping
        A connected graph (edge attribute ``weight``, default 1) or a config graph spec such as
        ``{"kind": "lollipop", "nodes": 6, "path": 3}``.
    which : tuple of {"xi2", "rw"}
    edges : "all" or list of "a->b"
    coupling : {"normalized", "raw"}
        ``rw`` is defined for the normalized random walk only.

    Returns
    -------
    list of dict
        ``{"edge": "a->b", "lambda_xi2": ..., "lambda_rw": ...}`` per directed link.

    Examples
    --------
    >>> import antisync
    >>> rows = antisync.measures.for_graph({"kind": "lollipop", "nodes": 6, "path": 3})
    >>> next(r for r in rows if r["edge"] == "2->1")["lambda_xi2"]  # doctest: +ELLIPSIS
    0.3625...
    """
    import networkx as nx

    from antisync import graphs
    from antisync.errors import ConfigError
    from antisync.measures.randomwalk import lambda_rw_all
    from antisync.measures.spectral import lambda_xi2_all

    for m in which:
        if m not in ("xi2", "rw"):
            raise ConfigError(
                f"measures: which must name xi2 or rw, got {m!r} (Lambda^KM and "
                "Lambda^linear need realizations: use antisync.run)"
            )
    if coupling not in ("normalized", "raw"):
        raise ConfigError(f"coupling must be normalized or raw, got {coupling!r}")
    if "rw" in which and coupling != "normalized":
        raise ConfigError("Lambda^RW is defined for the normalized random walk: coupling normalized")
    if isinstance(graph, Mapping):
        g = graphs.build_graph(dict(graph))
    else:
        g = nx.Graph(graph)
        for *_, d in g.edges(data=True):
            d.setdefault("weight", 1.0)
        if g.number_of_nodes() < 2 or not nx.is_connected(g):
            raise graphs.GraphError("measures need a connected graph with at least 2 nodes")
    nodes = graphs.node_order(g)
    index = {v: i for i, v in enumerate(nodes)}
    omega = graphs.omega_matrix(g)
    pairs = graphs.all_directed_edges(g) if edges == "all" else [graphs.parse_edge(e, g) for e in edges]
    idx = [(index[a], index[b]) for a, b in pairs]
    rows = [{"edge": graphs.edge_label(a, b)} for a, b in pairs]
    if "xi2" in which:
        for row, value in zip(rows, lambda_xi2_all(omega, idx, coupling), strict=True):
            row["lambda_xi2"] = float(value)
    if "rw" in which:
        for row, value in zip(rows, lambda_rw_all(omega, idx), strict=True):
            row["lambda_rw"] = float(value)
    return rows
