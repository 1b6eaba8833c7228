"""Build lsys3d's Blender extension (Blender 4.2+): a zip Blender installs with "Install from Disk".

    python tools/blender_extension.py [--platforms linux-x64 windows-x64 macos-arm64 macos-x64] [--out build]
                                      [--wheel dist/lsys3d-0.1.0-py3-none-any.whl]

The zip holds ``blender_manifest.toml``, an ``__init__.py`` that registers :mod:`lsys3d.blender`, and under
``wheels/`` the wheel of lsys3d (built from this checkout) and the binary wheels of its dependencies for
Blender's Python (3.11) on each platform, downloaded with ``pip download --only-binary=:all:``.  numpy is
not bundled: Blender ships its own, and lsys3d uses it.  ``--wheel`` bundles a wheel of lsys3d built already
(the test suite builds one for two tests) instead of building it.  ``make blender-extension`` runs this.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PYTHON_VERSION = "3.11"  # Blender 4.2 to 5.0's Python

# Blender's platform names -> pip's platform tags (newest first: pip matches a tag and the older ones it implies)
PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"],
    "windows-x64": ["win_amd64"],
    "macos-arm64": ["macosx_14_0_arm64", "macosx_11_0_arm64"],
    "macos-x64": ["macosx_14_0_x86_64", "macosx_10_15_x86_64", "macosx_10_9_x86_64"],
}

# lsys3d's dependencies and theirs, numpy left out (Blender's own)
BUNDLED = ("numba", "llvmlite", "trimesh", "manifold3d", "usd-core")

INIT = '''"""lsys3d: grow plants from L-systems (Add > Mesh > L-system plant; the sidebar's lsys3d tab)."""

from lsys3d.blender import register, unregister

__all__ = ["register", "unregister"]
'''


def requirements() -> list[str]:
    """pyproject's dependencies of :data:`BUNDLED` (their version ranges), llvmlite as numba pins it."""
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    chosen = [d for d in deps if d.split(">")[0].split("=")[0].strip() in BUNDLED]
    return [*chosen, "llvmlite"]


def download(platform: str, folder: Path) -> list[Path]:
    before = set(folder.glob("*.whl"))
    tags = [arg for tag in PLATFORMS[platform] for arg in ("--platform", tag)]
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:", *tags]
    cmd += ["--python-version", PYTHON_VERSION, "--implementation", "cp", "-d", str(folder), *requirements()]
    subprocess.run(cmd, check=True)
    return sorted(set(folder.glob("*.whl")) - before)


def manifest(version: str, platforms: list[str], wheels: list[str]) -> str:
    listed = ",\n".join(f'  "./wheels/{w}"' for w in wheels)
    plats = ", ".join(f'"{p}"' for p in platforms)
    return f'''schema_version = "1.0.0"

id = "lsys3d"
version = "{version}"
name = "lsys3d L-system plants"
tagline = "Grow 3D plants from L-systems, regrown live from the redo panel"
maintainer = "lsys3d"
type = "add-on"
tags = ["Add Mesh", "Modeling"]

blender_version_min = "4.2.0"
license = ["SPDX:MIT"]
platforms = [{plats}]

wheels = [
{listed}
]

[permissions]
files = "Read grammar files and textures, write exported plants"
'''


def build(platforms: list[str], out: Path, wheel: Path | None = None) -> Path:
    """The extension's zip in ``out`` for ``platforms``, bundling ``wheel`` as lsys3d's (default: built here)."""
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        wheels = Path(scratch) / "wheels"
        wheels.mkdir()
        if wheel is None:
            subprocess.run(
                [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(wheels), str(REPO)],
                check=True,
            )
        else:
            shutil.copyfile(wheel, wheels / wheel.name)
        for platform in platforms:
            download(platform, wheels)
        names = sorted(w.name for w in wheels.glob("*.whl"))
        suffix = "" if len(platforms) == len(PLATFORMS) else "-" + "-".join(platforms)
        target = out / f"lsys3d-blender-{version}{suffix}.zip"
        with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("blender_manifest.toml", manifest(version, platforms, names))
            archive.writestr("__init__.py", INIT)
            for name in names:  # stored: a wheel is a zip already (deflating its 95 MB again saved 1%, for 2 CPU s)
                archive.write(wheels / name, f"wheels/{name}", compress_type=zipfile.ZIP_STORED)
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platforms", nargs="+", default=list(PLATFORMS), choices=list(PLATFORMS))
    parser.add_argument("--out", type=Path, default=REPO / "build")
    parser.add_argument("--wheel", type=Path, help="lsys3d's wheel, built already (default: built from this checkout)")
    args = parser.parse_args()
    target = build(args.platforms, args.out, args.wheel)
    with zipfile.ZipFile(target) as archive:
        wheels = [n for n in archive.namelist() if n.startswith("wheels/")]
    print(f"wrote {target} ({target.stat().st_size / 2**20:.0f} MiB, {len(wheels)} wheels)")


if __name__ == "__main__":
    main()
