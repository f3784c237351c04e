"""Compile antisync's kernel families once, split over the cores: the step before the tests.

A fresh clone has no compiled kernels; numba compiles each family the first time a process
meets it and caches it on disk (antisync/_numba_cache.py). Under pytest-xdist the two workers
meet the same families at about the same time and both compile them. Here each family is
compiled by exactly one process: the identical oscillators' families in one, the models' in
the other, side by side; the workers then load every kernel from the cache.

Each group runs small real jobs through :func:`antisync.run` (the same calls the tests make,
so the same types and the same cache entries). Nothing here is checked: the tests check.

    python tools/warm_kernels.py            # both groups, in parallel; prints the wall times
    python tools/warm_kernels.py identical  # one group in this process
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

LOLLIPOP = {"kind": "lollipop", "nodes": 6, "path": 3}
BASE = {"graph": LOLLIPOP, "edges": ["2->1", "2->3"], "betas": [0.5], "realizations": 32, "block_size": 16}
FREQS = {"frequencies": [0.3, -0.1, -0.15, 0.2, -0.1, -0.15]}

#: (overrides of :data:`BASE`) per run, by group
GROUPS = {
    "identical": [
        {"dynamics": {"dt": 0.01, "t_max": 60}},
        {"dynamics": {"dt": 0.01, "t_max": 60, "precision": "float32"}},
        {"dynamics": {"integrator": "rk4", "dt": 0.04, "t_max": 60}},
        {"dynamics": {"dt": 0.01, "t_max": 60}, "lambda": {"method": "adjoint"}},
        {"dynamics": {"integrator": "rk4", "dt": 0.04, "t_max": 60}, "lambda": {"method": "adjoint-hybrid"}},
        {"dynamics": {"dt": 0.01, "t_max": 60}, "lambda": {"method": "hybrid"}},
        {"dynamics": {"dt": 0.01, "t_max": 60}, "lambda": {"method": "orbit"}},
        {"dynamics": {"dt": 0.01, "t_max": 60}, "measures": ["km", "xi2", "rw", "linear"]},
    ],
    "models": [
        {"dynamics": {"dt": 0.01, "t_max": 60}, "model": FREQS},
        {"dynamics": {"integrator": "rk4", "dt": 0.02, "t_max": 60}, "model": {**FREQS, "phase_lag": 0.2}},
        {
            "dynamics": {"integrator": "rk4", "dt": 0.01, "t_max": 60},
            "model": {**FREQS, "inertia": 0.5},
            "sync": {"criterion": "frequency", "tolerance": 0.002},
        },
        {
            "dynamics": {"integrator": "rk4", "dt": 0.02, "t_max": 60},
            "model": FREQS,
            "lambda": {"method": "adjoint"},
        },
        {"dynamics": {"dt": 0.01, "t_max": 60}, "model": FREQS, "lambda": {"method": "adjoint"}},
        {
            "dynamics": {"integrator": "rodas4", "dt": 0.01, "t_max": 60},
            "model": {**FREQS, "inertia": 0.5},
            "sync": {"criterion": "frequency", "tolerance": 0.002},
        },
    ],
}


def run_group(name: str) -> None:
    import antisync

    with tempfile.TemporaryDirectory() as tmp:
        for i, overrides in enumerate(GROUPS[name]):
            antisync.run({**BASE, **overrides}, output=Path(tmp) / f"{name}{i}.h5")


def main(argv: list[str]) -> int:
    if argv:
        run_group(argv[0])
        return 0
    start = time.perf_counter()
    procs = {
        name: subprocess.Popen([sys.executable, __file__, name], env=os.environ.copy()) for name in GROUPS
    }
    failed = [name for name, p in procs.items() if p.wait() != 0]
    print(
        f"warm_kernels: {', '.join(GROUPS)} compiled in {time.perf_counter() - start:.0f} s", file=sys.stderr
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
