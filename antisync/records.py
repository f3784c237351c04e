"""Summary records of decoded jobs, with or without a Kuramoto run, and how to list many.

:func:`antisync.summary.job_records` computes records from a job's statistics blocks. A job run
without ``km`` (``measures: [xi2, rw]``) integrated nothing and has no blocks; its records here
keep every key of a Kuramoto record, so tables and CSV files of mixed files share one set of
columns, with

- the Kuramoto values (``F_mean``, ``lambda_km``, its interval, ``tau0_mean``, ...) ``None``,
  the counts ``n``, ``realizations_done`` and ``realizations`` 0;
- the Kuramoto estimator's description (``lambda_method``, ``lambda_dbeta``,
  ``lambda_km_ci_level``, ``lambda_km_ci_method``) and warning ``None``;
- ``complete`` true once its measures are computed (they are written with the job).

:func:`sort_records` and :func:`flag_signs` order and flag the records of a graph with
hundreds of links (``antisync summary --sort``, the large-graph report). Pure: no file.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

from antisync.errors import AntisyncError
from antisync.summary import JobView, sign_resolved
from antisync.summary import job_records as _kuramoto_records
from antisync.summary import view_records as _kuramoto_view_records

__all__ = [
    "MEASURE_KEYS",
    "SORT_KEYS",
    "SortKey",
    "flag_signs",
    "is_kuramoto",
    "job_records",
    "primary_measure",
    "sort_records",
    "view_records",
]

SortKey = Literal["lambda", "km", "xi2", "rw", "linear", "km_nnc"]
"""What ``antisync summary --sort`` orders by: ``lambda`` is :func:`primary_measure`."""
SORT_KEYS: tuple[SortKey, ...] = get_args(SortKey)
#: record key of each measure, in the order :func:`primary_measure` prefers them
MEASURE_KEYS = {
    "km": "lambda_km",
    "xi2": "lambda_xi2",
    "rw": "lambda_rw",
    "linear": "lambda_linear",
    "km_nnc": "lambda_km_nnc",
}
# describe the Kuramoto estimator; meaningless where it did not run
_ESTIMATOR_KEYS = (
    "lambda_km_warning",
    "lambda_km_ci_level",
    "lambda_km_ci_method",
    "lambda_method",
    "lambda_dbeta",
)


def is_kuramoto(view: JobView) -> bool:
    """Whether ``view``'s job integrated the Kuramoto model: a job without ``km`` in its
    measures has no statistics blocks (a Kuramoto run has at least one realization)."""
    return view.done.size > 0


def job_records(view: JobView) -> list[dict]:
    """:func:`antisync.summary.job_records`, also for a job run without ``km``."""
    recs = _kuramoto_records(view)
    return recs if is_kuramoto(view) else [_exact_only(r) for r in recs]


def view_records(views: list[JobView]) -> list[dict]:
    """:func:`antisync.summary.view_records` (``lambda_km_nnc`` joined from twins), also for
    jobs run without ``km``."""
    exact = {v.graph for v in views if not is_kuramoto(v)}
    return [_exact_only(r) if r["graph"] in exact else r for r in _kuramoto_view_records(views)]


def _exact_only(rec: dict) -> dict:
    out = dict(rec)
    for key in _ESTIMATOR_KEYS:
        if key in out:
            out[key] = None
    out["realizations"] = out["realizations_done"] = 0
    out["complete"] = True
    return out


def primary_measure(records: list[dict]) -> str | None:
    """The record key that says most about the links: ``lambda_km`` when some record has it,
    else ``lambda_xi2``, ``lambda_rw``, ``lambda_linear`` (``None`` when no record has any)."""
    for key in MEASURE_KEYS.values():
        if any(_value(r, key) is not None for r in records):
            return key
    return None


def sort_records(records: list[dict], by: str) -> list[dict]:
    """``records`` ordered by a measure, largest (most antifragile) first.

    Parameters
    ----------
    by : {"lambda", "km", "xi2", "rw", "linear", "km_nnc"}
        ``lambda``: :func:`primary_measure`; otherwise the measure of that name.

    Returns
    -------
    list of dict
        A new list; records without the value keep their order, after the others. The sort
        is stable: the records of one link (one per beta) stay together, in beta order.

    Raises
    ------
    AntisyncError
        ``by`` is not a measure, or no record has it (one line naming what the records have).
    """
    if by not in SORT_KEYS:
        raise AntisyncError(f"cannot sort by {by!r}: give one of {', '.join(SORT_KEYS)}")
    key = primary_measure(records) if by == "lambda" else MEASURE_KEYS[by]
    if key is None or not any(_value(r, key) is not None for r in records):
        have = [m for m, k in MEASURE_KEYS.items() if any(_value(r, k) is not None for r in records)]
        raise AntisyncError(
            f"cannot sort by {by}: no record has {key or 'a measure'}; "
            + (f"these records have {', '.join(have)}" if have else "the file holds no records")
        )
    with_value = [r for r in records if _value(r, key) is not None]
    without = [r for r in records if _value(r, key) is None]
    return sorted(with_value, key=lambda r: -_value(r, key)) + without


def flag_signs(records: list[dict]) -> list[dict]:
    """Copies of ``records``, each with ``sign_resolved``: ``+1`` (antifragile), ``-1``
    (fragile) or ``0`` (unresolved) from :func:`antisync.summary.sign_resolved` (the record's
    ``lambda_km_ci_low`` .. ``lambda_km_ci_high`` interval); ``None`` where no Lambda^KM was
    estimated (a file run without ``km``)."""
    return [
        {**r, "sign_resolved": sign_resolved(r) if r.get("lambda_km") is not None else None} for r in records
    ]


def _value(rec: dict, key: str) -> float | None:
    x = rec.get(key)
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)
