"""Model-kernel checks under the numba CUDA simulator, each in its own process (see
tests/test_cuda_sim.py for why): ``python tests/cudasim_model_checks.py NAME [ARG]`` with
``NUMBA_ENABLE_CUDASIM=1``. The CUDA twin (kernels/cuda.py, simulate_model) must give the CPU driver's
statuses, steps and crossing fractions exactly. Sizes are tiny: the simulator runs each GPU
thread as a Python thread.
"""

from __future__ import annotations

import os
import sys

if __name__ == "__main__":
    if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1" or "numba" in sys.modules:
        sys.exit("run with NUMBA_ENABLE_CUDASIM=1 set before numba is imported")

import numpy as np

from antisync.execution.compute import simulate_job
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job

BASE = """
graph: {kind: lollipop, nodes: 6, path: 3}
edges: ['2->1', '3->4']
betas: [0.5]
"""
MODELS = {
    "euler-lag-normal": "model: {frequencies: {distribution: normal, sd: 0.1}, phase_lag: 0.3}\n"
    "dynamics: {dt: 0.02, t_max: 30, threshold: 0.9}\n",
    "rk4-inertia-relative": "model: {frequencies: [0.1, -0.1, 0.05, 0, 0, -0.05], inertia: 0.5}\n"
    "sync: {criterion: relative, fraction: 0.97}\ndynamics: {integrator: rk4, dt: 0.05, t_max: 30}\n",
    # dt 0.04: the simulator's time goes by steps (at dt 0.02 this case alone took 10.6 s of 19)
    "euler-inertia-frequency": "model: {frequencies: {distribution: uniform, width: 0.1}, inertia: 1.0}\n"
    "sync: {criterion: frequency, tolerance: 0.01}\n"
    "dynamics: {dt: 0.04, t_max: 30, crossing: interpolated}\n",
    "rk4-inertia-start": "model: {frequencies: [0.1, -0.1, 0.05, 0, 0, -0.05], inertia: 1.0, "
    "start: {around: locked, width: 1.5}}\nsync: {criterion: frequency, tolerance: 0.01}\n"
    "dynamics: {integrator: rk4, dt: 0.05, t_max: 30}\n",
}


def models(*names: str) -> None:
    """The cases ``names`` of :data:`MODELS` (default: every one)."""
    for name in names or MODELS:
        text = MODELS[name]
        job = make_job(load_config_text(BASE + text))
        cpu = simulate_job(job, 0, 10, "cpu")
        gpu = simulate_job(job, 0, 10, "cuda")
        for field in ("status0", "steps0", "status", "steps", "frac0", "frac"):
            a, b = getattr(cpu, field), getattr(gpu, field)
            assert np.array_equal(a, b), (name, field, a, b)
        assert (cpu.status0 == 0).sum() >= 5, (name, cpu.status0)
        print(name, "identical", int((cpu.status0 == 0).sum()), "synced")


def runner(folder: str) -> None:
    """``backend: cuda`` through run_config (host reductions) gives the cpu summary."""
    import antisync

    cfg = {
        "graph": {"kind": "lollipop", "nodes": 6, "path": 3},
        "edges": ["2->1"],
        "betas": [0.5],
        "realizations": 12,
        "keep_pairs": 4,
        "block_size": 4,
        "model": {"frequencies": {"distribution": "normal", "sd": 0.05}, "inertia": 0.3},
        "sync": {"criterion": "frequency", "tolerance": 0.01},
        "dynamics": {"dt": 0.02, "t_max": 30},
    }
    a = antisync.run({**cfg, "backend": "cpu"}, output=f"{folder}/cpu.h5").records
    b = antisync.run({**cfg, "backend": "cuda"}, output=f"{folder}/cuda.h5").records
    for ra, rb in zip(a, b, strict=True):
        for key in ("F_mean", "lambda_km", "tau0_mean", "n", "n_not_synced"):
            assert ra[key] == rb[key], (key, ra[key], rb[key])
    print("runner identical on cpu and cuda")


if __name__ == "__main__":
    {"models": models, "runner": runner}[sys.argv[1]](*sys.argv[2:])
