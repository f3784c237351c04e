"""A stiff grid to frequency locking: Rodas4 against RK4 and scipy's Radau, same starts.

    python bench/bench_implicit.py [--starts 200] [--radau-starts 20] [--threads 2]
                                   [--rtol 1e-6 --atol 1e-6] [--config configs/ieee300_grid.yaml]

The undamaged grid of ``--config`` (the IEEE 300 swing model by default) from the random starts
``0 .. starts-1`` of its seed (phases of :func:`antisync.physics.phases.phase`, frequencies 0),
until every frequency deviation is below the config's tolerance or ``t_max``:

- ``rk4``: antisync's RK4 at the config's ``dt`` (0.0005 s on IEEE 300, the stability bound),
  both CPU drivers: one trajectory per thread (``lanes=0``) and the lane driver (a lane group
  waits for its slowest start); the faster is the baseline;
- ``rodas4``: ``dynamics.integrator: rodas4`` at ``--rtol`` / ``--atol``
  (:mod:`antisync.kernels.implicit`);
- ``radau``: what a scipy user writes: ``solve_ivp(method="Radau")`` with the analytic sparse
  Jacobian, ``rtol=1e-6`` (``atol`` 1e-6), the criterion as a terminal event, serially in
  Python, on the first ``--radau-starts`` starts; rodas4 is timed alone on the same starts.

CPU per trajectory: each of the first ``--timed-starts`` starts alone on one thread, per
driver, reported for the starts that lock, those that never do (they run to ``t_max``) and all;
scipy's process time over its starts. Accuracy, per start
against rk4: equal statuses, ``|tau - tau_rk4| <= 1e-3 tau_rk4``, and ``<tau0>`` with its
standard error.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from antisync.execution.dispatch import job_model_params
from antisync.kernels import cpu, implicit
from antisync.kernels.shared import realization_ids
from antisync.physics.phases import phase
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job
from antisync.status import NOT_SYNCED, SYNCED

ROOT = Path(__file__).resolve().parent.parent


def _taus(res, dt):
    return (res.steps0 - 1 + res.frac0) * dt


def _radau(job, params, ks, seed, dt, t_max, rtol, atol):
    """scipy's Radau with the analytic sparse Jacobian: ``(status, tau, steps, cpu seconds)``
    per start ``ks`` (``params.starts``' rows when the config draws its starts around the locked
    state, ``model.start``; else the paper's phases)."""
    import scipy.sparse as sp
    from scipy.integrate import solve_ivp

    n = len(job.nodes)
    indptr, cols, w = job.csr.indptr, job.csr.indices, job.csr.weights
    rows = np.repeat(np.arange(n), np.diff(indptr))
    mass = np.broadcast_to(np.asarray(params.inertia, dtype=float), (n,))
    gamma = np.broadcast_to(np.asarray(params.damping, dtype=float), (n,))
    inert = np.flatnonzero(mass > 0)
    ni = inert.size
    lag = np.arctan2(params.sin_lag, params.cos_lag)
    p = params.freqs[0]
    tol = params.targets[0]

    def coupling(th):
        return np.bincount(rows, w * np.sin(th[cols] - th[rows] - lag), minlength=n)

    def f(t, y):
        th, nu = y[:n], y[n:]
        k = coupling(th)
        dth = (p + k) / gamma
        dth[inert] = nu
        dnu = (p[inert] + k[inert] - gamma[inert] * nu) / mass[inert]
        return np.concatenate([dth, dnu])

    def jac(t, y):
        th = y[:n]
        a = w * np.cos(th[cols] - th[rows] - lag)
        lap = sp.csr_matrix((a, (rows, cols)), shape=(n, n))
        lap = lap - sp.diags(np.asarray(lap.sum(axis=1)).ravel())
        # dk/dtheta = lap; theta' rows: first-order lap / gamma, inertial: the nu unit entries
        scale = np.where(mass > 0, 0.0, 1.0 / gamma)
        top_left = sp.diags(scale) @ lap
        top_right = sp.csr_matrix((np.ones(ni), (inert, np.arange(ni))), shape=(n, ni))
        bottom_left = sp.diags(1.0 / mass[inert]) @ lap[inert]
        bottom_right = sp.diags(-gamma[inert] / mass[inert])
        return sp.bmat([[top_left, top_right], [bottom_left, bottom_right]], format="csc")

    def deviation(t, y):
        d = f(t, y)
        dth = d[:n]
        dev = np.abs(dth - dth.mean()).max()
        if ni:
            g = dth.copy()
            g[inert] += mass[inert] / gamma[inert] * d[n:]
            dev = max(dev, np.abs(g - g.mean()).max())
        return dev - tol

    deviation.terminal = True
    deviation.direction = -1
    out = []
    starts = np.asarray(params.starts) if params.starts is not None else np.zeros((0, n))
    for r, k in enumerate(ks):
        if starts.shape[0]:
            th0 = starts[r].copy()
        else:
            th0 = np.array([phase(np.uint64(seed), np.uint64(k), i) for i in range(n)])
        y0 = np.concatenate([th0, np.zeros(ni)])
        c0 = time.process_time()
        sol = solve_ivp(f, (0.0, t_max), y0, method="Radau", jac=jac, rtol=rtol, atol=atol, events=deviation)
        cpu_s = time.process_time() - c0
        hit = sol.t_events[0]
        status, tau = (SYNCED, float(hit[0])) if hit.size else (NOT_SYNCED, t_max)
        out.append((status, tau, sol.t.size - 1, cpu_s))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "ieee300_grid.yaml")
    ap.add_argument("--starts", type=int, default=200)
    ap.add_argument("--radau-starts", type=int, default=20)
    ap.add_argument("--timed-starts", type=int, default=16, help="starts timed on one thread per driver")
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--rtol", type=float, default=implicit.DEFAULT_RTOL)
    ap.add_argument("--atol", type=float, default=implicit.DEFAULT_ATOL)
    ap.add_argument("--skip-rk4-lanes", action="store_true", help="time only the one-per-thread rk4")
    args = ap.parse_args()

    cfg = load_config(args.config)
    job = make_job(cfg)
    dyn = cfg.dynamics
    ks = realization_ids(0, args.starts, None)
    params = job_model_params(job, ks, job.model.targets[:1])
    empty = np.zeros((0, job.csr.weights.size))
    net = (cfg.seed, 0, args.starts, job.csr.indptr, job.csr.indices, job.csr.weights, empty, params)
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, {args.config.name}, "
        f"N = {len(job.nodes)}, {args.starts} starts, dt {dyn.dt}, t_max {dyn.t_max}, threads {args.threads}"
    )

    # compile (or load the cache) on two starts first
    warm = (cfg.seed, 0, 2, *net[3:7], job_model_params(job, ks[:2], job.model.targets[:1]))
    implicit.simulate_model(*warm, dt=dyn.dt, max_steps=200, threads=1)
    cpu.simulate_model(*warm, dt=dyn.dt, max_steps=200, integrator="rk4", threads=1, lanes=0)

    plan = implicit.factor_plan(job.csr.indptr, job.csr.indices)
    rod, stats = implicit.simulate_model(
        *net,
        dt=dyn.dt,
        max_steps=dyn.max_steps,
        rtol=args.rtol,
        atol=args.atol,
        threads=args.threads,
        plan=plan,
        stats=True,
    )
    rk = cpu.simulate_model(
        *net, dt=dyn.dt, max_steps=dyn.max_steps, integrator="rk4", threads=args.threads, lanes=0
    )

    # CPU per trajectory: one thread, each of the first --timed-starts starts alone, per driver
    timed = ks[: args.timed_starts]
    mx = dyn.max_steps

    def per_start(run) -> np.ndarray:
        out = []
        for k in timed:
            one = np.array([k], dtype=np.uint64)
            args1 = (cfg.seed, 0, 1, *net[3:7], job_model_params(job, one, job.model.targets[:1]))
            t0 = time.perf_counter()
            run(args1, one)
            out.append(time.perf_counter() - t0)
        return np.array(out)

    rod_t = per_start(
        lambda a, r: implicit.simulate_model(
            *a, dt=dyn.dt, max_steps=mx, rtol=args.rtol, atol=args.atol, threads=1, plan=plan, realizations=r
        )
    )
    rk_t = per_start(
        lambda a, r: cpu.simulate_model(
            *a, dt=dyn.dt, max_steps=mx, integrator="rk4", threads=1, lanes=0, realizations=r
        )
    )
    lanes_s = float("nan")
    if not args.skip_rk4_lanes:
        tnet = (cfg.seed, 0, timed.size, *net[3:7], job_model_params(job, timed, job.model.targets[:1]))
        t0 = time.perf_counter()
        cpu.simulate_model(*tnet, dt=dyn.dt, max_steps=mx, integrator="rk4", threads=1)
        lanes_s = (time.perf_counter() - t0) / timed.size

    tau_r, tau_k = _taus(rod, dyn.dt), _taus(rk, dyn.dt)
    same = rod.status0 == rk.status0
    both = (rod.status0 == SYNCED) & (rk.status0 == SYNCED)
    rel = np.abs(tau_r - tau_k)[both] / tau_k[both]
    close = rel <= 1e-3
    print(f"statuses equal: {same.sum()}/{args.starts}; differing starts: {np.flatnonzero(~same).tolist()}")
    print(
        f"|tau - tau_rk4| <= 1e-3 tau: {close.sum()}/{both.sum()} synchronized starts "
        f"(largest relative difference {rel.max():.3g}, median {np.median(rel):.3g})"
    )
    for name, tau in (("rk4", tau_k), ("rodas4", tau_r)):
        t = tau[both]
        print(f"<tau0> {name}: {t.mean():.5f} +- {t.std(ddof=1) / np.sqrt(t.size):.5f}")
    d = (tau_r - tau_k)[both]
    print(f"paired difference of <tau0>: {d.mean():.3g} +- {d.std(ddof=1) / np.sqrt(d.size):.3g}")
    print(
        f"rodas4 steps per start: accepted median {np.median(stats.accepted0):.0f} "
        f"(max {stats.accepted0.max()}), rejected median {np.median(stats.rejected0):.0f}"
    )
    locks = rk.status0[: timed.size] == SYNCED
    print(
        f"CPU s per trajectory, one thread, each of starts 0..{timed.size - 1} alone "
        f"({locks.sum()} lock, {(~locks).sum()} never do):"
    )
    for label, sel in (("that lock", locks), ("that never lock", ~locks), ("all", np.ones_like(locks))):
        if sel.any():
            a, b = rk_t[sel].mean(), rod_t[sel].mean()
            print(f"  starts {label:16s} rk4 {a:.3f}, rodas4 {b:.4f}: rk4 / rodas4 = {a / b:.1f}x")
    print(f"  (rk4 lanes, the {timed.size} starts together: {lanes_s:.3f} per trajectory)")

    if args.radau_starts:
        sub = ks[: min(args.radau_starts, timed.size)]
        rad = _radau(job, params, sub, cfg.seed, dyn.dt, dyn.t_max, 1e-6, 1e-6)
        rad_status = np.array([r[0] for r in rad])
        rad_tau = np.array([r[1] for r in rad])
        rad_t = np.array([r[3] for r in rad])
        agree = rad_status == rk.status0[: sub.size]
        ok = (rad_status == SYNCED) & (rk.status0[: sub.size] == SYNCED)
        rrel = np.abs(rad_tau - tau_k[: sub.size])[ok] / tau_k[: sub.size][ok]
        print(
            f"radau on starts 0..{sub.size - 1}: statuses equal to rk4 {agree.sum()}/{sub.size}, largest "
            f"relative tau difference {rrel.max():.3g}, steps median {np.median([r[2] for r in rad]):.0f}"
        )
        sub_locks = locks[: sub.size]
        for label, sel in (
            ("that lock", sub_locks),
            ("that never lock", ~sub_locks),
            ("all", sub_locks | True),
        ):
            if sel.any():
                a, b = rad_t[sel].mean(), rod_t[: sub.size][sel].mean()
                print(f"  starts {label:16s} radau {a:.3f}, rodas4 {b:.4f}: radau / rodas4 = {a / b:.1f}x")


if __name__ == "__main__":
    main()
