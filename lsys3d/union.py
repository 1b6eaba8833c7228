"""Union: tubes -> one watertight bark mesh, through manifold3d.

This module is the boundary with manifold3d: every Manifold it builds or
computes has its status checked here, and a problem raises
:class:`~lsys3d.errors.GeometryError` naming the part and the status; an
empty or broken mesh is never returned.

How the union stays fast
------------------------
A boolean in manifold costs time for every triangle it is given, touched or
not, and more for every triangle an intersection cuts.  So the tubes are not
unioned one by one, nor in one batch (manifold's own batch union groups
operands by bounding box, and the box of a long branch overlaps nearly
everything):

1. *Which tubes can touch.*  Each tube is covered by capsules, one per span
   (the piece between two neighbouring rings: the centroids of the two rings
   and the farthest ring vertex as radius).  The span boxes are hashed into a
   uniform grid and candidate pairs are confirmed with a segment-segment
   distance.  In a tree this leaves little more than the junctions: a branch
   meets its parent and its siblings.
2. *Only junctions go through the boolean* (``UnionOptions.local``).  A
   maximal run of spans of one tube that may touch another tube is closed
   with a temporary cap on each ring where it meets an untouched span and
   goes into the boolean; the untouched spans stay out.  Afterwards the
   temporary caps (found by their face ids) are removed and the untouched
   spans are welded back onto their rings (matched by exact position).  The
   seam and the result are checked (every directed edge once, its reverse
   once); if anything does not match, whole tubes are unioned instead.  When
   most spans touch something (every joint of ``monopodial`` carries a
   branch) the stitching would cost more than it saves and whole tubes go in.
3. *Layers instead of many operands.*  The may-touch graph (of runs, or of
   tubes) is coloured greedily; parts of one colour are pairwise disjoint, so
   each colour becomes one Manifold built from one mesh with no boolean at
   all (what ``Manifold.compose`` does, without building thousands of small
   Manifolds first).  A tree needs few colours (three for the benchmark
   trees); the layers are unioned with one ``Manifold.batch_boolean``, which
   manifold runs on all cores.

Shading attributes ride through the boolean as manifold vertex properties
(position, normal, uv: 8 channels).  The seam and cap wedges of each tube are
tied to their ring vertex with manifold's merge vectors, so manifold sees
closed meshes; new vertices on the intersection curves get interpolated
properties, and the normals are renormalised on the way out.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import manifold3d
import numpy as np

from .arrays import first_equal_row as _first_equal_row
from .arrays import gather
from .arrays import local_index as _local
from .arrays import offsets as _offsets
from .errors import GeometryError
from .mesh import Mesh, face_normals
from .options import Options, option
from .sweep import Tubes

__all__ = ["UnionOptions", "concatenate", "may_touch", "union"]

log = logging.getLogger("lsys3d")

_NUM_PROP = 8  # x y z, nx ny nz, u v


@dataclass(frozen=True)
class UnionOptions(Options):
    """Whether and how tubes are unioned; every default, range and help is in its field.

    ``layers`` groups pairwise-disjoint tubes into layers before the boolean
    (fast); off, every tube goes to ``Manifold.batch_boolean`` separately
    (manifold's own bounding-box grouping; slower, for comparison).
    ``local`` sends only the spans that may touch another tube through the
    boolean and stitches the rest of each tube back on (needs ``layers``),
    while at most ``local_max`` of the spans may touch.
    """

    enabled: bool = option(
        True, name="union", help="the union of the tubes into one watertight mesh (off: the tube soup, a fast preview)"
    )
    layers: bool = option(True, help="group pairwise-disjoint tubes into layers before the boolean", cli=False)
    local: bool = option(True, help="send only the spans that may touch through the boolean", cli=False)
    local_max: float = option(
        0.75, low=0, high=1, help="use the local path while at most this fraction of spans may touch", cli=False
    )
    margin: float = option(0.01, low=0, high=1, help="relative padding of the touch test", cli=False)


def concatenate(tubes: Tubes) -> Mesh:
    """All tubes as one tube-soup mesh (no boolean): the ``union=False`` bark.

    Each tube stays a closed, welded component; tubes may overlap.
    """
    return tubes.mesh()


def _check(manifold: manifold3d.Manifold, where: str) -> manifold3d.Manifold:
    status = manifold.status()
    if status != manifold3d.Error.NoError:
        raise GeometryError(f"{where}: manifold3d reported {status.name}")
    return manifold


def _manifold(tubes: Tubes, where: str, which=None) -> manifold3d.Manifold:
    """One Manifold of the whole (pairwise disjoint) tubes ``which`` (default all), attributes as properties.

    Each triangle's face id is its index in ``tubes.faces``, so the result can
    say which tube face every output triangle came from (``Mesh.face_source``).
    """
    which = np.arange(len(tubes))[slice(None) if which is None else which]
    part = tubes.select(which)
    return _manifold_of(part, part.faces, gather(tubes.face_offsets, which)[0], where)


class _Spans:
    """The spans of a set of tubes (the piece between two neighbouring rings), tube after tube.

    ``lo, hi (m, 3)`` box of the span's points; ``p, q (m, 3)`` centroids of its
    two rings and ``radius (m,)`` the farthest ring point from them, so the
    span lies inside the capsule ``p q`` of that radius; ``tube, local (m,)``.
    """

    def __init__(self, tubes: Tubes):
        rings, sides = tubes.rings, tubes.sides
        ring_sides = np.repeat(sides, rings)
        # ring points are every point but the two cap centres closing each tube
        mask = np.ones(len(tubes.points), bool)
        mask[tubes.point_offsets[1:] - 1] = False
        mask[tubes.point_offsets[1:] - 2] = False
        pts = tubes.points[mask]
        first = _offsets(ring_sides)[:-1]
        lo = np.minimum.reduceat(pts, first, axis=0)
        hi = np.maximum.reduceat(pts, first, axis=0)
        centre = np.add.reduceat(pts, first, axis=0) / ring_sides[:, None]
        dist = np.linalg.norm(pts - np.repeat(centre, ring_sides, axis=0), axis=1)
        radius = np.maximum.reduceat(dist, first)
        local_ring = _local(rings)
        a = np.flatnonzero(local_ring < np.repeat(rings, rings) - 1)  # first ring of each span
        self.lo = np.minimum(lo[a], lo[a + 1])
        self.hi = np.maximum(hi[a], hi[a + 1])
        self.p, self.q = centre[a], centre[a + 1]
        self.radius = np.maximum(radius[a], radius[a + 1])
        self.tube = np.repeat(np.arange(len(tubes)), rings)[a]
        self.local = local_ring[a]

    def __len__(self) -> int:
        return len(self.tube)


def _segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Distance between segments ``p1 q1`` and ``p2 q2`` (rows)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-300
    denom = a * e - b * b
    s = np.where(denom > tiny, np.clip((b * f - c * e) / np.maximum(denom, tiny), 0, 1), 0.0)
    t = np.where(e > tiny, (b * s + f) / np.maximum(e, tiny), 0.0)
    s = np.where(
        t < 0, np.clip(-c / np.maximum(a, tiny), 0, 1), np.where(t > 1, np.clip((b - c) / np.maximum(a, tiny), 0, 1), s)
    )
    t = np.clip(t, 0, 1)
    return np.linalg.norm(p1 + d1 * s[:, None] - p2 - d2 * t[:, None], axis=1)


def may_touch(tubes: Tubes, margin: float = 0.01) -> np.ndarray:
    """Pairs of tubes that may touch, ``(m, 2) int64`` with ``i < j``.

    Each tube is covered by capsules, one per span (the piece between two
    neighbouring rings); two tubes may touch when two of their capsules
    (radii padded by ``margin``) intersect.  Tubes that are not listed are
    disjoint; listed ones may or may not touch.
    """
    owner, a, b = _span_pairs(tubes, margin)
    if not len(a):
        return np.zeros((0, 2), np.int64)
    ta, tb = owner[a], owner[b]
    return np.unique(np.stack([np.minimum(ta, tb), np.maximum(ta, tb)], axis=1), axis=0)


def _span_pairs(tubes: Tubes, margin: float, spans: _Spans | None = None):
    """Spans of different tubes that may touch: ``owner (m,)`` (tube of each span), span pairs ``a, b``.

    Broad phase: span boxes hashed into a grid; narrow phase: the capsules
    around the spans (padded by ``margin``) intersect.
    """
    spans = _Spans(tubes) if spans is None else spans
    lo, hi, owner = spans.lo, spans.hi, spans.tube
    none = np.zeros(0, np.int64)
    if len(tubes) < 2:
        return owner, none, none
    pad = margin * (hi - lo).max(axis=1, keepdims=True) + 1e-9 * (np.abs(hi).max() + 1.0)
    lo, hi = lo - pad, hi + pad
    size = (hi - lo).max(axis=1)
    cell = max(float(np.median(size)), 1e-12)
    origin = lo.min(axis=0)
    for _ in range(20):  # grow the cells until the number of box-cell entries is modest
        c0 = np.floor((lo - origin) / cell).astype(np.int64)
        c1 = np.floor((hi - origin) / cell).astype(np.int64)
        ext = c1 - c0 + 1
        count = ext.prod(axis=1)
        if count.sum() <= 8 * len(lo) + 1000:
            break
        cell *= 1.5
    dims = c1.max(axis=0) + 1
    box = np.repeat(np.arange(len(lo)), count)
    k = _local(count)
    ex = ext[box]
    ix = c0[box, 0] + k % ex[:, 0]
    iy = c0[box, 1] + (k // ex[:, 0]) % ex[:, 1]
    iz = c0[box, 2] + k // (ex[:, 0] * ex[:, 1])
    key = (iz * dims[1] + iy) * dims[0] + ix
    srt = np.argsort(key, kind="stable")
    key, box = key[srt], box[srt]
    # every pair inside each cell: entry p pairs with the later entries of its cell
    brk = np.flatnonzero(np.diff(key)) + 1
    cell_end = np.repeat(np.append(brk, len(key)), np.diff(np.concatenate([[0], brk, [len(key)]])))
    later = cell_end - np.arange(len(key)) - 1
    a = np.repeat(np.arange(len(key)), later)
    b = a + 1 + _local(later)
    a, b = box[a], box[b]
    ok = owner[a] != owner[b]
    a, b = a[ok], b[ok]
    ok = ((lo[a] <= hi[b]) & (lo[b] <= hi[a])).all(axis=1)
    a, b = a[ok], b[ok]
    # a pair found in several cells counts once
    pair = np.unique(np.minimum(a, b) * len(lo) + np.maximum(a, b))
    a, b = pair // len(lo), pair % len(lo)
    reach = (spans.radius[a] + spans.radius[b]) * (1.0 + margin) + 1e-9 * (np.abs(hi).max() + 1.0)
    ok = _segment_distance(spans.p[a], spans.q[a], spans.p[b], spans.q[b]) <= reach
    return owner, a[ok], b[ok]


def _colour(n: int, pairs: np.ndarray) -> np.ndarray:
    """Greedy colouring of the may-touch graph, largest degree first."""
    colour = np.full(n, -1, np.int64)
    if not len(pairs):
        colour[:] = 0
        return colour
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.argsort(both[:, 0], kind="stable")]
    offsets = np.searchsorted(both[:, 0], np.arange(n + 1))
    nbr = both[:, 1].tolist()
    off = offsets.tolist()
    col = colour.tolist()
    for t in np.argsort(-np.diff(offsets), kind="stable").tolist():
        used = {col[x] for x in nbr[off[t] : off[t + 1]]}
        c = 0
        while c in used:
            c += 1
        col[t] = c
    return np.asarray(col, np.int64)


def union(tubes: Tubes, options: UnionOptions | None = None) -> Mesh:
    """Union the tubes of one tree into one watertight, consistently oriented mesh.

    Parameters
    ----------
    tubes : Tubes
        Closed tubes from :func:`lsys3d.sweep.sweep`.
    options : UnionOptions, optional

    Returns
    -------
    Mesh
        Welded, watertight 2-manifold with outward faces, unit corner normals
        and corner uv (:mod:`lsys3d.mesh`).

    Raises
    ------
    GeometryError
        No tubes, a tube manifold3d rejects, a failed boolean, or an empty
        result; the message says which part and manifold3d's status.
    """
    opt = UnionOptions() if options is None else options
    where = f"union of {len(tubes)} tubes"
    if not len(tubes):
        raise GeometryError("union: no tubes to union (empty skeleton?)")
    if not opt.layers:
        parts = [_manifold(tubes, f"union: tube {i} (chain {tubes.chain[i]})", [i]) for i in range(len(tubes))]
        return _weld_float32(_to_mesh(_batch_union(parts, where), where))
    spans = _Spans(tubes)
    owner, a, b = _span_pairs(tubes, opt.margin, spans)
    busy = np.zeros(len(spans), bool)
    busy[a] = True
    busy[b] = True
    if opt.local and len(a) and busy.mean() <= opt.local_max:
        mesh = _local_union(tubes, spans, busy, a, b, where)
        if mesh is not None:
            return _weld_float32(mesh)
    ta, tb = owner[a], owner[b]
    pairs = np.unique(np.stack([np.minimum(ta, tb), np.maximum(ta, tb)], axis=1), axis=0)
    colour = _colour(len(tubes), pairs)
    parts = [_manifold(tubes, f"union: layer {c}", colour == c) for c in range(int(colour.max()) + 1)]
    log.debug("union: %d tubes in %d layers", len(tubes), len(parts))
    return _weld_float32(_to_mesh(_batch_union(parts, where), where))


def _repair_corners(mesh: Mesh) -> None:
    """Give corners whose interpolated attributes manifold3d left non-finite the face normal and uv 0.

    Seen on degenerate input (hypothesis: 15 zero-width tubes 1e-12 apart) where
    manifold3d interpolates properties over a zero-area triangle.  The union's
    own fresh arrays are repaired in place.
    """
    normals = mesh.normals
    bad = ~np.isfinite(normals).all(axis=2) | (np.abs(normals).sum(axis=2) == 0)
    if bad.any():
        fn = np.nan_to_num(face_normals(mesh.vertices, mesh.faces).astype(np.float32))
        fn[np.abs(fn).sum(axis=1) == 0] = (0.0, 1.0, 0.0)
        normals[bad] = np.broadcast_to(fn[:, None, :], normals.shape)[bad]
    mesh.uv[~np.isfinite(mesh.uv)] = 0.0


def _weld_float32(mesh: Mesh) -> Mesh:
    """Merge vertices that share a float32 position and drop the triangles that collapse, if it stays closed.

    Where tubes meet almost tangentially, manifold3d keeps distinct vertices a
    few micrometres apart joined by needle triangles.  Stored as float32 (glTF,
    USD) they land on one position, and a reader that welds by position (as
    Blender's glTF import does) sees edges shared by four faces.  Welding here
    removes them (tree3d: 54 triangles of 73,608) while every edge keeps exactly
    two opposite faces; when it would not (crossings of coplanar tubes in the
    flat presets), the vertices are moved apart instead
    (:func:`_separate_float32`), and so are any left closer than readers weld.
    """
    _repair_corners(mesh)
    v32 = np.asarray(mesh.vertices, np.float32)
    unique, first, point = np.unique(v32, axis=0, return_index=True, return_inverse=True)
    if len(unique) == len(v32):
        return _separate_float32(mesh)
    point = point.ravel()
    faces = point[np.asarray(mesh.faces)]
    a, b, c = faces.T
    keep = (a != b) & (b != c) & (c != a)
    order = np.argsort(first)  # number the points in their first appearance, as before
    renumber = np.empty(len(order), np.int64)
    renumber[order] = np.arange(len(order))
    faces = renumber[faces[keep]]
    if not _closed(faces, len(unique)):
        return _separate_float32(mesh)
    source = None if mesh.face_source is None else mesh.face_source[keep]
    return _separate_float32(
        Mesh(unique[order].astype(np.float64), faces, mesh.normals[keep], mesh.uv[keep], face_source=source)
    )


def _separate_float32(mesh: Mesh, rounds: int = 32) -> Mesh:
    """Give distinct vertices distinct float32 positions, far enough apart that readers do not weld them.

    Where a weld would break the mesh (crossings of coplanar tubes), a vertex
    that shares its float32 position, or its cell of the 1e-8 grid that
    trimesh's ``merge_vertices`` welds by, with an earlier vertex is moved
    along its largest coordinate, on its own side of the earlier one, by
    ``k`` steps of ``max(float32 step, 2e-8)`` (the k-th such vertex of a
    position, so coincident vertices part too).  The moves are micrometres at
    most on a plant metres tall; the faces do not change.  When no separation
    is found in ``rounds`` passes the mesh is returned as it was.
    """
    v = np.asarray(mesh.vertices, np.float64)
    v32 = v.astype(np.float32)
    everything = np.arange(len(v32))
    direction = np.zeros(len(v32))

    def float32_bits():  # + 0.0 makes -0.0 and 0.0 one position
        return (v32 + np.float32(0.0)).view(np.int32)

    def weld_grid_cell():  # trimesh's merge_vertices rounds to 8 decimals
        return np.round(v32.astype(np.float64) * 1e8).astype(np.int64)

    for _ in range(rounds):
        moved = False
        for key in (float32_bits, weld_grid_cell):
            owner = _first_equal_row(key())
            later = np.flatnonzero(owner != everything)
            if not len(later):
                continue
            moved = True
            axis = np.argmax(np.abs(v[later]), axis=1)
            # a vertex keeps the side it first moved to, so it cannot swing between two neighbours
            fresh = direction[later] == 0
            direction[later[fresh]] = np.where(v[later, axis] >= v[owner[later], axis], 1.0, -1.0)[fresh]
            side = direction[later]
            by_owner = np.argsort(owner[later], kind="stable")
            sorted_owner = owner[later][by_owner]
            rank = np.empty(len(later), np.int64)
            rank[by_owner] = np.arange(len(later)) - np.searchsorted(sorted_owner, sorted_owner, side="left") + 1
            old = v32[later, axis]
            step = np.maximum(np.spacing(np.abs(old)).astype(np.float64), 2e-8)
            new = (old.astype(np.float64) + side * rank * step).astype(np.float32)
            same = new == old
            new[same] = np.nextafter(old[same], (side[same] * np.inf).astype(np.float32))
            v32[later, axis] = new
        if not moved:
            break
    else:
        return mesh
    moved = (v32 != v.astype(np.float32)).any(axis=1)
    log.debug("union: %d vertices moved to positions of their own", int(moved.sum()))
    points = np.where(moved[:, None], v32.astype(np.float64), v)
    return replace(mesh, vertices=points)


def _batch_union(parts: list[manifold3d.Manifold], where: str) -> manifold3d.Manifold:
    result = parts[0] if len(parts) == 1 else manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add)
    _check(result, where)
    if result.is_empty() or result.num_tri() == 0:
        raise GeometryError(f"{where}: manifold3d returned an empty mesh")
    return _drop_slivers(result)


def _drop_slivers(manifold: manifold3d.Manifold) -> manifold3d.Manifold:
    """Remove the closed, flat crumbs a boolean can leave where many tubes meet.

    Where several tubes cross at almost one point, manifold3d may return, beside
    the tree, a few separate pieces of 4-6 triangles that enclose no volume
    (seen on the ``tree`` preset: 17 of them, areas below 1e-6 m^2).  A piece is
    dropped when it is both tiny (area below 1e-6 of the whole) and flat (volume
    below 1e-3 * area^1.5, where a thin tube's ratio is near 0.2 * sqrt(r/L)).
    Real parts of a plant (a separate branch after an ``f`` move) are kept.
    """
    parts = manifold.decompose()
    if len(parts) < 2:
        return manifold
    area = np.array([p.surface_area() for p in parts])
    volume = np.abs([p.volume() for p in parts])
    crumb = (area < 1e-6 * area.sum()) & (volume < 1e-3 * area**1.5)
    if not crumb.any():
        return manifold
    log.debug(
        "union: dropped %d flat crumbs of %d triangles",
        crumb.sum(),
        sum(parts[i].num_tri() for i in np.flatnonzero(crumb)),
    )
    return manifold3d.Manifold.compose([p for p, c in zip(parts, crumb, strict=True) if not c])


def _local_union(tubes: Tubes, spans: _Spans, busy: np.ndarray, a: np.ndarray, b: np.ndarray, where: str):
    """Union only the runs of spans that may touch another tube; stitch the free spans back on.

    A *run* is a maximal stretch of busy spans of one tube.  Each run goes
    into the boolean as a closed piece: where it ends at a free span it is
    closed by a temporary cap on that ring.  No other tube comes near such a
    ring (the free span's capsule touches nothing), so manifold leaves the cap
    as it was; it is removed from the result, and the free spans of the tube
    (kept out of the boolean) are welded onto the ring.  Returns None when the
    result does not stitch exactly (the caller then unions whole tubes).
    """
    nt = len(tubes)
    rings, sides = tubes.rings, tubes.sides
    nspan = rings - 1
    span_off = _offsets(nspan)
    # runs of busy spans
    prev_busy = np.zeros(len(busy), bool)
    prev_busy[1:] = busy[:-1]
    starts = busy & ((spans.local == 0) | ~prev_busy)
    run_of_span = np.cumsum(starts) - 1
    run_start = np.flatnonzero(starts)
    nxt_busy = np.zeros(len(busy), bool)
    nxt_busy[:-1] = busy[1:]
    ends = busy & ((spans.local == nspan[spans.tube] - 1) | ~nxt_busy)
    run_end = np.flatnonzero(ends)
    run_tube = spans.tube[run_start]
    k0, k1 = spans.local[run_start], spans.local[run_end]

    # every face of every tube: its span and whether it goes into the boolean
    fo = tubes.face_offsets
    nf = len(tubes.faces)
    face_tube = np.repeat(np.arange(nt), np.diff(fo))
    lf = np.arange(nf) - fo[face_tube]
    s2 = 2 * sides[face_tube]
    body_faces = s2 * nspan[face_tube]
    face_span_local = np.where(lf < body_faces, lf // s2, np.where(lf < body_faces + s2 // 2, 0, nspan[face_tube] - 1))
    face_span = span_off[face_tube] + face_span_local
    face_busy = busy[face_span]

    # temporary caps where a run meets a free span: a fan from ring vertex 0
    cut_tube = np.concatenate([run_tube[k0 > 0], run_tube[k1 < nspan[run_tube] - 1]])
    cut_ring = np.concatenate([k0[k0 > 0], k1[k1 < nspan[run_tube] - 1] + 1])
    cut_run = np.concatenate([np.flatnonzero(k0 > 0), np.flatnonzero(k1 < nspan[run_tube] - 1)])
    cut_tip = np.concatenate([np.zeros((k0 > 0).sum(), bool), np.ones((k1 < nspan[run_tube] - 1).sum(), bool)])
    cap_faces, cap_run = [], []
    for s in np.unique(sides[cut_tube]).tolist() if len(cut_tube) else []:
        c = np.flatnonzero(sides[cut_tube] == s)
        j = np.arange(1, s - 1)
        fan_tip = np.stack([np.zeros_like(j), j, j + 1], axis=1)
        base = tubes.wedge_offsets[cut_tube[c]] + cut_ring[c] * (s + 1)
        fan = np.where(cut_tip[c][:, None, None], fan_tip[None], fan_tip[None][:, :, [0, 2, 1]])
        cap_faces.append((base[:, None, None] + fan).reshape(-1, 3))
        cap_run.append(np.repeat(cut_run[c], s - 2))
    cap_faces = np.concatenate(cap_faces) if cap_faces else np.zeros((0, 3), np.int64)
    cap_run = np.concatenate(cap_run) if cap_run else np.zeros(0, np.int64)

    # colour the runs; one Manifold per colour; union
    ra, rb = run_of_span[a], run_of_span[b]
    run_pairs = np.unique(np.stack([np.minimum(ra, rb), np.maximum(ra, rb)], axis=1), axis=0)
    colour = _colour(len(run_start), run_pairs)
    bf = np.flatnonzero(face_busy)
    tri = np.concatenate([tubes.faces[bf], cap_faces])
    tri_id = np.concatenate([bf, nf + np.arange(len(cap_faces))])  # ids >= nf mark temporary caps
    tri_colour = colour[np.concatenate([run_of_span[face_span[bf]], cap_run])]
    parts = []
    for c in range(int(colour.max()) + 1):
        sel = np.flatnonzero(tri_colour == c)
        parts.append(_manifold_of(tubes, tri[sel], tri_id[sel], f"union: layer {c} of the junction runs"))
    result = _batch_union(parts, where)
    log.debug("union: %d of %d spans in %d runs, %d layers", busy.sum(), len(busy), len(run_start), len(parts))

    out = result.to_mesh64()
    props = np.asarray(out.vert_properties)
    otri = np.asarray(out.tri_verts, np.int64)
    fid = np.asarray(out.face_id, np.int64)
    if props.shape[1] != _NUM_PROP or len(fid) != len(otri):
        raise GeometryError(f"{where}: manifold3d returned {props.shape[1]} properties, {len(fid)} face ids")
    point_of, npts = _weld(len(props), out)
    temp = fid >= nf
    if temp.sum() != len(cap_faces):
        log.debug("union: a temporary cap was changed by the boolean; unioning whole tubes")
        return None
    keep = ~temp
    # the rings under the temporary caps, found again by their positions
    cut_points = (
        tubes.point_offsets[cut_tube][:, None] + (cut_ring * sides[cut_tube])[:, None] + np.arange(sides.max())[None]
    )
    cut_points = cut_points[np.arange(sides.max())[None] < sides[cut_tube][:, None]]
    seam = np.unique(point_of[otri[temp]])
    if len(seam) != len(cut_points):
        log.debug("union: the temporary caps do not meet the boolean at their rings; unioning whole tubes")
        return None
    seam_pos = np.empty((npts, 3), np.float64)
    seam_pos[point_of] = props[:, :3]
    found = _match_rows(seam_pos[seam], tubes.points[cut_points])
    if found is None:
        log.debug("union: the rings of the temporary caps moved in the boolean; unioning whole tubes")
        return None
    # free spans: their faces, their points (ring points on a cut map onto the seam)
    ff = np.flatnonzero(~face_busy)
    free_pts = tubes.wedge_point[tubes.faces[ff]]
    new_index = np.full(len(tubes.points), -1, np.int64)
    used = np.zeros(len(tubes.points), bool)
    used[free_pts] = True
    used[cut_points] = False
    fresh = np.flatnonzero(used)
    new_index[fresh] = npts + np.arange(len(fresh))
    new_index[cut_points] = seam[found]
    vertices = np.concatenate([seam_pos, tubes.points[fresh]])
    faces = np.concatenate([point_of[otri[keep]], new_index[free_pts]])
    normals = np.concatenate([_unit_rows(props[otri[keep], 3:6]), tubes.wedge_normal[tubes.faces[ff]]])
    uv = np.concatenate([props[otri[keep], 6:], tubes.wedge_uv[tubes.faces[ff]]])
    if not _closed(faces, len(vertices)):
        log.debug("union: the stitched mesh is not closed; unioning whole tubes")
        return None
    # the tube face each triangle came from: manifold3d carries the face ids through the boolean
    return Mesh(vertices, faces, normals, uv, face_source=np.concatenate([fid[keep], ff]))


def _manifold_of(tubes: Tubes, tri: np.ndarray, tri_id: np.ndarray, where: str) -> manifold3d.Manifold:
    """One Manifold of the wedge-indexed triangles ``tri`` of ``tubes``, ``tri_id`` as face ids."""
    used = np.zeros(len(tubes.wedge_point), bool)
    used[tri] = True
    wedges = np.flatnonzero(used)
    remap = np.empty(len(tubes.wedge_point), np.int64)
    remap[wedges] = np.arange(len(wedges))
    w = len(wedges)
    wp = tubes.wedge_point[wedges]
    props = np.empty((w, _NUM_PROP), np.float64)  # float64: float32 would weld nearby vertices into slivers
    props[:, :3] = tubes.points[wp]
    props[:, 3:6] = tubes.wedge_normal[wedges]
    props[:, 6:] = tubes.wedge_uv[wedges]
    rep = np.empty(len(tubes.points), np.int64)
    rep[wp] = np.arange(w)
    merge_to = rep[wp]
    merge_from = np.flatnonzero(merge_to != np.arange(w))
    mesh = manifold3d.Mesh64(
        vert_properties=props,
        tri_verts=remap[tri].astype(np.uint64),
        merge_from_vert=merge_from.astype(np.uint64),
        merge_to_vert=merge_to[merge_from].astype(np.uint64),
        face_id=tri_id.astype(np.uint64),
    )
    return _check(manifold3d.Manifold(mesh), where)


def _weld(nprops: int, mesh: manifold3d.Mesh):
    """Point index of every property vertex of a manifold3d Mesh (merge vectors applied)."""
    rep = np.arange(nprops)
    rep[np.asarray(mesh.merge_from_vert, np.int64)] = np.asarray(mesh.merge_to_vert, np.int64)
    while (rep[rep] != rep).any():  # follow chains, should manifold ever write one
        rep = rep[rep]
    root = np.zeros(nprops, bool)
    root[rep] = True
    index = np.cumsum(root) - 1
    return index[rep], int(root.sum())


def _unit_rows(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(length > 1e-12, length, 1.0)


def _match_rows(have: np.ndarray, want: np.ndarray):
    """Index into ``have`` of every row of ``want`` (exact match), or None if any is missing or twice."""
    void = np.dtype((np.void, have.dtype.itemsize * 3))
    hk = np.ascontiguousarray(have).view(void).ravel()
    wk = np.ascontiguousarray(want).view(void).ravel()
    order = np.argsort(hk)
    hs = hk[order]
    if len(hs) > 1 and (hs[1:] == hs[:-1]).any():
        return None
    pos = np.searchsorted(hs, wk)
    pos = np.minimum(pos, len(hs) - 1)
    if not (hs[pos] == wk).all() or len(np.unique(pos)) != len(pos):
        return None
    return order[pos]


def _closed(faces: np.ndarray, nverts: int) -> bool:
    """Every directed edge once, and its reverse once: closed and consistently oriented."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    fwd = np.sort(e[:, 0] * nverts + e[:, 1])
    if len(fwd) > 1 and (fwd[1:] == fwd[:-1]).any():
        return False
    rev = e[:, 1] * nverts + e[:, 0]
    pos = np.minimum(np.searchsorted(fwd, rev), len(fwd) - 1)
    return bool((fwd[pos] == rev).all())


def _to_mesh(manifold: manifold3d.Manifold, where: str) -> Mesh:
    mesh = manifold.to_mesh64()
    props = np.asarray(mesh.vert_properties)
    if props.shape[1] != _NUM_PROP:
        raise GeometryError(f"{where}: expected {_NUM_PROP} vertex properties, manifold3d returned {props.shape[1]}")
    tri = np.asarray(mesh.tri_verts, np.int64)
    point_of, npts = _weld(len(props), mesh)
    vertices = np.empty((npts, 3))
    vertices[point_of] = props[:, :3]
    # manifold3d keeps each input triangle's face id (its index in Tubes.faces) on every piece of it
    face_source = np.asarray(mesh.face_id, np.int64)
    if len(face_source) != len(tri):
        raise GeometryError(f"{where}: manifold3d returned {len(face_source)} face ids for {len(tri)} triangles")
    return Mesh(vertices, point_of[tri], _unit_rows(props[tri, 3:6]), props[tri, 6:], face_source=face_source)
