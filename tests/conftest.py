"""Hypothesis profiles: the default one is derandomized, so the suite gives the same verdict on every run.

Profile "default" (plain ``pytest``): fixed examples, CI-sized.  Profile "fuzz"
(``HYPOTHESIS_PROFILE=fuzz pytest -k any``): random examples on demand, 2000 where a
test does not set its own count.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import first_run
import pytest
import shared
import warm_up
from hypothesis import settings

# Bytecode caches for the suite's own processes, as for any project: with PYTHONDONTWRITEBYTECODE set (as on the
# machines the suite's times are measured on) pytest rewrote every test module and every lsys3d module it imports
# (lsys3d is a pytest plugin's package: pytest rewrites its asserts too) in every worker and every inner pytest
# run (tests/test_golden.py) again, 3 CPU s a worker and 0.8 s a run; pytest reads its cached rewrites whatever
# the variable says, so the first process to rewrite a module writes it for the others (and the next runs).
# _byte_compile() below does the same for the plain imports of the lsys3d children the tests start.
sys.dont_write_bytecode = False

settings.register_profile("default", derandomize=True, print_blob=True)
settings.register_profile("fuzz", derandomize=False, max_examples=2000, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.hookimpl(wrapper=True)
def pytest_sessionstart(session):
    """The pipeline's kernels compiled once, in this process, before the first test.

    numba writes them to the package's ``__pycache__``, so the tests that run ``lsys3d`` in a subprocess (the
    CLI, batch workers) load them instead of each compiling them again, and a test that interrupts a
    subprocess does not catch it in the middle of a minute of compiling.  Under pytest-xdist (``make test``
    runs ``pytest -n auto``) this runs in the controller, so the workers load the kernels instead of compiling
    them side by side (two processes writing one kernel's cache index at once can point it at the other's
    machine code).  The default tree (a species: form, leaves) and the textbook tree3d take the paths most tests
    take, a polygon the turtle's rare ops (its kernel's second compilation), and tree3d is written as .glb and
    .usdc (the writers' kernels); warm, this costs about three seconds.  The two trees are shared with the
    workers (tests/shared.py), which would otherwise each grow them again.  (tests/warm_up.py; from an empty cache
    it splits what is left after the first run between this process and a helper process.)

    From an empty cache (a fresh clone, CI) the compiling starts with a user's first run, ``lsys3d generate``
    in a child process (tests/first_run.py): it compiles the default tree's kernels into the suite's cache
    the way a user's first run does (the cleanup's in a helper process on the other core), and its record
    is what tests/test_compiling.py's first-run test asserts on, instead of compiling them all once more.

    A hook wrapper: what the workers inherit (the shared folder, where the first run's record will be) is set
    before pytest-xdist starts them, and the compiling runs after, while they start and collect the suite
    (some 10 CPU seconds each, on the core the compiling leaves idle much of the time).  No test starts before
    it ends: the controller hands out the first tests when this hook returns.
    """
    if hasattr(session.config, "workerinput") or session.config.option.collectonly:
        return (yield)  # an xdist worker: the controller compiles them
    if getattr(session.config.option, "dist", "no") != "no":
        # the folder where the workers share what one of them computed (tests/shared.py), before they start
        run = tempfile.mkdtemp(prefix="lsys3d-tests-")
        os.environ[shared.SHARED] = run
        session.config.add_cleanup(lambda: shutil.rmtree(run, ignore_errors=True))
    _byte_compile()
    folder = None
    if first_run.cache_is_empty():
        # a fresh clone: the first compiling is a user's first run, done once for real (tests/first_run.py)
        folder = Path(tempfile.mkdtemp(prefix="lsys3d-first-run-"))
        session.config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
        os.environ[first_run.RECORD] = str(folder / "first-run.json")
    result = yield  # pytest-xdist starts the workers
    if folder is not None:
        first_run.run(folder)
    warm_up.warm_up(cold=folder is not None)
    return result


def _byte_compile() -> None:
    """lsys3d's modules (and the tests' helper modules) byte-compiled into their ``__pycache__``, where numba
    keeps the kernels, before the workers start, unless they are already.

    With ``PYTHONDONTWRITEBYTECODE`` set (as on the machines the suite's times are measured on) Python never
    writes them, so every process compiled the modules it imports from their source: each worker, and each of
    the hundreds of ``python -m lsys3d`` and ``python -c`` children the tests start (0.2-0.3 CPU s each for
    the pipeline's modules).  Python reads a ``.pyc`` whatever that variable says; this writes them once
    (compileall, in well under a second; a file already compiled is skipped).
    """
    import compileall
    import importlib.util

    package = importlib.util.find_spec("lsys3d").submodule_search_locations[0]
    not_imported = re.compile(r"(^|[/\\])(test_[^/\\]*|conftest)\.py$")  # pytest rewrites those (assertions)
    for folder in (package, os.path.dirname(__file__)):
        compileall.compile_dir(folder, quiet=1, rx=not_imported)


def pytest_collection_modifyitems(session, config, items):
    """The tests marked ``slow`` first (in their order), the rest after them: under pytest-xdist the long ones
    start while the other workers work through the short ones, instead of one of them ending the run alone.
    Every process sorts the same collection the same way, as pytest-xdist needs."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
