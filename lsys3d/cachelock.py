"""One process at a time writes an entry into numba's kernel cache.

numba keeps, per cached function, an index (signature -> data file) beside the data files, and saves a new
entry by reading the index, taking the first data-file name the index does not use, writing the index back,
then the data (``numba.core.caching.IndexDataCacheFile.save``).  Each file is replaced atomically, but the
four steps are not one step: two processes that compile one function at once for two signatures (two batch
workers or two ``lsys3d generate`` on a render farm, all starting from an empty cache) can both read the
index before either writes it.  Then one signature's entry is lost, or both take the same data-file name and
the index names the other signature's code, which the next process loads and calls with the wrong types
(numba issue 4807, "Cache causes Segmentation Faults when generated in parallel", open).

:func:`install` makes each save hold an exclusive lock (``fcntl.flock``) on one file in the cache folder,
``lsys3d-numba.lock``, so that the save reads the index as the other processes left it, and each load hold
it shared: numba writes the index before the data file it names, and after a change to a kernel's source
(an upgrade) the data files of the old code are still there under the names the new index reuses, so a
process loading between the two writes would run the old code.  It is installed by
``import lsys3d`` and costs nothing until numba is imported (an import hook patches numba's cache module
when it is loaded).  It serialises only the saves, a few milliseconds each, not the compiling.  Without
``fcntl`` (Windows) nothing is locked: numba guards its own saves there (numba issue 2028).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.abc
import importlib.machinery
import os
import sys
from collections.abc import Iterator

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

_MODULE = "numba.core.caching"
LOCK_NAME = "lsys3d-numba.lock"


@contextlib.contextmanager
def locked(folder: str, shared: bool = False) -> Iterator[None]:
    """Hold the lock of the cache folder ``folder``: exclusive, or ``shared`` (readers); nothing when the lock
    file cannot be opened (a read-only folder: numba cannot save there either)."""
    if fcntl is None:
        yield
        return
    try:
        handle = open(os.path.join(folder, LOCK_NAME), "a")  # noqa: SIM115 - held across the yield
    except OSError:
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _patch(caching) -> None:
    """Make ``caching.IndexDataCacheFile.save`` hold the folder's lock, and ``load`` hold it shared (once)."""
    cls = caching.IndexDataCacheFile
    save, load = cls.save, cls.load
    if getattr(save, "lsys3d_locked", False):
        return

    @functools.wraps(save)
    def locked_save(self, key, data):
        with locked(self._cache_path):
            return save(self, key, data)

    @functools.wraps(load)
    def locked_load(self, key):
        with locked(self._cache_path, shared=True):
            return load(self, key)

    locked_save.lsys3d_locked = locked_load.lsys3d_locked = True
    cls.save, cls.load = locked_save, locked_load


class _Hook(importlib.abc.MetaPathFinder):
    """Patches numba's cache module as it is loaded, then leaves ``sys.meta_path``."""

    def find_spec(self, name, path, target=None):
        if name != _MODULE:
            return None
        with contextlib.suppress(ValueError):
            sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(name, path, target)
        if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
            return spec
        exec_module = spec.loader.exec_module

        def exec_and_patch(module):
            exec_module(module)
            _patch(module)

        spec.loader.exec_module = exec_and_patch
        return spec


def install() -> None:
    """Lock numba's cache saves in this process: now if numba's cache module is loaded, else when it is."""
    module = sys.modules.get(_MODULE)
    if module is not None:
        _patch(module)
    elif not any(isinstance(finder, _Hook) for finder in sys.meta_path):
        sys.meta_path.insert(0, _Hook())
