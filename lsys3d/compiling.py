"""Numba's compilation of lsys3d's kernels, watched, and shared with a second process.

The first run of lsys3d compiles its kernels (numba, ``cache=True``) and writes them to the ``__pycache__``
folders beside their modules; later runs load them in a fraction of a second.  The first run takes a while,
so the command line says what it is doing meanwhile: :func:`watch` calls back on each kernel
compiled, with the number compiled so far and the number of kernels of the loaded modules that have no
cached code yet.

:func:`ahead` halves the wait on two cores: while the main process derives, draws, sweeps and unions
(compiling those stages' kernels), a helper process compiles the kernels of a later stage into the cache
(:mod:`lsys3d.mesh.precompile`: the cleanup's), and the main process loads them from there.  No kernel is
compiled by both at once: the helper compiles only the kernels of its own modules (:func:`only` stops it at
any other), and the main process waits for it (:func:`wait`) before it calls into those modules, and in any
case before it would compile one of their kernels itself.  The kernels the main process needs last (groups of
them, each a :class:`Spare`: :mod:`lsys3d.firstrun`'s) go to whichever process is idle first: the helper when it
is done with its own while the main process still works, the main process when it reaches the helper's modules
while the helper still works; the first to claim a group (a file created once) compiles it, and both take the
groups in the same order, one at a time.

Two decorators compile every kernel with no more than it needs: :func:`kernel` (numba's ``njit``, cached,
without the C-function wrapper nothing of lsys3d calls) for a kernel Python calls, and :func:`inner` for one
only other kernels call (without the CPython wrapper either).  Each wrapper is lowered, optimised and turned
into machine code with its kernel, for nothing: a tenth of a first run's compiling (a fifth of the cleanup's).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import NamedTuple

import numba
from numba.core import event
from numba.core.registry import CPUDispatcher

log = logging.getLogger("lsys3d")


def kernel(**options) -> Callable:
    """``numba.njit(cache=True, **options)`` without the C-function wrapper (for calling the kernel as a
    first-class function from other jitted code, which lsys3d never does).

    Examples
    --------
    In a module of lsys3d (numba caches a kernel beside its source file)::

        @kernel(nogil=True)
        def total(a):
            return a.sum()
    """
    return numba.njit(cache=True, no_cfunc_wrapper=True, **options)


class InnerKernel(CPUDispatcher):
    """A kernel compiled for other kernels only (:func:`inner`): called from Python, it raises."""

    def __call__(self, *args, **kwargs):
        name = f"{self.py_func.__module__}.{self.py_func.__qualname__}"
        raise TypeError(f"{name}: compiled for other kernels only (lsys3d.compiling.inner), not callable from Python")


def inner(**options) -> Callable:
    """:func:`kernel` for a kernel that only other kernels call: compiled without the CPython wrapper too.

    Its code would crash the process if Python called it, so the dispatcher raises :class:`TypeError`
    instead (``tests/test_compiling.py`` checks that no Python code of lsys3d names one).

    Examples
    --------
    In a module of lsys3d::

        @inner()
        def twice(x):
            return 2 * x

        @kernel()
        def four(x):
            return twice(twice(x))

    ``four(1)`` is 4; ``twice(1)`` raises :class:`TypeError`.
    """
    jit = numba.njit(cache=True, no_cfunc_wrapper=True, no_cpython_wrapper=True, **options)

    def decorate(func):
        dispatcher = jit(func)
        if isinstance(dispatcher, CPUDispatcher):  # (not under NUMBA_DISABLE_JIT: the plain function then)
            dispatcher.__class__ = InnerKernel
        return dispatcher

    return decorate


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


class ForeignKernel(RuntimeError):
    """A helper process (:func:`only`) was about to compile a kernel that is not one of its own."""


def _module(dispatcher) -> str:
    return getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""


def _name(dispatcher) -> str:
    """A kernel's module and qualified name, ``lsys3d.arrays.search_left``."""
    return f"{_module(dispatcher)}.{getattr(getattr(dispatcher, 'py_func', None), '__qualname__', '')}"


class _Only(event.Listener):
    def __init__(self, own: tuple[str, ...], but: tuple[str, ...] = ()):
        self.own, self.but = own, but

    def on_start(self, ev: event.Event) -> None:
        dispatcher = ev.data["dispatcher"]
        name = _name(dispatcher)
        if _own(dispatcher) and (not name.startswith(self.own) or (self.but and name.startswith(self.but))):
            raise ForeignKernel(f"lsys3d.compiling.only: {name} is not a kernel of {', '.join(self.own)}")

    def on_end(self, ev: event.Event) -> None:
        pass


@contextlib.contextmanager
def only(own: tuple[str, ...], but: tuple[str, ...] = ()) -> Iterator[None]:
    """Raise :class:`ForeignKernel` where numba would compile one of lsys3d's kernels outside ``own`` (prefixes of
    module names, or of a kernel's module and qualified name), or one of ``but`` (prefixes too: the spare
    groups among them): what a helper process of :func:`ahead` runs under."""
    listener = _Only(tuple(own), tuple(but))
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)


class Spare(NamedTuple):
    """Kernels either process of :func:`ahead` may compile: the first to claim them compiles them all.

    ``names`` are the prefixes of their names (module and qualified name: every kernel ``compile`` compiles,
    the kernels it calls too), ``compile`` compiles them (numba's ``compile`` with the signatures the pipeline
    calls them with).  None of them may be a kernel the main process compiles before it reaches the helper's
    modules (it would claim them then), one the helper's own kernels call or one of another spare group.  A
    group may hold kernels of the helper's own modules that the pipeline calls late (the group's names take them
    out of the helper's own), and its kernels may call helper's own ones that the helper compiles early (they
    come from the cache by the time a process is idle; should one not, the main process waits for the helper
    before compiling it, as for any of the helper's kernels).
    """

    names: tuple[str, ...]
    compile: Callable[[], None]

    def covers(self, dispatcher) -> bool:
        return _name(dispatcher).startswith(self.names)


_CLAIMS = "LSYS3D_COMPILING_CLAIMS"
"""The environment variable naming the folder where a file created claims a spare group (for the helper)."""


def _claim(path: str | None) -> bool:
    """Whether this process is the first to claim what the file ``path`` stands for (it creates the file)."""
    if not path:
        return False
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except OSError:  # FileExistsError: the other process was first (or the folder is gone)
        return False
    return True


_COMPILING_THRESHOLDS = (100_000, 50, 1_000)
"""Python's cycle collector's thresholds while a first run compiles (:func:`seldom_collected`; its defaults:
700, 10, 10)."""


@contextlib.contextmanager
def seldom_collected() -> Iterator[None]:
    """Python's cycle collector seldom while the block runs, and none of the objects made before it looked at.

    Numba makes many objects while it compiles, and most of them live on (the kernels' types, IR and
    libraries): with the default thresholds the collector walks them again and again, 1.5 CPU s of a first
    run's helper.  ``gc.freeze()`` leaves the objects made so far (the imported modules) out of its walks and
    :data:`_COMPILING_THRESHOLDS` make it run a hundred times less often; both are undone on the way out.
    Only :func:`ahead`, on a first run, and its helper use it.
    """
    previous = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(*_COMPILING_THRESHOLDS)
    try:
        yield
    finally:
        gc.set_threshold(*previous)
        gc.unfreeze()


def help_ahead(own: tuple[str, ...], run: Callable[[], None], spares: Sequence[Spare] = ()) -> None:
    """What a helper process of :func:`ahead` runs (its module's ``__main__``): ``run()``, under :func:`only`
    ``own``, then each of the ``spares`` the main process has not claimed yet (the collector seldom:
    :func:`seldom_collected`)."""
    with seldom_collected():
        with only(own, but=tuple(name for spare in spares for name in spare.names)):
            run()
        folder = os.environ.get(_CLAIMS)
        for i, spare in enumerate(spares):
            if folder and _claim(os.path.join(folder, str(i))):
                with only(spare.names):
                    spare.compile()


class Helper:
    """A process compiling the kernels of the modules ``own`` into numba's cache (see :func:`ahead`), and the
    groups of ``spares`` it claims first (``claims``: the folder of the files whose creation claims them);
    ``path``: folders put before this lsys3d on its ``PYTHONPATH`` (for a ``module`` outside lsys3d)."""

    def __init__(
        self,
        module: str,
        own: tuple[str, ...],
        spares: Sequence[Spare] = (),
        claims: str | None = None,
        main_only: Callable[[], None] | None = None,
        path: Sequence[str] = (),
    ):
        self.module = module
        self.own = tuple(own)
        self.spares, self._claims, self._main_only = tuple(spares), claims, main_only
        self._mine: dict[int, bool] = {}  # the spare groups claimed so far: by this process (True) or the helper
        self._idled = False
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # this lsys3d, not another install's
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([*path, root, *filter(None, [os.environ.get("PYTHONPATH")])]))
        env.pop(_CLAIMS, None)
        if spares and claims:
            env[_CLAIMS] = claims
        # a file, not a pipe: a helper with much to say never waits for the main process to read it
        self._stderr = tempfile.TemporaryFile()  # noqa: SIM115 (closed by wait)
        self.process = subprocess.Popen(
            [sys.executable, "-m", module],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=self._stderr,
        )
        self.returncode: int | None = None
        self._lock = threading.Lock()
        self._spare_lock = threading.RLock()

    def wait(self) -> None:
        """Wait for the process to end (at once if it has); its failure is only logged: the main process
        then compiles what it did not."""
        with self._lock:  # (the cleanup's two threads may both get here)
            if self.returncode is not None:
                return
            start = time.perf_counter()
            self.returncode = self.process.wait()
            waited = time.perf_counter() - start
            if waited > 0.05:
                log.info("compiling: waited %.1f s for the helper %s", waited, self.module)
            with self._stderr:
                self._stderr.seek(0)
                err = self._stderr.read()
        if self.returncode:
            tail = err.decode(errors="replace").strip().splitlines()[-1:] or [""]
            log.debug("compiling: the helper %s failed (%d): %s", self.module, self.returncode, tail[0])

    def covers(self, dispatcher) -> bool:
        """Whether this process must wait for the helper before compiling ``dispatcher``: one of a spare group the
        helper claimed (this process claims the group if nobody has), else one of the helper's own kernels."""
        for i, spare in enumerate(self.spares):
            if spare.covers(dispatcher):
                return not self.spare_is_mine(i)
        return _name(dispatcher).startswith(self.own)

    def spare_is_mine(self, i: int) -> bool:
        """Whether this process compiles the spare group ``i``: it claims it unless the helper was first."""
        with self._spare_lock:
            if i not in self._mine:
                self._mine[i] = _claim(self._claims and os.path.join(self._claims, str(i)))
            return self._mine[i]

    def idle(self) -> None:
        """The main process has nothing to do but wait for the helper: meanwhile it compiles the main-only
        kernels, then the spare groups the helper has not claimed (claiming each in turn, as the helper does when
        done with its own: so a helper done first finds groups left to share); nothing when the helper has ended
        (they are compiled where they are called)."""
        if not (self.spares or self._main_only) or self.process.poll() is not None:
            return
        with self._spare_lock:  # (reentrant: the gate asks spare_is_mine while they compile)
            if self._idled:
                return
            self._idled = True
            start = time.perf_counter()
            if self._main_only is not None:
                self._main_only()
            for i, spare in enumerate(self.spares):
                if self.spare_is_mine(i):
                    spare.compile()
        log.info("compiling: %.1f s compiling the spare kernels while the helper ran", time.perf_counter() - start)


_helpers: list[Helper] = []


class _Gate(event.Listener):
    """In the main process: before compiling a kernel of a running helper's modules, wait for the helper."""

    def on_start(self, ev: event.Event) -> None:
        dispatcher = ev.data["dispatcher"]
        for helper in list(_helpers):
            if helper.covers(dispatcher):
                helper.wait()

    def on_end(self, ev: event.Event) -> None:
        pass


def wait(module: str) -> None:
    """Wait for the helpers compiling the kernels of ``module`` (a module name): call it before calling into
    the module, so its kernels come from the cache.  Nothing to wait for, mostly: returns at once.  While a
    helper still runs, this process compiles the spare kernels first (:meth:`Helper.idle`)."""
    for helper in list(_helpers):
        if module.startswith(helper.own):
            helper.idle()
            helper.wait()


@contextlib.contextmanager
def ahead(
    module: str,
    own: tuple[str, ...],
    entries: Iterable[CPUDispatcher],
    spares: Sequence[Spare] = (),
    main_only: Callable[[], None] | None = None,
    path: Sequence[str] = (),
) -> Iterator[Helper | None]:
    """While the block runs, compile the kernels of the modules ``own`` in a helper process, ``python -m
    module``, if any of ``entries`` (the kernels it calls first) has no cached code: on a first run only.
    Each group of ``spares`` goes to whichever process is idle first (:class:`Spare`; the helper's module
    calls :func:`help_ahead` with the same ones, in the same order); ``main_only`` is what this process
    compiles while it waits for the helper (kernels that call ones it compiles before); ``path``: folders the
    helper's module needs on its ``PYTHONPATH`` besides this lsys3d (one outside the package, e.g. the tests').

    Yields the :class:`Helper`, or None when everything is cached.  The block must call :func:`wait` before
    it calls into those modules; should it compile one of their kernels first, it waits for the helper
    then (and compiles that kernel again: the lookup in the cache came before).  The helper is waited for
    on the way out.  The results are the same with or without it: it only fills the cache.
    """
    if all(is_cached(k) for k in entries):
        yield None
        return
    folder = tempfile.mkdtemp(prefix="lsys3d-compiling-") if spares else None
    try:
        helper = Helper(module, own, spares, folder, main_only, path)
    except OSError as exc:  # no process to be had: this one compiles everything, as without a helper
        log.debug("compiling: no helper %s: %s", module, exc)
        if folder:
            shutil.rmtree(folder, ignore_errors=True)
        yield None
        return
    gate = _Gate()
    _helpers.append(helper)
    event.register("numba:compile", gate)
    try:
        with seldom_collected():  # (a first run: this process compiles most of the time too)
            yield helper
    except BaseException:
        helper.process.terminate()  # (an error or ^C: its work is thrown away with the main process's)
        raise
    finally:
        event.unregister("numba:compile", gate)
        try:
            helper.wait()
        finally:
            _helpers.remove(helper)
            if folder:
                shutil.rmtree(folder, ignore_errors=True)
