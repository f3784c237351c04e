"""``sync.give_up``: a trajectory whose frequency deviations never came within a band by a time
is stopped there as GAVE_UP (a machine still slipping). Every other trajectory is the one
integrated without the rule, bit for bit; a GAVE_UP is a start that without the rule never
locks by ``t_max`` (on these starts); the refusals; the removal table counts it apart."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_models import LOLLIPOP
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.execution.dispatch import job_model_params
from antisync.grids.errors import GridError
from antisync.grids.removal import line_removal
from antisync.grids.removal_table import RemovalTable, line_rows
from antisync.kernels import implicit
from antisync.plan.config import load_config, load_config_text
from antisync.plan.jobs import make_job
from antisync.report.removal import removal_figure
from antisync.status import GAVE_UP, NOT_SYNCED, SYNCED, Status

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


# these compare removals with and without the rule at one coarse tolerance (rtol = atol = 1e-4,
# fast): the tolerance check rightly warns that their times depend on it, which is not tested here
COARSE_TOLERANCE = pytest.mark.filterwarnings("ignore:WARNING. tolerances checked:UserWarning")


def test_giving_up_stops_only_starts_that_never_lock():
    """IEEE 39 (generators beside first-order loads, frequency locking) at 40 starts, Rodas4
    with and without ``give_up = (10 s, 1 rad/s)``: the same steps and crossing on every start
    that locks, GAVE_UP exactly on the starts that without the rule never lock by t_max = 40 s."""
    cfg = load_config(CONFIGS / "ieee39_grid.yaml", ["realizations=40", "dynamics.t_max=40"])
    job = make_job(cfg)
    m = 40
    ks = np.arange(m, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets[:1])
    empty = np.zeros((0, job.csr.weights.size))
    net = (cfg.seed, 0, m, job.csr.indptr, job.csr.indices, job.csr.weights, empty, params)
    run = dict(dt=cfg.dynamics.dt, max_steps=cfg.dynamics.max_steps, rtol=1e-4, atol=1e-4)
    full = implicit.simulate_model(*net, **run)
    cut = implicit.simulate_model(*net, **run, give_up=(10.0, 1.0))
    assert (full.status0 == NOT_SYNCED).any() and (full.status0 == SYNCED).mean() > 0.5
    np.testing.assert_array_equal(cut.status0 == GAVE_UP, full.status0 == NOT_SYNCED)
    ok = full.status0 == SYNCED
    np.testing.assert_array_equal(cut.status0[ok], SYNCED)
    np.testing.assert_array_equal(cut.steps0[ok], full.steps0[ok])
    np.testing.assert_array_equal(cut.frac0[ok], full.frac0[ok])
    # a band no start's deviations exceed after their start: nothing is given up
    wide = implicit.simulate_model(*net, **run, give_up=(10.0, 1e9))
    np.testing.assert_array_equal(wide.status0, full.status0)
    np.testing.assert_array_equal(wide.steps0, full.steps0)


def test_a_slipping_trajectory_ends_at_the_time_given():
    """Two machines whose injections exceed the line's capacity (``P = +-2``, ``K = 1``) can
    never lock: from a slip already under way the trajectory ends GAVE_UP at the first accepted
    step at or after ``after``."""
    indptr, indices, weights = np.array([0, 1, 2]), np.array([1, 0]), np.array([1.0, 1.0])
    plan = implicit.factor_plan(indptr, indices)
    eq = (np.array([2.0, -2.0]), weights, indptr, indices, 1.0, 0.0, np.ones(2), np.ones(2))
    args = (
        np.array([0.0, 1.0]),
        np.array([2.0, -2.0]),
        eq,
        implicit.CRIT_FREQUENCY,
        1e-3,
        100.0,
        0.01,
        1e-6,
        1e-6,
        plan,
    )
    st, t, *_ = implicit.rodas4_sync(*args, False, math.inf, 0.0)
    assert st == NOT_SYNCED and t == 100.0
    st, t, *_ = implicit.rodas4_sync(*args, False, 7.5, 0.5)
    assert st == GAVE_UP and 7.5 <= t < 8.0


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("sync: {criterion: frequency, give_up: {after: 20}}", "sync.give_up must be a mapping"),
        ("sync: {criterion: frequency, give_up: 5}", "sync.give_up must be a mapping"),
        ("sync: {give_up: {after: 20, band: 1}}", "needs sync.criterion frequency"),
        (
            "sync: {criterion: frequency, give_up: {after: -1, band: 1}}",
            "sync.give_up.after must be a positive",
        ),
        ("sync: {criterion: frequency, give_up: {after: 20, band: 0.0001}}", "wider than sync.tolerance"),
        ("sync: {criterion: frequency, give_up: {after: 20, band: 1}}", "use integrator rodas4"),
        (
            "sync: {criterion: frequency, give_up: {after: 300, band: 1}}\n"
            "dynamics: {integrator: rodas4, t_max: 200}",
            "must come before dynamics.t_max",
        ),
    ],
)
def test_a_give_up_rule_that_cannot_hold_is_refused(text, words):
    with pytest.raises(ConfigError, match=words):
        load_config_text(LOLLIPOP + "model: {inertia: 0.5}\n" + text + "\n")


def test_only_the_removal_counts_gave_up(tmp_path):
    """``antisync run`` refuses the rule in one line (its estimators know no GAVE_UP), and
    leaves no file."""
    path = tmp_path / "c.yaml"
    path.write_text(
        LOLLIPOP + "model: {inertia: 0.5}\ndynamics: {integrator: rodas4, dt: 0.01}\n"
        "sync: {criterion: frequency, give_up: {after: 20, band: 1}}\n"
        "lambda: {method: central-difference}\n"
        f"output: {tmp_path / 'out.h5'}\n"
    )
    res = CliRunner().invoke(app, ["run", str(path)])
    assert res.exit_code == 2, res.output
    assert "only `antisync grid --removal` counts" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "out.h5").exists()


def test_the_removal_table_counts_gave_up_apart_and_as_not_synchronized():
    status0 = np.array([SYNCED, SYNCED, GAVE_UP, NOT_SYNCED], dtype=np.int8)
    status = np.array([[SYNCED], [GAVE_UP], [GAVE_UP], [SYNCED]], dtype=np.int8)
    tau0 = np.array([10.0, 12.0, np.nan, np.nan])
    tau = np.array([[11.0], [np.nan], [np.nan], [30.0]])
    rows = line_rows([(0, 1)], ["a", "b"], set(), 1.0, status0, tau0, status, tau)
    (r,) = rows
    assert (r.synced_before, r.synced_after, r.lost, r.gained, r.gave_up) == (2, 2, 1, 1, 2)
    config = {"sync": {"criterion": "frequency", "give_up": {"after": 20.0, "band": 1.0}}}
    table = RemovalTable("g", 1.0, 1, tuple(rows), status0, tau0, status, tau, config=config)
    assert table.gave_up0 == 1 and table.summary()["gave_up"] == 2
    assert table.p_sync == 0.5
    assert "stopped by sync.give_up" in table.to_markdown() and "1 intact, 2 after" in table.to_markdown()
    assert "slipping" in Status.GAVE_UP.message


@COARSE_TOLERANCE
def test_a_removal_with_the_rule_is_the_removal_without_it_where_it_did_not_give_up(tmp_path):
    """IEEE 39, two lines, 24 starts, Rodas4: the table with ``give_up`` holds GAVE_UP (or, for
    the audit's sample integrated to t_max, NOT_SYNCED) exactly where the table without it holds
    NOT_SYNCED, the same statuses and tau elsewhere, the same
    ``P_sync``, ``lost`` and ``gained``; a journal written with the rule is refused by a run
    without it in one line naming the rule (its key holds the whole sync section)."""
    run = dict(
        lines="1-2,2-3",
        realizations=24,
        dynamics={"integrator": "rodas4", "rtol": 1e-4, "atol": 1e-4, "t_max": 40.0},
        **{"lambda": {"method": "finite-difference"}},
    )
    rule = {"sync": {"criterion": "frequency", "tolerance": 1e-3, "give_up": {"after": 10.0, "band": 1.0}}}
    journal = tmp_path / "t.partial"
    cut = line_removal(CONFIGS / "ieee39_grid.yaml", journal=journal, **run, **rule)
    with pytest.raises(GridError, match="another removal run .config.sync.give_up"):
        line_removal(CONFIGS / "ieee39_grid.yaml", journal=journal, **run)
    full = line_removal(CONFIGS / "ieee39_grid.yaml", **run)
    a = np.column_stack([cut.status0, cut.status])
    b = np.column_stack([full.status0, full.status])
    assert (a == GAVE_UP).any()
    # the audit's sample (at least AUDIT_MIN given-up trajectories) ran to t_max: NOT_SYNCED
    assert cut.audit["sampled"] >= 2 and cut.audit["locked"] == 0
    assert int((a == NOT_SYNCED).sum()) == cut.audit["sampled"]
    np.testing.assert_array_equal((a == GAVE_UP) | (a == NOT_SYNCED), b == NOT_SYNCED)
    np.testing.assert_array_equal(a[a != GAVE_UP], b[a != GAVE_UP])
    np.testing.assert_array_equal(cut.tau, full.tau)
    np.testing.assert_array_equal(cut.tau0, full.tau0)
    for x, y in zip(cut.rows, full.rows, strict=True):
        assert (x.p_after, x.lost, x.gained) == (y.p_after, y.lost, y.gained)
    assert sum(r.gave_up for r in cut.rows) == cut.gave_up
    # the figure is drawn from the table (its title counts the stopped trajectories)
    png = removal_figure(cut, None, tmp_path / "cut.png")
    assert png.read_bytes().startswith(b"\x89PNG")


def test_a_trip_refuses_the_rule_in_one_line():
    """``--trip`` runs from the operating point for ``--t-max``: it has no slipping random
    starts to give up on, so the rule is refused rather than ignored."""
    res = CliRunner().invoke(
        app,
        [
            "grid",
            str(CONFIGS / "ieee39_grid.yaml"),
            "--trip",
            "--set",
            "dynamics.integrator=rodas4",
            "--set",
            "sync.give_up={after: 5, band: 1.0}",
        ],
    )
    assert res.exit_code == 2, res.output
    assert "sync.give_up" in res.output and "a trip runs from the operating point" in res.output
    assert len(res.output.strip().splitlines()) == 1


def _low_damping(factor: float) -> dict:
    """IEEE 39 with generator damping ``D = factor m`` (the shipped grid has ``D = m``; 0.2 m is
    2 p.u. on the machine base for H = 5 s, a common textbook value), loads as shipped."""
    read = _numbers
    inertia = read(CONFIGS / "ieee39_grid_inertia.txt")
    damping = np.where(inertia > 0, factor * inertia, read(CONFIGS / "ieee39_grid_damping.txt"))
    return {
        "frequencies": {"file": "ieee39_grid_power.txt"},
        "inertia": {"file": "ieee39_grid_inertia.txt"},
        "damping": damping.tolist(),
    }


def _numbers(path) -> np.ndarray:
    return np.array(
        [float(x) for row in path.read_text().splitlines() if not row.startswith("#") for x in row.split()]
    )


def test_the_rule_refuses_in_one_line_where_a_locking_start_would_be_stopped():
    """IEEE 39 at generator damping 0.2 m and 0.1 m: starts lock at 37-42 s, after the rule's 20 s,
    so the rule would count them as not synchronized. The pilot (the intact grid's starts
    without the rule and with ``after / PILOT_MARGIN``) sees it and refuses before any task."""
    run = dict(
        lines="6-7",
        realizations=24,
        seed=1,
        dynamics={"integrator": "rodas4", "rtol": 1e-4, "atol": 1e-4, "t_max": 200.0},
        **{"lambda": {"method": "finite-difference"}},
    )
    rule = {"sync": {"criterion": "frequency", "tolerance": 1e-3, "give_up": {"after": 20.0, "band": 1.0}}}
    for factor in (0.2, 0.1):
        with pytest.raises(
            GridError, match=r"sync.give_up is not trusted on this grid: \d+ of the \d+ starts"
        ):
            line_removal(CONFIGS / "ieee39_grid.yaml", model=_low_damping(factor), **run, **rule)


@COARSE_TOLERANCE
def test_the_audit_catches_a_given_up_start_that_locks_and_integrates_the_task_again(monkeypatch):
    """The audit of a task: a trajectory that locks without the rule but is marked GAVE_UP (a
    miscount the rule could make on a grid where the pilot passed) is found in the sample, and
    every given-up trajectory of the task is integrated again without the rule: the task's
    outcome is the rule-free one, the counts say so."""
    from antisync.grids import removal

    run = dict(
        lines="1-2",
        realizations=24,
        dynamics={"integrator": "rodas4", "rtol": 1e-4, "atol": 1e-4, "t_max": 40.0},
        **{"lambda": {"method": "finite-difference"}},
    )
    free = line_removal(CONFIGS / "ieee39_grid.yaml", **run)
    rule = {"sync": {"criterion": "frequency", "tolerance": 1e-3, "give_up": {"after": 10.0, "band": 1.0}}}
    real = removal._removal_task

    def miscounting(ks, variants, intact, fixed, threads):
        part = real(ks, variants, intact, {**fixed, "give_up": None}, threads)
        st = np.concatenate([part[0][:, None], part[2]], axis=1)
        tau = np.concatenate([part[1][:, None], part[3]], axis=1)
        todo = np.ones(st.shape, dtype=bool)
        todo[:, 0] = intact
        locked = np.flatnonzero(st[:, 1] == SYNCED)[:3]
        gone = np.flatnonzero(st[:, 1] == NOT_SYNCED)
        st[locked, 1] = GAVE_UP  # the miscount
        st[gone, 1] = GAVE_UP
        tau[locked, 1] = np.nan
        audit = removal._audited(ks, variants, fixed, threads, st, tau, todo)
        tau = np.where(st == SYNCED, tau, np.nan)
        return st[:, 0], tau[:, 0], st[:, 1:], tau[:, 1:], audit

    monkeypatch.setattr(removal, "_removal_task", miscounting)
    monkeypatch.setattr(removal, "AUDIT_MIN", 6)
    cut = line_removal(CONFIGS / "ieee39_grid.yaml", **run, **rule)
    assert cut.audit["locked"] >= 1 and cut.audit["rerun"] == int((free.status[:, 0] != SYNCED).sum()) + 3
    np.testing.assert_array_equal(cut.status, free.status)
    np.testing.assert_array_equal(cut.tau, free.tau)
    assert "integrated again without it" in cut.to_markdown()


def test_validate_checks_a_removal_config_with_the_rule():
    """``antisync validate`` of a ``--removal`` config with ``sync.give_up``: checked as that
    command checks it, ok in one line saying where the rule runs."""
    args = ["--set", "dynamics.integrator=rodas4", "--set", "sync.give_up={after: 20, band: 1.0}"]
    res = CliRunner().invoke(app, ["validate", str(CONFIGS / "ieee39_grid.yaml"), *args])
    assert res.exit_code == 0, res.output
    assert (
        "# ok: a config for antisync grid --removal (35 non-bridge lines; sync.give_up after 20 s"
        in res.output
    )


@pytest.mark.parametrize("key", ["rtol", "atol"])
def test_a_tolerance_below_what_float64_delivers_is_refused_in_one_line(key):
    """Rodas4 at rtol = atol = 1e-15 ended in a FloatingPointError after minutes: refused first."""
    args = ["--set", "dynamics.integrator=rodas4", "--set", f"dynamics.{key}=1e-15"]
    for cmd in (["validate"], ["grid", "--trip"], ["grid", "--removal"]):
        res = CliRunner().invoke(app, [cmd[0], str(CONFIGS / "ieee39_grid.yaml"), *cmd[1:], *args])
        assert res.exit_code == 2 and f"dynamics.{key} = 1e-15 is below what float64" in res.output, (
            res.output
        )
        assert len(res.output.strip().splitlines()) == 1


@COARSE_TOLERANCE
def test_a_removal_with_the_rule_on_dask_equals_the_local_table():
    """With ``sync.give_up`` the tasks are the same on a cluster as here (the audit samples each
    task's given-up trajectories): a LocalCluster of two workers gives the local table, the
    audit's counts included, where it would otherwise split the six lines into six tasks."""
    from helpers import local_cluster_client

    run = dict(
        lines="1-2,2-3,3-4,4-5,5-6,6-7",
        realizations=24,
        dynamics={"integrator": "rodas4", "rtol": 1e-4, "atol": 1e-4, "t_max": 40.0},
        sync={"criterion": "frequency", "tolerance": 1e-3, "give_up": {"after": 10.0, "band": 1.0}},
        **{"lambda": {"method": "finite-difference"}},
    )
    here = line_removal(CONFIGS / "ieee39_grid.yaml", **run)
    assert (here.status == GAVE_UP).any() and here.audit["sampled"] > 0
    with local_cluster_client() as client:
        there = line_removal(CONFIGS / "ieee39_grid.yaml", client=client, **run)
    for name in ("status0", "tau0", "status", "tau"):
        np.testing.assert_array_equal(getattr(there, name), getattr(here, name), err_msg=name)
    assert there.audit == here.audit
