"""The lines of a grid: naming them (``--lines``), picking them from a grid's capacities, and
its bridges (the lines whose removal islands it); :class:`Rows`, a table of per-line rows.
"""

from __future__ import annotations

import json

import networkx as nx
import numpy as np
import yaml

from antisync.grids.errors import GridError
from antisync.plan.config import yaml_load

__all__ = [
    "LINES_SYNTAX",
    "Rows",
    "grid_bridges",
    "lines_of",
    "listed",
    "parse_line_labels",
    "parse_lines",
    "pick_lines",
    "split_bridges",
]


class Rows:
    """A table of per-line rows (``self.rows``) read as a sequence of them."""

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    def __getitem__(self, k):
        return self.rows[k]


def lines_of(omega: np.ndarray, labels: list, lines) -> list[tuple[int, int]]:
    """0-based ``(a, b)``, ``a < b``, of ``lines`` (pairs of ``labels``; None: every line of
    ``omega > 0`` in node order); a pair that names no line of the grid, or a line named twice,
    is a one-line :class:`GridError`."""
    n = omega.shape[0]
    if lines is None:
        i, j = np.nonzero(np.triu(omega > 0))
        return list(zip(i.tolist(), j.tolist(), strict=True))
    index = {lab: k for k, lab in enumerate(labels)}
    out, seen = [], set()
    for line in lines:
        try:
            u, v = line
        except (TypeError, ValueError):
            raise GridError(f"a line is a pair of nodes (u, v), got {line!r}") from None
        if u not in index or v not in index:
            raise GridError(f"line {u}-{v}: no such node (nodes: {labels[0]}..{labels[n - 1]})")
        a, b = sorted((index[u], index[v]))
        if omega[a, b] <= 0:
            raise GridError(f"line {u}-{v} is not a line of the grid")
        if (a, b) in seen:
            raise GridError(f"line {u}-{v} is listed twice")
        seen.add((a, b))
        out.append((a, b))
    return out


def grid_bridges(omega: np.ndarray) -> set:
    """The bridges ``(a, b)``, ``a < b``, of the grid whose lines are ``omega > 0``: the lines
    whose removal islands it. A grid that is not connected is refused (one line)."""
    g = nx.Graph()
    g.add_nodes_from(range(omega.shape[0]))
    g.add_edges_from(zip(*np.nonzero(np.triu(omega > 0)), strict=True))
    if not nx.is_connected(g):
        raise GridError("the grid is not connected: it has no common locked state")
    return {tuple(sorted(e)) for e in nx.bridges(g)}


def split_bridges(omega, labels, todo, bridges, *, refuse: bool, hint: str) -> tuple[list, list]:
    """``(todo without the bridges, the bridges left out as label pairs)``; with ``refuse``, a
    bridge in ``todo`` is a one-line :class:`GridError` instead, ending with ``hint`` (how to
    ask for it anyway)."""
    hit = [e for e in todo if e in bridges]
    if hit and refuse:
        a, b = hit[0]
        more = f" (and {len(hit) - 1} other bridge(s))" if len(hit) > 1 else ""
        raise GridError(
            f"line {labels[a]}-{labels[b]} is a bridge: removing it islands the grid{more}; "
            f"weaken it (beta < 1) or {hint}"
        )
    return [e for e in todo if e not in bridges], [(labels[a], labels[b]) for a, b in hit]


#: How --lines names lines, for the messages (docs/power_grids.md).
LINES_SYNTAX = (
    'write --lines "4-5,2-3", or as a YAML list of pairs for any label: --lines \'[[a-b, c], ["x,y", -2]]\''
)


def parse_line_labels(text: str | None, labels) -> list[tuple] | None:
    """The lines named by ``text`` (``--lines``) as pairs of the grid's ``labels`` (None: every
    line).

    Two forms (docs/power_grids.md):

    - ``"4-5,2-3"``: lines separated by ``,``, each ``u-v``. A label may hold a dash (``a-b-c``,
      the negative integer ``-1``: ``-1--2``): the split is accepted when exactly one dash splits
      the item into two labels of the grid; two such readings are refused, naming both.
    - a YAML (or JSON) list of pairs, ``[[a-b, c], ["x,y", 2], [-1, -2]]``, which can name any
      label (one holding ``,``, or any other character, quoted): an item is the label with that
      typed value (the integer ``2``), else the one label whose string form it is.

    Raises
    ------
    GridError
        An item that names no line, or names one ambiguously: one line saying which and why.
    """
    if text is None:
        return None
    text = str(text)
    labels = list(labels)
    if text.lstrip().startswith("["):
        return _yaml_lines(text, labels)
    by_name: dict[str, list] = {}
    for lab in labels:
        by_name.setdefault(str(lab), []).append(lab)
    return [_dash_line(item.strip(), by_name, labels) for item in text.split(",")]


def _nodes_hint(labels: list) -> str:
    return f"nodes: {labels[0]}..{labels[-1]}" if labels else "the grid has no node"


def _dash_line(item: str, by_name: dict, labels: list) -> tuple:
    """``u-v`` split at the one dash that leaves two labels of the grid."""
    readings = []
    for i, ch in enumerate(item):
        if ch == "-":
            u, v = item[:i].strip(), item[i + 1 :].strip()
            if u in by_name and v in by_name:
                readings.append((u, v))
    if not readings:
        raise GridError(
            f"line {item!r} is not u-v with two nodes of the grid ({_nodes_hint(labels)}); {LINES_SYNTAX}"
        )
    if len(readings) > 1:
        forms = " or ".join("'" + json.dumps([[by_name[u][0], by_name[v][0]]]) + "'" for u, v in readings[:2])
        raise GridError(
            f"line {item!r} reads two ways, {' and '.join(f'{u} to {v}' for u, v in readings[:2])} "
            f"(labels holding '-'): name the one you mean as a YAML list, --lines {forms}"
        )
    u, v = readings[0]
    for name in (u, v):
        if len(by_name[name]) > 1:
            kinds = ", ".join(repr(x) for x in by_name[name])
            raise GridError(
                f"node {name!r} of line {item!r} is two labels of the grid ({kinds}); name it by its typed "
                "value in a YAML list, --lines '[[1, \"1\"]]'"
            )
    return by_name[u][0], by_name[v][0]


def _yaml_lines(text: str, labels: list) -> list[tuple]:
    """``--lines '[[u, v], ...]'``: each item the label of that typed value, else the one
    label of that string form."""
    try:
        items = yaml_load(text)
    except yaml.YAMLError:
        raise GridError(f"--lines {text!r} is not a YAML list of pairs; {LINES_SYNTAX}") from None
    if not isinstance(items, list) or not items:
        raise GridError(f"--lines {text!r} names no line; {LINES_SYNTAX}")
    out = []
    for pair in items:
        if not isinstance(pair, list) or len(pair) != 2:
            raise GridError(f"--lines item {pair!r} is not a pair [u, v]; {LINES_SYNTAX}")
        out.append(tuple(_label(x, pair, labels) for x in pair))
    return out


def _label(x, pair: list, labels: list):
    if isinstance(x, list | dict) or x is None:
        raise GridError(f"--lines item {pair!r}: {x!r} is not a node label")
    typed = [lab for lab in labels if type(lab) is type(x) and lab == x]
    if typed:
        return typed[0]
    named = [lab for lab in labels if str(lab) == str(x)]
    if len(named) == 1:
        return named[0]
    if named:
        kinds = ", ".join(repr(v) for v in named)
        raise GridError(
            f"--lines item {pair!r}: {x!r} could be any of the labels {kinds}; write the label's typed "
            'value (2, or "2" quoted for the string)'
        )
    raise GridError(f"--lines item {pair!r}: no node {x!r} in the grid ({_nodes_hint(labels)})")


def parse_lines(text: str | None, labels) -> list[tuple] | None:
    """``--lines`` as pairs of the grid's labels (None: every line): ``"4-5,2-3"`` (a dash
    inside a label is read when one split gives two labels) or a YAML list of pairs
    ``[[a-b, c], ["x,y", -2]]`` that can name any label (:func:`parse_line_labels`)."""
    return parse_line_labels(text, labels)


def pick_lines(omega: np.ndarray, labels: list, lines, beta: float, islanding: bool):
    """0-based ``(a, b)`` of the lines to change, the bridges among them, the skipped ones: a
    bridge asked for by name is refused unless ``islanding``; with every line asked for, the
    bridges are left out and listed."""
    if isinstance(lines, str):
        lines = parse_lines(lines, labels)
    todo = lines_of(omega, labels, lines)
    bridges = grid_bridges(omega)  # refuses a grid that is not connected, whatever beta
    if beta != 1.0:
        return todo, set(), []
    if islanding:
        return todo, bridges, []
    todo, skipped = split_bridges(
        omega,
        labels,
        todo,
        bridges,
        refuse=lines is not None,
        hint="ask for islanding (islanding=True, --islanding)",
    )
    return todo, bridges, skipped


#: the most line names a table's first line lists (the file and the API hold every one)
LISTED_LINES = 20


def listed(pairs) -> str:
    """``"a-b, c-d"`` of the label pairs ``pairs``, the first :data:`LISTED_LINES` of them and
    how many more (ACTIVSg10k skips 3,927 bridges: a first line of 60,000 characters)."""
    names = [f"{u}-{v}" for u, v in pairs]
    if len(names) <= LISTED_LINES:
        return ", ".join(names)
    return ", ".join(names[:LISTED_LINES]) + f", ... ({len(names) - LISTED_LINES} more)"
