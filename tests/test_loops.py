"""antisync.kernels.loops: a parallel loop compiled once for every item function of one
signature, its items' writes kept, an item's exception raised as itself."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit, prange

from antisync.kernels import loops


def _each(fn, inputs, outputs, scale):
    for i in prange(inputs[0].shape[0]):
        fn(*inputs, *outputs, scale, np.int64(i))


@njit
def _double(x, y, out, hits, scale, i):
    out[i] = scale * (x[i] + y[i])
    hits[i] += 1


@njit
def _square(x, y, out, hits, scale, i):
    out[i] = scale * x[i] * y[i]
    hits[i] += 1


@njit
def _refuse(x, y, out, hits, scale, i):
    if x[i] > 2.5:
        raise ValueError("item refused")
    out[i] = x[i]


def test_one_compiled_loop_runs_every_item_function_of_its_signature():
    x = np.arange(64.0)
    y = np.linspace(0.0, 1.0, 64)
    before = loops._compiled.cache_info().currsize
    for fn, want in ((_double, 3.0 * (x + y)), (_square, 3.0 * x * y)):
        out = np.zeros(64)
        hits = np.zeros(64, dtype=np.int64)
        loops.run(_each, fn, (x, y), (out, hits), 3.0, spread=(0, 1))
        np.testing.assert_array_equal(out, want)  # every write of every item kept
        np.testing.assert_array_equal(hits, 1)  # every item once
    assert loops._compiled.cache_info().currsize == before + 1  # one loop for both


def test_an_items_exception_is_raised_as_itself():
    x = np.arange(8.0)
    with pytest.raises(ValueError, match="item refused"):
        loops.run(_each, _refuse, (x, x), (np.zeros(8), np.zeros(8, dtype=np.int64)), 1.0, spread=(0, 1))
