"""Would Rodas4 gain from lanes? The numeric LU and the triangular solves of ACTIVSg2000's
shared plan, for one trajectory and for 8 at once (values stored ``(entries, 8)``: each index
of the plan read once for 8 trajectories), on a diagonally dominant matrix of the plan's
pattern; printed per trajectory (issue 62; bench/RESULTS.md, "Rodas4 against Radau at equal
accuracy"). A probe, not a driver: Rodas4 has no lanes.

    OPENBLAS_NUM_THREADS=1 python bench/rodas_lanes_probe.py
"""

import time

import numpy as np
from numba import njit

from antisync.kernels import implicit
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job

cfg = load_config("configs/activsg2000_grid.yaml")
job = make_job(cfg)
plan = implicit.factor_plan(job.csr.indptr, job.csr.indices)
fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj = plan
nnz = fp_col.size
n = fp_diag.size
print("n", n, "nnz LU", nnz, "updates", upd_ij.size)


@njit(cache=False)
def factor1(reps, val0, val):
    for _r in range(reps):
        val[:] = val0
        implicit._factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, 1.0)
    return val[0]


L = 8


@njit(cache=False, fastmath=False)
def factorL(reps, val0, val, ok):
    for _r in range(reps):
        val[:, :] = val0
        for k in range(n):
            d = fp_diag[k]
            inv = np.empty(L)
            for l in range(L):
                piv = val[d, l]
                ok[l] &= abs(piv) > 1e-12
                inv[l] = 1.0 / piv
                val[d, l] = inv[l]
            for e in range(div_ptr[k], div_ptr[k + 1]):
                p = div_pos[e]
                for l in range(L):
                    val[p, l] *= inv[l]
            for e in range(upd_ptr[k], upd_ptr[k + 1]):
                a = upd_ij[e]
                b = upd_ik[e]
                c = upd_kj[e]
                for l in range(L):
                    val[a, l] -= val[b, l] * val[c, l]
    return val[0, 0]


@njit(cache=False)
def solve1(reps, val, b, x, xp):
    for _r in range(reps):
        implicit._solve(val, fp_ptr, fp_col, fp_diag, fp_perm, b, x, xp)
    return x[0]


@njit(cache=False)
def solveL(reps, val, b, x, xp):
    for _r in range(reps):
        for k in range(n):
            for l in range(L):
                xp[k, l] = b[fp_perm[k], l]
        for k in range(n):
            acc = xp[k].copy()
            for q in range(fp_ptr[k], fp_diag[k]):
                c = fp_col[q]
                for l in range(L):
                    acc[l] -= val[q, l] * xp[c, l]
            xp[k] = acc
        for k in range(n - 1, -1, -1):
            acc = xp[k].copy()
            for q in range(fp_diag[k] + 1, fp_ptr[k + 1]):
                c = fp_col[q]
                for l in range(L):
                    acc[l] -= val[q, l] * xp[c, l]
            d = fp_diag[k]
            for l in range(L):
                xp[k, l] = acc[l] * val[d, l]
        for k in range(n):
            for l in range(L):
                x[fp_perm[k], l] = xp[k, l]
    return x[0, 0]


# a diagonally dominant matrix on the pattern
rng = np.random.default_rng(0)
val0 = np.zeros(nnz)
val0[fp_entry] = -rng.uniform(0.5, 1.5, fp_entry.size)
val0[fp_diag] = 50.0
v0L = np.repeat(val0[:, None], L, axis=1) * rng.uniform(0.9, 1.1, (1, L))
v0L = np.ascontiguousarray(v0L)
val = np.empty(nnz)
valL = np.empty((nnz, L))
ok = np.ones(L, dtype=np.bool_)
factor1(1, val0, val)
factorL(1, v0L, valL, ok)
b = rng.normal(size=n)
x = np.empty(n)
xp = np.empty(n)
bL = rng.normal(size=(n, L))
xL = np.empty((n, L))
xpL = np.empty((n, L))
solve1(1, val, b, x, xp)
solveL(1, valL, bL, xL, xpL)
R = 300
for _rep in range(2):
    t = time.perf_counter()
    factor1(R, val0, val)
    t1 = (time.perf_counter() - t) / R
    t = time.perf_counter()
    factorL(R, v0L, valL, ok)
    tL = (time.perf_counter() - t) / R
    t = time.perf_counter()
    solve1(R, val, b, x, xp)
    s1 = (time.perf_counter() - t) / R
    t = time.perf_counter()
    solveL(R, valL, bL, xL, xpL)
    sL = (time.perf_counter() - t) / R
    print(
        f"factor: 1 lane {t1 * 1e3:.3f} ms, {L} lanes {tL * 1e3:.3f} ms, "
        f"{t1 / (tL / L):.2f}x per trajectory; solve: 1 lane {s1 * 1e3:.3f} ms, "
        f"{L} lanes {sL * 1e3:.3f} ms, {s1 / (sL / L):.2f}x"
    )
