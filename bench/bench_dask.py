"""Dask executor against the local one: throughput, speedup, and the cost of one task.

Run on a quiet machine (it uses every core)::

    python bench/bench_dask.py                                  # configs/lollipop6.yaml, 20k
    python bench/bench_dask.py --realizations 400 --tasks 10 \
        --set "edges=['2->1']" --set "betas=[0.5]"              # a quick check that it runs

Rows, all measured in the same run on the same job and chunks:

* ``local``: :class:`LocalExecutor`, numba ``prange`` over all cores of this process;
* ``dask N``: :class:`DaskExecutor` on ``LocalCluster(n_workers=N, threads_per_worker=1)``,
  one numba thread per task; workers are warmed up (numba cache loaded) before timing.

Per-task overhead is everything a task costs outside :func:`compute_chunk`: scheduling,
pickling the chunk, sending the :class:`ChunkResult` (its histogram is ``H x bins x bins``
int64 whatever the chunk size) and handling it on the client. It is measured on the largest
cluster with ``--tasks`` one-realization chunks as ``(wall * threads - sum of in-task
seconds) / tasks``. The runner's journal write of each result (``save_chunk``, the same for
every executor) is timed separately. From these and the single-thread cost of a realization
the script prints the smallest chunk that keeps the overhead under 5%.

Results do not go into bench/RESULTS.md from here; copy the table by hand with the machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from antisync.execution.compute import compute_chunk  # noqa: E402
from antisync.execution.executors.dask import DaskExecutor  # noqa: E402
from antisync.execution.executors.local import LocalExecutor  # noqa: E402
from antisync.plan.config import load_config  # noqa: E402
from antisync.plan.jobs import Chunk, make_job  # noqa: E402


def _warm(job) -> float:
    """Load the numba cache in this process (a worker, when run through ``client.run``)."""
    start = time.perf_counter()
    compute_chunk(job, Chunk(0, 1), "cpu", 1)
    return time.perf_counter() - start


def _drain(executor, work) -> tuple[float, list]:
    start = time.perf_counter()
    results = [res for _, res in executor.run(work)]
    return time.perf_counter() - start, results


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "lollipop6.yaml"))
    ap.add_argument("--realizations", type=int, default=20_000)
    ap.add_argument(
        "--chunk-realizations",
        type=int,
        default=None,
        help="realizations per chunk (default: the runner's default for this job)",
    )
    ap.add_argument("--workers", default="1,2", help="Dask cluster sizes to time, e.g. 1,2,4")
    ap.add_argument("--tasks", type=int, default=200, help="one-realization tasks for overhead")
    ap.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        help="config override key=value, as for `antisync run --set`",
    )
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster

    cfg = load_config(args.config, [*args.overrides, f"realizations={args.realizations}"])
    job = make_job(cfg)
    n_var = len(job.variant_edge)
    chunks = job.chunks(args.chunk_realizations)
    work = [(job, c) for c in chunks]
    print(
        f"{job.name}: {cfg.realizations:,} realizations x {n_var + 1} integrations, "
        f"block {job.block_size}, {len(chunks)} chunks of <= "
        f"{chunks[0].n_blocks * job.block_size:,} realizations; {os.cpu_count()} cores"
    )

    _warm(job)
    compute_chunk(job, Chunk(0, 1), "cpu", None)  # and numba's thread pool, for `local`
    t1 = time.perf_counter()
    one = compute_chunk(job, Chunk(0, 1), "cpu", 1)
    per_real = (time.perf_counter() - t1) / one.count  # one thread, seconds per realization

    rows = []
    wall, _ = _drain(LocalExecutor("cpu", None), work)
    rows.append(("local (all cores)", wall))
    overhead = None
    sizes = [int(n) for n in args.workers.split(",") if n.strip()]
    for n in sizes:
        with (
            LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster, set_as_default=False) as client,
        ):
            client.run(_warm, job)
            with DaskExecutor(client, "cpu") as ex:
                wall, _ = _drain(ex, work)
                rows.append((f"dask {n} worker{'s' if n != 1 else ''}", wall))
                if n == max(sizes):
                    tiny_set = [*args.overrides, f"realizations={args.tasks}", "block_size=1"]
                    tiny = make_job(load_config(args.config, tiny_set))
                    client.run(_warm, tiny)
                    twall, results = _drain(ex, [(tiny, Chunk(b, 1)) for b in range(args.tasks)])
                    inside = sum(r.seconds for r in results)
                    overhead = (max(twall * n - inside, 0.0) / args.tasks, n, results[-1])

    print()
    print(f"{'executor':<20} {'wall s':>8} {'real/s':>10} {'speedup vs local':>17}")
    local = rows[0][1]
    for name, wall in rows:
        print(f"{name:<20} {wall:8.2f} {cfg.realizations / wall:10.1f} {local / wall:17.2f}")

    if overhead is None:
        return
    per_task, n, sample = overhead
    with tempfile.TemporaryDirectory() as tmp:
        from antisync.store import ResultStore

        store = ResultStore(Path(tmp) / "b.h5")
        store.start_journal({})
        t1 = time.perf_counter()
        for _ in range(5):
            store.save_chunk(job.name, sample)
        journal = (time.perf_counter() - t1) / 5
    nbytes = sum(a.nbytes for a in (sample.rec, sample.rec0, sample.tail, sample.hist))
    print()
    print(
        f"per-task overhead, dask {n} workers: {per_task * 1e3:.1f} ms "
        f"({args.tasks} one-realization tasks; result {nbytes / 1e6:.2f} MB)"
    )
    print(f"journal write per chunk (runner, any executor): {journal * 1e3:.1f} ms")
    print(f"one realization ({n_var + 1} integrations) on one thread: {per_real * 1e3:.2f} ms")
    cost = per_task + journal
    need = cost / 0.05 / per_real
    default = job.chunks()[0].n_blocks * job.block_size
    print(
        f"chunk size for < 5% overhead: >= {need:,.0f} realizations "
        f"(default chunk here: {default:,} realizations, overhead "
        f"~{100 * cost / (default * per_real):.1f}%)"
    )


if __name__ == "__main__":
    main()
