"""Figures that compare response measures, from a result file (never from a live run).

- ``fig5_measures``: the paper's Fig. 5, scatter plots of ``(Lambda_x, Lambda_y)`` over every
  damaged edge of every (normalized) job in the file: (a) KM against linear, (b) KM against
  xi2, (c) KM against RW, (d) RW against xi2, Lambda^KM on the y axis as in the paper's
  (Lambda^RW, Lambda^KM) of panel (c) and its fits Lambda^KM = gamma Lambda^(xi2) + C. Only
  the panels whose two measures were computed are drawn (``index.md`` says which were not);
  not written when every job with measures is a large graph, whose ``<stem>_measure_pairs``
  already shows the same panels. Each panel has the quadrants where the two signs agree
  shaded, the line ``y = x`` where both are on one scale (KM, linear), 95% intervals where
  the measure is statistical, drawn from their ends (KM: the record's ``lambda_km_ci_low`` ..
  ``_high``, which need not contain the estimate; linear, KM-NNC: the estimate -/+ 1.96
  standard errors), points coloured by Lambda^KM's resolved sign, Spearman's rank
  correlation and the share of links whose sign agrees (over the links whose Kuramoto sign is
  resolved, when Lambda^KM is one of the two).
- ``<stem>_fig7e_km_nnc``: the paper's Fig. 7e, ``Lambda^(KM)`` against ``Lambda^(KM-NNC)`` for
  every edge of a job run with ``km_nnc``, the diagonal, points labelled by edge.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterator

import numpy as np

from antisync.report.intervals import draw_intervals, record_intervals
from antisync.report.labels import spread_labels
from antisync.stats.multiplicity import fdr_signs
from antisync.stats.records import absence_reason
from antisync.stats.summary import JobView, view_records

__all__ = [
    "PAIRS",
    "available",
    "compare",
    "edge_records",
    "link_signs",
    "measure_figures",
    "missing_note",
    "not_computed",
    "pair_panels",
    "plot_fig5",
    "plot_fig7e",
    "plot_pair",
    "sign_agreement",
    "spearman",
]

#: Fig. 5 panels (a)-(d): (x, y) record keys, Lambda^KM on the y axis.
PAIRS = (
    ("lambda_linear", "lambda_km"),
    ("lambda_xi2", "lambda_km"),
    ("lambda_rw", "lambda_km"),
    ("lambda_xi2", "lambda_rw"),
)
#: pairs on one scale, where the line y = x means "the same value"
SAME_SCALE = {"lambda_km", "lambda_linear", "lambda_km_nnc"}
COLORS = {1: "#b2182b", -1: "#2166ac", 0: "#9a9a9a"}
NAMES = {1: "antifragile", -1: "fragile", 0: "unresolved"}
LABELS = {
    "lambda_km": r"$\Lambda^{(\mathrm{KM})}$",
    "lambda_linear": r"$\Lambda^{(\mathrm{linear})}$",
    "lambda_xi2": r"$\Lambda^{(\xi_2)}$",
    "lambda_rw": r"$\Lambda^{(\mathrm{RW})}$",
    "lambda_km_nnc": r"$\Lambda^{(\mathrm{KM-NNC})}$",
}
_MEASURE = {"lambda_linear": "linear", "lambda_xi2": "xi2", "lambda_rw": "rw"}
#: |Lambda| at or below this counts as neutral (0) when classifying signs: exact zeros such
#: as 1->2 on the lollipop come out as 0 or 1e-17, never as a small statistical value.
SIGN_ATOL = 1e-12


def _plt():
    # lazy: pyplot only after matplotlib.use("Agg"), so that no display is needed
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def edge_records(views: list[JobView]) -> list[dict]:
    """One record per (graph, edge) of the normalized jobs (Lambda does not depend on beta)."""
    twins = {v.graph for v in views if v.attrs and v.attrs.get("nnc_of")}
    seen, out = set(), []
    for r in view_records(views):
        key = (r["graph"], r["edge"])
        if r["graph"] not in twins and key not in seen:
            seen.add(key)
            out.append(r)
    return out


def _sign(x: np.ndarray) -> np.ndarray:
    return np.where(np.abs(x) <= SIGN_ATOL, 0, np.sign(x))


def sign_agreement(x, y) -> tuple[int, int]:
    """``(agreeing, total)``: edges whose antifragile/neutral/fragile class is the same."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return int(np.sum(_sign(x) == _sign(y))), int(x.size)


def _column(recs: list[dict], key: str) -> np.ndarray:
    return np.array([np.nan if r.get(key) is None else r[key] for r in recs], dtype=float)


def _symmetric_limits(values: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple[float, float]:
    """``(-top, top)`` around every value and every finite interval end."""
    reach = np.concatenate([np.abs(values), np.abs(low), np.abs(high)])
    top = float(np.nanmax(reach)) if np.isfinite(reach).any() else 1.0
    top = 1.1 * top if top > 0 else 1.0
    return -top, top


def missing_note(recs: list[dict], keys) -> str:
    """What a panel of ``keys`` shows when no record has them all: for each key no record
    has, why (not asked for, or Lambda^KM undefined because nothing synchronized, see
    :func:`antisync.stats.records.absence_reason`), wrapped to fit a panel."""
    notes = []
    for key in keys:
        if np.isfinite(_column(recs, key)).any():
            continue
        if key in _MEASURE:
            notes.append(f"{_MEASURE[key]} not computed: add {_MEASURE[key]} to measures")
        else:
            notes.append(absence_reason(recs, key))
    if not notes:
        notes.append("no link has both values")
    return "\n".join(textwrap.fill(n, 55) for n in dict.fromkeys(notes))


def link_signs(recs: list[dict], key: str) -> np.ndarray:
    """Sign of each record's ``key``: for Lambda^KM the call at false discovery rate 0.05 over
    ``recs``' links (:func:`antisync.stats.multiplicity.fdr_signs`, as ``antisync summary``'s
    ``sign_resolved``), the exact sign for an exact measure (0 within ``SIGN_ATOL``, or missing)."""
    if key == "lambda_km":
        return np.array([s or 0 for s in fdr_signs(recs)], dtype=int)
    x = _column(recs, key)
    return np.where(np.isfinite(x) & (np.abs(x) > SIGN_ATOL), np.sign(np.nan_to_num(x)), 0).astype(int)


def spearman(x, y) -> float:
    """Spearman rank correlation of the pairs where both are finite (NaN for fewer than 3
    pairs or a constant side)."""
    # lazy: scipy.stats takes ~0.5 s to import; only a comparison of two measures needs it
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
        Lambda^KM as ``kx`` or ``ky``, the links whose KM sign is resolved (:func:`link_signs`)
        and how many of them the other measure gives the same sign; otherwise every link, and
        how many have the same antifragile / neutral / fragile class (:func:`sign_agreement`);
        ``links``, how many records have both.
    """
    x, y = _column(recs, kx), _column(recs, ky)
    ok = np.isfinite(x) & np.isfinite(y)
    used = [r for r, good in zip(recs, ok, strict=True) if good]
    km, other = (kx, ky) if kx == "lambda_km" else (ky, kx)
    if km == "lambda_km":
        signs, exact = link_signs(used, km), _sign(_column(used, other))
        resolved = signs != 0
        agree, total = int(np.sum(signs[resolved] == exact[resolved])), int(resolved.sum())
    else:
        agree, total = sign_agreement(x[ok], y[ok])
    return {"spearman": spearman(x[ok], y[ok]), "agree": agree, "total": total, "links": int(ok.sum())}


def plot_pair(recs: list[dict], kx: str, ky: str, ax, *, label_points: bool = False, title: str = "") -> None:
    """One Fig. 5 panel: ``(rec[kx], rec[ky])`` over the records that have both.

    With Lambda^KM on an axis the points are coloured by its resolved sign (:func:`link_signs`)
    and the sign agreement counts only those resolved links; the title (after ``title``) gives
    Spearman's rho and the agreement.
    """
    x, y = _column(recs, kx), _column(recs, ky)
    ok = np.isfinite(x) & np.isfinite(y)
    ax.set_xlabel(LABELS[kx])
    ax.set_ylabel(LABELS[ky])
    head = title or f"{LABELS[ky]} against {LABELS[kx]}"
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
        ax.set_title(head, fontsize=10)
        return
    used = [r for r, good in zip(recs, ok, strict=True) if good]
    x, y = x[ok], y[ok]
    # 95% intervals as stored (NaN for an exact measure): Lambda^KM's need not contain the estimate
    xlo, xhi = record_intervals(used, kx)
    ylo, yhi = record_intervals(used, ky)
    xlim, ylim = _symmetric_limits(x, xlo, xhi), _symmetric_limits(y, ylo, yhi)
    # the quadrants where both measures give the same sign: both antifragile, both fragile
    ax.fill_between([0, xlim[1]], 0, ylim[1], color="#2ca02c", alpha=0.07, lw=0)
    ax.fill_between([xlim[0], 0], ylim[0], 0, color="#2ca02c", alpha=0.07, lw=0)
    ax.axhline(0, color="k", lw=0.6)
    ax.axvline(0, color="k", lw=0.6)
    if kx in SAME_SCALE and ky in SAME_SCALE:
        lo, hi = max(xlim[0], ylim[0]), min(xlim[1], ylim[1])
        ax.plot([lo, hi], [lo, hi], "k--", lw=0.8, label="$y = x$")
    km = "lambda_km" in (kx, ky)
    signs = link_signs(used, "lambda_km") if km else np.zeros(len(used), dtype=int)
    for s in (1, -1, 0):
        m = signs == s
        if not m.any():
            continue
        color = COLORS[s] if km else "#1f77b4"
        z = 2 if s == 0 else 3  # resolved links over the unresolved cloud
        style = {"color": color, "lw": 0.7, "alpha": 0.5, "zorder": z}
        drawn = draw_intervals(ax, y[m], xlo[m], xhi[m], horizontal=True, **style)
        drawn = draw_intervals(ax, x[m], ylo[m], yhi[m], **style) or drawn
        label = f"KM {NAMES[s]}: {int(m.sum())}" if km else f"{int(m.sum())} links"
        ax.plot(x[m], y[m], "o", ms=3.5, color=color, alpha=0.85, label=label, zorder=z)
    c = compare(recs, kx, ky)
    share = f" ({c['agree'] / c['total']:.0%})" if c["total"] else ""
    counted = "links with resolved KM sign" if km else "links"
    ax.set_title(
        f"{head}\nSpearman $\\rho$ = {c['spearman']:.2f} ({c['links']} links); "
        f"sign agrees on {c['agree']}/{c['total']} {counted}{share}",
        fontsize=9,
    )
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.legend(loc="best", fontsize=7, framealpha=0.85)
    if label_points:
        # each name beside its point, pushed off the other names and points where they crowd
        dx = 0.04 * (xlim[1] - xlim[0])
        texts = [
            ax.text(xi + dx, yi, r["edge"], fontsize=7, ha="center", va="center", zorder=4)
            for r, xi, yi in zip(used, x, y, strict=True)
        ]
        spread_labels(ax, texts, list(zip(x, y, strict=True)), 5.0)


def available(recs: list[dict], pairs=PAIRS) -> list[tuple[str, str]]:
    """The ``pairs`` whose two measures some record has: a measure not computed gets no panel."""
    have = {k for k in LABELS if np.isfinite(_column(recs, k)).any()}
    return [(kx, ky) for kx, ky in pairs if kx in have and ky in have]


def not_computed(recs: list[dict]) -> list[str]:
    """The Fig. 5 measures no record has (``linear``, ``xi2``, ``rw``, or ``km`` when
    Lambda^KM is undefined), for a note in ``index.md``."""
    keys = dict.fromkeys(k for pair in PAIRS for k in pair)
    return [k for k in keys if not np.isfinite(_column(recs, k)).any()]


def pair_panels(plt, count: int, width: float, height: float):
    """``(fig, axes)``: ``count`` panels of ``width`` x ``height`` inches in one row (up to three)
    or two columns, the spare ones hidden; ``axes`` is flat."""
    ncols = count if count <= 3 else 2
    nrows = -(-count // ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False, layout="constrained"
    )
    for ax in axes.ravel()[count:]:
        ax.set_visible(False)
    return fig, axes.ravel()


def plot_fig5(recs: list[dict], axes) -> None:
    """The panels of Fig. 5 on ``axes``, one per :func:`available` pair of :data:`PAIRS`,
    lettered in the paper's order."""
    graphs = sorted({r["graph"] for r in recs})
    few = len(recs) <= 30  # label points only when a single small graph is shown
    letters = dict(zip(PAIRS, "abcd", strict=True))
    for ax, (kx, ky) in zip(axes, available(recs), strict=False):
        title = f"({letters[(kx, ky)]}) {LABELS[ky]} against {LABELS[kx]}"
        plot_pair(recs, kx, ky, ax, label_points=few and len(graphs) == 1, title=title)


def plot_fig7e(recs: list[dict], ax) -> None:
    """Fig. 7e: ``Lambda^(KM)`` vs ``Lambda^(KM-NNC)`` of one job, edges labelled."""
    x, y = _column(recs, "lambda_km"), _column(recs, "lambda_km_nnc")
    ok = np.isfinite(x) & np.isfinite(y)
    below = int(np.sum(y[ok] < x[ok]))
    title = (
        f"{recs[0]['graph']}: "
        + r"$\Lambda^{(\mathrm{KM-NNC})} < \Lambda^{(\mathrm{KM})}$"
        + f" on {below}/{int(ok.sum())} edges"
    )
    plot_pair(recs, "lambda_km", "lambda_km_nnc", ax, label_points=True, title=title)


def measure_figures(
    views: list[JobView],
    *,
    stems: dict[str, str] | None = None,
    covered: set | frozenset = frozenset(),
    notes: list[str] | None = None,
) -> Iterator[tuple[object, str]]:
    """Yield ``(figure, file stem)`` for Fig. 5 and each job's Fig. 7e, when the data exist.

    ``stems``: each job's file stem (default its name); ``covered``: jobs whose own
    ``measure_pairs`` figure already shows Fig. 5's panels (no ``fig5_measures`` when every
    job with measures is one); ``notes``: a list the measures not computed are added to.
    """
    plt = _plt()
    recs = edge_records(views)
    stems = stems or {}
    if any(r.get(k) is not None for r in recs for k in _MEASURE):
        missing = not_computed(recs)
        if notes is not None:
            asked = [_MEASURE[k] for k in missing if k in _MEASURE]
            if asked:
                notes.append(f"{', '.join(asked)} not computed, so not drawn (add them to measures:)")
            if "lambda_km" in missing:
                notes.append(absence_reason(recs, "lambda_km"))
        with_measures = {r["graph"] for r in recs if any(r.get(k) is not None for k in _MEASURE)}
        pairs = available(recs)
        if pairs and not with_measures <= set(covered):
            fig, axes = pair_panels(plt, len(pairs), 5.6, 5.2)
            plot_fig5(recs, axes)
            fig.suptitle(
                "Response to damage: measures of every directed edge (the paper's Fig. 5)", fontsize=11
            )
            yield fig, "fig5_measures"
    for graph in dict.fromkeys(r["graph"] for r in recs):
        mine = [r for r in recs if r["graph"] == graph]
        if any(r.get("lambda_km_nnc") is not None for r in mine):
            fig, ax = plt.subplots(figsize=(6.5, 6))
            plot_fig7e(mine, ax)
            yield fig, f"{stems.get(graph, graph)}_fig7e_km_nnc"
