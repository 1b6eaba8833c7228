"""The cleaning driver (:func:`clean`): faces that need work, snapped, split, flipped or collapsed by the
:class:`Rules`, and the mesh cut in halves that two threads clean apart (:func:`halves`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...compiling import kernel
from .collapse import _rank, _try_collapse
from .flip import _flip, _flip_ok
from .geometry import _aspect, _aspect_xyz, _cross, _length, _moved_corners, _normal, _normal_xyz
from .halfedge import (
    _MAX_RING,
    FEATURE,
    LOCKED,
    ORIGINAL,
    PINNED,
    SEAM,
    HalfEdges,
    _apex,
    _dst,
    _half_edge,
    _inline_inner_once,
    _leaf_inner,
    _org,
    _prv,
    _valence,
)
from .split import _inherit, _split_edge

_MAX_SPAWN = 8  # splits one seam vertex's fan may make


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


@_leaf_inner
def _needs_work(he, f, rules):
    faces, p = he.faces, he.points
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    s = min(he.scale[a], min(he.scale[b], he.scale[c]))
    short = rules.short * s
    if _length(p, a, b) < short or _length(p, b, c) < short or _length(p, c, a) < short:
        return True
    return _aspect(p, a, b, c) > rules.bad


@_inline_inner_once
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


@_leaf_inner
def _snap(he, f, k, rules):
    """A cap: move its far corner ``x`` onto its edge ``k`` (``u w``) and give the face across the edge to it.

    Topologically an edge flip of ``u w`` (``x`` joins the vertex ``d`` across
    it), then ``x`` moves to its foot on ``u w``: the cap vanishes and the face
    across splits in two halves of itself, so only the faces around ``x``
    change shape, by at most the cap's height (under ``short`` scales).
    ``x`` takes the rank of the edge it now lies on (a tube edge, a rim, the
    seam).  Where ``x`` stands over an end of the edge (its foot in the
    outer tenths), it merges into that end instead: then ``-2 - h`` for the
    caller to collapse half-edge ``h`` (:func:`_try_collapse`, not linked
    into this helper's own code: a first run compiles it once less).
    Returns ``x``, or -1 when not allowed.
    """
    faces, p, flags = he.faces, he.points, he.flags
    g = 3 * f + k
    t = np.int64(he.opp[g])
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
        return -2 - h
    # a short move, or one along the faces around x (in their planes: the surface does not change)
    if math.sqrt(dx * dx + dy * dy + dz * dz) >= rules.short * s:
        h0 = he.out[x]
        h = h0
        while True:
            ff = h // 3
            if ff != f:
                nx, ny, nz = _normal(p, faces[ff, 0], faces[ff, 1], faces[ff, 2])
                nn = math.sqrt(nx * nx + ny * ny + nz * nz)
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
            corners = _moved_corners(p, f0, f1, f2, x, fx, fy, fz)
            qx, qy, qz = _normal_xyz(*corners)
            r0, r1, r2 = he.reference[ff, 0], he.reference[ff, 1], he.reference[ff, 2]
            if qx * r0 + qy * r1 + qz * r2 <= 0.17 * math.sqrt(qx * qx + qy * qy + qz * qz):
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


@_inline_inner_once
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
        return _split_edge(he, 3 * f + k, t if su else 1.0 - t)
    return -1


@kernel(nogil=True)
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
    queued = np.empty(fcap, np.bool_)
    queued[:] = False
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
    done = np.empty(5, np.int64)  # collapses, flips, snaps, fan splits, fallback collapses
    done[:] = 0
    rounds = 0 if everywhere else 3  # a second cleaning of a region does not look everywhere again
    while top > 0 and done[0] + done[1] + done[2] + done[3] + done[4] < rules.max_operations:
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
                touched = _snap(he, f, order[2], rules)
                if touched <= -2:  # x merges into an end of the edge
                    touched = _try_collapse(he, -2 - touched, rules.limit, rules.short, buf_a, buf_b)
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


@kernel(nogil=True)
def _sides(he, axis, cut, width, side, band, near):
    """:func:`halves`' passes: each face's side, the vertices with faces on both, ``width + 1`` rings more."""
    faces, p = he.faces, he.points
    nv, nf = he.counts[0], he.counts[1]
    reach = np.empty(nv, np.int64)  # bit s: the vertex has a face of side s
    reach[:] = 0
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
    dist = np.empty(nv, np.int64)
    dist[:] = far
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


@_leaf_inner
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
            area += math.sqrt(nx * nx + ny * ny + nz * nz)
            if f == h // 3 or f == t // 3:
                if end == 0:  # the two dying faces
                    change -= p[v, 0] * cx + p[v, 1] * cy + p[v, 2] * cz
            else:
                change += (x - p[v, 0]) * cx + (y - p[v, 1]) * cy + (z - p[v, 2]) * cz
            g = he.opp[_prv(g)]
            if g == h0:
                break
    return 3.0 * abs(change) / max(area, 1e-300)
