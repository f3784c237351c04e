"""Per-(edge, beta) records from stored block statistics: <F_beta>, Lambda^KM, <tau0>, counts.

Records are computed from the block records of a result file (never from a live run), so a
summary of a resumed, a Dask or a CUDA run is computed exactly like any other. A job run
without ``km`` (``measures: [xi2, rw]``) integrated nothing and has no blocks; its records keep
every key of a Kuramoto record (tables and CSV files of mixed files share one set of columns)
with the Kuramoto values ``None``, the counts 0, the estimator's description and warning
``None`` and ``complete`` true (its measures are written with the job). This module is
pure: a :class:`JobView` (one decoded job) in, records out. Reading a file is the store's
(:func:`antisync.store.read_views`, :func:`antisync.store.records`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from statistics import NormalDist

import numpy as np

from antisync.stats import estimators

__all__ = [
    "CI_LEVEL",
    "OUTSIDE_WHY",
    "RECORD_KEYS",
    "WARNING_KINDS",
    "JobView",
    "is_kuramoto",
    "join_nnc",
    "job_records",
    "graph_names",
    "lambda_intervals",
    "measure_fields",
    "named_views",
    "r_star_rows",
    "sign_resolved",
    "view_records",
    "warning_kind",
]

# error bars are flagged when the largest 0.1% of samples carry this share of the variance
TAIL_WARN = 0.5
# the interval warns when it rests on fewer tail values than this
TAIL_EVENTS = 10
#: level of the ``lambda_km_ci_low`` / ``lambda_km_ci_high`` interval of every record
CI_LEVEL = 0.95


@dataclass
class JobView:
    """What a summary needs from one stored job (decoded by :func:`antisync.store.read_views`,
    or taken from a run's memory at each checkpoint)."""

    graph: str
    edges: list
    betas: tuple
    dbeta: float
    variant_edge: np.ndarray
    variant_beta: np.ndarray
    rec: np.ndarray
    rec0: np.ndarray
    done: np.ndarray
    tail: np.ndarray
    realizations: int
    hist: np.ndarray | None = None
    hist_variants: np.ndarray | None = None
    tau_max_hist: float = 40.0
    lam_rec: np.ndarray | None = None
    lam_tail: np.ndarray | None = None
    lambda_method: str = "finite-difference"
    omega: np.ndarray | None = None
    nodes: list | None = None
    attrs: dict | None = None
    measures: dict | None = None  # Lambda^(linear, xi2, RW) arrays, see measures.pipeline
    unsynced_hint: str | None = None  # why nothing may lock (antisync.plan.model.unsynced_hint)
    # sync.criterion relative: r* of the undamaged network, then of each variant, (1 + V,);
    # None for another criterion and for a file written before it was stored
    r_star: np.ndarray | None = None

    def variant(self, edge_index: int, beta: float) -> int:
        hit = np.flatnonzero((self.variant_edge == edge_index) & np.isclose(self.variant_beta, beta))
        return int(hit[0]) if hit.size else -1


def _num(x: float):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def _pooled_tail(view: JobView) -> tuple[np.ndarray, int]:
    """The signed tail counts of every link of the job together (the tail model's prior) and
    the number of links with a value (:func:`estimators.pooled_tail`)."""
    return estimators.pooled_tail(view.lam_tail)


def _interval(view: JobView, e: int, pooled: tuple[np.ndarray, int], level: float):
    """Edge ``e``'s :func:`estimators.summarize_lambda` and :func:`estimators.lambda_ci`."""
    rec = view.lam_rec[view.done, e]
    s = estimators.summarize_lambda(rec)
    counts, links = pooled
    ci = estimators.lambda_ci(
        s["lambda"],
        rec,
        view.lam_tail[e],
        counts,
        view.dbeta,
        level,
        estimator=view.lambda_method,
        links=links,
    )
    return s, ci


def _few_tail_values(iv, se: float, se_batch: float) -> bool:
    """The interval rests on fewer than :data:`TAIL_EVENTS` values of the tail and is wider
    than 1.5x the batch-means one: the summary warns, and its coverage is the least sure
    (the runs of 2,000 in bench/RESULTS.md, "Calibration of Lambda's error bars")."""
    return iv is not None and iv.tail_events < TAIL_EVENTS and se > 1.5 * se_batch


def lambda_intervals(view: JobView, level: float = CI_LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """``(ci, thin)``: ``ci`` (E, 2) every link's Lambda^KM interval at ``level`` (NaN where no
    synchronized realization gives a value), as the records' ``lambda_km_ci_low`` / ``_high``
    at 95%; ``thin`` (E,) bool, where that interval rests on few tail values (the summary's
    heavy-tail warning)."""
    pooled = _pooled_tail(view)
    ci = np.full((len(view.edges), 2), np.nan)
    thin = np.zeros(len(view.edges), dtype=bool)
    z = NormalDist().inv_cdf((1 + level) / 2)
    for e in range(len(view.edges)):
        s, (low, high, _, iv) = _interval(view, e, pooled, level)
        if s["n"] >= 2:
            ci[e] = low, high
            thin[e] = _few_tail_values(iv, (high - low) / (2 * z), s["lambda"].se)
    return ci, thin


#: why a link's mean can lie outside its own interval: the words of the summary's warning, which
#: the figures repeat beside such a link (:mod:`antisync.report.links`)
OUTSIDE_WHY = (
    "a few rare large values carry the mean, and the tail model weighs them by how often such "
    "values come, not by their sizes; run more realizations before reading this link"
)

#: the kinds of ``lambda_km_warning`` that :func:`_lambda` writes, each by the words its text
#: begins with (numbers vary per link); the summary table prints one line per kind
WARNING_KINDS = {
    "too few synchronized realizations": re.compile(
        r"\d+ synchronized realizations?: no (estimate|standard)"
    ),
    "mean outside its interval": re.compile(r"the mean \S+ lies outside its interval"),
    "too few batches": re.compile(r"only \d+ batches"),
    "heavy tail, few tail values": re.compile(r"heavy tail: the interval rests on"),
    "heavy tail, no tail model": re.compile(r"heavy tail: top 0\.1% of samples"),
    "format-1 interval": re.compile(r"interval from batch means \(a format-1 file"),
    "links of different scales": re.compile(r"interval from batch means: the job's links differ"),
    "uncalibrated estimator": re.compile(r"\S+ derivatives have an unbounded tail"),
}


def warning_kind(warning: str) -> str:
    """The :data:`WARNING_KINDS` name of a ``lambda_km_warning``; a text of no known kind is
    its own kind."""
    return next((kind for kind, pattern in WARNING_KINDS.items() if pattern.match(warning)), warning)


def _lambda(view: JobView, e: int, pooled: tuple[np.ndarray, int]) -> tuple[dict, dict]:
    """Lambda's fields of edge ``e``'s records, and its :func:`estimators.summarize_lambda`."""
    rec = view.lam_rec[view.done, e]
    s, (low, high, method, iv) = _interval(view, e, pooled, CI_LEVEL)
    est = s["lambda"]
    share = estimators.tail_share(view.lam_tail[e])
    # the standard error to quote: the interval's half-width over z (decisions at other levels,
    # e.g. the sweeps' 4-sigma trend, scale it)
    se = (high - low) / (2 * estimators.Z95) if iv is not None else est.se
    warning = None
    if s["n"] < 2:
        # with none there is no estimate at all, with one no spread
        warning = (
            f"{s['n']} synchronized realization{'s' if s['n'] != 1 else ''}: no "
            + ("estimate and no interval" if s["n"] == 0 else "standard error")
            + " (see the unsynced count)"
        )
        if view.unsynced_hint and s["n_not_synced"]:
            warning += f"; {view.unsynced_hint}"
    elif not low <= est.mean <= high:
        warning = f"the mean {est.mean:+.4g} lies outside its interval [{low:.4g}, {high:.4g}]: {OUTSIDE_WHY}"
    elif est.n_batches < 10:
        warning = f"only {est.n_batches} batches: standard error is rough"
    elif _few_tail_values(iv, se, est.se):
        need = int(math.ceil(est.n * TAIL_EVENTS / max(iv.tail_events, 1) / 1000.0)) * 1000
        warning = (
            f"heavy tail: the interval rests on {iv.tail_events} values beyond |Lambda| = "
            f"{iv.u:.3g} and is {se / est.se:.1f}x the batch-means one; about {need:,} "
            f"realizations would sample {TAIL_EVENTS} of them"
        )
    elif iv is None and view.lam_tail.shape[-1] != estimators.LAMBDA_TAIL_BINS:
        warning = (
            "interval from batch means (a format-1 file has no signed tail counts), which "
            "undercovers heavy tails: rerun with this antisync for the tail model's interval"
        )
    elif iv is None and s["n"] >= 2 and pooled[1] and not np.any(pooled[0]):
        warning = (
            "interval from batch means: the job's links differ in |Lambda| by decades, so no "
            "pooled tail model applies (estimators.pooled_tail); batch means undercover a heavy "
            "tail, so read a sign near zero with care"
        )
    elif iv is None and not math.isnan(share) and share > TAIL_WARN:
        warning = (
            f"heavy tail: top 0.1% of samples carry {share:.0%} of the variance and too few "
            "values for the tail model: run more realizations"
        )
    elif view.lambda_method in estimators.UNCALIBRATED_ESTIMATORS:
        warning = (
            f"{view.lambda_method} derivatives have an unbounded tail (values to ~1e4 at "
            "probability ~1e-5): this interval covered only 74-98% of runs on the lollipop; "
            f"use lambda.method {estimators.UNCALIBRATED_ESTIMATORS[view.lambda_method]}"
            " (the same derivative, with error bars to trust)"
        )
    fields = {
        "lambda_km": _num(est.mean),
        "lambda_km_se": _num(se),
        "lambda_km_se_naive": _num(est.se_naive),
        "lambda_km_se_batch": _num(est.se_batch),
        "lambda_km_ci_low": _num(low),
        "lambda_km_ci_high": _num(high),
        "lambda_km_ci_level": CI_LEVEL,
        "lambda_km_ci_method": method,
        "lambda_km_tail_events": None if iv is None else iv.tail_events,
        "lambda_km_tail_share": _num(share),
        "lambda_km_warning": warning,
        "lambda_method": view.lambda_method,
        "lambda_quantity": estimators.lambda_quantity(
            view.lambda_method, str((view.attrs or {}).get("lambda_quantity", "")) or None
        ),
        "lambda_dbeta": view.dbeta,
        "lambda_n": s["n"],
        "lambda_n_flagged": s["n_flagged"],
    }
    fields.update(_lambda_tau(rec))
    fields.update(_sync_response(view, rec))
    return fields, s


def _lambda_tau(rec: np.ndarray) -> dict:
    """The additive response ``Lambda^tau = -d ln<tau(beta)>/dbeta`` at 0 of one edge
    (:func:`estimators.summarize_lambda_tau`), with a normal interval from its batch-means
    error at the records' level (:func:`estimators.lambda_tau_interval`); None where the file
    predates it (format 1-3)."""
    est = estimators.summarize_lambda_tau(rec)
    if est is None or math.isnan(est.mean):
        return {
            "lambda_tau": None,
            "lambda_tau_se": None,
            "lambda_tau_ci_low": None,
            "lambda_tau_ci_high": None,
        }
    low, high = estimators.lambda_tau_interval(est, CI_LEVEL)
    return {
        "lambda_tau": float(est.mean),
        "lambda_tau_se": _num(est.se),
        "lambda_tau_ci_low": _num(low),
        "lambda_tau_ci_high": _num(high),
    }


def _sync_response(view: JobView, rec: np.ndarray) -> dict:
    """The synchronized fraction's response to the link's damage (finite difference only:
    a derivative estimator integrates no damaged network that could fail to synchronize)."""
    r = estimators.sync_response(rec, view.dbeta) if view.lambda_method == "finite-difference" else None
    if r is None:
        return dict.fromkeys(SYNC_RESPONSE_KEYS)
    return {
        "p_sync_response": r["value"],
        "p_sync_response_ci_low": r["low"],
        "p_sync_response_ci_high": r["high"],
        "p_sync_lost": r["lost"],
        "p_sync_gained": r["gained"],
    }


#: the fields of a record that describe the synchronized fraction's response (basin stability)
SYNC_RESPONSE_KEYS = (
    "p_sync_response",
    "p_sync_response_ci_low",
    "p_sync_response_ci_high",
    "p_sync_lost",
    "p_sync_gained",
)


def sign_resolved(record: dict) -> int:
    """``+1`` (antifragile) or ``-1`` (fragile) when the record's ``lambda_km_ci_low`` ..
    ``lambda_km_ci_high`` interval excludes 0; ``0`` when it does not or is missing."""
    lo, hi = record.get("lambda_km_ci_low"), record.get("lambda_km_ci_high")
    if lo is None or hi is None:
        return 0
    return 1 if lo > 0 else -1 if hi < 0 else 0


# describe the Kuramoto estimator; meaningless where it did not run
_ESTIMATOR_KEYS = (
    "lambda_km_warning",
    "lambda_km_ci_level",
    "lambda_km_ci_method",
    "lambda_method",
    "lambda_quantity",
    "lambda_dbeta",
)


def is_kuramoto(view: JobView) -> bool:
    """Whether ``view``'s job integrated the Kuramoto model: a job without ``km`` in its
    measures has no statistics blocks (a Kuramoto run has at least one realization)."""
    return view.done.size > 0


def _exact_only(rec: dict) -> dict:
    out = dict(rec)
    for key in _ESTIMATOR_KEYS:
        if key in out:
            out[key] = None
    out["realizations"] = out["realizations_done"] = 0
    out["complete"] = True
    return out


def job_records(view: JobView) -> list[dict]:
    """One record per (edge, requested beta); with no betas, one record per edge (Lambda only)."""
    s0 = estimators.summarize_tau0(view.rec0[view.done])
    t0 = s0["tau0"]
    complete = bool(view.done.size and view.done.all())
    out = []
    pooled = _pooled_tail(view)
    for e, label in enumerate(view.edges):
        lam, s_lam = _lambda(view, e, pooled)
        for beta in view.betas or (None,):
            rec = {"graph": view.graph, "edge": label, "beta": beta}
            if beta is not None:
                s = estimators.summarize_variant(view.rec[view.done, view.variant(e, beta)])
                rec.update(
                    {
                        "F_mean": _num(s["F"].mean),
                        "F_se": _num(s["F"].se),
                        "F_se_naive": _num(s["F"].se_naive),
                        "tau_mean": _num(s["tau"].mean),
                        "tau_se": _num(s["tau"].se),
                        "n": s["n"],
                        "n_excluded": s["n_already"],
                        "n_not_synced": s["n_not_synced"],
                    }
                )
            else:
                s = s_lam
                rec.update(
                    {
                        "F_mean": None,
                        "F_se": None,
                        "F_se_naive": None,
                        "tau_mean": None,
                        "tau_se": None,
                        "n": s["n"],
                        "n_excluded": s["n_already"],
                        "n_not_synced": s["n_not_synced"],
                    }
                )
            rec.update(lam)
            done = int(s0["n"] + s0["n_already"] + s0["n_not_synced"])
            rec.update(
                {
                    "tau0_mean": _num(t0.mean),
                    "tau0_se": _num(t0.se),
                    "tau0_n": s0["n"],
                    # what every Kuramoto number is conditioned on: the undamaged network's
                    # synchronized fraction, and the share of realizations Lambda averages
                    "p_sync": (s0["n"] + s0["n_already"]) / done if done else None,
                    "lambda_km_fraction": s_lam["n"] / done if done else None,
                    "realizations_done": done,
                    # an interrupted run's estimates are partial: say so in every record
                    "realizations": int(view.realizations),
                    "complete": complete,
                    **_r_star_fields(view, e, beta),
                }
            )
            rec.update(measure_fields(view.measures, e))
            out.append(rec)
    return out if is_kuramoto(view) else [_exact_only(r) for r in out]


def _r_star_fields(view: JobView, e: int, beta: float | None) -> dict:
    """``r_star``, the undamaged network's r* (``sync.criterion: relative``), and
    ``r_star_damaged``, that of edge ``e`` damaged by ``beta`` (None without a beta); both None
    where the file stores no r* (another criterion, or written before r* was stored)."""
    if view.r_star is None:
        return {"r_star": None, "r_star_damaged": None}
    v = view.variant(e, beta) if beta is not None else -1
    return {
        "r_star": _num(float(view.r_star[0])),
        "r_star_damaged": _num(float(view.r_star[1 + v])) if v >= 0 else None,
    }


def r_star_rows(views: list[JobView]) -> list[dict]:
    """Per job that stores r* (``sync.criterion: relative``): ``graph``, ``undamaged`` (its
    r*), and ``damaged_min`` / ``damaged_max`` over its ``damaged`` variants (None without
    variants)."""
    rows = []
    for view in views:
        if view.r_star is None or not view.r_star.size:
            continue
        damaged = view.r_star[1:]
        rows.append(
            {
                "graph": view.graph,
                "undamaged": _num(float(view.r_star[0])),
                "damaged_min": _num(float(damaged.min())) if damaged.size else None,
                "damaged_max": _num(float(damaged.max())) if damaged.size else None,
                "damaged": int(damaged.size),
            }
        )
    return rows


def graph_names(views: list[JobView], name: str | None = None, safe=str) -> dict[str, str]:
    """``{job: its name}``: the one name a job goes by in the summary's ``graph`` column, the
    figures' titles and their file names (``safe``: :func:`antisync.report.figures.file_stem`
    for those).

    ``name`` is the config's ``name:`` (which defaults to the config file's stem): the name of
    a file of one job (its km_nnc twin's is ``<name>_nnc``), ``<name>_<job>`` for each of
    several; without ``name`` each job keeps its own (the graph's: ``lollipop_6_3``,
    ``connected_watts_strogatz_graph``, an edge list's file name).
    """
    twins = {v.graph: str(v.attrs["nnc_of"]) for v in views if v.attrs and v.attrs.get("nnc_of")}
    jobs = [v.graph for v in views if v.graph not in twins]
    names = {}
    for job in jobs:
        if not name:
            names[job] = safe(job)
        elif len(jobs) == 1:
            names[job] = safe(name)
        else:
            names[job] = f"{safe(name)}_{safe(job)}"
    for twin, of in twins.items():
        names[twin] = f"{names.get(of, safe(of))}_nnc"
    return names


def named_views(views: list[JobView], name: str | None) -> list[JobView]:
    """``views`` with each job called by :func:`graph_names` (a twin's ``nnc_of`` renamed
    alike), so that the records, the sum rule, r* and the figures all say the config's
    ``name:`` where it has one. The views are copies; the file is not touched."""
    if not name:
        return list(views)
    names = graph_names(views, name)
    out = []
    for v in views:
        attrs = dict(v.attrs or {})
        if attrs.get("nnc_of"):
            attrs["nnc_of"] = names.get(str(attrs["nnc_of"]), str(attrs["nnc_of"]))
        out.append(
            replace(v, graph=names.get(v.graph, v.graph), attrs=attrs if v.attrs is not None else None)
        )
    return out


def view_records(views: list[JobView]) -> list[dict]:
    """Records of ``views``, with each run's ``lambda_km_nnc`` taken from its raw-coupling twin."""
    return join_nnc(views, [r for view in views for r in job_records(view)])


# --- the exact measures' fields of a record ------------------------------------------------

#: Summary keys added to every record, ``None`` where not computed.
RECORD_KEYS = (
    "lambda_linear",
    "lambda_linear_se",
    "lambda_linear_n",
    "lambda_linear_n_excluded",
    "lambda_xi2",
    "lambda_rw",
    "lambda_km_nnc",
    "lambda_km_nnc_se",
)
_INT_KEYS = {"lambda_linear_n", "lambda_linear_n_excluded", "lambda_linear_n_already_synced"}


def measure_fields(measures: dict | None, e: int) -> dict:
    """The :data:`RECORD_KEYS` of edge ``e``; ``None`` for what was not computed."""
    rec = dict.fromkeys(RECORD_KEYS)
    for key in RECORD_KEYS:
        if measures is not None and key in measures:
            x = measures[key][e]
            if key in _INT_KEYS:
                rec[key] = int(x)
            else:
                rec[key] = float(x) + 0.0 if np.isfinite(x) else None  # no -0.0
    return rec


def join_nnc(views, records: list[dict]) -> list[dict]:
    """Fill ``lambda_km_nnc`` (``_se``) of each normalized job's records from its twin's.

    ``views`` are :class:`~antisync.stats.summary.JobView` s whose ``attrs`` may carry
    ``nnc_of``; ``records`` are their records, changed in place and returned.
    """
    twins = {str(v.attrs["nnc_of"]): v.graph for v in views if v.attrs and v.attrs.get("nnc_of")}
    if not twins:
        return records
    by_graph: dict[str, dict[str, tuple]] = {}
    for r in records:
        by_graph.setdefault(r["graph"], {}).setdefault(r["edge"], (r["lambda_km"], r["lambda_km_se"]))
    for r in records:
        twin = twins.get(r["graph"])
        if twin is not None and r["edge"] in by_graph.get(twin, {}):
            r["lambda_km_nnc"], r["lambda_km_nnc_se"] = by_graph[twin][r["edge"]]
    return records
