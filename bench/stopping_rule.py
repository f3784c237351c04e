"""How the stopping rule (``stop: {when: signs-resolved}``) spends realizations, and how often
it resolves a sign wrongly, on runs drawn from a calibration pool (bench/calibrate_errors.py).

Each simulated run draws ``budget`` realizations from the pool with replacement (the truth is
the pool's mean) and looks at ``first_look``, twice as many, ..., ``budget`` as the runner does
(:attr:`antisync.plan.config.Config.stop_looks`), computing every link's interval at the look level
of :func:`antisync.execution.stopping.look_level` with the summary's own functions. It reports, per
rule, the realizations spent (mean and quartiles, against the budget), the links whose sign is
resolved in the file it ends with (the records' 95% intervals at the realizations spent), and
the *false signs*: a resolved sign opposite to the pool mean's
(per link, and runs with any). The rules compared:

- ``bonferroni``: antisync's, each look at ``1 - 0.05 / looks``;
- ``naive``: every look at 95%, every interval counted (what a user who reruns until it
  looks resolved does);
- ``fixed``: no looks, the whole budget at 95% (the plain run).

Usage::

    python bench/stopping_rule.py lollipop --budget 64000 --first-look 2000 --runs 200

Results: bench/RESULTS.md ("The stopping rule").
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from calibrate_errors import LOLLIPOP, pool  # noqa: E402

from antisync.execution.stopping import look_level  # noqa: E402
from antisync.stats import estimators  # noqa: E402
from antisync.stats.summary import JobView, lambda_intervals  # noqa: E402


def looks(first: int, budget: int, block: int) -> list[int]:
    """As :attr:`Config.stop_looks`: ``first`` rounded up to blocks, doubling, then the budget."""
    n = min(budget, -(-first // block) * block)
    out = []
    while n < budget:
        out.append(n)
        n *= 2
    return [*out, budget]


def signs(run: np.ndarray, block: int, dbeta: float, level: float, look: bool = False) -> np.ndarray:
    """+1 / -1 / 0 per link: the sign its interval at ``level`` resolves, as the records say
    (``look=False``) or as a look of the rule counts it (``look=True``: an interval resting on
    few tail values does not count), both from :func:`antisync.stats.summary.lambda_intervals`."""
    rec, tail = estimators.lambda_block_records(
        run, np.zeros(run.shape, np.int8), np.zeros(run.shape, bool), block
    )
    nb, n_links = rec.shape[0], run.shape[1]
    view = JobView(
        graph="pool",
        edges=[str(e) for e in range(n_links)],
        betas=(),
        dbeta=dbeta,
        variant_edge=np.zeros(0, dtype=np.int64),
        variant_beta=np.zeros(0),
        rec=np.zeros((nb, 0, len(estimators.BLOCK_FIELDS))),
        rec0=np.zeros((nb, len(estimators.TAU0_FIELDS))),
        done=np.ones(nb, dtype=bool),
        tail=np.zeros((0, estimators.TAIL_BINS), dtype=np.int64),
        realizations=run.shape[0],
        lam_rec=rec,
        lam_tail=tail,
    )
    ci, thin = lambda_intervals(view, level)
    out = np.where(ci[:, 0] > 0, 1, np.where(ci[:, 1] < 0, -1, 0))
    return np.where(thin, 0, out) if look else out


def simulate(values, dbeta, budget, first, runs, seed) -> dict[str, dict]:
    """Per rule: realizations spent per run, final signs per run, as arrays."""
    mean = values.mean(axis=0)
    truth = np.where(np.abs(mean) < 1e-12, 0, np.sign(mean))
    block = max(100, -(-budget // 1000))  # the config's automatic block size at this budget
    plan = looks(first, budget, block)
    rules = {"bonferroni": look_level(len(plan)), "naive": 0.95}
    rng = np.random.default_rng(seed)
    out = {name: {"spent": [], "signs": []} for name in [*rules, "fixed"]}
    for _ in range(runs):
        run = values[rng.integers(0, values.shape[0], budget)]
        for name, level in rules.items():
            for n in plan:
                s = signs(run[:n], block, dbeta, level, look=name == "bonferroni")
                if (s != 0).all() or n == budget:
                    break
            out[name]["spent"].append(n)
            # what the file reports: the records of a plain run of n (95% intervals)
            out[name]["signs"].append(signs(run[:n], block, dbeta, 0.95))
        out["fixed"]["spent"].append(budget)
        out["fixed"]["signs"].append(signs(run, block, dbeta, 0.95))
    for d in out.values():
        d["spent"] = np.array(d["spent"])
        d["signs"] = np.array(d["signs"])
        d["false"] = (d["signs"] != 0) & (d["signs"] != truth)  # truth 0: any sign is false
    return {"plan": plan, "rules": rules, **out}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name", help="pool name (cache file <cache>/<name>.npz, see calibrate_errors.py)")
    p.add_argument("--graph", default=LOLLIPOP)
    p.add_argument("--realizations", type=int, default=2_000_000, help="pool size (made if missing)")
    p.add_argument("--budget", type=int, default=64_000)
    p.add_argument("--first-look", type=int, default=2000)
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--seed", type=int, default=1001, help="pool seed")
    p.add_argument("--draw-seed", type=int, default=11)
    p.add_argument("--method", default="finite-difference")
    p.add_argument("--integrator", default="rk4")
    p.add_argument("--dt", type=float, default=0.04)
    p.add_argument("--cache", default=str(Path(__file__).resolve().parent / ".cache"))
    p.add_argument(
        "--null",
        nargs="*",
        default=[],
        metavar="LINK",
        help="links made null: each value times a random sign (mean 0, the same heavy tail)",
    )
    args = p.parse_args()
    edges, values, dbeta = pool(args)
    flip = np.random.default_rng(args.draw_seed + 1)
    for label in args.null:
        e = edges.index(label)
        values[:, e] *= flip.choice([-1.0, 1.0], size=len(values))
        values[:, e] -= values[:, e].mean()  # exactly 0: every resolved sign of it is false
    t = time.perf_counter()
    res = simulate(values, dbeta, args.budget, args.first_look, args.runs, args.draw_seed)
    truth = values.mean(axis=0)
    print(
        f"# {args.name}: pool of {len(values):,}, {len(edges)} links; budget {args.budget:,}, looks at "
        f"{', '.join(f'{n:,}' for n in res['plan'])}; {args.runs} runs ({time.perf_counter() - t:.0f} s)\n"
    )
    print(
        "| rule | level per look | realizations spent: mean (25%-75%) | of budget "
        "| signs resolved at the end | false signs per link | runs with a false sign |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    levels = {**res["rules"], "fixed": 0.95}
    for name in ("bonferroni", "naive", "fixed"):
        d = res[name]
        q1, q3 = np.percentile(d["spent"], [25, 75])
        print(
            f"| {name} | {levels[name]:.4f} | {d['spent'].mean():,.0f} ({q1:,.0f}-{q3:,.0f}) | "
            f"{d['spent'].mean() / args.budget:.2f} | {(d['signs'] != 0).mean():.3f} | "
            f"{d['false'].mean():.4f} | {d['false'].any(axis=1).mean():.3f} |"
        )
    print(
        "\n| link | pool mean | bonferroni: resolved / false | naive: resolved / false "
        "| fixed: resolved / false |"
    )
    print("|---|---:|---:|---:|---:|")
    for e, label in enumerate(edges):
        cells = [
            f"{(res[r]['signs'][:, e] != 0).mean():.2f} / {res[r]['false'][:, e].mean():.3f}"
            for r in ("bonferroni", "naive", "fixed")
        ]
        print(f"| {label} | {truth[e]:+.4f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
