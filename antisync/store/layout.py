"""The HDF5 layout of result files: every group, attribute and dataset is read and written here.

Layout (one file per run or sweep)::

    /                      attrs: format="antisync-results", format_version, antisync_version,
                                  git_revision, command, created, config_yaml, complete
    /jobs/<name>/          one group per graph (``lollipop6``, ``G105``, ...)
        attrs:             graph, nodes (JSON), edges (JSON), betas, dbeta, seed, backend,
                           block_size, realizations, realizations_done, seconds, complete,
                           tau0 status counts, summary_json, kuramoto (false for measures
                           without km: no blocks, no variants, realizations 0)
        omega              (N, N) weights
        variant_edge       (V,) index into edges          variant_beta  (V,) damage
        blocks_done        (n_blocks,) bool               hist_variants (H,) variant indices
        block_records      (n_blocks, V, 7)  n, n_already, n_not_synced, sum d, sum d^2,
                                             sum tau, sum tau^2  (d = F - 1)
        tau0_records       (n_blocks, 5)     n, n_already, n_not_synced, sum tau0, sum tau0^2
        tail_counts        (V, bins) int64   log histogram of |F - 1|
        lambda_records     (n_blocks, E, 10) n, n_already, n_not_synced, sum L, sum L^2, n_flagged
                                             of the per-realization Lambda estimates (attrs
                                             lambda_method and lambda_quantity say which
                                             estimator and quantity), n_lost, n_gained (tau0
                                             synchronized and tau(dbeta) not, and the reverse;
                                             finite difference; format 3), sum_slope_tau,
                                             sum_tau0 (Lambda^tau; format 4)
        lambda_tail_counts (E, 2 bins) int64 signed log histogram of Lambda per realization
        hist               (H, bins, bins) int64, [v, i_tau0, i_tau_beta] on [0, tau_max)
        r_star             (1 + V,) float64, only with sync.criterion relative: r* of the
                           undamaged network's stable locked state, then of each variant's
                           (absent from files written before it was stored: read as None)
        kept/status0, kept/steps0, kept/status, kept/steps, kept/lambda: the first keep_pairs
                           realizations (steps are integration steps: tau = steps * dt;
                           status -1 = not run; lambda = per-realization estimate per edge)
        measures/          only with linear, xi2 or rw in measures: one (E,) dataset per value
                           (lambda_xi2, lambda_rw, lambda_linear, lambda_linear_se,
                           lambda_linear_n, ...) aligned with edges; attrs measures, coupling,
                           linear_method, linear_realizations, linear_dbeta, linear_seed, seconds
        attrs nnc_of:      on the raw-coupling twin ``<name>_nnc`` of job <name> (km_nnc)
    /sweep/                only in a sweep's file: attrs format="antisync-sweep", format_version;
        meta_json          the family, thresholds, every graph's screening and orbits, every
                           job's stage (see :func:`write_sweep_meta`)

Nothing else in antisync opens an HDF5 file: runs are written through
:class:`~antisync.store.result_store.ResultStore` (:func:`write_results`,
:func:`read_states`), and readers get decoded jobs (:func:`read_views`, one
:class:`~antisync.stats.summary.JobView` per job group), summary records (:func:`records`) or a
sweep's metadata (:func:`read_meta`). ``h5py`` is imported only when a file is opened.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from antisync._version import __version__
from antisync.errors import StoreError
from antisync.measures.pipeline import COMPUTED
from antisync.plan.jobs import Job
from antisync.plan.model import unsynced_hint
from antisync.stats import estimators
from antisync.stats.summary import JobView, job_records, view_records
from antisync.store.journal import digest_graph, graph_digest, jsonable
from antisync.store.provenance import now
from antisync.store.state import JobState

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "config_changes",
    "SWEEP_FORMAT",
    "SWEEP_FORMAT_VERSION",
    "is_complete",
    "is_sweep_file",
    "open_results",
    "read_measures",
    "read_meta",
    "read_states",
    "read_sweep_meta",
    "read_views",
    "records",
    "result_file_problem",
    "write_measures",
    "write_results",
    "write_sweep_meta",
]

FORMAT = "antisync-results"
# format 2: lambda_tail_counts is signed, (E, 2 TAIL_BINS); format-1 files ((E, TAIL_BINS)) are
# read, and their Lambda intervals fall back to batch means (summary.py says so in the record)
# format 3: lambda_records gain n_lost and n_gained (the synchronized fraction's response); in
# older files they read as NaN (not counted, never 0)
# format 4: lambda_records gain sum_slope_tau and sum_tau0 (the additive response Lambda^tau)
# and job groups the attribute lambda_quantity; in older files they read as NaN (a format-3
# file is resumed with NaN there: its Lambda^tau stays undefined)
FORMAT_VERSION = 4
# lambda_records' fields before format 3 and before format 4
_LAMBDA_FIELDS_V2 = 6
_LAMBDA_FIELDS_V3 = 8
SWEEP_FORMAT = "antisync-sweep"
SWEEP_FORMAT_VERSION = 2


# ---- opening ---------------------------------------------------------------------------------
def open_results(path: str | Path):
    """Open an antisync HDF5 file for reading, with a clear :class:`StoreError` otherwise."""
    # lazy: h5py only where a file is opened; execution.compute and `validate` load the store
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
        raise StoreError(
            f"{path} is damaged: its root attributes cannot be read ({type(exc).__name__})"
        ) from None
    if fmt != FORMAT:
        f.close()
        raise StoreError(f"{path} is an HDF5 file but not an antisync result file (no format={FORMAT!r})")
    try:
        version = int(raw_version)
    except (TypeError, ValueError):
        f.close()
        raise StoreError(
            f"{path} is damaged: root attribute format_version is {raw_version!r}, not an integer"
        ) from None
    if version > FORMAT_VERSION:
        f.close()  # the attributes were read above: after close() they cannot be
        raise StoreError(
            f"{path} was written by a newer antisync (format {version}); this one "
            f"reads format {FORMAT_VERSION} — upgrade antisync"
        )
    return f


def result_file_problem(path: Path) -> str | None:
    """What ``path`` is when it is not an antisync result file (None when it is one).

    ``--overwrite`` replaces only antisync result files (a run's or a sweep's).
    """
    # lazy: h5py only where a file is opened; execution.compute and `validate` load the store
    import h5py

    what = None
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != FORMAT:
                what = f"an HDF5 file without format={FORMAT!r}"
    except OSError:
        what = "not an HDF5 file"
    except Exception as exc:  # unreadable root attributes: not a result file we wrote
        what = f"an HDF5 file with unreadable attributes ({type(exc).__name__})"
    return what


def root_attrs(path: Path) -> dict:
    """The provenance a reader wants without the data: ``config_yaml``, ``complete``,
    ``antisync_version``, ``git_revision``, ``command``, ``created``, ``updated``."""
    keys = ("config_yaml", "antisync_version", "git_revision", "command", "created", "updated")
    with open_results(path) as f:
        out = {k: str(f.attrs.get(k, "")) for k in keys}
        out["complete"] = bool(f.attrs.get("complete", False))
    return out


def stored_config(path: Path) -> dict:
    """The config a result file stores (root attribute ``config_yaml``) as a mapping: what every
    reader (the summary's model line, the report's names, :func:`antisync.summarize`) decodes,
    here, with one policy (:func:`decode_config`)."""
    return decode_config(root_attrs(path)["config_yaml"], path)


def decode_config(text: str, where) -> dict:
    """``text`` (a result file's ``config_yaml``) as a mapping; ``{}`` when it is empty (a file
    written without one).

    Raises
    ------
    StoreError
        ``where`` is damaged: the text is not YAML, or not a mapping of config keys.
    """
    try:
        cfg = yaml.safe_load(text or "{}")
    except yaml.YAMLError:
        raise StoreError(f"{where} is damaged: its root attribute config_yaml is not YAML") from None
    if cfg is None:
        return {}
    if not isinstance(cfg, dict):
        raise StoreError(
            f"{where} is damaged: its root attribute config_yaml is not a mapping of config keys "
            f"(a {type(cfg).__name__})"
        )
    return cfg


def stop_record(path: Path) -> dict | None:
    """The stopping rule's record of a run that had one (root attribute ``stop_json``: rule,
    looks, budget, ``stopped_at``, the last look's counts), else None."""
    with open_results(path) as f:
        raw = f.attrs.get("stop_json")
        if raw is None:
            return None
        record = _read(path, "root attribute stop_json", lambda: json.loads(str(raw)))
    look = record.get("last_look") if isinstance(record, dict) else None
    if not isinstance(look, dict) or not _STOP_KEYS <= set(record) or not _LOOK_KEYS <= set(look):
        raise StoreError(f"{path} is damaged: root attribute stop_json lacks the stopping rule's fields")
    return record


def step_check_records(path: Path) -> dict[str, dict]:
    """Each checked job's record of the explicit step checked again at ``dt / 2`` (root attribute
    ``step_check_json``, :func:`antisync.execution.step_check.step_record`); ``{}`` for a file
    whose jobs were not checked (the paper's identical oscillators, Rodas4, files written before
    the check was stored)."""
    with open_results(path) as f:
        raw = f.attrs.get("step_check_json")
        if raw is None:
            return {}
        records = _read(path, "root attribute step_check_json", lambda: json.loads(str(raw)))
    if not isinstance(records, dict) or not all(
        isinstance(r, dict) and {"starts", "dt", "changed", "passed"} <= set(r) for r in records.values()
    ):
        raise StoreError(f"{path} is damaged: root attribute step_check_json lacks the step check's fields")
    return records


_STOP_KEYS = {"when", "tolerance", "looks", "level", "budget", "stopped_at", "stopped_early", "last_look"}
_LOOK_KEYS = {"realizations", "level", "links", "resolved", "settled", "unresolved"}


def stopped_early(path: Path, config_key: dict) -> dict | None:
    """:func:`stop_record` of ``path`` when it is complete, was made with ``config_key`` and
    its stopping rule ended it before the budget (its groups then hold fewer realizations than
    the config asks for: nothing is left to resume)."""
    if not is_complete(path):
        return None
    record = stop_record(path)
    if record is None or not record.get("stopped_early"):
        return None
    with open_results(path) as f:
        raw = f.attrs.get("simulation_key", "{}")
        stored = _read(path, "root attribute simulation_key", lambda: json.loads(str(raw)))
    return record if stored == config_key else None


def is_complete(path: Path) -> bool:
    """Whether the file ``path`` exists and says every job (every stage of a sweep) finished."""
    if not path.is_file():
        return False
    with open_results(path) as f:
        try:
            return bool(f.attrs.get("complete", False))
        except (TypeError, ValueError, OSError):
            return False


# ---- a run's jobs: writing and resuming -------------------------------------------------------
def write_results(path: Path, states: dict[str, JobState], provenance: dict, extra=None) -> None:
    """Write a whole result file at ``path`` from ``states`` (a checkpoint's temporary file).

    ``provenance`` keys beyond the standard ones become root attributes too; ``extra``, when
    given, is called as ``extra(h5file, states)`` before the file is closed, to add groups
    (a sweep's metadata, :func:`write_sweep_meta`) that must survive every checkpoint.
    """
    # lazy: h5py only where a file is opened; execution.compute and `validate` load the store
    import h5py

    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["antisync_version"] = __version__
        f.attrs["created"] = provenance.get("created", now())
        f.attrs["updated"] = now()
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


def read_states(path: Path, states: dict[str, JobState], config_key: dict) -> None:
    """Fill ``states`` from the job groups of ``path`` (a job without a group stays empty).

    Raises
    ------
    StoreError
        The file was made with another simulation key, or a job group with another graph
        (see :func:`~antisync.store.journal.graph_digest`), or a group is damaged or does not
        fit its job's shapes.
    """
    with open_results(path) as f:
        stored = _read(
            path, "root attribute simulation_key", lambda: json.loads(f.attrs.get("simulation_key", "{}"))
        )
        if stored != config_key:
            raise StoreError(
                f"{path} was made with a different config ({config_changes(stored, config_key)}); "
                "use --out for a new file, or resume with the stored values"
            )
        for name, st in states.items():
            if f"jobs/{name}" in f:
                g = f[f"jobs/{name}"]
                _check_graph(path, g, st.job)
                _read_state(path, g, st)


def config_changes(stored: dict, wanted: dict, most: int = 6) -> str:
    """The keys whose values differ between two simulation keys, as ``key: stored -> new``
    (dotted paths into nested sections, e.g. ``dynamics.t_max: 60 -> 80``; ``(absent)`` for a
    key one side lacks), the first ``most`` of them and a count of the rest: what a refused
    ``--resume`` names, so that the user sees what changed rather than every key."""
    changes = [f"{key}: {_shown(old)} -> {_shown(new)}" for key, old, new in _differences(stored, wanted, "")]
    if not changes:
        return "no key differs"
    more = f"; and {len(changes) - most} more" if len(changes) > most else ""
    return "; ".join(changes[:most]) + more


_ABSENT = object()


def _differences(old, new, prefix: str):
    """``(dotted key, old value, new value)`` of every leaf that differs, depth first."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in list(old) + [k for k in new if k not in old]:
            yield from _differences(old.get(key, _ABSENT), new.get(key, _ABSENT), f"{prefix}{key}.")
    elif old != new:
        yield prefix.rstrip("."), old, new


def _shown(value, width: int = 60) -> str:
    if value is _ABSENT:
        return "(absent)"
    text = json.dumps(value, default=str)
    return text if len(text) <= width else text[: width - 3] + "..."


def _write_state(g, st: JobState) -> None:
    job = st.job
    cfg = job.config
    g.attrs["graph"] = job.name
    g.attrs["graph_digest"] = graph_digest(job)  # compared on --resume
    g.attrs["nodes"] = json.dumps([jsonable(v) for v in job.nodes])
    g.attrs["edges"] = json.dumps(job.edge_labels)
    g.attrs["betas"] = np.array(job.betas, dtype=np.float64)
    g.attrs["dbeta"] = job.dbeta
    g.attrs["lambda_method"] = cfg.lambda_.method
    g.attrs["lambda_quantity"] = estimators.LAMBDA_QUANTITY[cfg.lambda_.method]
    g.attrs["seed"] = cfg.seed
    g.attrs["dt"] = cfg.dynamics.dt
    g.attrs["threshold"] = cfg.dynamics.threshold
    g.attrs["coupling"] = cfg.dynamics.coupling
    g.attrs["tau_max_hist"] = cfg.histogram.tau_max
    g.attrs["backend"] = ",".join(sorted(st.backends)) or cfg.backend
    g.attrs["block_size"] = job.block_size
    g.attrs["realizations"] = job.realizations  # 0 without km: no Kuramoto integration
    g.attrs["kuramoto"] = job.kuramoto
    g.attrs["realizations_done"] = st.realizations_done
    g.attrs["seconds"] = st.seconds
    g.attrs["complete"] = st.complete
    g.attrs["block_fields"] = json.dumps(list(estimators.BLOCK_FIELDS))
    g.attrs["tau0_fields"] = json.dumps(list(estimators.TAU0_FIELDS))
    g.attrs["lambda_fields"] = json.dumps(list(estimators.LAMBDA_FIELDS))
    g.create_dataset("omega", data=job.omega, compression="gzip", compression_opts=1)
    g.create_dataset("variant_edge", data=job.variant_edge)
    g.create_dataset("variant_beta", data=job.variant_beta)
    g.create_dataset("hist_variants", data=job.hist_variants)
    g.create_dataset("blocks_done", data=st.done)
    g.create_dataset("block_records", data=st.rec, compression="gzip", compression_opts=1)
    g.create_dataset("tau0_records", data=st.rec0, compression="gzip", compression_opts=1)
    g.create_dataset("tail_counts", data=st.tail, compression="gzip", compression_opts=1)
    g.create_dataset("lambda_records", data=st.lam_rec, compression="gzip", compression_opts=1)
    g.create_dataset("lambda_tail_counts", data=st.lam_tail, compression="gzip", compression_opts=1)
    g.create_dataset("hist", data=st.hist, compression="gzip", compression_opts=1)
    kept = g.create_group("kept")
    for key, arr in st.kept.items():
        kept.create_dataset(key, data=arr, compression="gzip", compression_opts=1)
    if job.nnc_of:
        g.attrs["nnc_of"] = job.nnc_of
    hint = unsynced_hint(cfg)
    if hint:
        g.attrs["unsynced_hint"] = hint
    r_star = _r_star(job)
    if r_star is not None:
        g.create_dataset("r_star", data=r_star)
    if st.measures is not None:
        write_measures(g, st.measures, cfg, st.measures_seconds)
    g.attrs["summary_json"] = json.dumps(job_records(state_view(st)))


def _r_star(job: Job) -> np.ndarray | None:
    """``job``'s r* per trajectory kind (undamaged, then each variant) with ``sync.criterion:
    relative`` (:class:`antisync.plan.model.ModelSetup`, or a law's
    :class:`antisync.plan.model.LawSetup`), else None."""
    setup = job.model if job.model is not None else job.law
    if setup is None or setup.r_star is None:
        return None
    return np.asarray(setup.r_star, dtype=np.float64)


def _read_state(path: Path, g, st: JobState) -> None:
    """Fill ``st`` from job group ``g`` of ``path``; a damaged or mismatched group is an error."""
    arrays = {
        "block_records": st.rec,
        "tau0_records": st.rec0,
        "blocks_done": st.done,
        "tail_counts": st.tail,
        "lambda_records": st.lam_rec,
        "lambda_tail_counts": st.lam_tail,
        "hist": st.hist,
    }
    arrays.update({f"kept/{k}": v for k, v in st.kept.items()})
    for name, target in arrays.items():
        data = _read(path, f"{g.name}/{name}", lambda name=name: g[name][...])
        if name == "lambda_records" and data.shape == target.shape[:-1] + (_LAMBDA_FIELDS_V2,):
            raise StoreError(
                f"{path} was written by an older antisync (format 2, without the counts of "
                "realizations that lose or gain synchronization): summary and report read it, "
                "but it cannot be resumed; use --out for a new file"
            )
        if name == "lambda_records" and data.shape == target.shape[:-1] + (_LAMBDA_FIELDS_V3,):
            data = _lambda_records(data)  # format 3: Lambda^tau's sums unknown (NaN)
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
        st.measures = _read(path, f"{g.name}/measures", lambda: read_measures(g))
        st.measures_seconds = _read(
            path,
            f"{g.name}/measures attribute seconds",
            lambda: float(g["measures"].attrs.get("seconds", 0.0)),
        )


def state_view(st: JobState) -> JobView:
    """A run's job in memory as a :class:`~antisync.stats.summary.JobView` (what a checkpoint's
    summary and the stopping rule read)."""
    job = st.job
    return JobView(
        graph=job.name,
        edges=job.edge_labels,
        betas=job.betas,
        dbeta=job.dbeta,
        variant_edge=job.variant_edge,
        variant_beta=job.variant_beta,
        rec=st.rec,
        rec0=st.rec0,
        done=st.done,
        tail=st.tail,
        realizations=job.realizations,
        lam_rec=st.lam_rec,
        lam_tail=st.lam_tail,
        lambda_method=job.config.lambda_.method,
        attrs={"lambda_quantity": estimators.LAMBDA_QUANTITY[job.config.lambda_.method]},
        measures=st.measures,
        unsynced_hint=unsynced_hint(job.config),
        r_star=_r_star(job),
    )


def _check_graph(path: Path, g, job: Job) -> None:
    stored = _read(path, f"{g.name} graph_digest", lambda: g.attrs.get("graph_digest"))
    if stored is None:  # written before graph digests: digest what the group stores
        stored = _read(
            path,
            f"{g.name} graph",
            lambda: digest_graph(
                json.loads(g.attrs["nodes"]),
                json.loads(g.attrs["edges"]),
                g["omega"][...],
                g["variant_edge"][...],
                g["variant_beta"][...],
            ),
        )
    if str(stored) != graph_digest(job):
        raise StoreError(
            f"{path} was made with a different graph for {job.name} ({_graph_changes(path, g, job)} "
            "differ from the graph built now: a random generator without a seed?); "
            "use --out for a new file"
        )


def _graph_changes(path: Path, g, job: Job) -> str:
    """Which parts of the graph of group ``g`` differ from ``job``'s: nodes, damaged edges,
    weights (omega), the damage variants."""
    parts = {
        "nodes": (lambda: json.loads(g.attrs["nodes"]), [jsonable(v) for v in job.nodes]),
        "damaged edges": (lambda: json.loads(g.attrs["edges"]), list(job.edge_labels)),
        "weights": (lambda: g["omega"][...], job.omega),
        "damage variants": (
            lambda: np.concatenate([g["variant_edge"][...], g["variant_beta"][...]]),
            np.concatenate([job.variant_edge, job.variant_beta]),
        ),
    }
    changed = []
    for name, (read, now_value) in parts.items():
        stored = _read(path, f"{g.name} {name}", read)
        same = (
            np.shape(stored) == np.shape(now_value) and np.array_equal(stored, now_value)
            if isinstance(stored, np.ndarray)
            else stored == now_value
        )
        if not same:
            changed.append(name)
    return " and ".join(changed) if changed else "the node order or weights"


def _read(path: Path, what: str, read):
    """``read()``, with damage reported as one :class:`StoreError` naming the file and ``what``."""
    try:
        return read()
    except KeyError:
        raise StoreError(f"{path} is damaged: {what} is missing; use --out for a new file") from None
    except (OSError, ValueError, TypeError) as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise StoreError(
            f"{path} is damaged: {what} cannot be read ({why}); use --out for a new file"
        ) from None


# ---- a job's measures (Lambda^(linear, xi2, RW), see antisync.measures.pipeline) -----------
def write_measures(group, values: dict, config, seconds: float = 0.0) -> None:
    """Write ``values`` (from :func:`~antisync.measures.pipeline.compute_measures`) into a new
    ``measures`` subgroup of job group ``group``.

    Layout: one dataset per key, length E and aligned with the job's ``edges`` attribute;
    attrs ``measures`` (JSON list of the computed measures), ``coupling``, ``seconds`` and,
    with ``linear``, ``linear_method``, ``linear_realizations``, ``linear_dbeta``,
    ``linear_seed`` (realizations ``0 .. linear_realizations - 1`` of that seed).
    """
    m = group.create_group("measures")
    done = [name for name in COMPUTED if any(k == f"lambda_{name}" for k in values)]
    m.attrs["measures"] = json.dumps(done)
    m.attrs["coupling"] = config.dynamics.coupling
    m.attrs["rw_coupling"] = "normalized"
    m.attrs["seconds"] = float(seconds)
    if "linear" in done:
        m.attrs["linear_method"] = config.linear.method
        m.attrs["linear_realizations"] = int(config.linear.realizations)
        m.attrs["linear_dbeta"] = float(config.lambda_.dbeta)
        m.attrs["linear_seed"] = int(config.seed)
    for key, arr in values.items():
        m.create_dataset(key, data=np.asarray(arr))


def read_measures(group) -> dict[str, np.ndarray] | None:
    """The arrays of a job group's ``measures`` subgroup, or ``None`` if it has none."""
    if "measures" not in group:
        return None
    return {key: ds[...] for key, ds in group["measures"].items()}


# ---- reading jobs ----------------------------------------------------------------------------
def read_views(path: str | Path) -> list[JobView]:
    """All jobs of a result file.

    Raises
    ------
    StoreError
        The file is not an antisync result file, or a job's attribute or dataset is missing,
        malformed (an ``edges`` that is not JSON, a shape that does not fit) or unreadable:
        the message names the file, the job and what is damaged.
    """
    views = []
    with open_results(path) as f:
        if "jobs" not in f:
            raise StoreError(f"{path} has no jobs group: not a complete antisync result file")
        for name, g in f["jobs"].items():
            r = _GroupReader(path, name, g)
            edges = r.attr("edges", _json_list)
            nodes = r.attr("nodes", _json_list)
            view = JobView(
                graph=r.attr("graph", str),
                edges=edges,
                betas=r.attr("betas", lambda b: tuple(float(x) for x in np.atleast_1d(b))),
                dbeta=r.attr("dbeta", float),
                variant_edge=r.data("variant_edge"),
                variant_beta=r.data("variant_beta"),
                rec=r.data("block_records"),
                rec0=r.data("tau0_records"),
                done=r.data("blocks_done").astype(bool),
                tail=r.data("tail_counts"),
                realizations=r.attr("realizations", int),
                hist=r.data("hist"),
                hist_variants=r.data("hist_variants"),
                tau_max_hist=r.attr("tau_max_hist", float),
                omega=r.data("omega"),
                lam_rec=_lambda_records(r.data("lambda_records")),
                lam_tail=r.data("lambda_tail_counts"),
                lambda_method=r.attr("lambda_method", str),
                nodes=nodes,
                attrs=r.read("attributes", r.plain_attrs),
                measures=r.read("measures group", r.measures),
                unsynced_hint=str(g.attrs["unsynced_hint"]) if "unsynced_hint" in g.attrs else None,
                r_star=r.optional("r_star", np.float64),
            )
            problem = _shape_problem(view)
            if problem:
                raise StoreError(f"{path}: job {name} is damaged: {problem}")
            views.append(view)
    return views


class _GroupReader:
    """Reads one job group of ``path``; anything missing or malformed is a one-line
    :class:`StoreError` naming the file, the job and the attribute or dataset."""

    def __init__(self, path, name: str, group):
        self.path, self.name, self.group = path, name, group

    def read(self, what: str, get):
        try:
            return get()
        except KeyError:
            raise StoreError(f"{self.path}: job {self.name} lacks {what}; the file is damaged") from None
        except Exception as exc:  # h5py: OSError; json: ValueError; casts: TypeError
            why = " ".join(str(exc).split()) or type(exc).__name__
            raise StoreError(f"{self.path}: job {self.name} has a damaged {what} ({why})") from None

    def data(self, key: str) -> np.ndarray:
        return self.read(f"dataset {key!r}", lambda: self.group[key][...])

    def optional(self, key: str, dtype) -> np.ndarray | None:
        """Dataset ``key`` as ``dtype``, or None where the group has none (an older file)."""
        if key not in self.group:
            return None
        return self.read(f"dataset {key!r}", lambda: self.group[key][...].astype(dtype))

    def attr(self, key: str, cast):
        return self.read(f"attribute {key!r}", lambda: cast(self.group.attrs[key]))

    def plain_attrs(self) -> dict:
        return {k: self.group.attrs[k] for k in self.group.attrs if k != "summary_json"}

    def measures(self) -> dict | None:
        return read_measures(self.group)


def _lambda_records(rec: np.ndarray) -> np.ndarray:
    """``lambda_records`` with the fields of this format: a format 1-2 file's lack ``n_lost``
    and ``n_gained``, a format 3 file's ``sum_slope_tau`` and ``sum_tau0``; they read as NaN
    (unknown, not zero)."""
    if rec.ndim == 3 and rec.shape[-1] in (_LAMBDA_FIELDS_V2, _LAMBDA_FIELDS_V3):
        pad = np.full(rec.shape[:2] + (len(estimators.LAMBDA_FIELDS) - rec.shape[-1],), np.nan)
        return np.concatenate([rec, pad], axis=-1)
    return rec


def _json_list(raw) -> list:
    """A JSON list stored as a string attribute (``edges``, ``nodes``)."""
    value = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    if not isinstance(value, list):
        raise ValueError(f"expected a JSON list, got {type(value).__name__}")
    return value


def _shape_problem(view: JobView) -> str | None:
    """Why the arrays of ``view`` cannot belong together (None when they can)."""
    if view.done.ndim != 1 or view.variant_edge.ndim != 1 or view.hist_variants.ndim != 1:
        return "datasets 'blocks_done', 'variant_edge' and 'hist_variants' must be one-dimensional"
    nb, nv, ne = view.done.shape[0], len(view.variant_edge), len(view.edges)
    bins = view.hist.shape[-1] if view.hist.ndim == 3 else -1
    expected = {
        "blocks_done": (view.done, (nb,)),
        "variant_beta": (view.variant_beta, (nv,)),
        "block_records": (view.rec, (nb, nv, len(estimators.BLOCK_FIELDS))),
        "tau0_records": (view.rec0, (nb, len(estimators.TAU0_FIELDS))),
        "lambda_records": (view.lam_rec, (nb, ne, len(estimators.LAMBDA_FIELDS))),
        "tail_counts": (view.tail, (nv, estimators.TAIL_BINS)),
        "lambda_tail_counts": (view.lam_tail, (ne, estimators.LAMBDA_TAIL_BINS)),
        "hist": (view.hist, (len(view.hist_variants), bins, bins)),
    }
    if view.lam_tail.shape == (ne, estimators.TAIL_BINS):  # a format-1 file: |Lambda| only
        del expected["lambda_tail_counts"]
    for key, (arr, shape) in expected.items():
        if arr.shape != shape:
            return f"dataset {key!r} has shape {arr.shape}, expected {shape} from its edges and blocks"
    if nv and (view.variant_edge.min() < 0 or view.variant_edge.max() >= ne):
        return "dataset 'variant_edge' points past the edges attribute"
    if view.hist_variants.size and (view.hist_variants.min() < 0 or view.hist_variants.max() >= nv):
        return "dataset 'hist_variants' points past the variants"
    if view.r_star is not None and view.r_star.shape != (1 + nv,):
        return f"dataset 'r_star' has shape {view.r_star.shape}, expected {(1 + nv,)} from its variants"
    return None


def records(path: str | Path) -> list[dict]:
    """Summary records of every job in a result file (see :func:`antisync.stats.summary.job_records`,
    which also covers a job run without ``km``); each run's
    ``lambda_km_nnc`` comes from its raw-coupling twin."""
    return view_records(read_views(path))


# ---- a sweep's metadata ----------------------------------------------------------------------
def write_sweep_meta(f, meta: dict) -> None:
    """Write a sweep's metadata into the open result file ``f`` (from a checkpoint's ``extra``).

    ``meta["complete"]`` (every stage finished) is also the root attribute ``complete``, as
    for a run's file.
    """
    f.attrs["complete"] = meta["complete"]
    grp = f.create_group("sweep")
    grp.attrs["format"] = SWEEP_FORMAT
    grp.attrs["format_version"] = SWEEP_FORMAT_VERSION
    grp.create_dataset("meta_json", data=json.dumps(meta))


def is_sweep_file(path: str | Path) -> bool:
    """Whether ``path`` is an antisync result file written by a sweep."""
    with open_results(path) as f:
        try:
            return "sweep" in f and f["sweep"].attrs.get("format") == SWEEP_FORMAT
        except Exception as exc:  # h5py reports a damaged group as OSError, KeyError, ...
            raise StoreError(
                f"{path} is damaged: its /sweep group cannot be read ({type(exc).__name__})"
            ) from None


# what sweep_summary and the reports read from /sweep/meta_json: checked once, on reading
_META_KEYS = {
    "name": str,
    "family": dict,
    "thresholds": list,
    "ranking_threshold": (int, float),
    "graphs": list,
    "jobs": list,
    "symmetry": dict,
}
_META_GRAPH_KEYS = ("graph", "orbits", "excluded")
_META_JOB_KEYS = ("job", "graph", "stage", "threshold", "repeat")


def read_sweep_meta(path: str | Path) -> dict | None:
    """The ``/sweep`` metadata, None for a run file; a damaged one is a :class:`StoreError`."""
    with open_results(path) as f:
        try:
            if "sweep" not in f:
                return None
            grp = f["sweep"]
            raw_version = grp.attrs.get("format_version", 0)
            raw = grp["meta_json"][()]
        except Exception as exc:  # a damaged group: OSError, KeyError, ... from h5py
            raise StoreError(
                f"{path} is damaged: /sweep/meta_json cannot be read ({type(exc).__name__})"
            ) from None
    try:
        version = int(raw_version)
    except (TypeError, ValueError):
        raise StoreError(
            f"{path} is damaged: /sweep attribute format_version is {raw_version!r}, not an integer"
        ) from None
    if version > SWEEP_FORMAT_VERSION:
        raise StoreError(
            f"{path} was written by a newer antisync (sweep format {version}); this "
            f"one reads sweep format {SWEEP_FORMAT_VERSION} — upgrade antisync"
        )
    try:
        meta = json.loads(raw.decode() if isinstance(raw, bytes) else raw)
    except (TypeError, ValueError, UnicodeDecodeError) as exc:
        why = " ".join(str(exc).split())
        raise StoreError(f"{path} is damaged: /sweep/meta_json is not valid JSON ({why})") from None
    problem = _meta_problem(meta)
    if problem:
        raise StoreError(f"{path} is damaged: /sweep/meta_json {problem}")
    return meta


def _meta_problem(meta) -> str | None:
    """What is wrong with sweep metadata ``meta`` (None if it has what the readers need)."""
    if not isinstance(meta, dict):
        return "is not a JSON object"
    for key, kind in _META_KEYS.items():
        if not isinstance(meta.get(key), kind):
            return f"lacks {key!r} or it is not a {getattr(kind, '__name__', 'number')}"
    for name, items, keys in (
        ("graphs", meta["graphs"], _META_GRAPH_KEYS),
        ("jobs", meta["jobs"], _META_JOB_KEYS),
    ):
        for i, item in enumerate(items):
            missing = [k for k in keys if not isinstance(item, dict) or k not in item]
            if missing:
                return f"entry {i} of {name!r} lacks {', '.join(map(repr, missing))}"
    return None


def read_meta(path: str | Path) -> dict:
    """The ``/sweep`` metadata of a sweep file (:class:`StoreError` if it is not one)."""
    meta = read_sweep_meta(path)
    if meta is None:
        raise StoreError(f"{path} is a result file of `antisync run`, not of a sweep")
    return meta
