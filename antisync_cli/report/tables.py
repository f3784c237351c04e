"""Summary records as an aligned table, JSON or CSV."""

from __future__ import annotations

import csv
import io
import json

__all__ = ["format_records"]

_TABLE_COLUMNS = [
    ("graph", "graph", "{}"), ("edge", "edge", "{}"), ("beta", "beta", "{:.3g}"),
    ("F_mean", "<F>", "{:.4f}"), ("F_se", "se", "{:.4f}"),
    ("lambda_km", "Lambda_KM", "{:+.4f}"), ("lambda_km_se", "se", "{:.4f}"),
    ("tau0_mean", "<tau0>", "{:.4f}"), ("tau0_se", "se", "{:.4f}"),
    ("n", "n", "{:,}"), ("n_excluded", "r0>=r", "{}"), ("n_not_synced", "unsynced", "{}"),
]
# shown only when some record has them (measures: linear, xi2, rw, km_nnc)
_MEASURE_COLUMNS = [
    ("lambda_linear", "Lambda_lin", "{:+.4f}"), ("lambda_linear_se", "se", "{:.4f}"),
    ("lambda_xi2", "Lambda_xi2", "{:+.4f}"), ("lambda_rw", "Lambda_RW", "{:+.4f}"),
    ("lambda_km_nnc", "Lambda_NNC", "{:+.4f}"), ("lambda_km_nnc_se", "se", "{:.4f}"),
]


def format_records(records: list[dict], fmt: str = "table") -> str:
    """Render summary records; ``fmt`` is ``table``, ``json`` or ``csv``."""
    if fmt == "json":
        return json.dumps(records, indent=2)
    if fmt == "csv":
        buf = io.StringIO()
        if records:
            writer = csv.DictWriter(buf, fieldnames=list(records[0]))
            writer.writeheader()
            writer.writerows(records)
        return buf.getvalue().rstrip("\n")
    columns = _TABLE_COLUMNS + [c for c in _MEASURE_COLUMNS
                                if any(r.get(c[0]) is not None for r in records)]
    rows = [[h for _, h, _ in columns]]
    for r in records:
        rows.append(["-" if r.get(k) is None else f.format(r[k]) for k, _, f in columns])
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    warnings = sorted({(r["edge"], r["lambda_km_warning"]) for r in records if r.get("lambda_km_warning")})
    lines += [f"warning: Lambda_KM of {e}: {w}" for e, w in warnings]
    return "\n".join(lines)
