"""Regenerate the shipped IEEE 39-bus (New England) grid with dynamic data (never needed at run time).

    pip install "antisync[grids]"          # PYPOWER (numpy, scipy), this script's only extra
    python tools/ieee39.py --out configs    # writes configs/ieee39_grid.*
    python tools/ieee39.py --check          # the shipped files are this script's output

The reduction is the structure-preserving model (Bergen and Hill, IEEE Trans. PAS-100, 25 (1981);
Nishikawa and Motter, New J. Phys. 17, 015012 (2015), Sec. 2.3) without the generators' internal
nodes: every bus is a node,

    m_i theta_i'' + D_i theta_i' = P_i + sum_j K_ij sin(theta_j - theta_i),

time in seconds, angles in radians, powers in per unit of the case's 100 MVA base, frequencies in
rad/s relative to omega_R = 2 pi 60 rad/s:

- ``m_i = 2 H_i / omega_R`` at the ten generator buses (30..39), ``H_i`` in seconds on the 100
  MVA base: the classic values of Athay, Podmore and Virmani, IEEE Trans. PAS-98, 573 (1979), as
  tabulated by Pai, "Energy Function Analysis for Power System Stability" (Kluwer, 1989),
  G1 at bus 39 (the New York interconnection aggregated into one machine) 500 s
  (:data:`H_PAI`). When ANDES is
  installed the script checks them against ANDES's ieee39 case (``andes/cases/ieee39/
  ieee39_full.xlsx``, GENROU ``M = 2 H``: Pai's values on a 1000 MVA base, ``H_100 = 5 M``) and
  stops on a difference.
- ``m_i = 0`` at the 29 other buses (first order; Bergen and Hill's frequency-dependent loads).
- Damping: neither source gives one (Pai's and ANDES's D are 0, the damping there comes from the
  machines' windings, which this model does not have). Chosen here: ``D_i = m_i * GAMMA_GEN``
  at generators (every machine's swing decays at the same rate ``GAMMA_GEN / 2``) and
  ``D_LOAD`` at the other buses (a load's frequency response, d P / d omega, in p.u. per rad/s).
- ``K_ij = |V_i| |V_j| B_ij`` with ``B_ij = Im(Y_ij) > 0`` the off-diagonal susceptance of the bus
  admittance matrix (transformer taps included, parallel circuits summed, line charging and
  conductances dropped: the lossless approximation), ``|V_i|`` the magnitudes of PYPOWER's
  solved AC power flow (``runpf``) of case39.
- ``P_i = Pg_i - Pd_i`` of the solved power flow (the slack's ``Pg`` includes the losses, so
  ``sum P`` is the losses, which antisync removes with the mean).

Files: ``ieee39_grid.edges`` (``from to K``), ``ieee39_grid_power.txt``,
``ieee39_grid_inertia.txt``, ``ieee39_grid_damping.txt`` (one number per bus 1..39).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

#: Inertia constants H (s) on the 100 MVA system base, generator bus -> H: Athay et al. (1979),
#: Pai (1989). G1 (bus 39) is the New York interconnection aggregated into one machine.
H_PAI = {30: 42.0, 31: 30.3, 32: 35.8, 33: 28.6, 34: 26.0, 35: 34.8, 36: 26.4, 37: 24.3, 38: 34.5, 39: 500.0}
#: The system frequency (Hz) and omega_R = 2 pi f (rad/s).
F_R = 60.0
OMEGA_R = 2 * math.pi * F_R
#: Generator damping over inertia, D_i / m_i (1/s): a swing decays as exp(-GAMMA_GEN t / 2).
GAMMA_GEN = 1.0
#: Damping of the first-order (load and transfer) buses, p.u. power per rad/s.
D_LOAD = 1.0

SOURCE = (
    "# Source: PYPOWER 5.1.21 (https://pypi.org/project/PYPOWER/), pypower/case39.py (network and\n"
    "# dispatch, solved by runpf), BSD 3-clause (see ieee39_LICENSE.txt); inertia constants of\n"
    "# Athay, Podmore and Virmani, IEEE Trans. PAS-98, 573 (1979), as in M. A. Pai, Energy Function\n"
    "# Analysis for Power System Stability (1989), checked against ANDES's ieee39 case.\n"
    "# Written by tools/ieee39.py (the structure-preserving reduction: see its docstring).\n"
)


def solved_case() -> dict:
    try:
        from pypower.api import ppoption, runpf
        from pypower.case39 import case39
    except ImportError as exc:
        sys.exit(f"ieee39: cannot import PYPOWER ({exc}); pip install 'antisync[grids]'")
    result, ok = runpf(case39(), ppoption(VERBOSE=0, OUT_ALL=0))
    if not ok:
        sys.exit("ieee39: PYPOWER's power flow of case39 did not converge")
    return result


def check_andes() -> str:
    """Compare :data:`H_PAI` with ANDES's ieee39 case when ANDES is installed: its GENROU sheet
    lists ``M = 2 H`` per machine, the same numbers as Pai's table on a 1000 MVA base (``H_100 =
    5 M``). (ANDES rates the machines at their own ``Sn``, 836 to 1684 MVA, so its own model's
    inertias differ from Pai's by up to 40%; the numbers taken here are Pai's.)"""
    try:
        import andes
        import openpyxl
    except ImportError:
        return "ANDES not installed: inertia constants not cross-checked"
    path = Path(andes.__file__).parent / "cases" / "ieee39" / "ieee39_full.xlsx"
    if not path.is_file():
        return f"ANDES {andes.__version__}: no {path.name}: not cross-checked"
    rows = list(openpyxl.load_workbook(path, read_only=True)["GENROU"].iter_rows(values_only=True))
    col = {name: k for k, name in enumerate(rows[0])}
    found = {int(r[col["bus"]]): 5.0 * float(r[col["M"]]) for r in rows[1:] if r[col["bus"]] is not None}
    if found.keys() != H_PAI.keys() or any(abs(found[b] - H_PAI[b]) > 1e-9 for b in H_PAI):
        sys.exit(f"ieee39: ANDES's inertia constants differ from Pai's table: {found}")
    return f"ANDES {andes.__version__} {path.name}: M = 2 H of the 10 machines = Pai's table / 5"


def convert(case: dict):
    """``(lines, K, P, m, D)`` of the solved case39 (module docstring)."""
    from pypower.makeYbus import makeYbus

    bus, gen, branch = case["bus"], case["gen"], case["branch"]
    n = bus.shape[0]
    if list(bus[:, 0].astype(int)) != list(range(1, n + 1)):
        sys.exit("ieee39: the case's buses are not numbered 1..N in order")
    base = case["baseMVA"]
    ibus, ibranch = bus.copy(), branch.copy()
    ibus[:, 0] -= 1  # makeYbus numbers buses from 0
    ibranch[:, :2] -= 1
    ybus, _, _ = makeYbus(base, ibus, ibranch)
    ybus = ybus.toarray()
    vm = bus[:, 7]
    p = -bus[:, 2].astype(float)
    for g in gen:
        if g[7] > 0:
            p[int(g[0]) - 1] += g[1]
    p /= base
    lines = sorted({(min(int(a), int(b)), max(int(a), int(b))) for a, b in branch[:, :2]})
    k = np.array([vm[a - 1] * vm[b - 1] * ybus[a - 1, b - 1].imag for a, b in lines])
    if (k <= 0).any():
        sys.exit("ieee39: a line with a non-positive susceptance")
    m = np.array([2 * H_PAI[b] / OMEGA_R if b in H_PAI else 0.0 for b in range(1, n + 1)])
    d = np.where(m > 0, m * GAMMA_GEN, D_LOAD)
    return lines, k, p, m, d


def files(prefix: str = "ieee39_grid") -> dict[str, str]:
    lines, k, p, m, d = convert(solved_case())
    n = p.size
    head = (
        "# IEEE 39-bus New England system, structure-preserving swing equation (tools/ieee39.py).\n" + SOURCE
    )
    edges = (
        f"# The {len(lines)} distinct branches (from to K): K_ij = |V_i||V_j| B_ij in p.u. of 100 MVA,\n"
        "# B_ij = Im(Ybus_ij), |V| of the solved AC power flow (raw coupling).\n" + head
    )
    edges += "".join(f"{a} {b} {x:.6g}\n" for (a, b), x in zip(lines, k, strict=True))
    power = (
        f"# P_i = Pg_i - Pd_i of bus i = 1..{n}, p.u. of 100 MVA, from the solved power flow; the sum,\n"
        f"# {p.sum():.4f} p.u., is the losses (antisync removes the mean).\n" + head
    )
    power += "".join(f"{x + 0.0:.6f}\n" for x in p)  # + 0.0: no "-0.000000"
    mass = (
        f"# m_i = 2 H_i / omega_R (s^2/rad in p.u.), omega_R = 2 pi {F_R:g} rad/s, H_i of Pai's table on\n"
        f"# 100 MVA at the 10 generator buses 30..39; 0 at the {n - 10} other buses (first order).\n" + head
    )
    mass += "".join(f"{x:.8g}\n" for x in m)
    damping = (
        f"# D_i (p.u. power per rad/s): m_i * {GAMMA_GEN:g}/s at the 10 generators (not in the sources,\n"
        f"# chosen: every swing decays at {GAMMA_GEN / 2:g}/s), {D_LOAD:g} at the other buses (loads).\n"
        + head
    )
    damping += "".join(f"{x:.8g}\n" for x in d)
    return {
        f"{prefix}.edges": edges,
        f"{prefix}_power.txt": power,
        f"{prefix}_inertia.txt": mass,
        f"{prefix}_damping.txt": damping,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("configs"))
    ap.add_argument("--prefix", default="ieee39_grid")
    ap.add_argument("--check", action="store_true", help="compare with the files in --out instead of writing")
    args = ap.parse_args()
    print(f"ieee39: {check_andes()}")
    differ = []
    for name, text in files(args.prefix).items():
        path = args.out / name
        if args.check:
            if not path.is_file() or path.read_text() != text:
                differ.append(str(path))
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if differ:
        sys.exit("ieee39: differs from the conversion: " + ", ".join(differ))
    if args.check:
        print("ieee39: the shipped files are the conversion's output")


if __name__ == "__main__":
    main()
