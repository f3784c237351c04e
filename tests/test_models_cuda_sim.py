"""The model kernels' CUDA twin equals the CPU driver under the numba CUDA simulator.

Each check runs ``tests/cudasim_model_checks.py`` in a fresh interpreter with
``NUMBA_ENABLE_CUDASIM=1`` (tests/test_cuda_sim.py explains why).
"""

from __future__ import annotations

import pytest
from test_cuda_sim import ROOT, _simulated

CHECKS = ROOT / "tests" / "cudasim_model_checks.py"


def _check(name: str, *args: str) -> str:
    proc = _simulated(str(CHECKS), name, *args)
    assert proc.returncode == 0, f"check {name} failed:\n{proc.stdout}\n{proc.stderr[-4000:]}"
    return proc.stdout


#: the Euler case with inertia and the frequency criterion (5.5 s of the simulator's 14.3 s) runs in
#: test-slow: in `make test` the runner's check below integrates the same features (Euler, inertia,
#: drawn frequencies, the frequency criterion) through run_config, and rk4-inertia-start checks the
#: frequency criterion on RK4
SLOW_MODELS = ("euler-inertia-frequency",)


def test_model_kernels_identical_to_cpu():
    """Euler and RK4, phase lag, inertia, drawn and fixed frequencies, all three criteria,
    starts around the locked state (model.start)."""
    from cudasim_model_checks import MODELS

    names = [name for name in MODELS if name not in SLOW_MODELS]
    assert _check("models", *names).count("identical") == len(names) == 3


@pytest.mark.slow
def test_slow_model_kernels_identical_to_cpu():
    assert _check("models", *SLOW_MODELS).count("identical") == len(SLOW_MODELS)


def test_model_run_on_cuda_matches_cpu(tmp_path):
    assert "identical on cpu and cuda" in _check("runner", str(tmp_path))


#: bench/gpu_models_check.py's own code path (9-10 s under the simulator): `make test-slow`, which
#: CI runs; the model kernels it calls are checked above in `make test`
@pytest.mark.slow
def test_gpu_models_check_tiny_runs_under_simulator():
    """The script run on a GPU machine (bench/gpu_models_check.py) still runs: its code path."""
    proc = _simulated(str(ROOT / "bench" / "gpu_models_check.py"), "--tiny")
    assert proc.returncode == 0, proc.stdout + proc.stderr[-4000:]
    assert "agreement: OK" in proc.stdout and proc.stdout.count("| 2 x ") == 3
