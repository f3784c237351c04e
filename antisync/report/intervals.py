"""Intervals drawn as intervals: a segment from the interval's low end to its high end.

The tail model's interval of Lambda^KM (:func:`antisync.stats.estimators.lambda_ci`) is not centred
on the estimate, and may not even contain it (a heavy tail pulls the mean outside the
interval the tail model gives). Error bars as ``estimate - low`` and ``high - estimate`` would
then be negative lengths (matplotlib refuses them) or, clipped, draw an interval that is not
the record's. Every figure therefore draws the segment ``[low, high]`` itself, beside the
point of the estimate, with :func:`draw_intervals`.
"""

from __future__ import annotations

import numpy as np

from antisync.stats.estimators import Z95

__all__ = ["draw_intervals", "interval_segments", "record_intervals"]


def interval_segments(position, low, high) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(position, low, high)`` of the intervals that can be drawn.

    Parameters
    ----------
    position, low, high : array_like
        One entry per interval: where it stands (x of a vertical segment, y of a horizontal
        one) and its two ends. ``None`` and NaN mean "no interval".

    Returns
    -------
    tuple of ndarray
        The entries whose three values are finite, each with ``low <= high`` (the ends are
        taken as given, never moved towards an estimate; a reversed pair is put in order).
    """
    pos, lo, hi = (
        np.array([np.nan if v is None else v for v in np.ravel(a)], dtype=float)
        for a in (position, low, high)
    )
    ok = np.isfinite(pos) & np.isfinite(lo) & np.isfinite(hi)
    lo, hi = lo[ok], hi[ok]
    return pos[ok], np.minimum(lo, hi), np.maximum(lo, hi)


def draw_intervals(ax, position, low, high, *, horizontal: bool = False, **style):
    """Draw each interval ``[low, high]`` as a segment at ``position`` on ``ax``.

    Vertical segments (``ax.vlines``: ``position`` is x, the interval runs along y) by
    default; ``horizontal=True`` draws ``ax.hlines`` (``position`` is y). Entries without a
    finite interval are skipped (see :func:`interval_segments`). ``style`` goes to matplotlib.
    Returns the LineCollection, or ``None`` when nothing was drawn.
    """
    pos, lo, hi = interval_segments(position, low, high)
    if not pos.size:
        return None
    draw = ax.hlines if horizontal else ax.vlines
    return draw(pos, lo, hi, **style)


def record_intervals(records: list[dict], key: str) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)``: the 95% interval of each record's ``key`` (NaN where it has none).

    A record's own ``<key>_ci_low`` .. ``<key>_ci_high`` when it has them (Lambda^KM: the tail
    model's interval, not centred on the estimate), else the normal interval
    ``value -/+ 1.96 <key>_se`` of a measure that carries only a standard error
    (Lambda^(linear), Lambda^(KM-NNC)); NaN for an exact measure and a missing value.
    """
    low = np.full(len(records), np.nan)
    high = np.full(len(records), np.nan)
    for i, r in enumerate(records):
        lo, hi = r.get(f"{key}_ci_low"), r.get(f"{key}_ci_high")
        value, se = r.get(key), r.get(f"{key}_se")
        if lo is not None and hi is not None:
            low[i], high[i] = lo, hi
        elif value is not None and se is not None and np.isfinite(se) and se >= 0:
            low[i], high[i] = value - Z95 * se, value + Z95 * se
    return low, high
