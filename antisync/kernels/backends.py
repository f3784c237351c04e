"""Backend choice: ``cpu``, ``cuda`` or ``auto`` (CUDA when a GPU is usable)."""

from __future__ import annotations

import os

from antisync.errors import AntisyncError
from antisync.types import Backend

__all__ = ["compiler_problem", "cuda_usable", "resolve_backend"]


def cuda_usable() -> tuple[bool, str]:
    """Whether numba-cuda can run kernels here, and a sentence saying what was looked for."""
    try:
        from numba import cuda
    except ImportError:
        return False, "numba.cuda could not be imported (install numba-cuda: pip install 'antisync[cuda]')"
    try:
        if cuda.is_available():
            simulated = os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"
            problem = None if simulated else compiler_problem()
            if problem is not None:
                return False, problem
            name = "the CUDA simulator" if simulated else cuda.get_current_device().name
            if isinstance(name, bytes):
                name = name.decode()
            return True, f"using {name}"
    except Exception as exc:  # the driver can fail in many ways; report, do not crash
        return False, f"numba.cuda found no usable GPU ({exc})"
    return False, "numba.cuda.is_available() is False: no NVIDIA driver or GPU was found"


def compiler_problem() -> str | None:
    """Why numba-cuda cannot compile kernels with the installed numpy, or None.

    numba-cuda loads its typing and lowering registries at the first kernel compilation, so a
    numpy it does not support fails there, deep inside the first launch (numba-cuda 0.30.4
    with numpy 2.5, which removed ``np.row_stack``: bench/RESULTS.md). Importing the registry
    here (under a second, no GPU needed) turns that into one sentence naming both versions.
    """
    try:
        import numba.cuda.cudaimpl  # noqa: F401
    except Exception as exc:  # whatever the registry trips on, report it
        import numpy

        return (
            f"numba-cuda {_version('numba-cuda')} cannot compile kernels with numpy {numpy.__version__} "
            f"({type(exc).__name__}: {exc}); install a numpy that it supports (for numba-cuda 0.30: "
            "pip install 'numpy<2.5') or a newer numba-cuda"
        )
    return None


def _version(dist: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return "?"


def resolve_backend(backend: Backend) -> tuple[str, str]:
    """Turn ``auto`` into a concrete backend; ``cuda`` without a GPU is an :class:`AntisyncError`.

    Returns ``(backend, note)`` where ``note`` says what was chosen and why.
    """
    if backend == "cpu":
        return "cpu", "backend cpu"
    ok, why = cuda_usable()
    if backend == "cuda":
        if not ok:
            raise AntisyncError(f"backend cuda is not usable: {why}; use --backend cpu or auto")
        return "cuda", f"backend cuda ({why})"
    return ("cuda", f"backend auto chose cuda ({why})") if ok else ("cpu", f"backend auto chose cpu: {why}")
