"""IEEE 39 side by side (docs/power_grids.md): every line's dynamic removal response, its
small-damage Lambda and the static indicators, their rank correlations and sign agreement, and
a drawing of the grid with the lines coloured by the removal response.

    antisync grid configs/ieee39_grid.yaml --removal --realizations 400 --seed 1 \\
        --out results/ieee39_removal.json                     # the dynamic table
    antisync run configs/ieee39_grid.yaml --realizations 200  # Lambda of every directed line
    python bench/grid_removal.py results/ieee39_removal.json --lambda results/ieee39_grid.h5 \\
        --figure docs/figures/ieee39_removal.png

Per line ``i-j``: the removal's ``d P_sync`` (McNemar's exact p), ``d tau`` on the pairs that
synchronize both times and the mean ratio ``F_1 = tau0 / tau`` (``> 1``: faster after the
removal); ``Lambda_line = Lambda_{i->j} + Lambda_{j->i}`` (the first-order response of ``F`` to
damaging both directions, ``> 0``: antifragile), and the static ``d margin``, ``d lambda2``,
``d max load`` of the locked state (antisync/grid.py). Spearman's rank correlations between
them, and the share of lines whose signs agree, where both are resolved from zero.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

# one BLAS thread, before numpy is imported: the static table's small eigenproblems ran ~40x
# slower with two threads on this busy two-core machine (bench/grid_static.py says the same)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def lambda_by_line(path: Path) -> dict:
    """``{(u, v): (Lambda_line, se)}`` from a run's records (both directions summed, their
    standard errors combined as independent: an upper bound for positively correlated ones)."""
    import antisync

    per = {}
    for r in antisync.load(path).records:
        a, b = (int(x) for x in str(r["edge"]).split("->"))
        per[(a, b)] = (float(r["lambda_km"]), float(r["lambda_km_se"]))
    out = {}
    for (a, b), (x, se) in per.items():
        if a < b and (b, a) in per:
            y, se2 = per[(b, a)]
            out[(a, b)] = (x + y, math.hypot(se, se2))
    return out


def spearman(x, y) -> tuple[float, float, int]:
    from scipy.stats import spearmanr

    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or np.ptp(x[ok]) == 0 or np.ptp(y[ok]) == 0:
        return math.nan, math.nan, int(ok.sum())  # too few lines, or one side constant
    res = spearmanr(x[ok], y[ok])
    return float(res.statistic), float(res.pvalue), int(ok.sum())


def draw(rows, static, labels_path: Path, out: Path, edges_file: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import networkx as nx

    from antisync.graphs import from_edgelist

    g = from_edgelist(edges_file)
    pos = nx.kamada_kawai_layout(g, weight=None)
    by_line = {tuple(r["line"]): r for r in rows}
    fig, ax = plt.subplots(figsize=(9, 7.5))
    cmap = plt.get_cmap("coolwarm")
    vals = [by_line[e]["ratio"] - 1 for e in by_line if by_line[e]["ratio"] is not None]
    lim = max(abs(v) for v in vals) if vals else 1.0
    norm = matplotlib.colors.Normalize(-lim, lim)
    bridges = [e for e in g.edges if tuple(sorted(e)) not in by_line]
    nx.draw_networkx_edges(g, pos, edgelist=bridges, ax=ax, edge_color="0.75", width=1.5, style="dotted")
    lines = [tuple(sorted(e)) for e in g.edges if tuple(sorted(e)) in by_line]
    colours = [cmap(norm((by_line[e]["ratio"] or 1.0) - 1)) for e in lines]
    nx.draw_networkx_edges(g, pos, edgelist=lines, ax=ax, edge_color=colours, width=4)
    trouble = [e for e in lines if by_line[e]["label"] in static["troublemakers"]]
    braess = [e for e in lines if by_line[e]["label"] in static["braess_dynamic"]]
    if trouble:
        nx.draw_networkx_edges(g, pos, edgelist=trouble, ax=ax, edge_color="k", width=1.2, style="dashed")
    mid = {e: (pos[e[0]] + pos[e[1]]) / 2 for e in lines}
    for e in braess:
        ax.plot(*mid[e], marker="o", ms=7, mfc="none", mec="k", mew=1.5)
    for e in lines:
        d = by_line[e]["lost"] - by_line[e]["gained"]
        if d:
            ax.annotate(f"{-d:+d}", mid[e], fontsize=7, xytext=(3, 3), textcoords="offset points")
    gens = [v for v in g.nodes if v >= 30]
    nx.draw_networkx_nodes(g, pos, nodelist=gens, ax=ax, node_color="#f2c14e", node_size=260, node_shape="s")
    nx.draw_networkx_nodes(
        g,
        pos,
        nodelist=[v for v in g.nodes if v < 30],
        ax=ax,
        node_color="white",
        edgecolors="k",
        node_size=200,
    )
    nx.draw_networkx_labels(g, pos, ax=ax, font_size=7)
    sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.7, label="F_1 - 1 = tau0/tau - 1 after removing the line (> 0: faster)")
    ax.set_title(
        "IEEE 39, dynamic N-1: each line coloured by the speed-up of synchronization after its removal\n"
        "o: dynamic Braess line (faster or P_sync up); dashed: troublemaker (P_sync lost)\n"
        "(both resolved at false discovery rate 0.05 over the lines)\n"
        "numbers: net realizations gained; dotted: bridges (not removed); squares: generators",
        fontsize=8,
    )
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    print(f"wrote {out}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("removal", type=Path, help="JSON of antisync grid --removal")
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "ieee39_grid.yaml")
    ap.add_argument("--lambda", dest="lam", type=Path, help="HDF5 of antisync run (Lambda per directed line)")
    ap.add_argument("--figure", type=Path, help="PNG of the grid coloured by the removal response")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from antisync.grid import load_grid_config, static_table
    from antisync.multiplicity import benjamini_hochberg
    from antisync.removal import tau_p_value

    doc = json.loads(args.removal.read_text())
    rows = doc["rows"]
    t0 = time.perf_counter()
    table = static_table(load_grid_config(args.config), beta=float(doc["summary"]["beta"]))
    t_static = time.perf_counter() - t0
    st = {r.line: r for r in table.rows}
    lam = lambda_by_line(args.lam) if args.lam else {}

    def nz(x):
        return math.nan if x is None else float(x)

    # resolved changes as the table calls them: false discovery rate 0.05 over the lines
    sync = benjamini_hochberg([r["p_value"] for r in rows])
    tau = benjamini_hochberg([tau_p_value(r["d_tau"], r["d_tau_se"]) for r in rows])
    sync_called = {r["label"] for r, c in zip(rows, sync, strict=True) if c}
    tau_called = {r["label"] for r, c in zip(rows, tau, strict=True) if c}
    speed = {r["label"] for r in rows if r["label"] in tau_called and r["d_tau"] < 0}
    slow = {r["label"] for r in rows if r["label"] in tau_called and r["d_tau"] > 0}
    s = doc["summary"]
    print(
        f"{s['name']}: {s['realizations']} realizations, intact P_sync {s['p_sync']:.4f} "
        f"[{s['p_sync_ci'][0]:.4f}, {s['p_sync_ci'][1]:.4f}], "
        f"tau0 {s['tau0_mean']:.3f} +- {s['tau0_se']:.3f}; "
        f"removal table {s['seconds']:.0f} s; static table {t_static:.2f} s"
    )
    print()
    print(
        "| line | lost | gained | d P_sync [exact 95%] | p | d tau +- se | F_1 - 1 | Lambda_line +- se "
        "| d margin | d lambda2 | d max load |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    cols = {k: [] for k in ("dp", "dtau", "f1", "lam", "dm", "dl2", "dload")}
    for r in sorted(rows, key=lambda r: (r["gained"] - r["lost"], -nz(r["d_tau"]))):
        line = tuple(r["line"])
        sr = st[line]
        lv, lse = lam.get(line, (math.nan, math.nan))
        f1 = nz(r["ratio"]) - 1
        cols["dp"].append(r["d_psync"])
        cols["dtau"].append(nz(r["d_tau"]))
        cols["f1"].append(f1)
        cols["lam"].append(lv)
        cols["dm"].append(sr.d_margin)
        cols["dl2"].append(sr.d_lambda2)
        cols["dload"].append(sr.d_max_load)
        lam_txt = "-" if math.isnan(lv) else f"{lv:+.3f} +- {lse:.3f}"
        tau_txt = f"{nz(r['d_tau']):+.3f} +- {nz(r['d_tau_se']):.3f}"
        ci = r["d_psync_ci"]
        print(
            f"| {r['label']} | {r['lost']} | {r['gained']} "
            f"| {r['d_psync']:+.4f} [{ci[0]:+.4f}, {ci[1]:+.4f}] "
            f"| {r['p_value']:.3g} | {tau_txt} | {f1:+.4f} | {lam_txt} | {sr.d_margin:+.4f} "
            f"| {sr.d_lambda2:+.4f} | {sr.d_max_load:+.4f} |"
        )
    print()
    print("Spearman rank correlations over the lines (rho, p, lines):")
    pairs = [
        ("F_1 - 1", "f1", "Lambda_line", "lam"),
        ("F_1 - 1", "f1", "d margin", "dm"),
        ("F_1 - 1", "f1", "d lambda2", "dl2"),
        ("F_1 - 1", "f1", "-d max load", "dload"),
        ("d P_sync", "dp", "d margin", "dm"),
        ("d P_sync", "dp", "d lambda2", "dl2"),
        ("d P_sync", "dp", "-d max load", "dload"),
        ("d P_sync", "dp", "Lambda_line", "lam"),
        ("d P_sync", "dp", "F_1 - 1", "f1"),
    ]
    for na, a, nb, b in pairs:
        yb = -np.asarray(cols[b]) if nb.startswith("-") else cols[b]
        rho, p, k = spearman(cols[a], yb)
        print(f"- {na} vs {nb}: rho = {rho:+.3f} (p = {p:.2g}, {k} lines)")
    # sign agreement: removal speeds synchronization (resolved) vs Lambda_line > 0 (resolved,
    # Benjamini-Hochberg over the lines as well)
    if lam:
        keys = list(lam)
        p_lam = [math.erfc(abs(lam[k][0]) / lam[k][1] / math.sqrt(2)) if lam[k][1] > 0 else 1.0 for k in keys]
        lam_called = {k for k, c in zip(keys, benjamini_hochberg(p_lam), strict=True) if c}
        res = [
            (r["label"] in speed, lam[tuple(r["line"])][0] > 0)
            for r in rows
            if (r["label"] in speed or r["label"] in slow) and tuple(r["line"]) in lam_called
        ]
        agree = sum(a == b for a, b in res)
        print(f"- sign of d tau (resolved) vs sign of Lambda_line (resolved): {agree}/{len(res)} lines agree")
    # static Braess candidates vs dynamic Braess lines
    static_braess = {r.label for r in table.braess_lines(margin="d_lambda2")}
    static_braess_m = {r.label for r in table.braess_lines()}
    dyn_braess = set(speed) | {
        r["label"] for r in rows if r["gained"] > r["lost"] and r["label"] in sync_called
    }
    print(f"- dynamic Braess lines ({len(dyn_braess)}): {', '.join(sorted(dyn_braess))}")
    for what, names in (
        ("static Braess candidates by margin/load", static_braess_m),
        ("static Braess candidates by lambda2/load", static_braess),
        ("both dynamic and static by margin/load", dyn_braess & static_braess_m),
    ):
        print(f"- {what} ({len(names)}): {', '.join(sorted(names)) or 'none'}")
    trouble = [r["label"] for r in rows if r["lost"] > r["gained"] and r["label"] in sync_called]
    print(f"- troublemakers resolved (McNemar, FDR 0.05 over the lines): {', '.join(trouble) or 'none'}")
    print(f"- removal slows synchronization (resolved): {', '.join(sorted(slow)) or 'none'}")
    if args.figure:
        marks = {"braess_dynamic": dyn_braess, "troublemakers": set(trouble)}
        draw(rows, marks, args.removal, args.figure, load_edges(args.config))
    return 0


def load_edges(config: Path) -> Path:
    import yaml

    cfg = yaml.safe_load(config.read_text())
    return config.parent / cfg["graph"]["path"]


if __name__ == "__main__":
    raise SystemExit(main())
