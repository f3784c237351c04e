"""Result files: the HDF5 layout, crash-safe checkpoints, resume, the writer lock, provenance.

This package is the only part of antisync that opens an HDF5 file.

- :mod:`~antisync.store.layout`: every group, attribute and dataset of a result file (a run's
  or a sweep's), written and read; decoded jobs (:func:`read_views`) and their summary
  records (:func:`records`).
- :mod:`~antisync.store.journal`: finished chunks in ``<output>.partial/`` until a checkpoint
  holds them, with tags that keep another run's chunks out (:func:`chunk_tag`,
  :func:`graph_digest`).
- :mod:`~antisync.store.lock`: one writer at a time (an ``flock`` on ``<output>.lock``) and
  the checks of an output path before anything is written.
- :mod:`~antisync.store.result_store`: :class:`ResultStore`, one output file as a run writes
  it (lock, prepare, resume, journal, atomic checkpoints).
- :mod:`~antisync.store.state`: :class:`JobState`, a job's results in memory.
- :mod:`~antisync.store.provenance`: the command, git revision and time stored with results.

Reading a file from Python::

    from antisync.store import records
    for r in records("results/lollipop6.h5"):
        print(r["edge"], r["beta"], r["F_mean"], r["F_se"], r["lambda_km"], r["lambda_km_se"])
"""

from antisync.store.journal import chunk_tag, graph_digest
from antisync.store.layout import (
    FORMAT,
    FORMAT_VERSION,
    SWEEP_FORMAT,
    SWEEP_FORMAT_VERSION,
    is_complete,
    is_sweep_file,
    open_results,
    read_meta,
    read_sweep_meta,
    read_views,
    records,
    root_attrs,
    state_view,
    step_check_records,
    stop_record,
    stored_config,
    write_sweep_meta,
)
from antisync.store.provenance import command_line, git_revision
from antisync.store.result_store import ResultStore
from antisync.store.state import JobState

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "SWEEP_FORMAT",
    "SWEEP_FORMAT_VERSION",
    "JobState",
    "ResultStore",
    "chunk_tag",
    "command_line",
    "git_revision",
    "graph_digest",
    "is_complete",
    "is_sweep_file",
    "open_results",
    "read_meta",
    "read_sweep_meta",
    "read_views",
    "records",
    "root_attrs",
    "state_view",
    "step_check_records",
    "stop_record",
    "stored_config",
    "write_sweep_meta",
]
