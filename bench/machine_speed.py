"""The machine's speed this hour: one fixed numba kernel's nanoseconds per step, one thread.

These VMs run 20-40% slower in some hours than in others (bench/RESULTS.md); a timing of the test
suite or of a benchmark means something only beside the machine's speed at that hour. The kernel
is fixed and owes nothing to antisync (plain ``numba.njit``, ``fastmath``): Euler steps of 20
Kuramoto oscillators on a complete graph, 200,000 steps, the best of five runs after compiling::

    python bench/machine_speed.py          # prints e.g. "machine speed: 1234.5 ns per step"
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit

N = 20
STEPS = 200_000
DT = 1e-3


@njit(fastmath=True, cache=False)
def _euler(theta, omega, steps, dt):
    n = theta.shape[0]
    dth = np.empty(n)
    for _ in range(steps):
        for i in range(n):
            acc = omega[i]
            for j in range(n):
                acc += np.sin(theta[j] - theta[i]) / n
            dth[i] = acc
        for i in range(n):
            theta[i] += dt * dth[i]
    return theta


def ns_per_step(repeats: int = 5) -> float:
    """The best of ``repeats`` runs of the fixed kernel, in nanoseconds per step."""
    rng = np.random.default_rng(0)
    omega = rng.normal(0.0, 0.1, N)
    _euler(np.zeros(N), omega, 10, DT)  # compile
    best = float("inf")
    for _ in range(repeats):
        theta = rng.uniform(-np.pi, np.pi, N)
        t = time.perf_counter()
        _euler(theta, omega, STEPS, DT)
        best = min(best, time.perf_counter() - t)
    return best / STEPS * 1e9


if __name__ == "__main__":
    print(f"machine speed: {ns_per_step():.1f} ns per step (fixed Euler kernel, N = {N}, one thread)")
