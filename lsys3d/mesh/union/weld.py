"""The union's last steps: crumbs dropped, broken corners mended, and the float32 weld (the mesh as a file will
hold it, its vertices welded where float32 makes them equal and kept apart where that would pinch the surface)."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ...arrays import first_equal_row as _first_equal_row
from ...arrays import isin, row_hash, unique
from ...compiling import inner, kernel
from ..mesh import Mesh, crumbs, face_normals
from .parts import _closed, _corner_rows, _kept_faces

log = logging.getLogger("lsys3d")


def _crumbs(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(f,) bool``: the boolean's crumbs (:func:`lsys3d.mesh.mesh.crumbs`), under 1e-6 of the whole area
    (seen on the ``tree`` preset: 17 of them, areas below 1e-6 m^2)."""
    crumb = crumbs(vertices, faces, 1e-6)
    if crumb.any():
        log.debug("union: dropped flat crumbs of %d triangles", int(crumb.sum()))
    return crumb


def _drop_crumbs(mesh: Mesh) -> Mesh:
    """The mesh without its crumbs (:func:`_crumbs`)."""
    faces = mesh.faces
    crumb = _crumbs(mesh.vertices, faces)
    if not crumb.any():
        return mesh
    keep = ~crumb
    used = np.zeros(len(mesh.vertices), bool)
    used[faces[keep]] = True
    renumber = np.cumsum(used) - 1
    source = None if mesh.face_source is None else mesh.face_source[keep]
    normals, uv = _corner_rows(mesh.normals, keep), _corner_rows(mesh.uv, keep)
    return Mesh(mesh.vertices[used], renumber[faces[keep]], normals, uv, face_source=source)


def _repair_corners(mesh: Mesh) -> None:
    """Give corners whose interpolated attributes manifold3d left non-finite the face normal and uv 0.

    Seen on degenerate input (hypothesis: 15 zero-width tubes 1e-12 apart) where
    manifold3d interpolates properties over a zero-area triangle.  The union's
    own fresh arrays are repaired in place, and their -0.0 made 0.0, as the
    files store them (the exporter can then use the normals without a copy).
    """
    normals = mesh.normals
    if normals.strides[0] == 0:  # not made (:func:`_no_corners`)
        return
    bad = np.zeros(normals.shape[:2], bool)
    if _mend_corners(normals, mesh.uv, bad):
        fn = np.nan_to_num(face_normals(mesh.vertices, mesh.faces).astype(np.float32))
        fn[np.abs(fn).sum(axis=1) == 0] = (0.0, 1.0, 0.0)
        normals[bad] = np.broadcast_to(fn[:, None, :], normals.shape)[bad] + normals.dtype.type(0.0)


@kernel(nogil=True)
def _mend_corners(normals, uv, bad):  # pragma: no cover - compiled
    """One pass of :func:`_repair_corners`: mark in ``bad`` the corners whose normal is not finite or zero, make
    the other normals' -0.0 0.0 and non-finite uv 0, in place; whether any corner is bad."""
    zero = normals.dtype.type(0.0)
    anybad = False
    for f in range(normals.shape[0]):
        for c in range(normals.shape[1]):
            x, y, z = normals[f, c, 0], normals[f, c, 1], normals[f, c, 2]
            if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)) or (x == 0 and y == 0 and z == 0):
                bad[f, c] = True
                anybad = True
            else:
                normals[f, c, 0], normals[f, c, 1], normals[f, c, 2] = x + zero, y + zero, z + zero
            for k in range(uv.shape[2]):
                if not np.isfinite(uv[f, c, k]):
                    uv[f, c, k] = 0.0
    return anybad


def _weld_float32(held: list[Mesh]) -> Mesh:
    """Merge vertices that share a float32 position and drop the triangles that collapse, if it stays closed.

    Where tubes meet almost tangentially, manifold3d keeps distinct vertices a
    few micrometres apart joined by needle triangles.  Stored as float32 (glTF,
    USD) they land on one position, and a reader that welds by position (as
    Blender's glTF import does) sees edges shared by four faces.  Welding here
    removes them (tree3d: 54 triangles of 73,608) while every edge keeps exactly
    two opposite faces; when it would not (crossings of coplanar tubes in the
    flat presets), the vertices are moved apart instead
    (:func:`_separate_float32`), and so are any left closer than readers weld.

    ``held`` is a list holding the mesh alone; it is emptied, so that nothing
    else keeps the mesh and each of its arrays goes as soon as it is replaced
    (the 262,143-segment plant's bark is 6.4 million faces, 0.6 GB).
    """
    mesh = held.pop()
    _repair_corners(mesh)
    vertices, faces, normals, uv, source = mesh.vertices, mesh.faces, mesh.normals, mesh.uv, mesh.face_source
    box = mesh.face_box_uv  # (a blob's box projection, carried face by face)
    del mesh
    v32 = vertices.astype(np.float32)
    v32 += np.float32(0.0)  # -0.0 and 0.0 are one position
    owner = _first_equal_row(v32.view(np.int32))
    first = owner == np.arange(len(v32))
    if first.all():  # no two vertices share a float32 position
        return _separate_float32(
            Mesh(vertices, faces, normals, uv, face_source=source, face_box_uv=box), float32_unique=True
        )
    renumber = np.cumsum(first) - 1  # the points numbered in their first appearance
    welded, keep = _welded_faces(faces, renumber[owner])
    merged = np.zeros(int(first.sum()), bool)  # the points that several vertices became
    merged[renumber[owner[~first]]] = True
    if not _closed(welded, int(first.sum()), merged):
        return _separate_float32(Mesh(vertices, faces, normals, uv, face_source=source, face_box_uv=box))
    # one array at a time: the old ones go as soon as they are replaced
    faces = welded
    del welded
    vertices = v32[first].astype(np.float64)
    del v32
    if not keep.all():
        normals = _corner_rows(normals, keep)
        uv = _corner_rows(uv, keep)
        source = None if source is None else source[keep]
        box = None if box is None else box[keep]
    return _separate_float32(
        Mesh(vertices, faces, normals, uv, face_source=source, face_box_uv=box), float32_unique=True
    )


@kernel(nogil=True)
def _welded_faces(faces, point):  # pragma: no cover - compiled
    """The faces on the welded points ``point[faces]`` without those that collapse, and which faces are kept.

    Two passes over the faces in place: no (f, 3) copy renumbered, then another of the kept rows.
    """
    keep = np.empty(len(faces), np.bool_)
    count = 0
    for f in range(len(faces)):
        a, b, c = point[faces[f, 0]], point[faces[f, 1]], point[faces[f, 2]]
        keep[f] = a != b and b != c and c != a
        count += keep[f]
    welded = np.empty((count, 3), np.int64)
    _kept_faces(point, faces, keep, welded)
    return welded, keep


def _owners(keys: np.ndarray, dirty: np.ndarray) -> np.ndarray:
    """:func:`~lsys3d.arrays.first_equal_row` of ``keys`` when only the rows ``dirty`` (ascending) may equal another.

    The other rows are known to be pairwise distinct, so only the dirty rows
    and the rows equal to one of them (found by hash) are grouped: the same
    answer as grouping all rows, for a fraction of the sort.
    """
    n = len(keys)
    if len(dirty) == n:
        return _first_equal_row(keys)
    owner = np.arange(n)
    if not len(dirty):
        return owner
    h = row_hash(keys)
    maybe = isin(h, h[dirty])  # a hash shared with a dirty row (a collision only adds a candidate)
    maybe[dirty] = True
    rows = np.flatnonzero(maybe)
    owner[rows] = rows[_first_equal_row(keys[rows])]
    return owner


@kernel(nogil=True)
def _weld_cells(v32):  # pragma: no cover - compiled
    """The vertices' cells of trimesh's 1e-8 weld grid, ``np.round(v32.astype(np.float64) * 1e8).astype(np.int64)``
    in one pass (no (v, 3) float64 temporaries): numpy's rounding, half to even."""
    out = np.empty((len(v32), 3), np.int64)
    for i in range(len(v32)):
        out[i, 0], out[i, 1], out[i, 2] = _weld_cell(v32, i)
    return out


@inner(nogil=True, inline="always")
def _weld_cell(v32, i):  # pragma: no cover - compiled
    """Vertex ``i``'s cell of the 1e-8 grid, as numpy rounds it (half to even)."""
    return (
        np.int64(np.rint(np.float64(v32[i, 0]) * 1e8)),
        np.int64(np.rint(np.float64(v32[i, 1]) * 1e8)),
        np.int64(np.rint(np.float64(v32[i, 2]) * 1e8)),
    )


def _separate_float32(mesh: Mesh, rounds: int = 32, float32_unique: bool = False) -> Mesh:
    """Give distinct vertices distinct float32 positions, far enough apart that readers do not weld them.

    Where a weld would break the mesh (crossings of coplanar tubes), a vertex
    that shares its float32 position, or its cell of the 1e-8 grid that
    trimesh's ``merge_vertices`` welds by, with an earlier vertex is moved
    along its largest coordinate, on its own side of the earlier one, by
    ``k`` steps of ``max(float32 step, 2e-8)`` (the k-th such vertex of a
    position, so coincident vertices part too).  The moves are micrometres at
    most on a plant metres tall; the faces do not change.  When no separation
    is found in ``rounds`` passes the mesh is returned as it was.
    ``float32_unique`` says that no two vertices share a float32 position yet
    (the weld just told them apart), which saves grouping them by it once.
    """
    v = np.asarray(mesh.vertices, np.float64)  # read here; copied only when a separation is found
    v32 = v.astype(np.float32)
    everything = np.arange(len(v32))
    direction = np.zeros(len(v32))

    def float32_bits():  # + 0.0 makes -0.0 and 0.0 one position
        return (v32 + np.float32(0.0)).view(np.int32)

    def weld_grid_cell():  # trimesh's merge_vertices rounds to 8 decimals
        return _weld_cells(v32)

    # the vertices moved since each key last grouped them: only those can share a key with another vertex
    # (the rest were told apart then), so later rounds group a few candidates instead of all vertices
    dirty = [np.zeros(0, np.int64) if float32_unique else everything, everything]
    separated = False
    for _ in range(rounds):
        moved = False
        for k, key in enumerate((float32_bits, weld_grid_cell)):
            if not len(dirty[k]):  # no vertex can share this key with another
                continue
            owner = _owners(key(), dirty[k])
            later = np.flatnonzero(owner != everything)
            dirty[k] = np.zeros(0, np.int64)
            if not len(later):
                continue
            moved = separated = True
            dirty = [unique(np.concatenate([d, later])) for d in dirty]
            axis = np.argmax(np.abs(v[later]), axis=1)
            # a vertex keeps the side it first moved to, so it cannot swing between two neighbours
            fresh = direction[later] == 0
            direction[later[fresh]] = np.where(v[later, axis] >= v[owner[later], axis], 1.0, -1.0)[fresh]
            side = direction[later]
            by_owner = np.argsort(owner[later], kind="stable")
            sorted_owner = owner[later][by_owner]
            rank = np.empty(len(later), np.int64)
            rank[by_owner] = np.arange(len(later)) - np.searchsorted(sorted_owner, sorted_owner, side="left") + 1
            old = v32[later, axis]
            step = np.maximum(np.spacing(np.abs(old)).astype(np.float64), 2e-8)
            new = (old.astype(np.float64) + side * rank * step).astype(np.float32)
            same = new == old
            new[same] = np.nextafter(old[same], (side[same] * np.inf).astype(np.float32))
            v32[later, axis] = new
        if not moved:
            break
    else:
        return mesh
    if not separated:  # every vertex has a float32 position and weld cell of its own already
        return mesh
    moved = (v32 != v.astype(np.float32)).any(axis=1)
    log.debug("union: %d vertices moved to positions of their own", int(moved.sum()))
    v = v.copy()
    v[moved] = v32[moved]
    return replace(mesh, vertices=v)
