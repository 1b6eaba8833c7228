"""Edge split: a vertex on an edge and two faces, attributes inherited."""

from __future__ import annotations

import numpy as np

from ...compiling import inner
from .halfedge import FEATURE, PINNED, _apex, _dst, _leaf_inner, _nxt, _org, _prv


@inner(nogil=True)
def _inherit(he, f, g):
    """Face ``f`` takes what face ``g`` knows of the tube face it lies on: part, flatness, source, reference normal
    (the normal element by element: a row copy would allocate, and the helpers run without numba's runtime)."""
    he.face_part[f] = he.face_part[g]
    he.face_flat[f] = he.face_flat[g]
    he.face_source[f] = he.face_source[g]
    for j in range(3):
        he.reference[f, j] = he.reference[g, j]


@_leaf_inner
def _split_edge(he, h, t):
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
    o = np.int64(opp[h])
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
