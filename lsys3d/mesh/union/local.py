"""The local union: only the runs of tube pieces that may touch another tube go through the boolean; the
free pieces are stitched back on (:func:`_local_union`), and the junctions may be cleaned before they are copied
(:class:`Junctions`)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ...arrays import components, release_memory, unique
from ...arrays import offsets as _offsets
from ..mesh import Mesh
from ..sweep import Tubes
from . import jobs as union_jobs
from . import repeats
from .booleans import Part
from .parts import (
    _NO_MAP,
    _cap_points,
    _closed,
    _concat,
    _corner_attributes,
    _face_pieces,
    _faces_of,
    _free_faces,
    _free_points,
    _join,
    _kept_faces,
    _no_corners,
    _part,
    _weld,
)
from .plan import _colour, _namer, _plan, _Progress, _unique_pairs, _use
from .sources import _true_sources
from .weld import _crumbs

log = logging.getLogger("lsys3d")


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


class Touching(NamedTuple):
    """Which pieces of the tubes may touch another tube (:func:`lsys3d.mesh.union.touch.touching`)."""

    pieces: object
    """The tubes' pieces (:func:`lsys3d.mesh.union.touch.pieces`)."""
    a: np.ndarray
    """(m,) int64: piece ``a[i]`` may touch piece ``b[i]``."""
    b: np.ndarray
    """(m,) int64"""
    busy: np.ndarray
    """(pieces,) bool: the pieces in some pair."""


class UnionRun(NamedTuple):
    """How one union runs: what its messages call it and what it is asked to make."""

    where: str
    """The union's name in messages."""
    workers: int
    """Processes for the boolean jobs."""
    progress: _Progress
    corners: bool = True
    """Make the corner normals and uv."""
    clean: JunctionCleaner | None = None
    """Cleans the junctions before they are copied (:func:`~lsys3d.mesh.union.union.union_cleaning_junctions`)."""
    origin: np.ndarray | None = None
    """For each face of the union's own tubes, the face of the given tubes it lies in."""


def _local_union(tubes: Tubes, touching: Touching, run: UnionRun):
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
    pcs, a, b, busy = touching
    where, workers, progress, corners, clean, origin = run
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
