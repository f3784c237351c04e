"""Execution: chunks of a job -> kernels -> the store.

``compute`` (one chunk on one backend), ``runner`` (a config's jobs to an HDF5 file, resumable),
``stopping`` (the stopping rule between looks at the store), ``capabilities`` (what runs where)
and ``executors/`` (local threads, Dask).
"""
