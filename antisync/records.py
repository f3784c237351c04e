"""How to list the records of a graph with hundreds of links: :func:`sort_records` and
:func:`flag_signs` order and flag them (``antisync summary --sort``, the large-graph report).
Pure: no file. The records themselves come from :func:`antisync.summary.job_records`.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

from antisync.errors import AntisyncError
from antisync.summary import sign_resolved

__all__ = [
    "MEASURE_KEYS",
    "SORT_KEYS",
    "SortKey",
    "flag_signs",
    "primary_measure",
    "sort_records",
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
