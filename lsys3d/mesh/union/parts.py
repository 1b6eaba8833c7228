"""Parts: the pieces of tube faces the boolean is given or kept out of it (:class:`~lsys3d.mesh.union.booleans.Part`),
the tubes' faces picked by piece, temporary caps, corner attributes, and parts joined and welded into one
:class:`~lsys3d.mesh.mesh.Mesh`; whether faces close up."""

from __future__ import annotations

import numpy as np

from ...arrays import offsets as _offsets
from ...arrays import search_left, sort_between
from ...compiling import kernel
from ...errors import GeometryError
from ..mesh import Mesh
from ..sweep import Tubes
from .booleans import Part

_NUM_PROP = 8  # x y z, nx ny nz, u v
_NO_MAP = np.zeros(0, np.int64)


def _no_corners(n: int, *shape: int) -> np.ndarray:
    """``(n, *shape)`` float32 zeros taking no memory: the corner attributes of ``union(..., corners=False)``."""
    return np.broadcast_to(np.zeros(shape, np.float32), (n, *shape))


def _corner_rows(values: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``values[keep]``; corner attributes not made (:func:`_no_corners`) stay not made."""
    if values.strides[0] == 0:
        return _no_corners(int(np.count_nonzero(keep)) if keep.dtype == bool else len(keep), *values.shape[1:])
    return values[keep]


@kernel(nogil=True)
def _faces_of(ids, nf, tube_faces, cap_faces, through):  # pragma: no cover - compiled
    """``(k, 3)`` wedge-indexed faces of the triangle ids ``ids``: tube face ``i < nf``, temporary cap ``i - nf``;
    mapped ``through`` an array (the wedges' points) unless it is empty."""
    out = np.empty((len(ids), 3), np.int64)
    mapped = len(through) > 0
    for i in range(len(ids)):
        k = ids[i]
        for c in range(3):
            w = tube_faces[k, c] if k < nf else cap_faces[k - nf, c]
            out[i, c] = through[w] if mapped else w
    return out


@kernel(nogil=True)
def _face_pieces(face_offsets, sides, nspan, span_offsets, span_piece):  # pragma: no cover - compiled
    """``(f,)``: the piece of every tube face: a wall face's span's, a base cap's first span's, a tip cap's last.

    A tube's faces are its walls, two triangles per side and span, span after span, then its base cap's
    ``sides`` triangles, then its tip cap's.
    """
    out = np.empty(face_offsets[-1], np.int64)
    for t in range(len(sides)):
        s2 = 2 * sides[t]
        body = s2 * nspan[t]
        for f in range(face_offsets[t], face_offsets[t + 1]):
            lf = f - face_offsets[t]
            if lf < body:
                span = lf // s2
            elif lf < body + s2 // 2:
                span = 0
            else:
                span = nspan[t] - 1
            out[f] = span_piece[span_offsets[t] + span]
    return out


@kernel(nogil=True)
def _cap_points(tri, fid, nf, point_of, pos, cap_faces, wedge_point, points, seam_of):  # pragma: no cover
    """Into ``seam_of`` (per tube point): the point (of ``point_of[tri]``, at ``pos``) each corner of the temporary
    cap triangles ``fid >= nf`` came back as, the triangle's corners matched by their exact positions in one of
    its three rotations; False when a cap triangle matches in none or a ring point came back as two points."""
    out = np.empty(3, np.int64)
    ring = np.empty(3, np.int64)
    for t in range(len(fid)):
        q = fid[t] - nf
        if q < 0:
            continue
        for k in range(3):
            out[k] = point_of[tri[t, k]]
            ring[k] = wedge_point[cap_faces[q, k]]
        turn = -1
        for r in range(3):
            same = True
            for k in range(3):
                o, p = out[(k + r) % 3], ring[k]
                same = same and pos[o, 0] == points[p, 0] and pos[o, 1] == points[p, 1] and pos[o, 2] == points[p, 2]
            if same:
                turn = r
                break
        if turn < 0:
            return False
        for k in range(3):
            o, p = out[(k + turn) % 3], ring[k]
            if seam_of[p] < 0:
                seam_of[p] = o
            elif seam_of[p] != o:
                return False
    return True


@kernel(nogil=True)
def _free_points(ff, tube_faces, wedge_point, used):  # pragma: no cover - compiled
    """Mark in ``used`` the points of the tube faces ``ff`` (no (k, 3) gathers of their wedges and points)."""
    for f in ff:
        for c in range(3):
            used[wedge_point[tube_faces[f, c]]] = True


@kernel(nogil=True)
def _free_faces(ff, tube_faces, wedge_point, new_index, out):  # pragma: no cover - compiled
    """Write the tube faces ``ff`` on the stitched mesh's points (``new_index`` of each tube point) into ``out``."""
    for i in range(len(ff)):
        for c in range(3):
            out[i, c] = new_index[wedge_point[tube_faces[ff[i], c]]]


@kernel(nogil=True)
def _kept_faces(point_of, tri, keep, faces):  # pragma: no cover - compiled
    """Write ``point_of[tri[keep]]`` into the first rows of ``faces``, in one pass without the (f, 3) gather."""
    f = 0
    for t in range(len(tri)):
        if keep[t]:
            for c in range(3):
                faces[f, c] = point_of[tri[t, c]]
            f += 1


@kernel(nogil=True)
def _corner_attributes(props, tri, keep, normals, uv):  # pragma: no cover - compiled
    """Write the unit corner normals and the uv of the triangles ``tri[keep]`` from manifold's ``props`` into the
    first rows.

    :func:`_unit_rows` of ``props[tri[keep], 3:6]`` and ``props[tri[keep], 6:]``, as float32, in one pass without
    the (f, 3) and (f, 3, 8) gathers: the same bits (the norm sums x, y, z as ``np.linalg.norm`` does).
    """
    f = -1
    for t in range(len(tri)):
        if not keep[t]:
            continue
        f += 1
        for c in range(3):
            r = tri[t, c]
            x, y, z = props[r, 3], props[r, 4], props[r, 5]
            length = np.sqrt(x * x + y * y + z * z)
            if not length > 1e-12:
                length = 1.0
            normals[f, c, 0] = np.float32(x / length)
            normals[f, c, 1] = np.float32(y / length)
            normals[f, c, 2] = np.float32(z / length)
            uv[f, c, 0] = np.float32(props[r, 6])
            uv[f, c, 1] = np.float32(props[r, 7])


def _part(tubes: Tubes, tri: np.ndarray, tri_id: np.ndarray, shading: bool = True) -> Part:
    """The wedge-indexed triangles ``tri`` of ``tubes`` as one manifold3d mesh, ``tri_id`` as face ids.

    With ``shading`` the normals and uv ride along as properties (a vertex
    per wedge, tied to its point by merge vectors); without, the points alone
    (the boolean's work is a sixth smaller: for a caller that makes its own
    normals and uv, the cleanup).
    """
    if not shading:
        points, tri = _used(len(tubes.points), tubes.wedge_point[tri])
        none = np.zeros(0, np.int64)
        return Part(tubes.points[points], tri, none, none, np.asarray(tri_id, np.int64))
    wedges, tri = _used(len(tubes.wedge_point), tri)
    w = len(wedges)
    wp = tubes.wedge_point[wedges]
    props = np.empty((w, _NUM_PROP), np.float64)  # float64: float32 would weld nearby vertices into slivers
    props[:, :3] = tubes.points[wp]
    props[:, 3:6] = tubes.wedge_normal[wedges]
    props[:, 6:] = tubes.wedge_uv[wedges]
    rep = np.empty(len(tubes.points), np.int64)
    rep[wp] = np.arange(w)
    merge_to = rep[wp]
    merge_from = np.flatnonzero(merge_to != np.arange(w))
    return Part(props, tri, merge_from, merge_to[merge_from], np.asarray(tri_id, np.int64))


def _used(n: int, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The items (of ``n``) that the triangles ``tri`` use, ascending, and ``tri`` renumbered onto them."""
    used = np.zeros(n, bool)
    used[tri] = True
    kept = np.flatnonzero(used)
    del used
    remap = np.empty(n, np.int64)
    remap[kept] = np.arange(len(kept))
    return kept, remap[tri]


def _concat(parts: list[Part]) -> Part:
    """Meshes side by side as one :class:`Part` (indices shifted).

    The list is emptied as its meshes are copied, so that at most one of them
    exists twice at any time.
    """
    if len(parts) == 1:
        return parts.pop()
    nv = np.array([len(p.props) for p in parts])
    nt = np.array([len(p.tri) for p in parts])
    nm = np.array([len(p.merge_from) for p in parts])
    v_off, t_off, m_off = _offsets(nv), _offsets(nt), _offsets(nm)
    out = Part(
        np.empty((v_off[-1], parts[0].props.shape[1])),
        np.empty((t_off[-1], 3), np.int64),
        np.empty(m_off[-1], np.int64),
        np.empty(m_off[-1], np.int64),
        np.empty(t_off[-1], np.int64),
    )
    for i in range(len(parts)):
        p = parts[i]
        parts[i] = None
        out.props[v_off[i] : v_off[i + 1]] = p.props
        np.add(p.tri, v_off[i], out=out.tri[t_off[i] : t_off[i + 1]])  # shifted in place: no temporary copy
        np.add(p.merge_from, v_off[i], out=out.merge_from[m_off[i] : m_off[i + 1]])
        np.add(p.merge_to, v_off[i], out=out.merge_to[m_off[i] : m_off[i + 1]])
        out.face_id[t_off[i] : t_off[i + 1]] = p.face_id
        del p
    parts.clear()
    return out


def _join(parts: list[Part], where: str):
    """The disjoint meshes side by side (the list is emptied): properties, triangles, face ids, point of each vertex."""
    for part in parts:
        if part.props.shape[1] not in (3, _NUM_PROP) or len(part.face_id) != len(part.tri):
            raise GeometryError(
                f"{where}: manifold3d returned {part.props.shape[1]} properties, {len(part.face_id)} face ids"
            )
    whole = _concat(parts)
    point_of, npts = _weld(len(whole.props), whole.merge_from, whole.merge_to)
    return whole.props, whole.tri, whole.face_id, point_of, npts


def _weld(nprops: int, merge_from: np.ndarray, merge_to: np.ndarray):
    """Point index of every property vertex (merge vectors applied) and the number of points."""
    rep = np.arange(nprops)
    rep[merge_from] = merge_to
    while (rep[rep] != rep).any():  # follow chains, should manifold ever write one
        rep = rep[rep]
    root = np.zeros(nprops, bool)
    root[rep] = True
    index = np.cumsum(root) - 1
    return index[rep], int(root.sum())


def _unit_rows(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(length > 1e-12, length, 1.0)


def _closed(faces: np.ndarray, nverts: int, near: np.ndarray | None = None) -> bool:
    """Every directed edge once, and its reverse once: closed and consistently oriented.

    With ``near`` (a mask of vertices), only the edges with an end among them
    are checked: the rest of the mesh is known to be closed (a boolean's output,
    whole tube pieces) and only the seams where the parts were joined need it.
    """
    faces = np.ascontiguousarray(faces)
    mask = np.ones(1, bool) if near is None else np.ascontiguousarray(near, bool)
    index = np.int32 if nverts < 2**31 else np.int64  # the edges' far ends: half the memory of int64 keys
    return bool(_closed_edges(faces, nverts, mask, near is not None, np.zeros(0, index)))


@kernel(nogil=True)
def _closed_edges(faces, nverts, near, use_near, like):  # pragma: no cover - compiled
    """:func:`_closed` by the checked edges grouped by their first end (a counting sort), without sorting keys.

    The directed edges ``a -> b`` (those with an end in ``near`` if
    ``use_near``) are listed per ``a``; there must be no edge twice, and for
    every edge ``a -> b`` the edge ``b -> a`` must be listed.  With no edge
    twice, every reverse being an edge is the same as the sorted edges equal to
    the sorted reverses (one set maps one to one onto the other).  A vertex's
    list is short; a long one (many triangles at one point) is sorted.
    """
    start = np.empty(nverts + 1, np.int64)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    start[:] = 0
    for f in range(len(faces)):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            if not use_near or near[a] or near[b]:
                start[a + 1] += 1
    for v in range(nverts):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    far = np.empty(start[nverts], like.dtype)
    for f in range(len(faces)):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            if not use_near or near[a] or near[b]:
                far[fill[a]] = b
                fill[a] += 1
    for v in range(nverts):
        lo, hi = start[v], start[v + 1]
        if hi - lo > 16:
            sort_between(far, lo, hi)
            for i in range(lo + 1, hi):
                if far[i] == far[i - 1]:
                    return False
        else:
            for i in range(lo + 1, hi):
                for j in range(lo, i):
                    if far[i] == far[j]:
                        return False
    for a in range(nverts):
        for i in range(start[a], start[a + 1]):
            b = far[i]
            lo, hi = start[b], start[b + 1]
            found = False
            if hi - lo > 16:
                j = lo + search_left(far[lo:hi], a)
                found = j < hi and far[j] == a
            else:
                for j in range(lo, hi):
                    if far[j] == a:
                        found = True
                        break
            if not found:
                return False
    return True


def _to_mesh(parts: list[Part], where: str, corners: bool = True) -> Mesh:
    """The disjoint meshes as one Mesh; manifold3d's face ids (the tube face of every piece) as ``face_source``."""
    props, tri, fid, point_of, npts = _join(parts, where)
    vertices = np.empty((npts, 3))
    vertices[point_of] = props[:, :3]
    if not corners:
        return Mesh(vertices, point_of[tri], _no_corners(len(tri), 3, 3), _no_corners(len(tri), 3, 2), face_source=fid)
    return Mesh(vertices, point_of[tri], _unit_rows(props[tri, 3:6]), props[tri, 6:], face_source=fid)
