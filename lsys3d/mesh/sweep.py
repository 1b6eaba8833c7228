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
from dataclasses import dataclass, replace

import numba
import numpy as np

from ..arrays import dot, gather, local_index, offsets, unique, unit
from ..errors import GeometryError, LimitError
from ..noise import bark_noise
from ..options import Options, option
from ..streams import Stream
from ..turtle.skeleton import MAX_COORDINATE, Skeleton
from .mesh import Mesh

__all__ = ["DEFAULT_MAX_TRIANGLES", "SweepOptions", "Tubes", "sweep"]

DEFAULT_MAX_TRIANGLES = 10_000_000
"""Most tube triangles :func:`sweep` builds (about 50 bytes a triangle in the tubes, more in the union)."""


@dataclass(frozen=True)
class SweepOptions(Options):
    """How chains become tubes; every default, range and help is in its field.

    ``sides_step`` drops sides per branch order: a chain of order ``k`` gets
    ``max(min_sides, sides - k * sides_step)`` sides.  A joint that turns less
    than ``merge_angle`` with a width that tapers linearly through it (within
    ``merge_width``) gets no ring.  ``bark_displacement`` moves every ring
    vertex along its radial direction by ``bark_displacement * r * n(p)``, a
    fraction of the local tube radius ``r``; ``n``
    (:func:`lsys3d.noise.bark_noise`, fBm with its contrast raised) lies in
    [-1, 1] and is evaluated at the undisplaced world position, so tubes that
    meet at a junction carry the same bark pattern.  Runs of segments shorter
    than the tube is wide merge into one ring span while the merged axis stays
    within ``merge_deviation`` of the radius of every joint it skips.

    Examples
    --------
    >>> SweepOptions(sides=6, sides_step=1, min_sides=4).sides_for_order([0, 1, 2, 5]).tolist()
    [6, 5, 4, 4]
    """

    sides: int = option(8, low=3, high=1024, help="vertices around the trunk's tubes (branch order 0)")
    sides_step: int = option(0, low=0, high=1024, help="sides dropped per branch order (0: all the same)")
    min_sides: int = option(3, low=3, high=1024, help="fewest sides of any tube")
    min_width: float = option(1e-3, low=0, low_open=True, help="smallest tube diameter; thinner widths are clamped")
    min_length: float = option(1e-9, low=0, help="segments shorter than this are dropped", cli=False)
    max_bend: float = option(
        120.0, low=0, high=180, low_open=True, high_open=True, help="degrees: a chain turning more is split there"
    )
    merge_angle: float = option(
        0.01, low=0, high=90, high_open=True, help="degrees: a straighter joint with a linear taper gets no ring"
    )
    merge_width: float = option(1e-6, low=0, help="relative tolerance of the linear taper of merge_angle", cli=False)
    merge_deviation: float = option(
        0.02,
        low=0,
        high=0.5,
        help="steps shorter than the tube is wide merge while within this fraction of its radius (0: off)",
    )
    bark_displacement: float = option(
        0.0, low=0, high=0.5, help="procedural bark: displace the tubes by noise up to this fraction of their radius"
    )
    bark_frequency: float = option(8.0, low=0, low_open=True, high=1e6, help="bark features per metre")
    bark_octaves: int = option(3, low=1, high=16, help="octaves of the bark noise")
    ring_spacing: float = option(
        0.0,
        low=0,
        high=1e6,
        help="rings at most this many tube sides apart (0: only at joints; 1 with bark displacement)",
    )
    elbow_angle: float = option(
        45.0,
        low=0,
        high=180,
        low_open=True,
        help="degrees: a joint turning more gets a ring on each side of its mitre (180: never)",
    )
    fork_blend: float = option(
        1.5,
        low=0,
        high=10,
        help="a child at least half as wide as its parent leaves it along the parent's heading and bends out over "
        "this many of its radii (0: off)",
    )
    fork_blend_min: float = option(
        0.002,
        low=0,
        high=1,
        help="fork_blend only for children at least this fraction of the plant's size wide (0: every thick fork)",
    )
    uv_tile: float = option(
        0.5,
        low=0,
        low_open=True,
        high=1e6,
        help="metres of bark around a branch one texture tile covers (a whole number of tiles goes around)",
    )

    def sides_for_order(self, order) -> np.ndarray:
        """Sides of the rings of chains of branch order ``order``, ``int64``."""
        order = np.asarray(order, np.int64)
        return np.maximum(self.fewest_sides, self.sides - order * self.sides_step)

    @property
    def fewest_sides(self) -> int:
        """The fewest sides any tube has: ``min_sides``, or ``sides`` when that is fewer."""
        return min(self.min_sides, self.sides)

    @property
    def spacing(self) -> tuple[float, float]:
        """The ring spacing in effect: (tube sides, metres); a span longer than both gets rings.

        ``ring_spacing`` sides when given; with bark displacement and no
        ``ring_spacing``, one side (square quads) but no closer than half the
        bark's feature size (``1 / bark_frequency``: two rings per bump of the
        noise's first octave); (0, 0): rings only at joints.
        """
        if self.ring_spacing > 0:
            return self.ring_spacing, 0.0
        if self.bark_displacement > 0:
            return 1.0, 0.5 / self.bark_frequency
        return 0.0, 0.0


@dataclass(frozen=True, eq=False)
class Tubes:
    """Closed tubes, each a welded 2-manifold, stored as flat arrays.

    Tube ``t`` owns ``points[point_offsets[t]:point_offsets[t+1]]``, the
    wedges ``wedge_offsets[t]:wedge_offsets[t+1]``, the faces
    ``face_offsets[t]:face_offsets[t+1]`` and the rings
    ``ring_offsets[t]:ring_offsets[t+1]``; all indices are global.

    Attributes
    ----------
    points : (V, 3) float64
        Welded vertex positions.
    wedge_point : (W,) int64
        The point of each wedge.
    wedge_normal : (W, 3) float32
        Unit normal of each wedge (smooth around a tube, sharp at the caps).
    wedge_uv : (W, 2) float32
        Texture coordinates in tiles (see the module's documentation): ``u``
        from 0 to ``tiles`` around the tube, ``v`` along the chain, a square
        texel everywhere; caps planar at the same density.
    faces : (F, 3) int64
        Triangles as wedge indices, counter-clockwise seen from outside.
    point_offsets, wedge_offsets, face_offsets : (t + 1,) int64
    chain : (t,) int64
        The chain (:attr:`Skeleton.chains`) each tube was swept along.
    sides, rings : (t,) int64
        Ring size and ring count of each tube.
    order : (t,) int32
        Branch order of each tube's chain.
    tiles : (t,) float64
        Texture tiles around each tube (a whole number).
    ring_center, ring_tangent, ring_axis : (R, 3) float64
        Each ring's centre, the normal of its plane (the mean direction of the
        segments meeting there) and the direction of its first vertex (``u = 0``),
        before any bark displacement; ``R = rings.sum()``, tube after tube.
    ring_radius, ring_v : (R,) float64
        Each ring's radius and texture ``v``.
    """

    points: np.ndarray
    wedge_point: np.ndarray
    wedge_normal: np.ndarray
    wedge_uv: np.ndarray
    faces: np.ndarray
    point_offsets: np.ndarray
    wedge_offsets: np.ndarray
    face_offsets: np.ndarray
    chain: np.ndarray
    sides: np.ndarray
    rings: np.ndarray
    order: np.ndarray
    tiles: np.ndarray
    ring_center: np.ndarray
    ring_tangent: np.ndarray
    ring_axis: np.ndarray
    ring_radius: np.ndarray
    ring_v: np.ndarray

    def __len__(self) -> int:
        return len(self.point_offsets) - 1

    @classmethod
    def empty(cls) -> Tubes:
        z = np.zeros(1, np.int64)
        e = np.zeros(0, np.int64)
        v3 = np.zeros((0, 3))
        return cls(
            v3,
            e,
            np.zeros((0, 3), np.float32),
            np.zeros((0, 2), np.float32),
            np.zeros((0, 3), np.int64),
            z,
            z,
            z,
            e,
            e,
            e,
            np.zeros(0, np.int32),
            np.zeros(0),
            v3,
            v3,
            v3,
            np.zeros(0),
            np.zeros(0),
        )

    @property
    def face_points(self) -> np.ndarray:
        """Triangles as point indices, ``(F, 3) int64``."""
        return self.wedge_point[self.faces]

    @property
    def ring_offsets(self) -> np.ndarray:
        """CSR offsets of each tube's rings, ``(t + 1,) int64``."""
        return offsets(self.rings)

    def face_kinds(self, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Of the faces ``face`` (indices into ``faces``): each one's tube, and its cap (``2 tube`` at the base,
        ``2 tube + 1`` at the tip, -1 on the wall), ``(f,) int64`` each."""
        tube, cap = np.empty(len(face), np.int64), np.empty(len(face), np.int64)
        _face_kinds(np.ascontiguousarray(face), self.face_offsets, self.sides, self.rings, tube, cap)
        return tube, cap

    def bounds(self) -> np.ndarray:
        """Axis-aligned box of each tube, ``(t, 2, 3)``."""
        if not len(self):
            return np.zeros((0, 2, 3))
        starts = self.point_offsets[:-1]
        lo = np.minimum.reduceat(self.points, starts, axis=0)
        hi = np.maximum.reduceat(self.points, starts, axis=0)
        return np.stack([lo, hi], axis=1)

    def volumes(self) -> np.ndarray:
        """Enclosed volume of each tube, ``(t,) float64`` (divergence theorem)."""
        if not len(self):
            return np.zeros(0)
        tri = self.points[self.face_points]
        six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
        return np.add.reduceat(six, self.face_offsets[:-1]) / 6.0

    def select(self, which) -> Tubes:
        """The tubes ``which`` (indices or a boolean mask), renumbered."""
        which = np.arange(len(self))[which]
        pts, p_old, p_new = gather(self.point_offsets, which)
        wed, w_old, w_new = gather(self.wedge_offsets, which)
        fac, _, f_new = gather(self.face_offsets, which)
        rng, _, _ = gather(self.ring_offsets, which)
        wedge_point = self.wedge_point[wed] - np.repeat(p_old - p_new[:-1], np.diff(w_new))
        faces = self.faces[fac] - np.repeat(w_old - w_new[:-1], np.diff(f_new))[:, None]
        return Tubes(
            self.points[pts],
            wedge_point,
            self.wedge_normal[wed],
            self.wedge_uv[wed],
            faces,
            p_new,
            w_new,
            f_new,
            self.chain[which],
            self.sides[which],
            self.rings[which],
            self.order[which],
            self.tiles[which],
            self.ring_center[rng],
            self.ring_tangent[rng],
            self.ring_axis[rng],
            self.ring_radius[rng],
            self.ring_v[rng],
        )

    def insert_rings(
        self, tube: np.ndarray, ring: np.ndarray, t: np.ndarray, *, origin: bool = False, shading: bool = True
    ):
        """These tubes with new rings between existing ones, each vertex interpolated along its wall edge.

        A new ring goes into tube ``tube[i]`` between its rings ``ring[i]`` and
        ``ring[i] + 1``, at the fraction ``0 < t[i] < 1`` of the way: vertex
        ``j`` of the new ring lies on the wall edge joining vertex ``j`` of the
        two rings, and its normal and uv are interpolated the same way.  On a
        span whose wall quads are planar (a straight, linearly tapered piece of
        tube, :func:`straight_spans`) the surface does not change; elsewhere it
        moves by at most the quads' distance from planar.  The existing points
        keep their exact values.

        With ``origin=True``, returns ``(tubes, face_origin)``: for each face of
        the new tubes, the face of these tubes it lies in (a wall face of a
        split span: the face of the same quad and half in the span it splits;
        a cap face: the same cap face).  Without ``shading`` (for a caller that
        reads the points alone) the new tubes' wedge normals and uv are zeros
        that take no memory (read-only views of one row).
        """
        tube, ring, t = (np.asarray(x) for x in (tube, ring, t))
        if not len(tube):
            return (self, np.arange(len(self.faces))) if origin else self
        nt, sides, rings = len(self), self.sides, self.rings
        all_tube = np.concatenate([np.repeat(np.arange(nt), rings), tube.astype(np.int64)])
        all_ring = np.concatenate([local_index(rings), ring.astype(np.int64)])
        all_t = np.concatenate([np.zeros(int(rings.sum())), t.astype(np.float64)])
        order = np.lexsort((all_t, all_ring, all_tube))
        rt, rk, rf = all_tube[order], all_ring[order], all_t[order]
        new_rings = np.bincount(rt, minlength=nt)
        local = local_index(new_rings)
        p_off = offsets(new_rings * sides + 2)
        w_off = offsets((new_rings + 2) * (sides + 1))
        f_off = offsets(2 * sides * new_rings)

        points = np.empty((p_off[-1], 3))
        nw = w_off[-1]
        wedge_point = np.empty(nw, np.int64)
        wedge_normal = np.empty((nw if shading else 0, 3), np.float32)
        wedge_uv = np.empty((nw if shading else 0, 2), np.float32)
        _ring_rows(
            (points, wedge_point, wedge_normal, wedge_uv),
            (self.points, self.wedge_normal, self.wedge_uv),
            rt,
            rk,
            rf,
            local,
            sides,
            (self.point_offsets, self.wedge_offsets, p_off, w_off),
        )
        points[p_off[1:] - 2] = self.points[self.point_offsets[1:] - 2]
        points[p_off[1:] - 1] = self.points[self.point_offsets[1:] - 1]
        # caps: centre and rim, base then tip, as they were; the rims point at the first and last ring
        cap_len = 2 * (sides + 1)
        cap_tube = np.repeat(np.arange(nt), cap_len)
        jc = local_index(cap_len)
        src = self.wedge_offsets[cap_tube] + rings[cap_tube] * (sides[cap_tube] + 1) + jc
        dest = w_off[cap_tube] + new_rings[cap_tube] * (sides[cap_tube] + 1) + jc
        if shading:
            wedge_normal[dest] = self.wedge_normal[src]
            wedge_uv[dest] = self.wedge_uv[src]
        else:
            wedge_normal = np.broadcast_to(np.zeros(3, np.float32), (nw, 3))
            wedge_uv = np.broadcast_to(np.zeros(2, np.float32), (nw, 2))
        s_c = sides[cap_tube]
        tip = jc > s_c
        jj = np.where(tip, jc - s_c - 1, jc)  # 0: centre, 1..s: rim
        rim_ring = np.where(tip, new_rings[cap_tube] - 1, 0)
        wedge_point[dest] = np.where(
            jj == 0, p_off[cap_tube + 1] - np.where(tip, 1, 2), p_off[cap_tube] + rim_ring * s_c + jj - 1
        )

        faces = np.empty((f_off[-1], 3), np.int64)
        for s in unique(sides).tolist():
            which = np.flatnonzero(sides == s)
            _tube_faces(faces, s, new_rings[which], w_off[which], f_off[which])
        # the rings themselves: an inserted ring lies on its span, perpendicular to it (as _insert_rings makes them)
        old_ring = self.ring_offsets[rt] + rk
        nxt = np.minimum(old_ring + 1, len(self.ring_center) - 1)
        moved = rf > 0
        fm = rf[moved][:, None]
        ring_center = self.ring_center[old_ring]
        ring_center[moved] = (1.0 - fm) * self.ring_center[old_ring[moved]] + fm * self.ring_center[nxt[moved]]
        ring_radius = self.ring_radius[old_ring]
        ring_radius[moved] = (1.0 - fm[:, 0]) * ring_radius[moved] + fm[:, 0] * self.ring_radius[nxt[moved]]
        ring_v = self.ring_v[old_ring]
        ring_v[moved] = (1.0 - fm[:, 0]) * ring_v[moved] + fm[:, 0] * self.ring_v[nxt[moved]]
        ring_tangent = self.ring_tangent[old_ring]
        ring_axis = self.ring_axis[old_ring]
        d = unit(self.ring_center[nxt[moved]] - self.ring_center[old_ring[moved]])
        ring_axis[moved] = _reflect_transport(ring_axis[moved], ring_tangent[moved], d)
        ring_tangent[moved] = d
        new = replace(  # the same tubes (chain, sides, order, tiles) with more rings
            self,
            points=points,
            wedge_point=wedge_point,
            wedge_normal=wedge_normal,
            wedge_uv=wedge_uv,
            faces=faces,
            point_offsets=p_off,
            wedge_offsets=w_off,
            face_offsets=f_off,
            rings=new_rings,
            ring_center=ring_center,
            ring_tangent=ring_tangent,
            ring_axis=ring_axis,
            ring_radius=ring_radius,
            ring_v=ring_v,
        )
        if not origin:
            return new
        # each new face's face before: wall faces by the span their first ring splits, caps as they were
        face_origin = np.empty(f_off[-1], np.int64)
        _face_origin(face_origin, f_off, sides, new_rings, offsets(new_rings), rings, rk, self.face_offsets)
        return new, face_origin

    def mesh(self, i: int | None = None) -> Mesh:
        """Tube ``i`` (or all tubes, as one tube soup) as a welded :class:`~lsys3d.mesh.mesh.Mesh`.

        Its ``face_source`` is each triangle's index in :attr:`faces`.
        """
        if i is None:
            tubes, source = self, np.arange(len(self.faces))
        else:
            tubes, source = self.select([i]), np.arange(self.face_offsets[i], self.face_offsets[i + 1])
        normals, uv = tubes.wedge_normal[tubes.faces], tubes.wedge_uv[tubes.faces]
        return Mesh(tubes.points, tubes.face_points, normals, uv, face_source=source)

    def uv_at(self, face: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Texture coordinates of ``points`` (k, 3) or (k, m, 3) in the chart of the tube faces ``face`` (k,).

        The chart of a wall face is its tube's cylinder coordinates about the
        span the face belongs to: ``u`` from the angle around the span's axis
        (measured in the tube's twist-free frame, so a ring vertex gets
        exactly its own ``u``), ``v`` from the position along it (the share of
        the way from one ring's plane to the next's, so every vertex of a
        tilted joint ring gets the ring's ``v``); a cap's chart is planar.
        This is what lets a stage that moves or adds vertices (the cleanup)
        give them texture coordinates that match the tube's: points need not
        lie on the face.  ``u`` is in ``[0, tiles)``; wrap it per triangle
        (:func:`wrap_u`, or :meth:`corner_uv`, which does).  Returns ``points``' shape with 2 in place of 3.
        """
        face = np.asarray(face, np.int64)
        points = np.asarray(points, np.float64)
        flat = np.ascontiguousarray(points.reshape(-1, 3))
        corners = np.arange(len(flat), dtype=np.int64).reshape(len(face), -1)
        uv = np.empty((*corners.shape, 2))
        _uv_at(face, flat, corners, False, uv, 0, len(face), *self._charts())
        return uv.reshape((*points.shape[:-1], 2))

    def corner_uv(
        self, face: np.ndarray, points: np.ndarray, faces: np.ndarray, out: np.ndarray, lo: int = 0, hi: int = -1
    ) -> np.ndarray:
        """Corner uv of triangles ``faces[lo:hi]`` (vertices of ``points``) into ``out[lo:hi]`` ``(f, 3, 2)``.

        Each corner in the chart of its triangle's tube face ``face`` (:meth:`uv_at`),
        wrapped per triangle as :func:`wrap_u` does; one compiled pass, no
        temporaries (two ranges may be filled by two threads at once).
        """
        hi = len(faces) if hi < 0 else hi
        _uv_at(face, points, faces, True, out, lo, hi, *self._charts())
        return out

    def _charts(self) -> tuple:
        """What :func:`_uv_at` reads of the tubes."""
        return (
            self.face_offsets,
            self.sides,
            self.rings,
            self.ring_offsets,
            self.ring_center,
            self.ring_tangent,
            self.ring_axis,
            self.ring_v,
            self.ring_radius,
            np.asarray(self.tiles, np.float64),
        )


@numba.njit(cache=True, nogil=True, inline="always")
def _face_place(face, offsets, sides, rings, t):  # pragma: no cover - compiled
    """Where tube face ``face`` lies: its tube (``t``, the tube of the face before, is tried first: the faces of
    a tube come together), its index among the tube's faces, and its end: -1 on the wall, 0 in the base's cap, 1
    in the tip's (a tube has ``2 s (rings - 1)`` wall faces, then ``s`` at its base and ``s`` at its tip)."""
    if t < 0 or not (offsets[t] <= face < offsets[t + 1]):
        t = np.searchsorted(offsets, face, side="right") - 1
    local = face - offsets[t]
    body = 2 * sides[t] * (rings[t] - 1)
    return t, local, -1 if local < body else (1 if local >= body + sides[t] else 0)


@numba.njit(cache=True, nogil=True)
def _face_kinds(face, offsets, sides, rings, tube, cap):  # pragma: no cover - compiled
    """:meth:`Tubes.face_kinds` into ``tube`` and ``cap`` (:func:`_face_place`)."""
    t = -1
    for i in range(len(face)):
        t, _, end = _face_place(face[i], offsets, sides, rings, t)
        tube[i] = t
        cap[i] = -1 if end < 0 else 2 * t + end


@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
def _span_frame(center, tangent, axis, r0, r1):  # pragma: no cover - compiled
    """The chart's frame of the span from ring ``r0`` to ``r1``: ring ``r0``'s axis carried onto the span's
    direction by the minimal rotation (two reflections), and the direction's cross product with it."""
    dx, dy, dz = center[r1, 0] - center[r0, 0], center[r1, 1] - center[r0, 1], center[r1, 2] - center[r0, 2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length > 0:
        dx, dy, dz = dx / length, dy / length, dz / length
    else:
        dx, dy, dz = tangent[r0, 0], tangent[r0, 1], tangent[r0, 2]
    ux, uy, uz = axis[r0, 0], axis[r0, 1], axis[r0, 2]
    nx, ny, nz = tangent[r0, 0] + dx, tangent[r0, 1] + dy, tangent[r0, 2] + dz
    f = 2.0 * (ux * nx + uy * ny + uz * nz) / max(nx * nx + ny * ny + nz * nz, 1e-30)
    ux, uy, uz = ux - f * nx, uy - f * ny, uz - f * nz
    f = 2.0 * (ux * dx + uy * dy + uz * dz)
    ux, uy, uz = ux - f * dx, uy - f * dy, uz - f * dz
    f = ux * dx + uy * dy + uz * dz
    ux, uy, uz = ux - f * dx, uy - f * dy, uz - f * dz
    f = np.sqrt(ux * ux + uy * uy + uz * uz)
    if f > 0:
        ux, uy, uz = ux / f, uy / f, uz / f
    return ux, uy, uz, dy * uz - dz * uy, dz * ux - dx * uz, dx * uy - dy * ux


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


def _reflect_transport(u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Carry ``u`` (perpendicular to unit ``a``) to unit ``b`` by the minimal rotation.

    The rotation is the product of two reflections: in the plane normal to
    ``a + b`` (which maps ``a`` to ``-b``) and in the plane normal to ``b``.
    """
    n = a + b
    u = u - (2.0 * dot(u, n) / np.maximum(dot(n, n), 1e-30))[:, None] * n
    u = u - (2.0 * dot(u, b))[:, None] * b
    # remove drift so the frame stays orthonormal over long chains
    return unit(u - dot(u, b)[:, None] * b)


def _perpendicular(d: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """``hint`` made perpendicular to unit ``d`` and unit (any perpendicular if parallel)."""
    u = hint - dot(hint, d)[:, None] * d
    bad = np.linalg.norm(u, axis=1) < 1e-6
    if bad.any():
        axis = np.where(np.abs(d[bad, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        u[bad] = np.cross(d[bad], axis)
    return unit(u)


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
        group = _merge_groups(chain, p0, p1, v0, v1, w0, w1, opt.merge_deviation, 1e-9 * (np.abs(p1).max() + 1.0))
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
        seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate, pinned = _fork_bases(
            skeleton, opt, chain_sides, seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate
        )
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

    parts = []
    for s in unique(sides_of_piece).tolist():
        pieces = np.flatnonzero(sides_of_piece == s)
        rsel = np.flatnonzero(sides_of_piece[ring_piece] == s)
        parts.append(
            (
                pieces,
                _build(
                    s,
                    rings[pieces],
                    center[rsel],
                    tangent[rsel],
                    axis_a[rsel],
                    axis_b[rsel],
                    radius[rsel],
                    slope[rsel],
                    tv[rsel],
                    stretch[rsel],
                    bend_dir[rsel],
                    tiles[chain_of_piece[pieces]],
                    displace,
                ),
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


FORK_RATIO = 0.5
"""A child at least this fraction of its parent's width gets a blended base (:func:`_fork_bases`)."""
FORK_PIECES = 3
"""Spans of a blended base: its bend turns at most a quarter of the child's lean at each of its rings."""
FORK_WAIST = 0.97
"""A blended base starts this fraction of the parent's inner radius wide (``r cos(pi / sides)``, the middle of
its faces), so it starts inside the parent."""


def _fork_bases(skeleton: Skeleton, opt: SweepOptions, chain_sides, seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate):
    """The kept segments with a blended base at the start of each thick child: ``seg ... rate`` with rows added,
    and which of them end at a ring of a curve (``pinned``: no ``merge_angle`` leaves it out).

    A child as thick as its parent that leans out of it (tree3d's trunk-top
    fork: three children as wide as the trunk, 23 degrees out) makes a ledge:
    its straight tube leaves the parent's wall all at once, turning the
    outline by the whole lean in one crease that no collar of the cleanup is
    wide enough to round.  So the first ``delta = blend * r`` metres of such
    a child are swept along a quadratic Bezier curve instead of the straight
    segment: from ``delta`` back along the parent's heading, through the
    control point at the fork, to ``delta`` along the child, in
    ``FORK_PIECES`` spans.  The child leaves the parent's wall along it and
    bends out ring by ring: the outline turns by a fraction of the lean at
    each ring, which the smooth normals and the collars blend.

    A child that starts a chain begins inside its parent, ``FORK_WAIST`` of
    the parent's inner radius wide; the child that goes on in its parent's chain
    (the continuation, one of the fork's children too) has the last ``delta``
    of its parent's segment replaced by the curve.  Beyond the curve the
    tubes are unchanged; within it the axis stays within ``delta * |c - a| / 4``
    of the straight one.  A child thinner than ``FORK_RATIO`` of its parent or
    than ``fork_blend_min`` of the plant's size (the diagonal of the
    skeleton's box: at 0.002 a child under 2 pixels wide in a 1,000-pixel
    picture of the whole plant, whose ledge cannot be seen), one that does
    not start at its parent's end, one that leans less than a degree or more
    than 90, one whose curve does not fit in 0.45 of its own and its parent's
    segment (short thick segments: a crowd, where curves would only add
    pieces that touch), and a bend where no other branch leaves, are left as
    they are.
    """
    k = len(seg)
    none = (seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate, np.zeros(k, bool))
    if k == 0:
        return none
    head = np.concatenate([[True], chain[1:] != chain[:-1]])
    parent = skeleton.parent[seg]
    children = np.bincount(parent[parent >= 0], minlength=len(skeleton))
    previous = np.concatenate([[-1], seg[:-1]])
    # a chain's first row, or a row going on from its parent's row at a fork
    on = ~head & (previous == parent) & (children[np.maximum(parent, 0)] > 1)
    rows = np.flatnonzero((parent >= 0) & (head | on))
    if not len(rows):
        return none
    par = parent[rows]
    ps, pe = skeleton.start[par].astype(np.float64), skeleton.end[par].astype(np.float64)
    parent_length = np.linalg.norm(pe - ps, axis=1)
    a = (pe - ps) / np.maximum(parent_length, 1e-300)[:, None]
    length = np.linalg.norm(p1[rows] - p0[rows], axis=1)
    c = (p1[rows] - p0[rows]) / np.maximum(length, 1e-300)[:, None]
    lean = np.degrees(np.arccos(np.clip(dot(a, c), -1.0, 1.0)))
    w_parent = skeleton.width_end[par]
    scale = np.abs(p1).max() + 1.0
    cont = on[rows]
    room = np.where(cont, np.linalg.norm(p1[rows - cont] - p0[rows - cont], axis=1), parent_length)
    # the whole curve fits in 0.45 of either segment (a segment may lose as much at each end: a child that is a
    # fork itself), or there is no blend: segments shorter than a blend are a crowd of short thick pieces (the
    # constant-width fern), where a curve in each would only add pieces that touch (over the union's limit)
    delta = opt.fork_blend * 0.5 * w0[rows]
    fits = delta <= 0.45 * np.minimum(length, room)
    size = float(np.linalg.norm(np.diff(skeleton.bounds(), axis=0)))
    ok = (
        (w0[rows] >= FORK_RATIO * w_parent)
        & (w0[rows] >= opt.fork_blend_min * size)
        & (np.linalg.norm(p0[rows] - pe, axis=1) <= 1e-9 * scale)
        & (lean >= 1.0)
        & (lean <= 90.0)
        & (delta > 0)
        & fits
    )
    if not ok.any():
        return none
    rows, a, c, delta, length, w_parent, cont = rows[ok], a[ok], c[ok], delta[ok], length[ok], w_parent[ok], cont[ok]
    before = rows - 1  # the parent's row, for a continuation
    n, m = len(rows), FORK_PIECES
    t = np.linspace(0.0, 1.0, m + 1)[None, :]
    fork = p0[rows]
    start = fork - delta[:, None] * a
    end = fork + delta[:, None] * c
    tt = t[..., None]
    curve = (1 - tt) ** 2 * start[:, None] + 2 * tt * (1 - tt) * fork[:, None] + tt**2 * end[:, None]  # (n, m+1, 3)
    f = delta / length  # the share of the child's first segment the curve replaces
    w_end = w0[rows] + f * (w1[rows] - w0[rows])
    tv_end = tv0[rows] + f * (tv1[rows] - tv0[rows])
    b = np.where(cont, before, 0)
    g = delta / np.maximum(np.linalg.norm(p1[b] - p0[b], axis=1), 1e-300)  # the share of the parent's row, likewise
    waist = FORK_WAIST * np.cos(np.pi / chain_sides[skeleton.chains.chain_of[par[ok]]]) * w_parent
    w_start = np.where(cont, w1[b] - g * (w1[b] - w0[b]), np.minimum(w0[rows], waist))
    tv_start = np.where(cont, tv1[b] - g * (tv1[b] - tv0[b]), 2 * tv0[rows] - tv_end)
    width = w_start[:, None] + t * (w_end - w_start)[:, None]
    tv = tv_start[:, None] + t * (tv_end - tv_start)[:, None]
    v = (v0[rows] - delta)[:, None] + t * (2 * delta)[:, None]
    # the continuations' parent rows now end where the curve starts
    p1, w1, v1, tv1 = p1.copy(), w1.copy(), v1.copy(), tv1.copy()
    bc = before[cont]
    p1[bc], w1[bc], v1[bc], tv1[bc] = start[cont], w_start[cont], v[cont, 0], tv_start[cont]
    # the m spans of each curve come before what is left of its child's first segment
    is_row = np.zeros(k, np.int64)
    is_row[rows] = 1
    place = np.arange(k) + m * np.cumsum(is_row)
    out = np.empty(k + n * m, np.int64)
    out[place] = np.arange(k)
    first = place[rows]
    spans = (first[:, None] - m + np.arange(m)[None, :]).ravel()
    out[spans] = np.repeat(rows, m)
    seg, chain, rate = seg[out], chain[out], rate[out]
    p0, p1, v0, v1, w0, w1, tv0, tv1 = (x[out] for x in (p0, p1, v0, v1, w0, w1, tv0, tv1))
    p0[spans], p1[spans] = curve[:, :-1].reshape(-1, 3), curve[:, 1:].reshape(-1, 3)
    w0[spans], w1[spans] = width[:, :-1].ravel(), width[:, 1:].ravel()
    v0[spans], v1[spans] = v[:, :-1].ravel(), v[:, 1:].ravel()
    tv0[spans], tv1[spans] = tv[:, :-1].ravel(), tv[:, 1:].ravel()
    p0[first], w0[first], v0[first], tv0[first] = end, w_end, v[:, -1], tv_end
    # the curve's rings (and the one where a continuation's curve starts) are its shape: merge_angle keeps them
    pinned = np.zeros(k + n * m, bool)
    pinned[spans] = True
    pinned[place[bc]] = True
    return seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate, pinned


def _seam_side(skeleton: Skeleton, seg: np.ndarray) -> np.ndarray:
    """Where the seam (``u = 0``) of the chains whose first kept segments are ``seg`` starts: the turtle's down.

    The seam of a texture rarely matches perfectly; it goes where it is least
    seen.  It is placed by the plant's own frame, not the world's, so that
    congruent parts of a plant (the same junction drawn again, turned) get
    congruent texture coordinates, and :mod:`lsys3d.mesh.union.repeats` unions them
    once.  The seam faces the turtle's down (``-U``) at the base of each
    chain; the twist-free frame carries it along the chain.  For the default
    turtle (heading +Y, up +Z) that is -Z at the trunk: the back of a glTF
    asset, whose front is +Z.  Turns (``+``, ``-``) keep ``U``, so a plant drawn
    in a plane has every seam at its back; a branch pitched down (``&``) from
    an upright stem has ``U`` tilted to the sky and its seam underneath, one
    pitched up (``^``) has it on top.
    """
    return -skeleton.up[seg]


def _transport(u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`_reflect_transport`, and ``u`` itself where ``b`` turns right back along ``a`` (a split chain)."""
    back = dot(a, b) < -1.0 + 1e-9
    if not back.any():
        return _reflect_transport(u, a, b)
    out = np.empty_like(u)
    out[~back] = _reflect_transport(u[~back], a[~back], b[~back])
    out[back] = _perpendicular(b[back], u[back])
    return out


def _inverse_mean(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """The mean of ``1 / r`` over a linear taper from ``r0`` to ``r1``: ``log(r1 / r0) / (r1 - r0)``."""
    x = (r1 - r0) / r0
    small = np.abs(x) < 1e-6
    return np.where(small, 1.0 - 0.5 * x, np.log1p(np.where(small, 0.0, x)) / np.where(small, 1.0, x)) / r0


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


@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
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


@numba.njit(cache=True, nogil=True)
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


def _tube_faces(faces: np.ndarray, s: int, rings: np.ndarray, wedge_start: np.ndarray, face_start: np.ndarray) -> None:
    """Write the faces of tubes of ``s`` sides into ``faces`` (in place): the one layout every tube has.

    Tube ``i`` has ``rings[i]`` rings of ``s + 1`` wedges from ``wedge_start[i]``, then the base and tip cap
    (centre and rim, ``s + 1`` wedges each); its ``2 s (rings[i] - 1)`` wall faces (two per quad, ring after
    ring) and ``2 s`` cap faces (base fan, tip fan) start at ``face_start[i]``.
    """
    if len(rings):
        _write_tube_faces(faces, s, np.asarray(rings, np.int64), wedge_start, face_start)


@numba.njit(cache=True, nogil=True)
def _write_tube_faces(faces, s, rings, wedge_start, face_start):  # pragma: no cover - compiled
    """:func:`_tube_faces`, a face at a time: no (spans, 2 s, 3) index temporaries."""
    for i in range(len(rings)):
        f = face_start[i]
        for k in range(rings[i] - 1):  # wall quads: (j, j + 1, j + s + 2) and (j, j + s + 2, j + s + 1)
            w = wedge_start[i] + k * (s + 1)
            for j in range(s):
                faces[f, 0], faces[f, 1], faces[f, 2] = w + j, w + j + 1, w + j + s + 2
                faces[f + 1, 0], faces[f + 1, 1], faces[f + 1, 2] = w + j, w + j + s + 2, w + j + s + 1
                f += 2
        base = wedge_start[i] + rings[i] * (s + 1)  # base cap fan (0, j + 2, j + 1), tip fan reversed
        tip = base + s + 1
        for j in range(s):
            nxt = j + 2 if j < s - 1 else 1  # the rim wraps
            faces[f, 0], faces[f, 1], faces[f, 2] = base, base + nxt, base + j + 1
            faces[f + s, 0], faces[f + s, 1], faces[f + s, 2] = tip, tip + j + 1, tip + nxt
            f += 1


def _build(
    s, rings, center, tangent, axis_a, axis_b, radius, slope, v, stretch, bend_dir, tiles, displace=None
) -> Tubes:
    """Tubes of ``s`` sides; ring arrays hold the rings of every tube, tube after tube.

    ``v`` is each ring's texture ``v``, ``tiles`` each tube's tiles around.
    ``displace(points (k, 3)) -> (k,)`` moves each ring vertex along its radial
    direction by that fraction of the ring's radius; the ring normals are then
    taken from the displaced surface.
    """
    nt = len(rings)
    n = len(center)
    theta = 2.0 * np.pi * np.arange(s + 1) / s
    c, si = np.cos(theta), np.sin(theta)
    c[s], si[s] = 1.0, 0.0
    radial = c[None, :, None] * axis_a[:, None, :] + si[None, :, None] * axis_b[:, None, :]  # (n, s+1, 3)
    off = radius[:, None, None] * radial
    off += ((stretch - 1.0)[:, None] * dot(off, bend_dir[:, None, :]))[:, :, None] * bend_dir[:, None, :]
    ring_pts = center[:, None, :] + off[:, :s]
    if displace is not None:
        bump = displace(ring_pts.reshape(-1, 3)).reshape(n, s) * radius[:, None]
        ring_pts = ring_pts + bump[:, :, None] * radial[:, :s]
    normal = unit(radial - slope[:, None, None] * tangent[:, None, :])

    p_off = offsets(rings * s + 2)
    w_off = offsets((rings + 2) * (s + 1))
    f_off = offsets(2 * s * rings)
    first_ring = offsets(rings)[:-1]
    tube_of_ring = np.repeat(np.arange(nt), rings)
    local = np.arange(n) - first_ring[tube_of_ring]
    jj = np.arange(s + 1)

    points = np.empty((p_off[-1], 3))
    points[(p_off[tube_of_ring] + local * s)[:, None] + jj[:s]] = ring_pts
    base = first_ring
    tip = first_ring + rings - 1
    points[p_off[1:] - 2] = center[base]
    points[p_off[1:] - 1] = center[tip]

    nw = w_off[-1]
    wedge_point = np.empty(nw, np.int64)
    wedge_normal = np.empty((nw, 3), np.float32)
    wedge_uv = np.empty((nw, 2), np.float32)
    ring_w = (w_off[tube_of_ring] + local * (s + 1))[:, None] + jj  # (n, s+1)
    wedge_point[ring_w] = (p_off[tube_of_ring] + local * s)[:, None] + jj % s
    wedge_normal[ring_w] = normal
    wedge_uv[ring_w, 0] = tiles[tube_of_ring][:, None] * jj / s
    wedge_uv[ring_w, 1] = v[:, None]
    # caps: centre then rim, base cap before tip cap; planar, as dense as the wall at their ring (Tubes.uv_at)
    half = 0.5 * tiles
    reach = tiles / (s * 2.0 * np.sin(np.pi / s))
    cap_w = (w_off[:-1] + rings * (s + 1))[:, None] + np.array([0, s + 1])  # (nt, 2)
    for which, ring, sign, centre_point in ((0, base, -1.0, p_off[1:] - 2), (1, tip, 1.0, p_off[1:] - 1)):
        cw = cap_w[:, which]
        wedge_point[cw] = centre_point
        rim = cw[:, None] + 1 + jj[:s]
        wedge_point[rim] = (p_off[:-1] + local[ring] * s)[:, None] + jj[:s]
        wedge_normal[cw] = sign * tangent[ring]
        wedge_normal[rim] = sign * tangent[ring][:, None, :]
        wedge_uv[cw] = np.stack([half, v[ring]], axis=1)
        wedge_uv[rim, 0] = half[:, None] + reach[:, None] * c[None, :s]
        wedge_uv[rim, 1] = v[ring][:, None] + reach[:, None] * si[None, :s]

    faces = np.empty((f_off[-1], 3), np.int64)
    _tube_faces(faces, s, rings, w_off[:-1], f_off[:-1])
    if displace is not None:
        _surface_normals(points, wedge_point, wedge_normal, faces, f_off, 2 * s * (rings - 1), ring_w)
    z = np.zeros(nt, np.int64)
    return Tubes(
        points,
        wedge_point,
        wedge_normal,
        wedge_uv,
        faces,
        p_off,
        w_off,
        f_off,
        z,
        z,
        rings,
        z.astype(np.int32),
        np.asarray(tiles, np.float64),
        center,
        tangent,
        axis_a,
        radius,
        v,
    )


def _surface_normals(points, wedge_point, wedge_normal, faces, f_off, body_faces, ring_w) -> None:
    """Set the ring wedges' normals to the area-weighted normals of the tube walls around their points.

    ``body_faces[t]`` is the number of wall faces (before the caps) of tube ``t``;
    the caps keep their flat normals.
    """
    tube_of_face = np.repeat(np.arange(len(body_faces)), np.diff(f_off))
    body = np.flatnonzero(np.arange(len(faces)) - f_off[tube_of_face] < body_faces[tube_of_face])
    fp = wedge_point[faces[body]]
    tri = points[fp]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    pn = np.zeros((len(points), 3))
    for c in range(3):
        pn[:, c] = sum(np.bincount(fp[:, k], weights=fn[:, c], minlength=len(points)) for k in range(3))
    wedge_normal[ring_w] = unit(pn)[wedge_point[ring_w]]


def _concat(parts: list[Tubes]) -> Tubes:
    """Tubes of several :func:`_build` calls, one after another (indices shifted)."""
    if len(parts) == 1:
        return parts[0]
    p_shift = np.cumsum([0] + [len(t.points) for t in parts[:-1]])
    w_shift = np.cumsum([0] + [len(t.wedge_point) for t in parts[:-1]])
    f_shift = np.cumsum([0] + [len(t.faces) for t in parts[:-1]])

    def shifted(name, shift):
        return np.concatenate([[0]] + [getattr(t, name)[1:] + sh for t, sh in zip(parts, shift, strict=True)])

    return Tubes(
        np.concatenate([t.points for t in parts]),
        np.concatenate([t.wedge_point + sh for t, sh in zip(parts, p_shift, strict=True)]),
        np.concatenate([t.wedge_normal for t in parts]),
        np.concatenate([t.wedge_uv for t in parts]),
        np.concatenate([t.faces + sh for t, sh in zip(parts, w_shift, strict=True)]),
        shifted("point_offsets", p_shift),
        shifted("wedge_offsets", w_shift),
        shifted("face_offsets", f_shift),
        *(
            np.concatenate([getattr(t, name) for t in parts])
            for name in (
                "chain",
                "sides",
                "rings",
                "order",
                "tiles",
                "ring_center",
                "ring_tangent",
                "ring_axis",
                "ring_radius",
                "ring_v",
            )
        ),
    )
