"""Text labels that do not overlap: each is pushed off the others and off fixed points.

Fig. 1a writes a value on every arrow and Fig. 7e names every point; where arrows or points
crowd (the triangle of the lollipop, 4->5 beside 4->6) their labels would print over each
other. :func:`spread_labels` moves them apart in display coordinates after the figure's layout
is fixed, so each label stays next to what it names.
"""

from __future__ import annotations

import numpy as np

__all__ = ["spread_labels"]


def spread_labels(ax, texts, fixed_xy=(), fixed_px: float = 0.0, steps: int = 200) -> None:
    """Move overlapping ``texts`` apart (and off the ``fixed_xy`` points, circles of
    ``fixed_px`` pixels): each overlapping pair is pushed apart along the axis where it overlaps
    less, in display coordinates, until none overlaps or ``steps`` passes are done. Call it
    once the axes' limits and size are fixed; the texts keep their new data positions."""
    if not texts:
        return
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    to_px, to_data = ax.transData, ax.transData.inverted()
    centre = np.array([to_px.transform(t.get_position()) for t in texts])
    size = np.array([[b.width, b.height] for b in (t.get_window_extent(renderer) for t in texts)]) + 3.0
    anchors = np.array([to_px.transform(p) for p in fixed_xy]).reshape(-1, 2)
    for _ in range(steps):
        push = np.zeros_like(centre)
        moved = False
        for i in range(len(texts)):
            for j in range(i + 1, len(texts)):
                gap = centre[j] - centre[i]
                over = (size[i] + size[j]) / 2 - np.abs(gap)
                if np.all(over > 0):
                    moved = True
                    axis = int(np.argmin(over / size[i]))  # the cheaper way out
                    way = np.sign(gap[axis]) or 1.0
                    push[i, axis] -= way * (over[axis] / 2 + 0.5)
                    push[j, axis] += way * (over[axis] / 2 + 0.5)
            for p in anchors:
                gap = centre[i] - p
                over = size[i] / 2 + fixed_px - np.abs(gap)
                if np.all(over > 0):
                    moved = True
                    axis = int(np.argmin(over))
                    push[i, axis] += (np.sign(gap[axis]) or 1.0) * (over[axis] + 0.5)
        if not moved:
            break
        centre += 0.5 * push
    for t, c in zip(texts, centre, strict=True):
        t.set_position(to_data.transform(c))
