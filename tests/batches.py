"""A small library grown once per test run by a real batch, shared by the batch and forest tests (and the xdist
workers)."""

from __future__ import annotations

import atexit
import functools
import os
import shutil
import tempfile
from pathlib import Path

from shared import SHARED, shared

from lsys3d.library.batch import batch

#: Two species, five jobs, each a fraction of a second: a tree with natural variation (every seed differs) and a
#: grammar file beside the jobs file.
JOBS = """\
[defaults]
formats = ["glb", "usdc"]
options = { sides = 4 }

[[jobs]]
grammar = "tree3d"
seeds = "0-2"
options = { iterations = 3, turtle = { angle_jitter = 10, branch_drop = 0.1 } }

[[jobs]]
grammar = "grammars/fern.toml"
seeds = [1, 2]
"""

FERN = """\
name = "fern"
axiom = "X"
iterations = 3
angle = 25
rules = ["X -> !(0.05)F[+X][-X]FX", "F -> FF"]

[turtle]
heading = 90
tropism = [0, -1, 0]
elasticity = 0.1
"""

IDS = ["tree3d_s0", "tree3d_s1", "tree3d_s2", "fern_s1", "fern_s2"]


def write_project(folder: Path, jobs: str = JOBS) -> Path:
    """A jobs file and its grammars in ``folder``; returns the jobs file."""
    (folder / "grammars").mkdir(parents=True, exist_ok=True)
    (folder / "grammars" / "fern.toml").write_text(FERN, encoding="utf-8")
    path = folder / "jobs.toml"
    path.write_text(jobs, encoding="utf-8")
    return path


@functools.cache
def _grown() -> tuple[Path, object]:
    """The batch run once in the whole test run (its folder in the run's shared folder, tests/shared.py, which
    the controller removes at the end), or once per process in a plain ``pytest``."""
    run = os.environ.get(SHARED)

    def grow() -> tuple[Path, object]:
        folder = Path(tempfile.mkdtemp(prefix="lsys3d-batch-", dir=run))
        if run is None:
            atexit.register(shutil.rmtree, folder, ignore_errors=True)
        return folder, batch(write_project(folder), folder / "out", workers=2)

    return shared("small-library", grow)


def small_library() -> tuple[Path, object]:
    """The project folder (``jobs.toml``, ``grammars/``, ``out/``) of the session's batch, and its BatchResult."""
    return _grown()


def copy_of_library(target: Path) -> Path:
    """A copy of the session's project folder (to change without disturbing the others); returns it."""
    folder, _ = _grown()
    shutil.copytree(folder, target / "project")
    return target / "project"
