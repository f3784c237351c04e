"""Three pure-Python costs of numba's compiler, removed with the same compiled code: a cold compile
of a parallel kernel takes a sixth to two fifths less time (``bench/compile_probe.py``: the lane
driver 20.1 s against 35.1 s with numba's own three, the trip kernels 20.6 against 27.1, the
model adjoint 30.2 against 36.6).

**Copy propagation.** ``numba.core.ir_utils.copy_propagate`` iterates its data-flow equations to a
fixed point and, to detect the fixed point, snapshots the per-block sets of copies with
``copy.deepcopy`` after every sweep. The sets hold tuples of variable names (strings), so a set
copy per block is the same snapshot; ``deepcopy`` walks every tuple in pure Python. In the
parallel lane drivers' compile (the ``prange`` bodies of hundreds of blocks, simplified again and
again by the parfor passes) the snapshots were a third of the profile: with :func:`copy_propagate`
a cold compile of the model's RK4 lane driver takes 30 s instead of 41-42 s
(``bench/compile_probe.py lanes``, with and without ``--numba-copy-propagate``), and
``tests/test_capabilities.py`` 309 s instead of 353 s (cold caches, the same two-core machine,
side by side). It is numba's own function with that one line changed; it returns the same
``(in_copies, out_copies)``. Its initial sets come from :func:`init_copy_propagate_data`,
numba's with one set hoisted out of a loop: numba's builds a block's assigned names again for
every copy of the program, blocks times copies times the block's copies (3.7% of a profile of
the lane driver's cold compile after the other fixes; 21.6-21.8 s against 22.2 s measured).

**Inlining.** ``InlineWorker.inline_ir`` (every ``inline="always"`` call and every overload numba
inlines) copies the callee's IR one block at a time, each block with its own ``copy.deepcopy``.
Every variable of a block holds the function's scope, which holds every variable of the
function, so each block's copy copied the whole scope again: blocks times variables. Here the
blocks are copied with one memo, so the scope is copied once and the copy shares variables
between blocks as the callee's IR itself does; the blocks' scopes are replaced by the caller's
when they are inlined. In a profile of the model adjoint's cold compile those copies were 13% of
the time. :func:`inline_ir` is numba's method compiled from numba's own source with those lines
changed (:data:`INLINE_COPY`).

**Liveness.** ``analysis.compute_live_map`` (the variables alive at each block's entry; the
parfor passes, dead-code removal and the placing of numba's deletions ask for it again and
again) runs two fixed points over sets of variable names, and each sweep unions, per block, the
names of every definition reaching it: blocks times variables, element by element in Python. In
a cold compile of the lane driver it was 14% of the time, of the trip kernels 13%.
:func:`compute_live_map` runs the same sweeps on integers (a bit per name, :class:`_Bits`), the
unions one ``|`` each, and returns the same sets: ``bench/compile_probe.py lanes`` 19.8 s
against 23.7 s with numba's, ``trip`` 21.0 against 23.6 (bench/RESULTS.md).

None changes the compiled code: tests/test_numba_compile.py runs numba's copy propagation and
the replacement on every call of a parallel compile and compares them, and compiles a kernel of
inlined functions with numba's inlining and this one: the same LLVM IR; and runs numba's
liveness and the replacement on every call of two parallel compiles: the same sets.
``bench/compile_probe.py`` prints a digest of every function's LLVM IR in a cold compile of a
kernel family (the lane drivers, the model adjoint, the trip kernels): the same with numba's own
passes (``--numba-copy-propagate --numba-inline --numba-live``) as with these (bench/RESULTS.md).

Each replaces numba's only where numba's source is the one it was written against (the SHA-1s
of :func:`inspect.getsource` below, numba 0.68.1); any other numba keeps its own. Numba is
patched by name where it is called: ``copy_propagate`` in ``ir_utils`` and ``parfors.parfor``
(which imported it by name), ``inline_ir`` on ``InlineWorker``, ``compute_live_map`` in
``analysis``, ``ir_utils`` and ``parfors.parfor``.

Every module that compiles with ``cache=True`` imports :mod:`antisync._numba_cache`, which
imports this module.
"""

from __future__ import annotations

import hashlib
import inspect
import textwrap

from numba.core import analysis, config, inline_closurecall, ir_utils

__all__ = [
    "compute_live_map",
    "copy_propagate",
    "inline_ir",
    "installed",
    "inline_installed",
    "live_installed",
]

#: SHA-1 of ``inspect.getsource(numba.core.ir_utils.copy_propagate)`` in the numba versions the
#: replacement was checked against (0.68.1)
KNOWN = {"1a90423ce674489b91d5160d7de74135ce4a9f62"}

#: SHA-1 of ``inspect.getsource(numba.core.inline_closurecall.InlineWorker.inline_ir)`` in the
#: numba versions :func:`inline_ir` was checked against (0.68.1)
KNOWN_INLINE = {"10d32b87fa025ae2c322724ae6ceca139a0a25ef"}

#: ``inline_ir``'s copy of the callee's blocks in numba (first) and here (second): one memo for
#: all the blocks, so that the function's scope is copied once, not once per block
INLINE_COPY = (
    """            for block_label, block in the_ir.blocks.items():
                new_block = copy.deepcopy(the_ir.blocks[block_label])
                kernel_copy.blocks[block_label] = new_block
""",
    """            memo = {}
            for block_label, block in the_ir.blocks.items():
                new_block = copy.deepcopy(the_ir.blocks[block_label], memo)
                kernel_copy.blocks[block_label] = new_block
""",
)

#: SHA-1 of ``inspect.getsource(numba.core.analysis.compute_live_map)`` in the numba versions
#: :func:`compute_live_map` was checked against (0.68.1)
KNOWN_LIVE = {"c3ebc82fe4f20a983009cb744905390288510c77"}

#: SHA-1 of ``inspect.getsource(numba.core.ir_utils.init_copy_propagate_data)`` (0.68.1)
KNOWN_INIT = {"f59e89942a394816ca80a277a03fc85b74b716ca"}

_numba_copy_propagate = ir_utils.copy_propagate
_numba_compute_live_map = analysis.compute_live_map
_numba_inline_ir = inline_closurecall.InlineWorker.inline_ir


def _snapshot(copies: dict) -> dict:
    """``copy.deepcopy(copies)`` for a dict of sets of tuples of names: a new set per block."""
    return {label: set(pairs) for label, pairs in copies.items()}


def init_copy_propagate_data(blocks, entry, typemap):
    """numba's ``ir_utils.init_copy_propagate_data`` with a block's assigned names made once per
    block, not once per block and copy of the program (the same sets, filled in the same order)."""
    gen_copies, extra_kill = ir_utils.get_block_copies(blocks, typemap)
    all_copies = set()
    for label in gen_copies:
        all_copies |= gen_copies[label]
    kill_copies = {}
    for label, gen_set in gen_copies.items():
        kill = kill_copies[label] = set()
        extra = extra_kill[label]
        assigned = {lhs for lhs, rhs in gen_set}
        for lhs, rhs in all_copies:
            if lhs in extra or rhs in extra:
                kill.add((lhs, rhs))
            # a copy is killed if it is not in this block and lhs or rhs are assigned in it
            if (lhs, rhs) not in gen_set and (lhs in assigned or rhs in assigned):
                kill.add((lhs, rhs))
    # all copies are in for all blocks except entry
    in_copies = {label: all_copies.copy() for label in blocks.keys()}
    in_copies[entry] = set()
    out_copies = {}
    for label in blocks.keys():
        out_copies[label] = gen_copies[label] | (in_copies[label] - kill_copies[label])
    out_copies[entry] = gen_copies[entry]
    return (gen_copies, all_copies, kill_copies, in_copies, out_copies)


def copy_propagate(blocks, typemap):
    """numba's ``ir_utils.copy_propagate``, its fixed point snapshotted by :func:`_snapshot` (and
    its initial sets by :func:`init_copy_propagate_data` where numba's is the known one)."""
    cfg = ir_utils.compute_cfg_from_blocks(blocks)
    entry = cfg.entry_point()
    init = init_copy_propagate_data if _init_known else ir_utils.init_copy_propagate_data
    gen_copies, _all, kill_copies, in_copies, out_copies = init(blocks, entry, typemap)
    old_point = None
    new_point = _snapshot(out_copies)
    while old_point != new_point:
        for label in blocks.keys():
            if label == entry:
                continue
            predecs = [i for i, _d in cfg.predecessors(label)]
            # in_b = intersect(predec(B))
            in_copies[label] = out_copies[predecs[0]].copy()
            for p in predecs:
                in_copies[label] &= out_copies[p]
            # out_b = gen_b | (in_b - kill_b)
            out_copies[label] = gen_copies[label] | (in_copies[label] - kill_copies[label])
        old_point = new_point
        new_point = _snapshot(out_copies)
    if config.DEBUG_ARRAY_OPT >= 1:
        print("copy propagate out_copies:", out_copies)
    return in_copies, out_copies


class _Bits:
    """Sets of variable names as Python integers (bit ``i`` for the ``i``-th name seen): a union
    is one integer ``|``, in C, instead of a set union of names, element by element."""

    def __init__(self):
        self.index: dict = {}
        self.names: list = []

    def of(self, variables) -> int:
        index, bits = self.index, 0
        for name in variables:
            i = index.get(name)
            if i is None:
                i = index[name] = len(self.names)
                self.names.append(name)
            bits |= 1 << i
        return bits

    def names_of(self, bits: int) -> set:
        names, out = self.names, set()
        while bits:
            low = bits & -bits
            out.add(names[low.bit_length() - 1])
            bits ^= low
        return out


def compute_live_map(cfg, blocks, var_use_map, var_def_map):
    """numba's ``analysis.compute_live_map`` (the variables alive at the entry of each block) with
    its two fixed points on :class:`_Bits`: the same passes in the same order, each a sweep of
    integer ``|``, ``&`` and ``~``; the same sets."""
    topo_order = cfg.topo_order()
    b = _Bits()
    defs = {}
    uses = {offset: b.of(var_use_map[offset]) for offset in (*blocks.keys(), *topo_order)}

    def def_bits(offset):
        if offset not in defs:
            defs[offset] = b.of(var_def_map[offset])
        return defs[offset]

    def_reach = {}
    changed = True
    while changed:  # every definition reaching the entry of a block
        changed = False
        for offset in topo_order:
            old = def_reach.get(offset, 0)
            here = old | def_bits(offset) | uses[offset]
            if here != old:
                def_reach[offset] = here
                changed = True
            for out_blk, _ in cfg.successors(offset):
                before = def_reach.get(out_blk, 0)
                after = before | here
                if after != before:
                    def_reach[out_blk] = after
                    changed = True
    live = {offset: uses[offset] for offset in blocks.keys()}
    order = list(reversed(topo_order))
    changed = True
    while changed:  # a use pushed back to every predecessor it is reachable at, not defined in
        changed = False
        for offset in order:
            live_vars = live[offset]
            for inc_blk, _data in cfg.predecessors(offset):
                before = live[inc_blk]
                after = before | (live_vars & def_reach.get(inc_blk, 0) & ~def_bits(inc_blk))
                if after != before:
                    live[inc_blk] = after
                    changed = True
    return {offset: b.names_of(bits) for offset, bits in live.items()}


def _known_source(function, known: set[str]) -> str | None:
    """``function``'s source where its SHA-1 is in ``known``, else None (another numba)."""
    try:
        source = inspect.getsource(function)
    except (OSError, TypeError):
        return None
    return source if hashlib.sha1(source.encode()).hexdigest() in known else None


def _inline_ir_from(source: str):
    """numba's ``InlineWorker.inline_ir`` compiled from its own ``source`` with
    :data:`INLINE_COPY`'s change, in its module's namespace (the names it reads are numba's)."""
    old, new = INLINE_COPY
    if source.count(old) != 1:
        return None
    namespace: dict = {}
    code = compile(textwrap.dedent(source.replace(old, new)), inline_closurecall.__file__, "exec")
    exec(code, vars(inline_closurecall), namespace)  # reads numba's module globals, live
    function = namespace["inline_ir"]
    function.__qualname__ = _numba_inline_ir.__qualname__
    function.__doc__ = _numba_inline_ir.__doc__
    return function


#: numba's ``InlineWorker.inline_ir`` with the callee's blocks copied under one memo; None where
#: numba's source is not the known one
inline_ir = _inline_ir_from(source) if (source := _known_source(_numba_inline_ir, KNOWN_INLINE)) else None


def _install_inline() -> bool:
    if inline_ir is None:
        return False  # another numba: its own inlining
    inline_closurecall.InlineWorker.inline_ir = inline_ir
    return True


def _install() -> bool:
    if _known_source(_numba_copy_propagate, KNOWN) is None:
        return False  # another numba: its own copy propagation
    from numba.parfors import parfor

    ir_utils.copy_propagate = copy_propagate
    if getattr(parfor, "copy_propagate", None) is _numba_copy_propagate:
        parfor.copy_propagate = copy_propagate
    return True


def _install_live() -> bool:
    if _known_source(_numba_compute_live_map, KNOWN_LIVE) is None:
        return False  # another numba: its own liveness
    from numba.parfors import parfor

    analysis.compute_live_map = compute_live_map
    for module in (ir_utils, parfor):  # they imported it by name
        if getattr(module, "compute_live_map", None) is _numba_compute_live_map:
            module.compute_live_map = compute_live_map
    return True


#: whether numba's ``init_copy_propagate_data`` is the one :func:`init_copy_propagate_data` copies
_init_known = _known_source(ir_utils.init_copy_propagate_data, KNOWN_INIT) is not None

#: whether numba's copy propagation is this module's (False: numba's own, another version)
installed = _install()

#: whether numba's ``InlineWorker.inline_ir`` is this module's (False: numba's own)
inline_installed = _install_inline()

#: whether numba's ``analysis.compute_live_map`` is this module's (False: numba's own)
live_installed = _install_live()
