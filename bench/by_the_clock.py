"""Every link's Lambda^KM by the clock: how many signs one run resolves after 10, 30, 60 minutes.

    python bench/by_the_clock.py configs/lesmis.yaml --minutes 10 30 60 \
        --set lambda.method=adjoint-hybrid --set 'measures=[km]'

Starts ``antisync run CONFIG`` with a realization count it should not finish, copies its output
file at each mark (the runner replaces the file atomically at every checkpoint, every 30 s, so
a copy is always a whole file), stops the run after the last mark and prints a markdown row
per mark: realizations, signs resolved by the calibrated 95% interval (what the package
reports, ``sign_resolved``) and by |Lambda| > 3 se, the split into antifragile / fragile, the
median and worst se and the share of (realization, link) pairs the hybrid replaced by secants.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def summarize(path: Path) -> dict:
    """The counts of one copied result file, from ``antisync summary --format json``."""
    out = subprocess.run(
        [sys.executable, "-m", "antisync", "summary", str(path), "--format", "json"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    recs = [r for r in json.loads(out)["records"] if r.get("lambda_km") is not None]
    lam = np.array([r["lambda_km"] for r in recs])
    se = np.array([r["lambda_km_se"] for r in recs])
    sign = np.array([r["sign_resolved"] for r in recs])
    n = np.array([r["lambda_n"] for r in recs])
    flagged = np.array([r["lambda_n_flagged"] or 0 for r in recs])
    nonzero = se > 0  # links whose damage leaves W unchanged have Lambda = 0 exactly
    z3 = np.abs(lam[nonzero]) > 3 * se[nonzero]
    return {
        "links": len(recs),
        "exact_zero": int((~nonzero).sum()),
        "realizations": int(max(r["realizations_done"] for r in recs)),
        "p_sync": recs[0]["p_sync"],
        "resolved": int((sign != 0).sum()),
        "antifragile": int((sign > 0).sum()),
        "fragile": int((sign < 0).sum()),
        "resolved_3se": int(z3.sum()),
        "se_median": float(np.median(se[nonzero])),
        "se_worst": float(se[nonzero].max()),
        "flagged": float(flagged.sum() / max(n.sum(), 1)),
        "unresolved_max_abs": float(np.abs(lam[sign == 0]).max()) if (sign == 0).any() else 0.0,
    }


def add_exact_measures(path: Path, config: str, sets: list[str]) -> None:
    """Write Lambda^xi2 and Lambda^RW of every link into the copy ``path`` (a run made with
    ``measures: [km]`` alone, so that its clock counts only the Kuramoto work): the exact
    measures are functions of the graph, computed here as the run would have computed them."""
    import h5py

    from antisync.measures.pipeline import compute_measures
    from antisync.plan.config import load_config
    from antisync.plan.jobs import make_job
    from antisync.store.layout import write_measures

    cfg = load_config(config, [*sets, "measures=[km, xi2, rw]"])
    job = make_job(cfg)
    start = time.perf_counter()
    values = compute_measures(job)
    with h5py.File(path, "r+") as f:
        group = f["jobs"][job.name]
        if "measures" not in group:
            write_measures(group, values, cfg, time.perf_counter() - start)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--minutes", type=float, nargs="+", default=[10, 30, 60])
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument(
        "--realizations",
        type=int,
        default=5_000_000,
        help="more than the run should finish by the last mark (the run's plan grows with it)",
    )
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--dir", default="/tmp/by_the_clock", help="where the copies go")
    ap.add_argument(
        "--exact-measures",
        action="store_true",
        help="add Lambda^xi2 and Lambda^RW to the last copy afterwards",
    )
    args = ap.parse_args()

    folder = Path(args.dir)
    folder.mkdir(parents=True, exist_ok=True)
    name = Path(args.config).stem
    out = folder / f"{name}.h5"
    cmd = [sys.executable, "-m", "antisync", "run", args.config, "--out", str(out), "--overwrite"]
    cmd += ["--realizations", str(args.realizations), "--threads", str(args.threads), "--quiet"]
    for s in args.sets:
        cmd += ["--set", s]
    print("#", " ".join(cmd), flush=True)
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    print(f"# {machine}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}", flush=True)
    start = time.monotonic()
    proc = subprocess.Popen(cmd)
    copies = []
    try:
        for mark in sorted(args.minutes):
            time.sleep(max(0.0, start + 60 * mark - time.monotonic()))
            if proc.poll() is not None:  # finished its realizations before this mark
                print(f"# the run ended before {mark:g} min (exit {proc.returncode})", flush=True)
                if out.exists():
                    copies.append((f"<= {mark:g} min (run complete)", out))
                break
            while not out.exists() and proc.poll() is None:  # the first checkpoint is late
                time.sleep(1)
            copy = folder / f"{name}_{mark:g}min.h5"
            shutil.copyfile(out, copy)
            copies.append((f"{mark:g} min", copy))
            print(f"# copied {copy} at {(time.monotonic() - start) / 60:.1f} min", flush=True)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()

    if not copies:
        sys.exit("the run wrote no result file")
    if args.exact_measures:
        add_exact_measures(copies[-1][1], args.config, args.sets)
    print(
        "\n| wall time | realizations | signs resolved (95% interval) | antifragile / fragile "
        "| resolved at 3 se | median / worst se | flagged | largest unresolved abs(Lambda) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for mark, copy in copies:
        s = summarize(copy)
        links = s["links"] - s["exact_zero"]
        print(
            f"| {mark} | {s['realizations']:,} | {s['resolved']} of {links} "
            f"({s['resolved'] / links:.0%}) | {s['antifragile']} / {s['fragile']} "
            f"| {s['resolved_3se']} ({s['resolved_3se'] / links:.0%}) "
            f"| {s['se_median']:.2g} / {s['se_worst']:.2g} | {s['flagged']:.2%} "
            f"| {s['unresolved_max_abs']:.2g} |",
            flush=True,
        )
    print(
        f"\n(links with Lambda = 0 exactly, left out of the counts: {s['exact_zero']}; p_sync {s['p_sync']})"
    )


if __name__ == "__main__":
    main()
