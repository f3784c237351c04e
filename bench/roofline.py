"""Roofline of the Euler lane kernel (issue 17, item 1): work per trajectory-step, the machine's
real limits, and what the compiled inner loops do.

For each graph of ``bench_sizes.py`` (N = 6, 20, 34, 77, 118, 500) it reports, per
trajectory-step (one Euler step of one trajectory = one lane):

- flops as the fused kernel ``euler_step_vec`` does them: ``4 nnz`` (two multiply-adds per
  directed edge) + ``30 N`` (per node: angle 4, ``a^2`` 1, Taylor cos 8 and sin 9, rotation 6,
  order-parameter sums 2) + 3 (``R``), split into multiplications (``2 nnz + 17 N + 2``) and
  additions (``2 nnz + 13 N + 1``): no fused multiply-add is allowed (the lanes must round
  exactly as the one-trajectory step does), so the multiplications, which only two of the four
  FP pipes of this core execute, set the arithmetic limit;
- bytes moved between registers and L1: per edge ``c_j, s_j`` (16 B) and the lane's weight
  (8 B; broadcast once per 16 lanes when every lane has the same weights), per node ``c_i, s_i``
  read and written (32 B), indices amortized over 16 lanes; and the working set of one thread
  (32 lanes), which decides the cache level those bytes come from;
- time per trajectory-step of the fused kernel and of the previous lane kernel
  (``euler_step_lanes``: lane loops over runtime-width arrays; it now shares the fused
  kernel's division-free Taylor polynomial), both measured here, one thread,
  the kernel alone in a loop (no lane refill, compiled as the driver is: see the loops below);
  of the RK4 lane kernel ``rk4_step_vec``, in ns and in fused Euler steps; and of the fused
  kernel on float32 lanes (``precision: float32``, twice the lanes per machine vector);
- the limits: an FMA loop that reaches the core's peak (6 independent 8-wide accumulators,
  ``llvm.fma``; the assembly is checked for ``vfmadd...pd``), and the same loop with separate
  multiplications or additions (the throughput the kernel's mix can use); the kernel's bound is
  ``max(muls / mul rate, adds / add rate)``.

Then the assembly of both kernels' step loops is summarized: vector width of the arithmetic,
gathers, divisions and square roots, calls, stack traffic (spills) and the overlap checks
LLVM inserts when it cannot prove arrays disjoint.

Usage: ``python bench/roofline.py [--seconds 0.3]``. Results: bench/RESULTS.md, issue 17.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import sys
import time
from pathlib import Path

import numba
import numpy as np
from llvmlite import ir
from numba import njit, prange
from numba.core import cgutils
from numba.extending import intrinsic

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sizes import csr, graphs_to_bench  # noqa: E402

from antisync.kernels.core import VEC, f64vec, vsplat, vstore  # noqa: E402
from antisync.kernels.precision import K64 as _K  # noqa: E402
from antisync.kernels.precision import step_vec as _step_vec  # noqa: E402 (the fused step of c's precision)

LANES = 32
DT = 0.01
CHAINS = 6  # independent accumulators of the peak loops

_step_lanes = _K.euler_step_lanes
_step_rk4 = _K.rk4_step_vec


@intrinsic
def _vfma(typingctx, a, b, c):
    if not (a == f64vec and b == f64vec and c == f64vec):
        return None

    def codegen(context, builder, sig, args):
        vt = args[0].type
        fnty = ir.FunctionType(vt, [vt] * 3)
        fma = cgutils.get_or_insert_function(builder.module, fnty, f"llvm.fma.v{VEC}f64")
        return builder.call(fma, args)

    return f64vec(a, b, c), codegen


# Six independent chains of VEC doubles: enough to cover the FMA latency (4 cycles) on two
# pipes, and few enough to stay in registers where a VEC-double vector takes two of the 16 AVX2
# registers (12 chains spilled there and measured a third of the multiplier's rate).


@njit
def _fma_loop(reps, b, c):
    """6 independent chains x = x * b + c: 2 * VEC * 6 flops per iteration."""
    vb = vsplat(b)
    vc = vsplat(c)
    x0 = x1 = x2 = x3 = x4 = x5 = vsplat(0.5)
    for _ in range(reps):
        x0 = _vfma(x0, vb, vc)
        x1 = _vfma(x1, vb, vc)
        x2 = _vfma(x2, vb, vc)
        x3 = _vfma(x3, vb, vc)
        x4 = _vfma(x4, vb, vc)
        x5 = _vfma(x5, vb, vc)
    return _store_all(x0, x1, x2, x3, x4, x5)


@njit
def _mul_loop(reps, b):
    """6 independent chains x = x * b: VEC * 6 multiplications per iteration."""
    vb = vsplat(b)
    x0 = x1 = x2 = x3 = x4 = x5 = vsplat(0.5)
    for _ in range(reps):
        x0 = x0 * vb
        x1 = x1 * vb
        x2 = x2 * vb
        x3 = x3 * vb
        x4 = x4 * vb
        x5 = x5 * vb
    return _store_all(x0, x1, x2, x3, x4, x5)


@njit
def _add_loop(reps, b):
    """6 independent chains x = x + b: VEC * 6 additions per iteration."""
    vb = vsplat(b)
    x0 = x1 = x2 = x3 = x4 = x5 = vsplat(0.5)
    for _ in range(reps):
        x0 = x0 + vb
        x1 = x1 + vb
        x2 = x2 + vb
        x3 = x3 + vb
        x4 = x4 + vb
        x5 = x5 + vb
    return _store_all(x0, x1, x2, x3, x4, x5)


@njit(inline="always")
def _store_all(x0, x1, x2, x3, x4, x5):
    out = np.empty(CHAINS * VEC)
    for k, x in enumerate((x0, x1, x2, x3, x4, x5)):
        vstore(out, k * VEC, x)
    return out


# The timing loops are compiled as the lane driver is, with ``parallel=True`` (the loop in a
# ``prange`` of one task): on an AVX2 core (Zen 3) the same Euler loop compiled as a plain njit
# function ran 24.6 ns per trajectory-step against 13.9 ns in a parallel body (different code:
# 84 against 124 ``vmulpd`` in the function), and only the latter matches the driver.


@njit(parallel=True)
def _run_vec(c, s, cn, sn, lw, w, shared, indptr, indices, dt, r2, nsteps):
    for _task in prange(1):
        x, y, xn, yn = c, s, cn, sn
        for _ in range(nsteps):
            _step_vec(x, y, xn, yn, lw, w, shared, indptr, indices, dt, r2)
            x, xn = xn, x
            y, yn = yn, y


@njit(parallel=True)
def _run_rk4(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2, nsteps):
    for _task in prange(1):
        for _ in range(nsteps):
            _step_rk4(c, s, k, ya_c, ya_s, yb_c, yb_s, lw, w, shared, indptr, indices, dt, r2, dr2)


@njit(parallel=True)
def _run_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, nsteps):
    for _task in prange(1):
        for _ in range(nsteps):
            _step_lanes(c, s, acc, sum_c, sum_s, tot_c, tot_s, lw, indptr, indices, dt, r2, True)


def _rate(fn, args, per_rep: float, seconds: float) -> float:
    """Operations per second of ``fn(reps, *args)``, ``per_rep`` operations per repetition."""
    fn(10, *args)
    reps = 1000
    while True:
        t = time.perf_counter()
        fn(reps, *args)
        sec = time.perf_counter() - t
        if sec > seconds:
            return per_rep * reps / sec
        reps *= 4


def limits(seconds: float) -> dict[str, float]:
    """Per-thread peak rates (best of three): FMA flops/s, multiplications/s, additions/s."""
    out = {"fma": 0.0, "mul": 0.0, "add": 0.0}
    for _ in range(3):
        out["fma"] = max(out["fma"], _rate(_fma_loop, (0.999999, 1e-7), 2 * CHAINS * VEC, seconds))
        out["mul"] = max(out["mul"], _rate(_mul_loop, (0.9999999,), CHAINS * VEC, seconds))
        out["add"] = max(out["add"], _rate(_add_loop, (1e-9,), CHAINS * VEC, seconds))
    return out


def _asm_summary(asm: str) -> dict[str, int]:
    lines = [x.strip() for x in asm.splitlines() if x.strip() and not x.strip().startswith((".", "#"))]
    arith = [x for x in lines if re.match(r"v(add|sub|mul|div|fmadd|fmsub|fnmadd)[a-z0-9]*p?[sd]\b", x)]

    def width(reg):
        return sum(1 for x in arith if f"%{reg}" in x)

    return {
        "instructions": len(lines),
        "FP arithmetic": len(arith),
        "of which zmm (8 lanes)": width("zmm"),
        "ymm (4 lanes)": width("ymm"),
        "xmm (scalar/2)": sum(1 for x in arith if "%xmm" in x and "%ymm" not in x and "%zmm" not in x),
        "fused multiply-adds": sum(1 for x in lines if re.match(r"vf(n)?m(add|sub)", x)),
        "gathers": sum(1 for x in lines if x.startswith("vgather")),
        "divisions": sum(1 for x in lines if x.startswith("vdiv")),
        "square roots": sum(1 for x in lines if x.startswith("vsqrt")),
        "calls": sum(1 for x in lines if x.startswith("call")),
        "stack loads/stores (spills)": sum(1 for x in lines if "(%rsp)" in x),
    }


def _function(asm: str, name: str) -> str:
    """The assembly of the function whose symbol contains ``name`` (not its wrappers)."""
    blocks = re.split(r"\n(?=_Z[^\s:]*:\n)", asm)
    hits = [b for b in blocks if re.match(rf"_Z\w*{name}\w*:", b) and "cpython" not in b.split(":")[0]]
    return hits[0] if hits else asm


def _overlap_checks(llvm: str) -> int:
    return llvm.count("vector.memcheck")


def state(indptr, indices, weights, rng):
    n, nnz = indptr.size - 1, indices.size
    theta = rng.uniform(0.0, 2.0 * np.pi, (n, LANES))
    lw = np.ascontiguousarray(np.repeat(weights[:, None], LANES, axis=1))
    return n, nnz, np.cos(theta), np.sin(theta), lw


def time_kernels(indptr, indices, weights, seconds: float) -> list[float]:
    """ns per trajectory-step of the fused kernel (per-lane weights, shared weights), of the
    previous lane kernel, of the RK4 lane kernel (per-lane weights) and of the fused kernel on
    float32 lanes (per-lane weights), one thread, best of three."""
    rng = np.random.default_rng(0)
    n, nnz, c0, s0, lw = state(indptr, indices, weights, rng)
    indptr = indptr.astype(np.int64)
    indices = indices.astype(np.int64)
    r2 = np.empty(LANES)
    best = [np.inf] * 5
    k_rk4 = np.zeros((8, n, LANES))
    lw32, w32 = lw.astype(np.float32), weights.astype(np.float32)

    def run(k, nsteps):
        c, s = c0.copy(), s0.copy()
        t = time.perf_counter()
        if k < 2:
            cn, sn = np.empty_like(c), np.empty_like(s)
            _run_vec(c, s, cn, sn, lw, weights, k == 1, indptr, indices, DT, r2, nsteps)
        elif k == 4:
            c, s = c.astype(np.float32), s.astype(np.float32)
            cn, sn, r32 = np.empty_like(c), np.empty_like(s), np.empty(LANES, np.float32)
            _run_vec(c, s, cn, sn, lw32, w32, False, indptr, indices, np.float32(DT), r32, nsteps)
        elif k == 2:
            e = np.empty_like(c)
            _run_lanes(c, s, e, e.copy(), e.copy(), r2.copy(), r2.copy(), lw, indptr, indices, DT, r2, nsteps)
        else:
            e = np.empty_like(c)
            y = (e, e.copy(), e.copy(), e.copy())
            _run_rk4(c, s, k_rk4, *y, lw, weights, False, indptr, indices, DT, r2, r2.copy(), nsteps)
        return time.perf_counter() - t

    for k in range(5):
        run(k, 2)
    nsteps = max(10, int(2e6 / (nnz + 3 * n)))
    for _ in range(3):
        for k in range(5):
            sec = run(k, nsteps)
            while sec < seconds / 3:
                nsteps *= 2
                sec = run(k, nsteps)
            best[k] = min(best[k], sec / nsteps / LANES * 1e9)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=0.3, help="minimum time per measurement")
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    numba.set_num_threads(1)
    print(
        f"# roofline: Euler lane kernel, {LANES} lanes, dt {DT}, one thread; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__}"
    )
    lim = limits(args.seconds)
    fma_asm = _function(_fma_loop.inspect_asm(_fma_loop.signatures[0]), "_fma_loop")
    fmas = sorted({m.group(0) for m in re.finditer(r"vfmadd\w+\s+%[xyz]mm", fma_asm)})
    print(
        f"# peak (FMA loop, {', '.join(fmas) or 'NO vfmadd FOUND'}): {lim['fma'] / 1e9:.1f} GFLOP/s "
        "per thread; "
        f"separate multiplications {lim['mul'] / 1e9:.1f} G/s, additions {lim['add'] / 1e9:.1f} G/s\n"
    )
    print(
        "| graph | N | nnz | flops (mul + add) | B from L1 (per-lane w / shared w) | working set, 32 lanes | "
        "bound ns | fused ns (shared w) | fraction of bound | fused GFLOP/s (of FMA peak) | previous ns | "
        "speed-up | RK4 ns (Euler steps) | float32 lanes ns (x float64) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, g in graphs_to_bench(args.seed):
        indptr, indices, weights = csr(g)
        n, nnz = indptr.size - 1, indices.size
        muls = 2 * nnz + 17 * n + 2
        adds = 2 * nnz + 13 * n + 1
        flops = muls + adds
        idx = (8 * nnz + 16 * n) / 16
        b_lane = 24 * nnz + 32 * n + idx
        b_shared = 16 * nnz + 32 * n + idx + 8 * nnz / 16
        ws = (4 * n * LANES + nnz * LANES) * 8 + 8 * (nnz + n)
        bound = max(muls / lim["mul"], adds / lim["add"]) * 1e9
        t_vec, t_shared, t_old, t_rk4, t_32 = time_kernels(indptr, indices, weights, args.seconds)
        gf = flops / t_vec
        print(
            f"| {label} | {n} | {nnz} | {flops} ({muls} + {adds}) | {b_lane:.0f} / {b_shared:.0f} | "
            f"{ws / 1024:.0f} KiB | {bound:.2f} | {t_vec:.2f} ({t_shared:.2f}) | {bound / t_vec:.0%} | "
            f"{gf:.1f} ({gf / (lim['fma'] / 1e9):.0%}) | {t_old:.2f} | {t_old / t_vec:.2f}x | "
            f"{t_rk4:.1f} ({t_rk4 / t_vec:.1f}) | {t_32:.2f} ({t_vec / t_32:.2f}x) |",
            flush=True,
        )

    print("\n## assembly of the step loops (the parallel body around the step, lollipop N = 6 types)\n")
    rows = {}
    kernels = (  # _run_vec was compiled for float64 lanes first, then for float32
        ("fused euler_step_vec", _run_vec, 0),
        ("the same, float32 lanes", _run_vec, 1),
        ("previous euler_step_lanes", _run_lanes, 0),
    )
    for name, fn, version in kernels:
        sig = fn.signatures[version]
        asm = _function(fn.inspect_asm(sig), "numba_parfor_gufunc")  # the loop's body
        rows[name] = _asm_summary(asm)
        rows[name]["overlap checks (vector.memcheck)"] = _overlap_checks(fn.inspect_llvm(sig))
    names = list(rows)
    print("| | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    for key in rows[names[0]]:
        print(f"| {key} | " + " | ".join(str(rows[k][key]) for k in names) + " |")


if __name__ == "__main__":
    main()
