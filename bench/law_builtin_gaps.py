"""A law against the built-in kernels, per realization: tau0, F = tau0 / tau(dbeta) and Lambda,
same integrator and steps (issue 61's agreement; tests/test_laws.py holds the bounds).

    python bench/law_builtin_gaps.py

The paper's model (``kuramoto``) on the lollipop and the karate club, the swing equation
(``swing``) on the karate club with injections, inertia and damping per node, and IEEE 39
(``configs/ieee39_grid.yaml``'s data) written as the law ``POWER_GRID`` of tests/test_laws.py
(generators beside first-order buses, frequency locking); four damaged links at dbeta 0.01.
Printed per case: the largest relative gap of tau0 and of F (interpolated times), whether the
paper's Lambda ``(tau0 / tau(dbeta) - 1) / dbeta`` on grid times is identical, and the largest
gap of Lambda from interpolated times, absolute and relative (unbounded where a realization's
Lambda is near 0).
"""

from __future__ import annotations

import sys
from pathlib import Path

import networkx as nx
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import test_laws as T  # noqa: E402  (the tests' laws and networks, not copied here)

from antisync.execution.dispatch import job_model_params  # noqa: E402
from antisync.kernels.core import CRIT_FREQUENCY  # noqa: E402
from antisync.kernels.law import LawParams, simulate_law  # noqa: E402
from antisync.kernels.model_steps import ModelParams  # noqa: E402
from antisync.laws.spec import Law, read_law  # noqa: E402
from antisync.plan.config import load_config  # noqa: E402
from antisync.plan.jobs import make_job  # noqa: E402
from antisync.status import SYNCED  # noqa: E402

DBETA = 0.01
LINKS = [0, 3, 5, 8]


def _gaps(name, model, law, seed, m, csr, integrator, dt, steps) -> None:
    args = (seed, 0, m, csr.indptr, csr.indices, csr.weights, T._damaged(csr, LINKS, DBETA))
    want = T._builtin(args, model, integrator, dt, steps)
    got = simulate_law(*args, law, dt=dt, max_steps=steps, integrator=integrator)
    assert (got.status == want.status).all() and (got.status0 == want.status0).all()
    ok0 = want.status0 == SYNCED
    ok = ok0[:, None] & (want.status == SYNCED)
    tau0 = [T._tau(r)[ok0] for r in (got, want)]
    f = [(T._tau(r)[:, None] / (r.steps - 1 + r.frac))[ok] for r in (got, want)]
    paper = [((r.steps0[:, None] / r.steps - 1) / DBETA)[ok] for r in (got, want)]
    lam = [(x - 1) / DBETA for x in f]
    print(
        f"| {name} | {integrator} | {ok.sum()} | {np.max(np.abs(tau0[0] - tau0[1]) / tau0[1]):.2g} "
        f"| {np.max(np.abs(f[0] - f[1]) / f[1]):.2g} | {'yes' if np.array_equal(*paper) else 'NO'} "
        f"| {np.max(np.abs(lam[0] - lam[1])):.2g} | {np.max(np.abs(lam[0] - lam[1]) / np.abs(lam[1])):.2g} |"
    )


def main() -> None:
    print("| law, network | integrator | pairs | tau0 gap | F gap | paper's Lambda same | Lambda abs | rel |")
    print("|---|---|---|---|---|---|---|---|")
    for gname, g in (("lollipop", nx.lollipop_graph(3, 3)), ("karate", nx.karate_club_graph())):
        nx.set_edge_attributes(g, 1.0, "weight")
        _, csr = T._csr(g)
        n = g.number_of_nodes()
        targets = np.full(1 + len(LINKS), (0.99 * n) ** 2)
        model = ModelParams(np.zeros((1, n)), 1.0, 0.0, 0.0, 1.0, 0, targets)
        law = LawParams(T.KURAMOTO, np.zeros((1, n)), targets)
        for integrator in ("euler", "rk4", "rodas4"):
            _gaps(f"kuramoto, {gname}", model, law, 7, 32, csr, integrator, 0.01, 20000)
    csr, p, m, gamma = T._karate_swing()
    targets = np.full(1 + len(LINKS), (0.95 * p.size) ** 2)
    model = ModelParams(p[None, :], 1.0, 0.0, m, gamma, 0, targets)
    law = LawParams(read_law("swing"), np.vstack([p, m, gamma]), targets)
    for integrator in ("euler", "rk4", "rodas4"):
        _gaps("swing, karate", model, law, 3, 32, csr, integrator, 0.01, 20000)
    cfg = load_config(ROOT / "configs" / "ieee39_grid.yaml")
    job = make_job(cfg)
    grid = job_model_params(job, np.arange(12), np.repeat(job.model.targets[:1], 1 + len(LINKS)))
    generator = (grid.inertia > 0).astype(float)
    values = np.vstack([grid.freqs[0], np.where(generator > 0, grid.inertia, 1.0), grid.damping, generator])
    law = LawParams(Law.from_mapping(T.POWER_GRID), values, grid.targets, criterion=CRIT_FREQUENCY)
    _gaps("IEEE 39", grid, law, cfg.seed, 12, job.csr, "rk4", cfg.dynamics.dt, 40000)
    _gaps("IEEE 39", grid, law, cfg.seed, 12, job.csr, "euler", 5e-4, 80000)


if __name__ == "__main__":
    main()
