"""antisync._numba_compile: numba's copy propagation with a faster fixed point, the same result."""

import numpy as np
from numba import njit, prange
from numba.core import ir_utils
from numba.parfors import parfor

from antisync import _numba_compile


def _parallel_kernel(x, w, out, steps):
    """A parfor with branches, loops and copies in its body: the parfor passes simplify it."""
    n = x.shape[0]
    for i in prange(n):
        a = x[i]
        b = a
        for _ in range(steps):
            if b > 0.0:
                c = b * w[i]
                b = c - 0.5 * a
            else:
                c = b
                b = -c + w[i]
            a = b
        out[i] = a if a == a else 0.0
    return out.sum()


def test_the_replacement_returns_numbas_result_on_every_call_of_a_parallel_compile(monkeypatch):
    """Compiling a parallel function, every copy propagation (the parfor passes' and ir_utils')
    runs numba's own function and the replacement on the same blocks: equal ``(in, out)`` copies
    on every call, and the compiled function's result unchanged. (Under any numba: where its
    source is not the known one the replacement is not installed, and this says whether it
    could be.)"""
    numbas = _numba_compile._numba_copy_propagate
    calls = []

    def both(blocks, typemap):
        want = numbas(blocks, typemap)
        got = _numba_compile.copy_propagate(blocks, typemap)
        assert got == want
        calls.append(sum(len(s) for s in want[1].values()))
        return got

    monkeypatch.setattr(ir_utils, "copy_propagate", both)
    monkeypatch.setattr(parfor, "copy_propagate", both)
    kernel = njit(parallel=True)(_parallel_kernel)  # no cache: compiled here
    x = np.linspace(-1.0, 1.0, 37)
    w = np.cos(np.arange(37.0))
    got = np.empty(37)
    kernel(x, w, got, 5)
    assert len(calls) >= 3 and max(calls) > 0  # the passes ran, on blocks with copies
    want = np.empty(37)
    _parallel_kernel(x, w, want, 5)  # the Python function (prange is range)
    np.testing.assert_array_equal(got, want)


def test_it_is_installed_where_numbas_source_is_the_known_one():
    """Installed in both modules that call it when numba's source is the one it was written
    against; numba's own everywhere otherwise."""
    import hashlib
    import inspect

    known = hashlib.sha1(inspect.getsource(_numba_compile._numba_copy_propagate).encode()).hexdigest()
    assert _numba_compile.installed == (known in _numba_compile.KNOWN)
    if _numba_compile.installed:
        assert ir_utils.copy_propagate is _numba_compile.copy_propagate
        assert parfor.copy_propagate is _numba_compile.copy_propagate
    else:
        assert ir_utils.copy_propagate is _numba_compile._numba_copy_propagate
