"""Exact tests of counts: the Clopper-Pearson interval of a binomial proportion, McNemar's exact
test of a paired change, and the normal p-value of a mean change with its standard error.

The dynamic line removal of a power grid (:mod:`antisync.grids.removal`, docs/power_grids.md)
reports its ``P_sync`` before and after, and their paired change, with these. Pure: counts in,
numbers out.
"""

from __future__ import annotations

import math

__all__ = ["clopper_pearson", "mcnemar_exact", "tau_p_value"]


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a binomial proportion ``k / n`` at ``level``:
    the ``(1 - level)/2`` and ``(1 + level)/2`` quantiles of ``Beta(k, n - k + 1)`` and
    ``Beta(k + 1, n - k)`` (0 for ``k = 0``, 1 for ``k = n``). ``(nan, nan)`` for ``n = 0``."""
    # scipy.stats costs a noticeable fraction of a second to import: only when an interval is asked
    from scipy.stats import beta

    if n == 0:
        return math.nan, math.nan
    if not 0 <= k <= n:
        raise ValueError(f"k must lie in [0, n], got k={k}, n={n}")
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def mcnemar_exact(lost: int, gained: int, n: int, level: float = 0.95) -> tuple[float, float, float]:
    """McNemar's exact test of a paired change of ``P_sync`` and its conditional interval.

    Conditional on the ``d = lost + gained`` discordant pairs, ``gained ~ Binomial(d, q)``; no
    change is ``q = 1/2``. Returns ``(p_value, low, high)``: the two-sided exact p-value
    (``scipy.stats.binomtest``; 1 when ``d = 0``) and the interval ``(d / n)(2 q - 1)`` of the
    change ``(gained - lost) / n`` at the ends of ``q``'s Clopper-Pearson interval."""
    # scipy.stats: imported on first use, as in clopper_pearson
    from scipy.stats import binomtest

    d = lost + gained
    if d == 0:
        return 1.0, 0.0, 0.0
    p = float(binomtest(gained, d, 0.5).pvalue)
    q_lo, q_hi = clopper_pearson(gained, d, level)
    return p, d / n * (2 * q_lo - 1), d / n * (2 * q_hi - 1)


def tau_p_value(d_tau: float | None, se: float | None) -> float:
    """Two-sided p-value of "``d_tau = 0``" (normal, from ``d_tau`` and its standard error; 1
    where there is no error)."""
    if d_tau is None or se is None or not (math.isfinite(se) and se > 0 and math.isfinite(d_tau)):
        return 1.0
    return math.erfc(abs(d_tau) / se / math.sqrt(2.0))
