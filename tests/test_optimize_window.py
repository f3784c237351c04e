"""The window objective J = 1 - time-averaged r, its discrete adjoint, and its projected design
(antisync.optimize.window)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from antisync.errors import ConfigError
from antisync.optimize import window
from antisync.optimize.budget import Budget, project
from antisync.optimize.window import (
    all_pairs,
    design_window,
    window_objective,
    window_steps,
)


def _sparse_problem(seed=0, n=12, n_links=10, n_starts=3):
    rng = np.random.default_rng(seed)
    pairs = all_pairs(n)
    links = pairs[rng.choice(len(pairs), n_links, replace=False)]
    freqs = rng.normal(0.0, 1.0, n)
    starts = rng.uniform(0.0, 2 * np.pi, (n_starts, n))
    x = rng.uniform(0.2, 2.0, n_links)
    return freqs, links, x, starts


def _dense_problem(seed=1, n=6, n_starts=2):
    rng = np.random.default_rng(seed)
    links = all_pairs(n)
    freqs = rng.uniform(-1.0, 1.0, n)
    starts = rng.uniform(0.0, 2 * np.pi, (n_starts, n))
    x = rng.uniform(0.1, 1.0, len(links))
    return freqs, links, x, starts


def _central_differences(freqs, links, x, starts, step=1e-5, **kw):
    out = np.empty_like(x)
    for l in range(x.size):
        e = np.zeros_like(x)
        e[l] = step
        hi = window_objective(freqs, links, x + e, starts=starts, gradient=False, **kw).value
        lo = window_objective(freqs, links, x - e, starts=starts, gradient=False, **kw).value
        out[l] = (hi - lo) / (2 * step)
    return out


@pytest.mark.parametrize("problem", [_sparse_problem, _dense_problem], ids=["sparse", "dense"])
def test_gradient_equals_central_differences_of_the_discrete_objective(problem):
    freqs, links, x, starts = problem()
    assert window._dense(freqs, links) == (problem is _dense_problem)  # both layouts run
    kw = dict(t_window=3.0, dt=0.05, coupling=0.8)
    got = window_objective(freqs, links, x, starts=starts, **kw)
    assert 0.0 < got.value < 1.0 and got.mean_r == pytest.approx(1.0 - got.value)
    fd = _central_differences(freqs, links, x, starts, **kw)
    assert np.linalg.norm(got.grad - fd) <= 1e-6 * np.linalg.norm(fd)


def test_dense_and_sparse_layouts_give_the_same_numbers():
    freqs, links, x, starts = _dense_problem(seed=5, n=9)
    n_steps, h = window_steps(2.0, 0.04)
    dense = window._objective(freqs, links, x, 1.3, starts, h, n_steps, True, True)
    sparse = window._objective(freqs, links, x, 1.3, starts, h, n_steps, True, False)
    assert dense[0] == pytest.approx(sparse[0], abs=1e-14)
    np.testing.assert_allclose(dense[1], sparse[1], rtol=1e-10, atol=1e-15)


def _reference(freqs, links, x, start, t_window, coupling):
    """1 - (1/T) int_0^T r dt by DOP853 at rtol 1e-10, the integral carried as one more state."""
    n = freqs.size
    w = np.zeros((n, n))
    w[links[:, 0], links[:, 1]] = x
    w[links[:, 1], links[:, 0]] = x

    def rhs(t, z):
        th = z[:n]
        s, c = np.sin(th), np.cos(th)
        dth = freqs + coupling * (c * (w @ s) - s * (w @ c))
        return np.append(dth, np.abs(np.exp(1j * th).mean()))

    sol = solve_ivp(rhs, (0.0, t_window), np.append(start, 0.0), method="DOP853", rtol=1e-10, atol=1e-12)
    return 1.0 - sol.y[-1, -1] / t_window


def test_discrete_objective_converges_to_the_continuous_one_as_dt_halves():
    freqs, links, x, starts = _sparse_problem(seed=3, n=8, n_links=7, n_starts=1)
    kw = dict(t_window=4.0, coupling=1.0)
    exact = _reference(freqs, links, x, starts[0], **kw)
    errors = [
        abs(window_objective(freqs, links, x, starts=starts, dt=dt, gradient=False, **kw).value - exact)
        for dt in (0.2, 0.1, 0.05, 0.025)
    ]
    assert errors[-1] < 1e-5
    ratios = [a / b for a, b in zip(errors, errors[1:], strict=False)]
    assert all(r > 3.5 for r in ratios), (errors, ratios)


def test_identical_frequencies_from_one_phase_keep_r_at_one():
    n = 7
    links = all_pairs(n)[::2]
    x = np.linspace(0.1, 1.0, len(links))
    got = window_objective(np.full(n, 0.3), links, x, starts=np.zeros((2, n)), t_window=2.5, dt=0.05)
    assert abs(got.value) < 1e-13
    assert np.max(np.abs(got.grad)) < 1e-13


def test_window_steps_end_exactly_at_the_window():
    assert window_steps(5.0, 0.02) == (250, 0.02)
    n, h = window_steps(1.0, 0.3)
    assert n == 3 and n * h == pytest.approx(1.0, abs=0)
    with pytest.raises(ConfigError):
        window_steps(1.0, 0.0)


def _short_problem(n=10):
    freqs = np.linspace(-0.5, 0.5, n)
    links = all_pairs(n)
    budget = Budget.of(2.0 * n, len(links), hi=1.5)
    starts = np.random.default_rng(7).uniform(-0.5, 0.5, (2, n))
    return freqs, links, budget, starts


def test_short_design_lowers_the_objective_and_stays_in_the_budget_set():
    freqs, links, budget, starts = _short_problem()
    kw = dict(starts=starts, t_window=3.0, dt=0.05)
    d = design_window(freqs, links, budget, steps=30, **kw)
    assert d.objective.shape == d.mean_r.shape == (31,)
    assert d.objective[-1] < 0.6 * d.objective[0]
    assert budget.contains(d.x)
    assert d.n_steps == 60 and d.dt == pytest.approx(0.05) and d.wall_s > 0
    again = window_objective(freqs, links, d.x, **kw)
    assert again.value == pytest.approx(d.objective[-1], rel=1e-12)


def test_textbook_adam_cannot_leave_the_uniform_start_when_every_derivative_has_one_sign():
    """Per-coordinate Adam steps by lr * sign(g) while g stays put: at the uniform start every
    dJ/dx_l < 0 (more coupling always helps), the step is a uniform shift, and the budget
    projection takes it back exactly; the scalar second moment follows g's direction."""
    freqs, links, budget, starts = _short_problem()
    grad = window_objective(freqs, links, budget.uniform(), starts=starts, t_window=3.0, dt=0.05).grad
    assert np.all(grad < 0)
    kw = dict(starts=starts, t_window=3.0, dt=0.05, steps=5)
    coordinate = design_window(freqs, links, budget, second_moment="coordinate", **kw)
    # only eps (1e-8 against derivatives down to 1e-6 here) tells the coordinates apart
    np.testing.assert_allclose(coordinate.x, budget.uniform(), rtol=2e-2)
    assert coordinate.objective[-1] > 0.99 * coordinate.objective[0]
    exact = design_window(freqs, links, budget, second_moment="coordinate", eps=0.0, **kw)
    np.testing.assert_allclose(exact.x, budget.uniform(), rtol=1e-12)
    default = design_window(freqs, links, budget, **kw)
    assert default.objective[-1] < 0.7 * default.objective[0]


def _slow_projection(y, budget):
    """The obvious reference: bisection on mu of clip(y - mu c, lo, hi) spending the budget."""
    lo_mu, hi_mu = -1e9, 1e9
    for _ in range(400):
        mid = 0.5 * (lo_mu + hi_mu)
        spent = budget.cost @ np.clip(y - mid * budget.cost, budget.lo, budget.hi)
        lo_mu, hi_mu = (mid, hi_mu) if spent > budget.total else (lo_mu, mid)
    return np.clip(y - 0.5 * (lo_mu + hi_mu) * budget.cost, budget.lo, budget.hi)


def test_the_budget_projection_is_the_bisection_reference():
    rng = np.random.default_rng(11)
    for trial in range(40):
        size = int(rng.integers(1, 60))
        cost = rng.uniform(0.2, 3.0, size) if trial % 2 else 1.0
        lo = rng.uniform(0.0, 0.3, size) if trial % 3 == 0 else 0.0
        hi = np.where(rng.random(size) < 0.5, np.inf, 0.5 + rng.uniform(0, 2, size)) if trial % 4 else np.inf
        c = np.broadcast_to(cost, (size,))
        lo_a = np.broadcast_to(lo, (size,))
        hi_a = np.broadcast_to(hi, (size,))
        total = float(c @ lo_a) + rng.uniform(0.1, 5.0)
        if np.isfinite(hi_a).all():
            total = min(total, 0.5 * (float(c @ lo_a) + float(c @ hi_a)))
        budget = Budget.of(total, size, cost=cost, lo=lo, hi=hi)
        y = rng.normal(0.0, 2.0, size) * rng.choice([1e-3, 1.0, 1e3])
        np.testing.assert_allclose(
            project(y, budget), _slow_projection(y, budget), rtol=1e-9, atol=1e-9 * (1 + np.abs(y).max())
        )


def test_bad_inputs_are_refused():
    freqs, links, x, starts = _sparse_problem()
    kw = dict(starts=starts, t_window=1.0, dt=0.1)
    with pytest.raises(ConfigError):
        window_objective(freqs, np.array([[0, 0]]), [1.0], **kw)
    with pytest.raises(ConfigError):
        window_objective(freqs, np.array([[0, 1], [1, 0]]), [1.0, 1.0], **kw)
    with pytest.raises(ConfigError):
        window_objective(freqs, links, x[:-1], **kw)
    with pytest.raises(ConfigError):
        window_objective(freqs, links, x, starts=starts[:, :-1], t_window=1.0, dt=0.1)
    with pytest.raises(ConfigError):
        design_window(freqs, links, 5.0, second_moment="diagonal", **kw)
