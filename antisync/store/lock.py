"""The writer lock of an output file, and the checks of its path before anything is written.

One writer at a time: while a run or a sweep writes, it holds an exclusive ``flock`` on
``<output>.lock`` (JSON: pid, host, started, command), see :meth:`OutputLock.hold`. A second
writer is refused before it deletes or modifies anything; the kernel drops the lock when the
holder dies, and a normal exit removes the file.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import socket
import stat
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from antisync.errors import StoreError
from antisync.store.journal import foreign_entry
from antisync.store.outputs import check_file_path
from antisync.store.provenance import command_line, now

try:  # POSIX; elsewhere runs are not locked (see OutputLock.hold)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = ["OutputLock", "writer_lock"]


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


class OutputLock:
    """The exclusive writer lock of the output ``path`` (its ``.partial`` journal and ``.lock``
    file are named by the caller, see :class:`~antisync.store.result_store.ResultStore`)."""

    def __init__(self, path: Path, journal: Path, lock_path: Path):
        self.path = path
        self.journal = journal
        self.lock_path = lock_path
        self._created_dirs: list[Path] = []  # folders made for the output, removed if left empty

    def check_target(self) -> None:
        """Refuse an output path antisync must not write, before anything is created.

        Refused: a symbolic link (the atomic rename would replace the link, not its target),
        a directory, device, FIFO or socket, a path below an existing file
        (``--out cfg.yaml/x.h5``), a path inside a ``*.partial`` journal folder (another run's
        unfinished work), and a ``.partial`` journal or ``.lock`` file that is not antisync's.
        """
        p = self.path
        check_file_path(p, "output", ".h5")
        ancestor = p.parent
        while not os.path.lexists(ancestor) and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        if not ancestor.is_dir():
            raise StoreError(
                f"cannot write {p}: {ancestor} is a file, not a folder; give --out a path inside a folder"
            )
        for side in (self.journal, self.lock_path):
            if side.is_symlink():
                raise StoreError(
                    f"{side} is a symbolic link, not antisync's; move it away or use --out for another file"
                )
        if os.path.lexists(self.journal) and not self.journal.is_dir():
            raise StoreError(
                f"{self.journal} is a file, not antisync's journal folder; move it "
                "away or use --out for another file"
            )
        if self.journal.is_dir():
            foreign = foreign_entry(self.journal)
            if foreign is not None:
                raise StoreError(
                    f"{self.journal} is not an antisync journal (it holds {foreign}); move it away "
                    "or use --out for another file"
                )

    @contextlib.contextmanager
    def hold(self, *, read_only_ok: bool = False, check: bool = True) -> Iterator[bool]:
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
        check : bool
            Run :meth:`check_target` first (a run's output and journal); False for a writer
            that checks its own path and journal (:func:`writer_lock`).

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
        if check:
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
                raise StoreError(
                    f"cannot lock {self.lock_path} ({exc.strerror}); antisync needs a "
                    "file system with flock for its output: use --out elsewhere"
                ) from None
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
            raise StoreError(
                f"cannot use {self.lock_path} as the lock file of {self.path} "
                f"({exc.strerror}); move it away or use --out for another file"
            ) from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise StoreError(
                f"{self.lock_path} is not a regular file; move it away or use --out for another file"
            )
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
                raise StoreError(
                    f"{self.lock_path} exists and is not an antisync lock file; move "
                    "it away or use --out for another file"
                )
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": now(),
            "command": command_line(),
        }
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


def writer_lock(path: str | Path) -> contextlib.AbstractContextManager[bool]:
    """The one-writer lock of any output ``path`` antisync writes (``<path>.lock``, the lock a
    run's HDF5 file has, see :meth:`OutputLock.hold`), for a writer with a journal of its own
    (``antisync grid --removal --out X.json`` and its ``X.json.partial``).

    Hold it before anything looks at the output or its journal: a second writer is then
    refused with the first one's pid, host, start time and command, instead of finding the
    journal and being told to ``--resume`` (which would make two writers of one journal).
    Only the lock: the writer checks its own path and journal. Yields True.
    """
    p = Path(path)
    lock = OutputLock(p, p.with_name(p.name + ".partial"), p.with_name(p.name + ".lock"))
    return lock.hold(check=False)


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
