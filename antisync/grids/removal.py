"""Dynamic line removal (dynamic N-1) of a power grid: does the grid still synchronize, and
how fast, when one line is removed or weakened (docs/power_grids.md)?

For every line ``i-j`` both directions are weakened, ``Omega_ij, Omega_ji -> (1 - beta)
Omega_ij`` (``beta = 1`` removes the line), and the damaged grid is integrated from the **same**
initial conditions as the intact one: realization ``k`` starts from the counter-based phases
``theta_i(0) = 2 pi u(seed, k, i)`` of :mod:`antisync.physics.phases` (``theta_i'(0) = 0``), whatever
line, chunk or thread. The integration is the compiled model driver
:func:`antisync.kernels.cpu.simulate_model` (the intact grid as the base network, one
variant per line on the same CSR pattern, a removed line's weights 0), so an intact run's
``tau0`` is the ordinary ``antisync run``'s ``tau0`` of the same seed, realization by
realization (tested).

Per line (:class:`LineRemoval`), from the paired outcomes of ``M`` realizations:

- ``P_sync`` before and after (synchronized: the criterion of ``sync:`` met by ``t_max``),
  each with its exact Clopper-Pearson interval; the basin-stability change (Menck et al.,
  Nat. Phys. 9, 89 (2013)) is ``d_psync = P_after - P_before``;
- ``lost`` (synchronized intact, not after) and ``gained`` (the reverse), with Clopper-Pearson
  intervals of ``lost / M`` and ``gained / M``; ``d_psync = (gained - lost) / M``. The paired
  test is McNemar's exact one: conditional on the ``d = lost + gained`` discordant pairs,
  ``gained ~ Binomial(d, q)`` with ``q = 1/2`` under no change (``p_value``, two-sided), and
  the interval of ``d_psync`` is ``(d / M)(2 q - 1)`` at the ends of ``q``'s Clopper-Pearson
  interval (conditional on ``d``; ``[0, 0]`` when no pair is discordant: then ``lost_ci`` and
  ``gained_ci`` bound the change);
- on the pairs that synchronize both times (status SYNCED both), the mean of ``d_tau = tau -
  tau0`` with its standard error, and the mean ratio ``tau0 / tau`` (the paper's ``F``) with its
  standard error.

Rankings (:class:`RemovalTable`): **troublemaker lines** (removal costs the most synchrony:
largest ``lost - gained``) and **dynamic Braess lines** (removal or weakening raises ``P_sync``
or speeds synchronization, ``d_tau < 0``). A change is *resolved* when the Benjamini-Hochberg
procedure at false discovery rate 0.05 over the table's lines calls it (McNemar's exact
p-values for ``P_sync``, normal ones of ``d_tau / se`` for tau; :mod:`antisync.stats.multiplicity`,
as the sign calls of ``antisync summary``): a per-line 5% test would call about one line in
twenty of an unaffected grid.

A bridge (a line whose removal islands the grid) at ``beta = 1`` is refused with a one-line
:class:`~antisync.grids.grid.GridError`; ``islanding=True`` integrates it anyway and marks the row
``islanding`` (the islands cannot share one frequency unless each is balanced, so with the
frequency criterion such a row normally loses every realization).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import tempfile
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from antisync.grids.grid import Grid, GridError, Rows
from antisync.plan import sources
from antisync.stats.multiplicity import FDR_LEVEL, benjamini_hochberg
from antisync.status import ALREADY_SYNCED, SYNCED
from antisync.store.outputs import check_output_path, config_inputs, json_format_problem

__all__ = [
    "FORMAT",
    "LineRemoval",
    "RemovalTable",
    "RemovalJournal",
    "journal_folder",
    "remove_journal",
    "clopper_pearson",
    "line_removal",
    "mcnemar_exact",
    "tau_p_value",
    "parse_lines",
    "resolve_config",
    "table_document",
    "replace_atomically",
    "check_beta",
    "planned_lines",
    "WHERE_KEYS",
    "work_config",
    "check_output",
    "check_new_file",
    "write_table",
]

#: The ``format`` of a JSON file written by :func:`write_table`.
FORMAT = "antisync-line-removal"
FORMAT_VERSION = 1
#: Realizations integrated per call of the compiled driver (progress and memory).
CHUNK = 256
#: Tasks per Dask worker thread that :func:`line_removal` aims for (lines are grouped so that a
#: few realizations x many lines still spread over the cluster).
TASKS_PER_WORKER = 4


# --- exact intervals -------------------------------------------------------------------------


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a binomial proportion ``k / n`` at ``level``:
    the ``(1 - level)/2`` and ``(1 + level)/2`` quantiles of ``Beta(k, n - k + 1)`` and
    ``Beta(k + 1, n - k)`` (0 for ``k = 0``, 1 for ``k = n``). ``(nan, nan)`` for ``n = 0``."""
    from scipy.stats import beta

    if n == 0:
        return math.nan, math.nan
    if not 0 <= k <= n:
        raise ValueError(f"k must lie in [0, n], got k={k}, n={n}")
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def mcnemar_exact(lost: int, gained: int, n: int, level: float = 0.95) -> tuple[float, float, float]:
    """McNemar's exact test of a paired change of ``P_sync`` and its conditional interval.

    Conditional on the ``d = lost + gained`` discordant pairs, ``gained ~ Binomial(d, q)``; no
    change is ``q = 1/2``. Returns ``(p_value, low, high)``: the two-sided exact p-value
    (``scipy.stats.binomtest``; 1 when ``d = 0``) and the interval ``(d / n)(2 q - 1)`` of the
    change ``(gained - lost) / n`` at the ends of ``q``'s Clopper-Pearson interval."""
    from scipy.stats import binomtest

    d = lost + gained
    if d == 0:
        return 1.0, 0.0, 0.0
    p = float(binomtest(gained, d, 0.5).pvalue)
    q_lo, q_hi = clopper_pearson(gained, d, level)
    return p, d / n * (2 * q_lo - 1), d / n * (2 * q_hi - 1)


def tau_p_value(d_tau: float | None, se: float | None) -> float:
    """Two-sided p-value of "``d_tau = 0``" (normal, from ``d_tau`` and its standard error; 1
    where there is no error)."""
    if d_tau is None or se is None or not (math.isfinite(se) and se > 0 and math.isfinite(d_tau)):
        return 1.0
    return math.erfc(abs(d_tau) / se / math.sqrt(2.0))


def _mean_se(x: np.ndarray) -> tuple[float, float]:
    if x.size == 0:
        return math.nan, math.nan
    se = float(x.std(ddof=1) / math.sqrt(x.size)) if x.size > 1 else math.nan
    return float(x.mean()), se


# --- results ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class LineRemoval:
    """One line's paired response to its removal (or weakening by ``beta``), module docstring.

    ``line``: the end nodes' labels; ``n``: realizations; ``synced_before`` / ``synced_after``:
    counts (SYNCED or ALREADY_SYNCED) with ``p_before`` / ``p_after`` and their Clopper-Pearson
    intervals; ``lost`` / ``gained`` with the intervals of ``lost / n`` and ``gained / n``;
    ``d_psync`` (the basin-stability change), McNemar's exact ``p_value`` and conditional
    interval ``d_psync_ci``; ``both``: pairs SYNCED both times, ``d_tau`` / ``d_tau_se`` and
    ``ratio`` / ``ratio_se`` (``tau0 / tau``) over them; ``islanding``: the line is a bridge
    removed anyway (``islanding=True``).
    """

    line: tuple
    nodes: tuple[int, int]
    beta: float
    n: int
    synced_before: int
    synced_after: int
    p_before: float
    p_before_ci: tuple[float, float]
    p_after: float
    p_after_ci: tuple[float, float]
    lost: int
    lost_ci: tuple[float, float]
    gained: int
    gained_ci: tuple[float, float]
    d_psync: float
    d_psync_ci: tuple[float, float]
    p_value: float
    both: int
    d_tau: float
    d_tau_se: float
    ratio: float
    ratio_se: float
    islanding: bool = False

    @property
    def label(self) -> str:
        return f"{self.line[0]}-{self.line[1]}"

    @property
    def net_lost(self) -> int:
        """``lost - gained``: realizations that no longer synchronize, net."""
        return self.lost - self.gained

    @property
    def tau_p_value(self) -> float:
        return tau_p_value(self.d_tau, self.d_tau_se)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["label"] = self.label
        d["line"] = list(self.line)
        return d


@dataclass(frozen=True)
class RemovalTable(Rows):
    """The rows of :func:`line_removal` (one :class:`LineRemoval` per line) and the intact
    grid's outcome, with the rankings of troublemaker and dynamic Braess lines.

    ``status0`` / ``tau0``: the intact grid's per-realization status and ``tau0`` (``nan``
    unless SYNCED); ``status`` / ``tau``: ``(M, L)``, the same after each line's change.
    """

    name: str
    beta: float
    seed: int
    rows: tuple[LineRemoval, ...]
    status0: np.ndarray
    tau0: np.ndarray
    status: np.ndarray
    tau: np.ndarray
    seconds: float = 0.0
    skipped: tuple = field(default=())
    config: dict = field(default_factory=dict)
    level: float = 0.95

    @property
    def n(self) -> int:
        return int(self.status0.size)

    @property
    def synced0(self) -> int:
        return int(np.isin(self.status0, (SYNCED, ALREADY_SYNCED)).sum())

    @property
    def p_sync(self) -> float:
        """The intact grid's ``P_sync`` (its basin stability at these starts)."""
        return self.synced0 / self.n if self.n else math.nan

    @property
    def p_sync_ci(self) -> tuple[float, float]:
        return clopper_pearson(self.synced0, self.n, self.level)

    @property
    def tau0_mean(self) -> tuple[float, float]:
        """Mean and standard error of ``tau0`` over the intact grid's SYNCED realizations."""
        return _mean_se(self.tau0[self.status0 == SYNCED])

    def row(self, u, v) -> LineRemoval:
        """The row of line ``u-v`` (labels, either order)."""
        for r in self.rows:
            if tuple(r.line) in ((u, v), (v, u)):
                return r
        raise GridError(f"line {u}-{v} is not in the table")

    def sync_called(self, q: float = FDR_LEVEL) -> set:
        """The lines whose change of ``P_sync`` is resolved: McNemar's exact p-values, called by
        the Benjamini-Hochberg procedure at false discovery rate ``q`` over the table's lines
        (about one line in twenty would pass a per-line 5% test by chance)."""
        calls = benjamini_hochberg([r.p_value for r in self.rows], q)
        return {r.line for r, c in zip(self.rows, calls, strict=True) if c}

    def tau_called(self, q: float = FDR_LEVEL) -> set:
        """The lines whose change of tau (``d_tau`` on the pairs that synchronize both times) is
        resolved, by the same procedure over :attr:`LineRemoval.tau_p_value`."""
        calls = benjamini_hochberg([r.tau_p_value for r in self.rows], q)
        return {r.line for r, c in zip(self.rows, calls, strict=True) if c}

    def troublemakers(self, k: int | None = 5) -> list[LineRemoval]:
        """Lines whose removal costs the most synchrony: ``lost - gained > 0``, largest first
        (ties by the slowdown ``d_tau``). The first ``k`` (all: None); the resolved ones are
        those in :meth:`sync_called`."""
        rows = [r for r in self.rows if r.net_lost > 0]
        rows.sort(key=lambda r: (-r.net_lost, -np.nan_to_num(r.d_tau)))
        return rows if k is None else rows[:k]

    def braess_lines(self, q: float = FDR_LEVEL) -> list[LineRemoval]:
        """Dynamic Braess lines: removal (or weakening) raises ``P_sync`` (in :meth:`sync_called`)
        or speeds synchronization (``d_tau < 0``, in :meth:`tau_called`), both at false discovery
        rate ``q``. Sorted by the gain of ``P_sync``, then by ``d_tau``."""
        sync, tau = self.sync_called(q), self.tau_called(q)
        rows = [
            r for r in self.rows if (r.net_lost < 0 and r.line in sync) or (r.d_tau < 0 and r.line in tau)
        ]
        rows.sort(key=lambda r: (r.net_lost, np.nan_to_num(r.d_tau)))
        return rows

    def ranked(self) -> list[LineRemoval]:
        """Every row, most harmful first: by ``lost - gained``, then by ``d_tau``."""
        return sorted(self.rows, key=lambda r: (-r.net_lost, -np.nan_to_num(r.d_tau)))

    def to_dicts(self) -> list[dict]:
        return [r.as_dict() for r in self.rows]

    def summary(self) -> dict:
        """The intact grid's numbers and the run's, as plain data."""
        t, se = self.tau0_mean
        return {
            "name": self.name,
            "beta": self.beta,
            "seed": self.seed,
            "realizations": self.n,
            "synced0": self.synced0,
            "p_sync": self.p_sync,
            "p_sync_ci": list(self.p_sync_ci),
            "tau0_mean": t,
            "tau0_se": se,
            "lines": len(self.rows),
            "skipped": [list(e) for e in self.skipped],
            "seconds": self.seconds,
            "level": self.level,
        }

    def to_markdown(self, top: int | None = None, q: float = FDR_LEVEL) -> str:
        """A markdown table ranked by :meth:`ranked` (the first ``top`` rows, all: None) after
        one line with the intact grid's ``P_sync`` and ``tau0``. ``T``: a troublemaker (``P_sync``
        lost, in :meth:`sync_called`); ``B``: a dynamic Braess line (:meth:`braess_lines`);
        ``slower``: ``d_tau > 0`` in :meth:`tau_called`; all at false discovery rate ``q``."""
        lo, hi = self.p_sync_ci
        t, se = self.tau0_mean
        skipped = ""
        if self.skipped:
            skipped = f"; bridges skipped: {', '.join(f'{u}-{v}' for u, v in self.skipped)}"
        head = (
            f"{self.name}: beta={self.beta:g}, {self.n} realizations (seed {self.seed}): intact "
            f"P_sync = {self.p_sync:.4f} [{lo:.4f}, {hi:.4f}], tau0 = {t:.3f} +- {se:.3f}; "
            f"{len(self.rows)} lines{skipped}; {self.seconds:.1f} s"
        )
        braess = {r.line for r in self.braess_lines(q)}
        sync, tau = self.sync_called(q), self.tau_called(q)
        out = [
            head,
            "",
            "| line | P_sync after [95% CI] | lost | gained | d P_sync [exact CI] | p (McNemar) "
            "| both | d tau +- se | tau0/tau +- se | mark |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        rows = self.ranked()
        for r in rows if top is None else rows[:top]:
            mark = []
            if r.net_lost > 0 and r.line in sync:
                mark.append("T")
            if r.line in braess:
                mark.append("B")
            if r.d_tau > 0 and r.line in tau:
                mark.append("slower")
            if r.islanding:
                mark.append("islands")
            out.append(
                f"| {r.label} | {r.p_after:.4f} [{r.p_after_ci[0]:.4f}, {r.p_after_ci[1]:.4f}] "
                f"| {r.lost} | {r.gained} | {r.d_psync:+.4f} [{r.d_psync_ci[0]:+.4f}, "
                f"{r.d_psync_ci[1]:+.4f}] | {_p(r.p_value)} | {r.both} | {_pm(r.d_tau, r.d_tau_se)} "
                f"| {_pm(r.ratio, r.ratio_se, 4)} | {' '.join(mark)} |"
            )
        return "\n".join(out)


def _p(p: float) -> str:
    return "1" if p >= 0.9995 else f"{p:.3g}"


def _pm(x: float, se: float, digits: int = 3) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:+.{digits}f} +- {se:.{digits}f}" if math.isfinite(se) else f"{x:+.{digits}f}"


# --- the driver ------------------------------------------------------------------------------


def _grid_mapping(grid: Grid) -> dict:
    """A config mapping of a :class:`~antisync.grids.grid.Grid` (its lines inline, injections,
    inertia and damping per node), with the dynamics of configs/ieee118_grid.yaml (rk4, dt
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
    """The :class:`~antisync.plan.config.Config` of a grid (a :class:`~antisync.grids.grid.Grid`, as
    :func:`line_removal` integrates it), a YAML path, a mapping or a Config, with ``overrides``
    (config keys); a value that is not valid is a one-line GridError."""
    from antisync.errors import ConfigError

    if isinstance(source, Grid):
        source = _grid_mapping(source)
    try:
        return sources.resolve_config(source, dict(overrides), None)
    except ConfigError as exc:
        raise GridError(str(exc)) from None


def parse_lines(text: str | None, labels) -> list[tuple] | None:
    """``--lines`` as pairs of the grid's labels (None: every line): ``"4-5,2-3"`` (a dash
    inside a label is read when one split gives two labels) or a YAML list of pairs
    ``[[a-b, c], ["x,y", -2]]`` that can name any label (:func:`antisync.grids.grid.parse_line_labels`)."""
    from antisync.grids.grid import parse_line_labels

    return parse_line_labels(text, labels)


def _pick_lines(omega: np.ndarray, labels: list, lines, beta: float, islanding: bool):
    """0-based ``(a, b)`` of the lines to change, the bridges among them, the skipped ones: a
    bridge asked for by name is refused unless ``islanding``; with every line asked for, the
    bridges are left out and listed."""
    from antisync.grids.grid import _lines_of, grid_bridges, split_bridges

    if isinstance(lines, str):
        lines = parse_lines(lines, labels)
    todo = _lines_of(omega, labels, lines)
    bridges = grid_bridges(omega)  # refuses a grid that is not connected, whatever beta
    if beta != 1.0:
        return todo, set(), []
    if islanding:
        return todo, bridges, []
    todo, skipped = split_bridges(
        omega,
        labels,
        todo,
        bridges,
        refuse=lines is not None,
        hint="ask for islanding (islanding=True, --islanding)",
    )
    return todo, bridges, skipped


#: Config keys that say where the work runs, not what it computes (a finished table is the
#: same run whatever they were).
WHERE_KEYS = ("threads", "executor", "backend")


def work_config(config) -> dict:
    """A removal run's config as plain JSON data without :data:`WHERE_KEYS`: what a journal's
    key and a finished table's check compare (the same run, wherever it runs)."""
    d = json.loads(json.dumps(_plain(config if isinstance(config, dict) else {}), default=str))
    return {k: v for k, v in d.items() if k not in WHERE_KEYS}


def planned_lines(cfg, lines, beta: float, islanding: bool) -> dict:
    """The lines a removal run of ``cfg`` would change, ``{(u, v) as strings: islanding}``,
    found as :func:`antisync.grids.removal.line_removal` finds them (its refusals, one line each:
    a line not in the grid, a bridge, a per-node value that does not fit the graph)."""
    from antisync.errors import AntisyncError
    from antisync.physics import graphs
    from antisync.plan.model import node_frequencies, node_parameters

    try:
        g = graphs.build_graph(cfg.graph, seed=cfg.seed)
        labels = graphs.node_order(g)
        node_frequencies(cfg.model, len(labels))
        node_parameters(cfg.model, len(labels))
    except AntisyncError as exc:
        raise GridError(str(exc)) from None
    todo, bridges, _ = _pick_lines(graphs.omega_matrix(g), labels, lines, beta, islanding)
    return {(str(labels[a]), str(labels[b])): (a, b) in bridges for a, b in todo}


def check_beta(beta) -> float:
    """``beta`` as a float in ``(0, 1]`` (1 removes the line), else a one-line GridError."""
    try:
        b = float(beta)
    except (TypeError, ValueError):
        raise GridError(f"beta must be a number in (0, 1] (1 removes the line), got {beta!r}") from None
    if not (0.0 < b <= 1.0):
        raise GridError(f"beta must be a number in (0, 1] (1 removes the line), got {beta!r}")
    return b


def line_removal(
    grid_or_config,
    *,
    lines=None,
    beta: float = 1.0,
    realizations: int | None = None,
    seed: int | None = None,
    islanding: bool = False,
    threads: int | None = None,
    level: float = 0.95,
    log=None,
    client=None,
    journal: str | Path | None = None,
    restart: bool = False,
    **overrides,
) -> RemovalTable:
    """Paired dynamic removal (or weakening) of grid lines, module docstring.

    Parameters
    ----------
    grid_or_config : path, mapping, Config or Grid
        A config with a ``model:`` (``configs/ieee39_grid.yaml``), the same keys as a mapping,
        an :class:`antisync.plan.config.Config`, or a :class:`antisync.grids.grid.Grid` (integrated with
        rk4, ``dt = 0.01``, ``t_max = 400`` and frequency locking to 1e-3 unless ``overrides``
        say otherwise).
    lines : list of (u, v), str or None
        The lines (node labels, or ``"4-5,2-3"``); default every line, the bridges left out
        (at ``beta = 1``) and listed in ``skipped``. A bridge named here is refused.
    beta : float
        ``Omega_ij, Omega_ji -> (1 - beta) Omega_ij``, in ``(0, 1]``; 1 removes the line.
    realizations, seed : int, optional
        Override the config's (realization ``k`` starts from ``phase(seed, k, i)``).
    islanding : bool
        Integrate a bridge's removal too, its row marked ``islanding``.
    threads : int, optional
        CPU threads of the compiled driver (default: all cores; on Dask, per task: 1).
    client : distributed.Client, optional
        Integrate on this Dask cluster's workers: tasks of up to :data:`CHUNK` realizations x a
        group of lines (the intact grid in the first group), about :data:`TASKS_PER_WORKER` per
        worker thread. Every trajectory is a function of ``(seed, k, weights)`` alone, so the
        table equals the local one, array for array (tests/test_grid_dynamic.py). The caller
        owns the cluster: anything but an open ``distributed.Client`` (a scheduler address
        included) is refused before any work.
    journal : path, optional
        A folder (``<out>.partial`` for ``antisync grid --out``) where every finished task is
        saved at once: a run killed at any moment and started again with the same journal and
        arguments integrates only what is missing (:class:`RemovalJournal`). A journal of other
        work (another config, seed, realization count, line set or beta) is refused in one line
        naming what differs; a task file in it that is damaged or not of this work (its tag) is
        deleted and its work done again, never merged.
    restart : bool
        Discard what ``journal`` holds (once the arguments are checked) and start over.
    level : float
        Confidence level of the exact intervals.
    log : callable, optional
        Receives one-line progress messages.
    **overrides
        Config keys, as :func:`antisync.run` takes them (``dynamics={"t_max": 200}``).

    Returns
    -------
    RemovalTable

    Raises
    ------
    antisync.grids.grid.GridError
        A line not in the grid, a bridge at ``beta = 1``, ``beta`` outside ``(0, 1]``, a config
        value that is not valid (per-node files of the wrong length included), a ``client`` that
        is not an open ``distributed.Client``, or a ``journal`` of other work: one line.
    """
    from antisync.physics import coupling, graphs
    from antisync.plan.jobs import check_step
    from antisync.plan.model import model_setup

    t_start = time.perf_counter()
    _check_client(client)
    beta = check_beta(beta)
    if not 0 < level < 1:
        raise GridError(f"level must lie in (0, 1), got {level}")
    if realizations is not None:
        overrides["realizations"] = realizations
    if seed is not None:
        overrides["seed"] = seed
    cfg = resolve_config(grid_or_config, overrides)
    from antisync.errors import AntisyncError

    try:
        g = graphs.build_graph(cfg.graph, seed=cfg.seed)
        labels = graphs.node_order(g)
        omega = graphs.omega_matrix(g)
        check_step(omega, cfg)
        todo, bridges, skipped = _pick_lines(omega, labels, lines, beta, islanding)
        if not todo:
            raise GridError("no line to remove: every line asked for is a bridge")
        pattern = omega > 0
        csr = coupling.to_csr(coupling.coupling_matrix(omega, cfg.dynamics.coupling), pattern=pattern)
        variants = np.empty((len(todo), csr.weights.size))
        for v, (a, b) in enumerate(todo):
            changed = omega.copy()
            changed[a, b] *= 1.0 - beta
            changed[b, a] *= 1.0 - beta
            variants[v] = coupling.to_csr(
                coupling.coupling_matrix(changed, cfg.dynamics.coupling), pattern
            ).weights
        names = [f"line {labels[a]}-{labels[b]} beta {beta:g}" for a, b in todo]
        setup, _, _ = model_setup(cfg, csr.indptr, csr.indices, [csr.weights, *variants], names)
    except AntisyncError as exc:
        if isinstance(exc, GridError):
            raise
        raise GridError(str(exc)) from None
    except ValueError as exc:  # a normalized coupling left with an isolated node
        raise GridError(f"cannot weaken the lines: {exc}") from None

    dyn = cfg.dynamics
    m = int(cfg.realizations)
    status0 = np.empty(m, dtype=np.int8)
    status = np.empty((m, len(todo)), dtype=np.int8)
    tau0 = np.full(m, np.nan)
    tau = np.full((m, len(todo)), np.nan)
    fixed = dict(
        seed=int(cfg.seed),
        indptr=csr.indptr,
        indices=csr.indices,
        base=csr.weights,
        setup=setup,
        model=cfg.model,
        n_nodes=len(labels),
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        integrator=dyn.integrator,
        interpolate=dyn.interpolate,
    )
    tasks = _plan(m, variants, base=csr.weights, groups=1 if client is None else _groups(client, m))
    done = 0
    book = None
    if journal is not None:
        key = {
            "config": work_config(cfg.to_dict()),
            "lines": [[str(labels[a]), str(labels[b])] for a, b in todo],
        }
        if restart:
            remove_journal(journal)
        key = {**key, "beta": beta, "islanding": bool(islanding)}
        book = RemovalJournal(journal, key, work=_work_digest(fixed, variants))
        have = book.load(status0, tau0, status, tau)
        tasks = _unfinished(tasks, have)
        done = int(have.sum())
        if done and log is not None:
            log(f"resumed: {done} trajectories read from {book.folder}")
    for (ks, group, intact), part in _run_tasks(tasks, variants, fixed, threads, client):
        span = slice(ks[0], ks[-1] + 1)
        if intact:
            status0[span], tau0[span] = part[0], part[1]
        status[span, group], tau[span, group] = part[2], part[3]
        if book is not None:
            book.save(ks, group, intact, part)
        done += ks.size * (group.size + intact)
        if log is not None:
            took = time.perf_counter() - t_start
            grids = len(todo) + 1
            log(f"{done}/{m * grids} trajectories ({m} realizations x {grids} grids), {took:.1f} s")

    ok0 = np.isin(status0, (SYNCED, ALREADY_SYNCED))
    rows = []
    for v, (a, b) in enumerate(todo):
        ok = np.isin(status[:, v], (SYNCED, ALREADY_SYNCED))
        lost = int((ok0 & ~ok).sum())
        gained = int((~ok0 & ok).sum())
        p_value, lo, hi = mcnemar_exact(lost, gained, m, level)
        both = (status0 == SYNCED) & (status[:, v] == SYNCED)
        dt_mean, dt_se = _mean_se(tau[both, v] - tau0[both])
        f_mean, f_se = _mean_se(tau0[both] / tau[both, v])
        rows.append(
            LineRemoval(
                line=(labels[a], labels[b]),
                nodes=(a, b),
                beta=beta,
                n=m,
                synced_before=int(ok0.sum()),
                synced_after=int(ok.sum()),
                p_before=float(ok0.mean()),
                p_before_ci=clopper_pearson(int(ok0.sum()), m, level),
                p_after=float(ok.mean()),
                p_after_ci=clopper_pearson(int(ok.sum()), m, level),
                lost=lost,
                lost_ci=clopper_pearson(lost, m, level),
                gained=gained,
                gained_ci=clopper_pearson(gained, m, level),
                d_psync=(gained - lost) / m,
                d_psync_ci=(lo, hi),
                p_value=p_value,
                both=int(both.sum()),
                d_tau=dt_mean,
                d_tau_se=dt_se,
                ratio=f_mean,
                ratio_se=f_se,
                islanding=(a, b) in bridges,
            )
        )
    return RemovalTable(
        name=cfg.name,
        beta=beta,
        seed=int(cfg.seed),
        rows=tuple(rows),
        status0=status0,
        tau0=tau0,
        status=status,
        tau=tau,
        seconds=time.perf_counter() - t_start,
        skipped=tuple(skipped),
        config=cfg.to_dict(),
        level=level,
    )


# --- the work: tasks of realizations x lines, run here or on Dask ----------------------------


def _plan(m: int, variants: np.ndarray, base: np.ndarray, groups: int) -> list[tuple]:
    """Tasks ``(realizations, line indices, with the intact grid)``: chunks of :data:`CHUNK`
    realizations x ``groups`` groups of lines; the first group of a chunk integrates the intact
    grid too, and so does any group holding a line whose change leaves the weights as they are
    (the driver copies such a line's result from the intact one)."""
    same = np.array([np.array_equal(w, base) for w in variants], dtype=bool)
    parts = [g for g in np.array_split(np.arange(variants.shape[0]), max(1, groups)) if g.size]
    out = []
    for first in range(0, m, CHUNK):
        ks = np.arange(first, min(m, first + CHUNK), dtype=np.int64)
        out += [(ks, g, j == 0 or bool(same[g].any())) for j, g in enumerate(parts)]
    return out


#: What :func:`line_removal` says to a ``client`` that is not a ``distributed.Client``.
CLIENT_HINT = (
    "to use a scheduler address, open Client('tcp://...') yourself or use `antisync grid --scheduler`"
)


def _check_client(client) -> None:
    """Refuse, before any work, a ``client`` that is not an open ``distributed.Client``.

    The caller owns the cluster (Dask functions take a client and never build or close one), so
    a scheduler address is not opened here: one line says how to do it.
    """
    if client is None:
        return
    # distributed is imported only when a client is given: importing it costs about a second
    from distributed import Client

    if not isinstance(client, Client):
        raise GridError(
            f"client must be a distributed.Client, got {type(client).__name__} {client!r:.80}; {CLIENT_HINT}"
        )
    if client.status not in ("running", "connecting", "newly-created"):
        raise GridError(f"client is a distributed.Client that is {client.status}: pass an open one")


def _groups(client, m: int) -> int:
    threads = sum(client.nthreads().values()) or 1
    chunks = -(-m // CHUNK)
    return max(1, -(-TASKS_PER_WORKER * threads // chunks))


def _removal_task(ks, variants, intact: bool, fixed: dict, threads):
    """Integrate realizations ``ks`` of the intact grid (if ``intact``) and of ``variants``:
    ``(status0, tau0, status, tau)``, times in the model's units (NaN where not SYNCED)."""
    from antisync.execution.compute import model_params
    from antisync.kernels.cpu import simulate_model
    from antisync.stats.estimators import crossing_times

    params = model_params(
        fixed["setup"], fixed["model"], fixed["seed"], ks, fixed["n_nodes"], fixed["targets"]
    )
    todo = None
    if not intact:
        todo = np.ones((ks.size, variants.shape[0] + 1), dtype=np.bool_)
        todo[:, 0] = False
    sim = simulate_model(
        fixed["seed"],
        0,
        0,
        fixed["indptr"],
        fixed["indices"],
        fixed["base"],
        variants,
        params,
        dt=fixed["dt"],
        max_steps=fixed["max_steps"],
        integrator=fixed["integrator"],
        threads=threads,
        realizations=ks,
        todo=todo,
    )
    t0, t = crossing_times(sim, fixed["interpolate"])
    dt = fixed["dt"]
    return (
        sim.status0,
        np.where(sim.status0 == SYNCED, t0 * dt, np.nan),
        sim.status,
        np.where(sim.status == SYNCED, t * dt, np.nan),
    )


def _run_tasks(tasks, variants, fixed, threads, client):
    """Yield ``(task, result)`` of :func:`_removal_task`: here in order, or on ``client``'s
    workers as they finish (each task's ``targets`` cut to its own lines)."""

    def args(task):
        ks, group, intact = task
        targets = fixed["setup"].targets
        targets = np.concatenate([targets[:1], targets[1:][group]])
        return ks, variants[group], intact, {**fixed, "targets": targets}

    if client is None:
        for task in tasks:
            yield task, _removal_task(*args(task), threads)
        return
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    futures = {client.submit(_removal_task, *args(task), threads or 1, pure=False): task for task in tasks}

    try:
        for fut in as_completed(list(futures), loop=client.loop):
            try:
                result = fut.result()
            except (KilledWorker, CancelledError) as exc:
                raise GridError(
                    f"the Dask cluster lost a removal task ({type(exc).__name__}: {exc}); with --out, "
                    "the finished tasks are kept: run the same command with --resume"
                ) from None
            yield futures[fut], result
    finally:
        client.cancel(list(futures))


def _unfinished(tasks: list[tuple], have: np.ndarray) -> list[tuple]:
    """``tasks`` less what ``have`` (bool ``(m, 1 + lines)``: column 0 the intact grid) holds."""
    out = []
    for ks, group, intact in tasks:
        intact = intact and not have[ks, 0].all()
        group = group[~have[ks][:, 1 + group].all(axis=0)]
        if intact or group.size:
            out.append((ks, group, intact))
    return out


def key_changes(old, new, most: int = 4) -> str:
    """What differs between two keys (a journal's, two tables' configs) as ``key: old -> new``
    with dotted paths into nested mappings (``seed: 11 -> 12``, ``dynamics.t_max: 60 -> 80``;
    ``(absent)`` for a key one side lacks), the first ``most`` and a count of the rest: a
    refusal names what changed rather than every key."""
    absent = object()

    def walk(a, b, prefix: str):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in [*a, *(k for k in b if k not in a)]:
                yield from walk(a.get(k, absent), b.get(k, absent), f"{prefix}{k}.")
        elif a != b:
            yield prefix.rstrip(".") or "the whole key", a, b

    def shown(v) -> str:
        text = "(absent)" if v is absent else json.dumps(v, default=str)
        return text if len(text) <= 40 else text[:37] + "..."

    changes = [f"{k}: {shown(a)} -> {shown(b)}" for k, a, b in walk(old, new, "")]
    if not changes:
        return "no key differs"
    more = f"; and {len(changes) - most} more" if len(changes) > most else ""
    return "; ".join(changes[:most]) + more


def _work_digest(fixed: dict, variants: np.ndarray) -> str:
    """SHA-256 of the work as built: the grid's CSR pattern and weights, every line's changed
    weights and the resolved model (per-node parameters, targets).

    Part of a :class:`RemovalJournal`'s task tag beside its key: the key names per-node files
    by path and a graph generator by its arguments, so an edited file or another built graph
    under the same key must still keep the old tasks out.
    """
    h = hashlib.sha256()

    def add(name: str, value) -> None:
        h.update(name.encode())
        if value is None:
            h.update(b"none")
        elif isinstance(value, np.ndarray):
            h.update(f"{value.dtype.str}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
        else:
            h.update(repr(value).encode())

    for name in ("indptr", "indices", "base"):
        add(name, np.asarray(fixed[name]))
    add("variants", np.asarray(variants))
    setup = fixed["setup"]
    for f in fields(setup):
        add(f.name, getattr(setup, f.name))
    return h.hexdigest()


class RemovalJournal:
    """Finished removal tasks on disk, so that an interrupted :func:`line_removal` resumes.

    The folder holds ``removal_key.json`` (the work: resolved config, lines, beta, islanding)
    and one ``task_<first realization>_<first line>_<lines>_<intact>.npz`` per finished task
    (written to a temporary name, then renamed: a file is whole or absent). A folder whose key
    is another work's is refused with one line and left as it is.

    Every task file carries a tag (:attr:`tag`: a digest of the key and of the work as built,
    :func:`_work_digest`), as the run journal's chunks do (:func:`antisync.store.journal.
    chunk_tag`): on load, a task file that is damaged (cut off, empty, not an ``.npz``), tagged
    for other work (copied from another run's journal), untagged, or whose arrays do not fit
    this work (shapes, dtypes, realizations or lines out of range) is deleted and never
    merged; its work is simply done again.

    Parameters
    ----------
    folder : path
        The journal folder (created when missing).
    key : dict
        The work, as plain JSON data; compared with the folder's ``removal_key.json``.
    work : str
        A digest of the work as built (:func:`_work_digest`), part of the tag.
    """

    KEY_FILE = "removal_key.json"

    def __init__(self, folder: str | Path, key: dict, work: str = ""):
        self.folder = Path(folder)
        self.key = json.loads(json.dumps(_plain(key), sort_keys=True))
        self.tag = hashlib.sha256(f"{json.dumps(self.key, sort_keys=True)}\n{work}".encode()).hexdigest()
        key_path = self.folder / self.KEY_FILE
        if self.folder.exists() and not self.folder.is_dir():
            raise GridError(f"{self.folder} is a file, not a removal journal (a folder); move it away")
        if key_path.exists() or key_path.is_symlink():
            try:
                theirs = json.loads(key_path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise GridError(
                    f"{key_path} cannot be read ({type(exc).__name__}), so the work this journal holds is "
                    "unknown: pass --overwrite (restart=True) to discard it, or move the folder away"
                ) from None
            if theirs != self.key:
                changed = key_changes(theirs, self.key)
                raise GridError(
                    f"{self.folder} holds the unfinished work of another removal run ({changed}): pass the "
                    "same arguments to finish it, or --overwrite to discard it"
                )
        elif self.folder.exists() and any(self.folder.iterdir()):
            raise GridError(f"{self.folder} exists and is not a removal journal; move it away")
        else:
            self.folder.mkdir(parents=True, exist_ok=True)
            replace_atomically(key_path, lambda tmp: tmp.write_text(json.dumps(self.key, sort_keys=True)))

    def tasks(self) -> list[Path]:
        return sorted(self.folder.glob("task_*.npz"))

    def load(self, status0, tau0, status, tau) -> np.ndarray:
        """Fill the arrays from the saved tasks that carry this journal's :attr:`tag` and fit
        the arrays; delete every other task file. Return which cells were filled (bool
        ``(realizations, 1 + lines)``, column 0 the intact grid)."""
        have = np.zeros((status0.size, 1 + status.shape[1]), dtype=bool)
        for path in self.tasks():
            task = self._read(path, status0.size, status.shape[1])
            if task is None:
                with contextlib.suppress(OSError):  # a folder of that name: not ours to remove
                    path.unlink()
                continue
            ks, group, intact, part = task
            if intact:
                status0[ks], tau0[ks] = part["status0"], part["tau0"]
                have[ks, 0] = True
            status[np.ix_(ks, group)], tau[np.ix_(ks, group)] = part["status"], part["tau"]
            have[np.ix_(ks, 1 + group)] = True
        return have

    def _read(self, path: Path, m: int, lines: int):
        """``(ks, group, intact, arrays)`` of the task file ``path``, or None when it is damaged,
        not tagged :attr:`tag`, or its arrays are not a task of ``m`` realizations x ``lines``
        lines (checked whole before anything is merged)."""
        try:
            with np.load(path, allow_pickle=False) as f:
                if str(f["tag"][()]) != self.tag:
                    return None
                ks, group, intact = f["ks"], f["group"], f["intact"]
                part = {k: f[k] for k in ("status0", "tau0", "status", "tau")}
        except Exception:  # any damage (cut off, empty, EOF, not a zip, a bad header, a
            return None  # missing array, a pickle refused) means the same: the work is done again
        n = ks.size
        index_ok = all(
            a.ndim == 1
            and a.dtype.kind in "iu"
            and a.size == np.unique(a).size
            and (a.size == 0 or (a.min() >= 0 and a.max() < top))
            for a, top in ((ks, m), (group, lines))
        )
        if not index_ok or n == 0 or intact.shape != () or intact.dtype != np.bool_:
            return None
        shapes = {"status": (n, group.size), "tau": (n, group.size)}
        if intact:
            shapes.update(status0=(n,), tau0=(n,))
        for k, shape in shapes.items():
            want = "iu" if k.startswith("status") else "f"
            if part[k].shape != shape or part[k].dtype.kind not in want:
                return None
        return ks.astype(np.int64), group.astype(np.int64), bool(intact), part

    def save(self, ks, group, intact: bool, part) -> None:
        name = f"task_{ks[0]}_{group[0] if group.size else 0}_{group.size}_{int(intact)}.npz"

        def write(tmp: Path) -> None:
            with open(tmp, "wb") as fh:
                np.savez(
                    fh,
                    ks=ks,
                    group=group,
                    intact=intact,
                    status0=part[0],
                    tau0=part[1],
                    status=part[2],
                    tau=part[3],
                    tag=np.array(self.tag),
                )

        replace_atomically(self.folder / name, write)


def remove_journal(folder: str | Path) -> None:
    """Delete a :class:`RemovalJournal`'s files and its folder (once empty); nothing else (a
    folder named like a task file, or any file not antisync's, stays, and so does the folder)."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    for path in [*folder.glob("task_*.npz"), folder / RemovalJournal.KEY_FILE]:
        with contextlib.suppress(OSError):
            path.unlink()
    with contextlib.suppress(OSError):
        folder.rmdir()


def journal_folder(out: str | Path) -> Path:
    """Where ``antisync grid --removal --out X.json`` keeps its journal: ``X.json.partial``."""
    out = Path(out)
    if out.name in ("", ".", ".."):
        raise GridError(f"--out {str(out)!r} names no file; give a file name ending in .json")
    return out.with_name(out.name + ".partial")


# --- files -----------------------------------------------------------------------------------


def check_output(path: str | Path, overwrite: bool = False, protect=()) -> Path:
    """The JSON output ``path``, checked before any work (:func:`check_new_file`): an existing
    file is replaced (``overwrite``) only when it is a removal table; ``protect``: the run's
    inputs (:func:`antisync.store.outputs.config_inputs`), never replaced."""
    return check_new_file(
        path,
        overwrite,
        "--out",
        (".json",),
        "the removal table is written as JSON; name it *.json",
        replaceable=lambda p: json_format_problem(p, FORMAT),
        kind=f"an antisync removal table (JSON of format {FORMAT!r})",
        protect=protect,
    )


def check_new_file(
    path: str | Path,
    overwrite: bool,
    option: str,
    suffixes: tuple[str, ...],
    hint: str,
    *,
    replaceable,
    kind: str,
    protect=(),
) -> Path:
    """An output ``path`` checked before any work by antisync's one output policy
    (:func:`antisync.store.outputs.check_output_path`): its suffix one of ``suffixes`` (else
    ``hint``), its folder existing, no link, no input of the run (``protect``), nothing inside
    a journal folder, and an existing file replaced only with ``overwrite`` and only when
    ``replaceable`` accepts it (``kind``); one-line GridErrors that name ``option``."""
    return check_output_path(
        path,
        option=option,
        suffixes=suffixes,
        hint=hint,
        overwrite=overwrite,
        replaceable=replaceable,
        kind=kind,
        protect=protect,
        error=GridError,
    )


def _plain(x):
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, float | np.floating):
        return None if not math.isfinite(x) else float(x)
    return x


def table_document(table: RemovalTable, command: str = "") -> dict:
    """``table`` as the plain mapping :func:`write_table` writes (the summary, every row, the
    troublemaker and Braess lists, the resolved calls, the resolved config and provenance;
    ``nan`` as ``None``)."""
    from antisync._version import __version__
    from antisync.store.provenance import git_revision, now

    sync, tau = table.sync_called(), table.tau_called()
    doc = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "version": __version__,
        "git_revision": git_revision(),
        "command": command,
        "written": now(),
        "summary": table.summary(),
        "troublemakers": [r.label for r in table.troublemakers(None)],
        "braess_lines": [r.label for r in table.braess_lines()],
        # the resolved changes (Benjamini-Hochberg, false discovery rate FDR_LEVEL over the lines)
        "fdr_level": FDR_LEVEL,
        "sync_called": [r.label for r in table.rows if r.line in sync],
        "tau_called": [r.label for r in table.rows if r.line in tau],
        "rows": table.to_dicts(),
        "config": table.config,
    }
    return _plain(doc)


def write_table(table: RemovalTable, path: str | Path, overwrite: bool = False, command: str = "") -> Path:
    """Write ``table`` as JSON (:func:`table_document`) atomically (:func:`replace_atomically`),
    so an existing result is never half-written. ``nan`` is written as ``null``. An existing
    ``path`` is replaced (``overwrite``) only when it is a removal table, and never when it is a
    file the table's config reads (:func:`check_output`)."""
    path = check_output(path, overwrite, protect=config_inputs(table.config))
    text = json.dumps(table_document(table, command), indent=1, default=str)

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
            fh.flush()
            os.fsync(fh.fileno())

    return replace_atomically(path, write)


def replace_atomically(path: Path, write) -> Path:
    """Call ``write(tmp)`` on a temporary file in ``path``'s folder, then rename it over
    ``path``: a reader sees the old file or the whole new one, never half of it; on an error the
    temporary file is removed and ``path`` is left as it was."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # mkstemp's 0600, as an ordinary new file would be
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
