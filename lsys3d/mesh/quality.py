"""Triangle and texture quality of a mesh: the measures a technical director checks before a mesh ships.

* **Aspect** of a triangle: longest edge / (2 sqrt(3) inradius).  1 for an
  equilateral triangle, 1.39 for a right isosceles one, growing without
  bound as a triangle degenerates (infinite for zero area).  A tube of
  :mod:`lsys3d.mesh.sweep` stays under 50; a triangle above 100 is a *needle* or a
  *cap* that breaks tangent generation, lightmap unwrapping, subdivision and
  decimation downstream.
* **Height**: the triangle's smallest altitude (twice its area over its
  longest edge).  Under 1 micrometre a triangle is a *sliver*: its normal is
  noise, and float32 files cannot tell its vertices apart from the edge.
* **UV stretch**: how much a square texel is stretched on the surface, the
  ratio of the largest to the smallest singular value of the map from the
  triangle to its texture coordinates (1: a checker stays square; 19 would be
  squares 19 times as long as wide).  Triangles whose uv have no area are
  left out.

:func:`quality` gathers them into a :class:`Quality` record (what ``lsys3d
stats --mesh`` prints and golden files hold, in the section ``quality``).

Examples
--------
>>> from lsys3d.mesh.mesh import Mesh
>>> q = quality(Mesh.box())
>>> q.triangles, q.over_100, q.slivers, round(q.max_aspect, 3)
(12, 0, 0, 1.394)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .mesh import Mesh

__all__ = ["NEEDLE", "SLIVER_HEIGHT", "Quality", "aspect_ratios", "heights", "quality", "uv_stretch"]

NEEDLE = 100.0
"""Aspect above which a triangle counts as a needle (``Quality.over_100``)."""

SLIVER_HEIGHT = 1e-6
"""Height (metres) under which a triangle counts as a sliver (``Quality.slivers``)."""


def _edges(vertices: np.ndarray, faces: np.ndarray):
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    e = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 1], tri[:, 0] - tri[:, 2]], axis=1)
    length = np.linalg.norm(e, axis=2)
    area = 0.5 * np.linalg.norm(np.cross(e[:, 0], e[:, 1]), axis=1)
    return length, area


def aspect_ratios(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Aspect of each triangle, longest edge / (2 sqrt(3) inradius), ``(f,) float64`` (inf for zero area).

    >>> aspect_ratios(np.array([[0, 0, 0], [1, 0, 0], [0.5, 3**0.5 / 2, 0]]), np.array([[0, 1, 2]])).round(9).tolist()
    [1.0]
    """
    length, area = _edges(vertices, faces)
    half_perimeter = 0.5 * length.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inradius = area / half_perimeter
        aspect = length.max(axis=1) / (2.0 * np.sqrt(3.0) * inradius)
    return np.where(area > 0, aspect, np.inf)


def heights(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Smallest altitude of each triangle (twice its area over its longest edge), ``(f,) float64``."""
    length, area = _edges(vertices, faces)
    longest = length.max(axis=1)
    return np.where(longest > 0, 2.0 * area / np.where(longest > 0, longest, 1.0), 0.0)


def uv_stretch(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Stretch of the texture on each triangle: largest over smallest singular value of the surface -> uv map.

    Parameters
    ----------
    vertices : (v, 3), faces : (f, 3)
    uv : (f, 3, 2)
        Texture coordinates per face corner (:attr:`lsys3d.mesh.mesh.Mesh.uv`).

    Returns
    -------
    (f,) float64
        1 where a square of texture stays square; NaN where the triangle or its
        uv have no area.

    Examples
    --------
    >>> v = np.array([[0.0, 0, 0], [2, 0, 0], [0, 1, 0]])
    >>> uv_stretch(v, np.array([[0, 1, 2]]), np.array([[[0, 0], [1, 0], [0, 1]]])).tolist()
    [2.0]
    """
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    uv = np.asarray(uv, np.float64).reshape(-1, 3, 2)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    # an orthonormal frame of each triangle's plane: x along e1
    len1 = np.linalg.norm(e1, axis=1)
    normal = np.cross(e1, e2)
    area2 = np.linalg.norm(normal, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = e1 / len1[:, None]
        y = np.cross(normal / area2[:, None], x)
        # positions in the plane: p1 = (len1, 0), p2 = (e2.x, e2.y); J maps the plane to uv
        p2x, p2y = np.einsum("ij,ij->i", e2, x), np.einsum("ij,ij->i", e2, y)
        du_dx = d1 / len1[:, None]
        du_dy = (d2 - du_dx * p2x[:, None]) / p2y[:, None]
    jac = np.stack([du_dx, du_dy], axis=2)  # (f, 2, 2): columns are d(uv)/dx, d(uv)/dy
    ok = (area2 > 0) & np.isfinite(jac).all(axis=(1, 2))
    s = np.full(len(tri), np.nan)
    if ok.any():
        sv = np.linalg.svd(jac[ok], compute_uv=False)
        with np.errstate(divide="ignore", invalid="ignore"):
            s[ok] = np.where(sv[:, 1] > 0, sv[:, 0] / sv[:, 1], np.nan)
    return s


@dataclass(frozen=True)
class Quality:
    """Triangle and uv quality of one mesh (see the module's documentation for the measures).

    Attributes
    ----------
    triangles : int
    over_100, over_1000 : int
        Triangles with an aspect above 100 (needles and caps) and above 1,000.
    slivers : int
        Triangles less than :data:`SLIVER_HEIGHT` (1 um) high.
    max_aspect : float
        The worst aspect (inf for a zero-area triangle).
    uv_stretch : float
        Median uv stretch over the triangles that have uv area (NaN if none do).
    """

    triangles: int
    over_100: int
    over_1000: int
    slivers: int
    max_aspect: float
    uv_stretch: float

    def to_json(self) -> dict:
        """Plain values with sorted keys (infinities and NaN as None, which JSON can hold)."""
        out = {}
        for k, v in sorted(asdict(self).items()):
            out[k] = None if isinstance(v, float) and not np.isfinite(v) else v
        return out


def quality(mesh: Mesh) -> Quality:
    """The :class:`Quality` of a mesh (all zeros for an empty one)."""
    if mesh.is_empty:
        return Quality(0, 0, 0, 0, 0.0, float("nan"))
    aspect = aspect_ratios(mesh.vertices, mesh.faces)
    height = heights(mesh.vertices, mesh.faces)
    stretch = uv_stretch(mesh.vertices, mesh.faces, mesh.uv)
    finite = stretch[np.isfinite(stretch)]
    return Quality(
        triangles=len(mesh.faces),
        over_100=int((aspect > NEEDLE).sum()),
        over_1000=int((aspect > 10 * NEEDLE).sum()),
        slivers=int((height < SLIVER_HEIGHT).sum()),
        max_aspect=float(aspect.max()),
        uv_stretch=float(np.median(finite)) if len(finite) else float("nan"),
    )
