"""Power grids read from files or configs: :class:`Grid` (capacities, injections, inertia,
damping, coupling and phase lag in node order) and the readers that build one
(docs/power_grids.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from antisync.errors import AntisyncError
from antisync.grids.errors import GridError
from antisync.physics import graphs
from antisync.plan.config import Config, load_config
from antisync.plan.model import node_frequencies, node_parameters, read_frequency_file

__all__ = ["Grid", "grid_from_config", "load_grid", "load_grid_config"]


@dataclass(frozen=True)
class Grid:
    """A power grid ready for :func:`line_indicators`: ``omega`` in :func:`antisync.physics.graphs.
    node_order` (bus ``i`` is row ``labels.index(i)``; for buses 1..N, row ``i - 1``), ``p``
    with its mean removed, ``inertia`` and ``damping`` (numbers or per-node arrays), the
    coupling and the phase lag ``alpha`` (``model.phase_lag``)."""

    name: str
    labels: list
    omega: np.ndarray
    p: np.ndarray
    inertia: object = 0.0
    damping: object = 1.0
    coupling: str = "raw"
    lag: float = 0.0
    law: object = None
    """A user's law (``model.law``): its :class:`~antisync.plan.model.LawSetup` on the
    coupling's CSR order (:func:`antisync.physics.coupling.to_csr` of ``omega``), whose nodes
    and links then hold the dynamics (``p``, ``inertia`` and ``damping`` are unused); None: the
    built-in swing equation. Only the line trip (:mod:`antisync.grids.trip`) runs a law."""


def _vector(path: Path, n: int, what: str) -> np.ndarray:
    """A per-node file read as a config's ``{file: PATH}`` is (one number per line, every
    number finite: a ``nan`` is refused naming its line)."""
    try:
        v = read_frequency_file(path, what)
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    if v.shape != (n,):
        raise GridError(f"{path}: expected {n} {what} (one per line, one line per node), got {v.size}")
    return v


def load_grid(
    edges,
    power,
    inertia=0.0,
    damping=1.0,
    *,
    scale: float = 1.0,
    coupling: str = "raw",
    name: str | None = None,
) -> Grid:
    """Read a grid from an edge list (``u v capacity``, :func:`antisync.physics.graphs.from_edgelist`)
    and a file of injections (one per node in node order); ``inertia``/``damping``: a number
    or a file like the injections. ``scale`` multiplies every capacity. The injections' mean
    is removed (the line losses of a case, docs/models.md)."""
    edges = Path(edges)
    try:
        g = graphs.from_edgelist(edges)
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    labels = graphs.node_order(g)
    omega = graphs.omega_matrix(g) * float(scale)
    n = len(labels)
    p = _vector(Path(power), n, "injections")
    per_node = []
    for what, v in (("inertia", inertia), ("damping", damping)):
        per_node.append(_vector(Path(v), n, what) if isinstance(v, str | Path) else v)
    return Grid(name or edges.stem, labels, omega, p - p.mean(), per_node[0], per_node[1], coupling)


def grid_from_config(config: Config, *, law: bool = False) -> Grid:
    """The :class:`Grid` of a validated config, read as ``antisync run`` reads it: its graph
    (any kind, ``graph.header``/``delimiter`` honoured; :func:`antisync.physics.graphs.build_graph`),
    ``model.frequencies`` (the injections, a list or ``{file: PATH}``; none: all 0), inertia,
    damping and ``phase_lag``, and ``dynamics.coupling``. With ``law`` (the line trip's caller) a
    config's ``model.law`` is read onto the grid (:attr:`Grid.law`).

    Raises
    ------
    GridError
        A graph or per-node value that cannot be read, frequencies drawn per realization (the
        static indicators need one operating point), or a law where ``law`` is False: one line.
    """
    model = config.model
    if model.law is not None:
        if not law:
            raise GridError(
                f"model.law {model.law['name']}: the static indicators need the built-in swing equation "
                "(its load flow and stability margin); a law runs antisync grid --removal and --trip, or "
                "write the grid with model: frequencies/inertia/damping"
            )
        return _law_grid(config)
    if model.drawn:
        raise GridError(
            f"model.frequencies {model.frequencies} are drawn per realization; the static indicators "
            "need the grid's injections: give model.frequencies as a list or {file: PATH} (or use --removal)"
        )
    try:
        g = graphs.build_graph(config.graph, seed=config.seed)
        labels = graphs.node_order(g)
        omega = graphs.omega_matrix(g)
        n = len(labels)
        p = node_frequencies(model, n)
        mass, gamma = node_parameters(model, n)
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    p = np.zeros(n) if p is None else np.asarray(p, dtype=np.float64)
    # one number stays one number (as the model kernels see it); per-node values as arrays
    inertia = model.inertia if isinstance(model.inertia, float) else mass
    damping = model.damping if isinstance(model.damping, float) else gamma
    return Grid(
        config.name, labels, omega, p - p.mean(), inertia, damping, config.dynamics.coupling, model.phase_lag
    )


def _law_grid(config: Config) -> Grid:
    """The grid of a config whose ``model.law`` holds its dynamics: the graph's capacities and
    the law's :class:`~antisync.plan.model.LawSetup` (its edge parameters read onto the links)."""
    from antisync.physics.coupling import to_csr
    from antisync.plan.model import law_edges, law_setup

    try:
        g = graphs.build_graph(config.graph, seed=config.seed)
        labels = graphs.node_order(g)
        omega = graphs.omega_matrix(g)
        csr = to_csr(omega)
        setup = law_setup(config, len(labels), law_edges(config.model, csr.indptr, csr.indices, labels, g))
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    if setup.drawn:
        names = ", ".join(config.model.user_law.params[k][0] for k, _ in setup.drawn)
        raise GridError(
            f"model.law {config.model.law['name']}: {names} drawn per realization; a line trip needs one "
            "operating point: give each parameter as a number, a list or {file: PATH}"
        )
    n = len(labels)
    return Grid(config.name, labels, omega, np.zeros(n), 0.0, 1.0, config.dynamics.coupling, 0.0, law=setup)


def load_grid_config(path, overrides: list[str] | None = None) -> Grid:
    """A :class:`Grid` from an antisync config such as ``configs/ieee14_grid.yaml``, read and
    validated by :func:`antisync.plan.config.load_config` exactly as ``antisync run`` reads it
    (``overrides``: ``key=value`` strings, the CLI's ``--set``), then :func:`grid_from_config`.

    Raises
    ------
    GridError
        The config's one-line error (an unknown key, a value out of range, a file that cannot
        be read), as ``antisync run`` words it.
    """
    try:
        config = load_config(path, list(overrides or []))
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    return grid_from_config(config)
