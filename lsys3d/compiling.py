"""Numba's compilation of lsys3d's kernels, watched.

The first run of lsys3d compiles its kernels (numba, ``cache=True``) and writes them to the ``__pycache__``
folders beside their modules; later runs load them in a fraction of a second.  The first run takes most of
a minute, so the command line says what it is doing meanwhile: :func:`watch` calls back on each kernel
compiled, with the number compiled so far and the number of kernels of the loaded modules that have no
cached code yet.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

from numba.core import event
from numba.core.registry import CPUDispatcher


def kernels() -> list[CPUDispatcher]:
    """lsys3d's kernels in the modules imported so far (each once)."""
    seen: dict[int, CPUDispatcher] = {}
    for name, module in list(sys.modules.items()):
        if (name != "lsys3d" and not name.startswith("lsys3d.")) or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                seen[id(value)] = value
    return list(seen.values())


def is_cached(kernel: CPUDispatcher) -> bool:
    """Whether ``kernel`` has compiled code in memory or an index of it on disk (for some signature)."""
    if kernel.overloads:
        return True
    cache_file = getattr(kernel._cache, "_cache_file", None)  # numba's FunctionCache; a NullCache has none
    if cache_file is None:
        return False
    return bool(cache_file._load_index())


def _own(dispatcher) -> bool:
    """Whether a dispatcher numba compiles is one of lsys3d's (not one of numba's own helpers)."""
    module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
    return module == "lsys3d" or module.startswith("lsys3d.")


class _Counter(event.Listener):
    """Counts the lsys3d kernels numba compiles (one per function, whatever its signatures)."""

    def __init__(self, report: Callable[[int, int, str], None], total: int):
        self.report = report
        self.total = total
        self.done: set[int] = set()

    def on_start(self, ev: event.Event) -> None:
        dispatcher = ev.data["dispatcher"]
        if not _own(dispatcher) or id(dispatcher) in self.done:
            return
        self.done.add(id(dispatcher))
        self.total = max(self.total, len(self.done))
        self.report(len(self.done), self.total, dispatcher.py_func.__qualname__)

    def on_end(self, ev: event.Event) -> None:
        pass


@contextlib.contextmanager
def watch(report: Callable[[int, int, str], None]) -> Iterator[None]:
    """Call ``report(compiled, total, name)`` each time numba starts compiling one of lsys3d's kernels.

    ``compiled`` counts the kernels compiled so far (a kernel once, whatever its signatures), ``total``
    the kernels of the modules imported when the watch began that had no cached code (more, should
    more be compiled), ``name`` the kernel's name.  Nothing is called when every kernel comes from the
    cache.
    """
    total = sum(not is_cached(k) for k in kernels())
    counter = _Counter(report, total)
    event.register("numba:compile", counter)
    try:
        yield
    finally:
        event.unregister("numba:compile", counter)
