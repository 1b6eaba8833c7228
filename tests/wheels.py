"""lsys3d's wheel, built from this checkout once per test run (``pip wheel``, a few CPU seconds), for the tests
that need it: the wheel's contents and a plain install (tests/test_packaging.py) and the Blender extension that
bundles it (tests/test_blender_addon.py)."""

from __future__ import annotations

import atexit
import functools
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from shared import SHARED, shared

ROOT = Path(__file__).resolve().parent.parent


@functools.cache
def lsys3d_wheel() -> Path:
    """The path of the wheel (in the run's shared folder under pytest-xdist, tests/shared.py, which the controller
    removes at the end; else in a temporary folder removed when this process ends)."""
    run = os.environ.get(SHARED)

    def build() -> Path:
        folder = Path(tempfile.mkdtemp(prefix="lsys3d-wheel-", dir=run))
        if run is None:
            atexit.register(shutil.rmtree, folder, ignore_errors=True)
        subprocess.run(
            [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(folder), str(ROOT)],
            check=True,
            capture_output=True,
        )
        (wheel,) = folder.glob("lsys3d-*.whl")
        return wheel

    return shared("lsys3d-wheel", build)
