"""Beyond identical oscillators (docs/models.md): natural frequencies, phase lag, inertia, and
the sync criteria, against the default kernels, closed forms and a slow solve_ivp reference."""

from __future__ import annotations

import math
from pathlib import Path

import naive
import numpy as np
import pytest
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.execution.compute import simulate_job
from antisync.kernels import cpu, model_steps
from antisync.kernels.shared import model_inputs
from antisync.physics import coupling, graphs
from antisync.physics.locked import locked_state
from antisync.physics.phases import initial_phases
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.status import Status

LOLLIPOP = "graph: {kind: lollipop, nodes: 6, path: 3}\n"


def job_of(text: str, overrides=None):
    return make_job(load_config_text(text, overrides))


def tau_of(sim, dt):
    """Interpolated tau0 and tau per variant (``(steps - 1 + frac) dt``; 0 when not SYNCED)."""
    t0 = np.where(sim.status0 == Status.SYNCED, (sim.steps0 - 1 + sim.frac0) * dt, 0.0)
    t = np.where(sim.status == Status.SYNCED, (sim.steps - 1 + sim.frac) * dt, 0.0)
    return t0, t


def dense_w(job, weights):
    n = len(job.nodes)
    rows = np.repeat(np.arange(n), np.diff(job.csr.indptr))
    w = np.zeros((n, n))
    w[rows, job.csr.indices] = weights
    return w


# ---- (a) the default model, bit for bit --------------------------------------------------


def test_model_kernel_with_default_parameters_is_the_default_kernel_bit_for_bit():
    """P = 0, alpha = 0, m = 0 through the model kernel: every status and step equals the
    default lane driver's (all 12 edges x {0.5, dbeta}, 150 realizations, Euler)."""
    job = job_of(LOLLIPOP + "betas: [0.5]\ndynamics: {dt: 0.01, t_max: 50}\n")
    n = len(job.nodes)
    v = job.variant_weights.shape[0]
    args = (1, 0, 150, job.csr.indptr, job.csr.indices, job.csr.weights, job.variant_weights)
    ref = cpu.simulate(*args, dt=0.01, threshold=0.99, max_steps=5000)
    cl, sl = model_steps.lag_terms(0.0)
    assert (cl, sl) == (1.0, 0.0)
    params = cpu.ModelParams(np.zeros((1, n)), cl, sl, 0.0, 1.0, 0, np.full(v + 1, (0.99 * n) ** 2))
    got = cpu.simulate_model(*args, params, dt=0.01, max_steps=5000)
    np.testing.assert_array_equal(got.status0, ref.status0)
    np.testing.assert_array_equal(got.steps0, ref.steps0)
    np.testing.assert_array_equal(got.status, ref.status)
    np.testing.assert_array_equal(got.steps, ref.steps)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"integrator": "heun"}, "integrator must be 'euler', 'rk4' or 'rodas4', got 'heun'"),
        ({"criterion": 7}, "unknown criterion code 7"),
        ({"freqs": np.zeros((2, 6))}, "freqs must have shape (1, 6) or (3, 6), got (2, 6)"),
        ({"freqs": np.zeros((1, 5))}, "freqs must have shape (1, 6) or (3, 6), got (1, 5)"),
        ({"targets": np.zeros(1)}, "targets must have shape ({v1},), got (1,)"),
        ({"starts": np.zeros((2, 6))}, "starts must have shape (3, 6) or be None, got (2, 6)"),
    ],
)
def test_model_inputs_name_what_is_wrong(change, message):
    """The model drivers' shared input check (CPU and CUDA call it first) names the argument,
    what it got and what would be valid."""
    job = job_of(LOLLIPOP + "betas: [0.5]\n")
    v = job.variant_weights.shape[0]
    fields = {"freqs": np.zeros((1, 6)), "criterion": 0, "targets": np.ones(v + 1)}
    fields.update({k: x for k, x in change.items() if k != "integrator"})
    params = cpu.ModelParams(
        fields["freqs"], 1.0, 0.0, 0.0, 1.0, fields["criterion"], fields["targets"], change.get("starts")
    )
    args = (0, 3, None, job.csr.indptr, job.csr.weights, job.variant_weights, params)
    with pytest.raises(ValueError) as err:
        model_inputs(*args, change.get("integrator", "euler"))
    assert str(err.value) == message.format(v1=v + 1)
    good = cpu.ModelParams(np.zeros((1, 6)), 1.0, 0.0, 0.0, 1.0, 0, np.ones(v + 1))
    ks, base, var_w, var_is_base, _, _, starts = model_inputs(*args[:-1], good, "rk4")
    assert starts.shape == (0, 6)  # the kernels draw the paper's phases
    assert ks.tolist() == [0, 1, 2] and var_w.shape == (v, base.size)
    assert var_is_base.tolist() == [bool((w == base).all()) for w in var_w]


def test_explicit_default_model_section_changes_nothing():
    """``model: {phase_lag: 0, frequencies: null, inertia: 0}`` and ``sync: {criterion:
    order-parameter, threshold: 0.99}`` are today's config: same stored config, default path."""
    plain = load_config_text(LOLLIPOP)
    explicit = load_config_text(
        LOLLIPOP + "model: {phase_lag: 0, frequencies: null, inertia: 0}\n"
        "sync: {criterion: order-parameter, threshold: 0.99}\n"
    )
    assert explicit.to_yaml() == plain.to_yaml()
    assert explicit.simulation_key() == plain.simulation_key()
    assert "model" not in plain.to_dict() and "sync" not in plain.to_dict()
    assert make_job(explicit).model is None


def test_sync_threshold_is_dynamics_threshold():
    a = load_config_text(LOLLIPOP + "sync: {threshold: 0.95}\n")
    assert a.dynamics.threshold == 0.95 and a.sync.threshold is None
    assert a.to_yaml() == load_config_text(LOLLIPOP + "dynamics: {threshold: 0.95}\n").to_yaml()
    with pytest.raises(ConfigError, match="disagree"):
        load_config_text(LOLLIPOP + "sync: {threshold: 0.95}\ndynamics: {threshold: 0.9}\n")


# ---- (b) inertia -> 0 ---------------------------------------------------------------------


def test_small_inertia_approaches_the_first_order_model_at_rate_m():
    """tau of ``m theta'' + theta' = ...`` minus tau of the first-order model, RK4 at dt =
    0.002 (error ~1e-10), fitted as ``C m^k``: the singular perturbation gives ``k = 1``."""
    text = (
        LOLLIPOP + "edges: ['2->1']\nbetas: []\nrealizations: 24\n"
        "dynamics: {integrator: rk4, dt: 0.002, t_max: 40, threshold: 0.95}\n"
        "model: {frequencies: [0.1, -0.05, 0.0, 0.08, -0.1, 0.02], phase_lag: 0.2}\n"
    )
    first = simulate_job(job_of(text), 0, 24)
    t_first, _ = tau_of(first, 0.002)
    assert (first.status0 == Status.SYNCED).all()
    ms = np.array([0.04, 0.02, 0.01, 0.005])
    gaps = []
    for m in ms:
        sim = simulate_job(job_of(text, [f"model.inertia={m}"]), 0, 24)
        assert (sim.status0 == Status.SYNCED).all()
        t_m, _ = tau_of(sim, 0.002)
        gaps.append(np.mean(np.abs(t_m - t_first)))
    order, _ = np.polyfit(np.log(ms), np.log(gaps), 1)
    assert 0.9 < order < 1.1, (order, gaps)
    assert gaps[-1] < 0.05


# ---- (c) closed forms and Newton ----------------------------------------------------------


@pytest.mark.parametrize("coupling_kind,weight", [("normalized", 1.0), ("raw", 2.5)])
@pytest.mark.parametrize("dw", [0.3, 1.2])
def test_two_oscillators_lock_at_the_closed_form(coupling_kind, weight, dw):
    """``delta' = dw - 2 K' sin delta``: locked at ``sin delta = dw / (2 K')``, ``r* =
    cos(delta / 2)``; ``K' = w_12 = w_21`` is 1 for normalized coupling (Eq. 1: each node has
    one neighbour) and ``Omega_12`` for raw coupling (Eq. 20)."""
    omega = np.array([[0.0, weight], [weight, 0.0]])
    w = coupling.coupling_matrix(omega, coupling_kind)
    k = w[0, 1]
    assert k == (1.0 if coupling_kind == "normalized" else weight)
    p = np.array([-dw / 2, dw / 2])  # node 2 runs ahead: delta = theta_2 - theta_1 > 0
    state = locked_state(w, p)
    delta = math.asin(dw / (2 * k))
    assert state is not None and state.stable
    assert state.phi[1] == pytest.approx(delta, abs=1e-12)
    assert state.r == pytest.approx(math.cos(delta / 2), abs=1e-12)
    # a long integration from random phases ends at the same r, to 1e-8
    status, _ = naive.model_tau(np.array([0.3, 2.9]), w, p, 0.0, 0.0, 1.0, "r", 1.1, 200.0)
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        lambda t, y: naive.model_rates(y, None, w, p, 0.0, 0.0, 1.0)[0],
        (0, 200.0),
        np.array([0.3, 2.9]),
        method="DOP853",
        rtol=1e-12,
        atol=1e-13,
    )
    assert status == Status.NOT_SYNCED  # r never reaches 1.1: the whole 200 were integrated
    assert naive.order_parameter(sol.y[:, -1]) == pytest.approx(state.r, abs=1e-8)


def test_two_oscillators_beyond_locking_have_no_locked_state():
    w = coupling.coupling_matrix(np.array([[0.0, 1.0], [1.0, 0.0]]))
    assert locked_state(w, np.array([-1.05, 1.05])) is None  # dw = 2.1 > 2 K'


@pytest.mark.parametrize("inertia", [0.0, 0.7])
def test_newton_fixed_point_is_where_long_integrations_end(inertia):
    """Lollipop(6,3), fixed frequencies and a phase lag: the order parameter after t = 300
    from random phases equals Newton's ``r*`` to 1e-8, for the first- and second-order model
    (the locked state does not depend on m; its stability is checked for each)."""
    job = job_of(LOLLIPOP + "dynamics: {threshold: 0.9}\n")
    w = dense_w(job, job.csr.weights)
    p = np.array([0.15, -0.1, 0.05, 0.12, -0.2, -0.02])
    p -= p.mean()
    state = locked_state(w, p, 0.4, inertia, 0.8)
    assert state is not None and state.stable
    from scipy.integrate import solve_ivp

    n = 6
    theta0 = initial_phases(3, 0, 1, n)[0]
    y0 = np.concatenate([theta0, np.zeros(n)]) if inertia else theta0

    def rhs(t, y):
        th, dnu = naive.model_rates(y[:n], y[n:], w, p, 0.4, inertia, 0.8)
        return np.concatenate([th, dnu]) if inertia else th

    sol = solve_ivp(rhs, (0, 300.0), y0, method="DOP853", rtol=1e-12, atol=1e-13)
    assert naive.order_parameter(sol.y[:n, -1]) == pytest.approx(state.r, abs=1e-8)
    # the locked frequency: theta' = nu / gamma for every node at the end
    th, _ = naive.model_rates(sol.y[:n, -1], sol.y[n:, -1], w, p, 0.4, inertia, 0.8)
    assert np.allclose(th, state.nu / (0.8 if inertia else 1.0), atol=1e-8)


def test_relative_criterion_uses_each_variants_locked_state():
    job = job_of(
        LOLLIPOP + "edges: ['2->1', '5->6']\nbetas: [0.5]\n"
        "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], phase_lag: 0.3}\n"
        "sync: {criterion: relative, fraction: 0.98}\n"
    )
    r_star = job.model.r_star
    p = np.array([0.15, -0.1, 0.05, 0.12, -0.2, -0.02])
    for v, weights in enumerate([job.csr.weights, *job.variant_weights]):
        assert r_star[v] == pytest.approx(locked_state(dense_w(job, weights), p, 0.3).r, abs=1e-12)
    assert len(set(np.round(r_star, 12))) > 2  # damage moves the locked state
    np.testing.assert_allclose(job.model.targets, (0.98 * r_star * 6) ** 2)


# ---- (d) the slow reference ---------------------------------------------------------------

MODELS = {
    "freq-lag-order": (
        "model: {frequencies: {distribution: normal, sd: 0.1}, phase_lag: 0.2}\n"
        "dynamics: {threshold: 0.95}\n",
        "r",
        2e-7,
    ),
    "uniform-frequency": (
        "model: {frequencies: {distribution: uniform, width: 0.15}}\n"
        "sync: {criterion: frequency, tolerance: 0.002}\n",
        "frequency",
        1e-7,
    ),
    "inertia-relative": (
        "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], phase_lag: 0.1, inertia: 0.5}\n"
        "sync: {criterion: relative, fraction: 0.98}\n",
        "r",
        2e-7,
    ),
    "inertia-frequency": (
        "model: {frequencies: {distribution: normal, sd: 0.05}, inertia: 1.0, damping: 1.5}\n"
        "sync: {criterion: frequency, tolerance: 0.003}\n",
        "frequency",
        1e-7,
    ),
}


def _reference(job, realizations, integrate):
    """``integrate(theta0, w, p, lag, m, gamma, crit, target)`` per realization, for tau0
    and the first variant."""
    cfg = job.config
    n = len(job.nodes)
    ks = np.arange(realizations, dtype=np.uint64)
    if cfg.model.drawn:
        freqs = model_steps.draw_frequencies(cfg.model.frequencies, cfg.seed, ks, n)
    else:
        freqs = np.repeat(np.array(cfg.model.frequencies)[None, :], realizations, axis=0)
    freqs = freqs - freqs.mean(axis=1, keepdims=True)
    crit = "frequency" if cfg.sync.criterion == "frequency" else "r"
    targets = job.model.targets if crit == "frequency" else np.sqrt(job.model.targets) / n
    out = []
    for k in range(realizations):
        theta0 = initial_phases(cfg.seed, k, 1, n)[0]
        row = []
        for v, weights in enumerate([job.csr.weights, job.variant_weights[0]]):
            w = dense_w(job, weights)
            m = cfg.model
            row.append(integrate(theta0, w, freqs[k], m.phase_lag, m.inertia, m.damping, crit, targets[v]))
        out.append(row)
    return out


#: realizations compared with the obvious reference: a few in ``make test``, the full set
#: (where rare trajectories, short dips among them, turn up) in ``make test-slow``; each
#: realization's comparison is as strict in both
FEW, MANY = "few", "many"
REFERENCE_COUNTS = [FEW, pytest.param(MANY, marks=pytest.mark.slow)]


def reference_cases(slow_few: tuple[str, ...] = ()) -> list:
    """``(name, size)`` for every model of :data:`MODELS` at both sizes: ``many`` in test-slow,
    and ``few`` too for the names in ``slow_few`` (whose few realizations are the first of the
    many, so test-slow checks them as strictly; a test that lists one says which of its other
    cases checks the same kernel path in ``make test``)."""
    return [
        pytest.param(name, size, marks=pytest.mark.slow) if size == MANY or name in slow_few else (name, size)
        for size in (FEW, MANY)
        for name in MODELS
    ]


#: inertia-frequency's few (14.6 s of a fresh clone's `make test`, the costliest reference) runs
#: in test-slow with its many: in `make test`, RK4's inertia is checked against solve_ivp by
#: inertia-relative, the frequency criterion's crossing by uniform-frequency, and both together
#: (generators beside load buses, the rate of relaxation in the deviation) by
#: tests/test_model_crossings.py's test_generators_beside_load_buses_match_solve_ivp
@pytest.mark.parametrize(("name", "size"), reference_cases(slow_few=("inertia-frequency",)))
def test_rk4_matches_solve_ivp(name, size):
    """tau0 and tau(0.5) of 2->1 from the model kernel's RK4 (dt = 0.005, interpolated
    crossing) equal solve_ivp's event times (DOP853, rtol 1e-11, steps of at most 0.01 so that
    its event search sees short dips) within the integrator's error, ~1e-9: every criterion is
    located on RK4's dense output (cubic Hermite of R, or of every frequency deviation with its
    rate), 4th order in state and crossing. Realizations 0-7 here, 0-99 (0-39) in test-slow."""
    text, _, tol = MODELS[name]
    count = 8 if size == FEW else (100 if name == "freq-lag-order" else 40)
    job = job_of(
        LOLLIPOP + f"edges: ['2->1']\nbetas: [0.5]\n{text}",
        ["dynamics.integrator=rk4", "dynamics.dt=0.005", "dynamics.t_max=60"],
    )
    sim = simulate_job(job, 0, count)
    t0, t = tau_of(sim, 0.005)
    ref = _reference(job, count, lambda *a: naive.model_tau(*a, 60.0))
    worst = 0.0
    for k in range(count):
        for v, (status, tau) in enumerate(ref[k]):
            got_status = sim.status0[k] if v == 0 else sim.status[k, 0]
            got_tau = t0[k] if v == 0 else t[k, 0]
            assert got_status == status, (k, v, got_status, status, got_tau, tau)
            if status == Status.SYNCED:
                worst = max(worst, abs(got_tau - tau))
    assert worst < tol, worst
    # the comparisons are of synchronized times: fewer than 10% of the starts unsynchronized (the
    # guard of 12, 40 and 100 realizations), at most one of the 8 of make test
    assert (sim.status0 != Status.SYNCED).sum() < max(2, 0.1 * count)


@pytest.mark.parametrize("name", ["freq-lag-order", "inertia-relative"])
def test_euler_matches_the_obvious_euler(name):
    """The model kernel's Euler (rotations of (cos, sin)) against Euler on theta: the same
    step in all but rare trajectories where rounding flips one step."""
    text, _, _ = MODELS[name]
    job = job_of(
        LOLLIPOP + f"edges: ['2->1']\nbetas: [0.5]\n{text}",
        ["dynamics.dt=0.01", "dynamics.t_max=60"],
    )
    count = 30
    sim = simulate_job(job, 0, count)
    ref = _reference(job, count, lambda *a: naive.model_euler_steps(*a, 0.01, 6000))
    got = np.stack([sim.steps0, sim.steps[:, 0]], axis=1)
    want = np.array([[s for _, s in row] for row in ref])
    assert np.abs(got - want).max() <= 1
    assert (got == want).mean() >= 0.95


def test_drawn_frequencies_are_per_realization_and_shared_by_its_variants():
    spec = {"distribution": "normal", "sd": 0.3, "mean": 0.0}
    a = model_steps.draw_frequencies(spec, 5, np.arange(0, 4000), 6)
    b = model_steps.draw_frequencies(spec, 5, np.arange(1000, 1010), 6)
    np.testing.assert_array_equal(a[1000:1010], b)  # keyed by (seed, k, node): any chunking
    assert abs(a.mean()) < 0.02 and a.std() == pytest.approx(0.3, rel=0.03)
    uniform = {"distribution": "uniform", "width": 0.2, "mean": 1.0}
    u = model_steps.draw_frequencies(uniform, 5, np.arange(4000), 6)
    assert u.min() >= 0.8 and u.max() < 1.2 and u.std() == pytest.approx(0.4 / math.sqrt(12), rel=0.03)
    # the frequency stream is not the phase stream
    first = model_steps.draw_frequencies(spec, 5, np.arange(3), 6)
    assert not np.allclose(first, 0.3 * initial_phases(5, 0, 3, 6))


def test_a_run_that_never_locks_is_counted_not_averaged(tmp_path):
    """Frequencies far too spread for the coupling: every realization NOT_SYNCED, counted."""
    import antisync

    res = antisync.run(
        {
            "graph": {"kind": "lollipop", "nodes": 6, "path": 3},
            "edges": ["2->1"],
            "betas": [0.5],
            "realizations": 20,
            "dynamics": {"dt": 0.05, "t_max": 20},
            "model": {"frequencies": {"distribution": "uniform", "width": 3.0}},
            "sync": {"criterion": "frequency"},
        },
        output=str(tmp_path / "never.h5"),
    )
    rec = res.records[0]
    assert rec["n_not_synced"] == 20 and rec["F_mean"] is None
    assert "frequencies" in rec["lambda_km_warning"]


# ---- (e) bad input: one line, exit code 2 -------------------------------------------------

runner = CliRunner()


def _one_line(tmp_path, text, message, files=None):
    for name, content in (files or {}).items():
        (tmp_path / name).write_text(content)
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    for command in ("validate", "run"):
        args = [command, str(cfg)] + (["--out", str(tmp_path / "o.h5"), "-q"] if command == "run" else [])
        res = runner.invoke(app, args)
        assert res.exit_code == 2, (command, res.output)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("antisync: error: "), res.stderr
        assert message in lines[0], (message, lines[0])
    assert not (tmp_path / "o.h5").exists()


SMALL = LOLLIPOP + "edges: ['2->1']\nbetas: [0.5]\nrealizations: 10\ndynamics: {t_max: 20}\n"
TWO = "graph: {kind: networkx, generator: path_graph, args: {n: 2}}\nbetas: []\nrealizations: 10\n"


@pytest.mark.parametrize(
    "extra,message,files",
    [
        ("model: {inertia: -1}\n", "model.inertia must be a number >= 0", None),
        ("model: {phase_lag: 2.0}\n", "model.phase_lag must be a number in (-pi/2, pi/2)", None),
        ("model: {phase_lag: -1.5708}\n", "model.phase_lag must be a number in (-pi/2, pi/2)", None),
        ("model: {damping: 0, inertia: 1}\n", "model.damping must be a positive number", None),
        ("model: {frequencies: [1, 2, 3]}\n", "model.frequencies has 3 values; the graph has 6 nodes", None),
        ("model: {frequencies: {file: f.txt}}\n", "has 2 values; the graph has 6", {"f.txt": "0.1\n-0.1\n"}),
        ("model: {frequencies: {file: nope.txt}}\n", "model.frequencies.file", None),
        ("model: {frequencies: {distribution: cauchy, sd: 1}}\n", "must be one of normal, uniform", None),
        ("model: {frequencies: {distribution: normal}}\n", "needs sd", None),
        ("model: {spin: 1}\n", "unknown key 'model.spin'", None),
        ("model: {inertia: 0.01}\ndynamics: {dt: 0.05}\n", "is unstable for the second-order model", None),
        ("model: {inertia: 1, damping: 0.01}\ndynamics: {dt: 0.01}\n", "unstable for the second-order", None),
        ("sync: {criterion: psychic}\n", "sync.criterion must be one of", None),
        ("model: {phase_lag: 0.1}\nlambda: {method: pathwise}\n", "use adjoint or adjoint-hybrid", None),
        (
            "model: {frequencies: {distribution: normal, sd: 0.1}}\nsync: {criterion: relative}\n",
            "sync.criterion relative needs fixed model.frequencies",
            None,
        ),
    ],
)
def test_bad_model_input_is_one_line(tmp_path, extra, message, files):
    _one_line(tmp_path, SMALL + extra, message, files)


def test_generalized_models_run_in_float64_only():
    from antisync.execution.compute import check_backend

    cfg = load_config_text(SMALL + "model: {phase_lag: 0.1}\ndynamics: {precision: float32}\n")
    with pytest.raises(ConfigError, match="float64 only"):
        check_backend(cfg, "cuda")
    # rk4 and interpolated crossings, CPU-only for the default model, run on the model kernels
    check_backend(
        load_config_text(SMALL + "model: {phase_lag: 0.1}\ndynamics: {integrator: rk4, dt: 0.01}\n"), "cuda"
    )


def test_relative_criterion_without_a_stable_locked_state_is_one_line(tmp_path):
    _one_line(
        tmp_path,
        TWO + "model: {frequencies: [-1.5, 1.5]}\nsync: {criterion: relative}\n",
        "sync.criterion relative: the undamaged network has no phase-locked state",
    )


def test_frequency_file_is_read_relative_to_the_config(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "p.txt").write_text("# P_i\n0.1\n-0.1\n0.05\n0\n0\n-0.05\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(SMALL + "model: {frequencies: {file: sub/p.txt}}\n")
    from antisync.plan.config import load_config

    job = make_job(load_config(cfg))
    np.testing.assert_allclose(job.model.freqs, [0.1, -0.1, 0.05, 0, 0, -0.05])
    assert Path(job.config.model.frequencies["file"]).is_absolute()
    # an edited frequency file is another simulation: --resume refuses to merge the two
    key = load_config(cfg).simulation_key()
    (tmp_path / "sub" / "p.txt").write_text("0.2\n-0.1\n0.05\n0\n0\n-0.15\n")
    assert load_config(cfg).simulation_key() != key
    assert graphs.node_order(job.graph) == [1, 2, 3, 4, 5, 6]


def test_power_grid_example_config():
    """configs/ieee14_grid.yaml: bus i is node i, injections from the file in bus order, and
    its first realizations frequency-lock."""
    from antisync.plan.config import load_config

    root = Path(__file__).resolve().parents[1]
    job = make_job(load_config(root / "configs" / "ieee14_grid.yaml"))
    assert job.nodes == list(range(1, 15)) and job.graph.number_of_edges() == 20
    p = np.array(
        [2.324, 0.183, -0.942, -0.478, -0.076, -0.112, 0, 0, -0.295, -0.09, -0.035, -0.061, -0.135, -0.149]
    )
    np.testing.assert_allclose(job.model.freqs, p - p.mean(), atol=1e-12)
    assert job.omega[0, 1] == 2.5 and job.omega[0, 4] == 2.5 and job.omega[0, 2] == 0
    sim = simulate_job(job, 0, 4)
    assert (sim.status0 == Status.SYNCED).all() and (sim.status == Status.SYNCED).all()


MODEL_KEYS = [
    "model",
    "model.frequencies",
    "model.frequencies.distribution",
    "model.frequencies.sd",
    "model.frequencies.file",
    "model.phase_lag",
    "model.inertia",
    "model.damping",
    "sync",
    "sync.criterion",
    "sync.threshold",
    "sync.fraction",
    "sync.tolerance",
]


def test_any_value_at_any_model_key_is_valid_or_one_clear_error():
    """As tests/test_hostile_input.py does for the other keys: set as YAML text or as a typed
    value, every value gives a job or one line (here with the relative criterion, so Newton
    runs on whatever frequencies get through)."""
    import yaml
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from antisync.errors import AntisyncError

    scalars = st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(2**70), 2**70),
        st.floats(),
        st.text(max_size=8),
        st.sampled_from(["1e23", "0.5", "normal", "uniform", "relative", "frequency", "-1.5"]),
    )
    values = st.recursive(
        scalars,
        lambda inner: st.one_of(
            st.lists(inner, min_size=0, max_size=7), st.dictionaries(st.text(max_size=4), inner, max_size=2)
        ),
        max_leaves=8,
    )
    base = SMALL + "sync: {criterion: relative}\nmodel: {frequencies: [0.1, 0, 0, 0, 0, -0.1]}\n"

    @settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
    @given(key=st.sampled_from(MODEL_KEYS), value=values, typed=st.booleans())
    def check(key, value, typed):
        try:
            if typed:
                cfg = load_config_text(base, values={key: value})
            else:
                text = yaml.safe_dump(value, default_flow_style=True).strip().replace("\n...", "")
                cfg = load_config_text(base, [f"{key}={text}"])
            make_job(cfg)
        except AntisyncError as exc:
            assert str(exc) and "\n" not in str(exc).strip()

    check()


# ---- the lane driver against the one-trajectory driver -----------------------------------

LANE_MODELS = {
    "euler-lag-normal": "model: {frequencies: {distribution: normal, sd: 0.1}, phase_lag: 0.3}\n"
    "dynamics: {dt: 0.02, t_max: 30, threshold: 0.9}\n",
    "euler-large-angles": "model: {frequencies: {distribution: uniform, width: 3.0}}\n"
    "dynamics: {dt: 0.05, t_max: 20, threshold: 0.9}\n",
    "rk4-order-lag": "model: {phase_lag: 0.2, frequencies: [0.1, -0.1, 0.05, 0, 0, -0.05]}\n"
    "dynamics: {integrator: rk4, dt: 0.05, t_max: 40}\n",
    "rk4-inertia-relative": "model: {frequencies: [0.1, -0.1, 0.05, 0, 0, -0.05], inertia: 0.5}\n"
    "sync: {criterion: relative, fraction: 0.97}\ndynamics: {integrator: rk4, dt: 0.05, t_max: 30}\n",
    "euler-inertia-frequency": "model: {frequencies: {distribution: uniform, width: 0.1}, inertia: 1.0}\n"
    "sync: {criterion: frequency, tolerance: 0.01}\ndynamics: {dt: 0.02, t_max: 30}\n",
    "rk4-mixed-inertia-frequency": "model: {frequencies: [0.2, -0.1, 0.05, 0, -0.1, -0.05], "
    "inertia: [1.0, 0, 0.5, 0, 2.0, 0], damping: [1.0, 1.0, 0.5, 2.0, 1.0, 1.0]}\n"
    "sync: {criterion: frequency, tolerance: 0.01}\ndynamics: {integrator: rk4, dt: 0.04, t_max: 40}\n",
    "rk4-first-order-frequency": "model: {frequencies: {distribution: normal, sd: 0.2}}\n"
    "sync: {criterion: frequency, tolerance: 0.005}\ndynamics: {integrator: rk4, dt: 0.04, t_max: 40}\n",
}


def _model_sim(job, count, **kw):
    from antisync.execution.dispatch import job_model_params

    ks = np.arange(count, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets)
    dyn = job.config.dynamics
    return cpu.simulate_model(
        job.config.seed,
        0,
        0,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        job.variant_weights,
        params,
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        integrator=dyn.integrator,
        realizations=ks,
        **kw,
    )


@pytest.mark.parametrize("name", list(LANE_MODELS))
def test_lane_driver_is_the_one_trajectory_driver_bit_for_bit(name):
    """Every status, step and crossing fraction of the lane driver (refill, per-lane
    frequencies and targets, per-node inertia) equals the one-trajectory driver's; with 7
    lanes some lanes refill mid-run and the lane count does not divide the items."""
    job = job_of(LOLLIPOP + "edges: ['2->1', '3->4', '5->6']\nbetas: [0.5]\n" + LANE_MODELS[name])
    ref = _model_sim(job, 60, lanes=0)
    assert (ref.status0 == Status.SYNCED).sum() >= 20, ref.status0
    for lanes in (cpu.LANES, 7):
        got = _model_sim(job, 60, lanes=lanes)
        for field in ("status0", "steps0", "status", "steps", "frac0", "frac"):
            np.testing.assert_array_equal(
                getattr(got, field), getattr(ref, field), err_msg=f"{field} {lanes}"
            )


def test_lane_driver_todo_integrates_only_the_marked_items():
    job = job_of(LOLLIPOP + "edges: ['2->1', '3->4']\nbetas: [0.5]\n" + LANE_MODELS["rk4-inertia-relative"])
    rng = np.random.default_rng(3)
    todo = rng.random((40, 1 + job.variant_weights.shape[0])) < 0.3
    ref = _model_sim(job, 40, lanes=0, todo=todo)
    got = _model_sim(job, 40, todo=todo)
    for field in ("status0", "steps0", "status", "steps", "frac0", "frac"):
        np.testing.assert_array_equal(getattr(got, field), getattr(ref, field), err_msg=field)
    assert (got.steps0[~todo[:, 0]] == -1).all() and (got.steps0[todo[:, 0]] >= 0).all()


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("lanes", [0, cpu.LANES])
def test_a_diverged_trajectory_is_never_synchronized(integrator, lanes):
    """An explicit step far beyond its stability bound (raw coupling 40 per link, dt 0.5: the
    configs' check refuses it, a direct kernel call does not) drives the state to inf and NaN.
    The frequency criterion's deviation then is NaN, never 0: numba's ``max(0.0, nan)`` is 0.0,
    and such trajectories were reported SYNCED within a few steps. Now none is: each runs to
    ``t_max`` and counts as NOT_SYNCED, on both drivers."""
    job = job_of(
        LOLLIPOP + "edges: ['2->1']\nbetas: [0.5]\n"
        "model: {frequencies: [0.1, -0.1, 0.05, 0.0, -0.05, 0.0], inertia: 1.0}\n"
        "sync: {criterion: frequency, tolerance: 0.01}\n"
        f"dynamics: {{coupling: raw, integrator: {integrator}, dt: 0.01, t_max: 20}}\n"
    )
    ks = np.arange(8, dtype=np.uint64)
    from antisync.execution.dispatch import job_model_params

    params = job_model_params(job, ks, job.model.targets)
    sim = cpu.simulate_model(
        job.config.seed,
        0,
        0,
        job.csr.indptr,
        job.csr.indices,
        40.0 * job.csr.weights,
        40.0 * job.variant_weights,
        params,
        dt=0.5,
        max_steps=40,
        integrator=integrator,
        realizations=ks,
        lanes=lanes,
    )
    assert (sim.status0 == Status.NOT_SYNCED).all(), sim.status0
    assert (sim.status == Status.NOT_SYNCED).all(), sim.status
