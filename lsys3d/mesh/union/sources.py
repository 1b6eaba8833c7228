"""Which face of the given tubes each face of the union lies in (``Mesh.face_source``): manifold's face ids,
checked against the faces' distance from their tube face and made true where they are not."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ...arrays import dot3, isin, ranges, unique
from ...compiling import inner, kernel
from ...errors import GeometryError
from ..mesh import Mesh
from ..sweep import Tubes

log = logging.getLogger("lsys3d")


def _misplaced(vertices: np.ndarray, faces: np.ndarray, source: np.ndarray, tubes: Tubes) -> np.ndarray:
    """``(f,) bool``: the faces whose centroid is farther from their source tube face than its radius and side.

    A piece of a face lies on the face; one of a span split by new rings lies
    in the quad of the span (within a side of the tube, ``2 r sin(pi / sides)``,
    more than the radius when a tube has 3-5 sides).  A slice at a time.
    """
    radius = np.maximum.reduceat(tubes.ring_radius, tubes.ring_offsets[:-1])
    radius = radius * (1.0 + 2.0 * np.sin(np.pi / tubes.sides))
    reach = radius[np.searchsorted(tubes.face_offsets, source, side="right") - 1] * (1 + 1e-6) + 1e-9
    return _far_from_source(vertices, faces, source, tubes.points, tubes.wedge_point, tubes.faces, reach)


@kernel(nogil=True)
def _far_from_source(vertices, faces, source, points, wedge_point, tube_faces, reach):  # pragma: no cover - compiled
    """``(f,) bool``: the centroid of face ``f`` is farther than ``reach[f]`` from tube face ``source[f]``.

    A face at a time, without the (f, 3, 3) gathers.  The arithmetic is numpy's,
    in its order (``np.cross``; ``np.einsum`` dot products sum x, z, then y;
    ``np.linalg.norm`` x, y, z; ``mean`` divides the sum by 3), so the answer
    is the same as the vectorised distance's at every face.
    """
    out = np.empty(len(faces), np.bool_)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    out[:] = False
    p = np.empty(3)
    tri = np.empty((3, 3))
    for f in range(len(faces)):
        for j in range(3):
            p[j] = (vertices[faces[f, 0], j] + vertices[faces[f, 1], j] + vertices[faces[f, 2], j]) / 3.0
        for c in range(3):
            w = wedge_point[tube_faces[source[f], c]]
            for j in range(3):
                tri[c, j] = points[w, j]
        d = _triangle_distance(p, tri)
        out[f] = d > reach[f]
    return out


@inner(nogil=True)
def _triangle_distance(p, tri):  # pragma: no cover - compiled
    """Distance of the point ``p`` (3,) from the triangle ``tri`` (3, 3)."""
    a0, a1, a2 = tri[0, 0], tri[0, 1], tri[0, 2]
    u0, u1, u2 = tri[1, 0] - a0, tri[1, 1] - a1, tri[1, 2] - a2
    v0, v1, v2 = tri[2, 0] - a0, tri[2, 1] - a1, tri[2, 2] - a2
    n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if length < 1e-300:  # np.maximum(length, 1e-300), NaN kept
        length = 1e-300
    n0, n1, n2 = n0 / length, n1 / length, n2 / length
    height = dot3(p[0] - a0, p[1] - a1, p[2] - a2, n0, n1, n2)
    q0, q1, q2 = p[0] - height * n0, p[1] - height * n1, p[2] - height * n2
    inside = True
    edge = np.inf
    for k in range(3):
        s0, s1, s2 = tri[k, 0], tri[k, 1], tri[k, 2]
        e0, e1, e2 = tri[(k + 1) % 3, 0] - s0, tri[(k + 1) % 3, 1] - s1, tri[(k + 1) % 3, 2] - s2
        w0, w1, w2 = q0 - s0, q1 - s1, q2 - s2
        c0, c1, c2 = e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0
        inside &= dot3(c0, c1, c2, n0, n1, n2) >= 0
        ee = dot3(e0, e1, e2, e0, e1, e2)
        if ee < 1e-300:  # np.maximum(ee, 1e-300), NaN kept
            ee = 1e-300
        t = dot3(p[0] - s0, p[1] - s1, p[2] - s2, e0, e1, e2) / ee
        if t < 0.0:  # np.clip(t, 0, 1), NaN kept
            t = 0.0
        elif t > 1.0:
            t = 1.0
        r0, r1, r2 = p[0] - (s0 + t * e0), p[1] - (s1 + t * e1), p[2] - (s2 + t * e2)
        d = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        if np.isnan(d) or np.isnan(edge):  # np.minimum propagates NaN
            edge = np.nan
        elif d < edge:
            edge = d
    return abs(height) if inside else edge


def _true_sources(mesh: Mesh, tubes: Tubes, checked: int | None = None) -> Mesh:
    """The mesh with every face's source a tube face it lies on or next to.

    Only the first ``checked`` faces (all by default) are checked: the local
    path puts the boolean's output first and the untouched tube pieces, whose
    faces are their own sources, after it.

    manifold3d keeps each input triangle's face id on its pieces, but where
    coplanar tubes cross (the flat presets: ``tree`` 31 of 279,780 faces,
    ``abop-1.24c`` 4 of 287,018), it gives a few triangles the id of a face
    of another tube, far away.  Such a face takes the source of a neighbour
    (sharing a vertex) whose source face it does lie next to (``tree``: 24 of
    the 31; ``abop-1.24c``: 1 of 4); a face none of whose neighbours fits (a
    long triangle across several coplanar tubes) keeps its id, and is logged.
    """
    faces, source = mesh.faces, mesh.face_source
    checked = len(faces) if checked is None else checked
    bad = np.flatnonzero(_misplaced(mesh.vertices, faces[:checked], source[:checked], tubes))
    if not len(bad):
        return mesh
    source = source.copy()
    found = len(bad)
    for _ in range(8):
        good_faces = np.ones(len(faces), bool)
        good_faces[bad] = False
        near = np.zeros(len(mesh.vertices), bool)
        near[faces[bad]] = True
        cand = np.flatnonzero(near[faces].any(axis=1) & good_faces)
        cv = faces[cand].ravel()
        cf = np.repeat(cand, 3)
        order = np.argsort(cv, kind="stable")
        cv, cf = cv[order], cf[order]
        bv = faces[bad].ravel()  # each bad face's corners
        lo, hi = np.searchsorted(cv, bv, "left"), np.searchsorted(cv, bv, "right")
        pair_face = np.repeat(np.repeat(bad, 3), hi - lo)
        pair_src = source[cf[ranges(lo, hi - lo)]]
        ok = ~_misplaced(mesh.vertices, faces[pair_face], pair_src, tubes)
        fixed, first = np.unique(pair_face[ok], return_index=True)
        source[fixed] = pair_src[ok][first]
        bad = unique(bad)
        bad = bad[~isin(bad, fixed)]
        if not len(bad) or not len(fixed):
            break
    log.debug("union: %d faces given a neighbour's source face, %d left as manifold3d gave them", found, len(bad))
    return replace(mesh, face_source=source)


def _sourced(mesh: Mesh, origin: np.ndarray, where: str) -> Mesh:
    """The mesh with ``face_source`` naming the faces of the tubes given to :func:`union`.

    ``origin[k]`` is the original face of face ``k`` of the tubes that went
    into the boolean (:func:`_prepare` may have left tubes out and inserted
    rings).  Every face id must be a tube face: a temporary cap that survived
    the stitching would be a bug, never a face to pass on.
    """
    src = mesh.face_source
    if src is None or len(src) != len(mesh.faces) or (src < 0).any() or (src >= len(origin)).any():
        raise GeometryError(f"{where}: a face of the result is no piece of a tube face (union bug)")
    return replace(mesh, face_source=origin[src])
