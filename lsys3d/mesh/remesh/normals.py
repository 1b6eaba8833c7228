"""Per-corner normals (:func:`corner_normals`): smooth across curved faces, flat on the caps."""

from __future__ import annotations

import math

import numpy as np

from ...compiling import kernel
from .geometry import _cross, _normal_xyz
from .halfedge import _leaf_inner, in_two


def corner_normals(points, faces, flat, pool=None):
    """Corner normals ``(f, 3, 3) float32``: angle-weighted vertex normals of the curved faces; flat faces' own.

    A corner whose vertex gets no normal (its faces cancel out) takes its
    face's; a face without area takes +Y.  With a ``pool`` (an executor), one
    of its threads sums the normals of the second half of the vertices (each
    vertex's faces in the same order: the same bits) and writes the second half
    of the corners.
    """
    nv, nf = len(points), len(faces)
    vn = np.zeros((nv, 3))
    some = np.zeros(nv, np.bool_)  # the vertex has a normal of its own (then unit)
    if pool is None:  # each half of the vertices reads every face: without a pool, one pass for all of them
        _vertex_normal_sums(points, faces, flat, vn, some, 0, nv)
    else:
        in_two(pool, _vertex_normal_sums, (points, faces, flat, vn, some), 0, nv // 2, nv)
    out = np.empty((nf, 3, 3), np.float32)
    in_two(pool, _corner_rows, (points, faces, flat, vn, some, out), 0, nf // 2, nf)
    return out


@kernel(nogil=True)
def _vertex_normal_sums(points, faces, flat, vn, some, lo, hi):  # pragma: no cover - compiled
    """:func:`corner_normals`' unit vertex normals of the vertices ``lo:hi`` (``some``: they have one): the
    angle-weighted sum of the normals of their curved faces, face after face."""
    for f in range(len(faces)):
        if flat[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if not (lo <= a < hi or lo <= b < hi or lo <= c < hi):
            continue
        fx, fy, fz, area = _unit_normal(points, a, b, c)
        if not area:
            continue
        for k in range(3):
            v, w, u = faces[f, k], faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            if not lo <= v < hi:
                continue
            ex, ey, ez = points[w, 0] - points[v, 0], points[w, 1] - points[v, 1], points[w, 2] - points[v, 2]
            gx, gy, gz = points[u, 0] - points[v, 0], points[u, 1] - points[v, 1], points[u, 2] - points[v, 2]
            cx, cy, cz = _cross(ex, ey, ez, gx, gy, gz)
            angle = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ex * gx + ey * gy + ez * gz)
            vn[v, 0] += angle * fx
            vn[v, 1] += angle * fy
            vn[v, 2] += angle * fz
    for v in range(lo, hi):
        n = math.sqrt(vn[v, 0] * vn[v, 0] + vn[v, 1] * vn[v, 1] + vn[v, 2] * vn[v, 2])
        if not n < 1e-12:
            some[v] = True
            vn[v, 0], vn[v, 1], vn[v, 2] = vn[v, 0] / n, vn[v, 1] / n, vn[v, 2] / n


@kernel(nogil=True)
def _corner_rows(points, faces, flat, vn, some, out, lo, hi):  # pragma: no cover - compiled
    """:func:`corner_normals`' rows ``lo:hi`` of ``out``: a flat face's corners (or a corner whose vertex has no
    normal) take the face's own normal (made again: no (f, 3) array of them), the others their vertex's.
    ``+ 0.0`` makes a -0.0 0.0 (as the files store it: the writers need not copy the normals to fold it)."""
    for f in range(lo, hi):
        fx, fy, fz, _ = _unit_normal(points, faces[f, 0], faces[f, 1], faces[f, 2])
        for k in range(3):
            v = faces[f, k]
            if flat[f] or not some[v]:
                out[f, k, 0], out[f, k, 1], out[f, k, 2] = fx + 0.0, fy + 0.0, fz + 0.0
            else:
                out[f, k, 0], out[f, k, 1], out[f, k, 2] = vn[v, 0] + 0.0, vn[v, 1] + 0.0, vn[v, 2] + 0.0


@_leaf_inner
def _unit_normal(p, a, b, c):
    """Triangle ``a b c``'s unit normal and whether it has area (+Y when it has none).  (From the coordinates:
    :func:`~lsys3d.mesh.remesh.geometry._normal` is compiled for the half-edges' int32 corners, these are int64.)"""
    nx, ny, nz = _normal_xyz(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])
    n = math.sqrt(nx * nx + ny * ny + nz * nz)
    if n > 0.0:
        return nx / n, ny / n, nz / n, True
    return 0.0, 1.0, 0.0, False
