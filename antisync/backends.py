"""Backend choice: ``cpu``, ``cuda`` or ``auto`` (CUDA when a GPU is usable)."""

from __future__ import annotations

import os

from antisync.errors import AntisyncError
from antisync.types import Backend

__all__ = ["cuda_usable", "resolve_backend"]


def cuda_usable() -> tuple[bool, str]:
    """Whether numba-cuda can run kernels here, and a sentence saying what was looked for."""
    try:
        from numba import cuda
    except ImportError:
        return False, "numba.cuda could not be imported (install numba-cuda: pip install 'antisync[cuda]')"
    try:
        if cuda.is_available():
            simulated = os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"
            name = "the CUDA simulator" if simulated else cuda.get_current_device().name
            if isinstance(name, bytes):
                name = name.decode()
            return True, f"using {name}"
    except Exception as exc:  # the driver can fail in many ways; report, do not crash
        return False, f"numba.cuda found no usable GPU ({exc})"
    return False, "numba.cuda.is_available() is False: no NVIDIA driver or GPU was found"


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
