"""Summary records as an aligned table, JSON or CSV."""

from __future__ import annotations

import csv
import io
import json
import math

from antisync.stats.multiplicity import link_key
from antisync.stats.summary import warning_kind

__all__ = [
    "ASYMMETRY",
    "asymmetric",
    "fmt_interval",
    "fmt_pm",
    "format_records",
    "format_sweep",
    "format_table1",
    "lambda_warnings",
    "link_rows",
    "sync_warnings",
]

# a link's columns: its Lambda (one row per link, whatever its betas), the undamaged network's
# <tau0> and Lambda's counts (r0>=r and unsynced only where a link has no beta rows: with betas
# they are the counts of each beta's damaged network, in the per-beta table)
_LINK_COLUMNS = [
    ("graph", "graph", "{}"),
    ("edge", "edge", "{}"),
    ("lambda_km", "Lambda_KM", "{:+.4f}"),
    ("lambda_km_se", "se", "{:.4f}"),
    ("sign_resolved", "sign", "{:+d}"),
    ("tau0_mean", "<tau0>", "{:.4f}"),
    ("tau0_se", "se", "{:.4f}"),
    ("lambda_n", "n", "{:,}"),
    ("n_excluded", "r0>=r", "{}"),
    ("n_not_synced", "unsynced", "{}"),
]
# one row per (link, beta): only where some record has a beta
_BETA_COLUMNS = [
    ("graph", "graph", "{}"),
    ("edge", "edge", "{}"),
    ("beta", "beta", "{:.3g}"),
    ("F_mean", "<F>", "{:.4f}"),
    ("F_se", "se", "{:.4f}"),
    ("n", "n", "{:,}"),
    ("n_excluded", "r0>=r", "{}"),
    ("n_not_synced", "unsynced", "{}"),
]
# the Kuramoto run's columns: left out when no record has a realization (a file run without km)
_KM_KEYS = {
    "lambda_km",
    "lambda_km_se",
    "tau0_mean",
    "tau0_se",
    "lambda_n",
    "n_excluded",
    "n_not_synced",
}
# kept when every row is "-": the run's headline number, whose absence the warnings explain
_ALWAYS = {"graph", "edge", "lambda_km"}
# shown only when some record has them (measures: linear, xi2, rw, km_nnc; Lambda^tau, format 4)
_MEASURE_COLUMNS = [
    ("lambda_linear", "Lambda_lin", "{:+.4f}"),
    ("lambda_linear_se", "se", "{:.4f}"),
    ("lambda_xi2", "Lambda_xi2", "{:+.4f}"),
    ("lambda_rw", "Lambda_RW", "{:+.4f}"),
    ("lambda_km_nnc", "Lambda_NNC", "{:+.4f}"),
    ("lambda_km_nnc_se", "se", "{:.4f}"),
    ("lambda_tau", "Lambda_tau", "{:+.4f}"),
    ("lambda_tau_se", "se", "{:.4f}"),
]


# the synchronized fraction's response dP_sync/dbeta with its 95% interval
_SYNC_COLUMNS = [
    ("p_sync_response", "dPsync", "{:+.3f}"),
    ("p_sync_response_ci_low", "ci_low", "{:+.3f}"),
    ("p_sync_response_ci_high", "ci_high", "{:+.3f}"),
]

#: Lambda^KM's interval is shown as ``[low, high]`` instead of ``se`` when, for some link, its
#: two arms (estimate to low end, estimate to high end) differ by more than this share of its
#: half-width: the tail model's interval is not centred on the estimate
ASYMMETRY = 0.1


def format_records(records: list[dict], fmt: str = "table") -> str:
    """Render summary records; ``fmt`` is ``table``, ``json`` or ``csv``.

    JSON and CSV hold every record with every key. The table is for reading: one row per
    link (Lambda^KM with its standard error, or its interval ``[low, high]`` where some link's
    interval is asymmetric, :data:`ASYMMETRY`; the sign; <tau0>; the counts; the exact
    measures), then, where some record has a beta, one row per (link, beta) with <F_beta>.
    A column that is ``-`` on every row is left out (``beta`` and ``<F>`` of a run with
    ``betas: []``). Warnings follow, one line per kind.
    """
    if fmt == "json":
        return json.dumps(records, indent=2)
    if fmt == "csv":
        buf = io.StringIO()
        if records:
            writer = csv.DictWriter(buf, fieldnames=list(records[0]))
            writer.writeheader()
            writer.writerows(records)
        return buf.getvalue().rstrip("\n")
    kuramoto = not records or any(r.get("realizations") for r in records)
    lines = _aligned(_link_columns(records, kuramoto), link_rows(records))
    betas = [r for r in records if r.get("beta") is not None]
    if betas and kuramoto:
        lines += [""] + _aligned(_BETA_COLUMNS, betas)
    lines += lambda_warnings(records)
    lines += [f"warning: {w}" for w in sync_warnings(records)]
    for graph in dict.fromkeys(r["graph"] for r in records if r.get("complete") is False):
        r = next(r for r in records if r["graph"] == graph)
        lines.append(
            f"warning: {graph} is not complete ({r['realizations_done']:,} of "
            f"{r['realizations']:,} realizations done): rerun the same command with --resume"
        )
    return "\n".join(lines)


def link_rows(records: list[dict]) -> list[dict]:
    """One record per link (:func:`antisync.stats.multiplicity.link_key`), the first of its betas,
    in the order of ``records``; ``n_excluded`` and ``n_not_synced`` are left out (None) of a
    link with beta rows, where they count a damaged network, not Lambda's realizations."""
    first: dict[tuple, dict] = {}
    for r in records:
        first.setdefault(link_key(r), r)
    return [
        r if r.get("beta") is None else {**r, "n_excluded": None, "n_not_synced": None}
        for r in first.values()
    ]


def _link_columns(records: list[dict], kuramoto: bool) -> list[tuple]:
    """The link table's columns for ``records``: the Kuramoto ones of a Kuramoto run, the sign
    once flagged, Lambda's interval in place of its ``se`` where asymmetric, then the measures
    and the synchronized fraction's response that some record has."""
    columns = [
        c
        for c in _LINK_COLUMNS
        if (kuramoto or c[0] not in _KM_KEYS) and (c[0] != "sign_resolved" or _has(records, c[0]))
    ]
    if any(asymmetric(r) for r in records):
        level = next((r["lambda_km_ci_level"] for r in records if r.get("lambda_km_ci_level")), 0.95)
        interval = ("lambda_km_ci_low", f"{level:.0%} interval", _interval_cell)
        columns = [interval if c[0] == "lambda_km_se" else c for c in columns]
    columns += [c for c in _MEASURE_COLUMNS if _has(records, c[0])]
    if any(r.get("p_sync_response") is not None and (r.get("p_sync") or 1) < 1 for r in records):
        columns += _SYNC_COLUMNS  # only where some realizations never synchronized
    return columns


def asymmetric(record: dict, tolerance: float = ASYMMETRY) -> bool:
    """Whether ``record``'s Lambda^KM interval is off-centre: its arms from the estimate differ
    by more than ``tolerance`` of its half-width (False without an interval)."""
    lam, low, high = (record.get(k) for k in ("lambda_km", "lambda_km_ci_low", "lambda_km_ci_high"))
    if lam is None or low is None or high is None or not high > low:
        return False
    return abs((high - lam) - (lam - low)) > tolerance * (high - low) / 2


def fmt_interval(low: float | None, high: float | None, digits: int = 2) -> str:
    """``[low, high]`` with signs, each end to ``digits`` significant digits of the half-width,
    or of the end itself where that shows more (an end near 0 keeps its sign and digits:
    ``[+0.00016, +0.035]``); ``-`` without an interval."""
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return "-"

    def decimals(x: float) -> int:
        return digits - 1 - math.floor(math.log10(abs(x))) if x else 0

    width = decimals((high - low) / 2) if high > low else 0
    ends = [f"{x:+.{min(max(width, decimals(x), 0), 8)}f}" for x in (low, high)]
    return f"[{ends[0]}, {ends[1]}]"


def _interval_cell(record: dict) -> str:
    return fmt_interval(record.get("lambda_km_ci_low"), record.get("lambda_km_ci_high"))


def _aligned(columns: list[tuple], records: list[dict]) -> list[str]:
    """``records`` as right-aligned text columns under their headers; a column that is ``-``
    on every row is left out (unless in :data:`_ALWAYS`)."""
    cells = [[_cell(r, key, f) for key, _, f in columns] for r in records]
    keep = [
        i
        for i, (key, _, _) in enumerate(columns)
        if key in _ALWAYS or not cells or any(row[i] != "-" for row in cells)
    ]
    rows = [[columns[i][1] for i in keep]] + [[row[i] for i in keep] for row in cells]
    widths = [max(len(row[i]) for row in rows) for i in range(len(keep))]
    return ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in rows]


def lambda_warnings(records: list[dict], most: int = 5) -> list[str]:
    """``warning: Lambda_KM of <edge>: <why>`` lines, one per kind of warning
    (:func:`antisync.stats.summary.warning_kind`): a kind that several links share is one line that
    counts them, names the first ``most`` and, where their texts differ (the numbers of each
    link), quotes the first as an example."""
    kinds: dict[str, dict[tuple, str]] = {}
    for r in records:
        w = r.get("lambda_km_warning")
        if w:
            # one entry per link: the records of its betas repeat the same warning
            kinds.setdefault(warning_kind(w), {}).setdefault((r.get("graph"), r["edge"]), w)
    lines = []
    for kind, links in sorted(kinds.items(), key=lambda item: min(e for _, e in item[1])):
        order = sorted(links, key=lambda link: link[1])
        (first, *_), texts = order, set(links.values())
        if len(order) == 1:
            lines.append(f"warning: Lambda_KM of {first[1]}: {links[first]}")
            continue
        names = list(dict.fromkeys(e for _, e in order))
        shown = ", ".join(names[:most]) + (", ..." if len(names) > most else "")
        why = links[first] if len(texts) == 1 else f"{kind}, e.g. {first[1]}: {links[first]}"
        lines.append(f"warning: Lambda_KM of {len(order)} links ({shown}): {why}")
    return lines


def _cell(record: dict, key: str, fmt) -> str:
    """One cell: ``fmt(record)`` for a computed cell, else ``record[key]`` formatted."""
    if callable(fmt):
        return fmt(record)
    value = record.get(key)
    if value is None:
        return "-"
    return "0" if fmt == "{:+d}" and value == 0 else fmt.format(value)


def _has(records: list[dict], key: str) -> bool:
    return any(r.get(key) is not None for r in records)


def sync_warnings(records: list[dict], most: int = 5) -> list[str]:
    """Where realizations never reached the threshold, saying what to do: one line per graph,
    or, where several graphs share a remedy (raise t_max; or nothing, they are counted), one
    line for them that counts them, names the first ``most`` and quotes the worst."""
    kinds: dict[str, list[tuple]] = {}
    for graph in dict.fromkeys(r["graph"] for r in records):
        rs = [r for r in records if r["graph"] == graph]
        worst = max(rs, key=lambda r: r.get("n_not_synced") or 0)
        n_bad, done = worst.get("n_not_synced") or 0, worst.get("realizations_done") or 0
        if n_bad and done:
            kinds.setdefault(_sync_hint(n_bad, done), []).append((graph, worst, rs))
    out = []
    for hint, graphs in kinds.items():
        if len(graphs) == 1:
            graph, worst, rs = graphs[0]
            p = worst.get("p_sync")
            shown = f"P_sync = {p:.3f} undamaged" if p is not None else "P_sync"
            out.append(f"{graph}: {_unsynced(worst)}; {hint}{_conditioned(rs, shown)}")
            continue
        graph, worst, _ = max(graphs, key=lambda g: g[1]["n_not_synced"] / g[1]["realizations_done"])
        names = ", ".join(g[0] for g in graphs[:most]) + (", ..." if len(graphs) > most else "")
        every = [r for g in graphs for r in g[2]]
        out.append(
            f"{len(graphs)} graphs ({names}): realizations did not synchronize by t_max, most in "
            f"{graph} ({worst['n_not_synced']:,} of {worst['realizations_done']:,}, {_where(worst)}); "
            f"{hint}{_conditioned(every, 'P_sync of each graph in --format json')}"
        )
    return out


def _sync_hint(n_bad: int, done: int) -> str:
    """What to do about ``n_bad`` of ``done`` realizations that never synchronized."""
    if n_bad > done / 2:
        return (
            "raise dynamics.t_max, or check that this graph synchronizes (rings and other "
            "graphs with stable twisted states do not)"
        )
    return "they are counted (unsynced) and left out of every mean"


def _unsynced(worst: dict) -> str:
    """``12 of 200 realizations did not synchronize by t_max (2->1, beta 0.5)``."""
    return (
        f"{worst['n_not_synced']:,} of {worst['realizations_done']:,} realizations did not "
        f"synchronize by t_max ({_where(worst)})"
    )


def _where(record: dict) -> str:
    """The link of ``record`` and its beta: ``2->1, beta 0.5`` (``2->1`` without a beta)."""
    return record["edge"] + (f", beta {record['beta']:g}" if record.get("beta") else "")


def _conditioned(records: list[dict], p_sync: str) -> str:
    """What the Kuramoto numbers of ``records`` are conditioned on, where some undamaged
    realizations never synchronized and the records have dPsync ("" otherwise)."""
    partial = any(r.get("p_sync") is not None and r["p_sync"] < 1 for r in records)
    if not partial or not any(r.get("p_sync_response") is not None for r in records):
        return ""
    return (
        f"; Lambda_KM and <F> are conditioned on synchronizing ({p_sync}), "
        "and dPsync is each link's effect on that fraction"
    )


# ---- sweeps --------------------------------------------------------------------------------
_SWEEP_JSON_KEYS = (
    "sweep",
    "complete",
    "thresholds",
    "ranking_threshold",
    "records",
    "excluded",
    "top",
    "screen",
    "symmetry",
    "grid",
)


def format_sweep(summary: dict, fmt: str = "table") -> str:
    """Render :func:`antisync.sweeps.sweep_summary`.

    ``json``: one object with ``records`` (per directed edge, with ``graph``), ``excluded``
    (``{graph, reason, fraction_not_synced, ...}``), ``top``, ``screen`` and ``symmetry``.
    ``csv``: the records only. ``table``: the records, then excluded graphs and savings.
    A grid sweep's records are grouped by grid point (``table``) or carry one column per
    grid key (``csv``).
    """
    if fmt == "json":
        return json.dumps({k: summary.get(k) for k in _SWEEP_JSON_KEYS}, indent=2)
    if fmt == "csv":
        flat = [
            {**{k: v for k, v in r.items() if k != "grid"}, **(r.get("grid") or {})}
            for r in summary["records"]
        ]
        return format_records(flat + summary["top"], "csv")
    # per-edge warnings would repeat for every graph: count them instead
    rough = sum(1 for r in summary["records"] + summary["top"] if r.get("lambda_km_warning"))
    records = [{**r, "lambda_km_warning": None} for r in summary["records"]]
    lines = []
    thresholds = sorted({r["threshold"] for r in records})
    points = list(dict.fromkeys(r.get("point") for r in records))  # None without a grid
    for point in points:
        for t in thresholds:
            part = [r for r in records if r["threshold"] == t and r.get("point") == point]
            if not part:
                continue
            head = [f"grid point {point}"] if point is not None else []
            if len(thresholds) > 1 and (point is None or "threshold=" not in point):
                head.append(f"threshold r = {t:g}")
            if head:
                lines.append("== " + "; ".join(head))
            lines.append(format_records(part, "table"))
    if summary["top"]:
        lines.append(f"== top stage (edge of largest Lambda_KM, r = {summary['ranking_threshold']:g})")
        lines.append(format_records([{**r, "lambda_km_warning": None} for r in summary["top"]], "table"))
    if rough:
        lines.append(
            f"warning: {rough} record(s) have rough Lambda_KM errors (few batches or heavy "
            "tails; see lambda_km_warning in --format json)"
        )
    for ex in summary["excluded"]:
        lines.append(
            f"excluded {ex['graph']}: {ex['reason']} "
            f"(fraction not synchronized {ex['fraction_not_synced']:.3f})"
        )
    s = summary["symmetry"]
    lines.append(
        f"symmetry: {s['directed_edges']} directed edges in {s['representatives']} orbits; "
        f"{s['integrations_saved']:,} of {s['integrations_without_symmetry']:,} "
        f"integrations saved ({s['fraction_saved']:.0%})"
    )
    if not summary["complete"]:
        lines.append("warning: the sweep is not complete; rerun `antisync sweep ... --resume`")
    return "\n".join(lines)


def fmt_pm(value, se, digits: int = 2) -> tuple[str, str]:
    """``(value, se)`` as strings rounded to ``digits`` significant digits of the error."""
    if value is None:
        return "-", "-"
    if se is None or not math.isfinite(se) or se <= 0:
        return f"{value:.4g}", "-"
    decimals = max(0, digits - 1 - int(math.floor(math.log10(se))))
    return f"{value:.{decimals}f}", f"{se:.{decimals}f}"


TABLE1_COLUMNS = (
    "rank",
    "graph",
    "tau0_mean",
    "tau0_se",
    "edge",
    "lambda_km",
    "lambda_km_se",
    "F_mean",
    "F_se",
    "beta",
    "n_tau0",
    "n_F",
)


def format_table1(rows: list[dict], fmt: str = "markdown") -> str:
    """Table 1 of the paper: rank, graph, <tau0>, max Lambda^KM and its edge, <F_beta> there.

    ``rows`` come from :func:`antisync.report.sweep.table1_rows`; ``fmt`` is
    ``markdown``, ``csv`` or ``latex``. Values carry standard errors (two significant
    digits of the error); CSV keeps full precision.
    """
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=list(TABLE1_COLUMNS), extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
        return buf.getvalue().rstrip("\n")
    beta = next((r["beta"] for r in rows if r.get("beta") is not None), 0.5)
    cells = []
    for r in rows:
        t0, t0e = fmt_pm(r.get("tau0_mean"), r.get("tau0_se"))
        lam, lame = fmt_pm(r.get("lambda_km"), r.get("lambda_km_se"))
        f, fe = fmt_pm(r.get("F_mean"), r.get("F_se"))
        cells.append((str(r["rank"]), str(r["graph"]), (t0, t0e), str(r["edge"]), (lam, lame), (f, fe)))
    if fmt == "latex":

        def pm(v):
            return f"${v[0]} \\pm {v[1]}$" if v[1] != "-" else f"${v[0]}$"

        edge = r"\to"
        out = [
            r"\begin{tabular}{c c c c c c}",
            r"{\bf Rank} & {\bf Graph} & $\langle \tau_0 \rangle$ & edge $a \to b$ & "
            r"$\Lambda^{(\mathrm{KM})}$ & $\langle \mathcal{F}_{\beta=" + f"{beta:g}" + r"} \rangle$ \\",
            r"\hline",
        ]
        for rank, g, t0, e, lam, f in cells:
            g = g.replace("_", r"\_")
            out.append(f"{rank} & {g} & {pm(t0)} & ${e.replace('->', edge)}$ & {pm(lam)} & {pm(f)} \\\\")
        out += [r"\hline", r"\end{tabular}"]
        return "\n".join(out)
    if fmt != "markdown":
        raise ValueError(f"format must be markdown, csv or latex, got {fmt!r}")

    def pm(v):
        return f"{v[0]} ± {v[1]}" if v[1] != "-" else v[0]

    out = [
        f"| rank | graph | <tau0> | edge a->b | Lambda_KM (max) | <F_{beta:g}> on a->b |",
        "|---:|:---|---:|:---:|---:|---:|",
    ]
    for rank, g, t0, e, lam, f in cells:
        out.append(f"| {rank} | {g} | {pm(t0)} | {e} | {pm(lam)} | {pm(f)} |")
    return "\n".join(out)
