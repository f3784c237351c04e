"""The kernels whose arguments became groups, timed on one thread, with a digest of each result:
Rodas4 on IEEE 300 (8 starts, rtol = atol = 1e-4), the model's one-trajectory driver and its
adjoint on IEEE 14 (100 realizations), the window objective of a 40-node design (dense and
sparse). Best of 3 after a warm-up. To compare two trees, run it in each, alternating::

    git worktree add /tmp/old <commit>
    (cd /tmp/old && PYTHONPATH=/tmp/old python /path/to/bench/ab_groups.py)
    PYTHONPATH=. python bench/ab_groups.py

Equal digests: the same bits (bench/RESULTS.md, "Arguments in groups").
"""

import hashlib
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
import numpy as np

from antisync.execution import dispatch
from antisync.kernels import cpu, implicit
from antisync.kernels.adjoint import link_derivatives
from antisync.kernels.model_adjoint import simulate_model_adjoint
from antisync.optimize.window import all_pairs, window_objective
from antisync.plan.config import load_config
from antisync.plan.jobs import make_job


def digest(*arrs):
    h = hashlib.sha1()
    for a in arrs:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:10]


cases = []
job = make_job(load_config("configs/ieee300_grid.yaml"))
ks = np.arange(8, dtype=np.uint64)
params = dispatch.job_model_params(job, ks, job.model.targets[:1])
nov = np.zeros((0, job.csr.weights.size))
a300 = (job.config.seed, 0, 8, job.csr.indptr, job.csr.indices, job.csr.weights, nov, params)
plan = implicit.factor_plan(job.csr.indptr, job.csr.indices)
dyn = job.config.dynamics


def rodas():
    r = implicit.simulate_model(
        *a300, dt=dyn.dt, max_steps=dyn.max_steps, rtol=1e-4, atol=1e-4, threads=1, plan=plan
    )
    return digest(r.status0, r.steps0, r.frac0)


cases.append(("rodas4 IEEE300 8 starts", rodas))
job14 = make_job(load_config("configs/ieee14_grid.yaml"))
m = 100
ks14 = np.arange(m, dtype=np.uint64)
p14 = dispatch.job_model_params(job14, ks14, job14.model.targets[:1])
ea, eb, _, _ = job14.tangent
deriv = link_derivatives(
    job14.omega, job14.csr, list(zip(ea.tolist(), eb.tolist(), strict=True)), job14.config.dynamics.coupling
)
a14 = (job14.config.seed, 0, m, job14.csr.indptr, job14.csr.indices, job14.csr.weights)
d14 = job14.config.dynamics
kw = dict(dt=d14.dt, max_steps=d14.max_steps, integrator=d14.integrator, threads=1)


def fwd():
    r = cpu.simulate_model(*a14, np.zeros((0, job14.csr.weights.size)), p14, lanes=0, **kw)
    return digest(r.status0, r.steps0, r.frac0)


def adj():
    r = simulate_model_adjoint(*a14, deriv, p14, dtarget=job14.model.dtarget, **kw)
    return digest(r.status0, r.steps0, r.frac0, r.dtau)


cases.append(("model one-per-thread IEEE14 100", fwd))
cases.append(("model adjoint IEEE14 100", adj))
rng = np.random.default_rng(0)
n = 40
freqs = rng.normal(0, 0.5, n)
freqs -= freqs.mean()
links = all_pairs(n)
x = rng.uniform(0, 0.2, links.shape[0])
starts = rng.uniform(0, 2 * np.pi, (4, n))


def win_dense():
    r = window_objective(freqs, links, x, starts=starts, t_window=5.0, dt=0.01)
    return digest(np.array([r.value]), r.grad)


cases.append(("window dense N=40", win_dense))
lk = np.array([(i, (i + 1) % n) for i in range(n)] + [(i, (i + 7) % n) for i in range(n)])
xs = rng.uniform(0.5, 1.5, lk.shape[0])


def win_sparse():
    r = window_objective(freqs, lk, xs, starts=starts, t_window=5.0, dt=0.01)
    return digest(np.array([r.value]), r.grad)


cases.append(("window sparse N=40", win_sparse))
for name, f in cases:
    d = f()
    best = 1e9
    for _ in range(3):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    print(f"{name:34s} {best * 1e3:9.1f} ms  {d}", flush=True)
