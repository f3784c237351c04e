"""A faster fixed point in numba's copy propagation: the same result, a quarter less compile time
for a parallel kernel.

``numba.core.ir_utils.copy_propagate`` iterates its data-flow equations to a fixed point and, to
detect the fixed point, snapshots the per-block sets of copies with ``copy.deepcopy`` after every
sweep. The sets hold tuples of variable names (strings), so a set copy per block is the same
snapshot; ``deepcopy`` walks every tuple in pure Python. In the parallel lane drivers' compile
(the ``prange`` bodies of hundreds of blocks, simplified again and again by the parfor passes)
the snapshots were a third of the profile: with this module, a cold compile of the model's RK4
lane driver takes 30 s instead of 41-42 s (``bench/compile_probe.py lanes``, with and without
``--numba-copy-propagate``), and ``tests/test_capabilities.py`` 309 s instead of 353 s (cold
caches, the same two-core machine, side by side).

The replacement is numba's own function with that one line changed; it returns the same
``(in_copies, out_copies)`` and so changes no compiled code: tests/test_numba_compile.py
compiles a parallel function under a check that runs both on every call and compares them, and
that lane driver's LLVM IR (1.1 MB) is the same text either way (bench/RESULTS.md).
It replaces numba's only where numba's source is the one it was written against (the SHA-1 of
:func:`inspect.getsource` below); any other numba keeps its own. Numba is patched by name in
the two modules that call it, ``ir_utils`` and ``parfors.parfor`` (which imported it by name).

Every module that compiles with ``cache=True`` imports :mod:`antisync._numba_cache`, which
imports this module.
"""

from __future__ import annotations

import hashlib
import inspect

from numba.core import config, ir_utils

__all__ = ["copy_propagate", "installed"]

#: SHA-1 of ``inspect.getsource(numba.core.ir_utils.copy_propagate)`` in the numba versions the
#: replacement was checked against (0.68.1)
KNOWN = {"1a90423ce674489b91d5160d7de74135ce4a9f62"}

_numba_copy_propagate = ir_utils.copy_propagate


def _snapshot(copies: dict) -> dict:
    """``copy.deepcopy(copies)`` for a dict of sets of tuples of names: a new set per block."""
    return {label: set(pairs) for label, pairs in copies.items()}


def copy_propagate(blocks, typemap):
    """numba's ``ir_utils.copy_propagate``, its fixed point snapshotted by :func:`_snapshot`."""
    cfg = ir_utils.compute_cfg_from_blocks(blocks)
    entry = cfg.entry_point()
    gen_copies, _all, kill_copies, in_copies, out_copies = ir_utils.init_copy_propagate_data(
        blocks, entry, typemap
    )
    old_point = None
    new_point = _snapshot(out_copies)
    while old_point != new_point:
        for label in blocks.keys():
            if label == entry:
                continue
            predecs = [i for i, _d in cfg.predecessors(label)]
            # in_b = intersect(predec(B))
            in_copies[label] = out_copies[predecs[0]].copy()
            for p in predecs:
                in_copies[label] &= out_copies[p]
            # out_b = gen_b | (in_b - kill_b)
            out_copies[label] = gen_copies[label] | (in_copies[label] - kill_copies[label])
        old_point = new_point
        new_point = _snapshot(out_copies)
    if config.DEBUG_ARRAY_OPT >= 1:
        print("copy propagate out_copies:", out_copies)
    return in_copies, out_copies


def _install() -> bool:
    try:
        source = inspect.getsource(_numba_copy_propagate)
    except (OSError, TypeError):
        return False
    if hashlib.sha1(source.encode()).hexdigest() not in KNOWN:
        return False  # another numba: its own copy propagation
    from numba.parfors import parfor

    ir_utils.copy_propagate = copy_propagate
    if getattr(parfor, "copy_propagate", None) is _numba_copy_propagate:
        parfor.copy_propagate = copy_propagate
    return True


#: whether numba's copy propagation is this module's (False: numba's own, another version)
installed = _install()
