"""Executors: where a run's chunks are computed. Every one satisfies :class:`Executor`.

- :class:`~antisync.execution.executors.local.LocalExecutor`: in this process (numba threads);
- :class:`~antisync.execution.executors.dask.DaskExecutor`: on a Dask cluster (docs/dask.md).

Work that is not a run's chunks (a grid's line removal) maps its own pure function over its
tasks with :func:`antisync.execution.executors.tasks.map_tasks`, here or on a client.

Whoever creates an executor closes it: :func:`antisync.execution.runner.run_jobs` closes only the local
executor it makes itself, and an executor handed to it (a sweep hands one to every stage)
stays open.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from antisync.execution.compute import ChunkResult
    from antisync.plan.jobs import Chunk, Job

__all__ = ["Executor"]


@runtime_checkable
class Executor(Protocol):
    """What the runner needs from an executor."""

    def run(self, work: Iterable[tuple[Job, Chunk]]) -> Iterator[tuple[Job, ChunkResult]]:
        """Compute every ``(job, chunk)`` and yield ``(job, result)`` as results arrive (in any
        order; the runner merges them by block position)."""
        ...

    def describe(self) -> str:
        """One line for the log: where and with how many workers/threads."""
        ...

    def close(self) -> None:
        """Release what the executor owns (a cluster it started); called by its creator."""
        ...
