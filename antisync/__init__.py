"""antisync: antifragility of Kuramoto synchronization to the damage of one link.

The Python API (:mod:`antisync.api`), for notebooks and scripts::

    import antisync

    res = antisync.run("configs/lollipop6.yaml", realizations=2000, output="l.h5")
    res.records                      # per (edge, beta): <F_beta>, Lambda^KM, <tau0>, errors
    antisync.load("l.h5").to_pandas()
    antisync.measures.for_graph({"kind": "lollipop", "nodes": 6, "path": 3})  # exact xi2, RW
    antisync.grid.static("configs/ieee39_grid.yaml").records  # a power grid's lines (docs/api.md)

The command line (``antisync run configs/lollipop6.yaml``) is a thin layer over the same
functions. Importing antisync is cheap and changes nothing global: no environment variable,
no numba setting (numba's cache for antisync's own kernels is chosen per function, see
:mod:`antisync._numba_cache`); heavy modules load on first use. (The first kernel module loaded
makes numba's copy propagation, inlining and liveness analysis faster for every compile in the
process, with the same compiled code: :mod:`antisync._numba_compile`.)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from antisync._version import __version__

__all__ = ["Result", "__version__", "design", "grid", "load", "measures", "run", "summarize", "sweep"]

if TYPE_CHECKING:
    from antisync import measures
    from antisync.api import Result, design, load, run, summarize, sweep
    from antisync.api import grids as grid


def __getattr__(name: str):
    """Load the API on first use, so ``import antisync`` (and ``antisync --help``) stay fast."""
    if name in ("Result", "design", "load", "run", "summarize", "sweep"):
        return getattr(importlib.import_module("antisync.api"), name)
    if name == "grid":
        return importlib.import_module("antisync.api.grids")
    if name == "measures":
        return importlib.import_module("antisync.measures")
    raise AttributeError(f"module 'antisync' has no attribute {name!r}")
