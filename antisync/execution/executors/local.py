"""Local executor: chunks one after another in this process, realizations in parallel threads."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from antisync.execution.compute import ChunkResult, compute_chunk
from antisync.plan.jobs import Chunk, Job

__all__ = ["LocalExecutor"]


class LocalExecutor:
    """Runs :func:`~antisync.execution.compute.compute_chunk` in-process (numba ``prange`` threads)."""

    name = "local"

    def __init__(self, backend: str = "cpu", threads: int | None = None):
        self.backend = backend
        self.threads = threads

    def run(self, work: Iterable[tuple[Job, Chunk]]) -> Iterator[tuple[Job, ChunkResult]]:
        for job, chunk in work:
            yield job, compute_chunk(job, chunk, self.backend, self.threads)

    def describe(self) -> str:
        return f"local executor, {self.threads or 'all'} threads"

    def close(self) -> None:
        """Nothing to release (the interface of every executor: its creator closes it)."""
