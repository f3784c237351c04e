"""`antisync grid static|removal|trip CONFIG`: a power grid's lines (docs/power_grids.md).

One thin module per subcommand over the Python face (:mod:`antisync.api.grids`):

- ``static``: the static indicators of the locked state after each line's removal;
- ``removal``: the dynamic N-1 by random starts (``--out`` a JSON table, ``--resume``);
- ``trip``: the engineer's N-1 from the operating point, with faults and critical clearing times;
- ``flags``: the earlier one-command form, ``antisync grid CONFIG [--removal | --trip]``, still
  read (the group sends a command line that does not start with a subcommand there).
"""
