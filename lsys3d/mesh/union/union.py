"""Union: tubes -> one watertight bark mesh, through manifold3d.

This module is the boundary with manifold3d: every Manifold it builds or
computes has its status checked, and a problem raises
:class:`~lsys3d.errors.GeometryError` naming the part and the status; an
empty or broken mesh is never returned.

How the union's cost follows its result
---------------------------------------
A boolean in manifold costs time for every triangle it is given, touched or
not, and much more for every triangle an intersection cuts.  So the tubes are
not unioned one by one, nor in one batch (manifold's own batch union groups
operands by bounding box, and the box of a long branch overlaps nearly
everything):

1. *Culling* (:mod:`lsys3d.mesh.union.touch`).  A tube equal to an earlier one, or wholly
   inside a straight span of another (a short thick twig buried in its
   parent), adds nothing and stays out.
2. *Which pieces can touch.*  Each tube is cut into pieces (a span between two
   rings, or about a diameter of tiny spans) covered by capsules; boxes in a
   grid and a segment-segment distance find the pairs that may touch, one
   candidate at a time.  More than ``UnionOptions.max_pairs`` pairs (a
   thousand branches from one point) is refused up front with
   :class:`~lsys3d.errors.LimitError`, before the memory is taken.
3. *Refinement.*  A long straight span touched only near one place (a twig on
   a trunk whose straight joints were merged into one span) gets new rings
   around the touched stretch; on a straight span they lie exactly on the wall.
4. *Only junctions go through the boolean* (``UnionOptions.local``).  A
   maximal run of busy pieces of one tube is closed with a temporary cap on
   each ring where it meets an untouched piece; the untouched pieces stay out
   and are welded back onto their rings afterwards (caps found by manifold
   face ids, rings by exact position; the seam and the result are checked,
   and whole tubes are unioned if anything does not match).
5. *Jobs* (:mod:`lsys3d.mesh.union.jobs`).  Runs (or tubes) that touch form clusters;
   small clusters are packed into jobs, a crowded cluster is split in space
   and its halves merged back (the merges of up to a quarter of the work in
   the job of their halves, without a round trip through a mesh: see
   :func:`_plan`).  Within a job the touch graph is coloured
   greedily and each colour becomes one Manifold of pairwise disjoint parts
   (no boolean), unioned with one ``Manifold.batch_boolean``.  Big unions run
   their jobs in worker processes on every core (``UnionOptions.workers``);
   the result is the same bytes with any number of workers.

Shading attributes ride through the boolean as manifold vertex properties
(position, normal, uv: 8 channels).  The seam and cap wedges of each tube are
tied to their ring vertex with manifold's merge vectors, so manifold sees
closed meshes; new vertices on the intersection curves get interpolated
properties, and the normals are renormalised on the way out.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import NamedTuple

import manifold3d
import numba
import numpy as np

from ...arrays import components, dot3, gather, isin, ranges, release_memory, row_hash, unique
from ...arrays import first_equal_row as _first_equal_row
from ...arrays import offsets as _offsets
from ...errors import GeometryError
from ...options import Options, option
from ..mesh import Mesh, crumbs, face_normals
from ..sweep import Tubes
from . import booleans, repeats
from . import jobs as union_jobs
from .booleans import BooleanError, Part
from .touch import DEFAULT_MAX_PAIRS, buried_tubes, duplicate_tubes, free_stretches, pieces, touching

__all__ = ["Junctions", "UnionOptions", "concatenate", "may_touch", "union", "union_cleaning_junctions"]

log = logging.getLogger("lsys3d")

_NUM_PROP = 8  # x y z, nx ny nz, u v
_JOB_TRIANGLES = 60_000  # smallest job worth its own boolean (a few tenths of a second in manifold)


@dataclass(frozen=True)
class UnionOptions(Options):
    """Whether and how tubes are unioned; every default, range and help is in its field.

    ``layers`` groups pairwise-disjoint tubes into layers before the boolean
    (fast); off, every tube goes to ``Manifold.batch_boolean`` separately
    (manifold's own bounding-box grouping; slower, for comparison).
    ``local`` sends only the pieces that may touch another tube through the
    boolean and stitches the rest of each tube back on (needs ``layers``),
    while at most ``local_max`` of the pieces may touch.  ``workers`` is how
    the work runs, not what it makes: the result is the same bytes with any
    number of workers, so it is left out of :meth:`plain` (and of the
    provenance of the files).
    """

    enabled: bool = option(
        True, name="union", help="the union of the tubes into one watertight mesh (off: the tube soup, a fast preview)"
    )
    layers: bool = option(True, help="group pairwise-disjoint tubes into layers before the boolean", cli=False)
    local: bool = option(True, help="send only the pieces that may touch through the boolean", cli=False)
    local_max: float = option(
        0.75, low=0, high=1, help="use the local path while at most this fraction of pieces may touch", cli=False
    )
    margin: float = option(0.01, low=0, high=1, help="relative padding of the touch test", cli=False)
    workers: int = option(
        0,
        low=0,
        high=4096,
        help="processes the union may use (0: one per core this process may run on; 1 also keeps the cleanup on "
        "one thread; the result is the same)",
    )
    max_pairs: int = option(
        DEFAULT_MAX_PAIRS,
        low=1,
        name="max_union_pairs",
        help="most pairs of tube pieces that may touch in the union (more is a crowd of branches that would take "
        "minutes; about 0.1 ms of boolean work each)",
    )

    def plain(self) -> dict:
        """The options as plain data, without ``workers`` (how the work runs, not what it makes)."""
        data = super().plain()
        del data["workers"]
        return data


class Junctions(NamedTuple):
    """What the boolean made of the junctions that :func:`union_cleaning_junctions` has cleaned before the copies.

    Every cluster of runs the boolean unioned (one of each set of repeated
    ones: :mod:`lsys3d.mesh.union.repeats`), as one mesh of closed pieces, each closed by
    temporary caps where its runs meet untouched tube pieces.  The cleaner
    must give the caps back exactly as they are (faces and points): the
    untouched pieces are welded onto their rings afterwards; and each face's
    ``source`` as it is, or its parent's for a face it makes: the copies
    find their own faces by it.

    The union works on tubes of its own (tubes equal to another or buried
    in one left out, rings inserted around touched stretches, which are no
    shape to keep): ``source`` numbers their faces, ``origin`` says which
    face of the tubes given to the union each lies in.

    Attributes
    ----------
    vertices : (v, 3) float64
    faces : (f, 3) int64
    source : (f,) int64
        The face of the union's own tubes each face is a piece of, or
        ``len(origin) + k`` for the face ``k`` of the temporary caps.
    origin : (n,) int64
        For each face of the union's own tubes, the face of the given tubes it lies in.
    cap_face : (k,) int64
        For each face of the temporary caps, a face (of the given tubes) of the tube it closes.
    cap_number : (k,) int64
        Which temporary cap each cap face is a face of.
    """

    vertices: np.ndarray
    faces: np.ndarray
    source: np.ndarray
    origin: np.ndarray
    cap_face: np.ndarray
    cap_number: np.ndarray


JunctionCleaner = Callable[[Junctions], "tuple[np.ndarray, np.ndarray, np.ndarray] | None"]
"""Cleans :class:`Junctions`: returns their vertices, faces and sources cleaned, or None to leave them."""


def concatenate(tubes: Tubes) -> Mesh:
    """All tubes as one tube-soup mesh (no boolean): the ``union=False`` bark.

    Each tube stays a closed, welded component; tubes may overlap.
    """
    return tubes.mesh()


def _manifold(tubes: Tubes, where: str, first_face: int = 0) -> manifold3d.Manifold:
    """One Manifold of whole (pairwise disjoint) tubes, attributes as properties.

    The face ids are the faces' indices from ``first_face`` on (their index in
    the tubes these were selected from, for ``Mesh.face_source``).
    """
    try:
        ids = first_face + np.arange(len(tubes.faces))
        return booleans.manifold_of(_part(tubes, tubes.faces, ids), where)
    except BooleanError as exc:
        raise GeometryError(str(exc)) from None


def may_touch(tubes: Tubes, margin: float = 0.01) -> np.ndarray:
    """Pairs of tubes that may touch, ``(m, 2) int64`` with ``i < j``.

    Each tube is covered by capsules, one per piece (a span between two
    neighbouring rings, or a run of short spans); two tubes may touch when two
    of their capsules (radii padded by ``margin``) intersect.  Tubes that are
    not listed are disjoint; listed ones may or may not touch.
    """
    pcs = pieces(tubes)
    a, b = touching(pcs, margin, max_pairs=np.iinfo(np.int64).max)
    if not len(a):
        return np.zeros((0, 2), np.int64)
    ta, tb = pcs.tube[a], pcs.tube[b]
    return np.unique(np.stack([np.minimum(ta, tb), np.maximum(ta, tb)], axis=1), axis=0)


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


def _unique_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(k, 2)`` distinct pairs ``(min, max)`` of ``a, b``, without self pairs."""
    keep = a != b
    lo, hi = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    if not len(lo):
        return np.zeros((0, 2), np.int64)
    key = unique(lo * (int(hi.max()) + 1) + hi)
    return np.stack([key // (int(hi.max()) + 1), key % (int(hi.max()) + 1)], axis=1)


def union(
    tubes: Tubes,
    options: UnionOptions | None = None,
    *,
    progress: Callable[[float], None] | None = None,
    corners: bool = True,
) -> Mesh:
    """Union the tubes of one tree into one watertight, consistently oriented mesh.

    Parameters
    ----------
    tubes : Tubes
        Closed tubes from :func:`lsys3d.mesh.sweep.sweep`.
    options : UnionOptions, optional
    progress : callable, optional
        Called with the fraction of the boolean work done (0 to 1) as it goes.
    corners : bool
        Whether to make the corner normals and uv.  Without them (for a caller
        that makes its own, as :func:`lsys3d.mesh.cleanup.cleanup` does) they are
        zeros that take no memory (read-only views of one row), and the
        points alone go through the boolean, without the normals and uv as
        properties (a sixth less of its work): the same triangles on the same
        points with the same face sources, in an order of their own.  The
        262,143-segment plant's corners are 0.4 GB.

    Returns
    -------
    Mesh
        Welded, watertight 2-manifold with outward faces, unit corner normals
        and corner uv; its ``face_source`` is, for every triangle, the index
        in ``tubes.faces`` of the tube face it is a piece of (on every path:
        whole tubes, junction jobs, copies of repeated junctions, untouched
        pieces stitched back on).

    Raises
    ------
    GeometryError
        No tubes, a tube manifold3d rejects, a failed boolean, or an empty
        result; the message says which part and manifold3d's status.
    LimitError
        More than ``options.max_pairs`` pairs of tube pieces may touch.
    """
    held = [tubes]  # _union holds the tubes alone: the soup goes as soon as it is culled (if the caller let go)
    del tubes
    try:
        return _union(held, UnionOptions() if options is None else options, progress, corners)[0]
    finally:
        release_memory()  # the union's temporaries, freed as _union returned


def union_cleaning_junctions(
    held: list,
    options: UnionOptions | None,
    clean: JunctionCleaner,
    progress: Callable[[float], None] | None = None,
) -> tuple[Mesh, bool]:
    """:func:`union` of ``held.pop()`` without corners, whose junctions ``clean`` cleans before they are copied.

    A junction that repeats (:mod:`lsys3d.mesh.union.repeats`) is then cleaned once and
    its clean result moved onto every copy, and the untouched tube pieces,
    which need no cleaning, are not in what ``clean`` is given.  Returns the
    mesh and whether its junctions were cleaned: not when the union took
    another path than the local one (whole tubes: crowded plants, or a seam
    that did not stitch), or ``clean`` returned None, or its result did not
    give the temporary caps back exactly; the mesh is then :func:`union`'s.

    ``held`` is a list holding the tubes alone (it is emptied: the union holds them).
    """
    try:
        return _union(held, UnionOptions() if options is None else options, progress, False, clean)
    finally:
        release_memory()


def _union(
    held: list,
    opt: UnionOptions,
    progress: Callable[[float], None] | None,
    corners: bool = True,
    clean: JunctionCleaner | None = None,
) -> tuple[Mesh, bool]:
    """:func:`union` of ``held.pop()``; whether ``clean`` cleaned its junctions (:func:`union_cleaning_junctions`)."""
    tubes = held.pop()
    where = f"union of {len(tubes)} tubes"
    if not len(tubes):
        raise GeometryError("union: no tubes to union (empty skeleton?)")
    bad = ~np.isfinite(tubes.points).all(axis=1)
    if bad.any():
        t = int(np.searchsorted(tubes.point_offsets, np.flatnonzero(bad)[0], side="right") - 1)
        raise GeometryError(f"union: tube {t} (chain {int(tubes.chain[t])}) has a point that is not a finite number")
    workers = opt.workers or union_jobs.default_workers()
    progress = _Progress(progress)
    progress(0.0)
    nf = len(tubes.faces)
    if not opt.layers:
        fo = tubes.face_offsets
        parts = [
            _manifold(tubes.select([i]), f"union: tube {i} (chain {tubes.chain[i]})", int(fo[i]))
            for i in range(len(tubes))
        ]
        result = parts[0] if len(parts) == 1 else manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add)
        if result.status() != manifold3d.Error.NoError:
            raise GeometryError(f"{where}: manifold3d reported {result.status().name}")
        if result.is_empty() or result.num_tri() == 0:
            raise GeometryError(f"{where}: manifold3d returned an empty mesh")
        mesh = _to_mesh([booleans.part_of(result)], where, corners)
        mesh = _weld_float32([_true_sources(_drop_crumbs(mesh), tubes)])
        progress(1.0)
        return _sourced(mesh, np.arange(nf), where), False
    t0 = time.perf_counter()
    tubes, pcs, a, b, origin = _prepare(tubes, opt, progress, corners)
    release_memory()
    log.debug("union: %d pieces, %d touching pairs (%.2f s)", len(pcs), len(a), time.perf_counter() - t0)
    progress(0.10)
    busy = np.zeros(len(pcs), bool)
    busy[a] = True
    busy[b] = True
    if opt.local and len(a) and busy.mean() <= opt.local_max:
        held = [_local_union(tubes, pcs, busy, a, b, where, workers, progress, corners, clean, origin)]
        if held[0] is not None:
            progress(0.90)
            mesh, from_boolean, cleaned = held.pop()
            # the cleaned junctions' sources were made true before they were cleaned (and their copies' follow)
            held.append(mesh if cleaned else _true_sources(mesh, tubes, from_boolean))
            del mesh
            del tubes, pcs, a, b, busy  # the weld's memory: the stitched mesh is all that is needed now
            mesh = _weld_float32(held)
            progress(1.0)
            return _sourced(mesh, origin, where), cleaned
    ta, tb = pcs.tube[a], pcs.tube[b]
    pairs = _unique_pairs(ta, tb)
    colour = _colour(len(tubes), pairs)
    weight = np.diff(tubes.face_offsets).astype(np.float64)
    box = tubes.bounds()
    jobs = _plan(weight, box.mean(axis=1), pairs)

    def leaf(i: int) -> list[Part]:
        items = jobs.leaves[i]
        out = []
        for c in unique(colour[items]).tolist():
            which = np.sort(items[colour[items] == c])
            sel = tubes.select(which)
            out.append(_part(sel, sel.faces, gather(tubes.face_offsets, which)[0], corners))
        return out

    use = _use(workers, weight.sum(), jobs)
    roots, stats = union_jobs.run(jobs, leaf, _namer(jobs, "layer"), use, progress.boolean)
    log.debug("union: %d tubes in %d jobs, %d workers", len(tubes), stats["jobs"], stats["workers"])
    held = [_to_mesh(roots, where, corners)]
    progress(0.85)
    held.append(_true_sources(_drop_crumbs(held.pop()), tubes))
    mesh = _weld_float32(held)
    progress(1.0)
    return _sourced(mesh, origin, where), False


def _misplaced(vertices: np.ndarray, faces: np.ndarray, source: np.ndarray, tubes: Tubes) -> np.ndarray:
    """``(f,) bool``: the faces whose centroid is farther from their source tube face than its radius and side.

    A piece of a face lies on the face; one of a span split by new rings lies
    in the quad of the span (within a side of the tube, ``2 r sin(pi / sides)``,
    more than the radius when a tube has 3-5 sides).  A slice at a time.
    """
    radius = np.maximum.reduceat(tubes.ring_radius, tubes.ring_offsets[:-1])
    radius = radius * (1.0 + 2.0 * np.sin(np.pi / tubes.sides))
    reach = radius[np.searchsorted(tubes.face_offsets, source, side="right") - 1] * (1 + 1e-6) + 1e-9
    return _far_from_source(vertices, faces, source, tubes.points, tubes.wedge_point, tubes.faces, reach)


@numba.njit(cache=True, nogil=True)
def _far_from_source(vertices, faces, source, points, wedge_point, tube_faces, reach):  # pragma: no cover - compiled
    """``(f,) bool``: the centroid of face ``f`` is farther than ``reach[f]`` from tube face ``source[f]``.

    A face at a time, without the (f, 3, 3) gathers.  The arithmetic is numpy's,
    in its order (``np.cross``; ``np.einsum`` dot products sum x, z, then y;
    ``np.linalg.norm`` x, y, z; ``mean`` divides the sum by 3), so the answer
    is the same as the vectorised distance's at every face.
    """
    out = np.zeros(len(faces), np.bool_)
    p = np.empty(3)
    tri = np.empty((3, 3))
    for f in range(len(faces)):
        for j in range(3):
            p[j] = (vertices[faces[f, 0], j] + vertices[faces[f, 1], j] + vertices[faces[f, 2], j]) / 3.0
        for c in range(3):
            w = wedge_point[tube_faces[source[f], c]]
            for j in range(3):
                tri[c, j] = points[w, j]
        d = _triangle_distance(p, tri)
        out[f] = d > reach[f]
    return out


@numba.njit(cache=True, nogil=True)
def _triangle_distance(p, tri):  # pragma: no cover - compiled
    """Distance of the point ``p`` (3,) from the triangle ``tri`` (3, 3)."""
    a0, a1, a2 = tri[0, 0], tri[0, 1], tri[0, 2]
    u0, u1, u2 = tri[1, 0] - a0, tri[1, 1] - a1, tri[1, 2] - a2
    v0, v1, v2 = tri[2, 0] - a0, tri[2, 1] - a1, tri[2, 2] - a2
    n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if length < 1e-300:  # np.maximum(length, 1e-300), NaN kept
        length = 1e-300
    n0, n1, n2 = n0 / length, n1 / length, n2 / length
    height = dot3(p[0] - a0, p[1] - a1, p[2] - a2, n0, n1, n2)
    q0, q1, q2 = p[0] - height * n0, p[1] - height * n1, p[2] - height * n2
    inside = True
    edge = np.inf
    for k in range(3):
        s0, s1, s2 = tri[k, 0], tri[k, 1], tri[k, 2]
        e0, e1, e2 = tri[(k + 1) % 3, 0] - s0, tri[(k + 1) % 3, 1] - s1, tri[(k + 1) % 3, 2] - s2
        w0, w1, w2 = q0 - s0, q1 - s1, q2 - s2
        c0, c1, c2 = e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0
        inside &= dot3(c0, c1, c2, n0, n1, n2) >= 0
        ee = dot3(e0, e1, e2, e0, e1, e2)
        if ee < 1e-300:  # np.maximum(ee, 1e-300), NaN kept
            ee = 1e-300
        t = dot3(p[0] - s0, p[1] - s1, p[2] - s2, e0, e1, e2) / ee
        if t < 0.0:  # np.clip(t, 0, 1), NaN kept
            t = 0.0
        elif t > 1.0:
            t = 1.0
        r0, r1, r2 = p[0] - (s0 + t * e0), p[1] - (s1 + t * e1), p[2] - (s2 + t * e2)
        d = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        if np.isnan(d) or np.isnan(edge):  # np.minimum propagates NaN
            edge = np.nan
        elif d < edge:
            edge = d
    return abs(height) if inside else edge


def _true_sources(mesh: Mesh, tubes: Tubes, checked: int | None = None) -> Mesh:
    """The mesh with every face's source a tube face it lies on or next to.

    Only the first ``checked`` faces (all by default) are checked: the local
    path puts the boolean's output first and the untouched tube pieces, whose
    faces are their own sources, after it.

    manifold3d keeps each input triangle's face id on its pieces, but where
    coplanar tubes cross (the flat presets: ``tree`` 31 of 279,780 faces,
    ``abop-1.24c`` 4 of 287,018), it gives a few triangles the id of a face
    of another tube, far away.  Such a face takes the source of a neighbour
    (sharing a vertex) whose source face it does lie next to (``tree``: 24 of
    the 31; ``abop-1.24c``: 1 of 4); a face none of whose neighbours fits (a
    long triangle across several coplanar tubes) keeps its id, and is logged.
    """
    faces, source = mesh.faces, mesh.face_source
    checked = len(faces) if checked is None else checked
    bad = np.flatnonzero(_misplaced(mesh.vertices, faces[:checked], source[:checked], tubes))
    if not len(bad):
        return mesh
    source = source.copy()
    found = len(bad)
    for _ in range(8):
        good_faces = np.ones(len(faces), bool)
        good_faces[bad] = False
        near = np.zeros(len(mesh.vertices), bool)
        near[faces[bad]] = True
        cand = np.flatnonzero(near[faces].any(axis=1) & good_faces)
        cv = faces[cand].ravel()
        cf = np.repeat(cand, 3)
        order = np.argsort(cv, kind="stable")
        cv, cf = cv[order], cf[order]
        bv = faces[bad].ravel()  # each bad face's corners
        lo, hi = np.searchsorted(cv, bv, "left"), np.searchsorted(cv, bv, "right")
        pair_face = np.repeat(np.repeat(bad, 3), hi - lo)
        pair_src = source[cf[ranges(lo, hi - lo)]]
        ok = ~_misplaced(mesh.vertices, faces[pair_face], pair_src, tubes)
        fixed, first = np.unique(pair_face[ok], return_index=True)
        source[fixed] = pair_src[ok][first]
        bad = unique(bad)
        bad = bad[~isin(bad, fixed)]
        if not len(bad) or not len(fixed):
            break
    log.debug("union: %d faces given a neighbour's source face, %d left as manifold3d gave them", found, len(bad))
    return replace(mesh, face_source=source)


def _sourced(mesh: Mesh, origin: np.ndarray, where: str) -> Mesh:
    """The mesh with ``face_source`` naming the faces of the tubes given to :func:`union`.

    ``origin[k]`` is the original face of face ``k`` of the tubes that went
    into the boolean (:func:`_prepare` may have left tubes out and inserted
    rings).  Every face id must be a tube face: a temporary cap that survived
    the stitching would be a bug, never a face to pass on.
    """
    src = mesh.face_source
    if src is None or len(src) != len(mesh.faces) or (src < 0).any() or (src >= len(origin)).any():
        raise GeometryError(f"{where}: a face of the result is no piece of a tube face (union bug)")
    return replace(mesh, face_source=origin[src])


def _leave_out(tubes: Tubes, origin: np.ndarray, drop: np.ndarray, why: str):
    """The tubes without ``drop``, and ``origin`` (each face's face in the given tubes) for the faces kept."""
    log.debug("union: %d tubes %s left out", int(drop.sum()), why)
    return tubes.select(~drop), origin[gather(tubes.face_offsets, np.flatnonzero(~drop))[0]]


def _prepare(tubes: Tubes, opt: UnionOptions, progress: Callable[[float], None], corners: bool = True):
    """Cull what adds nothing, find what may touch, refine long straight spans.

    Returns the tubes, their pieces, the pairs of pieces that may touch, and
    for each face of the returned tubes the face of the given tubes it is (or
    lies in, for a span split by new rings).  Without ``corners`` (the points
    alone go through the boolean) the refined tubes carry no wedge normals and uv.
    """
    origin = np.arange(len(tubes.faces))

    dup = duplicate_tubes(tubes)
    if dup.any():
        tubes, origin = _leave_out(tubes, origin, dup, "equal to another")
    pcs = pieces(tubes)
    a, b = touching(pcs, opt.margin, opt.max_pairs)
    progress(0.04)
    buried = buried_tubes(tubes, pcs, a, b)
    if buried.any():
        tubes, origin = _leave_out(tubes, origin, buried, "buried inside another")
        pcs = pieces(tubes)
        a, b = touching(pcs, opt.margin, opt.max_pairs)
    if opt.local:
        tube, ring, t = free_stretches(tubes, pcs, a, b, opt.margin)
        if len(tube):
            log.debug("union: %d rings inserted around touched stretches", len(tube))
            tubes, inserted = tubes.insert_rings(tube, ring, t, origin=True, shading=corners)
            origin = origin[inserted]
            progress(0.07)
            pcs = pieces(tubes)
            a, b = touching(pcs, opt.margin, opt.max_pairs)
    return tubes, pcs, a, b, origin


class _Progress:
    """The union's progress as one fraction: preparing (to 15%), the boolean jobs (to 75%), stitching and welding."""

    def __init__(self, report: Callable[[float], None] | None):
        self.report = report
        self.last = -1.0

    def __call__(self, fraction: float) -> None:
        if self.report and fraction >= self.last + 0.01:
            self.last = fraction
            self.report(min(fraction, 1.0))

    def boolean(self, fraction: float) -> None:
        self(0.15 + 0.60 * fraction)


def _job_target(total: float) -> float:
    """Triangles per job: about 16 jobs (for the workers and for progress), none too small to pay for itself.

    The same for any number of workers: how the work is split decides the
    result's bytes (manifold3d may triangulate a cut differently in another
    grouping), the number of workers must not.
    """
    return max(total / 16, _JOB_TRIANGLES)


def _plan(weight: np.ndarray, centre: np.ndarray, pairs: np.ndarray) -> union_jobs.Plan:
    """The jobs of a union: :func:`_job_target` triangles each; the merges of up to a quarter of all inner.

    A crowded cluster (the dense fern: one cluster of 582,240 triangles) is
    split in space into leaves whose results are merged pairwise.  A merge
    that goes out to a worker costs a mesh export and two rebuilds besides
    its boolean (the fern's 15 merges: 20 s of 51 s of boolean CPU, 9 s on
    manifold3d's own objects); the merges of up to a quarter of the work are
    done in the job of their leaves, which leaves at least four jobs for the
    workers.  Merged in memory, smaller leaves pay: a crowded cluster's are
    half the job size (the fern's boolean CPU, one worker: 50.5 s before,
    47.7 s with inner merges, 44.5 s with them and half-size leaves, 44.3 s
    with quarter-size ones).  Like the leaves, independent of the number of
    workers.
    """
    total = float(weight.sum())
    target = _job_target(total)
    return union_jobs.plan(weight, centre, pairs[:, 0], pairs[:, 1], target, job=total / 4, leaf=target / 2)


def _use(workers: int, triangles: float, jobs: union_jobs.Plan) -> int:
    """Worker processes for a plan: all of them for big unions, none (this process) for small ones."""
    if workers > 1 and triangles >= union_jobs.POOL_MIN_TRIANGLES and len(jobs.weight) > 1:
        return min(workers, len(jobs.weight))
    return 1


def _namer(jobs: union_jobs.Plan, what: str) -> Callable[[int], str]:
    def name(node: int) -> str:
        if len(jobs.weight) == 1:
            return f"union: {what} 0"
        kind = "job" if node < len(jobs.leaves) else "merge"
        return f"union: {kind} {node} of {len(jobs.weight)}"

    return name


def _crumbs(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(f,) bool``: the boolean's crumbs (:func:`lsys3d.mesh.mesh.crumbs`), under 1e-6 of the whole area
    (seen on the ``tree`` preset: 17 of them, areas below 1e-6 m^2)."""
    crumb = crumbs(vertices, faces, 1e-6)
    if crumb.any():
        log.debug("union: dropped flat crumbs of %d triangles", int(crumb.sum()))
    return crumb


def _drop_crumbs(mesh: Mesh) -> Mesh:
    """The mesh without its crumbs (:func:`_crumbs`)."""
    faces = mesh.faces
    crumb = _crumbs(mesh.vertices, faces)
    if not crumb.any():
        return mesh
    keep = ~crumb
    used = np.zeros(len(mesh.vertices), bool)
    used[faces[keep]] = True
    renumber = np.cumsum(used) - 1
    source = None if mesh.face_source is None else mesh.face_source[keep]
    normals, uv = _corner_rows(mesh.normals, keep), _corner_rows(mesh.uv, keep)
    return Mesh(mesh.vertices[used], renumber[faces[keep]], normals, uv, face_source=source)


def _no_corners(n: int, *shape: int) -> np.ndarray:
    """``(n, *shape)`` float32 zeros taking no memory: the corner attributes of ``union(..., corners=False)``."""
    return np.broadcast_to(np.zeros(shape, np.float32), (n, *shape))


def _corner_rows(values: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``values[keep]``; corner attributes not made (:func:`_no_corners`) stay not made."""
    if values.strides[0] == 0:
        return _no_corners(int(np.count_nonzero(keep)) if keep.dtype == bool else len(keep), *values.shape[1:])
    return values[keep]


def _repair_corners(mesh: Mesh) -> None:
    """Give corners whose interpolated attributes manifold3d left non-finite the face normal and uv 0.

    Seen on degenerate input (hypothesis: 15 zero-width tubes 1e-12 apart) where
    manifold3d interpolates properties over a zero-area triangle.  The union's
    own fresh arrays are repaired in place, and their -0.0 made 0.0, as the
    files store them (the exporter can then use the normals without a copy).
    """
    normals = mesh.normals
    if normals.strides[0] == 0:  # not made (:func:`_no_corners`)
        return
    bad = np.zeros(normals.shape[:2], bool)
    if _mend_corners(normals, mesh.uv, bad):
        fn = np.nan_to_num(face_normals(mesh.vertices, mesh.faces).astype(np.float32))
        fn[np.abs(fn).sum(axis=1) == 0] = (0.0, 1.0, 0.0)
        normals[bad] = np.broadcast_to(fn[:, None, :], normals.shape)[bad] + normals.dtype.type(0.0)


@numba.njit(cache=True, nogil=True)
def _mend_corners(normals, uv, bad):  # pragma: no cover - compiled
    """One pass of :func:`_repair_corners`: mark in ``bad`` the corners whose normal is not finite or zero, make
    the other normals' -0.0 0.0 and non-finite uv 0, in place; whether any corner is bad."""
    zero = normals.dtype.type(0.0)
    anybad = False
    for f in range(normals.shape[0]):
        for c in range(normals.shape[1]):
            x, y, z = normals[f, c, 0], normals[f, c, 1], normals[f, c, 2]
            if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)) or (x == 0 and y == 0 and z == 0):
                bad[f, c] = True
                anybad = True
            else:
                normals[f, c, 0], normals[f, c, 1], normals[f, c, 2] = x + zero, y + zero, z + zero
            for k in range(uv.shape[2]):
                if not np.isfinite(uv[f, c, k]):
                    uv[f, c, k] = 0.0
    return anybad


def _weld_float32(held: list[Mesh]) -> Mesh:
    """Merge vertices that share a float32 position and drop the triangles that collapse, if it stays closed.

    Where tubes meet almost tangentially, manifold3d keeps distinct vertices a
    few micrometres apart joined by needle triangles.  Stored as float32 (glTF,
    USD) they land on one position, and a reader that welds by position (as
    Blender's glTF import does) sees edges shared by four faces.  Welding here
    removes them (tree3d: 54 triangles of 73,608) while every edge keeps exactly
    two opposite faces; when it would not (crossings of coplanar tubes in the
    flat presets), the vertices are moved apart instead
    (:func:`_separate_float32`), and so are any left closer than readers weld.

    ``held`` is a list holding the mesh alone; it is emptied, so that nothing
    else keeps the mesh and each of its arrays goes as soon as it is replaced
    (the 262,143-segment plant's bark is 6.4 million faces, 0.6 GB).
    """
    mesh = held.pop()
    _repair_corners(mesh)
    vertices, faces, normals, uv, source = mesh.vertices, mesh.faces, mesh.normals, mesh.uv, mesh.face_source
    del mesh
    v32 = vertices.astype(np.float32)
    v32 += np.float32(0.0)  # -0.0 and 0.0 are one position
    owner = _first_equal_row(v32.view(np.int32))
    first = owner == np.arange(len(v32))
    if first.all():  # no two vertices share a float32 position
        return _separate_float32(Mesh(vertices, faces, normals, uv, face_source=source), float32_unique=True)
    renumber = np.cumsum(first) - 1  # the points numbered in their first appearance
    welded, keep = _welded_faces(faces, renumber[owner])
    merged = np.zeros(int(first.sum()), bool)  # the points that several vertices became
    merged[renumber[owner[~first]]] = True
    if not _closed(welded, int(first.sum()), merged):
        return _separate_float32(Mesh(vertices, faces, normals, uv, face_source=source))
    # one array at a time: the old ones go as soon as they are replaced
    faces = welded
    del welded
    vertices = v32[first].astype(np.float64)
    del v32
    if not keep.all():
        normals = _corner_rows(normals, keep)
        uv = _corner_rows(uv, keep)
        source = None if source is None else source[keep]
    return _separate_float32(Mesh(vertices, faces, normals, uv, face_source=source), float32_unique=True)


@numba.njit(cache=True, nogil=True)
def _welded_faces(faces, point):  # pragma: no cover - compiled
    """The faces on the welded points ``point[faces]`` without those that collapse, and which faces are kept.

    Two passes over the faces in place: no (f, 3) copy renumbered, then another of the kept rows.
    """
    keep = np.empty(len(faces), np.bool_)
    count = 0
    for f in range(len(faces)):
        a, b, c = point[faces[f, 0]], point[faces[f, 1]], point[faces[f, 2]]
        keep[f] = a != b and b != c and c != a
        count += keep[f]
    welded = np.empty((count, 3), np.int64)
    _kept_faces(point, faces, keep, welded)
    return welded, keep


def _owners(keys: np.ndarray, dirty: np.ndarray) -> np.ndarray:
    """:func:`~lsys3d.arrays.first_equal_row` of ``keys`` when only the rows ``dirty`` (ascending) may equal another.

    The other rows are known to be pairwise distinct, so only the dirty rows
    and the rows equal to one of them (found by hash) are grouped: the same
    answer as grouping all rows, for a fraction of the sort.
    """
    n = len(keys)
    if len(dirty) == n:
        return _first_equal_row(keys)
    owner = np.arange(n)
    if not len(dirty):
        return owner
    h = row_hash(keys)
    maybe = isin(h, h[dirty])  # a hash shared with a dirty row (a collision only adds a candidate)
    maybe[dirty] = True
    rows = np.flatnonzero(maybe)
    owner[rows] = rows[_first_equal_row(keys[rows])]
    return owner


@numba.njit(cache=True, nogil=True)
def _weld_cells(v32):  # pragma: no cover - compiled
    """The vertices' cells of trimesh's 1e-8 weld grid, ``np.round(v32.astype(np.float64) * 1e8).astype(np.int64)``
    in one pass (no (v, 3) float64 temporaries): numpy's rounding, half to even."""
    out = np.empty((len(v32), 3), np.int64)
    for i in range(len(v32)):
        out[i, 0], out[i, 1], out[i, 2] = _weld_cell(v32, i)
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _weld_cell(v32, i):  # pragma: no cover - compiled
    """Vertex ``i``'s cell of the 1e-8 grid, as numpy rounds it (half to even)."""
    return (
        np.int64(np.rint(np.float64(v32[i, 0]) * 1e8)),
        np.int64(np.rint(np.float64(v32[i, 1]) * 1e8)),
        np.int64(np.rint(np.float64(v32[i, 2]) * 1e8)),
    )


def _separate_float32(mesh: Mesh, rounds: int = 32, float32_unique: bool = False) -> Mesh:
    """Give distinct vertices distinct float32 positions, far enough apart that readers do not weld them.

    Where a weld would break the mesh (crossings of coplanar tubes), a vertex
    that shares its float32 position, or its cell of the 1e-8 grid that
    trimesh's ``merge_vertices`` welds by, with an earlier vertex is moved
    along its largest coordinate, on its own side of the earlier one, by
    ``k`` steps of ``max(float32 step, 2e-8)`` (the k-th such vertex of a
    position, so coincident vertices part too).  The moves are micrometres at
    most on a plant metres tall; the faces do not change.  When no separation
    is found in ``rounds`` passes the mesh is returned as it was.
    ``float32_unique`` says that no two vertices share a float32 position yet
    (the weld just told them apart), which saves grouping them by it once.
    """
    v = np.asarray(mesh.vertices, np.float64)  # read here; copied only when a separation is found
    v32 = v.astype(np.float32)
    everything = np.arange(len(v32))
    direction = np.zeros(len(v32))

    def float32_bits():  # + 0.0 makes -0.0 and 0.0 one position
        return (v32 + np.float32(0.0)).view(np.int32)

    def weld_grid_cell():  # trimesh's merge_vertices rounds to 8 decimals
        return _weld_cells(v32)

    # the vertices moved since each key last grouped them: only those can share a key with another vertex
    # (the rest were told apart then), so later rounds group a few candidates instead of all vertices
    dirty = [np.zeros(0, np.int64) if float32_unique else everything, everything]
    separated = False
    for _ in range(rounds):
        moved = False
        for k, key in enumerate((float32_bits, weld_grid_cell)):
            if not len(dirty[k]):  # no vertex can share this key with another
                continue
            owner = _owners(key(), dirty[k])
            later = np.flatnonzero(owner != everything)
            dirty[k] = np.zeros(0, np.int64)
            if not len(later):
                continue
            moved = separated = True
            dirty = [unique(np.concatenate([d, later])) for d in dirty]
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
    if not separated:  # every vertex has a float32 position and weld cell of its own already
        return mesh
    moved = (v32 != v.astype(np.float32)).any(axis=1)
    log.debug("union: %d vertices moved to positions of their own", int(moved.sum()))
    v = v.copy()
    v[moved] = v32[moved]
    return replace(mesh, vertices=v)


def _local_union(
    tubes: Tubes,
    pcs,
    busy: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    where: str,
    workers: int,
    progress: _Progress,
    corners: bool = True,
    clean: JunctionCleaner | None = None,
    origin: np.ndarray | None = None,
):
    """Union only the runs of pieces that may touch another tube; stitch the free pieces back on.

    A *run* is a maximal stretch of busy pieces of one tube.  Each run goes
    into the boolean as a closed piece: where it ends at a free piece it is
    closed by a temporary cap on that ring.  No other tube comes near such a
    ring (the free piece's capsule touches nothing), so manifold leaves the cap
    as it was; it is removed from the result, and the free pieces of the tube
    (kept out of the boolean) are welded onto the ring.  ``clean`` (see
    :func:`union_cleaning_junctions`) cleans the boolean's result before it
    is copied onto repeated junctions (``origin``: :attr:`Junctions.origin`).
    Returns the mesh, how many of its faces (the first ones) came out of the
    boolean and whether ``clean`` cleaned them, or None when the result does
    not stitch exactly (the caller then unions whole tubes).
    """
    rings, sides = tubes.rings, tubes.sides
    # runs of busy pieces (pieces are numbered tube after tube, in ring order)
    prev_same = np.zeros(len(busy), bool)
    prev_same[1:] = (pcs.tube[1:] == pcs.tube[:-1]) & busy[:-1]
    starts = busy & ~prev_same
    run_of_piece = np.cumsum(starts) - 1
    run_start = np.flatnonzero(starts)
    next_same = np.zeros(len(busy), bool)
    next_same[:-1] = (pcs.tube[1:] == pcs.tube[:-1]) & busy[1:]
    run_end = np.flatnonzero(busy & ~next_same)
    run_tube = pcs.tube[run_start]
    k0, k1 = pcs.first[run_start], pcs.last[run_end]  # first and last ring of each run

    # every face of every tube: its span, its piece and whether it goes into the boolean
    fo = tubes.face_offsets
    nf = len(tubes.faces)
    nspan = rings - 1
    face_piece = _face_pieces(fo, sides, nspan, _offsets(nspan), pcs.span_piece)
    face_busy = busy[face_piece]

    # temporary caps where a run meets a free piece: a fan from ring vertex 0
    open_base, open_tip = k0 > 0, k1 < rings[run_tube] - 1
    cut_tube = np.concatenate([run_tube[open_base], run_tube[open_tip]])
    cut_ring = np.concatenate([k0[open_base], k1[open_tip]])
    cut_run = np.concatenate([np.flatnonzero(open_base), np.flatnonzero(open_tip)])
    cut_tip = np.concatenate([np.zeros(open_base.sum(), bool), np.ones(open_tip.sum(), bool)])
    cap_faces, cap_run, cap_cut = [], [], []
    for s in unique(sides[cut_tube]).tolist() if len(cut_tube) else []:
        c = np.flatnonzero(sides[cut_tube] == s)
        j = np.arange(1, s - 1)
        fan_tip = np.stack([np.zeros_like(j), j, j + 1], axis=1)
        base = tubes.wedge_offsets[cut_tube[c]] + cut_ring[c] * (s + 1)
        fan = np.where(cut_tip[c][:, None, None], fan_tip[None], fan_tip[None][:, :, [0, 2, 1]])
        cap_faces.append((base[:, None, None] + fan).reshape(-1, 3))
        cap_run.append(np.repeat(cut_run[c], s - 2))
        cap_cut.append(np.repeat(c, s - 2))
    cap_faces = np.concatenate(cap_faces) if cap_faces else np.zeros((0, 3), np.int64)
    cap_run = np.concatenate(cap_run) if cap_run else np.zeros(0, np.int64)
    cap_cut = np.concatenate(cap_cut) if cap_cut else np.zeros(0, np.int64)  # the cut each cap face closes

    # the runs' triangles (ids >= nf mark temporary caps), grouped by run
    bf = np.flatnonzero(face_busy)
    tri_run = np.concatenate([run_of_piece[face_piece[bf]], cap_run])
    by_run = np.argsort(tri_run, kind="stable")
    tri_id = np.concatenate([bf, nf + np.arange(len(cap_faces))])[by_run]
    tri_off = np.searchsorted(tri_run[by_run], np.arange(len(run_start) + 1))
    del tri_run, by_run, bf

    def faces_of(ids: np.ndarray, points: bool = False) -> np.ndarray:
        through = tubes.wedge_point if points else _NO_MAP
        return _faces_of(np.asarray(ids, np.int64), nf, tubes.faces, cap_faces, through)

    # clusters of runs that touch; congruent clusters are unioned once
    run_pairs = _unique_pairs(run_of_piece[a], run_of_piece[b])
    label = components(len(run_start), run_pairs[:, 0], run_pairs[:, 1])
    by_label = np.argsort(label, kind="stable")  # the runs cluster after cluster (no list of 44k arrays)
    cuts = np.flatnonzero(np.diff(label[by_label])) + 1
    runs_per_cluster = np.diff(np.concatenate([[0], cuts, [len(by_label)]]))
    del cuts
    clusters = repeats.find(tubes, by_label, runs_per_cluster, tri_id, tri_off, faces_of, nf, corners)
    progress(0.15)
    is_rep = clusters.rep == np.arange(len(clusters))
    rep_run = np.empty(len(by_label), bool)
    rep_run[by_label] = np.repeat(is_rep, runs_per_cluster)
    todo = np.flatnonzero(rep_run)  # the representatives' runs
    del rep_run
    index = np.full(len(run_start), -1, np.int64)
    index[todo] = np.arange(len(todo))
    todo_pairs = index[run_pairs]
    todo_pairs = todo_pairs[(todo_pairs >= 0).all(axis=1)]
    colour = _colour(len(todo), todo_pairs)
    weight = np.diff(tri_off)[todo].astype(np.float64)
    centre = 0.5 * (pcs.p[run_start[todo]] + pcs.q[run_end[todo]])
    jobs = _plan(weight, centre, todo_pairs)

    def leaf(i: int) -> list[Part]:
        items = jobs.leaves[i]
        out = []
        for c in unique(colour[items]).tolist():
            runs = todo[np.sort(items[colour[items] == c])]
            ids = np.concatenate([tri_id[tri_off[r] : tri_off[r + 1]] for r in runs.tolist()])
            out.append(_part(tubes, faces_of(ids), ids, corners))
        return out

    use = _use(workers, weight.sum(), jobs)
    roots, stats = union_jobs.run(jobs, leaf, _namer(jobs, "layer"), use, progress.boolean)
    log.debug(
        "union: %d of %d pieces in %d runs, %d clusters (%d unioned, %d triangles, %d colours), %d jobs, "
        "%d workers, %.2f s boolean CPU",
        busy.sum(),
        len(busy),
        len(run_start),
        len(clusters),
        is_rep.sum(),
        weight.sum(),
        colour.max(initial=0) + 1,
        stats["jobs"],
        stats["workers"],
        stats["boolean_cpu"],
    )
    done = _concat(roots)
    del roots
    point_of, npts = _weld(len(done.props), done.merge_from, done.merge_to)
    positions = np.empty((npts, 3))
    positions[point_of] = done.props[:, :3]
    welded = point_of[done.tri]  # the triangles on the points
    del point_of
    crumb = _crumbs(positions, welded)  # before the copies: a representative's crumbs are its copies'
    if crumb.any():
        done = Part(done.props, done.tri[~crumb], done.merge_from, done.merge_to, done.face_id[~crumb])
        welded = welded[~crumb]
    cleaned = False
    if clean is not None:
        junctions = Junctions(positions, welded, done.face_id, origin, origin[fo[cut_tube[cap_cut]]], cap_cut)
        better = _cleaned_junctions(junctions, tubes, clean)
        if better is not None:
            done, cleaned = better, True
        del junctions, better
    del positions, welded
    roots = [repeats.with_copies(clusters, tubes, done, nf, len(cap_faces))]
    del done, clusters
    progress(0.80)
    props, otri, fid, point_of, npts = _join(roots, where)
    del roots
    release_memory()
    seam_pos = np.empty((npts, 3), np.float64)
    seam_pos[point_of] = props[:, :3]
    if not corners:
        props = None  # only the positions were needed: the normals and uv are not made
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
    # each cap triangle came back whole: its corners are its ring's points, matched by position (the only
    # question is which corner manifold put first), each ring point onto one seam point, no seam point twice.
    # Every cap corner is then one of these seam points: they are the caps' points, the seam
    seam_of = np.full(len(tubes.points), -1, np.int64)
    matched = _cap_points(otri, fid, nf, point_of, seam_pos, cap_faces, tubes.wedge_point, tubes.points, seam_of)
    seam_of_cut = seam_of[cut_points]
    del seam_of
    claimed = np.zeros(npts, bool)
    claimed[seam_of_cut[seam_of_cut >= 0]] = True
    if not matched or (seam_of_cut < 0).any() or claimed.sum() != len(cut_points):
        log.debug("union: the temporary caps did not come back on their rings; unioning whole tubes")
        return None
    del claimed
    # the stitched mesh, written in place part by part (no full-size temporaries): first the boolean's output
    ff = np.flatnonzero(~face_busy)  # the free pieces' faces
    source = np.concatenate([fid[keep], ff])  # the tube face of each triangle (the boolean kept the ids)
    del fid, face_busy
    nb = len(source) - len(ff)
    faces = np.empty((nb + len(ff), 3), np.int64)
    _kept_faces(point_of, otri, keep, faces)  # the boolean's triangles but the caps', on the points
    del point_of
    if corners:
        normals = np.empty((len(faces), 3, 3), np.float32)
        uv = np.empty((len(faces), 3, 2), np.float32)
        _corner_attributes(props, otri, keep, normals, uv)
    else:
        normals, uv = _no_corners(len(faces), 3, 3), _no_corners(len(faces), 3, 2)
    del props, otri, keep, face_piece
    # then the free pieces: their points (ring points on a cut map onto the seam) and attributes
    if corners:
        wedges = tubes.faces[ff]
        np.take(tubes.wedge_normal, wedges, axis=0, out=normals[nb:])
        np.take(tubes.wedge_uv, wedges, axis=0, out=uv[nb:])
        del wedges
    used = np.zeros(len(tubes.points), bool)
    _free_points(ff, tubes.faces, tubes.wedge_point, used)
    used[cut_points] = False
    fresh = np.flatnonzero(used)
    del used
    new_index = np.full(len(tubes.points), -1, np.int64)
    new_index[fresh] = npts + np.arange(len(fresh))
    new_index[cut_points] = seam_of_cut
    _free_faces(ff, tubes.faces, tubes.wedge_point, new_index, faces[nb:])
    del ff, new_index
    vertices = np.concatenate([seam_pos, tubes.points[fresh]])
    del seam_pos, fresh
    near = np.zeros(len(vertices), bool)  # the seams: the rings where untouched pieces meet the boolean's output
    near[seam_of_cut] = True
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    if not used.all():  # the vertices of dropped crumbs, and property vertices manifold left unused
        renumber = np.cumsum(used) - 1
        for lo in range(0, len(faces), 1 << 20):  # in place, a slice at a time
            faces[lo : lo + (1 << 20)] = renumber[faces[lo : lo + (1 << 20)]]
        vertices, near = vertices[used], near[used]
    log.debug("union: %d faces from the boolean (and its copies), %d from untouched pieces", nb, len(faces) - nb)
    if not _closed(faces, len(vertices), near):
        log.debug("union: the stitched mesh is not closed at a seam; unioning whole tubes")
        return None
    return Mesh(vertices, faces, normals, uv, face_source=source), nb, cleaned


def _cleaned_junctions(junctions: Junctions, tubes: Tubes, clean: JunctionCleaner) -> Part | None:
    """The boolean's result (welded: ``junctions``, its sources as manifold3d gave them) cleaned by ``clean``, as a
    :class:`Part`, or None when it was not or the caps did not come back.

    The sources are made true first (:func:`_true_sources`), as the cleaner
    reads them.  The result is the points alone, without merge vectors: the
    cleanup makes the normals and uv of the whole bark.
    """
    nf = len(tubes.faces)
    vertices, faces = junctions.vertices, junctions.faces
    source = junctions.source.copy()
    on_tube = source < nf  # the others are the temporary caps'
    k = int(on_tube.sum())
    wall = Mesh(vertices, faces[on_tube], _no_corners(k, 3, 3), _no_corners(k, 3, 2), face_source=source[on_tube])
    source[on_tube] = _true_sources(wall, tubes).face_source
    del wall
    out = clean(junctions._replace(source=source))
    if out is None:
        return None
    v, f, s = out
    # the temporary caps exactly as they were: the same faces on the same points
    before, after = np.flatnonzero(~on_tube), np.flatnonzero(s >= nf)
    before, after = before[np.argsort(source[before], kind="stable")], after[np.argsort(s[after], kind="stable")]
    if not (
        len(before) == len(after)
        and np.array_equal(source[before], s[after])
        and np.array_equal(vertices[faces[before]], v[f[after]])
    ):
        log.debug("union: the cleaning of the junctions changed a temporary cap; they stay as the boolean made them")
        return None
    props = np.zeros((len(v), 3))  # the points alone: the cleaner's caller makes normals and uv
    props[:, :3] = v
    none = np.zeros(0, np.int64)
    return Part(props, np.asarray(f, np.int64), none, none, np.asarray(s, np.int64))


@numba.njit(cache=True, nogil=True)
def _faces_of(ids, nf, tube_faces, cap_faces, through):  # pragma: no cover - compiled
    """``(k, 3)`` wedge-indexed faces of the triangle ids ``ids``: tube face ``i < nf``, temporary cap ``i - nf``;
    mapped ``through`` an array (the wedges' points) unless it is empty."""
    out = np.empty((len(ids), 3), np.int64)
    mapped = len(through) > 0
    for i in range(len(ids)):
        k = ids[i]
        for c in range(3):
            w = tube_faces[k, c] if k < nf else cap_faces[k - nf, c]
            out[i, c] = through[w] if mapped else w
    return out


_NO_MAP = np.zeros(0, np.int64)


@numba.njit(cache=True, nogil=True)
def _face_pieces(face_offsets, sides, nspan, span_offsets, span_piece):  # pragma: no cover - compiled
    """``(f,)``: the piece of every tube face: a wall face's span's, a base cap's first span's, a tip cap's last.

    A tube's faces are its walls, two triangles per side and span, span after span, then its base cap's
    ``sides`` triangles, then its tip cap's.
    """
    out = np.empty(face_offsets[-1], np.int64)
    for t in range(len(sides)):
        s2 = 2 * sides[t]
        body = s2 * nspan[t]
        for f in range(face_offsets[t], face_offsets[t + 1]):
            lf = f - face_offsets[t]
            if lf < body:
                span = lf // s2
            elif lf < body + s2 // 2:
                span = 0
            else:
                span = nspan[t] - 1
            out[f] = span_piece[span_offsets[t] + span]
    return out


@numba.njit(cache=True, nogil=True)
def _cap_points(tri, fid, nf, point_of, pos, cap_faces, wedge_point, points, seam_of):  # pragma: no cover
    """Into ``seam_of`` (per tube point): the point (of ``point_of[tri]``, at ``pos``) each corner of the temporary
    cap triangles ``fid >= nf`` came back as, the triangle's corners matched by their exact positions in one of
    its three rotations; False when a cap triangle matches in none or a ring point came back as two points."""
    out = np.empty(3, np.int64)
    ring = np.empty(3, np.int64)
    for t in range(len(fid)):
        q = fid[t] - nf
        if q < 0:
            continue
        for k in range(3):
            out[k] = point_of[tri[t, k]]
            ring[k] = wedge_point[cap_faces[q, k]]
        turn = -1
        for r in range(3):
            same = True
            for k in range(3):
                o, p = out[(k + r) % 3], ring[k]
                same = same and pos[o, 0] == points[p, 0] and pos[o, 1] == points[p, 1] and pos[o, 2] == points[p, 2]
            if same:
                turn = r
                break
        if turn < 0:
            return False
        for k in range(3):
            o, p = out[(k + turn) % 3], ring[k]
            if seam_of[p] < 0:
                seam_of[p] = o
            elif seam_of[p] != o:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _free_points(ff, tube_faces, wedge_point, used):  # pragma: no cover - compiled
    """Mark in ``used`` the points of the tube faces ``ff`` (no (k, 3) gathers of their wedges and points)."""
    for f in ff:
        for c in range(3):
            used[wedge_point[tube_faces[f, c]]] = True


@numba.njit(cache=True, nogil=True)
def _free_faces(ff, tube_faces, wedge_point, new_index, out):  # pragma: no cover - compiled
    """Write the tube faces ``ff`` on the stitched mesh's points (``new_index`` of each tube point) into ``out``."""
    for i in range(len(ff)):
        for c in range(3):
            out[i, c] = new_index[wedge_point[tube_faces[ff[i], c]]]


@numba.njit(cache=True, nogil=True)
def _kept_faces(point_of, tri, keep, faces):  # pragma: no cover - compiled
    """Write ``point_of[tri[keep]]`` into the first rows of ``faces``, in one pass without the (f, 3) gather."""
    f = 0
    for t in range(len(tri)):
        if keep[t]:
            for c in range(3):
                faces[f, c] = point_of[tri[t, c]]
            f += 1


@numba.njit(cache=True, nogil=True)
def _corner_attributes(props, tri, keep, normals, uv):  # pragma: no cover - compiled
    """Write the unit corner normals and the uv of the triangles ``tri[keep]`` from manifold's ``props`` into the
    first rows.

    :func:`_unit_rows` of ``props[tri[keep], 3:6]`` and ``props[tri[keep], 6:]``, as float32, in one pass without
    the (f, 3) and (f, 3, 8) gathers: the same bits (the norm sums x, y, z as ``np.linalg.norm`` does).
    """
    f = -1
    for t in range(len(tri)):
        if not keep[t]:
            continue
        f += 1
        for c in range(3):
            r = tri[t, c]
            x, y, z = props[r, 3], props[r, 4], props[r, 5]
            length = np.sqrt(x * x + y * y + z * z)
            if not length > 1e-12:
                length = 1.0
            normals[f, c, 0] = np.float32(x / length)
            normals[f, c, 1] = np.float32(y / length)
            normals[f, c, 2] = np.float32(z / length)
            uv[f, c, 0] = np.float32(props[r, 6])
            uv[f, c, 1] = np.float32(props[r, 7])


def _part(tubes: Tubes, tri: np.ndarray, tri_id: np.ndarray, shading: bool = True) -> Part:
    """The wedge-indexed triangles ``tri`` of ``tubes`` as one manifold3d mesh, ``tri_id`` as face ids.

    With ``shading`` the normals and uv ride along as properties (a vertex
    per wedge, tied to its point by merge vectors); without, the points alone
    (the boolean's work is a sixth smaller: for a caller that makes its own
    normals and uv, the cleanup).
    """
    if not shading:
        points, tri = _used(len(tubes.points), tubes.wedge_point[tri])
        none = np.zeros(0, np.int64)
        return Part(tubes.points[points], tri, none, none, np.asarray(tri_id, np.int64))
    wedges, tri = _used(len(tubes.wedge_point), tri)
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
    return Part(props, tri, merge_from, merge_to[merge_from], np.asarray(tri_id, np.int64))


def _used(n: int, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The items (of ``n``) that the triangles ``tri`` use, ascending, and ``tri`` renumbered onto them."""
    used = np.zeros(n, bool)
    used[tri] = True
    kept = np.flatnonzero(used)
    del used
    remap = np.empty(n, np.int64)
    remap[kept] = np.arange(len(kept))
    return kept, remap[tri]


def _concat(parts: list[Part]) -> Part:
    """Meshes side by side as one :class:`Part` (indices shifted).

    The list is emptied as its meshes are copied, so that at most one of them
    exists twice at any time.
    """
    if len(parts) == 1:
        return parts.pop()
    nv = np.array([len(p.props) for p in parts])
    nt = np.array([len(p.tri) for p in parts])
    nm = np.array([len(p.merge_from) for p in parts])
    v_off, t_off, m_off = _offsets(nv), _offsets(nt), _offsets(nm)
    out = Part(
        np.empty((v_off[-1], parts[0].props.shape[1])),
        np.empty((t_off[-1], 3), np.int64),
        np.empty(m_off[-1], np.int64),
        np.empty(m_off[-1], np.int64),
        np.empty(t_off[-1], np.int64),
    )
    for i in range(len(parts)):
        p = parts[i]
        parts[i] = None
        out.props[v_off[i] : v_off[i + 1]] = p.props
        np.add(p.tri, v_off[i], out=out.tri[t_off[i] : t_off[i + 1]])  # shifted in place: no temporary copy
        np.add(p.merge_from, v_off[i], out=out.merge_from[m_off[i] : m_off[i + 1]])
        np.add(p.merge_to, v_off[i], out=out.merge_to[m_off[i] : m_off[i + 1]])
        out.face_id[t_off[i] : t_off[i + 1]] = p.face_id
        del p
    parts.clear()
    return out


def _join(parts: list[Part], where: str):
    """The disjoint meshes side by side (the list is emptied): properties, triangles, face ids, point of each vertex."""
    for part in parts:
        if part.props.shape[1] not in (3, _NUM_PROP) or len(part.face_id) != len(part.tri):
            raise GeometryError(
                f"{where}: manifold3d returned {part.props.shape[1]} properties, {len(part.face_id)} face ids"
            )
    whole = _concat(parts)
    point_of, npts = _weld(len(whole.props), whole.merge_from, whole.merge_to)
    return whole.props, whole.tri, whole.face_id, point_of, npts


def _weld(nprops: int, merge_from: np.ndarray, merge_to: np.ndarray):
    """Point index of every property vertex (merge vectors applied) and the number of points."""
    rep = np.arange(nprops)
    rep[merge_from] = merge_to
    while (rep[rep] != rep).any():  # follow chains, should manifold ever write one
        rep = rep[rep]
    root = np.zeros(nprops, bool)
    root[rep] = True
    index = np.cumsum(root) - 1
    return index[rep], int(root.sum())


def _unit_rows(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(length > 1e-12, length, 1.0)


def _closed(faces: np.ndarray, nverts: int, near: np.ndarray | None = None) -> bool:
    """Every directed edge once, and its reverse once: closed and consistently oriented.

    With ``near`` (a mask of vertices), only the edges with an end among them
    are checked: the rest of the mesh is known to be closed (a boolean's output,
    whole tube pieces) and only the seams where the parts were joined need it.
    """
    faces = np.ascontiguousarray(faces)
    mask = np.ones(1, bool) if near is None else np.ascontiguousarray(near, bool)
    index = np.int32 if nverts < 2**31 else np.int64  # the edges' far ends: half the memory of int64 keys
    return bool(_closed_edges(faces, nverts, mask, near is not None, np.zeros(0, index)))


@numba.njit(cache=True, nogil=True)
def _closed_edges(faces, nverts, near, use_near, like):  # pragma: no cover - compiled
    """:func:`_closed` by the checked edges grouped by their first end (a counting sort), without sorting keys.

    The directed edges ``a -> b`` (those with an end in ``near`` if
    ``use_near``) are listed per ``a``; there must be no edge twice, and for
    every edge ``a -> b`` the edge ``b -> a`` must be listed.  With no edge
    twice, every reverse being an edge is the same as the sorted edges equal to
    the sorted reverses (one set maps one to one onto the other).  A vertex's
    list is short; a long one (many triangles at one point) is sorted.
    """
    start = np.zeros(nverts + 1, np.int64)
    for f in range(len(faces)):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            if not use_near or near[a] or near[b]:
                start[a + 1] += 1
    for v in range(nverts):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    far = np.empty(start[nverts], like.dtype)
    for f in range(len(faces)):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            if not use_near or near[a] or near[b]:
                far[fill[a]] = b
                fill[a] += 1
    for v in range(nverts):
        lo, hi = start[v], start[v + 1]
        if hi - lo > 16:
            far[lo:hi] = np.sort(far[lo:hi])
            for i in range(lo + 1, hi):
                if far[i] == far[i - 1]:
                    return False
        else:
            for i in range(lo + 1, hi):
                for j in range(lo, i):
                    if far[i] == far[j]:
                        return False
    for a in range(nverts):
        for i in range(start[a], start[a + 1]):
            b = far[i]
            lo, hi = start[b], start[b + 1]
            found = False
            if hi - lo > 16:
                j = lo + np.searchsorted(far[lo:hi], a)
                found = j < hi and far[j] == a
            else:
                for j in range(lo, hi):
                    if far[j] == a:
                        found = True
                        break
            if not found:
                return False
    return True


def _to_mesh(parts: list[Part], where: str, corners: bool = True) -> Mesh:
    """The disjoint meshes as one Mesh; manifold3d's face ids (the tube face of every piece) as ``face_source``."""
    props, tri, fid, point_of, npts = _join(parts, where)
    vertices = np.empty((npts, 3))
    vertices[point_of] = props[:, :3]
    if not corners:
        return Mesh(vertices, point_of[tri], _no_corners(len(tri), 3, 3), _no_corners(len(tri), 3, 2), face_source=fid)
    return Mesh(vertices, point_of[tri], _unit_rows(props[tri, 3:6]), props[tri, 6:], face_source=fid)
