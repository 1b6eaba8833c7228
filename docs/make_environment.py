"""Draw the picture of docs/environment.md: the scene presets over their scenes, rendered by Blender.

    LSYS3D_BLENDER=.venv-bpy/bin/python python docs/make_environment.py

Each preset is grown as ``lsys3d generate`` grows it (the tube soup: the union changes nothing a picture
shows) and rendered by :func:`lsys3d.render.preview.preview` with its scene (``scene=True``: the wall, the
post; the topiary's pruning box is left out, so the hedge shows), path traced by Cycles, then the four
pictures are set side by side and their colours rounded to steps of 8, so the PNG stays small.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.images import png_bytes
from lsys3d.render.preview import PreviewOptions, preview

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from pngs import read_png  # Blender's PNGs use every row filter: the tests' reader unfilters them

OUT = Path(__file__).resolve().parent / "environment"
HEIGHT = 270
VIEWS = {  # preset: (view, picture width in pixels)
    "ivy-wall": ("front", 350),
    "topiary": ("iso", 290),
    "tree-wall": ("front", 240),
    "vine-post": ("front", 120),
}
STEP = 8


def picture(name: str, folder: Path) -> np.ndarray:
    view, width = VIEWS[name]
    tree = lsys3d.generate(name, union=False)
    options = PreviewOptions(size=(width, HEIGHT), view=view, quality="final", samples=24, scene=True, margin=0.03)
    path = preview(tree, folder / f"{name}.png", options)
    return read_png(path)[..., :3]


def main() -> None:
    OUT.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        pictures = [picture(name, Path(folder)) for name in VIEWS]
    gap = np.full((HEIGHT, 8, 3), 255, np.uint8)
    row = []
    for p in pictures:
        row += [p, gap]
    image = np.concatenate(row[:-1], axis=1).astype(np.float64)
    image = (np.round(image / STEP) * STEP).clip(0, 255).astype(np.uint8)
    (OUT / "scenes.png").write_bytes(png_bytes(image))


if __name__ == "__main__":
    main()
