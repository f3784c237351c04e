"""Sweeps: a family of graphs, screened for synchronization, reduced by symmetry, one HDF5 file.

A sweep config is a run config (``betas``, ``lambda``, ``dynamics``, ``realizations``, ``seed``,
``backend``, ``output``, ...) without ``graph:`` and with a ``sweep:`` section::

    name: atlas6
    sweep: {family: atlas, nodes: 6}     # every connected 6-node graph of the networkx atlas
    edges: all                           # all | fig2 (lollipop family) | ["0->1", ...]
    thresholds: [0.9, 0.99, 0.999]       # one job per (graph, threshold); default: dynamics.threshold
    repeats: 1                           # independent Lambda estimates; repeat k uses seed + k
    screen: {realizations: 200, t_max: 200, exclude_fraction: 0}
    top: {graphs: 7, betas: [0.5], realizations: 20000}

Families (``sweep.family``):

- ``atlas``: ``nodes`` (2..7; an int, a list, or ``"a..b"``): every connected graph of
  :func:`networkx.graph_atlas_g` with that many nodes, named ``G<index>`` (112 for six nodes).
- ``lollipop``: ``nodes`` and ``path`` (same forms): lollipops ``lollipop_<N>_<L>`` with the
  paper's labels (:func:`antisync.physics.graphs.lollipop`).
- ``graphs``: ``graphs``: a list of graph specs as in a run config (``{kind: atlas, index: 105}``,
  ...), each with an optional ``name``.

Grids (``sweep.grid`` / ``sweep.zip``, :mod:`~antisync.sweeps.points`): any config key that
decides the numbers (``model.phase_lag``, ``dynamics.threshold``, ``model.inertia``, ...)
over a list of values, on one graph (a top-level ``graph:`` and no ``family``) or on every
graph of a family; one job per (graph, grid point, repeat).

What a sweep does (:func:`run_sweep`):

1. **Screening** (:mod:`antisync.sweeps.screening`): every graph is integrated from
   ``screen.realizations`` random starts; a graph with realizations that converge to a stable
   non-synchronized state (a twisted state) is excluded, with the reason and the fraction.
2. **Symmetry**: directed edges mapped onto each other by a graph automorphism have the same
   Lambda; one representative per orbit is integrated
   (:func:`~antisync.physics.graphs.edge_orbits`) and its records are fanned out to the whole
   orbit when the file is summarized (:func:`sweep_summary`).
3. **Main stage**: one job per (kept graph, threshold, repeat). Repeat 0 carries ``betas``;
   later repeats estimate Lambda only. With a ``stop:`` section (docs/stopping.md) the
   stopping rule looks at every job of the stage together and ends it at the first look
   where every link of every job has a known sign (refused with ``top.graphs > 0``).
4. **Top stage** (optional, ``top.graphs > 0``): the graphs ranked first by the sum of their
   positive Lambda^KM (Fig. 3 of the paper) get a job for their most antifragile edge with
   ``top.betas`` and ``top.realizations`` (Table 1 and the histograms of Fig. 4).

Everything, screening included, is stored in one HDF5 file (group ``/sweep``, dataset
``meta_json``, next to the usual ``/jobs``; see :mod:`antisync.store.layout`) and a sweep
killed at any moment and rerun with ``resume=True`` ends with the same numbers as an
uninterrupted one.

Modules:

- :mod:`~antisync.sweeps.schema`: the config (:class:`Sweep`, :class:`Screen`, :class:`Top`,
  :func:`load_sweep`);
- :mod:`~antisync.sweeps.families`: the graphs of a family, their edges and orbits
  (:func:`family_graphs`);
- :mod:`~antisync.sweeps.points`: the points of a grid over config keys;
- :mod:`~antisync.sweeps.stages`: running it (:func:`run_sweep`);
- :mod:`~antisync.sweeps.analysis`: pure statistics over records (:func:`ranking`,
  :func:`edge_lambdas`, :func:`trend_in_n`, :func:`expand_records`);
- :mod:`~antisync.sweeps.results`: :func:`sweep_summary` of a sweep's file.

Whether a file is a sweep's and its ``/sweep`` metadata are the store's
(:func:`antisync.store.is_sweep_file`, :func:`antisync.store.read_meta`).
"""

from antisync.physics.graphs import edge_orbits
from antisync.sweeps.analysis import edge_lambdas, expand_records, ranking, trend_in_n
from antisync.sweeps.families import FAMILIES, GraphEntry, family_graphs, fig2_edge
from antisync.sweeps.results import sweep_summary
from antisync.sweeps.schema import PAPER_THRESHOLD, Screen, Sweep, Top, load_sweep, load_sweep_text
from antisync.sweeps.stages import main_jobs, run_sweep, top_jobs

__all__ = [
    "FAMILIES",
    "PAPER_THRESHOLD",
    "GraphEntry",
    "Screen",
    "Sweep",
    "Top",
    "edge_lambdas",
    "edge_orbits",
    "expand_records",
    "family_graphs",
    "fig2_edge",
    "load_sweep",
    "load_sweep_text",
    "main_jobs",
    "ranking",
    "run_sweep",
    "sweep_summary",
    "top_jobs",
    "trend_in_n",
]
