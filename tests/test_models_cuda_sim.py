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


def test_model_kernels_identical_to_cpu():
    """Euler and RK4, phase lag, inertia, drawn and fixed frequencies, all three criteria,
    starts around the locked state (model.start)."""
    assert _check("models").count("identical") == 4


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
