"""CUDA backend: identical to the CPU backend under the numba CUDA simulator.

Why subprocesses: numba decides once, when it is first imported, whether ``numba.cuda`` is the
simulator (``NUMBA_ENABLE_CUDASIM=1``) or the real driver. Other tests import numba without
the variable, and pytest's import order (or ``-k``, ``-x``, xdist) decides which test imports
it first, so setting the variable from a fixture or a conftest would work or not by accident.
Each check of ``tests/cudasim_checks.py`` therefore runs in a fresh interpreter with the
variable set before anything is imported; in that process the CPU backend is ordinary numba
code, so both backends run side by side. A separate ``pytest`` invocation would also work but
would have to be remembered; this runs with the default ``pytest``.

The simulator runs every GPU thread as a Python thread, so the sizes are tiny (dt = 0.01,
t_max = 50, 12-40 realizations); the whole file takes about 80 s on two cores.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import HANG_GUARD_S

ROOT = Path(__file__).resolve().parents[1]
CHECKS = ROOT / "tests" / "cudasim_checks.py"


def _simulated(*argv: str, timeout: float = HANG_GUARD_S) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["NUMBA_ENABLE_CUDASIM"] = "1"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run(
        [sys.executable, *argv], env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )


def _check(name: str, *args: str) -> str:
    proc = _simulated(str(CHECKS), name, *args)
    assert proc.returncode == 0, f"check {name} failed:\n{proc.stdout}\n{proc.stderr[-4000:]}"
    return proc.stdout


#: The lollipop's check (12 realizations x 24 variants, 23.6 s of a fresh clone's `make test`, the
#: simulator running each GPU thread in Python) runs in `make test-slow`; `make test` checks the
#: same kernels on the house graph with raw coupling (20 x 24) and on every status.
@pytest.mark.parametrize("name", [pytest.param("lollipop", marks=pytest.mark.slow), "house_raw", "statuses"])
def test_identical_to_cpu(name):
    """Status and steps of every realization and variant equal the CPU backend's."""
    assert "identical" in _check(name)


def test_device_reductions_equal_host():
    """Block records, tail counts and 2D histograms reduced on the device equal the host's."""
    assert "reductions identical" in _check("reductions")


def test_device_counts_realizations_that_lose_or_gain_synchronization():
    """n_lost and n_gained of the finite difference, counted on the device, equal the host's."""
    assert "reductions identical" in _check("reduction_flips")


def test_run_config_cuda_matches_cpu(tmp_path):
    """``backend: cuda`` through the runner (host and device reductions) gives the cpu summary."""
    assert "identical on cpu and cuda" in _check("runner", str(tmp_path))


def test_run_config_cuda_with_a_derivative_method_matches_cpu(tmp_path):
    """Every lambda.method runs with ``backend: cuda``; the Lambda pass stays on the CPU."""
    assert "identical on cpu and cuda" in _check("runner_derivatives", str(tmp_path))


def test_float32_close():
    assert "float32" in _check("float32")


#: bench/gpu_check.py's own code path (2.7 s under the simulator): `make test-slow` and `make
#: test-cuda`, as bench/gpu_models_check.py's; the kernels it calls are checked above in `make test`
@pytest.mark.slow
def test_gpu_check_tiny_runs_under_simulator():
    proc = _simulated(str(ROOT / "bench" / "gpu_check.py"), "--tiny")
    assert proc.returncode == 0, proc.stdout + proc.stderr[-4000:]
    assert "| tau0 alone (realizations/s) |" in proc.stdout
    assert "agreement: OK" in proc.stdout


# ---- in this process: no GPU and no simulator (skipped where a GPU is present) ----


def _gpu_here() -> bool:
    from antisync.kernels.backends import cuda_usable

    return cuda_usable()[0]


def _lollipop_job(**dyn):
    from antisync.plan.config import load_config_text
    from antisync.plan.jobs import make_job

    extra = "".join(f", {k}: {v}" for k, v in dyn.items())
    return make_job(
        load_config_text(
            "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['3->4']\nbetas: [0.5]\n"
            f"dynamics: {{dt: 0.01, t_max: 1{extra}}}\nrealizations: 10\n"
        )
    )


def test_module_imports_and_refuses_without_gpu():
    if _gpu_here():
        pytest.skip("a GPU (or the simulator) is usable in this process")
    from antisync.errors import AntisyncError
    from antisync.kernels import cuda as gpu

    job = _lollipop_job()
    with pytest.raises(AntisyncError, match="CUDA backend cannot run here"):
        gpu.simulate(
            1,
            0,
            2,
            job.csr.indptr,
            job.csr.indices,
            job.csr.weights,
            job.variant_weights,
            dt=0.01,
            threshold=0.99,
            max_steps=100,
        )


def test_too_many_nodes_is_a_clear_error():
    from antisync.errors import AntisyncError
    from antisync.kernels import cuda as gpu

    n = gpu.MAX_NODES + 1
    indptr = np.arange(n + 1, dtype=np.int64)
    indices = (np.arange(n, dtype=np.int64) + 1) % n
    w = np.ones(n)
    with pytest.raises(AntisyncError, match=f"at most {gpu.MAX_NODES}"):
        gpu.simulate(1, 0, 1, indptr, indices, w, w[None], dt=0.01, threshold=0.99, max_steps=10)


FLOAT32 = (
    "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['3->4']\nbetas: [0.5]\n"
    "dynamics: {dt: 0.01, t_max: 1, precision: float32}\nrealizations: 10\nbackend: cpu\n"
)


def test_float32_runs_on_the_cpu_lanes(tmp_path):
    from antisync import store
    from antisync.execution.runner import run_config
    from antisync.plan.config import load_config_text

    out = tmp_path / "r.h5"
    run_config(load_config_text(FLOAT32), output=out, progress=False)
    attrs = store.root_attrs(out)
    assert attrs["complete"] and "precision: float32" in attrs["config_yaml"]


@pytest.mark.parametrize(
    "override, message",
    [
        ("dynamics.integrator=rk4", "precision float32 runs dynamics.integrator euler only"),
        ("lambda.method=adjoint", "precision float32 runs lambda.method finite-difference only"),
        ("dynamics.dt=0.1", r"graph lollipop_6_3 at dt 0.1 reaches 0.1: use a smaller dynamics.dt"),
    ],
)
def test_float32_on_cpu_refuses_what_its_lanes_do_not_run(tmp_path, override, message):
    from antisync.errors import ConfigError
    from antisync.execution.runner import run_config
    from antisync.plan.config import load_config_text

    out = tmp_path / "r.h5"
    with pytest.raises(ConfigError, match=message):
        run_config(load_config_text(FLOAT32, [override]), output=out, progress=False)
    assert not out.exists()


@pytest.mark.parametrize(
    "setting, key",
    [
        ("dynamics: {integrator: rk4, dt: 0.04}", "dynamics.integrator rk4"),
        ("lambda: {method: adjoint}\ndynamics: {integrator: rk4, dt: 0.04}", "dynamics.integrator rk4"),
        ("dynamics: {crossing: interpolated}", "dynamics.crossing interpolated"),
    ],
)
def test_cuda_refuses_what_only_the_cpu_implements(setting, key):
    from antisync.errors import ConfigError
    from antisync.execution.compute import check_backend
    from antisync.plan.config import load_config_text

    cfg = load_config_text(f"graph: {{kind: lollipop, nodes: 6, path: 3}}\n{setting}\n")
    check_backend(cfg, "cpu")
    with pytest.raises(ConfigError, match=f"{key} runs on the cpu backend only"):
        check_backend(cfg, "cuda")


def test_precision_key_is_validated():
    from antisync.errors import ConfigError
    from antisync.plan.config import load_config_text

    text = "graph: {kind: lollipop, nodes: 6, path: 3}\n"
    assert load_config_text(text).dynamics.precision == "float64"
    assert load_config_text(text, ["dynamics.precision=float32"]).dynamics.precision == "float32"
    with pytest.raises(ConfigError, match="dynamics.precision must be one of float64, float32"):
        load_config_text(text, ["dynamics.precision=float16"])


#: NVVM lowering every kernel (10 s of a fresh clone's `make test`): `make test-slow` (which CI runs)
#: and `make test-cuda`, the command to run after changing a CUDA kernel; `make test` checks the
#: kernels' arithmetic under the simulator
@pytest.mark.slow
def test_kernels_compile_for_a_real_gpu():
    """PTX for sm_90 through NVVM (needs a CUDA toolkit, not a GPU): the simulator cannot tell
    whether numba-cuda types and lowers the kernels for hardware; this does."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    proc = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "ptx_check.py"), "--cc", "9.0"],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    if proc.returncode == 3:
        pytest.skip(proc.stdout.strip() or "no CUDA toolkit")
    assert proc.returncode == 0, proc.stdout + proc.stderr[-4000:]


def test_a_numpy_that_numba_cuda_cannot_compile_with_is_named_in_one_line():
    """numba-cuda 0.30.4 with numpy 2.5 (no ``np.row_stack``) failed deep inside the first
    launch on a real GPU (bench/RESULTS.md); compiler_problem names both versions instead."""
    from antisync.kernels.backends import compiler_problem

    assert compiler_problem() is None  # this environment compiles
    code = (
        "import numpy; del numpy.row_stack\n"
        "from antisync.kernels.backends import compiler_problem\n"
        "print(compiler_problem())\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=HANG_GUARD_S
    )
    assert proc.returncode == 0, proc.stderr
    line = proc.stdout.strip()
    assert "cannot compile kernels with numpy" in line and "row_stack" in line, line
    assert "\n" not in line
