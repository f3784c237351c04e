"""``antisync report`` and ``antisync summary`` of the tables that ``antisync grid`` writes (JSON,
or HDF5 with an ``.h5`` suffix): a dynamic line removal (``removal --out``) and the engineer's
N-1 (``trip --out``).

:func:`table_kind` tells such a file from a result file; :func:`write_table_report` draws its
figures (:func:`antisync.report.removal.removal_figure`, by the speedup and by ``d P_sync``;
:func:`antisync.report.removal.trip_figure`) into a folder with an ``index.md`` that holds the
table, as ``antisync report`` does for an HDF5 file. A table needs no config to be drawn: a
removal table keeps its resolved config and a trip table its network.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from antisync.execution.step_check import step_check_line
from antisync.grids.errors import GridError
from antisync.grids.removal_file import FORMAT as REMOVAL_FORMAT
from antisync.grids.removal_file import is_hdf5_table, plain, read_document
from antisync.grids.removal_table import audit_line
from antisync.grids.trip import FORMAT as TRIP_FORMAT
from antisync.grids.trip import format_trips
from antisync.report.removal import removal_doc, removal_figure, resolved, trip_figure
from antisync.store.grid_file import grid_table_kind

__all__ = [
    "TABLE_KINDS",
    "read_table",
    "removal_markdown",
    "table_kind",
    "table_text",
    "trip_doc",
    "write_table_report",
]

#: The JSON tables ``antisync report`` draws, by their ``format``.
TABLE_KINDS = {REMOVAL_FORMAT: "removal", TRIP_FORMAT: "trip"}

#: Rows of a removal table in its index.md (ranked; the JSON file holds every row).
TOP_ROWS = 40

#: What every row of a trip table holds, and the keys of its network.
_TRIP_ROW_KEYS = ("line", "settles", "settle_time", "max_frequency", "max_angle", "post_locked")
_NETWORK_KEYS = ("nodes", "links", "inertia")


def _read_json(path: Path):
    if is_hdf5_table(path) or grid_table_kind(path) is not None:
        return read_document(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise GridError(f"{path}: cannot read it as JSON ({type(exc).__name__}: {exc})") from None


def table_kind(path: str | Path) -> str | None:
    """``"removal"`` or ``"trip"`` for a table of ``antisync grid`` (JSON, or HDF5:
    :mod:`antisync.store.grid_file`); None for a file that is neither (a result file: the HDF5
    reports read it). A JSON file of another kind is a one-line :class:`GridError` naming the
    kinds that are drawn."""
    path = Path(path)
    kind = grid_table_kind(path)
    if kind is not None:
        return kind
    try:
        with open(path, "rb") as fh:
            head = fh.read(64).lstrip()
    except OSError:
        return None  # the HDF5 readers name what is wrong with it
    if not head.startswith(b"{"):
        return None
    doc = _read_json(path)
    fmt = doc.get("format") if isinstance(doc, dict) else None
    if fmt not in TABLE_KINDS:
        raise GridError(
            f"{path} is JSON of format {fmt!r}, not a table antisync report draws: "
            f"{', '.join(repr(f) for f in TABLE_KINDS)} (antisync grid --removal/--trip --out)"
        )
    return TABLE_KINDS[fmt]


def trip_doc(path: str | Path) -> dict:
    """A trip table (``antisync grid --trip --out``) read and checked: one line naming the file
    and what is missing or wrong."""
    path = Path(path)
    doc = _read_json(path)

    def refuse(what: str):
        raise GridError(f"{path}: not a whole trip table: {what} (written by antisync grid --trip --out)")

    if not isinstance(doc, dict) or doc.get("format") != TRIP_FORMAT:
        refuse(f"its format is not {TRIP_FORMAT!r}")
    for key in ("grid", "lines", "t_clear", "cct_max", "cct_tol"):
        if key not in doc:
            refuse(f"it lacks {key!r}")
    if not isinstance(doc["lines"], list):
        refuse("'lines' is not a list")
    cct = doc["cct_max"] is not None
    for k, row in enumerate(doc["lines"], start=1):
        if not isinstance(row, dict):
            refuse(f"row {k} is not a mapping")
        for key in (*_TRIP_ROW_KEYS, *(("cct",) if cct else ())):
            if key not in row:
                refuse(f"row {k} lacks {key!r}")
        for key in ("settle_time", "max_frequency", "max_angle", *(("cct",) if cct else ())):
            value = row[key]
            if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
                refuse(f"row {k}'s {key} is {value!r:.40}, not a number")
        for key in ("settles", "post_locked"):
            if not isinstance(row[key], bool):
                refuse(f"row {k}'s {key} is {row[key]!r:.40}, not true or false")
        if row["settle_time"] is None:  # nan, written as null
            row["settle_time"] = math.nan
    net = doc.get("network")
    if not isinstance(net, dict) or any(not isinstance(net.get(k), list) for k in _NETWORK_KEYS):
        refuse(
            "no 'network' with nodes, links and inertia (a table written before it kept one: draw it "
            "with antisync grid CONFIG --trip --figure)"
        )
    if len(net["inertia"]) != len(net["nodes"]):
        refuse(f"its network has {len(net['nodes'])} nodes but {len(net['inertia'])} inertia values")
    if doc.get("format_version", 1) not in (1, 2):
        refuse(f"format_version {doc['format_version']!r} is not one this antisync reads (1 or 2)")
    return doc


def _give_up_words(summary: dict) -> str:
    """What a removal table's summary says of ``sync.give_up`` (nothing without the rule)."""
    gave0, gave = summary.get("gave_up0") or 0, summary.get("gave_up") or 0
    audit = summary.get("give_up_audit")
    if not (gave0 or gave or audit):
        return ""
    text = (
        f" Stopped by sync.give_up (counted as not synchronized): {gave0} intact, {gave} after the changes."
    )
    return text + (f" {audit_line(audit)}." if audit else "")


def _step_words(summary: dict) -> str:
    """What a removal table's summary says of its step check (nothing for Rodas4 or an older
    table)."""
    check = summary.get("step_check")
    return f" The {step_check_line(check)}." if check else ""


def removal_markdown(doc: dict) -> str:
    """The removal table's summary and its first :data:`TOP_ROWS` rows, ranked by the net
    starts lost, then the change of tau (the marks of :func:`antisync.report.removal.resolved`)."""
    s = doc["summary"]
    marks = resolved(doc)
    lo, hi = s["p_sync_ci"]
    tau0 = math.nan if s["tau0_mean"] is None else s["tau0_mean"]
    out = [
        f"{s['name']}: beta = {s['beta']:g}, {s['realizations']} realizations (seed {s['seed']}"
        f"{'; ' + s['starts'] if 'starts' in s else ''}): intact "
        f"P_sync = {s['p_sync']:.4f} [{lo:.4f}, {hi:.4f}], tau0 = {tau0:.3f}; {s['lines']} lines. "
        "T: troublemaker (P_sync lost), B: Braess line, slower: tau rises (resolved at false "
        f"discovery rate {doc.get('fdr_level', 0.05):g} over the lines).{_give_up_words(s)}{_step_words(s)}",
        "",
        "| line | P_sync after | lost | gained | d P_sync | d tau +- se | tau0/tau +- se | mark |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def num(x):
        return math.nan if x is None else float(x)

    rows = sorted(doc["rows"], key=lambda r: (r["gained"] - r["lost"], -num(r["d_tau"])))
    for r in rows[:TOP_ROWS]:
        mark = [
            m
            for m, key in (("T", "troublemakers"), ("B", "braess"), ("slower", "slower"))
            if r["label"] in marks[key]
        ]
        out.append(
            f"| {r['label']} | {num(r['p_after']):.4f} | {r['lost']} | {r['gained']} "
            f"| {num(r['d_psync']):+.4f} | {num(r['d_tau']):+.3f} +- {num(r['d_tau_se']):.3f} "
            f"| {num(r['ratio']):.4f} +- {num(r['ratio_se']):.4f} | {' '.join(mark)} |"
        )
    if len(rows) > TOP_ROWS:
        out.append(f"\n({len(rows) - TOP_ROWS} more rows in the JSON file.)")
    return "\n".join(out)


def write_table_report(
    path: str | Path, folder: str | Path, *, pdf: bool = False, kind: str | None = None
) -> list[Path]:
    """Draw the JSON table ``path`` into ``folder`` (created): its figures (and their PDFs with
    ``pdf``), replaced where they exist, and ``index.md`` with the table. ``kind``: the file's
    :func:`table_kind` when the caller has it. Returns the files written."""
    path = Path(path)
    folder = Path(folder)
    kind = kind or table_kind(path)
    if kind is None:
        raise GridError(f"{path} is not a JSON table of antisync grid --removal/--trip --out")
    suffixes = (".png", ".pdf") if pdf else (".png",)
    written = []
    if kind == "removal":
        doc = removal_doc(path)
        name = doc["summary"]["name"]
        folder.mkdir(parents=True, exist_ok=True)
        figures = {"speedup": f"{name}_removal", "psync": f"{name}_removal_psync"}
        for by, stem in figures.items():
            for suffix in suffixes:
                written.append(removal_figure(doc, None, folder / (stem + suffix), by=by, overwrite=True))
        title = f"# {name}: the grid without each line, from random starts"
        body = [
            f"![F_1 - 1 by line]({figures['speedup']}.png)",
            "",
            f"![d P_sync by line]({figures['psync']}.png)",
            "",
            removal_markdown(doc),
        ]
    else:
        doc = trip_doc(path)
        name = doc["grid"]
        folder.mkdir(parents=True, exist_ok=True)
        stem = f"{name}_trips"
        for suffix in suffixes:
            written.append(trip_figure(doc, None, folder / (stem + suffix), overwrite=True))
        fault = (
            "no fault"
            if doc["t_clear"] is None
            else f"a fault of {doc['t_clear']:g} s at the line's first bus"
        )
        title = f"# {name}: each line tripped from the operating point ({fault})"
        body = [f"![the trips]({stem}.png)", "", format_trips(doc)]
    index = folder / "index.md"
    index.write_text("\n".join([title, "", f"From `{path.name}`.", "", *body]) + "\n", encoding="utf-8")
    return [*written, index]


def read_table(path: str | Path) -> tuple[str, dict]:
    """``(kind, document)`` of a grid table's file, checked (:func:`removal_doc`,
    :func:`trip_doc`); a one-line GridError for any other file."""
    kind = table_kind(path)
    if kind is None:
        raise GridError(f"{path} is not a table of antisync grid removal|trip --out (JSON or HDF5)")
    return kind, (removal_doc(path) if kind == "removal" else trip_doc(path))


def table_text(path: str | Path, format: str = "table") -> str:
    """What ``antisync summary`` prints of a grid table: the ranked table (Markdown), the whole
    document (``json``: ``kind``, ``file`` and the document's keys; ``nan`` as ``null``) or the
    rows (``csv``: one column per key, a pair as ``a-b``)."""
    import csv
    import io

    kind, doc = read_table(path)
    rows = doc["rows"] if kind == "removal" else doc["lines"]
    if format == "json":
        return json.dumps(plain({"kind": kind, "file": str(path), **doc}), indent=2, allow_nan=False)
    if format == "csv":
        keys = [k for k in rows[0] if all(k in r for r in rows)] if rows else []
        buf = io.StringIO()
        writer = csv.writer(buf)
        writer.writerow(keys)
        for r in rows:
            writer.writerow(
                [
                    "-".join(map(str, v)) if isinstance(v, list | tuple) else ("" if v is None else v)
                    for v in (r[k] for k in keys)
                ]
            )
        return buf.getvalue().rstrip("\n")
    return removal_markdown(doc) if kind == "removal" else format_trips(doc)
