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
   parent), adds nothing and stays out.  With ``UnionOptions.cover`` (off by
   default; :mod:`lsys3d.mesh.union.cover`), so does every tube within that
   fraction of its width of the spans of earlier tubes that stay (the
   nested short tubes of dense grammars), a bounded simplification.  With
   ``UnionOptions.blobs`` (on by default; :mod:`lsys3d.mesh.union.blobs`), a
   cluster of many mutually overlapping tubes is meshed as a level set
   instead, where a cost model finds that faster than the boolean, and its
   tubes leave the boolean too.
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

import manifold3d
import numpy as np

from ...arrays import gather, release_memory, unique
from ...errors import GeometryError, LimitError
from ...options import Options, option
from ..mesh import Mesh
from ..sweep import Tubes
from . import booleans
from . import jobs as union_jobs
from .blobs import blob_meshes
from .booleans import BooleanError, Part
from .cover import COVER_PAIRS, covered_tubes
from .local import JunctionCleaner, Junctions, Touching, UnionRun, _local_union
from .parts import _part, _to_mesh
from .plan import _colour, _namer, _plan, _Progress, _unique_pairs, _use
from .sources import _sourced, _true_sources
from .touch import DEFAULT_MAX_PAIRS, buried_tubes, duplicate_tubes, free_stretches, pieces, too_many_pairs, touching
from .weld import _drop_crumbs, _weld_float32

__all__ = ["Junctions", "UnionOptions", "concatenate", "may_touch", "union", "union_cleaning_junctions"]

log = logging.getLogger("lsys3d")


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
    cover: float = option(
        0.0,
        low=0,
        high=1,
        name="union_cover",
        help="leave out of the boolean every tube within this fraction of its width of the spans of earlier tubes "
        "that stay (0: off; the union's surface moves by at most that much: docs/mesh.md, dense grammars)",
    )
    blobs: float = option(
        0.25,
        low=0,
        high=1,
        name="union_blobs",
        help="mesh a cluster of many mutually overlapping tubes as a level set, on a grid whose edge is this fraction "
        "of its thinnest width, where a cost model finds that faster than the boolean (0: off, every cluster "
        "through the boolean; docs/mesh.md, dense grammars)",
    )
    max_pairs: int = option(
        DEFAULT_MAX_PAIRS,
        low=1,
        name="max_union_pairs",
        help="most pairs of tube pieces that may touch in the union (more is a crowd of branches that would take "
        "minutes; about 0.1 ms of boolean work each)",
    )

    def plain(self) -> dict:
        """The options as plain data, without ``workers`` (how the work runs, not what it makes).

        ``cover`` (off by default) is there only when on, so files made without it keep the bytes they had before
        it existed.  ``blobs`` is always there (on by default since issue 34; a file made before that, without
        the key, was made with it off).
        """
        data = super().plain()
        del data["workers"]
        if not self.cover:
            del data["cover"]
        return data


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
    tubes, pcs, a, b, origin, blobs = _prepare(tubes, opt, progress, corners)
    release_memory()
    if not len(tubes):  # every tube went into a level set: nothing for the boolean, no junction to clean
        progress(1.0)
        return _weld_float32([_joined(None, blobs)]), True
    log.debug("union: %d pieces, %d touching pairs (%.2f s)", len(pcs), len(a), time.perf_counter() - t0)
    progress(0.10)
    busy = np.zeros(len(pcs), bool)
    busy[a] = True
    busy[b] = True
    if opt.local and len(a) and busy.mean() <= opt.local_max:
        run = UnionRun(where, workers, progress, corners, clean, origin)
        held = [_local_union(tubes, Touching(pcs, a, b, busy), run)]
        if held[0] is not None:
            progress(0.90)
            mesh, from_boolean, cleaned = held.pop()
            # the cleaned junctions' sources were made true before they were cleaned (and their copies' follow)
            held.append(mesh if cleaned else _true_sources(mesh, tubes, from_boolean))
            del mesh
            del tubes, pcs, a, b, busy  # the weld's memory: the stitched mesh is all that is needed now
            mesh = _weld_float32(held)
            progress(1.0)
            return _with_blobs(_sourced(mesh, origin, where), blobs), cleaned
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
    return _with_blobs(_sourced(mesh, origin, where), blobs), False


def _joined(mesh: Mesh | None, blobs: list[Mesh]) -> Mesh:
    """The union's mesh and the level sets of the blobs (disjoint from it: other clusters) as one, face sources kept."""
    parts = ([] if mesh is None else [mesh]) + blobs
    shift = np.cumsum([0] + [len(m.vertices) for m in parts[:-1]])
    return Mesh(
        np.concatenate([m.vertices for m in parts]),
        np.concatenate([m.faces + k for m, k in zip(parts, shift, strict=True)]),
        np.concatenate([m.normals for m in parts]),
        np.concatenate([m.uv for m in parts]),
        face_source=np.concatenate([m.face_source for m in parts]),
        face_box_uv=_box_of(parts),
    )


def _box_of(parts: list[Mesh]) -> np.ndarray | None:
    """The parts' ``face_box_uv`` as one (0 for the faces of parts without it), or None if none has it."""
    if all(m.face_box_uv is None for m in parts):
        return None
    return np.concatenate(
        [np.zeros(len(m.faces), np.float32) if m.face_box_uv is None else m.face_box_uv for m in parts]
    )


def _with_blobs(mesh: Mesh, blobs: list[Mesh]) -> Mesh:
    """:func:`_joined`, welded as the union's own result is (nothing to do without blobs)."""
    return _weld_float32([_joined(mesh, blobs)]) if blobs else mesh


def _leave_out(tubes: Tubes, origin: np.ndarray, drop: np.ndarray, why: str):
    """The tubes without ``drop``, and ``origin`` (each face's face in the given tubes) for the faces kept."""
    log.debug("union: %d tubes %s left out", int(drop.sum()), why)
    return tubes.select(~drop), origin[gather(tubes.face_offsets, np.flatnonzero(~drop))[0]]


def _crowd_pairs(pcs, opt: UnionOptions):
    """The pairs of pieces that may touch, up to ``COVER_PAIRS`` times ``max_pairs`` of them (for the blobs' and the
    cover's tests, which run before the refusal); more is refused as ``max_pairs`` is (more than that many too)."""
    try:
        return touching(pcs, opt.margin, COVER_PAIRS * opt.max_pairs)
    except LimitError:
        raise too_many_pairs(opt.max_pairs) from None


def _prepare(tubes: Tubes, opt: UnionOptions, progress: Callable[[float], None], corners: bool = True):
    """Cull what adds nothing, find what may touch, refine long straight spans.

    Returns the tubes, their pieces, the pairs of pieces that may touch,
    for each face of the returned tubes the face of the given tubes it is (or
    lies in, for a span split by new rings), and the level sets of the
    clusters meshed as blobs (``UnionOptions.blobs``; their tubes are left
    out; their face sources name faces of the given tubes).  Without ``corners`` (the points
    alone go through the boolean) the refined tubes carry no wedge normals and uv.
    """
    origin = np.arange(len(tubes.faces))

    dup = duplicate_tubes(tubes)
    if dup.any():
        tubes, origin = _leave_out(tubes, origin, dup, "equal to another")
    pcs = pieces(tubes)
    blobs = []
    a = b = None  # the pairs of ``pcs`` that may touch, once found (up to COVER_PAIRS times max_pairs of them)
    if opt.blobs > 0:
        # the blobs are found before the refusal too: they are what makes a dense grammar's crowd
        a, b = _crowd_pairs(pcs, opt)
        pairs = _unique_pairs(pcs.tube[a], pcs.tube[b])
        blobs, meshed = blob_meshes(tubes, pairs[:, 0], pairs[:, 1], opt.blobs, corners)
        if meshed.any():
            blobs = [replace(m, face_source=origin[m.face_source]) for m in blobs]
            tubes, origin = _leave_out(tubes, origin, meshed, "meshed as level sets")
            if not len(tubes):
                return tubes, None, None, None, origin, blobs
            pcs = pieces(tubes)
            a = b = None
    if opt.cover > 0:
        # what may show is found before the refusal: a dense grammar's crowd is mostly covered tubes
        if a is None:
            a, b = _crowd_pairs(pcs, opt)
        covered = covered_tubes(tubes, pcs, a, b, opt.cover)
        if covered.any():
            tubes, origin = _leave_out(tubes, origin, covered, f"within {opt.cover:g} of their width of another")
            pcs = pieces(tubes)
            a = b = None
    if a is None:
        a, b = touching(pcs, opt.margin, opt.max_pairs)
    elif len(a) > opt.max_pairs:  # the pairs already found (no tube left since): refused as touching refuses
        raise too_many_pairs(opt.max_pairs)
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
    return tubes, pcs, a, b, origin, blobs
