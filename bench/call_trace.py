"""The calls between antisync's modules during one command, traced (``sys.setprofile``).

    python bench/call_trace.py run /tmp/tiny_run.yaml --quiet
    python bench/call_trace.py grid removal configs/ieee14_grid.yaml --lines 4-5 \\
        --realizations 2 --set dynamics.integrator=rodas4 --out /tmp/rem.h5 --quiet

Counts every antisync module one of whose functions ran, the distinct (caller function, callee
function) pairs between two different antisync modules, and how many of them call a module of
a later stage than the caller's (the stages of tests/test_architecture.py: a call back up the
import order, through a callback). Imports' own calls count too (module bodies are skipped).
Issue 60 counted "modules passed through" and "calls back up the layer order" by a definition
it does not state; this is a reproducible one, to compare commands with each other.
"""

from __future__ import annotations

import collections
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
    print(f"modules {len(modules)}, distinct calls between modules {len(edges)}, to a later stage {len(up)}")
    for e in up:
        print("   up:", e)
    for m in modules:
        print("  ", m)


if __name__ == "__main__":
    main()
