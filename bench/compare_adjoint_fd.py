"""Adjoint-hybrid against finite difference on common phases, paired (issue 14, item 2).

Both runs use the same seed, so realization ``k`` starts from the same phases in each; both
keep every realization's Lambda (``keep_pairs``), and the per-link difference of the two
estimates is judged by the standard error of the *paired* differences (far smaller than
either estimate's own error when the two move together). Reports, per link: both estimates,
their difference with its paired standard error and z, the adjoint-hybrid's flagged fraction,
and the per-realization variance ratio (adjoint-hybrid over finite difference).

With ``--dbetas H H/2`` the finite difference runs at each step on the same phases and a
second table shows, per link, the paired difference ``adjoint-hybrid - FD(h)`` at each step
and against the Richardson extrapolation ``2 FD(h/2) - FD(h)`` (which cancels the forward
difference's O(dbeta) curvature term): a difference that halves with the step is the forward
difference's bias, not the derivative's.

Usage::

    python bench/compare_adjoint_fd.py --realizations 3000 --links 8
    python bench/compare_adjoint_fd.py --realizations 3000 --links 8 --dbetas 0.01 0.005
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

KARATE = {"kind": "networkx", "generator": "karate_club_graph"}


def kept(
    method: str, edges, realizations: int, seed: int, dbeta: float = 0.01
) -> tuple[list[str], np.ndarray, np.ndarray, float]:
    """``(edges, values (m, E), flagged fraction per link, seconds)`` of one run."""
    import h5py

    import antisync

    out = Path(tempfile.mkdtemp()) / f"{method}.h5"
    cfg = {
        "graph": KARATE,
        "edges": edges,
        "betas": [],
        "seed": seed,
        "keep_pairs": realizations,
        "lambda": {"method": method, "dbeta": dbeta},
        "dynamics": {"integrator": "rk4", "dt": 0.04, "t_max": 200.0},
    }
    t = time.perf_counter()
    res = antisync.run(cfg, realizations=realizations, output=out, progress=False)
    seconds = time.perf_counter() - t
    with h5py.File(out, "r") as f:
        (g,) = f["jobs"].values()
        labels = json.loads(g.attrs["edges"])
        lam = g["kept/lambda"][...]
    flagged = {r["edge"]: r["lambda_n_flagged"] / max(r["lambda_n"], 1) for r in res.records}
    return labels, lam, np.array([flagged[e] for e in labels]), seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realizations", type=int, default=3000)
    ap.add_argument("--links", type=int, default=8, help="the first LINKS directed links of karate")
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--dbetas", type=float, nargs=2, metavar=("H", "H2"), help="also FD at H and H2 = H/2")
    args = ap.parse_args()
    import networkx as nx

    g = nx.karate_club_graph()
    pairs = sorted(g.edges())[: (args.links + 1) // 2]
    edges = [f"{a}->{b}" for a, b in pairs] + [f"{b}->{a}" for a, b in pairs]
    edges = edges[: args.links]
    labels, fd, _, t_fd = kept("finite-difference", edges, args.realizations, args.seed)
    labels2, ah, flag, t_ah = kept("adjoint-hybrid", edges, args.realizations, args.seed)
    assert labels == labels2
    ok = np.isfinite(fd).all(axis=1) & np.isfinite(ah).all(axis=1)
    fd, ah = fd[ok], ah[ok]
    m = fd.shape[0]
    print(
        f"# karate club, {len(labels)} links, RK4 dt 0.04, dbeta 0.01, {m:,} common realizations "
        f"(seed {args.seed}); finite difference {t_fd:.0f} s, adjoint-hybrid {t_ah:.0f} s\n"
    )
    print("| link | finite difference | adjoint-hybrid | difference | paired se | z | flagged | var ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    zs = []
    for e, label in enumerate(labels):
        d = ah[:, e] - fd[:, e]
        se_d = d.std(ddof=1) / math.sqrt(m)
        z = d.mean() / se_d if se_d > 0 else math.nan
        zs.append(z)
        se_fd = fd[:, e].std(ddof=1) / math.sqrt(m)
        se_ah = ah[:, e].std(ddof=1) / math.sqrt(m)
        print(
            f"| {label} | {fd[:, e].mean():+.4f} +- {se_fd:.4f} | {ah[:, e].mean():+.4f} +- {se_ah:.4f} | "
            f"{d.mean():+.4f} | {se_d:.4f} | {z:+.1f} | {flag[e]:.2%} | {(se_ah / se_fd) ** 2:.2f} |"
        )
    zs = np.array(zs)
    print(
        f"\njoint: sum z^2 = {np.nansum(zs**2):.1f} on {np.isfinite(zs).sum()} links "
        "(chi^2 with that many dof)"
    )
    if args.dbetas:
        richardson(labels, edges, ah[:, :], ok, args)


def _paired(d: np.ndarray) -> str:
    se = d.std(ddof=1) / math.sqrt(d.size)
    return f"{d.mean():+.4f} +- {se:.4f} ({d.mean() / se:+.1f})"


def richardson(labels, edges, ah, ok, args) -> None:
    """Adjoint-hybrid against FD(h), FD(h/2) and 2 FD(h/2) - FD(h), paired on common phases."""
    h, h2 = args.dbetas
    runs = {}
    for step in (h, h2):
        lab, v, _, t = kept("finite-difference", edges, args.realizations, args.seed, step)
        assert lab == labels
        runs[step] = v[ok]
        print(f"\n# finite difference dbeta {step}: {t:.0f} s", end="")
    ok2 = np.isfinite(runs[h]).all(axis=1) & np.isfinite(runs[h2]).all(axis=1)
    a, f1, f2 = ah[ok2], runs[h][ok2], runs[h2][ok2]
    rich = 2 * f2 - f1
    print(f"\n\n{ok2.sum():,} common realizations; paired difference +- se (z)\n")
    print(f"| link | AH - FD({h}) | AH - FD({h2}) | AH - (2 FD({h2}) - FD({h})) |")
    print("|---|---:|---:|---:|")
    for e, label in enumerate(labels):
        cols = [_paired(a[:, e] - f[:, e]) for f in (f1, f2, rich)]
        print(f"| {label} | " + " | ".join(cols) + " |")


if __name__ == "__main__":
    main()
