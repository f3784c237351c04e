"""Parallel loops whose work per item comes in as a first-class function.

A ``@njit(parallel=True)`` driver that calls a jitted function in its ``prange`` body links that
function's code into its own and optimizes all of it again: its cold compile costs about as
much as the function's (a driver of Rodas4's items, 8 s on top of the integrator's 10 s). Here
the loop is a plain Python function, ``loop(fn, *groups)``, whose ``prange`` body calls
``fn(..., i)``; :func:`run` compiles it with ``fn`` typed as numba's ``FunctionType`` (the
signature ``fn`` takes: the groups' types, then the item's index), so that the loop never links
``fn`` and is compiled once per argument types, cached on disk with antisync's kernels, whatever
function it runs: the items of every user law share one loop. ``fn`` itself is compiled (or
loaded from its cache) for that signature when it is first passed.

The call goes through a function pointer once per item, never per step: an item is a whole
trajectory, a group of lanes, a realization's adjoint or a line trip.

A group is a tuple the loop passes on: whole (``fn`` takes the tuple) or spread into the call
(``spread``: ``fn`` takes its elements). A tuple inside a tuple cannot enter a parallel loop
(numba's gufunc wrapper refuses it), so a loop takes the tuples ``fn`` takes whole, such as a
clock or a factorization plan, as groups of their own. A loop binds nothing from a group inside
its ``prange`` body but passes it on: a parallel loop loses its writes to arrays bound by
unpacking a tuple (tests/test_architecture.py); ``fn`` is an ordinary function, where that
does not happen.
"""

from __future__ import annotations

import functools

import numba
from numba import njit, types

from antisync import _numba_cache  # noqa: F401 -- antisync's cache folder for cache=True

__all__ = ["run"]


@functools.cache
def _compiled(loop, group_types: tuple, spread: tuple):
    call = []
    for k, t in enumerate(group_types):
        call += list(t.types) if k in spread else [t]
    fn = types.FunctionType(types.void(*call, types.int64))
    return njit(types.void(fn, *group_types), parallel=True, cache=True)(loop)


def run(loop, fn, *groups, spread: tuple = ()) -> None:
    """``loop(fn, *groups)``, ``loop`` compiled as a parallel function for the groups' types
    (``numba.typeof``) and ``fn`` for ``(the groups, spread where their index is in ``spread``,
    then an int64 index)``. An exception raised in ``fn`` is raised here as itself (numba reports
    it from a first-class function as a ``SystemError`` whose cause it is)."""
    loop = _compiled(loop, tuple(numba.typeof(g) for g in groups), tuple(spread))
    try:
        loop(fn, *groups)
    except SystemError as err:
        if err.__cause__ is None:
            raise
        raise err.__cause__ from None
