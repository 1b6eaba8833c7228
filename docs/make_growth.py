"""Regenerate the strip of frames of the growing herb in docs/growth/ (docs/growth.md shows it).

Run it with Blender's Python available to :func:`lsys3d.preview`::

    LSYS3D_BLENDER=.venv-bpy/bin/python .venv/bin/python docs/make_growth.py

The ``herb-growing`` preset with a 5-second growth animation, rendered by
Blender at six moments of the clip (the camera fitted to the grown plant, so
the frames line up), then laid side by side into one PNG.
"""

from __future__ import annotations

import struct
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.images import png_bytes
from lsys3d.render.preview import PreviewOptions, preview

PICTURES = Path(__file__).resolve().parent / "growth"
SECONDS = 5.0
TIMES = (0.5, 1.25, 2.0, 2.75, 3.5, 5.0)  # seconds into the clip
SIZE = (220, 360)


def read_png(data: bytes) -> np.ndarray:
    """The pixels of an 8-bit RGB or RGBA PNG (Blender's: any row filter), ``(h, w, c) uint8``."""
    pos, chunks, head = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            head = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            chunks.append(body)
        pos += 12 + length
    width, height, depth, color = head[:4]
    assert depth == 8 and color in (2, 6), "an 8-bit RGB or RGBA PNG"
    c = 3 if color == 2 else 4
    raw = np.frombuffer(zlib.decompress(b"".join(chunks)), np.uint8).reshape(height, 1 + width * c)
    out = np.zeros((height, width * c), np.int32)
    for y in range(height):
        kind, row = raw[y, 0], raw[y, 1:].astype(np.int32)
        up = out[y - 1] if y else np.zeros(width * c, np.int32)
        if kind in (0, 2):
            out[y] = (row + (up if kind == 2 else 0)) % 256
            continue
        for x in range(width * c):  # sub, average, Paeth: each byte needs its left neighbour
            left = out[y, x - c] if x >= c else 0
            corner = up[x - c] if x >= c else 0
            if kind == 1:
                pred = left
            elif kind == 3:
                pred = (left + up[x]) // 2
            else:
                p = left + up[x] - corner
                pa, pb, pc = abs(p - left), abs(p - up[x]), abs(p - corner)
                pred = left if pa <= pb and pa <= pc else (up[x] if pb <= pc else corner)
            out[y, x] = (row[x] + pred) % 256
    return out.astype(np.uint8).reshape(height, width, c)


def main() -> int:
    tree = lsys3d.generate("herb-growing", growth_animation=SECONDS)
    options = PreviewOptions(size=SIZE, view="front", samples=16)
    frames = []
    with tempfile.TemporaryDirectory() as folder:
        for k, t in enumerate(TIMES):
            path = preview(tree, Path(folder) / f"frame{k}.png", options, at=t)
            frames.append(read_png(path.read_bytes())[..., :3])
            print(f"frame at {t:g} s", file=sys.stderr)
    gap = np.full((SIZE[1], 4, 3), 255, np.uint8)
    strip = np.concatenate([x for f in frames for x in (f, gap)][:-1], axis=1)
    PICTURES.mkdir(exist_ok=True)
    (PICTURES / "strip.png").write_bytes(png_bytes(strip))
    print(PICTURES / "strip.png", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
