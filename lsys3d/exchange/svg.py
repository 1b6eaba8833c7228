"""SVG writer: the turtle's classic line drawing of a tree's skeleton, in plain text.

The skeleton's segments are projected on the plane of the drawing and
written as one ``<polyline>`` per run of a chain (an unbranched run of
segments) that has one stroke width; leaves are filled shapes on top of the
branches: ``{ . }`` polygons as ``<polygon>``, leaf instances as the outline
of the leaf model placed by each instance's transform.

The plane of the drawing is chosen from the extents of everything drawn:

* flat in Z (the 2D curves and plants of the presets): X to the right, Y up;
* flat in X: -Z to the right, Y up (seen from +X); flat in Y: X to the right,
  -Z up (seen from above);
* not flat: lsys3d's trees stand along +Y, so Y stays up and the wider of X
  and Z goes to the right (seen from +Z, or from +X).

SVG's y axis points down, so the vertical axis is flipped.  The ``viewBox`` is
the drawing's bounding box in the skeleton's units (scaled by
``ExportOptions.units``) with a margin; ``width`` and ``height`` make the
larger side :data:`DISPLAY_PIXELS` pixels.  Numbers are written with a fixed
number of decimals chosen from the drawing's size (a ten-thousandth of it or
finer), trailing zeros dropped: the same tree gives the same bytes.
``ExportOptions.up_axis`` does not apply (the plane is chosen as above).
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from ..errors import ExportError, printable
from ..look.materials import Material
from ..tree import Tree
from .atomic import write_bytes
from .common import UNITS, ExportOptions, metadata_json, to_float32

__all__ = ["DISPLAY_PIXELS", "drawing_plane", "svg_text", "write_svg"]

#: Width or height (the larger) of the drawing at its natural size, in pixels.
DISPLAY_PIXELS = 800
LINE_COLOR = "#1f1f1f"
MARGIN = 0.03  # of the larger extent, around the drawing
_FLAT = 1e-9  # an extent this small relative to the largest one is flat

_X, _Y, _Z = np.eye(3)


def drawing_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plane to draw ``points`` ``(m, 3)`` on: unit vectors ``(right, up)`` (see the module's rules)."""
    if len(points) == 0:
        return _X, _Y
    extent = points.max(axis=0) - points.min(axis=0)
    largest = extent.max()
    if largest > 0 and extent.min() <= _FLAT * largest:
        flat = int(np.argmin(extent[::-1]))  # on ties prefer Z, then Y: 2D drawings lie in XY
        flat = 2 - flat
        if flat == 0:
            return -_Z, _Y
        if flat == 1:
            return _X, -_Z
        return _X, _Y
    return (_X, _Y) if extent[0] >= extent[2] else (-_Z, _Y)


def _srgb(color) -> str:
    """A linear RGB(A) colour as an sRGB ``#rrggbb``."""
    out = []
    for c in color[:3]:
        c = min(max(float(c), 0.0), 1.0)
        c = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055
        out.append(round(c * 255))
    return "#" + "".join(f"{v:02x}" for v in out)


class _Numbers:
    """Fixed-decimal formatting: deterministic, no ``-0``, trailing zeros dropped."""

    def __init__(self, size: float):
        self.decimals = min(max(math.ceil(4 - math.log10(size)), 0), 12)

    def one(self, value: float) -> str:
        text = f"{value:.{self.decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
        return "0" if text == "-0" else text

    def points(self, uv: np.ndarray) -> str:
        """``u,v u,v ...`` for points ``(m, 2)``."""
        return " ".join(f"{self.one(u)},{self.one(v)}" for u, v in uv.tolist())


def _leaf_outline(model) -> list[np.ndarray]:
    """The boundary loops of the leaf model, as vertex index arrays (a flat blade has one)."""
    faces = np.asarray(model.faces)
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = edges[counts[inverse.reshape(-1)] == 1]
    following = {}
    for a, b in boundary.tolist():
        following.setdefault(a, b)
    loops, seen = [], set()
    for start in sorted(following):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen and v in following:
            seen.add(v)
            loop.append(v)
            v = following[v]
        if len(loop) >= 3:
            loops.append(np.array(loop))
    return loops


def _runs(widths: np.ndarray) -> list[tuple[int, int]]:
    """``(begin, end)`` of the runs of equal values in ``widths``."""
    cuts = np.flatnonzero(widths[1:] != widths[:-1]) + 1
    bounds = np.concatenate([[0], cuts, [len(widths)]]).tolist()
    return list(itertools.pairwise(bounds))


def svg_text(tree: Tree, options: ExportOptions | None = None, where: str = "svg") -> str:
    """The SVG document of ``tree`` (see the module's documentation), as text.

    Examples
    --------
    >>> import lsys3d
    >>> tree = lsys3d.generate("koch", iterations=1, union=False)
    >>> text = svg_text(tree)
    >>> text.count("<polyline"), 'viewBox="-0.14 -0.14 3.28 1.146"' in text
    (1, True)
    """
    options = ExportOptions() if options is None else options
    skeleton = tree.skeleton
    scale = 1.0 / UNITS[options.units]
    start = np.asarray(skeleton.start, np.float64) * scale
    end = np.asarray(skeleton.end, np.float64) * scale
    polygon_points = np.asarray(skeleton.polygon_points, np.float64) * scale
    leaf_shapes = []  # (k, L, 3) world outlines of the leaf instances, one array per loop
    if tree.leaves.instanced:
        model = tree.leaves.model.vertices
        t = np.asarray(tree.leaves.transforms, np.float64)
        for loop in _leaf_outline(tree.leaves.model):
            leaf_shapes.append((np.einsum("kij,lj->kli", t[:, :3, :3], model[loop]) + t[:, None, :3, 3]) * scale)
    everything = np.concatenate([start, end, polygon_points, *(s.reshape(-1, 3) for s in leaf_shapes)])
    if len(everything) == 0:
        raise ExportError(f"{where}: nothing to draw: the tree has no segment and no leaf")
    if not np.isfinite(everything).all():
        raise ExportError(f"{where}: the skeleton holds a NaN or infinite point")

    right, up = drawing_plane(everything)
    frame = np.stack([right, -up], axis=1)  # (3, 2): SVG's y points down

    def project(p):
        return p @ frame

    flat = project(everything)
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    size = float(max((hi - lo).max(), 1e-9))
    hairline = size / DISPLAY_PIXELS
    widths = np.maximum(0.5 * (skeleton.width_start + skeleton.width_end) * scale, 0.5 * hairline)
    if options.hairline:
        widths = np.full(len(skeleton), hairline)
    num = _Numbers(size)
    stroke = np.array([num.one(w) for w in widths.tolist()]) if len(skeleton) else np.zeros(0, str)
    margin = MARGIN * size + 0.5 * (float(widths.max()) if len(skeleton) else 0.0)
    x0, y0 = lo - margin
    w, h = hi - lo + 2 * margin
    to_float32([x0, y0, w, h], "the drawing's extent (with the branch widths)", where)  # what viewers draw with
    px_w, px_h = (DISPLAY_PIXELS, DISPLAY_PIXELS * (h / w)) if w >= h else (DISPLAY_PIXELS * (w / h), DISPLAY_PIXELS)

    title = tree.name
    metadata = _json_text(metadata_json(tree, where))
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" version="1.1" viewBox="{num.one(x0)} {num.one(y0)} '
        f'{num.one(w)} {num.one(h)}" width="{round(px_w)}" height="{round(px_h)}">',
        f"<title>{escape(printable(title))}</title>",  # XML 1.0 allows no control characters
        f"<metadata>{escape(metadata)}</metadata>",
        f'<rect x="{num.one(x0)}" y="{num.one(y0)}" width="{num.one(w)}" height="{num.one(h)}" fill="white"/>',
    ]
    if len(skeleton):
        out.append(f'<g fill="none" stroke="{LINE_COLOR}" stroke-linecap="round" stroke-linejoin="round">')
        out.extend(_polylines(skeleton, project(start), project(end), stroke, num))
        out.append("</g>")
    leaf_color = _srgb(tree.leaf_material.base_color)
    if skeleton.n_polygons or leaf_shapes:
        edge = _darker(tree.leaf_material)
        out.append(f'<g fill="{leaf_color}" stroke="{edge}" stroke-width="{num.one(0.5 * hairline)}">')
        offsets = np.asarray(skeleton.polygon_offsets).tolist()
        projected = project(polygon_points)
        for a, b in itertools.pairwise(offsets):
            if b - a >= 3:
                out.append(f'<polygon points="{num.points(projected[a:b])}"/>')
        if leaf_shapes:
            loops = [project(s) for s in leaf_shapes]
            for i in range(len(tree.leaves.transforms)):
                d = " ".join(f"M{num.points(loop[i])}Z" for loop in loops)
                out.append(f'<path d="{d}"/>')
        out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _polylines(skeleton, start2, end2, stroke, num) -> list[str]:
    """One ``<polyline>`` per run of equal stroke width along each chain."""
    chains = skeleton.chains
    lines = []
    offsets = chains.offsets.tolist()
    for c in range(len(chains)):
        segs = chains.segments[offsets[c] : offsets[c + 1]]
        for a, b in _runs(stroke[segs]):
            run = segs[a:b]
            pts = np.concatenate([start2[run[:1]], end2[run]])
            lines.append(f'<polyline stroke-width="{stroke[run[0]]}" points="{num.points(pts)}"/>')
    return lines


def _darker(material: Material) -> str:
    return _srgb([0.5 * c for c in material.base_color[:3]])


def _json_text(value) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)


def write_svg(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write the line drawing of ``tree`` to ``path`` atomically; see :func:`svg_text`."""
    data = svg_text(tree, options, where=str(path)).encode("utf-8")
    return write_bytes(path, [data], options.no_clobber)
