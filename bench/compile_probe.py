"""Cold compile time of one kernel family: the first call of a tiny run on an empty numba cache.

    NUMBA_CACHE_DIR=$(mktemp -d) python bench/compile_probe.py items

``items``: the one-trajectory model reference (``cpu.simulate_model(lanes=0)``), ``lanes``: the
model's parallel RK4 lane driver (``lanes=16``), ``rodas``: Rodas4's item driver, ``adjoint``:
the model adjoint, ``trip``: the trip kernels (IEEE 14, one line). The first call's time is numba
compiling the family (its run is milliseconds; the second call shows it); run each in a fresh
process with an empty ``NUMBA_CACHE_DIR``, or the cache answers instead of the compiler. Used to
choose how a parallel loop's body is written (bench/RESULTS.md, "The test suite on two cores, a
tenth time").

``--numba-copy-propagate`` compiles with numba's own copy propagation instead of
antisync._numba_compile's (the same result, a slower fixed point): the pair, each on its own
empty cache, is that module's measurement::

    for f in lanes adjoint trip; do for o in "" --numba-copy-propagate; do
      NUMBA_CACHE_DIR=$(mktemp -d) python bench/compile_probe.py $f $o; done; done

With ``lanes``, the line also gives the SHA-1 of the driver's LLVM IR (addresses and long
numbers masked): the same with either copy propagation.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from antisync.execution.dispatch import job_model_params
from antisync.kernels import cpu
from antisync.plan.config import load_config_text
from antisync.plan.jobs import make_job

ROOT = Path(__file__).resolve().parent.parent
MODEL = (
    "graph: {kind: lollipop, nodes: 6, path: 3}\nedges: all\nbetas: [0.5]\n"
    "model: {frequencies: [0.1, 0.2, 0, 0, 0, -0.3], inertia: 1.0}\n"
    "sync: {criterion: frequency, tolerance: 0.01}\n"
    "dynamics: {dt: 0.01, t_max: 5, integrator: rk4}\nrealizations: 4\n"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("family", choices=["items", "lanes", "rodas", "adjoint", "trip"])
    parser.add_argument("--numba-copy-propagate", action="store_true", help="numba's own copy propagation")
    args = parser.parse_args()
    which = args.family
    if args.numba_copy_propagate:
        from numba.core import ir_utils
        from numba.parfors import parfor

        from antisync import _numba_compile

        ir_utils.copy_propagate = parfor.copy_propagate = _numba_compile._numba_copy_propagate
    job = make_job(load_config_text(MODEL))
    ks = np.arange(4, dtype=np.uint64)
    params = job_model_params(job, ks, job.model.targets)
    net = (1, 0, 0, job.csr.indptr, job.csr.indices, job.csr.weights)

    def call():
        if which in ("items", "lanes"):
            return cpu.simulate_model(
                *net,
                job.variant_weights,
                params,
                dt=0.01,
                max_steps=500,
                integrator="rk4",
                lanes=0 if which == "items" else 16,
                realizations=ks,
            )
        if which == "rodas":
            from antisync.kernels import implicit

            return implicit.simulate_model(
                *net, job.variant_weights, params, dt=0.01, max_steps=500, realizations=ks
            )
        if which == "adjoint":
            from antisync.kernels.adjoint import link_derivatives
            from antisync.kernels.model_adjoint import simulate_model_adjoint

            index = {v: i for i, v in enumerate(job.nodes)}
            deriv = link_derivatives(job.omega, job.csr, [(index[a], index[b]) for a, b in job.edges])
            one = params._replace(targets=params.targets[:1])
            return simulate_model_adjoint(
                *net, deriv, one, dt=0.01, max_steps=500, integrator="rk4", realizations=ks
            )
        import antisync

        return antisync.grid.trip(ROOT / "configs" / "ieee14_grid.yaml", lines="1-2", t_clear=0.1, t_max=1.0)

    t = time.perf_counter()
    call()
    first = time.perf_counter() - t
    t = time.perf_counter()
    call()
    second = time.perf_counter() - t
    whose = "numba's" if args.numba_copy_propagate else "antisync's"
    line = f"{which} ({whose} copy propagation): first call {first:.1f} s (compiling), second {second:.3f} s"
    if which == "lanes":
        line += f"; LLVM IR {llvm_digest()}"
    print(line)


def llvm_digest() -> str:
    """The model's RK4 lane driver's LLVM IR: its length and SHA-1, addresses and long numbers
    (object ids in names) masked."""
    import hashlib
    import re

    from antisync.kernels.lanes import LaneFeatures, make_lane_driver

    text = "".join(make_lane_driver(LaneFeatures(model=True, rk4=True)).inspect_llvm().values())
    text = re.sub(r"\d{6,}", "N", re.sub(r"0x[0-9a-f]+", "0x", text))
    return f"{len(text):,} characters, SHA-1 {hashlib.sha1(text.encode()).hexdigest()[:12]}"


if __name__ == "__main__":
    main()
