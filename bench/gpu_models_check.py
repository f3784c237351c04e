"""Check the generalized models' CUDA twin (kernels/cuda.py, simulate_model) against the CPU model driver
on a real GPU, and time both.

Usage::

    python bench/gpu_models_check.py            # on a machine with an NVIDIA GPU
    NUMBA_ENABLE_CUDASIM=1 python bench/gpu_models_check.py --tiny   # code path only

Cases (``--realizations`` each, default 2000; ``--tiny``: 2 realizations, the first lollipop
model and both grids over a short ``t_max``):

- the three lollipop models of tests/cudasim_model_checks.py, imported from there (Euler with
  phase lag and drawn frequencies; RK4 with inertia and the relative criterion; Euler with
  inertia and the frequency criterion), edges 2->1 and 3->4 at beta 0.5;
- ``configs/ieee14_grid.yaml`` (swing equation, RK4 dt 0.02, frequency criterion): all 40
  directed lines at dbeta (the finite difference's variants);
- ``configs/ieee39_grid.yaml`` (per-node inertia, 29 first-order load buses, RK4 dt 0.0025):
  its first four lines in both directions at dbeta.

Agreement: the GPU contracts ``a*b + c`` into fused multiply-adds and its ``cos``/``sin`` are not
always correctly rounded, so a trajectory may cross the criterion one step apart, and one that
passes near a saddle may move further (docs/cuda.md). Reported: statuses that differ, steps that
differ, the largest change, and the largest change of the crossing fraction where the steps are
equal. Fails (exit 1) if more than 0.5% of trajectories change status or more than 1% change
step, since rounding cannot do that.

Throughput: trajectories per second on the GPU and on every CPU core of the machine (the model
driver, ``threads`` = all cores), the same realizations, timed after a one-realization warm-up
that compiles both. Prints a Markdown table. Exit 2 without a GPU.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

IEEE39_LINES = "['1->2', '2->1', '1->39', '39->1', '2->3', '3->2', '2->25', '25->2']"


def _cases(tiny: bool):
    from cudasim_model_checks import BASE, MODELS  # the simulator tests' three models

    from antisync.plan.config import load_config, load_config_text

    for name, text in MODELS.items():
        yield f"lollipop {name}", load_config_text(BASE + text)
        if tiny:  # the simulator runs each GPU thread as a Python thread: one model is enough
            break
    yield (
        "IEEE 14 swing, rk4 dt 0.02, 40 lines",
        load_config(
            ROOT / "configs" / "ieee14_grid.yaml",
            ["lambda.method=finite-difference"] + (["dynamics.t_max=1"] if tiny else []),
        ),
    )
    yield (
        "IEEE 39 per-node inertia, rk4 dt 0.0025, 8 lines",
        load_config(
            ROOT / "configs" / "ieee39_grid.yaml",
            ["lambda.method=finite-difference", f"edges={IEEE39_LINES}"]
            + (["dynamics.t_max=0.1"] if tiny else []),
        ),
    )


def _compare(cpu, gpu) -> tuple[int, int, int, float, int]:
    st = np.concatenate([(cpu.status0 != gpu.status0)[:, None], cpu.status != gpu.status], axis=1)
    d = np.concatenate([(gpu.steps0 - cpu.steps0)[:, None], gpu.steps - cpu.steps], axis=1)
    f = np.concatenate([(gpu.frac0 - cpu.frac0)[:, None], gpu.frac - cpu.frac], axis=1)
    same = (d == 0) & ~st
    dfrac = float(np.abs(f[same]).max()) if same.any() else 0.0
    return int(st.sum()), int((d != 0).sum()), int(np.abs(d).max()), dfrac, int(d.size)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tiny", action="store_true", help="tiny sizes (simulator smoke test)")
    p.add_argument("--realizations", type=int, default=2000)
    p.add_argument("--first", type=int, default=10**6, help="first realization (not the tests')")
    args = p.parse_args(argv)

    from antisync.kernels.backends import cuda_usable

    ok, why = cuda_usable()
    if not ok:
        print(f"gpu_models_check: no GPU to check: {why}", file=sys.stderr)
        return 2
    sim = os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"
    if sim and not args.tiny:
        print("gpu_models_check: under the simulator pass --tiny", file=sys.stderr)
        return 2

    from antisync.execution.compute import simulate_job
    from antisync.plan.jobs import make_job

    m = 2 if args.tiny else args.realizations
    threads = os.cpu_count() or 1
    rows, good = [], True
    for name, config in _cases(args.tiny):
        job = make_job(config)
        simulate_job(job, 0, 1, "cpu", threads=threads)  # compile both
        simulate_job(job, 0, 1, "cuda")
        t = time.perf_counter()
        cpu = simulate_job(job, args.first, m, "cpu", threads=threads)
        cpu_s = time.perf_counter() - t
        t = time.perf_counter()
        gpu = simulate_job(job, args.first, m, "cuda")
        gpu_s = time.perf_counter() - t
        n_st, n_steps, worst, dfrac, total = _compare(cpu, gpu)
        synced = float((cpu.status0 == 0).mean())
        if n_st > 0.005 * total or n_steps > 0.01 * total:
            good = False
        rows.append(
            (
                name,
                f"{m} x {total // m}",
                f"{synced:.3f}",
                f"{n_st}",
                f"{n_steps} (max {worst})",
                f"{dfrac:.1e}",
                f"{total / cpu_s:,.0f}",
                f"{total / gpu_s:,.0f}",
                f"{cpu_s / gpu_s:.1f}x",
            )
        )
    from numba import cuda

    dev = "numba CUDA simulator" if sim else cuda.get_current_device().name
    dev = dev.decode() if isinstance(dev, bytes) else str(dev)
    print(f"## antisync model kernels on the GPU: {dev}; CPU: {threads} cores\n")
    print(
        "| case | realizations x trajectories | tau0 synced | statuses differ | steps differ "
        "| max d frac (same step) | CPU traj/s | GPU traj/s | GPU/CPU |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print("\nagreement:", "OK" if good else "FAILED (more differences than rounding explains)")
    return 0 if good else 1


if __name__ == "__main__":
    sys.exit(main())
