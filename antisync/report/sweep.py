"""Figures and tables of a sweep file (never from a live run): the paper's Figs. 2, 3, 4, 6, Table 1.

Which outputs a sweep gets depends on what it holds:

- every sweep: ``index.md`` (screening, exclusions, symmetry savings, what was written);
- more than one graph, not lollipops: ``fig3_ranking`` (graphs sorted by the sum of their
  positive Lambda^KM, small multiples on one colour scale) and ``table1.{md,csv,tex}``;
  ``fig5_measures`` when the config's ``measures`` stored Lambda^(linear, xi2, RW);
- a top stage (or betas in the main stage): ``fig4_histograms`` of (tau0, tau(beta));
- the lollipop family: ``fig2a_F_beta`` (<F_beta> against beta, coloured by N) and
  ``fig2b_lambda_N`` (Lambda^KM against N, mean and standard deviation over repeats);
- several thresholds: ``fig6a_thresholds`` and ``fig6b_xi2`` (Lambda^KM against Lambda^(xi2)
  with the fits Lambda^KM = gamma Lambda^(xi2) + C; needs :mod:`antisync.measures.spectral`);
- a grid over config keys (``sweep.grid``/``zip``): ``grid_lambda`` (.png, .md) only
  (:mod:`antisync.report.grid_sweep`), since the figures above would mix the grid's points.

Each directed edge ``a -> b`` is drawn as the half of the link next to ``a``: damaging
``a -> b`` changes row ``a`` of ``W`` (Eq. 4), so a link's two halves show its two directions.
"""

from __future__ import annotations

import math
from pathlib import Path

import networkx as nx
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize

from antisync.report.figures import CMAP, _norm, _plt, hist_limit, plot_histogram
from antisync.report.grid_sweep import write_grid_report
from antisync.report.intervals import draw_intervals
from antisync.report.tables import fmt_pm, format_table1
from antisync.stats.estimators import Z95
from antisync.store import read_views
from antisync.sweeps.analysis import edge_lambdas, ranking, trend_in_n
from antisync.sweeps.results import sweep_summary

__all__ = [
    "fit_gamma",
    "lambda_xi2_records",
    "plot_fig2",
    "plot_fig5",
    "plot_fig6",
    "plot_ranking",
    "plot_top_histograms",
    "table1_rows",
    "write_sweep_report",
]


# ---- data ----------------------------------------------------------------------------------
def _graph_meta(summary: dict) -> dict[str, dict]:
    return {g["graph"]: g for g in summary["meta"]["graphs"]}


def _layout(gm: dict) -> dict:
    g = nx.Graph()
    g.add_nodes_from(str(v) for v in gm["nodes"])
    g.add_edges_from((str(u), str(v)) for u, v in gm["undirected_edges"])
    if g.number_of_nodes() <= 2:
        return {v: np.array([float(i), 0.0]) for i, v in enumerate(g.nodes)}
    return nx.kamada_kawai_layout(g)


def table1_rows(summary: dict, n: int = 7) -> list[dict]:
    """Rows of Table 1: the first ``n`` graphs of the ranking with their most antifragile edge.

    ``<tau0>`` and ``<F_beta>`` come from the top stage when there is one (more realizations,
    as in the paper), else from the main stage (``F`` only if it has a beta).
    """
    t = summary["ranking_threshold"]
    rows = ranking(summary["records"], t)[:n]
    top = {r["graph"]: r for r in summary["top"]}
    main_f = {}
    for r in summary["records"]:
        if r.get("beta") is not None and r.get("repeat", 0) == 0 and math.isclose(r["threshold"], t):
            main_f.setdefault((r["graph"], r["edge"]), []).append(r)
    out = []
    for row in rows:
        rec = {
            "rank": row["rank"],
            "graph": row["graph"],
            "edge": row["max_edge"],
            "lambda_km": row["lambda_max"],
            "lambda_km_se": row["lambda_max_se"],
            "tau0_mean": row["tau0_mean"],
            "tau0_se": row["tau0_se"],
            "F_mean": None,
            "F_se": None,
            "beta": None,
            "n_tau0": None,
            "n_F": None,
        }
        src = top.get(row["graph"])
        if src is None:
            cands = main_f.get((row["graph"], row["max_edge"]), [])
            src = min(cands, key=lambda r: abs(r["beta"] - 0.5)) if cands else None
        if src is not None:
            rec.update(
                F_mean=src["F_mean"],
                F_se=src["F_se"],
                beta=src["beta"],
                n_F=src["n"],
                n_tau0=src["tau0_n"],
                tau0_mean=src["tau0_mean"],
                tau0_se=src["tau0_se"],
            )
        out.append(rec)
    return out


def lambda_xi2_records(summary: dict, graphs: set | None = None) -> dict[tuple, float]:
    """``{(graph, edge): Lambda^(xi2)}`` (Eq. 16) for every fanned-out edge of the kept graphs.

    Raises ``ImportError`` when :func:`antisync.measures.spectral.lambda_xi2` is absent.
    """
    # lazy: plot_fig6 skips Fig. 6b on the ImportError this may raise
    from antisync.measures.spectral import lambda_xi2

    coupling = summary["meta"].get("coupling", "normalized")
    out = {}
    for name, gm in _graph_meta(summary).items():
        if gm["excluded"] or (graphs is not None and name not in graphs):
            continue
        index = {str(v): i for i, v in enumerate(gm["nodes"])}
        n = len(index)
        omega = np.zeros((n, n))
        for u, v in gm["undirected_edges"]:
            omega[index[str(u)], index[str(v)]] = omega[index[str(v)], index[str(u)]] = 1.0
        for label in gm["orbits"]:
            a, b = label.split("->")
            out[(name, label)] = float(lambda_xi2(omega, index[a], index[b], coupling))
    return out


def fit_gamma(x: np.ndarray, y: np.ndarray) -> dict:
    """Least-squares line ``y = gamma x + C`` with standard errors of ``gamma`` and ``C``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = x.size
    a = np.column_stack([x, np.ones(n)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    dof = max(n - 2, 1)
    cov = np.linalg.inv(a.T @ a) * float(resid @ resid) / dof
    r = float(np.corrcoef(x, y)[0, 1]) if n > 2 else math.nan
    return {
        "gamma": float(coef[0]),
        "gamma_se": float(math.sqrt(cov[0, 0])),
        "C": float(coef[1]),
        "C_se": float(math.sqrt(cov[1, 1])),
        "n": int(n),
        "pearson_r": r,
    }


# ---- drawing -------------------------------------------------------------------------------
def _draw_halves(
    ax,
    gm: dict,
    lam: dict,
    norm,
    cmap,
    *,
    width: float = 2.2,
    node_size: float = 18,
    labels: bool = False,
    mark: tuple | None = None,
) -> None:
    """Each link u-v as two halves: the half at u coloured by Lambda(u->v), the other by Lambda(v->u)."""
    pos = _layout(gm)
    segs, colors = [], []
    for u, v in gm["undirected_edges"]:
        u, v = str(u), str(v)
        pu, pv = np.asarray(pos[u]), np.asarray(pos[v])
        mid = (pu + pv) / 2
        for a, pa in ((u, pu), (v, pv)):
            b = v if a == u else u
            value = lam.get(f"{a}->{b}")
            segs.append([pa, mid])
            colors.append(cmap(norm(value)) if value is not None else (0.75, 0.75, 0.75, 1.0))
    ax.add_collection(LineCollection(segs, colors=colors, linewidths=width, zorder=1, capstyle="butt"))
    xy = np.array([pos[str(v)] for v in gm["nodes"]])
    ax.scatter(xy[:, 0], xy[:, 1], s=node_size, c="white", edgecolors="k", linewidths=0.6, zorder=2)
    if labels or mark:
        for v in gm["nodes"]:
            text = str(v)
            if mark and str(v) in mark:
                text = "a" if str(v) == mark[0] else "b"
            if labels or (mark and str(v) in mark):
                ax.annotate(
                    text,
                    pos[str(v)],
                    ha="center",
                    va="center",
                    fontsize=8,
                    zorder=3,
                    fontweight="bold" if mark and str(v) in mark else "normal",
                )
    # one square frame for every graph, so small multiples line up
    c = (xy.max(axis=0) + xy.min(axis=0)) / 2
    half = max(float(np.max(xy.max(axis=0) - xy.min(axis=0))) / 2, 0.5) + 0.22
    ax.set_xlim(c[0] - half, c[0] + half)
    ax.set_ylim(c[1] - half, c[1] + half)
    ax.set_aspect("equal")
    ax.set_axis_off()


def plot_ranking(summary: dict, ncols: int = 11):
    """Fig. 3: kept graphs ranked by the sum of their positive Lambda^KM, one colour scale."""
    plt = _plt()
    t = summary["ranking_threshold"]
    rows = ranking(summary["records"], t)
    lam_all = edge_lambdas(summary["records"], t)
    values = np.array([v["lambda_km"] for v in lam_all.values()], dtype=float)
    # the scale ends at the 99.5% quantile of |Lambda|: a few noisy extremes would wash out
    # every other link; the colour bar's arrows say that some values lie beyond
    top = float(np.nanquantile(np.abs(values), 0.995)) if values.size else 1.0
    norm = _norm([-top, top])
    extend = "both" if values.size and np.nanmax(np.abs(values)) > top else "neither"
    cmap = plt.get_cmap(CMAP)
    gms = _graph_meta(summary)
    ncols = max(1, min(ncols, len(rows)))
    nrows = max(1, -(-len(rows) // ncols))
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(1.3 * ncols, 1.3 * nrows + 0.9), squeeze=False, layout="constrained"
    )
    for ax in axes.flat:
        ax.set_axis_off()
    for ax, row in zip(axes.flat, rows, strict=False):
        lam = {e: v["lambda_km"] for (g, e), v in lam_all.items() if g == row["graph"]}
        _draw_halves(ax, gms[row["graph"]], lam, norm, cmap)
        ax.text(
            0.5,
            -0.02,
            f"{row['rank']}: {row['graph']}",
            transform=ax.transAxes,
            ha="center",
            va="top",
            fontsize=7,
        )
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(
        sm,
        ax=axes.ravel().tolist(),
        location="bottom",
        shrink=0.6,
        aspect=45,
        pad=0.02,
        extend=extend,
        label=r"$\Lambda^{(\mathrm{KM})}$ of $a\to b$, drawn on the half of the link at $a$",
    )
    n_ex = len(summary["excluded"])
    fig.suptitle(
        f"{len(rows)} graphs ranked by the sum of positive "
        r"$\Lambda^{(\mathrm{KM})}$" + f" (r = {t:g}; {n_ex} excluded by screening)",
        fontsize=10,
    )
    return fig


def plot_top_histograms(summary: dict, views: list, n: int = 7):
    """Fig. 4: for each top graph, the graph with its edge a->b and the (tau0, tau(beta)) histogram."""
    plt = _plt()
    t = summary["ranking_threshold"]
    by_job = {v.graph: v for v in views}
    gms = _graph_meta(summary)
    lam_all = edge_lambdas(summary["records"], t)
    norm = _norm([v["lambda_km"] for v in lam_all.values()])
    cmap = plt.get_cmap(CMAP)
    panels = []
    for row in table1_rows(summary, n):
        job = next(
            (
                jm["job"]
                for jm in summary["meta"]["jobs"]
                if jm["graph"] == row["graph"] and jm["stage"] == "top"
            ),
            None,
        )
        if job is None:
            job = next(
                (
                    jm["job"]
                    for jm in summary["meta"]["jobs"]
                    if jm["graph"] == row["graph"]
                    and jm["stage"] == "main"
                    and jm["repeat"] == 0
                    and math.isclose(jm["threshold"], t)
                ),
                None,
            )
        view = by_job.get(job)
        if view is None or view.hist is None or not len(view.hist_variants):
            continue
        rep = next(
            (
                r["representative"]
                for r in summary["records"]
                if r["graph"] == row["graph"] and r["edge"] == row["edge"]
            ),
            row["edge"],
        )
        ks = [k for k, v in enumerate(view.hist_variants) if view.edges[int(view.variant_edge[v])] == rep]
        if ks:
            k = min(ks, key=lambda k: abs(view.variant_beta[view.hist_variants[k]] - 0.5))
            panels.append((row, view, k))
    if not panels:
        return None
    fig, axes = plt.subplots(
        len(panels),
        2,
        figsize=(8.5, 4.0 * len(panels)),
        squeeze=False,
        gridspec_kw={"width_ratios": [1, 1.4], "hspace": 0.4},
    )
    # one pair of axes for every histogram, fitted to the data (not to the histogram's tau_max)
    limit = max(hist_limit([view.hist[k]], view.tau_max_hist) for _, view, k in panels)
    for (row, view, k), (ax_g, ax_h) in zip(panels, axes, strict=True):
        lam = {e: v["lambda_km"] for (g, e), v in lam_all.items() if g == row["graph"]}
        a, b = row["edge"].split("->")
        _draw_halves(ax_g, gms[row["graph"]], lam, norm, cmap, width=4, node_size=160, mark=(a, b))
        lm, ls = fmt_pm(row["lambda_km"], row["lambda_km_se"])
        ax_g.set_title(
            f"rank {row['rank']}: {row['graph']}, a->b = {row['edge']}\n"
            + r"$\Lambda^{(\mathrm{KM})}$"
            + f" = {lm} ± {ls}",
            fontsize=9,
        )
        plot_histogram(view, k, ax_h, limit=limit)
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=axes[:, 0].tolist(), location="left", shrink=0.5, label=r"$\Lambda^{(\mathrm{KM})}$")
    fig.suptitle(
        "left: each graph coloured by "
        + r"$\Lambda^{(\mathrm{KM})}$"
        + ", its most antifragile link a->b; right: synchronization times from the same initial\n"
        "phases without (" + r"$\tau_0$" + ") and with (" + r"$\tau(\beta)$" + ") damage to a->b; "
        "below the dashed line the damaged network synchronized faster",
        fontsize=9,
        y=1 - 0.15 / fig.get_figheight(),
    )
    fig.subplots_adjust(top=1 - 0.9 / fig.get_figheight())  # the default top leaves inches blank
    return fig


def plot_fig2(summary: dict):
    """Fig. 2: (a) <F_beta> against beta per lollipop size N; (b) Lambda^KM against N.

    Returns ``(fig_a or None, fig_b, rows_b)``; ``rows_b`` holds N, mean, sd over repeats and se.
    """
    plt = _plt()
    gms = _graph_meta(summary)
    size = {g: int(m["spec"]["nodes"]) for g, m in gms.items() if m["spec"].get("kind") == "lollipop"}
    t = summary["ranking_threshold"]
    recs = [r for r in summary["records"] if math.isclose(r["threshold"], t) and r["graph"] in size]
    fig_a = None
    curves = {}
    for r in recs:
        if r.get("beta") is not None and r.get("repeat", 0) == 0 and r["edge"] == r["representative"]:
            curves.setdefault(r["graph"], []).append(r)
    if curves:
        fig_a, ax = plt.subplots(figsize=(6.5, 4.6))
        ns = sorted(size[g] for g in curves)
        norm = Normalize(vmin=min(ns), vmax=max(ns))
        cmap = plt.get_cmap("viridis")
        for g in sorted(curves, key=lambda g: size[g]):
            rs = sorted(curves[g], key=lambda r: r["beta"])
            beta = [0.0] + [r["beta"] for r in rs]
            f = [1.0] + [r["F_mean"] for r in rs]
            se = [0.0] + [r["F_se"] or 0.0 for r in rs]
            color = cmap(norm(size[g]))
            ax.plot(beta, f, color=color, lw=1.3)
            ax.fill_between(beta, np.subtract(f, se), np.add(f, se), color=color, alpha=0.25, lw=0)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_xlabel(r"damage $\beta$")
        ax.set_ylabel(r"$\langle \mathcal{F}_\beta \rangle = \langle \tau_0/\tau(\beta) \rangle$")
        ax.set_title(
            f"lollipops, edge a->b in the clique away from the bridge (r = {t:g});\n"
            "bands: ± 1 standard error; dashed: no change",
            fontsize=9,
        )
        fig_a.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="N")
    lam = edge_lambdas(recs, t)
    rows = {}
    for (g, edge), v in lam.items():
        if g in size and v["representative"] == edge:
            rows.setdefault(size[g], v)
    rows_b = [{"N": n, **rows[n]} for n in sorted(rows)]
    fig_b, ax = plt.subplots(figsize=(6.0, 4.2))
    if rows_b:
        n = np.array([r["N"] for r in rows_b])
        m = np.array([r["lambda_km"] for r in rows_b])
        sd = np.array([r["sd"] for r in rows_b])
        se = np.array([r["lambda_km_se"] for r in rows_b])
        has_sd = np.all(np.isfinite(sd))
        if has_sd:  # the paper's error bar: the spread of single estimates
            ax.errorbar(
                n,
                m,
                yerr=sd,
                fmt="none",
                capsize=3,
                color="C0",
                alpha=0.5,
                lw=1,
                label=f"sd of {rows_b[0]['n_repeats']} repeats",
            )
        ax.errorbar(
            n,
            m,
            yerr=se,
            fmt="s",
            ms=5,
            capsize=2,
            color="C0",
            lw=2,
            label="mean ± standard error of the mean" if has_sd else "estimate ± standard error",
        )
        if np.all(m - se > 0):  # Lambda spans decades (0.06 at N = 4, 1e-4 near N = 20)
            ax.set_yscale("log")
        else:
            ax.axhline(0.0, color="k", lw=0.6)
        ax.legend(fontsize=8)
    ax.set_xlabel("N")
    ax.xaxis.set_major_locator(plt.MaxNLocator(integer=True))
    ax.set_ylabel(r"$\Lambda^{(\mathrm{KM})}$")
    ax.set_title("antifragility of the clique edge away from the bridge, L = 1", fontsize=9)
    return fig_a, fig_b, rows_b


def fig2b_verdict(summary: dict, rows_b: list[dict]) -> list[str]:
    """Markdown lines: the estimator used and what the rows resolve of Fig. 2b's claim."""
    if not rows_b:
        return []
    methods = sorted({r.get("lambda_method") or "finite-difference" for r in summary["records"]})
    tr = trend_in_n(rows_b)

    def ns(items) -> str:
        return ", ".join(str(x) if isinstance(x, int) else f"{x[0]}->{x[1]}" for x in items) or "none"

    lines = [
        f"Estimator: lambda.method {', '.join(methods)} (dbeta {summary['meta'].get('dbeta', 0.01):g}).",
        f"Positive by more than {tr['z']:g} standard errors at N = {ns(tr['positive'])}; "
        f"not resolved at N = {ns(tr['not_positive'])}.",
        f"Resolved decreases (> {tr['z']:g} combined standard errors): {ns(tr['decreases'])}; "
        f"resolved increases: {ns(tr['increases'])}; unresolved steps: {ns(tr['unresolved'])}.",
        "Every pair of sizes at least "
        f"{tr['gap']} apart decreases by more than {tr['z']:g} combined standard errors."
        if tr["gap"]
        else "Not every pair of sizes, however far apart, resolves a decrease.",
    ]
    if "orbit" in methods:
        lines.append(
            "The orbit estimator is the derivative d<F>/dbeta at 0 (central difference "
            "along the damage of all links of the orbit); the paper's forward difference "
            "of one link at dbeta = 0.01 differs from it by an O(dbeta) term."
        )
    return lines


def plot_fig6(summary: dict):
    """Fig. 6: (a) Lambda^KM(r*) against Lambda^KM(0.99); (b) against Lambda^(xi2), with fits.

    Returns ``(fig_a, fig_b or None, fits, note)``; ``note`` says why (b) is missing.
    """
    plt = _plt()
    ref = summary["ranking_threshold"]
    ts = summary["thresholds"]
    lam = {t: edge_lambdas(summary["records"], t) for t in ts}
    markers = ["o", "s", "^", "D", "v", "P"]
    fig_a, ax = plt.subplots(figsize=(5.6, 5.0))
    keys = sorted(lam[ref])
    x = np.array([lam[ref][k]["lambda_km"] for k in keys])
    for i, t in enumerate(ts):
        y = np.array([lam[t].get(k, {}).get("lambda_km", np.nan) for k in keys])
        ax.scatter(x, y, s=10, marker=markers[i % len(markers)], alpha=0.7, label=f"r* = {t:g}")
    lim = np.nanmax(np.abs(np.concatenate([x] + [[v["lambda_km"] for v in lam[t].values()] for t in ts])))
    ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.7)
    ax.set_xlabel(r"$\Lambda^{(\mathrm{KM})}$, r = " + f"{ref:g}")
    ax.set_ylabel(r"$\Lambda^{(\mathrm{KM})}$, r = r*")
    ax.set_title(f"(a) each link's Lambda at threshold r* against r = {ref:g}; dashed: y = x", fontsize=9)
    ax.legend(fontsize=8)
    try:
        xi2 = _stored_measure(summary, "lambda_xi2") or lambda_xi2_records(summary)
    except ImportError as exc:
        return (
            fig_a,
            None,
            [],
            (f"Fig. 6b skipped: Lambda^(xi2) needs antisync.measures.spectral.lambda_xi2 ({exc})"),
        )
    # the slopes gamma beside the scatter, not over it
    fig_b, (ax, ax_g) = plt.subplots(
        1, 2, figsize=(8.4, 4.6), gridspec_kw={"width_ratios": [2.2, 1]}, layout="constrained"
    )
    fits = []
    for i, t in enumerate(ts):
        ks = [k for k in lam[t] if k in xi2]
        xs = np.array([xi2[k] for k in ks])
        ys = np.array([lam[t][k]["lambda_km"] for k in ks])
        ax.scatter(xs, ys, s=10, marker=markers[i % len(markers)], alpha=0.7, label=f"r* = {t:g}")
        if len(ks) > 2:
            fit = fit_gamma(xs, ys)
            fits.append({"threshold": t, **fit})
            grid = np.linspace(xs.min(), xs.max(), 2)
            ax.plot(grid, fit["gamma"] * grid + fit["C"], lw=0.8, color=f"C{i}")
    ax.set_xlabel(r"$\Lambda^{(\xi_2)}$")
    ax.set_ylabel(r"$\Lambda^{(\mathrm{KM})}$, r = r*")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(
        r"(b) fits $\Lambda^{(\mathrm{KM})} = \gamma\,\Lambda^{(\xi_2)} + C$ per threshold", fontsize=9
    )
    ax_g.set_visible(bool(fits))
    if fits:
        inset = ax_g
        inset.errorbar(
            [f["threshold"] for f in fits],
            [f["gamma"] for f in fits],
            yerr=[f["gamma_se"] for f in fits],
            fmt="o-",
            ms=3,
            capsize=2,
        )
        # -log10(1 - r): 0.9, 0.99, 0.999 equally spaced
        inset.set_xscale(
            "function", functions=(lambda r: -np.log10(np.clip(1 - r, 1e-12, None)), lambda u: 1 - 10 ** (-u))
        )
        inset.set_xticks(ts)
        inset.set_xticklabels([f"{t:g}" for t in ts], fontsize=8)
        inset.tick_params(labelsize=8)
        inset.set_xlabel("threshold r*", fontsize=9)
        inset.set_ylabel(r"slope $\gamma^{(\xi_2-\mathrm{KM})}$ ± standard error", fontsize=9)
    return fig_a, fig_b, fits, ""


def _stored_measure(summary: dict, key: str) -> dict[tuple, float]:
    """``{(graph, edge): value}`` of a measure stored with the records (``measures:`` in the
    config), at the ranking threshold; empty when it was not computed."""
    t = summary["ranking_threshold"]
    out = {}
    for r in summary["records"]:
        if r.get(key) is not None and math.isclose(r["threshold"], t):
            out.setdefault((r["graph"], r["edge"]), r[key])
    return out


def plot_fig5(summary: dict):
    """Fig. 5: Lambda^KM against Lambda^(linear), Lambda^(xi2), Lambda^(RW), and xi2 against RW.

    Uses the measures stored with the records (``measures: [km, xi2, rw, linear]``); returns
    ``(fig, missing)`` with ``fig = None`` when none was computed.
    """
    plt = _plt()
    t = summary["ranking_threshold"]
    lam = edge_lambdas(summary["records"], t)
    km = {k: v["lambda_km"] for k, v in lam.items()}
    km_se = {k: v["lambda_km_se"] for k, v in lam.items()}
    m = {name: _stored_measure(summary, f"lambda_{name}") for name in ("linear", "xi2", "rw")}
    missing = [name for name, v in m.items() if not v]
    if len(missing) == 3:
        return None, missing
    label = {
        "km": r"$\Lambda^{(\mathrm{KM})}$",
        "linear": r"$\Lambda^{(\mathrm{linear})}$",
        "xi2": r"$\Lambda^{(\xi_2)}$",
        "rw": r"$\Lambda^{(\mathrm{RW})}$",
    }
    data = {"km": km, **m}
    # the paper's panels, Lambda^KM on the y axis; a measure not computed gets no panel (the
    # index says which were not)
    panels = [("a", "linear", "km"), ("b", "xi2", "km"), ("c", "rw", "km"), ("d", "xi2", "rw")]
    panels = [p for p in panels if any(k in data[p[2]] for k in data[p[1]])]
    if not panels:
        return None, missing
    ncols = len(panels) if len(panels) <= 3 else 2
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(4.8 * ncols, 4.6 * nrows), squeeze=False, layout="constrained"
    )
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    for ax, (tag, xk, yk) in zip(axes.flat, panels, strict=False):
        keys = [k for k in data[xk] if k in data[yk]]
        ax.set_xlabel(label[xk])
        ax.set_ylabel(label[yk])
        ax.set_title(f"({tag}) {label[yk]} against {label[xk]}", loc="left", fontsize=10)
        x = np.array([data[xk][k] for k in keys])
        y = np.array([data[yk][k] for k in keys])
        if yk == "km":
            # Lambda^KM's 95% interval (estimate -/+ 1.96 standard errors of the mean), and the
            # points whose interval excludes 0 dark, the others grey; the axis is fitted to the
            # points, so a wide interval runs off the frame
            se = np.array([km_se.get(k, np.nan) for k in keys])
            lo, hi = y - Z95 * se, y + Z95 * se
            draw_intervals(ax, x, lo, hi, color="#9ecae1", lw=0.6, alpha=0.5, zorder=1)
            resolved = (lo > 0) | (hi < 0)
            ax.scatter(
                x[~resolved], y[~resolved], s=8, color="#aaaaaa", zorder=2, label="interval contains 0"
            )
            ax.scatter(x[resolved], y[resolved], s=8, color="C0", zorder=3, label="interval excludes 0")
            top = 1.1 * float(np.max(np.abs(y))) if y.size else 1.0
            ax.set_ylim(-top, top)
            ax.legend(fontsize=7, loc="upper left" if tag != "b" else "upper right", framealpha=0.85)
        else:
            ax.scatter(x, y, s=8, alpha=0.6, zorder=2)
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
        if tag == "b":  # the paper: signs agree for |Lambda^KM| >= 0.1
            bad = int(np.sum((np.abs(y) >= 0.1) & (x * y < 0)))
            ax.text(
                0.02,
                0.98,
                f"sign disagreements with |Lambda_KM| >= 0.1: {bad}",
                transform=ax.transAxes,
                va="top",
                fontsize=7,
            )
        if len(keys) > 2:
            ax.text(
                0.98,
                0.02,
                f"Pearson r = {np.corrcoef(x, y)[0, 1]:.3f}, {len(keys)} edges",
                transform=ax.transAxes,
                ha="right",
                fontsize=7,
            )
    fig.suptitle(
        f"response measures of every directed edge (r = {t:g}); bars: 95% interval of "
        r"$\Lambda^{(\mathrm{KM})}$ (cut at the frame)",
        fontsize=10,
    )
    return fig, missing


# ---- the report ----------------------------------------------------------------------------
def write_sweep_report(path: str | Path, folder: str | Path, *, pdf: bool = False) -> list[Path]:
    """Write every figure and table that ``path`` supports into ``folder``; return the paths."""
    plt = _plt()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    views = read_views(path)
    summary = sweep_summary(path, views)
    written: list[Path] = []
    notes: list[str] = []

    def save(fig, stem: str) -> None:
        if fig is None:
            return
        for ext in ("png", "pdf") if pdf else ("png",):
            p = folder / f"{stem}.{ext}"
            fig.savefig(p, dpi=130, bbox_inches="tight")
            written.append(p)
        plt.close(fig)

    def text(name: str, body: str) -> None:
        p = folder / name
        p.write_text(body + "\n")
        written.append(p)

    family = summary["family"]["family"]
    kept = sorted({r["graph"] for r in summary["records"]})
    grid = summary.get("grid")
    if grid:  # one Lambda per grid point: the family's figures would mix the points
        write_grid_report(summary, save, text, notes)
    elif family == "lollipop":
        fig_a, fig_b, rows_b = plot_fig2(summary)
        save(fig_a, "fig2a_F_beta")
        save(fig_b, "fig2b_lambda_N")
        lines = [
            "| N | Lambda_KM (mean) | sd over repeats | standard error | repeats |",
            "|---:|---:|---:|---:|---:|",
        ]
        for r in rows_b:
            m, se = fmt_pm(r["lambda_km"], r["lambda_km_se"])
            sd = "-" if math.isnan(r["sd"]) else f"{r['sd']:.2g}"
            lines.append(f"| {r['N']} | {m} | {sd} | {se} | {r['n_repeats']} |")
        lines += ["", *fig2b_verdict(summary, rows_b)]
        text("fig2b_lambda_N.md", "\n".join(lines))
    elif len(kept) > 1:
        save(plot_ranking(summary), "fig3_ranking")
        rows = table1_rows(summary)
        for fmt, ext in (("markdown", "md"), ("csv", "csv"), ("latex", "tex")):
            text(f"table1.{ext}", format_table1(rows, fmt))
        fig5, missing = plot_fig5(summary)
        if fig5 is None:
            notes.append("Fig. 5 skipped: no measures stored (add measures: [km, xi2, rw, linear])")
        elif missing:
            notes.append(f"Fig. 5: {', '.join(missing)} not computed (add them to measures:)")
        save(fig5, "fig5_measures")
        fig = plot_top_histograms(summary, views)
        if fig is None:
            notes.append("Fig. 4 skipped: no (tau0, tau(beta)) histograms (set top.graphs > 0)")
        save(fig, "fig4_histograms")
    if len(summary["thresholds"]) > 1 and not grid:
        fig_a, fig_b, fits, note = plot_fig6(summary)
        save(fig_a, "fig6a_thresholds")
        save(fig_b, "fig6b_xi2")
        if note:
            notes.append(note)
        if fits:
            lines = ["| r* | gamma | C | edges | Pearson r |", "|---:|---:|---:|---:|---:|"]
            for f in fits:
                g, ge = fmt_pm(f["gamma"], f["gamma_se"])
                c, ce = fmt_pm(f["C"], f["C_se"])
                lines.append(
                    f"| {f['threshold']:g} | {g} ± {ge} | {c} ± {ce} | {f['n']} | {f['pearson_r']:.3f} |"
                )
            text("fig6b_fits.md", "\n".join(lines))
    text("index.md", _index(summary, written, notes))
    return written


def _grid_lines(summary: dict) -> list[str]:
    """The index's line per grid axis (none without a grid)."""
    out = []
    for axis in summary.get("grid") or []:
        keys = " + ".join(axis["keys"])
        vals = ", ".join(
            "/".join(f"{v:g}" if isinstance(v, float | int) else str(v) for v in t) for t in axis["values"]
        )
        out.append(f"- grid{' (zip)' if axis['zip'] else ''}: {keys} = {vals}")
    return out


def _index(summary: dict, written: list[Path], notes: list[str]) -> str:
    s = summary["symmetry"]
    screens = [x for x in summary["screen"] if x]
    kept = [x for x in screens if not x["excluded"]]
    lines = [f"# Sweep {summary['sweep']}", ""]
    if not summary["complete"]:
        lines += ["**Incomplete**: rerun `antisync sweep ... --resume`.", ""]
    lines += [
        f"- graphs: {len(summary['meta']['graphs'])} ({summary['family']['family']}), "
        f"excluded by screening: {len(summary['excluded'])}",
        f"- thresholds: {', '.join(f'{t:g}' for t in summary['thresholds'])}",
        *_grid_lines(summary),
        f"- symmetry: {s['directed_edges']} directed edges in {s['representatives']} orbits; "
        f"{s['integrations_saved']:,} of {s['integrations_without_symmetry']:,} integrations "
        f"saved ({s['fraction_saved']:.0%})",
    ]
    if kept:
        worst = max(kept, key=lambda x: x["fraction_not_synced"])
        slow = max(kept, key=lambda x: x["tau_max"] or 0)
        lines.append(
            f"- kept graphs: largest unsynchronized fraction {worst['fraction_not_synced']:.3f} "
            f"({worst['graph']}); slowest screening tau {slow['tau_max']:.1f} ({slow['graph']})"
        )
    if summary["excluded"]:
        lines += [
            "",
            "## Excluded graphs",
            "",
            "| graph | fraction not synchronized | reason |",
            "|:---|---:|:---|",
        ]
        for ex in summary["excluded"]:
            lines.append(f"| {ex['graph']} | {ex['fraction_not_synced']:.3f} | {ex['reason']} |")
    lines += ["", "## Files", ""] + [f"- [{p.name}]({p.name})" for p in written]
    if notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in notes]
    return "\n".join(lines)
