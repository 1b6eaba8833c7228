"""Texture coordinates of the tubes: u around (a whole number of tiles), v along (metres over the width)."""

from __future__ import annotations

import numpy as np

from ...arrays import search_right
from ...compiling import inner, kernel
from ...turtle.skeleton import Skeleton
from .frames import _inverse_mean, _span_frame
from .options import SweepOptions


@inner(nogil=True, inline="always")
def _face_place(face, offsets, sides, rings, t):  # pragma: no cover - compiled
    """Where tube face ``face`` lies: its tube (``t``, the tube of the face before, is tried first: the faces of
    a tube come together), its index among the tube's faces, and its end: -1 on the wall, 0 in the base's cap, 1
    in the tip's (a tube has ``2 s (rings - 1)`` wall faces, then ``s`` at its base and ``s`` at its tip)."""
    if t < 0 or not (offsets[t] <= face < offsets[t + 1]):
        t = search_right(offsets, face) - 1
    local = face - offsets[t]
    body = 2 * sides[t] * (rings[t] - 1)
    return t, local, -1 if local < body else (1 if local >= body + sides[t] else 0)


@kernel(nogil=True)
def _face_kinds(face, offsets, sides, rings, tube, cap):  # pragma: no cover - compiled
    """:meth:`Tubes.face_kinds` into ``tube`` and ``cap`` (:func:`_face_place`)."""
    t = -1
    for i in range(len(face)):
        t, _, end = _face_place(face[i], offsets, sides, rings, t)
        tube[i] = t
        cap[i] = -1 if end < 0 else 2 * t + end


@kernel(nogil=True)
def _uv_at(  # pragma: no cover - compiled
    face,
    points,
    corners,
    wrap,
    out,
    lo,
    hi,
    offsets,
    sides,
    rings,
    ring_offsets,
    center,
    tangent,
    axis,
    ring_v,
    radius,
    tiles,
):
    """:meth:`Tubes.uv_at` of ``points[corners[lo:hi]]`` into ``out[lo:hi]``, wrapped per row if ``wrap``
    (:func:`wrap_u`): one pass per face, no temporaries.  A row is made in float64 and then stored, so a
    float32 ``out`` holds the float64 values rounded once."""
    m = corners.shape[1]
    two_pi = 2.0 * np.pi
    row = np.empty((m, 2))
    t = -1
    last = -1  # the wall span whose frame is in (ux, uy, uz), (bx, by, bz): the faces of a span come together
    ux = uy = uz = bx = by = bz = 0.0
    for i in range(lo, hi):
        t, local, end = _face_place(face[i], offsets, sides, rings, t)
        s = sides[t]
        first = ring_offsets[t]
        if end >= 0:  # a cap: planar, at the density of the wall at its ring
            ring = first + rings[t] - 1 if end == 1 else first
            ax, ay, az = axis[ring, 0], axis[ring, 1], axis[ring, 2]
            tx, ty, tz = tangent[ring, 0], tangent[ring, 1], tangent[ring, 2]
            cx, cy, cz = ty * az - tz * ay, tz * ax - tx * az, tx * ay - ty * ax
            density = tiles[t] / (s * 2.0 * np.sin(np.pi / s) * radius[ring])
            for j in range(m):
                q = corners[i, j]
                x = points[q, 0] - center[ring, 0]
                y = points[q, 1] - center[ring, 1]
                z = points[q, 2] - center[ring, 2]
                row[j, 0] = 0.5 * tiles[t] + density * (x * ax + y * ay + z * az)
                row[j, 1] = ring_v[ring] + density * (x * cx + y * cy + z * cz)
        else:
            r0 = first + min(local // max(2 * s, 1), max(rings[t] - 2, 0))
            r1 = min(r0 + 1, first + rings[t] - 1)
            if r0 != last:
                ux, uy, uz, bx, by, bz = _span_frame(center, tangent, axis, r0, r1)
                last = r0
            for j in range(m):
                q = corners[i, j]
                x = points[q, 0] - center[r0, 0]
                y = points[q, 1] - center[r0, 1]
                z = points[q, 2] - center[r0, 2]
                angle = np.arctan2(x * bx + y * by + z * bz, x * ux + y * uy + z * uz)
                if angle < 0.0:  # % two_pi, without numba's general float modulo (+ 0.0: -0.0 becomes 0.0)
                    angle += two_pi
                angle += 0.0
                if angle > two_pi * (1.0 - 1e-12):
                    angle = 0.0  # the seam itself is u = 0 (wrap_u decides per face)
                row[j, 0] = tiles[t] * angle / two_pi
                # along: the share of the way from one ring's plane to the next's (a joint ring's plane is tilted)
                h0 = x * tangent[r0, 0] + y * tangent[r0, 1] + z * tangent[r0, 2]
                h1 = (
                    (center[r1, 0] - points[q, 0]) * tangent[r1, 0]
                    + (center[r1, 1] - points[q, 1]) * tangent[r1, 1]
                    + (center[r1, 2] - points[q, 2]) * tangent[r1, 2]
                )
                total = h0 + h1
                share = h0 / total if abs(total) > 1e-300 else 0.0
                row[j, 1] = ring_v[r0] + share * (ring_v[r1] - ring_v[r0])
        if wrap:  # as wrap_u: corners more than half a turn below the row's highest u go round once
            top = row[0, 0]
            for j in range(1, m):
                top = max(top, row[j, 0])
            for j in range(m):
                if top - row[j, 0] > 0.5 * tiles[t]:
                    row[j, 0] = row[j, 0] + tiles[t]
        for j in range(m):
            out[i, j, 0], out[i, j, 1] = row[j, 0], row[j, 1]


def wrap_u(uv: np.ndarray, tiles: np.ndarray) -> np.ndarray:
    """Per triangle ``(f, 3, 2)``: corners whose ``u`` lies more than half a turn below the others get ``+ tiles``.

    :meth:`Tubes.uv_at` gives ``u`` in ``[0, tiles)``; a triangle across the
    tube's seam needs its corners on one side of it (``u`` near ``tiles``, not 0).
    """
    u = uv[:, :, 0]
    tiles = np.asarray(tiles, np.float64)[:, None]
    wide = (u.max(axis=1, keepdims=True) - u) > 0.5 * tiles
    out = uv.copy()
    out[:, :, 0] = np.where(wide, u + tiles, u)
    return out


def _texture_v(skeleton: Skeleton, opt: SweepOptions, chain_sides, seg, chain, length, uv_tiles=None):
    """Tiles around each chain, and the texture ``v`` at the end of each segment (in chain order).

    A chain gets a whole number of tiles around, ``round(perimeter at its
    base / uv_tile)`` and at least one, so its texture wraps without a seam
    (``uv_tile`` from ``uv_tiles`` by its first segment's material when given);
    ``v`` grows by ``tiles / perimeter`` per metre, so a texel is square
    wherever the chain tapers.  A chain's ``v`` starts where its parent's ``v``
    is at the junction: the texture runs on from a branch into its child.
    """
    chains = skeleton.chains
    heads = chains.offsets[:-1]
    r0 = 0.5 * np.maximum(skeleton.width_start[seg], opt.min_width)
    r1 = 0.5 * np.maximum(skeleton.width_end[seg], opt.min_width)
    chord = chain_sides * 2.0 * np.sin(np.pi / chain_sides)  # perimeter / radius
    tile = opt.uv_tile if uv_tiles is None else np.asarray(uv_tiles)[skeleton.material[seg[heads]]]
    tiles = np.maximum(1.0, np.round(chord * r0[heads] / tile))
    rate = (tiles / chord)[chain]
    step = rate * length * _inverse_mean(r0, r1)
    cum = np.cumsum(step)
    local = cum - np.repeat(cum[heads] - step[heads], chains.lengths())
    # each chain starts at its parent's v where it branches off (parents come first: parent[s] < s)
    position = np.empty(len(seg), np.int64)
    position[seg] = np.arange(len(seg))
    parent = skeleton.parent[seg[heads]]
    has = parent >= 0
    at = position[parent[has]]
    start = np.zeros(len(chains))
    for _ in range(len(chains)):
        new = np.zeros(len(chains))
        new[has] = start[chain[at]] + local[at]
        if np.array_equal(new, start):
            break
        start = new
    return tiles, start[chain] + local
