"""Junction collars (:func:`collar`): how close each vertex is to a seam, the reach the fairing may move it."""

from __future__ import annotations

import math

import numpy as np

from ...compiling import kernel
from .geometry import _cross, _length, _normal
from .halfedge import SEAM, _dst, _leaf_inner, _prv


@kernel(nogil=True)
def collar(he, width, closeness):
    """How close each vertex is to a seam, in ``closeness`` (1 on the seam, 0 at ``width`` scales or beyond).

    The distance is measured along edges from the nearest seam vertex, in that
    seam vertex's own scale (the side of the thinner tube at the seam), so a
    twig's collar is as narrow as the twig.  Returns the number of vertices in
    a collar.
    """
    faces, p = he.faces, he.points
    nv = he.counts[0]
    reach = np.empty(nv)  # metres still to go from the best seam vertex
    reach[:] = 0.0
    span = np.empty(nv)  # that seam vertex's collar width in metres
    span[:] = 0.0
    # the vertices whose reach grew, to go on from (each in the queue at most once): a worklist from the seams
    # instead of sweeps over every face until none changes (a fraction of the work; the same answer but where
    # two paths tie within the 1e-12 below: the first found wins)
    queue = np.empty(max(nv, 1), np.int64)
    queued = np.empty(nv, np.bool_)
    queued[:] = False
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
        h0 = np.int64(he.out[u])
        g = h0
        while True:
            w = _dst(faces, g)
            left = reach[u] - _length(p, np.int32(u), w)  # (int32, as elsewhere: compiled once)
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


@_leaf_inner
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
    n = math.sqrt(nx * nx + ny * ny + nz * nz)
    if n <= 0.0:
        return 0.0, 0.0, 0.0
    return nx / n, ny / n, nz / n


@_leaf_inner
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


@_leaf_inner
def _faces_turned(he, v):
    """Whether a face around ``v`` is turned more than 80 degrees from its reference normal."""
    faces, p = he.faces, he.points
    h0 = he.out[v]
    g = h0
    while True:
        f = g // 3
        qx, qy, qz = _normal(p, faces[f, 0], faces[f, 1], faces[f, 2])
        r0, r1, r2 = he.reference[f, 0], he.reference[f, 1], he.reference[f, 2]
        if qx * r0 + qy * r1 + qz * r2 <= 0.17 * math.sqrt(qx * qx + qy * qy + qz * qz):
            return True
        g = he.opp[_prv(g)]
        if g == h0:
            return False


@_leaf_inner
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i
