"""The geometry the operations test: cross products, normals, aspects, lengths and distances, on coordinates."""

from __future__ import annotations

import math

from ...compiling import inner
from .halfedge import _inline_inner_once, _leaf_inner

_FLAT = 1e30  # the aspect of a triangle without area


@inner(nogil=True)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@inner(nogil=True)
def _norm(x, y, z):
    """The length of vector ``x y z`` (``x * x``, not ``x ** 2``: the same bits, a power fewer for numba to type)."""
    return math.sqrt(x * x + y * y + z * z)


@_leaf_inner
def _normal_xyz(ax, ay, az, bx, by, bz, cx, cy, cz):
    return _cross(bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az)


@inner(nogil=True)
def _before(ax, ay, az, bx, by, bz):
    """Whether point ``a`` comes before ``b`` in lexicographic order (a tie-break that ignores vertex order)."""
    if ax != bx:
        return ax < bx
    if ay != by:
        return ay < by
    return az < bz


@_leaf_inner
def _aspect_xyz(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Aspect (longest edge / (2 sqrt 3 inradius)) of a triangle given by coordinates; 1e30 when flat.

    The same bits whatever the order of the corners: the area's cross product
    is taken at the corner across the longest edge (the most accurate one;
    ties broken by the corners' coordinates), and a cross product with its
    two edges swapped is exactly negated.  A needle's area is mostly rounding
    noise; were it computed at whichever corner came first, a flip and the
    flip back could each look like an improvement, and :func:`clean` cycled
    (757,310 flips on abop-1.24a).
    """
    l0 = _norm(bx - ax, by - ay, bz - az)  # across c
    l1 = _norm(cx - bx, cy - by, cz - bz)  # across a
    l2 = _norm(ax - cx, ay - cy, az - cz)  # across b
    # the corner across the longest edge, as a rotation: (a, b, c), (b, c, a) or (c, a, b)
    base = 0
    if l1 > l0 or (l1 == l0 and _before(ax, ay, az, cx, cy, cz)):
        base = 1
        if l2 > l1 or (l2 == l1 and _before(bx, by, bz, ax, ay, az)):
            base = 2
    elif l2 > l0 or (l2 == l0 and _before(bx, by, bz, cx, cy, cz)):
        base = 2
    if base == 0:
        nx, ny, nz = _normal_xyz(cx, cy, cz, ax, ay, az, bx, by, bz)
    elif base == 1:
        nx, ny, nz = _normal_xyz(ax, ay, az, bx, by, bz, cx, cy, cz)
    else:
        nx, ny, nz = _normal_xyz(bx, by, bz, cx, cy, cz, ax, ay, az)
    area = 0.5 * math.sqrt(nx * nx + ny * ny + nz * nz)
    s = 0.5 * (l0 + l1 + l2)
    if area <= 1e-300 or s <= 0:
        return _FLAT
    return max(l0, max(l1, l2)) * s / (2.0 * math.sqrt(3.0) * area)


@_leaf_inner
def _moved_corners(p, a, b, c, moved, x, y, z):
    """The coordinates of triangle ``a b c``, vertex ``moved`` placed at ``x y z``."""
    ax, ay, az = p[a, 0], p[a, 1], p[a, 2]
    bx, by, bz = p[b, 0], p[b, 1], p[b, 2]
    cx, cy, cz = p[c, 0], p[c, 1], p[c, 2]
    if a == moved:
        ax, ay, az = x, y, z
    if b == moved:
        bx, by, bz = x, y, z
    if c == moved:
        cx, cy, cz = x, y, z
    return ax, ay, az, bx, by, bz, cx, cy, cz


@_leaf_inner
def _aspect(p, a, b, c):
    return _aspect_xyz(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])


@_leaf_inner
def _normal(p, a, b, c):
    return _normal_xyz(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])


@_leaf_inner
def _length(p, u, w):
    return _norm(p[u, 0] - p[w, 0], p[u, 1] - p[w, 1], p[u, 2] - p[w, 2])


@_inline_inner_once
def _edges_distance(p, a, b, c, d):
    """Distance between segments ``a b`` and ``c d``."""
    d1x, d1y, d1z = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    d2x, d2y, d2z = p[d, 0] - p[c, 0], p[d, 1] - p[c, 1], p[d, 2] - p[c, 2]
    rx, ry, rz = p[a, 0] - p[c, 0], p[a, 1] - p[c, 1], p[a, 2] - p[c, 2]
    aa = d1x * d1x + d1y * d1y + d1z * d1z
    ee = d2x * d2x + d2y * d2y + d2z * d2z
    ff = d2x * rx + d2y * ry + d2z * rz
    cc = d1x * rx + d1y * ry + d1z * rz
    bb = d1x * d2x + d1y * d2y + d1z * d2z
    tiny = 1e-300
    denom = aa * ee - bb * bb
    s = 0.0
    if denom > tiny:
        s = min(max((bb * ff - cc * ee) / denom, 0.0), 1.0)
    t = (bb * s + ff) / ee if ee > tiny else 0.0
    if t < 0.0:
        t = 0.0
        s = min(max(-cc / aa, 0.0), 1.0) if aa > tiny else 0.0
    elif t > 1.0:
        t = 1.0
        s = min(max((bb - cc) / aa, 0.0), 1.0) if aa > tiny else 0.0
    x = rx + d1x * s - d2x * t
    y = ry + d1y * s - d2y * t
    z = rz + d1z * s - d2z * t
    return math.sqrt(x * x + y * y + z * z)
