"""Fairing the collars (:func:`fair`): Laplacian steps toward the neighbours' mean along the normal, the
volume given back (:func:`settle`)."""

from __future__ import annotations

import math

import numpy as np

from ...compiling import inner, kernel
from .collar import _faces_turned, _fan_volume, _find, _vertex_normal
from .geometry import _cross, _normal
from .halfedge import FEATURE, LOCKED, _dst, _inline_inner_once, _leaf_inner, _prv, _valence, in_two

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
    pool's (:func:`in_two`; the same bits).  Returns the vertices moved.
    """
    members, slot, around = _fair_setup(he, closeness)
    na, m = len(around), len(members)
    pool = pool if m >= _FAIR_SHARE_MIN else None
    first = np.zeros(na + 1, np.int64)  # the neighbours of the collar and its neighbours, as CSR lists
    in_two(pool, _valences, (he, around, first[1:]), 0, na // 2, na)
    first = np.cumsum(first)
    nbr = np.empty(first[na], np.int64)
    in_two(pool, _neighbours, (he.faces, he.out, he.opp, around, first, nbr), 0, na // 2, na)
    p = he.points
    start = p[members]  # where the collar was
    # each vertex moves along its normal before the fairing (the moves are a fraction of a side; recomputing
    # it every step cost 60% of the fairing)
    normal = np.empty((m, 3))
    in_two(pool, _vertex_normals, (he, members, normal), 0, m // 2, m)
    lap = np.zeros((na, 3))
    target = np.zeros((m, 3))
    moving = (p, he.scale, members, slot, first, nbr, lap, normal, start, step, reach, inward, target)
    for _ in range(iterations):
        in_two(pool, _laplacians, (p, around, first, nbr, lap), 0, na // 2, na)
        in_two(pool, _fair_targets, moving, 0, m // 2, m)
        p[members] = target
    return _fair_finish(he, closeness, members, start)


@kernel(nogil=True)
def _fair_setup(he, closeness):
    """:func:`fair`'s collar vertices, their slots among them and their neighbours, and those (``around``)."""
    faces = he.faces
    nv = he.counts[0]
    chosen = np.empty(nv, np.int64)
    m = 0
    for v in range(nv):
        if closeness[v] > 0.0 and he.vertex_alive[v] and he.out[v] >= 0 and not (he.flags[v] & (LOCKED | FEATURE)):
            chosen[m] = v
            m += 1
    members = chosen[:m]
    # the collar and its neighbours (where the Laplacian is needed)
    slot = np.empty(nv, np.int64)
    slot[:] = -1
    around = np.empty(nv, np.int64)
    na = 0
    for v in members:
        if slot[v] < 0:
            slot[v] = na
            around[na] = v
            na += 1
        h0 = np.int64(he.out[v])
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


@kernel(nogil=True)
def _valences(he, around, count, lo, hi):
    """``count[lo:hi]``: how many neighbours ``around[lo:hi]`` have."""
    for i in range(lo, hi):
        count[i] = _valence(he, around[i])


@kernel(nogil=True)
def _neighbours(faces, out, opp, around, first, nbr, lo, hi):
    """The neighbours of ``around[lo:hi]`` into ``nbr[first[i]:first[i + 1]]`` (``faces``, ``out``, ``opp``: the
    half-edges')."""
    for i in range(lo, hi):
        g = np.int64(out[around[i]])
        for k in range(first[i], first[i + 1]):
            nbr[k] = _dst(faces, g)
            g = opp[_prv(g)]


@kernel(nogil=True)
def _vertex_normals(he, members, normal, lo, hi):
    """``normal[lo:hi]``: the normals of ``members[lo:hi]`` (:func:`_vertex_normal`)."""
    for i in range(lo, hi):
        normal[i, 0], normal[i, 1], normal[i, 2] = _vertex_normal(he, members[i])


@kernel(nogil=True)
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


@kernel(nogil=True)
def _fair_targets(p, scale, members, slot, first, nbr, lap, normal, start, step, reach, inward, target, lo, hi):
    """One Jacobi step of :func:`fair`, second pass: where ``members[lo:hi]`` move (into ``target``; ``p`` and
    ``scale``: the half-edges' points and scale)."""
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
        far = math.sqrt(ox * ox + oy * oy + oz * oz)
        limit = reach * scale[v]
        if far > limit:
            tx, ty, tz = (
                start[i, 0] + ox * limit / far,
                start[i, 1] + oy * limit / far,
                start[i, 2] + oz * limit / far,
            )
        target[i, 0], target[i, 1], target[i, 2] = tx, ty, tz


@kernel(nogil=True)
def _fair_finish(he, closeness, members, start):
    """:func:`fair`'s end: a vertex with a face turned away goes back, the collars give their volume back;
    the vertices moved."""
    faces, p = he.faces, he.points
    m = len(members)
    # a vertex with a face turned away from its surface goes back, until none is left: rounds in the members'
    # order, each seeing the reverts before it; a vertex is looked at again only once a neighbour went back
    # since it was last looked at (else it would go back no more than then: the same rounds, a fraction of the work)
    dirty = np.empty(m, np.bool_)
    for i in range(m):
        dirty[i] = True
    for _ in range(10):
        reverted = 0
        for i in range(m):
            if not dirty[i]:
                continue
            dirty[i] = False
            v = members[i]
            if p[v, 0] == start[i, 0] and p[v, 1] == start[i, 1] and p[v, 2] == start[i, 2]:
                continue
            h0 = np.int64(he.out[v])
            g = h0
            while True:
                f = g // 3
                qx, qy, qz = _normal(p, faces[f, 0], faces[f, 1], faces[f, 2])
                r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
                if qx * r0 + qy * r1 + qz * r2 <= 0.17 * math.sqrt(qx * qx + qy * qy + qz * qz):
                    p[v, 0], p[v, 1], p[v, 2] = start[i, 0], start[i, 1], start[i, 2]
                    reverted += 1
                    g = h0
                    while True:  # its neighbours among the members (ascending) are to be looked at again
                        w = _dst(faces, g)
                        # w's place among the members: np.searchsorted's generic search costs numba a second to
                        # compile, and arrays.search_left is not remesh's (the first run's helper compiles only
                        # lsys3d.mesh.remesh's kernels: precompile.OWN), so the same few lines as search_left
                        lo, hi = 0, m
                        while lo < hi:
                            mid = (lo + hi) >> 1
                            if members[mid] < w:
                                lo = mid + 1
                            else:
                                hi = mid
                        if lo < m and members[lo] == w:
                            dirty[lo] = True
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


@inner(nogil=True)
def _at(p, start, slot, m, v):
    """Where vertex ``v`` was before the fairing: ``start`` for a collar vertex, else where it is."""
    j = slot[v]
    if 0 <= j < m:
        return start[j, 0], start[j, 1], start[j, 2]
    return p[v, 0], p[v, 1], p[v, 2]


@_leaf_inner
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


@_inline_inner_once
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
    slot = np.empty(he.counts[0], np.int64)
    slot[:] = -1
    for i in range(m):
        slot[members[i]] = i
    parent = np.empty(m, np.int64)
    for i in range(m):
        parent[i] = i
    for i in range(m):
        h0 = np.int64(he.out[members[i]])
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
    gained = np.empty(m)
    gained[:] = 0.0
    slope = np.empty(m)
    slope[:] = 0.0
    lam = np.empty(m)
    lam[:] = 0.0
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


@kernel(nogil=True)
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
        q = math.sqrt(qx * qx + qy * qy + qz * qz)
        r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
        if q <= 0.0 or qx * r0 + qy * r1 + qz * r2 <= 0.17 * q:
            continue
        # halfway between the tube's and the faired face's: the later operations may turn a face at most 80
        # degrees from that, so a collar face still never turns over against its tube
        hx, hy, hz = r0 + qx / q, r1 + qy / q, r2 + qz / q
        h = math.sqrt(hx * hx + hy * hy + hz * hz)
        he.reference[f, 0], he.reference[f, 1], he.reference[f, 2] = hx / h, hy / h, hz / h
        n += 1
    return n
