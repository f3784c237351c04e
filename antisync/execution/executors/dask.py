"""Dask executor: the chunks of the local executor, computed on the workers of a Dask cluster.

Workers only compute: each task is :func:`~antisync.execution.compute.compute_chunk` on one chunk and
returns its :class:`~antisync.execution.compute.ChunkResult` to the client, where the runner journals
and merges it by block position like any other. Which worker ran a chunk, in which order, and
how often a chunk was retried therefore cannot change the numbers.

:class:`DaskExecutor` takes a ``distributed.Client`` and builds no cluster;
:meth:`DaskExecutor.from_options` is the one place that does, for the command line
(``--workers N`` starts a ``LocalCluster``, ``--scheduler ADDRESS`` connects to a running one).

Other work (a grid's line removal) submits its own pure function through :func:`map_on_client`
(usually by way of :func:`antisync.execution.executors.tasks.map_tasks`), on a client its caller
owns and checks with :func:`check_client`: this module is the one that talks to the cluster.
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from antisync.errors import AntisyncError
from antisync.execution.compute import ChunkResult, compute_chunk
from antisync.plan.jobs import Chunk, Job

__all__ = [
    "CONNECT_TIMEOUT",
    "DASHBOARD_ADDRESS",
    "TASKS_PER_THREAD",
    "DaskExecutor",
    "TaskLostError",
    "check_client",
    "client_threads",
    "map_on_client",
    "quiet_shutdown",
]

#: Tasks kept in flight per worker thread: enough that a worker never waits for the client
#: between chunks, few enough that a 1e9-realization job is not millions of futures at once.
TASKS_PER_THREAD = 3

#: Seconds to wait for a scheduler before giving up with a one-line error.
CONNECT_TIMEOUT = 5.0

#: Where a ``LocalCluster`` of :meth:`DaskExecutor.from_options` serves its dashboard: a free
#: port (``":0"``), never a fixed one that another cluster may hold.
DASHBOARD_ADDRESS = ":0"

# times one chunk may be resubmitted after the cluster cancelled it, before the run stops
_MAX_RESUBMITS = 3

# numba's workqueue threading layer aborts the process when two threads launch parallel
# kernels at once; a worker with several threads then runs its chunks one at a time.
_WORKQUEUE_LOCK = threading.Lock()


def _compute_on_worker(job: Job, chunk: Chunk, backend: str, threads: int) -> ChunkResult:
    """The task body: :func:`compute_chunk`, serialized only where numba needs it."""
    if backend == "cpu" and _workqueue_layer():
        with _WORKQUEUE_LOCK:
            return compute_chunk(job, chunk, backend, threads)
    return compute_chunk(job, chunk, backend, threads)


def _workqueue_layer() -> bool:
    import numba

    try:
        return numba.threading_layer() == "workqueue"
    except ValueError:  # no parallel kernel has run in this process yet: assume the worst
        return True


class DaskExecutor:
    """Runs chunks as Dask tasks and yields their results as they finish.

    Parameters
    ----------
    client : distributed.Client
        A connected client; the executor does not close it (unless it was made by
        :meth:`from_options`).
    backend : {"cpu", "cuda"}
        Backend of :func:`~antisync.execution.compute.compute_chunk` on the workers.
    threads : int, optional
        Numba threads per task. Default 1: Dask already runs one task per worker thread, and
        a worker per core with one numba thread each uses every core without oversubscribing
        them. Give more only for single-threaded workers on multi-core machines
        (``dask worker --nworkers 1 --nthreads 1`` per node).
    tasks_per_thread : int
        In-flight limit: at most this many unfinished tasks per worker thread (at least this
        many in all); more are submitted as results come back.
    log : callable, optional
        Receives one-line messages (worker deaths, retries).

    Notes
    -----
    The :class:`~antisync.plan.jobs.Job` is scattered to the workers once per job
    (``broadcast=True``); tasks carry only their :class:`~antisync.plan.jobs.Chunk`. A worker
    that dies mid-chunk makes the scheduler run the chunk again elsewhere; its first result is
    the only one yielded (finished chunks are tracked by job and block), so nothing is lost or
    counted twice.
    """

    name = "dask"

    def __init__(
        self,
        client,
        backend: str = "cpu",
        threads: int | None = None,
        *,
        tasks_per_thread: int = TASKS_PER_THREAD,
        log: Callable[[str], None] | None = None,
    ):
        if backend not in ("cpu", "cuda"):
            raise AntisyncError(f"the Dask executor runs backend cpu or cuda, got {backend!r}")
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise AntisyncError(f"threads must be None or an integer >= 1, got {threads!r}")
        if not isinstance(tasks_per_thread, int) or tasks_per_thread < 1:
            raise AntisyncError(f"tasks_per_thread must be an integer >= 1, got {tasks_per_thread!r}")
        self.client = client
        self.backend = backend
        self.threads = threads
        self.tasks_per_thread = tasks_per_thread
        self._say = log or (lambda msg: None)
        self._cluster = None  # set by from_options when the executor owns a LocalCluster
        self._owns_client = False
        self._threads_seen = 0
        self._threads_checked = -1e9

    # ---- construction for the CLI ------------------------------------------------------------
    @classmethod
    def from_options(
        cls,
        cfg,
        workers: int | None = None,
        scheduler: str | None = None,
        log: Callable[[str], None] | None = None,
        *,
        connect_timeout: float = CONNECT_TIMEOUT,
    ) -> DaskExecutor:
        """Make a client for ``antisync run`` and an executor that owns it.

        Parameters
        ----------
        cfg : Config
            Supplies ``backend`` and ``threads``.
        workers : int, optional
            Start a ``LocalCluster(n_workers=workers, threads_per_worker=1, processes=True)``.
        scheduler : str, optional
            Connect to the scheduler at this address (``tcp://host:8786``).
        connect_timeout : float
            Seconds before an unreachable scheduler is an :class:`AntisyncError`.

        Neither given: the scheduler named by Dask's own ``scheduler-address`` setting
        (``DASK_SCHEDULER_ADDRESS``) if there is one, else a ``LocalCluster`` with one
        single-threaded worker per core.
        """
        from antisync.kernels.backends import resolve_backend

        say = log or (lambda msg: None)
        if workers is not None and scheduler is not None:
            raise AntisyncError(
                "--workers starts a local Dask cluster and --scheduler connects to a running one: "
                "give only one of them"
            )
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise AntisyncError(f"--workers must be an integer >= 1, got {workers!r}")
        backend, _ = resolve_backend(cfg.backend)
        if workers is None and scheduler is None:
            import dask

            scheduler = dask.config.get("scheduler-address", None)
            if scheduler:
                say(f"Dask: using scheduler-address {scheduler} from the Dask configuration")
        if scheduler:
            client = _connect(scheduler, connect_timeout)
            cluster = None
            info = client.scheduler_info()
            n = len(info.get("workers", {}))
            say(
                f"Dask: connected to {scheduler} ({n} worker{'s' if n != 1 else ''}"
                + ("; tasks wait until workers join)" if n == 0 else ")")
            )
        else:
            from distributed import Client, LocalCluster

            n = workers or _cores()
            # the dashboard on a free port (its link is said below): the default 8787 is often
            # taken by another cluster, and distributed then warns "Port 8787 is already in use"
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=DASHBOARD_ADDRESS
            )
            client = Client(cluster, set_as_default=False)
            client.register_plugin(_quiet_close_plugin())
            say(
                f"Dask: started a LocalCluster of {n} single-threaded worker process"
                f"{'es' if n != 1 else ''} at {cluster.scheduler_address}"
            )
        link = _dashboard(client)
        if link:
            say(f"Dask dashboard: {link}")
        ex = cls(client, backend, cfg.threads, log=say)
        ex._cluster = cluster
        ex._owns_client = True
        return ex

    # ---- executor interface --------------------------------------------------------------------
    def run(self, work: Iterable[tuple[Job, Chunk]]) -> Iterator[tuple[Job, ChunkResult]]:
        """Submit ``(job, chunk)`` pairs, at most the in-flight limit at a time; yield results
        in the order they finish (the runner merges them by block position)."""
        from concurrent.futures import CancelledError

        from distributed import as_completed
        from distributed.scheduler import KilledWorker

        work = iter(work)
        finished = as_completed(loop=self.client.loop)
        pending: dict = {}  # future -> (job, chunk)
        done: set = set()  # (job name, first block) already yielded
        scattered: dict = {}  # job name -> [future of the Job, tasks using it]
        resubmits: dict = {}  # (job name, first block) -> times resubmitted
        exhausted = False
        try:
            while True:
                limit = self._in_flight_limit()
                while not exhausted and len(pending) < limit:
                    try:
                        job, chunk = next(work)
                    except StopIteration:
                        exhausted = True
                        break
                    if (job.name, chunk.first_block) in done:
                        continue
                    fut = self._submit(job, chunk, scattered)
                    pending[fut] = (job, chunk)
                    finished.add(fut)
                if not pending:
                    return
                fut = next(finished)
                job, chunk = pending.pop(fut)
                self._unref(job, scattered)
                try:
                    res = None if fut.status == "cancelled" else fut.result()
                except CancelledError:
                    # finished, then its worker died before the result was gathered: the
                    # scheduler reschedules it and, when the scattered job died too, cancels it
                    res = None
                except KilledWorker as exc:
                    raise AntisyncError(
                        f"chunk at block {chunk.first_block} of {job.name} killed "
                        f"{exc.allowed_failures + 1} Dask workers (out of memory? see the worker "
                        "logs); finished chunks are saved: fix the workers and rerun with --resume"
                    ) from None
                if res is None:
                    # the scheduler dropped it (e.g. every copy of the scattered job was lost
                    # with its workers): scatter again and resubmit; nothing was merged yet
                    key = (job.name, chunk.first_block)
                    resubmits[key] = resubmits.get(key, 0) + 1
                    if resubmits[key] > _MAX_RESUBMITS:
                        raise AntisyncError(
                            f"the Dask cluster cancelled the chunk at block {chunk.first_block} "
                            f"of {job.name} {resubmits[key]} times (workers lost?); finished "
                            "chunks are saved: rerun with --resume"
                        )
                    self._say(
                        f"Dask: chunk at block {chunk.first_block} of {job.name} was "
                        "cancelled by the cluster; resubmitting it"
                    )
                    fut = self._submit(job, chunk, scattered)
                    pending[fut] = (job, chunk)
                    finished.add(fut)
                    continue
                del fut
                key = (job.name, chunk.first_block)
                if key in done:  # a duplicate can only come from a resubmission: drop it
                    continue
                done.add(key)
                yield job, res
        finally:
            # best effort: a lost scheduler must not hide the error that ended the run
            with contextlib.suppress(Exception):
                if pending:
                    self.client.cancel(list(pending))
                for fut, _ in scattered.values():
                    fut.release()

    def describe(self) -> str:
        n, t = self._workers_threads()
        k = self.threads or 1
        return (
            f"dask executor, {_plural(n, 'worker')} / {_plural(t, 'thread')}, "
            f"{_plural(k, 'numba thread')} per task"
        )

    def close(self) -> None:
        """Close the client and cluster made by :meth:`from_options`; a given client stays open.

        Whoever makes an executor closes it: ``run_jobs`` and ``run_sweep`` use a given
        executor for every stage and leave it open.
        """
        if self._owns_client and self.client is not None:
            with quiet_shutdown():
                self.client.close()  # the client first: the cluster then has no one to tell
                if self._cluster is not None:
                    self._cluster.close()
            self.client = None
            self._cluster = None

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- helpers -------------------------------------------------------------------------------
    def _submit(self, job: Job, chunk: Chunk, scattered: dict):
        entry = scattered.get(job.name)
        if entry is None or entry[0].status != "finished":
            # once per job, on every worker: tasks then carry only their chunk (again only if
            # the cluster lost every copy)
            fut = self.client.scatter(job, broadcast=True, hash=False)
            entry = scattered[job.name] = [fut, entry[1] if entry else 0]
        entry[1] += 1
        key = f"antisync-chunk-{job.name}-{chunk.first_block}-{uuid.uuid4().hex[:12]}"
        return self.client.submit(
            _compute_on_worker,
            entry[0],
            chunk,
            self.backend,
            self.threads or 1,
            key=key,
            pure=False,
        )

    @staticmethod
    def _unref(job: Job, scattered: dict) -> None:
        entry = scattered.get(job.name)
        if entry is None:
            return
        entry[1] -= 1
        if entry[1] <= 0:  # no task of this job is in flight: let the workers forget it
            entry[0].release()
            del scattered[job.name]

    def _in_flight_limit(self) -> int:
        # refreshed at most every 2 s: workers may join (adaptive or batch-queued clusters)
        now = time.monotonic()
        if now - self._threads_checked > 2.0:
            self._threads_seen = self._workers_threads()[1]
            self._threads_checked = now
        return self.tasks_per_thread * max(1, self._threads_seen)

    def _workers_threads(self) -> tuple[int, int]:
        nthreads = self.client.nthreads()
        return len(nthreads), sum(nthreads.values())


# ---- any pure function over tasks, on a client the caller owns ---------------------------------
class TaskLostError(AntisyncError):
    """The cluster lost a task of :func:`map_on_client` (its workers died, or it was cancelled);
    ``cause``: the ``KilledWorker`` or ``CancelledError`` it ended with."""

    def __init__(self, cause: BaseException):
        super().__init__(f"the Dask cluster lost a task ({type(cause).__name__}: {cause})")
        self.cause = cause


def check_client(client, *, hint: str, error: type[Exception] = AntisyncError) -> None:
    """Refuse, before any work, a ``client`` that is not an open ``distributed.Client``.

    The caller owns the cluster (a function handed a client never builds or closes one), so a
    scheduler address is not opened here: the one-line ``error`` ends with ``hint`` (how to
    open one). None (no cluster) passes.
    """
    if client is None:
        return
    # distributed is imported only when a client is given: importing it costs about a second
    from distributed import Client

    if not isinstance(client, Client):
        got = f"{type(client).__name__} {client!r:.80}"
        raise error(f"client must be a distributed.Client, got {got}; {hint}")
    if client.status not in ("running", "connecting", "newly-created"):
        raise error(f"client is a distributed.Client that is {client.status}: pass an open one")


def client_threads(client) -> int:
    """The worker threads of ``client``'s cluster now (0 while no worker has joined)."""
    return sum(client.nthreads().values())


def map_on_client(client, fn: Callable[..., Any], calls: Iterable[tuple]) -> Iterator[tuple[int, Any]]:
    """``fn(*calls[i])`` of every call on ``client``'s workers: ``(i, result)`` as they finish.

    Every call is submitted at once (``pure=False``: each runs, even with equal arguments), an
    argument that every call shares (the same object) sent to the workers once; on
    any exit, what has not finished is cancelled, and the client stays open (its caller owns
    it). A task that the cluster loses (``KilledWorker``, ``CancelledError``) is a
    :class:`TaskLostError`: the results yielded before it stay valid, so a caller that saved
    them can resume.
    """
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    calls = list(calls)
    # an argument every call shares (a grid: a dense coupling matrix of N^2 doubles) goes to
    # the workers once, not in each task's message
    shared = {id(a): a for a in calls[0]} if len(calls) > 1 else {}
    for call in calls[1:]:
        shared = {id(a): a for a in call if id(a) in shared}
    # each in a list of one: scattering a dict itself would send each value under the dict's
    # own keys ("dt", "rtol"), shared by every map's settings, so two maps on one client
    # would read each other's values or lose them when the other's futures were released
    sent = {
        k: client.scatter([a], broadcast=True, hash=False)[0]
        for k, a in shared.items()
        if a is not None and not isinstance(a, bool | int | float | str)
    }
    futures = {
        client.submit(fn, *(sent.get(id(a), a) for a in call), pure=False): i for i, call in enumerate(calls)
    }
    try:
        for fut in as_completed(list(futures), loop=client.loop):
            try:
                result = fut.result()
            except (KilledWorker, CancelledError) as exc:
                raise TaskLostError(exc) from None
            yield futures[fut], result
    finally:
        client.cancel(list(futures))


@contextlib.contextmanager
def quiet_shutdown(level: int = logging.ERROR) -> Iterator[None]:
    """Raise the level of distributed's loggers to ``level`` while a cluster shuts down.

    Closing a ``LocalCluster`` whose worker is still computing a chunk (one cancelled when a
    stopping rule or an error ended the run: a numba kernel cannot be interrupted) makes its
    nanny wait 4 s, kill the process and warn "Worker process still alive after 4.0 seconds,
    killing": noise after a correct run. Errors still show, and the levels are restored after.
    """
    logger = logging.getLogger("distributed")
    old = logger.level
    logger.setLevel(max(level, logger.getEffectiveLevel()))
    try:
        yield
    finally:
        logger.setLevel(old)


#: The one error a closing worker logs about its own shutdown: a heartbeat that was under way
#: when its connection pool closed (a race of the cluster's close, seen on a correct run).
_SHUTDOWN_RACE = "Failed to communicate with scheduler during heartbeat"


def _quiet_close_plugin():
    """A worker plugin for the executor's own ``LocalCluster``: a worker process that closes
    while computing a chunk (see :func:`quiet_shutdown`) logs no warning about it ("Async
    instruction ... ended with CancelledError"), nor the heartbeat its own close cut short
    (:data:`_SHUTDOWN_RACE`); other errors, and every message of a running worker, still show."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class QuietClose(WorkerPlugin):
        name = "antisync-quiet-close"

        def setup(self, worker):
            from distributed.core import Status

            closing = {Status.closing, Status.closing_gracefully, Status.closed}

            def keep(record: logging.LogRecord) -> bool:
                if worker.status not in closing:
                    return True
                return record.levelno >= logging.ERROR and not record.getMessage().startswith(_SHUTDOWN_RACE)

            for handler in logging.getLogger("distributed").handlers:
                handler.addFilter(keep)

    return QuietClose()


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _dashboard(client) -> str | None:
    try:
        if "dashboard" not in client.scheduler_info().get("services", {}):
            return None
        return client.dashboard_link
    except Exception:  # the dashboard is a convenience; never fail a run over it
        return None


def _connect(address: str, timeout: float):
    """A ``Client`` for ``address``, or an :class:`AntisyncError` within about ``timeout`` s."""
    from distributed import Client
    from distributed.comm.addressing import parse_address, parse_host_port

    hint = "give an address like tcp://host:8786 of a running `dask scheduler`"
    try:
        scheme, loc = parse_address(address)
        host, port = parse_host_port(loc) if scheme in ("tcp", "tls") else (None, None)
    except (ValueError, TypeError) as exc:
        raise AntisyncError(f"Dask scheduler address {address!r} is not valid ({exc}); {hint}") from None
    if host is not None:
        # a plain TCP probe first: a refused connection fails at once, and no half-built
        # Client is left behind to time out again when it is garbage-collected
        try:
            with socket.create_connection((host, port), timeout=timeout):
                pass
        except OSError as exc:
            why = (
                f"no answer within {timeout:g} s"
                if isinstance(exc, TimeoutError)
                else (exc.strerror or str(exc)).lower()
            )
            raise AntisyncError(f"cannot reach the Dask scheduler at {address} ({why}); {hint}") from None
    # ask it who it is before building a Client: a Client that fails half-way is left to
    # time out again, noisily, when it is garbage-collected
    if _identity(address, timeout) != "Scheduler":
        raise AntisyncError(f"something answers at {address}, but not as a Dask scheduler; {hint}")
    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise AntisyncError(f"cannot connect to the Dask scheduler at {address} ({exc}); {hint}") from None


def _identity(address: str, timeout: float) -> str | None:
    """The ``type`` a Dask server at ``address`` reports (``"Scheduler"``), or None."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.core import rpc

    async def ask():
        async with rpc(address, timeout=timeout) as server:
            return await asyncio.wait_for(server.identity(), timeout)

    # in a thread of its own: the caller may already run an event loop (a notebook)
    with ThreadPoolExecutor(1) as pool:
        try:
            reply = pool.submit(asyncio.run, ask()).result()
        except Exception:  # a silent or non-Dask server can fail in any way
            return None
    return reply.get("type") if isinstance(reply, dict) else None
