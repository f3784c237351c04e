"""Sign calls that survive many links: the false discovery rate over a run's links.

A run over E links that calls each sign at 95% calls about E/20 null links "resolved" by
chance: a 12-ring run flagged 7->6 where symmetry makes Lambda 0, and the largest of 40 noisy
estimates of an IEEE 14 run shrank from 0.033 to 0.0115 at six times the realizations.
:func:`fdr_signs` calls the signs with the Benjamini-Hochberg procedure at level ``q`` over the
run's distinct links instead: among the links it calls, the expected fraction of false calls is
at most ``q`` (under independence or positive dependence of the links' estimates, which links
measured on common initial phases have).

Each link's two-sided p-value is read off its Lambda^KM interval (``lambda_km_ci_low`` ..
``lambda_km_ci_high`` at ``lambda_km_ci_level``) as a normal interval: centre ``(lo + hi)/2``,
standard error ``(hi - lo)/(2 z)``. It reproduces the interval's own decision at its level (a
95% interval excludes 0 exactly when p < 0.05), so with one link the rule is the per-link one.
Pure: records in, signs out.
"""

from __future__ import annotations

import math
from statistics import NormalDist

__all__ = ["FDR_LEVEL", "SIGN_RULE", "benjamini_hochberg", "fdr_signs", "link_key", "p_value"]

#: the false discovery rate of the sign calls of ``antisync summary`` and the report
FDR_LEVEL = 0.05
#: how the records' ``sign_resolved`` is decided, as the summary says it
SIGN_RULE = f"Benjamini-Hochberg false discovery rate {FDR_LEVEL:g} over the file's links"


def p_value(low: float, high: float, level: float = 0.95) -> float:
    """Two-sided p-value of ``Lambda = 0`` from an interval ``[low, high]`` at ``level``, read as
    a normal interval (1.0 for a degenerate or missing one)."""
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return 1.0
    z_level = NormalDist().inv_cdf((1 + level) / 2)
    se = (high - low) / (2 * z_level)
    centre = (low + high) / 2
    if se <= 0:
        return 0.0 if centre != 0 else 1.0
    return 2.0 * (1.0 - NormalDist().cdf(abs(centre) / se))


def benjamini_hochberg(pvalues, q: float = FDR_LEVEL) -> list[bool]:
    """Which of ``pvalues`` the Benjamini-Hochberg step-up procedure at level ``q`` calls: those
    up to the largest rank ``k`` with ``p_(k) <= k q / m`` (NaN counts as 1)."""
    p = [1.0 if p is None or not math.isfinite(p) else float(p) for p in pvalues]
    order = sorted(range(len(p)), key=p.__getitem__)
    cut = 0
    for k, i in enumerate(order, start=1):
        if p[i] <= k * q / len(p):
            cut = k
    called = [False] * len(p)
    for i in order[:cut]:
        called[i] = True
    return called


def link_key(record: dict) -> tuple:
    """The link a record's Lambda^KM belongs to: its job (graph, threshold, repeat, stage, the
    grid point of a grid sweep) and edge; the beta rows of one link share one Lambda."""
    return tuple(record.get(k) for k in ("graph", "threshold", "repeat", "stage", "point", "edge"))


def fdr_signs(records: list[dict], q: float = FDR_LEVEL) -> list[int | None]:
    """``sign_resolved`` of each record under the Benjamini-Hochberg procedure at level ``q``.

    Returns, aligned with ``records``: ``+1`` (antifragile) or ``-1`` (fragile) for a link the
    procedure calls, ``0`` for one it does not, ``None`` for a record without Lambda^KM. The
    family is the distinct links (:func:`link_key`) that have an interval.
    """
    pvals: dict[tuple, tuple[float, int]] = {}
    for r in records:
        if r.get("lambda_km") is None:
            continue
        lo, hi = r.get("lambda_km_ci_low"), r.get("lambda_km_ci_high")
        level = r.get("lambda_km_ci_level") or 0.95
        p = p_value(lo, hi, level)
        sign = 0 if lo is None or hi is None else (1 if lo + hi > 0 else -1)
        pvals.setdefault(link_key(r), (p, sign))
    keys = list(pvals)
    called = {
        key for key, c in zip(keys, benjamini_hochberg([pvals[k][0] for k in keys], q), strict=True) if c
    }
    out: list[int | None] = []
    for r in records:
        if r.get("lambda_km") is None:
            out.append(None)
            continue
        key = link_key(r)
        out.append(pvals[key][1] if key in called else 0)
    return out
