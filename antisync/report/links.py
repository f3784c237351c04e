"""Figures for a graph with many links (more than 20 nodes or 40 directed links), from a file.

Fig. 1a writes every link's value beside its arrow: unreadable beyond a few dozen links. For a
large graph :func:`antisync.report.figures.write_report` draws instead, per job (``<stem>``
the config's name, :func:`antisync.report.figures.job_stems`):

- ``<stem>_lambda_sorted``: (a) every link's Lambda, sorted, with its 95% interval
  (``lambda_km_ci_low`` .. ``lambda_km_ci_high``), coloured by its sign called at false
  discovery rate 0.05 (:func:`~antisync.report.measures.link_signs`, the summary's
  ``sign_resolved``): antifragile, fragile, unresolved;
- ``<stem>_top_links``: (b) left, the network (Kamada-Kawai layout up to 150 nodes, spring
  layout above), every link thin and grey, the ``k`` most antifragile and ``k`` most fragile
  links (:func:`strongest`) as arrows: solid and coloured where the sign is resolved, grey and
  dashed where it is not; right, the same links with their 95% intervals, filled or hollow;
- ``<stem>_map``: (d) when some sign is resolved, the network with every resolved link (at
  most :data:`MAP_LINKS`, the largest ``|Lambda|``) as an arrow coloured by its value
  (:func:`plot_resolved_map`);
- ``<stem>_measure_pairs``: (c) Lambda^KM (y) against Lambda^(linear), Lambda^(xi2) and
  Lambda^(RW), and Lambda^(RW) against Lambda^(xi2), a panel for each pair that was computed,
  each titled with the Spearman rank correlation over every link and the sign agreement over
  the links whose Kuramoto sign is resolved (:func:`antisync.report.measures.plot_pair`).

A file run without ``km`` has no Lambda^KM: (a) and (b) use the first exact measure it holds
(``lambda_xi2``, else ``lambda_rw``, see :func:`antisync.stats.records.primary_measure`), whose sign
is exact (zero within :data:`~antisync.report.measures.SIGN_ATOL` is neutral), and (c) plots
Lambda^(RW) against Lambda^(xi2).
"""

from __future__ import annotations

import textwrap

import networkx as nx
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from antisync.report.intervals import draw_intervals, record_intervals
from antisync.report.measures import (
    COLORS,
    LABELS,
    NAMES,
    PAIRS,
    _column,
    available,
    compare,
    link_signs,
    pair_panels,
    plot_pair,
    spearman,
)
from antisync.stats.records import absence_reason, primary_measure
from antisync.stats.summary import OUTSIDE_WHY, JobView

__all__ = [
    "LARGE_LINKS",
    "LARGE_NODES",
    "available_pairs",
    "compare",
    "draw_link",
    "is_large",
    "link_figures",
    "link_signs",
    "map_links",
    "mark_outside",
    "outside_interval",
    "plot_resolved_map",
    "plot_measure_pairs",
    "plot_sorted",
    "plot_top_intervals",
    "plot_top_links",
    "plot_vs",
    "spearman",
    "strongest",
    "top_links",
]

#: a graph with more nodes than this, or more damaged directed links than :data:`LARGE_LINKS`,
#: gets the figures of this module instead of Fig. 1a's per-link labels
LARGE_NODES = 20
LARGE_LINKS = 40
#: up to this many nodes (top_links) every node is named, above only those of the drawn links
LABEL_NODES = 40
#: up to this many nodes the layout is Kamada-Kawai (O(N^2) memory and time), above it spring
KAMADA_KAWAI_NODES = 150


def _plt():
    # lazy: pyplot only after matplotlib.use("Agg"), so that no display is needed
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: the legend's words for a link whose mean lies outside its own 95% interval, and the marker
#: that draws it (over the link's usual point)
OUTSIDE_LABEL = "mean outside its 95% interval"
OUTSIDE_MARKER = {"marker": "D", "ms": 9, "mfc": "none", "mec": "black", "mew": 1.1, "ls": "none"}


def outside_interval(values, low, high) -> np.ndarray:
    """Where a link's estimate lies outside its own interval ``[low, high]`` (bool; False where
    either is missing). The tail model's interval of Lambda^KM is not centred on the mean: a
    few rare large values can carry the mean outside it (the summary's warning)."""
    x, lo, hi = (np.asarray(a, dtype=float) for a in (values, low, high))
    with np.errstate(invalid="ignore"):
        return np.isfinite(x) & np.isfinite(lo) & np.isfinite(hi) & ((x < lo) | (x > hi))


def mark_outside(ax, x, y, outside: np.ndarray, *, below: float = 36, width: int = 70) -> None:
    """Ring the points ``(x, y)`` where ``outside`` with :data:`OUTSIDE_MARKER`, give the ring a
    legend entry and write under the axes why such a point lies outside its bar, in the
    summary's words (:data:`antisync.stats.summary.OUTSIDE_WHY`), so that no figure shows a point
    outside its interval unexplained. Nothing when no point is outside."""
    outside = np.asarray(outside, dtype=bool)
    if not outside.any():
        return
    count = f"{int(outside.sum())} link{'s' if outside.sum() > 1 else ''}"
    (ring,) = ax.plot(np.asarray(x)[outside], np.asarray(y)[outside], **OUTSIDE_MARKER, label=OUTSIDE_LABEL)
    ring.set_gid("outside interval")
    # below the tick labels and the axis label: a fixed distance in points, whatever the size
    note = ax.annotate(
        textwrap.fill(f"\u25c7 {OUTSIDE_LABEL} ({count}): {OUTSIDE_WHY}", width),
        xy=(0.0, 0.0),
        xycoords="axes fraction",
        xytext=(0, -below),
        textcoords="offset points",
        ha="left",
        va="top",
        fontsize=8,
        color="#333333",
    )
    note.set_gid("outside note")


def is_large(view: JobView) -> bool:
    """Whether ``view``'s graph has more than 20 nodes or more than 40 damaged directed links."""
    return len(view.nodes or ()) > LARGE_NODES or len(view.edges) > LARGE_LINKS


def top_links(recs: list[dict], key: str, k: int) -> tuple[list[dict], list[dict]]:
    """``(antifragile, fragile)``: the ``k`` resolved-positive records of largest ``key`` and
    the ``k`` resolved-negative ones of smallest ``key`` (fewer when fewer are resolved)."""
    signs = link_signs(recs, key)
    pos = sorted((r for r, s in zip(recs, signs, strict=True) if s > 0), key=lambda r: -r[key])
    neg = sorted((r for r, s in zip(recs, signs, strict=True) if s < 0), key=lambda r: r[key])
    return pos[:k], neg[:k]


def plot_sorted(recs: list[dict], key: str, ax, *, graph: str = "") -> None:
    """(a) every link's ``key``, sorted, with its 95% interval when it has one (Lambda^KM)."""
    x = _column(recs, key)
    order = [i for i in np.argsort(-np.nan_to_num(x, nan=-np.inf), kind="stable") if np.isfinite(x[i])]
    ranked = [recs[i] for i in order]
    vals = x[order]
    signs = link_signs(ranked, key)
    rank = np.arange(1, len(ranked) + 1)
    if key == "lambda_km":
        lo, hi = record_intervals(ranked, key)
        for s in (0, -1, 1):
            m = signs == s
            draw_intervals(ax, rank[m], lo[m], hi[m], color=COLORS[s], alpha=0.35, lw=1.0)
    small = len(ranked) <= 300
    for s in (1, -1, 0):
        m = signs == s
        if m.any():
            ax.plot(
                rank[m],
                vals[m],
                "o",
                ms=3 if small else 1.5,
                color=COLORS[s],
                label=f"{NAMES[s]}: {int(m.sum())} links",
            )
    if key == "lambda_km":
        mark_outside(ax, rank, vals, outside_interval(vals, lo, hi), width=110)
    # the extremes are named in a corner (beside the points their labels would overlap)
    if ranked:
        ax.text(
            0.02,
            0.03,
            f"largest: {', '.join(r['edge'] for r in ranked[:3])}\n"
            f"smallest: {', '.join(r['edge'] for r in ranked[-3:][::-1])}",
            transform=ax.transAxes,
            fontsize=8,
            va="bottom",
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
        )
    ax.axhline(0, color="k", lw=0.7)
    interval = " with its 95% interval" if key == "lambda_km" else " (exact)"
    ax.set_title(f"{graph}: {LABELS[key]} of every directed link{interval}", fontsize=10)
    ax.set_xlabel(f"link, sorted by {LABELS[key]} (rank)")
    ax.set_ylabel(LABELS[key])
    ax.set_xlim(0, len(ranked) + 1)
    rule = "sign called at false discovery rate 0.05" if key == "lambda_km" else "exact sign"
    ax.legend(loc="upper right", fontsize=8, title=rule, title_fontsize=8)


def _layout(und):
    if und.number_of_nodes() <= KAMADA_KAWAI_NODES:
        return nx.kamada_kawai_layout(und)
    return nx.spring_layout(und, seed=1, iterations=100)


def strongest(recs: list[dict], key: str, k: int) -> tuple[list[tuple[dict, bool]], list[tuple[dict, bool]]]:
    """``(antifragile, fragile)``: up to ``k`` ``(record, resolved)`` per side, the resolved
    links of largest (smallest) ``key`` first (:func:`top_links`), then, where fewer than ``k``
    are resolved, the unresolved ones of largest positive (smallest negative) estimate."""
    signs = link_signs(recs, key)
    x = _column(recs, key)
    out = []
    for side in (1, -1):
        resolved = [(r, True) for r, s in zip(recs, signs, strict=True) if s == side]
        rest = [(r, False) for r, s, v in zip(recs, signs, x, strict=True) if s == 0 and np.sign(v) == side]
        ranked = sorted(resolved, key=lambda rb: -side * rb[0][key]) + sorted(
            rest, key=lambda rb: -side * rb[0][key]
        )
        out.append(ranked[:k])
    return out[0], out[1]


#: how an unresolved link is drawn beside the resolved ones' colours
UNRESOLVED = {"color": "#8c8c8c", "style": "--"}


def _backbone(view: JobView, ax):
    """The network thin and grey on ``ax`` (every line once): ``(graph, positions, node
    size)`` for the arrows drawn over it."""
    und = nx.Graph()
    und.add_nodes_from(str(n) for n in view.nodes)
    for a, b in zip(*np.nonzero(view.omega), strict=True):
        if a < b:
            und.add_edge(str(view.nodes[a]), str(view.nodes[b]))
    pos = _layout(und)
    n = und.number_of_nodes()
    node_size = 70 if n <= 100 else 12
    nx.draw_networkx_edges(und, pos, ax=ax, edge_color="#d9d9d9", width=0.6 if n <= 100 else 0.3)
    nx.draw_networkx_nodes(
        und, pos, ax=ax, node_color="#eeeeee", edgecolors="#777777", node_size=node_size, linewidths=0.5
    )
    return und, pos, node_size


def draw_link(ax, pos, node_size, label: str, rad: float = 0.15, **style) -> tuple[str, str]:
    """Draw the directed link ``label`` ("a->b") as a curved arrow (``rad``: its bend) with
    networkx's ``style`` keywords; returns its ends. The arrow's gid is ``link a->b``."""
    a, b = label.split("->")
    arrows = nx.draw_networkx_edges(
        nx.DiGraph([(a, b)]),
        pos,
        ax=ax,
        arrows=True,
        node_size=node_size,
        connectionstyle=f"arc3,rad={rad}",
        **style,
    )
    for patch in arrows:
        patch.set_gid(f"link {label}")  # so a test (or a reader of the SVG) finds each link
    return a, b


def _name_nodes(ax, und, pos, touched: set) -> None:
    """Every name up to :data:`LABEL_NODES` nodes; beyond, the ends of the drawn links and the
    ten best connected (all 77 names of Les Miserables overlap)."""
    named = (
        set(und.nodes)
        if und.number_of_nodes() <= LABEL_NODES
        else touched | set(sorted(und, key=und.degree)[-10:])
    )
    nx.draw_networkx_labels(und, pos, labels={v: v for v in named}, ax=ax, font_size=7)
    ax.set_axis_off()


def plot_top_links(view: JobView, recs: list[dict], key: str, ax, *, k: int = 10) -> None:
    """(b) the network, with the ``k`` most antifragile and ``k`` most fragile links strong:
    solid and coloured where the sign is resolved, grey and dashed where it is not (a side
    with fewer than ``k`` resolved links is filled with its largest unresolved estimates)."""
    und, pos, node_size = _backbone(view, ax)
    touched = set()
    for links, s in zip(strongest(recs, key, k), (1, -1), strict=True):
        for rank, (r, resolved) in enumerate(links):
            touched |= set(
                draw_link(
                    ax,
                    pos,
                    node_size,
                    r["edge"],
                    edge_color=COLORS[s] if resolved else UNRESOLVED["color"],
                    style="solid" if resolved else UNRESOLVED["style"],
                    width=(3.0 - 1.5 * rank / max(1, k)) if resolved else 1.2,
                    arrowsize=12 if resolved else 9,
                )
            )
    _name_nodes(ax, und, pos, touched)


#: the map draws at most this many resolved links (those of largest |Lambda|)
MAP_LINKS = 150


def map_links(recs: list[dict], key: str, most: int = MAP_LINKS) -> tuple[list[dict], int]:
    """``(drawn, resolved)``: the records of the links whose sign is resolved, at most ``most``
    of them (largest ``|key|`` first), and how many are resolved in all."""
    signs = link_signs(recs, key)
    resolved = [r for r, s in zip(recs, signs, strict=True) if s != 0]
    return sorted(resolved, key=lambda r: -abs(r[key]))[:most], len(resolved)


def plot_resolved_map(view: JobView, recs: list[dict], key: str, ax, *, most: int = MAP_LINKS) -> None:
    """(d) the network with every link whose sign is resolved as an arrow, red (antifragile) or
    blue (fragile), its width proportional to ``|value|``; unresolved links are only the grey
    backbone. Beyond ``most`` resolved links, the ``most`` of largest ``|value|``."""
    drawn, resolved = map_links(recs, key, most)
    und, pos, node_size = _backbone(view, ax)
    top = max((abs(r[key]) for r in drawn), default=1.0) or 1.0

    def width(v: float) -> float:
        return 0.6 + 3.4 * abs(v) / top

    touched = set()
    for r in sorted(drawn, key=lambda r: abs(r[key])):  # the strongest drawn last, on top
        color = COLORS[1 if r[key] > 0 else -1]
        touched |= set(
            draw_link(ax, pos, node_size, r["edge"], edge_color=color, width=width(r[key]), arrowsize=9)
        )
    _name_nodes(ax, und, pos, touched if und.number_of_nodes() > LABEL_NODES else set(und.nodes))
    scale = [top, top / 3, top / 10]
    handles = [
        Line2D([], [], color=COLORS[1], lw=width(top), label="antifragile"),
        Line2D([], [], color=COLORS[-1], lw=width(top), label="fragile"),
    ]
    handles += [
        Line2D([], [], color="#555555", lw=width(v), label=f"|{LABELS[key]}| = {v:.2g}") for v in scale
    ]
    ax.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=5, frameon=False, fontsize=9
    )
    shown = f"all {resolved}" if len(drawn) == resolved else f"the {len(drawn)} largest of {resolved}"
    rule = "false discovery rate 0.05" if key == "lambda_km" else "exact, nonzero"
    ax.set_title(
        f"{view.graph}: {shown} links of {len(recs)} whose sign is resolved ({rule}), width by {LABELS[key]}"
        "\n(grey: the lines; a link a→b without an arrow is unresolved)",
        fontsize=11,
    )


def plot_top_intervals(recs: list[dict], key: str, ax, *, k: int = 10) -> None:
    """(b), right: the links of :func:`strongest` with their 95% intervals, most antifragile
    at the top; filled where the sign is resolved, hollow and grey where it is not; a side with
    no link says so."""
    pos_links, neg_links = strongest(recs, key, k)
    rows = pos_links + neg_links
    y = np.concatenate([np.arange(len(pos_links)), len(pos_links) + 0.8 + np.arange(len(neg_links))])
    y = -y  # the largest at the top
    recs_rows = [r for r, _ in rows]
    lo, hi = record_intervals(recs_rows, key)
    x = _column(recs_rows, key)
    for i, ((_, resolved), side) in enumerate(
        zip(rows, [1] * len(pos_links) + [-1] * len(neg_links), strict=True)
    ):
        color = COLORS[side] if resolved else UNRESOLVED["color"]
        draw_intervals(
            ax,
            [y[i]],
            [lo[i]],
            [hi[i]],
            horizontal=True,
            color=color,
            lw=1.6 if resolved else 1.0,
            linestyles="solid" if resolved else "dashed",
        )
        ax.plot(x[i], y[i], "o", ms=6, color=color, mfc=color if resolved else "white", mew=1.3)
    mark_outside(ax, x, y, outside_interval(x, lo, hi), width=55)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=7)
    ax.set_yticks(y, [r["edge"] for r in recs_rows], fontsize=8)
    ax.axvline(0, color="k", lw=0.7)
    ax.set_xlabel(LABELS[key] + (" and its 95% interval" if key == "lambda_km" else " (exact)"))
    # a side without a resolved link says so in a row of its own, above or below its group
    top, bottom = 0.8, min(y, default=-1) - 0.8
    empty_pos = not any(resolved for _, resolved in pos_links)
    empty_neg = not any(resolved for _, resolved in neg_links)
    top += 1.2 * empty_pos
    bottom -= 1.2 * empty_neg
    for empty, at, side in ((empty_pos, top - 0.9, "antifragile"), (empty_neg, bottom + 0.9, "fragile")):
        if empty:
            ax.text(
                0.5,
                at,
                f"no {side} link resolved",
                transform=ax.get_yaxis_transform(),
                ha="center",
                va="center",
                fontsize=9,
                color="#555555",
            )
    if not rows:
        ax.set_yticks([])
    ax.set_ylim(bottom, top)
    ax.grid(axis="x", color="#eeeeee", lw=0.6)
    ax.xaxis.set_major_locator(MaxNLocator(5))


def plot_vs(recs: list[dict], kx: str, ky: str, ax) -> None:
    """One panel of (c): ``ky`` against ``kx`` (:func:`antisync.report.measures.plot_pair`:
    Spearman's rho and the sign agreement in the title; with Lambda^KM on an axis, points
    coloured by its resolved sign, each with its 95% interval drawn from ``lambda_km_ci_low``
    to ``lambda_km_ci_high`` (which need not contain the estimate), and only resolved links
    counted for the sign agreement)."""
    plot_pair(recs, kx, ky, ax)


def available_pairs(recs: list[dict]) -> list[tuple[str, str]]:
    """The panels of :data:`~antisync.report.measures.PAIRS` whose two measures some record
    has (a measure not computed gets no empty panel)."""
    return available(recs, PAIRS)


def plot_measure_pairs(recs: list[dict], axes) -> None:
    """(c) on ``axes``, one per :func:`available_pairs`: Lambda^KM (y) against Lambda^(linear),
    Lambda^(xi2), Lambda^(RW), then Lambda^(RW) against Lambda^(xi2)."""
    for ax, (kx, ky) in zip(axes, available_pairs(recs), strict=False):
        plot_pair(recs, kx, ky, ax)


def link_figures(view: JobView, recs: list[dict], *, k: int = 10):
    """Yield ``(figure, suffix)`` for (a), (b) and (c) of ``view`` (its records ``recs``,
    one per directed link); (c) only when two measures were computed. When no record has a
    measure (nothing synchronized, say), only (a), saying why
    (:func:`antisync.stats.records.absence_reason`)."""
    plt = _plt()
    key = primary_measure(recs)
    if key is None:
        fig, ax = plt.subplots(figsize=(9, 5))
        why = textwrap.fill(absence_reason(recs, None), 90)
        ax.text(0.5, 0.5, why, ha="center", va="center", fontsize=9, transform=ax.transAxes)
        ax.set_title(f"{view.graph}: no link has a value of any measure", fontsize=10)
        ax.set_axis_off()
        yield fig, "lambda_sorted"
        return
    fig, ax = plt.subplots(figsize=(9, 5))
    plot_sorted(recs, key, ax, graph=view.graph)
    yield fig, "lambda_sorted"
    fig = plt.figure(figsize=(13, 7.5), layout="constrained")
    net, forest = fig.subplots(1, 2, width_ratios=[2.3, 1])
    plot_top_links(view, recs, key, net, k=k)
    plot_top_intervals(recs, key, forest, k=k)
    rule = "FDR 0.05" if key == "lambda_km" else "exact, nonzero"
    fig.suptitle(
        f"{view.graph}: the {k} links of largest and of smallest {LABELS[key]} (red: antifragile, blue: "
        f"fragile)\nsolid, filled: sign resolved ({rule}); grey, dashed, hollow: not resolved",
        fontsize=11,
    )
    yield fig, "top_links"
    if map_links(recs, key)[1]:
        fig, ax = plt.subplots(figsize=(11, 8.5), layout="constrained")
        plot_resolved_map(view, recs, key, ax)
        yield fig, "map"
    pairs = available_pairs(recs)
    if pairs:
        fig, axes = pair_panels(plt, len(pairs), 6, 5.4)
        plot_measure_pairs(recs, axes)
        fig.suptitle(f"{view.graph}: the response measures of every directed link", fontsize=11)
        yield fig, "measure_pairs"
