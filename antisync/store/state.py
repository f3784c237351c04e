"""A job's results in memory: block records, histograms and kept pairs, merged chunk by chunk.

:class:`JobState` is what a run accumulates and what a checkpoint writes
(:mod:`antisync.store.layout`); journal chunks (:mod:`antisync.store.journal`) are merged into
it, never twice.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from antisync.errors import StoreError
from antisync.plan.jobs import Chunk, Job
from antisync.stats import estimators

__all__ = ["ChunkResult", "JobState"]


@dataclass
class ChunkResult:
    """Partial statistics of one chunk; every field merges by addition or by block position.

    Attributes
    ----------
    rec, rec0 : block records (see :func:`antisync.stats.estimators.block_records`)
    tail : int64 (V, TAIL_BINS)
    hist : int64 (len(job.hist_variants), bins, bins)
    lam_rec, lam_tail : Lambda block records and signed Lambda tail counts per edge
    kept : dict of arrays or None
        Per-realization steps and status for realizations below ``keep_pairs``.
    """

    chunk: Chunk
    rec: np.ndarray
    rec0: np.ndarray
    tail: np.ndarray
    hist: np.ndarray
    lam_rec: np.ndarray
    lam_tail: np.ndarray
    kept: dict | None
    first: int
    count: int
    seconds: float
    backend: str


class JobState:
    """Everything known so far about one job: block records, histograms, kept pairs."""

    def __init__(self, job: Job):
        self.job = job
        nb, nv = job.n_blocks, len(job.variant_edge)
        self.rec = np.zeros((nb, nv, len(estimators.BLOCK_FIELDS)))
        self.rec0 = np.zeros((nb, len(estimators.TAU0_FIELDS)))
        self.done = np.zeros(nb, dtype=bool)
        self.tail = np.zeros((nv, estimators.TAIL_BINS), dtype=np.int64)
        ne = len(job.edges)
        self.lam_rec = np.zeros((nb, ne, len(estimators.LAMBDA_FIELDS)))
        self.lam_tail = np.zeros((ne, estimators.LAMBDA_TAIL_BINS), dtype=np.int64)
        bins = job.config.histogram.bins
        self.hist = np.zeros((len(job.hist_variants), bins, bins), dtype=np.int64)
        keep = min(job.config.keep_pairs, job.realizations)
        self.kept = {
            "status0": np.full(keep, -1, dtype=np.int8),
            "steps0": np.zeros(keep, dtype=np.int64),
            "status": np.full((keep, nv), -1, dtype=np.int8),
            "steps": np.zeros((keep, nv), dtype=np.int64),
            "lambda": np.zeros((keep, ne)),
        }
        self.seconds = 0.0
        self.backends: set[str] = set()
        self.measures: dict | None = None  # Lambda^(linear, xi2, RW): see measures.pipeline
        self.measures_seconds = 0.0

    def add(self, res: ChunkResult) -> None:
        """Merge a chunk; a chunk whose blocks are already done is an error, never added twice."""
        sl = slice(res.chunk.first_block, res.chunk.first_block + res.chunk.n_blocks)
        if self.done[sl].any():
            raise StoreError(f"chunk at block {res.chunk.first_block} of {self.job.name} was already merged")
        self.rec[sl] = res.rec
        self.rec0[sl] = res.rec0
        self.tail += res.tail
        self.hist += res.hist
        self.lam_rec[sl] = res.lam_rec
        self.lam_tail += res.lam_tail
        if res.kept is not None:
            k = res.kept["status0"].size
            for key, arr in res.kept.items():
                self.kept[key][res.first : res.first + k] = arr
        self.done[sl] = True
        self.seconds += res.seconds
        self.backends.add(res.backend)

    def pending(self, chunks: list[Chunk]) -> list[Chunk]:
        """The chunks none of whose blocks are done (a chunk is all done or all pending)."""
        out = []
        for c in chunks:
            sl = self.done[c.first_block : c.first_block + c.n_blocks]
            if sl.all():
                continue
            if sl.any():
                # chunk boundaries moved since the interrupted run: redo per block
                out.extend(
                    Chunk(b, 1) for b in range(c.first_block, c.first_block + c.n_blocks) if not self.done[b]
                )
            else:
                out.append(c)
        return out

    def truncated(self, realizations: int) -> JobState:
        """This state as a run of the first ``realizations`` would hold it (the stopping rule).

        Only whole, done blocks are kept, and nothing beyond them may have been merged: tail
        counts and histograms are sums over every merged chunk.
        """
        job = self.job
        nb = -(-realizations // job.block_size)
        if realizations % job.block_size and realizations != job.realizations:
            raise ValueError(f"{realizations} realizations is not a whole number of blocks")
        if not self.done[:nb].all() or self.done[nb:].any():
            raise StoreError(
                f"{job.name}: cannot cut at {realizations:,} realizations: a block before it "
                "is missing or one after it was merged"
            )
        out = JobState(replace(job, config=replace(job.config, realizations=realizations)))
        out.rec[...] = self.rec[:nb]
        out.rec0[...] = self.rec0[:nb]
        out.lam_rec[...] = self.lam_rec[:nb]
        out.done[...] = True
        out.tail[...] = self.tail
        out.lam_tail[...] = self.lam_tail
        out.hist[...] = self.hist
        for key, arr in out.kept.items():
            arr[...] = self.kept[key][: arr.shape[0]]
        out.seconds = self.seconds
        out.backends = set(self.backends)
        out.measures = self.measures
        out.measures_seconds = self.measures_seconds
        return out

    @property
    def realizations_done(self) -> int:
        b = self.job.block_size
        total = self.job.realizations
        return int(sum(min(b, total - i * b) for i in np.flatnonzero(self.done)))

    @property
    def complete(self) -> bool:
        return bool(self.done.all())
