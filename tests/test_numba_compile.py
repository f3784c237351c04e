"""antisync._numba_compile: numba's copy propagation, inlining and liveness, faster, the same result."""

import hashlib
import inspect
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from numba import njit, prange
from numba.core import inline_closurecall, ir_utils
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
        entry = ir_utils.compute_cfg_from_blocks(blocks).entry_point()
        initial = ir_utils.init_copy_propagate_data(blocks, entry, typemap)  # numba's
        assert _numba_compile.init_copy_propagate_data(blocks, entry, typemap) == initial
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
    known = hashlib.sha1(inspect.getsource(_numba_compile._numba_copy_propagate).encode()).hexdigest()
    assert _numba_compile.installed == (known in _numba_compile.KNOWN)
    if _numba_compile.installed:
        assert ir_utils.copy_propagate is _numba_compile.copy_propagate
        assert parfor.copy_propagate is _numba_compile.copy_propagate
    else:
        assert ir_utils.copy_propagate is _numba_compile._numba_copy_propagate


# -- inlining -----------------------------------------------------------------------------------


@njit(inline="always")
def _clipped(a, lo, hi):
    """Branches and a loop: an inlined callee of several blocks."""
    for _ in range(3):
        if a < lo:
            a = lo + 0.25 * (lo - a)
        elif a > hi:
            a = hi - 0.25 * (a - hi)
    return a


@njit(inline="always")
def _step(x, w, i):
    b = np.sin(x[i]) * w[i]  # numba's overloads inline too
    return _clipped(b, -0.5, 0.5) + _clipped(-b, -0.25, 0.75)


def _inlining_kernel(x, w, out):
    for i in prange(x.shape[0]):
        out[i] = _step(x, w, i) if x[i] > 0.0 else _step(w, x, i)
    return out.sum()


#: compiles :func:`_inlining_kernel` in a fresh process with numba's ``inline_ir`` or the
#: replacement (argv[1]) and prints how many times it ran and the SHA-1 of the LLVM IR (the
#: addresses in the names of parfor functions masked: they differ between any two processes)
_COMPILE_IN_A_FRESH_PROCESS = """
import hashlib, re, sys
import numpy as np
from numba import njit
from numba.core import inline_closurecall
sys.path.insert(0, sys.argv[2])
import test_numba_compile as t
from antisync import _numba_compile as nc

numbas = nc._numba_inline_ir
ours = nc.inline_ir or nc._inline_ir_from(t.inspect.getsource(numbas))
function = numbas if sys.argv[1] == "numba" else ours
calls = []

def inline_ir(*args, **kwargs):
    calls.append(1)
    return function(*args, **kwargs)

inline_closurecall.InlineWorker.inline_ir = inline_ir
kernel = njit(parallel=True)(t._inlining_kernel)
out = np.empty(29)
total = kernel(np.linspace(-1.0, 1.0, 29), np.cos(np.arange(29.0)), out)
text = re.sub(r"0x[0-9a-f]+", "0x", "".join(kernel.inspect_llvm().values()))
digests = [hashlib.sha1(b).hexdigest() for b in (text.encode(), out.tobytes())]
print(len(calls), len(text), total.hex(), *digests)
"""


def test_the_replacement_inlines_to_the_same_llvm_ir():
    """A parallel kernel of inlined functions (ours and numba's overloads), compiled with
    numba's ``inline_ir`` and with the replacement, each in a fresh process with the same hash
    seed (numba numbers blocks and functions by process-wide counters): the same LLVM IR, the
    same output, and each compile ran its own inlining as often. (Under any numba whose
    ``inline_ir`` copies the blocks as 0.68.1's does; the replacement is installed only where
    the whole source is the known one.)"""
    numbas = _numba_compile._numba_inline_ir
    if (_numba_compile.inline_ir or _numba_compile._inline_ir_from(inspect.getsource(numbas))) is None:
        assert not _numba_compile.inline_installed  # another numba's inlining: left as it is
        return
    env = dict(os.environ, PYTHONHASHSEED="0")
    here = str(Path(__file__).resolve().parent)
    lines = [
        subprocess.run(
            [sys.executable, "-c", _COMPILE_IN_A_FRESH_PROCESS, which, here],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        for which in ("numba", "ours")
    ]
    assert int(lines[0][0]) >= 4  # the inlining ran, in both (the same number of times)
    assert lines[1] == lines[0]


def test_the_inlining_is_installed_where_numbas_source_is_the_known_one():
    known = hashlib.sha1(inspect.getsource(_numba_compile._numba_inline_ir).encode()).hexdigest()
    assert _numba_compile.inline_installed == (known in _numba_compile.KNOWN_INLINE)
    want = _numba_compile.inline_ir if _numba_compile.inline_installed else _numba_compile._numba_inline_ir
    assert inline_closurecall.InlineWorker.inline_ir is want


# -- liveness -----------------------------------------------------------------------------------


def test_the_liveness_is_numbas_on_every_call_of_a_parallel_compile(monkeypatch):
    """Compiling parallel kernels (branches, loops, copies and inlined callees in their
    ``prange`` bodies), every liveness map numba asks for (the parfor passes', dead-code
    removal's, the variable lifetimes' that place the deletions) is computed by numba's own
    function and by the replacement on the same blocks: the same sets on every call, and the
    kernels' results unchanged. (Under any numba: the replacement is installed only where
    numba's source is the known one.)"""
    from numba.core import analysis

    numbas = _numba_compile._numba_compute_live_map
    calls = []

    def both(cfg, blocks, var_use_map, var_def_map):
        want = numbas(cfg, blocks, var_use_map, var_def_map)
        got = _numba_compile.compute_live_map(cfg, blocks, var_use_map, var_def_map)
        assert got == want
        calls.append(sum(len(s) for s in want.values()))
        return got

    for module in (analysis, ir_utils, parfor):
        monkeypatch.setattr(module, "compute_live_map", both)
    x = np.linspace(-1.0, 1.0, 37)
    w = np.cos(np.arange(37.0))
    got = np.empty(37)
    njit(parallel=True)(_parallel_kernel)(x, w, got, 5)  # no cache: compiled here
    want = np.empty(37)
    _parallel_kernel(x, w, want, 5)
    np.testing.assert_array_equal(got, want)
    got = np.empty(37)
    njit(parallel=True)(_inlining_kernel)(x, w, got)
    want = np.empty(37)
    _inlining_kernel(x, w, want)
    np.testing.assert_array_equal(got, want)
    assert len(calls) >= 10 and max(calls) > 0  # every pass that asks, on blocks with live variables


def test_the_liveness_is_installed_where_numbas_source_is_the_known_one():
    from numba.core import analysis

    known = hashlib.sha1(inspect.getsource(_numba_compile._numba_compute_live_map).encode()).hexdigest()
    assert _numba_compile.live_installed == (known in _numba_compile.KNOWN_LIVE)
    want = (
        _numba_compile.compute_live_map
        if _numba_compile.live_installed
        else _numba_compile._numba_compute_live_map
    )
    for module in (analysis, ir_utils, parfor):
        assert module.compute_live_map is want
