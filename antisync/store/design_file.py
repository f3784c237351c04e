"""The HDF5 file of a design (``antisync design``): every iterate, every check, the loop's state,
and the final paired comparison on fresh starts.

The file is small (iterations x links), so after every iteration it is written whole into
``<file>.tmp`` and renamed over the old one: a kill at any moment leaves the previous
iteration's file whole, and ``--resume`` continues from its stored state. ``--overwrite``
replaces a file only when its successor's first iteration is written (the old one stays
readable until then).

Layout::

    /            attrs: format "antisync-design", version, config (YAML), design (JSON),
                 complete (bool), reason
    /problem     labels, links (L, 2), start (L,), cost, lower, upper, candidate, budget (attr)
    /iterations  x (T, L), tau, tau_se, censored, grad (T, L), grad_se (T, L), step, seconds
    /checks      iteration, candidate_tau, best_tau, diff, diff_se, accepted
    /state       x, best, period_sum, velocity; attrs iteration, step, stall, period_count, done, reason
    /baselines   one dataset (L,) per named design (the designed one: "designed")
    /verification  names, tau (D, m), status (D, m), rows (JSON attr)
    /sensitivity   lambda (L,), lambda_se (L,): the graph's own links' Lambda (see the docs)
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np

from antisync.errors import StoreError
from antisync.store.outputs import check_output_path

__all__ = ["FORMAT", "check_design_target", "is_design_file", "read_design", "write_design"]

FORMAT = "antisync-design"
VERSION = 1

_ITER_KEYS = ("x", "tau", "tau_se", "censored", "grad", "grad_se", "step", "seconds")
_CHECK_KEYS = ("iteration", "candidate_tau", "best_tau", "diff", "diff_se", "accepted")


def is_design_file(path: str | Path) -> bool:
    """Whether ``path`` is an HDF5 file that ``antisync design`` wrote (False for anything else)."""
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == FORMAT
    except (OSError, ValueError):
        return False


def check_design_target(path: str | Path, *, resume: bool, overwrite: bool, protect=()) -> None:
    """``design.output`` checked before any work by antisync's one output policy
    (:func:`antisync.store.outputs.check_output_path`, as runs and grid tables): an ``.h5``
    path in an existing folder, no link, no input of the run (``protect``: the config and the
    files it reads), and an existing file replaced (``--overwrite``) or continued
    (``--resume``) only when it is a design file; a ``--resume`` of a damaged design file is
    refused before anything runs."""
    path = check_output_path(
        path,
        option="design.output",
        suffixes=(".h5", ".hdf5"),
        hint="a design is written as HDF5; give design.output a path ending in .h5",
        overwrite=True,  # an existing design file: --resume or --overwrite, below
        replaceable=lambda p: None if is_design_file(p) else "not a design file",
        kind="an antisync design file (HDF5 that antisync design wrote)",
        protect=protect,
    )
    if path.exists() and not (resume or overwrite):
        raise StoreError(
            f"{path} exists: continue it with --resume, replace it with --overwrite, or choose "
            "another design.output"
        )
    if resume and path.exists():
        read_design(path)  # a broken design file is refused before anything runs


def write_design(path: str | Path, record: dict) -> None:
    """Write the whole design ``record`` (the keys of :func:`read_design`) atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["config"] = record["config"]
        f.attrs["design"] = json.dumps(record["design"])
        f.attrs["complete"] = bool(record.get("complete", False))
        f.attrs["reason"] = record.get("reason", "")
        prob = f.create_group("problem")
        for key in ("links", "start", "cost", "lower", "upper", "candidate"):
            prob.create_dataset(key, data=np.asarray(record["problem"][key]))
        prob.create_dataset("labels", data=np.array(record["problem"]["labels"], dtype=h5py.string_dtype()))
        prob.attrs["budget"] = float(record["problem"]["budget"])
        its = f.create_group("iterations")
        rows = record["iterations"]
        for key in _ITER_KEYS:
            its.create_dataset(key, data=np.array([r[key] for r in rows], dtype=float))
        checks = f.create_group("checks")
        for key in _CHECK_KEYS:
            checks.create_dataset(key, data=np.array([c[key] for c in record["checks"]], dtype=float))
        state = record.get("state")
        if state is not None:
            st = f.create_group("state")
            for key in ("x", "best", "period_sum", "velocity"):
                st.create_dataset(key, data=np.asarray(state[key], dtype=float))
            for key in ("iteration", "step", "stall", "period_count", "done", "reason"):
                st.attrs[key] = state[key]
        base = f.create_group("baselines", track_order=True)
        for name, x in record.get("baselines", {}).items():
            base.create_dataset(name, data=np.asarray(x, dtype=float))
        ver = record.get("verification")
        if ver is not None:
            g = f.create_group("verification")
            g.create_dataset("names", data=np.array(ver["names"], dtype=h5py.string_dtype()))
            g.create_dataset("tau", data=ver["tau"], compression="gzip")
            g.create_dataset("status", data=ver["status"], compression="gzip")
            g.attrs["rows"] = json.dumps(ver["rows"])
        sens = record.get("sensitivity")
        if sens is not None:
            g = f.create_group("sensitivity")
            for key, value in sens.items():
                g.create_dataset(key, data=np.asarray(value, dtype=float))
    os.replace(tmp, path)


def read_design(path: str | Path) -> dict:
    """The record :func:`write_design` wrote; one-line :class:`StoreError` for anything else."""
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError) as exc:
        raise StoreError(
            f"{path} is not a readable HDF5 file ({exc}); give an antisync design file"
        ) from None
    with f:
        if f.attrs.get("format") != FORMAT:
            raise StoreError(
                f"{path} is not a design file (written by `antisync design`); "
                "for a run's file use antisync summary / report"
            )
        version = f.attrs.get("version")
        if version != VERSION:
            raise StoreError(
                f"{path} is a design file of format version {version}; this antisync reads version "
                f"{VERSION} (run the design again with this antisync, or read it with the one that wrote it)"
            )
        try:
            out = {
                "config": str(f.attrs["config"]),
                "design": json.loads(f.attrs["design"]),
                "complete": bool(f.attrs["complete"]),
                "reason": str(f.attrs["reason"]),
                "problem": {
                    k: f["problem"][k][()] for k in ("links", "start", "cost", "lower", "upper", "candidate")
                },
                "iterations": [],
                "checks": [],
            }
            out["problem"]["labels"] = [
                s.decode() if isinstance(s, bytes) else s for s in f["problem/labels"][()]
            ]
            out["problem"]["budget"] = float(f["problem"].attrs["budget"])
            cols = {k: f["iterations"][k][()] for k in _ITER_KEYS}
            for i in range(cols["tau"].size):
                out["iterations"].append({k: cols[k][i] for k in _ITER_KEYS})
            cols = {k: f["checks"][k][()] for k in _CHECK_KEYS}
            for i in range(cols["iteration"].size):
                row = {k: float(cols[k][i]) for k in _CHECK_KEYS}
                row["iteration"] = int(row["iteration"])
                row["accepted"] = bool(row["accepted"])
                out["checks"].append(row)
            if "state" in f:
                st = f["state"]
                state = {k: st[k][()] for k in ("x", "best", "period_sum", "velocity")}
                state.update(
                    {k: st.attrs[k] for k in ("iteration", "step", "stall", "period_count", "done", "reason")}
                )
                state["iteration"] = int(state["iteration"])
                state["stall"] = int(state["stall"])
                state["period_count"] = int(state["period_count"])
                state["step"] = float(state["step"])
                state["done"] = bool(state["done"])
                state["reason"] = str(state["reason"])
                out["state"] = state
            out["baselines"] = {k: f["baselines"][k][()] for k in f.get("baselines", {})}
            if "verification" in f:
                g = f["verification"]
                out["verification"] = {
                    "names": [s.decode() if isinstance(s, bytes) else s for s in g["names"][()]],
                    "tau": g["tau"][()],
                    "status": g["status"][()],
                    "rows": json.loads(g.attrs["rows"]),
                }
            if "sensitivity" in f:
                out["sensitivity"] = {k: f["sensitivity"][k][()] for k in f["sensitivity"]}
        except (KeyError, ValueError, TypeError) as exc:
            raise StoreError(
                f"{path}: a design file with a missing or damaged part ({exc}); rerun with --overwrite"
            ) from None
    return out
