"""The last pass (:func:`rescue`): any collapse or flip that removes a face still worse than an aspect, or lower
than a height, keeping the volume."""

from __future__ import annotations

import math

import numpy as np

from ...compiling import kernel
from .clean import _collapse_volume
from .collapse import _collapse, _collapse_geometry_ok, _collapse_ok, _collapse_topology_ok
from .flip import _flip, _flip_ok
from .geometry import _aspect, _cross, _length, _normal
from .halfedge import _MAX_RING, FEATURE, LOCKED, SEAM, _apex, _dst, _leaf_inner, _org, _prv, _valence, in_two
from .split import _split_edge


@_leaf_inner
def _flip_volume(he, h):
    """How far flipping the edge of half-edge ``h`` moves the surface, on average (see :func:`_collapse_volume`)."""
    faces, p = he.faces, he.points
    a, b, c, d = _org(faces, h), _dst(faces, h), _apex(faces, h), _apex(faces, np.int64(he.opp[h]))
    ex, ey, ez = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    cx, cy, cz = _cross(
        p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2], p[d, 0] - p[a, 0], p[d, 1] - p[a, 1], p[d, 2] - p[a, 2]
    )
    n0x, n0y, n0z = _normal(p, a, b, c)
    n1x, n1y, n1z = _normal(p, b, a, d)
    area = math.sqrt(n0x * n0x + n0y * n0y + n0z * n0z) + math.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
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
    in_two(pool, _needs_rescue, (he, worst, height, now), 0, nf // 2, nf)
    return _rescue(he, worst, height, flip, now) if now.any() else 0


@kernel(nogil=True)
def _needs_rescue(he, worst, height, now, lo, hi):
    """Into ``now[lo:hi]``: whether :func:`rescue` has anything to do on each face (as it looks at it)."""
    faces, p = he.faces, he.points
    for f in range(lo, hi):
        if not he.face_alive[f]:
            continue
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        weld = _weldable(he, a, b) or _weldable(he, b, c) or _weldable(he, c, a)
        now[f] = weld or not _aspect(p, a, b, c) <= worst or _low(p, a, b, c, height)


@_leaf_inner
def _weldable(he, u, w):
    """Whether edge ``u w`` is so short that readers would weld its ends (float32, trimesh's 1e-8 grid), and
    neither end is locked."""
    p = he.points
    weld = 1e-8 + 1e-6 * max(abs(p[w, 0]), max(abs(p[w, 1]), abs(p[w, 2])))
    return _length(p, u, w) < weld and not ((he.flags[u] | he.flags[w]) & LOCKED)


@_leaf_inner
def _low(p, a, b, c, height):
    """Whether triangle ``a b c`` is lower than ``height`` (twice its area over its longest edge)."""
    nx, ny, nz = _normal(p, a, b, c)
    longest = max(_length(p, a, b), max(_length(p, b, c), _length(p, c, a)))
    return math.sqrt(nx * nx + ny * ny + nz * nz) < height * longest


@kernel(nogil=True)
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
    again = np.empty(len(faces), np.bool_)  # and the next
    again[:] = False
    seen = np.empty(len(p) + 1, np.int64)  # per vertex, the last walk that reached it; the walks' count last
    seen[:] = 0
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
                if not _collapse_topology_ok(he, g, buf_a, buf_b):
                    continue
                w = _dst(faces, g)
                if _collapse_geometry_ok(he, g, p[w, 0], p[w, 1], p[w, 2], allowed) and (
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
                        if _collapse_geometry_ok(he, g, x, y, z, allowed) and (
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
                    v = _split_edge(he, g, 0.5)
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


@_leaf_inner
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
