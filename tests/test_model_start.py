"""Starts around the operating point (``model.start: {around: locked, width: w}``,
docs/models.md): ``theta_i(0) = phi_i + w (2 u_i - 1)`` around the undamaged network's stable
locked state ``phi``, ``u_i`` the paper's counter-based phases over ``2 pi``.

Every driver of the model family starts there: the RK4 lanes match solve_ivp started from the
host's phases (so the kernels read the starts they are given, not their own draws), the
one-trajectory driver and the lanes agree bit for bit, Rodas4 and the model adjoint give the
same statuses (the CUDA twin: tests/cudasim_model_checks.py). A tiny width starts on the locked
state itself. The config's checks, its stored form and a run's file close the loop."""

from __future__ import annotations

import math

import naive
import numpy as np
import pytest
from helpers import assert_one_line
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.execution.dispatch import job_model_params
from antisync.kernels import cpu, implicit
from antisync.kernels.adjoint import link_derivatives
from antisync.kernels.model_adjoint import simulate_model_adjoint
from antisync.physics.phases import initial_phases
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.plan.model import start_phases
from antisync.status import Status

#: a lollipop with fixed frequencies, inertia and the frequency criterion: a small power grid
GRID = (
    "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1']\nbetas: [0.5]\nrealizations: 12\n"
    "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], inertia: 1.0, damping: 1.5, "
    "start: {around: locked, width: WIDTH}}\n"
    "sync: {criterion: frequency, tolerance: 0.003}\n"
    "dynamics: {integrator: rk4, dt: 0.005, t_max: 60}\n"
)
COUNT = 12
#: realizations compared with solve_ivp (each comparison strict; the drivers' agreement below
#: covers all COUNT)
REFERENCE = 6


def grid_job(width: float = 1.5, *overrides: str):
    return make_job(load_config_text(GRID.replace("WIDTH", repr(width)), list(overrides)))


def run_model(job, simulate, **kwargs):
    """``simulate`` (a model driver's entry point) on ``job``'s first ``COUNT`` realizations and
    its variant, with the job's own model parameters (and so its starts)."""
    ks = np.arange(COUNT, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets)
    assert params.starts is not None and params.starts.shape == (COUNT, len(job.nodes))
    dyn = job.config.dynamics
    csr = job.csr
    return simulate(
        job.config.seed, 0, COUNT, csr.indptr, csr.indices, csr.weights, job.variant_weights, params,
        dt=dyn.dt, max_steps=dyn.max_steps, **kwargs,
    )  # fmt: skip


def test_start_phases_are_the_paper_phases_rescaled_around_the_centre():
    n, seed = 7, 5
    center = np.linspace(-1.0, 2.0, n)
    ks = np.array([3, 0, 41, 7], dtype=np.uint64)
    for width in (1e-3, 0.7, math.pi):
        got = start_phases(center, width, seed, ks)
        u = np.stack([initial_phases(seed, int(k), 1, n)[0] for k in ks]) / (2 * math.pi)
        np.testing.assert_allclose(got, center + width * (2 * u - 1), rtol=0, atol=1e-15)
        assert np.all(np.abs(got - center) <= width)
    # the whole circle at width pi: offsets spread over (-pi, pi), centred
    offsets = start_phases(np.zeros(50), math.pi, 1, np.arange(400, dtype=np.uint64)).ravel()
    assert offsets.min() < -3.1 and offsets.max() > 3.1 and abs(offsets.mean()) < 0.1


def test_the_centre_is_the_intact_networks_stable_locked_state():
    from antisync.physics.locked import locked_state

    job = grid_job()
    n = len(job.nodes)
    rows = np.repeat(np.arange(n), np.diff(job.csr.indptr))
    w = np.zeros((n, n))
    w[rows, job.csr.indices] = job.csr.weights
    p = np.array([0.15, -0.1, 0.05, 0.12, -0.2, -0.02])
    state = locked_state(w, p - p.mean(), 0.0, 1.0, 1.5)
    assert state.stable
    np.testing.assert_array_equal(job.model.start, state.phi)


def test_rk4_lanes_start_from_the_hosts_phases():
    """tau0 and tau(0.5) of the RK4 lanes equal solve_ivp's (DOP853, rtol 1e-11) started from
    :func:`start_phases`' rows (the first ``REFERENCE``), within RK4's error: the kernels
    integrate the starts they are given. (The paper's own phases would give other times; checked below.)"""
    job = grid_job()
    sim = run_model(job, cpu.simulate_model, integrator="rk4")
    dt = job.config.dynamics.dt
    starts = job_model_params(job, np.arange(COUNT, dtype=np.uint64), job.model.targets).starts
    n = len(job.nodes)
    rows = np.repeat(np.arange(n), np.diff(job.csr.indptr))
    p = np.array([0.15, -0.1, 0.05, 0.12, -0.2, -0.02])
    worst, moved = 0.0, 0
    for v, weights in enumerate([job.csr.weights, job.variant_weights[0]]):
        w = np.zeros((n, n))
        w[rows, job.csr.indices] = weights
        for k in range(REFERENCE):
            status, tau = naive.model_tau(starts[k], w, p - p.mean(), 0.0, 1.0, 1.5, "frequency", 0.003, 60.0)
            if v == 0:
                st, steps, frac = sim.status0[k], sim.steps0[k], sim.frac0[k]
            else:
                st, steps, frac = sim.status[k, 0], sim.steps[k, 0], sim.frac[k, 0]
            assert st == status, (k, v, st, status)
            if status == Status.SYNCED:
                got = (steps - 1 + frac) * dt
                worst = max(worst, abs(got - tau))
                if v == 0 and k < 3:  # the paper's phases would have given another time
                    theirs = initial_phases(job.config.seed, k, 1, n)[0]
                    _, other = naive.model_tau(
                        theirs, w, p - p.mean(), 0.0, 1.0, 1.5, "frequency", 0.003, 60.0
                    )
                    moved += abs(other - got) > 1e-3
    assert worst < 1e-7, worst
    assert moved == 3
    assert (sim.status0 == Status.SYNCED).all()


def test_every_driver_of_the_model_family_reads_the_starts():
    """The one-trajectory driver equals the lanes bit for bit (Euler and RK4); Rodas4 gives
    RK4's statuses and its tau within 1e-4 relative; the model adjoint's forward pass is the
    lanes' (status, steps, crossing) bit for bit."""
    job = grid_job()
    for integrator in ("euler", "rk4"):
        lanes = run_model(job, cpu.simulate_model, integrator=integrator)
        plain = run_model(job, cpu.simulate_model, integrator=integrator, lanes=0)
        for name in ("status0", "steps0", "frac0", "status", "steps", "frac"):
            np.testing.assert_array_equal(getattr(lanes, name), getattr(plain, name), err_msg=name)
    rk4 = lanes
    stiff = run_model(job, implicit.simulate_model, rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(stiff.status0, rk4.status0)
    np.testing.assert_array_equal(stiff.status, rk4.status)
    dt = job.config.dynamics.dt
    for a, b in (
        ((stiff.steps0, stiff.frac0), (rk4.steps0, rk4.frac0)),
        ((stiff.steps, stiff.frac), (rk4.steps, rk4.frac)),
    ):
        np.testing.assert_allclose((a[0] - 1 + a[1]) * dt, (b[0] - 1 + b[1]) * dt, rtol=1e-4)
    index = {v: i for i, v in enumerate(job.nodes)}
    deriv = link_derivatives(job.omega, job.csr, [(index[a], index[b]) for a, b in job.edges])
    params = job_model_params(job, np.arange(COUNT, dtype=np.uint64), job.model.targets[:1])
    adj = simulate_model_adjoint(
        job.config.seed, 0, COUNT, job.csr.indptr, job.csr.indices, job.csr.weights, deriv, params,
        dt=dt, max_steps=job.config.dynamics.max_steps, integrator="rk4",
    )  # fmt: skip
    for name in ("status0", "steps0", "frac0"):
        np.testing.assert_array_equal(getattr(adj, name), getattr(rk4, name), err_msg=name)


def test_a_tiny_width_starts_on_the_locked_state():
    """At width 1e-9 the intact network starts on its locked state: every frequency deviation
    is below the tolerance at t = 0 (ALREADY_SYNCED), where at width 1.5 every start has to
    lock first (test_rk4_lanes_start_from_the_hosts_phases: all SYNCED)."""
    sim = run_model(grid_job(1e-9), cpu.simulate_model, integrator="rk4")
    assert (sim.status0 == Status.ALREADY_SYNCED).all()


def test_the_config_checks_and_stores_the_start():
    cfg = grid_job(0.5).config
    assert cfg.to_dict()["model"]["start"] == {"around": "locked", "width": 0.5}
    assert cfg.simulation_key() != grid_job(0.6).config.simulation_key()
    plain = load_config_text(GRID.replace(", start: {around: locked, width: WIDTH}", ""))
    assert "start" not in plain.to_dict()["model"]  # files written before model.start read the same
    assert (
        load_config_text(GRID.replace("WIDTH", "1"), ["model.start.width=0.25"]).model.start["width"] == 0.25
    )
    bad = {
        "0": "model.start.width must be a number in (0, pi]",
        "3.2": "model.start.width must be a number in (0, pi]",
    }
    for width, words in bad.items():
        with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace("]", r"\]")):
            load_config_text(GRID.replace("WIDTH", width))
    with pytest.raises(ConfigError, match="needs fixed model.frequencies"):
        load_config_text(
            GRID.replace("WIDTH", "1").replace(
                "[0.15, -0.1, 0.05, 0.12, -0.2, -0.02]", "{distribution: normal, sd: 0.1}"
            )
        )


def test_bad_starts_are_one_line_and_touch_nothing(tmp_path):
    """A width out of range, an unknown centre, a network without a stable locked state: one
    line, exit 2, no result file."""
    runner = CliRunner()
    cases = {
        "width": (GRID.replace("WIDTH", "0"), "model.start.width must be a number in (0, pi]"),
        "around": (
            GRID.replace("around: locked", "around: origin").replace("WIDTH", "1"),
            "model.start.around",
        ),
        "unlocked": (
            GRID.replace("WIDTH", "1").replace(
                "[0.15, -0.1, 0.05, 0.12, -0.2, -0.02]", "[5, -5, 5, -5, 5, -5]"
            ),
            "model.start around the locked state: the undamaged network has no phase-locked state",
        ),
    }
    for name, (text, words) in cases.items():
        path = tmp_path / f"{name}.yaml"
        out = tmp_path / f"{name}.h5"
        path.write_text(text + f"output: {out}\n")
        res = runner.invoke(app, ["run", str(path)])
        assert_one_line(res, words)
        assert not out.exists()


def test_a_run_with_starts_stores_them(tmp_path):
    """`antisync run` of a config with model.start: the file's stored config keeps the start,
    and its undamaged tau0 mean is the lanes' over the same realizations."""
    import antisync

    path = tmp_path / "start.yaml"
    path.write_text(GRID.replace("WIDTH", "1.5") + "block_size: 12\n")
    res = antisync.run(str(path), output=str(tmp_path / "start.h5"), progress=False)
    back = antisync.load(tmp_path / "start.h5")
    assert load_config_text(back.config_yaml).model.start == {"around": "locked", "width": 1.5}
    sim = run_model(grid_job(), cpu.simulate_model, integrator="rk4")
    tau0 = (sim.steps0 - 1 + sim.frac0) * grid_job().config.dynamics.dt
    assert res.records[0]["tau0_mean"] == pytest.approx(tau0.mean(), rel=1e-12)
