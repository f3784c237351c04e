"""Every non-bridge line of IEEE 300 at 1,000 starts (issue 42): a random sample of lines timed
with ``sync.give_up`` and projected to all of them, and the rule checked against integrating
every trajectory to ``t_max`` on the same starts.

    python bench/removal_give_up.py [--lines 16] [--starts 1000] [--check-starts 200]
                                    [--study-starts 300] [--after 20] [--band 1.0]
                                    [--rtol 1e-3] [--threads 2]

The grid is ``configs/ieee300_grid.yaml`` with ``dynamics.integrator: rodas4`` at ``--rtol`` (=
``atol``) and uniform random starts of seed 1, as ``antisync grid --removal`` integrates it
(:func:`antisync.grids.removal.line_removal`, ``--threads`` threads, wall time):

1. **timed**: ``--lines`` lines drawn at random (numpy seed ``--sample-seed``) from the non-bridge lines, at
   ``--starts`` starts, with ``sync.give_up: {after, band}``; the rule's pilot (once per run:
   the intact grid's starts without the rule and at ``after / 1.25``) timed apart, the seconds
   per trajectory after it (the audit included; the intact grid counted as one more grid) times
   ``(L + 1) x 1,000`` for all ``L`` lines, plus the pilot at 1,000 starts, in hours on this
   machine's ``--threads`` cores;
2. **checked**: the same lines on the first ``--check-starts`` starts without ``give_up`` (every
   trajectory to ``t_max = 200`` s), timed too (the same run's baseline). Each trajectory's
   status with the rule against without: a ``GAVE_UP`` must be ``NOT_SYNCED`` without it, a
   ``SYNCED`` the same with the same tau; the others are counted and listed;
3. **studied** (``--study-starts``, 0: skipped): the intact grid's first starts to the
   criterion and, separately, until every frequency deviation is within ``--band`` (the
   criterion's target raised to the band): when the starts that lock first came within the band
   (what ``--after`` must exceed) and whether any start that never locks ever did.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from antisync.execution.dispatch import job_model_params
from antisync.grids.removal import line_removal
from antisync.grids.removal_config import planned_lines, resolve_config
from antisync.kernels import implicit
from antisync.plan.jobs import make_job
from antisync.status import GAVE_UP, NOT_SYNCED, SYNCED

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "ieee300_grid.yaml")
    ap.add_argument("--lines", type=int, default=16, help="lines drawn at random and timed")
    ap.add_argument("--sample-seed", type=int, default=0, help="numpy seed of the lines drawn")
    ap.add_argument("--starts", type=int, default=1000)
    ap.add_argument("--check-starts", type=int, default=200, help="starts integrated to t_max too (0: none)")
    ap.add_argument("--study-starts", type=int, default=300, help="intact starts studied (0: none)")
    ap.add_argument("--after", type=float, default=20.0)
    ap.add_argument("--band", type=float, default=1.0)
    ap.add_argument("--rtol", type=float, default=1e-3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    args = ap.parse_args()

    dynamics = {"integrator": "rodas4", "rtol": args.rtol, "atol": args.rtol}
    common = {"dynamics": dynamics, "lambda": {"method": "finite-difference"}}
    give_up = {
        "sync": {
            "criterion": "frequency",
            "tolerance": 1e-3,
            "give_up": {"after": args.after, "band": args.band},
        }
    }
    cfg = resolve_config(args.config, common)
    every = sorted(planned_lines(cfg, None, 1.0, False))
    rng = np.random.default_rng(args.sample_seed)
    sample = [every[i] for i in sorted(rng.choice(len(every), args.lines, replace=False))]
    lines = ",".join("-".join(p) for p in sample)  # as --lines takes them
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, threads {args.threads}, "
        f"{args.config.name}: {len(every)} non-bridge lines; sample {lines}; "
        f"rodas4 rtol = atol = {args.rtol:g}; give_up after {args.after:g} s, band {args.band:g} rad/s"
    )
    # compile (or load the cache) on a tiny run first
    line_removal(
        args.config, lines=lines.split(",")[0], realizations=2, threads=args.threads, **common, **give_up
    )

    t0 = time.perf_counter()
    marks = []  # when the pilot (once per run: the intact grid without the rule) ended

    def log(message):
        if message.startswith("sync.give_up pilot"):
            marks.append(time.perf_counter())

    fast = line_removal(
        args.config, lines=lines, realizations=args.starts, threads=args.threads, log=log, **common, **give_up
    )
    took = time.perf_counter() - t0
    pilot = marks[0] - t0 if marks else 0.0
    grids = args.lines + 1
    per = (took - pilot) / (args.starts * grids)
    hours = (per * 1000 * (len(every) + 1) + pilot * 1000 / args.starts) / 3600
    n_gave = int((fast.status0 == GAVE_UP).sum() + (fast.status == GAVE_UP).sum())
    print(
        f"timed: {args.starts} starts x {grids} grids in {took:.1f} s wall, of it the pilot {pilot:.1f} s; "
        f"{1e3 * per:.2f} ms per trajectory after it (the audit included: {fast.audit}); "
        f"GAVE_UP {n_gave} of {args.starts * grids}; intact P_sync {fast.p_sync:.4f}"
    )
    print(
        f"projected: every line at 1,000 starts = the pilot at 1,000 starts + {len(every) + 1} grids "
        f"x 1,000 x {1e3 * per:.2f} ms = {hours:.2f} h"
    )

    if args.study_starts:
        _study(cfg, args.study_starts, args.band, args.threads)

    m = args.check_starts
    if not m:
        return
    t0 = time.perf_counter()
    full = line_removal(args.config, lines=lines, realizations=m, threads=args.threads, **common)
    took_full = time.perf_counter() - t0
    per_full = took_full / (m * grids)
    a = np.column_stack([fast.status0[:m], fast.status[:m]])
    b = np.column_stack([full.status0, full.status])
    ta = np.column_stack([fast.tau0[:m], fast.tau[:m]])
    tb = np.column_stack([full.tau0, full.tau])
    gave = a == GAVE_UP
    ok_gave = gave & (b == NOT_SYNCED)
    synced = (a == SYNCED) & (b == SYNCED)
    same_tau = synced & (ta == tb)
    other = ~(ok_gave | same_tau | ((a == b) & (a != SYNCED)))
    print(
        f"checked on starts 0..{m - 1} ({m * grids} trajectories): without give_up {took_full:.1f} s wall, "
        f"{1e3 * per_full:.2f} ms per trajectory ({per_full / per:.1f}x the timed run's); "
        f"GAVE_UP {int(gave.sum())}, of them NOT_SYNCED without the rule {int(ok_gave.sum())}; "
        f"SYNCED both {int(synced.sum())}, same tau {int(same_tau.sum())}; NOT_SYNCED without the rule "
        f"{int((b == NOT_SYNCED).sum())}; disagreeing {int(other.sum())}"
        + (f" at (start, grid) {np.argwhere(other).tolist()[:20]}" if other.any() else "")
    )


def _study(cfg, count: int, band: float, threads: int) -> None:
    """The intact grid's starts ``0 .. count-1`` to the criterion and to the band, Rodas4 at the
    config's tolerances: when those that lock first came within the band, and whether any start
    that never locks ever did."""
    job = make_job(cfg)
    dyn = cfg.dynamics
    rtol, atol = dyn.tolerances
    ks = np.arange(count, dtype=np.uint64)
    empty = np.zeros((0, job.csr.weights.size))
    out = {}
    for name, target in (("criterion", job.model.targets[:1]), ("band", np.array([band]))):
        params = job_model_params(job, ks, target)
        net = (cfg.seed, 0, count, job.csr.indptr, job.csr.indices, job.csr.weights, empty, params)
        res = implicit.simulate_model(
            *net, dt=dyn.dt, max_steps=dyn.max_steps, rtol=rtol, atol=atol, threads=threads
        )
        out[name] = (res.status0, (res.steps0 - 1 + res.frac0) * dyn.dt)
    locks = out["criterion"][0] == SYNCED
    within, t_band = out["band"][0] == SYNCED, out["band"][1]
    t = t_band[locks]
    print(
        f"studied: intact starts 0..{count - 1}: {locks.sum()} lock, {(~locks).sum()} never do; "
        f"those that lock came within {band:g} rad/s by {t.max():.2f} s at the latest "
        f"(p99 {np.percentile(t, 99):.2f} s, "
        f"median {np.median(t):.2f} s; all within: {bool(within[locks].all())}); of those that never lock, "
        f"{int(within[~locks].sum())} ever came within {band:g} rad/s"
    )


if __name__ == "__main__":
    main()
