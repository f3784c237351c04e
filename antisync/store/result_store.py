"""One output file as a run or a sweep writes it: its lock, its journal and its checkpoints.

:class:`ResultStore` ties together the writer lock (:mod:`antisync.store.lock`), the journal
of finished chunks (:mod:`antisync.store.journal`) and the HDF5 file
(:mod:`antisync.store.layout`). Every ``checkpoint_seconds`` and at the end, the whole HDF5
file is rewritten from memory into a temporary file and atomically renamed over the old one;
then the journal's chunk files it now contains are deleted.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from pathlib import Path

from antisync.compute import ChunkResult
from antisync.errors import StoreError
from antisync.jobs import Job
from antisync.store import journal as _journal
from antisync.store.layout import is_complete, read_states, result_file_problem, stopped_early, write_results
from antisync.store.lock import OutputLock
from antisync.store.state import JobState

__all__ = ["ResultStore"]


class ResultStore:
    """One HDF5 result file, its journal of finished chunks and its writer lock.

    Writing goes: :meth:`lock` (which first runs :meth:`check_target`), :meth:`prepare`,
    :meth:`load_states` (on resume), :meth:`start_journal`, :meth:`save_chunk` per chunk and
    :meth:`checkpoint`; after a failure :meth:`discard_unfinished` removes what holds no
    finished work.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.journal = self.path.with_name(self.path.name + ".partial")
        self.lock_path = self.path.with_name(self.path.name + ".lock")
        self.tmp_path = self.path.with_name(self.path.name + ".tmp")
        self._lock = OutputLock(self.path, self.journal, self.lock_path)

    # ---- checks and the lock ---------------------------------------------------------------
    def check_target(self) -> None:
        """Refuse an output path antisync must not write, before anything is created
        (see :meth:`~antisync.store.lock.OutputLock.check_target`)."""
        self._lock.check_target()

    def lock(self, *, read_only_ok: bool = False) -> contextlib.AbstractContextManager[bool]:
        """Hold the exclusive writer lock of this output for the ``with`` block.

        The lock is an ``flock`` on ``<output>.lock``, which holds JSON ``{pid, host, started,
        command}`` naming the holder; see :meth:`~antisync.store.lock.OutputLock.hold`.
        Reentrant within one thread: a sweep holds it across the ``run_jobs`` calls of its
        stages.

        Parameters
        ----------
        read_only_ok : bool
            When the folder does not allow creating the lock file (read-only), yield False
            instead of raising: nothing may then be written, but a ``--resume`` can still
            find the file complete and leave it alone.

        Returns
        -------
        context manager yielding bool
            True when the lock is held and the output may be written.

        Raises
        ------
        StoreError
            On entering: another process (or another thread of this one) holds the lock (the
            message names its pid, host, start time and command), or the path is refused by
            :meth:`check_target`.
        """
        return self._lock.hold(read_only_ok=read_only_ok)

    # ---- opening -------------------------------------------------------------------------
    def prepare(self, *, resume: bool, overwrite: bool) -> None:
        """Check the output can be written as asked; nothing is modified unless ``overwrite``.

        Call it under :meth:`lock`. ``overwrite`` deletes only an antisync result file (a run's
        or a sweep's) and its journal; anything else is refused, untouched.
        """
        exists = self.path.exists() or self.journal.exists()
        if exists and not (resume or overwrite):
            raise StoreError(
                f"{self.path} already exists (or an interrupted run left {self.journal.name}); "
                "pass --resume to finish it, --overwrite to replace it, or --out for a new file"
            )
        if overwrite and not resume:
            if self.path.exists():
                self._check_replaceable()
            # every check passed: only now is anything deleted
            if self.path.exists():
                self.path.unlink()
            if self.journal.exists():
                shutil.rmtree(self.journal)
        if self.tmp_path.is_file() and not self.tmp_path.is_symlink():
            # a checkpoint cut off by a kill; under the lock it is nobody's work in progress
            with contextlib.suppress(OSError):
                self.tmp_path.unlink()

    def _check_replaceable(self) -> None:
        what = result_file_problem(self.path)
        if what is not None:
            raise StoreError(
                f"--overwrite replaces only antisync result files, and {self.path} is {what}; "
                "move it away or use --out for another file"
            )

    def file_complete(self) -> bool:
        """Whether the output file exists and says every job (every stage of a sweep) finished."""
        return is_complete(self.path)

    def stopped_early(self, config_key: dict) -> dict | None:
        """The stopping rule's record when the output is a complete run of ``config_key`` that
        its rule ended before the budget (see :func:`~antisync.store.layout.stopped_early`)."""
        return stopped_early(self.path, json.loads(json.dumps(config_key)))

    def load_states(self, jobs: list[Job], config_key: dict) -> dict[str, JobState]:
        """States for ``jobs``: from the HDF5 file when present, plus journal chunks.

        A job group made from another graph (see :func:`~antisync.store.journal.graph_digest`)
        is an error; a journal chunk that is damaged or tagged for another run is deleted, its
        blocks computed again.
        """
        states = {job.name: JobState(job) for job in jobs}
        wanted = json.loads(json.dumps(config_key))
        if self.path.exists():
            read_states(self.path, states, wanted)
        else:
            stored = _journal.stored_key(self.journal)
            if stored is not None and stored != wanted:
                raise StoreError(f"{self.journal} holds chunks of a different config; remove it or use --out")
        for st in states.values():
            for res in _journal.chunks(self.journal, st, _journal.chunk_tag(st.job, config_key)):
                sl = slice(res.chunk.first_block, res.chunk.first_block + res.chunk.n_blocks)
                if not st.done[sl].any():
                    st.add(res)
        return states

    # ---- writing -------------------------------------------------------------------------
    def start_journal(self, config_key: dict) -> None:
        """Create the journal folder and record ``config_key`` in it."""
        _journal.start(self.journal, config_key)

    def save_chunk(self, name: str, res: ChunkResult, tag: str = "") -> None:
        """Persist a finished chunk at once (atomic rename), before it is merged.

        ``tag`` is :func:`~antisync.store.journal.chunk_tag` of the chunk's job and run key: on
        resume, a chunk whose tag differs from the job's is never merged (so an untagged one
        never is).
        """
        _journal.save_chunk(self.journal, name, res, tag)

    def load_screens(self) -> list[dict]:
        """A sweep's screening results saved in the journal (see :meth:`save_screen`)."""
        return _journal.load_screens(self.journal)

    def save_screen(self, graph: str, result: dict) -> None:
        """Save the screening of ``graph`` in the journal at once (atomic rename)."""
        _journal.save_screen(self.journal, graph, result)

    def checkpoint(
        self, states: dict[str, JobState], provenance: dict, *, final: bool = False, extra=None
    ) -> None:
        """Rewrite the HDF5 file from ``states`` atomically, then drop merged journal chunks.

        ``provenance`` keys beyond the standard ones become root attributes too; ``extra``, when
        given, is called as ``extra(h5file, states)`` before the file is closed, to add groups
        (a sweep's screening and symmetry data) that must survive every checkpoint.
        """
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.tmp_path
        try:
            write_results(tmp, states, provenance, extra)
            os.replace(tmp, self.path)
        except BaseException:
            # the old file (if any) is intact; a half-written temporary file is of no use
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        if self.journal.exists():
            _journal.drop_chunks(self.journal)
            if final:
                shutil.rmtree(self.journal, ignore_errors=True)

    def discard_unfinished(self) -> None:
        """After a failure: remove what holds no finished work, so that the same command can be
        run again as it was (no ``--resume`` needed for a run that saved nothing).

        Removed: the temporary HDF5 file and a journal holding no chunk and no screening
        result (only its ``simulation_key.json``). Call it under :meth:`lock`, which removes
        the lock file and the folders it made for an output that was never written.
        """
        with contextlib.suppress(OSError):
            if self.tmp_path.is_file() and not self.tmp_path.is_symlink():
                self.tmp_path.unlink()
        if self.journal.is_dir() and not self.journal.is_symlink() and _journal.is_empty(self.journal):
            shutil.rmtree(self.journal, ignore_errors=True)

    def drop_journal(self) -> None:
        """Remove the journal of a complete file (a kill between the last checkpoint and the
        journal's removal leaves one; every block it holds is in the file). Under :meth:`lock`."""
        if self.journal.is_dir() and not self.journal.is_symlink():
            shutil.rmtree(self.journal, ignore_errors=True)
