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
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from antisync_cli import __version__, estimators
from antisync_cli.compute import ChunkResult
from antisync_cli.errors import StoreError
from antisync_cli.jobs import Chunk, Job

__all__ = ["FORMAT", "JobState", "ResultStore", "git_revision", "open_results"]

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


class ResultStore:
    """One HDF5 result file and its journal of finished chunks."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.journal = self.path.with_name(self.path.name + ".partial")

    # ---- opening -------------------------------------------------------------------------
    def prepare(self, *, resume: bool, overwrite: bool) -> None:
        """Check the output can be written as asked; nothing is modified unless ``overwrite``."""
        exists = self.path.exists() or self.journal.exists()
        if exists and not (resume or overwrite):
            raise StoreError(
                f"{self.path} already exists (or an interrupted run left {self.journal.name}); "
                "pass --resume to finish it, --overwrite to replace it, or --out for a new file"
            )
        if self.path.exists() and self.path.is_dir():
            raise StoreError(f"output {self.path} is a directory; give a file path ending in .h5")
        parent = self.path.parent
        if parent.exists() and not os.access(parent, os.W_OK):
            raise StoreError(f"cannot write to folder {parent}")
        if overwrite and not resume:
            if self.path.exists():
                self.path.unlink()
            if self.journal.exists():
                shutil.rmtree(self.journal)

    def load_states(self, jobs: list[Job], config_key: dict) -> dict[str, JobState]:
        """States for ``jobs``: from the HDF5 file when present, plus journal chunks."""
        states = {job.name: JobState(job) for job in jobs}
        if self.path.exists():
            with open_results(self.path) as f:
                stored = json.loads(f.attrs.get("simulation_key", "{}"))
                if stored != json.loads(json.dumps(config_key)):
                    raise StoreError(
                        f"{self.path} was made with a different config (graph, edges, betas, "
                        "dynamics, realizations, seed or histogram differ); use --out for a new file"
                    )
                for name, st in states.items():
                    if f"jobs/{name}" in f:
                        _read_state(f[f"jobs/{name}"], st)
        elif (self.journal / "simulation_key.json").exists():
            stored = json.loads((self.journal / "simulation_key.json").read_text())
            if stored != json.loads(json.dumps(config_key)):
                raise StoreError(
                    f"{self.journal} holds chunks of a different config; remove it or use --out"
                )
        for name, st in states.items():
            for res in self._journal_chunks(name):
                sl = slice(res.chunk.first_block, res.chunk.first_block + res.chunk.n_blocks)
                if not st.done[sl].any():
                    st.add(res)
        return states

    # ---- writing -------------------------------------------------------------------------
    def start_journal(self, config_key: dict) -> None:
        self.journal.mkdir(parents=True, exist_ok=True)
        _atomic_write_bytes(self.journal / "simulation_key.json", json.dumps(config_key).encode())

    def save_chunk(self, name: str, res: ChunkResult) -> None:
        """Persist a finished chunk at once (atomic rename), before it is merged."""
        arrays = {
            "rec": res.rec, "rec0": res.rec0, "tail": res.tail, "hist": res.hist,
            "lam_rec": res.lam_rec, "lam_tail": res.lam_tail,
            "meta": np.array([res.chunk.first_block, res.chunk.n_blocks, res.first, res.count]),
            "seconds": np.array([res.seconds]),
            "backend": np.array([res.backend]),
        }
        if res.kept is not None:
            arrays.update({f"kept_{k}": v for k, v in res.kept.items()})
        target = self.journal / f"{name}__{res.chunk.first_block:09d}.npz"
        tmp = target.with_suffix(".tmp")
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)

    def checkpoint(self, states: dict[str, JobState], provenance: dict, *, final: bool = False,
                   extra=None) -> None:
        """Rewrite the HDF5 file from ``states`` atomically, then drop merged journal chunks.

        ``provenance`` keys beyond the standard ones become root attributes too; ``extra``, when
        given, is called as ``extra(h5file, states)`` before the file is closed, to add groups
        (a sweep's screening and symmetry data) that must survive every checkpoint.
        """
        import h5py

        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".tmp")
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
        if self.journal.exists():
            for p in self.journal.glob("*.npz"):
                p.unlink()
            if final:
                shutil.rmtree(self.journal, ignore_errors=True)

    def _journal_chunks(self, name: str):
        if not self.journal.exists():
            return
        for p in sorted(self.journal.glob(f"{name}__*.npz")):
            try:
                with np.load(p) as z:
                    first_block, n_blocks, first, count = (int(x) for x in z["meta"])
                    kept = None
                    if "kept_status0" in z:
                        kept = {k: z[f"kept_{k}"]
                                for k in ("status0", "steps0", "status", "steps", "lambda")}
                    yield ChunkResult(
                        Chunk(first_block, n_blocks), z["rec"], z["rec0"], z["tail"], z["hist"],
                        z["lam_rec"], z["lam_tail"], kept, first, count, float(z["seconds"][0]),
                        str(z["backend"][0]),
                    )
            except (OSError, ValueError, KeyError):
                continue  # a chunk file cut off by a crash: its blocks are simply redone


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
    if f.attrs.get("format") != FORMAT:
        f.close()
        raise StoreError(f"{path} is an HDF5 file but not an antisync result file (no format={FORMAT!r})")
    if int(f.attrs.get("format_version", 0)) > FORMAT_VERSION:
        f.close()
        raise StoreError(f"{path} was written by a newer antisync (format {f.attrs['format_version']})")
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
        from antisync_cli.measures.pipeline import write_measures

        write_measures(g, st.measures, cfg, st.measures_seconds)
    from antisync_cli.summary import job_records  # late: summary reads this module's layout

    g.attrs["summary_json"] = json.dumps(job_records(_view_from_state(st)))


def _read_state(g, st: JobState) -> None:
    if g["block_records"].shape != st.rec.shape or g["hist"].shape != st.hist.shape:
        raise StoreError(f"group {g.name} does not match the config's edges, betas or histogram")
    st.rec[...] = g["block_records"][...]
    st.rec0[...] = g["tau0_records"][...]
    st.done[...] = g["blocks_done"][...]
    st.tail[...] = g["tail_counts"][...]
    st.lam_rec[...] = g["lambda_records"][...]
    st.lam_tail[...] = g["lambda_tail_counts"][...]
    st.hist[...] = g["hist"][...]
    for key in st.kept:
        st.kept[key][...] = g["kept"][key][...]
    st.seconds = float(g.attrs["seconds"])
    st.backends = set(str(g.attrs["backend"]).split(",")) - {""}
    if "measures" in g:
        from antisync_cli.measures.pipeline import read_measures

        st.measures = read_measures(g)
        st.measures_seconds = float(g["measures"].attrs.get("seconds", 0.0))


def _view_from_state(st: JobState):
    from antisync_cli.summary import JobView

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
    return " ".join([Path(sys.argv[0]).name] + sys.argv[1:])
