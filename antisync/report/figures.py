"""Figures from a result file (never from a live run): the paper's Fig. 1 panels per job.

- ``<job>_graph``: the graph with each directed edge drawn as an arrow coloured by Lambda^KM
  (Fig. 1a), its value written beside it (small graphs only; a file run without ``km`` colours
  by its first exact measure, Lambda^(xi2) or Lambda^(RW));
- ``<job>_F_beta``: <F_beta> against beta for every edge, coloured by Lambda^KM (Fig. 1b; no
  legend for a large graph);
- ``<job>_hist_<edge>_b<beta>``: log-density 2D histograms of (tau0, tau(beta)) with the
  line tau(beta) = tau0 (Figs. 1c-f; for a large graph only of the links drawn strong in
  ``<job>_top_links``);
- for a graph with more than 20 nodes or 40 links, instead of ``<job>_graph``:
  ``<job>_lambda_sorted``, ``<job>_top_links``, ``<job>_measure_pairs``, see
  :mod:`antisync.report.links`;
- ``fig5_measures``, ``<job>_fig7e_km_nnc``: see :mod:`antisync.report.measures`.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from antisync.records import primary_measure
from antisync.report.links import is_large, link_figures, top_links
from antisync.report.measures import LABELS
from antisync.summary import JobView, job_records

__all__ = ["write_report"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _norm(values):
    from matplotlib.colors import TwoSlopeNorm

    vals = np.array([v for v in values if v is not None and np.isfinite(v)])
    top = float(np.max(np.abs(vals))) if vals.size else 1.0
    top = top or 1.0
    return TwoSlopeNorm(vmin=-top, vcenter=0.0, vmax=top)


CMAP = "coolwarm"


def _lambdas(view: JobView) -> tuple[str, dict[str, float]]:
    """``(key, {edge: value})``: Lambda^KM, or the first exact measure of a job without km."""
    recs = job_records(view)
    key = primary_measure(recs) or "lambda_km"
    return key, {r["edge"]: r[key] for r in recs}


def plot_graph(view: JobView, ax) -> None:
    """Fig. 1a: arrows a->b coloured by Lambda^KM(a->b)."""
    import networkx as nx

    plt = _plt()
    key, lam = _lambdas(view)
    g = nx.DiGraph()
    g.add_nodes_from(str(n) for n in view.nodes)
    for label in view.edges:
        a, b = label.split("->")
        g.add_edge(a, b)
    und = nx.Graph(g)
    for a, b in zip(*np.nonzero(view.omega), strict=True):
        und.add_edge(str(view.nodes[a]), str(view.nodes[b]))
    pos = nx.kamada_kawai_layout(und)
    norm = _norm(lam.values())
    cmap = plt.get_cmap(CMAP)
    nx.draw_networkx_nodes(und, pos, ax=ax, node_color="#f0f0f0", edgecolors="k", node_size=420)
    nx.draw_networkx_labels(und, pos, ax=ax, font_size=10)
    nx.draw_networkx_edges(und, pos, ax=ax, edge_color="#dddddd", width=1.0)
    for label in view.edges:
        a, b = label.split("->")
        value = lam.get(label)
        color = cmap(norm(value)) if value is not None else "grey"
        nx.draw_networkx_edges(
            g,
            pos,
            edgelist=[(a, b)],
            ax=ax,
            edge_color=[color],
            width=2.5,
            arrows=True,
            arrowsize=14,
            node_size=420,
            connectionstyle="arc3,rad=0.18",
        )
        # the value sits beside the arrow, on the side its curvature bends to
        pa, pb = np.array(pos[a]), np.array(pos[b])
        mid = (pa + pb) / 2 + 0.12 * np.array([pb[1] - pa[1], pa[0] - pb[0]])
        if value is not None:
            ax.text(*mid, f"{value:+.3f}", fontsize=7, ha="center", va="center", color="k")
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    plt.colorbar(sm, ax=ax, label=LABELS[key], shrink=0.8)
    ax.set_title(f"{view.graph}: damaged link a->b coloured by " + LABELS[key])
    ax.set_axis_off()


def plot_f_beta(view: JobView, ax, *, legend: bool = True) -> None:
    """Fig. 1b: <F_beta> with standard errors against beta, one curve per directed edge."""
    plt = _plt()
    recs = [r for r in job_records(view) if r["beta"] is not None]
    lam = {r["edge"]: r["lambda_km"] for r in recs}
    norm = _norm(lam.values())
    cmap = plt.get_cmap(CMAP)
    for edge in sorted(lam, key=lambda e: -(lam[e] or 0)):
        rs = sorted((r for r in recs if r["edge"] == edge), key=lambda r: r["beta"])
        beta = [0.0] + [r["beta"] for r in rs]
        # a damage at which nothing synchronized has no <F_beta>: a gap in the curve
        f = [1.0] + [np.nan if r["F_mean"] is None else r["F_mean"] for r in rs]
        se = [0.0] + [r["F_se"] or 0.0 for r in rs]
        value = "n/a" if lam[edge] is None else f"{lam[edge]:+.3f}"
        ax.errorbar(
            beta,
            f,
            yerr=se,
            color=cmap(norm(lam[edge] or 0.0)),
            marker="o",
            ms=3,
            lw=1.4,
            capsize=2,
            label=f"{edge} ({value})",
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
    ax.set_xlabel(r"damage $\beta$")
    ax.set_ylabel(r"$\langle \mathcal{F}_\beta \rangle = \langle \tau_0/\tau(\beta) \rangle$")
    if legend:
        ax.set_title(r"global functionality; legend: edge ($\Lambda^{(\mathrm{KM})}$)")
        ax.legend(fontsize=7, ncol=2)
    else:
        ax.set_title(f"global functionality of {len(lam)} links, coloured by " + r"$\Lambda^{(\mathrm{KM})}$")
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    plt.colorbar(sm, ax=ax, label=r"$\Lambda^{(\mathrm{KM})}$")


def plot_histogram(view: JobView, k: int, ax) -> None:
    """Figs. 1c-f: log-density histogram of (tau0, tau(beta)) with the line tau(beta) = tau0."""
    from matplotlib.colors import LogNorm

    plt = _plt()
    v = int(view.hist_variants[k])
    h = view.hist[k].astype(float)
    total = h.sum()
    if total == 0:
        ax.text(0.5, 0.5, "no synchronized pairs", ha="center", transform=ax.transAxes)
        return
    tmax = view.tau_max_hist
    bins = h.shape[0]
    dens = h / (total * (tmax / bins) ** 2)
    dens[dens == 0] = np.nan
    img = ax.imshow(
        dens.T,
        origin="lower",
        extent=(0, tmax, 0, tmax),
        norm=LogNorm(),
        cmap="viridis",
        aspect="equal",
        interpolation="nearest",
    )
    ax.plot([0, tmax], [0, tmax], "w--", lw=1)
    edge = view.edges[int(view.variant_edge[v])]
    beta = float(view.variant_beta[v])
    below = np.tril(h, -1).sum() / total  # tau(beta) < tau0: the antifragile side
    ax.set_title(
        f"{edge}, beta={beta:g}: {below:.1%} of pairs below the line ({int(total):,} pairs)", fontsize=9
    )
    ax.set_xlabel(r"$\tau_0$")
    ax.set_ylabel(r"$\tau(\beta)$")
    plt.colorbar(img, ax=ax, label="probability density (log)")


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


def write_report(
    views: list[JobView], folder: str | Path, *, pdf: bool = False, hist_betas: tuple = (0.5,), top: int = 10
) -> list[Path]:
    """Write every figure for every job into ``folder``; returns the written paths.

    ``top``: for a large graph (:func:`~antisync.report.links.is_large`), how many of the most
    antifragile and of the most fragile links ``<job>_top_links`` draws strong.
    """
    plt = _plt()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def save(fig, stem: str, note: str | None = None) -> None:
        if note:
            fig.text(0.5, -0.01, note, ha="center", va="top", fontsize=8, wrap=True)
        for ext in ("png", "pdf") if pdf else ("png",):
            p = folder / f"{stem}.{ext}"
            fig.savefig(p, dpi=130, bbox_inches="tight")
            written.append(p)
        plt.close(fig)

    for view in views:
        large = is_large(view)
        hist_edges = None  # every edge's histograms
        note = conditioning_note(view)
        if large:
            first: dict[str, dict] = {}  # one record per link: Lambda does not depend on beta
            for r in job_records(view):
                first.setdefault(r["edge"], r)
            links = list(first.values())
            for fig, stem in link_figures(view, links, k=top):
                save(fig, stem, note)
            key = primary_measure(links)
            if key is not None:
                strong = top_links(links, key, top)
                hist_edges = {r["edge"] for r in strong[0] + strong[1]}
        else:
            fig, ax = plt.subplots(figsize=(7, 5.5))
            plot_graph(view, ax)
            save(fig, f"{view.graph}_graph", note)
        if view.betas:
            fig, ax = plt.subplots(figsize=(7.5, 5))
            plot_f_beta(view, ax, legend=not large)
            save(fig, f"{view.graph}_F_beta", note)
        chosen = [
            k
            for k, v in enumerate(view.hist_variants)
            if np.any(np.isclose(view.variant_beta[v], hist_betas))
            and (hist_edges is None or view.edges[int(view.variant_edge[v])] in hist_edges)
        ]
        for k in chosen:
            v = int(view.hist_variants[k])
            fig, ax = plt.subplots(figsize=(5.5, 4.8))
            plot_histogram(view, k, ax)
            edge = view.edges[int(view.variant_edge[v])].replace("->", "to")
            save(fig, f"{view.graph}_hist_{edge}_b{view.variant_beta[v]:g}", note)
    # Figs. 5 and 7e when the file holds linear/xi2/RW measures or a km_nnc twin
    from antisync.report.measures import measure_figures

    for fig, stem in measure_figures(views):
        save(fig, stem)
    return written
