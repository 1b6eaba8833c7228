"""The tube soup (:class:`Tubes`): points, wedges and faces of every tube, built from the rings, and joined."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ...arrays import dot, gather, local_index, offsets, unique, unit
from ...compiling import kernel
from ..mesh import Mesh
from .frames import _reflect_transport
from .rings import _face_origin, _ring_rows
from .uv import _face_kinds, _uv_at


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


def _tube_faces(faces: np.ndarray, s: int, rings: np.ndarray, wedge_start: np.ndarray, face_start: np.ndarray) -> None:
    """Write the faces of tubes of ``s`` sides into ``faces`` (in place): the one layout every tube has.

    Tube ``i`` has ``rings[i]`` rings of ``s + 1`` wedges from ``wedge_start[i]``, then the base and tip cap
    (centre and rim, ``s + 1`` wedges each); its ``2 s (rings[i] - 1)`` wall faces (two per quad, ring after
    ring) and ``2 s`` cap faces (base fan, tip fan) start at ``face_start[i]``.
    """
    if len(rings):
        _write_tube_faces(faces, s, np.asarray(rings, np.int64), wedge_start, face_start)


@kernel(nogil=True)
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


class RingRows(NamedTuple):
    """The rings of tubes, a row each, tube after tube: what :func:`_build` makes tubes of."""

    center: np.ndarray
    """(n, 3) float64: the ring's centre."""
    tangent: np.ndarray
    """(n, 3) float64: the unit normal of its plane."""
    axis_a: np.ndarray
    """(n, 3) float64: the frame's first axis in that plane (the texture's seam)."""
    axis_b: np.ndarray
    """(n, 3) float64: the second."""
    radius: np.ndarray
    """(n,) float64"""
    slope: np.ndarray
    """(n,) float64: how fast the radius shrinks along the tangent (the normals lean by it)."""
    v: np.ndarray
    """(n,) float64: the texture's v."""
    stretch: np.ndarray
    """(n,) float64: how far the ring is stretched across a bend (``1 / cos(bend / 2)``; 1 without a bend)."""
    bend_dir: np.ndarray
    """(n, 3) float64: the direction it is stretched in."""

    def take(self, rows) -> RingRows:
        """The rings ``rows``."""
        return RingRows(*(a[rows] for a in self))


def _build(s, rings, ring_rows: RingRows, tiles, displace=None) -> Tubes:
    """Tubes of ``s`` sides; ``ring_rows`` holds the rings of every tube (``rings`` of them each), tube after tube.

    ``v`` is each ring's texture ``v``, ``tiles`` each tube's tiles around.
    ``displace(points (k, 3)) -> (k,)`` moves each ring vertex along its radial
    direction by that fraction of the ring's radius; the ring normals are then
    taken from the displaced surface.
    """
    center, tangent, axis_a, axis_b, radius, slope, v, stretch, bend_dir = ring_rows
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
