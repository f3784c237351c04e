"""Figures that compare response measures, from a result file (never from a live run).

- ``fig5_measures``: the paper's Fig. 5, scatter plots of ``(Lambda_x, Lambda_y)`` over every
  damaged edge of every (normalized) job in the file: (a) KM vs linear, (b) KM vs xi2,
  (c) RW vs KM, (d) xi2 vs RW. Each panel has the line ``y = x``, the quadrants where the two
  signs agree shaded, 95% intervals where the measure is statistical, drawn from their ends
  (KM: the record's ``lambda_km_ci_low`` .. ``_high``, which need not contain the estimate;
  linear, KM-NNC: the estimate -/+ 1.96 standard errors), and the fraction of edges whose
  sign classification (antifragile > 0, neutral = 0, fragile < 0) agrees. Written when any
  of linear, xi2, rw was computed.
- ``<job>_fig7e_km_nnc``: the paper's Fig. 7e, ``Lambda^(KM)`` against ``Lambda^(KM-NNC)`` for
  every edge of a job run with ``km_nnc``, the diagonal, points labelled by edge.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterator

import numpy as np

from antisync.records import absence_reason
from antisync.report.intervals import draw_intervals, record_intervals
from antisync.summary import JobView, view_records

__all__ = [
    "PAIRS",
    "edge_records",
    "measure_figures",
    "missing_note",
    "plot_fig5",
    "plot_fig7e",
    "sign_agreement",
]

#: Fig. 5 panels (a)-(d): (x, y) record keys.
PAIRS = (
    ("lambda_km", "lambda_linear"),
    ("lambda_km", "lambda_xi2"),
    ("lambda_rw", "lambda_km"),
    ("lambda_xi2", "lambda_rw"),
)
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
    :func:`antisync.records.absence_reason`), wrapped to fit a panel."""
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


def plot_pair(recs: list[dict], kx: str, ky: str, ax, *, label_points: bool = False) -> None:
    """One Fig. 5 panel: ``(rec[kx], rec[ky])`` over the records that have both."""
    x, y = _column(recs, kx), _column(recs, ky)
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
    lo, hi = max(xlim[0], ylim[0]), min(xlim[1], ylim[1])
    ax.plot([lo, hi], [lo, hi], "k--", lw=0.8, label="$y = x$")
    style = {"color": "#9ecae1", "lw": 0.8}
    drawn = draw_intervals(ax, y, xlo, xhi, horizontal=True, **style)
    drawn = draw_intervals(ax, x, ylo, yhi, **style) or drawn
    if drawn is not None:
        drawn.set_label("95% interval")
    ax.plot(x, y, "o", ms=3.5, color="#1f77b4")
    if label_points:
        for r, xi, yi in zip(used, x, y, strict=True):
            ax.annotate(r["edge"], (xi, yi), fontsize=7, xytext=(3, 3), textcoords="offset points")
    agree, total = sign_agreement(x, y)
    ax.text(
        0.03,
        0.97,
        f"sign agrees: {agree}/{total} edges ({agree / total:.0%})",
        transform=ax.transAxes,
        ha="left",
        va="top",
        fontsize=8,
        bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
    )
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.legend(loc="lower right", fontsize=7)


def plot_fig5(recs: list[dict], axes) -> None:
    """The four panels of Fig. 5 on ``axes`` (four Axes, in the order of :data:`PAIRS`)."""
    graphs = sorted({r["graph"] for r in recs})
    few = len(recs) <= 30  # label points only when a single small graph is shown
    for ax, (kx, ky), letter in zip(axes, PAIRS, "abcd", strict=True):
        plot_pair(recs, kx, ky, ax, label_points=few and len(graphs) == 1)
        ax.set_title(f"({letter}) {LABELS[kx]} vs {LABELS[ky]}", fontsize=10)


def plot_fig7e(recs: list[dict], ax) -> None:
    """Fig. 7e: ``Lambda^(KM)`` vs ``Lambda^(KM-NNC)`` of one job, edges labelled."""
    plot_pair(recs, "lambda_km", "lambda_km_nnc", ax, label_points=True)
    x, y = _column(recs, "lambda_km"), _column(recs, "lambda_km_nnc")
    ok = np.isfinite(x) & np.isfinite(y)
    below = int(np.sum(y[ok] < x[ok]))
    ax.set_title(
        f"{recs[0]['graph']}: "
        + r"$\Lambda^{(\mathrm{KM-NNC})} < \Lambda^{(\mathrm{KM})}$"
        + f" on {below}/{int(ok.sum())} edges",
        fontsize=10,
    )


def measure_figures(views: list[JobView]) -> Iterator[tuple[object, str]]:
    """Yield ``(figure, file stem)`` for Fig. 5 and each job's Fig. 7e, when the data exist."""
    plt = _plt()
    recs = edge_records(views)
    if any(r.get(k) is not None for r in recs for k in _MEASURE):
        fig, axes = plt.subplots(2, 2, figsize=(10, 9))
        plot_fig5(recs, axes.ravel())
        fig.suptitle("Response to damage: four measures per directed edge (Fig. 5)")
        fig.tight_layout()
        yield fig, "fig5_measures"
    for graph in dict.fromkeys(r["graph"] for r in recs):
        mine = [r for r in recs if r["graph"] == graph]
        if any(r.get("lambda_km_nnc") is not None for r in mine):
            fig, ax = plt.subplots(figsize=(6.5, 6))
            plot_fig7e(mine, ax)
            yield fig, f"{graph}_fig7e_km_nnc"
