"""Where numba caches antisync's compiled kernels: a folder keyed by the package's source.

Numba invalidates a cached function only when the file that defines it changes, not when a
function it calls changes; the kernels are compiled from closures in ``kernels/core.py`` and
``phases.py``, so an edit there could leave stale machine code in use. antisync's functions
are therefore cached in ``__pycache__/numba-<hash of every source file>`` inside the package,
so any edit starts a fresh cache.

This is done with a cache *locator* that answers only for files inside this package, so
importing antisync changes where no other numba code in the process is cached (no environment
variable, no global cache folder). A user's own ``NUMBA_CACHE_DIR`` is respected: then numba
caches antisync there as it caches everything else. (One process-wide change comes with it:
:mod:`antisync._numba_compile` makes numba's copy propagation, inlining and liveness analysis faster for every
compile, with the same result.)

Every module that compiles with ``cache=True`` imports this module first (and so
:mod:`antisync._numba_compile`).
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

from numba.core import caching

from antisync import _numba_compile  # noqa: F401 -- numba's compiler passes, faster (see there)

__all__ = ["cache_dir"]

PACKAGE = Path(__file__).resolve().parent


@functools.cache
def cache_dir() -> Path:
    """``<package>/__pycache__/numba-<first 12 hex digits of the sources' SHA-1>``."""
    digest = hashlib.sha1()
    for path in sorted(PACKAGE.rglob("*.py")):
        digest.update(path.read_bytes())
    return PACKAGE / "__pycache__" / f"numba-{digest.hexdigest()[:12]}"


class _PackageCacheLocator(caching.UserProvidedCacheLocator):
    """Caches functions defined in antisync's own files in :func:`cache_dir`."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = str(cache_dir() / self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        if os.environ.get("NUMBA_CACHE_DIR"):
            return None  # the user chose a cache folder for everything: numba's own locator
        try:
            Path(py_file).resolve().relative_to(PACKAGE)
        except ValueError:
            return None  # not antisync's code: numba decides as usual
        return super(caching.UserProvidedCacheLocator, cls).from_function(py_func, py_file)


if _PackageCacheLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, _PackageCacheLocator)
