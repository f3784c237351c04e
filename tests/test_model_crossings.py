"""Where the model kernels find the crossing (dense output, issue 29) and per-node inertia and
damping (the structure-preserving power-grid model), against refinement in dt, the slow
solve_ivp reference and closed forms."""

from __future__ import annotations

from pathlib import Path

import naive
import numpy as np
import pytest
from test_models import FEW, LOLLIPOP, REFERENCE_COUNTS, _one_line, dense_w, job_of, tau_of

from antisync.execution.compute import simulate_job
from antisync.physics.locked import locked_state
from antisync.physics.phases import initial_phases
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job
from antisync.status import Status

GRID = Path(__file__).resolve().parents[1] / "configs" / "ieee14_grid.yaml"
CRITERIA = {
    "frequency": [],
    "order-parameter": ["sync.criterion=order-parameter", "dynamics.threshold=0.9"],
    "relative": ["sync.criterion=relative", "sync.fraction=0.99"],
}


def _grid_tau0(overrides, dt, count):
    job = make_job(
        load_config(
            GRID,
            ["edges=['1->2']", "realizations=10", f"dynamics.dt={dt}", "dynamics.t_max=200", *overrides],
        )
    )
    sim = simulate_job(job, 0, count)
    assert (sim.status0 == Status.SYNCED).all()
    return (sim.steps0 - 1 + sim.frac0) * dt


def _fitted_order(dts, errors):
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


@pytest.mark.parametrize("criterion", list(CRITERIA))
def test_tau0_of_the_ieee14_grid_converges_at_fourth_order_with_rk4(criterion):
    """The IEEE 14 swing-equation config (RK4): per-realization tau0 against dt = 0.0025 on 60
    common starts. The mean |error| falls 16x per halving of dt (fitted order 4), for the
    frequency criterion too: it is located on every node's Hermite-interpolated frequency
    deviation, so a dip below the tolerance between grid points is not missed (at dt 0.02 the
    grid-point check moved ~3% of tau0 by 0.05 to 1.3 and biased <tau0> by +0.02)."""
    count = 60
    ref = _grid_tau0(CRITERIA[criterion], 0.0025, count)
    dts = [0.04, 0.02, 0.01]
    errors = [np.abs(_grid_tau0(CRITERIA[criterion], dt, count) - ref).mean() for dt in dts]
    order = _fitted_order(dts, errors)
    assert 3.6 < order < 4.4, (order, errors)
    assert errors[1] < 1e-4  # dt 0.02, the config's step: no realization moved by a missed dip


def test_tau0_with_euler_converges_at_first_order_under_the_frequency_criterion():
    """Euler's dense output is the straight line between grid points: tau0 of a first-order
    lollipop with natural frequencies converges at first order to the RK4 value."""
    text = (
        LOLLIPOP + "edges: ['2->1']\nbetas: []\nsync: {criterion: frequency, tolerance: 0.002}\n"
        "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02]}\n"
    )

    def tau0(integrator, dt):
        job = job_of(text, [f"dynamics.integrator={integrator}", f"dynamics.dt={dt}", "dynamics.t_max=100"])
        sim = simulate_job(job, 0, 40)
        assert (sim.status0 == Status.SYNCED).all()
        return (sim.steps0 - 1 + sim.frac0) * dt

    ref = tau0("rk4", 0.0025)
    dts = [0.01, 0.005, 0.0025]
    errors = [np.abs(tau0("euler", dt) - ref).mean() for dt in dts]
    assert 0.85 < _fitted_order(dts, errors) < 1.15, errors


# ---- per-node inertia and damping --------------------------------------------------------

# generators (inertia) at nodes 1, 4 and 6 of the lollipop; loads (first order) at the others
MIXED = (
    "model: {frequencies: [0.3, -0.1, -0.15, 0.2, -0.1, -0.15], inertia: [1.0, 0, 0, 0.5, 0, 2.0], "
    "damping: [1.0, 0.8, 1.2, 0.6, 1.0, 1.5]}\n"
)


@pytest.mark.parametrize("size", REFERENCE_COUNTS)
@pytest.mark.parametrize(
    "sync",
    [
        "sync: {criterion: frequency, tolerance: 0.002}\n",
        "sync: {criterion: relative, fraction: 0.98}\n",
        "dynamics: {threshold: 0.9}\n",
    ],
)
def test_generators_beside_load_buses_match_solve_ivp(sync, size):
    """``m_i theta_i'' + gamma_i theta_i' = P_i + coupling`` with ``m_i = 0`` at load buses:
    tau0 and tau(0.5) of 2->1 from RK4 (dt 0.005, dense-output crossing) equal solve_ivp's
    event times, every criterion. Realizations 0-7 here (each a Python solve_ivp at rtol
    1e-11), 0-24 in test-slow."""
    job = job_of(
        LOLLIPOP + "edges: ['2->1']\nbetas: [0.5]\n" + MIXED + sync,
        ["dynamics.integrator=rk4", "dynamics.dt=0.005", "dynamics.t_max=80"],
    )
    count = 8 if size == FEW else 25
    sim = simulate_job(job, 0, count)
    t0, t = tau_of(sim, 0.005)
    m = np.array([1.0, 0, 0, 0.5, 0, 2.0])
    g = np.array([1.0, 0.8, 1.2, 0.6, 1.0, 1.5])
    p = np.array([0.3, -0.1, -0.15, 0.2, -0.1, -0.15])
    crit = "frequency" if "frequency" in sync else "r"
    targets = job.model.targets if crit == "frequency" else np.sqrt(job.model.targets) / 6
    worst = 0.0
    for k in range(count):
        theta0 = initial_phases(job.config.seed, k, 1, 6)[0]
        for v, weights in enumerate([job.csr.weights, job.variant_weights[0]]):
            status, tau = naive.model_tau(theta0, dense_w(job, weights), p, 0.0, m, g, crit, targets[v], 80.0)
            got = (sim.status0[k], t0[k]) if v == 0 else (sim.status[k, 0], t[k, 0])
            assert got[0] == status, (k, v, got, status, tau)
            if status == Status.SYNCED:
                worst = max(worst, abs(got[1] - tau))
    assert worst < 1e-7, worst
    assert (sim.status0 == Status.SYNCED).mean() > 0.9


def test_per_node_values_that_are_all_equal_are_the_single_value_bit_for_bit():
    base = LOLLIPOP + "edges: ['2->1']\nbetas: [0.5]\nsync: {criterion: frequency, tolerance: 0.003}\n"
    base += "dynamics: {integrator: rk4, dt: 0.02, t_max: 60}\n"
    one = job_of(base + "model: {frequencies: [0.1, 0, 0, 0, 0, -0.1], inertia: 0.7, damping: 1.3}\n")
    per = job_of(
        base + "model: {frequencies: [0.1, 0, 0, 0, 0, -0.1], inertia: [0.7, 0.7, 0.7, 0.7, 0.7, 0.7], "
        "damping: [1.3, 1.3, 1.3, 1.3, 1.3, 1.3]}\n"
    )
    a, b = simulate_job(one, 0, 50), simulate_job(per, 0, 50)
    for x, y in zip((a.steps0, a.frac0, a.steps, a.frac), (b.steps0, b.frac0, b.steps, b.frac), strict=True):
        np.testing.assert_array_equal(x, y)


def test_the_locked_state_with_per_node_damping_rotates_rigidly():
    """Newton's locked state of the mixed model is a rigid rotation: ``theta_i' = Omega`` at every
    node and ``nu' = 0`` at the generators, with ``gamma_i Omega = P_i + coupling_i``."""
    job = job_of(LOLLIPOP + MIXED + "sync: {criterion: relative}\n")
    w = dense_w(job, job.csr.weights)
    m = np.array([1.0, 0, 0, 0.5, 0, 2.0])
    g = np.array([1.0, 0.8, 1.2, 0.6, 1.0, 1.5])
    p = np.array([0.3, -0.1, -0.15, 0.2, -0.1, -0.15])
    state = locked_state(w, p, 0.2, m, g)
    assert state is not None and state.stable
    omega = state.nu / g.mean()
    th, dnu = naive.model_rates(state.phi, np.full(6, omega), w, p, 0.2, m, g)
    np.testing.assert_allclose(th, omega, atol=1e-12)
    np.testing.assert_allclose(dnu, 0.0, atol=1e-12)


def test_per_node_inertia_from_a_file(tmp_path):
    (tmp_path / "m.txt").write_text("# inertia per bus\n1.0\n0\n0\n0.5\n0\n2.0\n")
    (tmp_path / "c.yaml").write_text(
        LOLLIPOP
        + "edges: ['2->1']\nbetas: [0.5]\nmodel: {frequencies: [0.3, -0.1, -0.15, 0.2, -0.1, -0.15], "
        "inertia: {file: m.txt}, damping: [1.0, 0.8, 1.2, 0.6, 1.0, 1.5]}\n"
        "sync: {criterion: frequency, tolerance: 0.002}\ndynamics: {integrator: rk4, dt: 0.02, t_max: 60}\n"
    )
    from_file = make_job(load_config(tmp_path / "c.yaml"))
    listed = job_of(
        LOLLIPOP
        + "edges: ['2->1']\nbetas: [0.5]\n"
        + MIXED
        + "sync: {criterion: frequency, tolerance: 0.002}\n"
        "dynamics: {integrator: rk4, dt: 0.02, t_max: 60}\n"
    )
    np.testing.assert_array_equal(from_file.model.inertia, [1.0, 0, 0, 0.5, 0, 2.0])
    a, b = simulate_job(from_file, 0, 20), simulate_job(listed, 0, 20)
    np.testing.assert_array_equal(a.frac0, b.frac0)


SMALL = LOLLIPOP + "edges: ['2->1']\nbetas: [0.5]\nrealizations: 10\ndynamics: {t_max: 20}\n"


@pytest.mark.parametrize(
    "extra,message,files",
    [
        ("model: {inertia: [1, 1, 1]}\n", "model.inertia has 3 values; the graph has 6 nodes", None),
        ("model: {inertia: [1, 1, 1, 1, 1, 1], damping: [1, 1]}\n", "model.damping has 2 values", None),
        ("model: {inertia: [1, 1, -1, 1, 1, 1]}\n", "model.inertia[2] must be a number >= 0", None),
        (
            "model: {inertia: 1, damping: [1, 1, 0, 1, 1, 1]}\n",
            "model.damping[2] must be a positive number",
            None,
        ),
        ("model: {inertia: [0, 0, 0, 0, 0, 0]}\n", "model.inertia lists 0 for every node", None),
        ("model: {damping: [1, 2, 1, 1, 1, 1]}\n", "model.damping per node needs model.inertia > 0", None),
        # one damping for a first-order model was ignored by every kernel, silently
        ("model: {damping: 2}\n", "model.damping 2 needs model.inertia > 0 on some node", None),
        ("model: {inertia: 0, damping: 0.5}\n", "it would be ignored", None),
        ("model: {inertia: []}\n", "model.inertia is an empty list", None),
        ("model: {inertia: {file: m.txt}}\n", "m.txt has 0 for every node", {"m.txt": "0\n" * 6}),
        (
            "model: {inertia: {file: m.txt}}\n",
            "value 3 (-2) must be a number >= 0",
            {"m.txt": "1\n1\n-2\n1\n1\n1\n"},
        ),
        ("model: {inertia: {file: m.txt}}\n", "m.txt has 5 values", {"m.txt": "1\n" * 5}),
        ("model: {inertia: {path: m.txt}}\n", "model.inertia must be", None),
        (
            "model: {inertia: [1, 0, 0, 0.01, 0, 1]}\ndynamics: {dt: 0.05}\n",
            "model.inertia at node 3 must be at least",
            None,
        ),
    ],
)
def test_bad_per_node_parameters_are_one_line(tmp_path, extra, message, files):
    _one_line(tmp_path, SMALL + extra, message, files)


def test_a_stiff_second_order_grid_s_step_is_checked_on_its_own_modes():
    """With inertia the modes near synchrony solve ``m l^2 + g l + xi = 0`` (``|l| ~ sqrt(xi /
    m)``), not ``l = -xi``: a ring at K = 1000 (xi_max = 4000) steps at RK4 dt = 0.005, which
    the first-order bound (2.785 / 4000 = 0.0007) refused for runs and removals, while the
    second-order check still refuses a step beyond its own bound (~2.8 / 63 = 0.045)."""
    from antisync.errors import ConfigError
    from antisync.grids.removal_config import plan_removal
    from antisync.plan.config import config_from_mapping
    from antisync.plan.jobs import check_step

    links = [[i, (i + 1) % 6, 1000.0] for i in range(6)]
    base = {
        "graph": {"kind": "inline", "links": links},
        "model": {"frequencies": [1, -1, 0.5, -0.5, 0.8, -0.8], "inertia": 1.0, "damping": 1.0},
        "sync": {"criterion": "frequency", "tolerance": 1e-3},
        "realizations": 4,
    }
    rk4 = {"coupling": "raw", "integrator": "rk4"}
    ok = config_from_mapping({**base, "dynamics": {**rk4, "dt": 0.005}})
    plan = plan_removal(ok, [(0, 1)], 1.0, False)  # refused before: "dt < 0.000696"
    check_step(plan.omega, ok)
    too_large = config_from_mapping(
        {**base, "dynamics": {"coupling": "raw", "integrator": "rk4", "dt": 0.06}}
    )
    with pytest.raises(ConfigError, match="dt"):
        check_step(plan.omega, too_large)


# ---- the derivative d<F>/dbeta for every model: central differences ------------------------


def test_central_difference_runs_every_model_with_each_variants_own_target():
    """``lambda.method: central-difference`` on a model: each +-dbeta row carries its own
    relative target (r* of its weights), and the per-realization values are the central secant
    ``tau0 (1/tau(+h) - 1/tau(-h)) / (2 h)`` of trajectories integrated one by one."""
    from antisync.execution.compute import lambda_values
    from antisync.kernels import cpu
    from antisync.physics import coupling as cp

    job = job_of(
        LOLLIPOP + "edges: ['2->1', '4->3']\nbetas: []\nlambda: {method: central-difference, dbeta: 0.02}\n"
        "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], phase_lag: 0.3,\n"
        "        inertia: [0.5, 0, 0, 1, 0, 0]}\n"
        "sync: {criterion: relative, fraction: 0.98}\ndynamics: {integrator: rk4, dt: 0.02, t_max: 80}\n"
    )
    setup = job.model
    assert setup.orbit_targets.shape == (4,) and len(set(np.round(setup.orbit_r_star, 12))) == 4
    count = 30
    values, code, _, _ = lambda_values(job, None, 0, count)
    index = {v: i for i, v in enumerate(job.nodes)}
    dt = 0.02
    for e, (a, b) in enumerate(job.edges):
        taus = []
        for h in (0.02, -0.02):
            w = cp.variant_weights(job.omega, job.csr, [(index[a], index[b], h)], "normalized")[0]
            state = locked_state(dense_w(job, w), setup.freqs, 0.3, setup.inertia, setup.damping)
            target = (0.98 * state.r * 6) ** 2
            params = cpu.ModelParams(
                setup.freqs[None, :],
                setup.cos_lag,
                setup.sin_lag,
                setup.inertia,
                setup.damping,
                setup.criterion,
                np.array([setup.targets[0], target]),
            )
            sim = cpu.simulate_model(
                job.config.seed,
                0,
                count,
                job.csr.indptr,
                job.csr.indices,
                job.csr.weights,
                w[None, :],
                params,
                dt=dt,
                max_steps=4000,
                integrator="rk4",
            )
            taus.append((sim.steps[:, 0] - 1 + sim.frac[:, 0]) * dt)
        tau0 = (sim.steps0 - 1 + sim.frac0) * dt
        want = tau0 * (1 / taus[0] - 1 / taus[1]) / 0.04
        ok = code[:, e] == Status.SYNCED
        assert ok.mean() > 0.9
        np.testing.assert_allclose(values[ok, e], want[ok], rtol=1e-12, atol=1e-12)


def test_orbit_runs_a_model_that_keeps_the_symmetry_and_refuses_one_that_breaks_it(tmp_path):
    job = job_of(
        "graph: {kind: networkx, generator: complete_graph, args: {n: 5}}\nedges: ['0->1']\nbetas: []\n"
        "lambda: {method: orbit}\nmodel: {frequencies: {distribution: normal, sd: 0.1}, phase_lag: 0.2}\n"
    )
    from antisync.execution.compute import lambda_values

    values, code, _, _ = lambda_values(job, None, 0, 20)
    # K5's one orbit is every link: damaging all by beta leaves the normalized W unchanged
    np.testing.assert_array_equal(values[code == Status.SYNCED], 0.0)
    _one_line(
        tmp_path,
        SMALL + "model: {frequencies: [0.1, 0, 0, 0, 0, -0.1]}\nlambda: {method: orbit}\n",
        "lambda.method orbit averages over the graph's automorphisms",
    )
    _one_line(
        tmp_path,
        SMALL + "model: {phase_lag: 0.1}\nlambda: {method: pathwise}\n",
        "use adjoint or adjoint-hybrid (the same derivative",
    )
