"""The uv of a blob's crowd: a box projection where the nearest tube's chart would be confetti.

A blob (:mod:`lsys3d.mesh.union.blobs`) names, for each of its triangles, the
wall face of the nearest span, and its uv is that tube's chart (``u`` around,
``v`` along).  Along a stem that runs through the blob that is what a bark
texture needs.  In the crowd at an apex it is not: there the nearest span
changes every few triangles among thousands of tubes shorter than they are
wide, each with its own seam and its own ``v``, and a checker texture on L-Py's
fern came out as noise (``docs/mesh.md``, "Dense grammars: blobs").

So the triangles whose source tube is short (its axis shorter than
:data:`BOX_LENGTH` times its width) take a box projection instead: each
triangle is projected onto the coordinate plane it faces most (``u, v`` the
two other coordinates, ``u`` mirrored on the faces that look down the axis,
so the texture is not mirrored), at one density per blob, the median over its
tubes of the tubes' own (``tiles / perimeter``: texels as square as on the
tubes).  The texture then runs on unbroken across a leaflet, a seam only where
a triangle's plane changes (faces more than 54.7 degrees from every axis are
stretched up to 1.73 times).  The triangles of the long tubes keep their
tube's chart, so a seam also separates a stem from the crowd it enters.

The choice is made per tube and carried as ``Mesh.face_box_uv`` (the density,
0 for a tube's chart): the cleanup, which remakes every uv after it moves
vertices, reads it back per tube (:func:`tube_density`).
"""

from __future__ import annotations

import numba
import numpy as np

from ...arrays import ranges
from ..sweep import Tubes

BOX_LENGTH = 4.0
"""A tube of a blob whose axis is shorter than this many widths gets the box projection."""


def blob_density(tubes: Tubes, members: np.ndarray) -> np.ndarray:
    """``(t,) float64``: the box projection's density (tiles per metre) for the short tubes of ``members``, else 0.

    Every tube outside ``members`` and every long one of them gets 0 (its own chart).
    """
    out = np.zeros(len(tubes))
    if not len(members):
        return out
    first, rings = tubes.ring_offsets[members], tubes.rings[members]
    last = first + rings - 1
    centre = tubes.ring_center
    step = np.linalg.norm(np.diff(centre, axis=0), axis=1) if len(centre) > 1 else np.zeros(0)
    along = np.concatenate([[0.0], np.cumsum(step)])
    length = along[last] - along[first]  # (rings of one tube are consecutive rows)
    starts = np.concatenate([[0], np.cumsum(rings)[:-1]])
    width = 2.0 * np.maximum.reduceat(tubes.ring_radius[ranges(first, rings)], starts)
    sides = tubes.sides[members].astype(np.float64)
    perimeter = sides * 2.0 * np.sin(np.pi / sides) * 0.5 * width
    density = float(np.median(np.asarray(tubes.tiles, np.float64)[members] / perimeter))
    out[members[length < BOX_LENGTH * width]] = density
    return out


def tube_density(tubes: Tubes, face_source: np.ndarray, face_box_uv: np.ndarray | None) -> np.ndarray | None:
    """``(t,)`` density of each tube's box projection read back from a mesh's faces (None: no face has one)."""
    if face_box_uv is None or not np.any(face_box_uv > 0):
        return None
    boxed = np.flatnonzero(face_box_uv > 0)
    tube, _ = tubes.face_kinds(np.ascontiguousarray(face_source[boxed]))
    out = np.zeros(len(tubes))
    out[tube] = face_box_uv[boxed]
    return out


def face_density(tubes: Tubes, face_source: np.ndarray, per_tube: np.ndarray) -> np.ndarray:
    """``(f,) float32``: the density of the tube of each face's source (0: the tube's chart)."""
    tube, _ = tubes.face_kinds(np.ascontiguousarray(face_source))
    return per_tube[tube].astype(np.float32)


def box_uv(points: np.ndarray, faces: np.ndarray, density: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Overwrite ``uv[i]`` ``(f, 3, 2)`` of each face with ``density[i] > 0`` by its box projection; ``uv`` back."""
    which = np.flatnonzero(density > 0)
    if len(which):
        _box(np.asarray(points, np.float64), np.ascontiguousarray(faces), which, np.asarray(density), uv)
    return uv


@numba.njit(cache=True, nogil=True)
def _box(points, faces, which, density, uv):  # pragma: no cover - compiled
    """:func:`box_uv`, a face at a time (in float64, stored once)."""
    for i in which:
        a, b, c = faces[i, 0], faces[i, 1], faces[i, 2]
        n = np.empty(3)
        for k in range(3):
            k1, k2 = (k + 1) % 3, (k + 2) % 3
            n[k] = (points[b, k1] - points[a, k1]) * (points[c, k2] - points[a, k2]) - (
                points[b, k2] - points[a, k2]
            ) * (points[c, k1] - points[a, k1])
        axis = 0
        if abs(n[1]) > abs(n[axis]):
            axis = 1
        if abs(n[2]) > abs(n[axis]):
            axis = 2
        first, second = (axis + 1) % 3, (axis + 2) % 3
        sign = 1.0 if n[axis] >= 0.0 else -1.0
        for j in range(3):
            q = faces[i, j]
            uv[i, j, 0] = sign * density[i] * points[q, first]
            uv[i, j, 1] = density[i] * points[q, second]
