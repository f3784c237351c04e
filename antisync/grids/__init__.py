"""Power grids: static indicators of a line and dynamic N-1 by random starts, both on the
generalized model of :mod:`antisync.plan.model` (docs/power_grids.md).

One concept per module:

- ``errors``: :class:`~antisync.grids.errors.GridError`, the stage's one-line error;
- ``load``: :class:`~antisync.grids.load.Grid` and its readers (edge list, config);
- ``lines``: naming lines (``--lines``), picking them, bridges;
- ``static``: the static indicators of the locked state and their table;
- ``removal``: the dynamic removal's orchestrator, :func:`~antisync.grids.removal.line_removal`;
- ``removal_config``: what a removal computes (config, ``beta``, its lines);
- ``removal_table``: its result, one row per line, and the rankings;
- ``removal_journal``: its finished tasks on disk, for resuming;
- ``removal_file``: its JSON file and the output policy.

Nothing is re-exported here: importing one module does not import the others.
"""
