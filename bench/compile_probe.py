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
antisync._numba_compile's (the same result, a slower fixed point), ``--numba-inline`` with
numba's own ``InlineWorker.inline_ir`` (the same result, the callee's scope copied once per
block), ``--numba-live`` with numba's own ``analysis.compute_live_map`` (the same sets, unions of
names instead of integers); the runs, each on its own empty cache, are that module's
measurement::

    for f in lanes adjoint trip; do for o in "" "--numba-copy-propagate --numba-inline --numba-live"; do
      NUMBA_CACHE_DIR=$(mktemp -d) python bench/compile_probe.py $f $o; done; done

The line also gives a digest of the LLVM IR of every function the first call compiled (each
function's text, sorted; addresses, hash-numbered constants and numba's version counters in
names masked, which differ between any two processes; the probe runs itself under
``PYTHONHASHSEED=0``, as numba names some temporaries in the order of a set of strings): the
same with numba's passes and antisync's. With ``lanes``, also the lane driver's own digest
(its function alone).
"""

from __future__ import annotations

import argparse
import os
import sys
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
    if os.environ.get("PYTHONHASHSEED") != "0":
        # numba names some temporaries in the order it iterates sets of strings: one hash seed,
        # so that two processes compiling the same code write the same LLVM IR
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, "PYTHONHASHSEED": "0"})
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("family", choices=["items", "lanes", "rodas", "adjoint", "trip"])
    parser.add_argument("--numba-copy-propagate", action="store_true", help="numba's own copy propagation")
    parser.add_argument("--numba-inline", action="store_true", help="numba's own InlineWorker.inline_ir")
    parser.add_argument("--numba-live", action="store_true", help="numba's own analysis.compute_live_map")
    args = parser.parse_args()
    which = args.family
    from numba.core import analysis, inline_closurecall, ir_utils
    from numba.parfors import parfor

    from antisync import _numba_compile

    if args.numba_copy_propagate:
        ir_utils.copy_propagate = parfor.copy_propagate = _numba_compile._numba_copy_propagate
    if args.numba_inline:
        inline_closurecall.InlineWorker.inline_ir = _numba_compile._numba_inline_ir
    if args.numba_live:
        live = _numba_compile._numba_compute_live_map
        analysis.compute_live_map = ir_utils.compute_live_map = parfor.compute_live_map = live
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
    whose = ", ".join(
        f"{'numba' if own else 'antisync'}'s {what}"
        for what, own in (
            ("copy propagation", args.numba_copy_propagate),
            ("inlining", args.numba_inline),
            ("liveness", args.numba_live),
        )
    )
    line = f"{which} ({whose}): first call {first:.1f} s (compiling), second {second:.3f} s"
    line += f"; LLVM IR of {every_llvm_digest()}"
    if which == "lanes":
        line += f"; the lane driver's {llvm_digest()}"
    print(line)


def _masked(text: str) -> str:
    """LLVM IR without what differs between two processes compiling the same code: addresses,
    constants numbered by a string's hash (``@.bytes.-1234567``) and numba's version counters
    (``B4v118``: the order helpers were first compiled in)."""
    import re

    text = re.sub(r"0x[0-9a-f]+", "0x", text)
    text = re.sub(r"-?\d{6,}", "N", text)
    return re.sub(r"B\d+v\d+", "Bv", text)


def every_llvm_digest() -> str:
    """Every compiled numba function's LLVM IR in this process, each function's text masked by
    :func:`_masked`, sorted: how many, their length, and the SHA-1 of the whole."""
    import gc
    import hashlib

    from numba.core.registry import CPUDispatcher

    texts = sorted(
        _masked(text)
        for o in gc.get_objects()
        if isinstance(o, CPUDispatcher)
        for text in o.inspect_llvm().values()
    )
    whole = "".join(texts)
    digest = hashlib.sha1(whole.encode()).hexdigest()[:12]
    return f"{len(texts)} functions, {len(whole):,} characters, SHA-1 {digest}"


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
