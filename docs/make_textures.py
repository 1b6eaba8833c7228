"""Write the swatches of docs/textures.md: every procedural kind at 512 pixels, lit, shrunk to 256, in docs/textures/.

Each swatch is the base colour lit by the normal map (a light from the upper left, as a viewer shows it),
so the relief shows; the leaves keep their alpha.  Run from the repository's root:

    .venv/bin/python docs/make_textures.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lsys3d.images import png_bytes, png_pixels
from lsys3d.look.textures import KINDS, procedural

OUT = Path(__file__).resolve().parent / "textures"
STEP = 6
LIGHT = np.array([-0.45, 0.45, 0.77])  # from the upper left: -u, +v, out of the surface


def swatch(kind: str) -> np.ndarray:
    t = procedural(kind, seed=1, resolution=512)
    albedo = png_pixels(t.albedo.data).astype(np.float64) / 255
    normal = png_pixels(t.normal.data).astype(np.float64) / 255 * 2 - 1
    light = LIGHT / np.linalg.norm(LIGHT)
    shade = 0.3 + 0.85 * np.clip(normal @ light, 0, 1)  # sRGB values shaded directly: a preview, not a render
    rgb = np.clip(albedo[..., :3] * shade[..., None], 0, 1)
    out = np.concatenate([rgb, albedo[..., 3:]], axis=-1)
    small = out.reshape(256, 2, 256, 2, -1).mean(axis=(1, 3))  # 2 x 2 boxes: 256 pixels a side
    # 6 levels apart (43 a channel): the noisy bark compresses to under 100 kB, and looks the same
    return (np.round(small * 255 / STEP) * STEP).clip(0, 255).astype(np.uint8)


def main() -> None:
    OUT.mkdir(exist_ok=True)
    for kind in KINDS:
        data = png_bytes(swatch(kind))
        (OUT / f"{kind}.png").write_bytes(data)
        print(f"{kind}: {len(data) / 1000:.0f} kB")


if __name__ == "__main__":
    main()
