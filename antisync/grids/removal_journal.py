"""The journals of a grid's line work: every finished task on disk at once, so that an
interrupted dynamic line removal (:func:`antisync.grids.removal.line_removal`: realizations x a
group of lines) or an engineer's N-1 (:func:`antisync.grids.trip.trip_report`: a run of trips)
resumes where it stopped. Its files are written and read by the store's journal
(:func:`antisync.store.journal.save_arrays`, :func:`~antisync.store.journal.load_arrays`), as a
run's chunks are; this module says which work a folder holds and which task files fit it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from dataclasses import fields
from pathlib import Path

import numpy as np

from antisync.grids.errors import GridError
from antisync.grids.removal_file import plain
from antisync.store.journal import load_arrays, save_arrays, write_atomically

__all__ = [
    "RemovalJournal",
    "TaskJournal",
    "TripJournal",
    "journal_folder",
    "key_changes",
    "remove_journal",
    "work_digest",
]


def key_changes(old, new, most: int = 4) -> str:
    """What differs between two keys (a journal's, two tables' configs) as ``key: old -> new``
    with dotted paths into nested mappings (``seed: 11 -> 12``, ``dynamics.t_max: 60 -> 80``;
    ``(absent)`` for a key one side lacks), the first ``most`` and a count of the rest: a
    refusal names what changed rather than every key."""
    absent = object()

    def walk(a, b, prefix: str):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in [*a, *(k for k in b if k not in a)]:
                yield from walk(a.get(k, absent), b.get(k, absent), f"{prefix}{k}.")
        elif a != b:
            yield prefix.rstrip(".") or "the whole key", a, b

    def shown(v) -> str:
        text = "(absent)" if v is absent else json.dumps(v, default=str)
        return text if len(text) <= 40 else text[:37] + "..."

    changes = [f"{k}: {shown(a)} -> {shown(b)}" for k, a, b in walk(old, new, "")]
    if not changes:
        return "no key differs"
    more = f"; and {len(changes) - most} more" if len(changes) > most else ""
    return "; ".join(changes[:most]) + more


def work_digest(fixed: dict, variants: np.ndarray) -> str:
    """SHA-256 of the work as built: the grid's CSR pattern and weights, every line's changed
    weights and the resolved model (per-node parameters, targets), or the law.

    Part of a :class:`RemovalJournal`'s task tag beside its key: the key names per-node files
    by path and a graph generator by its arguments, so an edited file or another built graph
    under the same key must still keep the old tasks out.
    """
    h = hashlib.sha256()

    def add(name: str, value) -> None:
        h.update(name.encode())
        if value is None:
            h.update(b"none")
        elif isinstance(value, np.ndarray):
            h.update(f"{value.dtype.str}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
        else:
            h.update(repr(value).encode())

    for name in ("indptr", "indices", "base"):
        add(name, np.asarray(fixed[name]))
    add("variants", np.asarray(variants))
    setup = fixed["setup"] if fixed.get("law") is None else fixed["law"]  # a law's: its text too
    for f in fields(setup):
        add(f.name, getattr(setup, f.name))
    return h.hexdigest()


class TaskJournal:
    """Finished tasks of a grid's line work on disk, so that an interrupted run resumes: the
    folder holds :attr:`KEY_FILE` (the work, as plain JSON) and one ``task_*.npz`` per finished
    task (written by :func:`antisync.store.journal.save_arrays` to a temporary name, then
    renamed: a file is whole or absent). A folder whose key is another work's is refused with
    one line and left as it is.

    Every task file carries a tag (:attr:`tag`: a digest of the key and of the work as built,
    :func:`work_digest`), as the run journal's chunks do (:func:`antisync.store.journal.
    chunk_tag`): a task file that is damaged, tagged for other work, untagged, or whose arrays
    do not fit the work is deleted on load and never merged; its work is simply done again.
    :class:`RemovalJournal` (``--removal``) and :class:`TripJournal` (``--trip``) say what a
    task holds.

    Parameters
    ----------
    folder : path
        The journal folder (created when missing).
    key : dict
        The work, as plain JSON data; compared with the folder's :attr:`KEY_FILE`.
    work : str
        A digest of the work as built (:func:`work_digest`), part of the tag.
    """

    KIND = "task"
    KEY_FILE = "task_key.json"

    def __init__(self, folder: str | Path, key: dict, work: str = ""):
        self.folder = Path(folder)
        self.key = json.loads(json.dumps(plain(key), sort_keys=True))
        self.tag = hashlib.sha256(f"{json.dumps(self.key, sort_keys=True)}\n{work}".encode()).hexdigest()
        key_path = self.folder / self.KEY_FILE
        kind = self.KIND
        if self.folder.exists() and not self.folder.is_dir():
            raise GridError(f"{self.folder} is a file, not a {kind} journal (a folder); move it away")
        if key_path.exists() or key_path.is_symlink():
            try:
                theirs = json.loads(key_path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise GridError(
                    f"{key_path} cannot be read ({type(exc).__name__}), so the work this journal holds is "
                    "unknown: pass --overwrite (restart=True) to discard it, or move the folder away"
                ) from None
            if theirs != self.key:
                changed = key_changes(theirs, self.key)
                raise GridError(
                    f"{self.folder} holds the unfinished work of another {kind} run ({changed}): pass the "
                    "same arguments to finish it, or --overwrite to discard it"
                )
        elif self.folder.exists() and any(self.folder.iterdir()):
            raise GridError(f"{self.folder} exists and is not a {kind} journal; move it away")
        else:
            self.folder.mkdir(parents=True, exist_ok=True)
            write_atomically(key_path, json.dumps(self.key, sort_keys=True).encode())

    def tasks(self) -> list[Path]:
        return sorted(self.folder.glob("task_*.npz"))

    def _read_tasks(self, read):
        """``read(path)`` of every task file, each not None; a file ``read`` refuses (None) is
        deleted."""
        for path in self.tasks():
            task = read(path)
            if task is None:
                with contextlib.suppress(OSError):  # a folder of that name: not ours to remove
                    path.unlink()
                continue
            yield task


class RemovalJournal(TaskJournal):
    """The journal of :func:`antisync.grids.removal.line_removal` (:class:`TaskJournal`): the
    key holds the resolved config, lines, beta and islanding, and a task file
    ``task_<first realization>_<first line>_<lines>_<intact>.npz`` the outcomes of its
    realizations x lines (a file whose arrays are out of this work's shapes, realizations or
    lines is dropped)."""

    KIND = "removal"
    KEY_FILE = "removal_key.json"

    def load(self, status0, tau0, status, tau, audit=None) -> np.ndarray:
        """Fill the arrays from the saved tasks that carry this journal's :attr:`tag` and fit
        the arrays; delete every other task file. Return which cells were filled (bool
        ``(realizations, 1 + lines)``, column 0 the intact grid). ``audit``: ``sync.give_up``'s
        audit counts of the tasks read are added to it."""
        have = np.zeros((status0.size, 1 + status.shape[1]), dtype=bool)
        for task in self._read_tasks(lambda path: self._read(path, status0.size, status.shape[1])):
            ks, group, intact, part = task
            if intact:
                status0[ks], tau0[ks] = part["status0"], part["tau0"]
                have[ks, 0] = True
            status[np.ix_(ks, group)], tau[np.ix_(ks, group)] = part["status"], part["tau"]
            have[np.ix_(ks, 1 + group)] = True
            if audit is not None:
                audit += part["audit"]
        return have

    def _read(self, path: Path, m: int, lines: int):
        """``(ks, group, intact, arrays)`` of the task file ``path``, or None when it is damaged,
        not tagged :attr:`tag`, or its arrays are not a task of ``m`` realizations x ``lines``
        lines (checked whole before anything is merged)."""

        def read(f):
            part = {k: f[k] for k in ("status0", "tau0", "status", "tau")}
            part["audit"] = f["audit"] if "audit" in f else np.zeros(3, dtype=np.int64)
            return f["ks"], f["group"], f["intact"], part

        task = load_arrays(path, self.tag, read)
        if task is None:
            return None
        ks, group, intact, part = task
        n = ks.size
        index_ok = all(
            a.ndim == 1
            and a.dtype.kind in "iu"
            and a.size == np.unique(a).size
            and (a.size == 0 or (a.min() >= 0 and a.max() < top))
            for a, top in ((ks, m), (group, lines))
        )
        if not index_ok or n == 0 or intact.shape != () or intact.dtype != np.bool_:
            return None
        if part["audit"].shape != (3,) or part["audit"].dtype.kind not in "iu" or (part["audit"] < 0).any():
            return None
        shapes = {"status": (n, group.size), "tau": (n, group.size)}
        if intact:
            shapes.update(status0=(n,), tau0=(n,))
        for k, shape in shapes.items():
            want = "iu" if k.startswith("status") else "f"
            if part[k].shape != shape or part[k].dtype.kind not in want:
                return None
        return ks.astype(np.int64), group.astype(np.int64), bool(intact), part

    def save(self, ks, group, intact: bool, part) -> None:
        """Save a finished task at once (:func:`antisync.store.journal.save_arrays`: whole or
        absent), tagged :attr:`tag`; ``part``: ``(status0, tau0, status, tau, audit)`` (``audit``:
        ``sync.give_up``'s counts of the task, zeros without the rule)."""
        name = f"task_{ks[0]}_{group[0] if group.size else 0}_{group.size}_{int(intact)}.npz"
        arrays = {
            "ks": ks,
            "group": group,
            "intact": intact,
            "status0": part[0],
            "tau0": part[1],
            "status": part[2],
            "tau": part[3],
            "audit": np.asarray(part[4], dtype=np.int64),
        }
        save_arrays(self.folder / name, arrays, self.tag)


class TripJournal(TaskJournal):
    """The journal of ``antisync grid --trip`` (:func:`antisync.grids.trip.trip_report`;
    :class:`TaskJournal`): the key holds the grid's config, the trips and the fault, clearing
    and integration settings; a task file ``task_<first trip>_<trips>.npz`` the result rows
    (``(trips, width)`` float64) of a run of consecutive trips."""

    KIND = "trip"
    KEY_FILE = "trip_key.json"

    def load(self, values: np.ndarray) -> np.ndarray:
        """Fill ``values`` (``(trips, width)``) from the saved tasks that carry this journal's
        tag and fit it; delete every other task file. Return which rows were filled."""
        have = np.zeros(values.shape[0], dtype=bool)

        def read(path):
            task = load_arrays(path, self.tag, lambda f: (f["first"], f["rows"]))
            if task is None:
                return None
            first, rows = task
            if first.shape != () or first.dtype.kind not in "iu" or rows.dtype.kind != "f":
                return None
            first = int(first)
            if rows.ndim != 2 or rows.shape[1] != values.shape[1] or rows.shape[0] == 0:
                return None
            if first < 0 or first + rows.shape[0] > values.shape[0]:
                return None
            return first, rows

        for first, rows in self._read_tasks(read):
            values[first : first + rows.shape[0]] = rows
            have[first : first + rows.shape[0]] = True
        return have

    def save(self, first: int, rows: np.ndarray) -> None:
        """Save the finished rows of trips ``first ..`` at once, tagged :attr:`tag`."""
        arrays = {"first": np.int64(first), "rows": np.asarray(rows, dtype=np.float64)}
        save_arrays(self.folder / f"task_{first}_{len(rows)}.npz", arrays, self.tag)


def remove_journal(folder: str | Path) -> None:
    """Delete a :class:`RemovalJournal`'s files and its folder (once empty); nothing else (a
    folder named like a task file, or any file not antisync's, stays, and so does the folder)."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    for path in [*folder.glob("task_*.npz"), folder / RemovalJournal.KEY_FILE, folder / TripJournal.KEY_FILE]:
        with contextlib.suppress(OSError):
            path.unlink()
    with contextlib.suppress(OSError):
        folder.rmdir()


def journal_folder(out: str | Path) -> Path:
    """Where ``antisync grid --removal`` (or ``--trip``) ``--out X.json`` keeps its journal:
    ``X.json.partial``."""
    out = Path(out)
    if out.name in ("", ".", ".."):
        raise GridError(f"--out {str(out)!r} names no file; give a file name ending in .json")
    return out.with_name(out.name + ".partial")
