"""The grid wing's Python face (``antisync.grid``, :mod:`antisync.api.grids`) and the grid
subcommands (``antisync grid static|removal|trip``) over it (issue 60).

- each function takes a config as :func:`antisync.run` does (a path, a mapping, a networkx
  graph) with overrides merged by the same rules, and its records are the CLI table's rows, the
  JSON file's rows, and the grid modules' own numbers, exactly;
- the subcommands and the one-command form (``antisync grid CONFIG --removal``) print the same
  table and write the same file;
- bad arguments are one line before any file is made; a finished output with ``resume=True`` is
  checked and returned as it is.
"""

from __future__ import annotations

import json
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from typer.testing import CliRunner

import antisync
from antisync.cli.app import app
from antisync.errors import AntisyncError, ConfigError
from antisync.grids.errors import GridError
from antisync.grids.load import load_grid_config
from antisync.grids.removal_file import plain
from antisync.grids.static import static_table

REPO = Path(__file__).resolve().parent.parent
IEEE14 = REPO / "configs" / "ieee14_grid.yaml"
RING = "0 1 2.0\n1 2 2.0\n2 3 2.0\n3 4 2.0\n4 5 2.0\n5 0 2.0\n0 3 1.0\n"
RING_CONFIG = {
    "name": "ring6",
    "graph": {
        "kind": "inline",
        "links": [[int(a), int(b), float(w)] for a, b, w in map(str.split, RING.splitlines())],
    },
    "model": {"frequencies": [1.0, -1.0, 0.5, -0.5, 0.8, -0.8], "inertia": 1.0, "damping": 1.0},
    "sync": {"criterion": "frequency", "tolerance": 0.001},
    "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.02, "t_max": 20},
    "realizations": 6,
    "seed": 11,
}
runner = CliRunner()


def _without_provenance(doc: dict) -> dict:
    return {k: v for k, v in doc.items() if k not in ("written", "command", "git_revision", "version")}


def test_static_records_are_the_static_tables_rows_and_the_cli_prints_the_same():
    res = antisync.grid.static(IEEE14)
    table = static_table(load_grid_config(IEEE14))
    assert res.kind == "static" and res.path is None and not res.kept
    assert res.records == table.to_dicts() and len(res.records) == 19  # 20 lines, bridge 7-8 skipped
    try:
        import pandas  # noqa: F401  (an optional dependency)
    except ImportError:
        with pytest.raises(AntisyncError, match="needs pandas"):
            res.to_pandas()
    else:
        assert list(res.to_pandas()["label"]) == [r["label"] for r in res.records]
    # the subcommand and the one-command form print the face's table; the timing line aside
    body = res.to_markdown(top=4).splitlines()[1:]
    for args in (["grid", "static", str(IEEE14), "--top", "4"], ["grid", str(IEEE14), "--top", "4"]):
        out = runner.invoke(app, args)
        assert out.exit_code == 0, out.output
        assert out.output.splitlines()[1:] == body


def test_static_takes_overrides_a_mapping_and_a_networkx_graph():
    weak = antisync.grid.static(IEEE14, lines="1-2", beta=0.5, dynamics={"coupling": "raw"})
    assert [r["label"] for r in weak.records] == ["1-2"] and weak.records[0]["beta"] == 0.5
    ring = nx.cycle_graph(5)
    nx.set_edge_attributes(ring, 2.0, "weight")
    a = antisync.grid.static(ring)
    b = antisync.grid.static({"graph": ring}, model={"frequencies": [0.0] * 5})
    assert a.records == b.records and len(a.records) == 5
    assert all(r["stable"] for r in a.records)


@pytest.mark.parametrize(
    ("call", "error", "words"),
    [
        (lambda: antisync.grid.static(3.5), ConfigError, "antisync.grid.static: config must be"),
        (lambda: antisync.grid.static(IEEE14, lines=5), GridError, "lines must be None, a string"),
        (lambda: antisync.grid.static(IEEE14, lines="1-9"), GridError, "1-9"),
        (lambda: antisync.grid.static(IEEE14, beta=2), GridError, "beta must be a number in (0, 1]"),
        (lambda: antisync.grid.static(IEEE14, realizations=-1), GridError, "realizations"),
        (lambda: antisync.grid.removal(IEEE14, resume=True), GridError, "give its output"),
        (
            lambda: antisync.grid.removal(IEEE14, output="x.json", resume=True, overwrite=True),
            GridError,
            "give one",
        ),
        (lambda: antisync.grid.removal(IEEE14, log=3), ConfigError, "log must be None or a callable"),
        (lambda: antisync.grid.trip(IEEE14, t_max=-1), GridError, "--t-max must be a finite positive"),
        (lambda: antisync.grid.trip(IEEE14, cct=True, cct_max=0.0), GridError, "--cct-max must be"),
        (lambda: antisync.grid.trip(IEEE14, progress="yes"), ConfigError, "progress"),
        (lambda: antisync.grid.trip(IEEE14, source=3), ConfigError, "source must be None or the path"),
    ],
)
def test_bad_arguments_are_one_line_before_any_file(tmp_path, monkeypatch, call, error, words):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(error) as info:
        call()
    assert words in str(info.value) and "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_removal_writes_the_cli_s_table_and_resume_returns_a_finished_one_as_it_is(tmp_path):
    out = tmp_path / "r.json"
    messages = []
    res = antisync.grid.removal(RING_CONFIG, lines="0-1,2-3", output=out, log=messages.append)
    written = out.read_text()
    doc = json.loads(written)
    assert res.kind == "removal" and res.path == out and not res.kept
    assert res.records == doc["rows"] and [r["label"] for r in res.records] == ["0-1", "2-3"]
    assert res.table.n == 6 and f"wrote {out}" in messages and not (tmp_path / "r.json.partial").exists()
    # the same through the subcommand and the one-command form, from a YAML file
    (tmp_path / "ring.yaml").write_text(json.dumps(RING_CONFIG))
    for k, head in enumerate(
        (["grid", "removal", str(tmp_path / "ring.yaml")], ["grid", str(tmp_path / "ring.yaml"), "--removal"])
    ):
        cli = tmp_path / f"cli{k}.json"
        ran = runner.invoke(app, [*head, "--lines", "0-1,2-3", "--out", str(cli), "-q"])
        assert ran.exit_code == 0, ran.output
        assert ran.output.splitlines()[1:] == res.to_markdown().splitlines()[1:]  # the time aside
        got = json.loads(cli.read_text())
        for d in (got, doc):
            d["summary"].pop("seconds", None)
        assert _without_provenance(got) == _without_provenance(doc)
    again = antisync.grid.removal(RING_CONFIG, lines="0-1,2-3", output=out, resume=True)
    assert again.kept and again.records == res.records
    with pytest.raises(GridError, match="finished table of another run"):
        antisync.grid.removal(RING_CONFIG, lines="0-1", output=out, resume=True)
    with pytest.raises(GridError, match="exists"):
        antisync.grid.removal(RING_CONFIG, lines="0-1", output=out)
    assert out.read_text() == written  # the refusals left it as it was


def test_removal_protects_the_config_file_it_was_read_from(tmp_path):
    cfg = tmp_path / "ring.json"
    cfg.write_text(json.dumps(RING_CONFIG))
    before = cfg.read_bytes()
    with pytest.raises(GridError, match="config"):
        antisync.grid.removal(cfg, lines="0-1", output=cfg, overwrite=True)
    assert cfg.read_bytes() == before


def test_trip_records_are_the_json_table_s_lines_and_the_subcommand_writes_the_same(tmp_path):
    out = tmp_path / "t.json"
    res = antisync.grid.trip(IEEE14, lines="1-2,2-3", t_clear=0.1, t_max=5.0, output=out)
    doc = json.loads(out.read_text())
    assert res.kind == "trip" and res.table["t_clear"] == 0.1
    assert res.records == doc["lines"] == plain(res.table["lines"])  # nan as None, as in the file
    assert [tuple(r["line"]) for r in res.records] == [("1", "2"), ("2", "3")]
    assert all(np.isfinite(r["max_frequency"]) for r in res.records)
    cli = tmp_path / "cli.json"
    ran = runner.invoke(
        app,
        [
            "grid",
            "trip",
            str(IEEE14),
            "--lines",
            "1-2,2-3",
            "--t-clear",
            "0.1",
            "--t-max",
            "5",
            "--out",
            str(cli),
        ],
    )
    assert ran.exit_code == 0, ran.output
    assert _without_provenance(json.loads(cli.read_text())) == _without_provenance(doc)
    again = antisync.grid.trip(IEEE14, lines="1-2,2-3", t_clear=0.1, t_max=5.0, output=out, resume=True)
    assert again.kept and again.records == res.records


def test_contingencies_name_their_lines(tmp_path):
    (tmp_path / "c.txt").write_text("# label from to share\nA 1 2 1\nB 1 2 0.5\n")
    rows = antisync.grid.contingencies(IEEE14, tmp_path / "c.txt")
    assert rows == [
        {"label": "A", "line": [1, 2], "share": 1.0},  # the graph's own labels
        {"label": "B", "line": [1, 2], "share": 0.5},
    ]


def test_a_usage_error_of_the_one_command_form_names_antisync_grid():
    ran = runner.invoke(app, ["grid", str(IEEE14), "--no-such-option"])
    assert ran.exit_code == 2 and "(see antisync grid --help)" in ran.output and "flags" not in ran.output


# ---- grid tables in HDF5 (antisync.store.grid_file) and their readers ----


def test_a_removal_table_in_hdf5_is_the_json_document_and_every_start(tmp_path):
    """``output=X.h5``: the file holds the JSON file's document exactly (provenance and the
    run's seconds aside), its rows as columns, and every start's paired outcome."""
    import h5py

    from antisync.store.grid_file import read_grid_table, read_outcomes

    as_json = antisync.grid.removal(RING_CONFIG, lines="0-1,2-3", output=tmp_path / "r.json")
    as_hdf5 = antisync.grid.removal(RING_CONFIG, lines="0-1,2-3", output=tmp_path / "r.h5")
    doc = read_grid_table(tmp_path / "r.h5")
    other = json.loads((tmp_path / "r.json").read_text())
    for d in (doc, other):
        d["summary"].pop("seconds")
    assert _without_provenance(doc) == _without_provenance(other)
    assert as_hdf5.records == as_json.records
    outcomes = read_outcomes(tmp_path / "r.h5")
    table = as_hdf5.table
    for key in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(outcomes[key], getattr(table, key))
    assert outcomes["status"].shape == (6, 2)
    with h5py.File(tmp_path / "r.h5", "r") as f:
        assert f.attrs["kind"] == "removal" and f.attrs["command"] == doc["command"]
        assert [x.decode() for x in f["rows/label"][()]] == ["0-1", "2-3"]
        np.testing.assert_array_equal(f["rows/p_after"][()], [r["p_after"] for r in as_hdf5.records])


def test_load_summary_and_report_read_grid_tables_of_either_kind(tmp_path):
    """``antisync.load``, ``antisync summary`` (table, json, csv) and ``antisync report`` read a
    removal and a trip table, JSON or HDF5, and say the same of both files."""
    removal = {
        s: antisync.grid.removal(RING_CONFIG, lines="0-1,2-3", output=tmp_path / f"r{s}")
        for s in (".json", ".h5")
    }
    trip = {
        s: antisync.grid.trip(IEEE14, lines="1-2,2-3", t_clear=0.1, t_max=5.0, output=tmp_path / f"t{s}")
        for s in (".json", ".h5")
    }
    for kind, results in (("removal", removal), ("trip", trip)):
        loaded = {s: antisync.load(tmp_path / f"{kind[0]}{s}") for s in results}
        for s, res in loaded.items():
            assert (
                res.kind == kind
                and res.records == results[s].records
                and res.path == tmp_path / f"{kind[0]}{s}"
            )
        assert loaded[".json"].records == loaded[".h5"].records
        printed = {}
        for s in results:
            for fmt in ("table", "json", "csv"):
                ran = runner.invoke(app, ["summary", str(tmp_path / f"{kind[0]}{s}"), "--format", fmt])
                assert ran.exit_code == 0, ran.output
                printed[s, fmt] = ran.output
        assert printed[".json", "table"] == printed[".h5", "table"] == loaded[".h5"].to_markdown() + "\n"
        assert printed[".json", "csv"] == printed[".h5", "csv"]
        as_json = {s: json.loads(printed[s, "json"]) for s in results}
        assert as_json[".h5"]["kind"] == kind and as_json[".h5"]["file"].endswith(".h5")
        rows = "rows" if kind == "removal" else "lines"
        assert as_json[".json"][rows] == as_json[".h5"][rows] == loaded[".h5"].records
    ran = runner.invoke(app, ["report", str(tmp_path / "r.h5"), "--out", str(tmp_path / "fig")])
    assert ran.exit_code == 0, ran.output
    assert (tmp_path / "fig" / "index.md").is_file() and (tmp_path / "fig" / "ring6_removal.png").is_file()
    ran = runner.invoke(app, ["summary", str(tmp_path / "r.h5"), "--sort", "km"])
    assert ran.exit_code == 2 and "a grid table is ranked as it is" in ran.output


def test_an_hdf5_grid_table_resumes_and_replaces_only_its_own_kind(tmp_path):
    """``resume=True`` on a finished ``.h5`` table returns it as it is; ``overwrite`` replaces a
    removal table but never a run's result file or a trip table; a damaged ``.h5`` is one line
    to every reader."""
    out = tmp_path / "r.h5"
    first = antisync.grid.removal(RING_CONFIG, lines="0-1", output=out)
    before = out.read_bytes()
    again = antisync.grid.removal(RING_CONFIG, lines="0-1", output=out, resume=True)
    assert again.kept and again.records == first.records and out.read_bytes() == before
    run = antisync.run(
        {"graph": {"kind": "lollipop", "nodes": 4, "path": 1}, "betas": [], "edges": ["1->2"]},
        realizations=8,
        output=tmp_path / "run.h5",
    )
    trip = antisync.grid.trip(IEEE14, lines="1-2", t_max=2.0, output=tmp_path / "t.h5")
    for other in (run.path, trip.path):
        kept = other.read_bytes()
        with pytest.raises(GridError, match="not an HDF5 removal table"):
            antisync.grid.removal(RING_CONFIG, lines="0-1", output=other, overwrite=True)
        assert other.read_bytes() == kept
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(before[: len(before) // 2])
    ran = runner.invoke(app, ["summary", str(damaged)])
    assert ran.exit_code == 2 and len(ran.output.strip().splitlines()) == 1, ran.output
    with pytest.raises(AntisyncError):
        antisync.load(damaged)
