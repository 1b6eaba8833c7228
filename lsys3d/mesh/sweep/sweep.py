"""Sweep: :class:`~lsys3d.turtle.skeleton.Skeleton` -> closed tubes, one per chain.

Every unbranched chain of segments (:attr:`Skeleton.chains`) becomes one
generalized cylinder: a ring of ``sides`` vertices at the chain's base, at
every joint and at its tip, closed by a flat cap (a fan around a centre
vertex) at both ends.  The rings follow a rotation-minimising frame
(parallel transport by double reflection, Wang et al. 2008), so a tube never
twists; a joint ring lies in the plane that bisects the bend and is
stretched by ``1 / cos(bend / 2)`` across the bend (a mitred pipe elbow), so
the tube keeps its width on both sides of the joint.

Where a chain turns more than a ring can follow -- more than
``SweepOptions.max_bend``, or so sharply for its width that neighbouring
mitre planes would cross inside the tube -- the chain is split into two
tubes there.  Each piece runs on past the joint by ``r * min(tan(bend / 2),
1)`` so that the two pieces cover the outside of the elbow, and the union
(:mod:`lsys3d.mesh.union.union`) joins them.

Counts (exact, per tube with ``R`` rings of ``S`` sides)::

    points (welded vertices)   R * S + 2        (rings + two cap centres)
    triangles                  2 * S * R        (2 S (R - 1) around, S per cap)
    wedges (attribute corners) (R + 2) * (S + 1)

``R`` is the number of segments of the piece plus one, less the joint rings
that add no shape: a joint where the chain goes straight on (within
``merge_angle``) and the width tapers linearly through it needs no ring;
plus a ring on each side of a joint turning more than ``elbow_angle`` (the
texture's shear and the bent normals of its mitre stay at the elbow), the
rings of ``ring_spacing``, and 3 rings at the base of each thick child that
bends out of its parent (``fork_blend``, :func:`_fork_bases`).

A *wedge* is a vertex together with one set of shading attributes (Hoppe's
term): the seam of a tube (``u = 0`` and ``u = 1``) and the cap rims share a
point with a ring vertex but not its normal or texture coordinate.
:class:`Tubes` keeps points, wedges and faces separately so that a union
(which needs closed, welded meshes) and a renderer (which needs the
attributes) read the same arrays.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...arrays import dot, unique, unit
from ...errors import GeometryError, LimitError
from ...noise import bark_noise
from ...streams import Stream
from ...turtle.skeleton import MAX_COORDINATE, Skeleton
from .forks import Spans, _fork_bases
from .frames import _inverse_mean, _perpendicular, _reflect_transport, _seam_side, _transport
from .options import DEFAULT_MAX_TRIANGLES, SweepOptions
from .rings import _elbows, _insert_rings, _merge_groups, _spans
from .tubes import RingRows, Tubes, _build, _concat
from .uv import _texture_v


def _check_finite(skeleton: Skeleton) -> None:
    """A NaN or infinite coordinate would pass silently into every tube of its chain: refuse it by name.

    So would one too large for the arithmetic of the mesh stages (squared lengths, the union's weld grid,
    32-bit floats in the files): coordinates and widths are bounded by ``MAX_COORDINATE``.
    """
    with np.errstate(invalid="ignore"):  # NaN compares False: refused below
        ok = (np.abs(skeleton.start) <= MAX_COORDINATE).all(axis=1) & (np.abs(skeleton.end) <= MAX_COORDINATE).all(1)
        ok &= np.isfinite(skeleton.left).all(axis=1)
        ok &= (np.abs(skeleton.width_start) <= MAX_COORDINATE) & (np.abs(skeleton.width_end) <= MAX_COORDINATE)
    if not ok.all():
        s = int(np.flatnonzero(~ok)[0])
        raise GeometryError(
            f"sweep: segment {s} (module {int(skeleton.module[s])}) has a start, end, width or frame "
            f"that is not a finite number, or is beyond {MAX_COORDINATE:g} (lsys3d.turtle.skeleton.MAX_COORDINATE)"
        )


def _runs(chain: np.ndarray, seg: np.ndarray, sides: np.ndarray | None) -> np.ndarray:
    """The runs of segments a merge may join: each chain, cut where the grammar's sides (cpfg's ``@!``) change."""
    if sides is None or len(chain) < 2:
        return chain
    cut = (chain[1:] != chain[:-1]) | (sides[seg[1:]] != sides[seg[:-1]])
    return np.concatenate([[0], np.cumsum(cut)]).astype(chain.dtype)


def sweep(
    skeleton: Skeleton,
    options: SweepOptions | None = None,
    *,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    seed: int = 0,
    uv_tiles: np.ndarray | None = None,
) -> Tubes:
    """Sweep a closed tube along every chain of a skeleton.

    Parameters
    ----------
    skeleton : Skeleton
        Segments with widths (diameters) and turtle frames.
    options : SweepOptions, optional
        Sides, minimum width, bend limits, bark displacement (defaults if None).
    seed : int
        Seed of the bark noise (used only with ``bark_displacement``).
    max_triangles : int
        Refuse to build more triangles than this; the count is known exactly
        (see the module docstring) before the tubes are allocated.
    uv_tiles : (m,) float64, optional
        Metres of bark one texture tile covers, by material index (the
        materials' :attr:`~lsys3d.look.materials.Material.tile_size`): a chain
        takes that of its first segment's material instead of
        ``options.uv_tile``.

    Returns
    -------
    Tubes
        One tube per chain, or more where a chain bends too sharply; none for
        an empty skeleton.  Zero-length segments are dropped, widths below
        ``min_width`` clamped.

    Raises
    ------
    GeometryError
        A segment whose end points, width or frame are not finite numbers.
    LimitError
        More than ``max_triangles`` triangles (the message gives the count).

    Examples
    --------
    >>> import numpy as np
    >>> from lsys3d.turtle.skeleton import Skeleton
    >>> z = np.zeros(2)
    >>> sk = Skeleton(
    ...     start=np.array([[0.0, 0, 0], [0, 1, 0]]), end=np.array([[0.0, 1, 0], [0, 2, 0]]),
    ...     width_start=np.array([0.2, 0.2]), width_end=np.array([0.2, 0.1]),
    ...     heading=np.array([[0.0, 1, 0]] * 2), left=np.array([[-1.0, 0, 0]] * 2), up=np.array([[0.0, 0, 1]] * 2),
    ...     parent=np.array([-1, 0]), order=np.zeros(2, np.int32), material=np.zeros(2, np.int32), module=np.arange(2))
    >>> tubes = sweep(sk, SweepOptions(sides=6))
    >>> len(tubes), tubes.rings.tolist(), len(tubes.points), len(tubes.faces)
    (1, [3], 20, 36)
    """
    opt = SweepOptions() if options is None else options
    if not len(skeleton):
        return Tubes.empty()
    _check_finite(skeleton)
    chains = skeleton.chains
    seg = chains.segments
    chain = np.repeat(np.arange(len(chains)), chains.lengths())
    p0 = skeleton.start[seg].astype(np.float64)
    p1 = skeleton.end[seg].astype(np.float64)
    length = np.linalg.norm(p1 - p0, axis=1)
    # v along the chain counts every segment, dropped ones included
    cum = np.cumsum(length)
    v1 = cum - np.repeat(cum[chains.offsets[:-1]] - length[chains.offsets[:-1]], chains.lengths())
    chain_sides = opt.sides_for_order(skeleton.order[seg[chains.offsets[:-1]]])
    tiles, tv1 = _texture_v(skeleton, opt, chain_sides, seg, chain, length, uv_tiles)
    keep = length > opt.min_length
    if not keep.any():
        return Tubes.empty()
    seg, chain, p0, p1, length, v1, tv1 = seg[keep], chain[keep], p0[keep], p1[keep], length[keep], v1[keep], tv1[keep]
    d = (p1 - p0) / length[:, None]
    v0 = v1 - length
    w0 = np.maximum(skeleton.width_start[seg], opt.min_width)
    w1 = np.maximum(skeleton.width_end[seg], opt.min_width)
    # texture v per metre where the radius is r: tiles / perimeter = rate / r
    rate = tiles[chain] / (chain_sides[chain] * 2.0 * np.sin(np.pi / chain_sides[chain]))
    tv0 = tv1 - rate * length * _inverse_mean(0.5 * w0, 0.5 * w1)
    k = len(seg)
    if opt.merge_deviation > 0 and k > 1:
        group = _merge_groups(
            _runs(chain, seg, skeleton.sides),
            p0,
            p1,
            v0,
            v1,
            w0,
            w1,
            opt.merge_deviation,
            1e-9 * (np.abs(p1).max() + 1.0),
        )
        if group[-1] + 1 < k:
            first = np.flatnonzero(np.concatenate([[True], group[1:] != group[:-1]]))
            last = np.append(first[1:] - 1, k - 1)
            seg, chain, p0, p1, v0, v1 = seg[first], chain[first], p0[first], p1[last], v0[first], v1[last]
            w0, w1 = w0[first], w1[last]
            tv0, tv1, rate = tv0[first], tv1[last], rate[first]  # texture v of the run's ends (one chain: one rate)
            length = np.linalg.norm(p1 - p0, axis=1)
            d = (p1 - p0) / length[:, None]
            k = len(seg)

    pinned = np.zeros(k, bool)  # segments whose end ring stays whatever merge_angle says (a blended base's)
    if opt.fork_blend > 0 and k:
        spans, pinned = _fork_bases(
            skeleton, opt, chain_sides, Spans(seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate)
        )
        seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate = spans
        length = np.linalg.norm(p1 - p0, axis=1)
        d = (p1 - p0) / length[:, None]
        k = len(seg)

    # ---- joints between consecutive kept segments: split where a ring cannot follow
    same = chain[1:] == chain[:-1]
    cos = np.clip(dot(d[:-1], d[1:]), -1.0, 1.0)
    tan_half = np.sqrt((1.0 - cos) / np.maximum(1.0 + cos, 1e-12))
    r_joint = 0.25 * (w1[:-1] + w0[1:])
    scale = np.abs(p1).max() + 1.0
    gap = np.linalg.norm(p0[1:] - p1[:-1], axis=1) > 1e-9 * scale + 1e-6 * np.minimum(length[:-1], length[1:])
    bend = cos < math.cos(math.radians(opt.max_bend))
    # a displaced ring reaches out to (1 + bark_displacement) r: mitre planes must not cross inside that
    fold = r_joint * (1.0 + opt.bark_displacement) * tan_half > 0.5 * np.minimum(length[:-1], length[1:])
    split = same & (gap | bend | fold)
    if skeleton.sides is not None:  # the grammar's sides (cpfg's @!) change: a new piece, a new number of sides
        split |= same & (skeleton.sides[seg[1:]] != skeleton.sides[seg[:-1]])
    extend = np.where(split & ~gap, r_joint * np.minimum(tan_half, 1.0), 0.0)
    first = np.ones(k, bool)
    first[1:] = ~same | split
    piece_start = np.flatnonzero(first)
    npieces = len(piece_start)
    piece_len = np.diff(np.append(piece_start, k))
    piece_of = np.repeat(np.arange(npieces), piece_len)
    last = np.zeros(k, bool)
    last[piece_start[1:] - 1] = True
    last[-1] = True
    ext_start = np.zeros(k)
    ext_start[1:] = extend
    ext_end = np.zeros(k)
    ext_end[:-1] = extend

    # ---- rotation-minimising frame: u[s] perpendicular to d[s], carried along each chain (through its
    # splits too) from the seam side at the chain's base; all chains advance together
    u = np.empty((k, 3))
    chain_head = np.flatnonzero(np.concatenate([[True], ~same]))
    chain_len = np.diff(np.append(chain_head, k))
    u[chain_head] = _perpendicular(d[chain_head], _seam_side(skeleton, seg[chain_head]))
    by_len = np.argsort(-chain_len, kind="stable")
    starts_sorted = chain_head[by_len]
    neg_len = -chain_len[by_len]
    for step in range(1, int(chain_len.max())):
        rows = starts_sorted[: np.searchsorted(neg_len, -step, side="left")] + step
        u[rows] = _transport(u[rows - 1], d[rows - 1], d[rows])

    # ---- rings: one at each piece start, one at the end of every segment
    nr = k + npieces
    ring_of_end = np.arange(k) + piece_of + 1
    ring_start = piece_start + np.arange(npieces)
    center = np.empty((nr, 3))
    tangent = np.empty((nr, 3))
    axis_a = np.empty((nr, 3))
    width = np.empty(nr)
    v = np.empty(nr)
    tv = np.empty(nr)
    stretch = np.ones(nr)
    bend_dir = np.zeros((nr, 3))
    joint = np.zeros(nr, bool)

    center[ring_start] = p0[piece_start] - ext_start[piece_start, None] * d[piece_start]
    tangent[ring_start] = d[piece_start]
    axis_a[ring_start] = u[piece_start]
    width[ring_start] = w0[piece_start]
    v[ring_start] = v0[piece_start] - ext_start[piece_start]
    tv[ring_start] = tv0[piece_start] - rate[piece_start] * ext_start[piece_start] / (0.5 * w0[piece_start])

    e = np.flatnonzero(last)
    re = ring_of_end[e]
    center[re] = p1[e] + ext_end[e, None] * d[e]
    tangent[re] = d[e]
    axis_a[re] = u[e]
    width[re] = w1[e]
    v[re] = v1[e] + ext_end[e]
    tv[re] = tv1[e] + rate[e] * ext_end[e] / (0.5 * w1[e])

    j = np.flatnonzero(~last)  # segment j ends at a joint with segment j + 1
    rj = ring_of_end[j]
    joint[rj] = True
    center[rj] = p1[j]
    tangent[rj] = unit(d[j] + d[j + 1])
    axis_a[rj] = _reflect_transport(u[j], d[j], tangent[rj])
    width[rj] = 0.5 * (w1[j] + w0[j + 1])
    v[rj] = v1[j]
    tv[rj] = tv1[j]
    cj = cos[j]
    turning = cj < 1.0 - 1e-12
    stretch[rj] = np.where(turning, np.sqrt(2.0 / (1.0 + cj)), 1.0)
    bend_dir[rj] = np.where(turning[:, None], unit(d[j + 1] - d[j]), 0.0)

    # rings that add no shape: straight on, linear taper
    kept = np.ones(nr, bool)
    ds0 = v[rj] - v[rj - 1]
    ds1 = v[rj + 1] - v[rj]
    interp = (width[rj - 1] * ds1 + width[rj + 1] * ds0) / np.maximum(ds0 + ds1, 1e-300)
    straight = cj >= math.cos(math.radians(opt.merge_angle))
    kept[rj] = ~(straight & (np.abs(width[rj] - interp) <= opt.merge_width * width[rj])) | pinned[j]
    ring_piece = np.repeat(np.arange(npieces), piece_len + 1)
    sel = np.flatnonzero(kept)
    center, tangent, axis_a, width, v, tv = center[sel], tangent[sel], axis_a[sel], width[sel], v[sel], tv[sel]
    stretch, bend_dir, ring_piece = stretch[sel], bend_dir[sel], ring_piece[sel]
    chain_of_piece = chain[piece_start]
    sides_of_piece = chain_sides[chain_of_piece]
    if skeleton.sides is not None:
        own = skeleton.sides[seg[piece_start]].astype(np.int64)
        sides_of_piece = np.where(own > 0, own, sides_of_piece)
    rows = (center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece)
    if opt.elbow_angle < 180.0:
        rows = _insert_rings(*_elbows(opt, *rows), *rows)
    if opt.spacing[0] > 0:
        rows = _insert_rings(*_spans(opt.spacing, sides_of_piece, *rows), *rows)
    center, tangent, axis_a, width, v, tv, stretch, bend_dir, ring_piece = rows
    rings = np.bincount(ring_piece, minlength=npieces)
    radius = 0.5 * width
    axis_b = np.cross(tangent, axis_a)

    # taper slope dr/ds between neighbouring rings, for the normals
    ring_first = np.zeros(npieces + 1, np.int64)
    np.cumsum(rings, out=ring_first[1:])
    nxt = np.arange(len(v)) + 1
    prv = np.arange(len(v)) - 1
    is_last = np.zeros(len(v), bool)
    is_last[ring_first[1:] - 1] = True
    is_first = np.zeros(len(v), bool)
    is_first[ring_first[:-1]] = True
    nxt[is_last] -= 1
    prv[is_first] += 1
    slope = (radius[nxt] - radius[prv]) / np.maximum(v[nxt] - v[prv], 1e-300)

    order_of_piece = skeleton.order[skeleton.chains.segments[skeleton.chains.offsets[chain_of_piece]]]
    triangles = int((2 * sides_of_piece * rings).sum())
    if triangles > max_triangles:
        raise LimitError(
            f"sweep: the {len(skeleton):,} segments would make {triangles:,} tube triangles, more than the limit "
            f"of {max_triangles:,}; use fewer iterations or sides, or raise the limit (--max-triangles, or "
            "max_triangles=)"
        )

    displace = None
    if opt.bark_displacement > 0:
        amplitude, noise_seed = opt.bark_displacement, (int(seed), int(Stream.BARK_DISPLACEMENT))

        def displace(points):
            return amplitude * bark_noise(points, noise_seed, octaves=opt.bark_octaves, frequency=opt.bark_frequency)

    ring_rows = RingRows(center, tangent, axis_a, axis_b, radius, slope, tv, stretch, bend_dir)
    parts = []
    for s in unique(sides_of_piece).tolist():
        pieces = np.flatnonzero(sides_of_piece == s)
        rsel = np.flatnonzero(sides_of_piece[ring_piece] == s)
        parts.append(
            (
                pieces,
                _build(s, rings[pieces], ring_rows.take(rsel), tiles[chain_of_piece[pieces]], displace),
            )
        )
    order_all = np.concatenate([p for p, _ in parts])
    tubes = _concat([t for _, t in parts])
    return replace(
        tubes,
        chain=chain_of_piece[order_all],
        sides=sides_of_piece[order_all],
        rings=rings[order_all],
        order=order_of_piece[order_all].astype(np.int32),
    )
