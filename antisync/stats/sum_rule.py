"""The sum rule of a node's out-links: a diagnostic of what a Lambda^KM estimate measures.

With normalized coupling (Eq. 1) damaging every out-link ``a -> b`` of a node ``a`` by the same
``beta`` leaves ``W`` unchanged (each row of ``W`` is normalized), so the directional
derivative of ``<F_beta>`` along that direction is 0 and, the derivative being linear in the
damage direction,

    sum_b  d<F>/dbeta(a -> b)  =  0        for every node a.

An estimator of the derivative (central differences, ``orbit``, the adjoint) obeys it within
its error (the adjoint per realization, to rounding); the paper's forward secant
``(<F(dbeta)> - 1)/dbeta`` does not: near saddle passages tau(beta) has logarithmic
singularities close to beta = 0, and a one-sided secant keeps a bias of its side at any usable
dbeta (docs/equations.md, "Lambda near saddle passages"). A sum resolved away from 0 therefore
says that the links' values are not derivatives, whatever their intervals say.

The interval is the batch-means one of the per-block sum of the links' block means (blocks hold
the same realizations for every link of a job, so the links' correlation is kept), at the
records' level. Pure: a :class:`antisync.stats.summary.JobView` in, rows out.

Floating point cannot add the links' values to an exact 0: an estimator that obeys the rule
per realization (the adjoint) leaves sums of the order of the rounding of its terms, and with
hundreds of realizations their mean can be resolved away from 0 (-2.8e-18 with the interval
[-3.6e-18, -2.0e-18] on a 200-node graph). A sum counts as a violation only when its interval
lies beyond the rounding bound

    |sum|  <=  ROUNDING_ULPS * eps * sum_b rms(Lambda(a -> b))

with ``eps`` the float64 machine epsilon (2.2e-16) and ``rms`` the root mean square of a link's
per-realization values (from the records' ``sum2``: it bounds the mean of ``|Lambda|``, so the
bound holds for every realization's sum on average). :data:`ROUNDING_ULPS` (2^20, a bound of
2.3e-10 times the terms) covers the rounding of the values themselves, each the result of a
long integration (1e4 to 1e5 steps, each adding its rounding), and still lies many orders of
magnitude below anything an estimator's bias or a broken rule gives (the forward secant's
sums are a few percent of the terms).
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

__all__ = ["ROUNDING_ULPS", "SUM_RULE_LEVEL", "node_sums", "rounding_bound", "sum_rule_note", "views_sums"]

#: level of the sum rule's interval (the records' level)
SUM_RULE_LEVEL = 0.95
#: the rounding bound of a node's sum, in units of ``eps * sum_b rms(Lambda(a -> b))`` (see the
#: module's docstring): a sum whose interval reaches within it is consistent with the rule
ROUNDING_ULPS = 2.0**20
EPS = float(np.finfo(np.float64).eps)


def node_sums(view, coupling: str = "normalized", level: float = SUM_RULE_LEVEL) -> list[dict]:
    """``sum_b Lambda(a -> b)`` for every node ``a`` whose out-links are all in ``view``.

    Parameters
    ----------
    view : antisync.stats.summary.JobView
        One decoded job with Lambda block records (``lam_rec``).
    coupling : {"normalized", "raw"}
        The job's coupling: the rule holds for normalized coupling only, so ``raw`` gives [].
    level : float
        Level of each sum's interval.

    Returns
    -------
    list of dict
        ``{"graph", "node", "links", "sum", "low", "high", "rounding", "resolved",
        "rounding_only"}`` and the
        same for Lambda^tau (``tau_sum``, ``tau_low``, ``tau_high``, ``tau_rounding``,
        ``tau_resolved``) per node with at least two out-links (a node with one has ``W`` fixed
        by normalization: its link's Lambda is 0 by construction), in node order. ``low`` ..
        ``high`` is the interval at ``level``; ``rounding`` the bound of a sum that floating
        point leaves of an exact 0 (:func:`rounding_bound`); ``resolved`` is True when the sum
        is away from 0 at ``level`` over all the rows at once (Bonferroni: each at
        ``1 - (1 - level) / rows``), so that checking many nodes does not find a broken rule by
        chance, and farther from 0 than ``rounding``; ``rounding_only`` is True when the
        interval alone is away from 0 but the sum is within ``rounding`` (not a violation).
    """
    if coupling != "normalized" or view.lam_rec is None or not len(view.edges):
        return []
    done = np.asarray(view.done, dtype=bool)
    rec = np.asarray(view.lam_rec)[done]  # (blocks, E, fields): n, ..., sum, sum2
    if rec.shape[0] < 2:
        return []
    n, total, squares = rec[:, :, 0], rec[:, :, 3], rec[:, :, 4]
    by_node: dict = {}
    for e, label in enumerate(view.edges):
        a, _ = str(label).split("->", 1)
        by_node.setdefault(a, []).append(e)
    degree = _out_degrees(view)
    z = NormalDist().inv_cdf((1 + level) / 2)
    rows = []
    for a, links in by_node.items():  # a: the node's label, as in the edge labels
        if len(links) < 2 or (degree is not None and degree.get(a) != len(links)):
            continue  # not every out-link of the node was measured: the rule says nothing
        if (n[:, links] == 0).any():
            continue
        means = (total[:, links] / n[:, links]).sum(axis=1)  # per block: the sum of link means
        weights = n[:, links].min(axis=1)
        value = float(np.average(means, weights=weights))
        se = float(np.sqrt(np.average((means - value) ** 2, weights=weights) / (len(means) - 1)))
        low, high = value - z * se, value + z * se
        # each link's root mean square over the realizations: sqrt(sum x^2 / n)
        rms = np.sqrt(squares[:, links].sum(axis=0) / n[:, links].sum(axis=0))
        row = {
            "graph": view.graph,
            "node": a,
            "links": [str(view.edges[e]) for e in links],
            "sum": value,
            "low": low,
            "high": high,
            "rounding": rounding_bound(rms),
            "resolved": False,
        }
        row.update(_tau_sum(rec[:, links], z))
        rows.append(row)
    # the rows' decisions at the family-wise level: z of 1 - (1 - level) / rows
    z_all = NormalDist().inv_cdf(1 - (1 - level) / (2 * max(len(rows), 1)))
    for row in rows:
        row["resolved"] = _away(row["sum"], row["low"], row["high"], z, z_all, row["rounding"])
        # resolved from 0 by its interval alone, but within rounding: said in the summary's note
        row["rounding_only"] = not row["resolved"] and _away(row["sum"], row["low"], row["high"], z, z_all)
        if row["tau_sum"] is not None:
            row["tau_resolved"] = _away(
                row["tau_sum"], row["tau_low"], row["tau_high"], z, z_all, row["tau_rounding"]
            )
    return rows


def rounding_bound(scales) -> float:
    """``ROUNDING_ULPS * eps * sum(scales)``: how far from 0 floating point may leave a sum
    whose exact value is 0, its terms of sizes ``scales`` (see the module's docstring)."""
    total = float(np.sum(np.abs(np.asarray(scales, dtype=float))))
    return ROUNDING_ULPS * EPS * total if math.isfinite(total) else 0.0


def _away(value: float, low: float, high: float, z: float, z_all: float, rounding: float = 0.0) -> bool:
    """Whether ``value`` (with interval ``low`` .. ``high`` at quantile ``z``) is more than
    ``z_all`` of its standard errors from 0, and its interval at ``z_all`` (``value -/+ z_all
    se``) lies wholly beyond the rounding bound ``rounding`` of 0: a sum that rounding could
    leave is no violation, however narrow its interval."""
    se = (high - low) / (2 * z)
    if not (math.isfinite(se) and math.isfinite(value)):
        return False
    return bool(abs(value) > z_all * se and abs(value) - z_all * se > rounding)


def _tau_sum(rec: np.ndarray, z: float) -> dict:
    """The same rule for Lambda^tau (``tau_sum``, ``tau_low``, ``tau_high``, ``tau_resolved``):
    per block the sum of the links' ratios ``-sum_slope_tau / sum_tau0``, with batch means;
    None where the records predate its fields."""
    none = {"tau_sum": None, "tau_low": None, "tau_high": None, "tau_rounding": None, "tau_resolved": None}
    if rec.shape[-1] <= 9:
        return none
    slope, tau0 = rec[:, :, 8], rec[:, :, 9]
    if not (np.isfinite(slope).all() and np.isfinite(tau0).all()) or (tau0 <= 0).any():
        return none
    value = float((-slope.sum(axis=0) / tau0.sum(axis=0)).sum())
    per_block = (-slope / tau0).sum(axis=1)
    se = float(per_block.std(ddof=1) / math.sqrt(len(per_block)))
    low, high = value - z * se, value + z * se
    # the terms' sizes: each link's largest block ratio (no per-realization squares are kept)
    rounding = rounding_bound(np.abs(slope / tau0).max(axis=0))
    return {
        "tau_sum": value,
        "tau_low": low,
        "tau_high": high,
        "tau_rounding": rounding,
        "tau_resolved": False,
    }


def views_sums(views) -> list[dict]:
    """:func:`node_sums` of every job of a decoded result file, each with its own coupling."""
    rows = []
    for view in views:
        rows += node_sums(view, str((view.attrs or {}).get("coupling", "normalized")))
    return rows


def _out_degrees(view) -> dict | None:
    """Out-degree of every node from the job's weights (None when the view has none)."""
    if view.omega is None or view.nodes is None:
        return None
    omega = np.asarray(view.omega)
    return {str(v): int((omega[i] > 0).sum()) for i, v in enumerate(view.nodes)}


def sum_rule_note(rows: list[dict], quantity: str | None = None) -> str | None:
    """One line for a summary: how many nodes were checked, and the nodes whose sum is resolved
    away from 0 with what that means (None when no node could be checked)."""
    if not rows:
        return None
    bad = [r for r in rows if r["resolved"]]
    head = (
        "sum rule (normalized coupling: a node's out-links sum to 0 for the derivative): "
        f"{len(rows)} node(s) checked"
    )
    taus = [r for r in rows if r.get("tau_sum") is not None]
    tau_part = ""
    if taus:
        off = sum(1 for r in taus if r["tau_resolved"])
        tau_part = f"; Lambda^tau: {len(taus) - off} of {len(taus)} sums consistent with 0"
    rounding = [r for r in rows if r.get("rounding_only")]
    if rounding:  # say that (and how) rounding-level sums were judged, rather than hide them
        head += (
            f" ({len(rounding)} within floating-point rounding of 0: "
            f"|sum| <= 2^20 eps x the links' rms Lambda)"
        )
    if not bad:
        return head + ", every sum consistent with 0 (95% over the nodes checked)" + tau_part
    shown = "; ".join(
        f"{r['graph']} node {r['node']}: {r['sum']:+.4g} [{r['low']:+.3g}, {r['high']:+.3g}]" for r in bad[:5]
    )
    more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
    what = (
        "expected of the paper's forward secant, which is not the derivative near saddle passages "
        "(use lambda.method central-difference or adjoint-hybrid for the derivative)"
        if quantity == "forward-secant"
        else "these values are not derivatives within their errors: check the estimator and dbeta"
    )
    return f"{head}; resolved away from 0 at {shown}{more}: {what}{tau_part}"
