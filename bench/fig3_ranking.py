"""The Fig. 3 ranking with its uncertainty: is Table 1's top seven in the paper's order?

``python bench/fig3_ranking.py results/fig3_two_hours.h5`` reads a finished atlas sweep
(``make fig3-two-hours``) and prints, as markdown:

- the first ``--top`` graphs by score, the sum of their positive Lambda^KM over all directed
  links (every orbit member counted), with a standard error by batch means: each block of the
  job (``block_size`` realizations) gives a score from its own per-link means (the positive
  set fixed by the whole run), and the se is the blocks' sd over sqrt(blocks);
- for consecutive ranks, the score difference and its se from the paired blocks (every graph
  of a sweep draws the same initial phases per realization, so the difference is more precise
  than the two se together), and whether the order is resolved at ``--z``;
- where each of the paper's Table 1 graphs (atlas indices as in ``antisync.paper.make.TABLE1_ATLAS``)
  lands, and whether the paper's order 1..7 holds pair by pair.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from antisync.paper.make import TABLE1_ATLAS  # noqa: E402
from antisync.stats.estimators import LAMBDA_FIELDS  # noqa: E402
from antisync.store import read_meta, read_views  # noqa: E402
from antisync.sweeps.analysis import ranking, summarize  # noqa: E402


def block_scores(view, records: list[dict]) -> np.ndarray:
    """Per block of ``view`` (a main-stage job), the score from that block's own per-link means:
    every representative link whose whole-run Lambda^KM is positive, times its orbit size."""
    weight = {}
    for r in records:  # fanned out: one per directed link, each naming its representative
        if r["job"] == view.graph and r["beta"] is None and r["lambda_km"] > 0:
            weight[r["representative"]] = r["orbit_size"]
    rec = view.lam_rec[view.done]  # (blocks, links, fields)
    n, s = rec[:, :, LAMBDA_FIELDS.index("n")], rec[:, :, LAMBDA_FIELDS.index("sum")]
    with np.errstate(invalid="ignore", divide="ignore"):
        per_block = np.where(n > 0, s / n, 0.0)
    size = np.array([weight.get(e, 0) for e in view.edges], dtype=float)
    return per_block @ size


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path)
    ap.add_argument("--top", type=int, default=12, help="ranks to print")
    ap.add_argument("--z", type=float, default=3.0, help="standard errors for a resolved order")
    args = ap.parse_args()
    meta, views = read_meta(args.sweep), read_views(args.sweep)
    summary = summarize(meta, views)
    by_job = {v.graph: v for v in views}
    main_jobs = {j["graph"]: j["job"] for j in meta["jobs"] if j["stage"] == "main" and j["repeat"] == 0}
    rows = [
        {
            "graph": row["graph"],
            "score": row["score"],
            "blocks": block_scores(by_job[main_jobs[row["graph"]]], summary["records"]),
            "n": by_job[main_jobs[row["graph"]]].realizations,
        }
        for row in ranking(summary["records"], summary["ranking_threshold"])
    ]
    paper_rank = {f"G{atlas}": k for k, (atlas, _) in TABLE1_ATLAS.items()}
    print(f"{args.sweep}: {len(rows)} graphs, {rows[0]['n']:,} realizations each\n")
    print(
        "| rank | graph | paper's Table 1 | score (sum of positive Lambda^KM) | se "
        "| to the next rank | se (paired) | resolved |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---|")
    for k, r in enumerate(rows[: args.top]):
        se = r["blocks"].std(ddof=1) / np.sqrt(len(r["blocks"]))
        gap = gap_se = None
        if k + 1 < len(rows):
            nxt = rows[k + 1]
            d = r["blocks"] - nxt["blocks"]
            gap, gap_se = r["score"] - nxt["score"], d.std(ddof=1) / np.sqrt(len(d))
        resolved = "" if gap is None else ("yes" if gap > args.z * gap_se else "no")
        gap_text = "| |" if gap is None else f"| {gap:.4f} | {gap_se:.4f} |"
        print(
            f"| {k + 1} | {r['graph']} | {paper_rank.get(r['graph'], '')} | {r['score']:.4f} | {se:.4f} "
            f"{gap_text} {resolved} |"
        )
    where = {r["graph"]: k + 1 for k, r in enumerate(rows)}
    by_graph = {r["graph"]: r for r in rows}
    print("\nThe paper's order, pair by pair (paper rank k above k + 1):\n")
    print("| paper | graph | here | score | paper k+1 | score difference | se (paired) | here |")
    print("|---:|---|---:|---:|---|---:|---:|---|")
    for k in range(1, len(TABLE1_ATLAS) + 1):
        g = f"G{TABLE1_ATLAS[k][0]}"
        line = f"| {k} | {g} | {where.get(g, '-')} | {by_graph[g]['score']:.4f} |"
        if k + 1 in TABLE1_ATLAS:
            h = f"G{TABLE1_ATLAS[k + 1][0]}"
            d = by_graph[g]["blocks"] - by_graph[h]["blocks"]
            diff, se = by_graph[g]["score"] - by_graph[h]["score"], d.std(ddof=1) / np.sqrt(len(d))
            verdict = (
                "above, resolved"
                if diff > args.z * se
                else ("below, resolved" if diff < -args.z * se else "unresolved")
            )
            line += f" {h} | {diff:+.4f} | {se:.4f} | {verdict} |"
        else:
            line += " | | | |"
        print(line)


if __name__ == "__main__":
    main()
