"""Which parts of which tubes may touch: the union's broad phase, its culling and its refinement.

The union (:mod:`lsys3d.mesh.union.union`) sends through the boolean only what may touch
another tube.  This module finds that, in arrays, without building anything:

*Pieces.*  A tube is cut into pieces along its rings: a piece is one span
(the wall between two neighbouring rings) or, where spans are much shorter
than the tube is wide (a constant-width fern drawn in tiny steps), a run of
consecutive spans about one diameter long.  Each piece is covered by a capsule:
the segment joining the centres of its first and last ring, and as radius the
farthest of its ring points from that segment (distance to a segment is convex,
so the whole piece lies inside).  Grouping tiny spans keeps the number of
touching pairs near the number of real contacts instead of its square.

*Touching pairs* (:func:`touching`).  Piece boxes are hashed into a uniform grid;
the candidate pairs of each cell are tested one at a time in a compiled loop (no
arrays of candidates), a pair is kept only in the cell holding the low corner of
the two boxes' overlap (so it is found once without a global ``unique``), and
confirmed by the capsules' segment-segment distance.  The count is checked against ``max_pairs`` as the
pairs are found, so a pathological crowd (a thousand branches from one point) is
refused before its pairs fill the memory.

*Culling* (:func:`duplicate_tubes`, :func:`buried_tubes`).  A tube equal to an
earlier one, or wholly inside a straight span of another tube (a short thick
twig buried in its parent), adds nothing to the union and stays out of it.

*Refinement* (:func:`free_stretches`).  A long straight span that another tube
touches only near one place (a twig on a trunk whose rings were merged away) is
split by new rings around the touched stretch, so that only that stretch goes
through the boolean; on a straight span the new rings lie exactly on the wall
(:meth:`lsys3d.mesh.sweep.Tubes.insert_rings`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ...arrays import dot as _dot
from ...arrays import dot3, unique
from ...arrays import local_index as _local
from ...arrays import offsets as _offsets
from ...compiling import inner, kernel
from ...errors import LimitError
from ..sweep import Tubes

__all__ = [
    "DEFAULT_MAX_PAIRS",
    "Pieces",
    "buried_tubes",
    "duplicate_tubes",
    "free_stretches",
    "pieces",
    "straight_spans",
    "too_many_pairs",
    "touching",
]

log = logging.getLogger("lsys3d")

DEFAULT_MAX_PAIRS = 400_000
"""Most pairs of tube pieces that may touch before the union refuses (about 0.1 ms of boolean work each)."""

_SECONDS_PER_PAIR = 1e-4  # boolean work per touching pair in a crowd (500 parallel tubes: 124,750 pairs, 12 s CPU)


@dataclass(frozen=True)
class Pieces:
    """Pieces of tubes, each a run of consecutive spans, tube after tube.

    Attributes
    ----------
    tube : (m,) int64
        The tube of each piece.
    first, last : (m,) int64
        The piece covers the tube's rings ``first..last`` (spans ``first..last-1``).
    p, q : (m, 3) float64
        Centres of its first and last ring: the axis of its capsule.
    radius : (m,) float64
        Capsule radius: the farthest ring point of the piece from the segment ``p q``.
    lo, hi : (m, 3) float64
        Box of the piece's ring points.
    span_piece : (s,) int64
        The piece of every span (spans numbered tube after tube).
    """

    tube: np.ndarray
    first: np.ndarray
    last: np.ndarray
    p: np.ndarray
    q: np.ndarray
    radius: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    span_piece: np.ndarray

    def __len__(self) -> int:
        return len(self.tube)


@inner(nogil=True, inline="always")
def _lower(have, x):  # pragma: no cover - compiled
    """A step of ``np.minimum.reduce``: NaN kept, ``x`` on a tie (so -0.0 and 0.0 come out as numpy's do)."""
    return have if (have < x or np.isnan(have)) else x


@inner(nogil=True, inline="always")
def _higher(have, x):  # pragma: no cover - compiled
    """A step of ``np.maximum.reduce``: NaN kept, ``x`` on a tie."""
    return have if (have > x or np.isnan(have)) else x


@kernel(nogil=True)
def _pairwise_sum(points, start, n, j):  # pragma: no cover - compiled
    """``points[start:start + n, j]`` summed as numpy's pairwise summation does (its ``add`` reductions):
    one by one below 8 values, 8 running sums up to 128, halves (at a multiple of 8) above."""
    if n < 8:
        total = -0.0
        for i in range(start, start + n):
            total += points[i, j]
        return total
    if n > 128:
        half = n // 2
        half -= half % 8
        return _pairwise_sum(points, start, half, j) + _pairwise_sum(points, start + half, n - half, j)
    r = np.empty(8)
    for k in range(8):
        r[k] = points[start + k, j]
    i = 8
    while i < n - n % 8:
        for k in range(8):
            r[k] += points[start + i + k, j]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        total += points[start + i, j]
        i += 1
    return total


@kernel(nogil=True)
def _rings(points, point_offsets, rings, sides):  # pragma: no cover - compiled
    """Every ring, tube after tube: its first point, centre, radius (farthest point from the centre) and box.

    Read from the points in place (a tube's ring points come ring after ring, its two cap centres last), with
    numpy's arithmetic in its order (``np.add.reduceat`` adds to the first point the pairwise sum of the others,
    :func:`_pairwise_sum`; the norm adds x, y, then z), so the numbers are the bits of the vectorised version.
    """
    nr = 0
    for t in range(len(rings)):
        nr += rings[t]
    first = np.empty(nr, np.int64)
    centre = np.empty((nr, 3))
    radius = np.empty(nr)
    lo = np.empty((nr, 3))
    hi = np.empty((nr, 3))
    r = 0
    for t in range(len(rings)):
        s = sides[t]
        for k in range(rings[t]):
            f = point_offsets[t] + k * s
            first[r] = f
            for j in range(3):
                low, high = points[f, j], points[f, j]
                for i in range(1, s):
                    low, high = _lower(low, points[f + i, j]), _higher(high, points[f + i, j])
                centre[r, j] = (points[f, j] + _pairwise_sum(points, f + 1, s - 1, j)) / s
                lo[r, j], hi[r, j] = low, high
            far = 0.0
            for i in range(s):
                x = points[f + i, 0] - centre[r, 0]
                y = points[f + i, 1] - centre[r, 1]
                z = points[f + i, 2] - centre[r, 2]
                d = np.sqrt(x * x + y * y + z * z)
                far = d if i == 0 else _higher(far, d)
            radius[r] = far
            r += 1
    return first, centre, radius, lo, hi


@kernel(nogil=True)
def _piece_extent(points, ring_first, ring_sides, ring_lo, ring_hi, g0, g1, p, q):  # pragma: no cover - compiled
    """Each piece's capsule radius (the farthest of the points of its rings ``g0..g1`` from the segment
    ``p q``) and box, in one pass over the points in place; the arithmetic is numpy's, in its order
    (``np.einsum``'s dot products sum x, z then y; ``np.linalg.norm`` x, y, z), so they are the same bits."""
    n = len(g0)
    radius = np.empty(n)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    radius[:] = 0.0
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    for k in range(n):
        p0, p1, p2 = p[k, 0], p[k, 1], p[k, 2]
        d0, d1, d2 = q[k, 0] - p0, q[k, 1] - p1, q[k, 2] - p2
        dd = dot3(d0, d1, d2, d0, d1, d2)
        if dd < 1e-300:  # np.maximum(dd, 1e-300), NaN kept
            dd = 1e-300
        for j in range(3):
            lo[k, j], hi[k, j] = ring_lo[g0[k], j], ring_hi[g0[k], j]
        for g in range(g0[k], g1[k] + 1):
            if g > g0[k]:
                for j in range(3):
                    lo[k, j], hi[k, j] = _lower(lo[k, j], ring_lo[g, j]), _higher(hi[k, j], ring_hi[g, j])
            for i in range(ring_first[g], ring_first[g] + ring_sides[g]):
                r0, r1, r2 = points[i, 0] - p0, points[i, 1] - p1, points[i, 2] - p2
                t = dot3(r0, r1, r2, d0, d1, d2) / dd
                if t < 0.0:  # np.clip(t, 0, 1), NaN kept
                    t = 0.0
                elif t > 1.0:
                    t = 1.0
                e0, e1, e2 = r0 - t * d0, r1 - t * d1, r2 - t * d2
                off = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
                if off > radius[k] or np.isnan(off):  # np.maximum.at, NaN kept
                    radius[k] = off
    return radius, lo, hi


def pieces(tubes: Tubes, chunk: float = 2.0) -> Pieces:
    """Cut every tube into pieces: single spans, or runs of short spans about ``chunk`` ring radii long.

    A span at least ``chunk`` times its tube's largest ring radius long is a
    piece of its own; shorter spans are grouped by the distance along the tube
    (ring centre to ring centre) in bins of that length.
    """
    rings, sides = tubes.rings, tubes.sides
    nr = int(rings.sum())
    ring_first, centre, ring_radius, ring_lo, ring_hi = _rings(tubes.points, tubes.point_offsets, rings, sides)
    ring_tube = np.repeat(np.arange(len(tubes)), rings)
    ring_local = _local(rings)
    ring_start = _offsets(rings)[:-1]

    # spans: ring k to k + 1 of the same tube
    a = np.flatnonzero(ring_local < rings[ring_tube] - 1)
    span_tube = ring_tube[a]
    span_len = np.linalg.norm(centre[a + 1] - centre[a], axis=1)
    tube_radius = np.maximum.reduceat(ring_radius, ring_start) if nr else np.zeros(0)
    target = np.maximum(chunk * tube_radius[span_tube], 1e-300)
    # distance along the tube at each span's start, in units of the target length
    spans_per_tube = rings - 1
    cum = np.cumsum(span_len)
    start = cum - span_len
    start -= np.repeat(start[_offsets(spans_per_tube)[:-1]] if len(a) else np.zeros(0), spans_per_tube)
    bin_ = np.floor(start / target).astype(np.int64)
    new = np.ones(len(a), bool)
    new[1:] = (span_tube[1:] != span_tube[:-1]) | (bin_[1:] != bin_[:-1])
    new |= span_len >= target
    after_long = np.zeros(len(a), bool)
    after_long[1:] = span_len[:-1] >= target[:-1]
    new |= after_long
    span_piece = np.cumsum(new) - 1
    head = np.flatnonzero(new)
    tail = np.append(head[1:], len(a)) - 1
    tube = span_tube[head]
    first = ring_local[a[head]]
    last = ring_local[a[tail]] + 1
    g0 = a[head]  # global first ring of each piece
    g1 = a[tail] + 1  # global last ring
    p, q = centre[g0], centre[g1]
    radius, lo, hi = _piece_extent(tubes.points, ring_first, np.repeat(sides, rings), ring_lo, ring_hi, g0, g1, p, q)
    return Pieces(tube, first, last, p, q, radius, lo, hi, span_piece)


def segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Distance between segments ``p1 q1`` and ``p2 q2`` (rows)."""
    p1, q1, p2, q2 = (np.ascontiguousarray(x, np.float64).reshape(-1, 3) for x in (p1, q1, p2, q2))
    return _segment_distances(p1, q1, p2, q2)


@kernel(nogil=True)
def _segment_distances(p1, q1, p2, q2):  # pragma: no cover - compiled
    out = np.empty(len(p1))
    for i in range(len(p1)):
        out[i] = _segment_gap(p1[i], q1[i], p2[i], q2[i])
    return out


@inner(nogil=True, inline="always")
def _clip01(x):  # pragma: no cover - compiled
    """``np.clip(x, 0, 1)``, NaN kept."""
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@kernel(nogil=True, inline="always")
def _at_least(x, floor):  # pragma: no cover - compiled
    """``np.maximum(x, floor)``, NaN kept."""
    return x if (x >= floor or np.isnan(x)) else floor


@inner(nogil=True)
def _segment_gap(p1, q1, p2, q2):  # pragma: no cover - compiled
    """Distance between the segments ``p1 q1`` and ``p2 q2`` (3,): the closest points' parameters clamped to the
    segments, as in Ericson's *Real-Time Collision Detection* 5.1.9, with numpy's rounding (dot products as
    :func:`~lsys3d.arrays.dot3`, the norm summing x, y, then z), so the rows of a vectorised version agree."""
    d10, d11, d12 = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d20, d21, d22 = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    r0, r1, r2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = dot3(d10, d11, d12, d10, d11, d12)
    e = dot3(d20, d21, d22, d20, d21, d22)
    f = dot3(d20, d21, d22, r0, r1, r2)
    c = dot3(d10, d11, d12, r0, r1, r2)
    b = dot3(d10, d11, d12, d20, d21, d22)
    tiny = 1e-300
    denom = a * e - b * b
    s = _clip01((b * f - c * e) / _at_least(denom, tiny)) if denom > tiny else 0.0
    t = (b * s + f) / _at_least(e, tiny) if e > tiny else 0.0
    if t < 0:
        s = _clip01(-c / _at_least(a, tiny))
    elif t > 1:
        s = _clip01((b - c) / _at_least(a, tiny))
    t = _clip01(t)
    x = p1[0] + d10 * s - p2[0] - d20 * t
    y = p1[1] + d11 * s - p2[1] - d21 * t
    z = p1[2] + d12 * s - p2[2] - d22 * t
    return np.sqrt(x * x + y * y + z * z)


def touching(pcs: Pieces, margin: float = 0.01, max_pairs: int = DEFAULT_MAX_PAIRS) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of pieces of different tubes that may touch: ``a, b (k,) int64``, ``a < b``, sorted.

    Broad phase: piece boxes (padded by ``margin``) hashed into a grid;
    narrow phase: their capsules (radii padded by ``margin``) intersect.
    Listed pairs may touch; pairs that are not listed do not.

    Raises
    ------
    LimitError
        More than ``max_pairs`` pairs: the union would take minutes (about
        0.1 ms of boolean work per pair, measured) and gigabytes.  Raised as
        soon as the count passes the limit, before the pairs are all stored.
    """
    m = len(pcs)
    none = np.zeros(0, np.int64)
    if m < 2 or len(unique(pcs.tube)) < 2:
        return none, none
    lo, hi, owner = pcs.lo, pcs.hi, pcs.tube
    scale = float(np.abs(np.concatenate([lo, hi])).max()) + 1.0
    pad = margin * (hi - lo).max(axis=1, keepdims=True) + 1e-9 * scale
    lo, hi = lo - pad, hi + pad
    size = (hi - lo).max(axis=1)
    cell = max(float(np.median(size)), 1e-12)
    origin = lo.min(axis=0)
    for _ in range(60):  # grow the cells until the number of box-cell entries is modest
        c0 = np.floor((lo - origin) / cell).astype(np.int64)
        c1 = np.floor((hi - origin) / cell).astype(np.int64)
        ext = c1 - c0 + 1
        count = ext.prod(axis=1)
        if count.sum() <= 8 * m + 1000:
            break
        cell *= 1.5
    dims = c1.max(axis=0) + 1
    box = np.repeat(np.arange(m), count)
    k = _local(count)
    ex = ext[box]
    ix = c0[box, 0] + k % ex[:, 0]
    iy = c0[box, 1] + (k // ex[:, 0]) % ex[:, 1]
    iz = c0[box, 2] + k // (ex[:, 0] * ex[:, 1])
    del k, ex
    key = (iz * dims[1] + iy) * dims[0] + ix
    srt = np.argsort(key, kind="stable")
    key, box = key[srt], box[srt]
    del srt, ix, iy, iz
    args = (key, box, owner, lo, hi, origin, cell, dims, pcs.radius, pcs.p, pcs.q, margin, 1e-9 * scale, max_pairs)
    a, b, over = _cell_pairs(*args, 0, len(key))
    if over:
        raise too_many_pairs(max_pairs)
    order = np.lexsort((b, a))
    return a[order], b[order]


def too_many_pairs(max_pairs: int) -> LimitError:
    """The error :func:`touching` raises when more than ``max_pairs`` pairs of pieces may touch."""
    return LimitError(
        f"union: more than {max_pairs:,} pairs of tube pieces may touch, a crowd of branches (measured: "
        f"about 0.1 ms of boolean work a pair, so over {max_pairs * _SECONDS_PER_PAIR:,.0f} s); use fewer, "
        "thinner or more spread-out branches, or raise the limit (--max-union-pairs N, max_union_pairs=N)"
    )


@kernel(nogil=True)
def _cell_pairs(
    key, box, owner, lo, hi, origin, cell, dims, radius, p, q, margin, reach_pad, max_pairs, first, stop
):  # pragma: no cover - compiled
    """The narrow phase of :func:`touching` over the grid's cells, a pair at a time without temporaries.

    ``key, box`` are the box-cell entries sorted by cell; the cells that begin
    at entries ``first..stop-1`` are searched, whole.  A pair of boxes of
    different tubes is tested in the cell of the low corner of the boxes'
    overlap only (so once), and kept when the capsules are within reach.
    Returns ``a, b`` (``a < b``, in the order found) and whether more than
    ``max_pairs`` were found (the search stops there).
    """
    cap = 1024
    out_a = np.empty(cap, np.int64)
    out_b = np.empty(cap, np.int64)
    found = 0
    n = len(key)
    start = first
    while 0 < start < n and key[start] == key[start - 1]:  # a cell begun before ``first`` is not ours
        start += 1
    while start < stop:
        end = start + 1
        while end < n and key[end] == key[start]:
            end += 1
        here = key[start]
        for i in range(start, end):
            u = box[i]
            for j in range(i + 1, end):
                v = box[j]
                if owner[u] == owner[v]:
                    continue
                if not (
                    lo[u, 0] <= hi[v, 0]
                    and lo[u, 1] <= hi[v, 1]
                    and lo[u, 2] <= hi[v, 2]
                    and lo[v, 0] <= hi[u, 0]
                    and lo[v, 1] <= hi[u, 1]
                    and lo[v, 2] <= hi[u, 2]
                ):
                    continue
                c0 = np.int64(np.floor((max(lo[u, 0], lo[v, 0]) - origin[0]) / cell))
                c1 = np.int64(np.floor((max(lo[u, 1], lo[v, 1]) - origin[1]) / cell))
                c2 = np.int64(np.floor((max(lo[u, 2], lo[v, 2]) - origin[2]) / cell))
                if (c2 * dims[1] + c1) * dims[0] + c0 != here:
                    continue
                reach = (radius[u] + radius[v]) * (1.0 + margin) + reach_pad
                if not _segment_gap(p[u], q[u], p[v], q[v]) <= reach:
                    continue
                if found == max_pairs:
                    return out_a[:found], out_b[:found], True
                if found == cap:
                    cap *= 2
                    grown_a, grown_b = np.empty(cap, np.int64), np.empty(cap, np.int64)
                    for k in range(found):  # (not a slice copy: numba's check of its shapes compiles for a second)
                        grown_a[k], grown_b[k] = out_a[k], out_b[k]
                    out_a, out_b = grown_a, grown_b
                out_a[found], out_b[found] = min(u, v), max(u, v)
                found += 1
        start = end
    return out_a[:found], out_b[:found], False


def duplicate_tubes(tubes: Tubes) -> np.ndarray:
    """``(t,) bool``: tubes whose points equal an earlier tube's, bit for bit (coincident branches)."""
    dup = np.zeros(len(tubes), bool)
    npts = np.diff(tubes.point_offsets)
    for count in unique(npts).tolist():
        which = np.flatnonzero(npts == count)
        if len(which) < 2:
            continue
        idx = tubes.point_offsets[which][:, None] + np.arange(count)
        rows = np.ascontiguousarray(tubes.points[idx].reshape(len(which), -1))
        rows = np.concatenate([rows, tubes.sides[which, None].astype(np.float64)], axis=1)
        _, first = np.unique(rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))), return_index=True)
        keep = np.zeros(len(which), bool)
        keep[first] = True
        dup[which[~keep]] = True
    return dup


def straight_spans(tubes: Tubes, tube: np.ndarray, ring: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """``(k,) bool``: whether the span from ring ``ring[i]`` to the next of tube ``tube[i]`` is a straight frustum.

    Straight: both rings lie in planes perpendicular to the line through their
    centres, and the second ring is the first one scaled about its centre and
    moved along that line (within ``rtol`` of the span's size).  Its wall quads
    are then planar trapezoids: a ring inserted anywhere along it lies exactly on
    the wall, and its cross-sections are scaled copies of the rings.
    """
    tube, ring = np.asarray(tube, np.int64), np.asarray(ring, np.int64)
    if not len(tube):
        return np.zeros(0, bool)
    s = tubes.sides[tube]
    out = np.zeros(len(tube), bool)
    for side in unique(s).tolist():
        sel = np.flatnonzero(s == side)
        base = tubes.point_offsets[tube[sel]] + ring[sel] * side
        A = tubes.points[base[:, None] + np.arange(side)]
        B = tubes.points[(base + side)[:, None] + np.arange(side)]
        ca, cb = A.mean(axis=1), B.mean(axis=1)
        axis = cb - ca
        length = np.linalg.norm(axis, axis=1)
        u = axis / np.maximum(length, 1e-300)[:, None]
        ra, rb = A - ca[:, None], B - cb[:, None]
        na = np.sqrt((ra**2).sum(axis=(1, 2)) / side)
        nb = np.sqrt((rb**2).sum(axis=(1, 2)) / side)
        size = length + na + nb
        tol = rtol * size[:, None]
        flat = (np.abs(np.einsum("ijk,ik->ij", ra, u)) <= tol).all(axis=1)
        flat &= (np.abs(np.einsum("ijk,ik->ij", rb, u)) <= tol).all(axis=1)
        ratio = nb / np.maximum(na, 1e-300)
        similar = (np.linalg.norm(rb - ratio[:, None, None] * ra, axis=2) <= tol).all(axis=1)
        out[sel] = flat & similar & (length > 0) & (na > 0)
    return out


def _inscribed(tubes: Tubes, tube: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Distance from each ring's centre to its nearest wall edge (the radius of the circle the ring contains)."""
    out = np.empty(len(tube))
    s = tubes.sides[tube]
    for side in unique(s).tolist():
        sel = np.flatnonzero(s == side)
        base = tubes.point_offsets[tube[sel]] + ring[sel] * side
        A = tubes.points[base[:, None] + np.arange(side)]
        B = np.roll(A, -1, axis=1)
        c = A.mean(axis=1)[:, None]
        e = B - A
        t = np.clip(((c - A) * e).sum(axis=2) / np.maximum((e * e).sum(axis=2), 1e-300), 0.0, 1.0)
        out[sel] = np.linalg.norm(A + t[..., None] * e - c, axis=2).min(axis=1)
    return out


def buried_tubes(tubes: Tubes, pcs: Pieces, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(t,) bool``: tubes wholly inside a straight span of another tube they touch.

    Tested on the pairs of touching pieces: every point of the tube must lie
    strictly inside the frustum inscribed in the other tube's straight span
    (its cross-sections are the circles its rings contain), which lies inside
    that span.  A tube so buried adds nothing to the union.  Two tubes cannot
    both be buried in each other (the test is strict).
    """
    buried = np.zeros(len(tubes), bool)
    if not len(a):
        return buried
    inner = np.concatenate([a, b])
    outer = np.concatenate([b, a])
    # only single-span outer pieces, whose box holds the inner tube's box
    single = pcs.last[outer] - pcs.first[outer] == 1
    inner_tube = pcs.tube[inner]
    tb = tubes.bounds()
    fits = single & (tb[inner_tube, 0] >= pcs.lo[outer]).all(axis=1) & (tb[inner_tube, 1] <= pcs.hi[outer]).all(axis=1)
    inner_tube, outer = inner_tube[fits], outer[fits]
    if not len(outer):
        return buried
    ok = straight_spans(tubes, pcs.tube[outer], pcs.first[outer])
    inner_tube, outer = inner_tube[ok], outer[ok]
    if not len(outer):
        return buried
    ot, ring = pcs.tube[outer], pcs.first[outer]
    r0, r1 = _inscribed(tubes, ot, ring), _inscribed(tubes, ot, ring + 1)
    c0, c1 = pcs.p[outer], pcs.q[outer]
    axis = c1 - c0
    length = np.linalg.norm(axis, axis=1)
    u = axis / length[:, None]
    npts = np.diff(tubes.point_offsets)[inner_tube]
    pair = np.repeat(np.arange(len(outer)), npts)
    x = tubes.points[np.repeat(tubes.point_offsets[inner_tube], npts) + _local(npts)]
    s = _dot(x - c0[pair], u[pair])
    radial = np.linalg.norm(x - c0[pair] - s[:, None] * u[pair], axis=1)
    slack = 1e-7 * (length + r0)[pair]
    f = s / length[pair]
    inside = (s > slack) & (s < length[pair] - slack) & (radial < r0[pair] + (r1 - r0)[pair] * f - slack)
    whole = np.minimum.reduceat(inside, _offsets(npts)[:-1])
    buried[inner_tube[whole]] = True
    return buried


def free_stretches(
    tubes: Tubes, pcs: Pieces, a: np.ndarray, b: np.ndarray, margin: float = 0.01, min_gap: float = 64.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """New rings that cut long straight spans into touched and untouched stretches.

    For every single-span piece that is straight and touches others, each
    touching piece ``j`` can reach only the stretch of its axis between the
    projections of ``j``'s capsule axis, widened by ``j``'s padded radius (a
    point of the span projects onto the axis at its own cross-section, and the
    projection moves no point farther).  Where the union of those stretches
    leaves an untouched gap at least ``min_gap`` radii long, a ring goes at each
    end of the gap that is not an end of the span.  Shorter gaps are left
    alone: two new rings add ``4 sides`` triangles to the result, and what
    slows manifold down is long slender walls in the boolean (their triangles'
    boxes overlap everything around), not short ones (measured: 32 diameters
    leaves every bundled preset as it was and takes the 3D plant benchmark's
    union from 8.4 to 4.8 s).

    Returns
    -------
    tube, ring, t : (k,) arrays
        For :meth:`lsys3d.mesh.sweep.Tubes.insert_rings`: a ring between ``ring`` and
        ``ring + 1`` of ``tube`` at fraction ``t``.
    """
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if not len(a):
        return empty
    me = np.concatenate([a, b])
    other = np.concatenate([b, a])
    length = np.linalg.norm(pcs.q - pcs.p, axis=1)
    cand = (pcs.last[me] - pcs.first[me] == 1) & (length[me] > min_gap * pcs.radius[me])
    me, other = me[cand], other[cand]
    if not len(me):
        return empty
    span_ok = np.zeros(len(pcs), bool)
    uniq = unique(me)
    span_ok[uniq] = straight_spans(tubes, pcs.tube[uniq], pcs.first[uniq])
    keep = span_ok[me]
    me, other = me[keep], other[keep]
    if not len(me):
        return empty
    L = length[me]
    u = (pcs.q[me] - pcs.p[me]) / L[:, None]
    grow = pcs.radius[other] * (1.0 + margin)
    # only the part of the other axis within reach of this axis' line matters: |w0 + f w1| <= reach, f in [0, 1]
    reach = pcs.radius[me] * (1.0 + margin) + grow
    r0 = pcs.p[other] - pcs.p[me]
    d = pcs.q[other] - pcs.p[other]
    w0 = r0 - _dot(r0, u)[:, None] * u
    w1 = d - _dot(d, u)[:, None] * u
    qa, qb, qc = _dot(w1, w1), 2.0 * _dot(w0, w1), _dot(w0, w0) - reach**2
    disc = qb * qb - 4.0 * qa * qc
    flat = qa <= 1e-300  # parallel to this axis: all of it or none
    root = np.sqrt(np.maximum(disc, 0.0))
    f0 = np.where(flat, 0.0, (-qb - root) / np.where(flat, 1.0, 2.0 * qa))
    f1 = np.where(flat, 1.0, (-qb + root) / np.where(flat, 1.0, 2.0 * qa))
    f0, f1 = np.clip(f0, 0.0, 1.0), np.clip(f1, 0.0, 1.0)
    near = np.where(flat, qc <= 0, (disc >= 0) & (f0 <= f1))
    # the pair was found by the capsule test; keep the whole axis if rounding says otherwise
    f0, f1 = np.where(near, f0, 0.0), np.where(near, f1, 1.0)
    s0 = _dot(r0 + f0[:, None] * d, u)
    s1 = _dot(r0 + f1[:, None] * d, u)
    # widened by this piece's own radius too (the capsule of the untouched stretch ends in a half ball), and a
    # little more than the touch test's own padding, so that the untouched stretch is found untouched (the same
    # for every span, so that equal junctions get equal rings, see lsys3d.mesh.union.repeats)
    scale = float(np.abs(np.concatenate([pcs.lo, pcs.hi])).max()) + 1.0
    grow = 1.01 * (grow + pcs.radius[me] * (1.0 + margin)) + 1e-8 * scale
    # outward to a grid of a power of two near a sixteenth of the radius, counted from the span's start: junctions
    # that are equal up to where they sit on their spans get equal rings (lsys3d.mesh.union.repeats unions them once)
    step = np.exp2(np.round(np.log2(pcs.radius[me] / 16.0)))
    lo = np.clip(np.floor((np.minimum(s0, s1) - grow) / step) * step, 0.0, L)
    hi = np.clip(np.ceil((np.maximum(s0, s1) + grow) / step) * step, 0.0, L)
    # merge the stretches of each span: sort by span, then start
    order = np.lexsort((lo, me))
    me, lo, hi, L = me[order], lo[order], hi[order], L[order]
    first = np.ones(len(me), bool)
    first[1:] = me[1:] != me[:-1]
    # running maximum of hi within each span (segments restart at each span)
    group = np.cumsum(first) - 1
    shift = group * (2.0 * (L.max() + 1.0))
    reach = np.maximum.accumulate(hi + shift) - shift  # furthest end so far in this span
    prev_reach = np.empty(len(me))
    prev_reach[0] = 0.0
    prev_reach[1:] = reach[:-1]
    prev_reach[first] = 0.0
    # gaps: before each stretch (from the reach so far), and after the last stretch of each span
    gap_lo = prev_reach
    gap_hi = lo
    last = np.append(first[1:], True)
    radius = pcs.radius[me]
    need = min_gap * radius
    rings_t, rings_piece = [], []
    before = (gap_hi - gap_lo >= need) & ~first  # a gap between two stretches: a ring at both ends
    lead = first & (lo >= need)  # a gap from the span's start: a ring where the first stretch begins
    for cond, where in ((before, gap_lo), (before, gap_hi), (lead, lo)):
        rings_t.append(where[cond] / L[cond])
        rings_piece.append(me[cond])
    tail = last & (L - reach >= need)  # a gap to the span's end: a ring where the last stretch ends
    rings_t.append(reach[tail] / L[tail])
    rings_piece.append(me[tail])
    t = np.concatenate(rings_t)
    piece = np.concatenate(rings_piece)
    ok = (t > 1e-6) & (t < 1 - 1e-6)
    t, piece = t[ok], piece[ok]
    order = np.lexsort((t, piece))
    return pcs.tube[piece[order]], pcs.first[piece[order]], t[order]
