"""HDF5 result files: layout, crash-safe checkpoints, resume and provenance.

Layout (one file per run or sweep)::

    /                      attrs: format="antisync-results", format_version, antisync_version,
                                  git_revision, command, created, config_yaml, complete
    /jobs/<name>/          one group per graph (``lollipop6``, ``G105``, ...)
        attrs:             graph, nodes (JSON), edges (JSON), betas, dbeta, seed, backend,
                           block_size, realizations, realizations_done, seconds, complete,
                           tau0 status counts, summary_json
        omega              (N, N) weights
        variant_edge       (V,) index into edges          variant_beta  (V,) damage
        blocks_done        (n_blocks,) bool               hist_variants (H,) variant indices
        block_records      (n_blocks, V, 7)  n, n_already, n_not_synced, sum d, sum d^2,
                                             sum tau, sum tau^2  (d = F - 1)
        tau0_records       (n_blocks, 5)     n, n_already, n_not_synced, sum tau0, sum tau0^2
        tail_counts        (V, bins) int64   log histogram of |F - 1|
        lambda_records     (n_blocks, E, 6)  n, n_already, n_not_synced, sum L, sum L^2, n_flagged
                                             of the per-realization Lambda estimates (attr
                                             lambda_method says which estimator)
        lambda_tail_counts (E, bins) int64   log histogram of |Lambda| per realization
        hist               (H, bins, bins) int64, [v, i_tau0, i_tau_beta] on [0, tau_max)
        kept/status0, kept/steps0, kept/status, kept/steps, kept/lambda: the first keep_pairs
                           realizations (steps are integration steps: tau = steps * dt;
                           status -1 = not run; lambda = per-realization estimate per edge)
        measures/          only with linear, xi2 or rw in measures: one (E,) dataset per value
                           (lambda_xi2, lambda_rw, lambda_linear, lambda_linear_se,
                           lambda_linear_n, ...) aligned with edges; attrs measures, coupling,
                           linear_method, linear_realizations, linear_dbeta, linear_seed, seconds
        attrs nnc_of:      on the raw-coupling twin ``<name>_nnc`` of job <name> (km_nnc)

Crash safety: while a run is going, each finished chunk is written at once to its own file in
``<output>.partial/`` (write to a temporary name, then an atomic rename). Every
``checkpoint_seconds`` and at the end, the whole HDF5 file is rewritten from memory into a
temporary file and atomically renamed over the old one; then the chunk files it now contains
are deleted. A process killed at any moment therefore leaves a readable HDF5 file (or none)
plus chunk files, and ``--resume`` merges them without redoing or double-counting a block.

Each chunk file carries a tag, a digest of the run's key, its job's name and the graph actually
built (:func:`chunk_tag`): a chunk left by another run (another seed, or a graph generator that
built another graph) is never merged. Every job group stores ``graph_digest``
(:func:`graph_digest`), compared on ``--resume``.

One writer at a time: while a run or a sweep writes, it holds an exclusive ``flock`` on
``<output>.lock`` (JSON: pid, host, started, command), see :meth:`ResultStore.lock`. A second
writer is refused before it deletes or modifies anything; the kernel drops the lock when the
holder dies, and a normal exit removes the file.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import glob
import hashlib
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from antisync import __version__, estimators
from antisync.compute import ChunkResult
from antisync.errors import StoreError
from antisync.jobs import Chunk, Job

try:  # POSIX; elsewhere runs are not locked (see ResultStore.lock)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = ["FORMAT", "JobState", "ResultStore", "chunk_tag", "git_revision", "graph_digest",
           "open_results"]

FORMAT = "antisync-results"
FORMAT_VERSION = 1


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
        self.lam_tail = np.zeros((ne, estimators.TAIL_BINS), dtype=np.int64)
        bins = job.config.histogram.bins
        self.hist = np.zeros((len(job.hist_variants), bins, bins), dtype=np.int64)
        keep = min(job.config.keep_pairs, job.config.realizations)
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
                out.extend(Chunk(b, 1) for b in range(c.first_block, c.first_block + c.n_blocks)
                           if not self.done[b])
            else:
                out.append(c)
        return out

    @property
    def realizations_done(self) -> int:
        b = self.job.block_size
        total = self.job.config.realizations
        return int(sum(min(b, total - i * b) for i in np.flatnonzero(self.done)))

    @property
    def complete(self) -> bool:
        return bool(self.done.all())


# ---- the writer lock -------------------------------------------------------------------------
@dataclass
class _Held:
    fd: int  # the descriptor holding the flock (-1 where fcntl is missing)
    thread: int  # the thread that took it: only that thread may take it again
    depth: int  # nesting: run_sweep takes it once, then each of its run_jobs calls again


# Locks this process holds, by lock file path. Reentrant per thread so that a sweep can hold
# its output's lock across its stages; another thread of this process opens its own descriptor,
# which flock refuses exactly like another process.
_HELD: dict[str, _Held] = {}
_HELD_GUARD = threading.Lock()


class _NoLockFile(StoreError):
    """The folder does not let us create the lock file (read-only folder or file system)."""


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
        self._created_dirs: list[Path] = []  # folders made for the output, removed if left empty

    # ---- checks and the lock ---------------------------------------------------------------
    def check_target(self) -> None:
        """Refuse an output path antisync must not write, before anything is created.

        Refused: a symbolic link (the atomic rename would replace the link, not its target),
        a directory, device, FIFO or socket, a path below an existing file
        (``--out cfg.yaml/x.h5``), and a ``.partial`` journal or ``.lock`` file that is not
        antisync's.
        """
        p = self.path
        if p.is_symlink():
            raise StoreError(
                f"output {p} is a symbolic link (to {os.readlink(p)}); antisync replaces its output "
                "file and would replace the link, not its target: give the target's path or another --out"
            )
        if p.is_dir():
            raise StoreError(f"output {p} is a directory; give a file path ending in .h5")
        if p.exists() and not p.is_file():
            raise StoreError(f"output {p} is not a regular file (a device, FIFO or socket); "
                             "give --out a file path ending in .h5")
        ancestor = p.parent
        while not os.path.lexists(ancestor) and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        if not ancestor.is_dir():
            raise StoreError(f"cannot write {p}: {ancestor} is a file, not a folder; "
                             "give --out a path inside a folder")
        for side in (self.journal, self.lock_path):
            if side.is_symlink():
                raise StoreError(f"{side} is a symbolic link, not antisync's; move it away or use "
                                 "--out for another file")
        if os.path.lexists(self.journal) and not self.journal.is_dir():
            raise StoreError(f"{self.journal} is a file, not antisync's journal folder; move it "
                             "away or use --out for another file")
        if self.journal.is_dir():
            foreign = _foreign_in_journal(self.journal)
            if foreign is not None:
                raise StoreError(
                    f"{self.journal} is not an antisync journal (it holds {foreign}); move it away "
                    "or use --out for another file"
                )

    @contextlib.contextmanager
    def lock(self, *, read_only_ok: bool = False) -> Iterator[bool]:
        """Hold the exclusive writer lock of this output for the ``with`` block.

        The lock is an ``flock`` on ``<output>.lock``, which holds JSON ``{pid, host, started,
        command}`` naming the holder. The kernel releases it when the holder dies (even by
        ``kill -9``); a normal exit removes the file. Reentrant within one thread: a sweep
        holds it across the ``run_jobs`` calls of its stages.

        Parameters
        ----------
        read_only_ok : bool
            When the folder does not allow creating the lock file (read-only), yield False
            instead of raising: nothing may then be written, but a ``--resume`` can still
            find the file complete and leave it alone.

        Yields
        ------
        bool
            True when the lock is held and the output may be written.

        Raises
        ------
        StoreError
            Another process (or another thread of this one) holds the lock: the message names
            its pid, host, start time and command. Or the path is refused by
            :meth:`check_target`.
        """
        self.check_target()
        try:
            key = self._acquire()
        except _NoLockFile:
            if not read_only_ok:
                raise
            yield False
            return
        try:
            yield True
        finally:
            self._release(key)
            # folders made for an output that was never written go again (only when empty,
            # hence after the lock file is gone)
            if not os.path.lexists(self.path):
                for d in reversed(self._created_dirs):
                    with contextlib.suppress(OSError):
                        d.rmdir()
            self._created_dirs.clear()

    def _acquire(self) -> str:
        key = os.path.join(os.path.realpath(self.path.parent), self.lock_path.name)
        me = threading.get_ident()
        with _HELD_GUARD:
            held = _HELD.get(key)
            if held is not None and held.thread == me:
                held.depth += 1
                return key
        self._make_parent()
        if fcntl is None:  # no flock here: a second writer is not detected
            with _HELD_GUARD:
                _HELD[key] = _Held(-1, me, 1)
            return key
        for _ in range(100):
            fd = self._open_lock_file()
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                os.close(fd)
                raise StoreError(self._busy_message(holder)) from None
            except OSError as exc:
                os.close(fd)
                raise StoreError(f"cannot lock {self.lock_path} ({exc.strerror}); antisync needs a "
                                 "file system with flock for its output: use --out elsewhere") from None
            # The previous holder unlinks the file before it closes it: if it did so between our
            # open and our flock, we now hold a lock on a deleted file. Only a lock on the file
            # the path names counts; otherwise open the new one and try again.
            if _same_file(fd, self.lock_path):
                break
            os.close(fd)
        else:
            raise StoreError(f"could not lock {self.lock_path}: it kept being replaced; try again")
        try:
            self._claim(fd)
        except BaseException:
            os.close(fd)
            raise
        with _HELD_GUARD:
            _HELD[key] = _Held(fd, me, 1)
        return key

    def _release(self, key: str) -> None:
        with _HELD_GUARD:
            held = _HELD[key]
            held.depth -= 1
            if held.depth > 0:
                return
            del _HELD[key]
        if held.fd < 0:
            return
        try:
            # unlink while still holding the lock: see the retry in _acquire
            if _same_file(held.fd, self.lock_path):
                os.unlink(self.lock_path)
        except OSError:
            pass  # a lock file left behind is harmless: the next writer takes it over
        finally:
            os.close(held.fd)

    def _make_parent(self) -> None:
        missing = []
        d = self.path.parent
        while not os.path.lexists(d) and d != d.parent:
            missing.append(d)
            d = d.parent
        for d in reversed(missing):
            try:
                d.mkdir()
            except FileExistsError:
                continue  # made meanwhile by someone else: not ours to remove
            except OSError as exc:
                if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
                    raise _NoLockFile(f"cannot create folder {d} ({exc.strerror})") from None
                raise StoreError(f"cannot create folder {d} ({exc.strerror})") from None
            self._created_dirs.append(d)

    def _open_lock_file(self) -> int:
        flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(self.lock_path, flags, 0o644)
        except OSError as exc:
            if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
                raise _NoLockFile(
                    f"cannot write to folder {self.path.parent} (creating {self.lock_path.name}: "
                    f"{exc.strerror}); use --out in a folder you can write"
                ) from None
            raise StoreError(f"cannot use {self.lock_path} as the lock file of {self.path} "
                             f"({exc.strerror}); move it away or use --out for another file") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise StoreError(f"{self.lock_path} is not a regular file; move it away or use --out "
                             "for another file")
        return fd

    def _claim(self, fd: int) -> None:
        """Write who holds the lock; refuse a file of the same name that is not a lock file."""
        old = os.pread(fd, 65536, 0)
        if old.strip():
            try:
                previous = json.loads(old)
            except ValueError:
                previous = None
            ours = isinstance(previous, dict) and "pid" in previous  # a holder killed by -9
            if not ours:
                raise StoreError(f"{self.lock_path} exists and is not an antisync lock file; move "
                                 "it away or use --out for another file")
        holder = {"pid": os.getpid(), "host": socket.gethostname(), "started": _now(),
                  "command": command_line()}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(holder).encode(), 0)

    def _busy_message(self, holder: dict) -> str:
        def field(name: str) -> str:
            return " ".join(str(holder.get(name) or "?").split())  # one line, whatever it holds

        return (
            f"{self.path} is being written by another antisync process (pid {field('pid')} on "
            f"{field('host')}, started {field('started')}: {field('command')}); wait for it to "
            "finish or use --out for another file"
        )

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
        import h5py

        what = None
        try:
            with h5py.File(self.path, "r") as f:
                if f.attrs.get("format") != FORMAT:
                    what = f"an HDF5 file without format={FORMAT!r}"
        except OSError:
            what = "not an HDF5 file"
        except Exception as exc:  # unreadable root attributes: not a result file we wrote
            what = f"an HDF5 file with unreadable attributes ({type(exc).__name__})"
        if what is not None:
            raise StoreError(
                f"--overwrite replaces only antisync result files, and {self.path} is {what}; "
                "move it away or use --out for another file"
            )

    def file_complete(self) -> bool:
        """Whether the output file exists and says every job (every stage of a sweep) finished."""
        if not self.path.is_file():
            return False
        with open_results(self.path) as f:
            try:
                return bool(f.attrs.get("complete", False))
            except (TypeError, ValueError, OSError):
                return False

    def load_states(self, jobs: list[Job], config_key: dict) -> dict[str, JobState]:
        """States for ``jobs``: from the HDF5 file when present, plus journal chunks.

        A job group made from another graph (see :func:`graph_digest`) is an error; a journal
        chunk that is damaged or tagged for another run is deleted, its blocks computed again.
        """
        states = {job.name: JobState(job) for job in jobs}
        wanted = json.loads(json.dumps(config_key))
        if self.path.exists():
            with open_results(self.path) as f:
                stored = _read(self.path, "root attribute simulation_key",
                               lambda: json.loads(f.attrs.get("simulation_key", "{}")))
                if stored != wanted:
                    raise StoreError(
                        f"{self.path} was made with a different config (graph, edges, betas, "
                        "dynamics, realizations, seed or histogram differ); use --out for a new file"
                    )
                for name, st in states.items():
                    if f"jobs/{name}" in f:
                        g = f[f"jobs/{name}"]
                        _check_graph(self.path, g, st.job)
                        _read_state(self.path, g, st)
        elif (self.journal / "simulation_key.json").exists():
            try:
                stored = json.loads((self.journal / "simulation_key.json").read_text())
            except (OSError, ValueError):
                stored = None  # damaged: the chunks' own tags still keep foreign ones out
            if stored is not None and stored != wanted:
                raise StoreError(
                    f"{self.journal} holds chunks of a different config; remove it or use --out"
                )
        for st in states.values():
            for res in self._journal_chunks(st, chunk_tag(st.job, config_key)):
                sl = slice(res.chunk.first_block, res.chunk.first_block + res.chunk.n_blocks)
                if not st.done[sl].any():
                    st.add(res)
        return states

    # ---- writing -------------------------------------------------------------------------
    def start_journal(self, config_key: dict) -> None:
        self.journal.mkdir(parents=True, exist_ok=True)
        _atomic_write_bytes(self.journal / "simulation_key.json", json.dumps(config_key).encode())

    def save_chunk(self, name: str, res: ChunkResult, tag: str = "") -> None:
        """Persist a finished chunk at once (atomic rename), before it is merged.

        ``tag`` is :func:`chunk_tag` of the chunk's job and run key: on resume, a chunk whose
        tag differs from the job's is never merged (so an untagged one never is).
        """
        arrays = {
            "rec": res.rec, "rec0": res.rec0, "tail": res.tail, "hist": res.hist,
            "lam_rec": res.lam_rec, "lam_tail": res.lam_tail,
            "meta": np.array([res.chunk.first_block, res.chunk.n_blocks, res.first, res.count]),
            "seconds": np.array([res.seconds]),
            "backend": np.array([res.backend]),
            "tag": np.array(tag),
        }
        if res.kept is not None:
            arrays.update({f"kept_{k}": v for k, v in res.kept.items()})
        target = self.journal / f"{name}__{res.chunk.first_block:09d}.npz"
        tmp = target.with_suffix(".tmp")
        try:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise

    def checkpoint(self, states: dict[str, JobState], provenance: dict, *, final: bool = False,
                   extra=None) -> None:
        """Rewrite the HDF5 file from ``states`` atomically, then drop merged journal chunks.

        ``provenance`` keys beyond the standard ones become root attributes too; ``extra``, when
        given, is called as ``extra(h5file, states)`` before the file is closed, to add groups
        (a sweep's screening and symmetry data) that must survive every checkpoint.
        """
        import h5py

        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.tmp_path
        try:
            with h5py.File(tmp, "w") as f:
                f.attrs["format"] = FORMAT
                f.attrs["format_version"] = FORMAT_VERSION
                f.attrs["antisync_version"] = __version__
                f.attrs["created"] = provenance.get("created", _now())
                f.attrs["updated"] = _now()
                for key in ("command", "config_yaml", "git_revision", "simulation_key"):
                    f.attrs[key] = str(provenance.get(key, ""))
                for key, value in provenance.items():
                    if key not in f.attrs:
                        f.attrs[key] = str(value)
                f.attrs["complete"] = all(st.complete for st in states.values())
                jobs = f.create_group("jobs")
                for name, st in states.items():
                    _write_state(jobs.create_group(name), st)
                if extra is not None:
                    extra(f, states)
                f.flush()
            os.replace(tmp, self.path)
        except BaseException:
            # the old file (if any) is intact; a half-written temporary file is of no use
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise
        if self.journal.exists():
            for p in self.journal.glob("*.npz"):
                p.unlink()
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
        if self.journal.is_dir() and not self.journal.is_symlink() and _journal_is_empty(self.journal):
            shutil.rmtree(self.journal, ignore_errors=True)

    def drop_journal(self) -> None:
        """Remove the journal of a complete file (a kill between the last checkpoint and the
        journal's removal leaves one; every block it holds is in the file). Under :meth:`lock`."""
        if self.journal.is_dir() and not self.journal.is_symlink():
            shutil.rmtree(self.journal, ignore_errors=True)

    def _journal_chunks(self, st: JobState, tag: str) -> Iterator[ChunkResult]:
        if not self.journal.is_dir():
            return
        name = st.job.name
        for p in sorted(self.journal.glob(f"{glob.escape(name)}__*.npz")):
            if p.name[: -len(".npz")].rsplit("__", 1)[0] != name:
                continue  # a job whose name begins with this one's, e.g. "a__b"
            res = _load_chunk(p, tag)
            if res is None or not _chunk_fits(st, res):
                # cut off by a crash, damaged, or left by another run (another seed or graph):
                # never merged; its blocks are simply computed again
                with contextlib.suppress(OSError):
                    p.unlink()
                continue
            yield res


def graph_digest(job: Job) -> str:
    """SHA-256 of the graph ``job`` was built on: node order, weights, damaged edges, variants.

    Stored per job group (attr ``graph_digest``) and part of every journal chunk's tag: a
    networkx generator such as ``random_regular_graph`` without a seed builds another graph on
    each run from the same config, and results of two graphs must never be merged.
    """
    return _graph_digest([_jsonable(v) for v in job.nodes], list(job.edge_labels), job.omega,
                         job.variant_edge, job.variant_beta)


def chunk_tag(job: Job, key: dict) -> str:
    """The tag of ``job``'s journal chunks in a run with simulation key ``key``.

    A digest of ``key`` (the config's or the sweep's), the job's name and own simulation key,
    and :func:`graph_digest`: equal only for chunks that may be merged into this job.
    """
    payload = json.dumps({"key": key, "job": job.name, "config": job.config.simulation_key(),
                          "graph": graph_digest(job)}, sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()


def _graph_digest(nodes: list, edges: list, omega, variant_edge, variant_beta) -> str:
    h = hashlib.sha256(json.dumps({"nodes": nodes, "edges": edges}).encode())
    # fixed dtypes: the digest of a job and of the datasets it wrote must agree
    for arr, dtype in ((omega, np.float64), (variant_edge, np.int64), (variant_beta, np.float64)):
        a = np.ascontiguousarray(arr, dtype=dtype)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _check_graph(path: Path, g, job: Job) -> None:
    stored = _read(path, f"{g.name} graph_digest", lambda: g.attrs.get("graph_digest"))
    if stored is None:  # written before graph digests: digest what the group stores
        stored = _read(path, f"{g.name} graph", lambda: _graph_digest(
            json.loads(g.attrs["nodes"]), json.loads(g.attrs["edges"]), g["omega"][...],
            g["variant_edge"][...], g["variant_beta"][...]))
    if str(stored) != graph_digest(job):
        raise StoreError(
            f"{path} was made with a different graph for {job.name} (nodes, weights or damaged "
            "edges differ from the graph built now: a random generator without a seed?); "
            "use --out for a new file"
        )


def _load_chunk(p: Path, tag: str) -> ChunkResult | None:
    """The chunk saved in ``p``, or None if it is damaged or its tag is not ``tag``."""
    try:
        with np.load(p, allow_pickle=False) as z:
            if str(z["tag"][()]) != tag:
                return None
            first_block, n_blocks, first, count = (int(x) for x in z["meta"])
            kept = None
            if "kept_status0" in z:
                kept = {k: z[f"kept_{k}"] for k in ("status0", "steps0", "status", "steps", "lambda")}
            return ChunkResult(
                Chunk(first_block, n_blocks), z["rec"], z["rec0"], z["tail"], z["hist"],
                z["lam_rec"], z["lam_tail"], kept, first, count, float(z["seconds"][0]),
                str(z["backend"][0]),
            )
    except Exception:  # any damage (a zip cut off, EOF, a bad header, a missing array, a
        return None  # pickle refused) means the same: those blocks are computed again


def _chunk_fits(st: JobState, res: ChunkResult) -> bool:
    """Whether a loaded chunk has the shapes and position of a chunk of ``st``'s job."""
    c = res.chunk
    if c.n_blocks < 1 or c.first_block < 0 or c.first_block + c.n_blocks > st.done.size:
        return False
    if (res.first, res.count) != c.realizations(st.job.block_size, st.job.config.realizations):
        return False
    shapes = [(res.rec, (c.n_blocks, *st.rec.shape[1:])), (res.rec0, (c.n_blocks, *st.rec0.shape[1:])),
              (res.lam_rec, (c.n_blocks, *st.lam_rec.shape[1:])), (res.tail, st.tail.shape),
              (res.hist, st.hist.shape), (res.lam_tail, st.lam_tail.shape)]
    if res.kept is not None:
        for k, arr in st.kept.items():
            got = res.kept[k]
            if got.shape[1:] != arr.shape[1:] or res.first + got.shape[0] > arr.shape[0]:
                return False
    return all(a.shape == shape for a, shape in shapes)


def _foreign_in_journal(journal: Path) -> str | None:
    """The first entry of the folder ``journal`` antisync did not write there, or None."""
    for p in sorted(journal.iterdir()):
        if p.is_symlink():
            return p.name
        if p.is_dir():
            if p.name != "screen":
                return p.name + "/"
            for q in p.iterdir():
                if q.is_symlink() or not q.is_file() or q.suffix not in (".json", ".tmp"):
                    return f"screen/{q.name}"
        elif p.name != "simulation_key.json" and p.suffix not in (".npz", ".tmp"):
            return p.name
    return None


def _journal_is_empty(journal: Path) -> bool:
    """Whether ``journal`` holds no finished work: no chunk and no screening result."""
    if _foreign_in_journal(journal) is not None:
        return False
    if any(journal.glob("*.npz")):
        return False
    return not any((journal / "screen").glob("*.json"))


def _same_file(fd: int, path: Path) -> bool:
    try:
        st = os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    own = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)


def _read_holder(fd: int) -> dict:
    """The JSON the lock's holder wrote (it may still be writing it: a few short retries)."""
    for _ in range(20):
        raw = os.pread(fd, 65536, 0)
        try:
            holder = json.loads(raw)
            if isinstance(holder, dict):
                return holder
        except ValueError:
            pass
        time.sleep(0.05)
    return {}


def _read(path: Path, what: str, read):
    """``read()``, with damage reported as one :class:`StoreError` naming the file and ``what``."""
    try:
        return read()
    except KeyError:
        raise StoreError(f"{path} is damaged: {what} is missing; use --out for a new file") from None
    except (OSError, ValueError, TypeError) as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise StoreError(f"{path} is damaged: {what} cannot be read ({why}); "
                         "use --out for a new file") from None



def open_results(path: str | Path):
    """Open an antisync HDF5 file for reading, with a clear :class:`StoreError` otherwise."""
    import h5py

    path = Path(path)
    if not path.exists():
        raise StoreError(f"result file {path} does not exist")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise StoreError(f"{path} is not a readable HDF5 file") from None
    try:
        fmt = f.attrs.get("format")
        raw_version = f.attrs.get("format_version", 0)
    except Exception as exc:  # damaged attribute storage: h5py raises OSError, KeyError, ...
        f.close()
        raise StoreError(f"{path} is damaged: its root attributes cannot be read "
                         f"({type(exc).__name__})") from None
    if fmt != FORMAT:
        f.close()
        raise StoreError(f"{path} is an HDF5 file but not an antisync result file (no format={FORMAT!r})")
    try:
        version = int(raw_version)
    except (TypeError, ValueError):
        f.close()
        raise StoreError(f"{path} is damaged: root attribute format_version is {raw_version!r}, "
                         "not an integer") from None
    if version > FORMAT_VERSION:
        f.close()  # the attributes were read above: after close() they cannot be
        raise StoreError(f"{path} was written by a newer antisync (format {version}); this one "
                         f"reads format {FORMAT_VERSION} — upgrade antisync")
    return f


def git_revision() -> str:
    """The source checkout's git revision, or '' when antisync does not run from a checkout."""
    here = Path(__file__).resolve().parent.parent
    try:
        out = subprocess.run(["git", "-C", str(here), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return ""
    return out.stdout.strip() if out.returncode == 0 else ""


def _write_state(g, st: JobState) -> None:
    job = st.job
    cfg = job.config
    g.attrs["graph"] = job.name
    g.attrs["graph_digest"] = graph_digest(job)  # compared on --resume
    g.attrs["nodes"] = json.dumps([_jsonable(v) for v in job.nodes])
    g.attrs["edges"] = json.dumps(job.edge_labels)
    g.attrs["betas"] = np.array(job.betas, dtype=np.float64)
    g.attrs["dbeta"] = job.dbeta
    g.attrs["lambda_method"] = cfg.lambda_.method
    g.attrs["seed"] = cfg.seed
    g.attrs["dt"] = cfg.dynamics.dt
    g.attrs["threshold"] = cfg.dynamics.threshold
    g.attrs["coupling"] = cfg.dynamics.coupling
    g.attrs["tau_max_hist"] = cfg.histogram.tau_max
    g.attrs["backend"] = ",".join(sorted(st.backends)) or cfg.backend
    g.attrs["block_size"] = job.block_size
    g.attrs["realizations"] = cfg.realizations
    g.attrs["realizations_done"] = st.realizations_done
    g.attrs["seconds"] = st.seconds
    g.attrs["complete"] = st.complete
    g.attrs["block_fields"] = json.dumps(list(estimators.BLOCK_FIELDS))
    g.attrs["tau0_fields"] = json.dumps(list(estimators.TAU0_FIELDS))
    g.attrs["lambda_fields"] = json.dumps(list(estimators.LAMBDA_FIELDS))
    g.create_dataset("omega", data=job.omega)
    g.create_dataset("variant_edge", data=job.variant_edge)
    g.create_dataset("variant_beta", data=job.variant_beta)
    g.create_dataset("hist_variants", data=job.hist_variants)
    g.create_dataset("blocks_done", data=st.done)
    g.create_dataset("block_records", data=st.rec, compression="gzip", compression_opts=1)
    g.create_dataset("tau0_records", data=st.rec0, compression="gzip", compression_opts=1)
    g.create_dataset("tail_counts", data=st.tail)
    g.create_dataset("lambda_records", data=st.lam_rec, compression="gzip", compression_opts=1)
    g.create_dataset("lambda_tail_counts", data=st.lam_tail)
    g.create_dataset("hist", data=st.hist, compression="gzip", compression_opts=1)
    kept = g.create_group("kept")
    for key, arr in st.kept.items():
        kept.create_dataset(key, data=arr, compression="gzip", compression_opts=1)
    if job.nnc_of:
        g.attrs["nnc_of"] = job.nnc_of
    if st.measures is not None:
        from antisync.measures.pipeline import write_measures

        write_measures(g, st.measures, cfg, st.measures_seconds)
    from antisync.summary import job_records  # late: summary reads this module's layout

    g.attrs["summary_json"] = json.dumps(job_records(_view_from_state(st)))


def _read_state(path: Path, g, st: JobState) -> None:
    """Fill ``st`` from job group ``g`` of ``path``; a damaged or mismatched group is an error."""
    arrays = {"block_records": st.rec, "tau0_records": st.rec0, "blocks_done": st.done,
              "tail_counts": st.tail, "lambda_records": st.lam_rec,
              "lambda_tail_counts": st.lam_tail, "hist": st.hist}
    arrays.update({f"kept/{k}": v for k, v in st.kept.items()})
    for name, target in arrays.items():
        data = _read(path, f"{g.name}/{name}", lambda name=name: g[name][...])
        if data.shape != target.shape:
            raise StoreError(
                f"{path}: {g.name}/{name} has shape {data.shape} but the config needs "
                f"{target.shape}: the group does not match the config's edges, betas, realizations "
                "or histogram; use --out for a new file"
            )
        target[...] = data
    st.seconds = _read(path, f"{g.name} attribute seconds", lambda: float(g.attrs["seconds"]))
    backends = _read(path, f"{g.name} attribute backend", lambda: str(g.attrs["backend"]))
    st.backends = set(backends.split(",")) - {""}
    if "measures" in g:
        from antisync.measures.pipeline import read_measures

        st.measures = _read(path, f"{g.name}/measures", lambda: read_measures(g))
        st.measures_seconds = _read(path, f"{g.name}/measures attribute seconds",
                                    lambda: float(g["measures"].attrs.get("seconds", 0.0)))


def _view_from_state(st: JobState):
    from antisync.summary import JobView

    job = st.job
    return JobView(
        graph=job.name, edges=job.edge_labels, betas=job.betas, dbeta=job.dbeta,
        variant_edge=job.variant_edge, variant_beta=job.variant_beta,
        rec=st.rec, rec0=st.rec0, done=st.done, tail=st.tail,
        realizations=job.config.realizations, lam_rec=st.lam_rec, lam_tail=st.lam_tail,
        lambda_method=job.config.lambda_.method, measures=st.measures,
    )


def _jsonable(v):
    return v if isinstance(v, int | float | str) else str(v)


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def command_line() -> str:
    """The command that runs, as a user would type it (``python -m antisync`` included)."""
    name = Path(sys.argv[0]).name
    if name == "__main__.py":
        name = "antisync"
    return " ".join([name] + sys.argv[1:])
