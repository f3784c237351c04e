"""How to list the records of a graph with hundreds of links: :func:`sort_records` and
:func:`flag_signs` order and flag them (``antisync summary --sort``, the large-graph report).
Pure: no file. The records themselves come from :func:`antisync.stats.summary.job_records`.
"""

from __future__ import annotations

import math
from typing import Literal, get_args

from antisync.errors import AntisyncError
from antisync.stats.multiplicity import FDR_LEVEL, fdr_signs, link_key
from antisync.stats.summary import sign_resolved

__all__ = [
    "MEASURE_KEYS",
    "absence_reason",
    "SORT_KEYS",
    "SortKey",
    "flag_signs",
    "sign_rule_note",
    "primary_measure",
    "sort_records",
    "sortable",
    "why_absent",
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
        ``by`` is not a measure, or no record has it (one line saying why, see
        :func:`why_absent`, and which ``--sort`` values the records support).
    """
    if by not in SORT_KEYS:
        raise AntisyncError(f"cannot sort by {by!r}: give one of {', '.join(SORT_KEYS)}")
    key = primary_measure(records) if by == "lambda" else MEASURE_KEYS[by]
    if key is None or not any(_value(r, key) is not None for r in records):
        raise AntisyncError(f"cannot sort by {by}: {why_absent(records, key)}")
    with_value = [r for r in records if _value(r, key) is not None]
    without = [r for r in records if _value(r, key) is None]
    return sorted(with_value, key=lambda r: -_value(r, key)) + without


def sortable(records: list[dict]) -> list[str]:
    """The ``--sort`` values that order ``records``: each measure some record has, and
    ``lambda`` when there is one."""
    have = [m for m, k in MEASURE_KEYS.items() if any(_value(r, k) is not None for r in records)]
    return (["lambda"] if have else []) + have


def why_absent(records: list[dict], key: str | None) -> str:
    """One line: no record of ``records`` has ``key`` (a :data:`MEASURE_KEYS` value; ``None``:
    no measure at all), which measures and ``--sort`` values they have instead, and why
    (:func:`absence_reason`)."""
    if not records:
        return "the file holds no records"
    why = absence_reason(records, key)
    if key is None:
        return f"no record has a measure, so no --sort applies; {why}"
    ok = sortable(records)
    have = (
        f"; these records have {', '.join(ok[1:])} (--sort {', '.join(ok)})"
        if ok
        else " nor any other measure, so no --sort applies"
    )
    return f"no record has {key}{have}; {why}"


def absence_reason(records: list[dict], key: str | None) -> str:
    """Why no record of ``records`` has ``key`` (``None``: any measure): Lambda^KM undefined
    (nothing synchronized, nothing done) or not computed, a measure not asked for."""
    if not records:
        return "the file holds no records"
    if key is None or key == "lambda_km":
        return "; ".join(dict.fromkeys(_why_no_km(r) for r in records))
    if key == "lambda_km_nnc":
        if any(_value(r, "lambda_km") is not None for r in records):
            return "the run has no raw-coupling twin: add km_nnc to measures"
        return "; ".join(dict.fromkeys(_why_no_km(r) for r in records))
    name = next(m for m, k in MEASURE_KEYS.items() if k == key)
    return f"{name} is not among the run's measures, or is not finite on this graph"


def _why_no_km(rec: dict) -> str:
    """Why ``rec`` has no Lambda^KM: no Kuramoto run, nothing done, or nothing synchronized."""
    graph = rec.get("graph", "the graph")
    if not rec.get("realizations"):
        return f"{graph} was run without km: it holds exact measures only"
    done, p_sync, synced = rec.get("realizations_done") or 0, rec.get("p_sync"), rec.get("tau0_n") or 0
    if not done:
        return f"{graph} has no realization done yet: rerun the same command with --resume"
    # Lambda^KM averages d tau / d beta over the realizations that synchronize undamaged and damaged
    if p_sync == 0:
        return (
            f"Lambda^KM is undefined: none of the {done:,} realizations of {graph} synchronized by "
            "t_max (raise dynamics.t_max, or check that the graph synchronizes)"
        )
    if not synced:
        return (
            f"Lambda^KM is undefined: every one of the {done:,} realizations of {graph} started "
            "synchronized (r(0) >= r), so none has a synchronization time"
        )
    return (
        f"Lambda^KM is undefined: no realization of {graph} synchronized both with and without "
        f"the damage ({synced:,} of {done:,} did without it)"
    )


def flag_signs(records: list[dict]) -> list[dict]:
    """Copies of ``records``, each with ``sign_resolved``: ``+1`` (antifragile), ``-1``
    (fragile) or ``0`` (unresolved) by the Benjamini-Hochberg procedure at false discovery rate
    0.05 over the records' distinct links (:func:`antisync.stats.multiplicity.fdr_signs`: a run over
    many links calls few null links by chance), and ``sign_per_link``, the call of the record's
    own 95% interval alone (:func:`antisync.stats.summary.sign_resolved`); both ``None`` where no
    Lambda^KM was estimated (a file run without ``km``)."""
    out = []
    for r, sign in zip(records, fdr_signs(records), strict=True):
        own = sign_resolved(r) if r.get("lambda_km") is not None else None
        out.append({**r, "sign_resolved": sign, "sign_per_link": own})
    return out


def sign_rule_note(records: list[dict]) -> str | None:
    """One line saying how ``sign_resolved`` was decided and how many links each rule calls
    (None without Lambda^KM)."""
    links = {link_key(r): r for r in records if r.get("sign_resolved") is not None}
    if not links:
        return None
    fdr = sum(1 for r in links.values() if r["sign_resolved"])
    own = sum(1 for r in links.values() if r.get("sign_per_link"))
    return (
        f"signs: {fdr} of {len(links)} links called at false discovery rate {FDR_LEVEL:g} over the "
        f"file's links (Benjamini-Hochberg; sign_per_link, each 95% interval alone, calls {own})"
    )


def _value(rec: dict, key: str) -> float | None:
    x = rec.get(key)
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)
