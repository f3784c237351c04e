"""The calls between antisync's modules during one command, traced (``sys.setprofile``).

    python bench/call_trace.py run /tmp/tiny_run.yaml --quiet
    python bench/call_trace.py grid removal configs/ieee14_grid.yaml --lines 4-5 \\
        --realizations 2 --set dynamics.integrator=rodas4 --out /tmp/rem.h5 --quiet

Counts every antisync module one of whose functions ran, the distinct (caller function, callee
function) pairs between two different antisync modules, and how many of them call a module of
a later stage than the caller's (the stages of tests/test_architecture.py: a call back up the
import order, through a callback). Calls made while a module is imported (from a module's or a
class's body: a dataclass's defaults, typer's option lists) are not the command's work and are
not counted. The modules are counted twice: as files, and as the stage packages they belong to
(``antisync.grids``, ``antisync.store``, ...; the root's shared files, ``antisync.validation``
and the like, belong to no stage and are not counted there).

Issue 60 counted "modules passed through" and "calls back up the layer order" by a definition
it does not state; this is a reproducible one, to compare commands with each other. By it,
``antisync run`` of a lollipop passes through 8 stage packages (the number the issue gives for
a run), which suggests the issue counted packages.
"""

from __future__ import annotations

import collections
import inspect
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_architecture import STAGES  # noqa: E402 -- the layer order the tests hold


def stage(mod: str) -> int:
    """The stage of module ``mod`` (0: the package root's shared files)."""
    parts = mod.split(".")
    if len(parts) < 2 or parts[1] not in STAGES:
        return 0
    return STAGES.index(parts[1])


calls: collections.Counter = collections.Counter()


def prof(frame, event, arg) -> None:
    """Count a call from one antisync module into another."""
    if event != "call":
        return
    callee = frame.f_globals.get("__name__", "")
    if not callee.startswith("antisync"):
        return
    caller_f = frame.f_back
    if caller_f is None:
        return
    if not caller_f.f_code.co_flags & inspect.CO_NEWLOCALS:
        return  # a module's or a class's body: an import, not the command's work
    caller = caller_f.f_globals.get("__name__", "")
    if not caller.startswith("antisync") or caller == callee:
        return
    if frame.f_code.co_name.startswith("<"):
        return
    calls[(caller, caller_f.f_code.co_name, callee, frame.f_code.co_name)] += 1


def main() -> None:
    from antisync.cli.app import main as cli

    sys.setrecursionlimit(10000)
    sys.argv = ["antisync", *sys.argv[1:]]
    sys.setprofile(prof)
    try:
        cli()
    except SystemExit:
        pass
    sys.setprofile(None)
    edges = list(calls)
    modules = sorted({e[0] for e in edges} | {e[2] for e in edges})
    up = [e for e in edges if stage(e[2]) > stage(e[0])]
    packages = sorted({".".join(m.split(".")[:2]) for m in modules if stage(m) > 0})
    print(f"modules {len(modules)}, distinct calls between modules {len(edges)}, to a later stage {len(up)}")
    print(f"stage packages {len(packages)}: {', '.join(p.split('.')[1] for p in packages)}")
    for e in up:
        print("   up:", e)
    for m in modules:
        print("  ", m)


if __name__ == "__main__":
    main()
