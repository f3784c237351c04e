"""The stopping rule (``stop:``, docs/stopping.md): spend realizations until every sign is known.

A run with ``stop.when: signs-resolved`` treats ``realizations`` as a budget. The runner
integrates the realizations up to each of :attr:`~antisync.plan.config.Config.stop_looks` in turn
(``first_look``, twice as many, four times ..., the budget) and, after each, calls
:func:`take_look`: every link's Lambda^KM interval from the realizations so far, at the level
:func:`look_level`. The run ends at the first look where each link is

- *resolved*: its interval excludes 0 (antifragile or fragile) and does not rest on fewer
  than ten values of the tail (the summary's heavy-tail warning: there the interval's
  coverage is the least sure, so the rule waits for more), or
- *settled*: its interval lies inside ``[-tolerance, tolerance]`` (with tolerance 0: a link
  whose damage changes nothing, every value exactly 0).

The looks come in order over a prefix of the realizations, whose phases do not depend on how
many there will be, so a run that stops at ``n`` holds exactly the numbers of a plain run of
``n`` (:meth:`~antisync.store.JobState.truncated`; tested). Bonferroni over the looks keeps
the chance of a false sign at any look within the records' 5%: each look's interval has
level ``1 - 0.05 / looks``.

Example
-------
>>> from antisync.plan.config import load_config_text
>>> cfg = load_config_text('''
... graph: {kind: lollipop, nodes: 6, path: 3}
... realizations: 64000
... block_size: 100
... stop: {when: signs-resolved, first_look: 2000}
... ''')
>>> cfg.stop_looks
[2000, 4000, 8000, 16000, 32000, 64000]
>>> round(look_level(len(cfg.stop_looks)), 4)
0.9917
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from antisync.stats.summary import CI_LEVEL, lambda_intervals
from antisync.store import JobState, state_view

__all__ = ["Look", "already_stopped", "look_level", "stop_note", "take_look"]


def look_level(looks: int) -> float:
    """The interval level of each of ``looks`` looks: ``1 - (1 - 0.95) / looks``."""
    return 1.0 - (1.0 - CI_LEVEL) / max(1, looks)


@dataclass(frozen=True)
class Look:
    """What one look saw: how many links are resolved, settled and still open."""

    realizations: int
    level: float
    tolerance: float
    links: int
    resolved: int
    settled: int
    unresolved: tuple[str, ...]

    @property
    def all_known(self) -> bool:
        """Every link resolved or settled: the rule stops here."""
        return not self.unresolved

    def describe(self, budget: int) -> str:
        """One line for the run's log."""
        where = f"{self.realizations:,} of {budget:,} realizations"
        known = f"{self.resolved} of {self.links} link signs resolved at {self.level:.2%}"
        if self.settled:
            known += f", {self.settled} {_settled_words(self.tolerance)}"
        if self.all_known:
            return f"stop: {known} after {where}: stopping"
        shown = ", ".join(self.unresolved[:8]) + (" ..." if len(self.unresolved) > 8 else "")
        return f"stop: {known} after {where}; open: {shown}"

    def to_dict(self) -> dict:
        return {
            "realizations": self.realizations,
            "level": self.level,
            "tolerance": self.tolerance,
            "links": self.links,
            "resolved": self.resolved,
            "settled": self.settled,
            "unresolved": list(self.unresolved),
        }


def take_look(states: Mapping[str, JobState], realizations: int, level: float, tolerance: float) -> Look:
    """Every link's interval at ``level`` from the first ``realizations`` of each job.

    Every job's blocks up to ``realizations`` must be done and none beyond merged
    (:meth:`JobState.truncated` checks); jobs that integrate nothing are left out.
    """
    unresolved: list[str] = []
    links = resolved = settled = 0
    kuramoto = [st for st in states.values() if st.job.kuramoto]
    for st in kuramoto:
        view = state_view(st.truncated(realizations))
        ci, thin = lambda_intervals(view, level)
        for label, (low, high), few in zip(view.edges, ci, thin, strict=True):
            links += 1
            if (low > 0 or high < 0) and not few:
                resolved += 1
            elif -tolerance <= low and high <= tolerance:
                settled += 1
            else:  # NaN (no synchronized realization yet) lands here too
                unresolved.append(f"{st.job.name}:{label}" if len(kuramoto) > 1 else label)
    return Look(realizations, level, tolerance, links, resolved, settled, tuple(unresolved))


def _settled_words(tolerance: float) -> str:
    return f"within +-{tolerance:g}" if tolerance > 0 else "neutral (every value 0)"


def stop_note(record: dict | None, what: str = "run") -> str | None:
    """One line on what the stopping rule did (``record``: :func:`antisync.store.stop_record`),
    for the end of ``antisync summary``; None for a file without a rule. ``what``: ``"run"``,
    or ``"sweep"`` (the rule ended its main stage: every job at once)."""
    if not record:
        return None
    look = record["last_look"]
    n, budget = record["stopped_at"], record["budget"]
    known = f"{look['resolved']} of {look['links']} link signs resolved at {look['level']:.2%}"
    if look["settled"]:
        known += f", {look['settled']} {_settled_words(record['tolerance'])}"
    if record["stopped_early"]:
        return f"stop: the rule ended the {what} at {n:,} of {budget:,} realizations ({known})"
    if not look["unresolved"]:
        return f"stop: {known} only at the budget's {budget:,} realizations"
    shown = ", ".join(look["unresolved"][:8]) + (" ..." if len(look["unresolved"]) > 8 else "")
    return f"stop: the budget of {budget:,} realizations is spent with {known}; open: {shown}"


def already_stopped(path, record: dict) -> str:
    """The line ``--resume`` says on a file its stopping rule ended (``record``:
    :meth:`antisync.store.ResultStore.stopped_early`): nothing is left to run."""
    return (
        f"{path} is already complete: the stopping rule ended it at "
        f"{record['stopped_at']:,} of {record['budget']:,} realizations; nothing to do"
    )
