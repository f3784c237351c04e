"""Output safety: one writer at a time, --overwrite replaces only result files, --resume leaves a
finished file alone, failures leave nothing behind, damaged files and journal chunks are
reported or skipped, a Dask sweep through every stage. Real files, real processes, a real
LocalCluster; no mocks."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import networkx as nx
import numpy as np
import pytest
from helpers import HANG_GUARD_S, comparable
from typer.testing import CliRunner

from antisync.cli.app import app
from antisync.errors import StoreError
from antisync.execution.compute import compute_chunk
from antisync.execution.executors.local import LocalExecutor
from antisync.execution.runner import Interrupted, run_config, run_jobs
from antisync.physics import graphs
from antisync.plan.config import load_config
from antisync.plan.jobs import Chunk, make_job
from antisync.store import FORMAT_VERSION, ResultStore, chunk_tag, graph_digest, open_results, records

REPO = Path(__file__).resolve().parent.parent
ARRAYS = ("block_records", "tau0_records", "hist", "tail_counts", "blocks_done", "lambda_records")

SMALL = """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ["2->1", "2->3"]
betas: [0.5]
realizations: 600
block_size: 20
chunk_size: 20
seed: 7
dynamics: {dt: 0.002, t_max: 60}
"""


# ---- helpers -------------------------------------------------------------------------------
def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def cli(*args, timeout: float = HANG_GUARD_S) -> subprocess.CompletedProcess:
    """``python -m antisync ARGS`` in a process of its own."""
    return subprocess.run(
        [sys.executable, "-m", "antisync", *map(str, args)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def start(*args) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "antisync", *map(str, args)],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def wait_for_chunks(journal: Path, n: int, proc: subprocess.Popen, timeout: float = HANG_GUARD_S) -> None:
    # generous: a fresh process may first compile every kernel (numba cache keyed by source)
    deadline = time.monotonic() + timeout
    while len(list(journal.glob("*.npz"))) < n:
        assert proc.poll() is None, "the run ended before it saved the chunks the test needs"
        assert time.monotonic() < deadline, "no chunk saved in time"
        time.sleep(0.05)


def wait_for_holder(lock: Path, proc: subprocess.Popen, timeout: float = HANG_GUARD_S) -> None:
    """Wait until ``proc`` holds the output lock (its pid in ``<out>.lock``). Counting journal
    chunks is not enough after a kill -9: the killed writer may have left as many chunks as the
    test waits for before the next process has even started."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            if json.loads(lock.read_text()).get("pid") == proc.pid:
                return
        except (OSError, ValueError):
            pass  # not there yet, or caught between the holder's truncate and write
        assert proc.poll() is None, "the run ended before it took the lock"
        assert time.monotonic() < deadline, "the lock was not taken in time"
        time.sleep(0.05)


def kill(proc: subprocess.Popen) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()


def one_line_error(res) -> str:
    """The single ``antisync: error:`` line of a failed command (asserting there is only it)."""
    code = res.returncode if hasattr(res, "returncode") else res.exit_code
    assert code == 2, res
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("antisync: error:"), res.stderr
    assert "Traceback" not in res.stderr
    return lines[0]


def arrays(path) -> dict:
    with h5py.File(path, "r") as f:
        (g,) = f["jobs"].values()
        return {k: g[k][...] for k in ARRAYS} | {"kept": g["kept/steps"][...]}


def assert_same(a: dict, b: dict) -> None:
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def snapshot(path: Path) -> tuple:
    st = os.stat(path, follow_symlinks=False)
    return st.st_ino, st.st_mtime_ns, st.st_mode, st.st_size


@pytest.fixture
def cfg(tmp_path) -> Path:
    p = tmp_path / "small.yaml"
    p.write_text(SMALL)
    return p


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    """Clean runs of SMALL with seeds 7 and 8: {seed: arrays}."""
    d = tmp_path_factory.mktemp("ref")
    (d / "small.yaml").write_text(SMALL)
    out = {}
    for seed in (7, 8):
        path = run_config(load_config(d / "small.yaml", [f"seed={seed}"]), output=d / f"s{seed}.h5")
        out[seed] = arrays(path)
    return out


# ---- 1. one writer at a time ---------------------------------------------------------------
def test_second_writer_is_refused_before_touching_anything(tmp_path, cfg):
    """While a run writes, a second run of the same output (plain, --overwrite, --resume) exits 2
    with one line naming the holder, and nothing of the first run is deleted or modified; once
    the holder is killed (-9) the lock is free again."""
    big = tmp_path / "big.yaml"
    big.write_text(SMALL.replace("realizations: 600", "realizations: 100000"))
    out = tmp_path / "c.h5"
    journal, lock = tmp_path / "c.h5.partial", tmp_path / "c.h5.lock"
    a = start("run", big, "--out", out, "--quiet")
    try:
        wait_for_chunks(journal, 1, a)
        holder = json.loads(lock.read_text())
        assert holder["pid"] == a.pid and "run" in holder["command"] and holder["started"]
        key_before = (journal / "simulation_key.json").read_bytes()
        journal_ino = journal.stat().st_ino
        for extra in ([], ["--overwrite", "--seed", "8"], ["--resume"]):
            line = one_line_error(cli("run", big, "--out", out, "--quiet", *extra))
            assert f"pid {a.pid}" in line and "being written" in line, line
            assert "started " + holder["started"] in line and "wait" in line and "--out" in line
            assert a.poll() is None  # the first run goes on
            assert journal.stat().st_ino == journal_ino  # not deleted and made again
            assert (journal / "simulation_key.json").read_bytes() == key_before
            assert json.loads(lock.read_text())["pid"] == a.pid
    finally:
        kill(a)
    assert lock.exists()  # kill -9 leaves the file, but the kernel released the lock:
    store = ResultStore(out)
    with store.lock():
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert not lock.exists()  # a normal release removes it


def test_two_resumes_never_run_at_once(tmp_path):
    """A --resume while another --resume runs is refused (it used to crash both). Killed with
    -9, the first leaves a stale lock file, which the next writer takes over."""
    big = tmp_path / "big.yaml"
    big.write_text(SMALL.replace("realizations: 600", "realizations: 100000"))
    out = tmp_path / "r.h5"
    journal = tmp_path / "r.h5.partial"
    a = start("run", big, "--out", out, "--quiet")
    wait_for_chunks(journal, 2, a)
    kill(a)
    b = start("run", big, "--out", out, "--resume", "--quiet")
    try:
        wait_for_holder(tmp_path / "r.h5.lock", b)
        wait_for_chunks(journal, len(list(journal.glob("*.npz"))) + 1, b)
        line = one_line_error(cli("run", big, "--out", out, "--resume", "--quiet"))
        assert f"pid {b.pid}" in line and "--resume" in line
        assert b.poll() is None
    finally:
        kill(b)
    with ResultStore(out).lock():
        pass
    assert not (tmp_path / "r.h5.lock").exists()


def test_kill_during_overwrite_then_resume_gives_the_clean_numbers(tmp_path, cfg, reference):
    """The reproducer of the mixed-seed bug: seed 7 in the file, an --overwrite with seed 8
    killed -9 mid-run, and damaged chunk files beside the good ones; --resume with seed 8 gives
    exactly the clean seed-8 numbers."""
    out = tmp_path / "c.h5"
    journal = tmp_path / "c.h5.partial"
    assert invoke("run", cfg, "--out", out, "--quiet").exit_code == 0
    b = start("run", cfg, "--out", out, "--overwrite", "--seed", "8", "--quiet")
    wait_for_chunks(journal, 3, b)
    kill(b)
    chunks = sorted(journal.glob("*.npz"))
    data = chunks[-1].read_bytes()
    chunks[-1].write_bytes(data[: len(data) // 2])  # a chunk cut off mid-write
    (journal / (chunks[0].name[:-13] + "999999999.npz")).write_bytes(b"garbage")
    res = invoke("run", cfg, "--out", out, "--seed", "8", "--resume", "--quiet")
    assert res.exit_code == 0, res.output
    assert_same(reference[8], arrays(out))
    assert not journal.exists() and not (tmp_path / "c.h5.lock").exists()
    # and the finished seed-8 file refuses a --resume with the old seed
    assert "different config" in one_line_error(invoke("run", cfg, "--out", out, "--resume", "--quiet"))


def test_foreign_journal_chunks_are_never_merged(tmp_path, cfg):
    """A chunk tagged for another run (another seed, or another graph under the same config)
    and damaged chunk files are deleted on load; the job's own chunk is merged."""
    cfg7, cfg8 = load_config(cfg), load_config(cfg, ["seed=8"])
    job7, job8 = make_job(cfg7), make_job(cfg8)
    key7, key8 = cfg7.simulation_key(), cfg8.simulation_key()
    assert job7.name == job8.name and chunk_tag(job7, key7) != chunk_tag(job8, key8)
    store = ResultStore(tmp_path / "x.h5")
    store.start_journal(key8)
    own = compute_chunk(job8, Chunk(1, 1), "cpu", 1)
    store.save_chunk(job8.name, own, chunk_tag(job8, key8))
    # seed 7's chunk written into seed 8's journal, e.g. by a writer started before an overwrite
    store.save_chunk(job8.name, compute_chunk(job7, Chunk(0, 1), "cpu", 1), chunk_tag(job7, key7))
    # the same config and name, another graph: what an unseeded random generator does
    g = graphs.lollipop(6, 3)
    g.add_edge(*_non_edge(g))
    other = make_job(cfg8, graph=g, name=job8.name)
    assert graph_digest(other) != graph_digest(job8)
    store.save_chunk(job8.name, compute_chunk(other, Chunk(2, 1), "cpu", 1), chunk_tag(other, key8))
    store.save_chunk(job8.name, compute_chunk(job8, Chunk(3, 1), "cpu", 1), chunk_tag(job8, key8))
    cut = store.journal / f"{job8.name}__000000003.npz"
    cut.write_bytes(cut.read_bytes()[:100])
    # a job whose name starts with this one's: its chunk is not this job's to judge or delete
    neighbour = store.journal / f"{job8.name}__b__000000000.npz"
    shutil.copy(store.journal / f"{job8.name}__000000001.npz", neighbour)

    (st,) = store.load_states([job8], key8).values()
    assert st.done.tolist() == [False, True] + [False] * (job8.n_blocks - 2)
    assert np.array_equal(st.rec[1], own.rec[0])
    left = sorted(p.name for p in store.journal.glob("*.npz"))
    assert left == sorted([f"{job8.name}__000000001.npz", neighbour.name])


def _non_edge(g: nx.Graph) -> tuple:
    return next((u, v) for u in g for v in g if u < v and not g.has_edge(u, v))


def test_resume_refuses_a_file_made_with_another_graph(tmp_path, cfg):
    config = load_config(cfg, ["realizations=40"])
    job = make_job(config)
    out = tmp_path / "g.h5"
    run_jobs([job], config, output=out)
    with h5py.File(out, "r") as f:
        assert f[f"jobs/{job.name}"].attrs["graph_digest"] == graph_digest(job)
    g = graphs.lollipop(6, 3)
    g.add_edge(*_non_edge(g))
    before = snapshot(out)
    with pytest.raises(StoreError, match="made with a different graph"):
        run_jobs([make_job(config, graph=g, name=job.name)], config, output=out, resume=True)
    assert snapshot(out) == before
    # a file written before graph digests: the digest of the datasets it stores is compared
    with h5py.File(out, "a") as f:
        del f[f"jobs/{job.name}"].attrs["graph_digest"]
    with pytest.raises(StoreError, match="made with a different graph"):
        run_jobs([make_job(config, graph=g, name=job.name)], config, output=out, resume=True)
    run_jobs([job], config, output=out, resume=True)  # the same graph is fine


def test_lock_is_reentrant_per_thread_only(tmp_path):
    store = ResultStore(tmp_path / "t.h5")
    errors = []
    with store.lock(), store.lock():  # a sweep, then its stage's run_jobs
        t = threading.Thread(target=lambda: _try_lock(store, errors))
        t.start()
        t.join()
    assert len(errors) == 1 and f"pid {os.getpid()}" in errors[0]
    assert not store.lock_path.exists()
    # a lock file of another program is not taken over
    store.lock_path.write_text("my notes\n")
    with pytest.raises(StoreError, match="not an antisync lock file"), store.lock():
        pass
    assert store.lock_path.read_text() == "my notes\n"


def _try_lock(store, errors):
    try:
        with store.lock():
            pass
    except StoreError as exc:
        errors.append(str(exc))


# ---- 2. --overwrite replaces only result files ---------------------------------------------
def _make_target(tmp_path: Path, kind: str) -> Path:
    """An output path of ``kind``; what it points at must survive --overwrite untouched."""
    foreign = tmp_path / "notes.txt"
    foreign.write_text("precious\n")
    if kind == "text":
        return foreign
    if kind == "yaml":
        return tmp_path / "small.yaml"
    if kind == "directory":
        (tmp_path / "dir.h5").mkdir()
        (tmp_path / "dir.h5" / "keep").write_text("x")
        return tmp_path / "dir.h5"
    if kind == "symlink":
        (tmp_path / "link.h5").symlink_to(foreign)
        return tmp_path / "link.h5"
    if kind == "dangling":
        (tmp_path / "dangling.h5").symlink_to(tmp_path / "nowhere.h5")
        return tmp_path / "dangling.h5"
    if kind == "foreign-hdf5":
        with h5py.File(tmp_path / "data.h5", "w") as f:
            f["x"] = np.arange(3)
        return tmp_path / "data.h5"
    if kind == "devnull":
        return Path(os.devnull)
    if kind == "below-a-file":
        return tmp_path / "small.yaml" / "x.h5"
    if kind == "foreign-journal":
        (tmp_path / "j.h5.partial").mkdir()
        (tmp_path / "j.h5.partial" / "thesis.tex").write_text("x")
        return tmp_path / "j.h5"
    raise AssertionError(kind)


def _tree(tmp_path: Path) -> dict:
    return {
        str(p): (p.is_symlink(), p.read_bytes() if p.is_file() and not p.is_symlink() else None)
        for p in sorted(tmp_path.rglob("*"))
    }


@pytest.mark.parametrize(
    "kind",
    [
        "text",
        "yaml",
        "directory",
        "symlink",
        "dangling",
        "foreign-hdf5",
        "devnull",
        "below-a-file",
        "foreign-journal",
    ],
)
def test_overwrite_refuses_anything_but_a_result_file(tmp_path, cfg, kind):
    target = _make_target(tmp_path, kind)
    before = _tree(tmp_path)
    for extra in (["--overwrite"], ["--resume"], []):
        line = one_line_error(invoke("run", cfg, "--out", target, "--quiet", *extra))
        assert str(target) in line or str(target.parent) in line, line
        assert _tree(tmp_path) == before, extra  # nothing made, nothing deleted or modified
    assert not Path(str(target) + ".lock").exists()


def test_overwrite_refuses_a_foreign_file_for_a_sweep_too(tmp_path):
    from antisync.sweeps import load_sweep_text, run_sweep

    target = tmp_path / "notes.txt"
    target.write_text("precious\n")
    with pytest.raises(StoreError, match="replaces only antisync result files"):
        run_sweep(load_sweep_text(TINY_SWEEP), output=target, overwrite=True, progress=False)
    assert target.read_text() == "precious\n" and sorted(tmp_path.iterdir()) == [target]


def test_overwrite_replaces_a_result_file(tmp_path, cfg, reference):
    out = tmp_path / "o.h5"
    assert invoke("run", cfg, "--out", out, "--quiet").exit_code == 0
    assert invoke("run", cfg, "--out", out, "--overwrite", "--seed", "8", "--quiet").exit_code == 0
    assert_same(reference[8], arrays(out))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.h5", "small.yaml"]


# ---- 3. --resume of a finished file leaves it alone ----------------------------------------
def test_resume_of_a_complete_file_changes_nothing(tmp_path, cfg):
    out = tmp_path / "done.h5"
    config = load_config(cfg, ["realizations=40"])
    run_config(config, output=out)
    before = snapshot(out)
    said = []
    time.sleep(0.02)  # a rewrite would show in the mtime
    assert run_config(config, output=out, resume=True, log=said.append) == out
    assert snapshot(out) == before and any("already complete" in m for m in said), said
    # read-only file and folder: still no traceback, no change (as root the modes do not bite,
    # and the check is that nothing is written)
    out.chmod(0o444)
    tmp_path.chmod(0o555)
    try:
        said.clear()
        assert run_config(config, output=out, resume=True, log=said.append) == out
        res = invoke("run", cfg, "--out", out, "--resume", "--set", "realizations=40")
        assert res.exit_code == 0, res.output
        assert "already complete" in res.stderr
    finally:
        tmp_path.chmod(0o755)
    assert snapshot(out) == (before[0], before[1], (before[2] & ~0o777) | 0o444, before[3])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["done.h5", "small.yaml"]


def test_resume_of_a_complete_sweep_changes_nothing(tmp_path, sweep_reference):
    from antisync.sweeps import run_sweep

    sw, ref_path, _ = sweep_reference
    out = tmp_path / "sweep.h5"
    shutil.copy2(ref_path, out)
    before = snapshot(out)
    said = []
    time.sleep(0.02)
    run_sweep(sw, output=out, resume=True, progress=False, log=said.append)
    assert snapshot(out) == before and any("already complete" in m for m in said), said
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.h5"]


# ---- 4. failures leave nothing behind --------------------------------------------------------
class FailingExecutor:
    """A local executor whose ``after``-th chunk fails (a broken GPU, a lost cluster)."""

    def __init__(self, after: int, exc: type = RuntimeError):
        self.inner, self.after, self.exc = LocalExecutor("cpu", None), after, exc
        self.closed = False

    def run(self, work):
        for i, item in enumerate(self.inner.run(work)):
            if i == self.after:
                raise self.exc("device lost")
            yield item

    def describe(self):
        return "failing"

    def close(self):
        self.closed = True


def test_failure_before_any_chunk_leaves_nothing_behind(tmp_path, cfg):
    out = tmp_path / "new" / "deeper" / "f.h5"
    config = load_config(cfg)
    ex = FailingExecutor(0)
    with pytest.raises(RuntimeError, match="device lost"):
        run_config(config, output=out, executor=ex)
    assert not ex.closed  # a given executor is its creator's to close
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.yaml"]  # folders too
    res = invoke("run", cfg, "--out", out, "--quiet", "--set", "realizations=40")
    assert res.exit_code == 0, res.output  # the same command again, no --resume needed


def test_failure_after_chunks_keeps_them_and_no_temporary_file(tmp_path, cfg, reference):
    out = tmp_path / "f.h5"
    config = load_config(cfg)

    def broken_extra(f, states):
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        run_config(config, output=out, extra=broken_extra)
    assert not (tmp_path / "f.h5.tmp").exists() and not (tmp_path / "f.h5.lock").exists()
    assert len(list((tmp_path / "f.h5.partial").glob("*.npz"))) == 30  # finished work is kept
    run_config(config, output=out, resume=True)
    assert_same(reference[7], arrays(out))


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_cuda_node_limit_is_checked_before_any_file(tmp_path, command):
    """A graph too big for the CUDA kernels is refused before the lock, the journal (a sweep:
    the screening) or the output's folder exist; on the CUDA simulator, so that backend cuda
    resolves on any machine."""
    from antisync.kernels.cuda import MAX_NODES

    n = MAX_NODES + 1
    cfg = tmp_path / "big.yaml"
    common = "betas: [0.5]\nrealizations: 40\nblock_size: 20\n"
    if command == "run":
        cfg.write_text(f"graph: {{kind: lollipop, nodes: {n}, path: 3}}\nedges: ['2->1']\n" + common)
    else:
        cfg.write_text(
            "name: big\nsweep:\n  family: graphs\n  graphs:\n"
            f"    - {{kind: networkx, generator: path_graph, args: {{n: {n}}}}}\n" + common
        )
    env = os.environ | {"NUMBA_ENABLE_CUDASIM": "1"}
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "antisync",
            command,
            str(cfg),
            "--backend",
            "cuda",
            "--out",
            str(tmp_path / "new" / "c.h5"),
            "--quiet",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
        env=env,
    )
    line = one_line_error(res)
    assert f"{n} nodes" in line and f"at most {MAX_NODES}" in line and "--backend cpu" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.yaml"]


# ---- 5. damaged files ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def result_file(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("res")
    (d / "small.yaml").write_text(SMALL)
    return run_config(load_config(d / "small.yaml", ["realizations=40"]), output=d / "r.h5")


def _damaged(tmp_path, result_file, damage) -> Path:
    p = tmp_path / "d.h5"
    shutil.copy(result_file, p)
    with h5py.File(p, "a") as f:
        damage(f, next(iter(f["jobs"].values())))
    return p


def _set(obj, key, value):
    obj.attrs[key] = value


DAMAGES = {
    "newer format": (
        lambda f, g: _set(f, "format_version", 99),
        f"written by a newer antisync (format 99); this one reads format {FORMAT_VERSION}",
    ),
    "edges not JSON": (lambda f, g: _set(g, "edges", '["2->1", '), "damaged attribute 'edges'"),
    "edges not a list": (lambda f, g: _set(g, "edges", "{}"), "damaged attribute 'edges'"),
    "no block records": (lambda f, g: g.__delitem__("block_records"), "lacks dataset 'block_records'"),
    "realizations not a number": (
        lambda f, g: _set(g, "realizations", "many"),
        "damaged attribute 'realizations'",
    ),
    "shapes": (
        lambda f, g: (g.__delitem__("blocks_done"), g.create_dataset("blocks_done", data=[True])),
        "dataset 'block_records' has shape",
    ),
}


@pytest.mark.parametrize("what", list(DAMAGES))
def test_damaged_result_file_is_one_line(tmp_path, result_file, what):
    damage, message = DAMAGES[what]
    p = _damaged(tmp_path, result_file, damage)
    with pytest.raises(StoreError, match=message.replace("(", r"\(").replace(")", r"\)")) as exc:
        records(p)
    assert str(p) in str(exc.value) and "\n" not in str(exc.value)
    for command in ("summary", "report"):
        line = one_line_error(invoke(command, p))
        assert str(p) in line


def test_newer_format_says_upgrade(tmp_path, result_file):
    p = _damaged(tmp_path, result_file, DAMAGES["newer format"][0])
    with pytest.raises(StoreError, match="upgrade antisync"):
        open_results(p)


def test_damaged_file_is_refused_on_resume(tmp_path, result_file, cfg):
    config = load_config(cfg, ["realizations=40"])
    for damage, message in [
        (lambda f, g: _set(f, "simulation_key", "{not json"), "simulation_key cannot be read"),
        (lambda f, g: g.__delitem__("tau0_records"), "tau0_records is missing"),
    ]:
        p = _damaged(tmp_path, result_file, damage)
        with pytest.raises(StoreError, match=message):
            run_config(config, output=p, resume=True)


def test_damaged_sweep_metadata_is_one_line(tmp_path, sweep_reference):
    from antisync.sweeps import sweep_summary

    _, ref_path, _ = sweep_reference
    p = tmp_path / "s.h5"
    shutil.copy(ref_path, p)
    with h5py.File(p, "a") as f:
        del f["sweep/meta_json"]
        f["sweep"].create_dataset("meta_json", data='{"graphs": ')
    with pytest.raises(StoreError, match="meta_json is not valid JSON"):
        sweep_summary(p)
    one_line_error(invoke("summary", p))


# ---- 6. a Dask sweep through every stage -------------------------------------------------------
TINY_SWEEP = """
name: tiny
sweep:
  family: graphs
  graphs:
    - {kind: networkx, generator: path_graph, args: {n: 3}}
    - {kind: lollipop, nodes: 4, path: 1}
    - {kind: atlas, index: 18}
betas: [0.5]
measures: [km, xi2]
realizations: 60
block_size: 20
seed: 3
dynamics: {dt: 0.002, t_max: 60}
screen: {realizations: 30, t_max: 60}
top: {graphs: 2, realizations: 40}
"""


@pytest.fixture(scope="module")
def sweep_reference(tmp_path_factory):
    from antisync.sweeps import load_sweep_text, run_sweep, sweep_summary

    sw = load_sweep_text(TINY_SWEEP)
    path = tmp_path_factory.mktemp("sweep") / "tiny.h5"
    run_sweep(sw, output=path, progress=False, chunk_realizations=20)
    return sw, path, comparable(sweep_summary(path))


@pytest.mark.filterwarnings("ignore:Port 8787 is already in use")
def test_dask_sweep_with_a_top_stage(tmp_path, sweep_reference):
    """An executor that owns its LocalCluster (as `antisync sweep --workers 2` makes it) serves
    the main and the top stage: run_jobs no longer closes an executor it was handed (the top
    stage used to fail with 'NoneType' object has no attribute 'nthreads'). The numbers are the
    local executor's."""
    pytest.importorskip("distributed")
    from antisync.execution.executors.dask import DaskExecutor
    from antisync.sweeps import run_sweep, sweep_summary

    sw, _, ref = sweep_reference
    assert ref["top"] and ref["complete"]
    out = tmp_path / "dask.h5"
    # LocalCluster(n_workers=2, threads_per_worker=1, processes=True), owned by the executor
    ex = DaskExecutor.from_options(sw.base, workers=2)
    try:
        client = ex.client
        run_sweep(sw, output=out, progress=False, chunk_realizations=20, executor=ex)
        assert ex.client is client and client.status == "running"
        assert comparable(sweep_summary(out)) == ref
    finally:
        ex.close()  # its creator closes it
    assert ex.client is None and client.status == "closed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dask.h5"]


# ---- 7. an interrupted file says so ------------------------------------------------------------
def test_records_of_an_interrupted_run_say_incomplete(tmp_path, cfg):
    out = tmp_path / "i.h5"
    config = load_config(cfg, ["realizations=120"])
    with pytest.raises(Interrupted):
        run_config(config, output=out, executor=FailingExecutor(2, KeyboardInterrupt))
    recs = records(out)
    assert recs and all(r["complete"] is False for r in recs)
    assert all(r["realizations_done"] == 40 and r["realizations"] == 120 for r in recs)
    with h5py.File(out, "r") as f:
        assert not f.attrs["complete"]
    from antisync.report.tables import format_records

    assert (
        "is not complete (40 of 120 realizations done): rerun the same command with --resume"
        in format_records(recs)
    )
    run_config(config, output=out, resume=True)
    assert all(r["complete"] is True and r["realizations_done"] == 120 for r in records(out))
