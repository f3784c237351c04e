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
records' level. Pure: a :class:`antisync.summary.JobView` in, rows out.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

__all__ = ["SUM_RULE_LEVEL", "node_sums", "sum_rule_note", "views_sums"]

#: level of the sum rule's interval (the records' level)
SUM_RULE_LEVEL = 0.95


def node_sums(view, coupling: str = "normalized", level: float = SUM_RULE_LEVEL) -> list[dict]:
    """``sum_b Lambda(a -> b)`` for every node ``a`` whose out-links are all in ``view``.

    Parameters
    ----------
    view : antisync.summary.JobView
        One decoded job with Lambda block records (``lam_rec``).
    coupling : {"normalized", "raw"}
        The job's coupling: the rule holds for normalized coupling only, so ``raw`` gives [].
    level : float
        Level of each sum's interval.

    Returns
    -------
    list of dict
        ``{"graph", "node", "links", "sum", "low", "high", "resolved"}`` and the same for
        Lambda^tau (``tau_sum``, ``tau_low``, ``tau_high``, ``tau_resolved``) per node with at least
        two out-links (a node with one has ``W`` fixed by normalization: its link's Lambda is 0
        by construction), in node order. ``low`` .. ``high`` is the interval at ``level``;
        ``resolved`` is True when the sum is away from 0 at ``level`` over all the rows at once
        (Bonferroni: each at ``1 - (1 - level) / rows``), so that checking many nodes does not
        find a broken rule by chance.
    """
    if coupling != "normalized" or view.lam_rec is None or not len(view.edges):
        return []
    done = np.asarray(view.done, dtype=bool)
    rec = np.asarray(view.lam_rec)[done]  # (blocks, E, fields): n, ..., sum, sum2
    if rec.shape[0] < 2:
        return []
    n, total = rec[:, :, 0], rec[:, :, 3]
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
        row = {
            "graph": view.graph,
            "node": a,
            "links": [str(view.edges[e]) for e in links],
            "sum": value,
            "low": low,
            "high": high,
            "resolved": False,
        }
        row.update(_tau_sum(rec[:, links], z))
        rows.append(row)
    # the rows' decisions at the family-wise level: z of 1 - (1 - level) / rows
    z_all = NormalDist().inv_cdf(1 - (1 - level) / (2 * max(len(rows), 1)))
    for row in rows:
        row["resolved"] = _away(row["sum"], row["low"], row["high"], z, z_all)
        if row["tau_sum"] is not None:
            row["tau_resolved"] = _away(row["tau_sum"], row["tau_low"], row["tau_high"], z, z_all)
    return rows


def _away(value: float, low: float, high: float, z: float, z_all: float) -> bool:
    """Whether ``value`` (with interval ``low`` .. ``high`` at quantile ``z``) is more than
    ``z_all`` of its standard errors from 0."""
    se = (high - low) / (2 * z)
    return bool(math.isfinite(se) and abs(value) > z_all * se)


def _tau_sum(rec: np.ndarray, z: float) -> dict:
    """The same rule for Lambda^tau (``tau_sum``, ``tau_low``, ``tau_high``, ``tau_resolved``):
    per block the sum of the links' ratios ``-sum_slope_tau / sum_tau0``, with batch means;
    None where the records predate its fields."""
    none = {"tau_sum": None, "tau_low": None, "tau_high": None, "tau_resolved": None}
    if rec.shape[-1] <= 9:
        return none
    slope, tau0 = rec[:, :, 8], rec[:, :, 9]
    if not (np.isfinite(slope).all() and np.isfinite(tau0).all()) or (tau0 <= 0).any():
        return none
    value = float((-slope.sum(axis=0) / tau0.sum(axis=0)).sum())
    per_block = (-slope / tau0).sum(axis=1)
    se = float(per_block.std(ddof=1) / math.sqrt(len(per_block)))
    low, high = value - z * se, value + z * se
    return {"tau_sum": value, "tau_low": low, "tau_high": high, "tau_resolved": False}


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
