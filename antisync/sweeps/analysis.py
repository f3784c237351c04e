"""Statistics of a sweep from its records: pure functions, no file and no computation.

- :func:`summarize`: a sweep file's decoded jobs and metadata -> the records of every
  directed edge (:func:`expand_records` fans a representative's records out to its orbit),
  the top stage, the exclusions and the screening (what :func:`~antisync.sweeps.sweep_summary`
  returns for a file);
- :func:`edge_lambdas`, :func:`ranking`: Lambda^KM per edge (repeats averaged) and the graphs
  ranked by the sum of their positive Lambda^KM (Fig. 3, Table 1);
- :func:`trend_in_n`: whether Lambda is positive and decreasing in N (Fig. 2b).
"""

from __future__ import annotations

import math

import numpy as np

from antisync.errors import StoreError
from antisync.sweeps.points import point_label

__all__ = ["edge_lambdas", "expand_records", "ranking", "summarize", "trend_in_n"]


def expand_records(records: list[dict], orbits: dict[str, str]) -> list[dict]:
    """Fan records of representative edges out to every edge of their orbits.

    ``orbits`` maps each edge label to its representative's label, in the order the records
    should come out. Each output record is a copy of its representative's with ``edge`` set,
    plus ``representative`` and ``orbit_size``.
    """
    by_edge: dict[str, list[dict]] = {}
    for r in records:
        by_edge.setdefault(r["edge"], []).append(r)
    size: dict[str, int] = {}
    for rep in orbits.values():
        size[rep] = size.get(rep, 0) + 1
    out = []
    for label, rep in orbits.items():
        for r in by_edge.get(rep, []):
            out.append({**r, "edge": label, "representative": rep, "orbit_size": size[rep]})
    return out


def summarize(meta: dict, views: list) -> dict:
    """Everything a report needs from a sweep: its metadata and decoded jobs -> records.

    Parameters
    ----------
    meta : dict
        The sweep's metadata (:func:`antisync.store.read_meta`).
    views : list of JobView
        Every job of the sweep's file (:func:`antisync.store.read_views`).

    Returns
    -------
    dict
        ``records``: main-stage records fanned out to every selected directed edge of every
        kept graph (keys of :func:`antisync.stats.summary.job_records` plus ``job``,
        ``threshold``, ``repeat``, ``representative``, ``orbit_size``, and in a grid sweep
        ``grid``, the point's ``{key: value}``, and ``point``, its label
        ``model.phase_lag=0.1, ...``);
        ``top``: records of the top stage (plus ``rank``);
        ``excluded``: ``{graph, reason, fraction_not_synced, fraction_stuck, screened}``;
        ``screen``: the screening of every graph; ``symmetry``: integrations saved;
        ``complete``: whether every stage finished; ``grid``: the grid's axes
        (``[{keys, values, zip}, ...]``, ``None`` without a grid).
    """
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.stats.summary import view_records

    _refuse_shared_jobs(meta["jobs"])
    by_job: dict[str, list] = {}
    # view_records joins lambda_km_nnc from `<job>_nnc` twins (measures: [km, km_nnc])
    for r in view_records(views):
        by_job.setdefault(r["graph"], []).append(r)
    graphs = {g["graph"]: g for g in meta["graphs"]}
    records, top = [], []
    for jm in meta["jobs"]:
        if jm["job"] not in by_job:
            continue
        recs = [
            {
                **r,
                "graph": jm["graph"],
                "job": jm["job"],
                "threshold": jm["threshold"],
                "repeat": jm["repeat"],
                **_point_fields(jm),
            }
            for r in by_job[jm["job"]]
        ]
        if jm["stage"] == "main":
            records += expand_records(recs, graphs[jm["graph"]]["orbits"])
        else:
            orbits = graphs[jm["graph"]]["orbits"]
            for r in recs:
                r.update(
                    rank=jm["rank"],
                    edge=jm["edge"],
                    representative=r["edge"],
                    orbit_size=sum(1 for x in orbits.values() if x == r["edge"]),
                )
            top += recs
    excluded = [
        {
            "graph": g["graph"],
            "reason": g["screen"]["reason"],
            "fraction_not_synced": g["screen"]["fraction_not_synced"],
            "fraction_stuck": g["screen"]["fraction_stuck"],
            "screened": g["screen"]["realizations"],
        }
        for g in meta["graphs"]
        if g["excluded"]
    ]
    return {
        "sweep": meta["name"],
        "family": meta["family"],
        "thresholds": meta["thresholds"],
        "ranking_threshold": meta["ranking_threshold"],
        "complete": meta.get("complete", False),
        "records": records,
        "top": top,
        "excluded": excluded,
        "screen": [g["screen"] for g in meta["graphs"] if g.get("screen")],
        "symmetry": meta["symmetry"],
        "grid": meta.get("grid"),
        "meta": meta,
    }


def _refuse_shared_jobs(jobs_meta: list[dict]) -> None:
    """Refuse a file whose metadata lists two jobs of one name (written before grid values
    were named in full: seeds 1000001 and 1000002 both ``1e+06``): its one group holds one
    point's numbers, and both points would show them."""
    seen: dict[str, dict] = {}
    for jm in jobs_meta:
        first = seen.setdefault(jm["job"], jm)
        if first is not jm:
            a, b = (point_label(x.get("point") or {}) or x["graph"] for x in (first, jm))
            raise StoreError(
                f"the sweep's jobs {a} and {b} share the name {jm['job']!r} (an antisync that named "
                "grid values with 6 digits wrote it): one shows the other's numbers; run the sweep "
                "again with --overwrite"
            )


def _point_fields(job_meta: dict) -> dict:
    """A grid job's ``grid`` (``{key: value}``) and ``point`` (its label); ``{}`` otherwise."""
    point = job_meta.get("point")
    return {"grid": point, "point": point_label(point)} if point is not None else {}


def edge_lambdas(records: list[dict], threshold: float) -> dict[tuple, dict]:
    """``{(graph, edge): {lambda_km, lambda_km_se, sd, n_repeats, representative}}`` at ``threshold``.

    Repeats are averaged: ``lambda_km`` is their mean, ``lambda_km_se`` the combined standard
    error of that mean and ``sd`` their standard deviation (``nan`` for one repeat).
    """
    per: dict[tuple, dict] = {}
    for r in records:
        if not math.isclose(r.get("threshold", threshold), threshold):
            continue
        # one value per (edge, repeat): the records of different betas repeat the same Lambda
        per.setdefault((r["graph"], r["edge"]), {}).setdefault(
            r.get("repeat", 0), (r["lambda_km"], r["lambda_km_se"], r.get("representative", r["edge"]))
        )
    out = {}
    for key, reps in per.items():
        ok = [v for v in reps.values() if v[0] is not None]
        if not ok:
            continue
        vals = np.array([v[0] for v in ok])
        out[key] = {
            "lambda_km": float(vals.mean()),
            "lambda_km_se": float(math.sqrt(sum((v[1] or 0.0) ** 2 for v in ok)) / len(ok)),
            "sd": float(vals.std(ddof=1)) if len(ok) > 1 else math.nan,
            "n_repeats": len(ok),
            "representative": ok[0][2],
        }
    return out


def trend_in_n(rows: list[dict], z: float = 4.0) -> dict:
    """What Fig. 2b's claim needs: is Lambda positive at every N, and does it decrease with N?

    ``rows`` are ``{N, lambda_km, lambda_km_se}`` sorted by N. A value is *positive* when it
    exceeds ``z`` standard errors; a step N -> N' is a *resolved decrease* when the drop exceeds
    ``z`` combined standard errors and a *resolved increase* when the rise does.

    Returns
    -------
    dict
        ``positive`` / ``not_positive`` (lists of N), ``decreases`` / ``increases`` (resolved
        steps as ``(N, N')``), ``unresolved`` (the other steps), ``z``, and ``gap``: the
        smallest ``k`` such that every pair ``N < N'`` with ``N' - N >= k`` is a resolved
        decrease (``None`` if even the widest pair is not).
    """
    out = {"z": z, "positive": [], "not_positive": [], "decreases": [], "increases": [], "unresolved": []}
    for r in rows:
        ok = r["lambda_km"] > z * r["lambda_km_se"]
        out["positive" if ok else "not_positive"].append(r["N"])
    for a, b in zip(rows, rows[1:], strict=False):
        drop = a["lambda_km"] - b["lambda_km"]
        se = math.hypot(a["lambda_km_se"], b["lambda_km_se"])
        key = "decreases" if drop > z * se else "increases" if -drop > z * se else "unresolved"
        out[key].append((a["N"], b["N"]))

    def resolved_drop(a, b) -> bool:
        return a["lambda_km"] - b["lambda_km"] > z * math.hypot(a["lambda_km_se"], b["lambda_km_se"])

    out["gap"] = None
    if len(rows) > 1:
        for k in range(1, rows[-1]["N"] - rows[0]["N"] + 1):
            if all(
                resolved_drop(a, b) for i, a in enumerate(rows) for b in rows[i + 1 :] if b["N"] - a["N"] >= k
            ):
                out["gap"] = k
                break
    return out


def ranking(records: list[dict], threshold: float) -> list[dict]:
    """Graphs sorted by the sum of their positive Lambda^KM (the order of the paper's Fig. 3).

    ``records`` are fanned-out main-stage records; repeats are averaged. Returns one row per
    graph: ``rank``, ``graph``, ``score`` (sum of positive Lambda over all directed edges),
    ``max_edge`` / ``max_representative`` / ``lambda_max`` / ``lambda_max_se`` of its most
    antifragile edge, and ``tau0_mean`` / ``tau0_se`` (repeat 0).
    """
    tau0: dict[str, list] = {}
    for r in records:
        if math.isclose(r.get("threshold", threshold), threshold) and r.get("repeat", 0) == 0:
            tau0.setdefault(r["graph"], [r.get("tau0_mean"), r.get("tau0_se")])
    graphs: dict[str, dict] = {}
    for (g, edge), v in edge_lambdas(records, threshold).items():
        row = graphs.setdefault(g, {"graph": g, "score": 0.0, "lambda_max": -math.inf, "n_edges": 0})
        row["n_edges"] += 1
        if v["lambda_km"] > 0:
            row["score"] += v["lambda_km"]
        if v["lambda_km"] > row["lambda_max"]:
            row.update(
                lambda_max=v["lambda_km"],
                lambda_max_se=v["lambda_km_se"],
                max_edge=edge,
                max_representative=v["representative"],
            )
    rows = sorted(graphs.values(), key=lambda r: (-r["score"], r["graph"]))
    for k, row in enumerate(rows, 1):
        row["rank"] = k
        row["tau0_mean"], row["tau0_se"] = tau0.get(row["graph"], [None, None])
    return rows
