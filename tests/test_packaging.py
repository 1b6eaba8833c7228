"""A plain `pip install .` carries the presets inside the package."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

from wheels import lsys3d_wheel

ROOT = Path(__file__).resolve().parent.parent


def test_wheel_ships_the_presets(tmp_path):
    wheel = lsys3d_wheel()  # `pip wheel .`, once in the run (the Blender extension's test bundles it too)
    with zipfile.ZipFile(wheel) as archive:
        shipped = {name for name in archive.namelist() if name.startswith("lsys3d/")}
    # every module of the source tree is in the wheel (an import test alone can be fooled by the editable install)
    source = {f"lsys3d/{p.relative_to(ROOT / 'lsys3d').as_posix()}" for p in (ROOT / "lsys3d").rglob("*.py")}
    assert source <= shipped, sorted(source - shipped)
    # the editor's page and three.js with its licence (package data: lsys3d edit and the notebook viewer need them)
    static = {
        f"lsys3d/{p.relative_to(ROOT / 'lsys3d').as_posix()}" for p in (ROOT / "lsys3d" / "edit" / "static").rglob("*")
    }
    static = {name for name in static if not (ROOT / name).is_dir()}
    assert "lsys3d/edit/static/vendor/three/LICENSE" in static
    assert static <= shipped, sorted(static - shipped)
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
        check=True,
        capture_output=True,
    )
    code = (
        "import lsys3d, sys; assert lsys3d.__file__.startswith(sys.argv[1]), lsys3d.__file__;"
        "from lsys3d.render.preview import SCRIPT; assert SCRIPT.is_file(), SCRIPT;"  # Blender's side of previews
        "names = lsys3d.list_presets(); print(len(names), lsys3d.derive(lsys3d.load_preset('dog'), 1))"
    )
    env = dict(os.environ, PYTHONPATH=str(target))
    out = subprocess.run(
        [sys.executable, "-c", code, str(target)], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    count, text = out.stdout.split()
    assert int(count) == len(list((ROOT / "assets" / "presets").glob("*.toml")))
    assert text == "GOD"
