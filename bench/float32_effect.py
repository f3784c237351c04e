"""How much ``precision: float32`` moves tau and Lambda: float32 against float64, same phases.

Usage::

    python bench/float32_effect.py --realizations 100000          # on a GPU
    NUMBA_ENABLE_CUDASIM=1 python bench/float32_effect.py --realizations 20 --dt 0.01
    python bench/float32_effect.py --on cpu --dt 0.01 --betas "[]" --realizations 1000000

Same graph, seed, realizations and initial phases (drawn in double, rounded once to float32);
reports, for tau0 and every damaged variant of lollipop(6, 3) (all 12 directed edges at
beta = 0.5 and at dbeta = 0.01), the fraction of trajectories whose step count differs, the
largest |delta tau|, and what that does to the per-realization finite difference
(F_dbeta - 1) / dbeta that Lambda^KM averages (per edge: mean shift and its standard error).

``--on cpu`` runs the CPU backend's float32 lanes (``kernels.cpu.simulate(...,
precision="float32")``: the same step functions, ``core.make_kernels(njit, np.float32)``, bit
for bit the one-trajectory float32 driver) against its float64: a million realizations in
minutes where the simulator manages tens. It is the float32 arithmetic of the GPU kernels
without the GPU's fused multiply-adds and CUDA's cosf/sinf, so its statistics describe float32
rounding in general, not one device bit for bit.

Per edge it prints the float32 shift of the mean (F_dbeta - 1)/dbeta with its standard error,
and the shift in units of the standard error of Lambda itself at the same number of
realizations ("of se"; the issue-17 criterion for float32 lanes is below 0.1 at 1e6).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--realizations", type=int, default=20)
    p.add_argument("--first", type=int, default=0)
    p.add_argument("--dt", type=float, default=0.001)
    p.add_argument("--t-max", type=float, default=200.0)
    p.add_argument("--edges", default="all", help="'all' or a YAML list such as ['3->4']")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--betas", default="[0.5]", help="YAML list of damages besides dbeta")
    p.add_argument("--on", choices=("cuda", "cpu"), default="cuda")
    args = p.parse_args(argv)

    from antisync.kernels import cuda as gpu
    from antisync.kernels.backends import cuda_usable
    from antisync.plan.config import load_config_text
    from antisync.plan.jobs import make_job

    if args.on == "cuda":
        ok, why = cuda_usable()
        if not ok:
            print(f"float32_effect: {why}", file=sys.stderr)
            return 2
    job = make_job(
        load_config_text(
            f"graph: {{kind: lollipop, nodes: 6, path: 3}}\nedges: {args.edges}\nbetas: {args.betas}\n"
            f"lambda: {{dbeta: 0.01}}\ndynamics: {{dt: {args.dt}, t_max: {args.t_max}}}\n"
        )
    )
    dyn = job.config.dynamics
    a = (
        args.seed,
        args.first,
        args.realizations,
        job.csr.indptr,
        job.csr.indices,
        job.csr.weights,
        job.variant_weights,
    )
    kw = {"dt": dyn.dt, "threshold": dyn.threshold, "max_steps": dyn.max_steps}
    start = time.perf_counter()
    if args.on == "cuda":
        r64 = gpu.simulate(*a, **kw, precision="float64")
        r32 = gpu.simulate(*a, **kw, precision="float32")
    else:
        from antisync.kernels import cpu

        r64 = cpu.simulate(*a, **kw)
        r32 = cpu.simulate(*a, **kw, precision="float32")
    secs = time.perf_counter() - start

    steps64 = np.concatenate([r64.steps0[:, None], r64.steps], axis=1)
    steps32 = np.concatenate([r32.steps0[:, None], r32.steps], axis=1)
    st64 = np.concatenate([r64.status0[:, None], r64.status], axis=1)
    st32 = np.concatenate([r32.status0[:, None], r32.status], axis=1)
    diff = steps32 - steps64
    print(
        f"[{args.on}] lollipop(6,3), {args.realizations} realizations from {args.first}, dt = {dyn.dt}, "
        f"t_max = {dyn.t_max}, {steps64.shape[1]} trajectories each ({secs:.1f} s)"
    )
    print(f"  status differs: {int((st64 != st32).sum())} of {st64.size} trajectories")
    for name, cols in (("tau0", [0]), ("all variants", list(range(1, steps64.shape[1])))):
        d = diff[:, cols]
        print(
            f"  {name}: steps differ in {int((d != 0).sum())} of {d.size} trajectories "
            f"({(d != 0).mean():.1%}); realizations with any difference "
            f"{int((d != 0).any(axis=1).sum())} of {d.shape[0]}; max |delta tau| = "
            f"{np.abs(d).max() * dyn.dt:.4g} ({int(np.abs(d).max())} steps); mean delta steps "
            f"{d.mean():+.3f}; mean tau {steps64[:, cols].mean() * dyn.dt:.3f}"
        )
    fd = np.flatnonzero(np.isclose(job.variant_beta, job.dbeta))
    ok64 = (r64.status0[:, None] == 0) & (r64.status[:, fd] == 0)
    g64 = (r64.steps0[:, None] / r64.steps[:, fd] - 1.0) / job.dbeta
    g32 = (r32.steps0[:, None] / r32.steps[:, fd] - 1.0) / job.dbeta
    ok64 &= (r32.status0[:, None] == 0) & (r32.status[:, fd] == 0)
    dg = np.where(ok64, g32 - g64, 0.0)
    n = np.maximum(ok64.sum(axis=0), 1)
    shift = dg.sum(axis=0) / n
    se = np.sqrt(np.maximum((dg**2).sum(axis=0) / n - shift**2, 0.0) / n)
    sd = np.sqrt(
        np.maximum(
            np.where(ok64, g64**2, 0).sum(axis=0) / n - (np.where(ok64, g64, 0).sum(axis=0) / n) ** 2, 0.0
        )
    )
    print(
        f"  (F_dbeta - 1)/dbeta per realization: largest per-edge sd {sd.max():.3f}; "
        f"max |float32 - float64| {np.abs(dg).max():.4f}, mean |.| {np.abs(dg)[ok64].mean():.5f}"
    )
    for e in range(len(fd)):
        lam_se = sd[e] / np.sqrt(n[e])
        print(
            f"    {job.edge_labels[job.variant_edge[fd[e]]]:>5}: mean (F-1)/dbeta "
            f"{np.where(ok64[:, e], g64[:, e], 0).sum() / n[e]:+.4f} (sd {sd[e]:.3f}), float32 shift "
            f"{shift[e]:+.2e} +- {se[e]:.1e} = {abs(shift[e]) / lam_se if lam_se > 0 else 0.0:.3f} of se"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
