"""A user's law against the built-in kernels it rewrites, per trajectory-step, and its compile time.

    python bench/bench_laws.py [--threads 2] [--repeat 3] [--integrator euler] [--no-compile]
                               [--criterion frequency]

The paper's first-order Kuramoto model written as the law ``kuramoto`` (natural frequencies
omega: 0) and the built-in model kernels with the same network and starts, on the lollipop (N =
6), the karate club (N = 34) and a random 3-regular graph of N = 1,000 nodes, RK4 at dt 0.01 for
a fixed number of steps (the target ``R`` is out of reach: every item runs ``--steps`` steps;
with ``--criterion frequency`` the frequency tolerance, every step's deviations computed).
Timed per trajectory-step, in the same round, back to back, against:

- ``builtin lanes``: :func:`antisync.kernels.cpu.simulate_model`, the SIMD lane driver every
  model run uses (the competent baseline: 2 x VEC trajectories stepped together per thread);
- ``builtin one``: the same kernels one trajectory per item (``lanes=0``), the layout the law's
  generated driver has.

The law's RK4 steps its circle form (``(cos theta, sin theta)``, as the built-in kernels do:
:func:`antisync.kernels.law.circle_form`) on lane vectors (``law``: 16 trajectories per
thread, :data:`antisync.kernels.law.LAW_LANES`) or one trajectory per item (``law one``);
``law on theta`` is its RK4 on the angle itself (``circle=False``, the steps the adjoint
differentiates), with a sine per node and stage.

The law's cold compile (a fresh cache folder, a new process) and its load from the cache are
timed too. Prints the fastest of ``--repeat`` rounds per kind and each round's ratio.
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import subprocess
import sys
import tempfile
import time

import networkx as nx
import numpy as np

from antisync.kernels import cpu
from antisync.kernels.law import LawParams, simulate_law
from antisync.kernels.model_steps import ModelParams
from antisync.laws import read_law
from antisync.physics import coupling, graphs

GRAPHS = {
    "lollipop N=6": (lambda: nx.lollipop_graph(3, 3), 2048),
    "karate N=34": (nx.karate_club_graph, 512),
    "3-regular N=1000": (lambda: nx.random_regular_graph(3, 1000, seed=1), 32),
}

COMPILE = """
import time, numpy as np
t = time.perf_counter()
from antisync.kernels.law import LawParams, simulate_law
from antisync.laws import read_law
law = read_law(LAW)
ip = np.array([0, 1, 2, 3]); ix = np.array([1, 2, 0])
values = np.ones((len(law.params), 3))
simulate_law(1, 0, 2, ip, ix, np.ones(3), np.zeros((0, 3)), LawParams(law, values, np.full(1, 8.0)),
             dt=0.01, max_steps=10, integrator=INTEGRATOR)
print(time.perf_counter() - t)
"""


def _compile_times(law: str, integrator: str) -> tuple[float, float]:
    """A fresh cache folder: the compile of ``law``'s ``integrator`` drivers, then their load."""
    code = COMPILE.replace("INTEGRATOR", repr(integrator)).replace("LAW", repr(law))
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "ANTISYNC_LAW_CACHE": folder}
        cold = float(
            subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            ).stdout
        )
        warm = float(
            subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            ).stdout
        )
    return cold, warm


def unit_network(g):
    """``(csr, n, never)``: ``g`` at unit weights, normalized coupling, and a target ``R`` out
    of reach (``R = |sum e^{i theta}|^2 <= n^2``): every item runs all its steps."""
    nx.set_edge_attributes(g, 1.0, "weight")
    om = graphs.omega_matrix(g)
    csr = coupling.to_csr(coupling.coupling_matrix(om, "normalized"), pattern=om > 0)
    n = om.shape[0]
    return csr, n, np.full(1, 2.0 * n * n)


def time_rounds(kinds: dict, reference: str, repeat: int, per: int) -> tuple[dict, dict]:
    """Each of ``kinds`` (name: a call) once to compile, then ``repeat`` rounds back to back:
    ``(best, ratios)``, the fastest ns per ``per`` units of each and, per round, ``reference``'s
    time over each one's."""
    for f in kinds.values():
        f()  # compile or load
    best = {k: np.inf for k in kinds}
    ratios = {k: [] for k in kinds}
    for _ in range(repeat):
        t = {}
        for k, f in kinds.items():
            t0 = time.perf_counter()
            f()
            t[k] = (time.perf_counter() - t0) / per * 1e9
            best[k] = min(best[k], t[k])
        for k in kinds:
            ratios[k].append(t[reference] / t[k])
    return best, ratios


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--integrator", choices=("rk4", "euler"), default="rk4")
    ap.add_argument("--no-compile", action="store_true", help="skip the compile timings")
    ap.add_argument(
        "--criterion",
        choices=("order-parameter", "frequency"),
        default="order-parameter",
        help="frequency: every step's deviations too (the law's lanes by the scalar per lane)",
    )
    args = ap.parse_args()
    frequency = args.criterion == "frequency"
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, threads {args.threads}")
    # Stuart-Landau (two states, no circle form), the swing equation (RK4 on its circle form's lane
    # vectors, always hoisted) and the second harmonic (the same, hoisted or per link)
    for name in () if args.no_compile else ("stuart-landau", "swing", "second-harmonic"):
        for integrator in ("euler", "rk4", "rodas4"):
            cold, warm = _compile_times(name, integrator)
            print(
                f"law {name}, {integrator}: cold compile + first call {cold:.1f} s, "
                f"from the cache {warm:.2f} s (new processes)"
            )
    law = read_law("kuramoto")
    for name, (make, m) in GRAPHS.items():
        csr, n, never = unit_network(make())
        if frequency:
            never = np.full(1, -1.0)  # every deviation below -1: never
        vw = np.zeros((0, csr.weights.size))
        common = (5, 0, m, csr.indptr, csr.indices, csr.weights, vw)
        clock = {"dt": 0.01, "max_steps": args.steps, "threads": args.threads}
        builtin = ModelParams(np.zeros((1, n)), 1.0, 0.0, 0.0, 1.0, int(frequency), never)
        kinds = {
            "law": functools.partial(
                simulate_law,
                *common,
                LawParams(law, np.zeros((1, n)), never, criterion=int(frequency)),
                integrator=args.integrator,
                **clock,
            ),
            "law one": functools.partial(
                simulate_law,
                *common,
                LawParams(law, np.zeros((1, n)), never, criterion=int(frequency)),
                integrator=args.integrator,
                lanes=0,
                **clock,
            ),
            "law on theta": functools.partial(
                simulate_law,
                *common,
                LawParams(law, np.zeros((1, n)), never, criterion=int(frequency)),
                integrator=args.integrator,
                circle=False,
                **clock,
            ),
            "builtin lanes": functools.partial(
                cpu.simulate_model, *common, builtin, integrator=args.integrator, **clock
            ),
            "builtin one": functools.partial(
                cpu.simulate_model, *common, builtin, integrator=args.integrator, lanes=0, **clock
            ),
        }
        best, ratios = time_rounds(kinds, "law", args.repeat, m * args.steps)
        for k in kinds:
            r = np.median(ratios[k])
            print(
                f"{name:18s} {k:14s} {best[k]:10.1f} ns/trajectory-step   law / this: {r:.2f} "
                f"(rounds {min(ratios[k]):.2f}-{max(ratios[k]):.2f})"
            )


if __name__ == "__main__":
    main()
