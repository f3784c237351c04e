"""What a dynamic line removal computes: its config (a grid, a YAML file, a mapping or a Config
resolved with overrides), ``beta``, the lines it changes, and the part of its config that
names the work rather than where it runs (:func:`work_config`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from antisync.errors import AntisyncError, ConfigError
from antisync.grids.errors import GridError
from antisync.grids.lines import pick_lines
from antisync.grids.load import Grid
from antisync.grids.removal_file import plain
from antisync.physics import graphs
from antisync.plan import sources
from antisync.plan.config import Config
from antisync.plan.jobs import check_step
from antisync.plan.model import node_frequencies, node_parameters

__all__ = [
    "WHERE_KEYS",
    "RemovalPlan",
    "check_beta",
    "plan_removal",
    "planned_lines",
    "resolve_config",
    "work_config",
]


def _grid_mapping(grid: Grid) -> dict:
    """A config mapping of a :class:`~antisync.grids.load.Grid` (its lines inline, injections,
    inertia and damping per node), with the dynamics of configs/ieee118_uniform.yaml (rk4, dt
    0.01, t_max 400, frequency locking to 1e-3), which overrides may change."""
    n = len(grid.labels)
    rows, cols = np.nonzero(np.triu(grid.omega > 0))
    links = [
        [grid.labels[i], grid.labels[j], float(grid.omega[i, j])] for i, j in zip(rows, cols, strict=True)
    ]

    def node_values(v):
        a = np.asarray(v, dtype=np.float64)
        return float(a) if a.ndim == 0 else [float(x) for x in np.broadcast_to(a, (n,))]

    inertia = node_values(grid.inertia)
    model = {"frequencies": [float(x) for x in grid.p], "inertia": inertia}
    if grid.lag:
        model["phase_lag"] = float(grid.lag)
    if isinstance(inertia, list) and not any(inertia):
        model["inertia"] = 0.0
    elif not (isinstance(inertia, float) and inertia == 0):
        model["damping"] = node_values(grid.damping)
    return {
        "name": grid.name,
        "graph": {"kind": "inline", "links": links, "nodes": list(grid.labels)},
        "model": model,
        "sync": {"criterion": "frequency", "tolerance": 1e-3},
        "dynamics": {"coupling": grid.coupling, "integrator": "rk4", "dt": 0.01, "t_max": 400.0},
    }


def resolve_config(source, overrides: Mapping):
    """The :class:`~antisync.plan.config.Config` of a grid (a :class:`~antisync.grids.load.Grid`,
    as :func:`antisync.grids.removal.line_removal` integrates it), a YAML path, a mapping or a
    Config, with ``overrides`` (config keys); a value that is not valid is a one-line GridError.
    A Config without overrides is already resolved and validated: it is returned as it is (a
    command resolves its config once)."""
    if isinstance(source, Config) and not overrides:
        return source
    if isinstance(source, Grid):
        source = _grid_mapping(source)
    try:
        return sources.resolve_config(source, dict(overrides), None)
    except ConfigError as exc:
        raise GridError(str(exc)) from None


#: Config keys that say where the work runs, not what it computes (a finished table is the
#: same run whatever they were).
WHERE_KEYS = ("threads", "executor", "backend")


def work_config(config) -> dict:
    """A removal run's config as plain JSON data without :data:`WHERE_KEYS`: what a journal's
    key and a finished table's check compare (the same run, wherever it runs)."""
    d = json.loads(json.dumps(plain(config if isinstance(config, dict) else {}), default=str))
    return {k: v for k, v in d.items() if k not in WHERE_KEYS}


@dataclass(frozen=True)
class RemovalPlan:
    """A removal's work, resolved once (:func:`plan_removal`): its config, the grid's node
    labels and ``Omega`` as built from it, ``beta``, and the lines it changes.

    Attributes
    ----------
    config : Config
    labels : list
        The grid's node labels, in the order of ``omega``'s rows.
    omega : ndarray, shape (N, N)
    beta : float
    islanding : bool
    todo : list of (int, int)
        0-based ``(a, b)`` of the lines changed, in table order.
    bridges : set of (int, int)
        The bridges among ``todo`` (``islanding``; empty at ``beta < 1``).
    skipped : list
        The bridges left out (every line asked for, ``beta = 1``, no ``islanding``).
    """

    config: Config
    labels: list
    omega: np.ndarray = field(repr=False)
    beta: float
    islanding: bool
    todo: list
    bridges: set
    skipped: list
    graph: object = field(default=None, repr=False, compare=False)
    """The grid as built (a law's edge parameters are read onto it)."""

    @property
    def asked(self) -> dict:
        """``{(u, v) as strings: islanding}`` of the lines changed (what a finished table's
        rows are compared with)."""
        labels = self.labels
        return {(str(labels[a]), str(labels[b])): (a, b) in self.bridges for a, b in self.todo}


def plan_removal(cfg: Config, lines, beta: float, islanding: bool) -> RemovalPlan:
    """The :class:`RemovalPlan` of a removal run of ``cfg``: its graph built once, the lines
    picked, and every refusal the work makes before it starts, one line each (a line not in the
    grid, a bridge, a per-node value that does not fit the graph, a config whose step the grid
    cannot take, no line left, ``sync.give_up`` with a law)."""
    law = cfg.model.law is not None
    if law and cfg.stop_rule("removal") is not None:
        raise GridError(
            f"sync.give_up stops the built-in Rodas4 early; law {cfg.model.law['name']}'s kernels have "
            "no such stop: remove give_up"
        )
    try:
        g = graphs.build_graph(cfg.graph, seed=cfg.seed)
        labels = graphs.node_order(g)
        omega = graphs.omega_matrix(g)
        node_frequencies(cfg.model, len(labels))
        node_parameters(cfg.model, len(labels))
        if not law:  # a law's step is checked on its own Jacobian (line_removal)
            check_step(omega, cfg)
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    todo, bridges, skipped = pick_lines(omega, labels, lines, beta, islanding)
    if not todo:
        raise GridError("no line to remove: every line asked for is a bridge")
    return RemovalPlan(cfg, labels, omega, float(beta), bool(islanding), todo, bridges, skipped, g)


def planned_lines(cfg, lines, beta: float, islanding: bool) -> dict:
    """The lines a removal run of ``cfg`` would change, ``{(u, v) as strings: islanding}``
    (:attr:`RemovalPlan.asked` of :func:`plan_removal`, with its refusals)."""
    return plan_removal(cfg, lines, beta, islanding).asked


def check_beta(beta) -> float:
    """``beta`` as a float in ``(0, 1]`` (1 removes the line), else a one-line GridError."""
    try:
        b = float(beta)
    except (TypeError, ValueError):
        raise GridError(f"beta must be a number in (0, 1] (1 removes the line), got {beta!r}") from None
    if not (0.0 < b <= 1.0):
        raise GridError(f"beta must be a number in (0, 1] (1 removes the line), got {beta!r}")
    return b
