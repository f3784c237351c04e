"""``sync.give_up`` on lower-damping grids: does the rule's pilot refuse where a locking start
would be stopped, and where it passes, is any start miscounted?

    python bench/give_up_low_damping.py CASE FACTOR LINES STARTS T_MAX
    python bench/give_up_low_damping.py ieee39 0.2 6-7 100 200     # refused by the pilot
    python bench/give_up_low_damping.py ieee118 0.2 1-2 50 200     # refused by the pilot
    python bench/give_up_low_damping.py ieee39 0.5 6-7 100 200     # passes; 0 miscounted

``configs/<CASE>_grid.yaml`` with generator damping ``D = FACTOR m`` (load buses as shipped),
Rodas4 at rtol = atol = 1e-4, seed 1: the removal of ``LINES`` at ``STARTS`` starts integrated
to ``T_MAX`` without the rule, then with ``sync.give_up: {after: 20, band: 1}``; prints the
pilot's refusal, or the audit's counts and how many starts that lock without the rule are not
synchronized with it (must be 0).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from antisync.grids.errors import GridError
from antisync.grids.removal import line_removal
from antisync.status import GAVE_UP, SYNCED

CONFIGS = Path(__file__).resolve().parent.parent / "configs"


def _numbers(path: Path) -> np.ndarray:
    rows = path.read_text().splitlines()
    return np.array([float(x) for row in rows if not row.startswith("#") for x in row.split()])


def main() -> None:
    case, factor, lines, m, t_max = (
        sys.argv[1],
        float(sys.argv[2]),
        sys.argv[3],
        int(sys.argv[4]),
        float(sys.argv[5]),
    )
    inertia = _numbers(CONFIGS / f"{case}_grid_inertia.txt")
    damping = np.where(inertia > 0, factor * inertia, _numbers(CONFIGS / f"{case}_grid_damping.txt"))
    model = {
        "frequencies": {"file": f"{case}_grid_power.txt"},
        "inertia": {"file": f"{case}_grid_inertia.txt"},
        "damping": damping.tolist(),
    }
    run = dict(
        lines=lines,
        realizations=m,
        seed=1,
        model=model,
        dynamics={"integrator": "rodas4", "rtol": 1e-4, "atol": 1e-4, "t_max": t_max},
        **{"lambda": {"method": "finite-difference"}},
    )
    rule = {"sync": {"criterion": "frequency", "tolerance": 1e-3, "give_up": {"after": 20.0, "band": 1.0}}}
    config = CONFIGS / f"{case}_grid.yaml"
    start = time.perf_counter()
    full = line_removal(config, **run)
    locks0, locks = int((full.status0 == SYNCED).sum()), int((full.status == SYNCED).sum())
    print(
        f"{case}, D = {factor:g} m, lines {lines}, {m} starts: without the rule {locks0} intact and {locks} "
    )
    print(f"  damaged starts lock ({time.perf_counter() - start:.1f} s)")
    start = time.perf_counter()
    try:
        cut = line_removal(config, **run, **rule)
    except GridError as exc:
        print(f"  with the rule: refused: {exc} ({time.perf_counter() - start:.1f} s)")
        return
    a = np.column_stack([cut.status0, cut.status])
    b = np.column_stack([full.status0, full.status])
    miscounted = int(((b == SYNCED) & (a != SYNCED)).sum())
    print(f"  with the rule: {int((a == GAVE_UP).sum())} GAVE_UP, audit {cut.audit}")
    print(f"  miscounted (lock without the rule, not synchronized with it): {miscounted} of {b.size}")


if __name__ == "__main__":
    main()
