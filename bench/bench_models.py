"""The models on the lane driver against the identical model's lanes, per trajectory-step.

    python bench/bench_models.py [--threads 1] [--realizations M] [--repeat 3] [--only N=6]

For each network (the paper's lollipop N = 6, the karate club N = 34, the IEEE 118-bus topology
N = 118), the same three damaged links at beta = 0.5, and each integrator, one run of:

- ``identical``: the default lane driver (:func:`antisync.kernels.cpu.simulate`), the baseline;
- ``model P=0``: the model lane driver with no frequencies, lag or inertia (the same
  trajectories, checked: the ratio is the general step's cost alone);
- ``frequencies``, ``lag``, ``inertia``: the model lane driver with natural frequencies (normal,
  sd 0.1), a phase lag of 0.3, and inertia m = 1 (damping 1), order-parameter criterion;
- ``one-per-thread``: the one-trajectory model driver (``lanes=0``) on the frequency model, what
  the models ran on before.

Realizations default per network (:data:`REALIZATIONS`) so that each timed run lasts about
0.1-1 s: at 200 realizations the N = 6 runs last ~10 ms and their ratios moved by 0.3 between
two runs. Each is timed per trajectory-step (its own total of steps over every integrated item).
A round runs every kind once, back to back, after a first round that compiles (or loads the
cache). Printed: the fastest of ``--repeat`` rounds per kind and its ratio to the fastest
``identical``, and the median and range over the rounds of each round's own ratio (the kind
against the ``identical`` run of the same round: this machine's speed drifts by 20% over
minutes, and a ratio within one round sees the least of that drift). The models' trajectories
differ from the identical model's, so only the per-step cost is compared.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from antisync.kernels import cpu, model_steps
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job

NETWORKS = {
    "lollipop N=6": "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: ['2->1', '3->4', '5->6']\n",
    "karate N=34": "graph: {kind: networkx, generator: karate_club_graph}\n"
    "edges: ['0->1', '0->31', '33->32']\n",
    "IEEE 118 N=118": "graph: {kind: edgelist, path: configs/ieee118.edges}\n"
    "edges: ['1->2', '49->69', '100->103']\n",
}
INTEGRATORS = {"euler": 0.01, "rk4": 0.04}
KINDS = ("model P=0", "frequencies", "lag", "inertia", "one-per-thread")
#: realizations per network unless --realizations says otherwise
REALIZATIONS = {"lollipop N=6": 4000, "karate N=34": 400, "IEEE 118 N=118": 200}


def _params(job, kind: str, m: int):
    n = len(job.nodes)
    targets = np.full(job.variant_weights.shape[0] + 1, (0.99 * n) ** 2)
    freqs = np.zeros((1, n))
    lag, inertia = 0.0, 0.0
    if kind == "frequencies" or kind == "one-per-thread":
        rng = np.random.default_rng(1)
        freqs = rng.normal(0.0, 0.1, (m, n))
        freqs -= freqs.mean(axis=1, keepdims=True)
    elif kind == "lag":
        lag = 0.3
    elif kind == "inertia":
        inertia = 1.0
    cl, sl = model_steps.lag_terms(lag)
    return cpu.ModelParams(freqs, cl, sl, inertia, 1.0, 0, targets)


def _steps(sim) -> int:
    return int(np.maximum(sim.steps0, 0).sum() + np.maximum(sim.steps, 0).sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--realizations", type=int, default=None, help="default: REALIZATIONS per network")
    ap.add_argument("--repeat", type=int, default=3, help="timed rounds after the first; the fastest counts")
    ap.add_argument("--only", default="", help="networks and integrators whose name contains this")
    ap.add_argument("--kinds", default="", help="comma-separated runs besides identical (default: all)")
    a = ap.parse_args()
    print(f"{platform.processor() or platform.machine()}, numba threads {a.threads}")
    kinds = [k for k in KINDS if not a.kinds or k in a.kinds.split(",")]
    head = "| network | realizations | integrator | run | steps | ns / trajectory-step | ratio to identical |"
    print(head + " per-round ratio: median (range) |")
    print("|---|---|---|---|---|---|---|---|")
    for net, text in NETWORKS.items():
        m = a.realizations or REALIZATIONS[net]
        for integ, dt in INTEGRATORS.items():
            if a.only not in f"{net} {integ}":
                continue
            job = make_job(load_config_text(text + "betas: [0.5]\n"))
            args = (1, 0, m, job.csr.indptr, job.csr.indices, job.csr.weights, job.variant_weights)
            kw = {"dt": dt, "max_steps": int(round(200 / dt)), "integrator": integ, "threads": a.threads}
            best: dict = {}
            ratios: dict = {}
            for round_ in range(1 + a.repeat):  # round 0 compiles (or loads the cache)
                t = time.perf_counter()
                ref = cpu.simulate(*args, threshold=0.99, **kw)
                runs = [("identical", _steps(ref), (time.perf_counter() - t) / _steps(ref))]
                for kind in kinds:
                    params = _params(job, kind, m)
                    lanes = 0 if kind == "one-per-thread" else cpu.LANES
                    t = time.perf_counter()
                    sim = cpu.simulate_model(*args, params, lanes=lanes, **kw)
                    runs.append((kind, _steps(sim), (time.perf_counter() - t) / _steps(sim)))
                    if kind == "model P=0":
                        assert np.array_equal(sim.steps, ref.steps) and np.array_equal(sim.steps0, ref.steps0)
                for kind, steps, per in runs if round_ else []:
                    best[kind] = (steps, min(per, best.get(kind, (0, np.inf))[1]))
                    ratios.setdefault(kind, []).append(per / runs[0][2])
            rows = [(kind, steps, per) for kind, (steps, per) in best.items()]
            base = best["identical"][1]
            for kind, steps, per in rows:
                q = ratios[kind]
                spread = f"{np.median(q):.2f} ({min(q):.2f}-{max(q):.2f})"
                ns = f"{per * 1e9:.1f}"
                cells = (net, m, f"{integ} dt {dt}", kind, steps, ns, f"{per / base:.2f}", spread)
                print("| " + " | ".join(map(str, cells)) + " |")


if __name__ == "__main__":
    main()
