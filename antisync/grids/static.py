"""Static indicators of power-grid lines: what weakening or removing one line does to the
phase-locked operating state (docs/power_grids.md).

The model is antisync's generalized one (docs/models.md),
``m_i theta_i'' + gamma_i theta_i' = P_i + sum_j w_ij sin(theta_j - theta_i - alpha)``, its
phase-locked state connected to synchrony found by :func:`antisync.physics.locked.locked_state`
(Newton continuation from ``P = 0``). For one network ``W`` the static indicators of that state
``phi`` are (:class:`GridState`):

- ``exists`` / ``stable``: a locked state is found on the branch connected to synchrony, and
  every eigenvalue of its linearization but the rotation's zero has a negative real part;
- ``max_flow = max_{w_ij > 0} w_ij |sin(phi_j - phi_i)|``, the largest line flow (the power a
  line carries, ``F_ij = K_ij sin(theta_j - theta_i)`` in the lossless power-flow picture of
  Witthaut and Timme, New J. Phys. 14, 083036 (2012), Sec. 2);
- ``max_load = max_{w_ij > 0} |sin(phi_j - phi_i)|``, the largest relative load, flow over
  capacity: a line at ``|sin| = 1`` is at its static limit, and a load change that would push
  a line past it makes the locked state disappear (a saddle-node bifurcation). Witthaut and
  Timme's Braess's paradox is this: adding a line, or raising the capacity of one, can reroute
  flow onto a line that is already near ``|sin| = 1`` and so destroy the locked state;
- ``margin = -max Re(lambda)`` over the eigenvalues of the linearization
  (:func:`antisync.physics.locked.linearization`, per-node inertia and damping included: load buses
  with ``m_i = 0`` stay first order as in the structure-preserving model of Nishikawa and
  Motter, New J. Phys. 17, 015012 (2015)) other than the zero of the global rotation: the
  slowest decay rate of a small perturbation, the linear stability measure whose Braess
  paradox (a capacity increase that lowers it) Coletta and Jacquod study in Phys. Rev. E 93,
  032222 (2016). For the first-order model with ``P = 0`` it is the second smallest
  eigenvalue of the Laplacian of ``W``; negative for an unstable state;
- ``lambda2 = -max Re(mu)`` over the eigenvalues ``mu`` of the first-order Jacobian
  ``J_ik = w_ik cos(phi_k - phi_i - alpha)`` (minus the row sum on the diagonal) other than the
  rotation's zero: ``margin`` of the first-order model, the smallest nonzero eigenvalue of the
  loaded Laplacian (Coletta and Jacquod's stability measure). With inertia ``margin`` can
  saturate (uniform ``m``, ``gamma``: every mode with ``lambda_k > gamma^2 / 4m`` decays at
  ``gamma / 2m``), and ``lambda2`` still resolves a change;
- ``r``, the order parameter ``|mean_j exp(i phi_j)|`` of the locked state (``r*``).

Lag (``alpha != 0``) is accepted and enters the state and its stability; the loads above stay
``|sin(phi_j - phi_i)|`` as defined (their ``|sin| = 1`` limit is the ``alpha = 0`` one).

:func:`line_indicators` recomputes the state after weakening each line in both directions,
``Omega_ij -> (1 - beta) Omega_ij`` and ``Omega_ji -> (1 - beta) Omega_ji`` (``beta = 1``
removes the line; ``beta < 0`` strengthens it), and reports every indicator after the change
and its change from the intact grid (:class:`LineIndicators`). A line whose removal (or
weakening) *improves* the state, restoring a stable one, raising the margin or lowering the
largest relative load, is a static Braess candidate (:meth:`LineTable.braess_lines`); a line
whose removal destroys the stable state or lowers the margin most is a troublemaker
(:meth:`LineTable.troublemakers`). These are static statements about the operating point;
whether the grid's dynamics reaches the new state after a sudden removal is a dynamic question
this module does not answer.

Each line's state is found by Newton's method from the intact grid's locked state
(:class:`antisync.physics.warm.LineChanges`: the same state as the continuation's, accepted only
where that is proven, else the continuation for that line, named in ``LineTable.continued``).
``warm=False`` is the continuation for every line.

Pure numpy/scipy/networkx: nothing here compiles.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np
from tqdm import tqdm

from antisync.grids.errors import GridError
from antisync.grids.lines import Rows, grid_bridges, lines_of, listed, split_bridges
from antisync.grids.load import Grid
from antisync.physics.coupling import coupling_matrix
from antisync.physics.locked import SPARSE_FROM, LockedState, jacobian, locked_state, rightmost, vouched_bound
from antisync.physics.warm import LineChanges

__all__ = [
    "BRAESS_TOL",
    "RANK_KEYS",
    "GridState",
    "LineIndicators",
    "LineTable",
    "format_table",
    "grid_state",
    "line_indicators",
    "static_table",
]

#: The changes :meth:`LineTable.ranked` sorts by.
RANK_KEYS = ("d_margin", "d_lambda2", "d_max_load", "d_max_flow", "d_r")
#: Default tolerance of :meth:`LineTable.braess_lines`: an indicator must improve by more.
BRAESS_TOL = 1e-9


@dataclass(frozen=True)
class GridState:
    """The static indicators of one network's locked state (module docstring).

    ``exists`` is False when :func:`~antisync.physics.locked.locked_state` finds no locked state
    connected to synchrony; then every number is ``nan`` and ``stable`` is False.
    """

    exists: bool
    stable: bool
    margin: float
    max_flow: float
    max_load: float
    r: float
    lambda2: float
    #: 0-based end nodes ``(i, j)``, ``i < j``, of the line at ``max_load`` (None: no state)
    max_load_line: tuple[int, int] | None = None

    @classmethod
    def missing(cls) -> GridState:
        nan = math.nan
        return cls(False, False, nan, nan, nan, nan, nan)


@dataclass(frozen=True)
class LineIndicators:
    """One line's row: the state after weakening the line by ``beta`` and the changes.

    ``line``: the two end nodes (labels, ``u < v`` in node order); ``nodes``: their 0-based
    indices. ``stable``, ``margin``, ``max_flow``, ``max_load``, ``r``: the state after the
    change (:class:`GridState`; ``nan`` when none exists; an unstable state's values are
    kept, its margin negative). ``d_*``: after minus before, between two stable states
    (``nan`` when either is missing or unstable). ``restores``: the intact grid has no stable locked
    state and the changed one has; ``destroys``: the reverse.
    """

    line: tuple
    nodes: tuple[int, int]
    beta: float
    exists: bool
    stable: bool
    margin: float
    max_flow: float
    max_load: float
    r: float
    lambda2: float
    d_margin: float
    d_max_flow: float
    d_max_load: float
    d_r: float
    d_lambda2: float
    restores: bool
    destroys: bool

    @property
    def label(self) -> str:
        return f"{self.line[0]}-{self.line[1]}"

    def as_dict(self) -> dict:
        d = asdict(self)
        d["label"] = self.label
        return d


@dataclass(frozen=True)
class LineTable(Rows):
    """The rows of :func:`line_indicators` (a sequence of :class:`LineIndicators`) with the
    intact grid's state ``base`` and the rankings of the static Braess and troublemaker lines."""

    base: GridState
    rows: tuple[LineIndicators, ...]
    beta: float
    skipped: tuple = field(default=())  # bridges left out (``skip_bridges=True``)
    seconds: float = 0.0
    labels: tuple = field(default=())  # node labels in matrix order
    #: the lines (label pairs) whose state the continuation from ``P = 0`` found: the warm start
    #: from the intact state was refused (:mod:`antisync.physics.warm`) or not offered
    continued: tuple = field(default=())

    def name(self, line: tuple[int, int] | None) -> str:
        """``"u-v"`` of 0-based end nodes (e.g. ``base.max_load_line``) by the node labels."""
        if line is None:
            return "-"
        lab = self.labels or tuple(range(max(line) + 1))
        return f"{lab[line[0]]}-{lab[line[1]]}"

    def row(self, u, v) -> LineIndicators:
        """The row of line ``u-v`` (labels, either order)."""
        for r in self.rows:
            if r.line in ((u, v), (v, u)):
                return r
        raise GridError(f"line {u}-{v} is not in the table")

    def to_dicts(self) -> list[dict]:
        return [r.as_dict() for r in self.rows]

    def ranked(self, by: str = "d_margin", tol: float = BRAESS_TOL) -> list[LineIndicators]:
        """Rows most harmful first: those left without a stable locked state, then by ``by``
        ascending (``d_margin``, ``d_lambda2``, ``d_r``) or descending (``d_max_load``,
        ``d_max_flow``: a rising load harms). Changes within ``tol`` of each other count as
        equal (a saturated margin, rounding) and are ordered by ``d_max_load``, largest first."""
        if by not in RANK_KEYS:
            raise GridError(f"rank by one of {', '.join(RANK_KEYS)}, got {by!r}")
        sign = -1.0 if by in ("d_max_flow", "d_max_load") else 1.0  # harmful: load rises

        def key(r):
            v = getattr(r, by)
            if not (r.stable and math.isfinite(v)):
                return (0, 0.0, 0.0)
            return (1, sign * v if abs(v) > tol else 0.0, -np.nan_to_num(r.d_max_load))

        return sorted(self.rows, key=key)

    def braess_lines(self, tol: float = BRAESS_TOL, margin: str = "d_margin") -> list[LineIndicators]:
        """Static Braess candidates: lines whose weakening or removal improves the operating
        state. A row qualifies when it ``restores`` a stable state, or both states are stable
        and the margin (``margin``: ``"d_margin"`` or ``"d_lambda2"``) rises by more than
        ``tol`` or the largest relative load falls by more than ``tol``. Sorted: restoring rows
        first, then by the margin's rise, then by the load's fall, largest first."""
        _check_margin_key(margin)
        out = []
        for r in self.rows:
            both = self.base.stable and r.stable
            if r.restores or (both and (getattr(r, margin) > tol or r.d_max_load < -tol)):
                out.append(r)

        def key(r):
            rise = getattr(r, margin)
            return (not r.restores, -(rise if rise > tol else 0.0), np.nan_to_num(r.d_max_load))

        return sorted(out, key=key)

    def troublemakers(self, k: int | None = 5, by: str = "d_margin") -> list[LineIndicators]:
        """Lines whose weakening or removal harms most: those that destroy the stable state
        first, then by the change of ``by`` (``"d_margin"`` or ``"d_lambda2"``), most negative
        first; rows whose ``by`` does not fall by more than :data:`BRAESS_TOL` (a saturated
        margin, see the module docstring) are left out. The first ``k`` (all: None)."""
        _check_margin_key(by)
        if not self.base.stable:
            return []  # nothing to destroy: see braess_lines for lines that restore a state
        rows = [r for r in self.ranked(by) if r.destroys or getattr(r, by) < -BRAESS_TOL]
        return rows if k is None else rows[:k]


def _check_margin_key(key: str) -> None:
    if key not in ("d_margin", "d_lambda2"):
        raise GridError(f"the margin is d_margin or d_lambda2, got {key!r}")


def _state_of(w: np.ndarray, p: np.ndarray, lag, inertia, damping) -> GridState:
    return _indicators(w, locked_state(w, p, lag, inertia, damping), lag, inertia)


def _indicators(w: np.ndarray, st: LockedState | None, lag, inertia) -> GridState:
    """The :class:`GridState` of ``w``'s locked state ``st`` (None: none found)."""
    if st is None:
        return GridState.missing()
    rows, cols = np.nonzero(w)  # row-major: the first of equal loads is the dense argmax's
    if np.any(np.asarray(inertia) > 0):
        # the first-order Jacobian's rightmost eigenvalue but the rotation's zero (sparse on a
        # large grid, as locked.py's margin)
        sparse = w.shape[0] >= SPARSE_FROM
        bound = vouched_bound(st.phi, w, lag) if sparse else None
        lambda2 = -rightmost(jacobian(st.phi, w, lag, sparse=sparse), missed_below=bound)
    else:
        lambda2 = float(-st.max_real)  # the linearization is the Jacobian itself
    return _grid_state(st, rows, cols, w[rows, cols], lambda2)


def _grid_state(st: LockedState, rows, cols, vals, lambda2: float) -> GridState:
    """:class:`GridState` of the locked state ``st`` of the network whose nonzero entries are
    ``vals`` at ``rows, cols`` (row-major)."""
    s = np.abs(np.sin(st.phi[cols] - st.phi[rows]))
    top = int(np.argmax(s)) if s.size else 0
    return GridState(
        True,
        bool(st.stable),
        float(-st.max_real),
        float((vals * s).max()) if s.size else 0.0,
        float(s.max()) if s.size else 0.0,
        float(st.r),
        float(lambda2),
        (int(min(rows[top], cols[top])), int(max(rows[top], cols[top]))) if s.size else None,
    )


def _changes(after: GridState, before: GridState) -> dict:
    """``d_*`` of :class:`LineIndicators`: after minus before, both stable, else ``nan``."""
    both = after.stable and before.stable
    keys = ("margin", "max_flow", "max_load", "r", "lambda2")
    return {f"d_{k}": getattr(after, k) - getattr(before, k) if both else math.nan for k in keys}


def _check_inputs(omega, p, coupling, lag, inertia, damping):
    omega = np.asarray(omega, dtype=np.float64)
    if omega.ndim != 2 or omega.shape[0] != omega.shape[1]:
        raise GridError(f"omega must be a square matrix, got shape {omega.shape}")
    n = omega.shape[0]
    if not np.isfinite(omega).all() or (omega < 0).any() or np.any(np.diag(omega) != 0):
        raise GridError("omega must be finite and non-negative with a zero diagonal")
    if not np.array_equal(omega > 0, (omega > 0).T):
        raise GridError("omega must have its lines in both directions (Omega_ij > 0 iff Omega_ji > 0)")
    p = np.asarray(p, dtype=np.float64)
    if p.shape != (n,) or not np.isfinite(p).all():
        raise GridError(f"p must hold {n} finite injections, one per node, got shape {p.shape}")
    if coupling not in ("raw", "normalized"):
        raise GridError(f"coupling must be 'raw' or 'normalized', got {coupling!r}")
    for name, v in (("inertia", inertia), ("damping", damping)):
        a = np.asarray(v, dtype=np.float64)
        if a.shape not in ((), (n,)) or not np.isfinite(a).all():
            raise GridError(f"{name} must be one number or {n} (one per node)")
    if (np.asarray(inertia) < 0).any() or (np.asarray(damping) <= 0).any():
        raise GridError("inertia must be >= 0 and damping > 0")
    if not math.isfinite(lag):
        raise GridError(f"lag must be finite, got {lag}")
    return omega, p


def grid_state(omega, p, *, coupling: str = "raw", lag: float = 0.0, inertia=0.0, damping=1.0) -> GridState:
    """The static indicators (module docstring) of the grid ``omega`` with injections ``p``
    (used as given: remove their mean first for a balanced grid; it only shifts ``nu``)."""
    omega, p = _check_inputs(omega, p, coupling, lag, inertia, damping)
    return _state_of(coupling_matrix(omega, coupling), p, lag, inertia, damping)


def line_indicators(
    omega,
    p,
    *,
    coupling: str = "raw",
    lag: float = 0.0,
    inertia=0.0,
    damping=1.0,
    beta: float = 1.0,
    lines=None,
    labels=None,
    skip_bridges: bool = False,
    bridge_hint: str = "pass skip_bridges=True",
    progress: bool | None = False,
    warm: bool = True,
) -> LineTable:
    """The static indicators after weakening each line (both directions) by ``beta``
    (``progress``: a bar of the lines done on stderr; None: when stderr is a terminal).

    Parameters
    ----------
    omega : ndarray (N, N)
        Symmetric line capacities ``Omega`` (raw coupling: ``W = Omega``, the power-grid case).
    p : ndarray (N,)
        Injections ``P_i``, used as given (power grids: ``P - P.mean()``, :func:`load_grid`).
    coupling : "raw" or "normalized"
        ``W = coupling_matrix(Omega)`` before and after the change.
    lag, inertia, damping
        ``alpha``, ``m`` and ``gamma`` as in :func:`antisync.physics.locked.locked_state` (numbers or
        per-node arrays; ``m_i = 0`` nodes are first order).
    beta : float
        ``Omega_ij, Omega_ji -> (1 - beta) Omega_ij``: 1 removes the line (the default), 0.5
        halves it, a negative value strengthens it. ``beta <= 1``.
    lines : list of (u, v), optional
        The lines to change, as node labels (``labels``; 0-based indices without). Default:
        every line, in node order.
    labels : sequence, optional
        Node labels in matrix order, for naming lines (default ``0..N-1``).
    skip_bridges : bool
        With ``beta = 1`` a bridge (a line whose removal splits the grid into islands) is
        refused with :class:`GridError`; with ``skip_bridges=True`` bridges are left out and
        listed in the table's ``skipped`` instead.
    bridge_hint : str
        How to leave a bridge out, ending the refusal of one (the CLI names its option).
    warm : bool
        Start each line's Newton iteration at the intact grid's locked state
        (:class:`antisync.physics.warm.LineChanges`: lossless grids, raw coupling), the
        continuation from ``P = 0`` only where that is refused; False: the continuation for every
        line. The same locked state either way (``LineTable.continued`` names the lines the
        continuation solved).

    Returns
    -------
    LineTable
        One :class:`LineIndicators` per line, the intact grid's :class:`GridState` as
        ``base``, the wall time as ``seconds``.
    """
    t0 = time.perf_counter()
    omega, p = _check_inputs(omega, p, coupling, lag, inertia, damping)
    n = omega.shape[0]
    labels = list(range(n)) if labels is None else list(labels)
    if len(labels) != n:
        raise GridError(f"labels must name the {n} nodes, got {len(labels)}")
    try:
        beta = float(beta)
    except (TypeError, ValueError):
        raise GridError(f"beta must be a number <= 1, got {beta!r}") from None
    if not (math.isfinite(beta) and beta <= 1.0):
        raise GridError(f"beta must be a finite number <= 1 (1 removes the line), got {beta}")
    todo = lines_of(omega, labels, lines)
    skipped = []
    if beta == 1.0:
        todo, skipped = split_bridges(
            omega, labels, todo, grid_bridges(omega), refuse=not skip_bridges, hint=bridge_hint
        )
    w = coupling_matrix(omega, coupling)
    intact = locked_state(w, p, lag, inertia, damping)
    base = _indicators(w, intact, lag, inertia)
    changes = None
    if warm and coupling == "raw" and intact is not None:
        changes = LineChanges(w, p, intact, lag, inertia, damping)
        changes = changes if changes.applies else None
    job = _Job(omega, p, coupling, lag, inertia, damping, beta, labels, base, changes)
    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(
        todo, unit="line", desc="lines", delay=1.0, disable=not show, file=sys.stderr, dynamic_ncols=True
    )
    rows, continued = [], []
    for a, b in bar:
        row, cont = job.row(a, b)
        rows.append(row)
        continued.append(cont)
        if cont:
            bar.set_postfix_str(f"{sum(continued)} by continuation", refresh=False)
    bar.close()
    return LineTable(
        base,
        tuple(rows),
        beta,
        tuple(skipped),
        time.perf_counter() - t0,
        tuple(labels),
        tuple(r.line for r, cont in zip(rows, continued, strict=True) if cont),
    )


@dataclass(frozen=True)
class _Job:
    """What every line's row needs: the intact grid, the change and the warm starts."""

    omega: np.ndarray
    p: np.ndarray
    coupling: str
    lag: float
    inertia: object
    damping: object
    beta: float
    labels: list
    base: GridState
    changes: LineChanges | None

    def row(self, a: int, b: int) -> tuple[LineIndicators, bool]:
        """Line ``a - b``'s row, and whether the continuation from ``P = 0`` found its state."""
        warm = None if self.changes is None else self.changes.state(a, b, 1.0 - self.beta)
        if warm is None:
            changed = self.omega.copy()
            changed[a, b] *= 1.0 - self.beta
            changed[b, a] *= 1.0 - self.beta
            st = _state_of(
                coupling_matrix(changed, self.coupling), self.p, self.lag, self.inertia, self.damping
            )
        else:
            st = _grid_state(warm.state, warm.rows, warm.cols, warm.vals, warm.lambda2)
        base = self.base
        row = LineIndicators(
            line=(self.labels[a], self.labels[b]),
            nodes=(a, b),
            beta=self.beta,
            exists=st.exists,
            stable=st.stable,
            margin=st.margin,
            max_flow=st.max_flow,
            max_load=st.max_load,
            r=st.r,
            lambda2=st.lambda2,
            **_changes(st, base),
            restores=bool(st.stable and not base.stable),
            destroys=bool(base.stable and not st.stable),
        )
        return row, warm is None


def static_table(
    grid: Grid,
    *,
    beta: float = 1.0,
    lag: float | None = None,
    skip_bridges: bool = True,
    lines=None,
    bridge_hint: str = "pass skip_bridges=True",
    progress: bool | None = False,
    warm: bool = True,
) -> LineTable:
    """:func:`line_indicators` of a :class:`Grid` (bridges skipped by default when removing);
    ``lag``: the grid's own (``model.phase_lag``) unless given; ``progress``: a bar of the lines
    done on stderr (None: when stderr is a terminal); ``warm``: as there."""
    return line_indicators(
        grid.omega,
        grid.p,
        coupling=grid.coupling,
        lag=grid.lag if lag is None else lag,
        inertia=grid.inertia,
        damping=grid.damping,
        beta=beta,
        lines=lines,
        labels=grid.labels,
        skip_bridges=skip_bridges,
        bridge_hint=bridge_hint,
        progress=progress,
        warm=warm,
    )


def _num(x: float, width: int = 9, digits: int = 4) -> str:
    x = 0.0 if abs(x) < BRAESS_TOL else x  # a saturated margin's rounding: no sign
    return f"{'-':>{width}}" if not math.isfinite(x) else f"{x:+{width}.{digits}f}"


def format_table(table: LineTable, top: int | None = None, by: str = "d_margin") -> str:
    """A markdown table of ``table`` ranked by ``by`` (:meth:`LineTable.ranked`), the first
    ``top`` rows (all: None), after a line with the intact grid's values. The Braess column
    marks :meth:`LineTable.braess_lines` with the same margin (``by`` if it is ``d_lambda2``)."""
    b = table.base
    skipped = ""
    if table.skipped:
        skipped = f" ({len(table.skipped)} bridges skipped: {listed(table.skipped)})"
    head = (
        f"intact: stable={b.stable} margin={b.margin:.4f} lambda2={b.lambda2:.4f} "
        f"max_flow={b.max_flow:.4f} max_load={b.max_load:.4f} (line {table.name(b.max_load_line)}) "
        f"r={b.r:.4f}; "
        f"beta={table.beta:g}; {len(table)} lines{skipped}; {table.seconds:.2f} s"
    )
    margin = "d_lambda2" if by == "d_lambda2" else "d_margin"
    braess = {r.line for r in table.braess_lines(margin=margin)}
    lines = [
        head,
        "",
        "| line | state | margin | d margin | d lambda2 | max load | d max load | d max flow "
        "| d r | Braess |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rows = table.ranked(by)
    for r in rows if top is None else rows[:top]:
        state = "stable" if r.stable else ("unstable" if r.exists else "none")
        lines.append(
            f"| {r.label} | {state} | {_num(r.margin)} | {_num(r.d_margin)} "
            f"| {_num(r.d_lambda2)} | {_num(r.max_load)} | {_num(r.d_max_load)} "
            f"| {_num(r.d_max_flow)} | {_num(r.d_r)} | {'yes' if r.line in braess else ''} |"
        )
    return "\n".join(lines)
