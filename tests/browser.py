"""Headless Chromium for the tests that need a real browser (three.js pages, the editor).

Debian's ``chromium`` (``make browser``, part of ``make validators``) driven by ``playwright-core`` from
``package.json`` in a ``node`` child process.  As for the validators, a missing piece skips the test
locally and fails it under ``CI``.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from validators import REPO, require

#: The Chromium binary (override with ``LSYS3D_CHROMIUM``).
CHROMIUM = Path(os.environ.get("LSYS3D_CHROMIUM", "/usr/bin/chromium"))

#: Flags for a closed network and a root user: no sandbox, no GPU, no background connections.
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


def browser_available() -> tuple[bool, str]:
    if shutil.which("node") is None:
        return False, "node is not on PATH (install Node.js >= 18)"
    if not (REPO / "node_modules" / "playwright-core").is_dir():
        return False, "playwright-core is not installed (run `npm ci` at the repository root)"
    if not CHROMIUM.exists():
        return False, f"{CHROMIUM} is missing (run `make browser`, or `apt-get install chromium`)"
    return True, ""


def require_browser() -> None:
    """Skip (locally) or fail (under CI) when headless Chromium cannot be driven."""
    ok, reason = browser_available()
    require(ok, reason)
