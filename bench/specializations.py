"""The kernels numba compiled more than once, read from antisync's on-disk cache.

Run it after the test suite (or any workload) on a fresh cache: every function cached with more
than one signature is listed with the arguments whose types differ, and the total size of its
cached machine code (a proxy for its compile time). A literal argument (``Literal[bool](False)``,
``Literal[int](0)``), an omitted default or a second array layout means the same kernel was
compiled again for nothing (antisync/kernels/shared.py, ``has_inertia``, says how it happens)::

    NUMBA_CACHE_DIR=/tmp/nc make test      # or a fresh clone's `make test`
    python bench/specializations.py /tmp/nc

Without an argument it reads the package's own cache folder (``antisync._numba_cache``).
"""

from __future__ import annotations

import argparse
import pickle
from pathlib import Path


def cached_functions(folder: Path):
    """``(name, signatures, bytes)`` of every function in the numba cache under ``folder``."""
    for index in sorted(folder.rglob("*.nbi")):
        with index.open("rb") as fh:
            pickle.load(fh)  # numba's version
            _stamp, overloads = pickle.loads(fh.read())
        stem = index.name[: -len(".nbi")]
        size = sum(p.stat().st_size for p in index.parent.glob(stem + ".*.nbc"))
        yield stem, [key[0] for key in overloads], size


def differing(signatures) -> list[str]:
    """The argument positions whose types differ between ``signatures``, with the types."""
    out = []
    for i in range(max(len(s) for s in signatures)):
        kinds = sorted({str(s[i]) if i < len(s) else "(absent)" for s in signatures})
        if len(kinds) > 1:
            out.append(f"arg {i}: " + " | ".join(kind[:90] for kind in kinds))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", help="the numba cache folder (default: antisync's)")
    args = parser.parse_args(argv)
    if args.folder:
        folder = Path(args.folder)
    else:
        from antisync._numba_cache import cache_dir

        folder = cache_dir()
    rows = list(cached_functions(folder))
    if not rows:
        print(f"no numba cache index under {folder}")
        return 1
    total = sum(size for _, _, size in rows)
    twice = [row for row in rows if len(row[1]) > 1]
    print(
        f"{folder}: {len(rows)} functions, {sum(len(s) for _, s, _ in rows)} compiled signatures, "
        f"{total / 1e6:.1f} MB of machine code; {len(twice)} compiled more than once "
        f"({sum(size for *_, size in twice) / 1e6:.1f} MB):"
    )
    for name, signatures, size in sorted(twice, key=lambda row: -row[2]):
        print(f"  {len(signatures)} x {name} ({size / 1e3:.0f} kB)")
        for line in differing(signatures):
            print(f"      {line}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
