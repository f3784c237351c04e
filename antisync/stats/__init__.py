"""Statistics: arrays and decoded jobs in, records out (pure functions, no file).

``estimators`` (per-realization quantities and their means), ``multiplicity`` (FDR sign calls),
``sum_rule`` (the out-links' sum rule), ``summary`` (records of a job) and ``records`` (sorting
and flagging them). Imports only ``physics`` and the ground files.
"""
