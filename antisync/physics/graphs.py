"""Graph builders with the paper's node labels, graph files, and directed-edge parsing.

Every builder returns an undirected :class:`networkx.Graph` whose edges carry a ``weight``
(1.0 unless an edge list says otherwise). :func:`omega_matrix` turns it into the dense
weight matrix ``Omega`` in the fixed node order of :func:`node_order`.

Graph files (docs/graphs.md): edge lists (:func:`from_edgelist`: whitespace, CSV, tabs, quoted
names, an optional header line), GraphML (:func:`from_graphml`) and GML (:func:`from_gml`).
A networkx graph object becomes a config graph spec with :func:`graph_spec` (``kind: inline``,
its links written out), so that a result file holds the graph itself.
"""

from __future__ import annotations

import csv
import functools
import inspect
import math
import numbers
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import networkx as nx
import numpy as np
from networkx.algorithms.isomorphism import GraphMatcher, categorical_node_match

from antisync.errors import AntisyncError, ConfigError
from antisync.validation import (
    DECIMAL,
    number_text,
    parse_integer,
    read_input_bytes,
    read_input_text,
    show,
)

__all__ = [
    "GraphError",
    "all_directed_edges",
    "barbell",
    "build_graph",
    "edge_delimiter",
    "edge_label",
    "edge_orbits",
    "from_edgelist",
    "from_gml",
    "from_graphml",
    "from_inline",
    "graph_spec",
    "lollipop",
    "node_order",
    "omega_matrix",
    "parse_edge",
    "refined_colors",
    "link_values",
    "simple_graph",
]

GRAPH_KINDS = ("lollipop", "barbell", "atlas", "networkx", "edgelist", "graphml", "gml", "inline")
#: Largest lollipop or barbell antisync builds: their cliques grow as N^2 links.
MAX_BUILT_NODES = 2000
#: The most total weight a graph may carry: the raw Laplacian's spectrum overflows long before
#: float64's 1.8e308 (edge lists, graph files and graph objects alike).
MAX_TOTAL_WEIGHT = 1e100
#: ``graph.delimiter`` by name; ``None`` splits at runs of whitespace (the default).
DELIMITER_NAMES = {"whitespace": None, " ": None, "tab": "\t", "\\t": "\t"}
#: The delimiter of an edge list without ``graph.delimiter``, by the file's suffix.
SUFFIX_DELIMITERS = {".csv": ",", ".tsv": "\t"}
#: A first line naming its columns like this (case ignored) is a header (``graph.header: auto``).
HEADER_PAIRS = frozenset(
    {("source", "target"), ("from", "to"), ("u", "v"), ("node1", "node2"), ("src", "dst")}
)
#: Characters that cannot separate columns: quotes and comments, and parts of numbers.
_NOT_DELIMITERS = set('"#.+-_')
#: Graph files that are not edge lists, by suffix: the kind that reads them.
_OTHER_FORMATS = {".graphml": "graphml", ".gml": "gml"}


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


def from_edgelist(
    path: str | Path, delimiter: str | None = None, header: bool | str | None = None
) -> nx.Graph:
    """Read ``u v [weight]`` lines: one link per line. Integer labels stay integers.

    Parameters
    ----------
    path : str or Path
        The file, read by :func:`antisync.validation.read_input_text` (a regular file, UTF-8;
        a byte-order mark is dropped, UTF-16 with one decoded; NUL or control characters
        refused).
    delimiter : str, optional
        What separates the columns (:func:`edge_delimiter`): ``None`` (the default) means
        ``,`` for a ``.csv`` file, a tab for a ``.tsv`` file and runs of whitespace (spaces or
        tabs) for any other; ``"whitespace"``, ``"tab"`` or one character such as ``","``
        ``";"`` ``"|"`` choose.
    header : bool or "auto", optional
        ``True``: the first line (after comments) names the columns and is skipped; ``False``:
        every line is a link; ``None`` or ``"auto"`` (the default): the first line is skipped
        when its first two columns are a pair of :data:`HEADER_PAIRS` (``source,target``,
        ``from to``, ``u v``, ... any case), no other column is a number, and neither word is
        a node of another line. A header of more than three columns (``source target weight
        alpha``) names them: the weight is the column ``weight`` (every weight 1 without one),
        every line has as many columns, and the others are there for a law's
        ``model.edge_params`` (:func:`link_values`).

    Notes
    -----
    With whitespace columns, a name holding spaces is written in double quotes
    (``"Evelyn Jefferson" "Brenda Rogers" 6``; ``""`` inside quotes is one ``"``) and ``#``
    outside quotes starts a comment. With a delimiter the lines are read by :mod:`csv`
    (quotes as in spreadsheets, spaces around a column ignored) and ``#`` starts a comment at
    the start of a line only, so a name may hold ``#``.

    Nothing is read as something other than it says; each of these is refused with one line
    naming the line:

    - a weight not in the number grammar :data:`antisync.validation.DECIMAL` (``1,5``,
      ``0x10``, ``1_000``, a unicode minus: Python's ``float`` would read ``1_000``);
    - a label that is an integer written another way (``01``, ``+1``, ``1_0``, non-ASCII
      digits: ``int()`` would merge ``01`` with ``1`` into one node) or a non-integer number
      (``1.0`` would be a node apart from ``1``);
    - with whitespace columns, an unquoted label holding ``,`` or ``;`` (another file
      format's separator: ``1, 2`` would be the nodes ``1,`` and ``2``); any label holding
      ``->`` (edge labels could not name it);
    - a link listed twice (in either direction), a self-loop, an empty label.
    """
    path = Path(path)
    if path.suffix.lower() in _OTHER_FORMATS:
        kind = _OTHER_FORMATS[path.suffix.lower()]
        raise GraphError(
            f"{path} is a {kind.upper().replace('GRAPHML', 'GraphML')} file, not an edge list: "
            f"give graph: {{kind: {kind}, path: {path.name}}}"
        )
    sep = edge_delimiter(delimiter, path)
    header = _header_option(header)
    text = read_input_text(path, "edge list", GraphError)
    rows = _split_rows(text, path, sep)
    # without graph.header, a bad weight on the first line may be a header's word
    first = rows[0][0] if rows and header is None else None
    names = None
    if rows and (header is True or (header is None and _is_header(rows))):
        names = [text for text, _ in rows[0][2]]
        rows, first = rows[1:], None
    # a header of more columns names them: the weight is the column 'weight', the others are
    # read by whoever asks for them (a law's model.edge_params)
    at, width = 2, 3
    if names is not None and len(names) > 3:
        lower = [name.lower() for name in names[2:]]
        at = 2 + lower.index("weight") if "weight" in lower else None
        width = len(names)
    parsed = []
    for lineno, line, fields in rows:
        if width > 3 and len(fields) != width:
            raise GraphError(
                f"{path}:{lineno}: expected {width} columns as the header names them "
                f"({', '.join(names)}), got {show(line)}" + _columns_hint(line, sep, len(fields))
            )
        if width == 3 and len(fields) not in (2, 3):
            raise GraphError(
                f"{path}:{lineno}: expected 'u v' or 'u v weight', got {show(line)}"
                + _columns_hint(line, sep, len(fields))
            )
        for label, plain in fields[:2]:
            _check_label(label, path, lineno, plain)
        weight = 1.0
        if at is not None and len(fields) > at:
            token = fields[at][0]
            weight = number_text(token)
            if weight is None:
                hint = "; a header line? give graph.header: true" if lineno == first else ""
                raise GraphError(
                    f"{path}:{lineno}: weight {show(token)} is not a number (write decimal "
                    f"digits such as 2, 0.5 or 1e3){hint}"
                )
            if not (weight > 0 and math.isfinite(weight)):
                raise GraphError(f"{path}:{lineno}: weight must be positive and finite")
        parsed.append((fields[0][0], fields[1][0], weight, lineno))
    if not parsed:
        raise GraphError(f"{path}: no edges found")
    as_int = all(_is_int(u) and _is_int(v) for u, v, _, _ in parsed)
    g = nx.Graph()
    for u, v, w, lineno in parsed:
        if u == v:
            raise GraphError(f"{path}:{lineno}: self-loop {u}-{v} is not allowed")
        a, b = (int(u), int(v)) if as_int else (u, v)
        if g.has_edge(a, b):  # a second line would silently replace the first one's weight
            raise GraphError(
                f"{path}:{lineno}: edge {u}-{v} is listed twice (first on line "
                f"{g.edges[a, b]['line']}); give each undirected edge once"
            )
        g.add_edge(a, b, weight=w, line=lineno)
    total = sum(w for _, _, w, _ in parsed)
    if not math.isfinite(total) or total > MAX_TOTAL_WEIGHT:
        raise GraphError(
            f"{path}: weights sum to {total:.3g}; keep them below 1e100 "
            "(rescale them: normalized coupling only sees their ratios)"
        )
    for _, _, d in g.edges(data=True):
        del d["line"]
    return g


def link_values(path: str | Path, g: nx.Graph, column: str | None = None, what: str = "edge values") -> dict:
    """``{(u, v): value}`` for every link of ``g`` (both directions of a link share its value),
    read from an edge list: ``u v value`` lines, or a file whose first line names its columns
    (``source target weight alpha``, any pair of :data:`HEADER_PAIRS` first) and ``column`` the
    one to read (the graph's own edge list can carry a law's edge parameters so). Delimiters as
    :func:`from_edgelist` takes them by default (by the file's suffix).

    Labels are matched by their text (``1`` in the file is node ``1``). Refused with one line
    naming the file and the line (:class:`GraphError`): a link the graph does not have, a link
    given twice, a value that is not a finite number in the grammar of
    :data:`antisync.validation.DECIMAL`, a missing column, and a link of the graph the file does
    not give (none is filled in silently)."""
    path = Path(path)
    where = f"{what} {path}"
    sep = edge_delimiter(None, path)
    rows = _split_rows(read_input_text(path, what, GraphError), path, sep)
    if not rows:
        raise GraphError(f"{where}: no links found; give one 'u v value' line per link")
    header = len(rows[0][2]) >= 3 and _is_header(rows)  # the edge list's own rule
    if header:
        names, rows = [text for text, _ in rows[0][2]], rows[1:]
        if column is None and len(names) != 3:
            raise GraphError(
                f"{where}: its header names {len(names) - 2} value columns ({', '.join(names[2:])}); "
                "give column: NAME"
            )
        at = 2 if column is None else 2 + names[2:].index(column) if column in names[2:] else None
        if at is None:
            raise GraphError(f"{where}: no column {column!r} in its header (columns: {', '.join(names[2:])})")
    elif column is not None:
        raise GraphError(
            f"{where}: column {column!r} needs a first line that names the columns, e.g. "
            f"'source target {column}'"
        )
    else:
        at = 2
    by_name = {str(v): v for v in g.nodes}
    out: dict = {}
    seen: dict = {}
    for lineno, line, fields in rows:
        if len(fields) <= at or (not header and len(fields) != 3):
            raise GraphError(f"{where}:{lineno}: expected 'u v value', got {show(line)}")
        a, b = (by_name.get(text) for text, _ in fields[:2])
        if a is None or b is None or not g.has_edge(a, b):
            raise GraphError(f"{where}:{lineno}: {fields[0][0]}-{fields[1][0]} is not a link of the graph")
        token = fields[at][0]
        value = number_text(token)
        if value is None or not math.isfinite(value):
            raise GraphError(
                f"{where}:{lineno}: {show(token)} is not a finite number (write decimal digits such "
                "as -0.25 or 1.5e-3)"
            )
        if (a, b) in out:
            raise GraphError(
                f"{where}:{lineno}: the link {a}-{b} is given twice (first on line {seen[a, b]}); "
                "give each link once"
            )
        out[a, b] = out[b, a] = value
        seen[a, b] = seen[b, a] = lineno
    for a, b in g.edges:
        if (a, b) not in out:
            raise GraphError(
                f"{where}: the link {a}-{b} is not given ({len(out) // 2} of {g.number_of_edges()} are); "
                "give every link of the graph a value"
            )
    return out


def edge_delimiter(value, path: str | Path = "") -> str | None:
    """``graph.delimiter`` as the character between an edge list's columns; ``None`` for runs
    of whitespace.

    ``None`` (not given) is ``,`` for a ``.csv`` file, a tab for ``.tsv``, whitespace for any
    other (:data:`SUFFIX_DELIMITERS`); ``"whitespace"`` (or ``" "``) and ``"tab"`` (or
    ``"\\t"`` as two characters) by name; else one character that is not a letter, a digit,
    a quote, ``#`` or part of a number.
    """
    if value is None:
        return SUFFIX_DELIMITERS.get(Path(path).suffix.lower())
    if isinstance(value, str) and value.lower() in DELIMITER_NAMES:
        return DELIMITER_NAMES[value.lower()]
    if isinstance(value, str) and len(value) == 1 and value not in _NOT_DELIMITERS:
        if value == "\t" or (value.isprintable() and not value.isalnum() and not value.isspace()):
            return value
    raise GraphError(
        "graph.delimiter must be whitespace (the default; ',' for a .csv file, tab for .tsv), "
        f"tab or one character such as ',' ';' '|', got {show(value)}"
    )


def _header_option(value) -> bool | None:
    """``graph.header``: True, False, or None for auto (``"auto"`` or not given)."""
    if value is None or value == "auto":
        return None
    if isinstance(value, bool):
        return value
    raise GraphError(
        "graph.header must be true (the first line names the columns), false (every line is a "
        f"link) or auto (the default: a first line such as 'source,target,weight'), got {show(value)}"
    )


def _split_rows(text: str, path: Path, sep: str | None) -> list[tuple]:
    """``(lineno, line, [(column, plain), ...])`` of every line that is not blank or a
    comment; ``plain``: an unquoted column of a whitespace file (checked for ``,`` and ``;``)."""
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        where = f"{path}:{lineno}"
        if sep is None:
            fields = _split_whitespace(line, where)
        elif line.strip() and not line.lstrip().startswith("#"):
            fields = [(c.strip(), False) for c in _split_delimited(line, sep, where)]
        else:
            fields = []
        if fields:
            rows.append((lineno, line, fields))
    return rows


def _split_whitespace(line: str, where: str) -> list[tuple[str, bool]]:
    """The columns of ``line`` between runs of whitespace, as ``(text, plain)``. A column
    that starts with ``"`` runs to its closing quote (``""`` inside is one ``"``); ``#``
    outside quotes starts a comment."""
    out = []
    i, n = 0, len(line)
    while i < n:
        if line[i].isspace():
            i += 1
        elif line[i] == "#":
            break
        elif line[i] == '"':
            parts, j = [], i + 1
            while True:
                k = line.find('"', j)
                if k < 0:
                    raise GraphError(
                        f'{where}: a quote " is not closed in {show(line)}; write a name with '
                        'spaces in double quotes, e.g. "Evelyn Jefferson"'
                    )
                parts.append(line[j:k])
                if line[k + 1 : k + 2] != '"':
                    j = k + 1
                    break
                parts.append('"')
                j = k + 2
            if j < n and not line[j].isspace() and line[j] != "#":
                raise GraphError(
                    f"{where}: text right after a closing quote in {show(line)}; separate the "
                    "columns with spaces"
                )
            out.append(("".join(parts), False))
            i = j
        else:
            j = i
            while j < n and not line[j].isspace() and line[j] != "#":
                j += 1
            out.append((line[i:j], True))
            i = j
    return out


def _split_delimited(line: str, sep: str, where: str) -> list[str]:
    """The columns of one line of a delimited file, read by :mod:`csv` (spreadsheet quotes)."""
    try:
        return next(csv.reader([line], delimiter=sep, strict=True, skipinitialspace=True))
    except csv.Error as exc:
        raise GraphError(
            f"{where}: {exc} in {show(line)}; quote a whole name that holds {_delimiter_name(sep)} "
            'or a quote, e.g. "Smith, John"'
        ) from None


def _is_header(rows: list[tuple]) -> bool:
    """Is the first row a header (``graph.header: auto``, see :func:`from_edgelist`)?"""
    fields = [text for text, _ in rows[0][2]]
    if len(fields) < 2 or (fields[0].lower(), fields[1].lower()) not in HEADER_PAIRS:
        return False
    if any(number_text(name) is not None for name in fields[2:]):
        return False
    nodes = {text for row in rows[1:] for text, _ in row[2][:2]}
    return fields[0] not in nodes and fields[1] not in nodes


def _delimiter_name(sep: str | None) -> str:
    return {None: "whitespace", "\t": "a tab"}.get(sep, repr(sep))


def _columns_hint(line: str, sep: str | None, count: int) -> str:
    """Why a line may not have 2 or 3 columns, and the option that reads it."""
    if sep is None:
        if "\t" in line.strip() and count > 3:
            return "; its columns look tab-separated: give graph.delimiter: tab"
        others = [c for c in (",", ";", "|") if c in line]
        if count < 2 and others:
            return f"; its columns look separated by {others[0]!r}: give graph.delimiter: {others[0]!r}"
        if count > 3:
            return (
                '; a node name with spaces needs double quotes ("Evelyn Jefferson") or a '
                "graph.delimiter such as tab or ','"
            )
        return ""
    others = [c for c in (",", ";", "\t", "|") if c != sep and c in line]
    if count == 1 and others:
        yaml = "tab" if others[0] == "\t" else repr(others[0])
        return (
            f"; it holds no {_delimiter_name(sep)} (graph.delimiter) but {_delimiter_name(others[0])}: "
            f"give graph.delimiter: {yaml}"
        )
    return f" (columns separated by {_delimiter_name(sep)}, graph.delimiter)"


def from_graphml(path: str | Path, weight: str | None = None) -> nx.Graph:
    """Read a GraphML file (:func:`networkx.parse_graphml`; what Gephi and networkx write).

    Node ids are the labels (integers when every id is one, as in edge lists); the edge
    attribute ``weight`` (``graph.weight``; ``None``: the attribute ``weight``) gives the
    weights, see :func:`_weight_attribute` for an attribute that edges lack; parallel edges
    add up. A directed graph, XML that is not well formed or not GraphML is refused with one
    line.
    """
    path = Path(path)
    data = read_input_bytes(path, "GraphML file", GraphError)
    try:
        g = nx.parse_graphml(data)
    except ET.ParseError as exc:
        raise GraphError(
            f"{path} is not well-formed XML ({exc}); give a GraphML file (networkx.write_graphml "
            "or Gephi's GraphML export writes one)"
        ) from None
    except Exception as exc:  # noqa: BLE001 -- networkx's message names what it could not read
        raise GraphError(f"{path}: networkx cannot read it as GraphML: {_reason(exc)}") from None
    # a <default> of an edge key is the value of every edge without its own <data> (GraphML's
    # rule); networkx keeps it aside in G.graph["edge_default"] instead of on the edges
    defaults = g.graph.get("edge_default") or {}
    for *_, d in g.edges(data=True):
        for key, value in defaults.items():
            d.setdefault(key, value)
    return _file_graph(g, path, "GraphML", 'edgedefault="undirected"', weight)


def from_gml(path: str | Path, weight: str | None = None) -> nx.Graph:
    """Read a GML file (:func:`networkx.parse_gml`).

    Nodes are named by their ``label`` (by their ``id`` when some node has no label); the
    edge attribute ``weight`` (``graph.weight``; ``None``: the attribute ``weight``) gives the
    weights, see :func:`_weight_attribute` for an attribute that edges lack; the parallel
    edges of a ``multigraph 1`` file add up. A directed graph or a file that is not GML is
    refused with one line.
    """
    path = Path(path)
    text = read_input_text(path, "GML file", GraphError)
    try:
        g = nx.parse_gml(text, label=None)
    except Exception as exc:  # noqa: BLE001 -- networkx's message names what it could not read
        raise GraphError(f"{path}: networkx cannot read it as GML: {_reason(exc)}") from None
    labels = dict(g.nodes(data="label"))
    if labels and all(label is not None for label in labels.values()):
        seen: dict = {}
        for v, label in labels.items():
            if label in seen:
                raise GraphError(
                    f"{path}: nodes {seen[label]} and {v} have the same label {show(label)}; "
                    "give every node its own label"
                )
            seen[label] = v
        g = nx.relabel_nodes(g, labels)
    return _file_graph(g, path, "GML", "directed 0", weight)


def _reason(exc: Exception) -> str:
    """networkx's message on one line (a GraphML file without a graph raises a TypeError)."""
    if isinstance(exc, TypeError):
        return 'no <graph> element in the GraphML namespace (xmlns="http://graphml.graphdrawing.org/xmlns")'
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def _file_graph(g: nx.Graph, path: Path, fmt: str, undirected: str, weight: str | None) -> nx.Graph:
    """A graph read from a file as :func:`simple_graph` makes it, its labels and its weight
    attribute (:func:`_weight_attribute`) checked."""
    if g.is_directed():
        raise GraphError(
            f"{path}: the {fmt} graph is directed; antisync needs an undirected graph (Omega is "
            f"symmetric; damage on a->b and b->a are the two directions of one link): save it "
            f"with {undirected}, or pass networkx's G.to_undirected() to antisync.run"
        )
    if g.number_of_nodes() and all(isinstance(v, str) and _is_int(v) for v in g.nodes):
        g = nx.relabel_nodes(g, int)  # ids "1", "2": the nodes 1, 2, as in an edge list
    for v in g.nodes:
        if "->" in str(v):
            raise GraphError(f"{path}: node {show(v)} contains '->'; edge labels 'a->b' could not name it")
    return simple_graph(g, str(path), _weight_attribute(g, path, fmt, weight))


def _weight_attribute(g: nx.Graph, path: Path, fmt: str, weight: str | None) -> str:
    """The edge attribute that holds the weights of the file's graph ``g``, checked.

    ``weight``: ``graph.weight`` as given, ``None`` when not given (the attribute ``weight``).
    A file whose edges all lack the attribute has unit weights only when the attribute was
    not named: a named one (``graph.weight: value``) that no edge has is a misspelling or the
    wrong file, refused naming the attributes the edges do have. An attribute that some edges
    have and others lack is refused either way (naming how many lack it and one of them): a
    weight of 1 for those would be a number the file never gave.
    """
    attr = "weight" if weight is None else weight
    edges = list(g.edges(data=True))
    lacking = [(u, v) for u, v, d in edges if attr not in d]
    if not lacking or (len(lacking) == len(edges) and weight is None):
        return attr
    if not all(_usable_weight(d[attr]) for *_, d in edges if attr in d):
        return attr  # a value that is no weight at all is the first thing to say (simple_graph)
    if len(lacking) == len(edges):
        names = sorted({str(k) for *_, d in edges for k in d})
        have = (
            f"the edges have {', '.join(names)}"
            if names
            else "the edges have no attributes (leave graph.weight out for unit weights)"
        )
        raise GraphError(
            f"{path}: graph.weight names the edge attribute {attr!r}, which no edge of this "
            f"{fmt} file has; {have}"
        )
    u, v = lacking[0]
    raise GraphError(
        f"{path}: {len(lacking)} of {len(edges)} edges lack the weight attribute {attr!r} "
        f"(e.g. {u}-{v}); give every edge a weight (or none, for unit weights)"
    )


def simple_graph(graph: nx.Graph, where: str, weight: str = "weight") -> nx.Graph:
    """``graph`` as a simple undirected :class:`networkx.Graph` whose every edge has a
    positive finite float ``weight`` (the attribute ``weight``, default 1).

    The parallel edges of a multigraph add up: ``Omega_ij`` is the total weight between ``i``
    and ``j``. Nodes keep their insertion order (the node order of unsortable labels). Refused
    with one line starting with ``where``: a directed graph, a self-loop, a weight that is no
    positive finite number, weights summing above :data:`MAX_TOTAL_WEIGHT`, two nodes that
    print alike (records name links ``"a->b"`` by the labels' text). Connectivity is the
    caller's check (:func:`build_graph`).
    """
    if graph.is_directed():
        raise GraphError(
            f"{where}: antisync needs an undirected graph (Omega is symmetric), got a "
            f"{type(graph).__name__}; give graph.to_undirected() if each link counts in both directions"
        )
    g = nx.Graph()
    g.add_nodes_from(graph.nodes)
    for u, v, w in graph.edges(data=weight, default=1.0):
        if u == v:
            raise GraphError(f"{where}: self-loop {u}-{v} is not allowed; remove it")
        if not _usable_weight(w):
            raise GraphError(
                f"{where}: edge {u}-{v} has {weight} {show(w)}; weights must be positive finite numbers"
            )
        # parallel links of a multigraph add up: Omega_ij is the total weight between i and j
        total = float(w) + (g.edges[u, v]["weight"] if g.has_edge(u, v) else 0.0)
        g.add_edge(u, v, weight=total)
    total = sum(w for *_, w in g.edges(data="weight"))
    if not total <= MAX_TOTAL_WEIGHT:
        raise GraphError(
            f"{where}: the weights sum to {total:.3g}; keep them below {MAX_TOTAL_WEIGHT:.0e} "
            "(rescale them: normalized coupling only sees their ratios)"
        )
    labels: dict[str, object] = {}
    for v in g.nodes:  # records name links "a->b" by the labels' text: two alike would be one
        other = labels.setdefault(str(v), v)
        if other is not v:
            raise GraphError(
                f"{where}: nodes {other!r} and {v!r} print alike ({str(v)!r}), so their links "
                "could not be told apart; relabel them (networkx.convert_node_labels_to_integers)"
            )
    return g


def _usable_weight(w) -> bool:
    """A positive finite real number (not a bool, not a string of one, not an integer too
    large for a float)."""
    if isinstance(w, bool) or not isinstance(w, numbers.Real):
        return False
    try:
        return w > 0 and math.isfinite(w)
    except OverflowError:  # math.isfinite of an int beyond float's range
        return False


def graph_spec(graph: nx.Graph, where: str = "graph") -> dict:
    """The config graph spec of a networkx graph object: ``{kind: inline, links: [...]}``.

    What :func:`antisync.run` stores for ``{"graph": G}``: every link ``[u, v]`` or
    ``[u, v, weight]`` (weights other than 1), and ``nodes`` when their order or a node
    without links is not told by the links. The graph is read as
    :func:`antisync.measures.for_graph` reads it (:func:`simple_graph`: the ``weight``
    attribute, default 1; parallel edges add up; directed graphs refused). Node labels must be
    integers or strings (numpy integers count), so that the result file's YAML holds them.
    ``where`` starts every error message (``graph``, ``sweep.graphs[2]``).
    """
    if not isinstance(graph, nx.Graph):
        raise GraphError(f"{where} must be a networkx graph, got {show(graph)}")
    g = simple_graph(graph, where)
    label = {v: _plain_label(v, where) for v in g.nodes}
    nodes = [label[v] for v in g.nodes]
    links = [[label[u], label[v]] + ([w] if w != 1.0 else []) for u, v, w in g.edges(data="weight")]
    spec: dict = {"kind": "inline", "links": links}
    try:
        sorted(nodes)
        ordered = True
    except TypeError:  # integers and names together: node_order keeps the insertion order
        ordered = False
    if not ordered or any(d == 0 for _, d in g.degree):
        spec["nodes"] = nodes
    return spec


def _plain_label(v, where: str) -> int | str:
    """A graph object's node label as YAML stores it: a Python int or str."""
    if isinstance(v, numbers.Integral) and not isinstance(v, bool):
        out: int | str = int(v)
    elif isinstance(v, str):
        out = str(v)
    else:
        raise GraphError(
            f"{where}: node {show(v)} is a {type(v).__name__}; a graph object is stored in the result "
            "file with integer or string node labels: relabel it, e.g. "
            "networkx.convert_node_labels_to_integers(G, label_attribute='name')"
        )
    if "->" in str(out):
        raise GraphError(f"{where}: node {show(v)} contains '->'; edge labels 'a->b' could not name it")
    return out


def from_inline(links, nodes=None) -> nx.Graph:
    """The graph of a ``kind: inline`` spec: ``links`` is a list of ``[u, v]`` or
    ``[u, v, weight]`` (labels integers or strings, weights positive numbers, each undirected
    link once), ``nodes`` optionally every node in the order to keep."""
    if not isinstance(links, list | tuple) or not links:
        raise GraphError(
            "graph.links must be a non-empty list of links [u, v] or [u, v, weight], e.g. "
            f"[[1, 2], [2, 3, 0.5]], got {show(links)}"
        )
    g = nx.Graph()
    if nodes is not None:
        if not isinstance(nodes, list | tuple):
            raise GraphError(f"graph.nodes must be a list of node labels, got {show(nodes)}")
        for k, v in enumerate(nodes):
            v = _inline_label(v, f"graph.nodes[{k}]")
            if v in g:
                raise GraphError(f"graph.nodes[{k}]: node {show(v)} is listed twice")
            g.add_node(v)
    first: dict = {}
    for k, link in enumerate(links):
        at = f"graph.links[{k}]"
        if not isinstance(link, list | tuple) or len(link) not in (2, 3):
            raise GraphError(f"{at} must be [u, v] or [u, v, weight], got {show(link)}")
        u, v = (_inline_label(x, at) for x in link[:2])
        w = 1.0 if len(link) == 2 else link[2]
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (w > 0 and math.isfinite(w)):
            raise GraphError(f"{at}: weight must be a positive finite number, got {show(w)}")
        if u == v:
            raise GraphError(f"{at}: self-loop {u}-{v} is not allowed")
        for x in (u, v):
            if nodes is not None and x not in g:
                raise GraphError(f"{at}: node {show(x)} is not in graph.nodes")
        key = frozenset((u, v))
        if key in first:
            raise GraphError(
                f"{at}: link {u}-{v} is listed twice (first at graph.links[{first[key]}]); give "
                "each undirected link once"
            )
        first[key] = k
        g.add_edge(u, v, weight=float(w))
    return simple_graph(g, "graph.links")


def _inline_label(v, at: str) -> int | str:
    if isinstance(v, bool) or not isinstance(v, int | str) or v == "":
        raise GraphError(f"{at}: node label {show(v)} must be an integer or a non-empty name")
    if "->" in str(v):
        raise GraphError(f"{at}: node label {show(v)} contains '->'; edge labels 'a->b' could not name it")
    return v


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
    elif kind in ("edgelist", "graphml", "gml"):
        if not isinstance(spec.get("path"), str) or not spec["path"]:
            raise GraphError(f"graph.path must be a file path, got {spec.get('path')!r}")
        if kind == "edgelist":
            g = from_edgelist(spec["path"], spec.get("delimiter"), spec.get("header"))
        else:
            attr = spec.get("weight")  # None: the attribute "weight", unit weights if no edge has it
            if attr is not None and (not isinstance(attr, str) or not attr):
                raise GraphError(
                    f"graph.weight must name the edge attribute that holds the weights (default "
                    f"weight), got {show(attr)}"
                )
            g = (from_graphml if kind == "graphml" else from_gml)(spec["path"], attr)
    elif kind == "inline":
        g = from_inline(spec.get("links"), spec.get("nodes"))
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


def _check_label(label: str, path: Path, lineno: int, plain: bool = True) -> None:
    """Refuse a node label that would silently name another node (see :func:`from_edgelist`);
    ``plain``: an unquoted column of a whitespace file, where ``,`` or ``;`` means another
    file format."""
    where = f"{path}:{lineno}: node label {show(label)}"
    if not label:
        raise GraphError(f"{path}:{lineno}: a node label is empty; every link names two nodes")
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
    for sep in (",", ";") if plain else ():
        if sep in label:
            raise GraphError(
                f"{where} contains {sep!r}; for columns separated by {sep!r} give graph.delimiter: "
                f"{sep!r} (a .csv file has ','), for a name holding it write the name in double quotes"
            )
    if "->" in label:
        raise GraphError(f"{where} contains '->'; edge labels 'a->b' could not name it")


def refined_colors(g: nx.Graph, initial: dict | None = None) -> dict:
    """Each node's class in the coarsest equitable partition of the weighted graph that refines
    ``initial`` (sortable colours by node; default: one class), by colour refinement
    (1-dimensional Weisfeiler-Leman): split nodes whose multisets of ``(weight, neighbour's
    class)`` differ; repeat until no class splits.

    Every automorphism that keeps ``initial`` maps each node to a node of its class (the rounds
    are defined by the graph alone), so nodes of different classes are in different orbits; the
    converse need not hold (a regular graph is one class). Classes are numbered by their sorted
    signatures, the same for the same graph whatever its node order.
    """
    return _refine(g, initial)[0]


def _refine(g: nx.Graph, initial: dict | None = None) -> tuple[dict, int]:
    """:func:`refined_colors` and a certificate of the refinement: the hash of every round's
    sorted signatures, equal for two colourings an automorphism maps onto each other (the
    classes' numbers alone are not: every discrete partition is numbered 0..n-1)."""
    nodes = list(g)
    color = dict.fromkeys(nodes, 0) if initial is None else {v: initial[v] for v in nodes}
    classes = len(set(color.values()))
    rounds = [hash(tuple(sorted(color.values())))]
    while True:
        signature = {
            v: (color[v], tuple(sorted((d.get("weight", 1.0), color[u]) for u, d in g[v].items())))
            for v in nodes
        }
        ordered = sorted(signature.values())
        rounds.append(hash(tuple(ordered)))
        ids = {sig: k for k, sig in enumerate(dict.fromkeys(ordered))}
        color = {v: ids[signature[v]] for v in nodes}
        if len(ids) == classes:
            return color, hash(tuple(rounds))
        classes = len(ids)


def edge_orbits(g: nx.Graph, edges: list | None = None) -> dict:
    """Map each directed edge to the representative of its orbit under the automorphisms of ``g``.

    Two directed edges ``a -> b`` and ``c -> d`` are in one orbit when an automorphism (a
    weight-preserving relabelling of the nodes) maps ``a`` to ``c`` and ``b`` to ``d``; then
    damaging either gives the same distribution of ``(tau0, tau(beta))`` and the same Lambda.

    Parameters
    ----------
    g : networkx.Graph
    edges : list of (u, v), optional
        The directed edges to group (default: all, in :func:`~antisync.physics.graphs.all_directed_edges`
        order). The representative of an orbit is its first edge in this order.

    Returns
    -------
    dict
        ``{edge: representative}`` for every edge in ``edges``.

    Notes
    -----
    Rather than enumerating the automorphism group (18! elements for a 19-clique), each edge
    is tested against the representatives found so far with one VF2 search in which the two
    end nodes are pinned. Only edges whose ends are in the same classes of
    :func:`refined_colors` are compared, and the search maps nodes only within their class:
    automorphisms keep those classes, so neither changes the orbits (nor does refining the
    pinned ends' classes before each search, which keeps it from backtracking through the
    branches of a tree). An automorphism a search finds is a whole relabelling: every edge is
    joined at once to its image under it, and an edge already joined to a representative needs
    no search (a path of 1,025 nodes: one search in all, instead of one per pair of edges).
    """
    edges = list(all_directed_edges(g) if edges is None else edges)
    if not edges:
        return {}
    simple = nx.Graph(g)
    color = refined_colors(simple)
    # the two sides of a search in one graph, so that refining them numbers their classes alike
    both = nx.disjoint_union(simple, simple)  # nodes 0..n-1 and n..2n-1, in g's order
    index = {v: i for i, v in enumerate(simple)}
    n = len(index)
    match = categorical_node_match("color", -1)

    def same_weight(x: dict, y: dict) -> bool:
        return x.get("weight", 1.0) == y.get("weight", 1.0)

    def automorphism(e: tuple, f: tuple) -> dict | None:
        """An automorphism with ``e[0] -> f[0]`` and ``e[1] -> f[1]``, or None. The two ends
        are pinned on each side (``e``'s on the first copy, ``f``'s on the second), the pins
        refined into classes, and the search maps nodes only within them: on a tree, whose
        search could otherwise map a whole branch wrongly and find out only at a pinned leaf,
        the pinned ends' branches are told apart before the search begins."""
        pins = {index[e[0]]: 1, index[e[1]]: 2, n + index[f[0]]: 1, n + index[f[1]]: 2}
        initial = {i: (color[v], pins.get(i, 0)) for i, v in enumerate(simple)}
        initial.update({n + i: (color[v], pins.get(n + i, 0)) for i, v in enumerate(simple)})
        classes = refined_colors(both, initial)
        first = sorted(classes[i] for i in range(n))
        if first != sorted(classes[n + i] for i in range(n)):
            return None  # the two pinned graphs differ in their classes: no automorphism
        g1, g2 = nx.Graph(simple), nx.Graph(simple)
        nx.set_node_attributes(g1, {v: classes[i] for i, v in enumerate(simple)}, "color")
        nx.set_node_attributes(g2, {v: classes[n + i] for i, v in enumerate(simple)}, "color")
        matcher = GraphMatcher(g1, g2, node_match=match, edge_match=same_weight)
        return dict(matcher.mapping) if matcher.is_isomorphic() else None

    # edges joined by the automorphisms found so far (union-find); each set's representative
    parent = {e: e for e in edges}

    def root(e: tuple) -> tuple:
        while parent[e] != e:
            parent[e] = parent[parent[e]]
            e = parent[e]
        return e

    def join(sigma: dict) -> None:
        for a, b in edges:
            image = (sigma[a], sigma[b])
            if image in parent:
                x, y = root((a, b)), root(image)
                if x != y:
                    # the root that holds a representative stays the root
                    parent[y if x in rep_of else x] = x if x in rep_of else y

    @functools.cache
    def pinned(e: tuple) -> int:
        """The certificate of the graph refined with ``e``'s ends pinned: equal for two edges
        an automorphism maps onto each other (computed only for edges that have candidates:
        on a regular graph without automorphisms, every edge is one class before)."""
        initial = {v: (color[v], 1 if v == e[0] else 2 if v == e[1] else 0) for v in simple}
        return _refine(simple, initial)[1]

    rep_of: dict[tuple, tuple] = {}  # root -> the representative of its orbit
    reps: dict[tuple, list[tuple]] = {}  # representatives, by the classes of the two ends
    out = {}
    for e in edges:
        known = rep_of.get(root(e))
        if known is None:
            candidates = reps.setdefault((color[e[0]], color[e[1]]), [])
            for r in candidates:
                if len(candidates) > 1 and pinned(r) != pinned(e):
                    continue
                sigma = automorphism(r, e)
                if sigma is not None:
                    join(sigma)
                    known = r
                    break
            else:
                candidates.append(e)
                rep_of[root(e)] = known = e
        out[e] = known
    return out
