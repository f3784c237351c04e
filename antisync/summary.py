"""Per-(edge, beta) records from stored block statistics: <F_beta>, Lambda^KM, <tau0>, counts.

Records are computed from the block records of a result file (never from a live run), so a
summary of a resumed, a Dask or a CUDA run is computed exactly like any other.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from antisync import estimators
from antisync.measures.pipeline import join_nnc, measure_fields, read_measures

__all__ = ["JobView", "job_records", "read_views", "records", "view_records"]

# error bars are flagged when the largest 0.1% of samples carry this share of the variance
TAIL_WARN = 0.5


@dataclass
class JobView:
    """What a summary needs from one stored job."""

    graph: str
    edges: list
    betas: tuple
    dbeta: float
    variant_edge: np.ndarray
    variant_beta: np.ndarray
    rec: np.ndarray
    rec0: np.ndarray
    done: np.ndarray
    tail: np.ndarray
    realizations: int
    hist: np.ndarray | None = None
    hist_variants: np.ndarray | None = None
    tau_max_hist: float = 40.0
    lam_rec: np.ndarray | None = None
    lam_tail: np.ndarray | None = None
    lambda_method: str = "finite-difference"
    omega: np.ndarray | None = None
    nodes: list | None = None
    attrs: dict | None = None
    measures: dict | None = None  # Lambda^(linear, xi2, RW) arrays, see measures.pipeline

    def variant(self, edge_index: int, beta: float) -> int:
        hit = np.flatnonzero((self.variant_edge == edge_index) & np.isclose(self.variant_beta, beta))
        return int(hit[0]) if hit.size else -1


def _num(x: float):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def _lambda(view: JobView, e: int) -> dict:
    s = estimators.summarize_lambda(view.lam_rec[view.done, e])
    est = s["lambda"]
    share = estimators.tail_share(view.lam_tail[e])
    warning = None
    if s["n"] < 2:
        warning = (f"{s['n']} synchronized realization{'s' if s['n'] != 1 else ''}: no "
                   "standard error (see the unsynced count)")
    elif est.n_batches < 10:
        warning = f"only {est.n_batches} batches: standard error is rough"
    elif not math.isnan(share) and share > TAIL_WARN:
        warning = f"heavy tail: top 0.1% of samples carry {share:.0%} of the variance"
    elif not math.isnan(est.se_batch) and est.se_batch > 2 * est.se_naive:
        warning = "batch-means error exceeds twice the naive one: tail not yet sampled"
    return {
        "lambda_km": _num(est.mean),
        "lambda_km_se": _num(est.se),
        "lambda_km_se_naive": _num(est.se_naive),
        "lambda_km_se_batch": _num(est.se_batch),
        "lambda_km_tail_share": _num(share),
        "lambda_km_warning": warning,
        "lambda_method": view.lambda_method,
        "lambda_dbeta": view.dbeta,
        "lambda_n": s["n"],
        "lambda_n_flagged": s["n_flagged"],
    }


def job_records(view: JobView) -> list[dict]:
    """One record per (edge, requested beta); with no betas, one record per edge (Lambda only)."""
    s0 = estimators.summarize_tau0(view.rec0[view.done])
    t0 = s0["tau0"]
    complete = bool(view.done.size and view.done.all())
    out = []
    for e, label in enumerate(view.edges):
        lam = _lambda(view, e)
        for beta in view.betas or (None,):
            rec = {"graph": view.graph, "edge": label, "beta": beta}
            if beta is not None:
                s = estimators.summarize_variant(view.rec[view.done, view.variant(e, beta)])
                rec.update({
                    "F_mean": _num(s["F"].mean),
                    "F_se": _num(s["F"].se),
                    "F_se_naive": _num(s["F"].se_naive),
                    "tau_mean": _num(s["tau"].mean),
                    "tau_se": _num(s["tau"].se),
                    "n": s["n"],
                    "n_excluded": s["n_already"],
                    "n_not_synced": s["n_not_synced"],
                })
            else:
                s = estimators.summarize_lambda(view.lam_rec[view.done, e])
                rec.update({"F_mean": None, "F_se": None, "F_se_naive": None, "tau_mean": None,
                            "tau_se": None, "n": s["n"], "n_excluded": s["n_already"],
                            "n_not_synced": s["n_not_synced"]})
            rec.update(lam)
            rec.update({
                "tau0_mean": _num(t0.mean),
                "tau0_se": _num(t0.se),
                "tau0_n": s0["n"],
                "realizations_done": int(s0["n"] + s0["n_already"] + s0["n_not_synced"]),
                # an interrupted run's estimates are partial: say so in every record
                "realizations": int(view.realizations),
                "complete": complete,
            })
            rec.update(measure_fields(view.measures, e))
            out.append(rec)
    return out


def read_views(path: str | Path) -> list[JobView]:
    """All jobs of a result file.

    Raises
    ------
    StoreError
        The file is not an antisync result file, or a job's attribute or dataset is missing,
        malformed (an ``edges`` that is not JSON, a shape that does not fit) or unreadable:
        the message names the file, the job and what is damaged.
    """
    from antisync.errors import StoreError
    from antisync.store import open_results

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
                lam_rec=r.data("lambda_records"),
                lam_tail=r.data("lambda_tail_counts"),
                lambda_method=r.attr("lambda_method", str),
                nodes=nodes,
                attrs=r.read("attributes", r.plain_attrs),
                measures=r.read("measures group", r.measures),
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
        from antisync.errors import StoreError

        try:
            return get()
        except KeyError:
            raise StoreError(f"{self.path}: job {self.name} lacks {what}; the file is damaged") from None
        except Exception as exc:  # h5py: OSError; json: ValueError; casts: TypeError
            why = " ".join(str(exc).split()) or type(exc).__name__
            raise StoreError(f"{self.path}: job {self.name} has a damaged {what} ({why})") from None

    def data(self, key: str) -> np.ndarray:
        return self.read(f"dataset {key!r}", lambda: self.group[key][...])

    def attr(self, key: str, cast):
        return self.read(f"attribute {key!r}", lambda: cast(self.group.attrs[key]))

    def plain_attrs(self) -> dict:
        return {k: self.group.attrs[k] for k in self.group.attrs if k != "summary_json"}

    def measures(self) -> dict | None:
        return read_measures(self.group)


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
        "lambda_tail_counts": (view.lam_tail, (ne, estimators.TAIL_BINS)),
        "hist": (view.hist, (len(view.hist_variants), bins, bins)),
    }
    for key, (arr, shape) in expected.items():
        if arr.shape != shape:
            return f"dataset {key!r} has shape {arr.shape}, expected {shape} from its edges and blocks"
    if nv and (view.variant_edge.min() < 0 or view.variant_edge.max() >= ne):
        return "dataset 'variant_edge' points past the edges attribute"
    if view.hist_variants.size and (view.hist_variants.min() < 0 or view.hist_variants.max() >= nv):
        return "dataset 'hist_variants' points past the variants"
    return None


def records(path: str | Path) -> list[dict]:
    """Summary records of every job in a result file."""
    return view_records(read_views(path))


def view_records(views: list[JobView]) -> list[dict]:
    """Records of ``views``, with each run's ``lambda_km_nnc`` taken from its raw-coupling twin."""
    return join_nnc(views, [r for view in views for r in job_records(view)])
