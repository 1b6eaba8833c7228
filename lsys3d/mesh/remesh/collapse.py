"""Edge collapse: the link condition, the geometric check, the collapse itself and where the kept vertex goes."""

from __future__ import annotations

import math

import numpy as np

from .geometry import _aspect, _aspect_xyz, _cross, _length, _moved_corners, _normal, _normal_xyz
from .halfedge import (
    FEATURE,
    LOCKED,
    ORIGINAL,
    PINNED,
    SEAM,
    _apex,
    _dst,
    _inline_inner,
    _inline_inner_once,
    _leaf_inner,
    _nxt,
    _org,
    _prv,
    _ring,
    _valence,
)


@_inline_inner
def _collapse_topology_ok(he, h, buf_a, buf_b):
    """Whether collapsing half-edge ``h`` keeps a 2-manifold: the link condition, and valences of at least three."""
    faces = he.faces
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _apex(faces, h)
    d = _apex(faces, np.int64(he.opp[h]))
    if a == b or c == d or (he.flags[a] | he.flags[b]) & LOCKED or he.flags[a] & PINNED:
        return False
    if _valence(he, c, 3) <= 3 or _valence(he, d, 3) <= 3:
        return False
    na = _ring(he, a, buf_a)
    nb = _ring(he, b, buf_b)
    if na < 0 or nb < 0:
        return False
    for i in range(na):
        va = buf_a[i]
        if va in (c, d):
            continue
        for j in range(nb):
            if buf_b[j] == va:
                return False
    return True


@_inline_inner
def _collapse_geometry_ok(he, h, x, y, z, limit):
    """Whether the faces around half-edge ``h``'s ends, with both at ``x, y, z``, keep their side and shapes.

    Every face keeps within 80 degrees of its ``reference`` normal (the tube
    face it lies on, exact even for a sliver), or turns no farther from it
    than it is already turned, and the worst aspect around stays under
    ``limit`` or improves.
    """
    faces, p = he.faces, he.points
    a = _org(faces, h)
    b = _dst(faces, h)
    t = np.int64(he.opp[h])
    worst_old = max(_aspect(p, a, b, _apex(faces, h)), _aspect(p, b, a, _apex(faces, t)))
    worst_new = 0.0
    for end in range(2):
        v = a if end == 0 else b
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            if f != h // 3 and f != t // 3:
                f0, f1, f2 = faces[f, 0], faces[f, 1], faces[f, 2]
                corners = _moved_corners(p, f0, f1, f2, v, x, y, z)
                qx, qy, qz = _normal_xyz(*corners)
                q = math.sqrt(qx * qx + qy * qy + qz * qz)
                r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
                turned = qx * r0 + qy * r1 + qz * r2
                if turned <= 0.17 * q:
                    # turned away: allowed only for a face that was turned as far already (a fold left by the
                    # boolean must not block every collapse around it), and not further
                    ox, oy, oz = _normal(p, f0, f1, f2)
                    o = math.sqrt(ox * ox + oy * oy + oz * oz)
                    was = ox * r0 + oy * r1 + oz * r2
                    if q <= 0.0 or o <= 0.0 or was > 0.17 * o or turned / q < was / o:
                        return False
                worst_old = max(worst_old, _aspect(p, f0, f1, f2))
                worst_new = max(worst_new, _aspect_xyz(*corners))
            g = he.opp[_prv(g)]
            if g == h0:
                break
    return worst_new <= limit or worst_new < worst_old


@_leaf_inner
def _collapse_ok(he, h, x, y, z, limit, buf_a, buf_b, geometry=True):
    """Whether collapsing half-edge ``h`` (its origin into its end, placed at ``x, y, z``) is allowed.

    :func:`_collapse_topology_ok`, and unless ``geometry`` is off (for ends so
    close that nothing can move) :func:`_collapse_geometry_ok`.
    """
    if not _collapse_topology_ok(he, h, buf_a, buf_b):
        return False
    return not geometry or _collapse_geometry_ok(he, h, x, y, z, limit)


@_leaf_inner
def _collapse(he, h, x, y, z):
    """Collapse half-edge ``h``: its origin ``a`` merges into its end ``b``, placed at ``x, y, z``.

    The two faces of the edge die; every other face of ``a`` takes ``b``.
    Call only after :func:`_collapse_ok`.
    """
    faces, opp, out = he.faces, he.opp, he.out
    a = _org(faces, h)
    b = _dst(faces, h)
    t = np.int64(opp[h])
    f0, f1 = h // 3, t // 3
    h1, h2 = _nxt(h), _prv(h)  # b->c, c->a
    t1, t2 = _nxt(t), _prv(t)  # a->d, d->b
    o_h1, o_h2, o_t1, o_t2 = opp[h1], opp[h2], opp[t1], opp[t2]
    c = _dst(faces, h1)
    d = _dst(faces, t1)
    g0 = out[a]
    g = g0
    while True:  # every face around a takes b
        faces[g // 3, g % 3] = b
        g = opp[_prv(g)]
        if g == g0:
            break
    # the outer edges of the dead faces now face each other
    opp[o_h1] = o_h2
    opp[o_h2] = o_h1
    opp[o_t1] = o_t2
    opp[o_t2] = o_t1
    out[b] = o_t2
    out[c] = o_h1
    out[d] = o_t1
    he.face_alive[f0] = False
    he.face_alive[f1] = False
    for k in range(3):
        opp[3 * f0 + k] = -1
        opp[3 * f1 + k] = -1
    he.vertex_alive[a] = False
    out[a] = -1
    he.points[b, 0], he.points[b, 1], he.points[b, 2] = x, y, z
    he.flags[b] |= he.flags[a] & (SEAM | FEATURE)
    he.scale[b] = min(he.scale[a], he.scale[b])


@_inline_inner_once
def _volume_neutral(he, h, x, y, z):
    """Where to put the merged vertex of collapsing ``h``, near ``x, y, z``, so the enclosed volume stays.

    The volume is linear in the merged vertex's position (six times it is the
    sum of ``det(x, p, q)`` over the faces ``x p q`` around it), so the
    correction is one step along its gradient, at most the edge's length.
    Without it, collapses on a convex tube (all of them) would shrink it.
    """
    faces, p = he.faces, he.points
    a = _org(faces, h)
    b = _dst(faces, h)
    t = he.opp[h]
    before = 0.0
    after = 0.0
    gx, gy, gz = 0.0, 0.0, 0.0
    for end in range(2):
        v = a if end == 0 else b
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            k = g % 3
            u, w = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            ux, uy, uz = p[u, 0], p[u, 1], p[u, 2]
            wx, wy, wz = p[w, 0], p[w, 1], p[w, 2]
            cx, cy, cz = _cross(ux, uy, uz, wx, wy, wz)
            d = p[v, 0] * cx + p[v, 1] * cy + p[v, 2] * cz
            if f == h // 3 or f == t // 3:
                if end == 0:  # the two dying faces count once
                    before += d
            else:
                before += d
                after += x * cx + y * cy + z * cz
                gx += cx
                gy += cy
                gz += cz
            g = he.opp[_prv(g)]
            if g == h0:
                break
    g2 = gx * gx + gy * gy + gz * gz
    if g2 <= 0.0:
        return x, y, z
    step = (before - after) / g2
    sx, sy, sz = step * gx, step * gy, step * gz
    reach = _length(p, a, b)
    size = math.sqrt(sx * sx + sy * sy + sz * sz)
    if size > reach:
        sx, sy, sz = sx * reach / size, sy * reach / size, sz * reach / size
    return x + sx, y + sy, z + sz


@_leaf_inner
def _rank(flags, v):
    """Which end of a collapse keeps its place: a rim vertex, then a tube vertex, then a seam vertex."""
    f = flags[v]
    if f & FEATURE:
        return 3
    if f & ORIGINAL:
        return 2
    if f & SEAM:
        return 1
    return 0


@_leaf_inner
def _try_collapse(he, h, limit, short, buf_a, buf_b):
    """Collapse the edge of half-edge ``h`` the best way that is allowed; the kept vertex, or -1.

    The end of higher :func:`_rank` keeps its place (either, for two of equal
    rank), moved off it only as far as keeps the volume; two rim vertices
    merge only along their rim.  An edge of almost no length merges whatever
    the shapes around (they hardly move); a vertex of three neighbours across
    it, which would be left with two, first merges into its nearest
    neighbour when that is nearer than ``short`` scales.
    """
    faces = he.faces
    a = _org(faces, h)
    b = _dst(faces, h)
    if _rank(he.flags, a) == 3 and _rank(he.flags, b) == 3 and he.face_flat[h // 3] == he.face_flat[he.opp[h] // 3]:
        return -1  # two rim vertices, but not along the rim
    tiny = _length(he.points, a, b) < 1e-3 * min(he.scale[a], he.scale[b])
    # a vertex of three neighbours across the edge would be left with two: merge it away first
    for apex in (_apex(faces, h), _apex(faces, np.int64(he.opp[h]))):
        if _valence(he, apex, 3) == 3 and not (he.flags[apex] & LOCKED):
            best, best_length = -1, 1e300
            g0 = np.int64(he.out[apex])
            g = g0
            while True:
                n = _dst(faces, g)
                length = _length(he.points, apex, n)
                if _rank(he.flags, apex) <= _rank(he.flags, n) and length < best_length:
                    best, best_length = g, length
                g = he.opp[_prv(g)]
                if g == g0:
                    break
            if best >= 0 and best_length < short * he.scale[apex]:
                w = _dst(faces, best)
                x, y, z = he.points[w, 0], he.points[w, 1], he.points[w, 2]
                if _collapse_ok(he, best, x, y, z, limit, buf_a, buf_b):
                    _collapse(he, best, x, y, z)
                    return w
    for attempt in range(2):
        g = h if attempt == 0 else he.opp[h]
        u = _org(faces, g)  # goes
        w = _dst(faces, g)  # stays
        if _rank(he.flags, u) > _rank(he.flags, w):
            continue
        if not _collapse_topology_ok(he, g, buf_a, buf_b):
            continue
        x, y, z = he.points[w, 0], he.points[w, 1], he.points[w, 2]
        if not tiny and not (he.flags[w] & FEATURE):
            x, y, z = _volume_neutral(he, g, x, y, z)
        if _collapse_geometry_ok(he, g, x, y, z, 1e300 if tiny else limit):
            _collapse(he, g, x, y, z)
            return w
    return -1
