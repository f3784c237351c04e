"""A pure function over tasks, here or on a Dask cluster: the generic way for work that is not a
run's chunks (a grid's line removal) to use the executors.

:func:`map_tasks` calls the function in this process, in order, or hands every call to
:func:`antisync.execution.executors.dask.map_on_client` (the one module that talks to the
cluster). The caller owns the client: nothing here builds, connects or closes one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from antisync.execution.executors.dask import map_on_client

__all__ = ["map_tasks"]


def map_tasks(fn: Callable[..., Any], calls: Iterable[tuple], *, client=None) -> Iterator[tuple[int, Any]]:
    """``(i, fn(*call))`` for the ``i``-th of ``calls``.

    Parameters
    ----------
    fn : callable
        A pure function: its result depends on its arguments alone, so where and in which
        order the calls run cannot change it (on a cluster it must be importable by the
        workers: a module-level function).
    calls : iterable of tuple
        The arguments of each call. Here they are taken one at a time, as each call starts
        (only one call's arguments are built at once); on a cluster all are submitted at once.
    client : distributed.Client, optional
        Run the calls on this cluster's workers (its caller checks it, e.g. with
        :func:`antisync.execution.executors.dask.check_client`, and closes it); None: in this
        process, in order, the function's own threads doing the parallel work.

    Yields
    ------
    (int, object)
        The call's position in ``calls`` and its result: in order here, as they finish on a
        cluster.

    Raises
    ------
    antisync.execution.executors.dask.TaskLostError
        The cluster lost a call (its workers died): the results yielded before stay valid.
    """
    if client is None:
        for i, call in enumerate(calls):
            yield i, fn(*call)
        return
    yield from map_on_client(client, fn, calls)
