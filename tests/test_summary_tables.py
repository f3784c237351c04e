"""The summary as a researcher reads it (issue 30): columns that fit the run, Lambda once per
link, an asymmetric interval shown as [low, high], warnings one line per kind, which model ran,
r* of the relative criterion stored and shown, sign_resolved in the API's records."""

from __future__ import annotations

import json
import re
import shutil
import sys
import types

import h5py
import pytest
from typer.testing import CliRunner

import antisync
from antisync.cli.app import app
from antisync.execution.runner import run_config
from antisync.plan.config import load_config_text
from antisync.plan.describe import model_line
from antisync.report.tables import asymmetric, fmt_interval, format_records, sync_warnings
from antisync.stats.records import flag_signs
from antisync.store.layout import decode_config

LOLLIPOP = "graph: {kind: lollipop, nodes: 6, path: 3}\nrealizations: 200\nseed: 3\n"
RELATIVE = (
    LOLLIPOP
    + 'edges: ["2->1", "2->3"]\nbetas: [0.5]\n'
    + "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], phase_lag: 0.3}\n"
    + "sync: {criterion: relative, fraction: 0.98}\n"
)
DEFAULT_LINE = "model: identical first-order Kuramoto (the paper's Eq. 2); sync: r >= 0.99"


def _run(tmp_path_factory, name: str, text: str):
    out = tmp_path_factory.mktemp(name) / f"{name}.h5"
    return run_config(load_config_text(text), output=out)


@pytest.fixture(scope="module")
def no_betas(tmp_path_factory):
    """Every link of the lollipop, Lambda only; 5 batches, so every link warns alike."""
    return _run(tmp_path_factory, "nobetas", LOLLIPOP + "betas: []\nblock_size: 40\n")


@pytest.fixture(scope="module")
def two_betas(tmp_path_factory):
    return _run(tmp_path_factory, "betas", LOLLIPOP + 'edges: ["2->1", "2->3"]\nbetas: [0.1, 0.5]\n')


@pytest.fixture(scope="module")
def relative(tmp_path_factory):
    return _run(tmp_path_factory, "relative", RELATIVE)


@pytest.fixture(scope="module")
def older(relative, tmp_path_factory):
    """The relative run as a file written before r* was stored: its r_star datasets removed."""
    path = tmp_path_factory.mktemp("older") / "older.h5"
    shutil.copy(relative, path)
    with h5py.File(path, "r+") as f:
        for g in f["jobs"].values():
            del g["r_star"]
    return path


def _summary(path, *args) -> str:
    res = CliRunner().invoke(app, ["summary", str(path), *args])
    assert res.exit_code == 0, res.output
    return res.stdout


def _tables(text: str) -> list[list[list[str]]]:
    """The aligned tables at the top of a summary: rows of cells (columns are two or more
    spaces apart; a cell such as ``[+0.1, +0.2]`` holds single spaces only)."""
    tables, rows = [], []
    for line in text.splitlines():
        if not line.strip():
            tables.append(rows)
            rows = []
            continue
        if re.match(r"(warning|model|signs|sum rule|stop):", line):
            break
        rows.append(re.split(r"\s{2,}", line.strip()))
    return [t for t in [*tables, rows] if t]


# ---- 1. columns that fit the run ----------------------------------------------------------------
def test_no_column_is_empty_on_every_row_without_betas(no_betas):
    (table,) = _tables(_summary(no_betas))
    header, *rows = table
    assert not {"beta", "<F>"} & set(header), header
    assert len(rows) == 12  # the lollipop's 12 directed links, one row each
    for i, name in enumerate(header):
        assert any(row[i] != "-" for row in rows), name
    # machine output keeps every key (backward compatible): F_mean is there, null
    recs = json.loads(_summary(no_betas, "--format", "json"))["records"]
    assert all("F_mean" in r and r["F_mean"] is None and r["beta"] is None for r in recs)


def test_lambda_once_per_link_and_one_row_per_beta(two_betas):
    links, betas = _tables(_summary(two_betas))
    assert links[0][:3] == ["graph", "edge", "Lambda_KM"] and "beta" not in links[0]
    assert [row[1] for row in links[1:]] == ["2->1", "2->3"]
    assert betas[0][:4] == ["graph", "edge", "beta", "<F>"] and "Lambda_KM" not in betas[0]
    assert [(row[1], row[2]) for row in betas[1:]] == [
        ("2->1", "0.1"),
        ("2->1", "0.5"),
        ("2->3", "0.1"),
        ("2->3", "0.5"),
    ]
    recs = antisync.load(two_betas).records
    for r in recs[::2]:  # each link's Lambda, printed once
        assert _summary(two_betas).count(f"{r['lambda_km']:+.4f}") == 1
    # the CSV still has one row per (link, beta), Lambda on each
    rows = _summary(two_betas, "--format", "csv").splitlines()
    assert len(rows) == 5 and "lambda_km" in rows[0].split(",")


def test_an_asymmetric_interval_is_shown_as_its_ends(two_betas):
    recs = flag_signs(antisync.load(two_betas).records)
    # a link as reported: +0.0152 +- 0.0089 (resolved), its interval [0.00016, 0.035]
    edited = [
        {
            **r,
            "lambda_km": 0.0152,
            "lambda_km_se": 0.0089,
            "lambda_km_ci_low": 0.00016,
            "lambda_km_ci_high": 0.035,
        }
        if r["edge"] == "2->1"
        else r
        for r in recs
    ]
    assert asymmetric(edited[0]) and not asymmetric({**edited[0], "lambda_km_ci_high": 0.0302})
    links = _tables(format_records(edited))[0]
    assert links[0][3] == "95% interval"
    assert links[1][1:4] == ["2->1", "+0.0152", "[+0.00016, +0.035]"]
    assert links[2][3] == fmt_interval(recs[2]["lambda_km_ci_low"], recs[2]["lambda_km_ci_high"])
    # symmetric intervals keep the standard error
    symmetric = [
        {**r, "lambda_km_ci_low": r["lambda_km"] - 0.01, "lambda_km_ci_high": r["lambda_km"] + 0.01}
        for r in recs
    ]
    assert _tables(format_records(symmetric))[0][0][3] == "se"


def test_interval_ends_keep_their_sign_and_digits():
    assert fmt_interval(0.00016, 0.035) == "[+0.00016, +0.035]"
    assert fmt_interval(0.1534, 0.1789) == "[+0.153, +0.179]"
    assert fmt_interval(-0.0123, 0.0456) == "[-0.012, +0.046]"
    assert fmt_interval(None, 0.1) == "-" and fmt_interval(float("nan"), 0.1) == "-"


# ---- 2. warnings grouped ------------------------------------------------------------------------
def test_warnings_are_one_line_per_kind_with_a_count(no_betas):
    text = _summary(no_betas)
    warnings = [ln for ln in text.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1, warnings
    assert warnings[0].startswith("warning: Lambda_KM of 12 links (") and "only 5 batches" in warnings[0]


def test_unsynchronized_graphs_sharing_a_remedy_are_one_line():
    def rec(graph, bad):
        return {"graph": graph, "edge": "0->1", "beta": None, "n_not_synced": bad, "realizations_done": 100}

    lines = sync_warnings([rec(f"G{i}", 3 + i) for i in range(7)] + [rec("ring", 90), rec("fine", 0)])
    assert len(lines) == 2, lines
    few = next(ln for ln in lines if ln.startswith("7 graphs"))
    assert few.startswith("7 graphs (G0, G1, G2, G3, G4, ...): realizations did not synchronize")
    assert "most in G6 (9 of 100, 0->1)" in few and "left out of every mean" in few
    assert lines[1].startswith("ring: 90 of 100 realizations did not synchronize") and "t_max" in lines[1]


# ---- 3. which model ran, and r* -----------------------------------------------------------------
def test_default_model_line(no_betas):
    assert DEFAULT_LINE in _summary(no_betas).splitlines()
    assert antisync.load(no_betas).model == DEFAULT_LINE
    assert json.loads(_summary(no_betas, "--format", "json"))["model"] == DEFAULT_LINE


def test_swing_equation_and_frequency_locking_line(tmp_path):
    (tmp_path / "ieee14_power.txt").write_text("\n".join(["0.1", "-0.1"] * 3) + "\n")
    cfg = load_config_text(
        LOLLIPOP
        + "model: {frequencies: {file: ieee14_power.txt}, inertia: 1, damping: 1}\n"
        + "sync: {criterion: frequency}\n",
        source=tmp_path / "c.yaml",
    )
    assert model_line(decode_config(cfg.to_yaml(), "test")) == (
        "model: swing equation (inertia 1, damping 1), natural frequencies from ieee14_power.txt; "
        "sync: frequency locking, tolerance 0.001"
    )
    assert model_line({"model": {"inertia": [0, 1, 2]}}).startswith(
        "model: swing equation (inertia 0 to 2 per node, damping 1), identical natural frequencies"
    )
    assert model_line({"model": "nonsense"}) is None


def test_relative_r_star_is_stored_and_shown(relative):
    with h5py.File(relative, "r") as f:
        (g,) = f["jobs"].values()
        r_star = g["r_star"][...]
        variants = g["variant_edge"].shape[0]
    assert r_star.shape == (1 + variants,) and ((0.9 < r_star) & (r_star <= 1)).all()
    line = next(ln for ln in _summary(relative).splitlines() if ln.startswith("model:"))
    assert line.startswith(
        "model: first-order Kuramoto-Sakaguchi (phase lag 0.3), natural frequencies given per node "
        "(6 values, -0.2 to 0.15); sync: r >= 0.98 r*"
    )
    lo, hi = r_star[1:].min(), r_star[1:].max()
    assert f"r* = {r_star[0]:.4f} undamaged, {lo:.4f} to {hi:.4f} over {variants} damaged variants" in line
    data = json.loads(_summary(relative, "--format", "json"))
    (row,) = data["r_star"]
    assert row == pytest.approx(
        {
            "graph": "lollipop_6_3",
            "undamaged": r_star[0],
            "damaged_min": lo,
            "damaged_max": hi,
            "damaged": variants,
        }
    )
    res = antisync.load(relative)
    assert res.r_star == data["r_star"]
    for rec in data["records"]:
        assert rec["r_star"] == pytest.approx(r_star[0])
        assert lo <= rec["r_star_damaged"] <= hi
    assert [r["r_star_damaged"] for r in res.records] == [r["r_star_damaged"] for r in data["records"]]


def test_a_file_without_r_star_still_summarizes(older, relative):
    line = next(ln for ln in _summary(older).splitlines() if ln.startswith("model:"))
    assert line.endswith("r*: not stored (a file written before antisync stored it)")
    res = antisync.load(older)
    assert res.r_star == [] and all(r["r_star"] is None and r["r_star_damaged"] is None for r in res.records)
    # everything else reads as before
    strip = ("r_star", "r_star_damaged")
    new = [{k: v for k, v in r.items() if k not in strip} for r in antisync.load(relative).records]
    assert [{k: v for k, v in r.items() if k not in strip} for r in res.records] == new


def test_the_default_model_stores_no_r_star(no_betas):
    with h5py.File(no_betas, "r") as f:
        assert not any("r_star" in g for g in f["jobs"].values())
    assert all(r["r_star"] is None for r in antisync.load(no_betas).records)
    assert antisync.load(no_betas).r_star == []


# ---- 4. sign_resolved in the API --------------------------------------------------------------
def test_sign_resolved_in_records_as_in_summary_json(two_betas):
    data = json.loads(_summary(two_betas, "--format", "json"))
    res = antisync.load(two_betas)
    for key in ("sign_resolved", "sign_per_link"):
        assert [r[key] for r in res.records] == [r[key] for r in data["records"]]
    assert res.records == flag_signs(res.records)  # the same function decides, nothing duplicated
    assert {r["sign_resolved"] for r in res.records} <= {-1, 0, 1}


def test_to_pandas_has_sign_resolved(two_betas, monkeypatch):
    seen = {}

    class DataFrame:
        @staticmethod
        def from_records(records):
            seen["records"] = records
            return records

    monkeypatch.setitem(sys.modules, "pandas", types.SimpleNamespace(DataFrame=DataFrame))
    res = antisync.load(two_betas)
    res.to_pandas()
    assert all("sign_resolved" in r for r in seen["records"])


def test_to_pandas_columns(two_betas):
    pytest.importorskip("pandas")
    df = antisync.load(two_betas).to_pandas()
    assert {"sign_resolved", "sign_per_link", "r_star"} <= set(df.columns)
