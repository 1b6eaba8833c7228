"""Make docs/edit/editor.png, the picture of docs/edit.md: ``lsys3d edit`` on a copy of tree3d in headless
Chromium (``docs/edit_screenshot.mjs``; Debian's Chromium and playwright-core, ``make browser``).

Run from the repository's root: ``python docs/make_edit_screenshot.py``.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from lsys3d.lsystem.presets import preset_text

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "edit" / "editor.png"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-gl=angle", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader"]  # fmt: skip


def main() -> int:
    folder = Path(tempfile.mkdtemp(prefix="lsys3d-edit-doc-"))
    grammar = folder / "my-tree.toml"
    grammar.write_text(preset_text("tree3d"), encoding="utf-8")
    server = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "edit", str(grammar), "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        url = re.search(r"http://\S+", server.stdout.readline()).group(0)
        subprocess.run(
            ["node", str(ROOT / "docs" / "edit_screenshot.mjs"), url, str(OUT), "/usr/bin/chromium", json.dumps(ARGS)],
            check=True,
            cwd=ROOT,
        )
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=60)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
