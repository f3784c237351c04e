"""The Python API, the library's face: what the command line does, as functions that return data.

- :mod:`antisync.api.runs`: :func:`~antisync.api.runs.run`, :func:`~antisync.api.runs.sweep`,
  :func:`~antisync.api.runs.design`, :func:`~antisync.api.runs.load`,
  :func:`~antisync.api.runs.summarize` and their :class:`~antisync.api.runs.Result`;
- :mod:`antisync.api.grids` (``antisync.grid``): a power grid's lines, static
  (:func:`~antisync.api.grids.static`), by random starts (:func:`~antisync.api.grids.removal`) and
  tripped from the operating point (:func:`~antisync.api.grids.trip`), each a
  :class:`~antisync.api.grids.GridResult`.
"""

from __future__ import annotations

from antisync.api.runs import Result, design, load, run, summarize, sweep

__all__ = ["Result", "design", "load", "run", "summarize", "sweep"]
