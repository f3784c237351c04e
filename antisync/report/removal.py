"""The report of a dynamic line removal (:mod:`antisync.grids.removal`, docs/power_grids.md): the grid
drawn with each line coloured by its response, troublemaker and Braess lines marked
(:func:`removal_figure`), and the removal response beside the static indicators of the locked
state and Lambda, with rank correlations (:func:`side_by_side_report`).

A removal table is read once by :func:`removal_doc`, from a
:class:`~antisync.grids.removal_table.RemovalTable`, the JSON file
:func:`antisync.grids.removal_file.write_table` writes, or that file's parsed mapping;
everything else here takes the plain mapping it returns.
A line is *resolved* as the table resolves it: at false discovery rate 0.05 over the lines
(``sync_called`` for ``P_sync``, ``tau_called`` for tau). matplotlib is imported only when a
figure is drawn, with the Agg backend.
"""

from __future__ import annotations

import math
from pathlib import Path

import networkx as nx
import numpy as np

from antisync.errors import AntisyncError
from antisync.grids.errors import GridError
from antisync.grids.load import Grid
from antisync.grids.removal_config import resolve_config
from antisync.grids.removal_file import (
    FIGURE_SUFFIXES,
    FORMAT,
    check_figure,
    read_document,
    replace_atomically,
    table_document,
)
from antisync.grids.removal_journal import key_changes
from antisync.grids.removal_table import RemovalTable
from antisync.physics import graphs
from antisync.plan.model import node_parameters
from antisync.stats.exact import tau_p_value
from antisync.stats.multiplicity import benjamini_hochberg
from antisync.types import REMOVAL_BY, RemovalBy

__all__ = [
    "FIGURE_SUFFIXES",
    "check_figure",
    "trip_figure",
    "lambda_by_line",
    "merge_docs",
    "rank_correlations",
    "removal_doc",
    "removal_figure",
    "resolved",
    "side_by_side",
    "side_by_side_report",
]

#: Layouts: Kamada-Kawai up to this many nodes, a spring layout with a fixed seed above.
KAMADA_KAWAI_MAX = 200
LAYOUT_SEED = 1


def _num(x) -> float:
    """A JSON number (``null`` for ``nan``) as a float."""
    return math.nan if x is None else float(x)


# --- the table, read once --------------------------------------------------------------------


def removal_doc(source) -> dict:
    """A removal table as the plain mapping of :func:`antisync.grids.removal_file.write_table`'s JSON.

    Parameters
    ----------
    source : RemovalTable, str, Path or dict
        A table from :func:`antisync.grids.removal.line_removal`, its JSON file, or that file parsed.

    Returns
    -------
    dict
        ``summary``, ``rows`` (one dict per line, ``nan`` as ``None``), ``sync_called``,
        ``tau_called`` (labels resolved at false discovery rate ``fdr_level``) and ``config``.

    Raises
    ------
    antisync.grids.errors.GridError
        A file that cannot be read or is not a removal table, or a table that lacks a key the
        report reads or holds a value of the wrong kind there (:func:`_check_doc`): one line
        naming the file and the key.
    """
    return _read_doc(source, None)


def _read_doc(source, where: str | None) -> dict:
    """:func:`removal_doc`, its refusals starting with ``where`` (``"part 2"`` in
    :func:`merge_docs`; a file's refusals name the file too)."""
    if isinstance(source, RemovalTable):
        return table_document(source)
    if isinstance(source, str | Path):
        path = Path(source)
        where = str(path) if where is None else f"{where} ({path})"
        try:
            doc = read_document(path, "removal table")
        except GridError as exc:
            raise GridError(f"{where}: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise GridError(f"{where}: not a removal table (written by antisync grid --removal --out)")
        return _check_doc(doc, where)
    if isinstance(source, dict):
        where = "the removal table" if where is None else where
        if "format" in source and source["format"] != FORMAT:
            raise GridError(
                f"{where}: format {source['format']!r} is not a removal table's ({FORMAT!r}, written by "
                "antisync grid --removal --out)"
            )
        return _check_doc(source, where)
    kind = type(source).__name__
    what = "" if where is None else f"{where}: "
    raise GridError(f"{what}expected a RemovalTable, its JSON file or that file's mapping, got {kind}")


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _is_number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _is_value(x) -> bool:
    """A number, or ``None`` (how the JSON file writes ``nan``)."""
    return x is None or _is_number(x)


def _is_interval(x) -> bool:
    return isinstance(x, list | tuple) and len(x) == 2 and all(_is_value(v) for v in x)


def _is_line(x) -> bool:
    """Two node labels, as an edge list holds them (strings or numbers)."""
    return isinstance(x, list | tuple) and len(x) == 2 and all(isinstance(v, str | int | float) for v in x)


#: The keys a removal table's ``summary`` and rows must have for the report and
#: :func:`merge_docs` to read them, with what each must hold (as
#: :func:`antisync.grids.removal_file.table_document` writes them; ``nan`` as ``None``).
_SUMMARY_KEYS = {
    "name": (lambda x: isinstance(x, str), "a string"),
    "beta": (_is_number, "a number"),
    "seed": (_is_int, "an integer"),
    "realizations": (lambda x: _is_int(x) and x > 0, "a positive integer"),
    "synced0": (_is_int, "an integer"),
    "p_sync": (_is_number, "a number"),
    "p_sync_ci": (_is_interval, "two numbers"),
    "tau0_mean": (_is_value, "a number or null"),
    "tau0_se": (_is_value, "a number or null"),
    "lines": (_is_int, "an integer"),
    "seconds": (_is_number, "a number"),
    "level": (_is_number, "a number"),
}
_ROW_KEYS = {
    "label": (lambda x: isinstance(x, str), "a string"),
    "line": (_is_line, "two node labels"),
    "beta": (_is_number, "a number"),
    "n": (_is_int, "an integer"),
    "lost": (lambda x: _is_int(x) and x >= 0, "a count"),
    "gained": (lambda x: _is_int(x) and x >= 0, "a count"),
    "d_psync": (_is_number, "a number"),
    "d_psync_ci": (_is_interval, "two numbers"),
    "p_value": (lambda x: _is_number(x) and 0 <= x <= 1, "a p-value in [0, 1]"),
    "d_tau": (_is_value, "a number or null"),
    "d_tau_se": (_is_value, "a number or null"),
    "ratio": (_is_value, "a number or null"),
    "ratio_se": (_is_value, "a number or null"),
}


def _check_doc(doc: dict, where: str) -> dict:
    """``doc`` if it holds what the report and :func:`merge_docs` read (:data:`_SUMMARY_KEYS`,
    :data:`_ROW_KEYS`, the calls as lists of labels, the config as a mapping), its rows one per
    line and of the summary's realizations and beta; else a one-line GridError naming ``where``
    and the first key that is missing or wrong."""

    def refuse(what: str):
        raise GridError(
            f"{where}: not a whole removal table: {what} (written by antisync grid --removal --out)"
        )

    summary = doc.get("summary")
    if not isinstance(summary, dict):
        refuse("no 'summary' mapping" if summary is None else "'summary' is not a mapping")
    for key, (ok, kind) in _SUMMARY_KEYS.items():
        if key not in summary:
            refuse(f"its summary lacks {key!r}")
        if not ok(summary[key]):
            refuse(f"summary.{key} is {summary[key]!r:.40}, not {kind}")
    rows = doc.get("rows")
    if not isinstance(rows, list):
        refuse("no 'rows' list" if rows is None else "'rows' is not a list")
    for k, row in enumerate(rows, start=1):
        if not isinstance(row, dict):
            refuse(f"row {k} is not a mapping")
        for key, (ok, kind) in _ROW_KEYS.items():
            if key not in row:
                refuse(f"row {k} lacks {key!r}")
            if not ok(row[key]):
                refuse(f"row {k}'s {key} is {row[key]!r:.40}, not {kind}")
        if row["lost"] + row["gained"] > row["n"]:
            refuse(f"row {row['label']} has lost + gained = {row['lost'] + row['gained']} > n = {row['n']}")
        if row["n"] != summary["realizations"] or row["beta"] != summary["beta"]:
            refuse(
                f"row {row['label']} has n = {row['n']}, beta = {row['beta']}; the summary says "
                f"{summary['realizations']} realizations, beta = {summary['beta']}"
            )
    for key in ("gave_up0", "gave_up"):  # sync.give_up's counts (tables before it lack them)
        if key in summary and not (summary[key] is None or (_is_int(summary[key]) and summary[key] >= 0)):
            refuse(f"summary.{key} is {summary[key]!r:.40}, not a count")
    audit = summary.get("give_up_audit")
    if audit is not None and not (
        isinstance(audit, dict) and all(_is_int(audit.get(k)) for k in ("sampled", "locked", "rerun"))
    ):
        refuse("summary.give_up_audit is not sync.give_up's audit (sampled, locked and rerun counts)")
    check = summary.get("step_check")  # Euler's or RK4's step check (tables before it lack it)
    if check is not None and not (
        isinstance(check, dict)
        and all(_is_int(check.get(k)) for k in ("starts", "changed"))
        and all(isinstance(check.get(k), int | float) for k in ("dt", "largest_dtau"))
        and (check.get("worst") is None or _is_int(check["worst"]))
    ):
        refuse("summary.step_check is not the step check's record (starts, dt, changed, largest_dtau)")
    if summary["lines"] != len(rows):
        refuse(f"summary.lines is {summary['lines']} but it has {len(rows)} rows")
    for key in ("sync_called", "tau_called"):
        if key in doc and not (isinstance(doc[key], list) and all(isinstance(v, str) for v in doc[key])):
            refuse(f"{key!r} is not a list of line labels")
    if not isinstance(doc.get("config", {}), dict):
        refuse("'config' is not a mapping")
    return doc


def resolved(doc: dict) -> dict[str, set]:
    """The table's calls by label: ``troublemakers`` (``P_sync`` lost, resolved), ``braess``
    (``P_sync`` gained or ``d_tau < 0``, resolved: :meth:`~antisync.grids.removal_table.
    RemovalTable.braess_lines`), ``faster`` and ``slower`` (``d_tau`` resolved, by its sign)."""
    rows = doc["rows"]
    if "sync_called" in doc and "tau_called" in doc:
        sync, tau = set(doc["sync_called"]), set(doc["tau_called"])
    else:  # a file written before the calls were stored: the same procedure on its rows
        sync, tau = _calls(rows)
    faster = {r["label"] for r in rows if r["label"] in tau and _num(r["d_tau"]) < 0}
    return {
        "troublemakers": {r["label"] for r in rows if r["lost"] > r["gained"] and r["label"] in sync},
        "braess": faster | {r["label"] for r in rows if r["gained"] > r["lost"] and r["label"] in sync},
        "faster": faster,
        "slower": {r["label"] for r in rows if r["label"] in tau and _num(r["d_tau"]) > 0},
    }


def _calls(rows: list[dict]) -> tuple[set, set]:
    """Labels of the rows whose ``P_sync`` change and whose ``d_tau`` are resolved, at false
    discovery rate ``FDR_LEVEL`` over ``rows`` (as :class:`antisync.grids.removal_table.RemovalTable`)."""
    calls = benjamini_hochberg([r["p_value"] for r in rows])
    sync = {r["label"] for r, c in zip(rows, calls, strict=True) if c}
    calls = benjamini_hochberg([tau_p_value(r["d_tau"], r["d_tau_se"]) for r in rows])
    return sync, {r["label"] for r, c in zip(rows, calls, strict=True) if c}


def _same_run(config):
    """A part's config as :func:`merge_docs` compares it: where it ran (executor, threads,
    backend, output) left out and files by name, since parts run on other machines resolve the
    same shipped files to other folders (the intact grid's numbers, equal to the bit, are the
    check that the files held the same grid)."""
    if isinstance(config, dict):
        return {
            k: (Path(v).name if k in ("path", "file") and isinstance(v, str) else _same_run(v))
            for k, v in config.items()
            if k not in ("executor", "threads", "backend", "output")
        }
    if isinstance(config, list):
        return [_same_run(v) for v in config]
    return config


#: What the parts of one removal table must share (:func:`merge_docs`).
_SAME = ("name", "beta", "seed", "realizations", "synced0", "p_sync", "tau0_mean", "level")


def merge_docs(sources) -> dict:
    """One removal table from parts that removed disjoint lines of the same grid from the same
    starts (``antisync grid --removal --lines ... --out part.json`` on several machines, with
    the same config, seed, realizations and beta).

    The intact grid is integrated by every part from the same starts, so its numbers must agree
    exactly; the resolved calls (troublemakers, Braess lines, faster and slower) are made again
    at false discovery rate 0.05 over the union of the lines, as one run over all of them would
    make them (a part's own calls are over its lines only). ``summary.seconds`` is the parts'
    sum and ``merged_from`` lists each part's command and time.

    Raises
    ------
    antisync.grids.errors.GridError
        No part, a part that is not a removal table, parts of different runs, or a line in two
        parts: one line.
    """
    if isinstance(sources, str | Path | dict | RemovalTable):
        raise GridError("merge_docs takes a list of parts (removal tables, their JSON files or mappings)")
    try:
        sources = list(sources)
    except TypeError:
        kind = type(sources).__name__
        raise GridError(
            f"merge_docs takes a list of parts (removal tables or their files), got {kind}"
        ) from None
    if not sources:
        raise GridError("no removal table to merge")
    names = [f"part {k}" + (f" ({s})" if isinstance(s, str | Path) else "") for k, s in enumerate(sources, 1)]
    docs = [_read_doc(s, f"part {k}") for k, s in enumerate(sources, start=1)]
    head = docs[0]
    for name, doc in zip(names[1:], docs[1:], strict=True):
        for key in _SAME:
            a, b = head["summary"][key], doc["summary"][key]
            if a != b and not (_num(a) != _num(a) and _num(b) != _num(b)):  # nan == nan here
                raise GridError(
                    f"{name} differs from {names[0]} in {key} ({b} against {a}): merge only parts run with "
                    "the same config, seed, realizations and beta"
                )
        mine, theirs = _same_run(doc.get("config")), _same_run(head.get("config"))
        if mine != theirs:
            raise GridError(
                f"{name} was run with another config than {names[0]} ({key_changes(theirs, mine)}): merge "
                "only parts of one run"
            )
    rows = [r for doc in docs for r in doc["rows"]]
    seen: set = set()
    for r in rows:
        if r["label"] in seen:
            raise GridError(f"line {r['label']} is in two parts: give each line to one part only")
        seen.add(r["label"])
    sync, tau = _calls(rows)
    merged = {
        **head,
        "rows": rows,
        "summary": {
            **head["summary"],
            "lines": len(rows),
            "seconds": sum(float(d["summary"].get("seconds") or 0.0) for d in docs),
            # stopped by sync.give_up after the changes: each part's own lines (the intact
            # grid's gave_up0 is the same in every part)
            "gave_up": sum(int(d["summary"].get("gave_up") or 0) for d in docs),
        },
        "sync_called": [r["label"] for r in rows if r["label"] in sync],
        "tau_called": [r["label"] for r in rows if r["label"] in tau],
        "merged_from": [{"command": d.get("command", ""), "written": d.get("written", "")} for d in docs],
    }
    # as RemovalTable.troublemakers(None) and .braess_lines() order them
    tau_of = {r["label"]: 0.0 if _num(r["d_tau"]) != _num(r["d_tau"]) else _num(r["d_tau"]) for r in rows}
    net = {r["label"]: r["lost"] - r["gained"] for r in rows}
    trouble = sorted((lab for lab in net if net[lab] > 0), key=lambda lab: (-net[lab], -tau_of[lab]))
    braess = sorted(resolved(merged)["braess"], key=lambda lab: (net[lab], tau_of[lab]))
    merged["troublemakers"], merged["braess_lines"] = trouble, braess
    return merged


# --- the figure ------------------------------------------------------------------------------


def _network(config) -> tuple[nx.Graph, dict]:
    """The grid as a weighted graph and each node's inertia, from a config (path, mapping,
    Config) or a :class:`~antisync.grids.load.Grid`."""
    if isinstance(config, Grid):
        labels, omega = list(config.labels), config.omega
        inertia = np.broadcast_to(np.asarray(config.inertia, dtype=float), (len(labels),))
    else:
        cfg = resolve_config(config, {})
        try:
            g = graphs.build_graph(cfg.graph, seed=cfg.seed)
            labels, omega = graphs.node_order(g), graphs.omega_matrix(g)
            inertia = node_parameters(cfg.model, len(labels))[0]
        except AntisyncError as exc:
            raise GridError(str(exc)) from None
    g = nx.Graph()
    g.add_nodes_from(labels)
    for i, j in zip(*np.nonzero(np.triu(omega > 0)), strict=True):
        g.add_edge(labels[i], labels[j], weight=float(omega[i, j]))
    return g, {v: float(m) for v, m in zip(labels, inertia, strict=True)}


def _recorded_network(net: dict) -> tuple[nx.Graph, dict]:
    """:func:`_network` of a trip table's ``network`` (:func:`antisync.grids.trip.network_record`)."""
    g = nx.Graph()
    g.add_nodes_from(net["nodes"])
    g.add_weighted_edges_from((u, v, w) for u, v, w in net["links"])
    return g, dict(zip(net["nodes"], net["inertia"], strict=True))


def _layout(g: nx.Graph) -> dict:
    if g.number_of_nodes() <= KAMADA_KAWAI_MAX:
        return nx.kamada_kawai_layout(g, weight=None)
    return nx.spring_layout(g, seed=LAYOUT_SEED, weight=None)


#: Lines named on a large grid's figure beyond the resolved ones and those that lost or gained
#: starts: the largest responses (the table names every line).
NAMED_LINES = 8


def _named_lines(rows: dict, marks: dict, value, small: bool) -> set:
    """The labels written beside their line: every line on a small grid or a short table; on a
    large grid with many lines (their names collide) the resolved lines, those that lost or
    gained starts, and the :data:`NAMED_LINES` largest responses."""
    if small or len(rows) <= 2 * NAMED_LINES:
        return {r["label"] for r in rows.values()}
    called = set().union(*marks.values())
    moved = {r["label"] for r in rows.values() if r["gained"] != r["lost"]}
    finite = [r for r in rows.values() if math.isfinite(value(r))]
    top = sorted(finite, key=lambda r: -abs(value(r)))[:NAMED_LINES]
    return called | moved | {r["label"] for r in top}


def _draw_buses(g: nx.Graph, pos: dict, ax, inertia: dict, small: bool) -> None:
    """The buses: generators (inertia > 0) as squares, first-order buses as circles, labels on a
    small grid."""
    gens = [v for v in g.nodes if inertia[v] > 0]
    loads = [v for v in g.nodes if inertia[v] <= 0]
    size = (260, 200) if small else (45, 18)
    if gens:
        nx.draw_networkx_nodes(
            g, pos, nodelist=gens, ax=ax, node_color="#f2c14e", node_size=size[0], node_shape="s"
        )
    if loads:
        nx.draw_networkx_nodes(
            g, pos, nodelist=loads, ax=ax, node_color="white", edgecolors="k", node_size=size[1]
        )
    if small:
        nx.draw_networkx_labels(g, pos, ax=ax, font_size=7)


def _save(fig, path: Path, plt) -> Path:
    """Write ``fig`` to ``path`` atomically (its format from the suffix) and close it."""
    fmt = path.suffix.lower().lstrip(".")
    try:
        replace_atomically(path, lambda tmp: fig.savefig(tmp, dpi=130, bbox_inches="tight", format=fmt))
    finally:
        plt.close(fig)
    return path


def _where(summary: dict) -> str:
    """`` (phases within 1 rad of the operating point)`` for a table of such starts (tables of
    uniform starts, and those written before the summary said, have nothing added)."""
    starts = summary.get("starts", "")
    return f" ({starts})" if starts.startswith("phases within") else ""


def removal_figure(source, config, path, *, by: RemovalBy = "speedup", overwrite: bool = False) -> Path:
    """Draw the grid with every removed line coloured by its response.

    Parameters
    ----------
    source : RemovalTable, str, Path or dict
        The removal table, as :func:`removal_doc` takes it.
    config : str, Path, dict, Config, Grid or None
        The grid the table was run on (for its lines and which nodes have inertia); None: the
        resolved config stored with the table.
    path : str or Path
        The figure (``.png``, ``.pdf`` or ``.svg``), written atomically (a temporary file in the
        same folder, renamed over ``path``).
    by : {"speedup", "psync"}
        The colour: ``F_1 - 1`` (the mean ``tau0 / tau - 1`` on the pairs synchronized both
        times) or ``d P_sync``.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The file written.

    Notes
    -----
    Troublemaker lines (``P_sync`` lost) are dashed and Braess lines (``P_sync`` gained or
    synchronization faster) circled, both only where resolved at false discovery rate 0.05
    over the lines (:func:`resolved`); the numbers are the net starts gained (``gained -
    lost``; on grids of more than 60 nodes, which get no node labels, after the line's name,
    and there, with more than 16 lines in the table, only the resolved lines, those that lost
    or gained starts and the 8 largest responses are named: :func:`_named_lines`);
    bridges are dotted, lines not in the table thin and grey, lines without a value (no pair
    synchronized both times) dark grey, generators (``m > 0``) squares. Layout: Kamada-Kawai
    up to 200 nodes, else a spring layout of seed 1.
    """
    if by not in REMOVAL_BY:
        raise GridError(f"by must be one of {', '.join(REMOVAL_BY)}, got {by!r}")
    path = check_figure(path, overwrite)
    doc = removal_doc(source)
    g, inertia = _network(doc.get("config") if config is None else config)
    rows = {frozenset(r["line"]): r for r in doc["rows"]}
    if not all(len(k) == 2 and g.has_edge(*k) for k in rows):
        raise GridError("the removal table names lines that are not in this grid's config")
    marks = resolved(doc)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    def value(r) -> float:
        return _num(r["ratio"]) - 1 if by == "speedup" else _num(r["d_psync"])

    small = g.number_of_nodes() <= 60
    pos = _layout(g)
    fig, ax = plt.subplots(figsize=(9, 7.5) if small else (11, 9.5))
    cmap = plt.get_cmap("coolwarm")
    finite = [abs(value(r)) for r in rows.values() if math.isfinite(value(r))]
    lim = max(finite) if finite and max(finite) > 0 else 1.0
    norm = matplotlib.colors.Normalize(-lim, lim)
    bridges = {frozenset(e) for e in nx.bridges(g)}
    edges = list(g.edges)
    others = [e for e in edges if frozenset(e) not in rows]
    kinds = {
        "bridge": ([e for e in others if frozenset(e) in bridges], {"style": "dotted", "edge_color": "0.55"}),
        "other": ([e for e in others if frozenset(e) not in bridges], {"edge_color": "0.82"}),
    }
    for drawn, style in kinds.values():
        if drawn:
            nx.draw_networkx_edges(g, pos, edgelist=drawn, ax=ax, width=1.2 if small else 0.8, **style)
    lines = [e for e in edges if frozenset(e) in rows]
    colours = [
        cmap(norm(value(rows[frozenset(e)]))) if math.isfinite(value(rows[frozenset(e)])) else "0.3"
        for e in lines
    ]
    nx.draw_networkx_edges(g, pos, edgelist=lines, ax=ax, edge_color=colours, width=4)
    trouble = [e for e in lines if rows[frozenset(e)]["label"] in marks["troublemakers"]]
    if trouble:
        nx.draw_networkx_edges(g, pos, edgelist=trouble, ax=ax, edge_color="k", width=1.2, style="dashed")
    named = _named_lines(rows, marks, value, small)
    for e in lines:
        r = rows[frozenset(e)]
        mid = (np.asarray(pos[e[0]]) + np.asarray(pos[e[1]])) / 2
        if r["label"] in marks["braess"]:
            ax.plot(*mid, marker="o", ms=7, mfc="none", mec="k", mew=1.5, zorder=4)
        net = r["gained"] - r["lost"]
        # a large grid draws no node labels: name the line itself
        text = (f"{net:+d}" if net else "") if small else r["label"] + (f" ({net:+d})" if net else "")
        if text and r["label"] in named:
            box = None if small else {"fc": "white", "ec": "none", "alpha": 0.7, "pad": 0.5}
            ax.annotate(text, mid, fontsize=7, xytext=(3, 3), textcoords="offset points", bbox=box)
    _draw_buses(g, pos, ax, inertia, small)

    sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    label = {
        "speedup": "F_1 - 1 = mean tau0/tau - 1 without the line (> 0: faster)",
        "psync": "d P_sync without the line (> 0: more starts lock)",
    }[by]
    fig.colorbar(sm, ax=ax, shrink=0.7, label=label)
    s = doc["summary"]
    change = "removal" if s["beta"] == 1 else f"weakening by beta = {s['beta']:g}"
    gave_up = int(s.get("gave_up0") or 0) + int(s.get("gave_up") or 0)
    ax.set_title(
        f"{s['name']}: dynamic N-1, each line's {change}\n"
        f"{s['realizations']} paired starts{_where(s)}, intact P_sync = {s['p_sync']:.3f}; {len(rows)} lines"
        + (f"; {gave_up} trajectories stopped by sync.give_up" if gave_up else ""),
        fontsize=10,
    )
    handles = [
        Line2D([], [], color="k", ls="--", label="troublemaker: P_sync lost (FDR 0.05)"),
        Line2D(
            [], [], ls="", marker="o", mfc="none", mec="k", label="Braess: P_sync up or faster (FDR 0.05)"
        ),
        Line2D([], [], color="0.55", ls=":", label="bridge (not removed)"),
        Line2D([], [], ls="", marker="s", color="#f2c14e", label="generator (inertia > 0)"),
        Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="first-order bus"),
    ]
    if kinds["other"][0]:
        handles.insert(3, Line2D([], [], color="0.82", label="line not in the table"))
    if len(rows) <= 80:
        handles.append(Line2D([], [], ls="", marker="$+n$", ms=14, color="k", label="net starts gained"))
    if any(not math.isfinite(value(r)) for r in rows.values()):
        handles.append(Line2D([], [], color="0.3", lw=4, label="no pair synchronized both times"))
    ax.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2, fontsize=8, frameon=False
    )
    ax.axis("off")
    return _save(fig, path, plt)


def trip_figure(report: dict, grid: Grid | None, path, *, overwrite: bool = False) -> Path:
    """Draw the grid with every tripped line coloured by its critical clearing time (with
    ``--cct``), else by the maximum frequency deviation after its trip; lines after whose trip
    the grid does not settle dashed black, bridges dotted, generators squares. ``report`` is
    :func:`antisync.grids.trip.trip_report`'s (a line with several contingencies of a table is
    drawn by its worst: not settling, else the shortest clearing time or the largest swing);
    ``grid`` the grid it ran on (None: the network the table keeps); ``path`` a ``.png``,
    ``.pdf`` or ``.svg`` file, written atomically."""
    path = check_figure(path, overwrite)
    g, inertia = _network(grid) if grid is not None else _recorded_network(report["network"])
    cct = report["cct_max"] is not None
    key = "cct" if cct else "max_frequency"

    def badness(r):
        return (not r["settles"], -r[key] if cct else r[key])

    rows = {}
    for r in report["lines"]:
        line = frozenset(r["line"])
        if line not in rows or badness(r) > badness(rows[line]):
            rows[line] = r
    by_label = {frozenset(map(str, e)): e for e in g.edges}

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    small = g.number_of_nodes() <= 60
    pos = _layout(g)
    fig, ax = plt.subplots(figsize=(9, 7.5) if small else (11, 9.5))
    cmap = plt.get_cmap("viridis" if cct else "magma_r")
    values = [r[key] for r in rows.values()]
    norm = matplotlib.colors.Normalize(min(values, default=0.0), max(values, default=1.0) or 1.0)
    tripped = [by_label[k] for k in rows if k in by_label]
    others = [e for e in g.edges if frozenset(map(str, e)) not in rows]
    bridges = {frozenset(e) for e in nx.bridges(g)}
    for drawn, style in (
        ([e for e in others if frozenset(e) in bridges], {"style": "dotted", "edge_color": "0.55"}),
        ([e for e in others if frozenset(e) not in bridges], {"edge_color": "0.82"}),
    ):
        if drawn:
            nx.draw_networkx_edges(g, pos, edgelist=drawn, ax=ax, width=1.2, **style)
    colours = [cmap(norm(rows[frozenset(map(str, e))][key])) for e in tripped]
    nx.draw_networkx_edges(g, pos, edgelist=tripped, ax=ax, edge_color=colours, width=4)
    lost = [e for e in tripped if not rows[frozenset(map(str, e))]["settles"]]
    if lost:
        nx.draw_networkx_edges(g, pos, edgelist=lost, ax=ax, edge_color="k", width=1.2, style="dashed")
    _draw_buses(g, pos, ax, inertia, small)
    method = "scan" if report.get("format_version", 1) >= 2 else "bisection"  # tables before: bisection
    label = (
        f"critical clearing time (s; {method} to {report['cct_tol']:g} s, at most {report['cct_max']:g})"
        if cct
        else "max |theta'| after the trip (rad/s)"
        if report["t_clear"] is None
        else "max |theta'| from the fault on (rad/s)"  # a faulted load bus swings fastest
    )
    fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7, label=label)
    fault = "no fault" if report["t_clear"] is None else f"fault {report['t_clear']:g} s at the first bus"
    ax.set_title(
        f"{report['grid']}: each line tripped from the operating point ({fault}); {len(rows)} lines",
        fontsize=10,
    )
    handles = [
        Line2D([], [], color="k", ls="--", label="does not settle"),
        Line2D([], [], color="0.55", ls=":", label="bridge (not tripped)"),
        Line2D([], [], ls="", marker="s", color="#f2c14e", label="generator (inertia > 0)"),
        Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="first-order bus"),
    ]
    ax.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2, fontsize=8, frameon=False
    )
    ax.axis("off")
    return _save(fig, path, plt)


# --- the table beside the static indicators and Lambda ---------------------------------------


def lambda_by_line(records) -> dict:
    """``{(u, v): (Lambda_line, se)}`` from a run's records (``edge`` ``"u->v"``, ``lambda_km``,
    ``lambda_km_se``): both directions summed, their standard errors combined as independent
    (an upper bound for positively correlated ones). Integer labels stay integers."""

    def node(x: str):
        return int(x) if x.lstrip("-").isdigit() else x

    per = {}
    for r in records:
        a, b = (node(x) for x in str(r["edge"]).split("->"))
        per[(a, b)] = (_num(r["lambda_km"]), _num(r["lambda_km_se"]))
    out = {}
    for (a, b), (x, se) in per.items():
        if (b, a) in per and (b, a) not in out:
            y, se2 = per[(b, a)]
            out[(a, b)] = (x + y, math.hypot(se, se2))
    return out


def side_by_side(doc: dict, static, lam: dict | None = None) -> list[dict]:
    """One dict per line of the removal table, with the static indicators of the same change
    (``static``: a :class:`~antisync.grids.static.LineTable` of
    :func:`antisync.grids.static.static_table`) and
    ``Lambda_line`` (:func:`lambda_by_line`; ``nan`` without): ``label``, ``lost``, ``gained``,
    ``dp``, ``dp_ci``, ``p``, ``dtau``, ``dtau_se``, ``f1`` (``F_1 - 1``), ``lam``, ``lam_se``,
    ``dm`` (d margin), ``dl2`` (d lambda2), ``dload`` (d max load). Ranked from the largest net
    loss of ``P_sync`` to the largest gain, then by ``d_tau``."""
    st = {frozenset(r.line): r for r in static.rows}
    lam = {frozenset(k): v for k, v in (lam or {}).items()}
    out = []
    for r in sorted(doc["rows"], key=lambda r: (r["gained"] - r["lost"], -_num(r["d_tau"]))):
        key = frozenset(r["line"])
        if key not in st:
            raise GridError(f"line {r['label']} is not in the static table (another grid or beta?)")
        sr = st[key]
        lv, lse = lam.get(key, (math.nan, math.nan))
        out.append(
            {
                "label": r["label"],
                "lost": r["lost"],
                "gained": r["gained"],
                "dp": r["d_psync"],
                "dp_ci": r["d_psync_ci"],
                "p": r["p_value"],
                "dtau": _num(r["d_tau"]),
                "dtau_se": _num(r["d_tau_se"]),
                "f1": _num(r["ratio"]) - 1,
                "lam": lv,
                "lam_se": lse,
                "dm": sr.d_margin,
                "dl2": sr.d_lambda2,
                "dload": sr.d_max_load,
            }
        )
    return out


def _spearman(x, y) -> tuple[float, float, int]:
    from scipy.stats import spearmanr

    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or np.ptp(x[ok]) == 0 or np.ptp(y[ok]) == 0:
        return math.nan, math.nan, int(ok.sum())  # too few lines, or one side constant
    res = spearmanr(x[ok], y[ok])
    return float(res.statistic), float(res.pvalue), int(ok.sum())


#: (name, key, name, key, sign of the second): the rank correlations reported.
PAIRS = (
    ("F_1 - 1", "f1", "Lambda_line", "lam", 1),
    ("F_1 - 1", "f1", "d margin", "dm", 1),
    ("F_1 - 1", "f1", "d lambda2", "dl2", 1),
    ("F_1 - 1", "f1", "-d max load", "dload", -1),
    ("d P_sync", "dp", "d margin", "dm", 1),
    ("d P_sync", "dp", "d lambda2", "dl2", 1),
    ("d P_sync", "dp", "-d max load", "dload", -1),
    ("d P_sync", "dp", "Lambda_line", "lam", 1),
    ("d P_sync", "dp", "F_1 - 1", "f1", 1),
)


def rank_correlations(rows: list[dict]) -> list[tuple[str, str, float, float, int]]:
    """Spearman's rank correlations of :data:`PAIRS` over the lines of :func:`side_by_side`:
    ``(name, name, rho, p, lines)``, ``nan`` where fewer than 3 lines have both or one side is
    constant."""
    out = []
    for na, a, nb, b, sign in PAIRS:
        rho, p, k = _spearman([r[a] for r in rows], [sign * r[b] for r in rows])
        out.append((na, nb, rho, p, k))
    return out


def _pm(x: float, se: float) -> str:
    return "-" if math.isnan(x) else f"{x:+.3f} +- {se:.3f}"


def _f(x: float) -> str:
    return "-" if math.isnan(x) else f"{x:+.4f}"


def side_by_side_report(
    doc: dict, static, lam: dict | None = None, seconds_static: float | None = None
) -> str:
    """The removal table beside the static indicators and Lambda as markdown, then the rank
    correlations, the sign agreement of ``d tau`` and ``Lambda_line`` where both are resolved,
    and the dynamic Braess lines against the static candidates (docs/power_grids.md)."""
    rows = side_by_side(doc, static, lam)
    marks = resolved(doc)
    s = doc["summary"]
    took = "" if seconds_static is None else f"; static table {seconds_static:.2f} s"
    out = [
        f"{s['name']}: {s['realizations']} realizations, intact P_sync {s['p_sync']:.4f} "
        f"[{s['p_sync_ci'][0]:.4f}, {s['p_sync_ci'][1]:.4f}], tau0 {_num(s['tau0_mean']):.3f} +- "
        f"{_num(s['tau0_se']):.3f}; removal table {s['seconds']:.0f} s{took}",
        "",
        "| line | lost | gained | d P_sync [exact 95%] | p | d tau +- se | F_1 - 1 | Lambda_line +- se "
        "| d margin | d lambda2 | d max load |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        ci = r["dp_ci"]
        out.append(
            f"| {r['label']} | {r['lost']} | {r['gained']} | {r['dp']:+.4f} [{ci[0]:+.4f}, {ci[1]:+.4f}] "
            f"| {r['p']:.3g} | {_pm(r['dtau'], r['dtau_se'])} | {_f(r['f1'])} | {_pm(r['lam'], r['lam_se'])} "
            f"| {_f(r['dm'])} | {_f(r['dl2'])} | {_f(r['dload'])} |"
        )
    out += ["", "Spearman rank correlations over the lines (rho, p, lines):"]
    for na, nb, rho, p, k in rank_correlations(rows):
        out.append(f"- {na} vs {nb}: rho = {rho:+.3f} (p = {p:.2g}, {k} lines)")
    if lam:
        # removal speeds synchronization (resolved) vs Lambda_line > 0 (resolved at the same
        # false discovery rate over the lines)
        keys = list(lam)
        p_lam = [math.erfc(abs(lam[k][0]) / lam[k][1] / math.sqrt(2)) if lam[k][1] > 0 else 1.0 for k in keys]
        lam_called = {frozenset(k) for k, c in zip(keys, benjamini_hochberg(p_lam), strict=True) if c}
        lam_of = {frozenset(k): v[0] for k, v in lam.items()}
        res = [
            (r["label"] in marks["faster"], lam_of[frozenset(r["line"])] > 0)
            for r in doc["rows"]
            if r["label"] in marks["faster"] | marks["slower"] and frozenset(r["line"]) in lam_called
        ]
        agree = sum(a == b for a, b in res)
        out.append(f"- sign of d tau (resolved) vs sign of Lambda_line (resolved): {agree}/{len(res)} agree")
    static_m = {r.label for r in static.braess_lines()} & {r["label"] for r in doc["rows"]}
    static_l2 = {r.label for r in static.braess_lines(margin="d_lambda2")} & {r["label"] for r in doc["rows"]}
    dyn = marks["braess"]
    out.append(f"- dynamic Braess lines ({len(dyn)}): {', '.join(sorted(dyn)) or 'none'}")
    for what, names in (
        ("static Braess candidates by margin/load", static_m),
        ("static Braess candidates by lambda2/load", static_l2),
        ("both dynamic and static by margin/load", dyn & static_m),
    ):
        out.append(f"- {what} ({len(names)}): {', '.join(sorted(names)) or 'none'}")
    trouble = [r["label"] for r in doc["rows"] if r["label"] in marks["troublemakers"]]
    out.append(f"- troublemakers resolved (McNemar, FDR 0.05 over the lines): {', '.join(trouble) or 'none'}")
    out.append(f"- removal slows synchronization (resolved): {', '.join(sorted(marks['slower'])) or 'none'}")
    return "\n".join(out)
