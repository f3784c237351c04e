"""A user's law compiled into batch kernels: generated Numba code, once per law, cached on disk.

:class:`~antisync.laws.spec.Law` gives a node law and an edge law in sympy. This module writes
them as Python source over the CSR loops every kernel of antisync uses (``indptr``,
``indices``, one weight per in-link), appends the generic drivers of :data:`_DRIVERS` (Euler,
RK4 and Rodas4 from the realization's random phases to the order-parameter or the frequency
criterion), and
imports the file: numba compiles it once and caches the machine code beside it, keyed by the
law's text and antisync's sources, so a second process loads it in about a second. Nothing is
generated per node: the compile time does not depend on the network.

The generated functions (state ``y`` flat, state ``k`` of node ``i`` at ``y[k n + i]``;
per-node parameters ``P`` of shape ``(n_params, n)``):

- ``law_rhs(y, w, indptr, indices, P, out, G)``: ``out = f(y)``, each node's coupling inputs
  summed over its in-links (sympy's common subexpressions hoisted; a separable edge law from
  per-node factors, ``G`` their scratch of ``KH`` rows: :func:`_rhs_source`);
- ``law_order(y, f, P, n)``: ``(R, dR/dt)``, ``R = |sum_i e^{i phase_i}|^2``, with the phase's
  rate ``grad(phase) . f`` (the cubic Hermite crossing of :mod:`antisync.kernels.core` needs it);
- ``law_start(seed, k, P, y, n)``: the start of realization ``k`` from the paper's
  counter-based phases (:func:`antisync.physics.phases.phase`), or (``P`` with the two rows of
  :func:`with_start` below its own ``NROWS``) from phases around a locked state's, as
  ``model.start`` draws the built-in model's (:func:`antisync.plan.model.start_phases`);
- ``law_devs(y, f, w, indptr, indices, P, D)``: the frequency criterion's quantities and their
  rates, each minus its mean over the nodes (:func:`_frequency_source`);
- ``law_jac(y, w, indptr, indices, P, jq)``: the Jacobian's entries on the expanded pattern of
  :func:`expanded_pattern` (each node's ``S x S`` block with itself and with each in-neighbour),
  by the chain rule through the coupling inputs: what Rodas4 factors.

A law whose phase is one of its states, read (with every other angle) only through ``sin`` and
``cos``, also gets its *circle form* (:func:`circle_form`): each angle stored as ``(cos theta,
sin theta)``, its right-hand side a polynomial in them (``circle_law_rhs``, no sine or cosine
per step), ``R`` read off the phase's pair. RK4 steps it, each step projected back to the circle
(``circle_sync``): the built-in kernels' RK4, to the last bits on the paper's model. Euler,
Rodas4 and the adjoint step the angles themselves.

The drivers keep the statuses and the crossing times of the built-in model kernels: ``tau =
(steps - 1 + frac) dt``, the crossing on the cubic Hermite interpolant of ``R`` over the step
(RK4, Rodas4) or its straight line (Euler), a state that is not finite never synchronized.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np

from antisync import _numba_cache
from antisync.kernels import law_support as support
from antisync.kernels.core import CRIT_ORDER, VEC
from antisync.kernels.shared import (
    PathwiseResult,
    SimResult,
    Threads,
    check_collapsed,
    realization_ids,
    todo_mask,
    unset_outputs,
)
from antisync.laws.spec import Law, Symbolic
from antisync.status import SYNCED
from antisync.types import RODAS4_ATOL, RODAS4_RTOL

__all__ = [
    "Circle",
    "CompiledLaw",
    "LawParams",
    "cache_root",
    "check_step",
    "circle_form",
    "compile_law",
    "expanded_pattern",
    "generate_source",
    "integrate_law_trips",
    "jacobian",
    "node_phases",
    "simulate_law",
    "simulate_law_adjoint",
    "starts",
    "with_derived",
    "with_edges",
    "with_start",
]

#: bumped when the generated code's layout changes (old files are then never read)
GENERATOR = 20


class LawParams(NamedTuple):
    """A law's run constants: ``values`` ``(n_params, n)`` (the law's parameters per node, in
    the order of ``law.params``), ``targets`` ``(V + 1,)`` (base first: ``R = (r N)^2`` at the
    threshold, or the frequency tolerance), Rodas4's tolerances and the criterion
    (:data:`~antisync.kernels.core.CRIT_ORDER`, or :data:`~antisync.kernels.core.CRIT_FREQUENCY`:
    every deviation of the law's ``frequency`` quantities from their mean below the target)."""

    law: Law
    values: np.ndarray
    targets: np.ndarray
    rtol: float = RODAS4_RTOL
    atol: float = RODAS4_ATOL
    criterion: int = CRIT_ORDER
    drawn: tuple = ()
    """``(k, spec)`` per parameter drawn per realization (its row of ``values`` unused): ``spec``
    a distribution as ``model.frequencies`` takes it (:func:`parameter_blocks`)."""
    edges: np.ndarray | None = None
    """``(n_edge_params, nnz)``: the law's edge parameters per in-link, in the CSR order of the
    weights (None: the law has none)."""
    start: np.ndarray | None = None
    """``(2, n)``: ``model.start``'s phases around a locked state, the state's phase per node
    and the width (every start phase ``phi_i = center_i + width (2 u_i - 1)``); None: the
    paper's uniform phases."""


class CompiledLaw(NamedTuple):
    """The generated module's functions (module docstring) and the file they came from."""

    rhs: object
    order: object
    start: object
    jac: object
    hoisted: int
    """``KH``: the rows of ``law_rhs``' scratch ``G`` (``(KH, n)``)."""
    items: object
    """Euler's and RK4's item (``law_item_explicit``: one item's start, integration and record;
    every item of a batch in parallel by :func:`~antisync.kernels.law_support.each_item`)."""
    items_circle: object
    """RK4's item on the law's circle form (``law_item_circle``)."""
    items_circle_euler: object
    """Euler's item on the law's circle form (``law_item_circle_euler``)."""
    items_lanes_euler: object
    """Euler's on lane vectors (None where ``items_lanes`` is)"""
    items_lanes: object
    """RK4's on lane vectors (``law_items_lanes``; None where the circle form is missing or
    not arithmetic: :func:`vectorizable`)"""
    items_rodas4: object
    """Rodas4's item (``law_item_rodas4``)."""
    vjp: object
    adjoint: object
    circle: tuple
    """whether RK4 runs on the law's circle form (:func:`circle_form`) to the order-parameter
    criterion and to the frequency criterion"""
    path: Path
    items_lanes_frequency: object = None
    """RK4's on lane vectors to the frequency criterion (``law_items_lanes_frequency``; None
    where ``items_lanes`` is; used where ``circle[1]``)"""
    items_lanes_euler_frequency: object = None
    """Euler's on lane vectors to the frequency criterion (``law_items_lanes_euler_frequency``;
    None where ``items_lanes_frequency`` is)"""
    adjoint_freq: object = None
    """the adjoint's realization to the frequency criterion (``law_adjoint_item_freq``)"""
    devs: object = None
    """``law_devs``: the frequency criterion's deviations and their rates (``(2 KF, n)``)"""
    kf: int = 0
    """``KF``: the number of the frequency criterion's quantities"""
    trips: object = None
    """``(law_one_trip_rk4, law_one_trip_rodas4)``: one line trip from an operating point
    (every trip in parallel: :func:`integrate_law_trips`)"""


def cache_root() -> Path:
    """Where generated laws are written: ``$ANTISYNC_LAW_CACHE``, else
    ``$XDG_CACHE_HOME/antisync/laws`` (``~/.cache/antisync/laws``)."""
    env = os.environ.get("ANTISYNC_LAW_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "antisync" / "laws"


# -- code generation ----------------------------------------------------------------------------


def _printer():
    from sympy.printing.pycode import PythonCodePrinter

    class _Printer(PythonCodePrinter):
        """Python's ``math`` for numba; ``abs`` and ``sign`` spelt so numba types them."""

        def _print_Abs(self, expr):
            return f"abs({self._print(expr.args[0])})"

        def _print_sign(self, expr):
            a = self._print(expr.args[0])
            return f"(0.0 if {a} == 0 else math.copysign(1.0, {a}))"

    return _Printer({"fully_qualified_modules": True, "standard": "python3"})


def _block(exprs, targets, indent: str, printer, accumulate: bool = False) -> list[str]:
    """Lines assigning ``exprs`` to ``targets`` (``+=`` with ``accumulate``) with sympy's common
    subexpressions hoisted into ``c0, c1, ...`` locals."""
    import sympy

    subs, reduced = sympy.cse(list(exprs), symbols=sympy.numbered_symbols("c"), optimizations="basic")
    lines = [f"{indent}{sym} = {printer.doprint(e)}" for sym, e in subs]
    op = "+=" if accumulate else "="
    lines += [f"{indent}{t} {op} {printer.doprint(e)}" for t, e in zip(targets, reduced, strict=True)]
    return lines


def _loads(exprs, sym, indent: str, fmt: str) -> list[str]:
    """``name = <fmt(k)>`` for each symbol of ``sym`` some expression of ``exprs`` reads."""
    used = set().union(*(getattr(e, "free_symbols", set()) for e in exprs)) if exprs else set()
    return [f"{indent}{s} = {fmt.format(k=k)}" for k, s in enumerate(sym) if s in used]


def _node_loads(exprs, sym) -> list[str]:
    """Node ``i``'s states and parameters that ``exprs`` read (inside ``for i in range(n)``)."""
    return _loads(exprs, sym.x, "        ", "y[{k} * n + i]") + _loads(exprs, sym.p, "        ", "P[{k}, i]")


def _link_loop(exprs, sym) -> list[str]:
    """The loop over node ``i``'s in-links ``q`` (neighbour ``j``, weight ``w``) and the
    neighbour's states and parameters and the link's edge parameters that ``exprs`` read (the
    link's ``k``-th at ``P[n_params + k, q]``: :func:`parameter_blocks`)."""
    head = [
        "        for q in range(indptr[i], indptr[i + 1]):",
        "            j = indices[q]",
        "            w = wq[q]",
    ]
    return (
        head
        + _loads(exprs, sym.xj, "            ", "y[{k} * n + j]")
        + _loads(exprs, sym.pj, "            ", "P[{k}, j]")
        + _edge_loads(exprs, sym, "            ")
    )


def _edge_loads(exprs, sym, indent: str) -> list[str]:
    """The link ``q``'s edge parameters that ``exprs`` read (rows after the per-node ones), and
    the functions of them that :func:`with_edges` computes once per run (rows after those)."""
    derived = _derived_symbols(sym)
    return _loads(exprs, sym.e, indent, f"P[{len(sym.p)} + {{k}}, q]") + _loads(
        exprs, derived, indent, f"P[{len(sym.p) + len(sym.e)} + {{k}}, q]"
    )


def _derived_symbols(sym) -> tuple:
    """``ed0, ed1, ...``: one symbol per function of the edge parameters in ``sym.derived``."""
    import sympy

    return tuple(sympy.Symbol(f"ed{k}", real=True) for k in range(len(sym.derived)))


def _link_part(w, sym):
    """A separated term's link factor ``W`` with each function of the edge parameters alone
    (``cos(alpha)``) read as its row (:func:`with_edges`): no sine per link and step."""
    return w.xreplace(dict(zip(sym.derived, _derived_symbols(sym), strict=True))) if sym.derived else w


def _factors_of(sym) -> list:
    """The functions of the edge parameters alone (not a bare parameter, not a number) among
    the factors of ``sym``'s separated link parts ``W`` (:func:`_separate`)."""
    import sympy

    own = set(sym.e)
    out = []
    _, pairs, _, _ = _hoisting(sym)
    for w, _ in pairs:
        for f in sympy.Mul.make_args(w):
            if f.free_symbols and f.free_symbols <= own and not f.is_Symbol and f not in out:
                out.append(f)
    return out


def with_derived(sym):
    """``sym`` with :attr:`~antisync.laws.spec.Symbolic.derived`: the functions of the edge
    parameters alone that its separated edge law and its circle form's multiply a link's
    weight by (``w cos(alpha)``, ``w sin(alpha)`` of ``w sin(theta_j - theta_i - alpha)``), in a
    fixed order; :func:`with_edges` computes them per link once per run."""
    if not sym.e:
        return sym
    factors = _factors_of(sym)
    circle = circle_form(sym)
    if circle is not None:
        factors += [f for f in _factors_of(circle.sym) if f not in factors]
    return dataclasses.replace(sym, derived=tuple(factors))


@functools.lru_cache(maxsize=64)
def _derived_functions(law: Law) -> tuple:
    import sympy

    sym = with_derived(law.symbolic())
    return tuple(sympy.lambdify(list(sym.e), f, "numpy") for f in sym.derived)


def _edge_rows(law: Law, edges: np.ndarray | None) -> np.ndarray | None:
    """The kernels' per-link rows: the edge parameters ``edges`` ``(n_edge_params, nnz)`` and
    below them each function of them in :func:`with_derived`'s order, computed once here
    rather than per link and step; None without edge parameters."""
    if edges is None or not len(edges):
        return None
    edges = np.ascontiguousarray(edges, dtype=np.float64)
    rows = [np.broadcast_to(f(*edges), edges.shape[1:]) for f in _derived_functions(law)]
    return np.vstack([edges, *rows]) if rows else edges


#: the most neighbour sums a hoisted edge law may need (more: the law is evaluated per link)
MAX_HOISTED = 12


def _separate(h, sym):
    """``h`` as ``sum_t I_t W_t J_t`` (``I`` of the receiving node, ``W`` of the weight, ``J`` of
    the neighbour), after expanding sines and cosines of sums; None where a factor mixes them."""
    import sympy

    own = set(sym.x) | set(sym.p)
    other = set(sym.xj) | set(sym.pj)
    link = {sym.w, *sym.e}  # the link's own: its weight and edge parameters
    expanded = sympy.expand(sympy.expand_trig(h))
    terms = []
    for term in sympy.Add.make_args(expanded):
        parts = {"I": sympy.Integer(1), "W": sympy.Integer(1), "J": sympy.Integer(1)}
        for factor in sympy.Mul.make_args(term):
            free = factor.free_symbols
            if free <= own:
                parts["I"] *= factor
            elif free <= other:
                parts["J"] *= factor
            elif free <= link:
                parts["W"] *= factor
            else:
                return None
        terms.append((parts["I"], parts["W"], parts["J"]))
    return terms


def _rhs_source(sym, pr, prefix: str = "") -> list[str]:
    """``law_rhs(y, wq, indptr, indices, P, out, G)`` and ``rhs_rows(n, nnz)``, the rows of the
    scratch ``G`` it takes on a network of ``n`` nodes and ``nnz`` links (``prefix`` before
    every name: the circle form's right-hand side is ``circle_law_rhs``).

    An input whose edge law separates (:func:`_separate`: ``w sin(theta_j - theta_i) = w (sin
    theta_j cos theta_i - cos theta_j sin theta_i)``) can be formed from neighbour sums ``sum_j
    W(w_ij) J(state_j)``, each ``J`` computed once per node into a row of ``G`` (``KH`` rows): no
    function of a neighbour's state per link, as the built-in kernels form the Kuramoto coupling
    (``law_rhs_hoisted``). A ``J`` that is a neighbour's state or parameter itself is read where
    it is stored. That pays where the ``KH n`` per-node functions are fewer than the ``nnz``
    links, and always when there are none (``rhs_rows`` returns ``KH``, else 0); with ``G`` of
    no rows the edge law is evaluated per link (``law_rhs_link``)."""
    split, pairs, arrays, hoists = _hoisting(sym)
    # the circle form's per-node functions are polynomials in its stored states, as cheap as a
    # link's: hoisted wherever an input separates
    cheap = "True" if not arrays or prefix else "KH * n < nnz"
    kh = f"{prefix}KH".upper() if prefix else "KH"
    out = [
        f"{kh} = {max(1, len(arrays))}",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def {prefix}rhs_rows(n, nnz):",
        f"    return {kh} if {hoists} and {cheap.replace('KH', kh)} else 0",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def {prefix}law_rhs(y, wq, indptr, indices, P, out, G):",
    ]
    hoisted = f"{prefix}law_rhs_hoisted(y, wq, indptr, indices, P, out, G)"
    link = f"{prefix}law_rhs_link(y, wq, indptr, indices, P, out)"
    if prefix:  # one variant, so one compiled (rhs_rows never changes its mind)
        if hoists:
            return out + [f"    {hoisted}"] + _rhs_variant(sym, pr, hoisted, split, pairs, arrays)
        return out + [f"    {link}"] + _rhs_variant(sym, pr, link, split, {}, {})
    out += ["    if G.shape[0] > 0:", f"        {hoisted}", "    else:", f"        {link}"]
    out += _rhs_variant(sym, pr, hoisted, split, pairs, arrays)
    out += _rhs_variant(sym, pr, link, dict.fromkeys(split), {}, {})
    return out


def _stored(sym) -> dict:
    """A neighbour's states and parameters: where each is read in a link loop."""
    return {
        **{x: f"y[{k} * n + j]" for k, x in enumerate(sym.xj)},
        **{p: f"P[{k}, j]" for k, p in enumerate(sym.pj)},
    }


def _hoisted_inputs(sym, split: dict, pairs: dict, arrays: dict) -> tuple[dict, dict]:
    """``(sums, reuse)``: each hoisted input as its terms over the neighbour sums ``s{k}``, and
    the receiving node's factors that are rows of ``G`` (``gi{row}``: read from ``G``'s row for
    node ``i``, computed once in its pass: the same bits, no second sine per node)."""
    import sympy

    sums = {
        m: sum((i * sympy.Symbol(f"s{pairs[w, j]}") for i, w, j in terms), sympy.Integer(0))
        for m, terms in split.items()
        if terms is not None
    }
    own = {sym_j: sym_i for sym_j, sym_i in zip((*sym.xj, *sym.pj), (*sym.x, *sym.p), strict=True)}
    reuse = {j.xreplace(own): sympy.Symbol(f"gi{row}", real=True) for j, row in arrays.items()}
    return {m: e.xreplace(reuse) for m, e in sums.items()}, reuse


def _rhs_variant(sym, pr, signature: str, split: dict, pairs: dict, arrays: dict) -> list[str]:
    """One right-hand side: the inputs of ``split`` with terms from neighbour sums (``pairs``,
    ``G``'s rows ``arrays``, or the neighbour's stored values), the others per link."""

    n_s = len(sym.x)
    node_exprs = list(sym.rates)
    per_link = [m for m, terms in split.items() if terms is None]
    link_exprs = [sym.coupling[m] for m in per_link]
    out = [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def {signature}:",
        "    n = indptr.shape[0] - 1",
    ]
    if arrays:
        js = list(arrays)
        out += ["    for j in range(n):"]
        out += _loads(js, sym.xj, "        ", "y[{k} * n + j]")
        out += _loads(js, sym.pj, "        ", "P[{k}, j]")
        out += _block(js, [f"G[{k}, j]" for k in range(len(js))], "        ", pr)
    out += ["    for i in range(n):"]
    hoisted = [m for m in split if split[m] is not None]
    sums, reuse = _hoisted_inputs(sym, split, pairs, arrays)
    every = node_exprs + link_exprs + list(sums.values())
    out += _node_loads(every, sym)
    out += _loads(every, list(reuse.values()), "        ", "G[{k}, i]")
    out += [f"        s{k} = 0.0" for k in range(len(pairs))]
    out += [f"        {sym.u[m]} = 0.0" for m in per_link]
    out += _link_loop(link_exprs + [_link_part(w, sym) for w, _ in pairs], sym)
    stored = _stored(sym)
    for (w, j), k in pairs.items():
        w = _link_part(w, sym)
        if j == 1:
            term = pr.doprint(w)
        else:
            term = f"({pr.doprint(w)}) * {stored[j] if j in stored else f'G[{arrays[j]}, j]'}"
        out.append(f"            s{k} += {term}")
    if per_link:
        out += _block(link_exprs, [str(sym.u[m]) for m in per_link], "            ", pr, accumulate=True)
    if hoisted:
        out += _block([sums[m] for m in hoisted], [str(sym.u[m]) for m in hoisted], "        ", pr)
    out += _block(node_exprs, [f"out[{k} * n + i]" for k in range(n_s)], "        ", pr)
    return out


class Circle(NamedTuple):
    """A law on the circle's embedding: each angle state ``theta`` (a state its expressions read only
    through ``sin`` and ``cos``) stored as ``(cos theta, sin theta)``, as the built-in kernels
    store the phase (:mod:`antisync.kernels.core`); :func:`circle_form`."""

    sym: Symbolic
    """the law over the slots: ``x`` one symbol per slot, ``rates`` one per slot (an angle's
    ``(-sin theta theta', cos theta theta')``), the edge law in the slots' symbols"""
    slots: tuple
    """per state of the law: its slots, ``(c, s)`` for an angle, ``(k,)`` else"""
    phase: tuple
    """the phase's ``(c, s)`` slots"""
    frequency: bool
    """whether the frequency criterion's quantities read the angles through ``sin`` and ``cos``
    only (``sym.frequency`` in the slots; else that criterion steps the angles themselves)"""
    speeds: tuple
    """per slot, what Euler's step takes: an angle's rate ``theta'`` at both its slots (the
    rotation's angle over ``dt``), another state's rate at its own"""


def circle_form(sym: Symbolic) -> Circle | None:
    """``sym`` on the circle's embedding, or None where its phase is not one of its states or
    that state is read other than through ``sin`` and ``cos`` of integer combinations (after
    ``expand_trig``: ``sin(2 (theta_j - theta_i))`` is a polynomial in the ends' ``cos`` and
    ``sin``). Classical RK4 on the embedding, each step projected back to the circle, is the
    built-in kernels' RK4 (:func:`antisync.kernels.core.make_model_kernels`' ``rk4_step``); its
    right-hand side needs no sine or cosine."""
    import sympy

    if sym.phase not in sym.x:
        return None
    exprs = [sympy.expand_trig(e) for e in (*sym.coupling, *sym.rates)]
    subs, angles = {}, set()
    for k, (x, xj) in enumerate(zip(sym.x, sym.xj, strict=True)):
        c, s, cj, sj = sympy.symbols(f"xc{k} xs{k} xjc{k} xjs{k}", real=True)
        mine = {sympy.sin(x): s, sympy.cos(x): c, sympy.sin(xj): sj, sympy.cos(xj): cj}
        read = any(e.has(x) or e.has(xj) for e in exprs)
        if (read or x == sym.phase) and not any(e.xreplace(mine).has(x, xj) for e in exprs):
            subs.update(mine)
            angles.add(k)
    k_phase = sym.x.index(sym.phase)
    if k_phase not in angles:
        return None
    coupling, rates = exprs[: len(sym.coupling)], exprs[len(sym.coupling) :]
    frequency = tuple(sympy.expand_trig(q).xreplace(subs) for q in sym.frequency)
    on_circle = not any(q.has(*(sym.x[k] for k in angles)) for q in frequency)
    x, xj, new_rates, slots, speeds = [], [], [], [], []
    for k, rate in enumerate(rates):
        rate = rate.xreplace(subs)
        if k in angles:
            c, s, cj, sj = (subs[f(v)] for v in (sym.x[k], sym.xj[k]) for f in (sympy.cos, sympy.sin))
            slots.append((len(x), len(x) + 1))
            x += [c, s]
            xj += [cj, sj]
            new_rates += [-s * rate, c * rate]
            speeds += [rate, rate]
        else:
            slots.append((len(x),))
            x.append(sym.x[k])
            xj.append(sym.xj[k])
            new_rates.append(rate)
            speeds.append(rate)
    circle = dataclasses.replace(
        sym,
        x=tuple(x),
        xj=tuple(xj),
        coupling=tuple(h.xreplace(subs) for h in coupling),
        rates=tuple(new_rates),
        phase=x[slots[k_phase][0]],
        frequency=frequency if on_circle else (),
    )
    return Circle(circle, tuple(slots), slots[k_phase], on_circle, tuple(speeds))


def _hoisting(sym) -> tuple[dict, dict, dict, bool]:
    """``(split, pairs, arrays, hoists)`` of :func:`_rhs_source`: each input's separated terms
    (None: per link), the neighbour sums ``(W, J) -> k``, the ``J`` computed into rows of ``G``
    and whether any input is hoisted."""
    split = {m: _separate(h, sym) for m, h in enumerate(sym.coupling)}
    pairs: dict = {}
    for terms in split.values():
        if terms is not None:
            for _, w, j in terms:
                pairs.setdefault((w, j), len(pairs))
    if len(pairs) > MAX_HOISTED:
        split = dict.fromkeys(split)
        pairs = {}
    arrays: dict = {}  # J -> row of G
    for _, j in pairs:
        if j != 1 and j not in _stored(sym):
            arrays.setdefault(j, len(arrays))
    return split, pairs, arrays, any(t is not None for t in split.values())


#: the largest |integer power| a lane-vector law spells as products (x**2 -> (x*x))
MAX_POWER = 4


def _product_printer():
    """:func:`_printer` with integer powers spelt as products (``x**2`` as ``(x*x)``, ``x**-1``
    as ``(1.0/x)``): the circle form's arithmetic, the same on a scalar and on a lane vector."""
    base = type(_printer())

    class _Products(base):
        def _print_Pow(self, expr):
            b, e = expr.args
            if e.is_Integer and 1 <= abs(int(e)) <= MAX_POWER:
                x = self.parenthesize(b, 100)  # atomic: a symbol or a parenthesized expression
                prod = "*".join([x] * abs(int(e)))
                return f"({prod})" if e > 0 else f"(1.0/({prod}))"
            return super()._print_Pow(expr)

    return _Products({"fully_qualified_modules": True, "standard": "python3"})


def vectorizable(sym) -> bool:
    """Whether ``sym``'s edge and node laws are arithmetic only (``+ - * /`` and integer powers
    up to :data:`MAX_POWER`): what lane vectors compute (:mod:`antisync.kernels.core`)."""
    import sympy

    # a function of the edge parameters alone is read from its row (with_derived): a number
    for e in (*(_link_part(h, sym) for h in sym.coupling), *sym.rates):
        for node in sympy.preorder_traversal(e):
            if isinstance(node, sympy.Pow):
                if not (node.exp.is_Integer and 1 <= abs(int(node.exp)) <= MAX_POWER):
                    return False
            elif not isinstance(node, sympy.Add | sympy.Mul | sympy.Symbol | sympy.Number):
                return False
    return True


def _vec_block(exprs, targets, indent: str, pr) -> list[str]:
    """:func:`_block` for lane vectors: ``vstore(target, expr)`` (a number as ``vsplat``)."""
    import sympy

    subs, reduced = sympy.cse(list(exprs), symbols=sympy.numbered_symbols("c"), optimizations="basic")
    lines = [f"{indent}{sym} = {pr.doprint(e)}" for sym, e in subs]
    for (array, offset), e in zip(targets, reduced, strict=True):
        value = pr.doprint(e) if e.free_symbols else f"vsplat({float(e)!r})"
        lines.append(f"{indent}vstore({array}, {offset}, {value})")
    return lines


def _lane_rhs_variant(
    sym, pr, name: str, split: dict, pairs: dict, arrays: dict, stages: bool = True
) -> list[str]:
    """:func:`_rhs_variant` on lane vectors: every array flat with lane ``q`` of row ``r`` at
    ``r L + q``, ``VEC`` lanes per ``vload``; the neighbour sums (and the per-link inputs) in
    vector registers over a node's in-links, then its rates: stored for RK4's ``stages``
    (:func:`_lane_source`), else into ``f``."""
    import sympy

    hoisted = [m for m in split if split[m] is not None]
    per_link = [m for m in split if split[m] is None]
    link_exprs = [_link_part(sym.coupling[m], sym) for m in per_link]
    parts = {w: _link_part(w, sym) for w, _ in pairs}
    stored = {
        **{x: f"vload(y, ({k} * n + j) * L + o)" for k, x in enumerate(sym.xj)},
        **{p: f"vload(P, ({k} * n + j) * L + o)" for k, p in enumerate(sym.pj)},
    }
    out = [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def {name}(y, lw, indptr, indices, P, G, L, {'mode, z, f, acc, nxt, h' if stages else 'f'}):",
        "    n = indptr.shape[0] - 1",
        "    nnz = indices.shape[0]",
    ]
    if arrays:
        js = list(arrays)
        out += ["    for j in range(n):", "        for o in range(0, L, VEC):"]
        out += _loads(js, sym.xj, "            ", "vload(y, ({k} * n + j) * L + o)")
        out += _loads(js, sym.pj, "            ", "vload(P, ({k} * n + j) * L + o)")
        out += _vec_block(js, [("G", f"({k} * n + j) * L + o") for k in range(len(js))], "            ", pr)
    sums, reuse = _hoisted_inputs(sym, split, pairs, arrays)
    node_exprs = list(sym.rates)
    every = node_exprs + link_exprs + list(sums.values())
    pre = _loads(every, sym.x, "            ", "vload(y, ({k} * n + i) * L + o)")
    pre += _loads(every, sym.p, "            ", "vload(P, ({k} * n + i) * L + o)")
    pre += _loads(every, list(reuse.values()), "            ", "vload(G, ({k} * n + i) * L + o)")
    pre += [f"            s{k} = vsplat(0.0)" for k in range(len(pairs))]
    pre += [f"            {sym.u[m]} = vsplat(0.0)" for m in per_link]
    link = ["                w = vload(lw, e * L + o)"]
    link += _loads(link_exprs, sym.xj, "                ", "vload(y, ({k} * n + j) * L + o)")
    link += _loads(link_exprs, sym.pj, "                ", "vload(P, ({k} * n + j) * L + o)")
    # the link's edge rows, after the per-node ones: row NP + k of link e at (NP n + k nnz + e) L
    edge_rows = (*sym.e, *_derived_symbols(sym))
    every_link = link_exprs + list(parts.values())
    link += _loads(every_link, edge_rows, "                ", "vload(P, (NP * n + {k} * nnz + e) * L + o)")
    for (w, j), k in pairs.items():
        w = parts[w]
        term = pr.doprint(w) if j == 1 else f"({pr.doprint(w)}) * {stored.get(j) or _g_load(arrays[j])}"
        link.append(f"                s{k} = s{k} + {term}")
    if per_link:
        subs, reduced = sympy.cse(link_exprs, symbols=sympy.numbered_symbols("c"), optimizations="basic")
        link += [f"                {s} = {pr.doprint(e)}" for s, e in subs]
        link += [
            f"                {sym.u[m]} = {sym.u[m]} + {pr.doprint(e)}"
            for m, e in zip(per_link, reduced, strict=True)
        ]
    node = []
    if hoisted:
        node += _block([sums[m] for m in hoisted], [str(sym.u[m]) for m in hoisted], "            ", pr)
    node += _vec_rates(node_exprs, "            ", pr)
    # two lane vectors at a time (offsets o and o + VEC, the second's locals suffixed _b): two
    # independent chains of additions per neighbour sum, as the built-in lane kernels step pairs
    out += ["    for i in range(n):", "        for o in range(0, L, 2 * VEC):", "            ob = o + VEC"]
    out += pre + _second(pre)
    out += ["            for e in range(indptr[i], indptr[i + 1]):", "                j = indices[e]"]
    out += link + _second(link)
    out += node + _second(node)
    if not stages:
        for k in range(len(sym.x)):
            out += [f"            vstore(f, ({k} * n + i) * L + o, rate{k})"]
            out += [f"            vstore(f, ({k} * n + i) * L + ob, rate{k}_b)"]
        return out
    # the RK4 stage this right-hand side serves, fused (circle_lane_step): no pass of its own
    stores = {
        0: ["vstore(f, at, {r})", "vstore(nxt, at, vload(z, at) + h * {r})"],
        1: ["vstore(nxt, at, vload(z, at) + h * {r})", "vstore(acc, at, vload(f, at) + 2.0 * {r})"],
        2: ["vstore(nxt, at, vload(z, at) + h * {r})", "vstore(acc, at, vload(acc, at) + 2.0 * {r})"],
        3: ["vstore(z, at, vload(z, at) + h * (vload(acc, at) + {r}))"],
    }
    for mode, lines in stores.items():
        out.append(
            f"            {'if' if mode == 0 else 'elif' if mode < 3 else 'else'}"
            + (f" mode == {mode}:" if mode < 3 else ":")
        )
        for k in range(len(sym.x)):
            for offset, suffix in (("o", ""), ("ob", "_b")):
                out.append(f"                at = ({k} * n + i) * L + {offset}")
                out += [f"                {line.format(r=f'rate{k}{suffix}')}" for line in lines]
    return out


def _vec_rates(exprs, indent: str, pr) -> list[str]:
    """``rate0, rate1, ...`` = the node law's rates on lane vectors (a number as ``vsplat``)."""
    import sympy

    subs, reduced = sympy.cse(list(exprs), symbols=sympy.numbered_symbols("c"), optimizations="basic")
    lines = [f"{indent}{sym} = {pr.doprint(e)}" for sym, e in subs]
    for k, e in enumerate(reduced):
        value = pr.doprint(e) if e.free_symbols else f"vsplat({float(e)!r})"
        lines.append(f"{indent}rate{k} = {value}")
    return lines


#: the locals of a generated lane right-hand side (what :func:`_second` renames)
_LOCALS = re.compile(
    r"\b(x\d+|xj\d+|xc\d+|xs\d+|xjc\d+|xjs\d+|p\d+|pj\d+|ep\d+|ed\d+|u\d+|s\d+|gi\d+|c\d+|rate\d+|w)\b"
)


_OFFSET = re.compile(r"L \+ o\b")


def _second(lines: list[str]) -> list[str]:
    """``lines`` for the second lane vector of a pair: every local suffixed ``_b``, the offset
    ``o`` read as ``ob``."""
    return [_OFFSET.sub("L + ob", _LOCALS.sub(r"\1_b", line)) for line in lines]


def _g_load(row: int) -> str:
    return f"vload(G, ({row} * n + j) * L + o)"


def _lane_source(circle: Circle, pr) -> list[str]:
    """The circle form on lane vectors (:data:`antisync.kernels.core.VEC` trajectories per
    machine vector, as the built-in lane kernels): ``circle_lane_rhs``, its RK4 step and
    ``law_items_lanes``, the lane driver (``L`` items of a group stepped together, a lane
    refilled from the group's queue when its item ends). Only where the circle form is
    arithmetic (:func:`vectorizable`); ``LANES`` is False otherwise.

    Each lane does exactly the one-trajectory circle form's operations in the same order (the
    same variant, no fused multiply-add), so the results are ``law_items_circle``'s bit for bit
    (tests/test_laws.py)."""
    sym = circle.sym
    if not vectorizable(sym):
        return ["", "", "LANES = False"]
    split, pairs, arrays, hoists = _hoisting(sym)
    out = [
        "",
        "",
        "LANES = True",
        f"LANE_KH = {max(1, len(arrays))}",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_rhs(y, lw, indptr, indices, P, G, L, mode, z, f, acc, nxt, h):",
        "    \"\"\"The rates at the lanes' state y, stored for RK4's stage `mode` (0: f at the step's",
        "    state z and nxt = z + h f; 1: nxt = z + h k2, acc = f + 2 k2; 2: nxt = z + h k3, acc += 2",
        '    k3; 3: z += h (acc + k4)): circle_sync\'s additions in its order."""',
    ]
    # the variant circle_law_rhs has (hoisted wherever an input separates)
    variant = "circle_lane_rhs_hoisted" if hoists else "circle_lane_rhs_link"
    out += [f"    {variant}(y, lw, indptr, indices, P, G, L, mode, z, f, acc, nxt, h)"]
    out += _lane_rhs_variant(sym, pr, variant, split, pairs if hoists else {}, arrays if hoists else {})
    project = _projection(circle, "            ", "({r} * n + i) * L + o", vector=True)
    out += _lane_rhs_variant(
        dataclasses.replace(sym, rates=circle.speeds),
        pr,
        "circle_euler_lane_rhs",
        split,
        pairs if hoists else {},
        arrays if hoists else {},
        stages=False,
    )
    turn = []
    one = _projection(circle, "        ", "({r} * n + i) * L + q")
    for slots in circle.slots:
        if len(slots) == 1:
            at = f"({slots[0]} * n + i) * L + o"
            turn += [f"            vstore(z, {at}, vload(z, {at}) + dt * vload(F, {at}))"]
            continue
        c, s = slots
        turn += [
            f"            a = dt * vload(F, ({c} * n + i) * L + o)",
            "            if vany_outside(a, TAYLOR_MAX_ANGLE):",
            "                for q in range(o, o + VEC):  # rotation's own choice, lane by lane",
            f"                    ca, sa = rotation(dt * F[({c} * n + i) * L + q])",
            f"                    ci = z[({c} * n + i) * L + q]",
            f"                    si = z[({s} * n + i) * L + q]",
            f"                    z[({c} * n + i) * L + q] = ci * ca - si * sa",
            f"                    z[({s} * n + i) * L + q] = si * ca + ci * sa",
            "            else:",
            "                ca, sa = taylor_rotation(a)",
            f"                ci = vload(z, ({c} * n + i) * L + o)",
            f"                si = vload(z, ({s} * n + i) * L + o)",
            f"                vstore(z, ({c} * n + i) * L + o, ci * ca - si * sa)",
            f"                vstore(z, ({s} * n + i) * L + o, si * ca + ci * sa)",
        ]
    rates_of = []
    for slots in circle.slots:
        if len(slots) == 1:
            at = f"({slots[0]} * n + i) * L + q"
            rates_of += [f"            f[{at}] = F[{at}]"]
            continue
        c, s = (f"({r} * n + i) * L + q" for r in slots)
        rates_of += [f"            f[{c}] = -F[{c}] * z[{s}]", f"            f[{s}] = F[{s}] * z[{c}]"]
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_rates_of(z, F, f, n, L):",
        '    """circle_rates_of of every lane."""',
        "    for i in range(n):",
        "        for q in range(L):",
        *rates_of,
    ]
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_turn(z, F, n, dt, L):",
        '    """circle_euler_turn of every lane (Taylor rotations on vectors where every lane\'s angle',
        '    is within their range, else the scalar rotation lane by lane: the same bits)."""',
        "    for i in range(n):",
        "        for o in range(0, L, VEC):",
        *turn,
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_project(z, n, q, L):",
        '    """circle_project of lane q."""',
        "    for i in range(n):",
        *one,
    ]
    pc, ps = circle.phase
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_step(z, f, acc, ya, yb, lw, indptr, indices, P, G, dt, L):",
        '    """One RK4 step of every lane (circle_sync\'s, lane by lane), from z with its rates f and',
        '    its first stage state ya = z + dt / 2 f; on return the same at the new state."""',
        "    n = indptr.shape[0] - 1",
        "    h = 0.5 * dt",
        "    circle_lane_rhs(ya, lw, indptr, indices, P, G, L, 1, z, f, acc, yb, h)",
        "    circle_lane_rhs(yb, lw, indptr, indices, P, G, L, 2, z, f, acc, ya, dt)",
        "    circle_lane_rhs(ya, lw, indptr, indices, P, G, L, 3, z, f, acc, yb, dt / 6.0)",
        "    for i in range(n):",
        "        for o in range(0, L, VEC):",
        *project,
        "    circle_lane_rhs(z, lw, indptr, indices, P, G, L, 0, z, f, acc, ya, h)",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_order(z, f, n, r2, dr2, L):",
        '    """circle_order of every lane: (R, dR/dt) into r2, dr2."""',
        "    for o in range(0, L, VEC):",
        "        tc = vsplat(0.0)",
        "        ts = vsplat(0.0)",
        "        dc = vsplat(0.0)",
        "        ds = vsplat(0.0)",
        "        for i in range(n):",
        f"            tc = tc + vload(z, ({pc} * n + i) * L + o)",
        f"            ts = ts + vload(z, ({ps} * n + i) * L + o)",
        f"            dc = dc + vload(f, ({pc} * n + i) * L + o)",
        f"            ds = ds + vload(f, ({ps} * n + i) * L + o)",
        "        vstore(r2, o, tc * tc + ts * ts)",
        "        vstore(dr2, o, 2.0 * (tc * dc + ts * ds))",
    ]
    _, _, qs, _, _, rates, edge, edge_rates = _frequency_exprs(sym)
    quantities = dataclasses.replace(sym, coupling=(*edge, *edge_rates), rates=(*qs, *rates))
    if circle.frequency and vectorizable(quantities):
        out += ["", "", "LANES_FREQUENCY = True"] + _lane_frequency_source(sym, pr)
    else:  # never called: the frequency criterion runs one trajectory per item (LANES_FREQUENCY)
        out += [
            "",
            "",
            "LANES_FREQUENCY = False",
            "",
            "",
            '@njit(cache=True, error_model="numpy")',
            "def circle_lane_devs(y, f, lw, indptr, indices, P, DV, L):",
            "    DV[:] = np.nan",
        ]
    return out + "".join(_LANE_DRIVER.format(**kind) for kind in _LANE_KINDS.values()).splitlines()


def _projection(circle: Circle, indent: str, at: str, vector: bool = False) -> list[str]:
    """Lines putting every angle's ``(cos, sin)`` in ``z`` back on the unit circle, slot ``r`` at
    index ``at.format(r=r)``, on lane vectors with ``vector``. A pair at 0 becomes NaN (never
    synchronized): on vectors ``norm2 / norm2`` does that, exactly 1 everywhere else."""
    inv = (
        "1.0 / vsqrt(norm2) * (norm2 / norm2)"
        if vector
        else "1.0 / math.sqrt(norm2) if norm2 > 0.0 else math.nan"
    )
    lines = []
    for slots in circle.slots:
        if len(slots) == 1:
            continue
        c, s = (at.format(r=r) for r in slots)
        read = (f"vload(z, {c})", f"vload(z, {s})") if vector else (f"z[{c}]", f"z[{s}]")
        write = (
            (f"vstore(z, {c}, c * inv)", f"vstore(z, {s}, s * inv)")
            if vector
            else (
                f"z[{c}] = c * inv",
                f"z[{s}] = s * inv",
            )
        )
        lines += [f"c = {read[0]}", f"s = {read[1]}", "norm2 = c * c + s * s", f"inv = {inv}", *write]
    return [indent + line for line in lines]


def _circle_source(sym, circle: Circle | None, pr) -> list[str]:
    """The circle form's right-hand side (``circle_law_rhs``), its frequency quantities
    (``circle_law_devs``), its conversions and its RK4 (``circle_sync``); without a circle form a
    ``circle_sync`` that is the law's own RK4 (never chosen: ``CIRCLE`` is False)."""
    head = ["", "", f"CIRCLE = {circle is not None}"]
    sync_args = "y, wq, indptr, indices, P, dt, freq, target, max_steps"
    if circle is None:
        return head + [
            "CIRCLE_FREQUENCY = False",
            "",
            "",
            '@njit(cache=True, error_model="numpy")',
            f"def circle_sync({sync_args}):",
            "    return law_sync(y, wq, indptr, indices, P, dt, True, freq, target, max_steps)",
            "",
            "",
            '@njit(cache=True, error_model="numpy")',
            f"def circle_euler_sync({sync_args}):",
            "    return law_sync(y, wq, indptr, indices, P, dt, False, freq, target, max_steps)",
            "",
            "",
            "LANES = False",
            *_TRIP_RK4_ANGLES,
        ]
    out = head + [f"CIRCLE_FREQUENCY = {circle.frequency}", f"CS = {len(circle.sym.x)}"]
    pr = _product_printer()  # the same spelling on a scalar and on a lane vector
    out += _rhs_source(circle.sym, pr, prefix="circle_")
    if circle.frequency:
        out += _frequency_source(circle.sym, pr, prefix="circle_")
    else:  # never called: the frequency criterion steps the angles (CIRCLE_FREQUENCY)
        out += [
            "",
            "",
            '@njit(cache=True, error_model="numpy")',
            "def circle_law_devs(y, f, wq, indptr, indices, P, D):",
            "    D[:] = np.nan",
        ]
    # per slot: the start's conversion, Euler's step (each angle's (cos, sin) rotated by dt
    # theta', the built-in kernels' step) and the circle form's rates from Euler's
    convert, turn, rates_of = [], [], []
    for k, slots in enumerate(circle.slots):
        if len(slots) == 1:
            r = slots[0]
            convert += [f"        z[{r} * n + i] = y[{k} * n + i]"]
            turn += [f"        z[{r} * n + i] += dt * F[{r} * n + i]"]
            rates_of += [f"        f[{r} * n + i] = F[{r} * n + i]"]
            continue
        c, s = slots
        convert += [
            f"        z[{c} * n + i] = math.cos(y[{k} * n + i])",
            f"        z[{s} * n + i] = math.sin(y[{k} * n + i])",
        ]
        turn += [
            f"        ca, sa = rotation(dt * F[{c} * n + i])",
            f"        ci = z[{c} * n + i]",
            f"        si = z[{s} * n + i]",
            f"        z[{c} * n + i] = ci * ca - si * sa",
            f"        z[{s} * n + i] = si * ca + ci * sa",
        ]
        rates_of += [
            f"        f[{c} * n + i] = -F[{c} * n + i] * z[{s} * n + i]",
            f"        f[{s} * n + i] = F[{s} * n + i] * z[{c} * n + i]",
        ]
    project = _projection(circle, "        ", "{r} * n + i")
    out += _rhs_source(dataclasses.replace(circle.sym, rates=circle.speeds), pr, prefix="circle_euler_")
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_euler_turn(z, F, n, dt):",
        '    """One Euler step: z rotated (its angles) or advanced by dt F."""',
        "    for i in range(n):",
        *turn,
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_rates_of(z, F, f, n):",
        '    """The circle form\'s rates f (an angle\'s (-sin theta theta\', cos theta theta\')) from F."""',
        "    for i in range(n):",
        *rates_of,
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def circle_euler_sync({sync_args}):",
        '    """Euler on the circle\'s embedding from the state y to the order-parameter criterion, or',
        "    with freq the frequency criterion (every angle rotated by dt theta', renormalized every",
        '    RENORM_EVERY steps, as the built-in kernels): (status, steps, frac), as law_sync."""',
        "    n = indptr.shape[0] - 1",
        "    m = CS * n",
        "    G = np.empty((circle_euler_rhs_rows(n, indices.shape[0]), n))",
        "    z = np.empty(m)",
        "    F = np.empty(m)",
        "    f = np.empty(m)",
        "    D = np.empty((2 * KF, n))",
        "    Dp = np.empty((2 * KF, n))",
        "    circle_from(y, z, n)",
        "    circle_euler_law_rhs(z, wq, indptr, indices, P, F, G)",
        "    r2 = 0.0",
        "    if freq:",
        "        circle_rates_of(z, F, f, n)",
        "        circle_law_devs(z, f, wq, indptr, indices, P, D)",
        "        dev = law_deviation(D, D, n, dt, False, 1.0)",
        "        if dev != dev:",
        "            return NOT_SYNCED, max_steps, 0.0",
        "        if dev < target:",
        "            return ALREADY_SYNCED, 0, 0.0",
        "    else:",
        "        r2, _ = circle_order(z, z, n)",
        "        if r2 != r2:",
        "            return NOT_SYNCED, max_steps, 0.0",
        "        if r2 >= target:",
        "            return ALREADY_SYNCED, 0, 0.0",
        "    for step in range(1, max_steps + 1):",
        "        circle_euler_turn(z, F, n, dt)",
        "        r2_prev = r2",
        "        r2, _ = circle_order(z, z, n)",
        "        if step % RENORM_EVERY == 0:",
        "            circle_project(z, n)",
        "        circle_euler_law_rhs(z, wq, indptr, indices, P, F, G)",
        "        if freq:",
        "            D, Dp = Dp, D",
        "            circle_rates_of(z, F, f, n)",
        "            circle_law_devs(z, f, wq, indptr, indices, P, D)",
        "            dev = law_deviation(D, Dp, n, dt, False, 1.0)",
        "            if dev != dev:",
        "                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized",
        "            x = frequency_crossing(D, Dp, n, dt, False, target)",
        "        else:",
        "            if r2 != r2:",
        "                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized",
        "            x = order_crossing(r2_prev, 0.0, r2, 0.0, dt, False, target)",
        "        if x >= 0.0:",
        "            return SYNCED, step, x",
        "    return NOT_SYNCED, max_steps, 0.0",
    ]
    pc, ps = circle.phase
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_from(y, z, n):",
        '    """z = the state y on the circle\'s embedding."""',
        "    for i in range(n):",
        *convert,
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_project(z, n):",
        '    """Every angle\'s (cos, sin) back to the unit circle (a pair at 0: NaN)."""',
        "    for i in range(n):",
        *project,
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_order(z, f, n):",
        '    """(R, dR/dt) from the phase\'s (cos, sin) and their rates: no sine, no cosine."""',
        "    tc = 0.0",
        "    ts = 0.0",
        "    dc = 0.0",
        "    ds = 0.0",
        "    for i in range(n):",
        f"        tc += z[{pc} * n + i]",
        f"        ts += z[{ps} * n + i]",
        f"        dc += f[{pc} * n + i]",
        f"        ds += f[{ps} * n + i]",
        "    return tc * tc + ts * ts, 2.0 * (tc * dc + ts * ds)",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_rk4(z, f, k2, k3, k4, v, w, indptr, indices, P, G, h):",
        '    """One classical RK4 step of h on the circle\'s embedding from z (its rates f, the work',
        '    arrays k2 k3 k4 v), projected back to the circle: circle_sync\'s and trip_rk4\'s."""',
        "    m = z.shape[0]",
        "    half = 0.5 * h",
        "    for a in range(m):",
        "        v[a] = z[a] + half * f[a]",
        "    circle_law_rhs(v, w, indptr, indices, P, k2, G)",
        "    for a in range(m):",
        "        v[a] = z[a] + half * k2[a]",
        "    circle_law_rhs(v, w, indptr, indices, P, k3, G)",
        "    for a in range(m):",
        "        v[a] = z[a] + h * k3[a]",
        "    circle_law_rhs(v, w, indptr, indices, P, k4, G)",
        "    for a in range(m):",
        "        z[a] = z[a] + h / 6.0 * (f[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a])",
        "    circle_project(z, indptr.shape[0] - 1)",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def circle_sync({sync_args}):",
        '    """Classical RK4 on the circle\'s embedding from the state y (each step projected back to',
        "    the circle) to the order-parameter criterion, or with freq the frequency criterion:",
        '    (status, steps, frac), as law_sync."""',
        "    n = indptr.shape[0] - 1",
        "    m = CS * n",
        "    G = np.empty((circle_rhs_rows(n, indices.shape[0]), n))",
        *_CIRCLE_RK4_WORK,
        "    D = np.empty((2 * KF, n))",
        "    Dp = np.empty((2 * KF, n))",
        "    circle_from(y, z, n)",
        "    circle_law_rhs(z, wq, indptr, indices, P, f, G)",
        "    r2 = 0.0",
        "    dr2 = 0.0",
        "    if freq:",
        "        circle_law_devs(z, f, wq, indptr, indices, P, D)",
        "        dev = law_deviation(D, D, n, dt, True, 1.0)",
        "        if dev != dev:",
        "            return NOT_SYNCED, max_steps, 0.0",
        "        if dev < target:",
        "            return ALREADY_SYNCED, 0, 0.0",
        "    else:",
        "        r2, dr2 = circle_order(z, f, n)",
        "        if not (r2 == r2 and dr2 == dr2):",
        "            return NOT_SYNCED, max_steps, 0.0",
        "        if r2 >= target:",
        "            return ALREADY_SYNCED, 0, 0.0",
        "    for step in range(1, max_steps + 1):",
        "        circle_rk4(z, f, k2, k3, k4, v, wq, indptr, indices, P, G, dt)",
        "        circle_law_rhs(z, wq, indptr, indices, P, f, G)",
        "        if freq:",
        "            D, Dp = Dp, D",
        "            circle_law_devs(z, f, wq, indptr, indices, P, D)",
        "            dev = law_deviation(D, Dp, n, dt, True, 1.0)",
        "            if dev != dev:",
        "                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized",
        "            x = frequency_crossing(D, Dp, n, dt, True, target)",
        "        else:",
        "            r2_prev = r2",
        "            dr2_prev = dr2",
        "            r2, dr2 = circle_order(z, f, n)",
        "            if not (r2 == r2 and dr2 == dr2):",
        "                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized",
        "            x = order_crossing(r2_prev, dr2_prev, r2, dr2, dt, True, target)",
        "        if x >= 0.0:",
        "            return SYNCED, step, x",
        "    return NOT_SYNCED, max_steps, 0.0",
        "",
    ]
    out += _circle_trip_source(circle, pr) if circle.frequency else _TRIP_RK4_ANGLES
    return out + _lane_source(circle, pr)


#: circle_rk4's arrays, each m = CS * n long: the state z, its rates f, the stages, the stage state
_CIRCLE_RK4_WORK = [f"    {a} = np.empty(m)" for a in ("z", "f", "k2", "k3", "k4", "v")]


#: A line trip's RK4 on the law's own states (law_trip), where its circle form cannot run one.
_TRIP_RK4_ANGLES = [
    "",
    "",
    '@njit(cache=True, error_model="numpy")',
    "def trip_rk4(y0, w_fault, w_post, indptr, indices, P, t_clear, t_end, dt, tol, line, out):",
    "    law_trip(y0, w_fault, w_post, indptr, indices, P, t_clear, t_end, dt, tol, line, out)",
]


def _circle_trip_source(circle: Circle, pr) -> list[str]:
    """``trip_rk4``: a line trip (law_trip's) by classical RK4 on the circle's embedding, each step
    projected back to the circle, as the built-in kernels' trip (:func:`antisync.kernels.trip.
    rk4_trip`) steps ``(cos, sin, nu)``; the phase ``atan2(s, c)`` of its slots, its rate
    ``c s' - s c'``. Needs the frequency criterion on the circle (``circle.frequency``)."""
    pc, ps = circle.phase
    k_phase = next(k for k, slots in enumerate(circle.slots) if slots == circle.phase)
    out = _frequency_source(circle.sym, pr, prefix="circle_", raw=True)
    return out + [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_trip_eval(z, w, indptr, indices, P, f, G, T):",
        '    """trip_eval on the circle\'s embedding."""',
        "    D, Dp, Q, Qp, ph, dph, u, p_ph, p_dph, p_u = T",
        "    n = indptr.shape[0] - 1",
        "    circle_law_rhs(z, w, indptr, indices, P, f, G)",
        "    circle_law_devs(z, f, w, indptr, indices, P, D)",
        "    circle_law_freqs(z, f, w, indptr, indices, P, Q)",
        "    for i in range(n):",
        f"        c = z[{pc} * n + i]",
        f"        s = z[{ps} * n + i]",
        "        ph[i] = math.atan2(s, c)",
        f"        dph[i] = c * f[{ps} * n + i] - s * f[{pc} * n + i]",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def trip_rk4(y0, w_fault, w_post, indptr, indices, P, t_clear, t_end, dt, tol, line, out):",
        '    """law_trip by RK4 on the circle\'s embedding."""',
        "    n = indptr.shape[0] - 1",
        "    m = CS * n",
        "    G = np.empty((circle_rhs_rows(n, indices.shape[0]), n))",
        "    T = trip_arrays(n)",
        *_CIRCLE_RK4_WORK,
        "    circle_from(y0, z, n)",
        "    settle = np.nan",
        "    max_f = 0.0",
        "    max_a = 0.0",
        "    t = 0.0",
        "    failed = False",
        "    for stage in range(2):",
        "        if stage == 0 and t_clear <= 0.0:",
        "            continue  # no fault",
        "        w = w_fault if stage == 0 else w_post",
        "        circle_trip_eval(z, w, indptr, indices, P, f, G, T)",
        "        if t == 0.0:  # the unwrapped phases start at the state's own",
        "            for i in range(n):",
        f"                T[6][i] = y0[{k_phase} * n + i]",
        "        settle = trip_clock(T[0], T[0], n, t, 0.0, tol, settle, True)",
        "        t0 = t",
        "        length = t_clear if stage == 0 else t_end - t_clear",
        "        steps = max(1, int(math.ceil(length / dt - 1e-9)))",
        "        for k in range(steps):",
        "            h = dt if k < steps - 1 else length - (steps - 1) * dt",
        "            circle_rk4(z, f, k2, k3, k4, v, w, indptr, indices, P, G, h)",
        "            t_prev = t",
        "            t = t0 + (k + 1) * dt if k < steps - 1 else t0 + length",
        "            trip_keep(T)",
        "            circle_trip_eval(z, w, indptr, indices, P, f, G, T)",
        "            settle, max_f, max_a = trip_after(",
        "                T, indptr, indices, t_prev, t - t_prev, tol, settle, line, max_f, max_a",
        "            )",
        "            total = 0.0",
        "            for a in range(m):",
        "                total += z[a]",
        "            if not math.isfinite(total):",
        "                failed = True  # the step is unstable for this grid",
        "                break",
        "        if failed:",
        "            break",
        "    out[0] = np.nan if failed else settle",
        "    out[1] = max_f",
        "    out[2] = max_a",
        "    out[3] = 1.0 if failed else 0.0",
    ]


def _phase_lines(sym, rate, targets: list[str], pr) -> list[str]:
    """Inside ``for i in range(n)``: node ``i``'s phase and its rate along ``f`` into ``targets``."""
    out = _node_loads([sym.phase, rate], sym)
    out += [f"        f{k} = f[{k} * n + i]" for k in range(len(sym.x))]
    return out + _block([sym.phase, rate], targets, "        ", pr)


def generate_source(law: Law) -> str:
    """The Python source of ``law``'s kernels (module docstring)."""
    import sympy

    sym = with_derived(law.symbolic())
    pr = _printer()
    n_s, n_u = len(sym.x), len(sym.u)
    edge_exprs = list(sym.coupling)
    out = [
        f"# generated by antisync.kernels.law (generator {GENERATOR}); do not edit",
        f"# {law.dynamics_text}",
        "import math",
        "import numpy as np",
        "from numba import njit",
        "from antisync.kernels import law_support as support",
        "from antisync.kernels.law_support import ALREADY_SYNCED, NOT_SYNCED, SYNCED, RA, RC, RGAMMA",
        "from antisync.kernels.law_support import factor, item_of, order_crossing, phase, record, solve",
        "from antisync.kernels.law_support import trip_weights",
        "from antisync.kernels.law_support import frequency_crossing, law_binding, law_crossing_weights",
        "from antisync.kernels.law_support import law_deviation, near_step",
        "from antisync.kernels.law_support import copy_into, trip_clock, trip_keep",
        "from antisync.kernels.law_support import RENORM_EVERY, TAYLOR_MAX_ANGLE, VEC",
        "from antisync.kernels.law_support import rotation, taylor_rotation, vany_outside",
        "from antisync.kernels.law_support import vload, vsplat, vsqrt, vstore",
        "",
        f"S = {n_s}",
        f"NP = {len(sym.p)}",
        f"NROWS = {len(sym.p) + (len(sym.e) + len(sym.derived) if sym.e else 0)}",
    ]
    out += _rhs_source(sym, pr)

    # R and its rate: the phase and its gradient along f
    grad = list(sym.phase_gradient)
    rate = sum((g * sympy.Symbol(f"f{k}") for k, g in enumerate(grad)), sympy.Integer(0))
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_sums(y, f, P, n):",
        "    tc = 0.0",
        "    ts = 0.0",
        "    dc = 0.0",
        "    ds = 0.0",
        "    for i in range(n):",
    ]
    out += _phase_lines(sym, rate, ["ph", "rate"], pr)
    out += [
        "        co = math.cos(ph)",
        "        si = math.sin(ph)",
        "        tc += co",
        "        ts += si",
        "        dc -= si * rate",
        "        ds += co * rate",
        "    return tc, ts, dc, ds",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_order(y, f, P, n):",
        "    tc, ts, dc, ds = law_sums(y, f, P, n)",
        "    return tc * tc + ts * ts, 2.0 * (tc * dc + ts * ds)",
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_start(seed, k, P, y, n):",
        "    around = P.shape[0] > NROWS",
        "    for i in range(n):",
        "        phi = phase(seed, k, i)",
        "        if around:  # model.start: phases around a locked state's (rows NROWS, NROWS + 1)",
        "            phi = P[NROWS, i] + P[NROWS + 1, i] * (phi * (1.0 / np.pi) - 1.0)",
    ]
    out += _loads(list(sym.start), sym.p, "        ", "P[{k}, i]")
    out += _block(list(sym.start), [f"y[{k} * n + i]" for k in range(n_s)], "        ", pr)
    out += _frequency_source(sym, pr)
    # a line trip's largest frequency and angle differences: the quantities themselves, the phases
    out += _frequency_source(sym, pr, raw=True)
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_phases(y, f, P, n, ph, dph):",
        "    for i in range(n):",
    ]
    out += _phase_lines(sym, rate, ["ph[i]", "dph[i]"], pr)

    # the Jacobian on the expanded pattern: row (s, i), entries (r, i) then (r, j) per in-link
    d_edge_i = [[h.diff(x) for x in sym.x] for h in sym.coupling]  # d h_m / d x_r (own)
    d_edge_j = [[h.diff(x) for x in sym.xj] for h in sym.coupling]  # d h_m / d xj_r
    d_node_x = [[g.diff(x) for x in sym.x] for g in sym.rates]  # d g_s / d x_r
    d_node_u = [[g.diff(u) for u in sym.u] for g in sym.rates]  # d g_s / d u_m
    own = [f"a{m}_{r}" for m in range(n_u) for r in range(n_s)]
    flat_i = [d_edge_i[m][r] for m in range(n_u) for r in range(n_s)]
    gx = [f"gx{s}_{r}" for s in range(n_s) for r in range(n_s)]
    gu = [f"gu{s}_{m}" for s in range(n_s) for m in range(n_u)]
    node_flat = [d_node_x[s][r] for s in range(n_s) for r in range(n_s)]
    node_flat += [d_node_u[s][m] for s in range(n_s) for m in range(n_u)]
    hj = [f"hj{m}_{r}" for m in range(n_u) for r in range(n_s)]
    flat_j = [d_edge_j[m][r] for m in range(n_u) for r in range(n_s)]
    every = edge_exprs + flat_i + flat_j + node_flat
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_jac(y, wq, indptr, indices, P, jq):",
        "    n = indptr.shape[0] - 1",
        "    for i in range(n):",
        # node i's S rows are stored one after another, each S (1 + deg_i) long, after those of
        # the nodes before it (the layout expanded_pattern maps to the pattern's order)
        "        rowlen = S * (1 + indptr[i + 1] - indptr[i])",
        "        base = S * (S * i + S * indptr[i])",
    ]
    out += _node_loads(every, sym)
    out += [f"        {u} = 0.0" for u in sym.u]
    out += [f"        {a} = 0.0" for a in own]
    out += _link_loop(edge_exprs + flat_i, sym)
    out += _block(edge_exprs + flat_i, [str(u) for u in sym.u] + own, "            ", pr, accumulate=True)
    out += _block(node_flat, gx + gu, "        ", pr)
    # the diagonal block
    for s in range(n_s):
        for r in range(n_s):
            chain = " + ".join([f"gx{s}_{r}"] + [f"gu{s}_{m} * a{m}_{r}" for m in range(n_u)])
            out.append(f"        jq[base + {s} * rowlen + {r}] = {chain}")
    out += _link_loop(flat_j, sym)
    out += ["            at = base + S + S * (q - indptr[i])"]
    out += _block(flat_j, hj, "            ", pr)
    for s in range(n_s):
        for r in range(n_s):
            chain = " + ".join(f"gu{s}_{m} * hj{m}_{r}" for m in range(n_u))
            out.append(f"            jq[at + {s} * rowlen + {r}] = {chain}")
    out += ["", ""]
    out += _adjoint_source(sym, pr)
    out += _circle_source(sym, circle_form(sym), pr)
    return "\n".join(out) + _DRIVERS + _ADJOINT_DRIVERS + _TRIP_DRIVERS


def _frequency_exprs(sym) -> tuple:
    """``(f, fj, qs, read, du, rates, edge, edge_rates)`` of :func:`_frequency_source`: the rate
    symbols of a node and its neighbour, the quantities, the inputs they read (their indices
    and rate symbols), the quantities' rates, those inputs' edge laws and the edge laws' rates
    (each function of the edge parameters alone read as its row: :func:`_link_part`)."""
    import sympy

    n_s = len(sym.x)
    f = sympy.symbols(f"f0:{n_s}", real=True)
    fj = sympy.symbols(f"fj0:{n_s}", real=True)
    qs = list(sym.frequency)
    read = [m for m, u in enumerate(sym.u) if any(q.has(u) for q in qs)]
    du = {m: sympy.Symbol(f"du{m}", real=True) for m in read}
    rates = [
        sum((q.diff(x) * fk for x, fk in zip(sym.x, f, strict=True)), sympy.Integer(0))
        + sum((q.diff(sym.u[m]) * du[m] for m in read), sympy.Integer(0))
        for q in qs
    ]
    edge = [sym.coupling[m] for m in read]
    edge_rates = [
        sum(
            (h.diff(x) * fk + h.diff(xj) * fjk for x, xj, fk, fjk in zip(sym.x, sym.xj, f, fj, strict=True)),
            sympy.Integer(0),
        )
        for h in edge
    ]
    # a function of the edge parameters alone is read from its row (with_derived)
    edge = [_link_part(h, sym) for h in edge]
    edge_rates = [_link_part(h, sym) for h in edge_rates]
    return f, fj, qs, read, du, rates, edge, edge_rates


def _lane_frequency_source(sym, pr) -> list[str]:
    """``circle_lane_devs(y, f, lw, indptr, indices, P, DV, L)``: ``circle_law_devs`` of every lane
    (``DV`` flat, row ``r`` of node ``i`` in lane ``q`` at ``(r n + i) L + q``), the same operations
    in the same order on lane vectors: the same bits."""
    import sympy

    f, fj, qs, read, du, rates, edge, edge_rates = _frequency_exprs(sym)
    every = qs + rates + edge + edge_rates
    at = "({k} * n + i) * L + o"
    out = [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def circle_lane_devs(y, f, lw, indptr, indices, P, DV, L):",
        "    n = indptr.shape[0] - 1",
        "    nnz = indices.shape[0]",
        "    for i in range(n):",
        "        for o in range(0, L, VEC):",
    ]
    out += _loads(every, sym.x, "            ", f"vload(y, {at})")
    out += _loads(every, sym.p, "            ", f"vload(P, {at})")
    out += _loads(every, f, "            ", f"vload(f, {at})")
    if read:
        out += [f"            {sym.u[m]} = vsplat(0.0)" for m in read]
        out += [f"            {du[m]} = vsplat(0.0)" for m in read]
        links = edge + edge_rates
        out += ["            for e in range(indptr[i], indptr[i + 1]):", "                j = indices[e]"]
        out += ["                w = vload(lw, e * L + o)"]
        near = "({k} * n + j) * L + o"
        out += _loads(links, sym.xj, "                ", f"vload(y, {near})")
        out += _loads(links, sym.pj, "                ", f"vload(P, {near})")
        out += _loads(links, fj, "                ", f"vload(f, {near})")
        edge_rows = (*sym.e, *_derived_symbols(sym))
        out += _loads(links, edge_rows, "                ", "vload(P, (NP * n + {k} * nnz + e) * L + o)")
        subs, reduced = sympy.cse(links, symbols=sympy.numbered_symbols("c"), optimizations="basic")
        out += [f"                {c} = {pr.doprint(e)}" for c, e in subs]
        targets = [str(sym.u[m]) for m in read] + [str(du[m]) for m in read]
        out += [f"                {t} = {t} + {pr.doprint(e)}" for t, e in zip(targets, reduced, strict=True)]
    pairs = [e for pair in zip(qs, rates, strict=True) for e in pair]
    rows = [("DV", at.format(k=r)) for r in range(2 * len(qs))]
    out += _vec_block(pairs, rows, "            ", pr)
    out += [
        "    for row in range(2 * KF):",
        "        for o in range(0, L, VEC):",
        "            mean = vsplat(0.0)",
        "            for i in range(n):",
        "                mean = mean + vload(DV, (row * n + i) * L + o)",
        "            for i in range(n):",
        "                vstore(DV, (row * n + i) * L + o, vload(DV, (row * n + i) * L + o) - mean / n)",
    ]
    return out


def _frequency_source(sym, pr, prefix: str = "", raw: bool = False) -> list[str]:
    """``law_devs(y, f, wq, indptr, indices, P, D)`` (``prefix`` before its name): the frequency
    criterion's quantities ``q_k`` (``sym.frequency``) minus their means in ``D``'s rows ``2 k``
    and their rates minus theirs in rows ``2 k + 1`` (``KF`` quantities), the rates by the chain
    rule: ``dq/dt = dq/dx . f + dq/du . du/dt``, ``du_i/dt = sum_j (dh/dx_i . f_i + dh/dx_j .
    f_j)`` over the in-links (what the cubic Hermite crossing of the frequency criterion needs,
    as the built-in kernels' ``deviations``). With ``raw``: ``law_freqs``, the quantities and
    their rates themselves (a line trip's largest frequency, :data:`_TRIP_DRIVERS`)."""
    f, fj, qs, read, du, rates, edge, edge_rates = _frequency_exprs(sym)
    every = qs + rates + edge + edge_rates
    out = [] if prefix or raw else ["", "", f"KF = {len(qs)}"]
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        f"def {prefix}law_{'freqs' if raw else 'devs'}(y, f, wq, indptr, indices, P, D):",
        "    n = indptr.shape[0] - 1",
        "    for i in range(n):",
    ]
    out += _node_loads(every, sym)
    out += _loads(every, f, "        ", "f[{k} * n + i]")
    if read:
        out += [f"        {sym.u[m]} = 0.0" for m in read]
        out += [f"        {du[m]} = 0.0" for m in read]
        out += _link_loop(edge + edge_rates, sym)
        out += _loads(edge_rates, fj, "            ", "f[{k} * n + j]")
        targets = [str(sym.u[m]) for m in read] + [str(du[m]) for m in read]
        out += _block(edge + edge_rates, targets, "            ", pr, accumulate=True)
    rows = [f"D[{2 * k + r}, i]" for k in range(len(qs)) for r in range(2)]
    out += _block([e for pair in zip(qs, rates, strict=True) for e in pair], rows, "        ", pr)
    if raw:
        return out
    out += [
        "    for row in range(2 * KF):",
        "        mean = 0.0",
        "        for i in range(n):",
        "            mean += D[row, i]",
        "        for i in range(n):",
        "            D[row, i] -= mean / n",
    ]
    return out


def _vjp_source(sym, pr, name: str) -> list[str]:
    """``name(y, wq, indptr, indices, P, a, out_y, out_w)``: ``out_y += J^T a`` and ``out_w[q] +=
    (d f / d w_q)^T a`` of the law ``sym`` (its rates ``f`` of its states ``y``)."""
    n_s, n_u = len(sym.x), len(sym.u)
    node = list(sym.rates)
    edge = list(sym.coupling)
    gx = [g.diff(x) for g in node for x in sym.x]  # index s * S + r
    gu = [g.diff(u) for g in node for u in sym.u]  # index s * U + m
    hi = [h.diff(x) for h in edge for x in sym.x]  # index m * S + r
    hj = [h.diff(x) for h in edge for x in sym.xj]
    hw = [h.diff(sym.w) for h in edge]
    out = [
        '@njit(cache=True, error_model="numpy")',
        f"def {name}(y, wq, indptr, indices, P, a, out_y, out_w):",
        "    n = indptr.shape[0] - 1",
        "    for i in range(n):",
    ]
    out += _node_loads(node + edge + hi + hj + hw, sym)
    needs_u = any(e.has(u) for e in gx + gu for u in sym.u)
    if needs_u:
        out += [f"        {u} = 0.0" for u in sym.u]
        out += _link_loop(edge, sym)
        out += _block(edge, [str(u) for u in sym.u], "            ", pr, accumulate=True)
    names_x = [f"gx{s}_{r}" for s in range(n_s) for r in range(n_s)]
    names_u = [f"gu{s}_{m}" for s in range(n_s) for m in range(n_u)]
    out += _block(gx + gu, names_x + names_u, "        ", pr)
    out += [f"        a{s} = a[{s} * n + i]" for s in range(n_s)]
    for r in range(n_s):
        terms = " + ".join(f"a{s} * gx{s}_{r}" for s in range(n_s))
        out.append(f"        out_y[{r} * n + i] += {terms}")
    for m in range(n_u):
        terms = " + ".join(f"a{s} * gu{s}_{m}" for s in range(n_s))
        out.append(f"        b{m} = {terms}")
    out += _link_loop(hi + hj + hw, sym)
    names = [f"hi{m}_{r}" for m in range(n_u) for r in range(n_s)]
    names += [f"hj{m}_{r}" for m in range(n_u) for r in range(n_s)]
    names += [f"hw{m}" for m in range(n_u)]
    out += _block(hi + hj + hw, names, "            ", pr)
    for r in range(n_s):
        own = " + ".join(f"b{m} * hi{m}_{r}" for m in range(n_u))
        other = " + ".join(f"b{m} * hj{m}_{r}" for m in range(n_u))
        out.append(f"            out_y[{r} * n + i] += {own}")
        out.append(f"            out_y[{r} * n + j] += {other}")
    out.append("            out_w[q] += " + " + ".join(f"b{m} * hw{m}" for m in range(n_u)))
    return out


def _frequency_symbolic(sym):
    """The law whose vector-Jacobian product is the frequency criterion's crossing seed
    (``freq_vjp``, ``law_freq_seed``): its states the law's ``x`` and their rates ``f``, its
    inputs the law's ``u`` and their rates ``du = sum_j (dh/dx_i f_i + dh/dx_j f_j)``, its
    "rates" the criterion's quantities ``q_k`` (rows ``0 .. KF - 1``) and their rates ``dq_k/dt
    = dq/dx . f + dq/du . du`` (rows ``KF .. 2 KF - 1``), zero after them (padded with unread
    states where ``2 KF`` exceeds ``2 S``)."""
    import sympy

    n_s, n_u = len(sym.x), len(sym.u)
    f = sympy.symbols(f"f0:{n_s}", real=True)
    fj = sympy.symbols(f"fj0:{n_s}", real=True)
    du = sympy.symbols(f"du0:{n_u}", real=True) if n_u else ()
    qs = list(sym.frequency)
    rates = [
        sum((q.diff(x) * fk for x, fk in zip(sym.x, f, strict=True)), sympy.Integer(0))
        + sum((q.diff(u) * d for u, d in zip(sym.u, du, strict=True)), sympy.Integer(0))
        for q in qs
    ]
    dh = [
        sum(
            (h.diff(x) * fk + h.diff(xj) * fjk for x, xj, fk, fjk in zip(sym.x, sym.xj, f, fj, strict=True)),
            sympy.Integer(0),
        )
        for h in sym.coupling
    ]
    width = max(2 * n_s, 2 * len(qs))
    pad = sympy.symbols(f"pad0:{width - 2 * n_s}", real=True) if width > 2 * n_s else ()
    padj = sympy.symbols(f"padj0:{width - 2 * n_s}", real=True) if width > 2 * n_s else ()
    return dataclasses.replace(
        sym,
        x=(*sym.x, *f, *pad),
        xj=(*sym.xj, *fj, *padj),
        u=(*sym.u, *du),
        coupling=(*sym.coupling, *dh),
        rates=(*qs, *rates, *([sympy.Integer(0)] * (width - 2 * len(qs)))),
    )


def _adjoint_source(sym, pr) -> list[str]:
    """``law_vjp`` (``out_y += J^T a``, ``out_w[q] += (d f / d w_q)^T a``) and ``law_grads``
    (``gR = dR/dy`` and the part of ``d Rdot / dy`` that is not ``J^T gR``): what the adjoint of
    the steps and of the crossing needs (:data:`_ADJOINT_DRIVERS`)."""
    import sympy

    out = _vjp_source(sym, pr, "law_vjp")
    freq = _frequency_symbolic(sym)
    out += ["", "", f"FREQ_STATES = {len(freq.x)}", "", ""] + _vjp_source(freq, pr, "freq_vjp")
    n_s = len(sym.x)
    # R = C^2 + S^2, Rdot = 2 (C A + S B): A = -sum sin(phi) phi', B = sum cos(phi) phi'
    # (law_sums' four sums)
    f = [sympy.Symbol(f"f{k}") for k in range(n_s)]
    grad = list(sym.phase_gradient)
    rate = sum((g * fk for g, fk in zip(grad, f, strict=True)), sympy.Integer(0))
    hess_f = [sum((grad[r].diff(sym.x[t]) * f[t] for t in range(n_s)), sympy.Integer(0)) for r in range(n_s)]
    second = [sym.phase, rate, *grad, *hess_f]
    out += [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def law_grads(y, f, P, n, gR, gRd):",
        "    tc, ts, ta, tb = law_sums(y, f, P, n)",
        "    for i in range(n):",
    ]
    out += _node_loads(second, sym)
    out += [f"        f{k} = f[{k} * n + i]" for k in range(n_s)]
    out += _block(
        second, ["ph", "rate", *[f"d{r}" for r in range(n_s)], *[f"e{r}" for r in range(n_s)]], "        ", pr
    )
    out += [
        "        co = math.cos(ph)",
        "        si = math.sin(ph)",
        "        c1 = 2.0 * (-tc * si + ts * co)",
        "        c2 = 2.0 * (-si * ta + co * tb) + 2.0 * (-tc * co - ts * si) * rate",
    ]
    for r in range(n_s):
        out.append(f"        gR[{r} * n + i] = c1 * d{r}")
        out.append(f"        gRd[{r} * n + i] = c2 * d{r} + c1 * e{r}")
    out += ["", ""]
    return out


def expanded_pattern(indptr: np.ndarray, indices: np.ndarray, n_states: int) -> tuple[np.ndarray, ...]:
    """The Jacobian's CSR pattern for ``n_states`` states per node: row ``s n + i`` holds
    ``(r, i)`` for every state ``r``, then ``(r, j)`` for each in-neighbour ``j`` in CSR order
    (``law_jac`` writes its entries in that order; a neighbour that is the node itself is
    allowed, its entries then sit twice in the row and the factorization adds them)."""
    indptr = np.asarray(indptr, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    n = indptr.size - 1
    S = n_states
    rows = []
    # law_jac's layout is node-major: node i's S rows are consecutive blocks of length
    # S (1 + deg_i); expanded row (s, i) is stored at row index s n + i of the pattern
    ptr = np.zeros(S * n + 1, dtype=np.int64)
    cols = np.empty(S * S * (n + indices.size), dtype=np.int64)
    order = np.empty(S * n, dtype=np.int64)  # storage block of row s n + i
    at = 0
    for i in range(n):
        nb = indices[indptr[i] : indptr[i + 1]]
        line = [r * n + i for r in range(S)] + [r * n + int(j) for j in nb for r in range(S)]
        for s in range(S):
            cols[at : at + len(line)] = line
            order[s * n + i] = at
            at += len(line)
        rows.append(len(line))
    # the pattern in row order (s n + i): gather the node-major storage
    lengths = np.array([rows[r % n] for r in range(S * n)], dtype=np.int64)
    ptr[1:] = np.cumsum(lengths)
    out = np.empty(ptr[-1], dtype=np.int64)
    perm = np.empty(ptr[-1], dtype=np.int64)  # pattern position -> law_jac position
    for r in range(S * n):
        out[ptr[r] : ptr[r + 1]] = cols[order[r] : order[r] + lengths[r]]
        perm[ptr[r] : ptr[r + 1]] = np.arange(order[r], order[r] + lengths[r])
    return ptr, out, perm


# The drivers: generic in the law (they call law_rhs, law_order, law_start, law_jac above).
_DRIVERS = '''
@njit(cache=True, error_model="numpy")
def law_advance(y, out, f, wq, indptr, indices, P, dt, rk4, k2, k3, k4, z, G):
    """out = one Euler or RK4 step from y (f = law_rhs at y); out may be y."""
    m = y.shape[0]
    if not rk4:
        for a in range(m):
            out[a] = y[a] + dt * f[a]
        return
    h = 0.5 * dt
    for a in range(m):
        z[a] = y[a] + h * f[a]
    law_rhs(z, wq, indptr, indices, P, k2, G)
    for a in range(m):
        z[a] = y[a] + h * k2[a]
    law_rhs(z, wq, indptr, indices, P, k3, G)
    for a in range(m):
        z[a] = y[a] + dt * k3[a]
    law_rhs(z, wq, indptr, indices, P, k4, G)
    for a in range(m):
        out[a] = y[a] + dt / 6.0 * (f[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a])


@njit(cache=True, error_model="numpy")
def law_sync(y, wq, indptr, indices, P, dt, rk4, freq, target, max_steps):
    """Euler or RK4 from y to the order-parameter criterion, or with freq to the frequency
    criterion (every deviation of law_devs below target): (status, steps, frac)."""
    n = indptr.shape[0] - 1
    m = y.shape[0]
    G = np.empty((rhs_rows(n, indices.shape[0]), n))
    f = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    z = np.empty(m)
    D = np.empty((2 * KF, n))
    Dp = np.empty((2 * KF, n))
    law_rhs(y, wq, indptr, indices, P, f, G)
    r2 = 0.0
    dr2 = 0.0
    if freq:
        law_devs(y, f, wq, indptr, indices, P, D)
        dev = law_deviation(D, D, n, dt, rk4, 1.0)
        if dev != dev:
            return NOT_SYNCED, max_steps, 0.0
        if dev < target:
            return ALREADY_SYNCED, 0, 0.0
    else:
        r2, dr2 = law_order(y, f, P, n)
        if not (r2 == r2 and dr2 == dr2):
            return NOT_SYNCED, max_steps, 0.0
        if r2 >= target:
            return ALREADY_SYNCED, 0, 0.0
    for step in range(1, max_steps + 1):
        law_advance(y, y, f, wq, indptr, indices, P, dt, rk4, k2, k3, k4, z, G)
        law_rhs(y, wq, indptr, indices, P, f, G)
        if freq:
            D, Dp = Dp, D
            law_devs(y, f, wq, indptr, indices, P, D)
            dev = law_deviation(D, Dp, n, dt, rk4, 1.0)
            if dev != dev:
                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized
            x = frequency_crossing(D, Dp, n, dt, rk4, target)
        else:
            r2_prev = r2
            dr2_prev = dr2
            r2, dr2 = law_order(y, f, P, n)
            if not (r2 == r2 and dr2 == dr2):
                return NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized
            x = order_crossing(r2_prev, dr2_prev, r2, dr2, dt, rk4, target)
        if x >= 0.0:
            return SYNCED, step, x
    return NOT_SYNCED, max_steps, 0.0


@njit(cache=True, error_model="numpy")
def rodas4_work(n, nnz, m, plan, jperm):
    """The arrays of rodas4_attempt: (G, u, f, d, z, b, x, xp, jq, val)."""
    return (
        np.empty((rhs_rows(n, nnz), n)),
        np.zeros((6, m)),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(jperm.shape[0]),
        np.empty(plan[3].shape[0]),
    )


@njit(cache=True, error_model="numpy")
def rodas4_attempt(y, wq, indptr, indices, P, f0, h, rtol, atol, plan, jperm, work):
    """One Rodas4 step of h from y (f0: the rates there; work: rodas4_work's arrays): its stages
    into u, the step's state y + d + u[5]; returns its scaled error, -1 where the matrix did not
    factor."""
    fp_perm, fp_inv, fp_ptr, fp_col, fp_diag, fp_entry = plan[:6]
    div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj = plan[6:]
    G, u, f, d, z, b, x, xp, jq, val = work
    m = y.shape[0]
    g = 1.0 / (h * RGAMMA)
    inv_h = 1.0 / h
    law_jac(y, wq, indptr, indices, P, jq)
    val[:] = 0.0
    scale = 0.0
    for e in range(fp_entry.shape[0]):
        v = jq[jperm[e]]
        val[fp_entry[e]] -= v
        scale = max(scale, abs(v))
    for a in range(m):
        val[fp_diag[fp_inv[a]]] += g
    if not factor(val, fp_diag, div_ptr, div_pos, upd_ptr, upd_ij, upd_ik, upd_kj, scale + g):
        return -1.0
    for stage in range(6):
        if stage == 0:
            for a in range(m):
                f[a] = f0[a]
        else:
            if stage < 5:
                for a in range(m):
                    acc = 0.0
                    for s in range(stage):
                        acc += RA[stage, s] * u[s, a]
                    d[a] = acc
            else:
                for a in range(m):
                    d[a] += u[4, a]
            for a in range(m):
                z[a] = y[a] + d[a]
            law_rhs(z, wq, indptr, indices, P, f, G)
        for a in range(m):
            acc = f[a]
            for s in range(stage):
                acc += RC[stage, s] * inv_h * u[s, a]
            b[a] = acc
        solve(val, fp_ptr, fp_col, fp_diag, fp_perm, b, x, xp)
        for a in range(m):
            u[stage, a] = x[a]
    err = 0.0
    for a in range(m):
        yn = y[a] + d[a] + u[5, a]
        e = u[5, a] / (atol + rtol * max(abs(y[a]), abs(yn)))
        err += e * e
    return math.sqrt(err / m)


@njit(cache=True, error_model="numpy")
def law_rodas4(y, wq, indptr, indices, P, freq, target, t_max, h0, rtol, atol, plan, jperm):
    """Rodas4 (the coefficients and controller of antisync.kernels.implicit) from y to the
    order-parameter criterion, or with freq the frequency criterion: (status, tau, accepted,
    rejected, failed)."""
    n = indptr.shape[0] - 1
    m = y.shape[0]
    work = rodas4_work(n, indices.shape[0], m, plan, jperm)
    G, u, d = work[0], work[1], work[3]
    f0 = np.empty(m)
    kept = np.empty(m)
    kept_f = np.empty(m)
    D = np.empty((2 * KF, n))
    Dp = np.empty((2 * KF, n))
    law_rhs(y, wq, indptr, indices, P, f0, G)
    r2 = 0.0
    dr2 = 0.0
    if freq:
        law_devs(y, f0, wq, indptr, indices, P, D)
        dev = law_deviation(D, D, n, 0.0, False, 1.0)
        if dev != dev:
            return NOT_SYNCED, 0.0, 0, 0, False  # not finite at the start: never synchronized
        if dev < target:
            return ALREADY_SYNCED, 0.0, 0, 0, False
    else:
        r2, dr2 = law_order(y, f0, P, n)
        if not (r2 == r2 and dr2 == dr2):
            return NOT_SYNCED, 0.0, 0, 0, False  # not finite at the start: never synchronized
        if r2 >= target:
            return ALREADY_SYNCED, 0.0, 0, 0, False
    t = 0.0
    h = min(h0, t_max)
    h_cap = t_max
    cap_until = 0.0
    err_prev = 1.0
    accepted = 0
    rejected = 0
    in_row = 0
    while t < t_max:
        if h < support.H_FLOOR * t_max or in_row > support.MAX_REJECTS:
            return NOT_SYNCED, t, accepted, rejected, True
        last = False
        if t + h >= t_max:
            h = t_max - t
            last = True
        err = rodas4_attempt(y, wq, indptr, indices, P, f0, h, rtol, atol, plan, jperm, work)
        if err < 0.0:  # the matrix did not factor
            h *= 0.25
            rejected += 1
            in_row += 1
            continue
        if not err <= 1.0:
            h *= max(support.SHRINK, min(1.0, support.SAFETY * err**-0.25 if err == err else support.SHRINK))
            rejected += 1
            in_row += 1
            continue
        in_row = 0
        accepted += 1
        for a in range(m):
            kept[a] = y[a]
            kept_f[a] = f0[a]
            y[a] += d[a] + u[5, a]
        t_prev = t
        t = t_max if last else t + h
        r2_prev = r2
        dr2_prev = dr2
        law_rhs(y, wq, indptr, indices, P, f0, G)
        if freq:
            D, Dp = Dp, D
            law_devs(y, f0, wq, indptr, indices, P, D)
            dev = law_deviation(D, Dp, n, 0.0, False, 1.0)
            if dev != dev:
                return NOT_SYNCED, t, accepted, rejected, False  # diverged: never synchronized
            xc = frequency_crossing(D, Dp, n, t - t_prev, True, target)
        else:
            r2, dr2 = law_order(y, f0, P, n)
            if not (r2 == r2 and dr2 == dr2):
                return NOT_SYNCED, t, accepted, rejected, False  # diverged: never synchronized
            xc = order_crossing(r2_prev, dr2_prev, r2, dr2, t - t_prev, True, target)
        if xc >= 0.0:
            if freq:
                xl = frequency_crossing(D, Dp, n, t - t_prev, False, target)
            else:
                xl = order_crossing(r2_prev, dr2_prev, r2, dr2, t - t_prev, False, target)
            tau = t_prev + xc * (t - t_prev)
            if (xl >= 0.0 and abs(xc - xl) * (t - t_prev) <= support.CROSSING_RTOL * tau) or (
                t - t_prev <= support.H_FLOOR * 1e3 * t_max
            ):
                return SYNCED, tau, accepted, rejected, False
            for a in range(m):
                y[a] = kept[a]
                f0[a] = kept_f[a]
            if freq:
                D, Dp = Dp, D  # the deviations at the step's start again
            r2 = r2_prev
            dr2 = dr2_prev
            h_cap = support.REFINE * (t - t_prev)
            cap_until = t
            h = h_cap
            t = t_prev
            accepted -= 1
            continue
        err = max(err, 1e-10)
        fac = support.SAFETY * err**-support.BETA1 * err_prev**support.BETA2
        err_prev = err
        if t >= cap_until:
            h_cap = t_max
        h = min(h * max(support.SHRINK, min(support.GROW, fac)), h_cap)
        if freq:
            h = min(h, near_step(D, n, target))
        elif dr2 != 0.0:
            h = min(h, support.NEAR * max(target - r2, n * n - target) / abs(dr2))
    return NOT_SYNCED, t_max, accepted, rejected, False


@njit(cache=True, error_model="numpy")
def item_start(ks, seed, indptr, base_w, var_w, var_is_base, todo, PR, item, per):
    """(r, v, run, y, w, P): the item's realization and network, whether it runs, its start,
    its weights and its parameters (PR: one (n_params, n) block, or one per realization)."""
    r, v, run = item_of(item, per, var_is_base, todo)
    n = indptr.shape[0] - 1
    P = PR[0] if PR.shape[0] == 1 else PR[r]
    y = np.empty(S * n)
    if run:
        law_start(seed, ks[r], P, y, n)
    return r, v, run, y, base_w if v < 0 else var_w[v], P


@njit(cache=True, error_model="numpy")
def law_item_rodas4(ks, seed, indptr, indices, base_w, var_w, var_is_base, todo, PR, targets, clock, plan,
                    jperm, status0, steps0, frac0, status, steps, frac, collapsed, item):
    dt, t_max, max_steps, method, rtol, atol, criterion = clock
    per = var_w.shape[0] + 1
    r, v, run, y, w, P = item_start(ks, seed, indptr, base_w, var_w, var_is_base, todo, PR, item, per)
    if not run:
        return
    st, tau, acc, rej, failed = law_rodas4(
        y, w, indptr, indices, P, criterion == 1, targets[v + 1], t_max, dt, rtol, atol, plan, jperm
    )
    k, x = support.on_the_grid(st, tau, dt, int(max_steps))
    if failed:  # the step size collapsed: reported by simulate_law, never a status
        collapsed[r, v + 1] = True
        st = NOT_SYNCED
        k = int(max_steps)
        x = 0.0
    record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)
''' + "".join(
    # an explicit integrator's item: the start, its integration, its record
    f"""

@njit(cache=True, error_model="numpy")
def law_item_{kind}(ks, seed, indptr, indices, base_w, var_w, var_is_base, todo, PR, targets, clock, plan,
                    jperm, status0, steps0, frac0, status, steps, frac, collapsed, item):
    dt, t_max, max_steps, method, rtol, atol, criterion = clock
    per = var_w.shape[0] + 1
    r, v, run, y, w, P = item_start(ks, seed, indptr, base_w, var_w, var_is_base, todo, PR, item, per)
    if not run:
        return
    st, k, x = {sync}(y, w, indptr, indices, P, dt, {which}criterion == 1, targets[v + 1], int(max_steps))
    record(status0, steps0, frac0, status, steps, frac, r, v, st, k, x)
"""
    for kind, sync, which in (
        ("explicit", "law_sync", "method == 1, "),
        ("circle", "circle_sync", ""),
        ("circle_euler", "circle_euler_sync", ""),
    )
)


_ADJOINT_DRIVERS = '''

@njit(cache=True, error_model="numpy")
def law_step_adjoint(y, lam, wq, indptr, indices, P, dt, rk4, gw, kk, z, mu, kap, total, G):
    """lam <- the adjoint of one step from y (Euler or RK4), gw += its weight gradient.

    RK4's stages backwards, 4 to 1: stage s is evaluated at z_s = y + c_s k_(s-1) and its
    adjoint input is kap_s = b_s lam + a_s mu_(s+1), mu_s = J(z_s)^T kap_s; the new lam is lam
    plus every mu_s (kk holds k1 = f(y), k2, k3)."""
    m = y.shape[0]
    if not rk4:
        for a in range(m):
            kap[a] = dt * lam[a]
            mu[a] = 0.0
        law_vjp(y, wq, indptr, indices, P, kap, mu, gw)
        for a in range(m):
            lam[a] += mu[a]
        return
    h = 0.5 * dt
    law_rhs(y, wq, indptr, indices, P, kk[0], G)
    for a in range(m):
        z[a] = y[a] + h * kk[0, a]
    law_rhs(z, wq, indptr, indices, P, kk[1], G)
    for a in range(m):
        z[a] = y[a] + h * kk[1, a]
    law_rhs(z, wq, indptr, indices, P, kk[2], G)
    c = (dt, h, h, 0.0)
    b = (dt / 6.0, dt / 3.0, dt / 3.0, dt / 6.0)
    after = (0.0, dt, h, h)
    for a in range(m):
        total[a] = 0.0
        mu[a] = 0.0
    for stage in range(4):  # stages 4, 3, 2, 1
        row = 2 - stage
        for a in range(m):
            z[a] = y[a] + c[stage] * kk[row, a] if stage < 3 else y[a]
            kap[a] = b[stage] * lam[a] + after[stage] * mu[a]
            mu[a] = 0.0
        law_vjp(z, wq, indptr, indices, P, kap, mu, gw)
        for a in range(m):
            total[a] += mu[a]
    for a in range(m):
        lam[a] += total[a]


@njit(cache=True, error_model="numpy")
def law_crossing_seed(y, wq, indptr, indices, P, cr, cm, lam, gw, f, gR, gRd, mu, sc, G):
    \"\"\"lam += cr dR/dy + cm dRdot/dy at y and gw += cm dRdot/dw, with dRdot/dy = gRd + J^T gR
    and dRdot/dw = (df/dw)^T gR (law_grads, law_vjp).\"\"\"
    n = indptr.shape[0] - 1
    m = y.shape[0]
    law_rhs(y, wq, indptr, indices, P, f, G)
    law_grads(y, f, P, n, gR, gRd)
    for a in range(m):
        mu[a] = 0.0
        sc[a] = cm * gR[a]
    law_vjp(y, wq, indptr, indices, P, sc, mu, gw)
    for a in range(m):
        lam[a] += cr * gR[a] + cm * gRd[a] + mu[a]


@njit(cache=True, error_model="numpy")
def law_freq_seed(y, wq, indptr, indices, P, k, i, cq, cr, lam, gw, f, ya, a, oa, G):
    """lam += d(cq D + cr dD/dt)/dy and gw += the same by w, D the deviation of the frequency
    criterion's quantity k at node i from its mean: freq_vjp on (y, f) (the quantities and
    their rates as functions of the states and their rates), then its part by f through
    J^T (law_vjp)."""
    n = indptr.shape[0] - 1
    m = y.shape[0]
    law_rhs(y, wq, indptr, indices, P, f, G)
    ya[:] = 0.0
    copy_into(ya[:m], y)
    copy_into(ya[m : 2 * m], f)
    a[:] = 0.0
    oa[:] = 0.0
    for j in range(n):
        a[k * n + j] = -cq / n
        a[(KF + k) * n + j] = -cr / n
    a[k * n + i] += cq
    a[(KF + k) * n + i] += cr
    freq_vjp(ya, wq, indptr, indices, P, a, oa, gw)
    for b in range(m):
        lam[b] += oa[b]
    law_vjp(y, wq, indptr, indices, P, oa[m : 2 * m], lam, gw)


@njit(cache=True, error_model="numpy")
def law_adjoint_forward(y0, wq, indptr, indices, P, dt, rk4, freq, target, max_steps):
    """The forward pass of the adjoint: (status, steps, frac, ys), ys the states at every step
    (steps + 1 rows; only the start unless SYNCED)."""
    n = indptr.shape[0] - 1
    m = y0.shape[0]
    G = np.empty((rhs_rows(n, indices.shape[0]), n))
    y = y0.copy()
    st, steps, x = law_sync(y, wq, indptr, indices, P, dt, rk4, freq, target, max_steps)
    if st != SYNCED:
        return st, steps, x, np.empty((1, m))
    ys = np.empty((steps + 1, m))
    copy_into(ys[0], y0)
    f = np.empty(m)
    z = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    for k in range(1, steps + 1):
        law_rhs(ys[k - 1], wq, indptr, indices, P, f, G)
        law_advance(ys[k - 1], ys[k], f, wq, indptr, indices, P, dt, rk4, k2, k3, k4, z, G)
    return st, steps, x, ys


@njit(cache=True, error_model="numpy")
def law_adjoint_one(y0, wq, indptr, indices, P, dt, rk4, target, max_steps, gw):
    """d tau0 / d w_q of one trajectory to the order-parameter criterion (gw, zero unless
    SYNCED): (status, steps, frac, d tau0 / d target), the last 0 unless SYNCED."""
    n = indptr.shape[0] - 1
    m = y0.shape[0]
    st, steps, x, ys = law_adjoint_forward(y0, wq, indptr, indices, P, dt, rk4, False, target, max_steps)
    if st != SYNCED:
        return st, steps, x, 0.0
    G = np.empty((rhs_rows(n, indices.shape[0]), n))
    f = np.empty(m)
    law_rhs(ys[steps - 1], wq, indptr, indices, P, f, G)
    r0, d0 = law_order(ys[steps - 1], f, P, n)
    law_rhs(ys[steps], wq, indptr, indices, P, f, G)
    r1, d1 = law_order(ys[steps], f, P, n)
    c0, e0, c1, e1, ct = law_crossing_weights(r0, d0, r1, d1, dt, rk4, x)
    lam = np.zeros(m)
    gR = np.empty(m)
    gRd = np.empty(m)
    mu = np.empty(m)
    kap = np.empty(m)
    kk = np.empty((3, m))
    total = np.empty(m)
    z = np.empty(m)
    net = (wq, indptr, indices, P)
    law_crossing_seed(ys[steps], *net, c1, e1, lam, gw, f, gR, gRd, mu, kap, G)
    for k in range(steps, 0, -1):
        law_step_adjoint(ys[k - 1], lam, wq, indptr, indices, P, dt, rk4, gw, kk, z, mu, kap, total, G)
        if k == steps:
            law_crossing_seed(ys[k - 1], *net, c0, e0, lam, gw, f, gR, gRd, mu, kap, G)
    return st, steps, x, ct


@njit(cache=True, error_model="numpy")
def law_adjoint_one_freq(y0, wq, indptr, indices, P, dt, rk4, target, max_steps, gw):
    """law_adjoint_one to the frequency criterion: the crossing is that of the deviation whose
    interpolant sets it (law_binding), its seed law_freq_seed. Its own function, so that the
    order-parameter adjoint does not compile freq_vjp. The tolerance does not move with the
    weights: its d tau0 / d target is returned as 0."""
    n = indptr.shape[0] - 1
    m = y0.shape[0]
    st, steps, x, ys = law_adjoint_forward(y0, wq, indptr, indices, P, dt, rk4, True, target, max_steps)
    if st != SYNCED:
        return st, steps, x, 0.0
    G = np.empty((rhs_rows(n, indices.shape[0]), n))
    f = np.empty(m)
    Dp = np.empty((2 * KF, n))
    D = np.empty((2 * KF, n))
    law_rhs(ys[steps - 1], wq, indptr, indices, P, f, G)
    law_devs(ys[steps - 1], f, wq, indptr, indices, P, Dp)
    law_rhs(ys[steps], wq, indptr, indices, P, f, G)
    law_devs(ys[steps], f, wq, indptr, indices, P, D)
    bk, bi = law_binding(D, Dp, n, dt, rk4, x)
    r0, d0, r1, d1 = Dp[2 * bk, bi], Dp[2 * bk + 1, bi], D[2 * bk, bi], D[2 * bk + 1, bi]
    c0, e0, c1, e1, _ = law_crossing_weights(r0, d0, r1, d1, dt, rk4, x)
    lam = np.zeros(m)
    mu = np.empty(m)
    kap = np.empty(m)
    kk = np.empty((3, m))
    total = np.empty(m)
    z = np.empty(m)
    width = FREQ_STATES * n
    ya = np.empty(width)
    a = np.empty(width)
    oa = np.empty(width)
    net = (wq, indptr, indices, P)
    law_freq_seed(ys[steps], *net, bk, bi, c1, e1, lam, gw, f, ya, a, oa, G)
    for k in range(steps, 0, -1):
        law_step_adjoint(ys[k - 1], lam, wq, indptr, indices, P, dt, rk4, gw, kk, z, mu, kap, total, G)
        if k == steps:
            law_freq_seed(ys[k - 1], *net, bk, bi, c0, e0, lam, gw, f, ya, a, oa, G)
    return st, steps, x, 0.0

'''

#: the adjoint's items, one driver per criterion (each compiles only its own crossing seed)
_ADJOINT_ITEMS = """

@njit(cache=True, error_model="numpy")
def {name}(ks, seed, indptr, indices, wq, PR, dt, rk4, target, max_steps,
        status0, steps0, frac0, gw, coef, r):
    \"\"\"Realization r's start, its forward pass and adjoint (every realization in parallel:
    law_support.each_realization).\"\"\"
    n = indptr.shape[0] - 1
    P = PR[0] if PR.shape[0] == 1 else PR[r]
    y = np.empty(S * n)
    law_start(seed, ks[r], P, y, n)
    st, k, x, c = {one}(y, wq, indptr, indices, P, dt, rk4, target, max_steps, gw[r])
    status0[r] = st
    steps0[r] = k
    frac0[r] = x
    coef[r] = c
"""
_ADJOINT_DRIVERS += _ADJOINT_ITEMS.format(name="law_adjoint_item", one="law_adjoint_one")
_ADJOINT_DRIVERS += _ADJOINT_ITEMS.format(name="law_adjoint_item_freq", one="law_adjoint_one_freq")


# A line trip (the engineer's N-1, antisync.grids.trip) of the law: RK4 at a fixed step from its
# operating point, the fault's weights until t_clear, then the post-trip weights until t_end;
# the settling clock, frequency peak and first swing of antisync.kernels.trip.rk4_trip on the
# law's frequency quantities (law_devs, law_freqs) and phases (law_phases).
_TRIP_DRIVERS = '''

@njit(cache=True, error_model="numpy")
def trip_arrays(n):
    """What a trip keeps of its state now and at the last step's start: the deviations D, Dp, the
    frequency quantities Q, Qp (rows 2 k, their rates 2 k + 1), the phases, their rates and the
    unwrapped phases (ph, dph, u, then p_ph, p_dph, p_u)."""
    return (
        np.empty((2 * KF, n)),
        np.empty((2 * KF, n)),
        np.empty((2 * KF, n)),
        np.empty((2 * KF, n)),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
        np.empty(n),
    )


@njit(cache=True, error_model="numpy")
def trip_eval(y, w, indptr, indices, P, f, G, T):
    """The rates f at y on the weights w, and T's deviations, quantities, phases and rates there."""
    D, Dp, Q, Qp, ph, dph, u, p_ph, p_dph, p_u = T
    law_rhs(y, w, indptr, indices, P, f, G)
    law_devs(y, f, w, indptr, indices, P, D)
    law_freqs(y, f, w, indptr, indices, P, Q)
    law_phases(y, f, P, indptr.shape[0] - 1, ph, dph)


@njit(cache=True, error_model="numpy")
def trip_switch(y, w, indptr, indices, P, f, G, T, t, tol, settle, first):
    """Where a configuration starts (the fault at t = 0, the trip at its clearing time): the
    rates on its weights, the unwrapped phases set at the first, and the settling clock."""
    trip_eval(y, w, indptr, indices, P, f, G, T)
    D, Dp, Q, Qp, ph, dph, u, p_ph, p_dph, p_u = T
    if first:
        copy_into(u, ph)
    return trip_clock(D, D, indptr.shape[0] - 1, t, 0.0, tol, settle, True)


@njit(cache=True, error_model="numpy")
def trip_stepped(y, w, indptr, indices, P, f, G, T, t_prev, step, tol, settle, line, max_f, max_a):
    """After a step to y (T still holds its start): the rates and trip_after's bookkeeping."""
    trip_keep(T)
    trip_eval(y, w, indptr, indices, P, f, G, T)
    return trip_after(T, indptr, indices, t_prev, step, tol, settle, line, max_f, max_a)


@njit(cache=True, error_model="numpy")
def trip_after(T, indptr, indices, t_prev, step, tol, settle, line, max_f, max_a):
    """After a step (T: its end evaluated, its start kept): the unwrapped phases (each turn
    below pi), the swing's maxima and the settling clock over the step's interpolants, as
    (settle, max_f, max_a); line = (ta, tb, keep)."""
    D, Dp, Q, Qp, ph, dph, u, p_ph, p_dph, p_u = T
    for i in range(u.shape[0]):
        turn = ph[i] - p_ph[i]
        u[i] += math.atan2(math.sin(turn), math.cos(turn))
    max_f, max_a = support.trip_swing(
        p_u, p_dph, Qp[0], Qp[1], u, dph, Q[0], Q[1], step, indptr, indices, line, max_f, max_a
    )
    settle = trip_clock(D, Dp, u.shape[0], t_prev, step, tol, settle, False)
    return settle, max_f, max_a


@njit(cache=True, error_model="numpy")
def law_trip(y0, w_fault, w_post, indptr, indices, P, t_clear, t_end, dt, tol, line, out):
    """One trip from the state y0: ceil(t_clear / dt) RK4 steps on w_fault (the last ending at
    t_clear; none without a fault), then ceil((t_end - t_clear) / dt) on w_post (the last ending
    at t_end). out = [settle_time (from t = 0; nan: out of the band at t_end), max |q_0|, max
    line angle difference, failed (1: the state stopped being finite)]; line = (ta, tb, keep)."""
    n = indptr.shape[0] - 1
    m = y0.shape[0]
    G = np.empty((rhs_rows(n, indices.shape[0]), n))
    T = trip_arrays(n)
    y = y0.copy()
    f = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    z = np.empty(m)
    settle = np.nan
    max_f = 0.0
    max_a = 0.0
    t = 0.0
    failed = False
    for stage in range(2):
        if stage == 0 and t_clear <= 0.0:
            continue  # no fault
        w = w_fault if stage == 0 else w_post
        settle = trip_switch(y, w, indptr, indices, P, f, G, T, t, tol, settle, t == 0.0)
        t0 = t
        length = t_clear if stage == 0 else t_end - t_clear
        steps = max(1, int(math.ceil(length / dt - 1e-9)))
        for k in range(steps):
            h = dt if k < steps - 1 else length - (steps - 1) * dt
            law_advance(y, y, f, w, indptr, indices, P, h, True, k2, k3, k4, z, G)
            t_prev = t
            t = t0 + (k + 1) * dt if k < steps - 1 else t0 + length
            settle, max_f, max_a = trip_stepped(
                y, w, indptr, indices, P, f, G, T, t_prev, t - t_prev, tol, settle, line, max_f, max_a
            )
            total = 0.0
            for a in range(m):
                total += y[a]
            if not math.isfinite(total):
                failed = True  # the step is unstable for this grid
                break
        if failed:
            break
    out[0] = np.nan if failed else settle
    out[1] = max_f
    out[2] = max_a
    out[3] = 1.0 if failed else 0.0


@njit(cache=True, error_model="numpy")
def law_rodas4_trip(y0, w_fault, w_post, indptr, indices, P, t_clear, t_end, h0, tols, plan, jperm, line,
                    out):
    """law_trip by Rodas4 with adaptive steps (rodas4_attempt; antisync.kernels.implicit's
    rodas4_trip): the step that would pass t_clear ends there and the next starts afresh at h0;
    within the band's reach a step is at most near_step. tols = (band, rtol, atol); out as
    law_trip's, failed (1) where the step size collapsed (the other values those reached)."""
    tol, rtol, atol = tols
    n = indptr.shape[0] - 1
    m = y0.shape[0]
    work = rodas4_work(n, indices.shape[0], m, plan, jperm)
    G, u, d = work[0], work[1], work[3]
    T = trip_arrays(n)
    y = y0.copy()
    f0 = np.empty(m)
    fault = t_clear > 0.0
    w = w_fault if fault else w_post
    settle = trip_switch(y, w, indptr, indices, P, f0, G, T, 0.0, tol, np.nan, True)
    max_f = 0.0
    max_a = 0.0
    t = 0.0
    end = t_clear if fault else t_end  # the end of the current configuration
    h = min(h0, end)
    err_prev = 1.0
    in_row = 0
    failed = False
    while t < t_end:
        if h < support.H_FLOOR * t_end or in_row > support.MAX_REJECTS:
            failed = True
            break
        last = False
        if t + h >= end:
            h = end - t
            last = True
        err = rodas4_attempt(y, w, indptr, indices, P, f0, h, rtol, atol, plan, jperm, work)
        if not 0.0 <= err <= 1.0:
            h = support.shrunk(h, err)
            in_row += 1
            continue
        in_row = 0
        for a in range(m):
            y[a] += d[a] + u[5, a]
        t_prev = t
        t = end if last else t + h
        settle, max_f, max_a = trip_stepped(
            y, w, indptr, indices, P, f0, G, T, t_prev, t - t_prev, tol, settle, line, max_f, max_a
        )
        # a PI controller (Gustafsson), and within the band's reach at most near_step per step
        err = max(err, 1e-10)
        fac = support.SAFETY * err**-support.BETA1 * err_prev**support.BETA2
        err_prev = err
        h = h * max(support.SHRINK, min(support.GROW, fac))
        if last and t < t_end:  # the fault clears: the grid without the line from this state on
            w = w_post
            end = t_end
            settle = trip_switch(y, w, indptr, indices, P, f0, G, T, t, tol, settle, False)
            h = h0
            err_prev = 1.0
        h = min(h, near_step(T[0], n, tol))
    out[0] = settle
    out[1] = max_f
    out[2] = max_a
    out[3] = 1.0 if failed else 0.0
'''


_TRIP_DRIVERS += "".join(
    f"""

@njit(cache=True, error_model="numpy")
def law_one_trip_{kind}(y0, indptr, indices, P, k, ta, tb, keep, t_clear, t_after, dt, tols, plan, jperm, out,
                     e):
    \"\"\"Trip e of (ta, tb, keep, t_clear) from y0 for t_after after its trip by {kind} (out: one
    row of four per trip; every trip in parallel: law_support.each_trip). tols = (band, rtol,
    atol).\"\"\"
    w_fault, w_post = trip_weights(k, indptr, indices, ta[e], tb[e], keep[e])
    {call}
"""
    for kind, call in (
        (
            "rk4",
            "trip_rk4(y0, w_fault, w_post, indptr, indices, P, t_clear[e], t_clear[e] + t_after, dt, "
            "tols[0], (ta[e], tb[e], keep[e]), out[e])",
        ),
        (
            "rodas4",
            "law_rodas4_trip(y0, w_fault, w_post, indptr, indices, P, t_clear[e], t_clear[e] + t_after, "
            "dt, tols, plan, jperm, (ta[e], tb[e], keep[e]), out[e])",
        ),
    )
)


# -- compiling and running ----------------------------------------------------------------------


@functools.lru_cache(maxsize=32)
def compile_law(law: Law) -> CompiledLaw:
    """``law``'s kernels: the generated module, written once under :func:`cache_root` (named by
    the digest of the law's text, the generator and antisync's sources) and imported; numba
    caches its machine code beside it."""
    source = generate_source(law)
    key = hashlib.sha1(
        "\n".join([source, _numba_cache.cache_dir().name, numba.__version__]).encode()
    ).hexdigest()[:16]
    folder = cache_root() / key
    path = folder / f"law_{key}.py"
    if not path.is_file() or path.read_text(encoding="utf-8") != source:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(source)
        os.replace(tmp, path)  # atomic: a concurrent process reads the whole file or none
    name = f"antisync_law_{key}"
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return CompiledLaw(
        module.law_rhs,
        module.law_order,
        module.law_start,
        module.law_jac,
        module.KH,
        module.law_item_explicit,
        module.law_item_circle,
        module.law_item_circle_euler,
        module.law_items_lanes_euler if module.LANES else None,
        module.law_items_lanes if module.LANES else None,
        module.law_item_rodas4,
        module.law_vjp,
        module.law_adjoint_item,
        (module.CIRCLE, module.CIRCLE_FREQUENCY),
        path,
        module.law_items_lanes_frequency if module.LANES and module.LANES_FREQUENCY else None,
        module.law_items_lanes_euler_frequency if module.LANES and module.LANES_FREQUENCY else None,
        module.law_adjoint_item_freq,
        module.law_devs,
        module.KF,
        (module.law_one_trip_rk4, module.law_one_trip_rodas4),
    )


@functools.lru_cache(maxsize=16)
def _jacobian_plan(indptr: bytes, indices: bytes, n_states: int):
    from antisync.kernels.implicit import factor_plan

    ip = np.frombuffer(indptr, dtype=np.int64)
    ix = np.frombuffer(indices, dtype=np.int64)
    ptr, cols, perm = expanded_pattern(ip, ix, n_states)
    return factor_plan(ptr, cols), perm


def _no_plan():
    from antisync.kernels.implicit import FactorPlan

    empty = np.zeros(0, dtype=np.int64)
    return FactorPlan(*(empty for _ in range(12))), empty


_METHODS = {"euler": 0, "rk4": 1, "rodas4": 2}


def _batch(params: LawParams, first, count, realizations, indptr, indices) -> tuple:
    """A batch's ``(compiled law, realization ids, indptr, indices, per-node values)`` in the
    kernels' types."""
    law = params.law
    n = indptr.size - 1
    if params.edges is not None and np.shape(params.edges)[1:] != (np.size(indices),):
        raise ValueError(
            f"edges must have one column per in-link ({np.size(indices)}), got shape {np.shape(params.edges)}"
        )
    return (
        compile_law(law),
        realization_ids(first, count, realizations),
        np.ascontiguousarray(indptr, dtype=np.int64),
        np.ascontiguousarray(indices, dtype=np.int64),
        np.ascontiguousarray(params.values, dtype=np.float64).reshape(len(law.params), n),
    )


def with_start(P: np.ndarray, start: np.ndarray | None) -> np.ndarray:
    """The kernels' parameter array ``P`` (of :func:`with_edges`, or a stack of them) with
    ``start``'s two rows below it (:attr:`LawParams.start`): ``law_start`` reads a row beyond its
    law's ``NROWS`` as the phases around which it draws; ``P`` itself without ``start``."""
    if start is None:
        return P
    start = np.asarray(start, dtype=np.float64)
    *lead, rows, cols = P.shape
    out = np.zeros((*lead, rows + 2, max(cols, start.shape[1])))
    out[..., :rows, :cols] = P
    out[..., rows:, : start.shape[1]] = start
    return out


def parameter_blocks(
    values: np.ndarray, drawn: tuple, seed: int, ks: np.ndarray, law: Law | None = None, edges=None
) -> np.ndarray:
    """The kernels' parameters from the fixed ``values`` ``(n_params, n)``: ``(1, n_params, n)``
    when none is ``drawn`` (:attr:`LawParams.drawn`), else one block per realization ``ks`` with
    each drawn parameter ``k`` from its distribution on the counter
    streams ``1 + 2 k``, ``2 + 2 k`` keyed by ``(seed, realization, node)``
    (:func:`antisync.kernels.model_steps.draw_frequencies`: the same draws whatever the chunk,
    thread or executor; a law's first parameter draws the built-in model's frequencies).

    With ``law``'s edge parameters ``edges`` (:attr:`LawParams.edges`) every block is widened
    by :func:`with_edges`."""
    from antisync.kernels.model_steps import draw_frequencies

    values = np.ascontiguousarray(values, dtype=np.float64)
    if not drawn:
        return with_edges(values, law, edges)[None]
    n = values.shape[1]
    out = np.repeat(values[None], len(ks), axis=0)
    for k, spec in drawn:
        out[:, k, :] = draw_frequencies(spec, seed, np.asarray(ks), n, streams=(1 + 2 * k, 2 + 2 * k))
    return np.stack([with_edges(block, law, edges) for block in out])


def with_edges(values: np.ndarray, law: Law | None = None, edges: np.ndarray | None = None) -> np.ndarray:
    """The kernels' parameter array ``P``: the per-node ``values`` ``(n_params, n)``, below them
    ``law``'s per-link ``edges`` ``(n_edge_params, nnz)`` and each function of them that
    :func:`with_derived` lists (computed here once, not per link and step), in one ``(n_params +
    n_edge_rows, max(n, nnz))`` array (zero where a row is shorter). Every generated function
    reads a node's ``k``-th parameter at ``P[k, i]`` and a link's ``k``-th edge row at
    ``P[n_params + k, q]``, so no signature grows. ``values`` itself without edge parameters."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    wanted = 0 if law is None else len(law.edge_params)
    given = 0 if edges is None else len(edges)
    if law is None and given:
        raise ValueError("with_edges: edge parameters need their law (its functions of them are rows too)")
    if given != wanted:
        raise ValueError(f"law {law.name} has {wanted} edge parameter(s); edges gives {given} row(s)")
    if not given:
        return values
    rows = _edge_rows(law, edges)
    (n_p, n), (n_e, nnz) = values.shape, rows.shape
    out = np.zeros((n_p + n_e, max(n, nnz)))
    out[:n_p, :n] = values
    out[n_p:, :nnz] = rows
    return out


#: trajectories a law's lane driver steps together (RK4 on the circle form, order parameter)
LAW_LANES = 16


def _lane_width(lanes: int | None, compiled: CompiledLaw, params: LawParams) -> int:
    """The lanes of a circle-form Euler or RK4 run: ``lanes`` (0: one trajectory per item), else
    :data:`LAW_LANES`; 0 where the law has no lane drivers (one per item)."""
    if compiled.items_lanes is None:
        return 0
    if lanes is not None:
        if lanes < 0 or lanes % (2 * VEC):
            raise ValueError(f"lanes must be 0 or a positive multiple of {2 * VEC}, got {lanes}")
        return int(lanes)
    return LAW_LANES


def simulate_law(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    base_weights: np.ndarray,
    variant_weights: np.ndarray,
    params: LawParams,
    *,
    dt: float,
    max_steps: int,
    integrator: str = "rk4",
    threads: int | None = None,
    realizations: np.ndarray | None = None,
    todo: np.ndarray | None = None,
    circle: bool = True,
    lanes: int | None = None,
) -> SimResult:
    """Integrate realizations ``first .. first+count-1`` (or ``realizations``) of a user's law
    for the base weights and every row of ``variant_weights`` (the arguments of
    :func:`antisync.kernels.cpu.simulate_model`; ``params`` a :class:`LawParams`): one
    trajectory per item, in parallel. Rodas4 starts at step ``dt``, runs to ``t_max = max_steps
    dt`` and stores its crossing time on the grid of ``dt`` as the built-in drivers do; a
    trajectory whose step size collapses raises ``FloatingPointError`` naming it, as the
    built-in Rodas4 does (never a status). A state that is not finite is ``NOT_SYNCED``.

    RK4 steps the law's circle form where it has one (:func:`circle_form`: its angles as ``(cos,
    sin)``, each step projected back to the circle; the built-in kernels' RK4), unless ``circle``
    is False (RK4 on the angles themselves: the
    discretization the adjoint differentiates). Both are fourth order; they differ by the
    method's error."""
    if integrator not in _METHODS:
        raise ValueError(f"integrator must be one of {', '.join(_METHODS)}, got {integrator!r}")
    law = params.law
    compiled, ks, indptr, indices, values = _batch(params, first, count, realizations, indptr, indices)
    m = ks.size
    base = np.ascontiguousarray(base_weights, dtype=np.float64)
    var_w = np.ascontiguousarray(variant_weights, dtype=np.float64).reshape(-1, base.size)
    n_var = var_w.shape[0]
    var_is_base = np.array([np.array_equal(w, base) for w in var_w], dtype=np.bool_)
    targets = np.ascontiguousarray(params.targets, dtype=np.float64)
    if targets.shape != (n_var + 1,):
        raise ValueError(f"targets must have shape ({n_var + 1},), got {targets.shape}")
    todo = todo_mask(todo, m, n_var, var_is_base)
    if integrator == "rodas4":
        plan, jperm = _jacobian_plan(indptr.tobytes(), indices.tobytes(), len(law.states))
    else:
        plan, jperm = _no_plan()
    items = compiled.items_rodas4 if integrator == "rodas4" else compiled.items
    if integrator != "rodas4" and circle and compiled.circle[params.criterion != CRIT_ORDER]:
        items = compiled.items_circle if integrator == "rk4" else compiled.items_circle_euler
    clock = (
        float(dt),
        float(dt) * int(max_steps),
        float(max_steps),
        _METHODS[integrator],
        params.rtol,
        params.atol,
        float(params.criterion),
    )
    out = unset_outputs(m, n_var)
    collapsed = np.zeros((m, n_var + 1), dtype=np.bool_)
    blocks = with_start(parameter_blocks(values, params.drawn, seed, ks, law, params.edges), params.start)
    on_lanes = {
        compiled.items_circle: compiled.items_lanes,
        compiled.items_circle_euler: compiled.items_lanes_euler,
    }
    if params.criterion != CRIT_ORDER:
        on_lanes = {
            compiled.items_circle: compiled.items_lanes_frequency,
            compiled.items_circle_euler: compiled.items_lanes_euler_frequency,
        }
    if on_lanes.get(items) is None:
        on_lanes = {}
    width = _lane_width(lanes, compiled, params) if items in on_lanes else 0
    inputs = (ks, np.uint64(seed), indptr, indices, base, var_w, var_is_base, todo, blocks, targets)
    outputs = (out.status0, out.steps0, out.frac0, out.status, out.steps, out.frac)
    with Threads(threads):
        if width:
            groups = max(1, min(4 * numba.get_num_threads(), -(-m * (n_var + 1) // width)))
            support.each_group(on_lanes[items], inputs, clock, outputs, (groups, width))
        else:
            outputs += (collapsed,)
            support.each_item(items, inputs, clock, plan, jperm, outputs)
    support.share_rows(var_is_base, out)
    check_collapsed(collapsed, ks, f" of law {law.name}")
    return SimResult(out.status0, out.steps0, out.status, out.steps, out.frac0, out.frac)


def simulate_law_adjoint(
    seed: int,
    first: int,
    count: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    weights: np.ndarray,
    derivatives,
    params: LawParams,
    *,
    dt: float,
    max_steps: int,
    integrator: str = "rk4",
    dtarget: np.ndarray | None = None,
    threads: int | None = None,
    realizations: np.ndarray | None = None,
) -> PathwiseResult:
    """``d tau0 / d beta_e`` of every link of ``derivatives`` (a
    :class:`~antisync.kernels.adjoint.LinkDerivatives`: each link's ``dW/dbeta`` on the
    pattern) for realizations ``first .. first+count-1`` of a law, by the discrete adjoint of
    its Euler or RK4 steps and of the crossing inside the last step (the cubic Hermite
    interpolant of ``R``, or Euler's straight line): the exact derivative of the stored
    ``tau0 = (steps0 - 1 + frac0) dt`` while the crossing stays in its step. One backward pass
    per trajectory gives every link (the gradient with respect to every weight, then
    contracted with each link's ``dW/dbeta``); the forward states are kept, ``steps0 + 1`` of
    them. ``params.targets[0]`` is the target; ``dtarget`` ``(E,)``, where the target moves with
    the damage (the relative criterion's ``(fraction r* N)^2``), its ``d target / d beta_e``,
    added through the crossing's ``d tau0 / d target`` (None: a target that does not move)."""
    if integrator not in ("euler", "rk4"):
        raise ValueError(f"the adjoint differentiates euler or rk4 steps, not {integrator!r}")
    compiled, ks, indptr, indices, values = _batch(params, first, count, realizations, indptr, indices)
    m = ks.size
    w = np.ascontiguousarray(weights, dtype=np.float64)
    status0 = np.full(m, -1, dtype=np.int8)
    steps0 = np.full(m, -1, dtype=np.int64)
    frac0 = np.full(m, np.nan)
    gw = np.zeros((m, w.size))
    coef = np.zeros(m)
    adjoint = compiled.adjoint if params.criterion == CRIT_ORDER else compiled.adjoint_freq
    blocks = with_start(
        parameter_blocks(values, params.drawn, seed, ks, params.law, params.edges), params.start
    )
    with Threads(threads):
        args = (ks, np.uint64(seed), indptr, indices, w, blocks, float(dt), integrator == "rk4")
        args += (float(params.targets[0]), int(max_steps), status0, steps0, frac0, gw, coef)
        support.each_realization(adjoint, args)
    n_links = derivatives.indptr.size - 1
    link = np.repeat(np.arange(n_links), np.diff(derivatives.indptr))
    dtau = np.zeros((m, n_links))
    for e in range(n_links):
        part = link == e
        dtau[:, e] = gw[:, derivatives.position[part]] @ derivatives.value[part]
        if dtarget is not None:
            dtau[:, e] += coef * dtarget[e]
    dtau[status0 != SYNCED] = 0.0
    return PathwiseResult(status0, steps0, frac0, dtau)


def integrate_law_trips(
    law: Law, y0, P, indptr, indices, k, trips, t_after, h0, tols, integrator: str = "rk4", threads=None
):
    """Line trips of ``law`` from its operating point ``y0`` (the flat state) by the generated
    ``law_one_trip_rk4`` (RK4 at the step ``h0``) or ``law_one_trip_rodas4`` (Rodas4 from the first
    step ``h0``), one trip at a time per numba thread: the ``(items, 4)`` rows ``[settle_time,
    max_frequency, max_angle, failed]`` of :func:`antisync.kernels.trip.integrate_trips`, the
    frequency that of the law's first frequency quantity and the angles its phases'. ``P``:
    :func:`with_edges`' rows, ``k`` the CSR weights, ``trips = (ta, tb, keep, t_clear)``, ``tols
    = (band, rtol, atol)``."""
    if integrator not in ("rk4", "rodas4"):
        raise ValueError(f"a law's trip integrates by rk4 or rodas4, not {integrator}")
    compiled = compile_law(law)
    types = (np.int64, np.int64, np.float64, np.float64)
    ta, tb, keep, clear = (np.array(a, dtype=t) for a, t in zip(trips, types, strict=True))
    indptr = np.ascontiguousarray(indptr, dtype=np.int64)
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    rodas4 = integrator == "rodas4"
    plan, jperm = (
        _jacobian_plan(indptr.tobytes(), indices.tobytes(), len(law.states)) if rodas4 else _no_plan()
    )
    out = np.empty((ta.size, 4))
    with Threads(threads), numba.parallel_chunksize(1):
        y0 = np.ascontiguousarray(y0, dtype=np.float64)
        P = np.ascontiguousarray(P, dtype=np.float64)
        k = np.ascontiguousarray(k, dtype=np.float64)
        inputs = (y0, indptr, indices, P, k, ta, tb, keep, clear, float(t_after), float(h0))
        tols = tuple(float(v) for v in tols)
        support.each_trip(compiled.trips[rodas4], inputs, tols, plan, jperm, out)
    return out


#: the largest state (states x nodes) whose step is checked by a dense eigenvalue problem
CHECK_MAX_STATES = 3000


def _growth(z: np.ndarray, integrator: str) -> np.ndarray:
    """``|R(z)|``, the explicit step's amplification of a mode with ``z = dt lambda``."""
    if integrator == "euler":
        return np.abs(1 + z)
    return np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)


def jacobian(
    law: Law, values: np.ndarray, indptr, indices, weights, y: np.ndarray, edges: np.ndarray | None = None
) -> np.ndarray:
    """The law's Jacobian at the flat state ``y`` as a dense matrix (``(S n, S n)``); ``values``
    the per-node parameters, ``edges`` the per-link ones (:attr:`LawParams.edges`)."""
    compiled = compile_law(law)
    indptr = np.ascontiguousarray(indptr, dtype=np.int64)
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    ptr, cols, perm = expanded_pattern(indptr, indices, len(law.states))
    jq = np.empty(perm.size)
    compiled.jac(
        np.ascontiguousarray(y, dtype=np.float64),
        np.ascontiguousarray(weights, dtype=np.float64),
        indptr,
        indices,
        with_edges(values, law, edges),
        jq,
    )
    dense = np.zeros((ptr.size - 1, ptr.size - 1))
    rows = np.repeat(np.arange(ptr.size - 1), np.diff(ptr))
    np.add.at(dense, (rows, cols), jq[perm])
    return dense


def starts(law: Law, values: np.ndarray, seed: int, ks) -> np.ndarray:
    """The flat start of each realization ``ks`` (rows), as the kernels draw it."""
    compiled = compile_law(law)
    n = values.shape[1]
    out = np.empty((len(ks), len(law.states) * n))
    for row, k in enumerate(ks):
        compiled.start(
            np.uint64(seed), np.int64(k), np.ascontiguousarray(values, dtype=np.float64), out[row], n
        )
    return out


def in_phase(law: Law, values: np.ndarray) -> np.ndarray:
    """The flat state with every node at its start for the phase ``phi = 0`` (the in-phase
    state of a phase model, where synchrony is approached)."""
    import sympy

    sym = law.symbolic()
    n = values.shape[1]
    out = np.empty(len(law.states) * n)
    for k, expr in enumerate(sym.start):
        f = sympy.lambdify([sym.phi, *sym.p], expr, modules="math")
        out[k * n : (k + 1) * n] = [f(0.0, *values[:, i]) for i in range(n)]
    return out


def node_phases(law: Law, values: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Each node's phase (the law's ``phase`` expression) in the flat state ``y``, in
    ``(-pi, pi]`` (wrapped: a phase that is a state may have wound any number of times)."""
    import sympy

    sym = law.symbolic()
    n = values.shape[1]
    f = sympy.lambdify([*sym.x, *sym.p], sym.phase, modules="numpy")
    states = np.asarray(y, dtype=np.float64).reshape(len(law.states), n)
    angle = np.broadcast_to(np.asarray(f(*states, *np.asarray(values, dtype=np.float64)), dtype=float), (n,))
    return np.angle(np.exp(1j * angle))


def check_step(setup, seed: int, csr, dynamics) -> None:
    """Refuse a law that is not finite at its start, and an explicit ``dynamics.dt`` that a
    decaying mode of the law's Jacobian would make grow.

    At the start of realization 0 and at the in-phase state (every node's start at ``phi = 0``)
    the state, the rates and the Jacobian must be finite (any integrator); for Euler and RK4
    every eigenvalue ``lambda`` of the Jacobian there with a negative real part must have
    ``|R(dt lambda)| <= 1`` (the step's amplification). Beyond :data:`CHECK_MAX_STATES` states
    the eigenvalues are not computed (a dense problem); a diverging trajectory is then still
    never counted as synchronized (its state is not finite)."""
    from antisync.errors import ConfigError

    law = setup.law
    values = parameter_blocks(setup.values, setup.drawn, seed, np.zeros(1, dtype=np.int64))[0]
    n = values.shape[1]
    dt, integrator = dynamics.dt, dynamics.integrator
    explicit = integrator in ("euler", "rk4") and len(law.states) * n <= CHECK_MAX_STATES
    compiled = compile_law(law)
    ip = np.ascontiguousarray(csr.indptr, dtype=np.int64)
    ix = np.ascontiguousarray(csr.indices, dtype=np.int64)
    w = np.ascontiguousarray(csr.weights, dtype=np.float64)
    vals = with_edges(values, law, setup.edges)
    for where, y in (
        ("the start of realization 0", starts(law, values, seed, [0])[0]),
        ("the in-phase state", in_phase(law, values)),
    ):
        if not np.isfinite(y).all():
            raise ConfigError(
                f"model.law {law.name}: the start is not finite at {where}; check model.law.start "
                "and model.params"
            )
        f = np.empty(y.size)
        compiled.rhs(y, w, ip, ix, vals, f, np.empty((compiled.hoisted, n)))
        if not np.isfinite(f).all():
            bad = int(np.flatnonzero(~np.isfinite(f))[0])
            state, node = law.states[bad // n], bad % n
            raise ConfigError(
                f"model.law {law.name}: the rate of {state} is not finite at {where} (node {node}): "
                f"check model.law.rates.{state} ({dict(law.rates)[state]!r}) and model.params"
            )
        if not explicit:
            continue
        jac = jacobian(law, values, csr.indptr, csr.indices, csr.weights, y, setup.edges)
        if not np.isfinite(jac).all():
            raise ConfigError(
                f"model.law {law.name}: the law is not finite at {where} (its Jacobian has inf or "
                "NaN); check model.law.rates and model.params"
            )
        lam = np.linalg.eigvals(jac)
        decaying = lam[lam.real < 0]
        if decaying.size and _growth(dt * decaying, integrator).max() > 1.0 + 1e-12:
            lo, hi = 0.0, dt
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if _growth(mid * decaying, integrator).max() <= 1.0:
                    lo = mid
                else:
                    hi = mid
            fastest = decaying[np.argmax(np.abs(decaying))]
            raise ConfigError(
                f"dynamics.dt = {dt:g} is too large for law {law.name} on this graph: at {where} a decaying "
                f"mode (eigenvalue {fastest.real:.4g}{fastest.imag:+.4g}i of the Jacobian) grows under "
                f"{integrator} steps unless dt < {lo:.3g}; use a smaller dt or integrator rodas4"
            )


_LANE_DRIVER = '''

@njit(cache=True, error_model="numpy")
def {fill}(q, lo, hi, ks, seed, indptr, indices, base_w, var_w, var_is_base, todo, PR, targets,
              max_steps, per, y, zq, fq, Gq, z, f, ya, lw, PL, r2, dr2, lane_item, lane_target, dt, L,
              status0, steps0, frac0, status, steps, frac, DV, Dq):
    """Load the next item of lo .. hi - 1 that needs integrating into lane q (the ones that end
    at their start recorded on the way): the next item to look at, and whether q holds one."""
    n = indptr.shape[0] - 1
    while lo < hi:
        item = lo
        lo += 1
        r, v, run = item_of(item, per, var_is_base, todo)
        if not run:
            continue
        P = PR[0] if PR.shape[0] == 1 else PR[r]
        w = base_w if v < 0 else var_w[v]
        law_start(seed, ks[r], P, y, n)
        circle_from(y, zq, n)
        {rhs}(zq, w, indptr, indices, P, fq, Gq)
        if {freq}:  # the frequency criterion's deviations at the start: {sync}'s checks
{start_devs}
            b = 0.0
            if a != a:
                record(status0, steps0, frac0, status, steps, frac, r, v, NOT_SYNCED, max_steps, 0.0)
                continue
            if a < targets[v + 1]:
                record(status0, steps0, frac0, status, steps, frac, r, v, ALREADY_SYNCED, 0, 0.0)
                continue
        else:
            a, b = circle_order(zq, fq, n)
            if not (a == a and b == b):
                record(status0, steps0, frac0, status, steps, frac, r, v, NOT_SYNCED, max_steps, 0.0)
                continue
            if a >= targets[v + 1]:
                record(status0, steps0, frac0, status, steps, frac, r, v, ALREADY_SYNCED, 0, 0.0)
                continue
        h = 0.5 * dt
        for k in range(zq.shape[0]):
            z[k * L + q] = zq[k]
            f[k * L + q] = fq[k]
            ya[k * L + q] = zq[k] + h * fq[k]
        for e in range(w.shape[0]):
            lw[e * L + q] = w[e]
        for k in range(NP):
            for i in range(n):
                PL[(k * n + i) * L + q] = P[k, i]
        for k in range(NROWS - NP):  # a law's edge rows (with_edges), per link
            for e in range(w.shape[0]):
                PL[(NP * n + k * w.shape[0] + e) * L + q] = P[NP + k, e]
        if {freq}:  # the start's deviations: the next step's first end
            for row in range(2 * KF):
                for i in range(n):
                    DV[(row * n + i) * L + q] = Dq[row, i]
        r2[q] = a
        dr2[q] = b
        lane_item[q] = item
        lane_target[q] = targets[v + 1]
        return lo, True
    return lo, False


@njit(cache=True, error_model="numpy")
def {name}(ks, seed, indptr, indices, base_w, var_w, var_is_base, todo, PR, targets, clock,
                    status0, steps0, frac0, status, steps, frac, n_groups, L, group):
    """{what} on the circle form: the items of group `group` of n_groups, L stepped together
    ({sync}'s results; L a multiple of 2 VEC; every group in parallel: law_support.each_group)."""
    dt = clock[0]
    max_steps = int(clock[2])
    n = indptr.shape[0] - 1
    nnz = indices.shape[0]
    m = ks.shape[0]
    per = var_w.shape[0] + 1
    total = m * per
    rows = CS * n
    hoist = {rhs_rows}(n, nnz) > 0
    lo = group * total // n_groups
    hi = (group + 1) * total // n_groups
    z = np.zeros(rows * L)
    f = np.zeros(rows * L)
    acc = np.zeros(rows * L)
    ya = np.zeros(rows * L)
    yb = np.zeros(rows * L)
    lw = np.zeros(nnz * L)
    PL = np.zeros((NP * n + (NROWS - NP) * nnz) * L)
    G = np.empty(LANE_KH * n * L if hoist else 0)
    r2 = np.zeros(L)
    dr2 = np.zeros(L)
    r2p = np.zeros(L)
    dr2p = np.zeros(L)
    y = np.empty(S * n)
    zq = np.empty(rows)
    fq = np.empty(rows)
    Gq = np.empty(({rhs_rows}(n, nnz), n))
    lane_item = np.full(L, -1, dtype=np.int64)
    lane_t0 = np.zeros(L, dtype=np.int64)
    lane_target = np.zeros(L)
    # the frequency criterion's deviations of every lane at the step's two ends (DA and DB
    # by turns: the end of step t in DA for an even t), and one lane's for the crossing
    DA = np.empty(2 * KF * n * L if {freq} else 0)
    DB = np.empty(2 * KF * n * L if {freq} else 0)
    Dq = np.empty((2 * KF, n))
    Dpq = np.empty((2 * KF, n))
    t = 0
    active = 0
    while True:
        DV = DA if t % 2 == 0 else DB  # where a lane filled now keeps its start's deviations
        for q in range(L):
            if lane_item[q] < 0 and lo < hi:
                lo, got = {fill}(q, lo, hi, ks, seed, indptr, indices, base_w, var_w, var_is_base,
                                    todo, PR, targets, max_steps, per, y, zq, fq, Gq, z, f, ya, lw,
                                    PL, r2, dr2, lane_item, lane_target, dt, L,
                                    status0, steps0, frac0, status, steps, frac, DV, Dq)
                if got:
                    lane_t0[q] = t
                    active += 1
        if active == 0:
            break
        for q in range(L):
            r2p[q] = r2[q]
            dr2p[q] = dr2[q]
        t += 1
{step}
        for q in range(L):
            item = lane_item[q]
            if item < 0:
                continue
            k = t - lane_t0[q]
            if not (r2[q] == r2[q] and dr2[q] == dr2[q]):
                st, k, x = NOT_SYNCED, max_steps, 0.0  # diverged: never synchronized
            else:
{cross}
                if x >= 0.0:
                    st = SYNCED
                elif k >= max_steps:
                    st, x = NOT_SYNCED, 0.0
                else:
                    continue
            record(status0, steps0, frac0, status, steps, frac, item // per, item % per - 1, st, k, x)
            lane_item[q] = -1
            active -= 1
'''


#: what :data:`_LANE_DRIVER` holds for RK4 and for Euler
#: the frequency criterion on RK4's lanes: every lane's deviations by circle_lane_devs (circle_sync's
#: numbers, bit for bit), each lane's crossing on the last step's interpolants by the scalar code;
#: a deviation that is not a number: never synchronized
_FREQUENCY_CROSS = """\
                for row in range(2 * KF):
                    for i in range(n):
                        Dq[row, i] = DE[(row * n + i) * L + q]
                        Dpq[row, i] = DS[(row * n + i) * L + q]
                dev = law_deviation(Dq, Dpq, n, dt, {rk4}, 1.0)
                if dev != dev:
                    k = max_steps  # diverged: never synchronized
                    x = -1.0
                else:
                    x = frequency_crossing(Dq, Dpq, n, dt, {rk4}, lane_target[q])"""

#: the start's deviations in a lane's fill: RK4's circle rates are its right-hand side's; Euler's
#: are made from its angles' speeds (circle_rates_of), as circle_euler_sync makes them
_START_DEVS = {
    "rk4": """\
            circle_law_devs(zq, fq, w, indptr, indices, P, Dq)
            a = law_deviation(Dq, Dq, n, dt, True, 1.0)""",
    "euler": """\
            frq = np.empty(zq.shape[0])
            circle_rates_of(zq, fq, frq, n)
            circle_law_devs(zq, frq, w, indptr, indices, P, Dq)
            a = law_deviation(Dq, Dq, n, dt, False, 1.0)""",
}

_LANE_KINDS = {
    "rk4_frequency": {
        "name": "law_items_lanes_frequency",
        "fill": "lane_fill_frequency",
        "freq": "True",
        "rhs": "circle_law_rhs",
        "rhs_rows": "circle_rhs_rows",
        "what": "RK4 to the frequency criterion",
        "sync": "circle_sync",
        "step": """\
        circle_lane_step(z, f, acc, ya, yb, lw, indptr, indices, PL, G, dt, L)
        DE = DA if t % 2 == 0 else DB
        DS = DB if t % 2 == 0 else DA
        circle_lane_devs(z, f, lw, indptr, indices, PL, DE, L)""",
        "cross": _FREQUENCY_CROSS.format(rk4="True"),
        "start_devs": _START_DEVS["rk4"],
    },
    "euler_frequency": {
        "name": "law_items_lanes_euler_frequency",
        "fill": "lane_fill_euler_frequency",
        "freq": "True",
        "rhs": "circle_euler_law_rhs",
        "rhs_rows": "circle_euler_rhs_rows",
        "what": "Euler to the frequency criterion",
        "sync": "circle_euler_sync",
        # circle_euler_sync's order: the turn, the projection every RENORM_EVERY steps, the
        # angles' speeds, the circle rates from them (into acc, RK4's accumulator), the deviations
        "step": """\
        circle_lane_turn(z, f, n, dt, L)
        for q in range(L):
            if lane_item[q] >= 0 and (t - lane_t0[q]) % RENORM_EVERY == 0:
                circle_lane_project(z, n, q, L)
        circle_euler_lane_rhs(z, lw, indptr, indices, PL, G, L, f)
        circle_lane_rates_of(z, f, acc, n, L)
        DE = DA if t % 2 == 0 else DB
        DS = DB if t % 2 == 0 else DA
        circle_lane_devs(z, acc, lw, indptr, indices, PL, DE, L)""",
        "cross": _FREQUENCY_CROSS.format(rk4="False"),
        "start_devs": _START_DEVS["euler"],
    },
    "rk4": {
        "name": "law_items_lanes",
        "fill": "lane_fill",
        "freq": "False",
        "rhs": "circle_law_rhs",
        "rhs_rows": "circle_rhs_rows",
        "what": "RK4",
        "sync": "circle_sync",
        "step": """\
        circle_lane_step(z, f, acc, ya, yb, lw, indptr, indices, PL, G, dt, L)
        circle_lane_order(z, f, n, r2, dr2, L)""",
        "start_devs": _START_DEVS["rk4"],
        "cross": """\
                # the Hermite interpolant of R stays below max(R_0, R_1) + 4/27 (|m0| + |m1|):
                # a lane below that bound (widened for rounding) cannot cross in this step
                top = max(r2p[q], r2[q]) * (1.0 + 1e-12) + 0.15 * dt * (abs(dr2p[q]) + abs(dr2[q]))
                if top < lane_target[q] and k < max_steps:
                    continue
                x = order_crossing(r2p[q], dr2p[q], r2[q], dr2[q], dt, True, lane_target[q])""",
    },
    "euler": {
        "name": "law_items_lanes_euler",
        "fill": "lane_fill_euler",
        "freq": "False",
        "rhs": "circle_euler_law_rhs",
        "rhs_rows": "circle_euler_rhs_rows",
        "what": "Euler",
        "sync": "circle_euler_sync",
        "step": """\
        circle_lane_turn(z, f, n, dt, L)
        circle_lane_order(z, z, n, r2, dr2, L)
        for q in range(L):
            if lane_item[q] >= 0 and (t - lane_t0[q]) % RENORM_EVERY == 0:
                circle_lane_project(z, n, q, L)
        circle_euler_lane_rhs(z, lw, indptr, indices, PL, G, L, f)""",
        "start_devs": _START_DEVS["euler"],
        "cross": """\
                if r2[q] < lane_target[q] and k < max_steps:
                    continue  # a straight line between two values below the target
                x = order_crossing(r2p[q], 0.0, r2[q], 0.0, dt, False, lane_target[q])""",
    },
}
