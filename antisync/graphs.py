"""Graph builders with the paper's node labels, and directed-edge parsing.

Every builder returns an undirected :class:`networkx.Graph` whose edges carry a ``weight``
(1.0 unless an edge list says otherwise). :func:`omega_matrix` turns it into the dense
weight matrix ``Omega`` in the fixed node order of :func:`node_order`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import networkx as nx
import numpy as np

from antisync.errors import AntisyncError, ConfigError
from antisync.validation import DECIMAL, number_text, parse_integer, read_input_text, show

__all__ = [
    "GraphError",
    "all_directed_edges",
    "barbell",
    "build_graph",
    "edge_label",
    "edge_orbits",
    "from_edgelist",
    "lollipop",
    "node_order",
    "omega_matrix",
    "parse_edge",
]

GRAPH_KINDS = ("lollipop", "barbell", "atlas", "networkx", "edgelist")
#: Largest lollipop or barbell antisync builds: their cliques grow as N^2 links.
MAX_BUILT_NODES = 2000


class GraphError(AntisyncError, ValueError):
    """A graph specification or graph file that cannot be turned into a usable network."""


def lollipop(n_nodes: int, path: int) -> nx.Graph:
    """Lollipop graph with the paper's labels (Fig. 1).

    Parameters
    ----------
    n_nodes : int
        Total number of nodes ``N``.
    path : int
        Number of path nodes ``L`` (``1 <= L <= N - 2``).

    Returns
    -------
    networkx.Graph
        Nodes ``1..N``: the path ``1 - 2 - ... - L`` with node 1 its free end, the bridge
        ``L - (L+1)``, and the clique on ``L+1..N``. For ``N=6, L=3`` the edges are
        1-2, 2-3, 3-4, 4-5, 4-6, 5-6, so ``"2->1"`` means what the paper's Fig. 1 means.
    """
    if path < 1 or n_nodes - path < 2:
        raise GraphError(f"lollipop needs 1 <= path <= nodes - 2, got nodes={n_nodes}, path={path}")
    g = nx.Graph()
    g.add_nodes_from(range(1, n_nodes + 1))
    # the stick: 1 - 2 - ... - L, then the bridge L - (L+1)
    nx.add_path(g, range(1, path + 2), weight=1.0)
    # the candy: a clique on L+1 .. N
    clique = range(path + 1, n_nodes + 1)
    g.add_edges_from(((u, v) for u in clique for v in clique if u < v), weight=1.0)
    return g


def barbell(m1: int, m2: int = 0) -> nx.Graph:
    """Barbell graph (two ``m1``-cliques joined by a path of ``m2`` nodes), nodes ``1..N``."""
    if m1 < 2 or m2 < 0:
        raise GraphError(f"barbell needs m1 >= 2 and m2 >= 0, got m1={m1}, m2={m2}")
    g = nx.barbell_graph(m1, m2)
    return _unit_weights(nx.relabel_nodes(g, {v: v + 1 for v in g}))


def atlas(index: int) -> nx.Graph:
    """Graph ``index`` of the networkx graph atlas (``G<index>``), its 0-based labels kept."""
    if not 0 <= index < 1253:
        raise GraphError(f"atlas index must be in 0..1252, got {index}")
    g = nx.Graph(nx.graph_atlas(index))
    g.graph["name"] = f"G{index}"
    return _unit_weights(g)


def from_networkx(
    generator: str, args: dict | None = None, seed: int | None = None, weighted: bool = False
) -> nx.Graph:
    """Any networkx generator by name, e.g. ``("barbell_graph", {"m1": 3, "m2": 0})``.

    Parameters
    ----------
    generator : str
        Name of a networkx function that returns a graph.
    args : dict, optional
        Its keyword arguments.
    seed : int, optional
        For a random generator (one with a ``seed`` parameter) whose ``args`` give no seed:
        the seed it gets, so the same config builds the same graph on every run (the runner
        passes the run's seed). A random generator with neither is refused.
    weighted : bool
        Keep the generator's edge attribute ``weight`` (an edge without one weighs 1), e.g. the
        co-occurrence counts of ``les_miserables_graph``. Default: every weight is 1.
    """
    import inspect

    func = getattr(nx, generator, None)
    if func is None or not callable(func) or not generator.endswith(("graph", "_tree")):
        raise GraphError(
            f"unknown networkx generator {generator!r}; give the name of a networkx function "
            "that builds a graph, e.g. 'barbell_graph', 'path_graph', 'karate_club_graph'"
        )
    args = dict(args or {})
    try:
        random = "seed" in inspect.signature(func).parameters
    except (TypeError, ValueError):
        random = False
    if random and args.get("seed") is None:
        if seed is None:
            raise GraphError(
                f"networkx.{generator} is random: give graph.args.seed (an integer) "
                "so that every run builds the same graph"
            )
        args["seed"] = seed
    if random and (isinstance(args["seed"], bool) or not isinstance(args["seed"], int)):
        raise GraphError(f"graph.args.seed must be an integer, got {args['seed']!r}")
    try:
        g = func(**args)
    except Exception as exc:  # noqa: BLE001 -- networkx's own message names the bad argument
        raise GraphError(f"networkx.{generator} rejected args {args}: {exc}") from None
    if not isinstance(g, nx.Graph) or g.is_directed():
        raise GraphError(f"networkx.{generator} did not return an undirected graph")
    if not weighted:
        return _unit_weights(nx.Graph(g))
    out = nx.Graph(g)
    for u, v, d in out.edges(data=True):
        w = d.get("weight", 1.0)
        if isinstance(w, bool) or not isinstance(w, int | float) or not (w > 0 and math.isfinite(w)):
            raise GraphError(
                f"networkx.{generator}: edge {u}-{v} has weight {w!r}; weighted graphs need "
                "positive finite weights (or graph.weighted: false for unit weights)"
            )
        d["weight"] = float(w)
    return out


def from_edgelist(path: str | Path) -> nx.Graph:
    """Read ``u v [weight]`` lines (``#`` starts a comment). Integer labels stay integers.

    Columns are separated by spaces or tabs. The file is read by
    :func:`antisync.validation.read_input_text` (a regular file, UTF-8; a byte-order mark is
    dropped, UTF-16 with one decoded; NUL or control characters refused). Nothing is read as
    something other than it says; each of these is refused with one line naming the line:

    - a weight not in the number grammar :data:`antisync.validation.DECIMAL` (``1,5``,
      ``0x10``, ``1_000``, a unicode minus: Python's ``float`` would read ``1_000``);
    - a label that is an integer written another way (``01``, ``+1``, ``1_0``, non-ASCII
      digits: ``int()`` would merge ``01`` with ``1`` into one node) or a non-integer number
      (``1.0`` would be a node apart from ``1``);
    - a label holding ``,`` or ``;`` (another file format's separator: ``1, 2`` would be the
      nodes ``1,`` and ``2``) or ``->`` (edge labels could not name it).
    """
    path = Path(path)
    text = read_input_text(path, "edge list", GraphError)
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) not in (2, 3):
            raise GraphError(f"{path}:{lineno}: expected 'u v' or 'u v weight', got {show(line)}")
        for label in tokens[:2]:
            _check_label(label, path, lineno)
        weight = 1.0
        if len(tokens) == 3:
            weight = number_text(tokens[2])
            if weight is None:
                raise GraphError(
                    f"{path}:{lineno}: weight {show(tokens[2])} is not a number (write decimal "
                    "digits such as 2, 0.5 or 1e3)"
                )
            if not (weight > 0 and math.isfinite(weight)):
                raise GraphError(f"{path}:{lineno}: weight must be positive and finite")
        rows.append((tokens[0], tokens[1], weight, lineno))
    if not rows:
        raise GraphError(f"{path}: no edges found")
    as_int = all(_is_int(u) and _is_int(v) for u, v, _, _ in rows)
    g = nx.Graph()
    for u, v, w, lineno in rows:
        if u == v:
            raise GraphError(f"{path}:{lineno}: self-loop {u}-{v} is not allowed")
        a, b = (int(u), int(v)) if as_int else (u, v)
        if g.has_edge(a, b):  # a second line would silently replace the first one's weight
            raise GraphError(
                f"{path}:{lineno}: edge {u}-{v} is listed twice (first on line "
                f"{g.edges[a, b]['line']}); give each undirected edge once"
            )
        g.add_edge(a, b, weight=w, line=lineno)
    total = sum(w for _, _, w, _ in rows)
    if not math.isfinite(total) or total > 1e100:
        raise GraphError(
            f"{path}: weights sum to {total:.3g}; keep them below 1e100 "
            "(rescale them: normalized coupling only sees their ratios)"
        )
    for _, _, d in g.edges(data=True):
        del d["line"]
    return g


def build_graph(spec: dict, seed: int | None = None) -> nx.Graph:
    """Build a graph from the config's ``graph`` mapping and check it is usable.

    The graph must be connected, have at least two nodes and no self-loops. ``seed`` seeds a
    random networkx generator whose ``args`` give none (see :func:`from_networkx`).
    """
    kind = spec.get("kind")
    if kind == "lollipop":
        g = lollipop(_int_arg(spec, "nodes", hi=MAX_BUILT_NODES), _int_arg(spec, "path"))
    elif kind == "barbell":
        g = barbell(_int_arg(spec, "m1", hi=MAX_BUILT_NODES), _int_arg(spec, "m2", 0, hi=MAX_BUILT_NODES))
    elif kind == "atlas":
        g = atlas(_int_arg(spec, "index"))
    elif kind == "networkx":
        args = spec.get("args") or {}
        if not isinstance(args, dict):
            raise GraphError(f"graph.args must be a mapping of keyword arguments, got {args!r}")
        if not isinstance(spec.get("generator"), str):
            raise GraphError(
                f"graph.generator must be a networkx function name, got {spec.get('generator')!r}"
            )
        weighted = spec.get("weighted", False)
        if not isinstance(weighted, bool):
            raise GraphError(f"graph.weighted must be true or false, got {weighted!r}")
        g = from_networkx(spec["generator"], args, seed=seed, weighted=weighted)
    elif kind == "edgelist":
        if not isinstance(spec.get("path"), str):
            raise GraphError(f"graph.path must be a file path, got {spec.get('path')!r}")
        g = from_edgelist(spec["path"])
    else:
        raise GraphError(f"graph.kind must be one of {', '.join(GRAPH_KINDS)}; got {kind!r}")
    if g.number_of_nodes() < 2:
        raise GraphError("graph needs at least 2 nodes")
    if nx.number_of_selfloops(g):
        raise GraphError("graph has self-loops; remove them")
    if not nx.is_connected(g):
        parts = nx.number_connected_components(g)
        raise GraphError(f"graph is disconnected ({parts} components); antisync needs a connected graph")
    return g


def node_order(g: nx.Graph) -> list:
    """The fixed node order used for matrices: sorted labels when sortable, else insertion order."""
    nodes = list(g.nodes)
    try:
        return sorted(nodes)
    except TypeError:
        return nodes


def omega_matrix(g: nx.Graph) -> np.ndarray:
    """Dense symmetric weight matrix ``Omega`` in :func:`node_order`."""
    return nx.to_numpy_array(g, nodelist=node_order(g), weight="weight", dtype=np.float64)


def edge_label(u, v) -> str:
    """``"u->v"``, the label of a directed edge in configs and outputs."""
    return f"{u}->{v}"


def all_directed_edges(g: nx.Graph) -> list[tuple]:
    """Every directed edge ``(u, v)`` of ``g``, sorted by the node order of ``u`` then ``v``."""
    pos = {v: i for i, v in enumerate(node_order(g))}
    pairs = [(u, v) for u, v in g.edges] + [(v, u) for u, v in g.edges]
    return sorted(pairs, key=lambda e: (pos[e[0]], pos[e[1]]))


def parse_edge(text: str, g: nx.Graph) -> tuple:
    """Parse ``"a->b"`` into node labels of ``g``; :class:`GraphError` if it is not an edge."""
    parts = str(text).split("->")
    if len(parts) != 2 or not parts[0].strip() or not parts[1].strip():
        raise GraphError(f"edge {text!r} is not of the form 'a->b'")
    by_name = {str(v): v for v in g.nodes}
    a, b = (by_name.get(p.strip()) for p in parts)
    if a is None or b is None or not g.has_edge(a, b):
        sample = ", ".join(edge_label(u, v) for u, v in all_directed_edges(g)[:6])
        raise GraphError(f"edge {text!r} is not in the graph; valid edges look like {sample}, ...")
    return a, b


def _int_arg(spec: dict, key: str, default: int | None = None, hi: int | None = None) -> int:
    """An integer graph parameter (:func:`antisync.validation.parse_integer`: ``6``, ``6.0``,
    a numpy integer); 6.9 or true are refused rather than truncated."""
    value = spec.get(key, default)
    try:
        n = parse_integer(f"graph.{key}", value, -(2**63), 2**63 - 1, "-2**63..2**63-1")
    except ConfigError:
        raise GraphError(f"graph.{key} must be an integer, got {show(value)}") from None
    if hi is not None and n > hi:
        raise GraphError(
            f"graph.{key} must be at most {hi:,} (a clique of that size is "
            f"{hi * (hi - 1) // 2:,} links), got {n:,}"
        )
    return n


def _unit_weights(g: nx.Graph) -> nx.Graph:
    nx.set_edge_attributes(g, 1.0, "weight")
    return g


# "-0" is not plain: int() would merge it with "0"
_PLAIN_INT = re.compile(r"(?:0|-?[1-9][0-9]*)\Z")


def _is_int(token: str) -> bool:
    return bool(_PLAIN_INT.match(token))


def _check_label(label: str, path: Path, lineno: int) -> None:
    """Refuse a node label that would silently name another node (see :func:`from_edgelist`)."""
    where = f"{path}:{lineno}: node label {show(label)}"
    if _is_int(label):
        return
    try:
        value = int(label)
    except ValueError:
        value = None
    if value is not None:
        raise GraphError(f"{where} is the integer {value} written another way; write it as {value}")
    if DECIMAL.match(label):
        raise GraphError(f"{where} is a number but not an integer; node labels are integers or names")
    for sep in (",", ";", "->"):
        if sep in label:
            raise GraphError(f"{where} contains {sep!r}; separate columns with spaces or tabs ('u v weight')")


def _edge_invariant(g: nx.Graph, e: tuple) -> tuple:
    a, b = e
    return (
        g.degree(a),
        g.degree(b),
        tuple(sorted(g.degree(x) for x in g[a])),
        tuple(sorted(g.degree(x) for x in g[b])),
    )


def _maps_onto(g: nx.Graph, e: tuple, f: tuple) -> bool:
    """Is there an automorphism of ``g`` with ``e[0] -> f[0]`` and ``e[1] -> f[1]``?"""
    from networkx.algorithms.isomorphism import GraphMatcher, categorical_node_match

    g1, g2 = nx.Graph(g), nx.Graph(g)
    nx.set_node_attributes(g1, 0, "pin")
    nx.set_node_attributes(g2, 0, "pin")
    g1.nodes[e[0]]["pin"], g1.nodes[e[1]]["pin"] = 1, 2
    g2.nodes[f[0]]["pin"], g2.nodes[f[1]]["pin"] = 1, 2
    match = categorical_node_match("pin", 0)
    return GraphMatcher(
        g1, g2, node_match=match, edge_match=lambda x, y: x.get("weight", 1.0) == y.get("weight", 1.0)
    ).is_isomorphic()


def edge_orbits(g: nx.Graph, edges: list | None = None) -> dict:
    """Map each directed edge to the representative of its orbit under the automorphisms of ``g``.

    Two directed edges ``a -> b`` and ``c -> d`` are in one orbit when an automorphism (a
    weight-preserving relabelling of the nodes) maps ``a`` to ``c`` and ``b`` to ``d``; then
    damaging either gives the same distribution of ``(tau0, tau(beta))`` and the same Lambda.

    Parameters
    ----------
    g : networkx.Graph
    edges : list of (u, v), optional
        The directed edges to group (default: all, in :func:`~antisync.graphs.all_directed_edges`
        order). The representative of an orbit is its first edge in this order.

    Returns
    -------
    dict
        ``{edge: representative}`` for every edge in ``edges``.

    Notes
    -----
    Rather than enumerating the automorphism group (18! elements for a 19-clique), each edge
    is tested against the representatives found so far with one VF2 search in which the two
    end nodes are pinned; edges with different degree invariants are never compared.
    """
    edges = list(all_directed_edges(g) if edges is None else edges)
    reps: list[tuple] = []
    out = {}
    for e in edges:
        inv = _edge_invariant(g, e)
        for r in reps:
            if _edge_invariant(g, r) == inv and _maps_onto(g, r, e):
                out[e] = r
                break
        else:
            reps.append(e)
            out[e] = e
    return out
