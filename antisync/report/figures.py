"""Figures from a result file (never from a live run): the paper's Fig. 1 panels per job.

Files are named ``<stem>_<figure>.png``, ``<stem>`` the config's ``name:`` as the file stores it
(:func:`job_stems`, made safe by :func:`file_stem`; a km_nnc twin's ``<stem>_nnc``):

- ``<stem>_graph``: the graph with each directed edge drawn as an arrow coloured by Lambda^KM
  (Fig. 1a): solid where its sign is resolved (false discovery rate 0.05 over the file's links,
  as ``antisync summary``'s ``sign_resolved``), thin grey and dashed where it is not; a file
  run without ``km`` colours by its first exact measure, Lambda^(xi2) or Lambda^(RW). Up to
  :data:`LABEL_LINKS` links each value is written on its arrow; beyond, ``index.md`` has the
  table instead (labels of that many arrows overlap);
- ``<stem>_F_beta``: <F_beta> against beta for every edge, coloured by Lambda^KM (Fig. 1b; no
  legend for a large graph);
- ``<stem>_histograms``: one figure, a panel per (link, beta) of the log-density 2D histogram
  of (tau0, tau(beta)) with the line tau(beta) = tau0 (Figs. 1c-f), on shared axes cut at
  the 99.5% quantile of the times (for a large graph only the links drawn strong in
  ``<stem>_top_links``);
- for a graph with more than 20 nodes or 40 links, instead of ``<stem>_graph``:
  ``<stem>_lambda_sorted``, ``<stem>_top_links``, ``<stem>_map``, ``<stem>_measure_pairs``, see
  :mod:`antisync.report.links`;
- ``fig5_measures``, ``<stem>_fig7e_km_nnc``: see :mod:`antisync.report.measures`;
- ``index.md``: every file with the question it answers, what was not computed, and the
  table of every link of a graph too large for labels.
"""

from __future__ import annotations

import math
import re
import textwrap
from pathlib import Path

import networkx as nx
import numpy as np
from matplotlib import patheffects
from matplotlib.colors import LogNorm, TwoSlopeNorm
from matplotlib.lines import Line2D

from antisync.plan.describe import stored_name
from antisync.report.labels import spread_labels
from antisync.report.links import (
    NAMES,
    OUTSIDE_LABEL,
    draw_link,
    is_large,
    link_figures,
    link_signs,
    outside_interval,
    top_links,
)
from antisync.report.measures import LABELS, measure_figures
from antisync.report.tables import fmt_interval
from antisync.stats.records import primary_measure
from antisync.stats.summary import OUTSIDE_WHY, JobView, graph_names, job_records, named_views
from antisync.store import read_views, stored_config

__all__ = [
    "HIST_QUANTILE",
    "LABEL_LINKS",
    "conditioning_note",
    "file_stem",
    "hist_limit",
    "job_stems",
    "link_table",
    "plot_f_beta",
    "plot_graph",
    "plot_histogram",
    "plot_histograms",
    "write_file_report",
    "write_report",
]

#: a graph with more damaged directed links than this gets no value labels on its arrows
#: (they overlap on IEEE 14's 40 links) but a table in ``index.md``
LABEL_LINKS = 12
#: the histograms' axes end at this quantile of tau0 and of tau(beta), over every panel
HIST_QUANTILE = 0.995
CMAP = "coolwarm"
#: the line tau(beta) = tau0: dark and dashed, with a white halo so it shows over any density
DIAGONAL = {"color": "k", "ls": "--", "lw": 1.1, "zorder": 3}


def _plt():
    # lazy: pyplot only after matplotlib.use("Agg"), so that no display is needed
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _norm(values):
    vals = np.array([v for v in values if v is not None and np.isfinite(v)])
    top = float(np.max(np.abs(vals))) if vals.size else 1.0
    top = top or 1.0
    return TwoSlopeNorm(vmin=-top, vcenter=0.0, vmax=top)


# ---- names ---------------------------------------------------------------------------------
def file_stem(name) -> str:
    """``name`` made safe for a file name: every run of characters outside ``[A-Za-z0-9_.-]``
    becomes one ``_`` (``Zachary's Karate Club`` -> ``Zachary_s_Karate_Club``), leading and
    trailing ``_`` and ``.`` are dropped; ``run`` when nothing is left."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("_.")
    return stem or "run"


def job_stems(views: list[JobView], name: str | None = None) -> dict[str, str]:
    """``{job: file stem}``: the config's ``name`` for a file of one job (its km_nnc twin gets
    ``<name>_nnc``), ``<name>_<job>`` for each of several; the job's own name (the graph's,
    made safe) without ``name``."""
    return graph_names(views, name, safe=file_stem)  # the summary's names, made safe


# ---- Fig. 1a: the graph --------------------------------------------------------------------
def _lambdas(view: JobView) -> tuple[str, list[dict]]:
    """``(key, records)``: one record per link, ``key`` Lambda^KM or the first exact measure of
    a job without km."""
    first: dict[str, dict] = {}
    for r in job_records(view):
        first.setdefault(r["edge"], r)
    recs = list(first.values())
    return primary_measure(recs) or "lambda_km", recs


def _arc_middle(pa, pb, rad: float) -> np.ndarray:
    """The middle of matplotlib's ``arc3,rad=rad`` curve from ``pa`` to ``pb`` (a quadratic
    Bezier whose control point sits ``rad`` times the chord beside the chord's middle)."""
    pa, pb = np.asarray(pa, dtype=float), np.asarray(pb, dtype=float)
    d = pb - pa
    return (pa + pb) / 2 + 0.5 * rad * np.array([d[1], -d[0]])


def plot_graph(view: JobView, ax) -> None:
    """Fig. 1a: arrows a->b coloured by Lambda^KM(a->b), solid where the sign is resolved,
    grey and dashed where it is not; each value on its arrow up to :data:`LABEL_LINKS` links."""
    plt = _plt()
    key, recs = _lambdas(view)
    lam = {r["edge"]: r.get(key) for r in recs}
    signs = dict(zip((r["edge"] for r in recs), link_signs(recs, key), strict=True))
    und = nx.Graph()
    und.add_nodes_from(str(n) for n in view.nodes)
    for a, b in zip(*np.nonzero(view.omega), strict=True):
        und.add_edge(str(view.nodes[a]), str(view.nodes[b]))
    pos = nx.kamada_kawai_layout(und)
    norm = _norm(lam.values())
    cmap = plt.get_cmap(CMAP)
    node_size = 420
    nx.draw_networkx_nodes(und, pos, ax=ax, node_color="#f0f0f0", edgecolors="k", node_size=node_size)
    nx.draw_networkx_labels(und, pos, ax=ax, font_size=11)
    nx.draw_networkx_edges(und, pos, ax=ax, edge_color="#e4e4e4", width=1.0)
    labels = len(view.edges) <= LABEL_LINKS
    rad = 0.18
    texts = []
    for label in view.edges:
        a, b = label.split("->")
        value = lam.get(label)
        resolved = value is not None and signs.get(label, 0) != 0
        style = (
            {"edge_color": [cmap(norm(value))], "width": 2.8, "style": "solid", "arrowsize": 15}
            if resolved
            else {"edge_color": ["#8c8c8c"], "width": 1.2, "style": "--", "arrowsize": 10}
        )
        draw_link(ax, pos, node_size, label, rad, **style)
        if labels and value is not None:
            texts.append(
                ax.text(
                    *_arc_middle(pos[a], pos[b], rad),
                    f"{value:+.3f}",
                    fontsize=8,
                    ha="center",
                    va="center",
                    color="k" if resolved else "#6e6e6e",
                    zorder=4,
                    bbox={"facecolor": "white", "alpha": 0.85, "lw": 0, "pad": 0.6},
                )
            )
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    plt.colorbar(sm, ax=ax, label=LABELS[key] + " of the damaged link a→b", shrink=0.8)
    exact = key != "lambda_km"
    handles = [
        Line2D(
            [], [], color="#444444", lw=2.8, label="sign resolved" + (" (exact)" if exact else " (FDR 0.05)")
        ),
        Line2D([], [], color="#8c8c8c", lw=1.2, ls="--", label="not resolved" if not exact else "zero"),
    ]
    ax.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=2, frameon=False, fontsize=9
    )
    where = "value on each arrow" if labels else "values in index.md"
    ax.set_title(f"{view.graph}: damage to a→b, arrows coloured by {LABELS[key]} ({where})", fontsize=11)
    ax.set_axis_off()
    ax.margins(0.08)
    ax.autoscale_view()
    ax.set_xlim(ax.get_xlim())
    ax.set_ylim(ax.get_ylim())
    # nodes are drawn node_size points^2: a circle of sqrt(node_size) points across
    node_px = math.sqrt(node_size) / 2 * ax.figure.dpi / 72
    spread_labels(ax, texts, [pos[v] for v in und.nodes], node_px)


def link_table(view: JobView) -> list[str]:
    """Markdown lines: every link of ``view`` sorted by Lambda, with its 95% interval and the
    sign call (the table that replaces the arrows' labels on a graph of many links)."""
    key, recs = _lambdas(view)
    signs = link_signs(recs, key)
    rows = sorted(zip(recs, signs, strict=True), key=lambda rs: -(rs[0].get(key) or -math.inf))
    name = {"lambda_km": "Lambda^KM", "lambda_xi2": "Lambda^xi2", "lambda_rw": "Lambda^RW"}.get(key, key)
    rule = "sign (FDR 0.05)" if key == "lambda_km" else "sign (exact)"
    lines = [f"| link | {name} | 95% interval | {rule} |", "|:---|---:|:---|:---|"]
    outside = 0
    for r, s in rows:
        value = r.get(key)
        lo, hi = r.get(f"{key}_ci_low"), r.get(f"{key}_ci_high")
        interval = fmt_interval(lo, hi) if lo is not None and hi is not None else "exact"
        shown = "-" if value is None else f"{value:+.4g}"
        if outside_interval([value], [lo], [hi])[0]:  # as the figures mark it, with the reason below
            shown += " \u25c7"
            outside += 1
        lines.append(f"| {r['edge']} | {shown} | {interval} | {NAMES[int(s)]} |")
    if outside:
        lines += ["", f"\u25c7 {OUTSIDE_LABEL} ({outside}): {OUTSIDE_WHY}"]
    return lines


# ---- Fig. 1b: <F_beta> ---------------------------------------------------------------------
def plot_f_beta(view: JobView, ax, *, legend: bool = True) -> None:
    """Fig. 1b: <F_beta> with standard errors against beta, one curve per directed edge
    (dashed where Lambda^KM's sign is not resolved)."""
    plt = _plt()
    recs = [r for r in job_records(view) if r["beta"] is not None]
    lam = {r["edge"]: r["lambda_km"] for r in recs}
    key, links = _lambdas(view)
    signs = dict(zip((r["edge"] for r in links), link_signs(links, key), strict=True))
    norm = _norm(lam.values())
    cmap = plt.get_cmap(CMAP)
    for edge in sorted(lam, key=lambda e: -(lam[e] or 0)):
        rs = sorted((r for r in recs if r["edge"] == edge), key=lambda r: r["beta"])
        beta = [0.0] + [r["beta"] for r in rs]
        # a damage at which nothing synchronized has no <F_beta>: a gap in the curve
        f = [1.0] + [np.nan if r["F_mean"] is None else r["F_mean"] for r in rs]
        se = [0.0] + [r["F_se"] or 0.0 for r in rs]
        value = "n/a" if lam[edge] is None else f"{lam[edge]:+.3f}"
        resolved = signs.get(edge, 0) != 0
        ax.errorbar(
            beta,
            f,
            yerr=se,
            color=cmap(norm(lam[edge] or 0.0)),
            marker="o",
            ms=3,
            lw=1.4,
            ls="-" if resolved else "--",
            capsize=2,
            label=f"{edge} ({value})" + ("" if resolved else " n.s."),
        )
    if not any(r["F_mean"] is not None for r in recs):
        # only the anchor F_0 = 1 would show: say why there is no curve
        ax.text(
            0.5,
            0.7,
            textwrap.fill(
                "no <F_beta>: no damaged realization synchronized by t_max (see the summary's "
                "unsynced counts)",
                60,
            ),
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=9,
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
        )
        ax.set_xlim(0, max(view.betas) * 1.05)
    ax.axhline(1.0, color="k", ls="--", lw=0.8)
    ax.set_xlabel(r"damage $\beta$ (weight of a→b scaled by $1-\beta$)")
    ax.set_ylabel(r"$\langle \mathcal{F}_\beta \rangle = \langle \tau_0/\tau(\beta) \rangle$")
    title = f"{view.graph}: global functionality after damage to one link"
    if legend:
        ax.set_title(title, fontsize=11)
        ax.legend(
            fontsize=8,
            ncol=1,
            loc="center left",
            bbox_to_anchor=(1.25, 0.5),
            frameon=False,
            title="link (" + r"$\Lambda^{(\mathrm{KM})}$" + "); n.s.: sign not resolved",
            title_fontsize=8,
        )
    else:
        ax.set_title(f"{title}: {len(lam)} links, coloured by " + r"$\Lambda^{(\mathrm{KM})}$", fontsize=11)
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    plt.colorbar(sm, ax=ax, label=r"$\Lambda^{(\mathrm{KM})}$")


# ---- Figs. 1c-f: (tau0, tau(beta)) histograms ----------------------------------------------
def _nice_ceiling(x: float) -> float:
    """``x`` rounded up to a multiple of half its power of ten (27.3 -> 30, 8.2 -> 8.5)."""
    if x <= 0:
        return 1.0
    step = 10 ** math.floor(math.log10(x)) / 2
    return math.ceil(x / step - 1e-9) * step


def hist_limit(hists, tau_max: float, quantile: float = HIST_QUANTILE) -> float:
    """The histograms' upper axis limit: the ``quantile`` of tau0 and of tau(beta) in every one
    of ``hists`` (counts ``[i_tau0, i_tau]`` on ``[0, tau_max)``), 5% more, rounded up to a
    round number, at most ``tau_max``."""
    top = 0.0
    for h in hists:
        h = np.asarray(h, dtype=float)
        total = h.sum()
        if not total:
            continue
        width = tau_max / h.shape[0]
        for marginal in (h.sum(axis=1), h.sum(axis=0)):
            i = int(np.searchsorted(np.cumsum(marginal) / total, quantile))
            top = max(top, (i + 1) * width)
    return tau_max if top == 0 else min(tau_max, _nice_ceiling(1.05 * top))


def _density(view: JobView, k: int) -> tuple[np.ndarray, int]:
    h = view.hist[k].astype(float)
    total = int(h.sum())
    dens = h / (max(total, 1) * (view.tau_max_hist / h.shape[0]) ** 2)
    dens[dens == 0] = np.nan
    return dens, total


def plot_histogram(
    view: JobView, k: int, ax, *, limit: float | None = None, norm=None, colorbar: bool = True
):
    """Figs. 1c-f: log-density histogram of (tau0, tau(beta)) with the line tau(beta) = tau0.

    ``limit``: both axes end there (default :func:`hist_limit` of this histogram alone);
    ``norm``: the colour scale (shared by the panels of one figure). Returns the image, or
    None when no pair synchronized both times.
    """
    plt = _plt()
    v = int(view.hist_variants[k])
    edge = view.edges[int(view.variant_edge[v])]
    beta = float(view.variant_beta[v])
    tmax = view.tau_max_hist
    h = view.hist[k]
    dens, total = _density(view, k)
    limit = hist_limit([h], tmax) if limit is None else limit
    ax.set_title(f"{edge}, " + r"$\beta$" + f" = {beta:g}", fontsize=10)
    ax.set_xlabel(r"$\tau_0$, undamaged (time units)")
    ax.set_ylabel(r"$\tau(\beta)$, damaged")
    ax.set_xlim(0, limit)
    ax.set_ylim(0, limit)
    ax.set_aspect("equal")
    if total == 0:
        ax.text(
            0.5, 0.5, "no pair synchronized\nboth times", ha="center", va="center", transform=ax.transAxes
        )
        return None
    img = ax.imshow(
        dens.T,
        origin="lower",
        extent=(0, tmax, 0, tmax),
        norm=norm or LogNorm(),
        cmap="viridis",
        interpolation="nearest",
    )
    ax.set_xlim(0, limit)  # imshow resets the limits to its extent
    ax.set_ylim(0, limit)
    halo = [patheffects.withStroke(linewidth=2.4, foreground="white")]
    ax.plot([0, limit], [0, limit], **DIAGONAL, path_effects=halo, label=r"$\tau(\beta) = \tau_0$")
    faster = np.tril(h, -1).sum() / total  # tau(beta) < tau0: the antifragile side
    slower = np.triu(h, 1).sum() / total
    box = {"facecolor": "white", "alpha": 0.85, "lw": 0, "pad": 1.5}
    ax.text(
        0.97,
        0.03,
        f"faster after damage\n{faster:.0%} of {total:,}",
        transform=ax.transAxes,
        ha="right",
        va="bottom",
        fontsize=8,
        bbox=box,
    )
    ax.text(
        0.03, 0.97, f"slower: {slower:.0%}", transform=ax.transAxes, ha="left", va="top", fontsize=8, bbox=box
    )
    if colorbar:
        plt.colorbar(img, ax=ax, label="probability density (log scale)")
    return img


def _beyond(hists, tau_max: float, limit: float) -> tuple[int, int]:
    """``(pairs, total)``: how many of the pairs lie beyond ``limit`` on either axis."""
    beyond = total = 0
    for h in hists:
        h = np.asarray(h)
        cut = int(math.ceil(limit / (tau_max / h.shape[0]) - 1e-9))
        total += int(h.sum())
        beyond += int(h.sum() - h[:cut, :cut].sum())
    return beyond, total


def plot_histograms(view: JobView, ks: list[int]):
    """Every histogram ``ks`` of ``view`` in one figure: a row per link and a column per beta
    when there are several betas, else a grid of up to four columns; shared axes fitted to the
    data (:func:`hist_limit`), one colour scale, one line tau(beta) = tau0 per panel."""
    plt = _plt()
    edges = list(dict.fromkeys(int(view.variant_edge[view.hist_variants[k]]) for k in ks))
    betas = sorted({float(view.variant_beta[view.hist_variants[k]]) for k in ks})
    if len(betas) > 1:
        nrows, ncols = len(edges), len(betas)
        cell = {
            (
                edges.index(int(view.variant_edge[view.hist_variants[k]])),
                betas.index(float(view.variant_beta[view.hist_variants[k]])),
            ): k
            for k in ks
        }
    else:
        ncols = min(4, len(ks))
        nrows = -(-len(ks) // ncols)
        cell = {divmod(i, ncols): k for i, k in enumerate(ks)}
    hists = [view.hist[k] for k in ks]
    tmax = view.tau_max_hist
    limit = hist_limit(hists, tmax)
    dens = [_density(view, k)[0] for k in ks]
    finite = np.concatenate([d[np.isfinite(d)] for d in dens]) if dens else np.array([])
    norm = LogNorm(vmin=float(finite.min()), vmax=float(finite.max())) if finite.size else None
    fig, axes = plt.subplots(
        nrows,
        ncols,
        figsize=(2.9 * ncols + 1.2, 2.9 * nrows + 1.1),
        squeeze=False,
        sharex=True,
        sharey=True,
        layout="constrained",
    )
    img = None
    for (row, col), ax in np.ndenumerate(axes):
        k = cell.get((row, col))
        if k is None:
            ax.set_visible(False)
            continue
        img = plot_histogram(view, k, ax, limit=limit, norm=norm, colorbar=False) or img
        if row < nrows - 1 and cell.get((row + 1, col)) is not None:
            ax.set_xlabel("")
        if col > 0:
            ax.set_ylabel("")
    if img is not None:
        fig.colorbar(img, ax=axes.ravel().tolist(), shrink=0.7, label="probability density (log scale)")
    beyond, total = _beyond(hists, tmax, limit)
    fig.suptitle(
        f"{view.graph}: synchronization times from the same initial phases, without (" + r"$\tau_0$"
        ") and with (" + r"$\tau(\beta)$" + ") damage to a→b\nbelow the dashed line "
        r"$\tau(\beta) = \tau_0$" + ": the damaged network synchronized faster",
        fontsize=11,
    )
    shown = f"the {HIST_QUANTILE:.1%} quantile of both times" if limit < tmax else "the histogram's range"
    note = (
        f"Axes end at {limit:g} ({shown}; times beyond the histogram's {tmax:g} sit in its last "
        f"bin): {beyond:,} of {total:,} pairs ({beyond / max(total, 1):.2%}) lie outside. Faster / "
        f"slower: pairs in a bin below / above the line's bins (bins {tmax / view.hist.shape[1]:.2g} "
        "wide); the rest synchronized within one bin of tau0."
    )
    fig.text(
        0.5,
        -0.01,
        textwrap.fill(note, int(15 * fig.get_figwidth())),  # about 15 characters an inch at 8 pt
        ha="center",
        va="top",
        fontsize=8,
    )
    return fig


# ---- the report ----------------------------------------------------------------------------
def conditioning_note(view: JobView) -> str | None:
    """A figure's footnote when some realizations never synchronized: every Kuramoto number
    (F, tau, Lambda^KM) averages only over those that did."""
    n, n_already, n_not = (float(x) for x in view.rec0[view.done][:, :3].sum(axis=0))
    if not n_not:
        return None
    done = n + n_already + n_not
    return (
        "Kuramoto values average over the realizations that synchronized by t_max: "
        f"P_sync = {(n + n_already) / done:.3f} undamaged ({int(n_not):,} of {int(done):,} did "
        "not); the summary's p_sync_response is each link's effect on it"
    )


#: what each figure answers, for ``index.md``: (file suffix, text)
ANSWERS = (
    ("_graph", "Which links, damaged, speed up (red) or slow down (blue) synchronization?"),
    ("_F_beta", "How does global functionality <F_beta> change with the damage beta, link by link?"),
    ("_histograms", "Realization by realization, is the damaged network faster (below the line) or slower?"),
    ("_lambda_sorted", "How are the links' Lambda distributed, and which are resolved from 0?"),
    ("_top_links", "Where in the network are the most antifragile and most fragile links, and how sure?"),
    ("_map", "Where in the network is every link whose sign is resolved, and how strong is it?"),
    ("_measure_pairs", "Do the cheap exact measures rank and sign the links as Lambda^KM does?"),
    ("fig5_measures", "Do the response measures agree with each other (the paper's Fig. 5)?"),
    ("_fig7e_km_nnc", "Does non-normalized coupling change each link's Lambda (the paper's Fig. 7e)?"),
)


def _index(name: str | None, written: list[Path], notes: list[str], tables: dict[str, list[str]]) -> str:
    lines = [f"# Figures of {name}" if name else "# Figures", "", "| file | what it answers |", "|:---|:---|"]
    for p in written:
        if p.suffix != ".png":
            continue
        answer = next((a for suffix, a in ANSWERS if p.stem.endswith(suffix)), "")
        lines.append(f"| [{p.name}]({p.name}) | {answer} |")
    if notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in dict.fromkeys(notes)]
    for graph, table in tables.items():
        lines += ["", f"## Every link of {graph}", ""] + table
    return "\n".join(lines) + "\n"


def write_report(
    views: list[JobView],
    folder: str | Path,
    *,
    pdf: bool = False,
    hist_betas: tuple | None = None,
    top: int = 10,
    name: str | None = None,
) -> list[Path]:
    """Write every figure for every job into ``folder``, and ``index.md``; returns the paths.

    ``name``: the config's ``name:`` (see :func:`job_stems`; default: each job's own name).
    ``hist_betas``: the damages whose histograms are drawn (default: every one stored).
    ``top``: for a large graph (:func:`~antisync.report.links.is_large`), how many of the most
    antifragile and of the most fragile links ``<stem>_top_links`` draws strong.
    """
    plt = _plt()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    notes: list[str] = []
    tables: dict[str, list[str]] = {}
    stems = job_stems(views, name)
    # each job called by the name the summary gives it (titles, notes, tables), its files by
    # the same name made safe
    names = graph_names(views, name)
    stems = {names[job]: stem for job, stem in stems.items()}
    views = named_views(views, name)

    def save(fig, stem: str, note: str | None = None) -> None:
        if note:
            fig.text(0.5, -0.04, textwrap.fill(note, 130), ha="center", va="top", fontsize=8)
        for ext in ("png", "pdf") if pdf else ("png",):
            p = folder / f"{stem}.{ext}"
            fig.savefig(p, dpi=130, bbox_inches="tight")
            written.append(p)
        plt.close(fig)

    for view in views:
        stem = stems[view.graph]
        large = is_large(view)
        hist_edges = None  # every edge's histograms
        note = conditioning_note(view)
        if note:
            notes.append(f"{view.graph}: {note}")
        if large:
            first: dict[str, dict] = {}  # one record per link: Lambda does not depend on beta
            for r in job_records(view):
                first.setdefault(r["edge"], r)
            links = list(first.values())
            for fig, suffix in link_figures(view, links, k=top):
                save(fig, f"{stem}_{suffix}", note)
            key = primary_measure(links)
            if key is not None:
                strong = top_links(links, key, top)
                hist_edges = {r["edge"] for r in strong[0] + strong[1]}
        else:
            fig, ax = plt.subplots(figsize=(7.5, 6))
            plot_graph(view, ax)
            save(fig, f"{stem}_graph", note)
            if len(view.edges) > LABEL_LINKS:
                tables[view.graph] = link_table(view)
        if view.betas:
            fig, ax = plt.subplots(figsize=(7.5, 5))
            plot_f_beta(view, ax, legend=not large)
            save(fig, f"{stem}_F_beta", note)
        chosen = [
            k
            for k, v in enumerate(view.hist_variants if view.hist is not None else ())
            if (hist_betas is None or np.any(np.isclose(view.variant_beta[v], hist_betas)))
            and (hist_edges is None or view.edges[int(view.variant_edge[v])] in hist_edges)
        ]
        if chosen:
            save(plot_histograms(view, chosen), f"{stem}_histograms", note)
    # Figs. 5 and 7e when the file holds linear/xi2/RW measures or a km_nnc twin
    covered = {v.graph for v in views if is_large(v)}  # their measure_pairs already show Fig. 5
    for fig, stem in measure_figures(views, stems=stems, covered=covered, notes=notes):
        save(fig, stem)
    index = folder / "index.md"
    index.write_text(_index(name, written, notes, tables))
    written.append(index)
    return written


def write_file_report(
    path: str | Path, folder: str | Path, *, pdf: bool = False, top: int = 10
) -> list[Path]:
    """:func:`write_report` of the result file ``path`` (not a sweep's), its files named after
    the ``name:`` of the config it stores."""
    name = stored_name(stored_config(Path(path)))
    return write_report(read_views(path), folder, pdf=pdf, top=top, name=name)
