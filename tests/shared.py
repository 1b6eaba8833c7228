"""Results the test run computes once and shares between its processes (pytest-xdist's workers).

``make test`` runs ``pytest -n auto``: two workers on the 2-core machine, each a process of its own, so a
module-level cache is computed once per worker.  :func:`shared` computes a result once in the whole run: the
first process that needs it computes it and leaves it pickled in the run's folder (:data:`SHARED`, made by
``tests/conftest.py`` before the workers start); the others wait for it and load it.  lsys3d is deterministic
(same grammar, options and seed: same arrays in any process), so a loaded result is the one the process would
have computed; the tests treat shared results as read-only, as they do the per-process caches.
"""

from __future__ import annotations

import copyreg
import fcntl
import os
import pickle
import types
from pathlib import Path

#: The environment variable naming the run's shared folder (unset, as in a plain ``pytest``: no sharing).
SHARED = "LSYS3D_TESTS_SHARED"


def _mapping_proxy(items: dict) -> types.MappingProxyType:
    return types.MappingProxyType(items)


# a tree's read-only tables (mappingproxy) are pickled as the dict they show and read back as a proxy again
copyreg.pickle(types.MappingProxyType, lambda proxy: (_mapping_proxy, (dict(proxy),)))


def shared(key: str, make):
    """``make()``, computed once in the whole run under pytest-xdist (once per process without it)."""
    folder = os.environ.get(SHARED)
    if not folder:
        return make()
    path = Path(folder) / f"{key}.pickle"
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the other process waits for the result instead of computing it too
        try:
            if path.exists():
                return pickle.loads(path.read_bytes())
            value = make()
            partial = path.with_suffix(f".{os.getpid()}.part")
            partial.write_bytes(pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
            partial.replace(path)
            return value
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
