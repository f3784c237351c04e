"""Exact per-link measures of a whole graph in one call: Lambda^(xi2) and Lambda^(RW).

No integration and no result file: the measures that need no realizations, for every
directed link (or a chosen few) of a networkx graph or a config graph spec.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping

import networkx as nx
import numpy as np

from antisync.errors import ConfigError, MeasureError
from antisync.measures.randomwalk import lambda_rw_all
from antisync.measures.spectral import lambda_xi2_all
from antisync.physics import graphs
from antisync.plan.config import check_graph

__all__ = ["for_graph"]

_WHICH = ("xi2", "rw")
_COUPLINGS = ("normalized", "raw")


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
        A connected undirected graph (edge attribute ``weight``, a positive finite number,
        default 1) or a config graph spec such as ``{"kind": "lollipop", "nodes": 6, "path": 3}``.
        In a :class:`networkx.MultiGraph` the parallel edges between two nodes add up:
        ``Omega_ij`` is the total weight between ``i`` and ``j``. A directed graph is refused:
        the measures are derivatives around an undirected ``Omega``.
    which : tuple of {"xi2", "rw"}
        The measures (a single name is one measure).
    edges : "all" or list of "a->b"
    coupling : {"normalized", "raw"}
        ``rw`` is defined for the normalized random walk only.

    Returns
    -------
    list of dict
        ``{"edge": "a->b", "lambda_xi2": ..., "lambda_rw": ...}`` per directed link.

    Raises
    ------
    antisync.errors.ConfigError
        An argument of the wrong type or value (:class:`~antisync.physics.graphs.GraphError` for the
        graph), with a one-line message naming it.
    antisync.errors.MeasureError
        A graph whose measures are not finite numbers (weights spanning too many decades).

    Examples
    --------
    >>> import antisync
    >>> rows = antisync.measures.for_graph({"kind": "lollipop", "nodes": 6, "path": 3})
    >>> next(r for r in rows if r["edge"] == "2->1")["lambda_xi2"]  # doctest: +ELLIPSIS
    0.3625...
    """
    which = _which(which)
    if not isinstance(coupling, str) or coupling not in _COUPLINGS:
        raise ConfigError(f"measures: coupling must be normalized or raw, got {_shown(coupling)}")
    if "rw" in which and coupling != "normalized":
        raise ConfigError("Lambda^RW is defined for the normalized random walk: coupling normalized")
    edges = _edges(edges)
    g = _graph(graph)
    nodes = graphs.node_order(g)
    index = {v: i for i, v in enumerate(nodes)}
    omega = graphs.omega_matrix(g)
    pairs = graphs.all_directed_edges(g) if edges == "all" else [graphs.parse_edge(e, g) for e in edges]
    idx = [(index[a], index[b]) for a, b in pairs]
    rows = [{"edge": graphs.edge_label(a, b)} for a, b in pairs]
    try:
        if "xi2" in which:
            for row, value in zip(rows, lambda_xi2_all(omega, idx, coupling), strict=True):
                row["lambda_xi2"] = float(value)
        if "rw" in which:
            for row, value in zip(rows, lambda_rw_all(omega, idx), strict=True):
                row["lambda_rw"] = float(value)
    except ValueError as exc:  # the measures' own checks of Omega, and numpy's LinAlgError
        raise MeasureError(f"measures: {exc}") from None
    if not all(math.isfinite(v) for row in rows for k, v in row.items() if k != "edge"):
        raise MeasureError(
            "measures: Lambda is not a finite number for this graph: its weights span too many "
            "decades for float64 (rescale them; normalized coupling only sees their ratios)"
        )
    return rows


def _which(which) -> tuple[str, ...]:
    names = (which,) if isinstance(which, str) else which
    if not isinstance(names, list | tuple | set | frozenset) or not names:
        raise ConfigError(
            f"measures: which must name xi2, rw or both, e.g. ('xi2', 'rw'), got {_shown(which)}"
        )
    for m in names:
        if not isinstance(m, str) or m not in _WHICH:
            raise ConfigError(
                f"measures: which must name xi2 or rw, got {_shown(m)} (Lambda^KM and "
                "Lambda^linear need realizations: use antisync.run)"
            )
    return tuple(str(m) for m in names)


def _edges(edges) -> str | list[str]:
    if isinstance(edges, str) and edges == "all":
        return "all"
    if not isinstance(edges, list | tuple) or not edges or not all(isinstance(e, str) for e in edges):
        raise ConfigError(
            f"measures: edges must be 'all' or a non-empty list of links such as ['2->1'], "
            f"got {_shown(edges)}"
        )
    return [str(e) for e in edges]


def _graph(graph) -> nx.Graph:
    """``graph`` as a connected, simple, undirected :class:`networkx.Graph` whose every edge
    has a positive finite float ``weight`` (parallel edges of a multigraph added up)."""
    if isinstance(graph, Mapping):
        spec = _spec(graph)
        check_graph(spec)
        return graphs.build_graph(spec)
    if not isinstance(graph, nx.Graph):
        raise ConfigError(
            "measures: graph must be a networkx graph or a config graph spec such as "
            f"{{'kind': 'lollipop', 'nodes': 6, 'path': 3}}, got {_shown(graph)}"
        )
    # the conversion antisync.run uses for a graph object too (graphs.graph_spec)
    g = graphs.simple_graph(graph, "measures")
    if g.number_of_nodes() < 2 or not nx.is_connected(g):
        raise graphs.GraphError("measures need a connected graph with at least 2 nodes")
    return g


def _spec(value, depth: int = 0):
    """A config graph spec as plain data: numpy scalars as the Python numbers they hold
    (``np.int64(6)`` is ``6``), paths as strings; the rest is checked by the graph builders."""
    if depth > 16:
        return value  # a spec nested this deep is refused by the builders, not recursed into
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:  # a lone surrogate names no file and no generator
            raise ConfigError(f"graph: {_shown(value)} is not text that UTF-8 can encode") from None
        return value
    if isinstance(value, Mapping):
        return {k: _spec(v, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_spec(v, depth + 1) for v in value]
    return value


def _shown(value, limit: int = 60) -> str:
    """``value``'s repr on one line, shortened (a huge int or a broken repr by its type)."""
    try:
        text = " ".join(repr(value).split())
    except Exception:  # noqa: BLE001 -- Python refuses to print ints of more than 4300 digits
        return f"a {type(value).__name__} that cannot be printed"
    return text if len(text) <= limit else text[: limit - 3] + "..."
