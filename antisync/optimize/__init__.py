"""Design by gradient: the link weights, under a budget, that make a network synchronize fastest.

- :mod:`~antisync.optimize.budget`: the feasible set ``{lower <= x <= upper, cost . x = budget}``
  and the exact Euclidean projection onto it.
- :mod:`~antisync.optimize.ensemble`: the mean synchronization time over random starts, its
  gradient for every link from one adjoint pass per start, paired evaluations of designs.
- :mod:`~antisync.optimize.descent`: the stochastic projected descent, its stopping rule and the
  final comparison on fresh starts.
- :mod:`~antisync.optimize.spectral`: the exact spectral designs (lambda_2, total effective
  resistance, lambda_2 of the normalized Laplacian), the baselines and warm starts.
- :mod:`~antisync.optimize.window`: the time-averaged order parameter from given starts (GradNet's
  Kuramoto objective), its discrete adjoint and a projected Adam design.
- :mod:`~antisync.optimize.config`, :mod:`~antisync.optimize.run`: ``antisync design CONFIG``.

docs/design.md has the method and the measured examples.
"""
