"""The phase-locked state of a user's law, for the relative criterion's ``r*``.

A law's locked state rotates rigidly: every node's frequency quantities (the frequency
criterion's, by default its phase's rate: :attr:`antisync.laws.spec.Law.frequency`) are one
common value, and ``r(t)`` is a constant ``r*``. The built-in model finds its own by Newton's
method on the phase differences, continued from synchrony (:mod:`antisync.physics.locked`); a
law has no rotating frame antisync could write down for it (Stuart-Landau's amplitudes turn with
the phases), so here the state connected to synchrony is found as the network finds it: the
law's own right-hand side (:mod:`antisync.kernels.law`) integrated from its in-phase state
(every node's start at ``phi = 0``) by scipy's DOP853 at ``rtol = atol = 1e-12`` (on a stiff
network, from where DOP853 is near the lock but held to short steps by stability, by scipy's
Radau with the law's sparse Jacobian, which damps what an explicit method leaves ringing in the
fast modes: :data:`STIFF_STEPS`), until

- every frequency quantity is within :data:`TOL` of its mean (and each one's rate too), and
- ``R = (r N)^2`` changed by less than :data:`R_TOL` of itself over the last :data:`WINDOW`
  time units.

A state reached this way attracts its neighbourhood (it is stable); a law that does not lock
from synchrony within ``t_max`` has no ``r*`` here (:func:`locked_state` returns None), and the
relative criterion is refused in one line for it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LawLocked", "NEAR", "R_TOL", "STIFF_STEPS", "TOL", "WINDOW", "locked_state"]

#: The largest |deviation| of a frequency quantity (and of its rate) from its mean at lock.
TOL = 1e-10
#: ``R``'s largest relative change over the last window at lock.
R_TOL = 1e-12
#: The time between two checks, in the model's time units.
WINDOW = 5.0
#: DOP853 steps in one window, near the lock (every frequency quantity within :data:`NEAR` of
#: its mean), beyond which the network is stiff: a non-stiff law takes a few long steps there,
#: a stiff one (IEEE 39's first-order buses beside its generators: about 810) stays at its
#: stability bound and its deviations ring at ~1e-7, never reaching :data:`TOL`. The rest of
#: the integration is then Radau's.
STIFF_STEPS = 400
NEAR = 1e-3


@dataclass(frozen=True)
class LawLocked:
    """A law's locked state: the flat state ``y`` where the test passed at time ``t`` (from
    the in-phase state), its order parameter ``r`` (``r*``), and ``spread``, the largest
    |deviation| of a frequency quantity or its rate from its mean there."""

    y: np.ndarray
    r: float
    t: float
    spread: float


def locked_state(law, values, edges, indptr, indices, weights, *, t_max: float) -> LawLocked | None:
    """The locked state the law reaches from its in-phase state on the network ``weights``
    (CSR ``indptr``, ``indices``; ``values`` the per-node parameters ``(n_params, n)``,
    ``edges`` the per-link ones or None), or None if it is not locked by ``t_max``."""
    from scipy.integrate import solve_ivp

    from antisync.kernels.law import compile_law, expanded_pattern, in_phase, with_edges

    compiled = compile_law(law)
    n = values.shape[1]
    ip = np.ascontiguousarray(indptr, dtype=np.int64)
    ix = np.ascontiguousarray(indices, dtype=np.int64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    p = np.ascontiguousarray(with_edges(values, law, edges), dtype=np.float64)
    scratch = np.empty((compiled.hoisted, n))
    devs = np.empty((2 * compiled.kf, n))

    def rhs(_t, y):
        out = np.empty(y.size)
        compiled.rhs(np.ascontiguousarray(y), w, ip, ix, p, out, scratch)
        return out

    def big_r(y):
        return float(compiled.order(y, rhs(0.0, y), p, n)[0])

    def jac(_t, y):
        from scipy.sparse import csr_matrix

        jq = np.empty(perm.size)
        compiled.jac(np.ascontiguousarray(y), w, ip, ix, p, jq)
        return csr_matrix((jq[perm], cols, ptr), shape=(y.size, y.size))

    y = in_phase(law, values)
    t, r_prev = 0.0, big_r(y)
    method, options = "DOP853", {}
    while t < t_max:
        span = min(WINDOW, t_max - t)
        sol = solve_ivp(rhs, (t, t + span), y, method=method, rtol=1e-12, atol=1e-12, **options)
        if not sol.success or not np.isfinite(sol.y[:, -1]).all():
            return None
        y, t = np.ascontiguousarray(sol.y[:, -1]), t + span
        f = rhs(t, y)
        compiled.devs(y, f, w, ip, ix, p, devs)
        spread = float(np.abs(devs).max())
        r_now = big_r(y)
        if spread < TOL and abs(r_now - r_prev) <= R_TOL * r_now:
            return LawLocked(y, float(np.sqrt(r_now)) / n, t, spread)
        r_prev = r_now
        if method == "DOP853" and spread < NEAR and sol.t.size > STIFF_STEPS:
            ptr, cols, perm = expanded_pattern(ip, ix, len(law.states))
            method, options = "Radau", {"jac": jac}
    return None
