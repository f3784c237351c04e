"""Gradient design of coupling weights for the time-averaged Kuramoto order parameter.

The dynamics (phases ``theta``, natural frequencies ``omega``, coupling scale ``K``)::

    d theta_i / dt = omega_i + K sum_j W_ij sin(theta_j - theta_i)

with ``W`` symmetric and ``W_ab = W_ba = x_l`` for each design pair ``l = (a, b)`` (``links``,
shape ``(L, 2)``, 0-based; every other entry of ``W`` is 0). One trajectory is integrated by
classical RK4 with a fixed step ``h`` over ``[0, T]`` (``n = round(T / dt)`` steps and
``h = T / n``, so the window is exact), and the objective is

    J(x) = 1 - (1 / T) * trapezoid_h( r(t_0), ..., r(t_n) ),   r = |mean_j exp(i theta_j)|,

averaged over a batch of starts ``theta(0)`` (array ``(S, N)``). :func:`window_objective`
returns ``J`` and its exact gradient ``dJ/dx_l`` for every link from one backward pass: the
discrete adjoint of the RK4 steps and of the trapezoid sum, so the gradient is that of *this*
discrete ``J`` to rounding (tests compare it with central differences), not an approximation
of the continuous adjoint. The forward pass keeps every state (``(n + 1) N`` doubles; N = 100
and 2,000 steps is 1.6 MB); the backward pass recomputes the four stage states of each step
from the stored state. Per right-hand side the work is ``O(N + nnz)`` with the symmetric CSR
list of ``W`` (``nnz = 2 L``): the sines and cosines are taken per node,
``sin(theta_j - theta_i) = s_j c_i - c_j s_i``, so no pair costs a trigonometric call. All
pairs free (``L = N (N - 1) / 2``) is the dense case, ``O(N^2)`` per right-hand side.

:func:`design_window` runs Adam on ``J`` and projects every iterate onto the budget set
``{lo <= x <= hi, cost . x = total}`` (:func:`antisync.optimize.budget.project`). Its default
keeps one scalar second moment instead of one per weight: at equal weights every ``dJ/dx_l``
is negative (more coupling always helps), so textbook Adam's step ``lr * sign(g)`` is a
uniform shift that the budget projection takes back exactly, and it moves only as far as
``eps`` tells the coordinates apart (see :func:`design_window`).

GradNet's Kuramoto example (the benchmark, ``bench/bench_design_gradnet.py``)
-----------------------------------------------------------------------------
GradNet (Mikaberidze and Taylor, arXiv 2509.18279; PyPI ``gradnet`` 0.5.0, PyTorch, BSD-3).
Read from the public repository ``mikaberidze/gradnet`` at commit ``a654b70`` (2026-07-01;
its three ``src`` files below are byte-identical to the PyPI 0.5.0 wheel's):
``examples/2_kuramoto.ipynb`` (the example and its printed result), ``src/gradnet/gradnet.py``
(``GradNet``, ``DenseParameterization``, ``normalize``, ``_init_raw_weights``),
``src/gradnet/ode.py`` (``integrate_ode``) and ``src/gradnet/trainer.py`` (``fit``):

- Model (notebook, ``dθ_dt``): ``dθ_i/dt = ω_i + Σ_j A_ij sin(θ_j - θ_i)``, computed as
  ``ω + cos θ ⊙ (A sin θ) - sin θ ⊙ (A cos θ)``. No coupling scale: ``K = 1``, not ``K/N``.
- ``N = 100``, ``ω = torch.linspace(0, 1, N)`` (evenly spaced, both ends included), all phases
  0 at ``t = 0`` (one start), float32 (torch's default dtype).
- Weights (``gradnet.py``, ``GradNet(num_nodes=N, budget=2.0 * N, rand_init_weights=False,
  delta_sign="nonnegative", final_sign="free", strict_budget=True)``, dense mask of all
  off-diagonal pairs): a raw ``N x N`` parameter ``P`` (10,000 numbers) is mapped to
  ``A = budget * D / sum(D)`` with ``D = (0.5 (P + P^T))**2`` off the diagonal (0 on it).
  So ``A`` is symmetric and nonnegative (by squaring), and the budget is an L1 norm of the
  whole matrix, ``sum_{i != j} A_ij = 2 N = 200``: "2 per node" is the *mean* weighted degree
  (``sum_{i<j} A_ij = N``), a single total-sum constraint, not a per-node one. Initial
  ``P`` = all ones (``rand_init_weights=False`` with ``strict_budget=True``) rescaled to
  Frobenius norm ``sqrt(N (N - 1) / 2)``, i.e. uniform ``A_ij = 2 / (N - 1)``; after every
  optimizer step ``P`` is rescaled to that norm again (``renorm_params``; ``A`` does not change).
- Time grid and loss (notebook, ``loss_fn``): ``tt = torch.linspace(0, 5, 150)``;
  ``integrate_ode`` defaults: torchdiffeq ``odeint``, ``method="dopri5"``,
  ``rtol = atol = 1e-4``, autograd through the solver steps (``adjoint=False``);
  ``r(t_k) = |mean_j exp(i θ_j(t_k))|`` at the 150 grid points, loss ``1 - mean_k r(t_k)``
  (a plain sample mean of the 150 values: ``r(0) = 1`` counts with weight 1/150).
- Optimizer (notebook, ``fit``; ``trainer.py``): ``torch.optim.Adam`` on ``P``, ``lr = 1``,
  ``betas = (0.9, 0.999)``, 600 updates, no gradient clipping. Printed result: "optimal
  synchrony: 0.9985842704772949" (the 150-point mean r of the final ``A``).

The design here matches the problem (same model, ``K = 1``, same frequencies and start, same
feasible set: ``x >= 0`` on all 4,950 pairs with ``sum_l x_l = N``, i.e. ``Budget.of(N, L)``,
same uniform initial weights, ``T = 5``) but not GradNet's parameterization: Adam moves ``x``
itself and projects, where GradNet moves ``P`` and normalizes (``A ~ S^2`` makes its steps
multiplicative in ``A``). Its ``lr = 1`` is a step on ``P`` (entries of order 1), so it does
not carry over to ``x`` (entries of order 0.02); :func:`design_window`'s default step is twice
the uniform weight (0.04 here). The objective is the time average of ``r`` by the trapezoid
rule on the RK4 step grid rather than the 150-sample mean (which differ by about 5e-6 here);
the benchmark reports both for the final weights of either program, from an independent scipy
solve.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np
from numba import njit

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)
from antisync.errors import ConfigError
from antisync.kernels.shared import csr_mv2
from antisync.optimize.budget import Budget, project

__all__ = [
    "WindowDesign",
    "WindowObjective",
    "all_pairs",
    "design_window",
    "window_objective",
    "window_steps",
]


class WindowObjective(NamedTuple):
    """``J`` at one weight vector, with its gradient."""

    value: float
    """``J = 1 - mean r`` (mean over the window by the trapezoid rule, then over starts)."""
    mean_r: float
    """``1 - J``: the time- and start-averaged order parameter."""
    grad: np.ndarray | None
    """float64 (L,): ``dJ/dx_l`` of the discrete ``J``; ``None`` when not asked for."""


class WindowDesign(NamedTuple):
    """The result of :func:`design_window`."""

    x: np.ndarray
    """float64 (L,): the final (projected) weights."""
    objective: np.ndarray
    """float64 (steps + 1,): ``J`` at the initial weights and after each Adam step."""
    mean_r: np.ndarray
    """float64 (steps + 1,): ``1 - objective``."""
    wall_s: float
    """Seconds for the whole run (gradients, Adam and projections)."""
    n_steps: int
    """RK4 steps per trajectory."""
    dt: float
    """The RK4 step actually used, ``t_window / n_steps``."""


def all_pairs(n: int) -> np.ndarray:
    """int64 (n (n - 1) / 2, 2): every pair ``(a, b)``, ``a < b``, in row-major order."""
    a, b = np.triu_indices(int(n), k=1)
    return np.stack([a, b], axis=1).astype(np.int64)


def window_steps(t_window: float, dt: float) -> tuple[int, float]:
    """``(n, h)``: the number of RK4 steps over ``[0, t_window]`` and the step ``t_window / n``.

    ``n = max(1, round(t_window / dt))``, so ``h`` is within half a step of ``dt`` and the
    window ends exactly at ``t_window``.
    """
    t_window, dt = float(t_window), float(dt)
    if not (np.isfinite(t_window) and t_window > 0):
        raise ConfigError(f"t_window must be a positive number, got {t_window!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"dt must be a positive number, got {dt!r}")
    n = max(1, int(round(t_window / dt)))
    return n, t_window / n


# ----------------------------------------------------------------------------- kernels
#
# Two layouts of W share one RK4 / adjoint skeleton (``_objective``):
# - sparse: symmetric CSR (``indptr``, ``nbr``, per-entry weight ``wv``), ``O(N + nnz)`` per
#   right-hand side, and ``dJ/dx_l`` accumulated per link and stage;
# - dense (when the pairs fill at least a quarter of the matrix): ``W`` as an ``N x N`` array,
#   matrix-vector products the compiler vectorizes, and ``dJ/dx`` accumulated as a matrix
#   ``G`` by rank-2 updates per stage (``G_ab += (c v)_a s_b - (s v)_a c_b``), read off at
#   the end as ``K (G_ab + G_ba)``.
# Both give ``Ws = W sin(theta)`` and ``Wc = W cos(theta)``, from which
# ``f_i = omega_i + K (c_i (Ws)_i - s_i (Wc)_i)``.

#: the dense layout is used when ``2 L >= N^2 / 4``
DENSE_FILL = 0.25


@njit(cache=True)
def _csr(n, links):
    """Symmetric CSR of the design pairs: ``indptr``, neighbour ``nbr`` and link id ``eid``."""
    deg = np.zeros(n + 1, dtype=np.int64)
    for l in range(links.shape[0]):
        deg[links[l, 0] + 1] += 1
        deg[links[l, 1] + 1] += 1
    indptr = np.cumsum(deg)
    fill = indptr[:-1].copy()
    nbr = np.empty(2 * links.shape[0], dtype=np.int64)
    eid = np.empty(2 * links.shape[0], dtype=np.int64)
    for l in range(links.shape[0]):
        a, b = links[l, 0], links[l, 1]
        nbr[fill[a]] = b
        eid[fill[a]] = l
        fill[a] += 1
        nbr[fill[b]] = a
        eid[fill[b]] = l
        fill[b] += 1
    return indptr, nbr, eid


@njit(cache=True, fastmath={"reassoc", "contract"})
def _dense_mv2(w, a, b, out_a, out_b):
    """``out_a = w @ a`` and ``out_b = w @ b`` (``w`` C-contiguous ``N x N``)."""
    n = a.shape[0]
    for i in range(n):
        acc_a = 0.0
        acc_b = 0.0
        for j in range(n):
            acc_a += w[i, j] * a[j]
            acc_b += w[i, j] * b[j]
        out_a[i] = acc_a
        out_b[i] = acc_b


@njit(cache=True)
def _sparse_mv2(indptr, nbr, wv, a, b, out_a, out_b):
    """``out_a = W a`` and ``out_b = W b`` with ``W`` in symmetric CSR."""
    csr_mv2(indptr, nbr, wv, a, b, out_a, out_b)


@njit(cache=True, inline="always")
def _mv2(coupling, a, b, out_a, out_b):
    """``out_a = W a`` and ``out_b = W b`` with ``coupling = (dense, w, indptr, nbr, wv)``:
    ``W`` as the dense ``w`` or in symmetric CSR, as ``dense`` says."""
    dense, w, indptr, nbr, wv = coupling
    if dense:
        _dense_mv2(w, a, b, out_a, out_b)
    else:
        _sparse_mv2(indptr, nbr, wv, a, b, out_a, out_b)


@njit(cache=True, inline="always")
def _rhs(theta, omega, kc, coupling, s, c, ws, wc, out):
    """``out = f(theta)``; leaves ``s, c = sin, cos theta`` and ``ws, wc = W s, W c``."""
    n = theta.shape[0]
    for i in range(n):
        s[i] = math.sin(theta[i])
        c[i] = math.cos(theta[i])
    _mv2(coupling, s, c, ws, wc)
    for i in range(n):
        out[i] = omega[i] + kc * (c[i] * ws[i] - s[i] * wc[i])


@njit(cache=True, fastmath={"reassoc", "contract"})
def _rank2(g, cv, s, sv, c):
    """``g += cv s^T - sv c^T``."""
    n = s.shape[0]
    for a in range(n):
        p = cv[a]
        q = sv[a]
        for b in range(n):
            g[a, b] += p * s[b] - q * c[b]


@njit(cache=True, inline="always")
def _vjp(v, kc, coupling, links, s, c, ws, wc, scratch, ybar, grad, g):
    """``ybar = (df/dtheta)^T v`` at the state with ``s, c, ws, wc`` (see :func:`_rhs`), and
    the parameter part: ``grad += (df/dx)^T v`` (sparse) or ``g += cv s^T - sv c^T`` (dense);
    ``scratch`` holds ``cv, sv, wcv, wsv``.

    ``(J^T v)_j = K sum_i W_ij cos(theta_i - theta_j) (v_i - v_j)
    = K (c_j (W cv)_j + s_j (W sv)_j - v_j (c_j (Wc)_j + s_j (Ws)_j))`` with ``cv = c v``,
    ``sv = s v``; ``d(v . f)/dx_l = K sin(theta_b - theta_a) (v_a - v_b)`` for ``l = (a, b)``.
    """
    cv, sv, wcv, wsv = scratch
    n = s.shape[0]
    for i in range(n):
        cv[i] = c[i] * v[i]
        sv[i] = s[i] * v[i]
    _mv2(coupling, cv, sv, wcv, wsv)
    if coupling[0]:
        _rank2(g, cv, s, sv, c)
    else:
        for l in range(links.shape[0]):
            a = links[l, 0]
            b = links[l, 1]
            grad[l] += kc * (s[b] * c[a] - c[b] * s[a]) * (v[a] - v[b])
    for j in range(n):
        ybar[j] = kc * (c[j] * wcv[j] + s[j] * wsv[j] - v[j] * (c[j] * wc[j] + s[j] * ws[j]))


@njit(cache=True)
def _order(s, c):
    """``(r, C, S)`` from ``s, c = sin, cos theta``: ``C = sum c``, ``S = sum s``,
    ``r = |C + i S| / N``."""
    cs = 0.0
    ss = 0.0
    for i in range(s.shape[0]):
        cs += c[i]
        ss += s[i]
    return math.sqrt(cs * cs + ss * ss) / s.shape[0], cs, ss


@njit(cache=True, inline="always")
def _stages(th, h, omega, kc, coupling, y, sn, cn, wsn, wcn, k1, k2, k3, k4):
    """RK4's stages 2-4 of the step from ``th`` (``k1`` given): the states ``y[1..3]``, their
    sines, cosines and coupling sums, and ``k2``, ``k3``, ``k4``. The forward pass and the
    backward pass's recomputation call this one function: the same operations, the same bits."""
    n = th.size
    for i in range(n):
        y[1, i] = th[i] + 0.5 * h * k1[i]
    _rhs(y[1], omega, kc, coupling, sn[1], cn[1], wsn[1], wcn[1], k2)
    for i in range(n):
        y[2, i] = th[i] + 0.5 * h * k2[i]
    _rhs(y[2], omega, kc, coupling, sn[2], cn[2], wsn[2], wcn[2], k3)
    for i in range(n):
        y[3, i] = th[i] + h * k3[i]
    _rhs(y[3], omega, kc, coupling, sn[3], cn[3], wsn[3], wcn[3], k4)


@njit(cache=True)
def _objective(omega, links, x, kc, starts, h, n_steps, want_grad, dense):
    """``(J, grad)`` of the discrete objective, averaged over the rows of ``starts``."""
    n = omega.shape[0]
    n_starts = starts.shape[0]
    n_links = links.shape[0]
    indptr, nbr, eid = _csr(n, links)
    wv = np.empty(nbr.shape[0])
    for e in range(nbr.shape[0]):
        wv[e] = x[eid[e]]
    if dense:
        w = np.zeros((n, n))
        for l in range(n_links):
            w[links[l, 0], links[l, 1]] = x[l]
            w[links[l, 1], links[l, 0]] = x[l]
        g = np.zeros((n, n))
    else:
        w = np.zeros((1, 1))
        g = np.zeros((1, 1))
    grad = np.zeros(n_links)
    t_total = h * n_steps
    traj = np.empty((n_steps + 1, n))
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    # per stage: state, sin, cos, W sin, W cos
    y = np.empty((4, n))
    sn = np.empty((4, n))
    cn = np.empty((4, n))
    wsn = np.empty((4, n))
    wcn = np.empty((4, n))
    lam = np.empty(n)
    ak = np.empty((4, n))
    ybar = np.empty(n)
    scratch = (np.empty(n), np.empty(n), np.empty(n), np.empty(n))  # cv, sv, wcv, wsv
    coupling = (dense, w, indptr, nbr, wv)
    total = 0.0
    for q in range(n_starts):
        # forward: RK4, every state kept, trapezoid sum of r
        for i in range(n):
            traj[0, i] = starts[q, i]
        acc = 0.0
        for m in range(n_steps + 1):
            th = traj[m]
            _rhs(th, omega, kc, coupling, sn[0], cn[0], wsn[0], wcn[0], k1)
            r, _, _ = _order(sn[0], cn[0])
            acc += (0.5 * h if (m == 0 or m == n_steps) else h) * r
            if m == n_steps:
                break
            _stages(th, h, omega, kc, coupling, y, sn, cn, wsn, wcn, k1, k2, k3, k4)
            for i in range(n):
                traj[m + 1, i] = th[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        total += 1.0 - acc / t_total
        if not want_grad:
            continue
        # backward: lam = dJ_q / d theta_m, from m = n_steps down to 0
        for i in range(n):
            lam[i] = 0.0
        for m in range(n_steps, -1, -1):
            th = traj[m]
            # stage 1 (the state itself): its sin/cos also serve the trapezoid term
            _rhs(th, omega, kc, coupling, sn[0], cn[0], wsn[0], wcn[0], k1)
            if m < n_steps:
                # adjoint of theta_{m+1} = theta_m + h/6 (k1 + 2 k2 + 2 k3 + k4); lam holds
                # dJ/d theta_{m+1}. Recompute the stage states of step m (same operations as
                # the forward pass, so the same bits), then walk the stages backwards.
                _stages(th, h, omega, kc, coupling, y, sn, cn, wsn, wcn, k1, k2, k3, k4)
                for i in range(n):
                    ak[3, i] = h / 6.0 * lam[i]
                    ak[2, i] = h / 3.0 * lam[i]
                    ak[1, i] = h / 3.0 * lam[i]
                    ak[0, i] = h / 6.0 * lam[i]
                # k4 = f(y4), y4 = theta + h k3; k3 = f(y3), y3 = theta + h/2 k2;
                # k2 = f(y2), y2 = theta + h/2 k1; k1 = f(theta)
                for st in range(3, -1, -1):
                    _vjp(
                        ak[st], kc, coupling, links, sn[st], cn[st], wsn[st], wcn[st], scratch, ybar, grad, g
                    )
                    back = h if st == 3 else 0.5 * h
                    for i in range(n):
                        lam[i] += ybar[i]
                        if st > 0:
                            ak[st - 1, i] += back * ybar[i]
            # the trapezoid term of theta_m: -(w_m / T) dr/dtheta_m
            r, cs, ss = _order(sn[0], cn[0])
            big_r = r * n
            if big_r > 1e-300:
                wgt = 0.5 * h if (m == 0 or m == n_steps) else h
                fac = -wgt / t_total / (n * big_r)
                for i in range(n):
                    lam[i] += fac * (ss * cn[0, i] - cs * sn[0, i])
    if dense:
        for l in range(n_links):
            a = links[l, 0]
            b = links[l, 1]
            grad[l] = kc * (g[a, b] + g[b, a])
    for l in range(n_links):
        grad[l] /= n_starts
    return total / n_starts, grad


# ----------------------------------------------------------------------------- public API


def _dense(omega: np.ndarray, links: np.ndarray) -> bool:
    """Whether the pairs fill enough of ``W`` for the dense layout (:data:`DENSE_FILL`)."""
    return 2 * links.shape[0] >= DENSE_FILL * omega.size**2


def _check_problem(freqs, links, starts):
    omega = np.ascontiguousarray(freqs, dtype=np.float64)
    if omega.ndim != 1 or omega.size < 2 or not np.all(np.isfinite(omega)):
        raise ConfigError("freqs must be a finite 1-D array of at least 2 frequencies")
    n = omega.size
    links = np.ascontiguousarray(links, dtype=np.int64)
    if links.ndim != 2 or links.shape[1] != 2 or links.shape[0] < 1:
        raise ConfigError(f"links must be an (L, 2) array of node pairs, got {links.shape}")
    if np.any(links < 0) or np.any(links >= n) or np.any(links[:, 0] == links[:, 1]):
        raise ConfigError(f"links must pair two different nodes in 0..{n - 1}")
    key = np.sort(links, axis=1)
    if np.unique(key[:, 0] * n + key[:, 1]).size != links.shape[0]:
        raise ConfigError("links must not repeat a pair")
    starts = np.array(starts, dtype=np.float64, ndmin=2, order="C")
    if starts.ndim != 2 or starts.shape[1] != n or not np.all(np.isfinite(starts)):
        raise ConfigError(f"starts must be a finite (S, {n}) array of initial phases")
    return omega, links, starts


def window_objective(
    freqs,
    links,
    x,
    *,
    starts,
    t_window: float,
    dt: float,
    coupling: float = 1.0,
    gradient: bool = True,
) -> WindowObjective:
    """``J(x) = 1 - time-averaged r`` over ``[0, t_window]`` and its gradient in ``x``.

    Parameters
    ----------
    freqs : array_like, shape (N,)
        Natural frequencies ``omega``.
    links : array_like of int, shape (L, 2)
        The design pairs (0-based, each unordered pair at most once).
    x : array_like, shape (L,)
        The weight of each pair (``W_ab = W_ba = x_l``; any sign is integrated).
    starts : array_like, shape (S, N) or (N,)
        Initial phases, one row per start; ``J`` is the mean over rows.
    t_window : float
        The window ``T``.
    dt : float
        The RK4 step; ``round(T / dt)`` steps of ``T / round(T / dt)`` are taken.
    coupling : float, optional
        ``K`` in front of the sum (1 for GradNet's example; ``1 / N`` for ``K/N`` scaling).
    gradient : bool, optional
        Whether to run the backward pass.

    Returns
    -------
    WindowObjective
        ``value`` (``J``), ``mean_r`` (``1 - J``) and ``grad`` (``dJ/dx``, or ``None``).
    """
    omega, links, starts = _check_problem(freqs, links, starts)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.shape != (links.shape[0],) or not np.all(np.isfinite(x)):
        raise ConfigError(f"x must be a finite vector of length {links.shape[0]}")
    n_steps, h = window_steps(t_window, dt)
    value, grad = _objective(
        omega, links, x, float(coupling), starts, h, n_steps, bool(gradient), _dense(omega, links)
    )
    return WindowObjective(float(value), float(1.0 - value), grad if gradient else None)


def design_window(
    freqs,
    links,
    budget,
    *,
    starts,
    t_window: float,
    dt: float,
    steps: int = 600,
    lr: float | None = None,
    x0=None,
    coupling: float = 1.0,
    second_moment: str = "global",
    betas: tuple[float, float] = (0.9, 0.999),
    eps: float = 1e-8,
) -> WindowDesign:
    """Projected Adam on ``J`` (:func:`window_objective`) over the budget set.

    Each step: ``g = dJ/dx``; first moment ``m <- b1 m + (1 - b1) g``, second moment ``v``;
    bias corrections ``m_hat, v_hat``; ``x <- project(x - lr m_hat / (sqrt(v_hat) + eps))``.

    ``second_moment="coordinate"`` is textbook Adam (``v`` per coordinate, ``v <- b2 v +
    (1 - b2) g^2``): every weight then moves by about ``lr`` per step whatever the size of its
    own derivative. ``"global"`` (the default) keeps one scalar ``v <- b2 v + (1 - b2)
    mean(g^2)``: the step follows the direction of the momentum ``m`` (heavy-ball-like), and
    ``lr`` is still the RMS step in the units of ``x``. On GradNet's Kuramoto example (N =
    100, all pairs, 600 steps) textbook Adam stalls at mean r 0.99820 for every ``lr`` and
    schedule tried (0.003 to 2), spreading weight over thousands of pairs, while ``"global"``
    reaches 0.99858 (``bench/bench_design_gradnet.py``).

    Parameters
    ----------
    freqs, links, starts, t_window, dt, coupling
        As in :func:`window_objective`.
    budget : Budget or float
        The feasible set; a number is ``Budget.of(total, L)`` (``x >= 0``, ``sum x = total``).
    steps : int, optional
        Adam steps (600, as GradNet's example).
    lr : float, optional
        Adam's step, in the units of ``x``. Default: ``2 * total / sum(cost)``, twice the
        uniform feasible weight.
    x0 : array_like, optional
        Starting weights (projected first). Default: ``budget.uniform()``.
    second_moment : {"global", "coordinate"}, optional
        One scalar second moment, or one per coordinate (textbook Adam); see above.
    betas, eps : optional
        Adam's constants (PyTorch's defaults). Derivatives here can be as small as 1e-7, so
        with ``"coordinate"`` ``eps`` is not negligible for every weight.

    Returns
    -------
    WindowDesign
        Final ``x``, the histories of ``J`` and of mean ``r`` (``steps + 1`` entries: before
        the first step and after each), wall time, the RK4 step count and step.
    """
    start_clock = time.perf_counter()
    omega, links, starts = _check_problem(freqs, links, starts)
    n_links = links.shape[0]
    if not isinstance(budget, Budget):
        budget = Budget.of(budget, n_links)
    if budget.cost.size != n_links:
        raise ConfigError(f"the budget has {budget.cost.size} variables for {n_links} links")
    steps = int(steps)
    if steps < 0:
        raise ConfigError(f"steps must be >= 0, got {steps}")
    if lr is None:
        lr = 2.0 * budget.total / float(budget.cost.sum())
    lr = float(lr)
    if not (np.isfinite(lr) and lr > 0):
        raise ConfigError(f"lr must be a positive number, got {lr!r}")
    if second_moment not in ("global", "coordinate"):
        raise ConfigError(f"second_moment must be 'global' or 'coordinate', got {second_moment!r}")
    per_coordinate = second_moment == "coordinate"
    beta1, beta2 = float(betas[0]), float(betas[1])
    n_steps, h = window_steps(t_window, dt)
    proj = project
    x = budget.uniform() if x0 is None else proj(np.asarray(x0, dtype=float), budget)
    kc = float(coupling)
    dense = _dense(omega, links)
    m = np.zeros(n_links)
    v = np.zeros(n_links) if per_coordinate else 0.0
    history = np.empty(steps + 1)
    for k in range(steps + 1):
        value, grad = _objective(omega, links, x, kc, starts, h, n_steps, k < steps, dense)
        history[k] = value
        if k == steps:
            break
        m = beta1 * m + (1.0 - beta1) * grad
        v = beta2 * v + (1.0 - beta2) * (grad * grad if per_coordinate else float(grad @ grad) / n_links)
        m_hat = m / (1.0 - beta1 ** (k + 1))
        v_hat = v / (1.0 - beta2 ** (k + 1))
        x = proj(x - lr * m_hat / (np.sqrt(v_hat) + eps), budget)
    wall = time.perf_counter() - start_clock
    return WindowDesign(x, history, 1.0 - history, wall, n_steps, h)
