"""The rings of a chain: elbows, spacing, inserted rings, merged joints, and the rows of refined rings."""

from __future__ import annotations

import math

import numpy as np

from ...arrays import local_index, unit
from ...compiling import kernel
from .frames import _inverse_mean, _reflect_transport


def _elbows(opt, center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece):
    """Where the rings on both sides of each sharp joint go: ``(after, t)``, see :func:`_insert_rings`.

    A joint ring lies in the mitre plane: along the wall its vertices stand
    up to ``r tan(bend / 2)`` ahead of or behind its centre while the ring
    keeps one texture ``v``, and its normals bisect the bend.  On a long span
    ending at a sharp joint both would spread over the whole span (texture
    sheared by up to ``tan(bend / 2)``, a straight pipe shaded as if bent).  A
    ring across the span twice that far from the joint (at most 0.4 of the
    span, and clear of the mitre) keeps them in a band at the elbow.
    """
    n = len(center)
    sharp = np.flatnonzero(stretch > 1.0 / math.cos(math.radians(0.5 * opt.elbow_angle)))
    if not len(sharp):
        return np.zeros(0, np.int64), np.zeros(0)
    reach = 0.5 * width[sharp] * np.sqrt(stretch[sharp] ** 2 - 1.0) * (1.0 + opt.bark_displacement)  # r tan(b/2)
    after, t = [], []
    for near, sign in ((sharp - 1, -1.0), (sharp + 1, 1.0)):
        ok = (near >= 0) & (near < n)
        ok[ok] &= ring_piece[near[ok]] == ring_piece[sharp[ok]]
        gap = np.linalg.norm(center[np.clip(near, 0, n - 1)] - center[sharp], axis=1)
        at = np.minimum(4.0 * reach, 0.4 * gap)
        ok &= at > 1.25 * reach
        share = at[ok] / gap[ok]
        # the span runs from ring `after` to `after + 1`: before the joint it ends there, after it starts there
        after.append(np.where(sign < 0, near, sharp)[ok])
        t.append(1.0 - share if sign < 0 else share)
    return np.concatenate(after), np.concatenate(t)


def _spans(spacing, sides_of_piece, center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece):
    """Where the rings between neighbouring rings of a piece farther apart than ``spacing`` go (``(after, t)``).

    ``spacing`` is (tube sides, metres); the new rings are evenly spaced.
    """
    sides_apart, metres = spacing
    same = ring_piece[1:] == ring_piece[:-1]
    sides = sides_of_piece[ring_piece[:-1]]
    gap = np.linalg.norm(center[1:] - center[:-1], axis=1)
    side = np.minimum(width[1:], width[:-1]) * np.sin(np.pi / sides)  # 2 r sin(pi / S)
    extra = np.where(same, np.ceil(gap / np.maximum(sides_apart * side, metres)) - 1, 0).astype(np.int64)
    extra = np.maximum(extra, 0)
    after = np.repeat(np.arange(len(extra)), extra)
    return after, (local_index(extra) + 1) / (extra + 1)[after]


def _insert_rings(after, t, center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece):
    """The ring arrays with a new ring at the fraction ``0 < t[i] < 1`` of the span from ring ``after[i]`` on.

    A new ring is perpendicular to its span, with the span's twist-free frame
    and the linear taper's width; its texture ``v`` grows as the integral of
    ``1 / r`` (exact for the linear taper, so texels stay square).
    """
    if not len(after):
        return center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece
    n = len(center)
    pair = np.concatenate([np.arange(n), after])
    t = np.concatenate([np.zeros(n), t])
    order = np.lexsort((t, pair))
    pair, t = pair[order], t[order]
    nxt = np.minimum(pair + 1, n - 1)

    def lerp(a):
        tt = t.reshape(-1, *([1] * (a.ndim - 1)))
        return a[pair] + tt * (a[nxt] - a[pair])

    inserted = t > 0
    d = unit(center[nxt] - center[pair])
    out_tangent = np.where(inserted[:, None], d, tangent[pair])
    out_axis = axis_a[pair].copy()
    out_axis[inserted] = _reflect_transport(axis_a[pair][inserted], tangent[pair][inserted], d[inserted])
    out_stretch = np.where(inserted, 1.0, stretch[pair])
    out_bend = np.where(inserted[:, None], 0.0, bend_dir[pair])
    r0, r1 = 0.5 * width[pair], 0.5 * width[nxt]
    rt = r0 + t * (r1 - r0)
    share = t * _inverse_mean(r0, rt) / _inverse_mean(r0, r1)
    return (
        lerp(center),
        out_tangent,
        out_axis,
        lerp(width),
        lerp(v),
        tv[pair] + share * (tv[nxt] - tv[pair]),
        out_stretch,
        out_bend,
        ring_piece[pair],
    )


@kernel(nogil=True)
def _merge_groups(chain, p0, p1, v0, v1, w0, w1, deviation, gap):  # pragma: no cover - compiled
    """Group of each segment: runs of one chain whose joints stay near the straight line (SweepOptions.merge_deviation).

    Only segments shorter than the tube is wide take part.  A run grows from
    its first segment while every joint it would swallow lies within
    ``deviation`` times the run's smallest radius of the segment from the
    run's start to its new end, the width there within as much of the linear
    taper, and no gap opens between segments.  At most 64 segments a run, so
    the checks stay linear in the number of segments.
    """
    k = len(chain)
    group = np.empty(k, np.int64)
    g = 0
    i = 0
    while i < k:
        group[i] = g
        j = i
        rmin = 0.5 * min(w0[i], w1[i])
        while j + 1 < k and chain[j + 1] == chain[i] and j + 1 - i < 64 and v1[i] - v0[i] < 2.0 * rmin:
            n = j + 1
            if v1[n] - v0[n] >= min(w0[n], w1[n]):
                break
            step = 0.0
            for c in range(3):
                step += (p0[n, c] - p1[j, c]) ** 2
            if step > gap * gap:
                break
            r = min(rmin, 0.5 * min(w0[n], w1[n]))
            tol = deviation * r
            ax = p1[n, 0] - p0[i, 0]
            ay = p1[n, 1] - p0[i, 1]
            az = p1[n, 2] - p0[i, 2]
            aa = ax * ax + ay * ay + az * az
            span = v1[n] - v0[i]
            ok = aa > 0.0 and span > 0.0
            m = i
            while ok and m < n:  # the joint between m and m + 1
                qx = p1[m, 0] - p0[i, 0]
                qy = p1[m, 1] - p0[i, 1]
                qz = p1[m, 2] - p0[i, 2]
                t = min(max((qx * ax + qy * ay + qz * az) / aa, 0.0), 1.0)
                dx, dy, dz = qx - t * ax, qy - t * ay, qz - t * az
                if dx * dx + dy * dy + dz * dz > tol * tol:
                    ok = False
                f = (v1[m] - v0[i]) / span
                taper = w0[i] + f * (w1[n] - w0[i])
                if abs(w1[m] - taper) > 2.0 * tol or abs(w0[m + 1] - taper) > 2.0 * tol:
                    ok = False
                m += 1
            if not ok:
                break
            rmin = r
            j = n
            group[j] = g
        g += 1
        i = j + 1
    return group


@kernel(nogil=True)
def _ring_rows(out, old, rt, rk, rf, local, sides, offs):  # pragma: no cover - compiled
    """The ring points and wedges of :meth:`Tubes.insert_rings`, a ring at a time (no gathered temporaries).

    Row ``r`` of the sorted rings is old ring ``rk[r]`` of tube ``rt[r]`` (``rf[r] == 0``) or a new ring at
    the fraction ``rf[r]`` of the way to the next one, and becomes ring ``local[r]`` of its tube.  The
    arithmetic is the vectorised one's, element by element: ``(1 - f) a + f b`` in float64 (float32 normals
    and uv widened first), normals scaled by their norm (x, y, z summed in that order, as ``np.linalg.norm``
    does) and stored as float32.
    """
    points, wedge_point, wedge_normal, wedge_uv = out
    old_points, old_normal, old_uv = old
    point_offsets, wedge_offsets, p_off, w_off = offs
    shading = len(wedge_normal) > 0  # (empty: the points and wedge points alone)
    for r in range(len(rt)):
        tube, s, f = rt[r], sides[rt[r]], rf[r]
        moved = f > 0
        src = point_offsets[tube] + rk[r] * s
        dest = p_off[tube] + local[r] * s
        for j in range(s):
            for c in range(3):
                if moved:
                    points[dest + j, c] = (1.0 - f) * old_points[src + j, c] + f * old_points[src + j + s, c]
                else:
                    points[dest + j, c] = old_points[src + j, c]
        w = s + 1
        src = wedge_offsets[tube] + rk[r] * w
        wdest = w_off[tube] + local[r] * w
        for j in range(w):
            wedge_point[wdest + j] = dest + j % s
            if not shading:
                continue
            if not moved:
                for c in range(3):
                    wedge_normal[wdest + j, c] = old_normal[src + j, c]
                for c in range(2):
                    wedge_uv[wdest + j, c] = old_uv[src + j, c]
                continue
            a, b = src + j, src + j + w
            x = (1.0 - f) * np.float64(old_normal[a, 0]) + f * np.float64(old_normal[b, 0])
            y = (1.0 - f) * np.float64(old_normal[a, 1]) + f * np.float64(old_normal[b, 1])
            z = (1.0 - f) * np.float64(old_normal[a, 2]) + f * np.float64(old_normal[b, 2])
            length = np.sqrt(x * x + y * y + z * z)
            if not length > 0.0:
                length = 1.0
            wedge_normal[wdest + j, 0] = np.float32(x / length)
            wedge_normal[wdest + j, 1] = np.float32(y / length)
            wedge_normal[wdest + j, 2] = np.float32(z / length)
            for c in range(2):
                wedge_uv[wdest + j, c] = np.float32((1.0 - f) * np.float64(old_uv[a, c]) + f * np.float64(old_uv[b, c]))


@kernel(nogil=True)
def _face_origin(out, f_off, sides, new_rings, ring_off, rings, rk, old_f_off):  # pragma: no cover - compiled
    """The face before :meth:`Tubes.insert_rings` of every face after it, a face at a time.

    A wall face of tube ``i`` lies in the quad of the same place in the old span that its span's first ring
    (row ``ring_off[i] + span`` of the sorted rings, old ring ``rk``) starts; a cap face is the same cap face.
    """
    last = len(rk) - 1
    for i in range(len(f_off) - 1):
        s2 = 2 * sides[i]
        body = s2 * (new_rings[i] - 1)
        for lf in range(body):
            out[f_off[i] + lf] = old_f_off[i] + rk[min(ring_off[i] + lf // s2, last)] * s2 + lf % s2
        cap = s2 * (rings[i] - 1) - body
        for lf in range(body, f_off[i + 1] - f_off[i]):
            out[f_off[i] + lf] = old_f_off[i] + lf + cap
