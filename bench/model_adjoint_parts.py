"""Where a model adjoint's time goes: its forward pass alone (one trajectory per thread, and on
the lanes) against the whole adjoint (forward, checkpoint replays, backward pass), per
realization, one thread.

    python bench/model_adjoint_parts.py [config] [--realizations M]

Default config: configs/ieee14_grid.yaml, 300 realizations, three rounds.
"""

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # before numba is imported
import numpy as np  # noqa: E402

from antisync.execution import dispatch  # noqa: E402
from antisync.kernels import cpu  # noqa: E402
from antisync.kernels.adjoint import link_derivatives  # noqa: E402
from antisync.kernels.model_adjoint import simulate_model_adjoint  # noqa: E402
from antisync.plan.config import load_config  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("config", nargs="?", default="configs/ieee14_grid.yaml")
ap.add_argument("--realizations", type=int, default=300)
a = ap.parse_args()
job = make_job(load_config(a.config))
dyn = job.config.dynamics
m = a.realizations
ks = np.arange(m, dtype=np.uint64)
params = dispatch.job_model_params(job, ks, job.model.targets[:1])
edge_a, edge_b, _, _ = job.tangent
edges = list(zip(edge_a.tolist(), edge_b.tolist(), strict=True))
deriv = link_derivatives(job.omega, job.csr, edges, dyn.coupling)
args = (job.config.seed, 0, m, job.csr.indptr, job.csr.indices, job.csr.weights)
nov = np.zeros((0, job.csr.weights.size))
kw = dict(dt=dyn.dt, max_steps=dyn.max_steps, integrator=dyn.integrator, threads=1)


def fwd(lanes):
    return cpu.simulate_model(*args, nov, params, lanes=lanes, **kw)


def adj():
    return simulate_model_adjoint(*args, deriv, params, dtarget=job.model.dtarget, **kw)


runs = (
    ("forward one-per-thread", lambda: fwd(0)),
    ("forward lanes", lambda: fwd(cpu.LANES)),
    ("adjoint", adj),
)
for _, f in runs:
    f()  # compiles or loads the cache
print(f"{a.config}, {m} realizations, one thread; ms per realization:")
for _ in range(3):
    out = []
    for name, f in runs:
        t = time.perf_counter()
        f()
        out.append(f"{name} {(time.perf_counter() - t) / m * 1e3:.2f}")
    print("; ".join(out))
