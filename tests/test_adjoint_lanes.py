"""The adjoint's lane path against its one-trajectory reference, bit for bit, Euler and RK4.

``simulate_adjoint(..., lanes=True)`` (the default) runs ``LANES`` realizations side by side
(machine vectors for the Euler passes and the RK4 forward passes, lane loops for the RK4
backward pass); ``lanes=False`` runs the one-trajectory reference (``_adjoint_batch``). Every
lane performs the reference's operations in the same order, so status, steps, crossing
fraction and every ``d tau0 / d beta_e`` must be the same bits, including groups whose lanes
cross at different steps, never cross (NOT_SYNCED) or start synchronized (ALREADY_SYNCED).
"""

import numpy as np
import pytest
from test_adjoint import EULER, RK4, _network

from antisync.kernels.adjoint import LANES, link_derivatives, simulate_adjoint
from antisync.kernels.core import TAYLOR_MAX_ANGLE
from antisync.kernels.shared import row_sum_bound as _row_sum_bound
from antisync.status import ALREADY_SYNCED, NOT_SYNCED, SYNCED


def _run(csr, deriv, lanes, seed, first, count, **kw):
    return simulate_adjoint(
        seed, first, count, csr.indptr, csr.indices, csr.weights, deriv, lanes=lanes, **kw
    )


def _assert_same(a, b):
    for field in ("status0", "steps0", "frac0", "dtau"):
        x, y = getattr(a, field), getattr(b, field)
        assert x.dtype == y.dtype and np.array_equal(x, y), field


SETTINGS = {"euler": EULER, "rk4": RK4}


def _check_taylor(csr, dt):
    # the lane path runs only when every rotation angle is within the Taylor range
    assert dt * _row_sum_bound(csr.indptr, csr.weights, []) <= TAYLOR_MAX_ANGLE


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("kind", ["normalized", "raw"])
@pytest.mark.parametrize("name", ["lollipop", "random"])
def test_lanes_equal_one_trajectory_bit_for_bit(name, kind, integrator):
    omega, csr, edges = _network(name, kind)
    kw = dict(SETTINGS[integrator], integrator=integrator)
    if integrator == "euler":
        _check_taylor(csr, EULER["dt"])
    deriv = link_derivatives(omega, csr, edges, kind)
    m = 2 * LANES + 5  # three groups, the last one mostly empty lanes
    ref = _run(csr, deriv, False, 11, 0, m, **kw)
    lanes = _run(csr, deriv, True, 11, 0, m, **kw)
    assert (ref.status0 == SYNCED).all()
    assert ref.steps0.max() > 2 * ref.steps0.min()  # lanes of a group cross at different steps
    if integrator == "euler" and kind == "normalized":
        assert ref.steps0.max() > 1024  # renormalizations on the way
    _assert_same(lanes, ref)
    assert np.abs(ref.dtau).max() > 0.1


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("kind", ["normalized", "raw"])
def test_lanes_with_unsynchronized_and_presynchronized_lanes(kind, integrator):
    """One group holding every status: the group's clock runs to the step cap, lanes that start
    synchronized are never integrated, and both have zero derivatives."""
    omega, csr, edges = _network("lollipop", kind)
    deriv = link_derivatives(omega, csr, edges, kind)
    kw = dict(SETTINGS[integrator], integrator=integrator, threshold=0.62)
    probe = _run(csr, deriv, False, 2, 0, 400, **kw)
    cap = int(np.median(probe.steps0[probe.status0 == SYNCED]))
    kw["max_steps"] = cap
    probe = _run(csr, deriv, False, 2, 0, 400, **kw)
    pick = np.concatenate(
        [
            np.flatnonzero(probe.status0 == ALREADY_SYNCED)[:3],
            np.flatnonzero(probe.status0 == NOT_SYNCED)[:4],
            np.flatnonzero(probe.status0 == SYNCED)[:6],
        ]
    )
    assert pick.size == 13  # fewer than LANES: one group
    for realizations in (pick, np.arange(3 * LANES)):
        ref = simulate_adjoint(
            2, 0, 0, csr.indptr, csr.indices, csr.weights, deriv, realizations=realizations, lanes=False, **kw
        )
        lanes = simulate_adjoint(
            2, 0, 0, csr.indptr, csr.indices, csr.weights, deriv, realizations=realizations, **kw
        )
        assert set(np.unique(ref.status0)) == {SYNCED, NOT_SYNCED, ALREADY_SYNCED}
        _assert_same(lanes, ref)
        assert np.all(lanes.dtau[lanes.status0 != SYNCED] == 0.0)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
@pytest.mark.parametrize("threads", [1, 2])
def test_lanes_checkpoint_interval_and_threads_change_nothing(threads, integrator):
    omega, csr, edges = _network("random", "normalized")
    deriv = link_derivatives(omega, csr, edges, "normalized")
    kw = dict(SETTINGS[integrator], integrator=integrator)
    ref = _run(csr, deriv, False, 5, 3, 40, **kw)
    for k in (1, 7, 64, 100_000):
        got = _run(csr, deriv, True, 5, 3, 40, checkpoint_every=k, threads=threads, **kw)
        _assert_same(got, ref)


def test_lanes_fall_back_to_one_trajectory_outside_the_taylor_range():
    """A step too large for the Taylor rotations runs the reference path (same results)."""
    omega, csr, edges = _network("random", "raw")
    deriv = link_derivatives(omega, csr, edges, "raw")
    kw = dict(EULER, dt=0.02, max_steps=5_000)
    assert kw["dt"] * _row_sum_bound(csr.indptr, csr.weights, []) > TAYLOR_MAX_ANGLE
    _assert_same(_run(csr, deriv, True, 1, 0, 20, **kw), _run(csr, deriv, False, 1, 0, 20, **kw))
