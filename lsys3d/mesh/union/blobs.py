"""Blobs: a cluster of many mutually overlapping short tubes meshed as a level set instead of booleans.

Dense grammars (issue 34) nest thousands of tubes shorter than they are wide
at every apex: a chain of booleans over them costs time for every triangle of
every tube, most of which cannot show.  Where a cluster of touching tubes is
such a blob (:func:`blob_clusters`, a measured cost model), its surface is
made instead as the zero set of the tubes' signed distance, sampled on a grid
whose edge is a fraction of the width (``UnionOptions.blobs``):

1. *The distance.*  Every span (two neighbouring rings of a tube) is a
   tapered capsule along the rings' centres, with the radius that keeps the
   area of the tube's polygon (``r sqrt(s sin(2 pi / s) / (2 pi))`` for ``s``
   sides: the volume stays the tubes'), cut flat by its ring's plane at the
   two ends of a tube (as the tube's caps) and mitred at its inner joints (cut beyond them only).
   It is evaluated, in a compiled loop, only in the blocks of ``BLOCK``\\ :sup:`3`
   cells that some capsule reaches (a narrow band around it); further away it
   stays at the band's width.
2. *The surface.*  scikit-image's ``measure.marching_cubes`` (Lewiner's
   topologically consistent cases) runs on each block; a block shares its
   boundary samples with its neighbours, so each surface vertex is named by
   the grid edge it lies on and the blocks' surfaces weld into one closed,
   oriented 2-manifold (a value within ``NUDGE`` edges of zero is moved
   off it, so no vertex lands on a sample and no two edges share one).
3. *The check.*  The result must be closed and consistently oriented (every
   directed edge once and its reverse once), without faces of zero area, of
   positive volume (:func:`_checked`); a cluster whose level set fails the
   check on every grid offset goes through the boolean as before.

Each face's source (``Mesh.face_source``) is the wall face, on the nearest
span (by the same distance), nearest to the face's centre: the stages after
the union read the tube, branch and uv chart from it, so a blob's uv is the
nearest tube's chart projected (:meth:`~lsys3d.mesh.sweep.Tubes.corner_uv`),
except on the faces of its short tubes, which take a box projection
(:mod:`lsys3d.mesh.union.blob_uv`), and its normals are smooth everywhere (no
flat caps).

The cluster's surface differs from the exact union by at most about an edge
(the grid cannot hold detail finer than that): a sharp rim (a cap's edge, a
mitre's outer corner) is cut off and a concave seam between two tubes filled
over about one edge.  The volume: within 1.2% of the exact union's on the
dense set at an edge of a quarter of the width (:data:`CHORD`).  Deterministic: the same blocks, in the
same order, give the same samples and the same vertices in any process.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ...arrays import components, local_index, ranges
from ...compiling import kernel
from ...errors import OptionsError
from ..mesh import Mesh
from ..sweep import Tubes
from .blob_uv import blob_density, box_uv, face_density
from .parts import _closed, _no_corners

log = logging.getLogger("lsys3d")

BLOCK = 32
"""Cells along each side of a block of samples."""

NUDGE = 0.01
"""A sample closer to zero than this many edges is moved to this distance outside."""

SHIFTS = np.array(
    [[0.3183099, 0.1715729, 0.4142136], [0.7071068, 0.5772157, 0.2360680], [0.1180340, 0.8862269, 0.6931472]]
)
"""The grid's offset from the multiples of its edge, in edges: the first, the next if a level set fails the check."""

CHORD = 1.0 / 12.0
"""The wall is sampled this many ``edge^2 / radius`` further out, for the marching cubes' flat triangles.

A chord of length ``h`` on a circle of radius ``r`` lies ``h^2 / (8 r)`` inside it at its middle and
``h^2 / (12 r)`` on average.  Measured at an edge of a quarter of the width against the exact union
(``benchmarks/dense/README.md``): L-Py's barnsleyfern -0.62%, barnsleyfern3 -1.13%, nylki's tree25d +0.93%
(1/11.5: -0.52%, -0.99%, +1.08%; 1/8: +0.54%, +0.44%, +2.65%: the denser the union, the more of its concave
seams the triangles fill); one isolated long tube gains 0 at about 1/8.5 and loses 2% at 1/12.
"""

BAND = 1.25
"""The band around each capsule where the distance is sampled, in edges (beyond it: this many edges)."""

# the cost model, seconds per unit of work on the 2-core machine (shared, load average 10-13), rounded up for
# the level set and down for the boolean, so that a cluster goes to the level set only when it clearly pays:
# barnsleyfern's samples took 0.15-1.5 s for 15 million (1e-8 to 1e-7 a sample: 2.5e-8); its blocks' marching
# cubes, weld and sources about 0.3 s for 38 blocks of 32^3 cells (2.4e-7 a cell); its default boolean 120 s
# for 794,336 tube triangles (1.5e-4 a triangle), param-004's over 900 s for 2,381,712 (over 3.8e-4): 2.5e-5
# is six times below the cheapest measured
SECONDS_PER_SAMPLE = 2.5e-8  # the compiled distance, per span and sample in its box
SECONDS_PER_BLOCK_CELL = 2.5e-7  # marching cubes and welding, per cell of an active block
SECONDS_PER_BOOLEAN_TRIANGLE = 2.5e-5  # manifold's boolean per tube triangle of a crowded cluster
OVERLAP = 4.0
"""A cluster is a blob when its tubes touch at least this many others each (pairs of tubes per tube, twice)."""


def spans(tubes: Tubes, which: np.ndarray):
    """The spans of tubes ``which`` as cut cylinders: axis ends, radii, the planes of their rings, their ring.

    Returns ``a, b (n, 3)``, ``ra, rb (n,)``, ``ta, tb (n, 4)`` and ``ring (n,) int64`` (the global ring
    index of ``a``).  ``ta`` is the plane of the span's first ring (``x . ta[:3] + ta[3]`` is the distance
    out of the span through it), ``tb`` of its last: a span is the tube's wall between its two rings
    (round, of the radius that keeps the polygon's area), mitred as the sweep mitres it, so neighbouring
    spans meet on their shared ring's plane and a tube's first and last rings are its flat caps.
    """
    ring_offsets = tubes.ring_offsets
    rings = tubes.rings[which]
    start = ring_offsets[which]
    nspan = np.maximum(rings - 1, 0)
    first = np.repeat(start, nspan)
    local = local_index(nspan)
    ring = first + local
    area = tubes.sides * np.sin(2 * np.pi / tubes.sides) / (2 * np.pi)
    scale = np.repeat(np.sqrt(area[which]), nspan)
    a, b = tubes.ring_center[ring], tubes.ring_center[ring + 1]
    ra, rb = tubes.ring_radius[ring] * scale, tubes.ring_radius[ring + 1] * scale
    ta = _cap_plane(-tubes.ring_tangent[ring], a)
    tb = _cap_plane(tubes.ring_tangent[ring + 1], b)
    return a, b, ra, rb, ta, tb, ring


def _cap_plane(normal: np.ndarray, point: np.ndarray) -> np.ndarray:
    """``(n, 4)`` planes through ``point`` facing ``normal`` (out of the span)."""
    return np.concatenate([normal, -np.einsum("ij,ij->i", normal, point)[:, None]], axis=1)


@kernel(nogil=True)
def _fill(
    values, nearest, corner, origin, h, band, lo, hi, which, a, b, ra, rb, ta, tb, cap_a, cap_b
):  # pragma: no cover
    """Samples of one block (``values`` from grid index ``corner``): the least distance of its capsules ``which``,
    and which capsule is nearest (``nearest``, -1 beyond the band).  Whether the surface passes the block.

    A capsule is cut by the planes of its two rings: by a cap's (``cap_a``, ``cap_b``: its tube's first or last
    ring) on both sides, by an inner joint's only beyond it.  Inside, next to a joint, the distance stays the
    wall's: cut there too, two spans of one tube would each be a few cells long and bring the samples inside
    their shared ring near zero, and the marching cubes' vertices on the wall next to it would move inwards
    (measured on a chain of spans as long as the radius, edge half the radius: -3.9% of the volume).
    """
    n = values.shape[0]
    values[:] = band
    nearest[:] = -1
    for e in range(len(which)):
        s = which[e]
        i0, j0, k0 = max(lo[s, 0] - corner[0], 0), max(lo[s, 1] - corner[1], 0), max(lo[s, 2] - corner[2], 0)
        i1, j1, k1 = (
            min(hi[s, 0] - corner[0], n - 1),
            min(hi[s, 1] - corner[1], n - 1),
            min(hi[s, 2] - corner[2], n - 1),
        )
        # the capsule's constants, out of the loop over its samples
        ax, ay, az = a[s, 0], a[s, 1], a[s, 2]
        bx, by, bz = b[s, 0] - ax, b[s, 1] - ay, b[s, 2] - az
        ll = bx * bx + by * by + bz * bz
        if ll <= 0.0:  # a span of no length has no wall
            continue
        inv = 1.0 / ll
        r0, dr = ra[s], rb[s] - ra[s]
        for i in range(i0, i1 + 1):
            px = origin[0] + (corner[0] + i) * h - ax
            for j in range(j0, j1 + 1):
                py = origin[1] + (corner[1] + j) * h - ay
                for k in range(k0, k1 + 1):
                    pz = origin[2] + (corner[2] + k) * h - az
                    t = (px * bx + py * by + pz * bz) * inv
                    dx, dy, dz = px - t * bx, py - t * by, pz - t * bz
                    # the distance from the axis line (the wall runs on to the mitre planes), radius along it
                    d = np.sqrt(dx * dx + dy * dy + dz * dz) - (r0 + dr * min(max(t, 0.0), 1.0))
                    # cut by its rings' planes: a cap's on both sides, an inner joint's beyond it only
                    pa = (px + ax) * ta[s, 0] + (py + ay) * ta[s, 1] + (pz + az) * ta[s, 2] + ta[s, 3]
                    if pa > d and (pa > 0.0 or cap_a[s]):
                        d = pa
                    pb = (px + ax) * tb[s, 0] + (py + ay) * tb[s, 1] + (pz + az) * tb[s, 2] + tb[s, 3]
                    if pb > d and (pb > 0.0 or cap_b[s]):
                        d = pb
                    if d < values[i, j, k]:
                        values[i, j, k] = d
                        nearest[i, j, k] = s
    nudge = NUDGE * h
    lowest, highest = band, -band
    for i in range(n):
        for j in range(n):
            for k in range(n):
                v = values[i, j, k]
                if abs(v) < nudge:
                    v = nudge
                    values[i, j, k] = v
                lowest, highest = min(lowest, v), max(highest, v)
    return lowest < 0.0 < highest


@kernel(nogil=True)
def _nearest_spans(local, faces, nearest):  # pragma: no cover - compiled
    """For each face of one block (vertices ``local`` in the block's cells): the nearest capsule of the sample
    nearest its centre (one of its corners' samples when that one is beyond every band)."""
    n = nearest.shape[0]
    out = np.empty(len(faces), np.int64)
    for f in range(len(faces)):
        best = -1
        for c in range(4):  # the centre first, then each corner
            x = y = z = 0.0
            if c == 0:
                for m in range(3):
                    x += local[faces[f, m], 0] / 3
                    y += local[faces[f, m], 1] / 3
                    z += local[faces[f, m], 2] / 3
            else:
                x, y, z = local[faces[f, c - 1], 0], local[faces[f, c - 1], 1], local[faces[f, c - 1], 2]
            i = min(max(int(np.floor(x + 0.5)), 0), n - 1)
            j = min(max(int(np.floor(y + 0.5)), 0), n - 1)
            k = min(max(int(np.floor(z + 0.5)), 0), n - 1)
            best = nearest[i, j, k]
            if best >= 0:
                break
        out[f] = best
    return out


@kernel(nogil=True)
def _wall_faces(
    centre, span, ring, tube_of_ring, points, point_offsets, sides, ring_offsets, face_offsets
):  # pragma: no cover
    """For each face (its centre, its nearest span): the wall face of that span nearest to the centre."""
    out = np.empty(len(centre), np.int64)
    for f in range(len(centre)):
        x, y, z = centre[f, 0], centre[f, 1], centre[f, 2]
        r = ring[span[f]]
        t = tube_of_ring[r]
        s = sides[t]
        k = r - ring_offsets[t]  # the span's index in its tube
        p0 = point_offsets[t] + k * s
        best, side = np.inf, 0
        for j in range(s):
            jn = j + 1 if j + 1 < s else 0
            cx = points[p0 + j, 0] + points[p0 + jn, 0] + points[p0 + s + j, 0] + points[p0 + s + jn, 0]
            cy = points[p0 + j, 1] + points[p0 + jn, 1] + points[p0 + s + j, 1] + points[p0 + s + jn, 1]
            cz = points[p0 + j, 2] + points[p0 + jn, 2] + points[p0 + s + j, 2] + points[p0 + s + jn, 2]
            dx, dy, dz = cx / 4 - x, cy / 4 - y, cz / 4 - z
            d = dx * dx + dy * dy + dz * dz
            if d < best:
                best, side = d, j
        out[f] = face_offsets[t] + 2 * (s * k + side)
    return out


def level_set(tubes: Tubes, which: np.ndarray, edge: float):
    """The surface of the union of tubes ``which`` as a level set: vertices, faces and each face's source.

    Parameters
    ----------
    tubes : Tubes
    which : (k,) int64
        The tubes of one cluster.
    edge : float
        The grid's edge length.

    Returns
    -------
    tuple or None
        ``vertices (v, 3) float64``, ``faces (f, 3) int64`` (counter-clockwise seen from outside) and
        ``source (f,) int64`` (a wall face of ``tubes`` each face lies nearest); None when the level set is
        no closed, oriented 2-manifold (:func:`_checked`) on any of the grids :data:`SHIFTS` gives.
    """
    for attempt in range(len(SHIFTS)):
        made = _level_set(tubes, which, edge, attempt)
        if made is not None:
            return made
        log.debug("union: the level set of %d tubes failed the check on grid %d", len(which), attempt)
    log.warning("union: the level set of %d tubes is no closed 2-manifold; they go through the boolean", len(which))
    return None


def _level_set(tubes: Tubes, which: np.ndarray, edge: float, attempt: int):
    """:func:`level_set` on the grid offset by ``SHIFTS[attempt]``; None when it fails the check."""
    marching_cubes = _marching_cubes()
    if marching_cubes is None:
        raise OptionsError(
            "union_blobs: the level sets need scikit-image, a dependency of lsys3d (pip install scikit-image)"
        )
    t0 = time.perf_counter()
    a, b, ra, rb, ta, tb, ring = spans(tubes, which)
    if not len(a):
        return None
    h, band = float(edge), BAND * float(edge)
    # flat triangles between vertices on a round wall of radius r cut inside it by h^2 / (12 r) on average
    ra, rb = ra + CHORD * h * h / ra, rb + CHORD * h * h / rb
    tube_of_ring = np.repeat(np.arange(len(tubes)), tubes.rings)
    span_tube = tube_of_ring[ring]
    cap_a = ring == tubes.ring_offsets[span_tube]  # the span's first ring is its tube's first: a cap
    cap_b = ring + 2 == tubes.ring_offsets[span_tube] + tubes.rings[span_tube]
    reach = np.maximum(ra, rb)[:, None] + band
    box_lo = np.minimum(a, b) - reach
    box_hi = np.maximum(a, b) + reach
    # off the multiples of the edge by fractions of it that no drawing has: a planar fern on z = 0 gave samples
    # symmetric about a grid plane, whose exact ties in Lewiner's face tests joined four faces on an edge
    origin = (np.floor(box_lo.min(axis=0) / h) - 2 + SHIFTS[attempt]) * h
    lo = np.floor((box_lo - origin) / h).astype(np.int64)
    hi = np.ceil((box_hi - origin) / h).astype(np.int64)
    nb = hi.max(axis=0) // BLOCK + 2  # blocks along each axis
    # the blocks each capsule reaches: a sample on a block's upper face belongs to the next block too
    blo, bhi = np.maximum(lo - 1, 0) // BLOCK, hi // BLOCK
    count = np.prod(bhi - blo + 1, axis=1)
    span_of = np.repeat(np.arange(len(a)), count)
    local = local_index(count)
    ext = (bhi - blo + 1)[span_of]
    bi = blo[span_of, 0] + local // (ext[:, 1] * ext[:, 2])
    bj = blo[span_of, 1] + (local // ext[:, 2]) % ext[:, 1]
    bk = blo[span_of, 2] + local % ext[:, 2]
    key = (bi * nb[1] + bj) * nb[2] + bk
    order = np.lexsort((span_of, key))
    key, span_of = key[order], span_of[order]
    blocks, block_first = np.unique(key, return_index=True)
    block_first = np.append(block_first, len(key)).astype(np.int64)
    values = np.empty((BLOCK + 1,) * 3, np.float64)
    nearest = np.empty((BLOCK + 1,) * 3, np.int64)
    verts, tris, tri_span = [], [], []
    nverts = 0
    for n, blk in enumerate(blocks.tolist()):
        corner = np.array([blk // (nb[1] * nb[2]), (blk // nb[2]) % nb[1], blk % nb[2]], np.int64) * BLOCK
        mine = span_of[block_first[n] : block_first[n + 1]]
        if not _fill(values, nearest, corner, origin, h, band, lo, hi, mine, a, b, ra, rb, ta, tb, cap_a, cap_b):
            continue
        v, f, _, _ = marching_cubes(values, 0.0, allow_degenerate=True)
        v, f = v.astype(np.float64), f.astype(np.int64)
        tri_span.append(_nearest_spans(v, f, nearest))
        verts.append(v + corner)
        tris.append(f + nverts)
        nverts += len(v)
    if not verts:
        return None
    g = np.concatenate(verts)
    faces = np.concatenate(tris)
    span = np.concatenate(tri_span)
    del verts, tris, tri_span
    # each vertex by its grid edge: the axis along which it is off the samples, and the edge's lower sample;
    # a vertex off the samples in more than one axis is one Lewiner adds inside a cube (cases 7, 12, 13...):
    # keyed by its cube, after every edge (no other block has that cube)
    near = np.round(g)
    off = np.abs(g - near) > 1e-4
    axis = np.argmax(off, axis=1)
    idx = near.astype(np.int64)
    rows = np.arange(len(g))
    idx[rows, axis] = np.floor(g[rows, axis]).astype(np.int64)
    inner = off.sum(axis=1) > 1
    idx[inner] = np.floor(g[inner]).astype(np.int64)
    dims = nb * BLOCK + 1
    edge_key = ((idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]) * 4 + np.where(inner, 3, axis)
    _, first, inverse = np.unique(edge_key, return_index=True, return_inverse=True)
    vertices = origin + g[first] * h
    faces = inverse.reshape(-1)[faces]
    if not _checked(vertices, faces):
        return None
    centre = vertices[faces].mean(axis=1)
    source = _wall_faces(
        centre,
        span,
        ring,
        tube_of_ring,
        tubes.points,
        tubes.point_offsets,
        tubes.sides,
        tubes.ring_offsets,
        tubes.face_offsets,
    )
    log.debug(
        "union: level set of %d tubes (%d capsules, %d blocks, edge %.3g): %d faces, %.2f s",
        len(which),
        len(a),
        len(blocks),
        h,
        len(faces),
        time.perf_counter() - t0,
    )
    return vertices, faces, source


def _marching_cubes():
    """scikit-image's ``measure.marching_cubes``, or None where scikit-image does not import.

    A dependency of lsys3d, imported only when a cluster is a blob: most plants have none, and Blender's
    extension (``tools/blender_extension.py``) does not bundle scikit-image and scipy, so there the blobs go
    through the boolean (:func:`blob_meshes` warns).
    """
    try:
        from skimage.measure import marching_cubes
    except ImportError:
        return None
    return marching_cubes


def _checked(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether the surface is closed and consistently oriented (every directed edge once, its reverse once),
    with no face of zero area, and encloses a positive volume.

    manifold3d's own check (building a ``Manifold``) took 14.6 s of the 26 s level set of a space-filling
    curve's 3.3 million triangles; this one is the same edge test the union makes of its stitched seams.
    """
    if not len(faces) or not _closed(faces, len(vertices)):
        return False
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if not (np.einsum("ij,ij->i", cross, cross) > 0).all():
        return False
    return float(np.einsum("ij,ij->i", tri[:, 0], cross).sum()) > 0


def blob_clusters(tubes: Tubes, pair_a: np.ndarray, pair_b: np.ndarray, fraction: float) -> list[np.ndarray]:
    """The clusters of touching tubes to mesh as level sets, each ``(k,) int64`` tubes, in a fixed order.

    A cluster (tubes connected by ``pair_a, pair_b``, pairs of tubes that may
    touch) is a blob when its tubes overlap many others each (at least
    :data:`OVERLAP` pairs per tube) and the level set's estimated time, at an
    edge of ``fraction`` times its thinnest width, is below the boolean's
    (constants measured on the dense set, :data:`SECONDS_PER_SAMPLE`...).
    """
    n = len(tubes)
    if not len(pair_a) or fraction <= 0:
        return []
    label = components(n, pair_a, pair_b)
    # the clusters crowded enough, from the counts alone (most trees have none: nothing more to compute)
    size = np.bincount(label, minlength=n)
    pairs_per = np.bincount(label[pair_a], minlength=n)
    crowded = (size >= 2) & (2.0 * pairs_per >= OVERLAP * size)
    if not crowded.any():
        return []
    mine = np.flatnonzero(crowded[label])
    order = mine[np.argsort(label[mine], kind="stable")]
    cut = np.flatnonzero(np.diff(label[order])) + 1
    tri = np.diff(tubes.face_offsets)
    out = []
    for members in np.split(order, cut):
        per_tube = 2.0 * pairs_per[label[members[0]]] / len(members)
        h = fraction * 2.0 * _thinnest(tubes, members)
        a, b, ra, rb, _, _, _ = spans(tubes, members)
        reach = (np.linalg.norm(b - a, axis=1) + 2 * np.maximum(ra, rb) + 2 * BAND * h) / h
        samples = float(np.sum(reach**3))
        # active blocks: those holding a capsule's middle, and as many again that the capsules reach into
        blocks = 2.0 * len(np.unique(np.floor((a + b) / (2 * BLOCK * h)), axis=0))
        level = SECONDS_PER_SAMPLE * samples + SECONDS_PER_BLOCK_CELL * blocks * BLOCK**3
        boolean = SECONDS_PER_BOOLEAN_TRIANGLE * float(tri[members].sum())
        log.debug(
            "union: cluster of %d tubes, %.1f pairs per tube: level set ~%.2f s, boolean ~%.2f s",
            len(members),
            per_tube,
            level,
            boolean,
        )
        if level < boolean:
            out.append(np.sort(members))
    return out


def blob_meshes(
    tubes: Tubes, pair_a: np.ndarray, pair_b: np.ndarray, fraction: float, corners: bool = True
) -> tuple[list[Mesh], np.ndarray]:
    """The level sets of the blob clusters (:func:`blob_clusters`) as meshes, and which tubes they replace.

    Each mesh's ``face_source`` names faces of ``tubes``, and its ``face_box_uv``
    the box projection of the faces of its short tubes (:mod:`lsys3d.mesh.union.blob_uv`);
    with ``corners``, its corner normals are the area-weighted vertex normals
    and its uv each corner in the chart of its source face
    (:meth:`~lsys3d.mesh.sweep.Tubes.corner_uv`) or in that box projection;
    without, zeros that take no memory (the cleanup makes its own).
    """
    meshes, meshed = [], np.zeros(len(tubes), bool)
    clusters = blob_clusters(tubes, pair_a, pair_b, fraction)
    if clusters and _marching_cubes() is None:
        log.warning(
            "union: %d clusters of tubes would be level sets (union_blobs), but scikit-image does not import here; "
            "they go through the boolean (slower, the exact union)",
            len(clusters),
        )
        return meshes, meshed
    for members in clusters:
        made = level_set(tubes, members, fraction * 2.0 * _thinnest(tubes, members))
        if made is None:
            continue
        vertices, faces, source = made
        box = face_density(tubes, source, blob_density(tubes, members))
        if corners:
            normals = _vertex_normals(vertices, faces)[faces].astype(np.float32)
            uv = tubes.corner_uv(source, vertices, faces, np.empty((len(faces), 3, 2), np.float32))
            box_uv(vertices, faces, box, uv)
        else:
            normals, uv = _no_corners(len(faces), 3, 3), _no_corners(len(faces), 3, 2)
        meshes.append(Mesh(vertices, faces, normals, uv, face_source=source, face_box_uv=box))
        meshed[members] = True
    return meshes, meshed


def _thinnest(tubes: Tubes, members: np.ndarray) -> float:
    """The least ring radius of tubes ``members``."""
    return float(tubes.ring_radius[ranges(tubes.ring_offsets[members], tubes.rings[members])].min())


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(v, 3)`` unit area-weighted vertex normals."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    out = np.zeros_like(vertices)
    for c in range(3):
        for m in range(3):
            out[:, m] += np.bincount(faces[:, c], weights=cross[:, m], minlength=len(vertices))
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(length > 0, length, 1.0)
