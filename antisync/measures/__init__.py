"""Non-simulation response measures: Lambda^(xi2), Lambda^(RW) and Lambda^(linear).

- :mod:`~antisync.measures.spectral`: ``xi2`` and ``Lambda^(xi2)`` (Eqs. 15-16), exact.
- :mod:`~antisync.measures.randomwalk`: ``tau_RW`` and ``Lambda^(RW)`` (Appendix,
  Eqs. 23-25), exact.
- :func:`~antisync.measures.for_graph`: ``Lambda^(xi2)`` and ``Lambda^(RW)`` of every link of
  a graph in one call (what ``antisync.measures.for_graph(nx.karate_club_graph())`` returns).
- :mod:`~antisync.measures.linear`: the linearized dynamics, ``tau^(linear)`` and
  ``Lambda^(linear)`` (Eqs. 7-14), over realizations of the initial phases.

Equation numbers count the numbered equations of the paper's LaTeX source in order
(Eq. 1: ``w_ij``, Eq. 3: ``r(t)``, Eq. 9: ``dtheta/dt = -L theta``, Eq. 16: ``Lambda^(xi2)``,
Eq. 20: the raw-coupling model, Eq. 23: ``tau_j(0)``).

All functions take the dense weight matrix ``Omega`` and 0-based node indices; damage on
``a -> b`` follows :mod:`antisync.physics.coupling`.
"""

from antisync.measures.graph import for_graph
from antisync.measures.linear import (
    LinearResult,
    lambda_linear,
    order_parameter,
    tau_linear_euler,
    tau_linear_exact,
)
from antisync.measures.randomwalk import (
    f_rw,
    lambda_rw,
    lambda_rw_all,
    stationary_and_fundamental,
    tau_rw,
)
from antisync.measures.spectral import f_xi2, lambda_xi2, lambda_xi2_all, xi2

__all__ = [
    "LinearResult",
    "f_rw",
    "f_xi2",
    "for_graph",
    "lambda_linear",
    "lambda_rw",
    "lambda_rw_all",
    "lambda_xi2",
    "lambda_xi2_all",
    "order_parameter",
    "stationary_and_fundamental",
    "tau_linear_euler",
    "tau_linear_exact",
    "tau_rw",
    "xi2",
]
