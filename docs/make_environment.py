"""Draw the pictures of docs/environment.md: the scene presets seen from the front, over their scene.

    python docs/make_environment.py

Each picture is an orthographic view rasterised with numpy (no renderer needed): the scene's triangles
in grey, shaded by their facing, then the plant's segments in brown and its leaves in green, nearest
last (a depth buffer), written as PNG by :func:`lsys3d.images.png_bytes`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.images import png_bytes
from lsys3d.pipeline import draw
from lsys3d.turtle.environment import load_environment

OUT = Path(__file__).resolve().parent / "environment"
VIEWS = {  # preset: (view rotation about y in degrees, picture height in pixels)
    "ivy-wall": (0.0, 360),
    "topiary": (30.0, 360),
    "tree-wall": (0.0, 360),
    "vine-post": (0.0, 360),
}


def _rotation(yaw: float) -> np.ndarray:
    a = np.radians(yaw)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def picture(name: str) -> np.ndarray:
    yaw, height = VIEWS[name]
    g = lsys3d.load_preset(name)
    _, sk = draw(g, g.iterations, g.seed)
    env = load_environment(g)
    r = _rotation(yaw)
    tris = [m.vertices[m.faces] @ r.T for m in env.meshes if m.role != "volume"]
    boxes = [m.vertices[m.faces] @ r.T for m in env.meshes if m.role == "volume"]
    pts = np.concatenate([np.concatenate([sk.start, sk.end]) @ r.T, *[t.reshape(-1, 3) for t in tris + boxes]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    scale = (height - 20) / max(hi[1] - lo[1], 1e-9)
    width = int((hi[0] - lo[0]) * scale) + 20
    rgb = np.full((height, width, 3), 255.0)
    depth = np.full((height, width), -np.inf)

    def to_px(p):
        return (p[..., 0] - lo[0]) * scale + 10, height - 10 - (p[..., 1] - lo[1]) * scale

    light = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    for t in tris:  # the scene: each triangle filled by testing the pixels of its box
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        for tri, normal in zip(t, n, strict=True):
            x, y = to_px(tri)
            x0, x1 = int(max(np.floor(x.min()), 0)), int(min(np.ceil(x.max()), width - 1))
            y0, y1 = int(max(np.floor(y.min()), 0)), int(min(np.ceil(y.max()), height - 1))
            if x1 < x0 or y1 < y0:
                continue
            gx, gy = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
            d = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
            if abs(d) < 1e-12:
                continue
            a = ((x[1] - gx) * (y[2] - gy) - (x[2] - gx) * (y[1] - gy)) / d
            b = ((x[2] - gx) * (y[0] - gy) - (x[0] - gx) * (y[2] - gy)) / d
            c = 1 - a - b
            inside = (a >= 0) & (b >= 0) & (c >= 0)
            z = a * tri[0, 2] + b * tri[1, 2] + c * tri[2, 2]
            yy, xx = np.nonzero(inside)
            yy, xx, z = yy + y0, xx + x0, z[inside]
            near = z > depth[yy, xx]
            shade = 150 + 80 * abs(float(normal @ light))
            depth[yy[near], xx[near]] = z[near]
            rgb[yy[near], xx[near]] = shade
    for t in boxes:  # a pruning volume: its edges, over everything
        for k in range(3):
            a, b = t[:, k], t[:, (k + 1) % 3]
            for u in np.linspace(0, 1, 200):
                x, y = to_px(a * (1 - u) + b * u)
                rgb[np.clip(y.astype(int), 0, height - 1), np.clip(x.astype(int), 0, width - 1)] = 170
    start, end = sk.start @ r.T, sk.end @ r.T
    for t in np.linspace(0, 1, 12):  # the segments, sampled densely enough for a line
        p = start * (1 - t) + end * t
        x, y = to_px(p)
        xi, yi = np.clip(x.astype(int), 0, width - 1), np.clip(y.astype(int), 0, height - 1)
        near = p[:, 2] >= depth[yi, xi] - 0.02
        rgb[yi[near], xi[near]] = (95, 65, 40)
        depth[yi[near], xi[near]] = np.maximum(depth[yi[near], xi[near]], p[near, 2])
    leaves = sk.leaf_position @ r.T
    x, y = to_px(leaves)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            xi, yi = np.clip(x.astype(int) + dx, 0, width - 1), np.clip(y.astype(int) + dy, 0, height - 1)
            near = leaves[:, 2] >= depth[yi, xi] - 0.05
            rgb[yi[near], xi[near]] = (60, 130, 50)
    return rgb.astype(np.uint8)


def main() -> None:
    OUT.mkdir(exist_ok=True)
    pictures = [picture(name) for name in VIEWS]
    height = max(p.shape[0] for p in pictures)
    gap = np.full((height, 12, 3), 255, np.uint8)
    row = []
    for p in pictures:
        pad = np.full((height - p.shape[0], p.shape[1], 3), 255, np.uint8)
        row += [np.concatenate([pad, p]), gap]
    (OUT / "scenes.png").write_bytes(png_bytes(np.concatenate(row[:-1], axis=1)))


if __name__ == "__main__":
    main()
