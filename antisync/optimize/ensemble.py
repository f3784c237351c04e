"""The ensemble objective of a design: the synchronization time over random starts, its
gradient with respect to every designed weight, and paired evaluations of several designs.

A :class:`Problem` is a run config's network and model (the ``graph:``, ``dynamics:``,
``model:`` and ``sync:`` sections, as ``antisync run`` reads them) with one decision variable
``x_l`` per undirected link ``l = {a, b}``: ``Omega_ab = Omega_ba = x_l``. Candidate links
absent from the graph are variables like the others (absent at ``x_l = 0``). The coupling
``W(Omega)`` follows ``dynamics.coupling`` (Eq. 1, normalized, or Eq. 20, raw) on the fixed
pattern of every variable's two directions, so a link at weight 0 stays in the pattern and
keeps its derivative.

**What is estimated.** Start ``k`` of seed ``s`` draws the phases
:func:`antisync.physics.phases.phase` ``(s, k, node)`` as every run does. Its time is the
interpolated crossing ``tau = (steps - 1 + x) dt`` of the discrete integrator (Euler or RK4:
the quantity the adjoint differentiates, docs/equations.md A1-A5); a start that has not
synchronized by ``t_max`` counts as ``t_max`` with derivative 0 (a censored time: the design
objective is ``E[min(tau, t_max)]``, and the fraction censored is reported with it), a start
already synchronized at ``t = 0`` as 0. The gradient ``d tau / d x_l`` of every link comes
from one adjoint pass per start (:func:`antisync.kernels.adjoint.simulate_adjoint` for Eq. 2,
:func:`antisync.kernels.model_adjoint.simulate_model_adjoint` for the models, both reached
through the dispatch table's :func:`antisync.execution.dispatch.design_drivers`) with
``dW/dx_l`` in place of a damage direction: the derivative of the same discrete function of
the weights whose values are returned, so a central difference of :func:`sample`'s ``tau`` on
the same starts converges to it (tests/test_optimize.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import networkx as nx
import numpy as np

from antisync.errors import ConfigError
from antisync.execution.dispatch import design_drivers, law_params, model_params
from antisync.kernels.adjoint import LinkDerivatives
from antisync.optimize.budget import Budget
from antisync.physics import graphs
from antisync.physics.coupling import CouplingCSR, to_csr
from antisync.plan.config import Config
from antisync.plan.jobs import check_step, config_graph
from antisync.plan.model import STABLE_STEP, law_edges, law_setup, model_setup
from antisync.status import ALREADY_SYNCED, SYNCED

__all__ = ["Problem", "Sample", "check_designable", "evaluate", "make_problem", "sample"]


@dataclass(frozen=True)
class Problem:
    """A design problem: the network, its model, the decision variables and their budget."""

    config: Config
    """The run config whose network and model are designed (its ``edges``/``betas`` unused)."""
    nodes: list
    """Node labels in matrix order."""
    links: np.ndarray
    """int64 (L, 2): 0-based ``(a, b)``, ``a < b``, of every decision variable."""
    labels: tuple
    """``"u-v"`` per variable, in the graph's own node labels."""
    start: np.ndarray
    """float64 (L,): the graph's own weights (0 for a candidate link)."""
    budget: Budget
    candidate: np.ndarray
    """bool (L,): the variable is a candidate link, absent from the graph."""
    _pattern: CouplingCSR = field(init=False, repr=False, compare=False)
    _forward: np.ndarray = field(init=False, repr=False, compare=False)
    _backward: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        n = len(self.nodes)
        mask = np.zeros((n, n), dtype=bool)
        a, b = self.links[:, 0], self.links[:, 1]
        mask[a, b] = mask[b, a] = True
        pattern = to_csr(np.zeros((n, n)), pattern=mask)
        object.__setattr__(self, "_pattern", pattern)
        object.__setattr__(self, "_forward", np.array([pattern.position(i, j) for i, j in self.links]))
        object.__setattr__(self, "_backward", np.array([pattern.position(j, i) for i, j in self.links]))

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def coupling_kind(self) -> str:
        return self.config.dynamics.coupling

    def omega(self, x: np.ndarray) -> np.ndarray:
        """Dense symmetric ``Omega`` with ``Omega_ab = Omega_ba = x_l``."""
        n = self.n_nodes
        out = np.zeros((n, n))
        a, b = self.links[:, 0], self.links[:, 1]
        out[a, b] = x
        out[b, a] = x
        return out

    def coupling(self, x: np.ndarray) -> CouplingCSR:
        """``W(Omega(x))`` on the design's fixed pattern (a node whose every link is at 0 gets a
        zero row: it is cut off and never synchronizes)."""
        x = np.asarray(x, dtype=np.float64)
        raw = np.zeros(self._pattern.indices.size)
        raw[self._forward] = x
        raw[self._backward] = x
        if self.coupling_kind == "raw":
            return CouplingCSR(self._pattern.indptr, self._pattern.indices, raw)
        rows = np.repeat(np.arange(self.n_nodes), np.diff(self._pattern.indptr))
        strength = np.bincount(rows, weights=raw, minlength=self.n_nodes)
        safe = np.where(strength > 0, strength, 1.0)
        return CouplingCSR(self._pattern.indptr, self._pattern.indices, raw / safe[rows])

    def law_setup(self):
        """The config's law on the design's pattern (its edge parameters a number per link: a
        candidate link has no value in a file)."""
        p = self._pattern
        return law_setup(self.config, self.n_nodes, law_edges(self.config.model, p.indptr, p.indices))

    def check_step(self, x: np.ndarray, what: str) -> None:
        """Refuse weights ``x`` at which ``dynamics.dt`` makes the synchronized state unstable
        (the check ``antisync run`` makes of its graph: :func:`antisync.plan.jobs.check_step`, or
        with inertia :func:`antisync.plan.model.check_second_order_step`). A design moves the
        weights, so the step a run of the starting network allows can be too large for a
        designed one (a link given much of the budget): its times would be those of a repelling
        state, silently. ``what`` names the design in the one-line ConfigError."""
        config = self.config
        if config.dynamics.integrator not in STABLE_STEP:
            return
        try:
            if config.model.law is not None:
                from antisync.kernels.law import check_step as check_law_step

                law = self.law_setup()
                check_law_step(law, config.seed, self.coupling(x), config.dynamics)
                return
            check_step(self.omega(x), config)  # first or second order, as a run checks it
        except ConfigError as exc:
            raise ConfigError(
                f"{what}: {exc}; lower design.upper (or design.budget) or dynamics.dt so that every "
                "design the search may reach stays stable"
            ) from None

    def derivatives(self, x: np.ndarray) -> LinkDerivatives:
        """``dW/dx_l`` of every variable on the CSR pattern: rows ``a`` and ``b`` change.

        Raw coupling: ``dW_ab/dx_l = dW_ba/dx_l = 1``. Normalized (``W_ij = Omega_ij / S_i``):
        ``dW_aj/dx_l = ([j = b] - W_aj) / S_a`` on row ``a``, and the same on row ``b`` with
        ``a``; 0 on a row whose strength ``S`` is 0.
        """
        csr = self.coupling(x)
        indptr, indices, w = csr.indptr, csr.indices, csr.weights
        out_ptr = np.zeros(len(self.links) + 1, dtype=np.int64)
        position, value = [], []
        if self.coupling_kind == "raw":
            for l in range(len(self.links)):
                position.append([self._forward[l], self._backward[l]])
                value.append([1.0, 1.0])
                out_ptr[l + 1] = out_ptr[l] + 2
        else:
            x = np.asarray(x, dtype=np.float64)
            strength = np.zeros(self.n_nodes)
            np.add.at(strength, self.links[:, 0], x)
            np.add.at(strength, self.links[:, 1], x)
            for l, (a, b) in enumerate(self.links):
                for row, other in ((a, b), (b, a)):
                    lo, hi = indptr[row], indptr[row + 1]
                    if strength[row] > 0:
                        v = ((indices[lo:hi] == other) - w[lo:hi]) / strength[row]
                    else:
                        v = np.zeros(hi - lo)
                    position.append(np.arange(lo, hi))
                    value.append(v)
                out_ptr[l + 1] = out_ptr[l] + (indptr[a + 1] - indptr[a]) + (indptr[b + 1] - indptr[b])
        return LinkDerivatives(
            out_ptr,
            np.concatenate([np.asarray(p, dtype=np.int64) for p in position]),
            np.concatenate([np.asarray(v, dtype=np.float64) for v in value]),
        )

    def graph(self, x: np.ndarray, *, keep_zero: bool = False) -> nx.Graph:
        """The designed network as a weighted networkx graph in the original labels (links at
        weight 0 left out unless ``keep_zero``)."""
        g = nx.Graph()
        g.add_nodes_from(self.nodes)
        for (a, b), w in zip(self.links, np.asarray(x, dtype=float), strict=True):
            if w > 0 or keep_zero:
                g.add_edge(self.nodes[a], self.nodes[b], weight=float(w))
        return g


def check_designable(config: Config) -> None:
    """One clear :class:`ConfigError` for a config whose times a design cannot differentiate:
    the dispatch table's refusals (:data:`~antisync.execution.dispatch.DESIGN_REFUSALS`) and the
    config's stop rule (a design takes none)."""
    design_drivers(config)
    config.stop_rule("design")
    if config.model.per_link:
        name = next(k for k, v in config.model.edge_params.items() if isinstance(v, dict))
        raise ConfigError(
            f"model.edge_params.{name}: a design moves weights on links a file may not list (its "
            "candidates); give the edge parameter one number for every link"
        )


def make_problem(
    config: Config,
    budget: float | None = None,
    *,
    lower: float = 0.0,
    upper: float = np.inf,
    candidates: list | tuple = (),
    candidate_cost: float = 1.0,
    graph: nx.Graph | None = None,
) -> Problem:
    """A :class:`Problem` for ``config``'s network: one variable per link (cost 1) and per
    candidate link (``candidates``: ``"u-v"`` labels or node pairs, cost ``candidate_cost``).

    ``budget`` defaults to the graph's total link weight (what its own weights spend), so the
    graph itself is feasible when the bounds allow.
    """
    check_designable(config)
    if graph is None:
        graph = config_graph(config)
    nodes = graphs.node_order(graph)
    index = {v: i for i, v in enumerate(nodes)}
    links, labels, start = [], [], []
    for u, v, data in graph.edges(data=True):
        a, b = sorted((index[u], index[v]))
        links.append((a, b))
        labels.append(f"{nodes[a]}-{nodes[b]}")
        start.append(float(data.get("weight", 1.0)))
    existing = {tuple(p) for p in links}
    cost = [1.0] * len(links)
    named = {}
    for item in candidates:
        pair = _candidate_pair(item, index)
        if pair in named:
            raise ConfigError(
                f"design.candidates: {item!r} names the same link as {named[pair]!r}; give each "
                "candidate once"
            )
        named[pair] = item
        if pair in existing:
            raise ConfigError(
                f"design.candidates: {item!r} is already a link of the graph; candidates are "
                "links to add (every existing link is a design variable already)"
            )
        existing.add(pair)
        links.append(pair)
        labels.append(f"{nodes[pair[0]]}-{nodes[pair[1]]}")
        start.append(0.0)
        cost.append(float(candidate_cost))
    n_graph = graph.number_of_edges()
    total = float(np.sum(start)) if budget is None else budget
    spec = Budget.of(total, len(links), cost=np.array(cost), lo=lower, hi=upper)
    return Problem(
        config=config,
        nodes=nodes,
        links=np.array(links, dtype=np.int64).reshape(-1, 2),
        labels=tuple(labels),
        start=np.array(start),
        budget=spec,
        candidate=np.arange(len(links)) >= n_graph,
    )


def _candidate_pair(item, index: dict) -> tuple[int, int]:
    """``"u-v"`` or ``[u, v]`` as a sorted 0-based pair; one clear line when it names no pair."""
    if isinstance(item, str):
        parts = item.split("-")
        if len(parts) == 2:
            found = []
            for p in parts:
                p = p.strip()
                key = next((k for k in index if str(k) == p), None)
                found.append(key)
            if None not in found and found[0] != found[1]:
                return tuple(sorted((index[found[0]], index[found[1]])))
    elif isinstance(item, list | tuple) and len(item) == 2 and all(i in index for i in item):
        if item[0] != item[1]:
            return tuple(sorted((index[item[0]], index[item[1]])))
    raise ConfigError(
        f"design.candidates: {item!r} is not a pair of two different nodes of the graph "
        '(write "u-v" with node labels, e.g. "0-5")'
    )


class Sample(NamedTuple):
    """Per start: the (censored) time, its status and its gradient."""

    tau: np.ndarray
    """float64 (m,): ``min(tau, t_max)``; 0 for a start already synchronized."""
    status: np.ndarray
    """int8 (m,): :class:`~antisync.status.Status` codes."""
    grad: np.ndarray
    """float64 (m, L): ``d tau / d x_l`` (0 unless SYNCED)."""


def _times(config: Config, status, steps, frac) -> np.ndarray:
    dyn = config.dynamics
    tau = np.where(status == SYNCED, (steps - 1 + frac) * dyn.dt, dyn.t_max)
    return np.where(status == ALREADY_SYNCED, 0.0, tau)


def _model_params(problem: Problem, csr: CouplingCSR, ks: np.ndarray, kinds: int):
    config = problem.config
    if config.model.law is not None:
        return law_params(problem.law_setup(), config.dynamics, kinds)
    setup, _, _ = model_setup(config, csr.indptr, csr.indices, [csr.weights], [], 0)
    targets = np.full(kinds, setup.targets[0])
    return model_params(setup, config.model, config.seed, ks, problem.n_nodes, targets)


#: :func:`evaluate` checks the step of every design of a call with at most this many (the
#: baselines of a verification), else of the first (a secant's ``x``).
MAX_CHECKED = 16

#: A start's derivative along link ``l`` is replaced by a central secant where its relative size
#: ``|x_l (d tau / d x_l) / tau|`` exceeds this (``lambda.hybrid_cut``'s default, docs/estimators.md).
HYBRID_CUT = 2.0
#: The secants' relative step: ``h_l = SECANT_STEP x_l`` (``SECANT_STEP`` times the mean weight for
#: a link at 0, with a forward secant there).
SECANT_STEP = 0.01


def sample(
    problem: Problem,
    x: np.ndarray,
    seed: int,
    ks: np.ndarray,
    threads: int | None = None,
    *,
    cut: float | None = HYBRID_CUT,
) -> Sample:
    """Times and gradients of the starts ``ks`` of ``seed`` at the weights ``x``.

    Near a saddle passage a start's derivative is huge and of either sign (``P(|value| > v) ~
    1/v``: the mean of such values has no usable variance, and at the lambda2-optimal karate
    weights not one of 78 link means was resolved at 4,000 starts). As ``lambda.method:
    adjoint-hybrid`` does, each (start, link) pair whose relative derivative exceeds ``cut``
    takes the central secant of the same start's ``tau`` at ``x_l +- h_l`` instead: a bounded
    value with the same mean to ``O(h^2)``. ``cut=None``: the adjoint's values only (what the
    tests compare with central differences)."""
    config = problem.config
    ks = np.asarray(ks, dtype=np.uint64)
    problem.check_step(x, "a design's weights")
    csr = problem.coupling(x)
    params = _model_params(problem, csr, ks, 1) if config.generalized else None
    adjoint = design_drivers(config).adjoint
    res = adjoint(seed, csr.indptr, csr.indices, csr.weights, problem.derivatives(x), params, ks, threads)
    grad = np.where((res.status0 == SYNCED)[:, None], res.dtau, 0.0)
    tau = _times(config, res.status0, res.steps0, res.frac0)
    if cut is not None:
        _secants(problem, x, seed, ks, threads, tau, res.status0, grad, cut)
    return Sample(tau, res.status0, grad)


def _secants(problem, x, seed, ks, threads, tau, status, grad, cut) -> None:
    """Replace the outlying derivatives of ``grad`` in place by secants (see :func:`sample`)."""
    x = np.asarray(x, dtype=np.float64)
    mean = float(np.mean(x)) if np.mean(x) > 0 else 1.0
    h = np.where(x > 0, SECANT_STEP * x, SECANT_STEP * mean)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(h[None, :] / SECANT_STEP * grad) / tau[:, None]
    wild = (status == SYNCED)[:, None] & (rel > cut)
    if not wild.any():
        return
    rows = np.flatnonzero(wild.any(axis=1))
    n_links = x.size
    plus = np.repeat(x[None, :], n_links, axis=0) + np.diag(h)
    minus = np.repeat(x[None, :], n_links, axis=0) - np.diag(np.where(x > 0, h, 0.0))
    designs = [x, *plus, *minus]
    todo = np.zeros((rows.size, 1 + 2 * n_links), dtype=bool)
    todo[:, 1 : 1 + n_links] = wild[rows]
    todo[:, 1 + n_links :] = wild[rows]
    times, _ = evaluate(problem, designs, seed, ks[rows], threads, todo=todo)
    up, down = times[1 : 1 + n_links].T, times[1 + n_links :].T
    down = np.where(x[None, :] > 0, down, tau[rows][:, None])
    width = np.where(x > 0, 2 * h, h)[None, :]
    sub = grad[rows]
    sub[wild[rows]] = ((up - down) / width)[wild[rows]]
    grad[rows] = sub


def evaluate(
    problem: Problem,
    designs: list,
    seed: int,
    ks: np.ndarray,
    threads: int | None = None,
    todo: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Times ``(D, m)`` and statuses ``(D, m)`` of every design on the same starts (paired):
    one forward integration per design and start, the designs as variants of one batch
    (``todo``, bool ``(m, D)``: only the marked ones; the others' times are NaN)."""
    config = problem.config
    ks = np.asarray(ks, dtype=np.uint64)
    # every design compared; of a secant's designs (x +- h_l per link) the first, x: the others
    # are within SECANT_STEP of it
    for k, x in enumerate(designs if len(designs) <= MAX_CHECKED else designs[:1]):
        problem.check_step(x, f"design {k + 1} of {len(designs)}")
    weights = np.stack([problem.coupling(x).weights for x in designs])
    pattern = problem.coupling(designs[0])
    params = _model_params(problem, pattern, ks, len(designs)) if config.generalized else None
    forward = design_drivers(config).forward
    res = forward(seed, pattern.indptr, pattern.indices, weights[0], weights[1:], params, ks, threads, todo)
    status = np.vstack([res.status0[None, :], res.status.T])
    steps = np.vstack([res.steps0[None, :], res.steps.T])
    frac = np.vstack([res.frac0[None, :], res.frac.T])
    times = _times(config, status, steps, frac)
    if todo is not None:
        times[~todo.T] = np.nan
    return times, status
