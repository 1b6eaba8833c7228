"""Junctions that repeat: unioned once, the others placed by a rigid motion.

An L-system draws the same junction over and over: the 3D plant of the
union benchmark has 10,926 junction clusters at 8 generations and only 192
different ones.  A cluster (runs of tube pieces that touch each other, see
:mod:`lsys3d.mesh.union.union`) is compared with the others in its own frame: origin at
the centre of its first ring, axes from that ring's first two points.  Clusters
with the same triangles (the same faces on the same local points, ring after
ring) whose points, normals and ``u`` agree in that frame within a tight
tolerance (points: ``1e-7`` of the cluster's size and a hundredth of a float32
step at the tree's coordinates, finer than any file lsys3d writes can store),
and whose ``v`` differs by one constant per run, are congruent: only the first
of them goes through the boolean, and its result is moved onto the others.

On a copy, every vertex that is one of the cluster's own input points (all
that the boolean did not cut) gets that point's exact coordinates, so the
copies stitch onto their untouched tube pieces exactly; the new vertices on
the intersection curves are the representative's, moved (they differ from a boolean
of the copy itself by no more than the copy's points differ from the
representative's).  Shading moves along: normals are rotated, ``v`` shifted by the run's
offset, and face ids renumbered to the copy's own triangles.
"""

from __future__ import annotations

import numpy as np

from ...arrays import ROW_HASH_MIX, dot3, find_rows, first_equal_row, hash_word
from ...arrays import local_index as _local_counts
from ...arrays import offsets as _offsets
from ...compiling import kernel
from .booleans import Part

__all__ = ["Clusters", "find", "with_copies"]

_KEY = 1e-6  # relative size of the grid that buckets candidate clusters
_POINTS = 1e-7  # relative tolerance of congruent points (and 1/100 of a float32 step at the coordinates' size)
_CHECKED = 1 << 18  # triangles of candidates whose shading is compared at a time (about 200 bytes each)
_SHADING = 1e-5  # tolerance of congruent normals (unit) and u, and of the per-run v offset (texture tiles)


class Clusters:
    """The clusters of one local union, each a list of triangle ids and of input points.

    Attributes
    ----------
    tri, tri_off : triangle ids (tube faces, or ``nf + k`` for temporary cap ``k``) of every cluster, CSR
    point, point_off : the tube points its triangles use, ascending, CSR
    rep : (c,) int64
        The cluster whose boolean result this one reuses (itself for a representative).
    origin : (c, 3), frame : (c, 3, 3)
        Each cluster's frame: local coordinates are ``(x - origin) @ frame.T``.
    shift : v offset of every run of the cluster against its representative (CSR by ``run_off``)
    """

    def __init__(self, tri, tri_off, point, point_off, run_len, run_off, rep, origin, frame, shift):
        self.tri, self.tri_off = tri, tri_off
        self.point, self.point_off = point, point_off
        self.run_len, self.run_off = run_len, run_off
        self.rep, self.origin, self.frame, self.shift = rep, origin, frame, shift

    def __len__(self) -> int:
        return len(self.rep)


@kernel(nogil=True)
def _same_shading(wedge_normal, wedge_uv, wa, fa, wb, fb, run_of, first_tri, v_tolerance, offset):  # pragma: no cover
    """``(k,) bool``: the corners ``wa[i]`` in frame ``fa[i]`` are shaded as the corners ``wb[i]`` in frame ``fb[i]``.

    Normals (rotated into each frame) and ``u`` within ``_SHADING`` in every
    coordinate; ``v`` differs by one offset per run (``offset[i, run]``, written
    for every candidate: the difference at corner 0 of the run's first
    triangle ``first_tri[run]``; ``run_of[t]`` is the run of triangle ``t``)
    within ``v_tolerance``.  The rotated normals are ``np.einsum("gtcj,gkj->gtck",
    ...)``'s bits (it sums x, z, then y), the uv differences those of float64
    rows, computed a corner at a time: no (k, t, 3, ...) temporaries, and a
    candidate stops at its first difference.  NaN is a difference too, as in
    ``np.max``.
    """
    out = np.ones(len(wa), np.bool_)
    for i in range(len(wa)):
        for r in range(len(first_tri)):
            t = first_tri[r]
            offset[i, r] = np.float64(wedge_uv[wa[i, t, 0], 1]) - np.float64(wedge_uv[wb[i, t, 0], 1])
        for tt in range(wa.shape[1]):
            for c in range(3):
                ua, ub = wedge_uv[wa[i, tt, c]], wedge_uv[wb[i, tt, c]]
                if not abs(np.float64(ua[0]) - np.float64(ub[0])) <= _SHADING:
                    out[i] = False
                    break
                dv = np.float64(ua[1]) - np.float64(ub[1])
                if not abs(dv - offset[i, run_of[tt]]) <= v_tolerance:
                    out[i] = False
                    break
                na, nb = wedge_normal[wa[i, tt, c]], wedge_normal[wb[i, tt, c]]
                a0, a1, a2 = np.float64(na[0]), np.float64(na[1]), np.float64(na[2])
                b0, b1, b2 = np.float64(nb[0]), np.float64(nb[1]), np.float64(nb[2])
                for k in range(3):
                    x = dot3(a0, a1, a2, fa[i, k, 0], fa[i, k, 1], fa[i, k, 2])
                    y = dot3(b0, b1, b2, fb[i, k, 0], fb[i, k, 1], fb[i, k, 2])
                    if not abs(x - y) <= _SHADING:
                        out[i] = False
                        break
                if not out[i]:
                    break
            if not out[i]:
                break
    return out


@kernel(nogil=True)
def _member_keys(
    m, t, v, corners, tri_off, local_of_point, points, point, point_off, origin, frame, mix
):  # pragma: no cover - compiled
    """For the clusters ``m`` of one signature (``t`` triangles, ``v`` points each): their points in their own
    frames ``(g, v, 3)``, the largest coordinate of each, and the hash of each one's faces (on its own point
    numbers) and points bucketed on a grid of ``_KEY`` times that size.

    One pass without the (g, t, 3) and (g, v, 3) gathers; the numbers are those of the numpy version, in its
    order (``np.einsum``'s sums x, z, then y; ``np.round`` is ``rint``; :func:`~lsys3d.arrays.row_hash` of the
    faces' numbers then the buckets, a word at a time).
    """
    g = len(m)
    loc = np.empty((g, v, 3))
    size = np.empty(g)
    key = np.empty(g, np.uint64)
    for i in range(g):
        c = m[i]
        big = 0.0
        for p in range(v):
            q = point[point_off[c] + p]
            x, y, z = points[q, 0] - origin[c, 0], points[q, 1] - origin[c, 1], points[q, 2] - origin[c, 2]
            for k in range(3):
                loc[i, p, k] = dot3(x, y, z, frame[c, k, 0], frame[c, k, 1], frame[c, k, 2])
                big = max(big, abs(loc[i, p, k]))
        size[i] = big + 1e-300
        h = np.uint64(0)
        j = 0
        for f in range(tri_off[c], tri_off[c] + t):
            for k in range(3):
                h = hash_word(h, local_of_point[corners[f, k]], j, mix)
                j += 1
        cell = _KEY * size[i]
        for p in range(v):
            for k in range(3):
                h = hash_word(h, np.int64(np.rint(loc[i, p, k] / cell)), j, mix)
                j += 1
        key[i] = h
    return loc, size, key


@kernel(nogil=True)
def _cluster_points(corners, tri_off, npts):  # pragma: no cover - compiled
    """The points of every cluster (CSR, ascending), and each point's index among its cluster's.

    ``corners`` are the points of the clusters' triangles, cluster after
    cluster (``tri_off``).  Each cluster's few corners are sorted on their own:
    the order of one sort of all ``(cluster, point)`` keys, for a fraction of it.
    """
    point = np.empty(corners.size, np.int64)
    point_off = np.zeros(len(tri_off), np.int64)
    local_of_point = np.empty(npts, np.int64)
    n = 0
    for c in range(len(tri_off) - 1):
        mine = np.sort(corners[tri_off[c] : tri_off[c + 1]].ravel())
        for i in range(len(mine)):
            if i == 0 or mine[i] != mine[i - 1]:
                local_of_point[mine[i]] = n - point_off[c]
                point[n] = mine[i]
                n += 1
        point_off[c + 1] = n
    return point[:n].copy(), point_off, local_of_point


def find(
    tubes, runs: np.ndarray, n_runs_of: np.ndarray, tri_id, tri_off, faces_of, nf: int, shading: bool = True
) -> Clusters:
    """Describe the clusters and find the congruent ones.

    ``runs`` are the runs cluster after cluster, ``n_runs_of[c]`` of cluster
    ``c`` (ascending within it); run ``r``'s triangle ids are
    ``tri_id[tri_off[r]:tri_off[r + 1]]``; ``faces_of(ids)`` gives their
    wedge-indexed faces, ``faces_of(ids, points=True)`` their point-indexed ones.
    Without ``shading`` (a union that makes no corner normals and uv) the
    clusters need only be congruent: their normals and uv are not compared,
    and the v offsets are zero.
    """
    nc = len(n_runs_of)
    n_runs_of = np.asarray(n_runs_of, np.int64)
    run_off = _offsets(n_runs_of)
    run_len = (tri_off[runs + 1] - tri_off[runs]).astype(np.int64)
    tri = tri_id[np.repeat(tri_off[runs], run_len) + _local_counts(run_len)]
    per_cluster = np.add.reduceat(run_len, run_off[:-1]) if nc else np.zeros(0, np.int64)
    tri_off_c = _offsets(per_cluster)
    corners = faces_of(tri, points=True)  # (n, 3) points
    # the points of each cluster, ascending
    point, point_off, local_of_point = _cluster_points(corners, tri_off_c, len(tubes.points))
    n_points = np.diff(point_off)

    # every cluster's frame: centre of its first ring, the ring's first two points
    first = point[point_off[:-1]]
    s = tubes.sides[np.searchsorted(tubes.point_offsets, first, side="right") - 1]
    ring = point[np.repeat(point_off[:-1], s) + _local_counts(s)]
    origin = np.add.reduceat(tubes.points[ring], _offsets(s)[:-1], axis=0) / s[:, None]
    a = tubes.points[point[point_off[:-1]]] - origin
    b = tubes.points[point[point_off[:-1] + 1]] - origin
    e1 = a / np.linalg.norm(a, axis=1, keepdims=True)
    n = np.cross(a, b)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    frame = np.stack([e1, np.cross(n, e1), n], axis=1)  # rows: the local axes

    rep = np.arange(nc)
    shift = np.zeros(len(runs))
    # and never more than a hundredth of what float32 (the files' precision) can tell apart at these coordinates
    reach = max(float(tubes.points.max()), -float(tubes.points.min()))  # the largest |coordinate|, no abs() copy
    stored = 0.01 * float(np.spacing(np.float32(reach)))
    # candidates: same numbers of triangles, points and runs, and run sizes
    # (a row per cluster: the numbers, then the run sizes, -1 past its last run)
    sig = np.full((nc, 4 + int(n_runs_of.max(initial=0))), -1, np.int64)
    sig[:, :4] = np.stack([per_cluster, n_points, n_runs_of, s], axis=1)
    sig[np.repeat(np.arange(nc), n_runs_of), 4 + _local_counts(n_runs_of)] = run_len
    same_sig = first_equal_row(sig)
    by_sig = np.argsort(same_sig, kind="stable")  # each group's clusters together, ascending
    group_start = np.flatnonzero(np.diff(same_sig[by_sig], prepend=-1))
    group_size = np.diff(np.append(group_start, nc))
    wedge_uv = tubes.wedge_uv
    # v runs on along the whole plant (tiles, float32): where it is large, two float32 steps are the finest
    # difference the texture coordinates themselves can hold
    v_tolerance = max(_SHADING, 2.0 * float(np.spacing(np.abs(wedge_uv[:, 1]).max(initial=0.0)))) if shading else 0
    for first, size in zip(group_start[group_size > 1].tolist(), group_size[group_size > 1].tolist(), strict=True):
        m = by_sig[first : first + size]
        g, t, v = len(m), int(per_cluster[m[0]]), int(n_points[m[0]])
        tris = tri_off_c[m][:, None] + np.arange(t)  # (g, t) rows of `tri`
        # candidates: equal faces and bucketed points (a hash; the checks below confirm every match)
        loc, size, key = _member_keys(
            m, t, v, corners, tri_off_c, local_of_point, tubes.points, point, point_off, origin, frame, ROW_HASH_MIX
        )
        by_key = np.argsort(key, kind="stable")
        head = np.ones(g, bool)
        head[1:] = key[by_key][1:] != key[by_key][:-1]
        r = np.empty(g, np.int64)
        r[by_key] = by_key[np.flatnonzero(head)][np.cumsum(head) - 1]  # the first member with the same key
        cand = np.flatnonzero(r != np.arange(g))
        if not len(cand):
            continue
        rr = r[cand]
        ok = np.abs(loc[cand] - loc[rr]).max(axis=(1, 2)) <= np.minimum(_POINTS * size[rr], stored) + 1e-300
        # one v offset per run: the runs split the triangle list the same way in every member
        lens = run_len[run_off[m[0]] : run_off[m[0] + 1]]
        run_of = np.repeat(np.arange(len(lens)), lens)
        first_tri = _offsets(lens)[:-1]
        offset = np.zeros((len(cand), len(lens)))
        step = max(1, _CHECKED // t)  # the shading of a block of candidates and their representatives at a time
        for lo in range(0, len(cand) if shading else 0, step):
            block = slice(lo, lo + step)
            wa, wb = (faces_of(tri[tris[rows]].ravel()).reshape(len(rows), t, 3) for rows in (cand[block], rr[block]))
            fa, fb = frame[m[cand[block]]], frame[m[rr[block]]]
            ok[block] &= _same_shading(
                tubes.wedge_normal, wedge_uv, wa, fa, wb, fb, run_of, first_tri, v_tolerance, offset[block]
            )
            del wa, wb
        take = cand[ok]
        rep[m[take]] = m[r[take]]
        shift[run_off[m[take]][:, None] + np.arange(len(lens))] = offset[ok]  # every member has len(lens) runs
    return Clusters(tri, tri_off_c, point, point_off, run_len, run_off, rep, origin, frame, shift)


def with_copies(cl: Clusters, tubes, out: Part, nf: int, n_caps: int) -> Part:
    """The representatives' boolean results (``out``, face ids as given to the boolean) and their copies, as one Part.

    ``out`` first, then for every representative that has copies all its
    copies side by side, with their own face ids: the arrays ``parts._concat``
    makes of ``out`` and one part per representative, written in place (no
    per-copy temporaries and no second copy of the whole).
    """
    nc = len(cl)
    members = np.flatnonzero(cl.rep != np.arange(nc))
    if not len(members):
        return out
    cluster_of_id = np.full(nf + n_caps, -1, np.int64)
    pos_of_id = np.zeros(nf + n_caps, np.int64)
    per = np.diff(cl.tri_off)
    cluster_of_id[cl.tri] = np.repeat(np.arange(nc), per)
    pos_of_id[cl.tri] = _local_counts(per)
    out_cluster = cluster_of_id[out.face_id]
    order = np.argsort(cl.rep[members], kind="stable")
    members = members[order]
    reps, starts = np.unique(cl.rep[members], return_index=True)
    bounds = np.append(starts, len(members))
    tri_order = np.argsort(out_cluster, kind="stable")
    tri_bounds = np.searchsorted(out_cluster[tri_order], np.concatenate([reps, reps + 1]))
    # every output vertex belongs to one cluster (the roots are disjoint): group vertices and merge pairs by it
    vert_cluster = np.full(len(out.props), -1, np.int64)
    vert_cluster[out.tri.ravel()] = np.repeat(out_cluster, 3)
    vert_order = np.argsort(vert_cluster, kind="stable")
    vert_bounds = np.searchsorted(vert_cluster[vert_order], np.concatenate([reps, reps + 1]))
    merge_cluster = vert_cluster[out.merge_from]
    merge_order = np.argsort(merge_cluster, kind="stable")
    merge_bounds = np.searchsorted(merge_cluster[merge_order], np.concatenate([reps, reps + 1]))
    # what each representative's copies need, and where they go
    plans = []
    sizes = np.zeros((len(reps) + 1, 3), np.int64)  # vertices, triangles, merge pairs
    sizes[0] = len(out.props), len(out.tri), len(out.merge_from)
    for i, r in enumerate(reps.tolist()):
        mine = members[bounds[i] : bounds[i + 1]]
        sel = tri_order[tri_bounds[i] : tri_bounds[len(reps) + i]]  # the representative's output triangles
        used = vert_order[vert_bounds[i] : vert_bounds[len(reps) + i]]  # ascending: the sort was stable
        tri = np.searchsorted(used, out.tri[sel])
        msel = merge_order[merge_bounds[i] : merge_bounds[len(reps) + i]]
        merge = np.stack([np.searchsorted(used, out.merge_from[msel]), np.searchsorted(used, out.merge_to[msel])])
        plans.append((r, mine, sel, used, tri, merge))
        sizes[i + 1] = len(mine) * len(used), len(mine) * len(tri), len(mine) * merge.shape[1]
    off = np.concatenate([np.zeros((1, 3), np.int64), np.cumsum(sizes, axis=0)])
    joined = Part(
        np.empty((off[-1, 0], out.props.shape[1])),
        np.empty((off[-1, 1], 3), np.int64),
        np.empty(off[-1, 2], np.int64),
        np.empty(off[-1, 2], np.int64),
        np.empty(off[-1, 1], np.int64),
    )
    joined.props[: len(out.props)] = out.props
    joined.tri[: len(out.tri)] = out.tri
    joined.merge_from[: len(out.merge_from)] = out.merge_from
    joined.merge_to[: len(out.merge_to)] = out.merge_to
    joined.face_id[: len(out.face_id)] = out.face_id
    for i, (r, mine, sel, used, tri, merge) in enumerate(plans):
        props = out.props[used]
        # the representative's own input points among the output vertices (exact positions)
        rp = cl.point[cl.point_off[r] : cl.point_off[r + 1]]
        j = find_rows(tubes.points[rp], props[:, :3])
        # the run of each output vertex (for its v offset): from the first triangle using it
        pos = pos_of_id[out.face_id[sel]]
        run_bounds = np.cumsum(cl.run_len[cl.run_off[r] : cl.run_off[r + 1]])
        run_of_tri = np.searchsorted(run_bounds, pos, side="right")
        vertex_run = np.zeros(len(used), np.int64)
        vertex_run[tri[::-1].ravel()] = np.repeat(run_of_tri[::-1], 3)
        # into every copy's frame
        loc = (props[:, :3] - cl.origin[r]) @ cl.frame[r].T
        nrm = props[:, 3:6] @ cl.frame[r].T if props.shape[1] > 3 else loc[:, :0]  # (shading: see _place)
        shift = cl.shift[cl.run_off[mine][:, None] + np.arange(len(run_bounds))]  # (g, runs)
        v0, t0, m0 = off[i + 1]
        _place(
            joined.props[v0 : off[i + 2, 0]],
            (loc, nrm, props, j, vertex_run),
            (cl.frame[mine], cl.origin[mine], cl.point_off[mine], shift),
            cl.point,
            tubes.points,
        )
        g, nv = len(mine), len(used)
        step = (v0 + np.arange(g) * nv)[:, None]
        np.add(tri[None, :, :], step[:, :, None], out=joined.tri[t0 : off[i + 2, 1]].reshape(g, len(tri), 3))
        nm = merge.shape[1]
        np.add(merge[0][None, :], step, out=joined.merge_from[m0 : off[i + 2, 2]].reshape(g, nm))
        np.add(merge[1][None, :], step, out=joined.merge_to[m0 : off[i + 2, 2]].reshape(g, nm))
        _copy_ids(joined.face_id[t0 : off[i + 2, 1]], cl.tri, cl.tri_off[mine], pos)  # their own ids
    return joined


@kernel(nogil=True)
def _copy_ids(out, tri, first, pos):  # pragma: no cover - compiled
    """``out[g * len(pos) + k] = tri[first[g] + pos[k]]``: each copy's own face ids, copy after copy."""
    t = len(pos)
    for g in range(len(first)):
        for k in range(t):
            out[g * t + k] = tri[first[g] + pos[k]]


@kernel(nogil=True)
def _place(new, rep, copy, cluster_point, points):  # pragma: no cover - compiled
    """Write the properties of ``g`` copies of one representative's output vertices, copy after copy, into ``new``.

    ``rep``: the vertices in the representative's frame (positions ``loc``,
    normals ``nrm``), its properties, the index ``j`` among its own points
    (or -1) and run of every vertex; ``copy``: each copy's frame, origin,
    first point in ``cluster_point`` and v offset per run.  Positions and
    normals are ``np.einsum("vk,gkj->gvj", ...)``'s bits (it adds x, y, then z
    onto 0.0), positions plus the origin; a vertex that is one of the
    cluster's input points takes the copy's point exactly; ``v`` is shifted
    by its run's offset.  Properties of positions alone (a union without
    corners) get positions alone.
    """
    loc, nrm, props, j, vertex_run = rep
    frame, origin, point_off, shift = copy
    nv = len(loc)
    shading = new.shape[1] > 3
    for g in range(len(frame)):
        for v in range(nv):
            row = g * nv + v
            for c in range(3):
                x = ((0.0 + loc[v, 0] * frame[g, 0, c]) + loc[v, 1] * frame[g, 1, c]) + loc[v, 2] * frame[g, 2, c]
                new[row, c] = x + origin[g, c]
                if shading:
                    n = ((0.0 + nrm[v, 0] * frame[g, 0, c]) + nrm[v, 1] * frame[g, 1, c]) + nrm[v, 2] * frame[g, 2, c]
                    new[row, 3 + c] = n
            if j[v] >= 0:
                p = cluster_point[point_off[g] + j[v]]
                for c in range(3):
                    new[row, c] = points[p, c]
            if shading:
                new[row, 6] = props[v, 6]
                new[row, 7] = props[v, 7] + shift[g, vertex_run[v]]
