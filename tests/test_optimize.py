"""Design by gradient (antisync/optimize): the budget set, the gradient of the ensemble objective
against central differences of the same discrete function, paired evaluation, the stopping rule,
a killed design resumed to the same iterates, the CLI's bad input and the figures."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.optimize.budget import Budget, project
from antisync.optimize.config import design_from_mapping
from antisync.optimize.descent import Settings, State, run_descent, step
from antisync.optimize.ensemble import evaluate as evaluate_designs
from antisync.optimize.ensemble import make_problem, sample
from antisync.plan.config import config_from_mapping
from antisync.store.design_file import read_design

LOLLIPOP = {"kind": "lollipop", "nodes": 6, "path": 3}


def _problem(integrator="rk4", coupling="normalized", model=None, **kw):
    raw = {
        "graph": LOLLIPOP,
        "dynamics": {
            "integrator": integrator,
            "dt": 0.02 if integrator == "rk4" else 0.005,
            "t_max": 100,
            "coupling": coupling,
        },
        "seed": 3,
    }
    if model:
        raw["model"] = model
    return make_problem(config_from_mapping(raw), **kw)


def test_projection_is_the_nearest_feasible_point():
    rng = np.random.default_rng(0)
    for _ in range(300):
        n = int(rng.integers(1, 9))
        cost = rng.uniform(0.2, 3, n)
        lo = rng.uniform(0, 0.5, n) * (rng.random(n) < 0.5)
        hi = lo + rng.uniform(0.1, 2, n)
        total = float(cost @ lo + rng.uniform(0.05, 0.95) * (cost @ hi - cost @ lo))
        b = Budget.of(total, n, cost=cost, lo=lo, hi=hi)
        y = rng.normal(0, 3, n)
        x = project(y, b)
        assert b.contains(x)
        for _ in range(10):  # no feasible point is nearer to y
            z = project(x + rng.normal(0, 0.5, n), b)
            assert np.sum((y - x) ** 2) <= np.sum((y - z) ** 2) + 1e-9


@pytest.mark.parametrize(
    ("total", "lo", "hi"), [(-1.0, 0.0, np.inf), (1.0, 1.0, np.inf), (10.0, 0.0, 1.0), (1.0, 2.0, 1.0)]
)
def test_a_budget_no_weights_satisfy_is_one_clear_error(total, lo, hi):
    with pytest.raises(ConfigError, match="design"):
        Budget.of(total, 3, lo=lo, hi=hi)


@pytest.mark.parametrize(
    ("integrator", "coupling", "model"),
    [
        ("rk4", "normalized", None),
        ("euler", "raw", None),
        ("rk4", "normalized", {"frequencies": [0.1, -0.1, 0.05, 0.0, -0.05, 0.0]}),
    ],
)
def test_gradient_is_the_central_difference_of_the_same_discrete_times(integrator, coupling, model):
    p = _problem(integrator, coupling, model)
    rng = np.random.default_rng(1)
    x = p.budget.uniform() * rng.uniform(0.7, 1.3, len(p.links))
    ks = np.arange(12)
    s = sample(p, x, 3, ks, cut=None)
    assert np.all(s.status == 0)
    h = 1e-6
    for link in range(len(p.links)):
        up, down = x.copy(), x.copy()
        up[link] += h
        down[link] -= h
        fd = (sample(p, up, 3, ks, cut=None).tau - sample(p, down, 3, ks, cut=None).tau) / (2 * h)
        scale = np.max(np.abs(s.grad[:, link])) + 1.0
        assert np.max(np.abs(fd - s.grad[:, link])) < 1e-5 * scale, link


def test_paired_evaluation_gives_the_sampled_times_and_the_secants_keep_the_times():
    p = _problem()
    x = p.budget.uniform()
    ks = np.arange(200)
    s = sample(p, x, 5, ks)
    tau, status = evaluate_designs(p, [x, p.budget.uniform() * 1.0], 5, ks)
    assert np.array_equal(tau[0], s.tau) and np.array_equal(tau[0], tau[1])
    assert np.array_equal(status[0], s.status)
    plain = sample(p, x, 5, ks, cut=None)
    assert np.array_equal(plain.tau, s.tau)
    # only the outlying (start, link) pairs change, and each to a central secant of tau
    changed = np.argwhere(plain.grad != s.grad)
    rel = np.abs(x[None, :] * plain.grad) / plain.tau[:, None]
    assert np.all(rel[plain.grad != s.grad] > 2.0)
    for r, link in changed[:3]:
        h = 0.01 * x[link]
        up, down = x.copy(), x.copy()
        up[link] += h
        down[link] -= h
        t, _ = evaluate_designs(p, [up, down], 5, ks[r : r + 1])
        assert s.grad[r, link] == pytest.approx((t[0, 0] - t[1, 0]) / (2 * h), rel=1e-12)


def test_descent_lowers_the_mean_time_of_the_lollipop_from_uniform():
    p = _problem(lower=0.05)
    settings = Settings(iterations=30, starts=128, check_every=10, check_starts=1000, step=0.05)
    state = State.first(p.budget.uniform(), settings)
    checks = []
    state = run_descent(p, state, settings, save=lambda s, r, c: checks.append(c) if c else None)
    assert state.done and p.budget.contains(state.best)
    assert any(c["accepted"] for c in checks)
    tau, _ = evaluate_designs(p, [state.best, p.budget.uniform()], 99, np.arange(2000))
    diff = tau[0] - tau[1]
    assert diff.mean() < -5 * diff.std(ddof=1) / np.sqrt(diff.size)


def test_a_killed_descent_resumes_to_the_same_iterates():
    p = _problem(lower=0.05)
    settings = Settings(iterations=6, starts=32, check_every=3, check_starts=200)
    whole = []
    run_descent(
        p, State.first(p.budget.uniform(), settings), settings, save=lambda s, r, c: whole.append(r["x"])
    )
    state = State.first(p.budget.uniform(), settings)
    part = []
    for _ in range(4):  # "killed" after four iterations: the stored state is all that is left
        state, record, _ = step(p, state, settings)
        part.append(record["x"])
    run_descent(p, state, settings, save=lambda s, r, c: part.append(r["x"]))
    assert len(part) == len(whole) == 6
    assert all(np.array_equal(a, b) for a, b in zip(part, whole, strict=True))


DESIGN = """
graph: {kind: lollipop, nodes: 6, path: 3}
dynamics: {integrator: rk4, dt: 0.04, t_max: 100}
seed: 3
design: {lower: 0.05, iterations: 4, starts: 32, check_every: 2, check_starts: 200, evaluate: 300,
         output: OUT}
"""


def test_cli_design_writes_a_resumable_file_and_its_figures(tmp_path):
    cfg = tmp_path / "d.yaml"
    out = tmp_path / "d.h5"
    cfg.write_text(DESIGN.replace("OUT", str(out)))
    runner = CliRunner()
    res = runner.invoke(app, ["design", str(cfg), "-q"])
    assert res.exit_code == 0, res.output
    rec = read_design(out)
    assert rec["complete"] and len(rec["iterations"]) <= 4
    names = [r["design"] for r in rec["verification"]["rows"]]
    assert names[:4] == ["designed", "uniform", "lambda2", "resistance"]
    assert sorted(p.name for p in (tmp_path / "d_figures").iterdir()) == [
        "d_lambda.png",
        "d_network.png",
        "d_progress.png",
        "d_tau.png",
    ]
    before = out.read_bytes()
    again = runner.invoke(app, ["design", str(cfg), "-q"])
    assert again.exit_code == 2 and "--resume" in again.output
    done = runner.invoke(app, ["design", str(cfg), "--resume", "--no-figures"])
    assert done.exit_code == 0 and "nothing to do" in done.output
    assert out.read_bytes() == before
    rep = runner.invoke(app, ["report", str(out), "--out", str(tmp_path / "rep")])
    assert rep.exit_code == 0 and len(list((tmp_path / "rep").iterdir())) == 4


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("budget: -3", "design.budget must be a positive"),
        ("lower: 5", "outside what the bounds allow"),
        ("candidates: ['1-2']", "already a link"),
        ("candidates: ['1-99']", "not a pair of two different nodes"),
        ("objective: speed", "design.objective"),
        ("upper: 0.01", "design.upper"),
        ("colour: red", "design.colour"),
        ("start: worst", "design.start"),
    ],
)
def test_bad_design_input_is_one_line_exit_2_and_touches_nothing(tmp_path, change, message):
    out = tmp_path / "d.h5"
    out.write_bytes(b"an earlier file")
    text = DESIGN.replace("output: OUT}", f"output: {out}, {change}}}")
    assert change in text  # the last of a key wins
    cfg = tmp_path / "d.yaml"
    cfg.write_text(text)
    res = CliRunner().invoke(app, ["design", str(cfg), "--overwrite"])
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert out.read_bytes() == b"an earlier file"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"sync": {"criterion": "relative"}}, "sync.criterion relative"),
        ({"dynamics": {"integrator": "rodas4"}, "model": {"inertia": 1.0}}, "euler or rk4"),
        ({"backend": "cuda"}, "runs on the CPU"),
        ({"model": {"start": {"around": "locked", "width": 0.5}}}, "cannot use model.start"),
        ({}, None),
    ],
)
def test_what_a_design_cannot_differentiate_is_refused_before_anything_runs(extra, message):
    raw = {"graph": LOLLIPOP, "design": {}, **extra}
    if message is None:
        del raw["design"]
        message = "needs a 'design:' section"
    with pytest.raises(ConfigError, match=message):
        design_from_mapping(raw)


@pytest.mark.parametrize("name", ["karate_design.yaml", "ieee39_design.yaml"])
def test_the_shipped_design_configs_load_and_their_graphs_are_feasible(name):
    from pathlib import Path

    from antisync.optimize.config import load_design_config

    cfg, spec = load_design_config(Path(__file__).resolve().parent.parent / "configs" / name)
    problem = make_problem(cfg, spec.budget, lower=spec.lower, upper=spec.upper)
    assert problem.budget.contains(problem.start)  # the network's own weights spend the budget


def test_a_candidate_link_is_a_variable_absent_at_zero_and_its_derivative_is_right():
    p = _problem(candidates=["1-6"], candidate_cost=2.0)
    assert p.labels[-1] == "1-6" and p.candidate.tolist() == [False] * 6 + [True]
    assert p.start[-1] == 0.0 and p.budget.cost[-1] == 2.0 and p.budget.total == 6.0
    assert p.budget.contains(p.start)  # the graph itself, candidate absent
    x = p.budget.uniform()
    assert x[-1] > 0
    ks = np.arange(8)
    s = sample(p, x, 3, ks, cut=None)
    h = 1e-6
    up, down = x.copy(), x.copy()
    up[-1] += h
    down[-1] -= h
    fd = (sample(p, up, 3, ks, cut=None).tau - sample(p, down, 3, ks, cut=None).tau) / (2 * h)
    assert np.max(np.abs(fd - s.grad[:, -1])) < 1e-5 * (np.max(np.abs(fd)) + 1)
    # at weight 0 the link is in the pattern with a derivative of its own (it can grow back)
    zero = sample(p, p.start, 3, ks, cut=None)
    assert np.any(zero.grad[:, -1] != 0)


def test_validate_reads_a_design_config_and_run_sends_it_to_design():
    from pathlib import Path

    config = str(Path(__file__).resolve().parent.parent / "configs" / "karate_design.yaml")
    ok = CliRunner().invoke(app, ["validate", config])
    assert ok.exit_code == 0 and "# ok: design of 78 link weight(s) of 34 nodes" in ok.output
    run = CliRunner().invoke(app, ["run", config])
    assert run.exit_code == 2 and "antisync design" in run.output


def _write_design_config(tmp_path, out, extra: str = "") -> str:
    cfg = tmp_path / "d.yaml"
    cfg.write_text(DESIGN.replace("output: OUT}", f"output: {out}{extra}}}"))
    return str(cfg)


@pytest.mark.parametrize("kind", ["hdf5", "text", "link", "config"])
def test_design_overwrite_never_replaces_a_file_that_is_not_a_design(tmp_path, kind):
    """``antisync design --overwrite`` goes through the one output policy: a user's own HDF5
    file, a text file, a symbolic link and the config itself are refused in one line (exit 2)
    and left as they were, ``--overwrite`` or not."""
    import h5py

    out = tmp_path / "d.h5"
    if kind == "hdf5":
        with h5py.File(out, "w") as f:
            f["data"] = np.arange(3)
    elif kind == "text":
        out.write_text("my notes\n")
    elif kind == "link":
        (tmp_path / "target.h5").write_text("elsewhere\n")
        out.symlink_to(tmp_path / "target.h5")
    cfg = _write_design_config(tmp_path, out)
    if kind == "config":
        out = tmp_path / "d.yaml"
        cfg = _write_design_config(tmp_path, out)
        # the config's own path as its output: refused (it must end in .h5 first)
    before = out.read_bytes()
    for flags in ([], ["--overwrite"], ["--resume"]):
        res = CliRunner().invoke(app, ["design", cfg, "-q", "--no-figures", *flags])
        assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
        assert "design.output" in res.output or "exists" in res.output, res.output
        assert out.read_bytes() == before
    assert out.is_symlink() == (kind == "link")


def test_a_design_resumes_with_other_threads_and_keeps_its_rows_in_order(tmp_path):
    """Threads are where a design runs, not what it computes: a design started with ``--threads
    1`` and finished by a ``--resume`` without it; its verification rows in the order an
    uninterrupted design lists them (the baselines read back from the file are not re-sorted)."""
    from antisync.store.design_file import write_design

    out = tmp_path / "d.h5"
    cfg = _write_design_config(tmp_path, out)
    res = CliRunner().invoke(app, ["design", cfg, "-q", "--no-figures", "--threads", "1"])
    assert res.exit_code == 0, res.output
    whole = read_design(out)
    # cut it back to an unfinished file holding its baselines, as a killed run leaves it
    rec = {**whole, "complete": False}
    for key in ("verification", "sensitivity"):
        rec.pop(key, None)
    rec["baselines"] = {k: v for k, v in whole["baselines"].items() if k != "designed"}
    write_design(out, rec)
    res = CliRunner().invoke(app, ["design", cfg, "-q", "--no-figures", "--resume"])
    assert res.exit_code == 0, res.output
    again = read_design(out)
    names = [r["design"] for r in again["verification"]["rows"]]
    assert names == [r["design"] for r in whole["verification"]["rows"]]


def test_a_repeated_candidate_is_named_as_repeated(tmp_path):
    cfg = _write_design_config(tmp_path, tmp_path / "d.h5", ", candidates: ['1-6', '6-1']")
    res = CliRunner().invoke(app, ["design", cfg])
    assert res.exit_code == 2 and "names the same link as '1-6'" in res.output, res.output


def test_summary_and_report_read_design_files_and_refuse_another_version(tmp_path):
    import h5py

    out = tmp_path / "d.h5"
    cfg = _write_design_config(tmp_path, out)
    assert CliRunner().invoke(app, ["design", cfg, "-q", "--no-figures"]).exit_code == 0
    res = CliRunner().invoke(app, ["summary", str(out)])
    assert res.exit_code == 0 and "| designed |" in res.output and "| lambda2 |" in res.output, res.output
    res = CliRunner().invoke(app, ["summary", str(out), "--format", "csv"])
    assert res.exit_code == 0 and res.output.startswith("design,mean_tau")
    with h5py.File(out, "a") as f:
        f.attrs["version"] = 99
    for cmd in (["report", str(out), "--out", str(tmp_path / "rep")], ["summary", str(out)]):
        res = CliRunner().invoke(app, cmd)
        assert res.exit_code == 2 and "format version 99" in res.output, res.output
    assert not (tmp_path / "rep").exists()


def test_the_default_start_is_the_best_baseline_on_validation_starts(tmp_path):
    """``design.start: best`` (the default): the descent starts from the baseline with the
    smallest mean tau on the validation starts, named in the log with every baseline's mean; the
    first iterate is that baseline's weights."""
    out = tmp_path / "d.h5"
    cfg = _write_design_config(tmp_path, out)
    res = CliRunner().invoke(app, ["design", cfg, "--no-figures"])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith("design.start best: "))
    means = dict(
        part.rsplit(" ", 1) for part in line.split("(mean tau on 200 validation starts: ")[1][:-1].split(", ")
    )
    pick = line.split()[2]
    assert pick == min(means, key=lambda k: float(means[k]))
    rec = read_design(out)
    assert np.allclose(rec["iterations"][0]["x"], rec["baselines"][pick])


@pytest.mark.parametrize(("model", "weight"), [(None, 80.0), ({"inertia": 1.0, "damping": 1.0}, 2e4)])
def test_a_design_the_step_cannot_integrate_is_refused_not_timed(model, weight):
    """A design moves the weights: one that gives a link much of the budget can make the run's
    ``dynamics.dt`` repel synchrony (raw coupling, RK4 at dt 0.02: stable for the lollipop's unit
    weights, not for one link at weight 80, or 2e4 with inertia, whose modes oscillate).
    :func:`sample` and :func:`evaluate` refuse it in one
    line naming the design and what to lower, as ``antisync run`` refuses the graph, instead of
    returning the times of an unstable integration."""
    from antisync.optimize.ensemble import evaluate, sample

    problem = _problem(coupling="raw", model=model)
    start = np.asarray(problem.start, dtype=float)
    problem.check_step(start, "the start")  # the run's own graph: fine
    heavy = start.copy()
    heavy[0] = weight
    ks = np.arange(2, dtype=np.uint64)
    with pytest.raises(ConfigError, match="a design's weights: ") as info:
        sample(problem, heavy, 3, ks)
    assert "design.upper" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="design 2 of 2"):
        evaluate(problem, [start, heavy], 3, ks)
