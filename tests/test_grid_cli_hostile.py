"""`antisync grid` (static and ``--removal``) on hostile input: it reads, validates and writes as
`antisync run` does (issue 41).

- one config reader: the static table reads its config through :func:`antisync.plan.config.load_config`
  (the same refusals and messages as `antisync run`; ``--set``, ``model.phase_lag``,
  ``graph.header``/``delimiter`` honoured; the numbers those of
  :func:`antisync.grids.static.line_indicators`);
- the same option validators as `run` (``--threads``, ``--top``, ``--out ''``);
- one output-path policy (:mod:`antisync.store.outputs`): ``--overwrite`` replaces only a removal table
  or an image of its kind, never the config, a file it reads, a link, or a file inside a journal;
- ``--resume`` on a finished table compares the arguments with those it was run with;
- ``--lines`` names any line an edge list can hold (dashes, commas, negative integers).

Every refusal is one ``antisync: error:`` line, exit 2, and leaves every file as it was.
"""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest
from helpers import assert_one_line
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.grids.errors import GridError
from antisync.grids.lines import parse_lines
from antisync.grids.load import load_grid, load_grid_config
from antisync.grids.static import format_table, line_indicators

runner = CliRunner()

RING = "0 1 2.0\n1 2 2.0\n2 3 2.0\n3 4 2.0\n4 5 2.0\n5 0 2.0\n0 3 1.0\n"
POWER = "1.0\n-1.0\n0.5\n-0.5\n0.8\n-0.8\n"
BASE = (
    "name: ring6\ngraph: {kind: edgelist, path: ring.edges}\n"
    "model: {frequencies: {file: p.txt}, inertia: 1.0, damping: 1.0}\n"
    "sync: {criterion: frequency, tolerance: 0.001}\n"
    "dynamics: {coupling: raw, integrator: rk4, dt: 0.02, t_max: 20}\nrealizations: 4\nseed: 11\n"
)


@pytest.fixture
def ring(tmp_path):
    """A six-bus ring with a chord (no bridge), second order: ``tmp_path/ring.yaml``."""
    (tmp_path / "ring.edges").write_text(RING)
    (tmp_path / "p.txt").write_text(POWER)
    cfg = tmp_path / "ring.yaml"
    cfg.write_text(BASE)
    return cfg


def snapshot(folder) -> dict:
    """Every entry below ``folder``: a file's bytes, a link's target, a folder's mark."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = os.path.join(root, name)
            if os.path.islink(p):
                out[p] = ("link", os.readlink(p))
            elif os.path.isdir(p):
                out[p] = ("dir",)
            else:
                with open(p, "rb") as fh:
                    out[p] = ("file", fh.read())
    return out


def table_text(res) -> str:
    """The static table printed, without its wall time."""
    return re.sub(r"; [0-9.]+ s$", "", res.stdout.strip(), flags=re.M)


# --- one config reader ---------------------------------------------------------------------------


BAD_CONFIGS = {
    "empty": "",
    "a list": "- 1\n- 2\n",
    "graph a string": "graph: ring.edges\n",
    "model a list": BASE.replace(
        "model: {frequencies: {file: p.txt}, inertia: 1.0, damping: 1.0}", "model: [1]"
    ),
    "graph.path 5": BASE.replace("path: ring.edges", "path: 5"),
    "an unknown key": BASE + "bogus: 1\n",
    "a bogus criterion": BASE.replace("criterion: frequency", "criterion: bogus"),
}


@pytest.mark.parametrize("name", list(BAD_CONFIGS))
def test_static_grid_refuses_a_config_as_run_does(tmp_path, ring, name):
    bad = tmp_path / "bad.yaml"
    bad.write_text(BAD_CONFIGS[name])
    before = snapshot(tmp_path)
    ran = runner.invoke(app, ["run", str(bad), "--out", str(tmp_path / "x.h5"), "-q"])
    assert_one_line(ran)
    for extra in ([], ["--removal", "-q"]):
        res = runner.invoke(app, ["grid", str(bad), *extra])
        assert_one_line(res)
        assert res.stderr == ran.stderr, name
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "override", ["bogus.key=1", "sync.criterion=bogus", "model.phase_lag=2", "graph=5", "dynamics.coupling=x"]
)
def test_static_grid_refuses_an_override_as_run_does(tmp_path, ring, override):
    ran = runner.invoke(app, ["run", str(ring), "--set", override, "--out", str(tmp_path / "x.h5"), "-q"])
    res = runner.invoke(app, ["grid", str(ring), "--set", override])
    assert_one_line(res)
    assert res.stderr == ran.stderr
    assert not (tmp_path / "x.h5").exists()


def test_static_table_is_the_apis_with_overrides_lag_header_and_delimiter(tmp_path):
    """A CSV edge list with a header row (``graph.header``, ``graph.delimiter``), ``model.phase_lag``
    and ``inertia: 1e-1`` from the config and ``--set`` overrides: the CLI's static table is
    :func:`line_indicators` of the numbers the config names, read here by hand."""
    (tmp_path / "g.txt").write_text("from;to;cap\n" + RING.replace(" ", ";"))
    (tmp_path / "p.txt").write_text(POWER)
    cfg = tmp_path / "g.yaml"
    cfg.write_text(
        "name: g\ngraph: {kind: edgelist, path: g.txt, delimiter: ';', header: true}\n"
        "model: {frequencies: {file: p.txt}, inertia: 1e-1, damping: 1.0, phase_lag: 0.15}\n"
        "dynamics: {coupling: raw}\n"
    )
    sets = ["--set", "dynamics.coupling=normalized", "--set", "model.damping=2"]
    res = runner.invoke(app, ["grid", str(cfg), "--beta", "0.5", *sets])
    assert res.exit_code == 0, res.output
    omega = np.zeros((6, 6))
    for u, v, w in (line.split() for line in RING.splitlines()):
        omega[int(u), int(v)] = omega[int(v), int(u)] = float(w)
    p = np.array([float(x) for x in POWER.split()])
    api = line_indicators(
        omega,
        p - p.mean(),
        coupling="normalized",
        lag=0.15,
        inertia=0.1,
        damping=2.0,
        beta=0.5,
        labels=range(6),
    )
    assert table_text(res) == re.sub(r"; [0-9.]+ s$", "", format_table(api), flags=re.M)
    # the same without the overrides and the lag is another table: they were read
    plain = line_indicators(omega, p - p.mean(), coupling="raw", inertia=0.1, damping=1.0, beta=0.5)
    assert format_table(plain).splitlines()[0] != table_text(res).splitlines()[0]
    # the API reads the config through the same reader
    grid = load_grid_config(cfg, ["dynamics.coupling=normalized", "model.damping=2"])
    assert (grid.lag, grid.coupling, grid.inertia, grid.damping) == (0.15, "normalized", 0.1, 2.0)


def test_a_nan_injection_is_named(tmp_path, ring):
    (tmp_path / "p.txt").write_text(POWER.replace("0.5", "nan"))
    res = runner.invoke(app, ["grid", str(ring)])
    assert_one_line(res, "p.txt:3: 'nan' is not a finite number")
    with pytest.raises(GridError, match=r"p.txt:3: 'nan' is not a finite number"):
        load_grid(tmp_path / "ring.edges", tmp_path / "p.txt")


# --- the same option validators as run -----------------------------------------------------------


@pytest.mark.parametrize("threads", ["0", "-1"])
def test_threads_are_refused_as_run_refuses_them(tmp_path, ring, threads):
    ran = runner.invoke(app, ["run", str(ring), "--threads", threads, "--out", str(tmp_path / "x.h5")])
    assert_one_line(ran, "threads must be an integer in null or 1..4096")
    for extra in ([], ["--removal", "-q", "--lines", "0-1"]):
        res = runner.invoke(app, ["grid", str(ring), "--threads", threads, *extra])
        assert_one_line(res)
        assert res.stderr == ran.stderr


@pytest.mark.parametrize("top", ["-1", "0"])
def test_top_must_be_at_least_one(ring, top):
    for extra in ([], ["--removal", "-q"]):
        assert_one_line(
            runner.invoke(app, ["grid", str(ring), "--top", top, *extra]), "--top must be an integer >= 1"
        )


def test_an_empty_out_or_figure_is_one_line(tmp_path, ring):
    before = snapshot(tmp_path)
    for option in ("--out", "--figure"):
        res = runner.invoke(app, ["grid", str(ring), "--removal", option, ""])
        assert_one_line(res, "names no file")
    assert snapshot(tmp_path) == before


# --- one output-path policy ---------------------------------------------------------------------


def test_overwrite_never_replaces_the_config_its_files_a_link_or_a_foreign_file(tmp_path, ring):
    cfg = tmp_path / "cfg.json"  # a JSON config is YAML: it could be named as --out
    cfg.write_text(
        json.dumps({**_plain_config(), "model": {"frequencies": {"file": "p.json"}, "inertia": 1.0}})
    )
    (tmp_path / "p.json").write_text(POWER)  # a per-node file named like a table
    os.symlink("cfg.json", tmp_path / "link.json")
    os.link(cfg, tmp_path / "hard.json")
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    (tmp_path / "a.h5.partial").mkdir()  # a killed `antisync run`'s journal
    (tmp_path / "a.h5.partial" / "simulation_key.json").write_text("{}")
    (tmp_path / "t.json.partial").mkdir()
    cases = {
        "cfg.json": "is the config file",
        "hard.json": "is the config file",
        "p.json": "model.frequencies.file",
        "link.json": "is a symbolic link",
        "other.json": "--overwrite replaces only an antisync removal table",
        "a.h5.partial/t.json": "lies inside",
        "t.json.partial/x.json": "lies inside",
    }
    before = snapshot(tmp_path)
    for out, message in cases.items():
        args = [
            "grid",
            str(cfg),
            "--removal",
            "-q",
            "--lines",
            "0-1",
            "--out",
            str(tmp_path / out),
            "--overwrite",
        ]
        assert_one_line(runner.invoke(app, args), message)
        assert snapshot(tmp_path) == before, out


def _plain_config() -> dict:
    return {
        "graph": {"kind": "edgelist", "path": "ring.edges"},
        "sync": {"criterion": "frequency"},
        "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.02, "t_max": 20},
        "realizations": 4,
    }


def test_figure_replaces_only_an_image_of_its_kind(tmp_path, ring):
    (tmp_path / "notes.png").write_text("my notes")
    (tmp_path / "notes.svg").write_text("<html>not an image</html>")
    (tmp_path / "pdf.png").write_bytes(b"%PDF-1.4 a PDF named .png")
    os.symlink("ring.yaml", tmp_path / "link.svg")
    (tmp_path / "r.h5.partial").mkdir()
    cases = {
        "notes.png": "is not a PNG image",
        "notes.svg": "is not an SVG image",
        "pdf.png": "is not a PNG image",
        "link.svg": "is a symbolic link",
        "r.h5.partial/f.png": "lies inside",
    }
    before = snapshot(tmp_path)
    for fig, message in cases.items():
        args = [
            "grid",
            str(ring),
            "--removal",
            "-q",
            "--lines",
            "0-1",
            "--figure",
            str(tmp_path / fig),
            "--overwrite",
        ]
        assert_one_line(runner.invoke(app, args), message)
        assert snapshot(tmp_path) == before, fig
    # images of each kind, by their first bytes
    from antisync.store.outputs import image_problem

    (tmp_path / "a.png").write_bytes(b"\x89PNG\r\n\x1a\n....")
    (tmp_path / "a.pdf").write_bytes(b"%PDF-1.4\n...")
    (tmp_path / "a.svg").write_text('<?xml version="1.0"?>\n<!DOCTYPE svg>\n<svg xmlns="x"></svg>')
    assert [image_problem(tmp_path / f"a.{s}") for s in ("png", "pdf", "svg")] == [None, None, None]
    assert image_problem(tmp_path / "notes.png") == "not a PNG image"


# --- --resume on a finished table compares the arguments -----------------------------------------


def test_resume_of_a_finished_table_refuses_other_arguments(tmp_path, ring):
    out = tmp_path / "t.json"
    args = ["grid", str(ring), "--removal", "--lines", "0-1", "--out", str(out)]
    res = runner.invoke(app, [*args, "-q"])
    assert res.exit_code == 0, res.output
    before = snapshot(tmp_path)
    for extra, message in (
        (["--seed", "12"], "seed: 11 -> 12"),
        (["--realizations", "5"], "realizations: 4 -> 5"),
        (["--beta", "0.5"], "beta: 1.0 -> 0.5"),
        (["--lines", "0-1,1-2"], "lines: 1 asked not in the table (1-2)"),
        (["--lines", "1-2"], "lines: 1 in the table not asked (0-1), 1 asked not in the table (1-2)"),
        (["--set", "dynamics.t_max=30"], "dynamics.t_max: 20.0 -> 30.0"),
    ):
        for quiet in ([], ["-q"]):
            res = runner.invoke(app, [*args, "--resume", *extra, *quiet])
            assert_one_line(res, f"is the finished table of another run ({message}")
        assert snapshot(tmp_path) == before, extra
    # the same arguments (another thread count is the same run): nothing to resume
    res = runner.invoke(app, [*args, "--resume", "--threads", "1"])
    assert res.exit_code == 0 and "is complete: nothing to resume" in res.stderr
    assert snapshot(tmp_path) == before
    # a file that is not a removal table is not resumed either
    other = tmp_path / "o.json"
    other.write_text("{}")
    res = runner.invoke(app, ["grid", str(ring), "--removal", "--out", str(other), "--resume"])
    assert_one_line(res, "not a removal table")


# --- --lines names any line ----------------------------------------------------------------------


ODD_EDGES = 'a-b,c,2\nc,"x,y",2\n"x,y",-1,2\n-1,-2,2\n-2,a-b,2\na,b-c,2\nb-c,a-b,2\na,c,2\n'


def test_lines_name_labels_holding_dashes_commas_and_negative_integers(tmp_path):
    (tmp_path / "odd.csv").write_text(ODD_EDGES)
    cfg = tmp_path / "odd.yaml"
    cfg.write_text("graph: {kind: edgelist, path: odd.csv}\ndynamics: {coupling: raw}\n")

    def rows(lines: str) -> list[str]:
        res = runner.invoke(app, ["grid", str(cfg), "--beta", "0.5", "--lines", lines])
        assert res.exit_code == 0, res.output
        return sorted(line.split("|")[1].strip() for line in res.stdout.splitlines()[4:])

    assert rows("-1--2") == ["-1--2"]
    assert rows("a-b-b-c, -2-a-b") == ["-2-a-b", "a-b-b-c"]  # one split each gives two labels
    assert rows('[[a-b, c], ["x,y", -1], [c, "x,y"]]') == ["-1-x,y", "a-b-c", "c-x,y"]
    res = runner.invoke(app, ["grid", str(cfg), "--lines", "a-b-c"])  # a to b-c, or a-b to c
    assert_one_line(res, "reads two ways, a to b-c and a-b to c")
    assert '[["a", "b-c"]]' in res.stderr and '[["a-b", "c"]]' in res.stderr
    assert_one_line(runner.invoke(app, ["grid", str(cfg), "--lines", "[[a, nope]]"]), "no node 'nope'")
    assert_one_line(runner.invoke(app, ["grid", str(cfg), "--lines", "[[a, c]"]), "not a YAML list of pairs")
    # integer labels: typed values, negative ones included
    labels = [-2, -1, 3]
    assert parse_lines("-1--2,3--1", labels) == [(-1, -2), (3, -1)]
    assert parse_lines("[[-1, 3], ['-2', -1]]", labels) == [(-1, 3), (-2, -1)]
    assert parse_lines("4-5,2-3", [2, 3, 4, 5]) == [(4, 5), (2, 3)]
    # an inline graph may hold both 1 and "1": the plain form cannot tell them apart, the typed one can
    with pytest.raises(GridError, match="is two labels of the grid"):
        parse_lines("1-2", [1, "1", 2])
    assert parse_lines("[[1, 2], ['1', 2]]", [1, "1", 2]) == [(1, 2), ("1", 2)]
