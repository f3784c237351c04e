"""The adjoint of the generalized models (antisync/kernels/model_adjoint.py) against central
differences of the same discrete integrator's interpolated crossing, per realization."""

from __future__ import annotations

import numpy as np
import pytest
from test_models import LOLLIPOP, dense_w, job_of

from antisync.execution.compute import lambda_values
from antisync.kernels import cpu
from antisync.kernels.adjoint import link_derivatives
from antisync.kernels.model_adjoint import simulate_model_adjoint
from antisync.physics import coupling
from antisync.physics.locked import locked_state
from antisync.status import Status

LAG = "model: {frequencies: [0.15, -0.1, 0.05, 0.12, -0.2, -0.02], phase_lag: 0.3}\n"
MIXED = (
    "model: {frequencies: [0.3, -0.1, -0.15, 0.2, -0.1, -0.15], inertia: [1.0, 0, 0, 0.5, 0, 2.0],\n"
    "        damping: [1.0, 0.8, 1.2, 0.6, 1.0, 1.5], phase_lag: 0.1}\n"
)
ORDER = "dynamics: {threshold: 0.9}\n"
FREQUENCY = "sync: {criterion: frequency, tolerance: 0.002}\n"
RELATIVE = "sync: {criterion: relative, fraction: 0.98}\n"
CASES = {
    "lag-order": LAG + ORDER,
    "lag-frequency": LAG + FREQUENCY,
    "lag-relative": LAG + RELATIVE,
    "mixed-inertia-frequency": MIXED + FREQUENCY,
    "mixed-inertia-relative": MIXED + RELATIVE,
}


def _central_differences(job, params, dt, count, integrator, H=1e-6):
    """d tau0 / d beta_e of every link by central differences (beta = +-H) of the model
    driver's interpolated crossing, each row with its own target; and d target / d beta_e."""
    s = job.model
    n = len(job.nodes)
    index = {v: i for i, v in enumerate(job.nodes)}
    rows, targets = [], []
    for a, b in job.edges:
        for h in (H, -H):
            w = coupling.variant_weights(job.omega, job.csr, [(index[a], index[b], h)], "normalized")[0]
            rows.append(w)
            if s.r_star is None:
                targets.append(s.targets[0])
            else:
                r = locked_state(
                    dense_w(job, w), params.freqs[0], job.config.model.phase_lag, s.inertia, s.damping
                ).r
                targets.append((job.config.sync.fraction * r * n) ** 2)
    sim = cpu.simulate_model(
        job.config.seed,
        0,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        np.array(rows),
        params._replace(targets=np.array([s.targets[0], *targets])),
        dt=dt,
        max_steps=int(80 / dt),
        integrator=integrator,
    )
    tau = (sim.steps - 1 + sim.frac) * dt
    dtarget = (np.array(targets[0::2]) - np.array(targets[1::2])) / (2 * H)
    return (tau[:, 0::2] - tau[:, 1::2]) / (2 * H), dtarget


@pytest.mark.parametrize("integrator,dt", [("rk4", 0.02), ("euler", 0.005)])
@pytest.mark.parametrize("case", list(CASES))
def test_adjoint_equals_central_differences_of_the_crossing(case, integrator, dt):
    """Every link of the lollipop, 16 realizations: the adjoint's d tau0/d beta_e (through the
    model step, the dense-output crossing, and for the relative criterion the target's own
    dependence on the damage) equals the central difference at beta = +-1e-6 of the same
    discrete integrator: median relative difference below 1e-6, every value below 2e-4 at the
    better of two steps (+-1e-6, +-1e-7: a nearly tangent entry into the frequency band, d tau0 /
    d beta ~ 70, curves enough that the larger step is off by 1e-3)."""
    job = job_of(
        LOLLIPOP + "edges: all\nbetas: []\n" + CASES[case],
        [f"dynamics.integrator={integrator}", f"dynamics.dt={dt}", "dynamics.t_max=80"],
    )
    s = job.model
    count = 16
    params = cpu.ModelParams(
        s.freqs[None, :], s.cos_lag, s.sin_lag, s.inertia, s.damping, s.criterion, s.targets[:1]
    )
    index = {v: i for i, v in enumerate(job.nodes)}
    deriv = link_derivatives(job.omega, job.csr, [(index[a], index[b]) for a, b in job.edges])
    fd, dtarget = _central_differences(job, params, dt, count, integrator)
    fine, _ = _central_differences(job, params, dt, count, integrator, H=1e-7)
    adj = simulate_model_adjoint(
        job.config.seed,
        0,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        deriv,
        params,
        dt=dt,
        max_steps=int(80 / dt),
        integrator=integrator,
        dtarget=dtarget if s.r_star is not None else None,
    )
    base = cpu.simulate_model(
        job.config.seed,
        0,
        count,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        np.zeros((0, job.csr.weights.size)),
        params,
        dt=dt,
        max_steps=int(80 / dt),
        integrator=integrator,
    )
    np.testing.assert_array_equal(adj.steps0, base.steps0)  # the same trajectories, bit for bit
    np.testing.assert_array_equal(adj.frac0, base.frac0)
    ok = adj.status0 == Status.SYNCED
    assert ok.all()
    rel = np.abs(adj.dtau - fd)[ok] / np.maximum(np.abs(fd[ok]), 1e-3)
    rel_fine = np.abs(adj.dtau - fine)[ok] / np.maximum(np.abs(fine[ok]), 1e-3)
    assert np.median(rel) < 1e-6, np.median(rel)
    best = np.minimum(rel, rel_fine)
    assert best.max() < 2e-4, np.sort(best.ravel())[-5:]


def test_the_hybrid_and_the_adjoint_estimate_the_derivative_on_a_model():
    """``adjoint``, ``adjoint-hybrid`` and ``central-difference`` on the same 200 starts of a
    swing-equation lollipop: the hybrid's values equal the adjoint's where not flagged and the
    central secant where flagged; the three means agree paired (the derivative d<F>/dbeta)."""
    text = LOLLIPOP + "edges: ['2->1', '4->3']\nbetas: []\n" + MIXED + FREQUENCY
    text += "dynamics: {integrator: rk4, dt: 0.02, t_max: 80}\n"
    runs = {}
    for method in ("adjoint", "adjoint-hybrid", "central-difference"):
        job = job_of(text + f"lambda: {{method: {method}, dbeta: 0.01}}\n")
        values, code, flagged, _ = lambda_values(job, None, 0, 200)
        assert (code == Status.SYNCED).mean() > 0.95
        runs[method] = (values, flagged)
    adj, _ = runs["adjoint"]
    hyb, flagged = runs["adjoint-hybrid"]
    cen, _ = runs["central-difference"]
    np.testing.assert_array_equal(hyb[~flagged], adj[~flagged])
    np.testing.assert_allclose(hyb[flagged], cen[flagged], rtol=1e-12)
    for e in range(2):
        d = hyb[:, e] - cen[:, e]
        assert abs(d.mean()) < 4 * d.std() / np.sqrt(d.size) + 1e-12


@pytest.mark.parametrize("integrator,dt", [("rk4", 0.02), ("euler", 0.005)])
def test_checkpoint_spacing_never_changes_the_results(integrator, dt):
    """``every`` (steps between stored states; RK4's forward pass runs in pieces of that many
    steps) changes the memory only: statuses, steps, crossings and every d tau0 / d beta_e are
    the same bits for 1, 5, 64 and a spacing longer than the trajectories."""
    job = job_of(
        LOLLIPOP + "edges: all\nbetas: []\n" + CASES["mixed-inertia-frequency"],
        [f"dynamics.integrator={integrator}", f"dynamics.dt={dt}", "dynamics.t_max=80"],
    )
    s = job.model
    params = cpu.ModelParams(
        s.freqs[None, :], s.cos_lag, s.sin_lag, s.inertia, s.damping, s.criterion, s.targets[:1]
    )
    index = {v: i for i, v in enumerate(job.nodes)}
    deriv = link_derivatives(job.omega, job.csr, [(index[a], index[b]) for a, b in job.edges])
    args = (job.config.seed, 0, 12, job.csr.indptr, job.csr.indices, job.csr.weights, deriv, params)
    kw = dict(dt=dt, max_steps=int(80 / dt), integrator=integrator)
    runs = [simulate_model_adjoint(*args, every=every, **kw) for every in (64, 1, 5, 100_000)]
    assert (runs[0].status0 == Status.SYNCED).all()
    for other in runs[1:]:
        for name in ("status0", "steps0", "frac0", "dtau"):
            np.testing.assert_array_equal(getattr(other, name), getattr(runs[0], name), err_msg=name)


@pytest.mark.parametrize("case", ["lag-order", "mixed-inertia-frequency"])
def test_the_replay_step_is_the_drivers_rk4_step_bit_for_bit(case):
    """``_rk4_record`` (the backward pass's replay, which keeps the stage states) is written out
    beside ``make_model_kernels``' ``rk4_step``: 300 steps of both from the same start give the
    same states and rates, bit for bit, and the kept stage states are the step's own."""
    from antisync.kernels.core import WORK_ROWS
    from antisync.kernels.model_adjoint import _rhs, _rk4_record, _rk4_step
    from antisync.kernels.shared import per_node

    job = job_of(LOLLIPOP + "edges: all\nbetas: []\n" + CASES[case])
    s = job.model
    n = len(job.nodes)
    mass, gamma = per_node(s.inertia, n), per_node(s.damping, n)
    second = bool((mass > 0).any())
    eq = (s.freqs, job.csr.weights, job.csr.indptr, job.csr.indices, s.cos_lag, s.sin_lag, mass, gamma)
    theta = np.random.default_rng(3).uniform(0, 2 * np.pi, n)
    y = np.array([np.cos(theta), np.sin(theta), np.zeros(n)])
    th, dnu = np.empty(n), np.zeros(n)
    _rhs(y[0], y[1], y[2], eq, second, th, dnu)
    ref, th_ref, dnu_ref = y.copy(), th.copy(), dnu.copy()
    st, sth, k, work = np.empty((4, 3, n)), np.empty((4, n)), np.empty((3, 4, n)), np.empty((WORK_ROWS, n))
    for _ in range(300):
        start = y.copy()
        _rk4_record(y, st, sth, k, th, dnu, eq, second, 0.02)
        _rk4_step(ref[0], ref[1], ref[2], th_ref, dnu_ref, work, eq, second, 0.02)
        _rhs(ref[0], ref[1], ref[2], eq, second, th_ref, dnu_ref)
        np.testing.assert_array_equal(st[0], start)
        for arr, want in ((y, ref), (th, th_ref), (dnu, dnu_ref)):
            np.testing.assert_array_equal(arr, want)
    # the last step's third stage state, as rk4_step leaves it in its work rows 12-14
    np.testing.assert_array_equal(st[3], work[12:15])
