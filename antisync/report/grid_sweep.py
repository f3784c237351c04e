"""Lambda against a swept config value: the figure and table of a grid sweep (docs/sweeps.md).

A grid sweep (``sweep: {grid: {...}, zip: {...}}``, :mod:`antisync.sweeps.points`) holds one
Lambda^KM per (link, grid point). :func:`grid_curves` arranges them for drawing: the first axis
of the grid is the x axis, every combination of the other axes (and of the thresholds, when
they are swept by ``thresholds:``) is one panel, and the ``top`` links by largest
``|Lambda^KM|`` over the grid are the curves (one per automorphism orbit: its representative).
:func:`plot_grid` draws them with their 95% intervals (:func:`~antisync.report.intervals.
draw_intervals`); a filled marker is a resolved sign, an open one an unresolved sign, and a
shaded band with a dotted line in its middle marks a resolved sign that flips: it spans the
two nearest grid values whose signs are resolved and opposite (unresolved values between
them are skipped). :func:`grid_table` says the same in markdown. Pure
functions of a sweep summary (:func:`antisync.sweeps.sweep_summary`), no file read here.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from matplotlib.lines import Line2D

from antisync.report.figures import _plt
from antisync.report.intervals import draw_intervals, record_intervals
from antisync.stats.estimators import Z95
from antisync.stats.records import flag_signs
from antisync.sweeps.points import point_label

__all__ = ["TOP_LINKS", "grid_curves", "grid_table", "plot_grid", "write_grid_report"]

#: how many links a grid figure draws by default (largest |Lambda^KM| over the grid)
TOP_LINKS = 8


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _link_values(records: list[dict]) -> dict[tuple, dict]:
    """``{(graph, edge, point, threshold): {lambda, low, high, sign, orbit_size}}`` of the
    orbit representatives, repeats combined.

    One repeat: the record's own interval and its ``sign_resolved`` (false discovery rate over
    the file's links, :func:`antisync.stats.records.flag_signs`). Several: their mean, the normal
    interval of the combined standard error, and the sign that interval resolves.
    """
    per: dict[tuple, dict[int, dict]] = {}
    for r in flag_signs(records):
        if r["edge"] != r.get("representative", r["edge"]) or r.get("lambda_km") is None:
            continue
        key = (r["graph"], r["edge"], r.get("point"), r["threshold"])
        per.setdefault(key, {}).setdefault(r.get("repeat", 0), r)
    out = {}
    for key, reps in per.items():
        recs = list(reps.values())
        if len(recs) == 1:
            (r,) = recs
            (low,), (high,) = record_intervals([r], "lambda_km")
            value, sign = r["lambda_km"], r.get("sign_resolved") or 0
        else:
            value = float(np.mean([r["lambda_km"] for r in recs]))
            se = math.sqrt(sum((r.get("lambda_km_se") or 0.0) ** 2 for r in recs)) / len(recs)
            low, high = value - Z95 * se, value + Z95 * se
            sign = 1 if low > 0 else -1 if high < 0 else 0
        out[key] = {
            "lambda": value,
            "low": low,
            "high": high,
            "sign": sign,
            "orbit_size": recs[0].get("orbit_size", 1),
        }
    return out


def grid_curves(summary: dict, top: int = TOP_LINKS) -> dict | None:
    """What :func:`plot_grid` draws, as data; ``None`` for a sweep without a grid.

    Returns
    -------
    dict
        ``x_keys`` (the keys of the x axis: one, or the zipped keys), ``x_values`` (their
        values at each position), ``x`` (positions: the first key's values when they are
        numbers, else 0, 1, ...), ``x_labels``; ``panels``: ``[{label, curves}]`` with
        ``curves`` ``[{graph, edge, orbit_size, x, lambda, low, high, sign, flips}]`` (NaN where
        a point has no value; ``flips``: ``(x_a, x_b)`` of the nearest resolved values of
        opposite sign, see :func:`_flip_pairs`); ``links``
        (drawn, largest ``|Lambda^KM|`` first) and ``n_links`` (all of them).
    """
    axes = summary.get("grid")
    if not axes:
        return None
    values = _link_values(summary["records"])
    thresholds = sorted({k[3] for k in values})
    sets_threshold = any(k in ("dynamics.threshold", "sync.threshold") for a in axes for k in a["keys"])
    # the panel axes: every grid axis but the first, then the thresholds given by thresholds:
    x_axis, others = axes[0], axes[1:]
    panel_axes = [(a["keys"], [tuple(v) for v in a["values"]]) for a in others]
    if len(thresholds) > 1 and not sets_threshold:
        panel_axes.append((["threshold"], [(t,) for t in thresholds]))
    x_values = [tuple(v) for v in x_axis["values"]]
    first = [v[0] for v in x_values]
    numeric = all(_is_number(v) for v in first)
    x = np.array(first, dtype=float) if numeric else np.arange(len(first), dtype=float)
    links: dict[tuple, float] = {}
    for (graph, edge, _, _), v in values.items():
        if np.isfinite(v["lambda"]):
            links[(graph, edge)] = max(links.get((graph, edge), 0.0), abs(v["lambda"]))
    ranked = sorted(links, key=lambda k: (-links[k], k))
    drawn = ranked[:top]
    panels = []
    for combo in itertools.product(*(range(len(vals)) for _, vals in panel_axes)):
        fixed = {}
        for (keys, vals), i in zip(panel_axes, combo, strict=True):
            fixed.update(zip(keys, vals[i], strict=True))
        curves = []
        for graph, edge in drawn:
            rows = []
            for xv in x_values:
                point = {**dict(zip(x_axis["keys"], xv, strict=True)), **fixed}
                t = point.pop("threshold", None)
                label = point_label([(k, point[k]) for a in axes for k in a["keys"]])
                hits = [
                    v
                    for (g, e, p, th), v in values.items()
                    if g == graph and e == edge and p == label and (t is None or math.isclose(th, t))
                ]
                rows.append(hits[0] if hits else None)
            curve = {
                "graph": graph,
                "edge": edge,
                "orbit_size": next((r["orbit_size"] for r in rows if r), 1),
                "x": x,
                "lambda": np.array([r["lambda"] if r else np.nan for r in rows]),
                "low": np.array([r["low"] if r else np.nan for r in rows]),
                "high": np.array([r["high"] if r else np.nan for r in rows]),
                "sign": np.array([r["sign"] if r else 0 for r in rows], dtype=int),
            }
            curve["flips"] = [(x[i], x[j]) for i, j in _flip_pairs(curve["sign"])]
            curves.append(curve)
        panels.append({"label": point_label(fixed) if fixed else "", "fixed": fixed, "curves": curves})
    return {
        "x_keys": list(x_axis["keys"]),
        "x_values": x_values,
        "x": x,
        "x_labels": [", ".join(_short(v) for v in xv) for xv in x_values],
        "numeric": numeric,
        "panels": panels,
        "links": drawn,
        "n_links": len(ranked),
        "graphs": sorted({g for g, _ in links}),
    }


def _flip_pairs(sign) -> list[tuple[int, int]]:
    """``(i, j)``: neighbouring resolved signs (unresolved ones between them skipped) that are
    opposite; the sign flips somewhere between grid values ``i`` and ``j``."""
    resolved = [i for i, s in enumerate(sign) if s != 0]
    return [(i, j) for i, j in itertools.pairwise(resolved) if sign[i] != sign[j]]


def _short(v) -> str:
    return f"{v:g}" if _is_number(v) else str(v)


def _link_name(curve: dict, several_graphs: bool) -> str:
    name = f"{curve['graph']} {curve['edge']}" if several_graphs else curve["edge"]
    return name + (f" (orbit of {curve['orbit_size']})" if curve["orbit_size"] > 1 else "")


def plot_grid(curves: dict):
    """Lambda^KM of the drawn links against the first grid key, one panel per combination of
    the others (:func:`grid_curves`); returns the figure."""
    plt = _plt()
    panels = curves["panels"]
    ncols = min(len(panels), 3)
    nrows = math.ceil(len(panels) / ncols)
    fig, axs = plt.subplots(
        nrows, ncols, figsize=(4.6 * ncols + 2.4, 3.6 * nrows), sharey=True, squeeze=False
    )
    x = curves["x"]
    span = float(x.max() - x.min()) if x.size > 1 else 1.0
    k = len(curves["links"])
    colors = plt.get_cmap("tab10" if k <= 10 else "tab20")(np.arange(max(k, 1)) % (10 if k <= 10 else 20))
    several = len(curves["graphs"]) > 1
    for ax, panel in zip(axs.flat, panels, strict=False):
        ax.axhline(0.0, color="0.6", lw=0.8)
        for i, curve in enumerate(panel["curves"]):
            c = colors[i]
            # neighbouring links side by side, not on top of each other
            xs = x + (i - (k - 1) / 2) * 0.008 * span
            ax.plot(xs, curve["lambda"], "-", color=c, lw=1.0, alpha=0.8)
            draw_intervals(ax, xs, curve["low"], curve["high"], colors=[c], lw=1.2, alpha=0.7)
            resolved = curve["sign"] != 0
            ax.plot(xs[resolved], curve["lambda"][resolved], "o", color=c, ms=5)
            ax.plot(xs[~resolved], curve["lambda"][~resolved], "o", mfc="white", mec=c, ms=5, mew=1.2)
            for xa, xb in curve["flips"]:  # the sign changes somewhere in there
                ax.axvspan(xa, xb, color=c, alpha=0.12, lw=0)
                ax.axvline((xa + xb) / 2, color=c, ls=":", lw=1.3)
        ax.set_title(panel["label"], fontsize=9)
        ax.set_xlabel(" / ".join(curves["x_keys"]))
        if not curves["numeric"] or len(curves["x_keys"]) > 1:
            ax.set_xticks(x)
            ax.set_xticklabels(
                curves["x_labels"], fontsize=8, rotation=30 if len(curves["x_keys"]) > 1 else 0
            )
        ax.grid(alpha=0.25)
    for ax in axs.flat[len(panels) :]:
        ax.set_visible(False)
    for ax in axs[:, 0]:
        ax.set_ylabel("Lambda^KM")
    handles = [
        Line2D([], [], color=colors[i], marker="o", lw=1.0, label=_link_name(c, several))
        for i, c in enumerate(panels[0]["curves"])
    ]
    handles += [
        Line2D([], [], color="0.3", marker="o", ls="", label="sign resolved"),
        Line2D([], [], color="0.3", marker="o", mfc="white", ls="", label="sign unresolved"),
        Line2D([], [], color="0.3", ls=":", label="resolved sign flips\n(band: between which values)"),
    ]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, frameon=False)
    shown = f"{k} of {curves['n_links']} links" if k < curves["n_links"] else f"all {k} links"
    fig.suptitle(
        f"Lambda^KM against {' / '.join(curves['x_keys'])} ({shown}, largest |Lambda| first; "
        "bars: 95% intervals)",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def grid_table(curves: dict) -> str:
    """The drawn values as markdown: one table per panel (links by x value), then the flips."""
    lines = []
    several = len(curves["graphs"]) > 1
    mark = {1: " (+)", -1: " (-)", 0: " (?)"}
    for panel in curves["panels"]:
        if panel["label"]:
            lines += [f"## {panel['label']}", ""]
        head = " | ".join(f"{'/'.join(curves['x_keys'])}={x}" for x in curves["x_labels"])
        lines += [f"| link | {head} |", "|:---|" + "---:|" * len(curves["x_labels"])]
        for curve in panel["curves"]:
            cells = []
            for lam, lo, hi, s in zip(
                curve["lambda"], curve["low"], curve["high"], curve["sign"], strict=True
            ):
                if not np.isfinite(lam):
                    cells.append("-")
                    continue
                interval = f" [{lo:+.3g}, {hi:+.3g}]" if np.isfinite(lo) and np.isfinite(hi) else ""
                cells.append(f"{lam:+.3g}{interval}{mark[int(s)]}")
            lines.append(f"| {_link_name(curve, several)} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "(+)/(-): resolved sign (false discovery rate 0.05 over the file's links); (?): unresolved.",
        "",
    ]
    flips = flip_lines(curves)
    lines += ["## Resolved sign flips", ""] + ([f"- {f}" for f in flips] if flips else ["- none"])
    return "\n".join(lines)


def flip_lines(curves: dict) -> list[str]:
    """One sentence per resolved sign flip between neighbouring grid values."""
    out = []
    several = len(curves["graphs"]) > 1
    key = "/".join(curves["x_keys"])
    for panel in curves["panels"]:
        where = f" ({panel['label']})" if panel["label"] else ""
        for curve in panel["curves"]:
            for i, j in _flip_pairs(curve["sign"]):
                a, b = curves["x_labels"][i], curves["x_labels"][j]
                word = "fragile to antifragile" if curve["sign"][i] < 0 else "antifragile to fragile"
                out.append(f"{_link_name(curve, several)}: {word} between {key} = {a} and {b}{where}")
    return out


def write_grid_report(summary: dict, save, text, notes: list[str], top: int = TOP_LINKS) -> None:
    """The grid sweep's outputs through the report's ``save(fig, stem)`` and ``text(name,
    body)``: ``grid_lambda.png`` and ``grid_lambda.md``; a note says how many flips."""
    curves = grid_curves(summary, top)
    if curves is None or not curves["links"]:
        notes.append("grid figure skipped: no Lambda^KM estimated at any grid point")
        return
    save(plot_grid(curves), "grid_lambda")
    text("grid_lambda.md", grid_table(curves))
    flips = flip_lines(curves)
    notes.append(
        f"grid: Lambda^KM of {len(curves['links'])} of {curves['n_links']} links against "
        f"{'/'.join(curves['x_keys'])}; {len(flips)} resolved sign flip(s)"
        + (f", e.g. {flips[0]}" if flips else "")
    )
