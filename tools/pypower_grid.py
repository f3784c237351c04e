"""Regenerate the shipped power-grid files from a PYPOWER case (never needed at run time).

    pip install "antisync[grids]"      # PYPOWER, this script's only extra
    python tools/pypower_grid.py case118 --capacity 10 --out configs --prefix ieee118_uniform

writes ``<prefix>.edges`` (the case's distinct branches ``from to K``, parallel circuits merged,
each a line of capacity ``K``, raw coupling), ``<prefix>_power.txt`` (net injections ``P_i = Pg_i
- Pd_i`` of bus ``i`` in per unit of the case's MVA base, in-service generators only) and
``<prefix>_inertia.txt`` (the structure-preserving model of Nishikawa and Motter, New J. Phys.
17, 015012 (2015): inertia 1 at every bus with a generator or synchronous condenser in the
case, 0 at load buses). Buses must be numbered 1..N (they are node labels: bus i is node i).
The shipped ``configs/ieee118_uniform.*`` files are exactly this script's output with the command
above (checked by ``tools/pypower_grid.py --check``); the 14-bus files predate it.

The conversion: a line's capacity ``K`` is one number for every line (the literature's
dimensionless swing-equation grids, Rohden et al., Phys. Rev. Lett. 109, 064101 (2012)), not
derived from the branch reactances; choose it from the critical coupling, which ``antisync``'s
locked-state solver finds (``antisync.physics.locked.locked_state``, docs/models.md).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

import numpy as np

SOURCE = (
    "# Source: PYPOWER 5.1.21 (https://pypi.org/project/PYPOWER/), pypower/{case}.py, converted from\n"
    "# the IEEE Common Data Format (University of Washington Power Systems Test Case Archive).\n"
    "# PYPOWER: Copyright (c) 1996-2015 Power System Engineering Research Center (PSERC) and\n"
    "# contributors, BSD 3-clause licence (see ieee14_LICENSE.txt, the same licence).\n"
)


def load_case(name: str) -> dict:
    try:
        module = importlib.import_module(f"pypower.{name}")
    except ImportError as exc:
        sys.exit(f"pypower_grid: cannot import pypower.{name} ({exc}); pip install 'antisync[grids]'")
    return getattr(module, name)()


def convert(case: dict, capacity: float) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
    """``(lines, P, inertia)`` of a PYPOWER case (see the module docstring)."""
    bus, gen, branch = case["bus"], case["gen"], case["branch"]
    n = bus.shape[0]
    if sorted(bus[:, 0].astype(int)) != list(range(1, n + 1)):
        raise SystemExit("pypower_grid: the case's buses are not numbered 1..N")
    p = -bus[:, 2].astype(float)
    machines = set()
    for g in gen:
        machines.add(int(g[0]))
        if g[7] > 0:  # in service
            p[int(g[0]) - 1] += g[1]
    p /= case["baseMVA"]
    lines = sorted({(min(int(a), int(b)), max(int(a), int(b))) for a, b in branch[:, :2]})
    inertia = np.array([1.0 if b in machines else 0.0 for b in range(1, n + 1)])
    return lines, p, inertia


def files(name: str, capacity: float, prefix: str) -> dict[str, str]:
    lines, p, inertia = convert(load_case(name), capacity)
    n = p.size
    source = SOURCE.format(case=name)
    edges = (
        f"# {name}: the {len(lines)} distinct branches (from-bus to-bus; parallel circuits merged), each a\n"
        f"# line of capacity K = {capacity:g} (raw coupling). Written by tools/pypower_grid.py.\n" + source
    )
    edges += "".join(f"{a} {b} {capacity:g}\n" for a, b in lines)
    power = (
        f"# {name}: net injection P_i = Pg_i - Pd_i of bus i = 1..{n} in per unit of the case's MVA\n"
        f"# base; the sum, {p.sum():.3f} p.u., is the line losses (antisync removes the mean).\n"
        "# Written by tools/pypower_grid.py.\n" + source
    )
    power += "".join(f"{x:.4f}\n" for x in p)
    machines = int(inertia.sum())
    mass = (
        f"# {name}: inertia m_i of bus i = 1..{n}, the structure-preserving model: 1 at the {machines}\n"
        f"# buses with a generator or synchronous condenser, 0 at the {n - machines} load buses.\n"
        "# Written by tools/pypower_grid.py.\n" + source
    )
    mass += "".join(f"{int(m)}\n" for m in inertia)
    return {f"{prefix}.edges": edges, f"{prefix}_power.txt": power, f"{prefix}_inertia.txt": mass}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", help="a PYPOWER case name, such as case118")
    ap.add_argument("--capacity", type=float, required=True, help="K of every line")
    ap.add_argument("--out", type=Path, default=Path("configs"))
    ap.add_argument("--prefix", required=True)
    ap.add_argument("--check", action="store_true", help="compare with the files in --out instead of writing")
    args = ap.parse_args()
    write_or_check(files(args.case, args.capacity, args.prefix), args.out, args.check, "pypower_grid")


def write_or_check(texts: dict[str, str], out: Path, check: bool, tool: str) -> None:
    """Write each ``{file name: text}`` into ``out``, or with ``check`` exit unless the files
    there are exactly these texts (tools/grid_case.py uses it too)."""
    differ = []
    for name, text in texts.items():
        path = out / name
        if check:
            if not path.is_file() or path.read_text() != text:
                differ.append(str(path))
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if differ:
        sys.exit(f"{tool}: differs from the conversion: " + ", ".join(differ))
    if check:
        print(f"{tool}: the shipped files are the conversion's output")


if __name__ == "__main__":
    main()
