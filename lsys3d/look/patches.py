"""cpfg's surfaces: the bicubic Bezier patches of a vlab ``.s`` file, as a :class:`~lsys3d.mesh.mesh.Mesh`.

A vlab model's view file binds a surface to a letter (``surface: l leaf.s 1 8 4``: the surface ``~l``,
its file, its size and its precisions in s and t); the file (written by vlab's surface editor) holds
the surface's bounding box, its contact point, end point, heading, up vector and size, then one patch
after another: a name, a colour line, three lines of neighbours and 16 control points (4 rows of 4).

cpfg (``patches.c``: ``determine_transform``, ``get_patch``, ``calculate_surface``) moves each control
point by minus the contact point, scales it by ``size / SIZE``, writes it in the file's frame (``x``
along left = heading x up, ``y`` along the heading, ``z`` along up) and samples each patch at
``(s_precision + 1) x (t_precision + 1)`` points; the turtle then places that frame on its own left,
heading and up, scaled by ``~l(sx, sy, sz)``.  Here the surface is turned into the leaf-model frame of
:mod:`lsys3d.look.leaves` (``x`` = left, ``y`` = up, ``z`` = heading), each patch sampled as cpfg does,
with cpfg's texture coordinates: per surface (``TEXELS_PER_SURFACE``: ``s`` and ``t`` the point's place
in the surface's box along left and along the heading) or per patch (the patch's own parameters), as
``(u, v) = (s, t)``: both put the image's bottom row at ``t = 0`` (cpfg's PNG loader turns the rows over
for OpenGL; lsys3d's ``v`` is OpenGL's, which the glTF writer flips), the stem of a leaf image at the
surface's contact point.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import AssetError, clip
from ..mesh.mesh import Mesh

__all__ = ["MAX_PATCHES", "MAX_PRECISION", "TEXELS", "read_patches"]

MAX_PATCHES = 1000
"""Most patches of one surface file."""
MAX_PRECISION = 64
"""Largest precision in s or t (cpfg's ``S_COUNT``/``T_COUNT`` are of this order)."""
TEXELS = ("surface", "patch")
"""cpfg's two texture mappings: over the surface's box, or over each patch."""

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_VECTOR = re.compile(rf"X:\s*({_NUMBER})\s*Y:\s*({_NUMBER})\s*Z:\s*({_NUMBER})")
_BEZIER = np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 3, 0, 0], [1, 0, 0, 0]], np.float64)


def _basis(n: int) -> np.ndarray:
    """The four cubic Bernstein weights at ``n + 1`` even steps of [0, 1], ``(n + 1, 4)``."""
    u = np.linspace(0.0, 1.0, n + 1)
    return np.stack([u**3, u**2, u, np.ones_like(u)], axis=1) @ _BEZIER


def read_patches(
    text: str, source: str, size: float = 1.0, s_precision: int = 0, t_precision: int = 0, texels: str = "surface"
) -> Mesh:
    """The surface of a vlab ``.s`` file, sampled as cpfg samples it, in the leaf-model frame.

    Parameters
    ----------
    text : str
        The file's text.
    source : str
        Its name, for messages.
    size : float
        The view file's size: the surface is scaled by ``size / SIZE`` (the file's ``SIZE:``).
    s_precision, t_precision : int
        Points per patch in s and t less one (0: the file's ``PRECISION`` line, else cpfg's default, 8).
    texels : str
        ``surface`` or ``patch`` (:data:`TEXELS`).

    Raises
    ------
    AssetError
        ``source: what``: a line that is not what cpfg reads, no patch, too many, a degenerate frame.

    Examples
    --------
    >>> flat = "0 1 0 1 0 0\\nCONTACT POINT X: 0 Y: 0 Z: 0\\nEND POINT X: 0 Y: 1 Z: 0\\n"
    >>> flat += "HEADING X: 0 Y: 1 Z: 0\\nUP X: 0 Y: 0 Z: 1\\nSIZE: 1\\np\\n"
    >>> flat += "TOP COLOR: 0 DIFFUSE: 0 BOTTOM COLOR: 0 DIFFUSE: 0\\n"
    >>> flat += "AL: ~ A: ~ AR: ~\\nL: ~ R: ~\\nBL: ~ B: ~ BR: ~\\n"
    >>> flat += "\\n".join(" ".join(f"{x / 3:g} {y / 3:g} 0" for x in range(4)) for y in range(4))
    >>> m = read_patches(flat, "flat.s", 2.0, 2, 2)
    >>> len(m.faces), m.bounds.round(6).tolist()
    (8, [[0.0, 0.0, 0.0], [2.0, 0.0, 2.0]])
    """
    if texels not in TEXELS:
        raise AssetError(f"{source}: the texture mapping is one of {', '.join(TEXELS)}, not {clip(repr(texels))}")
    lines = [line.strip() for line in text.replace("\r", "\n").split("\n")]
    lines = [line for line in lines if line]

    def fail(what: str) -> AssetError:
        return AssetError(f"{clip(source, 100)}: {what} (a vlab surface file: cpfg's patches.c)")

    at = 0

    def line(prefix: str) -> str:
        nonlocal at
        if at >= len(lines) or not lines[at].upper().startswith(prefix):
            found = clip(repr(lines[at]), 40) if at < len(lines) else "the end of the file"
            raise fail(f"expected {prefix!r}, found {found}")
        at += 1
        return lines[at - 1][len(prefix) :]

    def vector(prefix: str) -> np.ndarray:
        m = _VECTOR.search(line(prefix))
        if m is None:
            raise fail(f"{prefix} expects X: x Y: y Z: z")
        return np.array([float(v) for v in m.groups()])

    words = []
    while at < len(lines) and not lines[at].upper().startswith(("PRECISION", "CONTACT")):
        words += lines[at].split()
        at += 1
    if len(words) != 6 or not all(re.fullmatch(_NUMBER, w) for w in words):
        raise fail(f"the first line must be the box's six numbers, not {clip(repr(' '.join(words)), 40)}")
    file_precision = 8  # cpfg: S_COUNT / 2 without a PRECISION line
    if lines[at].upper().startswith("PRECISION"):
        m = re.search(r"S:\s*(\d+)\s*T:\s*(\d+)", line("PRECISION"))
        if m is None:
            raise fail("PRECISION expects S: s T: t")
        file_precision = int(m.group(1))
    contact = vector("CONTACT POINT")
    vector("END POINT")
    heading, up = vector("HEADING"), vector("UP")
    words = line("SIZE:").split()
    if len(words) != 1 or not re.fullmatch(_NUMBER, words[0]) or not float(words[0]) > 0:
        raise fail("SIZE: expects one number above 0")
    scale = size / float(words[0])
    if not (np.linalg.norm(heading) > 0 and np.linalg.norm(up) > 0):
        raise fail("HEADING and UP must not be 0")
    heading, up = heading / np.linalg.norm(heading), up / np.linalg.norm(up)
    left = np.cross(heading, up)
    if not np.linalg.norm(left) > 1e-9:
        raise fail("HEADING and UP must not be parallel")
    left = left / np.linalg.norm(left)  # cpfg leaves it as it is; the file's are unit and at right angles
    up = np.cross(left, heading)
    # cpfg: the point (x, y, z) -> x * left + y * heading + z * up, in its frame (left, heading, up); the
    # leaf-model frame is (left, up, heading)
    frame = np.stack([left, heading, up], axis=0)  # rows: what x, y, z of the file become
    sp = s_precision or file_precision
    tp = t_precision or file_precision  # cpfg's determine_transform: t takes the file's s precision too
    if not (1 <= sp <= MAX_PRECISION and 1 <= tp <= MAX_PRECISION):
        raise fail(f"the precisions must be whole numbers in [1, {MAX_PRECISION}], not {sp} and {tp}")
    patches = []
    while at < len(lines):
        at += 1  # the patch's name
        line("TOP COLOR:")
        line("AL:")
        line("L:")
        line("BL:")
        numbers = []
        while at < len(lines) and len(numbers) < 48:
            numbers += lines[at].split()
            at += 1
        try:
            points = np.array([float(w) for w in numbers], np.float64)
        except ValueError:
            raise fail(f"the control points of patch {len(patches) + 1} must be numbers") from None
        if len(points) != 48 or not np.isfinite(points).all():
            raise fail(f"patch {len(patches) + 1} needs 16 control points of 3 numbers")
        patches.append(((points.reshape(4, 4, 3) - contact) * scale) @ frame)
        if len(patches) > MAX_PATCHES:
            raise fail(f"more than {MAX_PATCHES} patches (lsys3d.look.patches.MAX_PATCHES)")
    if not patches:
        raise fail("no patch")
    bs, bt = _basis(sp), _basis(tp)
    grids = [np.einsum("si,tj,ijc->stc", bs, bt, g) for g in patches]  # cpfg: s along the rows, t within them
    every = np.concatenate([g.reshape(-1, 3) for g in grids])
    lo, hi = every.min(axis=0), every.max(axis=0)
    extent = np.where(hi - lo > 0, hi - lo, 1.0)
    vertices, faces, uvs = [], [], []
    s_idx, t_idx = np.meshgrid(np.arange(sp), np.arange(tp), indexing="ij")
    quad = np.stack([s_idx * (tp + 1) + t_idx, (s_idx + 1) * (tp + 1) + t_idx], axis=-1).reshape(-1, 2)
    for k, grid in enumerate(grids):
        base = k * (sp + 1) * (tp + 1)
        flat = grid.reshape(-1, 3)
        if texels == "surface":
            st = (flat[:, :2] - lo[:2]) / extent[:2]  # x along left, y along the heading
        else:
            s, t = np.meshgrid(np.linspace(0, 1, sp + 1), np.linspace(0, 1, tp + 1), indexing="ij")
            st = np.stack([s.reshape(-1), t.reshape(-1)], axis=1)
        a, b = quad[:, 0], quad[:, 1]
        tri = np.concatenate([np.stack([a, b, a + 1], 1), np.stack([a + 1, b, b + 1], 1)])
        vertices.append(flat[:, [0, 2, 1]])  # the leaf-model frame: left, up, heading
        faces.append(tri + base)
        uvs.append(st)
    vertices = np.concatenate(vertices)
    faces = np.concatenate(faces)
    uv = np.concatenate(uvs)
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    keep = np.linalg.norm(cross, axis=1) > 1e-12 * max(1.0, float(np.abs(vertices).max()))
    faces, cross = faces[keep], cross[keep]  # a patch's collapsed edge (the leaf's tip) makes no triangle
    if not len(faces):
        raise fail("the patches have no area")
    corner = faces.reshape(-1)
    smooth = np.stack([np.bincount(corner, np.repeat(cross[:, c], 3), minlength=len(vertices)) for c in range(3)], 1)
    length = np.linalg.norm(smooth, axis=1, keepdims=True)
    smooth = np.where(length > 0, smooth / np.where(length > 0, length, 1.0), [0.0, 1.0, 0.0])
    if not math.isfinite(float(np.abs(vertices).max())):
        raise fail("the control points are not finite")
    return Mesh(vertices, faces, smooth[faces], uv[faces])
