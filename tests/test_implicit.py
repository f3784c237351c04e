"""Rodas4 (``dynamics.integrator: rodas4``): its sparse LU against a dense solve, its order on a
smooth problem, its stability on a stiff linear one, its crossing times against the obvious
reference (solve_ivp) and against RK4 on the same phases, and the run, refusals and notes around
it."""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import naive
import networkx as nx
import numpy as np
import pytest
from test_models import FEW, LOLLIPOP, MODELS, _reference, job_of, reference_cases, tau_of
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import ConfigError
from antisync.execution.compute import check_backend, simulate_job
from antisync.execution.dispatch import job_model_params
from antisync.kernels import cpu, implicit
from antisync.kernels.core import CRIT_FREQUENCY, CRIT_ORDER
from antisync.plan.config import load_config, load_config_text
from antisync.plan.jobs import make_job, stiffness_note
from antisync.status import Status

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


def _csr(w):
    n = w.shape[0]
    rows, cols = np.nonzero(w)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, rows + 1, 1)
    return np.cumsum(indptr), cols.astype(np.int64), w[rows, cols]


@pytest.mark.parametrize("lag", [0.0, 0.4])
def test_the_planned_sparse_lu_solves_as_a_dense_solve(lag):
    """``D + L(theta)`` (weights ``w_ij cos(theta_j - theta_i - alpha)``, unsymmetric with a
    lag or directed weights) factored on the minimum-degree plan solves as numpy's dense solve."""
    rng = np.random.default_rng(3)
    g = nx.gnm_random_graph(40, 90, seed=4)
    n = g.number_of_nodes()
    w = np.zeros((n, n))
    for a, b in g.edges:
        w[a, b] = rng.uniform(0.5, 3.0)
        w[b, a] = rng.uniform(0.5, 3.0)  # directed weights on a symmetric pattern
    indptr, indices, weights = _csr(w)
    plan = implicit.factor_plan(indptr, indices)
    theta = rng.uniform(0, 2 * np.pi, n)
    dd = rng.uniform(5.0, 9.0, n)
    c, s = np.cos(theta), np.sin(theta)
    a = w * np.cos(theta[None, :] - theta[:, None] - lag)
    dense = np.diag(dd + a.sum(axis=1)) - a
    val = np.empty(plan.col.size)
    implicit._assemble(
        val, c, s, indptr, indices, weights, math.cos(lag), math.sin(lag), dd, plan.entry, plan.diag, plan.inv
    )
    assert implicit._factor(val, plan.diag, *plan[6:], 1.0)
    b = rng.normal(size=n)
    x = np.empty(n)
    implicit._solve(val, plan.ptr, plan.col, plan.diag, plan.perm, b, x, np.empty(n))
    np.testing.assert_allclose(x, np.linalg.solve(dense, b), rtol=1e-11, atol=1e-12)
    assert plan.col.size < n * n / 4  # the fill stays sparse


def _one(theta0, w, p, mass, gamma, criterion, target, t_max, h, rtol=1e-6, atol=1e-6, fixed=False):
    indptr, indices, weights = _csr(w)
    plan = implicit.factor_plan(indptr, indices)
    n = w.shape[0]
    eq = (
        np.asarray(p, dtype=float),
        weights,
        indptr,
        indices,
        1.0,
        0.0,
        np.broadcast_to(np.asarray(mass, dtype=float), (n,)).copy(),
        np.broadcast_to(np.asarray(gamma, dtype=float), (n,)).copy(),
    )
    return implicit.rodas4_sync(
        np.asarray(theta0, dtype=float),
        np.zeros(n),
        eq,
        criterion,
        target,
        t_max,
        h,
        rtol,
        atol,
        plan,
        fixed,
        math.inf,
        0.0,
    )


def test_fixed_steps_converge_at_fourth_order():
    """Two oscillators, ``delta' = -2 K sin delta``: ``tan(delta / 2)`` decays as ``exp(-2 K
    t)``, so the time at which ``r = cos(delta / 2)`` reaches 0.99 is known in closed form
    (:func:`naive.two_oscillator_tau`). Rodas4 at fixed steps ``h`` (crossing on the step's cubic
    interpolant) misses it by ``C h^4``: the fitted order is 4 +- 0.4 (h = 0.2 .. 0.025)."""
    w = np.array([[0.0, 1.0], [1.0, 0.0]])
    phi0 = 2.6
    exact = naive.two_oscillator_tau(phi0, 0.99)
    errors = []
    hs = [0.2, 0.1, 0.05, 0.025]
    for h in hs:
        st, tau, _, _, failed = _one(
            [0.0, phi0], w, [0.0, 0.0], 0.0, 1.0, CRIT_ORDER, (0.99 * 2) ** 2, 50.0, h, fixed=True
        )
        assert st == Status.SYNCED and not failed
        errors.append(abs(tau - exact))
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert 3.6 < slope < 4.4, (slope, errors)


def test_stiff_linear_problem_is_stable_far_beyond_the_explicit_limit():
    """A chain with one link 10^4 times stronger than the other, started near synchrony (the
    linear regime ``theta' = -L theta``): at fixed steps 3,000 times RK4's stability limit
    (``h lambda_max = 10^4``) Rodas4 is stable and locks at the closed form's time, whose
    slow mode sets it; RK4 at a tenth of that step blows up."""
    w = np.array([[0.0, 1e4, 0.0], [1e4, 0.0, 1.0], [0.0, 1.0, 0.0]])
    lap = np.diag(w.sum(axis=1)) - w
    xi, vec = np.linalg.eigh(lap)
    theta0 = np.array([1e-3, -2e-3, 4e-3])
    target = 1e-6

    def deviation(t):
        theta = vec @ (np.exp(-xi * t) * (vec.T @ theta0))
        rate = -lap @ theta
        return np.abs(rate - rate.mean()).max()

    lo, hi = 0.0, 50.0  # the deviation decays monotonically here: bisect its crossing
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if deviation(mid) >= target else (lo, mid)
    exact = hi
    h = 0.5
    assert h > 3000 * 2.785 / xi.max()
    st, tau, _, _, failed = _one(
        theta0, w, np.zeros(3), 0.0, 1.0, CRIT_FREQUENCY, target, 60.0, h, fixed=True
    )
    assert st == Status.SYNCED and not failed
    assert tau == pytest.approx(exact, rel=2e-3)
    # adaptive, at tolerances for phases of 1e-3 (atol is absolute: radians)
    st, tau, _, _, failed = _one(
        theta0, w, np.zeros(3), 0.0, 1.0, CRIT_FREQUENCY, target, 60.0, 1e-3, 1e-10, 1e-12
    )
    assert st == Status.SYNCED and tau == pytest.approx(exact, rel=1e-5)
    # RK4 on the same linear system at a tenth of that step: its amplification of the fast mode
    # is R(-0.05 xi_max) with R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, far beyond 1
    z = -0.05 * xi
    growth = np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
    assert growth.max() > 1e10
    y = theta0.copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(40):  # two seconds of RK4 steps of 0.05
            k1 = -lap @ y
            k2 = -lap @ (y + 0.025 * k1)
            k3 = -lap @ (y + 0.025 * k2)
            k4 = -lap @ (y + 0.05 * k3)
            y = y + 0.05 / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert not np.all(np.abs(y) < 1.0)  # blown up (or overflowed), never locked


#: inertia-frequency's few (7.5 s of a fresh clone's `make test`) runs in test-slow with its many:
#: in `make test`, Rodas4's inertia is checked against solve_ivp by inertia-relative, its
#: frequency criterion by uniform-frequency, and both together on a stiff grid (IEEE 39's
#: generators beside load buses) by test_a_stiff_grid_matches_rk4_on_the_same_phases
@pytest.mark.parametrize(("name", "size"), reference_cases(slow_few=("inertia-frequency",)))
def test_rodas4_matches_solve_ivp(name, size):
    """tau0 and tau(0.5) of 2->1 from Rodas4 (default tolerances) equal solve_ivp's event
    times (the obvious reference, DOP853 at rtol 1e-11) with the same statuses, within 1e-4 of
    tau: every criterion, frequencies, lag, inertia (realizations 0-5 here, 0-39 in
    test-slow)."""
    text, _, _ = MODELS[name]
    count = 6 if size == FEW else 40
    job = job_of(
        LOLLIPOP + f"edges: ['2->1']\nbetas: [0.5]\n{text}",
        ["dynamics.integrator=rodas4", "dynamics.dt=0.005", "dynamics.t_max=60"],
    )
    sim = simulate_job(job, 0, count)
    t0, t = tau_of(sim, 0.005)
    ref = _reference(job, count, lambda *a: naive.model_tau(*a, 60.0))
    for k in range(count):
        for v, (status, tau) in enumerate(ref[k]):
            got_status = sim.status0[k] if v == 0 else sim.status[k, 0]
            got_tau = t0[k] if v == 0 else t[k, 0]
            assert got_status == status, (k, v, got_status, status, got_tau, tau)
            if status == Status.SYNCED:
                assert got_tau == pytest.approx(tau, rel=1e-4), (k, v)


def test_a_stiff_grid_matches_rk4_on_the_same_phases():
    """The IEEE 39 swing model (generators with inertia beside first-order load buses,
    frequency locking, largest rate 1038/s): Rodas4 at the default tolerances against RK4 at a
    quarter of the config's dt = 0.0025 (paired, same phases): the same statuses, tau within 1e-3
    of tau, ``<tau0>`` within two of its standard errors; and fewer steps than a third of RK4's
    at the config's dt.
    (At the config's dt, 93% of RK4's stability limit, RK4 locks start 4 at 16.04 s, which at
    dt / 4 and in Rodas4 never locks by t_max.)"""
    cfg = load_config(CONFIGS / "ieee39_grid.yaml", ["realizations=40", "dynamics.t_max=40"])
    job = make_job(cfg)
    m = 40
    ks = np.arange(m, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets[:1])
    net = (
        cfg.seed,
        0,
        m,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        np.zeros((0, job.csr.weights.size)),
        params,
    )
    dyn = cfg.dynamics
    rk = cpu.simulate_model(*net, dt=dyn.dt / 4, max_steps=4 * dyn.max_steps, integrator="rk4", lanes=0)
    ro, stats = implicit.simulate_model(*net, dt=dyn.dt, max_steps=dyn.max_steps, stats=True)
    assert (ro.status0 == rk.status0).all()
    ok = rk.status0 == Status.SYNCED
    assert ok.mean() > 0.5
    t_rk = (rk.steps0 - 1 + rk.frac0)[ok] * dyn.dt / 4
    t_ro = (ro.steps0 - 1 + ro.frac0)[ok] * dyn.dt
    np.testing.assert_allclose(t_ro, t_rk, rtol=1e-3)
    se = t_rk.std(ddof=1) / math.sqrt(t_rk.size)
    assert abs(t_ro.mean() - t_rk.mean()) <= 2 * se
    steps = stats.accepted0[ok] + stats.rejected0[ok]
    assert np.median(steps) < np.median(rk.steps0[ok]) / 4 / 3


def test_a_run_with_rodas4_writes_its_file_and_central_differences(tmp_path):
    """``antisync run`` end to end with rodas4 and central differences: the file holds the
    integrator and tolerances in its stored config, and Lambda^KM of every link agrees with
    RK4's run on the same realizations within their paired error."""
    base = (
        LOLLIPOP
        + "edges: ['2->1', '3->4']\nmodel: {inertia: 0.5, damping: 1.0}\n"
        + "lambda: {method: central-difference}\n"
    )
    runner = CliRunner()
    out = {}
    for integrator, extra in (("rodas4", ["dynamics.rtol=1e-7", "dynamics.atol=1e-8"]), ("rk4", [])):
        path = tmp_path / f"{integrator}.yaml"
        path.write_text(
            base
            + f"dynamics: {{integrator: {integrator}, dt: 0.01, t_max: 60}}\nrealizations: 300\n"
            + f"output: {tmp_path / integrator}.h5\n"
        )
        args = ["run", str(path), "--quiet"] + sum((["--set", e] for e in extra), [])
        res = runner.invoke(app, args)
        assert res.exit_code == 0, res.output
        with h5py.File(tmp_path / f"{integrator}.h5") as f:
            assert f"integrator: {integrator}" in f.attrs["config_yaml"]
        res = runner.invoke(app, ["summary", str(tmp_path / f"{integrator}.h5")])
        assert res.exit_code == 0, res.output
        rows = [line.split() for line in res.output.splitlines()]
        out[integrator] = [r for r in rows if len(r) > 2 and "->" in r[1]][:2]  # the Lambda table
    assert len(out["rk4"]) == 2
    for a, b in zip(out["rodas4"], out["rk4"], strict=True):
        assert a[1] == b[1]
        assert float(a[2]) == pytest.approx(float(b[2]), abs=2e-3), (a, b)


@pytest.mark.parametrize(
    ("sets", "words"),
    [
        (["lambda.method=adjoint"], "no discrete adjoint"),
        (
            ["dynamics.integrator=rk4", "dynamics.rtol=1e-5"],
            "dynamics.rtol sets the step control of integrator rodas4",
        ),
        (["dynamics.atol=-1"], "dynamics.atol"),
        (["dynamics.crossing=grid"], "too coarse for rodas4"),
    ],
)
def test_what_rodas4_does_not_run_is_refused_in_one_line(tmp_path, sets, words):
    path = tmp_path / "c.yaml"
    path.write_text(
        LOLLIPOP + "model: {inertia: 0.5}\ndynamics: {integrator: rodas4, dt: 0.01}\n"
        f"output: {tmp_path / 'out.h5'}\n"
    )
    args = ["run", str(path)] + sum((["--set", s] for s in sets), [])
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    assert words in res.output
    assert "Traceback" not in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "out.h5").exists()


def test_the_backend_refusals_give_their_reasons():
    """The identical oscillators are not stiff; the CUDA kernels hold no fill-in (the cell
    refused before a GPU is looked for, so on any machine)."""
    cfg = load_config_text(LOLLIPOP + "dynamics: {integrator: rodas4}\n")
    with pytest.raises(ConfigError, match="not stiff"):
        check_backend(cfg, "cpu")
    cfg = load_config_text(LOLLIPOP + "model: {inertia: 0.5}\ndynamics: {integrator: rodas4}\n")
    with pytest.raises(ConfigError, match="runs on the cpu backend only"):
        check_backend(cfg, "cuda")


def test_the_stiffness_note_names_a_stability_bound_step():
    """IEEE 300 at RK4's dt = 0.0005 (limit 0.000609, rates 4576/s to 0.0714/s): the note; with
    rodas4, for IEEE 39 (rates spanning 1.5e3, below the note's 1e4) or for the paper's lollipop,
    none."""
    cfg = load_config(CONFIGS / "ieee300_grid.yaml")
    note = stiffness_note(make_job(cfg))
    assert note is not None and "integrator rodas4" in note and "4576/s" in note and "0.0714/s" in note
    cfg = load_config(
        CONFIGS / "ieee300_grid.yaml", ["dynamics.integrator=rodas4", "lambda.method=finite-difference"]
    )
    assert stiffness_note(make_job(cfg)) is None
    assert stiffness_note(make_job(load_config(CONFIGS / "ieee39_grid.yaml"))) is None
    assert stiffness_note(make_job(load_config_text(LOLLIPOP + "model: {inertia: 0.5}\n"))) is None
