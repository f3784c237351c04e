"""The result of a dynamic line removal: one :class:`LineRemoval` per line (the paired change of
``P_sync`` with its exact intervals and McNemar's test, the change of tau) and the
:class:`RemovalTable` of them with its rankings (module :mod:`antisync.grids.removal`,
docs/power_grids.md).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from antisync.execution.step_check import step_check_line
from antisync.grids.errors import GridError
from antisync.grids.lines import Rows, listed
from antisync.stats.exact import clopper_pearson, mcnemar_exact, tau_p_value
from antisync.stats.multiplicity import FDR_LEVEL, benjamini_hochberg
from antisync.status import ALREADY_SYNCED, GAVE_UP, SYNCED

__all__ = ["LineRemoval", "RemovalTable", "audit_line", "line_rows"]


def _mean_se(x: np.ndarray) -> tuple[float, float]:
    if x.size == 0:
        return math.nan, math.nan
    se = float(x.std(ddof=1) / math.sqrt(x.size)) if x.size > 1 else math.nan
    return float(x.mean()), se


@dataclass(frozen=True)
class LineRemoval:
    """One line's paired response to its removal (or weakening by ``beta``), module docstring.

    ``line``: the end nodes' labels; ``n``: realizations; ``synced_before`` / ``synced_after``:
    counts (SYNCED or ALREADY_SYNCED) with ``p_before`` / ``p_after`` and their Clopper-Pearson
    intervals; ``lost`` / ``gained`` with the intervals of ``lost / n`` and ``gained / n``;
    ``d_psync`` (the basin-stability change), McNemar's exact ``p_value`` and conditional
    interval ``d_psync_ci``; ``both``: pairs SYNCED both times, ``d_tau`` / ``d_tau_se`` and
    ``ratio`` / ``ratio_se`` (``tau0 / tau``) over them; ``islanding``: the line is a bridge
    removed anyway (``islanding=True``); ``gave_up``: realizations stopped early after the
    change by ``sync.give_up`` (status GAVE_UP, among the not synchronized).
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
    gave_up: int = 0

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
    audit: dict | None = None
    """``sync.give_up``'s pilot and audit (:func:`antisync.grids.removal.line_removal`): the
    given-up trajectories sampled and integrated to ``t_max`` without the rule, how many of them
    locked, how many were integrated again, and the 95% upper bound of the share of the others
    that would lock (``bound95``, 3 / sampled when none did); None without the rule."""
    step_check: dict | None = None
    """The step check (:mod:`antisync.execution.step_check`): the intact grid's first starts
    integrated again at ``dt / 2`` (Euler, RK4) or at ten times finer tolerances (Rodas4), how
    many changed status and the largest change of ``tau``; None for tables written before it."""

    @property
    def n(self) -> int:
        return int(self.status0.size)

    @property
    def synced0(self) -> int:
        return int(np.isin(self.status0, (SYNCED, ALREADY_SYNCED)).sum())

    @property
    def gave_up0(self) -> int:
        """The intact grid's realizations stopped early by ``sync.give_up`` (status GAVE_UP)."""
        return int((self.status0 == GAVE_UP).sum())

    @property
    def gave_up(self) -> int:
        """The trajectories after the lines' changes stopped early by ``sync.give_up``."""
        return int((self.status == GAVE_UP).sum())

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

    @property
    def starts(self) -> str:
        """Where the realizations start, in words: the paper's uniform phases, or within
        ``model.start.width`` of the intact grid's operating point (docs/models.md)."""
        start = (self.config.get("model") or {}).get("start")
        if not start:
            return "uniform random phases"
        return f"phases within {start['width']:g} rad of the operating point"

    def summary(self) -> dict:
        """The intact grid's numbers and the run's, as plain data."""
        t, se = self.tau0_mean
        return {
            "name": self.name,
            "beta": self.beta,
            "seed": self.seed,
            "realizations": self.n,
            "starts": self.starts,
            "synced0": self.synced0,
            "gave_up0": self.gave_up0,
            "gave_up": self.gave_up,
            "give_up_audit": self.audit,
            "step_check": self.step_check,
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
            skipped = f"; bridges skipped: {listed(self.skipped)}"
        head = (
            f"{self.name}: beta={self.beta:g}, {self.n} realizations (seed {self.seed}; "
            f"{self.starts}): intact "
            f"P_sync = {self.p_sync:.4f} [{lo:.4f}, {hi:.4f}], tau0 = {t:.3f} +- {se:.3f}; "
            f"{len(self.rows)} lines{skipped}; {self.seconds:.1f} s"
        )
        if self.gave_up0 or self.gave_up:
            rule = (self.config.get("sync") or {}).get("give_up") or {}
            head += (
                f"; stopped by sync.give_up (deviation never below {rule.get('band', '?')} rad/s by "
                f"t = {rule.get('after', '?')} s, counted as not synchronized): {self.gave_up0} intact, "
                f"{self.gave_up} after the changes"
            )
        if self.audit is not None:
            head += f"; {audit_line(self.audit)}"
        if self.step_check is not None:
            head += f"; {step_check_line(self.step_check)}"
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


def line_rows(
    todo: list[tuple[int, int]],
    labels: list,
    bridges: set,
    beta: float,
    status0: np.ndarray,
    tau0: np.ndarray,
    status: np.ndarray,
    tau: np.ndarray,
    level: float = 0.95,
) -> list[LineRemoval]:
    """One :class:`LineRemoval` per line of ``todo`` (0-based ends, named by ``labels``) from the
    paired outcomes: the intact grid's ``status0`` / ``tau0`` (``(M,)``) and each line's
    ``status`` / ``tau`` (``(M, L)``, column ``v`` the line ``todo[v]``); ``bridges``: the lines
    removed although they island the grid (their rows marked ``islanding``)."""
    m = status0.size
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
                gave_up=int((status[:, v] == GAVE_UP).sum()),
            )
        )
    return rows


def audit_line(audit: dict) -> str:
    """One line on ``sync.give_up``'s pilot and audit (a removal table's ``audit``)."""
    pilot = audit.get("pilot", "every intact start that locks was inside the band early enough")
    text = (
        f"sync.give_up checked: pilot passed ({pilot}); audit integrated {audit['sampled']} "
        f"given-up trajectories to t_max without the rule, {audit['locked']} locked"
    )
    if audit["locked"]:
        rerun = audit["rerun"]
        return text + f", so the tasks holding them were integrated again without it ({rerun} trajectories)"
    bound = audit.get("bound95")
    if isinstance(bound, int | float) and not isinstance(bound, bool):
        text += f" (95% bound on the share of the others that would lock: {bound:.2g})"
    return text
