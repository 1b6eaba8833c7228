"""The half-edge mesh the remeshing works on (:class:`HalfEdges`): building it from faces (opposites, flags,
pinches locked), compacting it, and walking it: the next and previous half-edge, a half-edge's ends and apex,
the one-ring of a vertex (:func:`_ring`), its valence, the half-edge between two vertices.

Half-edge ``3 f + k`` runs from corner ``k`` of face ``f`` to corner ``k + 1``; ``opp`` pairs it with the
half-edge running the other way."""

from __future__ import annotations

from concurrent.futures import wait
from typing import NamedTuple

import numpy as np

from ...compiling import inner, kernel

SEAM = 1
"""Vertex flag: on an edge between faces of two different tubes (the boolean's intersection curve)."""
FEATURE = 2
"""Vertex flag: on a sharp rim (a flat cap's edge): it stays, and only merges along its rim."""
ORIGINAL = 4
"""Vertex flag: a vertex of the swept tubes (not made by the boolean)."""
LOCKED = 8
"""Vertex flag: never moved or removed (its faces do not form a single fan)."""
PINNED = 16
"""Vertex flag, with :data:`FEATURE`: never moved or removed, and no edge between two of them split or flipped
(the ring of a temporary cap, :func:`lsys3d.mesh.union.union.union`'s cleaning of junctions: the ring must come back
exactly where it was, the cap's faces exactly as they were).  Its other edges may be split, flipped or
collapsed into it."""
_MAX_RING = 256  # a vertex with more neighbours than this is left alone


# Kernels allocate with np.empty and a fill (``a[:] = 0``), not np.zeros or np.full: numba compiles its np.zeros
# (with the np.empty and the fill it calls) for each type and each set of its callers' flags, a few hundredths of
# a CPU second each on a first run, where the np.empty the kernels call is compiled already.  The same bits.
# The kernels Python calls take the arrays of a HalfEdges they use rather than all of it where they call no helper
# that takes it: numba makes each a CPython wrapper that unboxes every array passed, for a whole HalfEdges about
# 0.07 CPU s of a first run's compiling (against a few hundredths for three arrays).
# The helpers that allocate nothing are compiled without numba's reference counts: with them, a call counted each
# of the 14 arrays of a HalfEdges up on entry and down on return, atomic operations that numba could not prune
# around the calls (any of which may raise), a fifth of the cleanup's time on abop-1.24a (measured with perf).
# Only other kernels call them, so they have no CPython wrapper either (:func:`lsys3d.compiling.inner`): one that
# unboxes a HalfEdges' 14 arrays, compiled for nothing, was a fifteenth of the first run's compiling of the cleanup.
_leaf_inner = inner(nogil=True, _nrt=False)


# The helpers that a collapse calls a few times each (_ring, _valence, _half_edge, the collapse's two checks) are
# inlined into their callers by LLVM (numba's forceinline, LLVM's alwaysinline): a call passes the 14 arrays of a
# HalfEdges by value, about a hundred words pushed on the stack (numba's calling convention), which was half of
# _try_collapse's own time (perf); inlined, the first cleaning's halves run 18% faster.  Only these: inlining the
# callers as well (_try_collapse, _flip_ok...) made the cleaning loop slower (its registers spill).  numba types
# and lowers each of them once; inlined as numba IR instead (inline="always"), a copy was typed and lowered at
# every call site, and the rare paths (_collapse_ok, _rescue) called copies compiled apart: the cleanup's first
# compilation took about a CPU second longer, for the same speed (the same bytes).
_inline_inner = inner(nogil=True, _nrt=False, forceinline=True)
# A helper called from one place is compiled as part of its caller (numba IR, inline="always": typed and lowered
# once, there) rather than as a library of its own, which LLVM would optimise and emit into machine code once for
# itself and again for every kernel above it (numba links a callee's code into each caller's).  Not into a loop
# of a kernel with reference counts (one that allocates), where the helper's arrays would be counted up and down
# at every step (_fair_finish's volume pass took 30% longer with _collar_gain, _fan_volume and _faces_turned
# inlined), nor _snap into clean (abop-1.24a's cleaning took 4% longer).
_inline_inner_once = inner(nogil=True, inline="always")
# The smallest helpers (_nxt, _prv, _org, _dst, _apex, the geometry's _cross...) take no HalfEdges: they are
# called, not inlined as IR, and LLVM inlines them where they are used.  As IR, numba typed and lowered a copy at
# every call site: a first run compiled the cleanup's kernels about 3 CPU seconds longer (the same bytes, the
# same run time).


class HalfEdges(NamedTuple):
    """A closed triangle mesh as half-edges, with room to grow (arrays are longer than the mesh).

    The integer arrays but ``counts`` are int32 (:data:`INDEX_LIMIT`).

    points : (vcap, 3) float64
    faces : (fcap, 3) int32
    opp : (3 fcap,) int32
        The opposite half-edge of each half-edge.
    out : (vcap,) int32
        One half-edge leaving each vertex.
    face_alive, vertex_alive : bool
    flags : (vcap,) int32
        :data:`SEAM`, :data:`FEATURE`, :data:`ORIGINAL`, :data:`LOCKED` bits.
    scale : (vcap,) float64
        The local length scale at each vertex (the side of the thinnest tube there).
    face_part : (fcap,) int32
        The part (tube) of each face; an edge between two parts is a seam.
    face_flat : (fcap,) bool
        Faces of a flat cap: an edge between a flat and a curved face is a rim.
    reference : (fcap, 3) float64
        The unit normal each face should keep (of the tube face it lies on):
        exact even for a sliver, whose own normal is noise.
    face_source : (fcap,) int32
        The input face each face descends from.
    vertex_origin : (vcap,) int32
        The input vertex each vertex descends from.
    counts : (4,) int64
        Vertices and faces in use (alive or dead): the next free slots; then
        the ends of the room a split may take (``len(points)`` and
        ``len(faces)``, or a share of the room: :func:`halves`).
    """

    points: np.ndarray
    faces: np.ndarray
    opp: np.ndarray
    out: np.ndarray
    face_alive: np.ndarray
    vertex_alive: np.ndarray
    flags: np.ndarray
    scale: np.ndarray
    face_part: np.ndarray
    face_flat: np.ndarray
    reference: np.ndarray
    face_source: np.ndarray
    vertex_origin: np.ndarray
    counts: np.ndarray


def opposites(faces: np.ndarray, nv: int, pool=None, size: int = 0, dtype=np.int32) -> np.ndarray:
    """The opposite of each half-edge (-1 where none); ``[-2, ...]`` when a directed edge is used twice.

    Half-edges are listed by their origin (a counting sort), and each finds
    its reverse among those leaving its end: linear in the half-edges times
    the valence.  With a ``pool`` (an executor), one of its threads matches
    the half-edges of the second half of the vertices (the same result).
    The array is ``size`` long (at least one per half-edge: -1 after them) of ``dtype``.
    """
    if max(3 * len(faces), nv) > INDEX_LIMIT:
        raise ValueError(f"remesh.opposites: {3 * len(faces):,} half-edges, more than int32 holds ({INDEX_LIMIT:,})")
    half, head = np.empty(3 * len(faces), np.int32), np.empty(3 * len(faces), np.int32)
    start = _leaving(faces, nv, half, head)
    opp = np.full(max(size, 3 * len(faces)), -1, dtype)
    middle = int(np.searchsorted(start, len(head) // 2))  # about as many half-edges on either side
    if not all(in_two(pool, _match, (start, half, head, opp), 0, middle, nv)):
        opp[0] = -2
    return opp


def in_two(pool, kernel, args: tuple, lo: int, middle: int, hi: int) -> tuple:
    """``kernel(*args, lo, middle)`` here and ``kernel(*args, middle, hi)`` in a thread of ``pool`` (an executor;
    None: here too, after it); both results.  For kernels whose two ranges read and write apart.  If the first
    raises, the second is waited for before the error goes on (it writes into the same arrays)."""
    if pool is None:
        return kernel(*args, lo, middle), kernel(*args, middle, hi)
    second = pool.submit(kernel, *args, middle, hi)
    try:
        first = kernel(*args, lo, middle)
    except BaseException:
        wait([second])
        raise
    return first, second.result()


@kernel(nogil=True)
def _leaving(faces, nv, half, head):
    """Fill the half-edges leaving each vertex ``half[start[v]:start[v + 1]]`` and their ends ``head``; start."""
    nf = len(faces)
    start = np.empty(nv + 1, np.int64)
    start[:] = 0
    for f in range(nf):
        for k in range(3):
            start[faces[f, k] + 1] += 1
    for v in range(nv):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    for f in range(nf):
        for k in range(3):
            u = faces[f, k]
            i = fill[u]
            half[i] = 3 * f + k
            head[i] = faces[f, (k + 1) % 3]
            fill[u] = i + 1
    return start


@kernel(nogil=True)
def _match(start, half, head, opp, lo, hi):
    """:func:`opposites` for the half-edges leaving the vertices ``lo .. hi - 1``; False if one is there twice."""
    for u in range(lo, hi):
        for i in range(start[u], start[u + 1]):
            w = head[i]
            for j in range(start[u], i):
                if head[j] == w:
                    return False
            for j in range(start[w], start[w + 1]):
                if head[j] == u:
                    opp[half[i]] = half[j]
                    break
    return True


INDEX_LIMIT = 2**31 - 1
"""The largest index :class:`HalfEdges` hold: they are int32 (half the memory of int64, and every kernel compiled
for one type).  A mesh of more half-edges (715 million triangles, some 40 GB of half-edges: no union that lsys3d
can make on a machine of today) is not cleaned: :func:`build` raises ValueError, and the cleanup leaves the
union's bark as it was, with a warning."""


def build(
    points,
    faces,
    flags,
    scale,
    face_part,
    face_flat,
    reference,
    face_source,
    extra_vertices: int = 0,
    index_limit: int | None = None,
    pool=None,
):
    """Half-edges of a closed, consistently oriented mesh (every directed edge once, its reverse once).

    ``extra_vertices`` reserves room for splits (each adds one vertex and two
    faces).  Vertices whose faces do not form one fan are flagged
    :data:`LOCKED`.  The indices are int32: raises ValueError when the
    half-edges, vertices, face sources or parts are more than ``index_limit``
    (:data:`INDEX_LIMIT`), and for a mesh that is not closed.
    """
    points = np.asarray(points, np.float64)
    faces = np.asarray(faces, np.int64)
    nv, nf = len(points), len(faces)
    vcap, fcap = nv + extra_vertices, nf + 2 * extra_vertices
    largest = max(3 * fcap, vcap, int(np.max(face_source, initial=0)), int(np.max(face_part, initial=0)))
    limit = INDEX_LIMIT if index_limit is None else index_limit
    if largest > limit:
        raise ValueError(f"remesh.build: indices up to {largest:,}, more than int32 half-edges hold ({limit:,})")
    index = np.int32
    org = faces.reshape(-1)
    opp = opposites(faces, nv, pool, 3 * fcap, index)  # the largest array, made at its size and type
    if nf and opp[0] == -2:
        raise ValueError("remesh.build: a directed edge is used twice (the mesh is not a consistent 2-manifold)")
    if nf and opp[: 3 * nf].min() < 0:
        raise ValueError("remesh.build: the mesh is not closed (a half-edge has no opposite)")

    def grow(a, n, fill, dtype=None):
        a = np.asarray(a) if dtype is None else np.asarray(a, dtype)
        out = np.empty((n, *a.shape[1:]), a.dtype)
        out[: len(a)] = a
        out[len(a) :] = fill
        return out

    def leaving():  # one half-edge leaving each vertex: its first
        out = np.full(vcap, -1, index)
        out[org[::-1]] = np.arange(3 * nf, dtype=index)[::-1]
        return out

    # the arrays with their room, made in two shares (:func:`in_two`: the pool's thread takes the second; mostly
    # page faults and copies)
    made = (
        ("reference", lambda: grow(reference, fcap, 0.0, np.float64)),
        ("faces", lambda: grow(faces, fcap, 0, index)),
        ("face_source", lambda: grow(face_source, fcap, -1, index)),
        ("scale", lambda: grow(scale, vcap, 0.0, np.float64)),
        ("vertex_origin", lambda: grow(np.arange(nv, dtype=index), vcap, -1)),
        ("face_alive", lambda: grow(np.ones(nf, bool), fcap, False)),
        ("points", lambda: grow(points, vcap, 0.0)),
        ("out", leaving),
        ("face_part", lambda: grow(face_part, fcap, -1, index)),
        ("flags", lambda: grow(flags, vcap, 0, index)),
        ("face_flat", lambda: grow(face_flat, fcap, False, bool)),
        ("vertex_alive", lambda: grow(np.ones(nv, bool), vcap, False)),
    )
    shares = in_two(pool, lambda lo, hi: {name: make() for name, make in made[lo:hi]}, (), 0, 6, len(made))
    he = HalfEdges(**shares[0], **shares[1], opp=opp, counts=np.array([nv, nf, vcap, fcap], np.int64))
    in_two(pool, _lock_pinches, (he.out, he.opp, he.flags, np.bincount(org, minlength=nv)), 0, nv // 2, nv)
    return he


@kernel(nogil=True)
def _lock_pinches(out, opp, flags, incidence, lo, hi):
    """Lock each vertex ``lo .. hi - 1`` whose faces are not one fan (two cones touching at a point): a walk
    around it meets fewer faces than it has (``incidence``).  ``out``, ``opp``, ``flags``: the half-edges'."""
    for v in range(lo, hi):
        h0 = out[v]
        n = 0
        if h0 >= 0:
            h = h0
            while True:
                n += 1
                h = opp[_prv(h)]
                if h == h0 or n > 100000:
                    break
        if n != incidence[v]:
            flags[v] |= LOCKED


def compact(he: HalfEdges, pool=None):
    """The live mesh: ``points, faces, face_part, face_flat, face_source, vertex_origin, flags``, renumbered.

    With a ``pool`` (an executor), one of its threads copies the second half of the faces (the same arrays).
    """
    nv, nf = int(he.counts[0]), int(he.counts[1])
    fa = np.flatnonzero(he.face_alive[:nf])
    used = np.zeros(nv, bool)
    _corners_used(he.faces, fa, used)
    keep = np.flatnonzero(used)
    renumber = np.full(nv, -1, np.int64)
    renumber[keep] = np.arange(len(keep))
    n = len(fa)
    faces, part, source = np.empty((n, 3), np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    flat = np.empty(n, bool)
    into = (fa, renumber, faces, part, flat, source)
    in_two(pool, _compact_faces, (he.faces, he.face_part, he.face_flat, he.face_source, *into), 0, n // 2, n)
    origin, flags = he.vertex_origin[keep].astype(np.int64), he.flags[keep].astype(np.int64)
    return he.points[keep], faces, part, flat, source, origin, flags  # int64 whatever the half-edges' index type


@kernel(nogil=True)
def _corners_used(faces, fa, used):
    """``used[v]``: ``v`` is a corner of one of the faces ``fa``."""
    for f in fa:
        used[faces[f, 0]] = True
        used[faces[f, 1]] = True
        used[faces[f, 2]] = True


@kernel(nogil=True)
def _compact_faces(he_faces, he_part, he_flat, he_source, fa, renumber, faces, part, flat, source, lo, hi):
    """:func:`compact`'s faces ``fa[lo:hi]``: corners renumbered, part, flatness and source (from the
    half-edges' ``faces``, ``face_part``, ``face_flat`` and ``face_source``)."""
    for i in range(lo, hi):
        f = fa[i]
        for k in range(3):
            faces[i, k] = renumber[he_faces[f, k]]
        part[i] = he_part[f]
        flat[i] = he_flat[f]
        source[i] = he_source[f]


@kernel(nogil=True)
def cut_caps(faces, part, cap, ncaps):  # pragma: no cover - compiled
    """``(ncaps,) bool``: the caps (``cap``: a face's cap, -1 on a wall) that a face of another part meets along
    an edge: :func:`mark`'s ``cut`` for a closed mesh without half-edges.  Each edge of a cap face is matched
    with the face running it the other way among the faces around its first vertex (only the cap faces'
    vertices get their faces listed)."""
    nv = 0
    for f in range(len(faces)):
        for k in range(3):
            nv = max(nv, faces[f, k] + 1)
    near = np.empty(nv, np.bool_)
    near[:] = False
    for f in range(len(faces)):
        if cap[f] >= 0:
            for k in range(3):
                near[faces[f, k]] = True
    start = np.empty(nv + 1, np.int64)
    start[:] = 0
    for f in range(len(faces)):
        for k in range(3):
            if near[faces[f, k]]:
                start[faces[f, k] + 1] += 1
    for v in range(nv):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    around = np.empty(start[nv], np.int64)
    for f in range(len(faces)):
        for k in range(3):
            v = faces[f, k]
            if near[v]:
                around[fill[v]] = f
                fill[v] += 1
    cut = np.empty(ncaps, np.bool_)
    cut[:] = False
    for f in range(len(faces)):
        if cap[f] < 0 or cut[cap[f]]:
            continue
        for k in range(3):
            u, w = faces[f, k], faces[f, (k + 1) % 3]
            for i in range(start[u], start[u + 1]):
                g = around[i]
                if part[g] == part[f]:
                    continue
                for j in range(3):
                    if faces[g, j] == w and faces[g, (j + 1) % 3] == u:
                        cut[cap[f]] = True
    return cut


@kernel(nogil=True)
def mark(he, nf, part, cap, flat, cut):
    """Flag the vertices of seams (:data:`SEAM`: an edge between two parts) and rims (:data:`FEATURE`: between a
    flat and a curved face of one part) of the first ``nf`` faces; a cap (``cap``: its number per face, -1 on a
    wall) that a seam crosses is cut (``cut[cap]``, False on entry): its faces are no longer ``flat`` (a thick
    child's base poking out of its parent is a ledge, no rim to keep).  ``he.face_flat`` takes ``flat``."""
    faces, opp, flags = he.faces, he.opp, he.flags
    for f in range(nf):
        for k in range(3):
            across = opp[3 * f + k] // 3
            if part[f] != part[across]:
                flags[faces[f, k]] |= SEAM
                flags[faces[f, (k + 1) % 3]] |= SEAM
                if cap[f] >= 0:
                    cut[cap[f]] = True
    for f in range(nf):
        if flat[f] and cap[f] >= 0 and cut[cap[f]]:
            flat[f] = False
        he.face_flat[f] = flat[f]
    for f in range(nf):
        for k in range(3):
            across = opp[3 * f + k] // 3
            if flat[f] != flat[across] and part[f] == part[across]:
                flags[faces[f, k]] |= FEATURE
                flags[faces[f, (k + 1) % 3]] |= FEATURE


# A half-edge computed (3 f + k, _nxt...) is int64, one read from the arrays (opp, out) int32: those passed on to
# _nxt, _apex and _dst are made int64 (np.int64(opp[h]), a walk's start np.int64(out[v])), so that each is
# compiled for one type (a second costs a first run a few hundredths of a CPU second; _prv still takes both:
# the walks that only count or mark).
@inner(nogil=True)
def _nxt(h):
    return h - 2 if h % 3 == 2 else h + 1


@inner(nogil=True)
def _prv(h):
    return h + 2 if h % 3 == 0 else h - 1


@inner(nogil=True)
def _org(faces, h):
    q = h // 3
    return faces[q, h - 3 * q]


@inner(nogil=True)
def _dst(faces, h):
    q = h // 3
    r = h - 3 * q
    return faces[q, 0 if r == 2 else r + 1]


@inner(nogil=True)
def _apex(faces, h):
    """The corner of ``h``'s face across from it."""
    q = h // 3
    r = h - 3 * q
    return faces[q, r - 1 if r > 0 else 2]


@_inline_inner
def _ring(he, v, buf):
    """Neighbours of ``v`` into ``buf``; their number, or -1 if more than fit."""
    h0 = np.int64(he.out[v])
    h = h0
    n = 0
    while True:
        if n >= len(buf):
            return -1
        buf[n] = _dst(he.faces, h)
        n += 1
        h = he.opp[_prv(h)]
        if h == h0:
            return n


@_inline_inner
def _valence(he, v, most=_MAX_RING):
    """The neighbours of ``v``, counted up to ``most + 1`` (a walk of at most that many steps): ``most`` 3 is
    enough to tell a valence of 3 or under from the rest, in four steps rather than a whole ring."""
    h0 = he.out[v]
    h = h0
    n = 0
    while True:
        n += 1
        h = he.opp[_prv(h)]
        if h == h0 or n > most:
            return n


@_inline_inner
def _half_edge(he, u, w):
    """The half-edge from ``u`` to ``w``, or -1."""
    h0 = np.int64(he.out[u])
    h = h0
    n = 0
    while True:
        if _dst(he.faces, h) == w:
            return h
        h = he.opp[_prv(h)]
        n += 1
        if h == h0 or n > _MAX_RING:
            return -1
