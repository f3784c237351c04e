"""Config -> jobs -> chunks.

A :class:`Job` is one graph with its damaged edges and beta grid, converted once into the flat
arrays that every backend consumes (STYLE habit 2). Its *variants* are the damages actually
integrated: every requested ``beta`` and the finite-difference ``dbeta`` for each edge.
A :class:`Chunk` is a contiguous range of statistics blocks, the unit of work of executors.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import networkx as nx
import numpy as np

from antisync.errors import ConfigError
from antisync.physics import coupling, graphs
from antisync.physics.locked import linearization
from antisync.plan.config import Config, graph_name
from antisync.plan.model import (
    DTARGET_STEP,
    STABLE_STEP,
    LawSetup,
    ModelSetup,
    check_second_order_step,
    law_on_network,
    model_setup,
    node_parameters,
    with_law_dtarget,
)
from antisync.types import LAMBDA_ROWS

__all__ = ["Chunk", "Job", "make_job", "stiffness_note"]

ADJOINT_MIN_CHUNK = 512
"""Fewest realizations per chunk for ``lambda.method: adjoint`` (and ``adjoint-hybrid``): enough
16-lane groups that grouping by predicted crossing time leaves few lanes idle."""


@dataclass(frozen=True)
class Chunk:
    """Blocks ``first_block .. first_block + n_blocks - 1`` of a job."""

    first_block: int
    n_blocks: int

    def realizations(self, block: int, total: int) -> tuple[int, int]:
        """``(first, count)`` of the realizations this chunk covers."""
        first = self.first_block * block
        return first, min(self.n_blocks * block, total - first)


@dataclass(frozen=True)
class Job:
    """One graph's experiment, ready for a kernel.

    Attributes
    ----------
    name : str
        Graph name (``G105``, ``lollipop_6_3``, ...) and HDF5 group name.
    nodes : list
        Node labels in matrix order.
    omega : ndarray (N, N)
        Undamaged weights.
    edges : list of (label, label)
        Damaged directed edges, ``edge_labels[i] == "a->b"``.
    betas : tuple of float
        Requested damages (may be empty: Lambda only).
    variant_edge, variant_beta : ndarrays (V,)
        Edge index and damage of each integrated variant.
    csr : CouplingCSR
        ``W(Omega)``; ``variant_weights[v]`` is ``W(Omega*)`` of variant ``v`` on its pattern.
    tangent : tuple of arrays
        ``(edge_a, edge_b, rho, mu)`` per edge for the pathwise kernel.
    secant_weights : ndarray (2 E, nnz)
        ``W(Omega*)`` of each edge at ``beta = +dbeta`` (row ``e``) and ``-dbeta`` (row
        ``E + e``): the hybrids' central secants.
    orbit_weights : ndarray (2 E, nnz) or None
        ``lambda.method: orbit``: each edge's automorphism orbit damaged by ``+dbeta`` (row
        ``2 e``) and ``-dbeta`` (row ``2 e + 1``), see
        :func:`~antisync.physics.coupling.orbit_variant_weights`;
        ``central-difference``: the same with every edge its own orbit.
    orbit_sizes : ndarray (E,) or None
        Number of directed links in each edge's orbit.
    model : ModelSetup or None
        The ``model:`` and ``sync:`` sections resolved for the kernels (docs/models.md);
        ``None`` for the paper's model, which runs on the default kernels, and for a law.
    law : LawSetup or None
        A user's law (``model.law``) with its parameters per node; None otherwise.
    nnc_of : str
        For the raw-coupling twin of a run (``km_nnc``, Sec. 3.4), the name of the normalized
        job it pairs with; ``""`` otherwise.
    """

    config: Config
    name: str
    graph: nx.Graph
    nodes: list
    omega: np.ndarray
    edges: list
    edge_labels: list
    betas: tuple
    dbeta: float
    variant_edge: np.ndarray
    variant_beta: np.ndarray
    csr: coupling.CouplingCSR
    variant_weights: np.ndarray
    tangent: tuple
    secant_weights: np.ndarray
    nnc_of: str = ""
    orbit_weights: np.ndarray | None = None
    orbit_sizes: np.ndarray | None = None
    model: ModelSetup | None = None
    law: LawSetup | None = None

    @property
    def kuramoto(self) -> bool:
        """Whether the job integrates the Kuramoto model (``km`` in ``measures``). Without it
        the job has no blocks, no chunks and no variants: only the exact measures are
        computed."""
        return "km" in self.config.measures

    @property
    def realizations(self) -> int:
        """Realizations integrated: ``config.realizations``, or 0 without ``km``."""
        return self.config.realizations if self.kuramoto else 0

    @property
    def block_size(self) -> int:
        return self.config.resolved_block_size

    @property
    def n_blocks(self) -> int:
        return -(-self.realizations // self.block_size)

    def variant(self, edge_index: int, beta: float) -> int:
        """Index of the variant damaging ``edges[edge_index]`` by ``beta``."""
        hit = np.flatnonzero((self.variant_edge == edge_index) & np.isclose(self.variant_beta, beta))
        if hit.size == 0:
            raise KeyError((edge_index, beta))
        return int(hit[0])

    @property
    def hist_variants(self) -> np.ndarray:
        """Variants whose (tau0, tau(beta)) histogram is kept: requested betas in histogram.betas."""
        wanted = set(np.round(self.betas, 12)) & set(np.round(self.config.histogram.betas, 12))
        keep = np.isin(np.round(self.variant_beta, 12), np.array(sorted(wanted)))
        return np.flatnonzero(keep)

    @property
    def integrations_per_realization(self) -> int:
        """Trajectories integrated per realization (tau0, variants, orbit differences)."""
        extra = 0 if self.orbit_weights is None else len(self.orbit_weights)
        return 1 + len(self.variant_edge) + extra

    @property
    def work_per_realization(self) -> float:
        """A realization's cost in integrations of the paper's lollipop (12 directed edges):
        the integrations, a derivative pass (pathwise: one tangent per link; adjoint: forward,
        recomputed and backward sweeps, ~4 trajectories), scaled by the graph's directed edges.
        Sizes chunks only (so a checkpoint comes every few seconds on any graph)."""
        kind = LAMBDA_ROWS[self.config.lambda_.method].passes if self.kuramoto else None
        passes = {"tangents": 1 + len(self.edges), "backward": 4}.get(kind, 0)
        size = max(1.0, len(self.csr.indices) / 12)
        return (self.integrations_per_realization + passes) * size

    def chunks(self, realizations_per_chunk: int | None = None) -> list[Chunk]:
        """Split the job into chunks of whole blocks (sizes never change the results)."""
        if realizations_per_chunk is None:
            # aim at ~25k lollipop integrations per chunk: a few seconds on one core
            realizations_per_chunk = max(1, int(25_000 // self.work_per_realization))
            if self.kuramoto and LAMBDA_ROWS[self.config.lambda_.method].passes == "backward":
                # the adjoint's 16-lane groups run to their slowest lane: sorted by predicted
                # crossing, fewer than ~32 groups waste lanes (Les Miserables: ~118 per chunk
                # took 13% more CPU than 1024)
                realizations_per_chunk = max(realizations_per_chunk, ADJOINT_MIN_CHUNK)
        per = max(1, -(-realizations_per_chunk // self.block_size))
        return [Chunk(b, min(per, self.n_blocks - b)) for b in range(0, self.n_blocks, per)]


def config_graph(config: Config) -> nx.Graph:
    """The graph of ``config.graph`` (seeded by ``config.seed``); any failure to build it is one
    :class:`~antisync.physics.graphs.GraphError` naming the spec."""
    try:
        return graphs.build_graph(config.graph, seed=config.seed)
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, graphs.GraphError):
            raise
        raise graphs.GraphError(f"graph {config.graph}: {exc}") from None


def make_job(
    config: Config, graph: nx.Graph | None = None, name: str | None = None, command: str = "run"
) -> Job:
    """Build the graph, resolve edges and betas, and compute all coupling arrays (for
    ``command``, ``"run"`` or ``"sweep"``: the config's stop rule is ruled on for it)."""
    config.stop_rule(command)
    if graph is None:
        graph = config_graph(config)
    nodes = graphs.node_order(graph)
    index = {v: i for i, v in enumerate(nodes)}
    omega = graphs.omega_matrix(graph)
    kuramoto = "km" in config.measures
    if kuramoto and config.model.law is None:  # without km nothing is integrated: dt does not matter
        check_step(omega, config)  # a law's step is checked on its own Jacobian (execution.dispatch)
    if config.edges == "all":
        edges = graphs.all_directed_edges(graph)
    else:
        edges = []
        for text in config.edges:
            e = graphs.parse_edge(text, graph)
            if e in edges:
                raise ConfigError(f"edge {text!r} is listed twice")
            edges.append(e)
    dbeta = config.lambda_.dbeta
    needs = LAMBDA_ROWS[config.lambda_.method]
    grid = sorted(set(config.betas) | ({dbeta} if needs.dbeta_variant else set())) if kuramoto else []
    variant_edge = np.repeat(np.arange(len(edges)), len(grid))
    variant_beta = np.tile(np.array(grid, dtype=np.float64), len(edges))
    csr = coupling.coupling_csr(omega, config.dynamics.coupling)
    damages = [
        (index[edges[e][0]], index[edges[e][1]], float(b))
        for e, b in zip(variant_edge, variant_beta, strict=True)
    ]
    vw = coupling.variant_weights(omega, csr, damages, config.dynamics.coupling)
    edge_idx = [(index[a], index[b]) for a, b in edges]
    # the hybrids' central secants: every edge at +dbeta (rows 0..E-1), then at -dbeta
    secant = coupling.variant_weights(
        omega,
        csr,
        [(a, b, float(h)) for h in (dbeta, -dbeta) for a, b in edge_idx] if kuramoto else [],
        config.dynamics.coupling,
    )
    orbit = _orbit_fields(graph, nodes, omega, csr, edges, config)
    model = law = None
    if config.model.law is not None:
        labels = [
            f"variant {graphs.edge_label(*edges[e])} beta {b:g}"
            for e, b in zip(variant_edge, variant_beta, strict=True)
        ]
        law = law_on_network(config, nodes, graph, csr, vw, labels)
        rows = _dtarget_rows(config, omega, csr, edge_idx)
        if rows is not None:
            h = DTARGET_STEP
            names = [f"{graphs.edge_label(*e)} beta {x:g}" for e in edges for x in (h, -h)]
            law = with_law_dtarget(law, csr.indptr, csr.indices, rows, names, h)
    elif config.generalized:
        model = _model_fields(
            config, edges, edge_idx, variant_edge, variant_beta, omega, csr, vw, secant, orbit
        )
    return Job(
        config=config.resolved(),
        name=name or graph.graph.get("name") or _job_name(config),
        graph=graph,
        nodes=nodes,
        omega=omega,
        edges=edges,
        edge_labels=[graphs.edge_label(a, b) for a, b in edges],
        betas=tuple(float(b) for b in config.betas) if kuramoto else (),
        dbeta=float(dbeta),
        variant_edge=variant_edge,
        variant_beta=variant_beta,
        csr=csr,
        variant_weights=vw,
        tangent=coupling.tangent_coefficients(omega, edge_idx, config.dynamics.coupling),
        secant_weights=secant,
        model=model,
        law=law,
        **orbit,
    )


def _dtarget_rows(config: Config, omega, csr, edge_idx) -> np.ndarray | None:
    """The weights of every link at ``+DTARGET_STEP`` then ``-DTARGET_STEP`` of damage (rows
    ``2 e``, ``2 e + 1``): the networks whose targets give the adjoint's ``d target / d beta_e``
    with the relative criterion (``r*`` moves with the damage); None where the run needs none."""
    if LAMBDA_ROWS[config.lambda_.method].passes != "backward" or config.sync.criterion != "relative":
        return None
    h = DTARGET_STEP
    damages = [(a, b, x) for a, b in edge_idx for x in (h, -h)]
    return coupling.variant_weights(omega, csr, damages, config.dynamics.coupling)


def _model_fields(
    config, edges, edge_idx, variant_edge, variant_beta, omega, csr, vw, secant, orbit
) -> ModelSetup:
    """The job's :class:`~antisync.plan.model.ModelSetup`, with the targets of the damaged networks
    its estimator integrates besides the variants: central differences' rows (``orbit``,
    ``central-difference``), the hybrids' secants, and for the adjoint with the relative
    criterion ``d target / d beta_e`` (a central difference of the target at ``+-DTARGET_STEP``)."""
    needs = LAMBDA_ROWS[config.lambda_.method]
    labels = [
        f"{graphs.edge_label(*edges[e])} beta {b:g}" for e, b in zip(variant_edge, variant_beta, strict=True)
    ]
    blocks = {}
    ow = orbit.get("orbit_weights")
    if ow is not None:
        blocks["orbits"] = (list(ow), [(e // 2, (-1) ** e * config.lambda_.dbeta) for e in range(len(ow))])
    if needs.secants:
        blocks["secant"] = (
            list(secant),
            [
                (e % len(edges), (1 - 2 * (e // len(edges))) * config.lambda_.dbeta)
                for e in range(len(secant))
            ],
        )
    rows = _dtarget_rows(config, omega, csr, edge_idx)
    if rows is not None:
        blocks["dtarget"] = (list(rows), [(e // 2, (-1) ** e * DTARGET_STEP) for e in range(len(rows))])
    extra = []
    for rows, names in blocks.values():
        extra += rows
        labels += [f"{graphs.edge_label(*edges[e])} beta {b:g}" for e, b in names]
    setup, targets, r_star = model_setup(
        config, csr.indptr, csr.indices, [csr.weights, *vw, *extra], labels, len(extra)
    )
    fields = {}
    at = 0
    for name, (rows, _) in blocks.items():
        part = slice(at, at + len(rows))
        at += len(rows)
        if name == "orbits":
            fields["orbit_targets"] = targets[part]
            fields["orbit_r_star"] = None if r_star is None else r_star[part]
        elif name == "secant":
            fields["secant_targets"] = targets[part]
        else:
            fields["dtarget"] = (targets[part][0::2] - targets[part][1::2]) / (2 * DTARGET_STEP)
    return replace(setup, **fields)


def _job_name(config: Config) -> str:
    """A run's job name: its graph's (``lollipop_6_3``, ``G105``, an edge list's file name);
    for a graph given inline (a graph object passed to :func:`antisync.run`), the config's
    ``name``."""
    if config.graph.get("kind") == "inline":
        return config.name
    return graph_name(config.graph)


def check_step(omega: np.ndarray, config: Config) -> None:
    """Refuse a ``dynamics.dt`` at which the synchronized state is unstable for the integrator.

    Near synchrony the model is the linear system ``theta' = -L theta`` (Eq. 9) with ``L`` the
    coupling's Laplacian; a step ``dt`` with ``dt * xi_max`` beyond the integrator's stability
    interval makes that state repel, so no realization would ever synchronize (every one would
    end NOT_SYNCED with no hint why). Raw coupling with huge weights fails here too. With
    inertia on some node the modes solve ``m lambda^2 + gamma lambda + xi = 0`` instead, and the
    check is :func:`antisync.plan.model.check_second_order_step` (picked here: a run, a removal,
    a sweep and a design check a network's step through this one function).
    """
    dyn = config.dynamics
    sym, _ = coupling.symmetrized_laplacian(omega, dyn.coupling)
    if not np.isfinite(sym).all():
        raise ConfigError("the graph's weights overflow the coupling matrix; rescale them")
    if dyn.integrator not in STABLE_STEP:
        return  # rodas4: L-stable, any step
    if config.model.law is None:
        mass, gamma = node_parameters(config.model, omega.shape[0])
        if (mass > 0).any():
            # with inertia the modes are m lambda^2 + gamma lambda + xi = 0, not -xi: the bound
            # below would refuse a stiff grid's stable step (|lambda| ~ sqrt(xi / m) << xi)
            csr = coupling.coupling_csr(omega, dyn.coupling)
            check_second_order_step(config, csr.indptr, csr.indices, csr.weights, mass, gamma)
            return
    xi_max = float(np.linalg.eigvalsh(sym)[-1])
    limit = STABLE_STEP[dyn.integrator] / xi_max
    if dyn.dt >= limit:
        raise ConfigError(
            f"dynamics.dt = {dyn.dt:g} is too large for this graph: {dyn.integrator} steps make the "
            f"synchronized state unstable unless dt < {limit:.3g} ({STABLE_STEP[dyn.integrator]:g} / "
            f"xi_max, xi_max = {xi_max:.4g} the largest Laplacian eigenvalue); the paper uses 0.001"
        )


#: the stiffness ratio (fastest over slowest decay rate near synchrony) from which a
#: stability-bound explicit step is worth a note, and the largest network the note is computed
#: for (a dense eigenvalue problem of the linearization)
STIFF_RATIO = 1e4
STIFF_NOTE_MAX_NODES = 1500


def stiffness_note(job: Job) -> str | None:
    """A one-line note when ``job``'s explicit step is bound by stability rather than by its
    dynamics: a generalized model (docs/models.md) whose linearization at the in-phase state has
    decay rates spanning more than :data:`STIFF_RATIO`, at a ``dynamics.dt`` within a tenth of
    the explicit step's stability limit; None otherwise (or for more than
    :data:`STIFF_NOTE_MAX_NODES` nodes). ``antisync validate`` and ``antisync run`` print it."""
    dyn = job.config.dynamics
    if job.model is None or not job.kuramoto or dyn.integrator not in STABLE_STEP:
        return None
    n = len(job.nodes)
    if n > STIFF_NOTE_MAX_NODES:
        return None
    rows = np.repeat(np.arange(n), np.diff(job.csr.indptr))
    w = np.zeros((n, n))
    w[rows, job.csr.indices] = job.csr.weights
    lap = np.diag(w.sum(axis=1)) - w
    rates = -np.linalg.eigvals(linearization(-lap, job.model.inertia, job.model.damping)).real
    scale = float(np.abs(rates).max()) if rates.size else 0.0
    rates = rates[rates > 1e-9 * scale]  # the rotation's zero mode neither grows nor decays
    if rates.size < 2:
        return None
    fast, slow = float(rates.max()), float(rates.min())
    limit = STABLE_STEP[dyn.integrator] / fast
    if fast / slow < STIFF_RATIO or dyn.dt < 0.1 * limit:
        return None
    return (
        f"dynamics.dt {dyn.dt:g} is bound by stability, not by the dynamics: near synchrony the "
        f"fastest mode decays at {fast:.4g}/s (an explicit {dyn.integrator} step needs dt < "
        f"{limit:.3g}), the slowest at {slow:.3g}/s; integrator rodas4 takes steps the dynamics "
        f"allow (docs/models.md, stiff networks)"
    )


@functools.lru_cache(maxsize=64)
def _all_orbits(nodes: tuple, omega_rows: tuple) -> dict:
    """:func:`~antisync.physics.graphs.edge_orbits` of the weighted graph, cached: the repeats and
    thresholds of a sweep build the same graph many times (1 s for a 20-node lollipop)."""
    g = nx.Graph()
    g.add_nodes_from(nodes)
    for i, row in enumerate(omega_rows):
        for j, w in enumerate(row):
            if j > i and w > 0:
                g.add_edge(nodes[i], nodes[j], weight=w)
    return graphs.edge_orbits(g)


def _orbit_fields(
    graph: nx.Graph, nodes: list, omega: np.ndarray, csr: coupling.CouplingCSR, edges: list, config: Config
) -> dict:
    """``orbit_weights`` and ``orbit_sizes`` for ``lambda.method: orbit`` and, with every link
    its own orbit, ``central-difference`` (else empty)."""
    orbit = LAMBDA_ROWS[config.lambda_.method].orbit
    if orbit is None or "km" not in config.measures:
        return {}
    index = {v: i for i, v in enumerate(nodes)}
    if orbit == "edge":
        orbits = [[(index[a], index[b])] for a, b in edges]
    else:
        rep = _all_orbits(tuple(nodes), tuple(map(tuple, omega)))
        orbits = [[(index[a], index[b]) for a, b in rep if rep[a, b] == rep[e]] for e in edges]
    weights = coupling.orbit_variant_weights(
        omega, csr, orbits, config.lambda_.dbeta, config.dynamics.coupling
    )
    return {"orbit_weights": weights, "orbit_sizes": np.array([len(o) for o in orbits])}
