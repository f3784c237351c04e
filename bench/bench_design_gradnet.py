"""GradNet's Kuramoto example (Mikaberidze and Taylor, arXiv 2509.18279) with antisync's design.

    python bench/bench_design_gradnet.py [--steps 600] [--dt 0.04] [--markdown out.md]

The problem, as GradNet's ``examples/2_kuramoto.ipynb`` sets it (details and sources in the
docstring of :mod:`antisync.optimize.window`): N = 100 oscillators, ``omega = linspace(0, 1,
N)``, ``d theta_i/dt = omega_i + sum_j A_ij sin(theta_j - theta_i)`` (no K/N), every pair
free, ``A`` symmetric and nonnegative with ``sum_ij A_ij = 2 N`` (mean weighted degree 2, one
total-sum budget: ``sum_{i<j} A_ij = N``), uniform initial weights, all phases 0 at t = 0,
maximize the mean of r(t) over t in [0, 5]; 600 Adam steps.

antisync: :func:`antisync.optimize.window.design_window` (projected Adam on the trapezoid time
average of r along fixed-step RK4, exact discrete adjoint gradient), run twice: with its
default scalar second moment and with textbook per-coordinate Adam. The final weights are
then checked independently: scipy ``solve_ivp`` DOP853 at rtol 1e-10 (atol 1e-12) with the
integral of r carried as an extra state (the time average), and GradNet's own measure, the
plain mean of r at ``linspace(0, 5, 150)``, from the dense output.

GradNet itself runs in a separate interpreter (never a dependency of antisync): the one named
by ``$GRADNET_PYTHON``, else ``/tmp/gradnet-venv/bin/python`` if it exists (made with
``python3 -m venv /tmp/gradnet-venv && /tmp/gradnet-venv/bin/pip install gradnet``), else the
comparison is skipped with a note. It runs this file with ``--gradnet-child`` under
``/usr/bin/time -v``: GradNet's example code as its notebook has it (same model, grid, loss,
``GradNet(...)`` and ``fit(...)`` arguments) except ``logger=False`` and no checkpoints (the
notebook logs to TensorBoard and writes a checkpoint every step; timing the optimization
alone). Its final adjacency comes back and gets the same independent check.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

N = 100
T_WINDOW = 5.0
BUDGET_PER_NODE = 2.0


def gradnet_child(steps: int, out: str) -> None:
    """GradNet's example (run inside GradNet's own environment): JSON on stdout, A to ``out``."""
    import torch
    from gradnet import GradNet, fit, integrate_ode

    omega = torch.linspace(0, 1, N)
    gn = GradNet(
        num_nodes=N,
        budget=BUDGET_PER_NODE * N,
        rand_init_weights=False,
        delta_sign="nonnegative",
        final_sign="free",
        strict_budget=True,
    )

    def rhs(t, theta, adj, om):
        s, c = torch.sin(theta), torch.cos(theta)
        return om + c * (adj @ s) - s * (adj @ c)

    def loss_fn(model):
        tt = torch.linspace(0, T_WINDOW, 150)
        _, theta = integrate_ode(model, f=rhs, x0=torch.zeros(N), tt=tt, f_kwargs={"om": omega})
        r_mean = torch.abs(torch.mean(torch.exp(1j * theta), dim=1)).mean()
        return 1 - r_mean, {"r": r_mean}

    start = time.perf_counter()
    fit(
        gn=gn,
        loss_fn=loss_fn,
        num_updates=steps,
        optim_cls=torch.optim.Adam,
        optim_kwargs={"lr": 1, "betas": (0.9, 0.999)},
        device="cpu",
        logger=False,
        verbose=False,
    )
    wall = time.perf_counter() - start
    _, measures = loss_fn(gn)
    np.save(out, gn.to_numpy().astype(np.float64))
    from importlib.metadata import version

    print(
        json.dumps(
            {
                "wall_s": wall,
                "mean_r_own": float(measures["r"]),
                "torch": torch.__version__,
                "gradnet": version("gradnet"),
                "torch_threads": torch.get_num_threads(),
            }
        )
    )


def independent_check(adj: np.ndarray, omega: np.ndarray) -> dict:
    """Time-averaged r (DOP853, rtol 1e-10, integral as a state) and GradNet's 150-point mean."""
    from scipy.integrate import solve_ivp

    n = omega.size

    def rhs(t, z):
        th = z[:n]
        s, c = np.sin(th), np.cos(th)
        return np.append(omega + c * (adj @ s) - s * (adj @ c), np.abs(np.exp(1j * th).mean()))

    sol = solve_ivp(
        rhs, (0.0, T_WINDOW), np.zeros(n + 1), method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True
    )
    grid = np.linspace(0.0, T_WINDOW, 150)
    r_grid = np.abs(np.exp(1j * sol.sol(grid)[:n]).mean(axis=0))
    return {
        "time_avg": float(sol.y[-1, -1] / T_WINDOW),
        "mean150": float(r_grid.mean()),
        "r_end": float(r_grid[-1]),
        "rhs_evals": int(sol.nfev),
    }


def run_gradnet(steps: int) -> dict | None:
    """GradNet's example in its own interpreter, or None (with the reason printed)."""
    python = os.environ.get("GRADNET_PYTHON") or "/tmp/gradnet-venv/bin/python"
    if not Path(python).exists():
        print(f"GradNet: skipped (no interpreter at {python}; set GRADNET_PYTHON or make /tmp/gradnet-venv)")
        return None
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "adj.npy")
        cmd = [python, str(Path(__file__).resolve()), "--gradnet-child", "--steps", str(steps), "--out", out]
        timer = ["/usr/bin/time", "-v"] if Path("/usr/bin/time").exists() else []
        start = time.perf_counter()
        proc = subprocess.run(timer + cmd, capture_output=True, text=True, cwd=tmp)
        process_wall = time.perf_counter() - start
        if proc.returncode != 0:
            print(f"GradNet: failed (exit {proc.returncode}); last output:\n{proc.stderr[-2000:]}")
            return None
        info = json.loads(proc.stdout.strip().splitlines()[-1])
        info["adj"] = np.load(out)
    info["process_wall_s"] = process_wall
    for line in proc.stderr.splitlines():
        if "Maximum resident set size" in line:
            info["max_rss_mb"] = int(line.split(":")[-1]) / 1024
        if "Percent of CPU this job got" in line:
            info["cpu_percent"] = line.split(":")[-1].strip()
    return info


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (
        f"{platform.platform()}, {cpu}, os.cpu_count() = {os.cpu_count()}, Python {platform.python_version()}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--dt", type=float, default=0.04, help="RK4 step of the design (default 0.04)")
    parser.add_argument(
        "--lr", type=float, default=None, help="Adam step in weight units (default: design_window's)"
    )
    parser.add_argument("--skip-gradnet", action="store_true")
    parser.add_argument("--skip-textbook", action="store_true", help="skip the per-coordinate Adam run")
    parser.add_argument("--markdown", help="also write the results as markdown to this file")
    parser.add_argument("--gradnet-child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.gradnet_child:
        gradnet_child(args.steps, args.out)
        return

    import numba

    from antisync.optimize.budget import Budget
    from antisync.optimize.window import all_pairs, design_window, window_objective

    omega = np.linspace(0.0, 1.0, N)
    links = all_pairs(N)
    budget = Budget.of(BUDGET_PER_NODE * N / 2, len(links))  # sum_{i<j} A_ij = N <=> sum_ij A_ij = 2N
    starts = np.zeros((1, N))

    def to_adj(x):
        adj = np.zeros((N, N))
        adj[links[:, 0], links[:, 1]] = x
        adj[links[:, 1], links[:, 0]] = x
        return adj

    print(f"machine: {machine()}; numba {numba.__version__}, numpy {np.__version__} (1 thread)")
    start = time.perf_counter()
    window_objective(omega[:12], links[:5], np.ones(5), starts=starts[:, :12], t_window=0.1, dt=0.05)
    window_objective(omega[:40], all_pairs(40), np.ones(780), starts=starts[:, :40], t_window=0.1, dt=0.05)
    print(f"compile / load of the kernels: {time.perf_counter() - start:.1f} s (not in the wall times below)")

    uniform = independent_check(to_adj(budget.uniform()), omega)
    print(f"uniform initial weights: time-averaged r {uniform['time_avg']:.6f}")

    rows = []
    modes = ["global"] + ([] if args.skip_textbook else ["coordinate"])
    results = {}
    for mode in modes:
        d = design_window(
            omega, links, budget, starts=starts, t_window=T_WINDOW, dt=args.dt, steps=args.steps, lr=args.lr,
            second_moment=mode,
        )  # fmt: skip
        check = independent_check(to_adj(d.x), omega)
        results[mode] = (d, check)
        name = "antisync, scalar 2nd moment (default)" if mode == "global" else "antisync, textbook Adam"
        print(
            f"{name}: {args.steps} steps, RK4 dt {d.dt:g} ({d.n_steps} steps over [0, {T_WINDOW:g}]), "
            f"wall {d.wall_s:.2f} s ({1e3 * d.wall_s / max(1, args.steps):.1f} ms/step)\n"
            f"    design's own mean r (trapezoid on the RK4 grid) {d.mean_r[-1]:.9f}\n"
            f"    independent DOP853 rtol 1e-10: time-averaged r {check['time_avg']:.9f} "
            f"(|difference| {abs(check['time_avg'] - d.mean_r[-1]):.1e}), "
            f"150-point mean (GradNet's measure) {check['mean150']:.6f}\n"
            f"    links with weight > 1e-6: {np.sum(d.x > 1e-6)}, largest weight {d.x.max():.3f}"
        )
        rows.append((name, d.wall_s, check["time_avg"], check["mean150"], int(np.sum(d.x > 1e-6))))

    gradnet = None if args.skip_gradnet else run_gradnet(args.steps)
    if gradnet is not None:
        adj = 0.5 * (gradnet["adj"] + gradnet["adj"].T)
        check = independent_check(adj, omega)
        gradnet["check"] = check
        print(
            f"GradNet {gradnet['gradnet']} (torch {gradnet['torch']}, {gradnet['torch_threads']} threads, "
            f"dopri5 rtol=atol=1e-4, float32): {args.steps} steps, fit wall {gradnet['wall_s']:.2f} s "
            f"(whole process {gradnet['process_wall_s']:.1f} s, "
            f"max RSS {gradnet.get('max_rss_mb', float('nan')):.0f} MB, "
            f"CPU {gradnet.get('cpu_percent', '?')})\n"
            f"    its own printed measure (150-point mean, float32) {gradnet['mean_r_own']:.6f}\n"
            f"    independent DOP853 rtol 1e-10: time-averaged r {check['time_avg']:.9f}, "
            f"150-point mean {check['mean150']:.6f}; links with weight > 1e-6: "
            f"{int(np.sum(adj[np.triu_indices(N, 1)] > 1e-6))}, largest {adj.max():.3f}"
        )
        rows.append(
            (
                f"GradNet {gradnet['gradnet']} (torch, {gradnet['torch_threads']} threads)",
                gradnet["wall_s"],
                check["time_avg"],
                check["mean150"],
                int(np.sum(adj[np.triu_indices(N, 1)] > 1e-6)),
            )
        )
        ratio = gradnet["wall_s"] / results["global"][0].wall_s
        print(f"wall-time ratio GradNet / antisync (default): {ratio:.1f}x")

    if args.markdown:
        lines = [
            f"Machine: {machine()}; numba {numba.__version__}. antisync design: RK4 dt {args.dt:g}, "
            f"{args.steps} projected Adam steps, 1 thread.",
            "",
            "| run | wall (s) | time-averaged r (DOP853 1e-10) | 150-point mean r | links > 1e-6 |",
            "|---|---|---|---|---|",
        ]
        lines += [f"| {a} | {b:.2f} | {c:.6f} | {d:.6f} | {e} |" for a, b, c, d, e in rows]
        if gradnet is not None:
            lines += ["", f"GradNet / antisync wall-time ratio: {ratio:.1f}x"]
        Path(args.markdown).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
