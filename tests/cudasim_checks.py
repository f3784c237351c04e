"""CUDA-backend checks that must run under the numba CUDA simulator, in their own process.

numba reads ``NUMBA_ENABLE_CUDASIM`` once, when it is first imported, and the rest of the test
suite imports numba without it; so ``tests/test_cuda_sim.py`` runs each check here in a fresh
interpreter with the variable set (``python tests/cudasim_checks.py NAME [ARG]``). Every check
compares the CUDA kernels with the CPU backend run in the same process: CPU kernels are
ordinary ``njit`` code whether or not the simulator is on.

The simulator runs each GPU thread as a Python thread, so sizes are tiny: dt = 0.01,
t_max = 50 and a few realizations.
"""

from __future__ import annotations

import os
import sys

if __name__ == "__main__":
    if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1" or "numba" in sys.modules:
        sys.exit("run with NUMBA_ENABLE_CUDASIM=1 set before numba is imported")

import numpy as np

from antisync.kernels import cpu
from antisync.kernels import cuda as gpu
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job
from antisync.stats import estimators

LOLLIPOP = """
graph: {kind: lollipop, nodes: 6, path: 3}
betas: [0.5]
lambda: {dbeta: 0.01}
dynamics: {dt: 0.01, t_max: 50}
"""
# a 5-node graph (square with a roof, 6 links = 12 directed edges) with the raw coupling of Eq. 20
HOUSE_RAW = """
graph: {kind: networkx, generator: house_graph}
betas: [0.5]
lambda: {dbeta: 0.01}
dynamics: {coupling: raw, dt: 0.01, t_max: 50}
"""


def _args(job, first, count):
    dyn = job.config.dynamics
    return (
        (
            job.config.seed,
            first,
            count,
            job.csr.indptr,
            job.csr.indices,
            job.csr.weights,
            job.variant_weights,
        ),
        {"dt": dyn.dt, "threshold": dyn.threshold, "max_steps": dyn.max_steps},
    )


def _same(a, b, what):
    for f in ("status0", "steps0", "status", "steps"):
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and x.shape == y.shape, (what, f, x.dtype, y.dtype)
        if not np.array_equal(x, y):
            bad = np.argwhere(x != y)[:5].tolist()
            raise AssertionError(f"{what}: {f} differs at {bad}")


def check_equal(text: str, count: int, first: int = 0) -> None:
    """Per-realization status and steps identical to the CPU backend, all edges x 2 betas."""
    job = make_job(load_config_text(text))
    assert len(job.edges) == 12 and len(job.variant_edge) == 24, job.edge_labels
    args, kw = _args(job, first, count)
    ref = cpu.simulate(*args, **kw)
    got = gpu.simulate(*args, **kw)
    _same(ref, got, job.name)
    assert (ref.status0 == 0).all(), "the check should exercise synchronized realizations"
    print(
        f"{job.name}: {count} realizations x {len(job.variant_edge)} variants identical; "
        f"mean tau0 = {ref.steps0.mean() * job.config.dynamics.dt:.3f}"
    )


def check_lollipop() -> None:
    check_equal(LOLLIPOP, count=12, first=1000)


def check_house_raw() -> None:
    check_equal(HOUSE_RAW, count=20)


def check_statuses() -> None:
    """ALREADY_SYNCED and NOT_SYNCED come out as on the CPU (threshold and t_max at extremes)."""
    # r(0) >= 0.3 happens for some random starts on 5 nodes; t_max = 0.05 stops everyone else
    job = make_job(
        load_config_text(HOUSE_RAW, ["edges=['0->1']", "dynamics.threshold=0.3", "dynamics.t_max=0.05"])
    )
    args, kw = _args(job, 0, 40)
    ref = cpu.simulate(*args, **kw)
    got = gpu.simulate(*args, **kw)
    _same(ref, got, "statuses")
    seen = set(ref.status0.tolist()) | set(ref.status.ravel().tolist())
    assert {0, 1, 2} <= seen, seen
    print("statuses", sorted(seen), "identical")


def check_reductions(flips: bool = False) -> None:
    """simulate_reduced equals the host's reductions of the CPU outcomes, exactly.

    Block records, tail counts, 2D histograms and the finite-difference Lambda records
    (:func:`antisync.execution.compute.lambda_values` + ``lambda_block_records``). Blocks of 6 over
    23 realizations (a short last block) and device batches of 12 realizations, so block
    offsets, batching and accumulation across batches are exercised. With ``flips``, a
    damage of 0.5 and t_max = 2 make realizations lose (16) and gain (2) synchronization,
    counted as n_lost and n_gained.
    """
    from antisync.execution.compute import lambda_values
    from antisync.execution.dispatch import fd_variants, sync_flips

    extra = ["lambda.dbeta=0.5", "dynamics.t_max=2.0"] if flips else []
    job = make_job(load_config_text(HOUSE_RAW, ["histogram.bins=16", "histogram.tau_max=3.0", *extra]))
    first, count, block = 60, 23, 6
    args, kw = _args(job, first, count)
    ref = cpu.simulate(*args, **kw)
    rec, rec0, tail = estimators.block_records(ref, kw["dt"], block)
    hv = job.hist_variants
    assert hv.size == 12, hv
    hist = estimators.histogram2d(ref, hv, kw["dt"], 16, 3.0)
    values, code, flagged, _, slope, tau0 = lambda_values(job, ref, first, count, with_tau=True)
    lam_rec, lam_tail = estimators.lambda_block_records(
        values, code, flagged, block, sync_flips(job, ref), slope, tau0
    )
    if flips:
        assert lam_rec[..., 6].sum() == 16 and lam_rec[..., 7].sum() == 2, lam_rec[..., 6:].sum(axis=(0, 1))
    got = gpu.simulate_reduced(
        *args,
        **kw,
        block=block,
        hist_variants=hv,
        bins=16,
        tau_max=3.0,
        lambda_variants=fd_variants(job),
        dbeta=job.dbeta,
        batch_pairs=12 * 25,
    )
    names = ("rec", "rec0", "tail", "hist", "lam_rec", "lam_tail")
    for name, x, y in zip(names, (rec, rec0, tail, hist, lam_rec, lam_tail), got, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape, (name, x.dtype, y.dtype, x.shape, y.shape)
        # exact: the same operations, summed in the same order
        assert np.array_equal(x, y), (name, np.argwhere(x != y)[:5].tolist())
    assert hist.sum() > 0 and tail.sum() > 0 and lam_tail.sum() > 0
    assert rec0[:, 0].sum() == (16 if flips else count)  # t_max = 2 stops 7 of the 23
    print(
        f"reductions identical: rec {rec.shape}, lam_rec {lam_rec.shape}, tail {tail.sum()}, "
        f"hist {hist.sum()} pairs"
    )


def _count_device_reductions() -> list:
    """From now on, every chunk reduced on the device appends its first realization to the
    returned list (compute_chunk imports ``simulate_reduced`` from the module at call time)."""
    calls = []
    reduced = gpu.simulate_reduced

    def counted(*args, **kwargs):
        calls.append(args[1])
        return reduced(*args, **kwargs)

    gpu.simulate_reduced = counted
    return calls


def check_runner(tmp: str) -> None:
    """``backend: cuda`` through run_config stores the same summary as ``backend: cpu``."""
    from antisync import store
    from antisync.execution.runner import run_config

    text = HOUSE_RAW + "edges: ['0->1', '2->4']\nrealizations: 30\nblock_size: 10\n"
    calls = _count_device_reductions()
    out = {}
    for backend, keep in (("cpu", 0), ("cuda", 0), ("cuda", 12)):
        # keep_pairs 0: every chunk is reduced on the device; 12: the first two chunks
        # (realizations 0-19) keep pairs, so they are reduced on the host
        cfg = load_config_text(text, [f"backend={backend}", f"keep_pairs={keep}"])
        path = run_config(
            cfg, output=os.path.join(tmp, f"{backend}{keep}.h5"), progress=False, chunk_realizations=10
        )
        out[backend, keep] = store.records(path)
    assert calls == [0, 10, 20, 20], calls
    assert out["cpu", 0] == out["cuda", 0] == out["cuda", 12], out
    assert all(r["n"] > 0 for r in out["cpu", 0]), out["cpu", 0]
    print(f"run_config: {len(out['cpu', 0])} summary records identical on cpu and cuda")


def check_runner_derivatives(tmp: str) -> None:
    """A derivative method with ``backend: cuda``: the GPU integrates tau0 and the pairs, the
    Lambda pass runs on the CPU lanes (no chunk is reduced on the device), and the stored
    summary is the ``backend: cpu`` run's."""
    from antisync import store
    from antisync.execution.runner import run_config

    text = HOUSE_RAW + "edges: ['0->1', '2->4']\nrealizations: 20\nblock_size: 10\nkeep_pairs: 0\n"
    calls = _count_device_reductions()
    for method in ("adjoint-hybrid", "central-difference"):
        out = {}
        for backend in ("cpu", "cuda"):
            cfg = load_config_text(text, [f"backend={backend}", f"lambda.method={method}"])
            path = os.path.join(tmp, f"{method}-{backend}.h5")
            out[backend] = store.records(run_config(cfg, output=path, progress=False, chunk_realizations=10))
        assert out["cpu"] == out["cuda"], (method, out)
        assert all(r["lambda_n"] > 0 for r in out["cpu"] if "lambda_n" in r), out["cpu"]
    assert calls == [], calls
    print(f"derivative methods: {len(out['cpu'])} summary records identical on cpu and cuda")


def check_float32() -> None:
    """float32 runs the same kernels in single precision: close to, not equal to, float64."""
    job = make_job(load_config_text(LOLLIPOP, ["edges=['3->4']"]))
    args, kw = _args(job, 0, 6)
    ref = gpu.simulate(*args, **kw)
    got = gpu.simulate(*args, **kw, precision="float32")
    assert np.array_equal(ref.status0, got.status0) and np.array_equal(ref.status, got.status)
    diff = np.abs(np.concatenate([ref.steps0 - got.steps0, (ref.steps - got.steps).ravel()]))
    # a relative 1e-7 perturbation moves tau by far less than 1% here
    assert diff.max() <= 0.01 * ref.steps0.min(), diff
    print(f"float32: max |delta steps| = {diff.max()} of ~{int(ref.steps0.mean())}")


def check_reduction_flips() -> None:
    """check_reductions where damage moves realizations in and out of synchronization."""
    check_reductions(flips=True)


if __name__ == "__main__":
    name, *rest = sys.argv[1:]
    globals()[f"check_{name}"](*rest)
