"""Covered tubes: what cannot show (or shows less than a stated bound) leaves the boolean's input.

Dense grammars (issue 34) draw thousands of short tubes nested inside one
another where a branch forks again and again within its own width: a
Barnsley-like fern of L-Py's tutorial holds 19,683 tubes of about three
segments, each shorter than the tube is wide.  Most of them add almost nothing
to the union, and they are what makes its boolean slow (every triangle
handed to manifold costs time, and these overlap many others).

:func:`covered_tubes` finds the tubes each of whose spans lies within a
distance ``d`` of one span of another tube that stays (not always the same
one: the tube lies within ``d`` of the union of its neighbours' spans): then
dropping the tube moves the union's
surface by at most ``d`` (inwards: the union can only lose what stuck out of
its neighbours by at most ``d``).  ``d = cover * width`` of the dropped tube,
``cover`` from :class:`~lsys3d.mesh.union.union.UnionOptions` (0, the default,
leaves this step out).

Why the bound holds
-------------------
A tube is the union of its spans (its caps lie in its end rings' planes), and
each span (two rings and the wall between them) lies in the convex hull of
its two rings' points; the covering set ``C`` is convex (the cylinder on the axis of one span of the other tube,
of the radius of the circle its rings contain).  The distance to a convex
set is convex, so its largest value on the hull is at one of the two rings'
points: testing the points is enough.  ``C`` lies inside the other tube's
span except where the span's rings are tilted against its axis (a joint
that turns): the cylinder's rim then passes the ring's plane by at most
``r tan(tilt)``, which is added to every distance measured.  The test is
made with an upper bound of the distance to ``C`` (the distance to the nearest
point in the same axial half-plane, or on the nearer end disk).

Tubes are decided in their order, each against tubes before it that stay, so
a dropped tube never covers another (the bounds do not add up) and the result
is the same in any process.
"""

from __future__ import annotations

import logging

import numpy as np

from ...compiling import inner, kernel
from ..sweep import Tubes
from .touch import Pieces

log = logging.getLogger("lsys3d")

COVER_PAIRS = 16
"""Before the cover test, up to this many times ``UnionOptions.max_pairs`` pairs may touch (the refusal comes after)."""


def covered_tubes(tubes: Tubes, pcs: Pieces, a: np.ndarray, b: np.ndarray, cover: float) -> np.ndarray:
    """``(t,) bool``: tubes whose every span is within ``cover`` times their width of a span of an earlier kept tube.

    Parameters
    ----------
    tubes : Tubes
    pcs : Pieces
        The tubes' pieces (:func:`~lsys3d.mesh.union.touch.pieces`).
    a, b : (m,) int64
        Pairs of pieces that may touch (:func:`~lsys3d.mesh.union.touch.touching`);
        a tube is tested only against the tubes these pair it with.
    cover : float
        The largest distance a dropped tube may reach out of the one that
        covers it, as a fraction of the dropped tube's width (``0``: a tube
        must lie wholly inside).

    Returns
    -------
    numpy.ndarray
        ``(t,) bool``, True for the tubes to leave out.
    """
    n = len(tubes)
    if not len(a) or n < 2:
        return np.zeros(n, bool)
    ta, tb = pcs.tube[a], pcs.tube[b]
    # (later tube, a piece of an earlier tube): a tube is tested against the spans of the pieces it may touch
    late = np.where(ta > tb, ta, tb)
    piece = np.where(ta > tb, b, a)
    keep = ta != tb
    late, piece = late[keep], piece[keep]
    if not len(late):
        return np.zeros(n, bool)
    m = np.int64(len(pcs))
    key = np.unique(late * m + piece)
    late, piece = key // m, key % m
    first = np.searchsorted(late, np.arange(n + 1))
    ring_offsets = np.concatenate([[0], np.cumsum(tubes.rings)]).astype(np.int64)
    start = ring_offsets[pcs.tube[piece]] + pcs.first[piece]
    stop = ring_offsets[pcs.tube[piece]] + pcs.last[piece]
    inscribed = tubes.ring_radius * np.cos(np.pi / tubes.sides.repeat(tubes.rings))
    dropped = _covered(
        tubes.points,
        tubes.point_offsets,
        tubes.rings,
        tubes.sides,
        ring_offsets,
        tubes.ring_center,
        tubes.ring_tangent,
        inscribed,
        tubes.ring_radius,
        first,
        pcs.tube[piece],
        start,
        stop,
        float(cover),
    )
    log.debug("union: %d of %d tubes within %g of their width of another", int(dropped.sum()), n, cover)
    return dropped


@kernel(nogil=True)
def _covered(
    points,
    point_offsets,
    rings,
    sides,
    ring_offsets,
    center,
    tangent,
    inscribed,
    radius,
    first,
    other,
    start,
    stop,
    cover,
):  # pragma: no cover - compiled
    n = len(point_offsets) - 1
    dropped = np.zeros(n, np.bool_)
    for t in range(n):
        if first[t] == first[t + 1] or rings[t] < 2:
            continue
        width = 0.0
        for k in range(ring_offsets[t], ring_offsets[t + 1]):
            width = max(width, 2.0 * radius[k])
        limit = cover * width
        side = sides[t]
        every = True
        # each span of the tube (its two rings' points) within the limit of one span of a kept earlier tube
        for j in range(rings[t] - 1):
            p0 = point_offsets[t] + j * side
            found = False
            for e in range(first[t], first[t + 1]):
                if dropped[other[e]]:
                    continue
                for k in range(start[e], stop[e]):
                    if _within(points, p0, p0 + 2 * side, center, tangent, inscribed, k, limit):
                        found = True
                        break
                if found:
                    break
            if not found:
                every = False
                break
        dropped[t] = every
    return dropped


@inner(nogil=True)
def _within(points, p0, p1, center, tangent, inscribed, k, limit):  # pragma: no cover - compiled
    """Whether every point ``p0..p1`` is within ``limit`` of the cylinder inscribed in span ``k .. k+1``."""
    ax = center[k + 1, 0] - center[k, 0]
    ay = center[k + 1, 1] - center[k, 1]
    az = center[k + 1, 2] - center[k, 2]
    length = np.sqrt(ax * ax + ay * ay + az * az)
    if length <= 0.0:
        return False
    ax, ay, az = ax / length, ay / length, az / length
    r = min(inscribed[k], inscribed[k + 1])
    # the rim passes a tilted ring's plane by at most r tan(tilt)
    slack = 0.0
    for j in (k, k + 1):
        c = abs(tangent[j, 0] * ax + tangent[j, 1] * ay + tangent[j, 2] * az)
        c = min(c, 1.0)
        if c < 1e-3:
            return False
        slack = max(slack, r * np.sqrt(1.0 - c * c) / c)
    room = limit - slack
    if room < 0.0:
        return False
    for i in range(p0, p1):
        dx = points[i, 0] - center[k, 0]
        dy = points[i, 1] - center[k, 1]
        dz = points[i, 2] - center[k, 2]
        s = dx * ax + dy * ay + dz * az
        rx, ry, rz = dx - s * ax, dy - s * ay, dz - s * az
        out = max(np.sqrt(rx * rx + ry * ry + rz * rz) - r, 0.0)
        if s < 0.0:
            out = np.sqrt(s * s + out * out)
        elif s > length:
            out = np.sqrt((s - length) ** 2 + out * out)
        if out > room:
            return False
    return True
