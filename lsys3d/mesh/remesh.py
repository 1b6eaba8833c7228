"""Local remeshing of a closed triangle mesh: edge collapses, flips and splits that keep it closed.

The numba kernels behind :mod:`lsys3d.mesh.cleanup`.  The mesh is held as
half-edges in flat arrays (:class:`HalfEdges`): half-edge ``3 f + k`` runs
from corner ``k`` of face ``f`` to corner ``k + 1``; ``opp`` pairs it with
the half-edge running the other way.  Every operation keeps the mesh a
closed, consistently oriented 2-manifold:

* an **edge collapse** merges the two ends of an edge only when their
  neighbourhoods share exactly the two vertices across the edge (the *link
  condition*), both vertices across keep at least three neighbours, and no
  face around turns away from the surface it lies on;
* an **edge flip** replaces the diagonal of the two faces of an edge when the
  other diagonal is not an edge already and the faces do not fold;
* an **edge split** adds a vertex on an edge and two faces.

Faces die by a flag (``face_alive``) and the mesh is compacted at the end
(:func:`compact`), which also says where every surviving vertex came from
(``vertex_origin``: itself, or for a vertex made by a split the nearer end of
the edge it split) and every face (``face_source``: the input face it
descends from).  Those two maps carry per-vertex and per-face attributes
(branch id, order...) from the input to the output: ``attribute[vertex_origin]``.

Vertices carry flags: :data:`SEAM` (on a junction seam), :data:`FEATURE` (on
a sharp rim that must stay: the edge of a tube's flat cap), :data:`ORIGINAL`
(a vertex of the swept tubes, not made by the boolean), :data:`LOCKED`
(never touched: a vertex whose faces do not form one fan) and :data:`PINNED`
(a rim vertex that stays where it is and whose rim stays as it is: the ring
under a temporary cap of the union, which the union stitches back on).
"""

from __future__ import annotations

from concurrent.futures import wait
from typing import NamedTuple

import numba
import numpy as np

__all__ = [
    "FEATURE",
    "LOCKED",
    "ORIGINAL",
    "PINNED",
    "SEAM",
    "HalfEdges",
    "Rules",
    "build",
    "clean",
    "compact",
    "cut_caps",
    "index_dtype",
    "mark",
    "rescue",
]

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
_FLAT = 1e30  # the aspect of a triangle without area
_MAX_SPAWN = 8  # splits one seam vertex's fan may make

# The helpers that allocate nothing are compiled without numba's reference counts: with them, a call counted each
# of the 14 arrays of a HalfEdges up on entry and down on return, atomic operations that numba could not prune
# around the calls (any of which may raise), a fifth of the cleanup's time on abop-1.24a (measured with perf).
_leaf = numba.njit(cache=True, nogil=True, _nrt=False)
# The helpers that a collapse calls a few times each are inlined into their callers, as numba IR: a call passes
# the 14 arrays of a HalfEdges by value, about a hundred words pushed on the stack (numba's calling convention),
# which was half of _try_collapse's own time (perf); inlined, the first cleaning's halves run 18% faster.  Only
# these: inlining the callers as well (_try_collapse, _flip_ok...) made the cleaning loop slower (its registers
# spill) and its first compilation about three times as long.  As it is, with the rare paths calling the checks
# rather than inlining them (below), the first run of a fresh install (numba compiling every kernel: tree3d)
# takes 46 s instead of 43 s, once.
_inline = numba.njit(cache=True, nogil=True, _nrt=False, inline="always")


class HalfEdges(NamedTuple):
    """A closed triangle mesh as half-edges, with room to grow (arrays are longer than the mesh).

    The integer arrays but ``counts`` are of one index type (:func:`index_dtype`):
    int32 while every half-edge fits, int64 beyond (the kernels take either).

    points : (vcap, 3) float64
    faces : (fcap, 3) int32 or int64
    opp : (3 fcap,) int32 or int64
        The opposite half-edge of each half-edge.
    out : (vcap,) int32 or int64
        One half-edge leaving each vertex.
    face_alive, vertex_alive : bool
    flags : (vcap,) int32 or int64
        :data:`SEAM`, :data:`FEATURE`, :data:`ORIGINAL`, :data:`LOCKED` bits.
    scale : (vcap,) float64
        The local length scale at each vertex (the side of the thinnest tube there).
    face_part : (fcap,) int32 or int64
        The part (tube) of each face; an edge between two parts is a seam.
    face_flat : (fcap,) bool
        Faces of a flat cap: an edge between a flat and a curved face is a rim.
    reference : (fcap, 3) float64
        The unit normal each face should keep (of the tube face it lies on):
        exact even for a sliver, whose own normal is noise.
    face_source : (fcap,) int32 or int64
        The input face each face descends from.
    vertex_origin : (vcap,) int32 or int64
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


class Rules(NamedTuple):
    """The thresholds of :func:`clean`, lengths in local scales (see :class:`lsys3d.mesh.cleanup.CleanupOptions`)."""

    short: float
    """Collapse edges shorter than this."""
    limit: float
    """A collapse may leave a triangle of at most this aspect (or improve the worst one around)."""
    bad: float
    """Faces of a worse aspect are flipped, snapped or split."""
    flip_tolerance: float
    """A flip may move the surface by at most this."""
    long: float
    """Split fan edges leaving a seam that are longer than this..."""
    step: float
    """...this far from the seam."""
    fallback: float
    """A bad face whose shortest edge is shorter than this gets it collapsed."""
    max_operations: int
    """Stop after this many operations (a guard; never reached on sane input)."""


def opposites(faces: np.ndarray, nv: int, pool=None, size: int = 0, dtype=np.int64) -> np.ndarray:
    """The opposite of each half-edge (-1 where none); ``[-2, ...]`` when a directed edge is used twice.

    Half-edges are listed by their origin (a counting sort), and each finds
    its reverse among those leaving its end: linear in the half-edges times
    the valence.  With a ``pool`` (an executor), one of its threads matches
    the half-edges of the second half of the vertices (the same result).
    The array is ``size`` long (at least one per half-edge: -1 after them) of ``dtype``.
    """
    index = index_dtype(max(3 * len(faces), nv))  # int32 while it fits: half the memory
    half, head = np.empty(3 * len(faces), index), np.empty(3 * len(faces), index)
    start = _leaving(faces, nv, half, head)
    opp = np.full(max(size, 3 * len(faces)), -1, dtype)
    middle = int(np.searchsorted(start, len(head) // 2))  # about as many half-edges on either side
    if not all(_in_two(pool, _match, (start, half, head, opp), 0, middle, nv)):
        opp[0] = -2
    return opp


def _in_two(pool, kernel, args: tuple, lo: int, middle: int, hi: int) -> tuple:
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


@numba.njit(cache=True, nogil=True)
def _leaving(faces, nv, half, head):
    """Fill the half-edges leaving each vertex ``half[start[v]:start[v + 1]]`` and their ends ``head``; start."""
    nf = len(faces)
    start = np.zeros(nv + 1, np.int64)
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


@numba.njit(cache=True, nogil=True)
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
"""The largest index :class:`HalfEdges` keep as int32 (half the memory of int64); beyond it, int64."""


def index_dtype(largest: int, limit: int = INDEX_LIMIT) -> type:
    """The integer type of :class:`HalfEdges`' indices, given the largest number they hold: int32 up to ``limit``."""
    return np.int32 if largest <= limit else np.int64


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
    :data:`LOCKED`.  The indices are int32 when the half-edges, vertices, face
    sources and parts are all at most ``index_limit`` (:data:`INDEX_LIMIT`),
    int64 otherwise (:func:`index_dtype`).  Raises ValueError for a mesh that is not closed.
    """
    points = np.asarray(points, np.float64)
    faces = np.asarray(faces, np.int64)
    nv, nf = len(points), len(faces)
    vcap, fcap = nv + extra_vertices, nf + 2 * extra_vertices
    largest = max(3 * fcap, vcap, int(np.max(face_source, initial=0)), int(np.max(face_part, initial=0)))
    index = index_dtype(largest, INDEX_LIMIT if index_limit is None else index_limit)
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

    # the arrays with their room, made in two shares (:func:`_in_two`: the pool's thread takes the second; mostly
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
    shares = _in_two(pool, lambda lo, hi: {name: make() for name, make in made[lo:hi]}, (), 0, 6, len(made))
    he = HalfEdges(**shares[0], **shares[1], opp=opp, counts=np.array([nv, nf, vcap, fcap], np.int64))
    _in_two(pool, _lock_pinches, (he, np.bincount(org, minlength=nv)), 0, nv // 2, nv)
    return he


@numba.njit(cache=True, nogil=True)
def _lock_pinches(he, incidence, lo, hi):
    """Lock each vertex ``lo .. hi - 1`` whose faces are not one fan (two cones touching at a point): a walk
    around it meets fewer faces than it has (``incidence``)."""
    for v in range(lo, hi):
        h0 = he.out[v]
        n = 0
        if h0 >= 0:
            h = h0
            while True:
                n += 1
                h = he.opp[_prv(h)]
                if h == h0 or n > 100000:
                    break
        if n != incidence[v]:
            he.flags[v] |= LOCKED


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
    _in_two(pool, _compact_faces, (he, fa, renumber, faces, part, flat, source), 0, n // 2, n)
    origin, flags = he.vertex_origin[keep].astype(np.int64), he.flags[keep].astype(np.int64)
    return he.points[keep], faces, part, flat, source, origin, flags  # int64 whatever the half-edges' index type


@numba.njit(cache=True, nogil=True)
def _corners_used(faces, fa, used):
    """``used[v]``: ``v`` is a corner of one of the faces ``fa``."""
    for f in fa:
        used[faces[f, 0]] = True
        used[faces[f, 1]] = True
        used[faces[f, 2]] = True


@numba.njit(cache=True, nogil=True)
def _compact_faces(he, fa, renumber, faces, part, flat, source, lo, hi):
    """:func:`compact`'s faces ``fa[lo:hi]``: corners renumbered, part, flatness and source."""
    for i in range(lo, hi):
        f = fa[i]
        for k in range(3):
            faces[i, k] = renumber[he.faces[f, k]]
        part[i] = he.face_part[f]
        flat[i] = he.face_flat[f]
        source[i] = he.face_source[f]


@numba.njit(cache=True, nogil=True)
def cut_caps(faces, part, cap, ncaps):  # pragma: no cover - compiled
    """``(ncaps,) bool``: the caps (``cap``: a face's cap, -1 on a wall) that a face of another part meets along
    an edge: :func:`mark`'s ``cut`` for a closed mesh without half-edges.  Each edge of a cap face is matched
    with the face running it the other way among the faces around its first vertex (only the cap faces'
    vertices get their faces listed)."""
    nv = 0
    for f in range(len(faces)):
        for k in range(3):
            nv = max(nv, faces[f, k] + 1)
    near = np.zeros(nv, np.bool_)
    for f in range(len(faces)):
        if cap[f] >= 0:
            for k in range(3):
                near[faces[f, k]] = True
    start = np.zeros(nv + 1, np.int64)
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
    cut = np.zeros(ncaps, np.bool_)
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


@numba.njit(cache=True, nogil=True)
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


# ---------------------------------------------------------------------------------------- navigation
@numba.njit(cache=True, nogil=True, inline="always")
def _nxt(h):
    return h - 2 if h % 3 == 2 else h + 1


@numba.njit(cache=True, nogil=True, inline="always")
def _prv(h):
    return h + 2 if h % 3 == 0 else h - 1


@numba.njit(cache=True, nogil=True, inline="always")
def _org(faces, h):
    q = h // 3
    return faces[q, h - 3 * q]


@numba.njit(cache=True, nogil=True, inline="always")
def _dst(faces, h):
    q = h // 3
    r = h - 3 * q
    return faces[q, 0 if r == 2 else r + 1]


@numba.njit(cache=True, nogil=True, inline="always")
def _apex(faces, h):
    """The corner of ``h``'s face across from it."""
    q = h // 3
    r = h - 3 * q
    return faces[q, r - 1 if r > 0 else 2]


@_inline
def _ring(he, v, buf):
    """Neighbours of ``v`` into ``buf``; their number, or -1 if more than fit."""
    h0 = he.out[v]
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


@_inline
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


@_inline
def _half_edge(he, u, w):
    """The half-edge from ``u`` to ``w``, or -1."""
    h0 = he.out[u]
    h = h0
    n = 0
    while True:
        if _dst(he.faces, h) == w:
            return h
        h = he.opp[_prv(h)]
        n += 1
        if h == h0 or n > _MAX_RING:
            return -1


# ---------------------------------------------------------------------------------------- geometry
@numba.njit(cache=True, nogil=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@_leaf
def _normal_xyz(ax, ay, az, bx, by, bz, cx, cy, cz):
    return _cross(bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az)


@numba.njit(cache=True, nogil=True, inline="always")
def _before(ax, ay, az, bx, by, bz):
    """Whether point ``a`` comes before ``b`` in lexicographic order (a tie-break that ignores vertex order)."""
    if ax != bx:
        return ax < bx
    if ay != by:
        return ay < by
    return az < bz


@_leaf
def _aspect_xyz(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Aspect (longest edge / (2 sqrt 3 inradius)) of a triangle given by coordinates; 1e30 when flat.

    The same bits whatever the order of the corners: the area's cross product
    is taken at the corner across the longest edge (the most accurate one;
    ties broken by the corners' coordinates), and a cross product with its
    two edges swapped is exactly negated.  A needle's area is mostly rounding
    noise; were it computed at whichever corner came first, a flip and the
    flip back could each look like an improvement, and :func:`clean` cycled
    (757,310 flips on abop-1.24a).
    """
    l0 = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)  # across c
    l1 = np.sqrt((cx - bx) ** 2 + (cy - by) ** 2 + (cz - bz) ** 2)  # across a
    l2 = np.sqrt((ax - cx) ** 2 + (ay - cy) ** 2 + (az - cz) ** 2)  # across b
    # the corner across the longest edge, as a rotation: (a, b, c), (b, c, a) or (c, a, b)
    base = 0
    if l1 > l0 or (l1 == l0 and _before(ax, ay, az, cx, cy, cz)):
        base = 1
        if l2 > l1 or (l2 == l1 and _before(bx, by, bz, ax, ay, az)):
            base = 2
    elif l2 > l0 or (l2 == l0 and _before(bx, by, bz, cx, cy, cz)):
        base = 2
    if base == 0:
        nx, ny, nz = _normal_xyz(cx, cy, cz, ax, ay, az, bx, by, bz)
    elif base == 1:
        nx, ny, nz = _normal_xyz(ax, ay, az, bx, by, bz, cx, cy, cz)
    else:
        nx, ny, nz = _normal_xyz(bx, by, bz, cx, cy, cz, ax, ay, az)
    area = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
    s = 0.5 * (l0 + l1 + l2)
    if area <= 1e-300 or s <= 0:
        return _FLAT
    return max(l0, max(l1, l2)) * s / (2.0 * np.sqrt(3.0) * area)


@_leaf
def _corners(p, a, b, c, moved, x, y, z):
    """The coordinates of triangle ``a b c``, vertex ``moved`` placed at ``x y z``."""
    ax, ay, az = p[a, 0], p[a, 1], p[a, 2]
    bx, by, bz = p[b, 0], p[b, 1], p[b, 2]
    cx, cy, cz = p[c, 0], p[c, 1], p[c, 2]
    if a == moved:
        ax, ay, az = x, y, z
    if b == moved:
        bx, by, bz = x, y, z
    if c == moved:
        cx, cy, cz = x, y, z
    return ax, ay, az, bx, by, bz, cx, cy, cz


@_leaf
def _aspect(p, a, b, c):
    return _aspect_xyz(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])


@_leaf
def _normal(p, a, b, c):
    return _normal_xyz(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])


@_leaf
def _length(p, u, w):
    return np.sqrt((p[u, 0] - p[w, 0]) ** 2 + (p[u, 1] - p[w, 1]) ** 2 + (p[u, 2] - p[w, 2]) ** 2)


@_leaf
def _segment_distance(p, a, b, c, d):
    """Distance between segments ``a b`` and ``c d``."""
    d1x, d1y, d1z = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    d2x, d2y, d2z = p[d, 0] - p[c, 0], p[d, 1] - p[c, 1], p[d, 2] - p[c, 2]
    rx, ry, rz = p[a, 0] - p[c, 0], p[a, 1] - p[c, 1], p[a, 2] - p[c, 2]
    aa = d1x * d1x + d1y * d1y + d1z * d1z
    ee = d2x * d2x + d2y * d2y + d2z * d2z
    ff = d2x * rx + d2y * ry + d2z * rz
    cc = d1x * rx + d1y * ry + d1z * rz
    bb = d1x * d2x + d1y * d2y + d1z * d2z
    tiny = 1e-300
    denom = aa * ee - bb * bb
    s = 0.0
    if denom > tiny:
        s = min(max((bb * ff - cc * ee) / denom, 0.0), 1.0)
    t = (bb * s + ff) / ee if ee > tiny else 0.0
    if t < 0.0:
        t = 0.0
        s = min(max(-cc / aa, 0.0), 1.0) if aa > tiny else 0.0
    elif t > 1.0:
        t = 1.0
        s = min(max((bb - cc) / aa, 0.0), 1.0) if aa > tiny else 0.0
    x = rx + d1x * s - d2x * t
    y = ry + d1y * s - d2y * t
    z = rz + d1z * s - d2z * t
    return np.sqrt(x * x + y * y + z * z)


# ---------------------------------------------------------------------------------------- collapse
@_inline
def _collapse_topology_ok(he, h, buf_a, buf_b):
    """Whether collapsing half-edge ``h`` keeps a 2-manifold: the link condition, and valences of at least three."""
    faces = he.faces
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _apex(faces, h)
    d = _apex(faces, he.opp[h])
    if a == b or c == d or (he.flags[a] | he.flags[b]) & LOCKED or he.flags[a] & PINNED:
        return False
    if _valence(he, c, 3) <= 3 or _valence(he, d, 3) <= 3:
        return False
    na = _ring(he, a, buf_a)
    nb = _ring(he, b, buf_b)
    if na < 0 or nb < 0:
        return False
    for i in range(na):
        va = buf_a[i]
        if va in (c, d):
            continue
        for j in range(nb):
            if buf_b[j] == va:
                return False
    return True


@_inline
def _collapse_geometry_ok(he, h, x, y, z, limit):
    """Whether the faces around half-edge ``h``'s ends, with both at ``x, y, z``, keep their side and shapes.

    Every face keeps within 80 degrees of its ``reference`` normal (the tube
    face it lies on, exact even for a sliver), or turns no farther from it
    than it is already turned, and the worst aspect around stays under
    ``limit`` or improves.
    """
    faces, p = he.faces, he.points
    a = _org(faces, h)
    b = _dst(faces, h)
    t = he.opp[h]
    worst_old = max(_aspect(p, a, b, _apex(faces, h)), _aspect(p, b, a, _apex(faces, t)))
    worst_new = 0.0
    for end in range(2):
        v = a if end == 0 else b
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            if f != h // 3 and f != t // 3:
                f0, f1, f2 = faces[f, 0], faces[f, 1], faces[f, 2]
                corners = _corners(p, f0, f1, f2, v, x, y, z)
                qx, qy, qz = _normal_xyz(*corners)
                q = np.sqrt(qx * qx + qy * qy + qz * qz)
                r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
                turned = qx * r0 + qy * r1 + qz * r2
                if turned <= 0.17 * q:
                    # turned away: allowed only for a face that was turned as far already (a fold left by the
                    # boolean must not block every collapse around it), and not further
                    ox, oy, oz = _normal(p, f0, f1, f2)
                    o = np.sqrt(ox * ox + oy * oy + oz * oz)
                    was = ox * r0 + oy * r1 + oz * r2
                    if q <= 0.0 or o <= 0.0 or was > 0.17 * o or turned / q < was / o:
                        return False
                worst_old = max(worst_old, _aspect(p, f0, f1, f2))
                worst_new = max(worst_new, _aspect_xyz(*corners))
            g = he.opp[_prv(g)]
            if g == h0:
                break
    return worst_new <= limit or worst_new < worst_old


# The same two checks called, not inlined, for the rare paths (:func:`_collapse_ok`, :func:`_rescue`): a copy
# compiled into each of their call sites would cost seconds of the first compilation and buy nothing.
_topology_ok_called = _leaf(_collapse_topology_ok.py_func)
_geometry_ok_called = _leaf(_collapse_geometry_ok.py_func)


@_leaf
def _collapse_ok(he, h, x, y, z, limit, buf_a, buf_b, geometry=True):
    """Whether collapsing half-edge ``h`` (its origin into its end, placed at ``x, y, z``) is allowed.

    :func:`_collapse_topology_ok`, and unless ``geometry`` is off (for ends so
    close that nothing can move) :func:`_collapse_geometry_ok`.
    """
    if not _topology_ok_called(he, h, buf_a, buf_b):
        return False
    return not geometry or _geometry_ok_called(he, h, x, y, z, limit)


@_leaf
def _collapse(he, h, x, y, z):
    """Collapse half-edge ``h``: its origin ``a`` merges into its end ``b``, placed at ``x, y, z``.

    The two faces of the edge die; every other face of ``a`` takes ``b``.
    Call only after :func:`_collapse_ok`.
    """
    faces, opp, out = he.faces, he.opp, he.out
    a = _org(faces, h)
    b = _dst(faces, h)
    t = opp[h]
    f0, f1 = h // 3, t // 3
    h1, h2 = _nxt(h), _prv(h)  # b->c, c->a
    t1, t2 = _nxt(t), _prv(t)  # a->d, d->b
    o_h1, o_h2, o_t1, o_t2 = opp[h1], opp[h2], opp[t1], opp[t2]
    c = _dst(faces, h1)
    d = _dst(faces, t1)
    g0 = out[a]
    g = g0
    while True:  # every face around a takes b
        faces[g // 3, g % 3] = b
        g = opp[_prv(g)]
        if g == g0:
            break
    # the outer edges of the dead faces now face each other
    opp[o_h1] = o_h2
    opp[o_h2] = o_h1
    opp[o_t1] = o_t2
    opp[o_t2] = o_t1
    out[b] = o_t2
    out[c] = o_h1
    out[d] = o_t1
    he.face_alive[f0] = False
    he.face_alive[f1] = False
    for k in range(3):
        opp[3 * f0 + k] = -1
        opp[3 * f1 + k] = -1
    he.vertex_alive[a] = False
    out[a] = -1
    he.points[b, 0], he.points[b, 1], he.points[b, 2] = x, y, z
    he.flags[b] |= he.flags[a] & (SEAM | FEATURE)
    he.scale[b] = min(he.scale[a], he.scale[b])


@_inline
def _volume_neutral(he, h, x, y, z):
    """Where to put the merged vertex of collapsing ``h``, near ``x, y, z``, so the enclosed volume stays.

    The volume is linear in the merged vertex's position (six times it is the
    sum of ``det(x, p, q)`` over the faces ``x p q`` around it), so the
    correction is one step along its gradient, at most the edge's length.
    Without it, collapses on a convex tube (all of them) would shrink it.
    """
    faces, p = he.faces, he.points
    a = _org(faces, h)
    b = _dst(faces, h)
    t = he.opp[h]
    before = 0.0
    after = 0.0
    gx, gy, gz = 0.0, 0.0, 0.0
    for end in range(2):
        v = a if end == 0 else b
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            k = g % 3
            u, w = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            ux, uy, uz = p[u, 0], p[u, 1], p[u, 2]
            wx, wy, wz = p[w, 0], p[w, 1], p[w, 2]
            cx, cy, cz = _cross(ux, uy, uz, wx, wy, wz)
            d = p[v, 0] * cx + p[v, 1] * cy + p[v, 2] * cz
            if f == h // 3 or f == t // 3:
                if end == 0:  # the two dying faces count once
                    before += d
            else:
                before += d
                after += x * cx + y * cy + z * cz
                gx += cx
                gy += cy
                gz += cz
            g = he.opp[_prv(g)]
            if g == h0:
                break
    g2 = gx * gx + gy * gy + gz * gz
    if g2 <= 0.0:
        return x, y, z
    step = (before - after) / g2
    sx, sy, sz = step * gx, step * gy, step * gz
    reach = _length(p, a, b)
    size = np.sqrt(sx * sx + sy * sy + sz * sz)
    if size > reach:
        sx, sy, sz = sx * reach / size, sy * reach / size, sz * reach / size
    return x + sx, y + sy, z + sz


@_leaf
def _rank(flags, v):
    """Which end of a collapse keeps its place: a rim vertex, then a tube vertex, then a seam vertex."""
    f = flags[v]
    if f & FEATURE:
        return 3
    if f & ORIGINAL:
        return 2
    if f & SEAM:
        return 1
    return 0


@_leaf
def _try_collapse(he, h, limit, short, buf_a, buf_b):
    """Collapse the edge of half-edge ``h`` the best way that is allowed; the kept vertex, or -1.

    The end of higher :func:`_rank` keeps its place (either, for two of equal
    rank), moved off it only as far as keeps the volume; two rim vertices
    merge only along their rim.  An edge of almost no length merges whatever
    the shapes around (they hardly move); a vertex of three neighbours across
    it, which would be left with two, first merges into its nearest
    neighbour when that is nearer than ``short`` scales.
    """
    faces = he.faces
    a = _org(faces, h)
    b = _dst(faces, h)
    if _rank(he.flags, a) == 3 and _rank(he.flags, b) == 3 and he.face_flat[h // 3] == he.face_flat[he.opp[h] // 3]:
        return -1  # two rim vertices, but not along the rim
    tiny = _length(he.points, a, b) < 1e-3 * min(he.scale[a], he.scale[b])
    # a vertex of three neighbours across the edge would be left with two: merge it away first
    for apex in (_apex(faces, h), _apex(faces, he.opp[h])):
        if _valence(he, apex, 3) == 3 and not (he.flags[apex] & LOCKED):
            best, best_length = -1, 1e300
            g0 = he.out[apex]
            g = g0
            while True:
                n = _dst(faces, g)
                length = _length(he.points, apex, n)
                if _rank(he.flags, apex) <= _rank(he.flags, n) and length < best_length:
                    best, best_length = g, length
                g = he.opp[_prv(g)]
                if g == g0:
                    break
            if best >= 0 and best_length < short * he.scale[apex]:
                w = _dst(faces, best)
                x, y, z = he.points[w, 0], he.points[w, 1], he.points[w, 2]
                if _collapse_ok(he, best, x, y, z, limit, buf_a, buf_b):
                    _collapse(he, best, x, y, z)
                    return w
    for attempt in range(2):
        g = h if attempt == 0 else he.opp[h]
        u = _org(faces, g)  # goes
        w = _dst(faces, g)  # stays
        if _rank(he.flags, u) > _rank(he.flags, w):
            continue
        if not _collapse_topology_ok(he, g, buf_a, buf_b):
            continue
        x, y, z = he.points[w, 0], he.points[w, 1], he.points[w, 2]
        if not tiny and not (he.flags[w] & FEATURE):
            x, y, z = _volume_neutral(he, g, x, y, z)
        if _collapse_geometry_ok(he, g, x, y, z, 1e300 if tiny else limit):
            _collapse(he, g, x, y, z)
            return w
    return -1


# ---------------------------------------------------------------------------------------- flip
@_leaf
def _flip_ok(he, h, tolerance):
    """Whether flipping the edge of half-edge ``h`` improves its two faces without changing the shape much.

    The surface moves by at most the distance between the old and the new
    diagonal, which must stay under ``tolerance``; the new faces keep the
    side of the old pair, and their worse aspect must be better than the old
    worse one.
    Seam and rim edges are never flipped.
    """
    faces, p = he.faces, he.points
    t = he.opp[h]
    f0, f1 = h // 3, t // 3
    if he.face_part[f0] != he.face_part[f1]:
        return False
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _apex(faces, h)
    d = _apex(faces, t)
    flags = he.flags
    if c == d or ((flags[a] & FEATURE) and (flags[b] & FEATURE)):
        return False
    if (flags[a] | flags[b] | flags[c] | flags[d]) & LOCKED:
        return False
    # the shape first, then the walks around the vertices (most edges fail on shape: a long needle's)
    if _segment_distance(p, a, b, c, d) > tolerance:
        return False
    n0x, n0y, n0z = _normal(p, a, b, c)
    n1x, n1y, n1z = _normal(p, b, a, d)
    mx, my, mz = n0x + n1x, n0y + n1y, n0z + n1z
    qx, qy, qz = _normal(p, c, a, d)
    if qx * mx + qy * my + qz * mz <= 0.0:
        return False
    qx, qy, qz = _normal(p, d, b, c)
    if qx * mx + qy * my + qz * mz <= 0.0:
        return False
    old = max(_aspect(p, a, b, c), _aspect(p, b, a, d))
    new = max(_aspect(p, c, a, d), _aspect(p, d, b, c))
    if not new < 0.999 * old:
        return False
    if _valence(he, a, 3) <= 3 or _valence(he, b, 3) <= 3:
        return False
    return _half_edge(he, c, d) < 0


@_leaf
def _flip(he, h):
    """Flip the edge of half-edge ``h`` (faces ``a b c`` and ``b a d`` become ``c a d`` and ``d b c``)."""
    faces, opp, out = he.faces, he.opp, he.out
    t = opp[h]
    f0, f1 = h // 3, t // 3
    h1, h2 = _nxt(h), _prv(h)  # b->c, c->a
    t1, t2 = _nxt(t), _prv(t)  # a->d, d->b
    o_h1, o_h2, o_t1, o_t2 = opp[h1], opp[h2], opp[t1], opp[t2]
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _dst(faces, h1)
    d = _dst(faces, t1)
    faces[f0, 0], faces[f0, 1], faces[f0, 2] = c, a, d
    faces[f1, 0], faces[f1, 1], faces[f1, 2] = d, b, c
    e0, e1, e2 = 3 * f0, 3 * f0 + 1, 3 * f0 + 2  # c->a, a->d, d->c
    g0, g1, g2 = 3 * f1, 3 * f1 + 1, 3 * f1 + 2  # d->b, b->c, c->d
    opp[e0], opp[o_h2] = o_h2, e0
    opp[e1], opp[o_t1] = o_t1, e1
    opp[g0], opp[o_t2] = o_t2, g0
    opp[g1], opp[o_h1] = o_h1, g1
    opp[e2], opp[g2] = g2, e2
    out[a] = e1
    out[b] = g1
    out[c] = e0
    out[d] = g0


# ---------------------------------------------------------------------------------------- split
@numba.njit(cache=True, nogil=True, inline="always")
def _inherit(he, f, g):
    """Face ``f`` takes what face ``g`` knows of the tube face it lies on: part, flatness, source, reference normal
    (the normal element by element: a row copy would allocate, and the helpers run without numba's runtime)."""
    he.face_part[f] = he.face_part[g]
    he.face_flat[f] = he.face_flat[g]
    he.face_source[f] = he.face_source[g]
    for j in range(3):
        he.reference[f, j] = he.reference[g, j]


@_leaf
def _split(he, h, t):
    """Split the edge of half-edge ``h`` at ``a + t (b - a)``: one new vertex, two new faces; the vertex or -1.

    The new vertex's origin is the nearer end; the new faces copy their old
    face's part, flatness, reference normal and source.  -1 when there is no room,
    or the edge joins two :data:`PINNED` vertices.
    """
    faces, opp, out, p = he.faces, he.opp, he.out, he.points
    nv, nf = he.counts[0], he.counts[1]
    if nv >= he.counts[2] or nf + 2 > he.counts[3]:
        return -1
    if he.flags[_org(faces, h)] & he.flags[_dst(faces, h)] & PINNED:
        return -1
    o = opp[h]
    f0, f1 = h // 3, o // 3
    a = _org(faces, h)
    b = _dst(faces, h)
    c = _apex(faces, h)
    d = _apex(faces, o)
    m = nv
    for k in range(3):
        p[m, k] = p[a, k] + t * (p[b, k] - p[a, k])
    he.vertex_alive[m] = True
    he.flags[m] = FEATURE if (he.flags[a] & he.flags[b]) & FEATURE else 0
    he.scale[m] = min(he.scale[a], he.scale[b])
    he.vertex_origin[m] = he.vertex_origin[a] if t <= 0.5 else he.vertex_origin[b]
    # f0 (a b c) -> (a m c) and new g0 (m b c); f1 (b a d) -> (m a d) and new g1 (b m d)
    g0, g1 = nf, nf + 1
    o_bc, o_ca, o_ad, o_db = opp[_nxt(h)], opp[_prv(h)], opp[_nxt(o)], opp[_prv(o)]
    faces[f0, 0], faces[f0, 1], faces[f0, 2] = a, m, c
    faces[g0, 0], faces[g0, 1], faces[g0, 2] = m, b, c
    faces[f1, 0], faces[f1, 1], faces[f1, 2] = m, a, d
    faces[g1, 0], faces[g1, 1], faces[g1, 2] = b, m, d
    for new, old in ((g0, f0), (g1, f1)):
        he.face_alive[new] = True
        _inherit(he, new, old)
    # f0: a->m, m->c, c->a; g0: m->b, b->c, c->m; f1: m->a, a->d, d->m; g1: b->m, m->d, d->b
    F0, G0, F1, G1 = 3 * f0, 3 * g0, 3 * f1, 3 * g1
    opp[F0], opp[F1] = F1, F0
    opp[G0], opp[G1] = G1, G0
    opp[F0 + 1], opp[G0 + 2] = G0 + 2, F0 + 1
    opp[F1 + 2], opp[G1 + 1] = G1 + 1, F1 + 2
    opp[F0 + 2], opp[o_ca] = o_ca, F0 + 2
    opp[G0 + 1], opp[o_bc] = o_bc, G0 + 1
    opp[F1 + 1], opp[o_ad] = o_ad, F1 + 1
    opp[G1 + 2], opp[o_db] = o_db, G1 + 2
    out[m] = G0
    out[a] = F0
    out[b] = G0 + 1
    out[c] = F0 + 2
    out[d] = F1 + 2
    he.counts[0] = nv + 1
    he.counts[1] = nf + 2
    return m


# ---------------------------------------------------------------------------------------- the driver
@_leaf
def _needs_work(he, f, rules):
    faces, p = he.faces, he.points
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    s = min(he.scale[a], min(he.scale[b], he.scale[c]))
    short = rules.short * s
    if _length(p, a, b) < short or _length(p, b, c) < short or _length(p, c, a) < short:
        return True
    return _aspect(p, a, b, c) > rules.bad


@_leaf
def _push_fan(he, v, stack, queued, top, rules):
    """Queue the faces around ``v`` that need work; the new stack height."""
    h0 = he.out[v]
    if h0 < 0:
        return top
    g = h0
    n = 0
    while True:
        f = g // 3
        if not queued[f] and _needs_work(he, f, rules):
            queued[f] = True
            stack[top] = f
            top += 1
        g = he.opp[_prv(g)]
        n += 1
        if g == h0 or n > _MAX_RING:
            return top


@_leaf
def _snap(he, f, k, rules, buf_a, buf_b):
    """A cap: move its far corner ``x`` onto its edge ``k`` (``u w``) and give the face across the edge to it.

    Topologically an edge flip of ``u w`` (``x`` joins the vertex ``d`` across
    it), then ``x`` moves to its foot on ``u w``: the cap vanishes and the face
    across splits in two halves of itself, so only the faces around ``x``
    change shape, by at most the cap's height (under ``short`` scales).
    ``x`` takes the rank of the edge it now lies on (a tube edge, a rim, the
    seam).  Where ``x`` stands over an end of the edge (its foot in the
    outer tenths), it merges into that end instead.  Returns the vertex left
    (``x``, or the end), or -1 when not allowed.
    """
    faces, p, flags = he.faces, he.points, he.flags
    g = 3 * f + k
    t = he.opp[g]
    u, w, x = faces[f, k], faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
    d = _apex(faces, t)
    if x == d or (flags[u] | flags[w] | flags[x] | flags[d]) & LOCKED or flags[x] & FEATURE:
        return -1
    if flags[u] & flags[w] & PINNED:  # the edge of a pinned ring: the face across is a cap that must stay
        return -1
    ex, ey, ez = p[w, 0] - p[u, 0], p[w, 1] - p[u, 1], p[w, 2] - p[u, 2]
    e2 = ex * ex + ey * ey + ez * ez
    if e2 <= 0.0:
        return -1
    tt = ((p[x, 0] - p[u, 0]) * ex + (p[x, 1] - p[u, 1]) * ey + (p[x, 2] - p[u, 2]) * ez) / e2
    fx, fy, fz = p[u, 0] + tt * ex, p[u, 1] + tt * ey, p[u, 2] + tt * ez
    s = min(he.scale[u], min(he.scale[w], he.scale[x]))
    dx, dy, dz = fx - p[x, 0], fy - p[x, 1], fz - p[x, 2]
    if not (0.1 < tt < 0.9):
        # x stands over an end of the edge: merge it into that end instead (the halves would be needles)
        h = _half_edge(he, x, u if tt <= 0.5 else w)
        if h < 0 or _rank(flags, x) > _rank(flags, _dst(faces, h)):
            return -1
        return _try_collapse(he, h, rules.limit, rules.short, buf_a, buf_b)
    # a short move, or one along the faces around x (in their planes: the surface does not change)
    if np.sqrt(dx * dx + dy * dy + dz * dz) >= rules.short * s:
        h0 = he.out[x]
        h = h0
        while True:
            ff = h // 3
            if ff != f:
                nx, ny, nz = _normal(p, faces[ff, 0], faces[ff, 1], faces[ff, 2])
                nn = np.sqrt(nx * nx + ny * ny + nz * nz)
                if nn <= 0.0 or abs(nx * dx + ny * dy + nz * dz) > rules.flip_tolerance * s * nn:
                    return -1
            h = he.opp[_prv(h)]
            if h == h0:
                break
    if _valence(he, u, 3) <= 3 or _valence(he, w, 3) <= 3 or _half_edge(he, x, d) >= 0:
        return -1
    # the faces around x (but the cap), with x at its foot: on their surface, no worse than the limit or than now
    worst_old = _aspect(p, u, w, x)
    worst_new = 0.0
    h0 = he.out[x]
    h = h0
    while True:
        ff = h // 3
        if ff != f:
            f0, f1, f2 = faces[ff, 0], faces[ff, 1], faces[ff, 2]
            corners = _corners(p, f0, f1, f2, x, fx, fy, fz)
            qx, qy, qz = _normal_xyz(*corners)
            r0, r1, r2 = he.reference[ff, 0], he.reference[ff, 1], he.reference[ff, 2]
            if qx * r0 + qy * r1 + qz * r2 <= 0.17 * np.sqrt(qx * qx + qy * qy + qz * qz):
                return -1
            worst_old = max(worst_old, _aspect(p, f0, f1, f2))
            worst_new = max(worst_new, _aspect_xyz(*corners))
        h = he.opp[_prv(h)]
        if h == h0:
            break
    for pair in range(2):  # the two halves of the face across
        a0, a1 = (u, d) if pair == 0 else (d, w)
        worst_new = max(worst_new, _aspect_xyz(fx, fy, fz, p[a0, 0], p[a0, 1], p[a0, 2], p[a1, 0], p[a1, 1], p[a1, 2]))
    if not (worst_new <= rules.limit or worst_new < worst_old):
        return -1
    on_seam = he.face_part[f] != he.face_part[t // 3]
    across = t // 3
    _flip(he, g)
    for ff in (f, across):  # both faces are now halves of the face across
        _inherit(he, ff, across)
    p[x, 0], p[x, 1], p[x, 2] = fx, fy, fz
    if on_seam:
        flags[x] |= SEAM
    elif (flags[u] & (ORIGINAL | FEATURE)) and (flags[w] & (ORIGINAL | FEATURE)):
        flags[x] |= ORIGINAL
    return x


@_leaf
def _split_fan(he, f, order, lengths, rules, spawned):
    """A needle of a seam's fan: split its longest edge that leaves the seam ``step`` scales from it; the vertex or -1.

    The boolean joins each point of its intersection curve to the far corners
    of the tube faces it cut: fans of needles as long as the span.  The
    vertices put on one fan's edges merge in the next collapses, leaving short
    triangles along the seam and one fan of ordinary ones beyond.  A seam
    vertex spawns at most a few (a new vertex that merges back into a tube
    vertex would bring the fan back, and the split again: a cycle).
    """
    faces, flags = he.faces, he.flags
    for i in range(3):
        k = order[i]
        u, w = faces[f, k], faces[f, (k + 1) % 3]
        su, sw = (flags[u] & SEAM) != 0, (flags[w] & SEAM) != 0
        if su == sw or (flags[u] | flags[w]) & LOCKED:
            continue
        v = u if su else w
        if lengths[k] <= rules.long * he.scale[v] or spawned[v] >= _MAX_SPAWN:
            continue
        spawned[v] += 1
        t = rules.step * he.scale[v] / lengths[k]
        return _split(he, 3 * f + k, t if su else 1.0 - t)
    return -1


@numba.njit(cache=True, nogil=True)
def clean(he, rules, region, side, own, spawned):
    """Remove the needles and caps of ``he`` by local operations; returns how many of each kind were done.

    Every face that needs work (an edge shorter than ``rules.short`` local
    scales, or an aspect above ``rules.bad``) goes on a stack; the faces
    around whatever an operation changes go on it again, and when the stack
    runs dry every face is looked at again (up to three times: an operation
    also changes the valences around it, which may unblock another).  For
    each face:

    1. its edges shorter than ``short`` are collapsed, shortest first, where allowed;
    2. if its aspect is above ``bad``: its edges are flipped, longest first,
       where :func:`_flip_ok` allows it (the surface moving less than
       ``flip_tolerance`` scales);
    3. failing that, a cap's far corner is snapped onto its longest edge (:func:`_snap`);
    4. failing that, a seam fan's needle is split (:func:`_split_fan`);
    5. failing that, its shortest edge is collapsed if shorter than ``fallback``.

    Lengths are in local scales (``he.scale``: the side of the thinnest tube there).
    ``region`` (a flag per vertex) limits the work to the faces touching it
    (empty: everywhere).  ``side`` (a number per face, or empty) limits it to
    the faces of side ``own``, and the faces a split makes join it: one half
    of :func:`halves`, while another thread cleans the other.  ``spawned``
    counts the fan splits each vertex made (zeros at first; the halves and
    the pass after them share it).  Returns the counts of collapses, flips,
    snaps, fan splits and fallback collapses.
    """
    faces, p = he.faces, he.points
    fcap = len(faces)
    buf_a = np.empty(_MAX_RING, np.int64)
    buf_b = np.empty(_MAX_RING, np.int64)
    lengths = np.empty(3)
    order = np.empty(3, np.int64)
    queued = np.zeros(fcap, np.bool_)
    stack = np.empty(fcap, np.int64)
    top = 0
    everywhere = len(region) == 0
    halved = len(side) > 0
    for f in range(he.counts[1] - 1, -1, -1):
        if (halved and side[f] != own) or not he.face_alive[f]:
            continue
        if not everywhere and not (region[faces[f, 0]] or region[faces[f, 1]] or region[faces[f, 2]]):
            continue
        if _needs_work(he, f, rules):
            queued[f] = True
            stack[top] = f
            top += 1
    done = np.zeros(5, np.int64)  # collapses, flips, snaps, fan splits, fallback collapses
    rounds = 0 if everywhere else 3  # a second cleaning of a region does not look everywhere again
    while top > 0 and done.sum() < rules.max_operations:
        top -= 1
        f = stack[top]
        queued[f] = False
        if not he.face_alive[f] or (halved and side[f] != own):
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        s = min(he.scale[a], min(he.scale[b], he.scale[c]))
        for k in range(3):
            lengths[k] = _length(p, faces[f, k], faces[f, (k + 1) % 3])
        # edges by length, shortest first
        order[0], order[1], order[2] = 0, 1, 2
        for i in range(3):
            for j in range(2 - i):
                if lengths[order[j]] > lengths[order[j + 1]]:
                    order[j], order[j + 1] = order[j + 1], order[j]
        touched = -1
        touched2 = -1
        for i in range(3):
            k = order[i]
            if lengths[k] >= rules.short * s:
                break
            touched = _try_collapse(he, 3 * f + k, rules.limit, rules.short, buf_a, buf_b)
            if touched >= 0:
                done[0] += 1
                break
        if touched < 0 and _aspect(p, a, b, c) > rules.bad:
            for i in range(2, -1, -1):
                g = 3 * f + order[i]
                if _flip_ok(he, g, rules.flip_tolerance * s):
                    touched, touched2 = _org(faces, g), _dst(faces, g)
                    _flip(he, g)
                    done[1] += 1
                    break
            if touched < 0:
                touched = _snap(he, f, order[2], rules, buf_a, buf_b)
                done[2] += touched >= 0
            if touched < 0:
                order[0], order[2] = order[2], order[0]  # longest first
                touched = _split_fan(he, f, order, lengths, rules, spawned)
                order[0], order[2] = order[2], order[0]
                done[3] += touched >= 0
                if halved and touched >= 0:
                    side[he.counts[1] - 2] = own
                    side[he.counts[1] - 1] = own
            if touched < 0 and lengths[order[0]] < rules.fallback * s:
                touched = _try_collapse(he, 3 * f + order[0], rules.limit, rules.short, buf_a, buf_b)
                done[4] += touched >= 0
        if touched < 0:
            continue
        for v in (touched, touched2):
            if v >= 0:
                top = _push_fan(he, v, stack, queued, top, rules)
        if he.face_alive[f] and not queued[f] and _needs_work(he, f, rules):
            queued[f] = True
            stack[top] = f
            top += 1
        if top == 0 and rounds < 3:
            # faces an operation changed only by the valences around them: look at everything again
            rounds += 1
            for g in range(he.counts[1] - 1, -1, -1):
                if (halved and side[g] != own) or not he.face_alive[g]:
                    continue
                if _needs_work(he, g, rules):
                    queued[g] = True
                    stack[top] = g
                    top += 1
    return done


def halves(he: HalfEdges, width: int, region=None, skip: int = -1):
    """Two halves of ``he`` that :func:`clean` can work on at once: ``side`` per face; ``band``, ``near`` per vertex.

    The cut is a plane across the mesh's longest extent, through the median
    of its vertices.  The ``band`` is every vertex within ``width`` edges of
    one with faces on both sides of it, and ``side`` is 0 or 1 for a face by
    where its centre lies, 3 for a face with a vertex within ``width + 1``
    edges (the band's faces and those next to them: left to the pass after
    the halves over the vertices ``near`` the cut, within ``width + 1``), 2
    for the faces splits will make.  An
    operation on a face of one side changes at most the faces around its
    vertices and their neighbours, none locked; with the band :data:`LOCKED`
    as well, neither half reads or writes what the other may change, so the
    result does not depend on which runs first, or on both running at once.
    With a ``region`` (a flag per vertex), the median is that of its
    vertices, and the cut is across their longest extent but along axis
    ``skip`` (the band of a first cut, cut again across).  Also returns the axis.
    """
    nv = int(he.counts[0])
    alive = he.vertex_alive[:nv] if region is None else he.vertex_alive[:nv] & region[:nv]
    points = he.points[:nv] if alive.all() else he.points[:nv][alive]  # no copy of a whole mesh
    extent = np.ptp(points, axis=0) if len(points) else np.zeros(3)
    if 0 <= skip < 3:
        extent[skip] = -1.0
    axis = int(np.argmax(extent))
    if not len(points):
        cut = 0.0
    elif region is None:
        cut = float(np.median(points[:, axis]))
    else:
        # across a band, the median may run along a trunk, its junctions all near the cut: of the middle
        # positions, the one with the fewest seam vertices within a few of their scales
        seam = (he.flags[:nv][alive] & SEAM) != 0
        x, reach = points[seam, axis], 4.0 * he.scale[:nv][alive][seam]
        cuts = np.quantile(points[:, axis], np.linspace(0.3, 0.7, 9))
        crowd = [np.count_nonzero(np.abs(x - c) < reach) for c in cuts]
        cut = float(cuts[int(np.argmin(crowd))])
    side = np.full(len(he.faces), 2, np.int8)
    band = np.zeros(len(he.points), np.bool_)
    near = np.zeros(len(he.points), np.bool_)
    _sides(he, axis, cut, width, side, band, near)
    return side, band, near, axis


@numba.njit(cache=True, nogil=True)
def _sides(he, axis, cut, width, side, band, near):
    """:func:`halves`' passes: each face's side, the vertices with faces on both, ``width + 1`` rings more."""
    faces, p = he.faces, he.points
    nv, nf = he.counts[0], he.counts[1]
    reach = np.zeros(nv, np.int8)  # bit s: the vertex has a face of side s
    for f in range(nf):
        if not he.face_alive[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        s = 0 if p[a, axis] + p[b, axis] + p[c, axis] < 3.0 * cut else 1
        side[f] = s
        reach[a] |= 1 << s
        reach[b] |= 1 << s
        reach[c] |= 1 << s
    # the distance in edges from a vertex with faces on both sides, up to width + 1: breadth first from those
    far = width + 2
    dist = np.full(nv, far, np.int64)
    queue = np.empty(nv, np.int64)
    top = 0
    for v in range(nv):
        if reach[v] == 3:
            dist[v] = 0
            queue[top] = v
            top += 1
    head = 0
    while head < top:
        v = queue[head]
        head += 1
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            if dist[v] <= width:  # the faces around a vertex of the band: their corners one edge farther
                for k in range(3):
                    w = faces[f, k]
                    if dist[w] > dist[v] + 1:
                        dist[w] = dist[v] + 1
                        queue[top] = w
                        top += 1
            side[f] = 3  # a face with a corner within width + 1
            g = he.opp[_prv(g)]
            if g == h0:
                break
    for v in range(nv):
        band[v] = dist[v] <= width
        near[v] = dist[v] <= width + 1


@_leaf
def _collapse_volume(he, h, x, y, z):
    """How far collapsing half-edge ``h`` (ends placed at ``x, y, z``) moves the surface around, on average.

    Six times the volume it adds or removes over twice the area of the faces
    around its ends (what a uniform move of them by that distance would add).
    """
    faces, p = he.faces, he.points
    a = _org(faces, h)
    b = _dst(faces, h)
    t = he.opp[h]
    change = 0.0
    area = 0.0
    for end in range(2):
        v = a if end == 0 else b
        h0 = he.out[v]
        g = h0
        while True:
            f = g // 3
            k = g % 3
            u, w = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            cx, cy, cz = _cross(p[u, 0], p[u, 1], p[u, 2], p[w, 0], p[w, 1], p[w, 2])
            nx, ny, nz = _normal(p, v, u, w)
            area += np.sqrt(nx * nx + ny * ny + nz * nz)
            if f == h // 3 or f == t // 3:
                if end == 0:  # the two dying faces
                    change -= p[v, 0] * cx + p[v, 1] * cy + p[v, 2] * cz
            else:
                change += (x - p[v, 0]) * cx + (y - p[v, 1]) * cy + (z - p[v, 2]) * cz
            g = he.opp[_prv(g)]
            if g == h0:
                break
    return 3.0 * abs(change) / max(area, 1e-300)


@_leaf
def _flip_volume(he, h):
    """How far flipping the edge of half-edge ``h`` moves the surface, on average (see :func:`_collapse_volume`)."""
    faces, p = he.faces, he.points
    a, b, c, d = _org(faces, h), _dst(faces, h), _apex(faces, h), _apex(faces, he.opp[h])
    ex, ey, ez = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    cx, cy, cz = _cross(
        p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2], p[d, 0] - p[a, 0], p[d, 1] - p[a, 1], p[d, 2] - p[a, 2]
    )
    n0x, n0y, n0z = _normal(p, a, b, c)
    n1x, n1y, n1z = _normal(p, b, a, d)
    area = np.sqrt(n0x * n0x + n0y * n0y + n0z * n0z) + np.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
    return 3.0 * abs(ex * cx + ey * cy + ez * cz) / max(area, 1e-300)


def rescue(he, worst, height, flip, pool=None):
    """The last resort for faces still worse than aspect ``worst`` or lower than ``height``; returns the count fixed.

    First, on every face, an edge so short that readers would weld its ends
    (float32 files, trimesh's 1e-8 grid) merges whenever the topology allows.
    Then such a face may flip an edge that moves the surface by up to
    ``flip`` local scales (more than :func:`clean` allows); failing that, any
    of its edges may collapse, either way or to a point between (a quarter,
    half or three quarters along), whatever the ranks of its ends,
    when every face around keeps its side and the worst aspect around
    becomes better than this face's (for a face lower than ``height``:
    whatever the aspects); a vertex of three neighbours on it, or across one
    of its edges (which blocks the collapse of that edge), may merge into any
    of them on the same terms (whatever the aspects, into one nearer than a
    tenth of a side: the next round collapses the face's edge).  No flip or
    collapse here may move the surface around it by more than a twentieth of
    the local scale on average (the volume it changes over the area of the
    faces): on the flat presets, where long needles lie along the tubes,
    unguarded ones took abop-1.24e's bark down 2.7%.

    The first round looks only at the faces that need it (found beforehand,
    in two halves with a ``pool``): a face that needs nothing and that no
    operation before it changed would be left as it is (the same result).
    Where none needs it (monopodial, the Koch curves, snowflake, dragon...),
    the rescue is not called, nor compiled (6 s of a fresh install's first run).
    """
    now = np.zeros(len(he.faces), np.bool_)
    nf = int(he.counts[1])
    _in_two(pool, _needs_rescue, (he, worst, height, now), 0, nf // 2, nf)
    return _rescue(he, worst, height, flip, now) if now.any() else 0


@numba.njit(cache=True, nogil=True)
def _needs_rescue(he, worst, height, now, lo, hi):
    """Into ``now[lo:hi]``: whether :func:`rescue` has anything to do on each face (as it looks at it)."""
    faces, p = he.faces, he.points
    for f in range(lo, hi):
        if not he.face_alive[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        weld = _weldable(he, a, b) or _weldable(he, b, c) or _weldable(he, c, a)
        now[f] = weld or not _aspect(p, a, b, c) <= worst or _low(p, a, b, c, height)


@_leaf
def _weldable(he, u, w):
    """Whether edge ``u w`` is so short that readers would weld its ends (float32, trimesh's 1e-8 grid), and
    neither end is locked."""
    p = he.points
    weld = 1e-8 + 1e-6 * max(abs(p[w, 0]), max(abs(p[w, 1]), abs(p[w, 2])))
    return _length(p, u, w) < weld and not ((he.flags[u] | he.flags[w]) & LOCKED)


@_leaf
def _low(p, a, b, c, height):
    """Whether triangle ``a b c`` is lower than ``height`` (twice its area over its longest edge)."""
    nx, ny, nz = _normal(p, a, b, c)
    longest = max(_length(p, a, b), max(_length(p, b, c), _length(p, c, a)))
    return np.sqrt(nx * nx + ny * ny + nz * nz) < height * longest


@numba.njit(cache=True, nogil=True)
def _rescue(he, worst, height, flip, now):
    """:func:`rescue`, the faces to look at first in ``now``."""
    faces, p = he.faces, he.points
    buf_a = np.empty(_MAX_RING, np.int64)
    buf_b = np.empty(_MAX_RING, np.int64)
    fixed = 0
    splits = 0
    # a bound on the splits (not counts: a room's gaps): only abop-1.24a's seams, where coplanar tubes lie
    # along each other, reach it; there a hundredth of the faces (some 670 allowed, 331 made) took its faces above
    # aspect 1,000 or under the height from 374 to 313 in 12 rounds, a thousandth (124) to 314, a third faster
    max_splits = 64 + np.count_nonzero(he.face_alive[: he.counts[1]]) // 1000
    # After the first round a face is looked at again only if an operation changed something near it (within
    # _NEAR edges of a vertex the operation moved, merged or changed the valence of): what a face needs and
    # whether an operation on it is allowed depend on nothing farther, and a look that changes nothing has no
    # effect, so the result is that of looking at every face every round, at the cost of the changes.
    # ``now``: look at it this round
    again = np.zeros(len(faces), np.bool_)  # and the next
    seen = np.zeros(len(p) + 1, np.int64)  # per vertex, the last walk that reached it; the walks' count last
    queue = np.empty(_NEAR_QUEUE, np.int64)
    for _ in range(12):
        changed = 0
        for f in range(he.counts[1]):
            if not he.face_alive[f] or not now[f]:
                continue
            now[f] = False
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            # an edge readers would weld (float32, or trimesh's 1e-8 grid): merge it if the topology allows
            for k in range(3):
                g = 3 * f + k
                u, w = faces[f, k], faces[f, (k + 1) % 3]
                if _weldable(he, u, w) and _collapse_ok(he, g, p[w, 0], p[w, 1], p[w, 2], 1e300, buf_a, buf_b, False):
                    _collapse(he, g, p[w, 0], p[w, 1], p[w, 2])
                    _touch_near(he, w, now, again, seen, queue)
                    changed += 1
                    break
            if not he.face_alive[f]:
                continue
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            bad = _aspect(p, a, b, c)
            low = _low(p, a, b, c, height)
            if bad <= worst and not low:
                continue
            # a sliver goes whatever it leaves around (as long as nothing turns over)
            allowed = 1e300 if low else 0.999 * bad
            done = False
            # a flip that moves the surface by up to ``flip`` local scales
            s = min(he.scale[a], min(he.scale[b], he.scale[c]))
            budget = 0.05 * s  # the surface around moves by at most this on average
            lengths = np.array([_length(p, a, b), _length(p, b, c), _length(p, c, a)])
            for k in np.argsort(-lengths):
                g = 3 * f + k
                if _flip_ok(he, g, flip * s) and _flip_volume(he, g) <= budget:
                    _flip(he, g)
                    for k2 in range(3):
                        _touch_near(he, faces[g // 3, k2], now, again, seen, queue)
                    _touch_near(he, _apex(faces, he.opp[g]), now, again, seen, queue)
                    done = True
                    break
            # candidate half-edges: the face's own (both ways), then those leaving a corner of three neighbours
            for k in range(6 if not done else 0):
                g = 3 * f + k % 3
                if k >= 3:
                    g = he.opp[g]
                if he.flags[_org(faces, g)] & (LOCKED | FEATURE):
                    continue
                # whether the edge may collapse at all does not depend on where its ends meet: asked once
                if not _topology_ok_called(he, g, buf_a, buf_b):
                    continue
                w = _dst(faces, g)
                if _geometry_ok_called(he, g, p[w, 0], p[w, 1], p[w, 2], allowed) and (
                    (_collapse_volume(he, g, p[w, 0], p[w, 1], p[w, 2])) <= budget
                ):
                    _collapse(he, g, p[w, 0], p[w, 1], p[w, 2])
                    _touch_near(he, w, now, again, seen, queue)
                    done = True
                    break
                # or both ends meet on the edge (on a crease, either end may turn a face over, a point between not)
                u = _org(faces, g)
                if k < 3 and not (he.flags[w] & (LOCKED | FEATURE)):
                    for t in (0.5, 0.25, 0.75):
                        x = p[u, 0] + t * (p[w, 0] - p[u, 0])
                        y = p[u, 1] + t * (p[w, 1] - p[u, 1])
                        z = p[u, 2] + t * (p[w, 2] - p[u, 2])
                        if _geometry_ok_called(he, g, x, y, z, allowed) and (
                            (_collapse_volume(he, g, x, y, z)) <= budget
                        ):
                            _collapse(he, g, x, y, z)
                            _touch_near(he, w, now, again, seen, queue)
                            done = True
                            break
                    if done:
                        break
            if not done:
                for k in range(6):  # its corners, then the corners across its edges
                    v = faces[f, k] if k < 3 else _apex(faces, he.opp[3 * f + k - 3])
                    if _valence(he, v, 3) != 3 or he.flags[v] & (LOCKED | FEATURE):
                        continue
                    g0 = he.out[v]
                    g = g0
                    while True:
                        w = _dst(faces, g)
                        # a merge along an edge of a tenth of a side moves nothing that counts: whatever the
                        # aspects (the face being fixed, unchanged by it, may be the worst around)
                        near = _length(p, v, w) < 0.1 * he.scale[v]
                        if _collapse_ok(
                            he, g, p[w, 0], p[w, 1], p[w, 2], 1e300 if near else allowed, buf_a, buf_b
                        ) and ((_collapse_volume(he, g, p[w, 0], p[w, 1], p[w, 2])) <= budget):
                            _collapse(he, g, p[w, 0], p[w, 1], p[w, 2])
                            _touch_near(he, w, now, again, seen, queue)
                            done = True
                            break
                        g = he.opp[_prv(g)]
                        if g == g0:
                            break
                    if done:
                        break
            if not done and not low and bad > worst and splits < max_splits:
                # nothing else helps (a strip of seam along a twig lying against its parent, its ends far apart):
                # cut its longest edge in two (the surface does not move); the flips and collapses then finish
                k = np.argmax(lengths)
                g = 3 * f + k
                u, w = faces[f, k], faces[f, (k + 1) % 3]
                across = he.face_part[f] != he.face_part[he.opp[g] // 3]
                if he.flags[u] & he.flags[w] & SEAM and not ((he.flags[u] | he.flags[w]) & LOCKED):
                    v = _split(he, g, 0.5)
                    if v >= 0:
                        _touch_near(he, v, now, again, seen, queue)
                        he.flags[v] |= SEAM if across else 0
                        splits += 1
                        done = True
            changed += done
        fixed += changed
        if changed == 0:
            break
        now, again = again, now
        again[:] = False
    return fixed


_NEAR = 3
"""How far (in edges from a vertex an operation changed) :func:`rescue` looks again: a bad face's look reads
the faces around its corners, around the corners across its edges and around their neighbours (a vertex of
three neighbours merges into one of them), which an operation changes within one edge of its vertex."""
_NEAR_QUEUE = 1 << 14


@_leaf
def _touch_near(he, v, now, again, seen, queue):
    """Mark the faces around every vertex within :data:`_NEAR` edges of ``v`` to be looked at this round and
    the next (every face, when the neighbourhood is too large to walk)."""
    walk = seen[-1] + 1
    seen[-1] = walk
    seen[v] = walk
    queue[0] = v
    head, tail, level_end, depth = 0, 1, 1, 0
    while head < tail:
        if head == level_end:
            depth += 1
            level_end = tail
        u = queue[head]
        head += 1
        g0 = he.out[u]
        if g0 < 0:
            continue
        g = g0
        n = 0
        while True:
            now[g // 3] = True
            again[g // 3] = True
            w = _dst(he.faces, g)
            if depth < _NEAR and seen[w] != walk:
                if tail == len(queue):
                    now[:] = True
                    again[:] = True
                    return
                seen[w] = walk
                queue[tail] = w
                tail += 1
            g = he.opp[_prv(g)]
            n += 1
            if g == g0 or n > _MAX_RING:
                break


# ---------------------------------------------------------------------------------------- junction collars
@numba.njit(cache=True, nogil=True)
def collar(he, width, closeness):
    """How close each vertex is to a seam, in ``closeness`` (1 on the seam, 0 at ``width`` scales or beyond).

    The distance is measured along edges from the nearest seam vertex, in that
    seam vertex's own scale (the side of the thinner tube at the seam), so a
    twig's collar is as narrow as the twig.  Returns the number of vertices in
    a collar.
    """
    faces, p = he.faces, he.points
    nv = he.counts[0]
    reach = np.zeros(nv)  # metres still to go from the best seam vertex
    span = np.zeros(nv)  # that seam vertex's collar width in metres
    # the vertices whose reach grew, to go on from (each in the queue at most once): a worklist from the seams
    # instead of sweeps over every face until none changes (a fraction of the work; the same answer but where
    # two paths tie within the 1e-12 below: the first found wins)
    queue = np.empty(max(nv, 1), np.int64)
    queued = np.zeros(nv, np.bool_)
    head, size = 0, 0
    for v in range(nv):
        if he.vertex_alive[v] and he.out[v] >= 0 and he.flags[v] & SEAM:
            span[v] = width * he.scale[v]
            reach[v] = span[v]
            queue[size] = v
            queued[v] = True
            size += 1
    while size > 0:
        u = queue[head]
        head = (head + 1) % nv
        size -= 1
        queued[u] = False
        if reach[u] <= 0.0:
            continue
        h0 = he.out[u]
        g = h0
        while True:
            w = _dst(faces, g)
            left = reach[u] - _length(p, u, w)
            # the seam whose collar is left the larger share of wins
            if left > 0.0 and (span[w] == 0.0 or left * span[w] > reach[w] * span[u] * (1.0 + 1e-12)):
                reach[w] = left
                span[w] = span[u]
                if not queued[w]:
                    queued[w] = True
                    queue[(head + size) % nv] = w
                    size += 1
            g = he.opp[_prv(g)]
            if g == h0:
                break
    n = 0
    for v in range(nv):
        closeness[v] = reach[v] / span[v] if span[v] > 0.0 else 0.0
        n += closeness[v] > 0.0
    return n


@_leaf
def _vertex_normal(he, v):
    faces, p = he.faces, he.points
    h0 = he.out[v]
    g = h0
    nx, ny, nz = 0.0, 0.0, 0.0
    while True:
        f = g // 3
        ax, ay, az = _normal(p, faces[f, 0], faces[f, 1], faces[f, 2])
        nx += ax
        ny += ay
        nz += az
        g = he.opp[_prv(g)]
        if g == h0:
            break
    n = np.sqrt(nx * nx + ny * ny + nz * nz)
    if n <= 0.0:
        return 0.0, 0.0, 0.0
    return nx / n, ny / n, nz / n


@_leaf
def _fan_volume(p, faces, he, v):
    """Six times the volume of the cone from the origin over the faces around ``v``, and its gradient in ``v``."""
    h0 = he.out[v]
    g = h0
    six, gx, gy, gz = 0.0, 0.0, 0.0, 0.0
    while True:
        f = g // 3
        k = g % 3
        u, w = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
        cx, cy, cz = _cross(p[u, 0], p[u, 1], p[u, 2], p[w, 0], p[w, 1], p[w, 2])
        six += p[v, 0] * cx + p[v, 1] * cy + p[v, 2] * cz
        gx += cx
        gy += cy
        gz += cz
        g = he.opp[_prv(g)]
        if g == h0:
            break
    return six, gx, gy, gz


@_leaf
def _faces_turned(he, v):
    """Whether a face around ``v`` is turned more than 80 degrees from its reference normal."""
    faces, p = he.faces, he.points
    h0 = he.out[v]
    g = h0
    while True:
        f = g // 3
        qx, qy, qz = _normal(p, faces[f, 0], faces[f, 1], faces[f, 2])
        r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
        if qx * r0 + qy * r1 + qz * r2 <= 0.17 * np.sqrt(qx * qx + qy * qy + qz * qz):
            return True
        g = he.opp[_prv(g)]
        if g == h0:
            return False


@_leaf
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


_FAIR_SHARE_MIN = 4096
"""Collar vertices from which :func:`fair` shares its steps with a second thread."""


def fair(he, closeness, iterations, step, reach, inward, pool=None):
    """Round the junction creases: make each collar as smooth as a thin plate bent between its tubes.

    The collar vertices (``closeness > 0``) move along their normals to make
    the bi-Laplacian vanish (the Laplacian weighted by 1 / length^2, applied
    twice), with every vertex outside the collar held: steps of ``step``
    times the bi-Laplacian's normal part, ``iterations`` times (Jacobi, so the
    order of the vertices does not matter).  The collar then leaves each tube
    with its tangent plane and the crease between them becomes a fillet about as wide as the collar.  Weighting by the
    inverse square of the edge length makes the Laplacian a property of the
    surface rather than of the mesh: the long edges of a tube's spans hardly
    count, where a plain mean would drag a vertex along them.  Unless
    ``inward``, vertices only move outwards (the concave creases fill; a convex
    tube is never pulled in).  No vertex moves farther than ``reach`` local
    scales from where it was (a narrow crotch is not webbed over), and a
    vertex that leaves a face turned more than 80 degrees from its reference
    normal goes back where it was.

    A fillet fills its crease: on its own it adds volume (koch +8.6%, tree3d
    +1.2%: short tubes, deep creases).  So each collar (a connected piece of
    collar vertices) then gives the volume it gained back: its vertices sink
    along their normals in proportion to their closeness to the seam and
    their scale (a slight waist under the fillet), so a collar blends
    without inflating the junction.  With a ``pool`` (an executor), each
    Jacobi step's two passes are shared by the calling thread and one of the
    pool's (:func:`_in_two`; the same bits).  Returns the vertices moved.
    """
    members, slot, around = _fair_setup(he, closeness)
    na, m = len(around), len(members)
    pool = pool if m >= _FAIR_SHARE_MIN else None
    first = np.zeros(na + 1, np.int64)  # the neighbours of the collar and its neighbours, as CSR lists
    _in_two(pool, _valences, (he, around, first[1:]), 0, na // 2, na)
    first = np.cumsum(first)
    nbr = np.empty(first[na], np.int64)
    _in_two(pool, _neighbours, (he, around, first, nbr), 0, na // 2, na)
    p = he.points
    start = p[members]  # where the collar was
    # each vertex moves along its normal before the fairing (the moves are a fraction of a side; recomputing
    # it every step cost 60% of the fairing)
    normal = np.empty((m, 3))
    _in_two(pool, _vertex_normals, (he, members, normal), 0, m // 2, m)
    lap = np.zeros((na, 3))
    target = np.zeros((m, 3))
    moving = (he, members, slot, first, nbr, lap, normal, start, step, reach, inward, target)
    for _ in range(iterations):
        _in_two(pool, _laplacians, (p, around, first, nbr, lap), 0, na // 2, na)
        _in_two(pool, _fair_targets, moving, 0, m // 2, m)
        p[members] = target
    return _fair_finish(he, closeness, members, start)


@numba.njit(cache=True, nogil=True)
def _fair_setup(he, closeness):
    """:func:`fair`'s collar vertices, their slots among them and their neighbours, and those (``around``)."""
    faces = he.faces
    nv = he.counts[0]
    member = np.zeros(nv, np.bool_)
    for v in range(nv):
        if closeness[v] > 0.0 and he.vertex_alive[v] and he.out[v] >= 0 and not (he.flags[v] & (LOCKED | FEATURE)):
            member[v] = True
    members = np.flatnonzero(member)
    # the collar and its neighbours (where the Laplacian is needed)
    slot = np.full(nv, -1, np.int64)
    around = np.empty(nv, np.int64)
    na = 0
    for v in members:
        if slot[v] < 0:
            slot[v] = na
            around[na] = v
            na += 1
        h0 = he.out[v]
        g = h0
        while True:
            w = _dst(faces, g)
            if slot[w] < 0:
                slot[w] = na
                around[na] = w
                na += 1
            g = he.opp[_prv(g)]
            if g == h0:
                break
    return members, slot, around[:na]


@numba.njit(cache=True, nogil=True)
def _valences(he, around, count, lo, hi):
    """``count[lo:hi]``: how many neighbours ``around[lo:hi]`` have."""
    for i in range(lo, hi):
        count[i] = _valence(he, around[i])


@numba.njit(cache=True, nogil=True)
def _neighbours(he, around, first, nbr, lo, hi):
    """The neighbours of ``around[lo:hi]`` into ``nbr[first[i]:first[i + 1]]``."""
    for i in range(lo, hi):
        g = he.out[around[i]]
        for k in range(first[i], first[i + 1]):
            nbr[k] = _dst(he.faces, g)
            g = he.opp[_prv(g)]


@numba.njit(cache=True, nogil=True)
def _vertex_normals(he, members, normal, lo, hi):
    """``normal[lo:hi]``: the normals of ``members[lo:hi]`` (:func:`_vertex_normal`)."""
    for i in range(lo, hi):
        normal[i, 0], normal[i, 1], normal[i, 2] = _vertex_normal(he, members[i])


@numba.njit(cache=True, nogil=True)
def _laplacians(p, around, first, nbr, lap, lo, hi):
    """One Jacobi step of :func:`fair`, first pass: the weighted Laplacian at ``around[lo:hi]``."""
    for i in range(lo, hi):
        v = around[i]
        mx, my, mz, total = 0.0, 0.0, 0.0, 0.0
        for k in range(first[i], first[i + 1]):
            w = nbr[k]
            dx, dy, dz = p[w, 0] - p[v, 0], p[w, 1] - p[v, 1], p[w, 2] - p[v, 2]
            weight = 1.0 / max(dx * dx + dy * dy + dz * dz, 1e-300)
            mx += weight * dx
            my += weight * dy
            mz += weight * dz
            total += weight
        lap[i, 0], lap[i, 1], lap[i, 2] = mx / total, my / total, mz / total


@numba.njit(cache=True, nogil=True)
def _fair_targets(he, members, slot, first, nbr, lap, normal, start, step, reach, inward, target, lo, hi):
    """One Jacobi step of :func:`fair`, second pass: where ``members[lo:hi]`` move (into ``target``)."""
    p = he.points
    for i in range(lo, hi):
        v = members[i]
        j = slot[v]
        mx, my, mz, total = 0.0, 0.0, 0.0, 0.0
        for k in range(first[j], first[j + 1]):
            w = nbr[k]
            dx, dy, dz = p[w, 0] - p[v, 0], p[w, 1] - p[v, 1], p[w, 2] - p[v, 2]
            weight = 1.0 / max(dx * dx + dy * dy + dz * dz, 1e-300)
            lw = slot[w]
            mx += weight * (lap[lw, 0] - lap[j, 0])
            my += weight * (lap[lw, 1] - lap[j, 1])
            mz += weight * (lap[lw, 2] - lap[j, 2])
            total += weight
        bx, by, bz = mx / total, my / total, mz / total
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        along = bx * nx + by * ny + bz * nz
        if along > 0.0 and not inward:  # only outwards: creases fill, tubes do not shrink
            along = 0.0
        # d(L(L(x)))/dx_v is about 2 for a regular neighbourhood
        tx = p[v, 0] - 0.5 * step * along * nx
        ty = p[v, 1] - 0.5 * step * along * ny
        tz = p[v, 2] - 0.5 * step * along * nz
        ox, oy, oz = tx - start[i, 0], ty - start[i, 1], tz - start[i, 2]
        far = np.sqrt(ox * ox + oy * oy + oz * oz)
        limit = reach * he.scale[v]
        if far > limit:
            tx, ty, tz = (
                start[i, 0] + ox * limit / far,
                start[i, 1] + oy * limit / far,
                start[i, 2] + oz * limit / far,
            )
        target[i, 0], target[i, 1], target[i, 2] = tx, ty, tz


@numba.njit(cache=True, nogil=True)
def _fair_finish(he, closeness, members, start):
    """:func:`fair`'s end: a vertex with a face turned away goes back, the collars give their volume back;
    the vertices moved."""
    faces, p = he.faces, he.points
    m = len(members)
    # a vertex with a face turned away from its surface goes back, until none is left: rounds in the members'
    # order, each seeing the reverts before it; a vertex is looked at again only once a neighbour went back
    # since it was last looked at (else it would go back no more than then: the same rounds, a fraction of the work)
    dirty = np.ones(m, np.bool_)
    for _ in range(10):
        reverted = 0
        for i in range(m):
            if not dirty[i]:
                continue
            dirty[i] = False
            v = members[i]
            if p[v, 0] == start[i, 0] and p[v, 1] == start[i, 1] and p[v, 2] == start[i, 2]:
                continue
            h0 = he.out[v]
            g = h0
            while True:
                f = g // 3
                qx, qy, qz = _normal(p, faces[f, 0], faces[f, 1], faces[f, 2])
                r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
                if qx * r0 + qy * r1 + qz * r2 <= 0.17 * np.sqrt(qx * qx + qy * qy + qz * qz):
                    p[v, 0], p[v, 1], p[v, 2] = start[i, 0], start[i, 1], start[i, 2]
                    reverted += 1
                    g = h0
                    while True:  # its neighbours among the members (ascending) are to be looked at again
                        w = _dst(faces, g)
                        j = np.searchsorted(members, w)
                        if j < m and members[j] == w:
                            dirty[j] = True
                        g = he.opp[_prv(g)]
                        if g == h0:
                            break
                    break
                g = he.opp[_prv(g)]
                if g == h0:
                    break
        if reverted == 0:
            break
    _give_back_volume(he, closeness, members, start)
    moves = 0
    for i in range(len(members)):
        v = members[i]
        moves += p[v, 0] != start[i, 0] or p[v, 1] != start[i, 1] or p[v, 2] != start[i, 2]
    return moves


@numba.njit(cache=True, nogil=True, inline="always")
def _at(p, start, slot, m, v):
    """Where vertex ``v`` was before the fairing: ``start`` for a collar vertex, else where it is."""
    j = slot[v]
    if 0 <= j < m:
        return start[j, 0], start[j, 1], start[j, 2]
    return p[v, 0], p[v, 1], p[v, 2]


@_leaf
def _collar_gain(he, slot, around, start, m, root, gained):
    """Into ``gained[root]``: six times the volume each collar's moves added (faces with a collar corner, once each)."""
    faces, p = he.faces, he.points
    gained[:] = 0.0
    for i in range(m):
        h0 = he.out[around[i]]
        g = h0
        while True:
            f = g // 3
            once = True  # the face counts at its collar corner of the lowest slot
            for k in range(3):
                j = slot[faces[f, k]]
                if 0 <= j < i:
                    once = False
            if once:  # six times the cone over the face now, less before (collar corners at ``start``)
                a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
                cx, cy, cz = _cross(p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2])
                gained[root[i]] += p[a, 0] * cx + p[a, 1] * cy + p[a, 2] * cz
                ax, ay, az = _at(p, start, slot, m, a)
                bx, by, bz = _at(p, start, slot, m, b)
                qx, qy, qz = _at(p, start, slot, m, c)
                cx, cy, cz = _cross(bx, by, bz, qx, qy, qz)
                gained[root[i]] -= ax * cx + ay * cy + az * cz
            g = he.opp[_prv(g)]
            if g == h0:
                break


@numba.njit(cache=True, nogil=True)
def _give_back_volume(he, closeness, members, start):
    """Sink each collar along its normals by what its fairing added to the volume (see :func:`fair`).

    The collars are the connected pieces of the vertices ``members`` (which
    were at ``start`` before the fairing).  Each vertex sinks ``lam *
    closeness * scale`` along its normal, one ``lam`` per collar from the
    volume's gradient (the volume is linear in each vertex's position), in two
    Newton steps; a vertex that would turn a face over keeps its faired place.
    """
    faces, p = he.faces, he.points
    m = len(members)
    slot = np.full(he.counts[0], -1, np.int64)
    for i in range(m):
        slot[members[i]] = i
    parent = np.arange(m)
    for i in range(m):
        h0 = he.out[members[i]]
        g = h0
        while True:
            j = slot[_dst(faces, g)]
            if j >= 0:
                a, b = _find(parent, i), _find(parent, j)
                if a != b:
                    parent[max(a, b)] = min(a, b)
            g = he.opp[_prv(g)]
            if g == h0:
                break
    root = np.empty(m, np.int64)
    normal = np.empty((m, 3))
    faired = np.empty((m, 3))
    for i in range(m):
        v = members[i]
        root[i] = _find(parent, i)
        normal[i, 0], normal[i, 1], normal[i, 2] = _vertex_normal(he, v)
        faired[i, 0], faired[i, 1], faired[i, 2] = p[v, 0], p[v, 1], p[v, 2]
    # every collar vertex sinks, the more the nearer the seam (sinking only those the fairing did not raise
    # leaves nothing to sink where the whole collar rose: koch's short tubes kept +7.7%)
    share = np.empty(m)
    for i in range(m):
        v = members[i]
        share[i] = closeness[v] * he.scale[v]
    gained = np.zeros(m)
    slope = np.zeros(m)
    lam = np.zeros(m)
    for i in range(m):  # the volume's slope, at the faired collar (the second step reuses it)
        _, gx, gy, gz = _fan_volume(p, faces, he, members[i])
        slope[root[i]] += share[i] * (gx * normal[i, 0] + gy * normal[i, 1] + gz * normal[i, 2])
    for _ in range(2):
        _collar_gain(he, slot, members, start, m, root, gained)
        for i in range(m):
            if root[i] == i and slope[i] > 0.0:
                lam[i] += gained[i] / slope[i]
        for i in range(m):
            v = members[i]
            w = lam[root[i]] * share[i]
            for c in range(3):
                p[v, c] = faired[i, c] - w * normal[i, c]
    for i in range(m):
        v = members[i]
        if _faces_turned(he, v):
            p[v, 0], p[v, 1], p[v, 2] = faired[i, 0], faired[i, 1], faired[i, 2]


@numba.njit(cache=True, nogil=True)
def settle(he, closeness):
    """Turn the faired collars' reference normals halfway to their own normals; returns how many changed.

    A faired collar face turns, by design, up to nearly 80 degrees from the
    tube face it lies on; measured against the tube, the operations after the
    fairing (:func:`clean` of the collars, :func:`rescue`) could hardly move
    its vertices (bush kept needles of aspect 1,600 there).  Measured against
    its own normal, they could turn it up to 160 degrees from the tube: folds
    (abop-1.24e's bark grew 23% in volume).  Halfway, neither.  Faces without
    area, or turned too far already, keep their tube's.
    """
    faces, p = he.faces, he.points
    n = 0
    for f in range(he.counts[1]):
        if not he.face_alive[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if closeness[a] <= 0.0 and closeness[b] <= 0.0 and closeness[c] <= 0.0:
            continue
        qx, qy, qz = _normal(p, a, b, c)
        q = np.sqrt(qx * qx + qy * qy + qz * qz)
        r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
        if q <= 0.0 or qx * r0 + qy * r1 + qz * r2 <= 0.17 * q:
            continue
        # halfway between the tube's and the faired face's: the later operations may turn a face at most 80
        # degrees from that, so a collar face still never turns over against its tube
        hx, hy, hz = r0 + qx / q, r1 + qy / q, r2 + qz / q
        h = np.sqrt(hx * hx + hy * hy + hz * hz)
        he.reference[f, 0], he.reference[f, 1], he.reference[f, 2] = hx / h, hy / h, hz / h
        n += 1
    return n


# ---------------------------------------------------------------------------------------- per-corner helpers
def corner_normals(points, faces, flat, pool=None):
    """Corner normals ``(f, 3, 3) float32``: angle-weighted vertex normals of the curved faces; flat faces' own.

    A corner whose vertex gets no normal (its faces cancel out) takes its
    face's; a face without area takes +Y.  With a ``pool`` (an executor), one
    of its threads sums the normals of the second half of the vertices (each
    vertex's faces in the same order: the same bits) and writes the second half
    of the corners.
    """
    nv, nf = len(points), len(faces)
    vn = np.zeros((nv, 3))
    some = np.zeros(nv, np.bool_)  # the vertex has a normal of its own (then unit)
    if pool is None:  # each half of the vertices reads every face: without a pool, one pass for all of them
        _vertex_normal_sums(points, faces, flat, vn, some, 0, nv)
    else:
        _in_two(pool, _vertex_normal_sums, (points, faces, flat, vn, some), 0, nv // 2, nv)
    out = np.empty((nf, 3, 3), np.float32)
    _in_two(pool, _corner_rows, (points, faces, flat, vn, some, out), 0, nf // 2, nf)
    return out


@numba.njit(cache=True, nogil=True)
def _vertex_normal_sums(points, faces, flat, vn, some, lo, hi):  # pragma: no cover - compiled
    """:func:`corner_normals`' unit vertex normals of the vertices ``lo:hi`` (``some``: they have one): the
    angle-weighted sum of the normals of their curved faces, face after face."""
    for f in range(len(faces)):
        if flat[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if not (lo <= a < hi or lo <= b < hi or lo <= c < hi):
            continue
        fx, fy, fz, area = _unit_normal(points, a, b, c)
        if not area:
            continue
        for k in range(3):
            v, w, u = faces[f, k], faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
            if not lo <= v < hi:
                continue
            ex, ey, ez = points[w, 0] - points[v, 0], points[w, 1] - points[v, 1], points[w, 2] - points[v, 2]
            gx, gy, gz = points[u, 0] - points[v, 0], points[u, 1] - points[v, 1], points[u, 2] - points[v, 2]
            cx, cy, cz = _cross(ex, ey, ez, gx, gy, gz)
            angle = np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), ex * gx + ey * gy + ez * gz)
            vn[v, 0] += angle * fx
            vn[v, 1] += angle * fy
            vn[v, 2] += angle * fz
    for v in range(lo, hi):
        n = np.sqrt(vn[v, 0] ** 2 + vn[v, 1] ** 2 + vn[v, 2] ** 2)
        if not n < 1e-12:
            some[v] = True
            vn[v, 0], vn[v, 1], vn[v, 2] = vn[v, 0] / n, vn[v, 1] / n, vn[v, 2] / n


@numba.njit(cache=True, nogil=True)
def _corner_rows(points, faces, flat, vn, some, out, lo, hi):  # pragma: no cover - compiled
    """:func:`corner_normals`' rows ``lo:hi`` of ``out``: a flat face's corners (or a corner whose vertex has no
    normal) take the face's own normal (made again: no (f, 3) array of them), the others their vertex's.
    ``+ 0.0`` makes a -0.0 0.0 (as the files store it: the writers need not copy the normals to fold it)."""
    for f in range(lo, hi):
        fx, fy, fz, _ = _unit_normal(points, faces[f, 0], faces[f, 1], faces[f, 2])
        for k in range(3):
            v = faces[f, k]
            if flat[f] or not some[v]:
                out[f, k, 0], out[f, k, 1], out[f, k, 2] = fx + 0.0, fy + 0.0, fz + 0.0
            else:
                out[f, k, 0], out[f, k, 1], out[f, k, 2] = vn[v, 0] + 0.0, vn[v, 1] + 0.0, vn[v, 2] + 0.0


@_leaf
def _unit_normal(p, a, b, c):
    """Triangle ``a b c``'s unit normal and whether it has area (+Y when it has none)."""
    nx, ny, nz = _normal(p, a, b, c)
    n = np.sqrt(nx * nx + ny * ny + nz * nz)
    if n > 0.0:
        return nx / n, ny / n, nz / n, True
    return 0.0, 1.0, 0.0, False


def tube_faces(points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute, pool=None):
    """What each face of the union learns from the tube face it is a piece of (``source``), in one pass.

    The tube faces are ``wedge_point[tube_faces]`` (:class:`lsys3d.mesh.sweep.Tubes`).

    Returns ``scale (v,)``: the shortest edge of the tube faces around each
    vertex (inf for none); ``original (v,) bool``: the vertex lies on a corner
    of one of its faces' tube faces, within ``relative`` times that face's
    shortest edge or ``absolute`` times the coordinate's magnitude (the union
    moves vertices that share a float32 position apart by a few float32
    steps); ``reference (f, 3)``: the tube face's unit normal (zero when it
    has no area).  With a ``pool`` (an executor), one of its threads reads
    the second half of the faces, into vertex arrays of its own that are
    then merged (a minimum, an or: the same values).
    """
    nf, nv = len(faces), len(points)
    scale, original, reference = np.full(nv, np.inf), np.zeros(nv, np.bool_), np.zeros((nf, 3))
    args = (points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute)
    if pool is None:
        _tube_faces(*args, scale, original, reference, 0, nf)
        return scale, original, reference
    scale2, original2 = np.full(nv, np.inf), np.zeros(nv, np.bool_)
    second = pool.submit(_tube_faces, *args, scale2, original2, reference, nf // 2, nf)
    _tube_faces(*args, scale, original, reference, 0, nf // 2)
    second.result()
    np.minimum(scale, scale2, out=scale)
    original |= original2
    return scale, original, reference


@numba.njit(cache=True, nogil=True)
def _tube_faces(
    points, faces, tube_points, wedge_point, tube_faces, source, relative, absolute, scale, original, reference, lo, hi
):  # pragma: no cover - compiled
    """:func:`tube_faces` of the faces ``lo .. hi - 1``, into ``scale``, ``original`` and ``reference``."""
    corner = np.empty((3, 3))
    for f in range(lo, hi):
        tf = source[f]
        for j in range(3):
            q = wedge_point[tube_faces[tf, j]]
            corner[j, 0], corner[j, 1], corner[j, 2] = tube_points[q, 0], tube_points[q, 1], tube_points[q, 2]
        shortest = 1e300
        for j in range(3):
            k = (j + 1) % 3
            d = 0.0
            for c in range(3):
                d += (corner[j, c] - corner[k, c]) ** 2
            shortest = min(shortest, np.sqrt(d))
        nx, ny, nz = _normal_xyz(
            corner[0, 0], corner[0, 1], corner[0, 2], corner[1, 0], corner[1, 1], corner[1, 2],
            corner[2, 0], corner[2, 1], corner[2, 2],
        )  # fmt: skip
        n = np.sqrt(nx * nx + ny * ny + nz * nz)
        if n > 0.0:
            reference[f, 0], reference[f, 1], reference[f, 2] = nx / n, ny / n, nz / n
        for i in range(3):
            v = faces[f, i]
            scale[v] = min(scale[v], shortest)
            if original[v]:
                continue
            size = max(abs(points[v, 0]), max(abs(points[v, 1]), abs(points[v, 2])))
            near = max(relative * shortest, absolute * size)
            for j in range(3):
                d = 0.0
                for c in range(3):
                    d += (points[v, c] - corner[j, c]) ** 2
                if np.sqrt(d) <= near:
                    original[v] = True
                    break
