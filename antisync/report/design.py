"""The figures of a design file (``antisync design``, docs/design.md).

- ``NAME_network.png``: the network drawn with its designed weights (width), links the design
  removed dashed, added candidate links in orange;
- ``NAME_progress.png``: the training estimate of ``<tau>`` against iteration with +-2 standard
  errors, and each check's paired validation comparison (accepted filled);
- ``NAME_tau.png``: histograms of ``tau`` on the fresh starts, the designed weights against the
  baselines, with the paired differences and their 95% intervals in the legend;
- ``NAME_lambda.png``: each link's designed weight relative to the graph's own against that
  link's Lambda at the graph's own weights (are the weakened links the antifragile ones?).
"""

from __future__ import annotations

from pathlib import Path

import networkx as nx
import numpy as np

from antisync.store.design_file import read_design

__all__ = ["draw_design"]

REMOVED = 1e-9
"""A designed weight below this fraction of the mean weight is drawn as removed."""


def draw_design(path: str | Path, folder: str | Path | None = None) -> list[Path]:
    """Draw the four figures of the design file ``path`` into ``folder`` (default: next to the
    file, ``<stem>_figures``); return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    rec = read_design(path)
    folder = Path(folder) if folder is not None else path.with_name(path.stem + "_figures")
    folder.mkdir(parents=True, exist_ok=True)
    stem = path.stem
    prob = rec["problem"]
    labels = prob["labels"]
    links = prob["links"]
    base = rec.get("baselines", {})
    designed = base.get("designed", rec["state"]["best"] if "state" in rec else prob["start"])
    out = []

    # the network
    g = nx.Graph()
    names = sorted({int(v) for v in links.ravel()})
    g.add_nodes_from(names)
    for a, b in links:
        g.add_edge(int(a), int(b))
    pos = nx.spring_layout(g, seed=1)
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    mean = float(np.mean(designed)) or 1.0
    for l, (a, b) in enumerate(links):
        (x0, y0), (x1, y1) = pos[int(a)], pos[int(b)]
        w = designed[l] / mean
        if designed[l] <= REMOVED * mean:
            ax.plot([x0, x1], [y0, y1], ls="--", color="0.6", lw=0.8, zorder=1)
        else:
            color = "tab:orange" if prob["candidate"][l] else "tab:blue"
            ax.plot([x0, x1], [y0, y1], color=color, lw=0.5 + 2.5 * min(w, 3.0), zorder=1)
    xy = np.array([pos[v] for v in names])
    ax.scatter(xy[:, 0], xy[:, 1], s=40, color="k", zorder=2)
    ax.set_title("designed weights (width; dashed: removed, orange: added)")
    ax.set_axis_off()
    out.append(_save(fig, folder / f"{stem}_network.png", plt))

    # progress
    its = rec["iterations"]
    if its:
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        t = np.arange(1, len(its) + 1)
        tau = np.array([r["tau"] for r in its])
        se = np.array([r["tau_se"] for r in its])
        ax.plot(t, tau, lw=1, label="training <tau> (fresh starts each iteration)")
        ax.fill_between(t, tau - 2 * se, tau + 2 * se, alpha=0.3)
        for c in rec["checks"]:
            style = dict(color="tab:green" if c["accepted"] else "tab:red")
            ax.errorbar(
                c["iteration"],
                c["candidate_tau"],
                yerr=2 * c["diff_se"],
                fmt="o",
                ms=4,
                mfc=style["color"] if c["accepted"] else "white",
                **style,
            )
        ax.set_xlabel("iteration")
        ax.set_ylabel("<tau>")
        ax.set_title("descent (checks: validation <tau>, filled when the improvement was resolved)")
        ax.legend(fontsize=8)
        out.append(_save(fig, folder / f"{stem}_progress.png", plt))

    # tau histograms on fresh starts
    ver = rec.get("verification")
    if ver is not None:
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        tau = ver["tau"]
        hi = float(np.quantile(tau, 0.995))
        bins = np.linspace(0, hi, 60)
        for i, name in enumerate(ver["names"]):
            row = ver["rows"][i]
            text = f"{name}: {row['mean_tau']:.4g}"
            if i:
                text += f" (+{row['minus_designed']:.3g} [{row['low']:.3g}, {row['high']:.3g}])"
            ax.hist(tau[i], bins=bins, histtype="step", lw=1.4, label=text)
        ax.set_xlabel("tau on fresh starts")
        ax.set_ylabel("starts")
        ax.set_title(f"{tau.shape[1]} fresh paired starts: <tau>, difference to designed [95%]")
        ax.legend(fontsize=7)
        out.append(_save(fig, folder / f"{stem}_tau.png", plt))

    # designed weights against Lambda
    sens = rec.get("sensitivity")
    if sens is not None:
        existing = ~prob["candidate"].astype(bool)
        start = prob["start"][existing]
        ratio = designed[existing] / start
        lam, lam_se = sens["lambda"][existing], sens["lambda_se"][existing]
        fig, ax = plt.subplots(figsize=(6.4, 4.4))
        ax.errorbar(lam, ratio, xerr=1.96 * lam_se, fmt="o", ms=4, lw=0.8)
        ax.axvline(0, color="0.5", lw=0.8)
        ax.axhline(float(np.sum(designed[existing]) / np.sum(start)), color="0.5", lw=0.8, ls=":")
        order = np.argsort(-np.abs(lam))[:6]
        for i in order:
            ax.annotate(
                [lab for lab, e in zip(labels, existing, strict=True) if e][i], (lam[i], ratio[i]), fontsize=7
            )
        ax.set_xlabel("Lambda of the link at the graph's own weights (> 0: antifragile)")
        ax.set_ylabel("designed weight / graph's weight")
        ax.set_title("are the weakened links the antifragile ones?")
        out.append(_save(fig, folder / f"{stem}_lambda.png", plt))
    return out


def _save(fig, path: Path, plt) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
