"""The budget set of a design and the Euclidean projection onto it.

A design chooses one weight ``x_l`` per undirected link ``l`` (an existing link, or a
candidate that is absent at ``x_l = 0``). The feasible set is

    B = { x : lo_l <= x_l <= hi_l,  sum_l c_l x_l = budget }

with costs ``c_l > 0``: the budget is spent, not merely bounded (with normalized coupling,
Eq. 1, the dynamics do not change when every weight is scaled by one factor, so the budget
fixes the scale at which the bounds are read; with raw coupling it is the total coupling).
``lo_l >= 0``; ``lo_l = 0`` lets a design remove a link.

:func:`project` is the Euclidean projection onto ``B``: ``x = clip(y - mu c, lo, hi)`` with the
one ``mu`` at which the budget holds, found exactly on the piecewise-linear budget curve.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from antisync.errors import ConfigError

__all__ = ["Budget", "project"]


class Budget(NamedTuple):
    """The feasible set ``{lo <= x <= hi, cost . x = total}`` of one design."""

    total: float
    """The budget ``sum_l c_l x_l``."""
    cost: np.ndarray
    """float64 (L,): ``c_l > 0`` per design variable."""
    lo: np.ndarray
    """float64 (L,): lower bounds, ``>= 0``."""
    hi: np.ndarray
    """float64 (L,): upper bounds, ``>= lo`` (``inf`` allowed)."""

    @classmethod
    def of(cls, total, size: int, *, cost=1.0, lo=0.0, hi=np.inf) -> Budget:
        """A budget over ``size`` variables, checked: one clear :class:`ConfigError` if empty.

        ``cost``, ``lo`` and ``hi`` are scalars or arrays of length ``size``.
        """
        total = float(total)
        if not np.isfinite(total) or total <= 0:
            raise ConfigError(f"design.budget must be a positive number, got {total!r}")
        cost = np.broadcast_to(np.asarray(cost, dtype=float), (size,)).copy()
        lo = np.broadcast_to(np.asarray(lo, dtype=float), (size,)).copy()
        hi = np.broadcast_to(np.asarray(hi, dtype=float), (size,)).copy()
        if size < 1:
            raise ConfigError("a design needs at least one link to weigh")
        if not np.all(np.isfinite(cost)) or np.any(cost <= 0):
            raise ConfigError("design costs must be positive finite numbers")
        if not np.all(np.isfinite(lo)) or np.any(lo < 0):
            raise ConfigError("design.lower must be a finite number >= 0 (0 lets a link be removed)")
        if np.any(np.isnan(hi)) or np.any(hi < lo):
            raise ConfigError("design.upper must be >= design.lower for every link")
        least, most = float(cost @ lo), float(np.sum(cost * hi))
        if not least <= total * (1 + 1e-12) or not total <= most * (1 + 1e-12):
            raise ConfigError(
                f"design.budget {total:g} is outside what the bounds allow "
                f"([{least:g}, {most:g}] = sum of cost x lower .. cost x upper): no weights "
                "satisfy both; change the budget or the bounds"
            )
        return cls(total, cost, lo, hi)

    def contains(self, x: np.ndarray, rtol: float = 1e-9) -> bool:
        """Whether ``x`` is in the set (bounds exact, budget to ``rtol``)."""
        x = np.asarray(x, dtype=float)
        return bool(
            np.all(x >= self.lo)
            and np.all(x <= self.hi)
            and abs(self.cost @ x - self.total) <= rtol * self.total
        )

    def uniform(self) -> np.ndarray:
        """The feasible point closest to equal weights: the projection of a constant vector."""
        return project(np.full(self.cost.size, self.total / self.cost.sum()), self)


def project(y: np.ndarray, budget: Budget) -> np.ndarray:
    """Euclidean projection of ``y`` onto ``budget``'s set (exact up to rounding), ``O(L log L)``.

    ``x(mu) = clip(y - mu c, lo, hi)`` and ``g(mu) = c . x(mu)`` is continuous, piecewise
    linear and non-increasing; its breakpoints are where a coordinate meets a bound. ``g`` is
    evaluated at every breakpoint at once (sorted breakpoints and cumulative sums), the segment
    that holds ``g = total`` is found among them and ``mu`` solved on it, so the result
    satisfies the budget to rounding whatever the scale of ``y`` (about 1 ms at L = 4,950).
    """
    y = np.asarray(y, dtype=float)
    c, lo, hi, total = budget.cost, budget.lo, budget.hi, budget.total
    if y.shape != c.shape or not np.all(np.isfinite(y)):
        raise ValueError(f"project needs a finite vector of length {c.size}, got {y.shape}")
    c2 = c * c
    base = float(c @ lo)
    # coordinate i is at hi for mu <= u_i, free between, at lo for mu >= l_i:
    # g(mu) = base + sum_{l_i > mu} c_i (y_i - lo_i - mu c_i) - sum_{u_i > mu} c_i (y_i - hi_i - mu c_i)
    lb = (y - lo) / c
    finite_hi = np.isfinite(hi)
    ub = (y[finite_hi] - hi[finite_hi]) / c[finite_hi]
    ol = np.argsort(lb)
    lb_s = lb[ol]
    al = np.concatenate([np.cumsum((c * (y - lo))[ol][::-1])[::-1], [0.0]])
    bl = np.concatenate([np.cumsum(c2[ol][::-1])[::-1], [0.0]])
    ou = np.argsort(ub)
    ub_s = ub[ou]
    au = np.concatenate([np.cumsum((c[finite_hi] * (y[finite_hi] - hi[finite_hi]))[ou][::-1])[::-1], [0.0]])
    bu = np.concatenate([np.cumsum(c2[finite_hi][ou][::-1])[::-1], [0.0]])

    def spent(mu):
        kl = np.searchsorted(lb_s, mu, side="right")
        ku = np.searchsorted(ub_s, mu, side="right")
        return base + (al[kl] - mu * bl[kl]) - (au[ku] - mu * bu[ku])

    points = np.unique(np.concatenate([lb, ub]))
    values = spent(points)
    right = int(np.searchsorted(-values, -total, side="left"))
    if right == 0:
        left_mu, right_mu = points[0] - 1.0, points[0]
    elif right == points.size:
        left_mu, right_mu = points[-1], points[-1] + 1.0
    else:
        left_mu, right_mu = points[right - 1], points[right]
    mid = 0.5 * (left_mu + right_mu)
    free = (y - mid * c > lo) & (y - mid * c < hi)
    if not np.any(free):
        mu = mid
    else:
        fixed = np.clip(y - mid * c, lo, hi)
        mu = (float(c[free] @ y[free]) + float(c[~free] @ fixed[~free]) - total) / float(c[free] @ c[free])
    return np.clip(y - mu * c, lo, hi)
