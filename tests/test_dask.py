"""The Dask executor gives the local executor's numbers exactly: with other chunk sizes, with
a worker killed mid-chunk, and through the CLI. A real two-process LocalCluster, no mocks."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import signal
import socket
import time
import warnings

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("distributed")

from helpers import local_cluster_client  # noqa: E402

from antisync.cli.app import app  # noqa: E402
from antisync.errors import AntisyncError  # noqa: E402
from antisync.execution.executors.dask import DaskExecutor  # noqa: E402
from antisync.execution.executors.local import LocalExecutor  # noqa: E402
from antisync.execution.runner import run_config  # noqa: E402
from antisync.plan.config import load_config  # noqa: E402

TINY = """\
name: tiny
graph: {kind: lollipop, nodes: 5, path: 2}
edges: ["2->1", "3->4"]
betas: [0.5]
realizations: 400
block_size: 50
seed: 3
"""
ARRAYS = ("block_records", "hist", "tau0_records", "blocks_done", "tail_counts")
UNREACHABLE = "tcp://127.0.0.1:1"


@pytest.fixture(scope="module")
def client():
    with local_cluster_client() as c:
        yield c


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("cfg") / "tiny.yaml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def reference(config_path, tmp_path_factory):
    """The local executor's run, in one chunk: arrays and `antisync summary --format json`."""
    out = tmp_path_factory.mktemp("local") / "local.h5"
    run_config(load_config(config_path), output=out, executor=LocalExecutor("cpu", None))
    return _arrays(out), _summary(out)


def _arrays(path) -> dict:
    with h5py.File(path, "r") as f:
        (name,) = f["jobs"]
        return {k: f[f"jobs/{name}/{k}"][()] for k in ARRAYS}


def _summary(path) -> list:
    res = CliRunner().invoke(app, ["summary", str(path), "--format", "json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)["records"]


def _assert_same(path, reference) -> None:
    arrays, summary = reference
    got = _arrays(path)
    for k in ARRAYS:
        assert got[k].dtype == arrays[k].dtype, k
        assert np.array_equal(got[k], arrays[k]), k  # exact: integers and per-block sums
    assert _summary(path) == summary


class Watched:
    """An executor around another that counts the chunks it has pulled from ``work`` and calls
    ``on_result(i, pulled, item)`` after the i-th result (1-based)."""

    def __init__(self, inner, on_result):
        self.inner, self.on_result, self.pulled = inner, on_result, 0

    def run(self, work):
        def counted():
            for item in work:
                self.pulled += 1
                yield item

        for i, item in enumerate(self.inner.run(counted()), 1):
            self.on_result(i, self.pulled, item)
            yield item

    def describe(self):
        return self.inner.describe()

    def close(self):
        self.inner.close()


def test_same_numbers_as_local_with_bounded_in_flight(client, config_path, reference, tmp_path):
    ex = DaskExecutor(client, "cpu", tasks_per_thread=1)
    limit = 1 * 2  # tasks_per_thread * worker threads

    def check(i, pulled, item):
        assert pulled - i < limit  # never more than `limit` unfinished tasks

    out = run_config(
        load_config(config_path),
        output=tmp_path / "d.h5",
        executor=Watched(ex, check),
        chunk_realizations=50,
    )  # 8 one-block chunks
    _assert_same(out, reference)
    assert client.status == "running"  # a given client is not the executor's to close


def _results_waiting(client, yielded: int) -> int:
    """Chunks finished on a worker whose future the executor still holds, other than the one
    at block ``yielded`` (gathered, its future perhaps not yet released)."""
    held = set(client.futures)
    return sum(
        1
        for k, ws in client.who_has().items()
        if ws and k in held and "chunk" in str(k) and f"-{yielded}-" not in str(k)
    )


@pytest.mark.parametrize("victims", ["one", "all", "all-holding-results"])
def test_worker_killed_mid_chunk(client, config_path, reference, tmp_path, victims):
    """SIGKILL worker processes after the first result: their chunks are rerun elsewhere (or,
    when every copy of the scattered job died with them, resubmitted), none merged twice.

    "all-holding-results" kills them once a further chunk has finished but is not yet
    gathered: its result dies with the worker, and the rescheduled task is cancelled while the
    executor waits on it (a race a CI run met)."""
    client.wait_for_workers(2, timeout=60)
    pids = client.run(os.getpid)
    killed = []

    def kill(i, pulled, item):
        if i != 1:
            return
        if victims == "all-holding-results":
            deadline = time.monotonic() + 30
            first = item[1].chunk.first_block
            while not _results_waiting(client, first) and time.monotonic() < deadline:
                time.sleep(0.02)
            assert _results_waiting(client, first), "no finished chunk waited to be gathered"
        busy = {w for w, keys in client.processing().items() if keys}
        targets = [w for w in pids if w in busy][:1] if victims == "one" else list(pids)
        assert targets, "no worker was busy: nothing to kill"
        for w in targets:
            os.kill(pids[w], signal.SIGKILL)
            killed.append(w)

    said = []
    out = run_config(
        load_config(config_path),
        output=tmp_path / "k.h5",
        executor=Watched(DaskExecutor(client, log=said.append), kill),
        chunk_realizations=50,
    )
    assert killed
    if victims != "one":  # the scattered job died with its last copy: resubmitted, not lost
        assert any("resubmitting" in m for m in said), said
    _assert_same(out, reference)
    client.wait_for_workers(2, timeout=60)  # nannies restart the killed workers


def test_unreachable_scheduler_is_a_quick_user_error(config_path):
    start = time.monotonic()
    with pytest.raises(AntisyncError, match="127.0.0.1:1"):
        DaskExecutor.from_options(load_config(config_path), scheduler=UNREACHABLE)
    assert time.monotonic() - start < 15  # a failure-mode timeout, not a speed target


@pytest.mark.parametrize(
    "args",
    [
        ["--scheduler", UNREACHABLE],
        ["--scheduler", "not-an-address"],
        ["--workers", "2", "--scheduler", UNREACHABLE],
        ["--workers", "0"],
    ],
)
def test_cli_dask_errors_are_one_line(config_path, tmp_path, args):
    res = CliRunner().invoke(app, ["run", str(config_path), "-o", str(tmp_path / "x.h5"), *args])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error:"), res.stderr
    assert "Traceback" not in res.output
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.filterwarnings("ignore:Port 8787 is already in use")
def test_cli_workers_same_summary_as_local(config_path, reference, tmp_path):
    out = tmp_path / "w.h5"
    res = CliRunner().invoke(
        app, ["run", str(config_path), "--workers", "2", "-o", str(out), "--set", "chunk_size=100"]
    )
    assert res.exit_code == 0, res.output
    assert "LocalCluster of 2" in res.stderr
    _assert_same(out, reference)


def test_cli_scheduler_same_summary_as_local(client, config_path, reference, tmp_path):
    out = tmp_path / "s.h5"
    address = client.scheduler.address
    res = CliRunner().invoke(
        app,
        ["run", str(config_path), "--scheduler", address, "-o", str(out), "--set", "executor=dask"],
    )
    assert res.exit_code == 0, res.output
    assert f"connected to {address}" in res.stderr
    _assert_same(out, reference)
    assert client.status == "running"  # closing the CLI's client leaves the cluster up


def test_both_executors_satisfy_the_executor_protocol():
    from antisync.execution.executors import Executor
    from antisync.execution.executors.dask import DaskExecutor
    from antisync.execution.executors.local import LocalExecutor

    assert isinstance(LocalExecutor("cpu", 1), Executor)
    for name in ("run", "describe", "close"):
        assert callable(getattr(DaskExecutor, name))
    assert issubclass(DaskExecutor, Executor)


@pytest.mark.parametrize(("edges", "stopped_at"), [('["2->1", "2->3"]', 200), ('["2->1", "3->4"]', 3200)])
def test_stopping_rule_on_the_cluster_stops_where_the_local_run_does(client, tmp_path, edges, stopped_at):
    """``stop: signs-resolved`` through the Dask executor (chunks finish out of order; each
    look waits for its prefix): the same looks and the same file as the local executor's, for
    a run that stops at its first look and one that spends its budget (3->4 stays open)."""
    from antisync.plan.config import load_config_text
    from antisync.store import records, stop_record

    text = TINY.replace("realizations: 400", "realizations: 3200").replace("betas: [0.5]", "betas: []")
    text = text.replace('["2->1", "3->4"]', edges) + "stop: {when: signs-resolved, first_look: 200}\n"
    cfg = load_config_text(text)
    local = run_config(cfg, output=tmp_path / "local.h5", executor=LocalExecutor("cpu", None))
    with DaskExecutor(client) as ex:
        remote = run_config(cfg, output=tmp_path / "dask.h5", executor=ex, chunk_realizations=50)
    assert stop_record(remote) == stop_record(local) and stop_record(local)["stopped_at"] == stopped_at
    assert records(remote) == records(local)


# ---- a quiet cluster -------------------------------------------------------------------------
NOISE = ("already in use", "still alive", "CancelledError")


@contextlib.contextmanager
def _port_taken(port: int):
    """Hold ``port`` (if it is free) as another cluster's dashboard would."""
    sock = socket.socket()
    try:
        sock.bind(("", port))
        sock.listen()
    except OSError:
        pass  # taken already: all the better
    try:
        yield
    finally:
        sock.close()


class _Records(logging.Handler):
    """What distributed logs in this process (it does not propagate to pytest's caplog)."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def _distributed_logs():
    handler = _Records()
    logger = logging.getLogger("distributed")
    logger.addHandler(handler)
    try:
        yield handler.messages
    finally:
        logger.removeHandler(handler)


def test_executor_dask_run_prints_no_cluster_noise(config_path, reference, tmp_path, capfd):
    """``executor: dask`` starts a LocalCluster: with port 8787 taken by another cluster, no
    "Port 8787 is already in use" warning (the dashboard takes a free port), and no shutdown
    warnings ("Worker process still alive ..., killing") on stderr; the numbers are the local
    executor's."""
    cfg = tmp_path / "dask.yaml"
    cfg.write_text(config_path.read_text() + "executor: dask\n")
    out = tmp_path / "q.h5"
    with _port_taken(8787), _distributed_logs() as logged, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = CliRunner().invoke(app, ["run", str(cfg), "--workers", "2", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "LocalCluster of 2" in res.stderr and "Dask dashboard: " in res.stderr
    err = capfd.readouterr().err + res.stderr + "\n".join(logged) + "\n".join(str(w.message) for w in caught)
    assert not [n for n in NOISE if n in err], err
    _assert_same(out, reference)


def test_closing_a_cluster_that_still_computes_is_quiet(config_path, capfd):
    """A chunk still running when the executor closes its LocalCluster (a stopping rule or an
    error ended the run): the worker is killed after 4 s without a warning; errors would show,
    and the log level is restored after."""
    logger = logging.getLogger("distributed")
    level = logger.level
    ex = DaskExecutor.from_options(load_config(config_path), workers=1)
    fut = ex.client.submit(time.sleep, 60, pure=False)
    deadline = time.monotonic() + 60
    while not any(ex.client.processing().values()) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)  # the task is executing on the worker
    with _distributed_logs() as logged:
        ex.close()
    del fut
    err = capfd.readouterr().err + "\n".join(logged)
    assert not [n for n in NOISE if n in err], err
    assert logger.level == level and ex.client is None


def test_a_closing_worker_drops_only_the_heartbeat_its_close_cut_short():
    """The shutdown race seen on a correct run (a heartbeat under way when the worker's own
    connection pool closed: "Failed to communicate with scheduler during heartbeat", with a
    CancelledError traceback) is dropped while the worker closes; other errors still show."""
    from types import SimpleNamespace

    from distributed.core import Status

    from antisync.execution.executors.dask import _SHUTDOWN_RACE, _quiet_close_plugin

    logger = logging.getLogger("distributed")
    handler = logging.StreamHandler()  # as distributed configures in a worker process
    logger.addHandler(handler)
    worker = SimpleNamespace(status=Status.closing)
    _quiet_close_plugin().setup(worker)
    try:
        (keep,) = handler.filters

        def record(level, msg):
            return logging.LogRecord("distributed.worker", level, __file__, 1, msg, None, None)

        assert not keep(record(logging.ERROR, _SHUTDOWN_RACE + "."))
        assert not keep(record(logging.WARNING, "Async instruction ... ended with CancelledError"))
        assert keep(record(logging.ERROR, "Compute Failed"))
        worker.status = Status.running
        assert keep(record(logging.ERROR, _SHUTDOWN_RACE + "."))
        assert keep(record(logging.WARNING, "anything"))
    finally:
        logger.removeHandler(handler)
        for other in logger.handlers:  # the plugin filters every handler it finds
            other.filters = [f for f in other.filters if f is not keep]


def test_a_law_runs_on_the_cluster_as_locally(client, tmp_path):
    """A user's law (model.law) on the cluster: each worker loads the generated kernels from the
    law cache (or compiles them once), and the file is the local run's, array for array."""
    path = tmp_path / "law.yaml"
    path.write_text(
        "graph: {kind: lollipop, nodes: 6, path: 3}\nmodel: {law: stuart-landau, params: {omega: 0.1}}\n"
        "edges: ['2->1', '4->3']\nbetas: [0.5]\nrealizations: 200\nblock_size: 50\nseed: 2\n"
        "lambda: {method: adjoint-hybrid}\ndynamics: {integrator: rk4, dt: 0.01}\n"
    )
    local = run_config(load_config(path), output=tmp_path / "local.h5", executor=LocalExecutor("cpu", None))
    out = run_config(
        load_config(path),
        output=tmp_path / "dask.h5",
        executor=DaskExecutor(client, "cpu", tasks_per_thread=1),
        chunk_realizations=50,
    )
    _assert_same(out, (_arrays(local), _summary(local)))


def test_two_maps_on_one_client_read_their_own_shared_settings(client):
    """A settings dict every call shares is sent once, under a key of its own: two maps whose
    dicts have the same keys ({"dt": ...}) each read their own values, and releasing one map's
    copy loses nothing of the other's (a dict scattered as itself was stored under "dt")."""
    import operator

    from antisync.execution.executors.dask import map_on_client

    first, second = {"dt": 0.1}, {"dt": 0.05}
    opened = map_on_client(client, operator.getitem, [(first, "dt"), (first, "dt")])
    assert next(opened)[1] == 0.1
    assert sorted(map_on_client(client, operator.getitem, [(second, "dt")] * 2)) == [(0, 0.05), (1, 0.05)]
    opened.close()
    assert sorted(map_on_client(client, operator.getitem, [(second, "dt")] * 2)) == [(0, 0.05), (1, 0.05)]
