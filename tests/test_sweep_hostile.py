"""Hostile inputs to `antisync sweep --grid/--zip` (issue 41): job names that cannot collide,
old files named the old way, a key given twice, a grid too large to plan.

Every run is tiny (4-node lollipop, 16 realizations, t_max 40): seconds each once compiled.
"""

from __future__ import annotations

import math

import pytest
from helpers import CrashAfter, assert_one_line, comparable
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError, StoreError
from antisync.sweeps import family_graphs, load_sweep, load_sweep_text, main_jobs, run_sweep, sweep_summary
from antisync.sweeps import points as points_mod
from antisync.sweeps import stages as stages_mod
from antisync.sweeps.points import point_label

CFG = """
name: h
graph: {kind: lollipop, nodes: 4, path: 1}
betas: []
realizations: 16
block_size: 8
seed: 2
dynamics: {dt: 0.05, integrator: rk4, t_max: 40}
screen: {enabled: false}
"""


def _old_name(value) -> str:
    """How grid values were named before issue 41: six significant digits."""
    return f"{value:g}"


def _cli(*args: str):
    return CliRunner().invoke(app, ["sweep", *args])


def _by_point(path) -> dict:
    """A sweep file's records by point label, without the fields that name the job."""
    out: dict[str, list] = {}
    for r in comparable(sweep_summary(path))["records"]:
        out.setdefault(r["point"], []).append(
            {k: v for k, v in r.items() if k not in ("job", "grid", "point")}
        )
    return out


# ---- item 1: two values that print alike are two jobs, each with its own numbers ----------
@pytest.mark.parametrize("grid", ["seed=1000001,1000002", "model.phase_lag=0.1,0.1000001"])
def test_values_alike_to_six_digits_are_two_points_with_their_own_numbers(tmp_path, grid):
    """Seeds 1000001 and 1000002 (both ``1e+06`` with ``:g``), lags 0.1 and 0.1000001: two
    jobs; killed after one chunk and finished with ``--resume``, each point holds the numbers
    a sweep of that value alone gives."""
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    key, text = grid.split("=")
    sw = load_sweep(cfg, grid=[grid])
    _, meta = main_jobs(sw, family_graphs(sw))
    assert len({m["job"] for m in meta}) == 2
    labels = [point_label(p.values) for p in sw.points]
    assert labels == [f"{key}={v}" for v in text.split(",")]
    out = tmp_path / "h.h5"
    with pytest.raises(RuntimeError, match="killed"):
        run_sweep(sw, output=out, progress=False, chunk_realizations=8, executor=CrashAfter(1))
    res = _cli(str(cfg), "--out", str(out), "--grid", grid, "--resume", "-q")
    assert res.exit_code == 0, res.output
    got = _by_point(out)
    assert sorted(got) == sorted(labels)
    for value, label in zip(text.split(","), labels, strict=True):
        ref = tmp_path / f"ref{value}.h5"
        res = _cli(str(cfg), "--out", str(ref), "--grid", f"{key}={value}", "-q")
        assert res.exit_code == 0, res.output
        assert got[label] == _by_point(ref)[label]
    if key == "seed":  # other seeds, other numbers: the two points are not one
        assert got[labels[0]] != got[labels[1]]
    # `--resume` of the finished file keeps it, and it still shows each point's own numbers
    res = _cli(str(cfg), "--out", str(out), "--grid", grid, "--resume", "-q")
    assert res.exit_code == 0, res.output
    assert _by_point(out) == got


def test_names_of_ordinary_values_are_unchanged_and_every_name_is_distinct():
    """Values whose six-digit text reads back as themselves keep their names (files of shipped
    configs resume); every other value is written in full, so no two values share a text."""
    sw = load_sweep_text(
        CFG,
        grid=["model.phase_lag=0.1,0.2", "realizations=1000,2000", "seed=1000000,2"],
    )
    _, meta = main_jobs(sw, family_graphs(sw))
    assert meta[0]["job"] == "lollipop_4_1_phase_lag0.1_realizations1000_seed1e+06"
    assert meta[-1]["job"] == "lollipop_4_1_phase_lag0.2_realizations2000_seed2"
    assert point_label(meta[0]["point"]) == "model.phase_lag=0.1, realizations=1000, seed=1e+06"
    tricky = [
        0.1, 0.1000001, 1000000, 1000001, 1000002, 1e6 + 0.5, 2**53, 2**53 + 1, 10**30, 10**30 + 1,
        0.99, 0.9900001, 1e-5, 1.00000001e-5, -0.0, 1.5, math.inf, -math.inf, math.nan,
        True, False, None, "0.1", "nan", "none", "true", "rk4", "a b", "a_b",
        [0.1, 0.2], [0.1, 0.2000001], {"distribution": "normal", "sd": 0.1},
        {"distribution": "normal", "sd": 0.1000001},
    ]  # fmt: skip
    texts = [points_mod.point_text(v) for v in tricky]
    assert len(set(texts)) == len(tricky), texts
    assert [points_mod.point_text(v) for v in (0.1, 0.2, 1000, 2, 1.0, 0.99, 1e-5)] == [
        "0.1", "0.2", "1000", "2", "1", "0.99", "1e-05"
    ]  # fmt: skip
    # a threshold list names its jobs the same way
    sw = load_sweep_text(
        "sweep: {family: lollipop, nodes: 4, path: 1}\nthresholds: [0.99, 0.9900001]\nbetas: []\n"
    )
    _, meta = main_jobs(sw, family_graphs(sw))
    assert [m["job"] for m in meta] == ["lollipop_4_1_r0.99", "lollipop_4_1_r0.9900001"]


def test_two_jobs_of_one_name_are_refused_before_anything_runs(tmp_path, monkeypatch):
    """The second guard: whatever names two jobs alike is refused in one line naming both,
    before the output exists. Shown with the old six-digit suffix, and with a graph named like
    another graph's top-stage job."""
    monkeypatch.setattr(
        stages_mod,
        "point_suffix",
        lambda point, axes: "".join(f"_{k.rsplit('.', 1)[-1]}{_old_name(v)}" for k, v in point.values),
    )
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    out = tmp_path / "h.h5"
    res = _cli(str(cfg), "--out", str(out), "--grid", "seed=1000001,1000002")
    assert_one_line(res, "grid point seed=1000001 and graph lollipop_4_1 grid point seed=1000002")
    assert "would both be job 'lollipop_4_1_seed1e+06'" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.yaml"]
    monkeypatch.undo()
    text = (
        "sweep: {family: graphs, graphs: [{kind: atlas, index: 52, name: g}, "
        "{kind: atlas, index: 38, name: g_top}]}\nbetas: []\nrealizations: 16\ntop: {graphs: 1}\n"
    )
    sw = load_sweep_text(text)
    with pytest.raises(ConfigError, match=r"graph g_top and graph g \(top stage\) would both be job 'g_top'"):
        stages_mod.check_sweep(sw, family_graphs(sw))


# ---- item 1, old files: named the old way, refused, never mixed --------------------------
def _old_style(monkeypatch, *, guard: bool = True) -> None:
    """Name grid values as antisync did before issue 41 (``raising=False``: the module of an
    older checkout has no such function)."""
    monkeypatch.setattr(points_mod, "number_name", _old_name, raising=False)
    monkeypatch.setattr(stages_mod, "number_name", _old_name, raising=False)
    if not guard:  # and without the checks that refuse what it wrote
        monkeypatch.setattr(stages_mod, "_refuse_shared_names", lambda descs, sweep: None, raising=False)
        monkeypatch.setattr(
            stages_mod, "_refuse_renamed_jobs", lambda path, stored, meta: None, raising=False
        )


def test_resume_of_a_file_named_the_old_way_is_refused(tmp_path, monkeypatch):
    """A sweep killed while seeds were named with six digits (1234567 -> ``1.23457e+06``): its
    ``--resume`` now names the job otherwise, and is refused in one line, the file untouched."""
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    out = tmp_path / "h.h5"
    grid = "seed=1,1234567"
    _old_style(monkeypatch)
    with pytest.raises(RuntimeError, match="killed"):
        run_sweep(
            load_sweep(cfg, grid=[grid]),
            output=out,
            progress=False,
            chunk_realizations=8,
            checkpoint_seconds=0,
            executor=CrashAfter(2),
        )
    monkeypatch.undo()
    assert out.exists()  # a checkpoint with the old job names
    before = out.read_bytes()
    res = _cli(str(cfg), "--out", str(out), "--grid", grid, "--resume")
    assert_one_line(res, "'lollipop_4_1_seed1.23457e+06', this antisync 'lollipop_4_1_seed1234567'")
    assert "--overwrite" in res.stderr
    assert out.read_bytes() == before
    res = _cli(str(cfg), "--out", str(out), "--grid", grid, "--overwrite", "-q")
    assert res.exit_code == 0, res.output
    assert sorted(_by_point(out)) == ["seed=1", "seed=1234567"]


def test_a_file_whose_points_share_a_job_is_refused_by_summary_and_resume(tmp_path, monkeypatch):
    """What the old naming wrote for seeds 1000001 and 1000002 (refused, then finished by
    ``--resume`` with one job for both points): ``summary`` and ``--resume`` now refuse it,
    naming both points, instead of showing one point's numbers under the other."""
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    out = tmp_path / "h.h5"
    grid = "seed=1000001,1000002"
    _old_style(monkeypatch, guard=False)
    with pytest.raises(StoreError, match="already merged"):
        run_sweep(load_sweep(cfg, grid=[grid]), output=out, progress=False)
    run_sweep(load_sweep(cfg, grid=[grid]), output=out, resume=True, progress=False)
    monkeypatch.undo()
    with pytest.raises(StoreError, match="seed=1000001 and seed=1000002 share the name"):
        sweep_summary(out)
    res = CliRunner().invoke(app, ["summary", str(out)])
    assert_one_line(res, "seed=1000001 and seed=1000002 share the name 'lollipop_4_1_seed1e+06'")
    res = _cli(str(cfg), "--out", str(out), "--grid", grid, "--resume")
    assert_one_line(res, "grid points seed=1000001 and seed=1000002 under one job")


# ---- item 2: a key given twice -----------------------------------------------------------
@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["--grid", "dynamics.dt=0.01,0.02", "--grid", "dynamics.dt=0.05"],
            "--grid dynamics.dt is given twice",
        ),
        (
            ["--zip", "dynamics.dt=0.01,0.02", "--zip", "dynamics.dt=0.05,0.04"],
            "--zip dynamics.dt is given twice",
        ),
        (["--grid", "dynamics.dt=0.01,0.02", "--zip", "dynamics.dt=0.05"], "given to both --grid and --zip"),
        (["--grid", "seed=1,2,1"], "sweep.grid.seed lists a value twice (1)"),
        (["--grid", "seed=1,1.0"], "sweep.grid.seed lists a value twice"),
    ],
)
def test_a_key_given_twice_is_refused_in_one_line(tmp_path, options, message):
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    res = _cli(str(cfg), "--out", str(tmp_path / "h.h5"), *options)
    assert_one_line(res, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.yaml"]


def test_an_option_on_a_key_of_the_config_grid_replaces_it_and_says_so(tmp_path):
    """``--grid KEY`` replaces the config's ``sweep.grid.KEY`` as ``--set`` replaces a value,
    and says so; the config's ``zip`` key given to ``--grid`` is refused; a config grid that
    is not a mapping is refused, not replaced."""
    text = CFG + "sweep: {grid: {seed: [1, 2, 3]}, zip: {dynamics.dt: [0.05, 0.04]}}\n"
    sw = load_sweep_text(text, grid=["seed=7,8"])
    assert [p.as_dict()["seed"] for p in sw.points] == [7, 7, 8, 8]
    assert sw.notes == ("--grid seed replaces the config's sweep.grid.seed (3 value(s))",)
    with pytest.raises(ConfigError, match="--grid dynamics.dt: the config's sweep.zip already sweeps"):
        load_sweep_text(text, grid=["dynamics.dt=0.01"])
    with pytest.raises(ConfigError, match="sweep.grid must be a mapping"):
        load_sweep_text(CFG + "sweep: {grid: [1, 2]}\n", grid=["seed=1,2"])
    assert load_sweep_text(CFG, grid=["seed=1,2"]).notes == ()


# ---- item 3: a grid too large to plan ----------------------------------------------------
def _values(n: int, first: int = 0) -> str:
    return ",".join(str(first + i) for i in range(n))


def test_a_900000_point_grid_is_refused_at_once_naming_the_count(tmp_path):
    """3 axes of 100, 100 and 90 values: refused from the axes' lengths before any point is
    expanded (it used to plan for many minutes), one line with the count and the limit."""
    cfg = tmp_path / "h.yaml"
    cfg.write_text(CFG)
    res = _cli(
        str(cfg),
        "--out",
        str(tmp_path / "h.h5"),
        "--grid",
        f"seed={_values(100)}",
        "--grid",
        f"dynamics.dt={','.join(repr(0.01 + i * 1e-4) for i in range(100))}",
        "--grid",
        f"dynamics.t_max={_values(90, first=10)}",
    )
    assert_one_line(res, "900,000 grid points (100 x 100 x 90); a grid sweep runs at most 10,000 jobs")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.yaml"]


def test_the_limit_counts_graphs_thresholds_and_repeats():
    axis = [f"seed={_values(2501)}"]
    with pytest.raises(
        ConfigError,
        match=r"2,501 grid points \(2,501\) x 2 graphs x 2 \(thresholds x repeats\) = 10,004 jobs",
    ):
        load_sweep_text(
            "sweep: {family: lollipop, nodes: [4, 5], path: 1}\nthresholds: [0.9, 0.99]\nbetas: []\n",
            grid=axis,
        )
    # one list with a value listed twice at its end: found in one pass, not pair by pair
    values = _values(5000) + ",0"
    with pytest.raises(ConfigError, match=r"sweep.grid.seed lists a value twice \(0\)"):
        load_sweep_text(CFG, grid=[f"seed={values}"])
