"""Figures for a graph with many links (more than 20 nodes or 40 directed links), from a file.

Fig. 1a writes every link's value beside its arrow: unreadable beyond a few dozen links. For a
large graph :func:`antisync.report.figures.write_report` draws instead, per job:

- ``<job>_lambda_sorted``: (a) every link's Lambda, sorted, with its 95% interval
  (``lambda_km_ci_low`` .. ``lambda_km_ci_high``), coloured by
  :func:`antisync.summary.sign_resolved`: antifragile, fragile, unresolved;
- ``<job>_top_links``: (b) the network (Kamada-Kawai layout up to 150 nodes, spring layout
  above), every link thin and grey, the ``k`` most antifragile and ``k`` most fragile resolved
  links drawn as strong arrows and listed in the legend;
- ``<job>_measure_pairs``: (c) Lambda^KM against Lambda^(xi2) and against Lambda^(RW), each
  panel titled with the Spearman rank correlation over every link and the sign agreement over
  the links whose Kuramoto sign is resolved (``sign_resolved != 0``).

A file run without ``km`` has no Lambda^KM: (a) and (b) use the first exact measure it holds
(``lambda_xi2``, else ``lambda_rw``, see :func:`antisync.records.primary_measure`), whose sign
is exact (zero within :data:`~antisync.report.measures.SIGN_ATOL` is neutral), and (c) plots
Lambda^(xi2) against Lambda^(RW).
"""

from __future__ import annotations

import numpy as np

from antisync.records import absence_reason, primary_measure
from antisync.report.intervals import draw_intervals, record_intervals
from antisync.report.measures import LABELS, SIGN_ATOL, missing_note, sign_agreement
from antisync.summary import JobView

__all__ = [
    "LARGE_LINKS",
    "LARGE_NODES",
    "compare",
    "is_large",
    "link_figures",
    "link_signs",
    "plot_measure_pairs",
    "plot_sorted",
    "plot_top_links",
    "plot_vs",
    "spearman",
    "top_links",
]

#: a graph with more nodes than this, or more damaged directed links than :data:`LARGE_LINKS`,
#: gets the figures of this module instead of Fig. 1a's per-link labels
LARGE_NODES = 20
LARGE_LINKS = 40
#: up to this many nodes the layout is Kamada-Kawai (O(N^2) memory and time), above it spring
KAMADA_KAWAI_NODES = 150
COLORS = {1: "#b2182b", -1: "#2166ac", 0: "#9a9a9a"}
NAMES = {1: "antifragile", -1: "fragile", 0: "unresolved"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def is_large(view: JobView) -> bool:
    """Whether ``view``'s graph has more than 20 nodes or more than 40 damaged directed links."""
    return len(view.nodes or ()) > LARGE_NODES or len(view.edges) > LARGE_LINKS


def link_signs(recs: list[dict], key: str) -> np.ndarray:
    """Sign of each record's ``key``: for Lambda^KM the call at false discovery rate 0.05 over
    ``recs``' links (:func:`antisync.multiplicity.fdr_signs`, as ``antisync summary``'s
    ``sign_resolved``), the exact sign for an exact measure (0 within ``SIGN_ATOL``, or missing)."""
    if key == "lambda_km":
        from antisync.multiplicity import fdr_signs

        return np.array([s or 0 for s in fdr_signs(recs)], dtype=int)
    x = np.array([np.nan if r.get(key) is None else r[key] for r in recs], dtype=float)
    return np.where(np.isfinite(x) & (np.abs(x) > SIGN_ATOL), np.sign(np.nan_to_num(x)), 0).astype(int)


def _values(recs: list[dict], key: str) -> np.ndarray:
    return np.array([np.nan if r.get(key) is None else r[key] for r in recs], dtype=float)


def top_links(recs: list[dict], key: str, k: int) -> tuple[list[dict], list[dict]]:
    """``(antifragile, fragile)``: the ``k`` resolved-positive records of largest ``key`` and
    the ``k`` resolved-negative ones of smallest ``key`` (fewer when fewer are resolved)."""
    signs = link_signs(recs, key)
    pos = sorted((r for r, s in zip(recs, signs, strict=True) if s > 0), key=lambda r: -r[key])
    neg = sorted((r for r, s in zip(recs, signs, strict=True) if s < 0), key=lambda r: r[key])
    return pos[:k], neg[:k]


def spearman(x, y) -> float:
    """Spearman rank correlation of the pairs where both are finite (NaN for fewer than 3
    pairs or a constant side)."""
    from scipy.stats import spearmanr

    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or np.ptp(x[ok]) == 0 or np.ptp(y[ok]) == 0:
        return float("nan")
    return float(spearmanr(x[ok], y[ok]).statistic)


def compare(recs: list[dict], kx: str, ky: str) -> dict:
    """How ``ky`` ranks and signs the links against ``kx``, over the records that have both.

    Returns
    -------
    dict
        ``spearman`` (rank correlation over every such link), ``agree`` and ``total``: with
        ``kx`` Lambda^KM, the links whose :func:`~antisync.summary.sign_resolved` is not 0 and
        how many of them ``ky`` gives the same sign; otherwise every link, and how many have
        the same antifragile / neutral / fragile class
        (:func:`~antisync.report.measures.sign_agreement`).
    """
    x, y = _values(recs, kx), _values(recs, ky)
    ok = np.isfinite(x) & np.isfinite(y)
    used = [r for r, good in zip(recs, ok, strict=True) if good]
    if kx == "lambda_km":
        signs, exact = link_signs(used, kx), link_signs(used, ky)
        resolved = signs != 0
        agree, total = int(np.sum(signs[resolved] == exact[resolved])), int(resolved.sum())
    else:
        agree, total = sign_agreement(x[ok], y[ok])
    return {"spearman": spearman(x[ok], y[ok]), "agree": agree, "total": total, "links": int(ok.sum())}


def plot_sorted(recs: list[dict], key: str, ax, *, graph: str = "") -> None:
    """(a) every link's ``key``, sorted, with its 95% interval when it has one (Lambda^KM)."""
    x = _values(recs, key)
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
    ax.legend(loc="upper right", fontsize=8)


def _layout(und):
    import networkx as nx

    if und.number_of_nodes() <= KAMADA_KAWAI_NODES:
        return nx.kamada_kawai_layout(und)
    return nx.spring_layout(und, seed=1, iterations=100)


def plot_top_links(view: JobView, recs: list[dict], key: str, ax, *, k: int = 10) -> None:
    """(b) the network, with the ``k`` most antifragile and ``k`` most fragile links strong."""
    import networkx as nx

    und = nx.Graph()
    und.add_nodes_from(str(n) for n in view.nodes)
    for a, b in zip(*np.nonzero(view.omega), strict=True):
        if a < b:
            und.add_edge(str(view.nodes[a]), str(view.nodes[b]))
    pos = _layout(und)
    n = und.number_of_nodes()
    node_size = 60 if n <= 100 else 12
    nx.draw_networkx_edges(und, pos, ax=ax, edge_color="#cccccc", width=0.6 if n <= 100 else 0.3)
    nx.draw_networkx_nodes(
        und, pos, ax=ax, node_color="#eeeeee", edgecolors="#777777", node_size=node_size, linewidths=0.5
    )
    pos_links, neg_links = top_links(recs, key, k)
    touched = set()
    for links, s in ((pos_links, 1), (neg_links, -1)):
        for rank, r in enumerate(links):
            a, b = r["edge"].split("->")
            touched |= {a, b}
            arrow = nx.DiGraph([(a, b)])
            nx.draw_networkx_edges(
                arrow,
                pos,
                ax=ax,
                edge_color=COLORS[s],
                width=3.0 - 1.5 * rank / max(1, k),
                arrows=True,
                arrowsize=12,
                node_size=node_size,
                connectionstyle="arc3,rad=0.15",
            )
            ax.plot([], [], color=COLORS[s], lw=2, label=f"{r['edge']}  {r[key]:+.3g}")
    if n <= 100:
        nx.draw_networkx_labels(und, pos, ax=ax, font_size=6)
    else:
        nx.draw_networkx_labels(und, pos, labels={v: v for v in touched}, ax=ax, font_size=6)
    which = "resolved " if key == "lambda_km" else ""
    ax.set_title(
        f"{view.graph}: the {len(pos_links)} most antifragile (red) and {len(neg_links)} most fragile "
        f"(blue) {which}links by {LABELS[key]}",
        fontsize=10,
    )
    if pos_links or neg_links:
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=7, title=LABELS[key], frameon=False)
    ax.set_axis_off()


def plot_vs(recs: list[dict], kx: str, ky: str, ax) -> None:
    """One panel of (c): ``ky`` (an exact measure) against ``kx``, Spearman's rho and the sign
    agreement in the title; with ``kx`` Lambda^KM, points coloured by their resolved sign, each
    with its 95% interval drawn from ``lambda_km_ci_low`` to ``lambda_km_ci_high`` (which need
    not contain the estimate), and only resolved links counted for the sign agreement."""
    x, y = _values(recs, kx), _values(recs, ky)
    ok = np.isfinite(x) & np.isfinite(y)
    ax.set_xlabel(LABELS[kx])
    ax.set_ylabel(LABELS[ky])
    if not ok.any():
        ax.text(
            0.5,
            0.5,
            missing_note(recs, (kx, ky)),
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=8,
        )
        ax.set_title(f"{LABELS[ky]} vs {LABELS[kx]}", fontsize=10)
        return
    used = [r for r, good in zip(recs, ok, strict=True) if good]
    x, y = x[ok], y[ok]
    ax.axhline(0, color="k", lw=0.6)
    ax.axvline(0, color="k", lw=0.6)
    c = compare(recs, kx, ky)
    if kx == "lambda_km":
        signs = link_signs(used, kx)
        # the interval as stored: the tail model's may not contain the estimate
        lo, hi = record_intervals(used, kx)
        for s in (0, -1, 1):
            m = signs == s
            if m.any():
                draw_intervals(ax, y[m], lo[m], hi[m], horizontal=True, color=COLORS[s], alpha=0.5, lw=0.6)
                ax.plot(
                    x[m], y[m], "o", ms=3, color=COLORS[s], alpha=0.8, label=f"KM {NAMES[s]}: {int(m.sum())}"
                )
        counted = "links with resolved KM sign"
    else:
        ax.plot(x, y, "o", ms=3, color="#1f77b4", label=f"{len(x)} links")
        counted = "links"
    agree, total = c["agree"], c["total"]
    share = f" ({agree / total:.0%})" if total else ""
    ax.set_title(
        f"{LABELS[ky]} vs {LABELS[kx]}: Spearman $\\rho$ = {c['spearman']:.2f} ({c['links']} links)\n"
        f"sign agrees on {agree}/{total} {counted}{share}",
        fontsize=10,
    )
    ax.legend(loc="lower right", fontsize=7)


def plot_measure_pairs(recs: list[dict], axes) -> None:
    """(c) on ``axes``: Lambda^KM against Lambda^(xi2) and Lambda^(RW) (two Axes), or, for a
    file without Lambda^KM, Lambda^(xi2) against Lambda^(RW) (one Axes)."""
    if primary_measure(recs) == "lambda_km":
        plot_vs(recs, "lambda_km", "lambda_xi2", axes[0])
        plot_vs(recs, "lambda_km", "lambda_rw", axes[1])
    else:
        plot_vs(recs, "lambda_xi2", "lambda_rw", axes[0])


def link_figures(view: JobView, recs: list[dict], *, k: int = 10):
    """Yield ``(figure, file stem)`` for (a), (b) and (c) of ``view`` (its records ``recs``,
    one per directed link). When no record has a measure (nothing synchronized, say), only
    (a), saying why (:func:`antisync.records.absence_reason`)."""
    plt = _plt()
    key = primary_measure(recs)
    if key is None:
        import textwrap

        fig, ax = plt.subplots(figsize=(9, 5))
        why = textwrap.fill(absence_reason(recs, None), 90)
        ax.text(0.5, 0.5, why, ha="center", va="center", fontsize=9, transform=ax.transAxes)
        ax.set_title(f"{view.graph}: no link has a value of any measure", fontsize=10)
        ax.set_axis_off()
        yield fig, f"{view.graph}_lambda_sorted"
        return
    fig, ax = plt.subplots(figsize=(9, 5))
    plot_sorted(recs, key, ax, graph=view.graph)
    yield fig, f"{view.graph}_lambda_sorted"
    fig, ax = plt.subplots(figsize=(10, 8))
    plot_top_links(view, recs, key, ax, k=k)
    yield fig, f"{view.graph}_top_links"
    if key == "lambda_km":
        fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    else:
        fig, ax = plt.subplots(figsize=(6.5, 5.5))
        axes = [ax]
    plot_measure_pairs(recs, axes)
    fig.tight_layout()
    yield fig, f"{view.graph}_measure_pairs"
