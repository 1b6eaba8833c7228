"""Edge flip: whether the other diagonal of an edge's two faces is better, and the flip."""

from __future__ import annotations

import numpy as np

from .geometry import _aspect, _edges_distance, _normal
from .halfedge import FEATURE, LOCKED, _apex, _dst, _half_edge, _leaf_inner, _nxt, _org, _prv, _valence


@_leaf_inner
def _flip_ok(he, h, tolerance):
    """Whether flipping the edge of half-edge ``h`` improves its two faces without changing the shape much.

    The surface moves by at most the distance between the old and the new
    diagonal, which must stay under ``tolerance``; the new faces keep the
    side of the old pair, and their worse aspect must be better than the old
    worse one.
    Seam and rim edges are never flipped.
    """
    faces, p = he.faces, he.points
    t = np.int64(he.opp[h])
    f0, f1 = h // 3, t // 3
    if he.face_part[f0] != he.face_part[f1]:
        return False
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _apex(faces, h)
    d = _apex(faces, t)
    flags = he.flags
    if c == d or ((flags[a] & FEATURE) and (flags[b] & FEATURE)):
        return False
    if (flags[a] | flags[b] | flags[c] | flags[d]) & LOCKED:
        return False
    # the shape first, then the walks around the vertices (most edges fail on shape: a long needle's)
    if _edges_distance(p, a, b, c, d) > tolerance:
        return False
    n0x, n0y, n0z = _normal(p, a, b, c)
    n1x, n1y, n1z = _normal(p, b, a, d)
    mx, my, mz = n0x + n1x, n0y + n1y, n0z + n1z
    qx, qy, qz = _normal(p, c, a, d)
    if qx * mx + qy * my + qz * mz <= 0.0:
        return False
    qx, qy, qz = _normal(p, d, b, c)
    if qx * mx + qy * my + qz * mz <= 0.0:
        return False
    old = max(_aspect(p, a, b, c), _aspect(p, b, a, d))
    new = max(_aspect(p, c, a, d), _aspect(p, d, b, c))
    if not new < 0.999 * old:
        return False
    if _valence(he, a, 3) <= 3 or _valence(he, b, 3) <= 3:
        return False
    return _half_edge(he, c, d) < 0


@_leaf_inner
def _flip(he, h):
    """Flip the edge of half-edge ``h`` (faces ``a b c`` and ``b a d`` become ``c a d`` and ``d b c``)."""
    faces, opp, out = he.faces, he.opp, he.out
    t = np.int64(opp[h])
    f0, f1 = h // 3, t // 3
    h1, h2 = _nxt(h), _prv(h)  # b->c, c->a
    t1, t2 = _nxt(t), _prv(t)  # a->d, d->b
    o_h1, o_h2, o_t1, o_t2 = opp[h1], opp[h2], opp[t1], opp[t2]
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _dst(faces, h1)
    d = _dst(faces, t1)
    faces[f0, 0], faces[f0, 1], faces[f0, 2] = c, a, d
    faces[f1, 0], faces[f1, 1], faces[f1, 2] = d, b, c
    e0, e1, e2 = 3 * f0, 3 * f0 + 1, 3 * f0 + 2  # c->a, a->d, d->c
    g0, g1, g2 = 3 * f1, 3 * f1 + 1, 3 * f1 + 2  # d->b, b->c, c->d
    opp[e0], opp[o_h2] = o_h2, e0
    opp[e1], opp[o_t1] = o_t1, e1
    opp[g0], opp[o_t2] = o_t2, g0
    opp[g1], opp[o_h1] = o_h1, g1
    opp[e2], opp[g2] = g2, e2
    out[a] = e1
    out[b] = g1
    out[c] = e0
    out[d] = g0
