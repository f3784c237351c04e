"""Compile every CUDA kernel of antisync to PTX for a real GPU target, without a GPU.

Usage::

    python bench/ptx_check.py [--cc 9.0] [--show]

The simulator runs kernels as Python, so it cannot tell whether numba-cuda types and lowers
them for the hardware. This script does, with NVVM from a CUDA toolkit (libnvvm and
libdevice; no driver, no GPU), and checks two properties the backend relies on:

- the float32 Euler step does its arithmetic in single precision (no promotion to double);
- the block- and Lambda-record reductions contain no fused multiply-add, so their sums round
  exactly as the CPU's :func:`antisync.stats.estimators.block_records` and
  ``lambda_block_records`` (the GPU integrator itself *is* contracted; docs/cuda.md says what
  that means).

When the toolkit has no NVRTC library (numba-cuda asks it only which architectures exist and
where libdevice is), the script answers those two questions itself by patching numba-cuda
internals: a development aid, never used by antisync itself.

Exit codes: 0 compiled and checked, 1 a property failed, 3 no usable CUDA toolkit here.
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import sys
from collections import Counter


def _offline_toolkit(cc: tuple[int, int]) -> str:
    """Make numba-cuda compile without a driver; return a note on what was patched."""
    from numba.cuda import dispatcher

    class _Device:  # device functions ask the current device for its compute capability
        compute_capability = cc

    dispatcher.get_current_device = lambda: _Device()
    try:
        from numba.cuda.cudadrv import nvrtc

        nvrtc.get_supported_ccs()
        return "NVRTC found"
    except Exception:
        pass
    from numba.cuda.cudadrv import libs, nvrtc, nvvm

    roots = [os.environ.get("CUDA_HOME", ""), os.environ.get("CUDA_PATH", "")]
    roots += sorted(glob.glob("/usr/local/cuda*"), reverse=True)
    found = [p for r in roots if r for p in glob.glob(f"{r}/nvvm/libdevice/libdevice*.bc")]
    if not found:
        raise FileNotFoundError("no libdevice*.bc under CUDA_HOME or /usr/local/cuda*")
    libdevice = found[0]
    ccs = [(5, 0), (6, 0), (7, 0), (7, 5), (8, 0), (8, 6), (8, 9), (9, 0), (10, 0), (12, 0)]
    nvrtc.get_supported_ccs = lambda: ccs
    libs.get_libdevice = lambda: libdevice
    nvvm.get_libdevice = lambda: libdevice
    return f"no NVRTC: patched the architecture list and libdevice ({libdevice})"


def _ops(ptx: str) -> Counter:
    return Counter(re.findall(r"^\s*(?:@%p\d+\s+)?([a-z]+(?:\.[a-z0-9]+)*)", ptx, re.M))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cc", default="9.0", help="compute capability, e.g. 8.0 or 9.0")
    p.add_argument("--show", action="store_true", help="print floating-point op counts")
    args = p.parse_args(argv)
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
        print("ptx_check: unset NUMBA_ENABLE_CUDASIM (the simulator compiles nothing)")
        return 3
    cc = tuple(int(x) for x in args.cc.split("."))
    try:
        import numpy as np
        from numba import cuda
        from numba import types as t

        note = _offline_toolkit(cc)
        cuda.compile_ptx(lambda x: None, (t.float64[::1],), cc=cc)
    except Exception as exc:  # no toolkit, no libnvvm, or an incompatible numba-cuda
        print(f"ptx_check: cannot compile for CUDA here: {type(exc).__name__}: {exc}")
        return 3

    from antisync.kernels import cuda as kc
    from antisync.kernels.core import make_kernels

    i64, u64, i8, f64 = t.int64, t.uint64, t.int8, t.float64
    failed = []
    print(f"ptx_check: compute capability {args.cc}; {note}")
    for prec, ft, nt in (("float64", np.float64, t.float64), ("float32", np.float32, t.float32)):
        tau0, variant = kc._kernels(prec)
        sigs = {
            "tau0": (tau0, (u64, i64, i64, i64[::1], i64[::1], nt[::1], nt, nt, i64, i8[::1], i64[::1])),
            "variants": (
                variant,
                (
                    u64,
                    i64,
                    i64,
                    i64[::1],
                    i64[::1],
                    nt[:, ::1],
                    t.boolean[::1],
                    nt,
                    nt,
                    i64,
                    i8[::1],
                    i64[::1],
                    i8[:, ::1],
                    i64[:, ::1],
                ),
            ),
        }
        for name, (k, sig) in sigs.items():
            ops = _ops(cuda.compile_ptx(k.py_func, sig, cc=cc)[0])
            print(
                f"  {prec} {name}: ok ({sum(ops.values())} instructions, "
                f"{ops['fma.rn.f64'] + ops['fma.rn.f32']} fma)"
            )
        step = make_kernels(cuda.jit(device=True), ft).euler_step
        ops = _ops(
            cuda.compile_ptx(
                step.py_func, (nt[::1],) * 3 + (i64[::1],) * 2 + (nt[::1], nt), device=True, cc=cc
            )[0]
        )
        fp = {k: v for k, v in ops.items() if re.search(r"\.f(32|64)$", k)}
        if args.show:
            print(f"  {prec} euler_step floating-point ops: {dict(sorted(fp.items()))}")
        if prec == "float32":
            # libdevice's cosf keeps a double Payne-Hanek reduction for huge arguments: allow
            # that handful, flag any real promotion of the step (which would be dozens)
            n64 = sum(v for k, v in fp.items() if k.endswith(".f64"))
            if n64 > 8:
                failed.append(f"float32 euler_step has {n64} double-precision ops")
    block_kernel, lambda_kernel, hist_kernel = kc._reducers()
    sig = (
        i8[::1],
        i64[::1],
        i8[:, ::1],
        i64[:, ::1],
        f64,
        i64,
        f64[::1],
        f64[:, :, ::1],
        f64[:, ::1],
        i64[:, ::1],
    )
    ops = _ops(cuda.compile_ptx(block_kernel.py_func, sig, cc=cc)[0])
    print(f"  block records: ok ({ops['fma.rn.f64']} fma, {ops['mul.rn.f64']} mul.rn)")
    if ops["fma.rn.f64"]:
        failed.append("the block-record reduction contains fused multiply-adds")
    sig = (
        i8[::1],
        i64[::1],
        i8[:, ::1],
        i64[:, ::1],
        i64[::1],
        f64,
        f64,
        i64,
        f64[::1],
        f64[:, :, ::1],
        i64[:, ::1],
    )
    ops = _ops(cuda.compile_ptx(lambda_kernel.py_func, sig, cc=cc)[0])
    print(f"  Lambda records: ok ({ops['fma.rn.f64']} fma, {ops['mul.rn.f64']} mul.rn)")
    if ops["fma.rn.f64"]:
        failed.append("the Lambda-record reduction contains fused multiply-adds")
    sig = (i8[::1], i64[::1], i8[:, ::1], i64[:, ::1], i64[::1], f64, i64[:, :, ::1])
    ops = _ops(cuda.compile_ptx(hist_kernel.py_func, sig, cc=cc)[0])
    print(f"  histogram: ok ({sum(v for k, v in ops.items() if k.startswith('atom'))} atomics)")
    # the generalized models' kernel: its groups of arrays travel as tuples
    graph = t.Tuple((i64[::1], i64[::1], f64[::1], f64[:, ::1], t.boolean[::1]))
    model = t.Tuple((f64[:, ::1], f64[:, ::1], f64, f64, f64[::1], f64[::1], i64, f64[::1]))
    out = t.Tuple((i8[::1], i64[::1], f64[::1], i8[:, ::1], i64[:, ::1], f64[:, ::1]))
    sig = (u64, u64[::1], graph, model, f64, t.boolean, i64, out)
    ops = _ops(cuda.compile_ptx(kc._model_kernel().py_func, sig, cc=cc)[0])
    print(f"  model kernel: ok ({sum(ops.values())} instructions)")
    for f in failed:
        print("FAILED:", f)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
