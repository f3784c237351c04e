"""Tests of the spectral designs (antisync.optimize.spectral).

Closed forms on the path (Ghosh and Boyd's lambda2-optimal weights, the resistance-optimal
weights of a tree), the karate club (lambda2 and normalized lambda2 designs from the uniform
weights), an independent solver (SLSQP) for the resistance, the certified bounds against
random feasible points, the gradients against central differences, and bad input.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
from scipy.optimize import minimize

from antisync.errors import ConfigError
from antisync.optimize.budget import Budget, project
from antisync.optimize.spectral import (
    SpectralDesign,
    design_lambda2,
    design_normalized_lambda2,
    design_resistance,
    lambda2,
    lambda2_gradient,
    laplacian,
    normalized_lambda2,
    total_resistance,
    total_resistance_gradient,
)

# --- helpers -------------------------------------------------------------------------------


def path_links(n: int) -> np.ndarray:
    return np.array([(k, k + 1) for k in range(n - 1)])


def karate() -> tuple[int, np.ndarray]:
    g = nx.karate_club_graph()
    return g.number_of_nodes(), np.array(g.edges())


def random_graph(n: int, p: float, seed: int) -> np.ndarray:
    """Links of a connected G(n, p) graph (the first seed from ``seed`` that is connected)."""
    while True:
        g = nx.gnp_random_graph(n, p, seed=seed)
        if nx.is_connected(g):
            return np.array(g.edges())
        seed += 1000


def random_budget(links: np.ndarray, rng: np.random.Generator) -> Budget:
    """Unequal costs, some positive lower bounds, some finite upper bounds."""
    size = len(links)
    cost = rng.uniform(0.5, 2.0, size)
    lo = np.where(rng.random(size) < 0.5, rng.uniform(0.0, 0.3, size), 0.0)
    hi = np.where(rng.random(size) < 0.5, lo + rng.uniform(0.2, 1.5, size), np.inf)
    least = float(cost @ lo)
    return Budget.of(least + rng.uniform(3.0, 6.0), size, cost=cost, lo=lo, hi=hi)


def random_feasible(budget: Budget, rng: np.random.Generator, count: int) -> list[np.ndarray]:
    size = budget.cost.size
    return [
        project(budget.uniform() + rng.uniform(0.1, 3.0) * rng.normal(size=size), budget)
        for _ in range(count)
    ]


@pytest.fixture(scope="module")
def karate_lambda2() -> SpectralDesign:
    n, links = karate()
    return design_lambda2(n, links, Budget.of(78, len(links)))


# --- the objectives --------------------------------------------------------------------------


def test_laplacian_matches_networkx():
    rng = np.random.default_rng(0)
    links = random_graph(9, 0.4, seed=1)
    x = rng.uniform(0.1, 2.0, len(links))
    g = nx.Graph()
    g.add_nodes_from(range(9))
    g.add_weighted_edges_from((int(a), int(b), float(w)) for (a, b), w in zip(links, x, strict=True))
    np.testing.assert_allclose(laplacian(9, links, x), nx.laplacian_matrix(g).toarray(), atol=1e-14)
    expected = np.sort(np.linalg.eigvalsh(nx.normalized_laplacian_matrix(g).toarray()))[1]
    assert normalized_lambda2(9, links, x)[0] == pytest.approx(expected, rel=1e-12)
    pinv = np.linalg.pinv(nx.laplacian_matrix(g).toarray())
    assert total_resistance(9, links, x) == pytest.approx(9 * np.trace(pinv), rel=1e-12)
    # a tree: R is the sum over links of (pairs the link separates) / weight
    k = np.arange(1, 6)
    assert total_resistance(6, path_links(6), k) == pytest.approx(np.sum(k * (6 - k) / k), rel=1e-12)


def _central_difference(f, x: np.ndarray, h: float = 1e-5) -> np.ndarray:
    out = np.empty_like(x)
    for l in range(x.size):
        step = np.zeros_like(x)
        step[l] = h
        out[l] = (f(x + step) - f(x - step)) / (2 * h)
    return out


@pytest.mark.parametrize("objective", ["lambda2", "resistance", "normalized"])
@pytest.mark.parametrize("seed", [2, 3])
def test_gradients_equal_central_differences(objective, seed):
    rng = np.random.default_rng(seed)
    n = 9
    links = random_graph(n, 0.4, seed)
    x = rng.uniform(0.3, 2.0, len(links))  # interior: eigenvalues simple (almost surely)
    value, grad = {
        "lambda2": lambda: (lambda z: lambda2(n, links, z), lambda2_gradient(n, links, x)),
        "resistance": lambda: (
            lambda z: total_resistance(n, links, z),
            total_resistance_gradient(n, links, x),
        ),
        "normalized": lambda: (
            lambda z: normalized_lambda2(n, links, z)[0],
            normalized_lambda2(n, links, x)[1],
        ),
    }[objective]()
    numeric = _central_difference(value, x)
    assert np.max(np.abs(grad - numeric)) <= 1e-6 * np.max(np.abs(numeric))


# --- lambda2 ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "total", "as_list"), [(10, 9.0, False), (7, 5.0, True)])
def test_lambda2_path_closed_form(n, total, as_list):
    """Ghosh and Boyd: on the path, x*_k ~ k (n - k) and lambda2* = 12 B / (n (n^2 - 1))."""
    links = path_links(n)
    result = design_lambda2(n, links.tolist() if as_list else links, Budget.of(total, n - 1))
    k = np.arange(1, n)
    expected = total * k * (n - k) / np.sum(k * (n - k))
    star = 12 * total / (n * (n * n - 1))
    np.testing.assert_allclose(result.x, expected, rtol=1e-6)
    assert result.value == pytest.approx(star, rel=1e-6)
    assert result.value <= star * (1 + 1e-12) <= result.bound * (1 + 2e-12)
    assert result.bound - result.value <= 1e-9 * result.bound
    assert result.value == pytest.approx(lambda2(n, links, result.x), rel=1e-12)
    assert result.history.shape == (result.iterations + 1,)


def test_karate_lambda2(karate_lambda2):
    n, links = karate()
    budget = Budget.of(78, len(links))
    assert lambda2(n, links, budget.uniform()) == pytest.approx(0.4685, abs=1e-4)
    result = karate_lambda2
    assert budget.contains(result.x)
    assert result.value >= 0.92
    assert result.bound >= result.value
    assert result.bound - result.value <= 1e-8 * result.bound
    assert result.value == pytest.approx(lambda2(n, links, result.x), rel=1e-12)
    rng = np.random.default_rng(5)
    assert max(lambda2(n, links, x) for x in random_feasible(budget, rng, 50)) <= result.value


def test_lambda2_bound_holds_under_general_bounds():
    """Unequal costs, lower and upper bounds: the bound holds and nothing beats the design."""
    rng = np.random.default_rng(7)
    links = random_graph(8, 0.5, seed=7)
    budget = random_budget(links, rng)
    result = design_lambda2(8, links, budget)
    assert budget.contains(result.x)
    assert result.value <= result.bound <= result.value * (1 + 1e-8)
    assert max(lambda2(8, links, x) for x in random_feasible(budget, rng, 200)) <= result.value


def test_a_one_point_budget_returns_that_point():
    links = random_graph(6, 0.6, seed=4)
    lo = np.full(len(links), 0.5)
    budget = Budget.of(0.5 * len(links), len(links), lo=lo)
    for design in (design_lambda2, design_resistance):
        result = design(6, links, budget)
        np.testing.assert_allclose(result.x, lo)
        assert result.iterations == 0
    assert design_lambda2(6, links, budget).bound >= lambda2(6, links, lo)


# --- normalized lambda2 ----------------------------------------------------------------------


def test_karate_normalized_lambda2():
    n, links = karate()
    budget = Budget.of(78, len(links), lo=0.05)
    start = normalized_lambda2(n, links, budget.uniform())[0]
    assert start == pytest.approx(0.132, abs=1e-3)
    result = design_normalized_lambda2(n, links, budget)
    assert result.history[0] == pytest.approx(start, rel=1e-12)
    assert result.value >= 0.659
    assert np.isnan(result.bound)
    assert budget.contains(result.x)
    assert result.value == pytest.approx(normalized_lambda2(n, links, result.x)[0], rel=1e-12)
    assert result.value == pytest.approx(np.max(result.history), rel=1e-12)


def test_karate_normalized_lambda2_at_lower_0_reaches_the_lower_005_optimum():
    """At ``lower: 0`` the plain ascent stalled at 0.250 where a leaf's link went to 0; the set
    holds the ``lower: 0.05`` optimum (>= 0.662), which the continuation reaches and passes."""
    n, links = karate()
    at_0 = design_normalized_lambda2(n, links, Budget.of(78, len(links)))
    at_005 = design_normalized_lambda2(n, links, Budget.of(78, len(links), lo=0.05))
    assert at_005.value >= 0.662 and at_0.value >= at_005.value
    assert Budget.of(78, len(links)).contains(at_0.x) and np.isnan(at_0.bound)
    assert at_0.value == pytest.approx(normalized_lambda2(n, links, at_0.x)[0], rel=1e-12)


def _dense_normalized(n, links, total, parts):
    """An independent search: normalized lambda_2 at every point of the budget simplex on a grid
    of ``total / parts`` (every composition of ``parts`` into the links), dense eigenvalues."""
    import itertools

    size = len(links)
    cuts = np.array(list(itertools.combinations(range(parts + size - 1), size - 1)))
    edges = np.concatenate([-np.ones((len(cuts), 1)), cuts, np.full((len(cuts), 1), parts + size - 1)], 1)
    x = (np.diff(edges, axis=1) - 1) * total / parts
    w = np.zeros((len(x), n, n))
    for k, (a, b) in enumerate(links):
        w[:, a, b] = w[:, b, a] = x[:, k]
    degree = w.sum(axis=2)
    keep = (degree > 0).all(axis=1)
    s = 1 / np.sqrt(degree[keep])
    lam = np.linalg.eigvalsh(np.eye(n)[None] - s[:, :, None] * w[keep] * s[:, None, :])[:, 1]
    return float(lam.max())


@pytest.mark.parametrize("graph", ["lollipop", "bull", "house", "path"])
def test_normalized_lambda2_at_lower_0_beats_a_dense_search_and_every_positive_bound(graph):
    """Small graphs at ``lower: 0``: the design is at least the best point of an independent dense
    search of the whole budget set (grid 1/30 of the budget) and at least the design at a positive
    lower bound (a subset). At ``lower: 0`` the supremum is approached as leaf links vanish (on the
    path P5, lambda_2 -> 1 as its end links -> 0: the ends follow their neighbours at full
    normalized strength, unheard), so no maximum is attained and the design is a best point."""
    g = {
        "lollipop": nx.lollipop_graph(3, 3),
        "bull": nx.bull_graph(),
        "house": nx.house_graph(),
        "path": nx.path_graph(5),
    }[graph]
    n = g.number_of_nodes()
    links = np.array(sorted((min(u, v), max(u, v)) for u, v in g.edges()))
    total = float(len(links))
    result = design_normalized_lambda2(n, links, Budget.of(total, len(links)))
    assert result.value >= _dense_normalized(n, links, total, 30) - 1e-9
    assert (
        result.value >= design_normalized_lambda2(n, links, Budget.of(total, len(links), lo=0.1)).value - 1e-9
    )
    if graph == "path":
        assert 0.98 < result.value <= 1.0


# --- resistance ------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "total"), [(10, 9.0), (7, 5.0)])
def test_resistance_path_closed_form(n, total):
    """A tree has R = sum_l s_l (n - s_l) / x_l; under sum x = B: x_l ~ sqrt(s_l (n - s_l))."""
    k = np.arange(1, n)
    root = np.sqrt(k * (n - k))
    result = design_resistance(n, path_links(n), Budget.of(total, n - 1))
    np.testing.assert_allclose(result.x, total * root / root.sum(), rtol=1e-6)
    star = root.sum() ** 2 / total
    assert result.value == pytest.approx(star, rel=1e-9)
    assert result.bound <= star * (1 + 1e-12)
    assert result.value - result.bound <= 1e-9 * result.value


def test_resistance_small_graph_against_slsqp():
    rng = np.random.default_rng(11)
    n = 7
    links = random_graph(n, 0.5, seed=11)
    budget = random_budget(links, rng)
    result = design_resistance(n, links, budget)
    assert budget.contains(result.x)
    assert result.value <= total_resistance(n, links, budget.uniform())
    assert result.bound <= result.value <= result.bound * (1 + 1e-9)
    reference = minimize(
        lambda z: total_resistance(n, links, z),
        budget.uniform(),
        jac=lambda z: total_resistance_gradient(n, links, z),
        method="SLSQP",
        bounds=[(lo, hi if np.isfinite(hi) else None) for lo, hi in zip(budget.lo, budget.hi, strict=True)],
        constraints=[
            {"type": "eq", "fun": lambda z: budget.cost @ z - budget.total, "jac": lambda z: budget.cost}
        ],
        options={"ftol": 1e-14, "maxiter": 500},
    )
    assert reference.success
    assert result.bound <= reference.fun * (1 + 1e-12)
    assert result.value == pytest.approx(reference.fun, rel=1e-8)


def test_karate_resistance_improves_on_uniform():
    n, links = karate()
    budget = Budget.of(78, len(links))
    result = design_resistance(n, links, budget)
    assert result.bound <= result.value < total_resistance(n, links, budget.uniform())
    assert result.value - result.bound <= 1e-9 * result.value


# --- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize("design", [design_lambda2, design_resistance, design_normalized_lambda2])
def test_a_disconnected_graph_is_a_config_error(design):
    links = np.array([(0, 1), (1, 2), (3, 4)])
    with pytest.raises(ConfigError, match="connect") as info:
        design(5, links, Budget.of(3, 3))
    assert "\n" not in str(info.value)
    # links that the upper bounds switch off count as absent
    with pytest.raises(ConfigError, match="connect"):
        design(3, np.array([(0, 1), (1, 2)]), Budget.of(1, 2, hi=np.array([1.0, 0.0])))


@pytest.mark.parametrize(
    ("links", "match"),
    [
        (np.array([0, 1, 2]), "shape"),
        (np.array([(0, 1), (1, 5)]), "nodes 0..3"),
        (np.array([(0, 1), (1, 1)]), "self-loop"),
        (np.array([(0, 1), (1, 0)]), "once"),
        (np.array([(0.5, 1.0), (1.0, 2.0)]), "integer"),
    ],
)
def test_bad_links_are_config_errors(links, match):
    with pytest.raises(ConfigError, match=match):
        design_lambda2(4, links, Budget.of(2, 2))


def test_bad_budgets_are_config_errors():
    links = path_links(4)
    with pytest.raises(ConfigError, match="outside what the bounds allow"):
        Budget.of(1.0, 3, lo=0.5)
    with pytest.raises(ConfigError, match="outside what the bounds allow"):
        Budget.of(10.0, 3, hi=1.0)
    with pytest.raises(ConfigError, match="over the 3 links"):
        design_resistance(4, links, Budget.of(2, 4))
