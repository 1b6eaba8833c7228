"""Regenerate docs/looks/: example textures and a leaf model, and the pictures of materials, textures, custom
leaves, organs and a posed rig that docs/looks.md shows.

Run it with Blender's Python available to :func:`lsys3d.preview`::

    LSYS3D_BLENDER=.venv-bpy/bin/python .venv/bin/python docs/make_looks.py [NAME ...]

``assets`` writes the example files the grammars in docs/looks/ name (``bark.png``, ``bark_normal.png``,
``leaf.png``, ``maple_leaf.glb``): procedural, seeded, the same bytes on every run.  The other names render a
picture each (default: the assets, then every picture).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.images import png_bytes
from lsys3d.look.organs import organs
from lsys3d.noise import fbm3
from lsys3d.render.preview import PreviewOptions, preview

LOOKS = Path(__file__).resolve().parent / "looks"
PIXELS = 360  # small pictures keep the repository small


# ---------------------------------------------------------------- assets


def _bark_height(size: int = 128) -> np.ndarray:
    """Bark relief in [0, 1], tiling in both directions: fBm on a torus, its ridges running along v."""
    v, u = np.mgrid[0:size, 0:size] / size
    big, small = 4.0, 0.7  # around the torus' two circles: features stretched along v
    ring = big + small * np.cos(2 * np.pi * v)
    points = np.stack(
        [ring * np.cos(2 * np.pi * u), ring * np.sin(2 * np.pi * u), small * np.sin(2 * np.pi * v)], axis=-1
    )
    h = fbm3(points.reshape(-1, 3) * 1.6, seed=5, octaves=5).reshape(size, size)
    h = (h - h.min()) / (h.max() - h.min())
    return h**1.4  # deep, narrow furrows between broad plates


def bark_png() -> bytes:
    h = _bark_height()
    dark, light = np.array([52, 36, 24]), np.array([150, 120, 92])
    rgb = dark + (light - dark) * h[..., None]
    return png_bytes(np.round(rgb[::-1]).astype(np.uint8))  # rows top first: v grows upward


def bark_normal_png() -> bytes:
    h = _bark_height()
    strength = 6.0
    du = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) / 2
    dv = (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) / 2
    n = np.stack([-du * strength, -dv * strength, np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return png_bytes(np.round((n[::-1] * 0.5 + 0.5) * 255).astype(np.uint8))


def leaf_png(width: int = 128, height: int = 256) -> bytes:
    """A leaf with a serrated edge, a midrib and side veins; transparent around it; stem at the bottom."""
    rows, cols = np.mgrid[0:height, 0:width]
    z = 1.0 - (rows + 0.5) / height  # 0 at the bottom (the stem), 1 at the tip
    x = (cols + 0.5) / width * 2 - 1  # -1 .. 1 across
    blade = (z - 0.08) / 0.92
    half = np.where(blade > 0, np.sin(np.pi * np.clip(blade, 0, 1) ** 0.75) ** 0.9, 0.0)
    half *= 0.92 + 0.06 * np.sin(blade * 60)  # the serrated edge
    inside = np.abs(x) < half
    stem = (blade <= 0.02) & (np.abs(x) < 0.035)
    vein = np.abs(x) < 0.02 + 0.02 * (1 - blade)
    side = np.abs(np.mod(blade - 0.55 * np.abs(x), 0.11) - 0.055) < 0.006 + 0.004 * (1 - np.abs(x))
    shade = 0.75 + 0.25 * np.clip(1 - np.abs(x) / np.maximum(half, 1e-6), 0, 1)
    rgb = np.stack([60 * shade, 140 * shade, 45 * shade], axis=-1)
    rgb = np.where(((vein | side) & inside)[..., None], [150, 190, 90], rgb)
    rgb = np.where(stem[..., None], [110, 90, 50], rgb)
    alpha = np.where(inside | stem, 255, 0)
    return png_bytes(np.dstack([np.round(rgb), alpha]).astype(np.uint8))


def maple_leaf_glb() -> bytes:
    """A five-lobed leaf, cupped a little, in the leaf-model frame (stem at the origin, tip along +z, front +y)."""
    import manifold3d
    import trimesh

    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    lobes = 0.62 + 0.38 * np.abs(np.cos(2.5 * (t - np.pi))) ** 1.5  # five lobes, the middle one at the tip
    r = 0.5 * lobes * (1 - 0.55 * np.exp(-(((t - np.pi) / 0.35) ** 2)))  # a notch where the stem joins
    x, z = r * np.sin(t), 0.5 - r * np.cos(t)
    outline = np.stack([x, z], axis=1)
    faces = np.asarray(manifold3d.triangulate([outline]), np.int64).reshape(-1, 3)
    y = 0.12 * x**2 / 0.25  # cupped: the edges rise
    vertices = np.stack([x, y, z], axis=1)
    tri = vertices[faces]
    back = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 1] < 0
    faces[back] = faces[back][:, ::-1]  # the front faces +y
    stem = np.array([[-0.012, 0, -0.15], [0.012, 0, -0.15], [0.012, 0, 0.08], [-0.012, 0, 0.08]])
    vertices = np.concatenate([vertices, stem])
    n = len(x)
    faces = np.concatenate([faces, [[n, n + 2, n + 1], [n, n + 3, n + 2]]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return mesh.export(file_type="glb")


ASSETS = {
    "bark.png": bark_png,
    "bark_normal.png": bark_normal_png,
    "leaf.png": leaf_png,
    "maple_leaf.glb": maple_leaf_glb,
}


def write_assets() -> None:
    LOOKS.mkdir(exist_ok=True)
    for name, make in ASSETS.items():
        data = make()
        (LOOKS / name).write_bytes(data)
        print(f"{name}: {len(data):,} bytes", file=sys.stderr)


# ---------------------------------------------------------------- pictures


def _rigged():
    return lsys3d.generate("tree3d", iterations=5, seed=7, rig=True)


def _organs():
    """tree3d with a berry (a sphere organ) where every leaf would grow, and the leaves themselves."""
    tree = lsys3d.generate("tree3d", iterations=5, seed=7)
    sk = tree.skeleton
    frame = np.stack([sk.leaf_left, sk.leaf_up, sk.leaf_heading], axis=2)
    sizes = np.full(len(sk.leaf_position), 0.16)
    berries = organs(["sphere"] * len(sizes), sk.leaf_position, frame, sizes, np.full(len(sizes), 4))
    table = replace(tree.materials, by_index={4: lsys3d.Material("berry", (0.55, 0.02, 0.05, 1.0), roughness=0.25)})
    return replace(tree, organs=berries, materials=table)


def _bark_closeup():
    """A fork (as in docs/variation) with the example bark texture and normal map on 64-sided tubes."""
    bark = {"texture": str(LOOKS / "bark.png"), "normal_texture": str(LOOKS / "bark_normal.png")}
    fork = lsys3d.Grammar(
        name="fork",
        axiom="!(0.5)F(1.2)[&(35)!(0.3)F(1.4)][/(180)&(30)!(0.25)F(1.2)]!(0.35)F(1.4)",
        materials={"bark": {**bark, "base_color": [1, 1, 1], "roughness": 0.9}},
    )
    return lsys3d.generate(fork, 0, sides=64)


# name: (how to grow it, preview options, caption)
PICTURES = {
    "four_materials": (lambda: lsys3d.generate(LOOKS / "four_materials.toml"), {}, "four materials"),
    "textures": (lambda: lsys3d.generate(LOOKS / "textured.toml"), {}, "bark texture and normal map, leaf cards"),
    "bark_closeup": (_bark_closeup, {}, "the bark texture and its normal map, close up"),
    "maple": (lambda: lsys3d.generate(LOOKS / "maple.toml"), {}, "a leaf model from a .glb"),
    "organs": (_organs, {}, "sphere organs"),
    "rig_rest": (_rigged, {}, "the rig at rest"),
    "rig_posed": (_rigged, {"pose": ("b0_j2=12", "b81_j0=-20", "b162_j0=25")}, "three joints bent in Blender"),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = ["assets", *PICTURES]
    parser.add_argument("names", nargs="*", help=f"what to make (default all: {', '.join(names)})")
    args = parser.parse_args(argv)
    for name in args.names or names:
        if name == "assets":
            write_assets()
            continue
        grow, extra, caption = PICTURES[name]
        t0 = time.perf_counter()
        tree = grow()
        options = PreviewOptions(size=(PIXELS, PIXELS), view="iso", quality="final", **extra)
        preview(tree, LOOKS / f"{name}.png", options)
        print(f"{name}.png: {caption} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
