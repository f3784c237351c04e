"""Plan: YAML, mappings, overrides and graphs -> a validated ``Config`` -> a job's arrays.

``config`` (the one reader of a config), ``model`` (the generalized model's parameters),
``jobs`` (a job's CSR arrays and variants) and ``describe`` (a model in words). Above the
kernels (a model knows which compiled features it needs), below everything that runs.
"""
