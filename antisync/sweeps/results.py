"""A sweep's result file for its readers: the store's decoding, then the pure analysis."""

from __future__ import annotations

from pathlib import Path

from antisync.errors import StoreError
from antisync.sweeps.analysis import summarize

__all__ = ["sweep_summary"]


def sweep_summary(path: str | Path, views=None) -> dict:
    """Everything a report needs from a sweep file: :func:`~antisync.sweeps.analysis.summarize`
    of its metadata and jobs.

    Parameters
    ----------
    path : str or Path
        A sweep's result file (a run's file is a :class:`~antisync.errors.StoreError`).
    views : list of JobView, optional
        The file's jobs when already read (:func:`antisync.store.read_views`).

    Returns
    -------
    dict
        See :func:`antisync.sweeps.analysis.summarize`.
    """
    # lazy: loads numba, which reading a sweep config (`import antisync.sweeps`) does not need
    from antisync.store import read_meta, read_views

    meta = read_meta(path)
    views = views if views is not None else read_views(path)
    try:
        return summarize(meta, views)
    except StoreError as exc:  # a file that cannot be read as it is: say which
        raise StoreError(f"{path}: {exc}") from None
