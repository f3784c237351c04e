"""Spectral network design: the link weights that optimize a spectral quantity under a budget.

A design chooses one weight ``x_l >= 0`` per undirected link ``l = (a_l, b_l)`` of a graph on
``n`` nodes, inside the budget set of :mod:`antisync.optimize.budget`. The weighted Laplacian is

    L(x) = sum_l x_l b_l b_l^T,    b_l = e_a - e_b,

linear in ``x``. Three objectives are offered:

* the algebraic connectivity ``lambda2(L(x))``, concave and nonsmooth in ``x`` (the minimum
  of ``u^T L(x) u`` over unit ``u`` orthogonal to ``1``): :func:`design_lambda2` solves the
  semidefinite program ``max t : L(x) >= t (I - 11^T/n)`` with a barrier method and
  certifies its gap (S. Boyd, *Convex optimization of graph Laplacian eigenvalues*, Proc.
  ICM 2006, Sec. 3; A. Ghosh and S. Boyd, *Growing well-connected graphs*, Proc. 45th IEEE
  CDC, 6605 (2006));
* the total effective resistance ``R(x) = n trace(L(x)^+)`` (the Kirchhoff index: the sum of
  the effective resistances over all node pairs), convex and smooth where the graph is
  connected: :func:`design_resistance` minimizes it with a barrier method and certifies its
  gap (A. Ghosh, S. Boyd and A. Saberi, *Minimizing effective resistance of a graph*, SIAM
  Rev. 50, 37 (2008));
* the second eigenvalue of the normalized Laplacian ``I - D^-1/2 A D^-1/2``, not concave in
  ``x``: :func:`design_normalized_lambda2` runs projected supergradient ascent and certifies
  nothing.

Each design returns a :class:`SpectralDesign` and raises :class:`~antisync.errors.ConfigError`
for links that cannot connect the graph. The weights of a design are strictly inside their
bounds (interior-point iterates): a weight the optimum puts at its lower bound comes out a
tiny amount above it.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import numpy as np
from scipy.sparse.csgraph import connected_components

from antisync.errors import ConfigError
from antisync.optimize.budget import Budget, project

__all__ = [
    "SpectralDesign",
    "design_lambda2",
    "design_normalized_lambda2",
    "design_resistance",
    "lambda2",
    "lambda2_gradient",
    "laplacian",
    "normalized_lambda2",
    "total_resistance",
    "total_resistance_gradient",
]

#: Barrier methods: the barrier weight ``s`` grows by this factor once the iterate is centred.
_GROWTH = 10.0
#: ... and the iterate counts as centred when half the squared Newton decrement is below this.
_CENTRED = 1e-3
#: ... and they stop (whatever the gap) once ``m / s`` falls below this fraction of the value:
#: past it, rounding in the Newton systems dominates and the iterates no longer improve.
_FLOOR = 1e-13


class SpectralDesign(NamedTuple):
    """The result of a spectral design."""

    x: np.ndarray
    """float64 (L,): the designed weights, inside the budget set."""
    value: float
    """The objective at ``x``."""
    bound: float
    """A certified bound on the optimum (upper for a maximization, lower for a minimization);
    ``nan`` where the method gives none."""
    iterations: int
    """Iterations the method ran (Newton steps for the barrier methods)."""
    history: np.ndarray
    """float64 (iterations + 1,): the objective at the start and after each iteration."""


# ---------------------------------------------------------------------------------------------
# the objectives and their gradients


def laplacian(n: int, links, x) -> np.ndarray:
    """Weighted Laplacian ``L = sum_l x_l (e_a - e_b)(e_a - e_b)^T`` of ``n`` nodes.

    Parameters
    ----------
    n : int
        Number of nodes.
    links : array_like of int, shape (L, 2)
        0-based node pairs ``(a, b)``, ``a != b``, each undirected link once.
    x : array_like, shape (L,)
        One weight per link.

    Returns
    -------
    ndarray, shape (n, n)
        Symmetric with zero row sums; ``L_ab = L_ba = -x_l`` for the link ``l = (a, b)``.
    """
    a, b = _pairs(n, links)
    return _lap(n, a, b, _weights(x, a.size))


def lambda2(n: int, links, x) -> float:
    """Algebraic connectivity: the second-smallest eigenvalue of :func:`laplacian`.

    Zero when the links of positive weight do not connect the ``n`` nodes (M. Fiedler,
    Czech. Math. J. 23, 298 (1973)).
    """
    return float(np.linalg.eigvalsh(laplacian(n, links, x))[1])


def lambda2_gradient(n: int, links, x) -> np.ndarray:
    """Gradient of :func:`lambda2`: ``d lambda2 / d x_l = (u_a - u_b)^2``.

    ``u`` is the unit Fiedler vector: first-order perturbation gives ``d lambda2 = u^T dL u``
    with ``dL / dx_l = b_l b_l^T``. This is the gradient where ``lambda2`` is simple; where it
    is multiple it is a supergradient of the concave ``lambda2`` (any unit ``u`` of the
    eigenspace gives one).

    Returns
    -------
    ndarray, shape (L,)
    """
    a, b = _pairs(n, links)
    _, vectors = np.linalg.eigh(_lap(n, a, b, _weights(x, a.size)))
    u = vectors[:, 1]
    return (u[a] - u[b]) ** 2


def total_resistance(n: int, links, x) -> float:
    """Total effective resistance ``R = n trace(L^+)``: the sum of ``R_ij`` over node pairs.

    ``L^+`` is the pseudoinverse of :func:`laplacian`, so ``R = n sum_{i >= 2} 1 / lambda_i``
    (Ghosh, Boyd and Saberi, SIAM Rev. 50, 37 (2008), Sec. 2). ``inf`` when the links of
    positive weight do not connect the graph.
    """
    a, b = _pairs(n, links)
    return _resistance(n, a, b, _weights(x, a.size))[0]


def total_resistance_gradient(n: int, links, x) -> np.ndarray:
    """Gradient of :func:`total_resistance`: ``d R / d x_l = -n ||L^+ (e_a - e_b)||^2``.

    From ``dL^+ = -L^+ dL L^+`` on the complement of ``1`` (Ghosh, Boyd and Saberi, SIAM
    Rev. 50, 37 (2008), Sec. 5). Raises ``ValueError`` for a disconnected graph, where ``R``
    is infinite.

    Returns
    -------
    ndarray, shape (L,)
    """
    a, b = _pairs(n, links)
    value, grad, _ = _resistance(n, a, b, _weights(x, a.size), order=1)
    if not np.isfinite(value):
        raise ValueError("total_resistance_gradient: the weighted graph is disconnected (R is infinite)")
    return grad


def normalized_lambda2(n: int, links, x) -> tuple[float, np.ndarray]:
    """Second-smallest eigenvalue of the normalized Laplacian, and its gradient.

    The normalized Laplacian is ``I - D^-1/2 A D^-1/2`` with ``A`` the weighted adjacency and
    ``D = diag(A 1)`` the weighted degrees (F. Chung, *Spectral Graph Theory*, AMS 1997,
    Sec. 1.2). Its eigenvalues are those of ``L u = lambda D u``; with ``u^T D u = 1``,
    first-order perturbation gives ``d lambda = u^T (dL - lambda dD) u``, that is

        d lambda / d x_l = (u_a - u_b)^2 - lambda (u_a^2 + u_b^2).

    Where the eigenvalue is multiple this is the derivative along one eigenvector (used as an
    ascent direction, not a gradient). A node of zero degree makes the graph disconnected:
    the value is then 0 and the gradient zeros.

    Returns
    -------
    value : float
    gradient : ndarray, shape (L,)
    """
    a, b = _pairs(n, links)
    return _normalized(n, a, b, _weights(x, a.size))


# ---------------------------------------------------------------------------------------------
# the designs


def design_lambda2(
    n: int, links, budget: Budget, *, rtol: float = 1e-9, max_iter: int = 300
) -> SpectralDesign:
    """Weights in the budget set that maximize :func:`lambda2`, with a certified gap.

    Parameters
    ----------
    n : int
        Number of nodes.
    links : array_like of int, shape (L, 2)
        Candidate links (0-based node pairs).
    budget : Budget
        The feasible set (:class:`~antisync.optimize.budget.Budget` over the ``L`` links).
    rtol : float
        Stop when ``bound - value <= rtol * bound``.
    max_iter : int
        Most Newton steps.

    Returns
    -------
    SpectralDesign
        ``value``: ``lambda2`` at ``x`` (the best iterate); ``bound``: at least ``lambda2(z)``
        for every ``z`` in the set.

    Notes
    -----
    With ``Q`` an orthonormal basis of the complement of ``1`` and ``w_l = Q^T b_l``,
    ``lambda2(x) = lambda_min(S(x))``, ``S(x) = sum_l x_l w_l w_l^T``, and the problem is the
    SDP ``max t : S(x) - t I >= 0, x in set`` (Boyd 2006, Sec. 3). The method is the barrier
    method (S. Boyd and L. Vandenberghe, *Convex Optimization*, CUP 2004, Sec. 11.3):
    Newton's method with the budget as an equality constraint on
    ``-s t - log det(S(x) - t I) - sum log(x - lo) - sum log(hi - x)``, ``s`` raised tenfold
    each time the iterate is centred; the Hessian of the log-det term is
    ``(w_l^T P w_m)^2`` with ``P = (S - t I)^-1``. A step costs ``O(L^2 n + L^3)`` (a dense
    ``L x L`` Newton system): meant for graphs of up to a few hundred links.

    The bound does not rest on the solver's accuracy. Any ``Y >= 0`` with ``trace Y = 1``
    gives ``lambda2(x) <= trace(Y S(x)) = g . x`` with ``g_l = w_l^T Y w_l``, so
    ``lambda2* <= max_z g . z`` over the set, a fractional knapsack computed exactly. Two
    ``Y`` are tried: the barrier's ``P / trace P`` (the central path's dual point; its
    accuracy stalls near ``1e-6`` relative when ``lambda2*`` is multiple, as ``S - t I`` is
    then nearly singular) and, once within 0.1 %, a polished one supported on the eigenvectors
    of the smallest eigenvalues of ``S(x)``, fitted so that ``g_l / c_l`` is equal over the
    links strictly inside their bounds (the optimality condition). The smallest bound met is
    returned.
    """
    a, b = _check_design(n, links, budget)
    basis = _complement_of_ones(n)
    w = (basis[a] - basis[b]).T  # (n - 1, L): w_l = Q^T b_l

    x = _interior_point(budget)
    if x is None:  # the set is (to rounding) one point: its value, and the bound from there
        x = budget.uniform()
        values, vectors = np.linalg.eigh((w * x) @ w.T)
        bound = _polished_bound(values, vectors, w, x, budget)
        bound = min(bound, _extreme(np.square(vectors[:, 0] @ w), budget, maximize=True))
        return SpectralDesign(x, float(values[0]), float(bound), 0, np.array([values[0]]))

    values, vectors = np.linalg.eigh((w * x) @ w.T)
    t = 0.5 * values[0]
    barrier = _BoundBarrier(budget)
    m = (n - 1) + barrier.count
    s = m / values[0]
    best_x, best, bound = x, float(values[0]), np.inf
    history = [best]
    iterations = 0
    free = barrier.free
    while True:
        # P = (S - tI)^-1 from the eigenpairs of S, which also give lambda2 = values[0]
        p = (vectors / (values - t)) @ vectors.T
        pw = p @ w
        diag = np.einsum("ij,ij->j", w, pw)  # w_l^T P w_l
        trace = float(np.trace(p))
        bound = min(bound, _extreme(diag / trace, budget, maximize=True))
        if bound - values[0] <= 1e-3 * abs(bound):  # close: try the polished certificate
            bound = min(bound, _polished_bound(values, vectors, w, x, budget))
        if bound - best <= rtol * abs(bound) or iterations >= max_iter or m / s < _FLOOR * abs(best):
            break
        wf, pwf = w[:, free], pw[:, free]
        hess = np.zeros((free.size + 1, free.size + 1))
        hess[:-1, :-1] = np.square(wf.T @ pwf)
        hess[:-1, -1] = hess[-1, :-1] = -np.einsum("ij,ij->j", pwf, pwf)
        hess[-1, -1] = float(np.sum(p * p))
        bgrad, bhess = barrier.derivatives(x)
        hess[np.arange(free.size), np.arange(free.size)] += bhess
        grad = np.append(-diag[free] + bgrad, trace - s)
        step, decrement = _newton(grad, hess, budget.cost[free])
        alpha = 0.0
        if decrement / 2 > _CENTRED:
            merit = partial(_lambda2_merit, w, x, t, s, barrier)
            alpha = _line_search(merit, step, decrement, barrier.max_step(x, step[:-1]))
        if alpha == 0.0:  # centred (or stalled by rounding): raise s
            s *= _GROWTH
            continue
        iterations += 1
        x = x.copy()
        x[free] += alpha * step[:-1]
        t += alpha * step[-1]
        values, vectors = np.linalg.eigh((w * x) @ w.T)
        history.append(float(values[0]))
        if values[0] > best:
            best_x, best = x, float(values[0])
    return SpectralDesign(best_x, best, float(bound), iterations, np.array(history))


def design_resistance(
    n: int, links, budget: Budget, *, rtol: float = 1e-9, max_iter: int = 300
) -> SpectralDesign:
    """Weights in the budget set that minimize :func:`total_resistance`, with a certified gap.

    Parameters
    ----------
    n : int
        Number of nodes.
    links : array_like of int, shape (L, 2)
        Candidate links (0-based node pairs).
    budget : Budget
        The feasible set over the ``L`` links.
    rtol : float
        Stop when ``value - bound <= rtol * value``.
    max_iter : int
        Most Newton steps.

    Returns
    -------
    SpectralDesign
        ``value``: ``R`` at ``x`` (the best iterate); ``bound <= R*``.

    Notes
    -----
    ``R`` is convex in ``x`` and smooth where the graph is connected, with gradient
    ``-n ||L^+ b_l||^2`` and Hessian ``2 n (B^T L^+ B) o (B^T L^+2 B)`` (``o`` the entrywise
    product; Ghosh, Boyd and Saberi, SIAM Rev. 50, 37 (2008), Sec. 5). The method is the
    barrier method on ``s R(x) - sum log(x - lo) - sum log(hi - x)`` with the budget as an
    equality constraint (Boyd and Vandenberghe 2004, Sec. 11.3). The bound
    is the Frank-Wolfe (linearization) bound: for convex differentiable ``R``,
    ``R(x) + min_z grad R(x) . (z - x) <= R*``, the minimum over the set being a fractional
    knapsack, computed exactly; the best one over the iterates is returned. A step costs
    ``O(L^2 n + L^3)``.
    """
    a, b = _check_design(n, links, budget)
    x = _interior_point(budget)
    if x is None:  # the set is (to rounding) one point
        x = budget.uniform()
        value, grad, _ = _resistance(n, a, b, x, order=1)
        bound = (
            value + _extreme(grad, budget, maximize=False) - float(grad @ x) if grad is not None else -np.inf
        )
        return SpectralDesign(x, value, float(bound), 0, np.array([value]))

    barrier = _BoundBarrier(budget)
    m = barrier.count
    value, grad, hess = _resistance(n, a, b, x, order=2)
    s = max(m, 1) / value
    best_x, best, bound = x, value, -np.inf
    history = [value]
    iterations = 0
    while True:
        bound = max(bound, value + _extreme(grad, budget, maximize=False) - float(grad @ x))
        if best - bound <= rtol * abs(best) or iterations >= max_iter or max(m, 1) / s < _FLOOR * best:
            break
        free = barrier.free
        bgrad, bhess = barrier.derivatives(x)
        full_hess = s * hess[np.ix_(free, free)]
        full_hess[np.arange(free.size), np.arange(free.size)] += bhess
        step, decrement = _newton(s * grad[free] + bgrad, full_hess, budget.cost[free])
        alpha = 0.0
        if decrement / 2 > _CENTRED:
            merit = partial(_resistance_merit, n, a, b, x, s, barrier)
            alpha = _line_search(merit, step, decrement, barrier.max_step(x, step))
        if alpha == 0.0:  # centred (or stalled by rounding): raise s
            s *= _GROWTH
            continue
        iterations += 1
        x = x.copy()
        x[free] += alpha * step
        value, grad, hess = _resistance(n, a, b, x, order=2)
        history.append(value)
        if value < best:
            best_x, best = x, value
    return SpectralDesign(best_x, float(best), float(bound), iterations, np.array(history))


def design_normalized_lambda2(
    n: int, links, budget: Budget, *, max_iter: int = 1000, step: float = 2.0
) -> SpectralDesign:
    """Weights in the budget set that (locally) maximize :func:`normalized_lambda2`.

    Parameters
    ----------
    n : int
        Number of nodes.
    links : array_like of int, shape (L, 2)
        Candidate links (0-based node pairs).
    budget : Budget
        The feasible set over the ``L`` links.
    max_iter : int
        Number of ascent steps of each stage (below).
    step : float
        Length of each stage's first step, in units of ``|x0|`` (``x0 = budget.uniform()``).

    Returns
    -------
    SpectralDesign
        The best point of every stage; ``bound`` is ``nan`` (the objective is not concave:
        nothing is certified, and the result is a local improvement, the best found).

    Notes
    -----
    Projected supergradient ascent ``x <- P(x + s_k g / |g|)``, ``g`` the derivative of
    :func:`normalized_lambda2` and ``P`` the projection onto the set, with the diminishing,
    non-summable steps ``s_k = step |x0| / sqrt(k + 1)`` (N. Z. Shor, *Minimization Methods
    for Non-Differentiable Functions*, Springer 1985, Ch. 2); the best iterate is kept. The
    optimum is typically a multiple eigenvalue, where the function is not differentiable.

    **The boundary where a degree vanishes.** At ``lo = 0`` the ascent from ``x0`` drives a
    leaf's only link towards 0, where its degree and the normalized Laplacian are undefined, and
    it stalls there (the karate club at ``lower: 0``: 0.250, while the optimum at ``lower: 0.05``,
    0.662, is feasible). So the ascent runs in stages on the **continuation** of the lower
    bounds ``lo_k = max(lo, f_k x0)``, ``f_k`` = :data:`CONTINUATION` down to 0, each stage
    started from the last one's best: every stage's set lies inside the given one, so every
    iterate is feasible, and a weight reaches 0 only in the last stages, from a point where the
    other links already carry the leaf's node. A first stage at the given bounds from ``x0``
    (the plain ascent) is kept too; the result is the best point of all stages.
    """
    a, b = _check_design(n, links, budget)
    x0 = budget.uniform()
    scale = step * float(np.linalg.norm(x0))
    best_x, best, history = _ascend(n, a, b, budget, x0, max_iter, scale)
    x = x0
    for f in CONTINUATION:
        lo = np.maximum(budget.lo, f * x0)
        stage = Budget(budget.total, budget.cost, lo, np.maximum(budget.hi, lo))
        x, value, part = _ascend(n, a, b, stage, project(x, stage), max_iter, scale)
        history = np.concatenate([history, part])
        if value > best:
            best_x, best = x, value
    return SpectralDesign(best_x, float(best), float("nan"), len(history) - 1, history)


#: The stages of :func:`design_normalized_lambda2`'s continuation: each stage's lower bounds
#: are these fractions of the uniform point's weights (and at least the given ones).
CONTINUATION = (0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.0)


def _ascend(n, a, b, budget: Budget, x, max_iter: int, scale: float):
    """Projected supergradient ascent of :func:`normalized_lambda2` from ``x`` (feasible):
    ``(best x, best value, values)``."""
    value, grad = _normalized(n, a, b, x)
    best_x, best = x, value
    history = [value]
    for k in range(max_iter):
        norm = float(np.linalg.norm(grad))
        if norm == 0.0:  # a stationary point (or an isolated node at the start)
            break
        trial = project(x + scale / np.sqrt(k + 1) * grad / norm, budget)
        value, trial_grad = _normalized(n, a, b, trial)
        history.append(value)
        if not np.any(trial_grad):  # a node lost all its links: stay; the next step is shorter
            continue
        x, grad = trial, trial_grad
        if value > best:
            best_x, best = x, value
    return best_x, best, np.array(history)


# ---------------------------------------------------------------------------------------------
# input checks


def _pairs(n: int, links) -> tuple[np.ndarray, np.ndarray]:
    """The two endpoint arrays of ``links``, checked (``ConfigError`` saying what is wrong)."""
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 2:
        raise ConfigError(f"the number of nodes must be an integer >= 2, got {n!r}")
    arr = np.asarray(links)
    if arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ConfigError(f"links must be an (L, 2) array of node pairs, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        if not np.issubdtype(arr.dtype, np.number) or not np.all(arr == np.round(arr)):
            raise ConfigError("links must hold integer node indices")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise ConfigError(f"links must name nodes 0..{n - 1}, got indices {arr.min()}..{arr.max()}")
    if np.any(arr[:, 0] == arr[:, 1]):
        raise ConfigError("links must join two different nodes (a self-loop was given)")
    if np.unique(np.sort(arr, axis=1), axis=0).shape[0] != arr.shape[0]:
        raise ConfigError("links must list each undirected link once (a duplicate was given)")
    return arr[:, 0].copy(), arr[:, 1].copy()


def _weights(x, size: int) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.shape != (size,):
        raise ValueError(f"need one weight per link: shape ({size},), got {x.shape}")
    return x


def _check_design(n: int, links, budget: Budget) -> tuple[np.ndarray, np.ndarray]:
    """Endpoints of ``links``, after checking that the budget fits them and they connect."""
    a, b = _pairs(n, links)
    if not isinstance(budget, Budget) or budget.cost.shape != (a.size,):
        size = getattr(getattr(budget, "cost", None), "size", None)
        raise ConfigError(f"the budget must be a Budget over the {a.size} links, got one over {size}")
    usable = budget.hi > 0
    adjacency = np.zeros((n, n), dtype=bool)
    adjacency[a[usable], b[usable]] = True
    count, labels = connected_components(adjacency, directed=False)
    if count > 1:
        node = int(np.flatnonzero(labels != labels[0])[0])
        raise ConfigError(
            f"the links that may carry weight (upper bound > 0) split the {n} nodes into {count} "
            f"parts (node {node} cannot reach node 0), so lambda2 = 0 for every design; "
            "give links that connect all nodes"
        )
    return a, b


# ---------------------------------------------------------------------------------------------
# numerics


def _complement_of_ones(n: int) -> np.ndarray:
    """An orthonormal basis (n, n - 1) of the vectors orthogonal to ``1``."""
    q, _ = np.linalg.qr(np.hstack([np.ones((n, 1)), np.eye(n)[:, : n - 1]]))
    return q[:, 1:]


def _lap(n: int, a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.zeros((n, n))
    np.add.at(out, (a, b), -x)
    np.add.at(out, (b, a), -x)
    out[np.diag_indices(n)] = -out.sum(axis=1)
    return out


def _resistance(n: int, a, b, x, order: int = 0):
    """``R = n sum_i 1 / lambda_i`` and, up to ``order``, its gradient and Hessian.

    With ``E_li = v_ia - v_ib`` (``v_i`` the eigenvectors of nonzero eigenvalue):
    ``b_l^T L^+ b_m = sum_i E_li E_mi / lambda_i`` and ``L^+2`` likewise with ``lambda_i^2``.
    """
    values, vectors = np.linalg.eigh(_lap(n, a, b, x))
    if values[1] <= 1e-12 * max(values[-1], 1e-300):
        return float("inf"), None, None
    values, diff = values[1:], vectors[a, 1:] - vectors[b, 1:]
    value = n * float(np.sum(1.0 / values))
    if order == 0:
        return value, None, None
    one = (diff / values) @ diff.T  # B^T L^+ B
    two = (diff / values**2) @ diff.T  # B^T L^+2 B
    grad = -n * np.diag(two).copy()
    return value, grad, (2 * n * one * two if order > 1 else None)


def _normalized(n: int, a, b, x) -> tuple[float, np.ndarray]:
    lap = _lap(n, a, b, x)
    degree = np.diag(lap).copy()
    if np.any(degree <= 0):
        return 0.0, np.zeros(a.size)
    scale = 1.0 / np.sqrt(degree)
    values, vectors = np.linalg.eigh(scale[:, None] * lap * scale[None, :])
    lam = float(values[1])
    u = vectors[:, 1] * scale  # u^T D u = 1
    return lam, (u[a] - u[b]) ** 2 - lam * (u[a] ** 2 + u[b] ** 2)


def _extreme(g: np.ndarray, budget: Budget, maximize: bool) -> float:
    """``max`` (or ``min``) of ``g . z`` over the budget set: a fractional knapsack, exactly.

    From ``z = lo`` the rest of the budget goes to the variables in order of ``g_l / c_l``
    (largest first to maximize), each up to its upper bound.
    """
    sign = 1.0 if maximize else -1.0
    order = np.argsort(-sign * g / budget.cost, kind="stable")
    cost, lo, hi = budget.cost[order], budget.lo[order], budget.hi[order]
    room = (hi - lo) * cost
    before = np.concatenate([[0.0], np.cumsum(room)[:-1]])
    left = budget.total - float(budget.cost @ budget.lo)
    spend = np.minimum(room, np.maximum(left - before, 0.0))
    z = lo + spend / cost
    return float(g[order] @ z)


def _interior_point(budget: Budget) -> np.ndarray | None:
    """A point strictly inside every non-degenerate bound, on the budget; ``None`` if none.

    ``x = lo + alpha (h - lo)`` with ``h = hi`` (or, for ``hi = inf``, far enough that the
    budget is reached at ``alpha < 1``).
    """
    lo, hi, cost = budget.lo, budget.hi, budget.cost
    spare = budget.total - float(cost @ lo)
    free = hi > lo
    if not np.any(free) or spare <= 1e-9 * budget.total:
        return None
    target = np.where(np.isfinite(hi), hi, lo + 2 * spare / cost)
    alpha = spare / float(cost[free] @ (target[free] - lo[free]))
    if alpha >= 1 - 1e-9:
        return None
    return np.where(free, lo + alpha * (target - lo), lo)


class _BoundBarrier:
    """``-sum log(x - lo) - sum log(hi - x)`` over the variables with ``lo < hi``."""

    def __init__(self, budget: Budget):
        self.free = np.flatnonzero(budget.hi > budget.lo)
        self.lo = budget.lo[self.free]
        self.hi = budget.hi[self.free]
        self.upper = np.isfinite(self.hi)
        self.count = int(self.free.size + self.upper.sum())

    def value(self, x: np.ndarray) -> float:
        below = x[self.free] - self.lo
        above = self.hi[self.upper] - x[self.free][self.upper]
        if np.any(below <= 0) or np.any(above <= 0):
            return np.inf
        return -float(np.sum(np.log(below)) + np.sum(np.log(above)))

    def derivatives(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gradient and Hessian diagonal over the free variables."""
        below = x[self.free] - self.lo
        grad, hess = -1.0 / below, 1.0 / below**2
        above = self.hi[self.upper] - x[self.free][self.upper]
        grad[self.upper] += 1.0 / above
        hess[self.upper] += 1.0 / above**2
        return grad, hess

    def max_step(self, x: np.ndarray, dx: np.ndarray) -> float:
        """Largest ``alpha <= 1`` that keeps ``x + alpha dx`` strictly inside (99 % of the way)."""
        alpha = 1.0
        below = x[self.free] - self.lo
        down = dx < 0
        if np.any(down):
            alpha = min(alpha, 0.99 * float(np.min(below[down] / -dx[down])))
        up = self.upper & (dx > 0)
        if np.any(up):
            alpha = min(alpha, 0.99 * float(np.min((self.hi[up] - x[self.free][up]) / dx[up])))
        return alpha


def _newton(grad: np.ndarray, hess: np.ndarray, cost: np.ndarray) -> tuple[np.ndarray, float]:
    """Newton step for ``min f`` subject to ``cost . dx = 0`` and its squared decrement.

    ``cost`` covers the first ``cost.size`` variables (any further one, like ``t``, is free of
    the budget). The bordered KKT system is solved after a symmetric diagonal (Jacobi)
    scaling, which tames the barrier terms of variables close to their bounds.
    """
    size = grad.size
    kkt = np.zeros((size + 1, size + 1))
    kkt[:size, :size] = hess
    kkt[: cost.size, size] = kkt[size, : cost.size] = cost
    scale = np.sqrt(np.abs(np.append(np.diag(hess), 1.0)))
    scale[scale == 0] = 1.0
    rhs = np.append(-grad, 0.0) / scale
    try:
        solution = np.linalg.solve(kkt / scale[:, None] / scale[None, :], rhs) / scale
    except np.linalg.LinAlgError:
        solution = np.linalg.lstsq(kkt / scale[:, None] / scale[None, :], rhs, rcond=None)[0] / scale
    step = solution[:size]
    return step, max(-float(grad @ step), 0.0)


def _lambda2_merit(w, x, t, s, barrier: _BoundBarrier, z: np.ndarray) -> float:
    """Barrier function of :func:`design_lambda2` at ``(x, t) + z`` (``inf`` outside)."""
    trial = x.copy()
    trial[barrier.free] += z[:-1]
    inside = barrier.value(trial)
    gaps = np.linalg.eigvalsh((w * trial) @ w.T) - (t + z[-1])
    if not np.isfinite(inside) or gaps[0] <= 0:
        return np.inf
    return -s * (t + z[-1]) - float(np.sum(np.log(gaps))) + inside


def _resistance_merit(n, a, b, x, s, barrier: _BoundBarrier, z: np.ndarray) -> float:
    """Barrier function of :func:`design_resistance` at ``x + z`` (``inf`` outside)."""
    trial = x.copy()
    trial[barrier.free] += z
    inside = barrier.value(trial)
    if not np.isfinite(inside):
        return np.inf
    return s * _resistance(n, a, b, trial)[0] + inside


def _line_search(merit, step: np.ndarray, decrement: float, alpha: float) -> float:
    """Backtracking (Armijo) on ``merit(alpha step)`` from ``alpha``; 0 if no decrease is found."""
    start = merit(np.zeros_like(step))
    while alpha > 1e-12:
        if merit(alpha * step) <= start - 0.25 * alpha * decrement:
            return alpha
        alpha *= 0.5
    return 0.0


def _polished_bound(values, vectors, w, x, budget: Budget) -> float:
    """Bound on ``lambda2*`` from ``Y = U Z U^T``, ``U`` the eigenvectors of the low eigenvalues.

    At the optimum ``Y*`` lives on the eigenspace of ``lambda2`` and makes ``g_l / c_l`` equal
    for every link strictly inside its bounds. For ``k = 1, 2, ...`` lowest eigenvectors and a
    few thresholds for "strictly inside", ``Z`` (``k x k``, trace 1) is fitted to those
    equations by least squares, made positive semidefinite, and the exact knapsack bound of
    :func:`design_lambda2` computed; the smallest is returned (each one is valid).
    """
    lo, hi, cost = budget.lo, budget.hi, budget.cost
    typical = budget.total / float(cost.sum())
    near = int(np.sum(values <= values[0] + 0.1 * abs(values[0])))
    best = np.inf
    for k in range(1, min(near, 8) + 1):
        proj = vectors[:, :k].T @ w  # (k, L): U^T w_l
        rows, cols = np.triu_indices(k)
        factor = np.where(rows == cols, 1.0, 2.0)
        terms = (proj[rows] * proj[cols]) * factor[:, None]  # g_l = terms[:, l] . z_upper
        for threshold in (1e-3, 1e-5, 1e-7):
            inner = (x - lo > threshold * typical) & (hi - x > threshold * typical)
            if not np.any(inner):
                continue
            # unknowns (z_upper, nu): g_l - nu c_l = 0 on the inner links, trace Z = 1
            eqs = np.hstack([terms[:, inner].T, -cost[inner, None]])
            eqs = np.vstack([eqs, np.append(np.where(rows == cols, 1.0, 0.0), 0.0)])
            rhs = np.zeros(eqs.shape[0])
            rhs[-1] = 1.0
            sol = np.linalg.lstsq(eqs, rhs, rcond=None)[0][:-1]
            z = np.zeros((k, k))
            z[rows, cols] = sol
            z = z + np.triu(z, 1).T
            evals, evecs = np.linalg.eigh(z)
            evals = np.maximum(evals, 0.0)
            if evals.sum() <= 0:
                continue
            z = (evecs * (evals / evals.sum())) @ evecs.T
            g = np.einsum("il,ij,jl->l", proj, z, proj)
            best = min(best, _extreme(g, budget, maximize=True))
    return best
