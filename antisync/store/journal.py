"""The journal: finished chunks on disk, in ``<output>.partial/``, until a checkpoint holds them.

While a run is going, each finished chunk is written at once to its own file
``<output>.partial/<job>__<first block>.npz`` (write to a temporary name, then an atomic
rename). Every checkpoint rewrites the HDF5 file from memory (:mod:`antisync.store.layout`)
and then deletes the chunk files it now contains. A process killed at any moment therefore
leaves a readable HDF5 file (or none) plus chunk files, and ``--resume`` merges them without
redoing or double-counting a block.

Each chunk file carries a tag, a digest of the run's key, its job's name and the graph actually
built (:func:`chunk_tag`): a chunk left by another run (another seed, or a graph generator that
built another graph) is never merged. Chunk files are written and read by :func:`save_arrays` and
:func:`load_arrays`, tagged array files that a grid's line removal keeps its finished tasks in
too (:mod:`antisync.grids.removal_journal`). The folder also holds ``simulation_key.json`` (the run's
key) and, for a sweep, ``screen/<graph>.json`` (each graph's screening, see
:func:`save_screen`). A run started with ``--overwrite`` over an existing result file leaves that
file in place until its successor is complete: the folder then also holds ``replaces`` (the
marker) and ``replacement.h5`` (the successor's latest checkpoint), see
:class:`antisync.store.ResultStore`. Anything else in it means it is not antisync's.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from antisync.plan.jobs import Chunk, Job
from antisync.store.state import ChunkResult, JobState

__all__ = [
    "REPLACEMENT_FILE",
    "REPLACES_FILE",
    "chunk_tag",
    "chunks",
    "digest_graph",
    "drop_chunks",
    "foreign_entry",
    "graph_digest",
    "is_empty",
    "jsonable",
    "load_arrays",
    "load_screens",
    "save_arrays",
    "save_chunk",
    "save_screen",
    "start",
    "stored_key",
    "write_atomically",
]

T = TypeVar("T")

KEY_FILE = "simulation_key.json"
SCREEN_FOLDER = "screen"
#: marker of a run that replaces an existing result file (``--overwrite``): the old file stays
#: in place and the run's checkpoints go to REPLACEMENT_FILE until the run is complete
REPLACES_FILE = "replaces"
REPLACEMENT_FILE = "replacement.h5"


# ---- tags ------------------------------------------------------------------------------------
def graph_digest(job: Job) -> str:
    """SHA-256 of the graph ``job`` was built on: node order, weights, damaged edges, variants.

    Stored per job group (attr ``graph_digest``) and part of every journal chunk's tag: a
    networkx generator such as ``random_regular_graph`` without a seed builds another graph on
    each run from the same config, and results of two graphs must never be merged.
    """
    return digest_graph(
        [jsonable(v) for v in job.nodes], list(job.edge_labels), job.omega, job.variant_edge, job.variant_beta
    )


def chunk_tag(job: Job, key: dict) -> str:
    """The tag of ``job``'s journal chunks in a run with simulation key ``key``.

    A digest of ``key`` (the config's or the sweep's), the job's name and own simulation key,
    and :func:`graph_digest`: equal only for chunks that may be merged into this job.
    """
    payload = json.dumps(
        {"key": key, "job": job.name, "config": job.config.simulation_key(), "graph": graph_digest(job)},
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(payload.encode()).hexdigest()


def digest_graph(nodes: list, edges: list, omega, variant_edge, variant_beta) -> str:
    """:func:`graph_digest` from its parts (as a job group stores them, for older files)."""
    h = hashlib.sha256(json.dumps({"nodes": nodes, "edges": edges}).encode())
    # fixed dtypes: the digest of a job and of the datasets it wrote must agree
    for arr, dtype in ((omega, np.float64), (variant_edge, np.int64), (variant_beta, np.float64)):
        a = np.ascontiguousarray(arr, dtype=dtype)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def jsonable(v):
    """A node label as stored in JSON: numbers and strings as they are, anything else as str."""
    return v if isinstance(v, int | float | str) else str(v)


# ---- chunks ----------------------------------------------------------------------------------
def start(folder: Path, config_key: dict) -> None:
    """Create the journal ``folder`` and record the run's key in it."""
    folder.mkdir(parents=True, exist_ok=True)
    write_atomically(folder / KEY_FILE, json.dumps(config_key).encode())


def stored_key(folder: Path) -> dict | None:
    """The key recorded by :func:`start`; None when there is none or it is damaged (the chunks'
    own tags still keep foreign ones out)."""
    if not (folder / KEY_FILE).exists():
        return None
    try:
        return json.loads((folder / KEY_FILE).read_text())
    except (OSError, ValueError):
        return None


def save_chunk(folder: Path, name: str, res: ChunkResult, tag: str = "") -> None:
    """Persist a finished chunk of job ``name`` at once (atomic rename), before it is merged.

    ``tag`` is :func:`chunk_tag` of the chunk's job and run key: on resume, a chunk whose
    tag differs from the job's is never merged (so an untagged one never is).
    """
    arrays = {
        "rec": res.rec,
        "rec0": res.rec0,
        "tail": res.tail,
        "hist": res.hist,
        "lam_rec": res.lam_rec,
        "lam_tail": res.lam_tail,
        "meta": np.array([res.chunk.first_block, res.chunk.n_blocks, res.first, res.count]),
        "seconds": np.array([res.seconds]),
        "backend": np.array([res.backend]),
    }
    if res.kept is not None:
        arrays.update({f"kept_{k}": v for k, v in res.kept.items()})
    save_arrays(folder / f"{name}__{res.chunk.first_block:09d}.npz", arrays, tag)


def chunks(folder: Path, st: JobState, tag: str) -> Iterator[ChunkResult]:
    """The chunks of ``st``'s job in ``folder`` that carry ``tag`` and fit its shapes.

    A chunk cut off by a crash, damaged, or left by another run (another seed or graph) is
    deleted and never merged: its blocks are simply computed again.
    """
    if not folder.is_dir():
        return
    name = st.job.name
    for p in sorted(folder.glob(f"{glob.escape(name)}__*.npz")):
        if p.name[: -len(".npz")].rsplit("__", 1)[0] != name:
            continue  # a job whose name begins with this one's, e.g. "a__b"
        res = _load_chunk(p, tag)
        if res is None or not _chunk_fits(st, res):
            with contextlib.suppress(OSError):
                p.unlink()
            continue
        yield res


def drop_chunks(folder: Path) -> None:
    """Delete every chunk file of ``folder`` (a checkpoint now holds them)."""
    for p in folder.glob("*.npz"):
        p.unlink()


def _load_chunk(p: Path, tag: str) -> ChunkResult | None:
    """The chunk saved in ``p``, or None if it is damaged or its tag is not ``tag``."""

    def read(z) -> ChunkResult:
        first_block, n_blocks, first, count = (int(x) for x in z["meta"])
        kept = None
        if "kept_status0" in z:
            kept = {k: z[f"kept_{k}"] for k in ("status0", "steps0", "status", "steps", "lambda")}
        return ChunkResult(
            Chunk(first_block, n_blocks),
            z["rec"],
            z["rec0"],
            z["tail"],
            z["hist"],
            z["lam_rec"],
            z["lam_tail"],
            kept,
            first,
            count,
            float(z["seconds"][0]),
            str(z["backend"][0]),
        )

    return load_arrays(p, tag, read)


def _chunk_fits(st: JobState, res: ChunkResult) -> bool:
    """Whether a loaded chunk has the shapes and position of a chunk of ``st``'s job."""
    c = res.chunk
    if c.n_blocks < 1 or c.first_block < 0 or c.first_block + c.n_blocks > st.done.size:
        return False
    if (res.first, res.count) != c.realizations(st.job.block_size, st.job.config.realizations):
        return False
    shapes = [
        (res.rec, (c.n_blocks, *st.rec.shape[1:])),
        (res.rec0, (c.n_blocks, *st.rec0.shape[1:])),
        (res.lam_rec, (c.n_blocks, *st.lam_rec.shape[1:])),
        (res.tail, st.tail.shape),
        (res.hist, st.hist.shape),
        (res.lam_tail, st.lam_tail.shape),
    ]
    if res.kept is not None:
        for k, arr in st.kept.items():
            got = res.kept[k]
            if got.shape[1:] != arr.shape[1:] or res.first + got.shape[0] > arr.shape[0]:
                return False
    return all(a.shape == shape for a, shape in shapes)


# ---- tagged array files ----------------------------------------------------------------------
# The one crash-safe file of finished work: a run's chunks above and a grid removal's tasks
# (antisync.grids.removal_journal) are both written and read by these two functions.
def save_arrays(path: Path, arrays: Mapping[str, np.ndarray], tag: str) -> None:
    """Write ``arrays`` and ``tag`` (array ``"tag"``) to the ``.npz`` file ``path`` at once.

    The file is written under a temporary name in the same folder, flushed to disk and renamed
    over ``path``: a reader (or a process killed at any moment) sees the whole file or none,
    and a failed write leaves no temporary file behind.
    """
    tmp = path.with_suffix(".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays, tag=np.array(tag))
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def load_arrays(path: Path, tag: str, read: Callable[[Any], T]) -> T | None:
    """``read(z)`` of the ``.npz`` file ``path`` (``z``: its arrays by name) when the file carries
    ``tag``; None when it carries another tag or none, or is damaged in any way (cut off, empty,
    not an ``.npz``, a missing array, a pickle refused, or ``read`` failing on it): its work is
    then simply done again."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["tag"][()]) != tag:
                return None
            return read(z)
    except Exception:  # any damage (a zip cut off, EOF, a bad header, a missing array, a
        return None  # pickle refused) means the same: that work is computed again


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename (whole or absent)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


# ---- a sweep's screening ---------------------------------------------------------------------
def load_screens(folder: Path) -> list[dict]:
    """The screening results saved by :func:`save_screen` (creating ``screen/`` if missing);
    one cut off by a crash is left out, and that graph is screened again."""
    cache = folder / SCREEN_FOLDER
    cache.mkdir(parents=True, exist_ok=True)
    out = []
    for p in cache.glob("*.json"):
        try:
            out.append(json.loads(p.read_text()))
        except (OSError, ValueError):
            continue
    return out


def save_screen(folder: Path, graph: str, result: dict) -> None:
    """Save the screening ``result`` of ``graph`` (atomic rename)."""
    path = folder / SCREEN_FOLDER / f"{graph}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(result))
    os.replace(tmp, path)


# ---- what the folder holds -------------------------------------------------------------------
def foreign_entry(folder: Path) -> str | None:
    """The first entry of the folder ``folder`` antisync did not write there, or None."""
    for p in sorted(folder.iterdir()):
        if p.is_symlink():
            return p.name
        if p.is_dir():
            if p.name != SCREEN_FOLDER:
                return p.name + "/"
            for q in p.iterdir():
                if q.is_symlink() or not q.is_file() or q.suffix not in (".json", ".tmp"):
                    return f"{SCREEN_FOLDER}/{q.name}"
        elif p.name not in (KEY_FILE, REPLACES_FILE, REPLACEMENT_FILE) and p.suffix not in (".npz", ".tmp"):
            return p.name
    return None


def is_empty(folder: Path) -> bool:
    """Whether ``folder`` holds no finished work: no chunk, no screening result and no
    checkpoint of a replacement."""
    if foreign_entry(folder) is not None:
        return False
    if any(folder.glob("*.npz")) or (folder / REPLACEMENT_FILE).exists():
        return False
    return not any((folder / SCREEN_FOLDER).glob("*.json"))
