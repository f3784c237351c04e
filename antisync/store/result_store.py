"""One output file as a run or a sweep writes it: its lock, its journal and its checkpoints.

:class:`ResultStore` ties together the writer lock (:mod:`antisync.store.lock`), the journal
of finished chunks (:mod:`antisync.store.journal`) and the HDF5 file
(:mod:`antisync.store.layout`). Every ``checkpoint_seconds`` and at the end, the whole HDF5
file is rewritten from memory into a temporary file and atomically renamed over the old one;
then the journal's chunk files it now contains are deleted.

``--overwrite`` never deletes the file it replaces: the old file stays where it is, readable and
whole, until its successor is complete. Until then the successor's checkpoints go to
``<output>.partial/replacement.h5`` (next to the marker ``replaces``), and the completing
checkpoint renames it over the old file in one atomic step. A refused, failed or interrupted
``--overwrite`` therefore leaves the old file byte for byte; ``--resume`` finishes an
interrupted replacement, and another ``--overwrite`` starts it again.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from pathlib import Path

from antisync.errors import StoreError
from antisync.plan.jobs import Job
from antisync.store import journal as _journal
from antisync.store.journal import REPLACEMENT_FILE, REPLACES_FILE
from antisync.store.layout import (
    config_changes,
    is_complete,
    read_states,
    result_file_problem,
    stopped_early,
    write_results,
)
from antisync.store.lock import OutputLock
from antisync.store.state import ChunkResult, JobState

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
        # set by prepare(overwrite=True): start_journal then clears what the old run left
        self._fresh = False

    @property
    def replacing(self) -> bool:
        """Whether this output's run replaces an existing file that stays until it is complete
        (``--overwrite``; the journal holds the marker, so every store of the path agrees)."""
        return (self.journal / REPLACES_FILE).is_file()

    @property
    def current(self) -> Path:
        """The file that holds this run's latest checkpoint: :attr:`path`, or while replacing
        an existing file, the journal's ``replacement.h5``."""
        return self.journal / REPLACEMENT_FILE if self.replacing else self.path

    # ---- checks and the lock ---------------------------------------------------------------
    def check_target(self) -> None:
        """Refuse an output path antisync must not write, before anything is created
        (see :meth:`~antisync.store.lock.OutputLock.check_target`)."""
        self._lock.check_target()

    def lock(self, *, read_only_ok: bool = False) -> contextlib.AbstractContextManager[bool]:
        """Hold the exclusive writer lock of this output for the ``with`` block: a context
        manager yielding True when the output may be written (False with ``read_only_ok`` in a
        read-only folder). The lock, its reentrance and its errors are
        :meth:`~antisync.store.lock.OutputLock.hold`'s (this output's path checked first)."""
        return self._lock.hold(read_only_ok=read_only_ok)

    # ---- opening -------------------------------------------------------------------------
    def prepare(self, *, resume: bool, overwrite: bool) -> None:
        """Check the output can be written as asked; nothing existing is modified here.

        Call it under :meth:`lock`. ``overwrite`` replaces only an antisync result file (a run's
        or a sweep's); anything else is refused, untouched. The file it replaces stays in place
        until the new run is complete, and the old run's journal is cleared only when the new
        run starts its own (:meth:`start_journal`), after every refusal.
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
            self._fresh = True
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
        """Whether the output file exists and says every job (every stage of a sweep) finished
        (while replacing: whether the replacement does)."""
        return is_complete(self.current)

    def stopped_early(self, config_key: dict) -> dict | None:
        """The stopping rule's record when the output is a complete run of ``config_key`` that
        its rule ended before the budget (see :func:`~antisync.store.layout.stopped_early`)."""
        return stopped_early(self.current, json.loads(json.dumps(config_key)))

    def load_states(self, jobs: list[Job], config_key: dict) -> dict[str, JobState]:
        """States for ``jobs``: from the HDF5 file when present, plus journal chunks.

        A job group made from another graph (see :func:`~antisync.store.journal.graph_digest`)
        is an error; a journal chunk that is damaged or tagged for another run is deleted, its
        blocks computed again.
        """
        states = {job.name: JobState(job) for job in jobs}
        wanted = json.loads(json.dumps(config_key))
        if self.current.exists():
            read_states(self.current, states, wanted)
        else:
            stored = _journal.stored_key(self.journal)
            if stored is not None and stored != wanted:
                raise StoreError(
                    f"{self.journal} holds chunks of a different config ({config_changes(stored, wanted)}); "
                    "remove it or use --out"
                )
        for st in states.values():
            for res in _journal.chunks(self.journal, st, _journal.chunk_tag(st.job, config_key)):
                sl = slice(res.chunk.first_block, res.chunk.first_block + res.chunk.n_blocks)
                if not st.done[sl].any():
                    st.add(res)
        return states

    # ---- writing -------------------------------------------------------------------------
    def start_journal(self, config_key: dict) -> None:
        """Create the journal folder and record ``config_key`` in it.

        After ``prepare(overwrite=True)`` this is where the old run's journal goes (every
        refusal has happened by now) and, when a result file exists, the marker that sends
        the checkpoints to the replacement until it is complete.
        """
        if self._fresh:
            if self.journal.is_dir() and not self.journal.is_symlink():
                shutil.rmtree(self.journal)
            _journal.start(self.journal, config_key)
            if self.path.exists():
                (self.journal / REPLACES_FILE).write_text(f"{self.path.name}\n")
            self._fresh = False
            return
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
        replacing = self.replacing
        try:
            write_results(tmp, states, provenance, extra)
            # a replacement takes the old file's place only once it is complete
            promote = not replacing or is_complete(tmp)
            os.replace(tmp, self.path if promote else self.journal / REPLACEMENT_FILE)
        except BaseException:
            # the old file (if any) is intact; a half-written temporary file is of no use
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        if replacing and promote:
            for name in (REPLACEMENT_FILE, REPLACES_FILE):
                with contextlib.suppress(OSError):
                    (self.journal / name).unlink()
        if self.journal.exists():
            _journal.drop_chunks(self.journal)
            if final and not self.replacing:
                # a sweep stage's final checkpoint may precede its top stage: an unfinished
                # replacement keeps its journal (marker and checkpoint) until it is complete
                shutil.rmtree(self.journal, ignore_errors=True)

    def discard_unfinished(self, *, refused: bool = False) -> None:
        """After a failure: remove what holds no finished work, so that the same command can be
        run again as it was (no ``--resume`` needed for a run that saved nothing).

        Removed: the temporary HDF5 file and a journal holding no chunk and no screening
        result (only its ``simulation_key.json``). Call it under :meth:`lock`, which removes
        the lock file and the folders it made for an output that was never written.

        Parameters
        ----------
        refused : bool
            The failure was a refusal of the command as given (a sweep whose screening excluded
            every graph): its screening results serve no corrected command (another config is
            another key), so a journal holding nothing else goes too.
        """
        with contextlib.suppress(OSError):
            if self.tmp_path.is_file() and not self.tmp_path.is_symlink():
                self.tmp_path.unlink()
        if not self.journal.is_dir() or self.journal.is_symlink():
            return
        if refused and _journal.foreign_entry(self.journal) is None:
            shutil.rmtree(self.journal / _journal.SCREEN_FOLDER, ignore_errors=True)
        if _journal.is_empty(self.journal):
            shutil.rmtree(self.journal, ignore_errors=True)

    def drop_journal(self) -> None:
        """Remove the journal of a complete file (a kill between the last checkpoint and the
        journal's removal leaves one; every block it holds is in the file). Under :meth:`lock`."""
        if self.journal.is_dir() and not self.journal.is_symlink():
            shutil.rmtree(self.journal, ignore_errors=True)
