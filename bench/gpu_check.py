"""Check the CUDA backend against the CPU backend on a real GPU, and time it.

Usage::

    python bench/gpu_check.py            # on a machine with an NVIDIA GPU (paper settings)
    NUMBA_ENABLE_CUDASIM=1 python bench/gpu_check.py --tiny   # code path only, no timings worth reading

Everything runs on the paper's lollipop graph (N = 6, L = 3; all 12 directed edges), Euler
with dt = 0.001, r = 0.99, t_max = 200 (``--tiny``: dt = 0.05, t_max = 50, one realization).

1. Agreement: ``--check`` realizations (default 2000) x (tau0 + 12 edges x {0.5, dbeta})
   on the GPU and on the CPU. In float64 statuses must be identical and steps identical except
   rare one-step flips (FMA contraction, CUDA cos/sin; see docs/cuda.md); float32 is reported
   against the CPU's float64.
2. Throughput, float64 and float32: realizations/s for tau0 alone, and for all-edge Lambda^KM
   (tau0 + 12 finite-difference variants at dbeta = 0.01, reduced on the device as a run does).
3. The per-realization sd of (F_dbeta - 1)/dbeta on each edge (measured in the Lambda run) and
   the projected GPU time until every edge's Lambda^KM has standard error 1e-4.
4. A (tau0, tau(0.5)) 2D histogram of 1e7 pairs on one edge, extrapolated to 1e9 pairs.

Prints a Markdown table. Exit codes: 0 all good, 1 disagreement with the CPU, 2 no GPU.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def _fail_no_gpu(tiny: bool) -> None:
    from antisync.kernels.backends import cuda_usable

    ok, why = cuda_usable()
    if not ok:
        print(f"gpu_check: no GPU to check: {why}", file=sys.stderr)
        sys.exit(2)
    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" and not tiny:
        print(
            "gpu_check: NUMBA_ENABLE_CUDASIM=1 is set: the simulator gives no meaningful "
            "timings; pass --tiny to exercise the code path only",
            file=sys.stderr,
        )
        sys.exit(2)


def _device_name() -> str:
    from numba import cuda

    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
        return "numba CUDA simulator (timings meaningless)"
    dev = cuda.get_current_device()
    name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
    return f"{name} (compute capability {dev.compute_capability[0]}.{dev.compute_capability[1]})"


def _job(edges, betas, dt, t_max):
    from antisync.plan.config import load_config_text
    from antisync.plan.jobs import make_job

    text = (
        "graph: {kind: lollipop, nodes: 6, path: 3}\n"
        f"edges: {edges}\nbetas: {list(betas)}\nlambda: {{dbeta: 0.01}}\n"
        f"dynamics: {{dt: {dt}, t_max: {t_max}}}\n"
    )
    return make_job(load_config_text(text))


def _common(job, variant_weights=None):
    dyn = job.config.dynamics
    vw = job.variant_weights if variant_weights is None else variant_weights
    return (job.csr.indptr, job.csr.indices, job.csr.weights, vw), {
        "dt": dyn.dt,
        "threshold": dyn.threshold,
        "max_steps": dyn.max_steps,
    }


def _timed(fn, *args):
    start = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - start


def _fmt_time(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.1f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def _sized(run, target_s: float, start: int, cap: int) -> tuple[int, float, object]:
    """Grow the problem until one run takes about ``target_s``; return (count, seconds, out)."""
    count = start
    while True:
        out, secs = _timed(run, count)
        if secs >= target_s / 4 or count >= cap:
            break
        count = min(cap, count * max(2, int(target_s / max(secs, 1e-3) / 2)))
    if secs < target_s / 2 and count < cap:
        count = min(cap, int(count * target_s / max(secs, 1e-3)))
        out, secs = _timed(run, count)
    return count, secs, out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tiny", action="store_true", help="tiny sizes (simulator smoke test)")
    p.add_argument("--check", type=int, default=2000, help="realizations compared with the CPU")
    p.add_argument("--seconds", type=float, default=5.0, help="target duration of each timing")
    p.add_argument("--hist-pairs", type=int, default=10_000_000, help="pairs in the timed histogram")
    p.add_argument("--hist-edge", default="3->4", help="damaged edge of the histogram")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    _fail_no_gpu(args.tiny)

    from antisync.kernels import cpu
    from antisync.kernels import cuda as gpu

    if args.tiny:
        dt, t_max, n_check, hist_pairs, target, cap = 0.05, 50.0, 1, 2, 0.0, 1
    else:
        dt, t_max, n_check, hist_pairs, target, cap = (
            0.001,
            200.0,
            args.check,
            args.hist_pairs,
            args.seconds,
            1 << 26,
        )
    seed = args.seed
    full = _job("all", [0.5], dt, t_max)
    lam = _job("all", [], dt, t_max)  # the 12 dbeta variants only
    hjob = _job([args.hist_edge], [0.5], dt, t_max)
    v05 = hjob.variant(0, 0.5)
    hw = hjob.variant_weights[[v05]]
    rows = []

    # compile every kernel once, outside the timings
    a, kw = _common(full)
    cpu.simulate(seed, 0, 1, *a, **kw)
    for prec in ("float64", "float32"):
        a, kw = _common(lam)
        gpu.simulate(seed, 0, 1, *a, **kw, precision=prec)
        gpu.simulate_reduced(
            seed, 0, 1, *a, **kw, block=1, hist_variants=[0], bins=8, tau_max=40.0, precision=prec
        )

    # 1. agreement with the CPU backend
    a, kw = _common(full)
    first = 10**6  # realizations not used by the tests
    ref, cpu_s = _timed(lambda: cpu.simulate(seed, first, n_check, *a, **kw))
    ok = True
    agree = {}
    for prec in ("float64", "float32"):
        got = gpu.simulate(seed, first, n_check, *a, **kw, precision=prec)
        d = np.concatenate([(got.steps0 - ref.steps0)[:, None], got.steps - ref.steps], axis=1)
        st = np.concatenate([(got.status0 != ref.status0)[:, None], got.status != ref.status], axis=1)
        n_diff = int((d != 0).sum())
        agree[prec] = (
            f"{n_diff} of {d.size} trajectories differ; max abs delta steps "
            f"{int(np.abs(d).max())}; {int(st.sum())} statuses differ"
        )
        if prec == "float64" and (st.any() or np.abs(d).max() > 1 or n_diff > max(1, d.size // 1000)):
            ok = False
    rows.append(
        (f"agreement with CPU float64 ({n_check} realizations x 25)", agree["float64"], agree["float32"])
    )
    rows.append(
        ("CPU backend, same check (realizations/s)", f"{n_check / cpu_s:,.0f} ({os.cpu_count()} cores)", "")
    )

    # 2./3. throughput and the projected time to se 1e-4 on every edge's Lambda^KM
    res = {}
    for prec in ("float64", "float32"):
        a, kw = _common(lam, variant_weights=np.empty((0, lam.csr.weights.size)))
        n0, s0, _ = _sized(
            lambda m, a=a, kw=kw, prec=prec: gpu.simulate(seed, 0, m, *a, **kw, precision=prec),
            target,
            1 << 12 if not args.tiny else 1,
            cap,
        )
        a, kw = _common(lam)
        block = 1000 if not args.tiny else 1
        n1, s1, red = _sized(
            lambda m, a=a, kw=kw, prec=prec, block=block: gpu.simulate_reduced(
                seed, 0, m, *a, **kw, block=block, hist_variants=[], bins=2, tau_max=40.0, precision=prec
            ),
            target,
            1 << 10 if not args.tiny else 1,
            max(1, cap // 16),
        )
        rec = red[0].sum(axis=0)  # (V, fields): n, n_already, n_not, sum_d, sum_d2, ...
        n = np.maximum(rec[:, 0], 1)
        sd = np.sqrt(np.maximum(rec[:, 4] / n - (rec[:, 3] / n) ** 2, 0.0)) / lam.dbeta
        worst = int(np.argmax(sd))
        need = (sd.max() / 1e-4) ** 2
        res[prec] = (n0 / s0, n1 / s1, sd, worst, need, need / (n1 / s1))
    rows.append(("tau0 alone (realizations/s)", *(f"{res[p][0]:,.0f}" for p in res)))
    rows.append(
        ("all-edge Lambda^KM, 12 edges, dbeta 0.01 (realizations/s)", *(f"{res[p][1]:,.0f}" for p in res))
    )
    rows.append(
        (
            "max over edges of sd((F_dbeta - 1)/dbeta) [edge]",
            *(f"{res[p][2].max():.3f} [{lam.edge_labels[res[p][3]]}]" for p in res),
        )
    )
    rows.append(("realizations for se 1e-4 on every edge", *(f"{res[p][4]:.3g}" for p in res)))
    rows.append(("projected time to se 1e-4 on every edge", *(_fmt_time(res[p][5]) for p in res)))

    # 4. a 2D histogram of (tau0, tau(0.5)) pairs, timed on hist_pairs, extrapolated to 1e9
    hist_row = []
    for prec in ("float64", "float32"):
        a, kw = _common(hjob, variant_weights=hw)
        block = 10_000 if not args.tiny else 1
        out, secs = _timed(
            lambda a=a, kw=kw, prec=prec, block=block: gpu.simulate_reduced(
                seed,
                0,
                hist_pairs,
                *a,
                **kw,
                block=block,
                hist_variants=[0],
                bins=120,
                tau_max=40.0,
                precision=prec,
            )
        )
        hist_row.append(
            f"{_fmt_time(secs * 1e9 / hist_pairs)} ({hist_pairs:.0e} pairs in "
            f"{secs:.2f} s; {int(out[3].sum()):,} counted)"
        )
    rows.append((f"2D histogram of 1e9 (tau0, tau(0.5)) pairs, edge {args.hist_edge}", *hist_row))

    print(f"## antisync CUDA check: {_device_name()}\n")
    print(
        f"lollipop(6, 3), dt = {dt}, t_max = {t_max}, r = 0.99, seed {seed}; "
        f"numba-cuda {_numba_cuda_version()}\n"
    )
    print("| quantity | float64 | float32 |")
    print("|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print()
    print("agreement:", "OK" if ok else "FAILED (float64 should match the CPU except rare one-step flips)")
    return 0 if ok else 1


def _numba_cuda_version() -> str:
    try:
        from importlib.metadata import version

        return version("numba-cuda")
    except Exception:
        return "?"


if __name__ == "__main__":
    sys.exit(main())
