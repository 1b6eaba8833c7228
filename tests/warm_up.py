"""The session's warm-up (``pytest_sessionstart`` in tests/conftest.py): the kernels the tests need compiled, or
loaded, before the first test, and the trees many tests read grown and shared (tests/grown.py).

With a warm cache it is a few seconds in the controlling process: the default tree and tree3d grown, a polygon
drawn (the turtle kernel's variant for its rare ops), tree3d written as .glb and .usdc (the writers' kernels).

From an empty cache (a fresh clone, CI) it follows the session's first run (tests/first_run.py), which compiled
the default tree's kernels, and what is left is split between two processes, as a first run splits its
compiling (:mod:`lsys3d.compiling`), instead of one process compiling while the other core idles: a helper
process, ``python -m warm_up``, draws the polygon and a grammar whose rules ask the turtle (a query module:
the incremental turtle's ``answer_pass``, which calls the same turtle helpers as the rare-ops variant, so the
two are compiled one after the other in one process; a worker compiled it for 11 CPU s during the tests while
the other worker had the other core); meanwhile this process grows tree3d (the cleanup's rescue), writes it,
and grows the species of :data:`MAIN_PRESETS` (trees the headroom test of tests/test_hostile.py and the
species tests would grow anyway, now grown on a core that would idle).  The helper compiles only the kernels
of :data:`HELPER_OWN` (``compiling.only`` stops it at any other: it then fails, and what it did not compile is
compiled where it is needed); this process waits for the helper before compiling one of those (a gate on
numba's compile event), so no kernel is compiled by both at once: the first run's machinery,
:func:`lsys3d.compiling.ahead` with this file as the helper's module.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

#: What the helper compiles (prefixes of a kernel's module and name): the turtle kernel and the helpers it calls
#: (the scene's steering and probe, the bending), the incremental turtle and the derivation's walks.
HELPER_OWN = (
    "lsys3d.turtle.kernel",
    "lsys3d.turtle.scene",
    "lsys3d.turtle.bending",
    "lsys3d.turtle.steering",
    "lsys3d.turtle.incremental",
    "lsys3d.lsystem.walks",
)
#: The presets this process grows (and shares) while the helper works, after the default tree and tree3d: the
#: species whose kernels the default tree's and tree3d's are, but for the union's repeated parts (birch), so
#: none waits for the helper (grass draws with the turtle's rare ops: the helper's; left to the tests).
MAIN_PRESETS = (
    "aspen",
    "beech",
    "birch",
    "fern",
    "foxglove",
    "hazel",
    "ivy",
    "maple",
    "palm",
    "pine",
    "spruce",
    "weeping-willow",
)


def _polygon() -> None:
    """The turtle kernel's other compilation, for strings with its rare ops (lsys3d.turtle.kernel.RARE_OPS)."""
    import lsys3d
    from lsys3d.turtle import interpret

    polygon = lsys3d.Grammar(axiom="F{.f+f+f+f}F")
    interpret(polygon.axiom_modules, polygon)


def _query() -> None:
    """A grammar whose rule asks the turtle where the apex is: derivation runs the incremental turtle."""
    import lsys3d
    from lsys3d.pipeline import draw

    apex = lsys3d.Grammar(axiom="A?P(0,0,0)", rules=["A > ?P(x, y, z) : y < 3 -> FA"], turtle={"heading": 90})
    draw(apex, 5, 0)


def _write_tree3d() -> None:
    """tree3d written as .glb and .usdc: the writers' kernels, which most CLI tests' subprocesses call."""
    from grown import grown

    import lsys3d

    with tempfile.TemporaryDirectory(prefix="lsys3d-precompile-") as scratch:
        for suffix in (".glb", ".usdc"):
            lsys3d.export(grown("tree3d"), os.path.join(scratch, f"tree3d{suffix}"))


def warm_up(cold: bool) -> None:
    """Compile (or load) the kernels and grow the shared trees; ``cold``: the cache was empty at the session's
    start and the run's workers share trees (``shared.SHARED``), so a helper process takes half of it."""
    import shared
    from grown import grown

    import lsys3d
    from lsys3d import compiling

    if not (cold and os.environ.get(shared.SHARED)):
        for preset in (lsys3d.DEFAULT_PRESET, "tree3d"):
            grown(preset)  # and left for the workers' tests of these presets
        _polygon()
        _write_tree3d()
        return
    from lsys3d.turtle.incremental import answer_pass

    here = str(Path(__file__).resolve().parent)  # (the helper's module, warm_up, is this file)
    with compiling.ahead("warm_up", HELPER_OWN, (answer_pass,), path=(here,)) as helper:
        for preset in (lsys3d.DEFAULT_PRESET, "tree3d"):
            grown(preset)
        _write_tree3d()
        for preset in MAIN_PRESETS:
            grown(preset)
    if helper is not None and helper.returncode:  # what it did not compile is compiled where the tests need it
        sys.stderr.write(f"tests/warm_up.py: the helper failed ({helper.returncode})\n")


def _helper() -> None:
    """The helper process: the polygon and the query, compiling no kernel outside :data:`HELPER_OWN`."""
    from lsys3d import compiling

    compiling.help_ahead(HELPER_OWN, lambda: (_polygon(), _query()))


if __name__ == "__main__":
    _helper()
