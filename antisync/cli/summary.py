"""`antisync summary RESULTS.h5`: per-(edge, beta) estimates as a table, JSON or CSV."""

from __future__ import annotations

from typing import Annotated, Literal

import typer

from antisync.cli.common import DebugOpt, ResultArg, one_of, user_errors
from antisync.stats.records import SortKey

Format = Literal["table", "json", "csv"]


@user_errors
def summary(
    results: ResultArg,
    format: Annotated[
        Format, typer.Option("--format", "-f", parser=one_of("--format", Format), help="table, json or csv.")
    ] = "table",
    sort: Annotated[
        SortKey | None,
        typer.Option(
            "--sort",
            parser=one_of("--sort", SortKey),
            help="Order records by a measure, largest (most antifragile) first: lambda (Lambda^KM, "
            "or the first exact measure computed when the file has no km), km, xi2, rw, linear, km_nnc.",
        ),
    ] = None,
    debug: DebugOpt = False,
) -> None:
    """Print <F_beta>, Lambda^KM, <tau0> with standard errors and status counts.

    JSON is one object for run and sweep files alike: {"kind": "run" | "sweep", "file",
    "complete", "records": [...], "config_yaml", and for sweeps "excluded", "top", "screen",
    "symmetry", "thresholds", ...} (see antisync.api.summarize). Every record printed here also
    carries sign_resolved: +1 antifragile, -1 fragile, 0 unresolved (Benjamini-Hochberg at
    false discovery rate 0.05 over the file's links), and sign_per_link (its own 95% interval
    lambda_km_ci_low..lambda_km_ci_high alone), null without Lambda^KM, and r_star, r_star_damaged
    (sync.criterion relative: r* of the undamaged and of the record's damaged network); the
    object's "model" says which model ran and "r_star" lists each graph's r*. CSV holds the
    records only. The table has one row per link (Lambda^KM with its standard error, or its
    interval [low, high] where asymmetric) and, with betas, one per (link, beta) (<F_beta>);
    columns empty on every row are left out. It ends with warnings (one line per kind), which
    model ran and, for a sweep, the excluded graphs.

    A table of `antisync grid removal|trip --out` (JSON or HDF5) prints as its ranked table,
    its whole document (json) or its rows (csv).
    """
    import json

    from antisync.api import summarize
    from antisync.errors import AntisyncError
    from antisync.execution.step_check import step_check_notes
    from antisync.execution.stopping import stop_note
    from antisync.plan.describe import stored_name
    from antisync.report.grid_tables import table_kind, table_text
    from antisync.report.tables import format_records, format_sweep
    from antisync.stats.records import flag_signs, sign_rule_note, sort_records
    from antisync.stats.sum_rule import sum_rule_note, views_sums
    from antisync.stats.summary import named_views, view_records
    from antisync.store import is_sweep_file, read_views, step_check_records, stop_record, stored_config
    from antisync.store.design_file import is_design_file, read_design
    from antisync.sweeps import sweep_summary

    def listed(recs: list[dict]) -> list[dict]:
        return flag_signs(sort_records(recs, sort) if sort else recs)

    if table_kind(results) is not None:  # a table of `antisync grid removal|trip --out`
        if sort is not None:
            raise AntisyncError("--sort orders a result file's links; a grid table is ranked as it is")
        typer.echo(table_text(results, format))
        return
    if is_design_file(results):
        typer.echo(_design_summary(read_design(results), results, format))
        return

    if format == "json":
        s = summarize(results)
        typer.echo(json.dumps({**s, "records": listed(s["records"])}, indent=2))
    elif is_sweep_file(results):
        s = sweep_summary(results)
        typer.echo(format_sweep({**s, "records": listed(s["records"])}, format))
        if format == "table":
            note = _model_note(results, s["records"], None)
            if note and s.get("grid"):  # the stored config is the grid's base
                keys = ", ".join(k for axis in s["grid"] for k in axis["keys"])
                note = f"{note} (the base config; each grid point sets {keys})"
            for line in (note, stop_note(stop_record(results), "sweep")):
                if line:
                    typer.echo(line)
    else:
        # decoded once for the records and the sum rule. The table, read by people, calls each
        # job by the config's name: as the report's figures do; CSV and JSON, read by programs,
        # keep the job's name (its HDF5 group's), as antisync.summarize does
        views = read_views(results)
        if format == "table":
            views = named_views(views, stored_name(stored_config(results)))
        recs = listed(view_records(views))
        typer.echo(format_records(recs, format))
        if format == "table":
            quantities = {r.get("lambda_quantity") for r in recs} - {None}
            quantity = quantities.pop() if len(quantities) == 1 else None
            rule = sum_rule_note(views_sums(views), quantity)
            notes = (
                _model_note(results, recs, views),
                sign_rule_note(recs),
                rule,
                stop_note(stop_record(results)),
                *step_check_notes(step_check_records(results)),
            )
            for note in notes:
                if note:
                    typer.echo(note)


def _model_note(path, records: list[dict], views) -> str | None:
    """The table's ``model: ...; sync: ...`` line (with r* for ``sync.criterion: relative``);
    None for a file without a Kuramoto run (its exact measures depend on no model)."""
    from antisync.plan.describe import model_line, relative_criterion
    from antisync.stats.summary import r_star_rows
    from antisync.store import read_views, stored_config

    if not any(r.get("realizations") for r in records):
        return None
    cfg = stored_config(path)
    rows = r_star_rows(views if views is not None else read_views(path)) if relative_criterion(cfg) else None
    return model_line(cfg, rows)


def _design_summary(rec: dict, path, format: str) -> str:
    """A design file (``antisync design``) as its verification table: each design's mean tau on
    the fresh starts with its standard error, the synchronized share and its paired difference
    to the designed one with a 95% interval; JSON the whole row list, CSV the rows."""
    import csv
    import io
    import json

    ver = rec.get("verification") or {}
    rows = ver.get("rows", [])
    if format == "json":
        keep = {"complete": rec["complete"], "reason": rec["reason"], "design": rec["design"]}
        return json.dumps({"kind": "design", "file": str(path), **keep, "verification": rows}, indent=2)
    if format == "csv":
        buf = io.StringIO()
        fields = ["design", "mean_tau", "se", "synced", "minus_designed", "low", "high"]
        writer = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
        return buf.getvalue().rstrip("\n")
    head = f"{path}: a design ({rec['reason'] or 'not finished'})"
    if not rows:
        return head + "; no verification yet (antisync design CONFIG --resume finishes it)"
    out = [head, "", "| design | mean tau +- se | synced | minus designed [95% CI] |", "|---|---|---|---|"]
    for r in rows:
        out.append(
            f"| {r['design']} | {r['mean_tau']:.4g} +- {r['se']:.2g} | {r['synced']:.3f} | "
            f"{r['minus_designed']:+.4g} [{r['low']:+.4g}, {r['high']:+.4g}] |"
        )
    return "\n".join(out)
