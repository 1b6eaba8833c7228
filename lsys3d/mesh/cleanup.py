"""Cleanup: the union's bark -> a production mesh (no slivers, smooth junctions, even uv, smooth normals).

A boolean cuts the tube faces it crosses into polygons and triangulates
them: needles from each point of the intersection curve to the far corners
of the cut faces (as long as the span), caps where the curve passes close to
a vertex, and zero-area slivers where tubes meet almost tangentially.  On
``tree3d`` 45% of the union's triangles have an aspect above 100 and 739 are
less than a micrometre high; they break tangent generation, lightmap
unwrapping, subdivision and decimation downstream.  This stage removes them
with operations that keep the mesh closed (:mod:`lsys3d.mesh.remesh`):

* every triangle knows the tube face it is a piece of
  (:attr:`lsys3d.mesh.mesh.Mesh.face_source`, carried through the boolean), so the
  *seam* (edges between two tubes), the *rims* of the tubes' flat caps and the
  local length *scale* (the side of the thinnest tube at a vertex) are exact;
* edges shorter than ``short`` scales collapse (the end on a tube keeps its
  place, moved off it only as far as keeps the volume); caps' long edges flip
  where that moves the surface less than ``flip_tolerance`` scales, or their
  far corner snaps onto the edge; the fans of needles from the seam are cut
  ``step`` scales from it; a last pass removes what is still worse than
  aspect 500 or lower than 1 um;
* where a cap of a tube was cut by the boolean (a thick child's base poking
  out of its parent), the cap is no rim to keep: it is part of the junction;
* the first cleaning runs on two halves of the mesh at once, kept apart by a
  locked band that a pass cleans after them (:func:`lsys3d.mesh.remesh.halves`):
  the same bytes with one thread or two.

Per-vertex attributes made before the cleanup (branch id, order...) follow
the map :attr:`Cleaned.vertex_origin`: ``attribute[cleaned.vertex_origin]``
(a vertex made by a split takes its nearer end's); per-face ones follow
``Mesh.face_source`` of the result, which still names the tube face.

Examples
--------
>>> import lsys3d
>>> from lsys3d.mesh.quality import quality
>>> tree = lsys3d.generate("abop-1.24a", iterations=2)  # the pipeline cleans by default
>>> q = quality(tree.bark)
>>> q.over_1000, q.slivers, tree.bark.is_watertight
(0, 0, True)
"""

from __future__ import annotations

import logging
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import compiling
from ..errors import GeometryError
from ..options import Options, option
from . import remesh
from .mesh import Mesh, crumbs
from .sweep import Tubes
from .union.blob_uv import box_uv, face_density, tube_density
from .union.local import Junctions
from .union.weld import _separate_float32  # the union's last step, kept true here

__all__ = ["Cleaned", "CleanupOptions", "clean_junctions", "clean_mesh", "cleanup", "smooth_normals", "tube_uv"]

log = logging.getLogger("lsys3d")


@dataclass(frozen=True)
class CleanupOptions(Options):
    """How the union's bark is cleaned; every default, range and help is in its field.

    Lengths are in local *scales*: the side of the thinnest tube at a place
    (its circumference over its sides).
    """

    enabled: bool = option(True, name="cleanup", help="remove the union's needles and slivers (off: the raw boolean)")
    smooth: bool = option(True, name="smooth_junctions", help="blend each branch into its parent over a collar")
    collar: float = option(
        1.5, low=0, high=100, help="width of a junction's collar, in sides of the thinner tube", cli=False
    )
    fairing: int = option(10, low=0, high=1000, help="smoothing steps of the collars", cli=False)
    reach: float = option(0.5, low=0, help="farthest a collar vertex moves, in local scales", cli=False)
    short: float = option(0.4, low=0, high=1, help="collapse edges shorter than this many local scales", cli=False)
    limit: float = option(40.0, low=1, help="a collapse may leave triangles of at most this aspect", cli=False)
    bad: float = option(60.0, low=1, help="triangles of a worse aspect are flipped, snapped or split", cli=False)
    flip_tolerance: float = option(
        0.05, low=0, help="a flip may move the surface by at most this many local scales", cli=False
    )
    long: float = option(3.0, low=0, help="cut seam fans whose edges are longer than this many scales", cli=False)
    step: float = option(1.5, low=0, help="this many scales from the seam", cli=False)
    fallback: float = option(1.0, low=0, help="a bad face's shortest edge collapses below this many scales", cli=False)
    rescue: float = option(500.0, low=1, help="aspect above which the last pass takes any collapse", cli=False)
    sliver: float = option(1e-6, low=0, help="metres: the last pass removes triangles lower than this", cli=False)

    def bulge(self, sides: int) -> float:
        """How far the collars may move a vertex out of its tube, in radii of a tube of ``sides`` sides.

        A vertex moves at most ``reach`` local scales (a side of the thinner
        tube, ``2 r sin(pi / sides)``); the stages that find a vertex's branch
        by its distance from the skeleton (attributes, materials) allow it.
        """
        if not (self.enabled and self.smooth):
            return 0.0
        return self.reach * 2.0 * float(np.sin(np.pi / max(int(sides), 3)))


@dataclass(frozen=True, eq=False)
class Cleaned:
    """What :func:`clean_mesh` returns.

    Attributes
    ----------
    mesh : Mesh
        The cleaned bark; ``face_source`` still names the tube face of each triangle.
    vertex_origin : (v,) int64
        The vertex of the input each vertex descends from: ``attribute[vertex_origin]``
        carries a per-vertex attribute of the input.
    operations : dict
        How many of each operation were done (for logs and benchmarks).
    """

    mesh: Mesh
    vertex_origin: np.ndarray
    operations: dict


_ROOM_SHARE, _ROOM_MIN = 0.125, 1024
"""Room for the splits to start with: this share of the faces, plus this many (the presets make under 4 %)."""


class _Surface(NamedTuple):
    """What the cleaning reads of the union's bark: its normals and uv are made anew at the end."""

    vertices: np.ndarray
    faces: np.ndarray
    face_source: np.ndarray


def _drop_crumbs(bark: Mesh | _Surface) -> _Surface:
    """Remove closed pieces that enclose (almost) nothing: flat or inside-out crumbs of the boolean.

    Where coplanar tubes cross (the flat presets), a boolean can leave a
    tetrahedron of four triangles beside the plant, enclosing no volume or a
    negative one: :func:`lsys3d.mesh.mesh.crumbs`, under 1e-3 of the bark's area.
    """
    crumb = crumbs(bark.vertices, bark.faces, 1e-3, inside_out=True)
    if not crumb.any():
        return _Surface(bark.vertices, bark.faces, bark.face_source)
    keep = ~crumb
    log.debug("cleanup: dropped crumbs of %d triangles", crumb.sum())
    return _Surface(bark.vertices, bark.faces[keep], bark.face_source[keep])


def _classify(bark: _Surface, tubes: Tubes, caps: Junctions | None = None, pool=None):
    """Per face: tube, flat (cap), which cap, reference normal; per vertex: scale and flags (:mod:`lsys3d.mesh.remesh`).

    A face's cap is ``2 tube + (0 at the base, 1 at the tip)``, -1 on the wall.
    With ``caps`` (:class:`lsys3d.mesh.union.local.Junctions`), the sources are faces
    of the union's own tubes (``caps.origin`` says which face of ``tubes``
    each lies in), and from ``len(caps.origin)`` on faces of temporary caps:
    flat, cap ``2 len(tubes) + its number``, the tube of ``caps.cap_face``,
    their points :data:`~lsys3d.mesh.remesh.PINNED`.  Everything else is read from
    the faces of ``tubes`` the faces lie in, as for the bark of the whole
    union: the union's own rings are no shape to keep.
    """
    if caps is None:
        src = bark.face_source
        part, cap = tubes.face_kinds(src)
        points, wedge_point, table = tubes.points, tubes.wedge_point, tubes.faces
    else:
        n = len(caps.origin)
        temp = bark.face_source >= n
        k = bark.face_source[temp] - n
        lies = caps.origin[np.where(temp, 0, bark.face_source)]
        lies[temp] = caps.cap_face[k]
        part, cap = tubes.face_kinds(lies)
        cap[temp] = 2 * len(tubes) + caps.cap_number[k]
        # the corners of the tube faces the junctions lie in, then the caps' own (not a copy of all the tubes)
        used, inverse = np.unique(lies[~temp], return_inverse=True)
        corners = np.concatenate([tubes.points[tubes.wedge_point[tubes.faces[used]]], bark.vertices[bark.faces[temp]]])
        src = np.empty(len(temp), np.int64)
        src[~temp] = inverse
        src[temp] = len(used) + np.arange(int(temp.sum()))
        points = corners.reshape(-1, 3)
        wedge_point = np.arange(len(points))
        table = wedge_point.reshape(-1, 3)
    flat = cap >= 0
    # the shortest edge of the tube faces around each vertex, whether it is a tube vertex, each face's tube normal
    scale, original, reference = remesh.tube_faces(
        bark.vertices, bark.faces, points, wedge_point, table, src, 1e-4, 1e-5, pool
    )
    flags = np.where(original, remesh.ORIGINAL, 0).astype(np.int64)
    if caps is not None:
        flags[np.unique(bark.faces[temp])] |= remesh.PINNED
    return part, flat, cap, scale, flags, reference


def _half_edges(bark: _Surface, tubes: Tubes, room: int, pool=None, caps: Junctions | None = None):
    """The half-edges of ``bark`` with ``room`` for splits, classified and marked; the reason if it is not closed.

    ``caps``: the temporary caps of :class:`lsys3d.mesh.union.local.Junctions` (see :func:`_classify`)."""
    part, flat, cap, scale, flags, reference = _classify(bark, tubes, caps, pool)
    try:
        he = remesh.build(
            bark.vertices, bark.faces, flags, scale, part, flat, reference, bark.face_source, room, pool=pool
        )
    except ValueError as exc:
        return str(exc)
    del scale, flags, reference
    # the seams and rims flagged; the caps the boolean cut are no rims (``flat`` changes)
    remesh.mark(he, len(bark.faces), part, cap, flat, np.zeros(int(cap.max(initial=-1)) + 1, bool))
    return he


def _full(he) -> bool:
    """Whether the half-edges ran out of room for a split (a split that found none was not made)."""
    return bool(he.counts[0] >= he.counts[2] or he.counts[1] + 2 > he.counts[3])


_HALVES_MIN = 4096
"""Faces under which the first cleaning is not split in halves (two threads would cost more than they save)."""
_BAND = 3
"""Edges from the cut between the halves that neither half touches (see :func:`lsys3d.mesh.remesh.halves`)."""
_NO_REGION, _NO_SIDE = np.zeros(0, bool), np.zeros(0, np.int8)


class _Inline:
    """An executor that runs each call at once in the calling thread (the cleanup on one core): the same results."""

    def submit(self, fn, *args) -> Future:
        done = Future()
        try:
            done.set_result(fn(*args))
        except BaseException as exc:  # handed to whoever asks for the result, as a thread's would be
            done.set_exception(exc)
        return done

    def map(self, fn, *iterables):
        return map(fn, *iterables)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None


def _executor(threads: int):
    """The threads the cleanup's passes are shared with, one pool for a whole cleaning (threads start once), or
    none (``threads`` 1): the same bytes either way.  Two: a pass given to one may share its own work with the
    other (:func:`tube_uv`)."""
    return ThreadPoolExecutor(2) if threads > 1 else _Inline()


def _clean_halves(
    he, rules, order=None, spawned=None, region=_NO_REGION, skip: int = -1, depth: int = 2, pool=None
) -> tuple[np.ndarray, bool]:
    """The first cleaning, both halves at once (:func:`lsys3d.mesh.remesh.halves`), then the band between them,
    itself in two halves across it, then what is near that second cut.

    Each half splits into its own share of the room.  The result does not
    depend on the threads: ``order`` (a test's) runs the halves one after
    the other in that order instead.  With a ``pool`` (an executor), the
    second half runs in one of its threads and the first in the calling
    thread (no thread to wake for it).  ``spawned`` counts each vertex's
    fan splits through all of it; ``region``, ``skip``
    and ``depth`` are the second cut's.  The operations done, and whether a
    half ran out of room.
    """
    nv, nf, vcap, fcap = (int(c) for c in he.counts)
    if spawned is None:
        spawned = np.zeros(vcap, np.int64)
    if nf < _HALVES_MIN or depth == 0:
        return remesh.clean(he, rules, region, _NO_SIDE, 0, spawned), _full(he)
    side, band, near, axis = remesh.halves(he, _BAND, region if len(region) else None, skip)
    lock = band & ((he.flags & remesh.LOCKED) == 0)
    he.flags[lock] |= remesh.LOCKED
    half = (vcap - nv) // 2
    counts = (
        np.array([nv, nf, nv + half, nf + 2 * half], np.int64),
        np.array([nv + half, nf + 2 * half, vcap, fcap], np.int64),
    )

    def run(own, _=None):  # (_in_two's range: this half and the next)
        return remesh.clean(he._replace(counts=counts[own]), rules, region, side, own, spawned)

    # the second half in one of the pool's threads and the first here; a test's ``order``: one after the other
    done = sum(remesh.in_two(pool, run, (), 0, 1, None) if order is None else [run(own) for own in order])
    he.flags[lock] &= ~remesh.LOCKED
    full = any(_full(he._replace(counts=c)) for c in counts)
    he.counts[:2] = counts[1][:2]  # the second half's room is after the first's: the rest splits after it
    del band, lock
    rest, rest_full = _clean_halves(he, rules, order, spawned, near, axis, depth - 1, pool)
    return done + rest, full or rest_full


def _clean(he, opt: CleanupOptions, budget: int, order=None, pool=None):
    """Clean, fair and rescue ``he`` in place; the operations done, faired, rescued, and whether it ran out of room.

    ``pool`` (an executor): the calling thread and one of its threads share the halves, the fairing's steps,
    and the looking for what the rescue has to do."""
    rules = remesh.Rules(opt.short, opt.limit, opt.bad, opt.flip_tolerance, opt.long, opt.step, opt.fallback, budget)
    done, full = _clean_halves(he, rules, order, pool=pool)
    faired = 0
    if opt.smooth:
        closeness = np.zeros(len(he.points))
        remesh.collar(he, opt.collar, closeness)
        faired = remesh.fair(he, closeness, opt.fairing, 0.8, opt.reach, False, pool)
        remesh.settle(he, closeness)  # the faired surface is now (half) the side to keep
        # the faired collars may have made a few needles
        done += remesh.clean(he, rules, closeness > 0, _NO_SIDE, 0, np.zeros(len(he.points), np.int64))
    rescued = remesh.rescue(he, opt.rescue, opt.sliver, 10 * opt.flip_tolerance, pool)
    return done, faired, rescued, full or _full(he)


def clean_mesh(
    bark: Mesh, tubes: Tubes, options: CleanupOptions | None = None, threads: int = 2, junctions: bool = False
) -> Cleaned:
    """Clean a unioned bark (see the module's documentation); the mesh and the map of its vertices.

    Parameters
    ----------
    bark : Mesh
        The union's result: closed, consistently oriented, with ``face_source``.
    tubes : Tubes
        The tubes it was made of.
    options : CleanupOptions, optional
    threads : int
        2 (the default): the passes that can are shared with other threads;
        1: all in the calling thread (a tree per core).  The same bytes either way.
    junctions : bool
        The union cleaned the junctions already (:func:`clean_junctions`, through
        :func:`lsys3d.mesh.union.union.union_cleaning_junctions`): only the normals and uv are made.

    Returns
    -------
    Cleaned
        The input unchanged (and an identity map) when cleaning is off, the
        mesh has no face sources, or it is not a closed 2-manifold.
    """
    opt = CleanupOptions() if options is None else options
    identity = Cleaned(bark, np.arange(len(bark.vertices)), {})
    if not opt.enabled or bark.face_source is None or not len(bark.faces) or not len(tubes):
        return identity
    compiling.wait(remesh.__name__)  # a first run's helper compiling the kernels (lsys3d.mesh.precompile)
    with _executor(threads) as pool:
        if junctions:
            points, faces, fsrc = bark.vertices, bark.faces, bark.face_source
            fflat, origin, operations = None, np.arange(len(points)), {}  # the flat faces: beside the uv, below
        else:
            cleaned = _clean_arrays(bark, tubes, opt, pool=pool)
            if cleaned is None:
                return identity
            (points, faces, fflat, fsrc, origin), operations = cleaned  # the half-edges are gone: a third
        # the uv (in two halves) beside the flat faces, then the normals in two
        boxed = tube_density(tubes, bark.face_source, bark.face_box_uv)  # a blob's crowd: a box projection
        uv = pool.submit(tube_uv, tubes, points, faces, fsrc, pool, boxed)
        if fflat is None:
            fflat = _flat_faces(faces, fsrc, tubes)
        normals = smooth_normals(points, faces, fflat, pool)
        uv = uv.result()
    mesh = Mesh(points, faces, normals, uv, face_source=fsrc)
    if not junctions:  # (with them, the vertices are the union's, which it has separated already)
        # end as the union ends: no two vertices that a float32 file or a reader's weld would merge
        mesh = _separate_float32(mesh)
    return Cleaned(mesh, origin, operations)


def clean_junctions(tubes: Tubes, junctions: Junctions, options: CleanupOptions | None = None, threads: int = 2):
    """The junctions cleaned for :func:`~lsys3d.mesh.union.union.union_cleaning_junctions`: vertices, faces, sources.

    ``tubes`` are the tubes given to the union.  The same cleaning as
    :func:`clean_mesh`'s, on the pieces of the bark that came out of the
    boolean, closed by temporary caps: their rings are
    :data:`~lsys3d.mesh.remesh.PINNED`, so the caps come back exactly as they were,
    and the union stitches the untouched tube pieces back onto them.  None
    when cleaning is off or the pieces are not closed 2-manifolds.
    """
    opt = CleanupOptions() if options is None else options
    if not opt.enabled or not len(junctions.faces):
        return None
    compiling.wait(remesh.__name__)
    surface = _Surface(junctions.vertices, junctions.faces, junctions.source)
    with _executor(threads) as pool:
        cleaned = _clean_arrays(surface, tubes, opt, pool=pool, caps=junctions)
    if cleaned is None:
        return None
    (points, faces, _, source, _), operations = cleaned
    log.debug("cleanup of the junctions: %s", operations)
    return points, faces, source


def _clean_arrays(bark: Mesh | _Surface, tubes: Tubes, opt: CleanupOptions, order=None, pool=None, caps=None):
    """The cleaned bark's points, faces, flat faces, face sources and vertex origins, and the operations done;
    None when the bark is not a closed 2-manifold (a warning says so).  ``order``: see :func:`_clean_halves`;
    ``pool``: :func:`_executor`'s (None: all in the calling thread); ``caps``: :func:`_classify`'s."""
    pool = _Inline() if pool is None else pool
    if isinstance(pool, ThreadPoolExecutor):
        whole = _Surface(bark.vertices, bark.faces, bark.face_source)
        # the crumbs are looked for beside the half-edges' making, which is made again if some are dropped
        crumbs = pool.submit(_drop_crumbs, bark)
        room = int(len(whole.faces) * _ROOM_SHARE) + _ROOM_MIN
        try:
            made = _half_edges(whole, tubes, room, pool, caps)
        finally:
            bark = crumbs.result()
        if len(bark.faces) != len(whole.faces):
            made = None
        del whole
    else:
        bark, made = _drop_crumbs(bark), None
    nf = len(bark.faces)
    # room for the splits: the presets make at most 4 % of the faces' count (bush); a run that fills the room
    # is made again with four times as much, so the result never depends on the room (only memory does)
    room = int(nf * _ROOM_SHARE) + _ROOM_MIN
    # a budget of operations, a guard the presets never reach (under one per face; flips cannot cycle since
    # the aspect is the same whatever the order of a triangle's corners): if reached, the result says so
    budget = 4 * nf
    while True:
        # made again for each try (a try changes the flags and flat faces): what the half-edges hold a copy of
        # is not kept while they are cleaned
        he = made if made is not None else _half_edges(bark, tubes, room, caps=caps)
        made = None
        if isinstance(he, str):
            log.warning("cleanup: skipped, %s", he)
            return None
        *result, full = _clean(he, opt, budget, order, pool)
        if not full:
            break
        log.debug("cleanup: %d splits filled the room; again with %d", room, 4 * room)
        room *= 4
    done, faired, rescued = result
    if done.sum() >= budget:
        log.warning("cleanup: stopped after %d operations (%d flips); some needles may remain", done.sum(), done[1])
    operations = {
        "collapses": int(done[0] + done[4]),
        "flips": int(done[1]),
        "snaps": int(done[2]),
        "splits": int(done[3]),
        "rescued": int(rescued),
        "faired": int(faired),
    }
    log.debug("cleanup: %s", operations)
    points, faces, _, fflat, fsrc, origin, _ = remesh.compact(he, pool)
    return (points, faces, fflat, fsrc, origin), operations


def _flat_faces(faces: np.ndarray, source: np.ndarray, tubes: Tubes) -> np.ndarray:
    """``(f,) bool``: the faces of a tube's flat cap that no seam crosses (:func:`lsys3d.mesh.remesh.mark`'s ``flat``).

    A cap that meets a face of another tube along an edge is part of a
    junction (a thick child's base poking out of its parent), no rim to keep
    (:func:`lsys3d.mesh.remesh.cut_caps`).
    """
    part, cap = tubes.face_kinds(source)
    flat = cap >= 0
    if not flat.any():
        return flat
    cut = remesh.cut_caps(np.ascontiguousarray(faces), part, cap, int(cap.max()) + 1)
    on_cap = np.flatnonzero(flat)  # a few of the faces: no full-size temporaries
    flat[on_cap] = ~cut[cap[on_cap]]
    return flat


def tube_uv(
    tubes: Tubes, points: np.ndarray, faces: np.ndarray, source: np.ndarray, pool=None, boxed: np.ndarray | None = None
) -> np.ndarray:
    """Corner uv ``(f, 3, 2) float32``: each face's corners in the chart of the tube face it lies on
    (:meth:`Tubes.uv_at`, made in float64 and rounded once, as :class:`~lsys3d.mesh.mesh.Mesh` keeps them).

    Vertices the cleanup moved or made get the texture coordinates the tube
    itself would give them, so the texture is not dragged along.  With a
    ``pool`` (an executor), one of its threads fills the second half (the same values).
    ``boxed`` ``(t,)``: the tubes of a blob's crowd whose faces take a box projection at that
    density instead (:mod:`lsys3d.mesh.union.blob_uv`; 0 or None: the tube's chart).
    """
    uv = np.empty((len(faces), 3, 2), np.float32)
    source, points, faces = (np.ascontiguousarray(a) for a in (source, np.asarray(points, np.float64), faces))
    remesh.in_two(pool, tubes.corner_uv, (source, points, faces, uv), 0, len(faces) // 2, len(faces))
    if boxed is not None:
        box_uv(points, faces, face_density(tubes, source, boxed), uv)
    return uv


def cleanup(
    bark: Mesh, tubes: Tubes, options: CleanupOptions | None = None, threads: int = 2, junctions: bool = False
) -> Mesh:
    """The cleanup stage: :func:`clean_mesh`'s mesh (``threads``, ``junctions``: see there).

    Raises
    ------
    GeometryError
        Cleaning is on but the bark does not say which tube face each
        triangle is a piece of (``Mesh.face_source``, set by
        :func:`lsys3d.mesh.union.union.union`): the cleanup would silently do nothing.
    """
    opt = CleanupOptions() if options is None else options
    if opt.enabled and len(bark.faces) and bark.face_source is None:
        raise GeometryError("cleanup: the bark has no face sources (Mesh.face_source); it is not the union's output")
    return clean_mesh(bark, tubes, opt, threads, junctions).mesh


def smooth_normals(vertices: np.ndarray, faces: np.ndarray, flat: np.ndarray, pool=None) -> np.ndarray:
    """Corner normals ``(f, 3, 3) float32``: angle-weighted vertex normals of curved faces; flat faces keep their own.

    Continuous across every edge between curved faces (the junction seams
    among them), sharp at the rims of flat caps.  With a ``pool`` (an
    executor), one of its threads makes half of them (the same bits).
    """
    points, faces, flat = np.asarray(vertices, np.float64), np.asarray(faces, np.int64), np.asarray(flat, bool)
    compiling.wait(remesh.__name__)
    return remesh.corner_normals(points, faces, flat, pool)
