"""The CPU kernel against the slow reference and against closed forms."""

import numpy as np
import pytest
from naive import sync_steps, two_oscillator_tau

from antisync.kernels.cpu import simulate
from antisync.physics import coupling, graphs
from antisync.physics.phases import initial_phases
from antisync.status import Status


def _arrays(g, damages, kind="normalized"):
    omega = graphs.omega_matrix(g)
    csr = coupling.to_csr(coupling.coupling_matrix(omega, kind), pattern=omega > 0)
    return omega, csr, coupling.variant_weights(omega, csr, damages, kind)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_cpu_kernel_matches_naive_reference(kind):
    g = graphs.lollipop(6, 3)
    damages = [(1, 0, 0.5), (4, 5, 0.3), (1, 2, 0.01), (0, 1, 0.5)]
    omega, csr, vw = _arrays(g, damages, kind)
    dt, thr, max_steps, m = 0.002, 0.99, 40_000, 24
    res = simulate(
        9, 0, m, csr.indptr, csr.indices, csr.weights, vw, dt=dt, threshold=thr, max_steps=max_steps
    )
    theta0 = initial_phases(9, 0, m, 6)
    w0 = coupling.coupling_matrix(omega, kind)
    mismatched = 0
    for r in range(m):
        st, k = sync_steps(theta0[r], w0, dt, thr, max_steps)
        assert res.status0[r] == st
        # (cos, sin) rotation and theta updates round differently: a crossing may move by a
        # step when r(t) passes the threshold within rounding of a grid point
        assert abs(int(res.steps0[r]) - k) <= 1
        mismatched += int(res.steps0[r] != k)
        for v, (a, b, beta) in enumerate(damages):
            wv = coupling.coupling_matrix(coupling.damaged_omega(omega, a, b, beta), kind)
            st, k = sync_steps(theta0[r], wv, dt, thr, max_steps)
            assert res.status[r, v] == st
            assert abs(int(res.steps[r, v]) - k) <= 1
            mismatched += int(res.steps[r, v] != k)
    assert mismatched <= 1  # out of 120 integrations


def test_two_oscillators_closed_form_and_first_order_convergence():
    """N=2: tau = ln(tan(phi0/2)/tan(arccos r))/2 exactly; Euler's error must shrink like dt."""
    g = graphs.from_networkx("path_graph", {"n": 2})
    omega, csr, vw = _arrays(g, [])
    thr = 0.99
    # pick realizations with a comfortable initial phase difference
    theta0 = initial_phases(2, 0, 200, 2)
    phi0 = np.angle(np.exp(1j * (theta0[:, 1] - theta0[:, 0])))
    keep = np.flatnonzero((np.abs(phi0) > 0.8) & (np.abs(phi0) < 2.6))[:5]
    exact = np.array([two_oscillator_tau(phi0[r], thr) for r in keep])
    dts = np.array([0.004, 0.002, 0.001, 0.0005])
    errors = []
    for dt in dts:
        res = simulate(
            2, 0, 200, csr.indptr, csr.indices, csr.weights, vw, dt=dt, threshold=thr, max_steps=200_000
        )
        assert np.all(res.status0[keep] == Status.SYNCED)
        errors.append(np.abs(res.steps0[keep] * dt - exact).mean())
    order = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert 0.8 < order < 1.2, (order, errors)
    assert errors[-1] < 2e-3


def test_already_synced_and_not_synced_status():
    g = graphs.from_networkx("path_graph", {"n": 2})
    omega, csr, vw = _arrays(g, [])
    theta0 = initial_phases(2, 0, 200, 2)
    r0 = np.abs(np.exp(1j * theta0).mean(axis=1))
    res = simulate(2, 0, 200, csr.indptr, csr.indices, csr.weights, vw, dt=0.01, threshold=0.99, max_steps=5)
    assert np.array_equal(res.status0 == Status.ALREADY_SYNCED, r0 >= 0.99)
    assert np.all(res.steps0[res.status0 == Status.ALREADY_SYNCED] == 0)
    assert np.any(res.status0 == Status.NOT_SYNCED)


def test_results_do_not_depend_on_threads_or_batching():
    g = graphs.lollipop(6, 3)
    omega, csr, vw = _arrays(g, [(1, 0, 0.5), (4, 5, 0.5)])
    args = (csr.indptr, csr.indices, csr.weights, vw)
    kw = dict(dt=0.002, threshold=0.99, max_steps=40_000)
    one = simulate(4, 0, 64, *args, threads=1, **kw)
    two = simulate(4, 0, 64, *args, threads=2, **kw)
    part = simulate(4, 40, 24, *args, threads=2, **kw)
    for name in ("status0", "steps0", "status", "steps"):
        assert np.array_equal(getattr(one, name), getattr(two, name))
        assert np.array_equal(getattr(one, name)[40:], getattr(part, name))


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_todo_integrates_only_the_marked_items_with_the_same_bits(integrator):
    """``todo`` refills the lanes from the marked (realization, network) items alone: each is
    the trajectory of the full call, the rest are marked -1, and a variant equal to the base is
    integrated rather than copied from a base that did not run."""
    g = graphs.lollipop(6, 3)
    # 0 -> 1 leaves a degree-1 node: its normalized W equals the base
    omega, csr, vw = _arrays(g, [(1, 0, 0.5), (0, 1, 0.5), (4, 5, 0.01)])
    args = (csr.indptr, csr.indices, csr.weights, vw)
    dt = 0.002 if integrator == "euler" else 0.04
    kw = dict(dt=dt, threshold=0.99, max_steps=30_000, integrator=integrator)
    full = simulate(5, 0, 40, *args, **kw)
    todo = np.random.default_rng(1).random((40, 4)) < 0.15
    todo[3, 2] = True  # the base-equal variant, with the base itself not asked for
    todo[3, 0] = False
    part = simulate(5, 0, 40, *args, todo=todo, threads=2, lanes=8, **kw)
    for name, col in (("status0", 0), ("steps0", 0), ("frac0", 0), ("status", 1), ("steps", 1), ("frac", 1)):
        got, want = getattr(part, name), getattr(full, name)
        mask = todo[:, 0] if col == 0 else todo[:, 1:]
        assert np.array_equal(got[mask], want[mask]), name
        skipped = got[~mask]
        assert (np.isnan(skipped) if name.startswith("frac") else skipped == -1).all(), name
    # the default 32 lanes narrowed to 16 for these few items (_layout): same bits
    wide = simulate(5, 0, 40, *args, todo=todo, **kw)
    for name in ("status0", "steps0", "status", "steps"):
        assert np.array_equal(getattr(wide, name), getattr(part, name)), name
    for name in ("frac0", "frac"):
        np.testing.assert_array_equal(getattr(wide, name), getattr(part, name))
    with pytest.raises(ValueError, match=r"todo must have shape \(40, 4\)"):
        simulate(5, 0, 40, *args, todo=todo[:, :3], **kw)
    with pytest.raises(ValueError, match="todo runs in the lane driver"):
        simulate(5, 0, 40, *args, todo=todo, lanes=0, dt=0.002, threshold=0.99, max_steps=100)


def test_scattered_items_narrow_the_lanes_and_the_groups():
    """A todo run's layout: 32 lanes halved to 16 (never below, never widened) while a group
    would get fewer than eight items a lane, and no more groups than it takes to fill them."""
    from antisync.kernels.cpu import _layout

    assert _layout(46, 1, 32) == (1, 16)
    assert _layout(46, 2, 32) == (2, 16)
    assert _layout(10, 2, 32) == (1, 16)
    assert _layout(256, 1, 32) == (1, 32)
    assert _layout(300, 2, 32) == (2, 16)
    assert _layout(5, 4, 8) == (1, 8)
    assert _layout(0, 2, 32) == (1, 16)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_lane_driver_is_bit_identical_to_scalar_driver(kind):
    """Lanes step many trajectories together; each must see exactly the scalar arithmetic."""
    g = graphs.lollipop(7, 2)
    omega, csr, vw = _arrays(g, [(1, 0, 0.5), (0, 1, 0.5), (4, 5, 0.01), (2, 3, 0.9)], kind)
    args = (csr.indptr, csr.indices, csr.weights, vw)
    kw = dict(dt=0.002, threshold=0.99, max_steps=30_000)
    scalar = simulate(6, 0, 90, *args, lanes=0, **kw)
    for lanes in (1, 7, 32):
        lane = simulate(6, 0, 90, *args, lanes=lanes, **kw)
        for name in ("status0", "steps0", "status", "steps"):
            assert np.array_equal(getattr(scalar, name), getattr(lane, name)), (lanes, name)


@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_float32_lanes_are_bit_identical_to_the_float32_scalar_driver(kind):
    """float32 lanes (twice the lanes per machine vector, renormalized every 64 steps) against
    the one-trajectory float32 driver, lane counts that do and do not fill a vector block; and
    close to, not equal to, float64."""
    g = graphs.lollipop(7, 2)
    omega, csr, vw = _arrays(g, [(1, 0, 0.5), (0, 1, 0.5), (4, 5, 0.01), (2, 3, 0.9)], kind)
    args = (csr.indptr, csr.indices, csr.weights, vw)
    kw = dict(dt=0.002, threshold=0.99, max_steps=30_000, precision="float32")
    scalar = simulate(6, 0, 90, *args, lanes=0, **kw)
    for lanes in (1, 16, 32, 40):
        lane = simulate(6, 0, 90, *args, lanes=lanes, **kw)
        for name in ("status0", "steps0", "status", "steps"):
            assert np.array_equal(getattr(scalar, name), getattr(lane, name)), (lanes, name)
        assert ((lane.frac > 0) & (lane.frac <= 1)).all()
    double = simulate(6, 0, 90, *args, **{**kw, "precision": "float64"})
    assert np.array_equal(double.status, scalar.status)
    steps = np.concatenate([scalar.steps0[:, None], scalar.steps], axis=1)
    ref = np.concatenate([double.steps0[:, None], double.steps], axis=1)
    assert 0 < (steps != ref).mean() < 0.05  # a few one-step changes
    assert np.abs(steps - ref).max() <= 0.01 * ref.max()


def test_float32_runs_the_euler_step_with_taylor_rotations_only():
    g = graphs.lollipop(6, 3)
    omega, csr, vw = _arrays(g, [(1, 0, 0.5)])
    args = (4, 0, 8, csr.indptr, csr.indices, csr.weights, vw)
    kw = dict(threshold=0.99, max_steps=100, precision="float32")
    with pytest.raises(ValueError, match="float32 runs the euler integrator only"):
        simulate(*args, dt=0.04, integrator="rk4", **kw)
    with pytest.raises(ValueError, match=r"needs dt \* max_i sum_j \|w_ij\| <= 0.05 \(got 0.1\)"):
        simulate(*args, dt=0.1, **kw)
    with pytest.raises(ValueError, match="precision must be one of float64, float32, got 'float16'"):
        simulate(*args, dt=0.01, **{**kw, "precision": "float16"})
    # the one-trajectory driver rotates by cos/sin beyond the Taylor range
    assert simulate(*args, dt=0.1, lanes=0, **kw).status0.shape == (8,)


def test_rk4_converges_with_fourth_order_and_euler_interpolated_with_first():
    """Crossing times located inside the step (linear for Euler, cubic Hermite for RK4) against
    the exact two-oscillator tau: the fitted orders must be 1 and 4."""
    g = graphs.from_networkx("path_graph", {"n": 2})
    omega, csr, vw = _arrays(g, [])
    theta0 = initial_phases(2, 0, 200, 2)
    phi0 = np.angle(np.exp(1j * (theta0[:, 1] - theta0[:, 0])))
    keep = np.flatnonzero((np.abs(phi0) > 0.8) & (np.abs(phi0) < 2.6))[:6]
    exact = np.array([two_oscillator_tau(phi0[r], 0.99) for r in keep])
    for integrator, dts, expected in (
        ("euler", [0.004, 0.002, 0.001], 1.0),
        ("rk4", [0.2, 0.1, 0.05, 0.025], 4.0),
    ):
        errors = []
        for dt in dts:
            res = simulate(
                2,
                0,
                200,
                csr.indptr,
                csr.indices,
                csr.weights,
                vw,
                dt=dt,
                threshold=0.99,
                max_steps=int(100 / dt),
                integrator=integrator,
            )
            tau = (res.steps0 - 1 + res.frac0) * dt
            errors.append(np.abs(tau[keep] - exact).max())
        order = np.polyfit(np.log(dts), np.log(errors), 1)[0]
        assert abs(order - expected) < 0.25, (integrator, order, errors)
    assert errors[-1] < 1e-7  # rk4 at dt = 0.025


def test_rk4_matches_fine_euler_on_the_lollipop():
    g = graphs.lollipop(6, 3)
    omega, csr, vw = _arrays(g, [(1, 0, 0.5), (1, 2, 0.5)])
    args = (csr.indptr, csr.indices, csr.weights, vw)
    fine = simulate(12, 0, 40, *args, dt=0.0005, threshold=0.99, max_steps=400_000)
    rk4 = simulate(12, 0, 40, *args, dt=0.04, threshold=0.99, max_steps=5_000, integrator="rk4")
    t_fine = (fine.steps - 1 + fine.frac) * 0.0005
    t_rk4 = (rk4.steps - 1 + rk4.frac) * 0.04
    # Euler's global error is O(dt) ~ 1e-3 in tau; RK4 at dt = 0.04 is far more accurate
    assert np.median(np.abs(t_fine - t_rk4) / t_fine) < 2e-4
