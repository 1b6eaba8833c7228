"""Which tube face each face lies on (:func:`tube_faces`), checked by distance."""

from __future__ import annotations

import math

import numpy as np

from ...compiling import kernel
from .geometry import _normal_xyz


def tube_faces(points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute, pool=None):
    """What each face of the union learns from the tube face it is a piece of (``source``), in one pass.

    The tube faces are ``wedge_point[tube_faces]`` (:class:`lsys3d.mesh.sweep.Tubes`).

    Returns ``scale (v,)``: the shortest edge of the tube faces around each
    vertex (inf for none); ``original (v,) bool``: the vertex lies on a corner
    of one of its faces' tube faces, within ``relative`` times that face's
    shortest edge or ``absolute`` times the coordinate's magnitude (the union
    moves vertices that share a float32 position apart by a few float32
    steps); ``reference (f, 3)``: the tube face's unit normal (zero when it
    has no area).  With a ``pool`` (an executor), one of its threads reads
    the second half of the faces, into vertex arrays of its own that are
    then merged (a minimum, an or: the same values).
    """
    nf, nv = len(faces), len(points)
    scale, original, reference = np.full(nv, np.inf), np.zeros(nv, np.bool_), np.zeros((nf, 3))
    args = (points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute)
    if pool is None:
        _tube_faces(*args, scale, original, reference, 0, nf)
        return scale, original, reference
    scale2, original2 = np.full(nv, np.inf), np.zeros(nv, np.bool_)
    second = pool.submit(_tube_faces, *args, scale2, original2, reference, nf // 2, nf)
    _tube_faces(*args, scale, original, reference, 0, nf // 2)
    second.result()
    np.minimum(scale, scale2, out=scale)
    original |= original2
    return scale, original, reference


@kernel(nogil=True)
def _tube_faces(
    points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute, scale, original, reference, lo, hi
):  # pragma: no cover - compiled
    """:func:`tube_faces` of the faces ``lo .. hi - 1``, into ``scale``, ``original`` and ``reference``."""
    corner = np.empty((3, 3))
    for f in range(lo, hi):
        tf = source[f]
        for j in range(3):
            q = wedge_point[tube_faces[tf, j]]
            corner[j, 0], corner[j, 1], corner[j, 2] = tube_points[q, 0], tube_points[q, 1], tube_points[q, 2]
        shortest = 1e300
        for j in range(3):
            k = (j + 1) % 3
            d = 0.0
            for c in range(3):
                e = corner[j, c] - corner[k, c]
                d += e * e
            shortest = min(shortest, math.sqrt(d))
        nx, ny, nz = _normal_xyz(
            corner[0, 0], corner[0, 1], corner[0, 2], corner[1, 0], corner[1, 1], corner[1, 2],
            corner[2, 0], corner[2, 1], corner[2, 2],
        )  # fmt: skip
        n = math.sqrt(nx * nx + ny * ny + nz * nz)
        if n > 0.0:
            reference[f, 0], reference[f, 1], reference[f, 2] = nx / n, ny / n, nz / n
        for i in range(3):
            v = faces[f, i]
            scale[v] = min(scale[v], shortest)
            if original[v]:
                continue
            size = max(abs(points[v, 0]), max(abs(points[v, 1]), abs(points[v, 2])))
            near = max(relative * shortest, absolute * size)
            for j in range(3):
                d = 0.0
                for c in range(3):
                    e = points[v, c] - corner[j, c]
                    d += e * e
                if math.sqrt(d) <= near:
                    original[v] = True
                    break
