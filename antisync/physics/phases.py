"""Counter-based initial phases keyed by ``(seed, realization, node)``.

Realization ``k`` of a run with seed ``s`` starts from the phases
``theta_i(0) = 2 pi u(s, k, i)``, where ``u`` is a SplitMix64-style hash of the three
integers mapped to ``[0, 1)`` with 53 random bits. Nothing depends on how realizations are
split into chunks, threads, processes or GPU blocks, so every backend and executor draws the
same phases, and ``tau0`` and every ``tau(beta)`` of one realization share them (paper, Sec. 2.2).

The hash is written in the subset of Python that both ``numba.njit`` and
``numba.cuda.jit(device=True)`` compile, so the CPU and CUDA kernels call the same code.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from antisync import _numba_cache  # noqa: F401 -- before any cache=True function (see there)

__all__ = ["initial_phases", "make_phase", "make_uniform", "phase", "phases_of", "start_phase"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO_PI_2M53 = 2.0 * np.pi / 9007199254740992.0  # 2 pi / 2**53
_INV_2M53 = 1.0 / 9007199254740992.0  # 2**-53


def _mix(z):
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


def make_phase(jit):
    """Compile :func:`phase` with ``jit`` (``numba.njit`` or ``numba.cuda.jit(device=True)``)."""
    mix = jit(_mix)

    def phase(seed, k, node):
        """Initial phase in ``[0, 2 pi)`` of ``node`` in realization ``k`` (non-negative ints)."""
        z = mix(np.uint64(seed) * _GOLDEN + np.uint64(1))
        z = mix(z ^ (np.uint64(k) * _GOLDEN + np.uint64(2)))
        z = mix(z ^ (np.uint64(node) * _GOLDEN + np.uint64(3)))
        return np.float64(z >> _S11) * _TWO_PI_2M53

    return jit(phase)


phase = make_phase(lambda f: njit(f, inline="always"))


@njit(inline="always")
def start_phase(starts, seed, k, r, i):
    """Node ``i``'s initial phase in row ``r`` (realization ``k``) of a model kernel's batch:
    ``starts[r, i]`` when the batch carries its starts (``model.start``, drawn on the host by
    :func:`antisync.plan.model.start_phases`), else the paper's :func:`phase`."""
    if starts.shape[0] > 0:
        return starts[r, i]
    return phase(seed, k, i)


def make_uniform(jit):
    """Compile ``uniform(seed, k, node, stream)``: a number in ``[0, 1)`` (53 random bits) keyed
    by ``(seed, k, node)`` like :func:`phase` and by a ``stream >= 1`` (natural frequencies use
    streams 1 and 2, :mod:`antisync.plan.model`). The stream is mixed in after the seed with its own
    offset, so no stream reproduces the phases' numbers."""
    mix = jit(_mix)

    def uniform(seed, k, node, stream):
        z = mix(np.uint64(seed) * _GOLDEN + np.uint64(1))
        z = mix(z ^ (np.uint64(stream) * _GOLDEN + np.uint64(4)))
        z = mix(z ^ (np.uint64(k) * _GOLDEN + np.uint64(2)))
        z = mix(z ^ (np.uint64(node) * _GOLDEN + np.uint64(3)))
        return np.float64(z >> _S11) * _INV_2M53

    return jit(uniform)


@njit(cache=True)
def _fill(seed, ks, out):
    for r in range(out.shape[0]):
        for i in range(out.shape[1]):
            out[r, i] = phase(seed, ks[r], i)


def phases_of(seed: int, ks: np.ndarray, n_nodes: int) -> np.ndarray:
    """Phases of the realizations ``ks`` (uint64 ids, any order), shape ``(len(ks), n_nodes)``."""
    if seed < 0:
        raise ValueError("seed must be non-negative")
    ks = np.ascontiguousarray(ks, dtype=np.uint64)
    out = np.empty((ks.size, n_nodes))
    _fill(np.uint64(seed), ks, out)
    return out


def initial_phases(seed: int, first: int, count: int, n_nodes: int) -> np.ndarray:
    """Phases of realizations ``first .. first + count - 1``, shape ``(count, n_nodes)``."""
    if seed < 0 or first < 0:
        raise ValueError("seed and realization indices must be non-negative")
    return phases_of(seed, np.arange(first, first + count, dtype=np.uint64), n_nodes)
