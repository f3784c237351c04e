"""antisync: antifragility of Kuramoto synchronization to the damage of one link.

A notebook user can compute without touching a file::

    from antisync import graphs
    g = graphs.lollipop(6, 3)

See the README for the command line (``antisync run configs/lollipop6.yaml``).
"""

import hashlib
import os
import sys
from pathlib import Path

__version__ = "0.1.0"


def _numba_cache_dir() -> None:
    """Key numba's on-disk cache by the package's source.

    Numba invalidates a cached function only when the file that defines it changes, not when
    a function it calls changes; the kernels are compiled from closures in ``kernels/core.py``
    and ``phases.py``, so an edit there could leave stale machine code in use. A cache folder
    named after a hash of every source file makes any edit start a fresh cache. A user's own
    ``NUMBA_CACHE_DIR`` is respected.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    src = Path(__file__).resolve().parent
    digest = hashlib.sha1()
    for path in sorted(src.rglob("*.py")):
        digest.update(path.read_bytes())
    folder = str(src / "__pycache__" / f"numba-{digest.hexdigest()[:12]}")
    os.environ["NUMBA_CACHE_DIR"] = folder
    if "numba" in sys.modules:  # numba read its config already: tell it too
        sys.modules["numba"].config.CACHE_DIR = folder


_numba_cache_dir()
