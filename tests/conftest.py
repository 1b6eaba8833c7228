"""Hypothesis profiles: the default one is derandomized, so the suite gives the same verdict on every run.

Profile "default" (plain ``pytest``): fixed examples, CI-sized.  Profile "fuzz"
(``HYPOTHESIS_PROFILE=fuzz pytest -k any``): random examples on demand, 2000 where a
test does not set its own count.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import first_run
import pytest
import shared
from hypothesis import settings

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
    workers (tests/shared.py), which would otherwise each grow them again.

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
    folder = None
    if first_run.cache_is_empty():
        # a fresh clone: the first compiling is a user's first run, done once for real (tests/first_run.py)
        folder = Path(tempfile.mkdtemp(prefix="lsys3d-first-run-"))
        session.config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
        os.environ[first_run.RECORD] = str(folder / "first-run.json")
    result = yield  # pytest-xdist starts the workers
    if folder is not None:
        first_run.run(folder)
    _warm_up()
    return result


def _warm_up() -> None:
    """The default tree and tree3d grown (and shared), a polygon drawn, tree3d written as .glb and .usdc."""
    from grown import grown

    import lsys3d
    from lsys3d.turtle import interpret

    for preset in (lsys3d.DEFAULT_PRESET, "tree3d"):
        grown(preset)  # and left for the workers' tests of these presets
    # the turtle kernel's other compilation, for strings with its rare ops (lsys3d.turtle.kernel.RARE_OPS: a polygon)
    polygon = lsys3d.Grammar(axiom="F{.f+f+f+f}F")
    interpret(polygon.axiom_modules, polygon)
    with tempfile.TemporaryDirectory(prefix="lsys3d-precompile-") as scratch:
        for suffix in (".glb", ".usdc"):  # the writers' kernels, which most CLI tests' subprocesses call
            lsys3d.export(grown("tree3d"), os.path.join(scratch, f"tree3d{suffix}"))


def pytest_collection_modifyitems(session, config, items):
    """The tests marked ``slow`` first (in their order), the rest after them: under pytest-xdist the long ones
    start while the other workers work through the short ones, instead of one of them ending the run alone.
    Every process sorts the same collection the same way, as pytest-xdist needs."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
