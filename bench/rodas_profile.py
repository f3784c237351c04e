"""Where a Rodas4 trajectory's time goes on a large grid (issue 62, item 4).

    python bench/rodas_profile.py [--config configs/activsg2000_grid.yaml] [--starts 2] [--repeat 200]

One thread. The config's undamaged grid from starts ``0 .. starts-1`` within 1 rad of its
operating point, as ``bench/bench_rodas_large.py`` runs them: CPU seconds, accepted and rejected
steps, hence the time of one step. Then the parts of a step timed alone, each ``--repeat``
times in a compiled loop at the operating point (their cost does not depend on the values):
the matrix assembled (``_assemble``), its numeric LU on the shared symbolic plan (``_factor``),
one triangular solve (``_solve``), one right-hand side with its cosines (``_eval``). A step is
one assembly, one LU, six solves and six right-hand sides (five stages and the accepted state's
rates); what is left is the stages' vector work and the criterion. Printed with the LU's size
(the entries of L + U against the Jacobian's, and the multiply-adds of the numeric LU).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from numba import njit

from antisync.execution.dispatch import job_model_params
from antisync.kernels import implicit
from antisync.kernels.shared import per_node
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job

ROOT = Path(__file__).resolve().parent.parent


@njit(cache=False)
def _assembles(reps, val, cy, sy, eq, dd, plan):
    """The matrix assembled ``reps`` times."""
    _, w, indptr, indices, cl, sl, _, _ = eq
    fp_inv, fp_diag, fp_entry = plan[1], plan[4], plan[5]
    for _ in range(reps):
        implicit._assemble(val, cy, sy, indptr, indices, w, cl, sl, dd, fp_entry, fp_diag, fp_inv)
    return val[0]


@njit(cache=False)
def _assemble_factor(reps, val, cy, sy, eq, dd, plan, scale):
    p, w, indptr, indices, cl, sl, mass, gamma = eq
    fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry = plan[:6]
    div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj = plan[6:]
    ok = True
    for _ in range(reps):
        implicit._assemble(val, cy, sy, indptr, indices, w, cl, sl, dd, fp_entry, fp_diag, fp_inv)
        ok &= implicit._factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, scale)
    return ok


@njit(cache=False)
def _solves(reps, val, plan, b, x, xp):
    fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry = plan[:6]
    for _ in range(reps):
        implicit._solve(val, fp_ptr, fp_col, fp_diag, fp_perm, b, x, xp)
    return x[0]


@njit(cache=False)
def _rates(reps, th, nu, cy, sy, eq, second, f_th, f_nu):
    for _ in range(reps):
        implicit._eval(th, nu, cy, sy, eq, second, f_th, f_nu)
    return f_th[0]


def _clock(fn, *args) -> float:
    t0 = time.process_time()
    fn(*args)
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "activsg2000_grid.yaml")
    ap.add_argument("--starts", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args()

    cfg = load_config(args.config, ["model.start={around: locked, width: 1.0}", "threads=1"])
    job = make_job(cfg)
    dyn = cfg.dynamics
    rtol, atol = dyn.tolerances
    csr = job.csr
    n = len(job.nodes)
    plan = implicit.factor_plan(csr.indptr, csr.indices)
    empty = np.zeros((0, csr.weights.size))
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, {args.config.name}, "
        f"N = {n}, rodas4 rtol {rtol} atol {atol}, one thread"
    )

    def one(k):
        ks = np.array([k], dtype=np.uint64)
        params = job_model_params(job, ks, job.model.targets[:1])
        return implicit.simulate_model(
            cfg.seed, 0, 1, csr.indptr, csr.indices, csr.weights, empty, params,
            dt=dyn.dt, max_steps=dyn.max_steps, rtol=rtol, atol=atol, threads=1, plan=plan,
            realizations=ks, stats=True,
        )  # fmt: skip

    one(0)  # compile or load
    per_step = []
    for k in range(args.starts):
        c0 = time.process_time()
        _, stats = one(k)
        took = time.process_time() - c0
        steps = int(stats.accepted0[0] + stats.rejected0[0])
        per_step.append(took / steps)
        print(
            f"start {k}: {took:.2f} CPU s, {int(stats.accepted0[0])} accepted + "
            f"{int(stats.rejected0[0])} rejected steps: {1e3 * took / steps:.3f} ms a step"
        )
    step = float(np.mean(per_step))

    # the parts, at the operating point (their cost does not depend on the values)
    params = job_model_params(job, np.array([0], dtype=np.uint64), job.model.targets[:1])
    mass, gamma = per_node(params.inertia, n), per_node(params.damping, n)
    freqs = np.ascontiguousarray(params.freqs[0], dtype=np.float64)
    th = np.zeros(n)  # the parts' cost does not depend on the state
    nu = np.zeros(n)
    cy, sy = np.cos(th), np.sin(th)
    eq = (freqs, csr.weights, csr.indptr, csr.indices, params.cos_lag, params.sin_lag, mass, gamma)
    second = bool((mass > 0).any())
    fp_col = plan[3]
    val = np.zeros(fp_col.shape[0])
    h = 0.01
    g = 1.0 / (h * implicit._GAMMA)
    _, gamma_eff = implicit._orders(mass, gamma)
    dd = g * (mass * g + gamma_eff) if second else np.full(n, g)
    scale = implicit._row_scale(csr.indptr, csr.weights) * (g + 1.0)
    b, x, xp = np.ones(n), np.empty(n), np.empty(n)
    f_th, f_nu = np.empty(n), np.empty(n)
    reps = args.repeat
    _assembles(1, val, cy, sy, eq, dd, plan)
    _assemble_factor(1, val, cy, sy, eq, dd, plan, scale)
    _solves(1, val, plan, b, x, xp)
    _rates(1, th, nu, cy, sy, eq, second, f_th, f_nu)
    t_asm = _clock(_assembles, reps, val, cy, sy, eq, dd, plan) / reps
    t_lu = _clock(_assemble_factor, reps, val, cy, sy, eq, dd, plan, scale) / reps - t_asm
    t_solve = _clock(_solves, reps, val, plan, b, x, xp) / reps
    t_rhs = _clock(_rates, reps, th, nu, cy, sy, eq, second, f_th, f_nu) / reps
    parts = {
        "assemble": t_asm,
        "numeric LU": t_lu,
        "6 solves": 6 * t_solve,
        "6 right-hand sides": 6 * t_rhs,
    }
    rest = step - sum(parts.values())
    nnz_j = csr.indices.size + n
    mult = int(plan[8][-1])
    print(
        f"LU: {fp_col.shape[0]:,} entries of L + U against {nnz_j:,} of the matrix "
        f"({fp_col.shape[0] / nnz_j:.2f}x fill), {mult:,} multiply-adds a factorization"
    )
    print(f"a step: {1e3 * step:.3f} ms")
    for name, t in parts.items():
        print(f"  {name:<20} {1e3 * t:8.3f} ms  {100 * t / step:5.1f}%")
    print(f"  {'the rest':<20} {1e3 * rest:8.3f} ms  {100 * rest / step:5.1f}%  (stage vectors, criterion)")


if __name__ == "__main__":
    main()
