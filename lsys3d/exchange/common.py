"""What every writer shares: the options, the file frame, and mesh gathering.

The writers gather plain arrays here (split vertices, instance transforms,
polylines) and then write them; nothing here knows a file format.
"""

from __future__ import annotations

import json
import logging
import re
from dataclasses import dataclass, field

import numpy as np

from ..arrays import first_equal_row, isin, unique
from ..compiling import kernel
from ..errors import ExportError
from ..images import Image
from ..look.attributes import ATTRIBUTES
from ..look.materials import Material
from ..mesh.mesh import Mesh
from ..options import Options, option

__all__ = [
    "ExportOptions",
    "MeshArrays",
    "TextureFiles",
    "decompose_transforms",
    "file_frame",
    "frame_transforms",
    "gather_mesh",
    "material_groups",
    "metadata_json",
    "split_tangents",
    "to_float32",
]

log = logging.getLogger("lsys3d")

UNITS = {"m": 1.0, "cm": 0.01}
UP_AXES = ("Y", "Z")

POINT_ATTRIBUTES = frozenset(a.key for a in ATTRIBUTES if a.point)
"""Attributes that are positions: carried into the file's frame with the vertices."""

# Y up -> Z up: a +90 degree turn about X, so +Y (the trunk) goes to +Z and +Z to -Y.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class ExportOptions(Options):
    """How :func:`lsys3d.exchange.export` writes a tree; every default, range and help is in its field.

    ``units = "cm"`` scales the geometry by 100 and authors ``metersPerUnit =
    0.01`` (USD); ``up_axis = "Z"`` turns the geometry +90 degrees about X and
    authors ``upAxis = "Z"``.  glTF is always metres and Y up.
    ``instance_leaves`` writes leaves as instances of one leaf model (USD
    ``PointInstancer``, glTF ``EXT_mesh_gpu_instancing``) instead of one merged
    mesh; ``None`` (default) picks the format's natural choice: instanced for
    USD, merged for glTF (readable by every viewer) and for ``.usdz`` (ARKit's
    profile of USD, which AR Quick Look reads, has no ``PointInstancer``).
    """

    units: str = option("m", choices=tuple(UNITS), help="length unit of a USD file")
    up_axis: str = option("Y", choices=UP_AXES, help="up axis of a USD file")
    instance_leaves: bool | None = option(
        None, kind=bool, help="leaves as instances of one model (None: the format's choice)", cli=False
    )
    skeleton_curves: bool = option(False, help="also write the branch skeleton as curves")
    no_clobber: bool = option(False, help="refuse to overwrite an existing file")
    hairline: bool = option(False, help="SVG: lines one pixel wide instead of as wide as branches")
    scene: bool = option(
        False, help="also write the scene the plant grew in ([environment], --environment) under a node 'scene'"
    )

    @property
    def meters_per_unit(self) -> float:
        return UNITS[self.units]


SCENE_MATERIAL = Material("scene", (0.50, 0.50, 0.48, 1.0), roughness=0.9)
"""What a scene's obstacles and supports look like in the file (``--scene``): a matte light grey, so that
walls and posts read as the set a plant is placed against (glTF's default material is a rough metal)."""

SCENE_VOLUME = Material("scene_volume", (0.35, 0.55, 0.35, 0.15), roughness=1.0, double_sided=True)
"""A pruning volume's look: a faint translucent green, a guide around the plant it shapes, not a solid that
hides it (USD also gives it the purpose ``guide``: viewports draw it on request, renderers leave it out)."""


def scene_meshes(tree, options: ExportOptions, where: str) -> tuple:
    """The scene meshes to write with ``tree`` (``options.scene``): ``(name, (n, 3) points in the file's frame,
    (f, 3) faces, role, material)`` each, named uniquely; empty without ``--scene``.

    Raises
    ------
    ExportError
        ``--scene`` for a plant that grew in no scene.
    """
    if not options.scene:
        return ()
    if not tree.scene:
        raise ExportError(f"{where}: --scene: the plant grew in no scene (give the grammar an [environment], or "
                          "--environment FILE)")  # fmt: skip
    frame = file_frame(options)
    out, seen = [], set()
    for k, m in enumerate(tree.scene):
        name = re.sub(r"[^A-Za-z0-9_]", "_", f"{m.role}_{m.name}") or f"mesh_{k}"
        if name[0].isdigit():
            name = "_" + name
        while name in seen:
            name += f"_{k}"
        seen.add(name)
        look = SCENE_VOLUME if m.role == "volume" else SCENE_MATERIAL
        out.append((name, np.asarray(m.vertices, np.float64) @ frame.T, np.asarray(m.faces, np.int64), m.role, look))
    return tuple(out)


def file_frame(options: ExportOptions) -> np.ndarray:
    """The linear map ``(3, 3)`` from lsys3d's frame (metres, Y up) to the file's (units, up axis).

    It is a rotation times a uniform scale, so it maps normals too (after
    dropping the scale).
    """
    m = np.eye(3) / options.meters_per_unit
    if options.up_axis == "Z":
        m = _Y_TO_Z @ m
    return m


@dataclass(frozen=True)
class MeshArrays:
    """A mesh gathered for writing.

    points : (v, 3) float32
        Welded vertices, renumbered in the order faces first use them (unused ones dropped).
    faces : (f, 3) int32
        Triangles indexing ``points``.
    normals : (f * 3, 3) float32
        Unit normal per face corner.
    uv : (f * 3, 2) float32
        Texture coordinates per face corner.
    split_points, split_normals, split_uv : (s, ...) float32
        One vertex per unique (point, normal, uv): what glTF needs.
    split_index : (f * 3,) uint32
        Split vertex of each face corner.
    colors, split_colors : (v, 3) / (s, 3) float32 or None
        Linear RGB vertex colours (:attr:`lsys3d.mesh.mesh.Mesh.colors`), per point and per split vertex.
    attributes, split_attributes : dict of str to (v, ...) / (s, ...) float32
        The mesh's per-vertex attributes (:attr:`lsys3d.mesh.mesh.Mesh.attributes`), points among them
        (:data:`lsys3d.look.attributes.ATTRIBUTES`) in the file's frame, per point and per split vertex.
    """

    points: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uv: np.ndarray | None
    split_points: np.ndarray
    split_normals: np.ndarray
    split_uv: np.ndarray | None
    split_index: np.ndarray
    colors: np.ndarray | None = None
    split_colors: np.ndarray | None = None
    attributes: dict = field(default_factory=dict)
    split_attributes: dict = field(default_factory=dict)


FLOAT32_MAX = float(np.finfo(np.float32).max)
_SLICE = 1 << 20  # normals checked at once (bounds the temporaries)


def to_float32(values, what: str, where: str) -> np.ndarray:
    """``values`` as float32, the precision of the files, refusing what float32 cannot hold (an overflow to inf)."""
    values = np.asarray(values, dtype=np.float64)
    # the largest and least values, no abs() copy (a NaN makes both NaN: not ok)
    ok = values.size == 0 or bool(values.max() <= FLOAT32_MAX and values.min() >= -FLOAT32_MAX)
    if not ok:
        raise ExportError(
            f"{where}: {what} holds a value that is not a number or beyond the 32-bit float range (3.4e38)"
        )
    return values.astype(np.float32)


def _off_unit(normals: np.ndarray) -> np.ndarray:
    """``(n,) bool``: the rows of ``normals`` (float32) whose length is not 1 within float32 rounding, or NaN."""
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    length2 = x * x + y * y + z * z
    return ~(np.abs(length2 - 1) < 4e-7)  # also catches NaN


def _needs_unit(normals: np.ndarray) -> bool:
    """Whether :func:`_unit_normals` would change a row, a slice at a time (no full-size temporaries)."""
    return any(_off_unit(normals[lo : lo + _SLICE]).any() for lo in range(0, len(normals), _SLICE))


def _has_negative_zero(values: np.ndarray) -> bool:
    """Whether ``values`` (float32) hold a -0.0, a slice at a time."""
    bits = values.reshape(len(values), -1).view(np.uint32)
    return any((bits[lo : lo + _SLICE] == 0x80000000).any() for lo in range(0, len(bits), _SLICE))


def _unit_normals(normals: np.ndarray, faces: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Rows of ``normals`` (float32, ``(f * 3, 3)``) scaled to unit length, in place when possible.

    Rows of zero or non-finite length take the normal of their face.
    """
    off = np.concatenate([_off_unit(normals[lo : lo + _SLICE]) for lo in range(0, len(normals), _SLICE)] or [[]])
    if not off.any():
        return normals
    rows = np.flatnonzero(off)
    x, y, z = normals[rows].T
    length = np.sqrt((x * x + y * y + z * z).astype(np.float64))  # float32 squares, as _off_unit found them
    fixed = normals[rows].astype(np.float64)
    bad = ~(np.isfinite(length) & (length > 1e-20))
    if bad.any():
        tri = vertices[faces[rows[bad] // 3]]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        fl = np.linalg.norm(fn, axis=1)
        fn[fl == 0] = (0.0, 1.0, 0.0)  # a degenerate face with no usable normal: any unit vector
        fixed[bad] = fn
        length[bad] = np.where(fl == 0, 1.0, fl)
    normals[rows] = (fixed / length[:, None]).astype(np.float32)
    return normals


def _first_use_order(corner_v: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Renumber vertices in the order the face list first uses them.

    Returns ``(old_of_new, new_of_old)`` (unused vertices get ``-1`` in
    ``new_of_old``), or None when the numbering is already in that order.
    """
    new_of_old = np.full(n, -1, _index_type(n))  # int32 where it fits: the corners renumbered are f * 3 of them
    old_of_new = np.empty(n, np.int64)
    used = _first_uses(corner_v, new_of_old, old_of_new)
    if used == n and (old_of_new == np.arange(n)).all():
        return None
    return old_of_new[:used], new_of_old


@kernel(nogil=True)
def _first_uses(corner_v, new_of_old, old_of_new):  # pragma: no cover - compiled
    """Number the vertices in the order ``corner_v`` first uses them (into both maps); how many are used."""
    k = 0
    for i in range(len(corner_v)):
        v = corner_v[i]
        if new_of_old[v] < 0:
            new_of_old[v] = k
            old_of_new[k] = v
            k += 1
    return k


def _index_type(n: int) -> type:
    """The smaller integer type that can number ``n`` things (and -1)."""
    return np.int32 if n < 2**31 else np.int64


def gather_mesh(mesh: Mesh, frame: np.ndarray, where: str) -> MeshArrays:
    """Gather a welded mesh with corner attributes into arrays for the writers.

    Parameters
    ----------
    mesh : Mesh
        Welded vertices, corner normals and uv, optional vertex colours.
    frame : (3, 3) float64
        Linear map into the file's frame (see :func:`file_frame`).
    where : str
        Name used in error messages.
    """
    vertices = mesh.vertices
    faces = mesh.faces
    if not len(faces):
        raise ExportError(f"{where}: the mesh has no triangles")
    if not np.isfinite(vertices).all():
        raise ExportError(f"{where}: the mesh has non-finite vertices")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ExportError(f"{where}: a face points past the {len(vertices)} vertices")
    # float32 corner normals, copied only when they are rotated, normalised or have a -0.0 to fold
    normals = np.asarray(mesh.normals, dtype=np.float32).reshape(-1, 3)
    uv = np.ascontiguousarray(mesh.uv, dtype=np.float32).reshape(-1, 2)
    if not np.isfinite(uv).all():
        raise ExportError(f"{where}: the uv hold a NaN or infinite value")
    colors = mesh.colors
    attributes = dict(mesh.attributes)
    if not all(np.isfinite(a).all() for a in attributes.values()):
        raise ExportError(f"{where}: a vertex attribute holds a NaN or infinite value")
    if colors is not None and not (np.isfinite(colors).all() and (colors >= 0).all()):
        raise ExportError(f"{where}: the vertex colours hold a negative, NaN or infinite value")

    corner_v = faces.reshape(-1)
    renumber = _first_use_order(corner_v, len(vertices))
    if renumber is not None:
        old_of_new, new_of_old = renumber
        corner_v = new_of_old[corner_v]
        vertices = vertices[old_of_new]
        if colors is not None:
            colors = colors[old_of_new]
        attributes = {k: a[old_of_new] for k, a in attributes.items()}
    identity = np.array_equal(frame, np.eye(3))
    points = to_float32(vertices if identity else vertices @ frame.T, "the vertices", where)

    if not identity:
        rotation = (frame / np.cbrt(np.linalg.det(frame))).astype(np.float32)
        normals = normals @ rotation.T
    shared = np.may_share_memory(normals, mesh.normals)
    if shared and (_needs_unit(normals) or _has_negative_zero(normals)):
        normals, shared = normals.copy(), False  # a private copy, fixed in place below; the mesh's stay as they are
    if not shared:  # (shared: all unit already, and no -0.0)
        normals = _unit_normals(normals, corner_v.reshape(-1, 3), points)
    normals = np.ascontiguousarray(normals, dtype=np.float32)  # _split views the rows as bytes
    if not shared:
        normals += np.float32(0.0)  # -0.0 -> 0.0, so corners that compare equal are equal bit for bit

    if not identity:  # positions among the attributes go into the file's frame like the vertices
        attributes = {
            k: (a @ frame.T).astype(np.float32) if k in POINT_ATTRIBUTES else a for k, a in attributes.items()
        }
    split_index, split_points, split_normals, split_uv, split_colors, vertex_of_split = _split(
        points, corner_v, normals, uv, colors
    )
    split_attributes = {k: a if vertex_of_split is None else a[vertex_of_split] for k, a in attributes.items()}
    return MeshArrays(
        points=points,
        faces=corner_v.astype(np.int32, copy=False).reshape(-1, 3),
        normals=normals,
        uv=uv,
        split_points=split_points,
        split_normals=split_normals,
        split_uv=split_uv,
        split_index=split_index,
        colors=colors,
        split_colors=split_colors,
        attributes=attributes,
        split_attributes=split_attributes,
    )


def _split(points, corner_v, normals, uv, colors=None):
    """Un-weld: one vertex per unique (point, normal, uv), numbered like the points, seams appended.

    Most corners carry the same attributes as some representative corner of
    their point; only the others (seams, creases) are hashed to find their
    distinct combinations, so the cost stays linear for a typical mesh.
    """
    n = len(points)
    no_uv = np.zeros((0, 2), np.uint32)
    # compare bit patterns (normals were normalised, -0.0 folded), in compiled passes
    # int64 corners, whoever calls (the leaves hold int32 ones): _others is compiled once
    rep, extra, keys = _others(
        corner_v.astype(np.int64, copy=False), n, normals.view(np.uint32), no_uv if uv is None else uv.view(np.uint32)
    )
    split_index = corner_v.astype(np.uint32)
    corners = rep
    vertex_of_split = None
    if extra.size:
        # the new vertices numbered in order of first use, so the output does not depend on the hash
        new_corners = _number_others(first_equal_row(keys), extra, n, split_index)
        del keys
        corners = np.concatenate([rep, new_corners])
        vertex_of_split = np.concatenate([np.arange(n), corner_v[new_corners]])
    split_points = points if vertex_of_split is None else points[vertex_of_split]
    split_normals = np.take(normals, corners, axis=0)
    split_uv = None if uv is None else np.take(uv, corners, axis=0)
    split_colors = None
    if colors is not None:  # a colour belongs to the point: split vertices copy their point's
        split_colors = colors if vertex_of_split is None else colors[vertex_of_split]
    return split_index, split_points, split_normals, split_uv, split_colors, vertex_of_split


@kernel(nogil=True)
def _others(corner_v, n, normal_bits, uv_bits):  # pragma: no cover - compiled
    """:func:`_split`'s representative (last) corner of each point, the corners whose normal or uv bits differ
    from their point's representative's, and those corners' rows of point, normal and uv bits (``uv_bits``
    empty: no uv)."""
    m = len(corner_v)
    has_uv = len(uv_bits) > 0
    rep = np.empty(n, np.int64)
    for i in range(m):
        rep[corner_v[i]] = i
    same = np.empty(m, np.bool_)
    count = 0
    for i in range(m):
        r = rep[corner_v[i]]
        s = normal_bits[i, 0] == normal_bits[r, 0] and normal_bits[i, 1] == normal_bits[r, 1]
        s = s and normal_bits[i, 2] == normal_bits[r, 2]
        if has_uv:
            s = s and uv_bits[i, 0] == uv_bits[r, 0] and uv_bits[i, 1] == uv_bits[r, 1]
        same[i] = s
        count += not s
    extra = np.empty(count, np.int64)
    keys = np.empty((count, 6 if has_uv else 4), np.uint32)
    k = 0
    for i in range(m):
        if same[i]:
            continue
        extra[k] = i
        keys[k, 0] = corner_v[i]
        for c in range(3):
            keys[k, 1 + c] = normal_bits[i, c]
        if has_uv:
            keys[k, 4], keys[k, 5] = uv_bits[i, 0], uv_bits[i, 1]
        k += 1
    return rep, extra, keys


@kernel(nogil=True)
def _number_others(owner, extra, n, split_index):  # pragma: no cover - compiled
    """Number the distinct combinations of the corners ``extra`` (``owner``: each one's first equal row) from
    ``n`` in the order of their first corners, into ``split_index``; those first corners."""
    rank = np.empty(len(owner), np.int64)
    k = 0
    for i in range(len(owner)):
        if owner[i] == i:
            rank[i] = k
            k += 1
    first = np.empty(k, np.int64)
    for i in range(len(owner)):
        r = rank[owner[i]]
        split_index[extra[i]] = n + r
        if owner[i] == i:
            first[r] = extra[i]
    return first


def split_tangents(arrays: MeshArrays) -> np.ndarray:
    """Tangents of a gathered mesh's split vertices for normal maps, ``(s, 4) float32``: glTF's ``TANGENT``.

    ``xyz`` is the direction in which ``u`` grows, made perpendicular to the
    vertex normal (each face's share weighted by its size, the usual way of
    summing them); ``w`` (+1 or -1) says on which side the direction in which
    ``v`` grows lies (``bitangent = w * normal x tangent``), so mirrored uv
    are right too.  A vertex whose faces have no usable uv gradient gets some
    unit vector perpendicular to its normal.  Normal maps are read with +Y
    toward growing ``v`` (the OpenGL convention glTF and UsdPreviewSurface use).
    """
    points = arrays.split_points.astype(np.float64)
    normals = arrays.split_normals.astype(np.float64)
    uv = arrays.split_uv.astype(np.float64) if arrays.split_uv is not None else np.zeros((len(points), 2))
    tri = arrays.split_index.reshape(-1, 3).astype(np.int64)
    # the corners' rows by np.take on contiguous index columns, the first corner's once (the same values)
    i0, i1, i2 = (np.ascontiguousarray(tri[:, k]) for k in range(3))
    p0, q0 = np.take(points, i0, axis=0), np.take(uv, i0, axis=0)
    e1 = np.take(points, i1, axis=0) - p0
    e2 = np.take(points, i2, axis=0) - p0
    d1 = np.take(uv, i1, axis=0) - q0
    d2 = np.take(uv, i2, axis=0) - q0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    # dP/du and dP/dv of each face, times |det| (so a face's weight grows with its uv and 3D size)
    sign = np.sign(det)[:, None]
    t = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * sign
    b = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * sign
    corner = tri.reshape(-1)
    n = len(points)
    tangent = np.stack([np.bincount(corner, np.repeat(t[:, c], 3), minlength=n) for c in range(3)], axis=1)
    bitangent = np.stack([np.bincount(corner, np.repeat(b[:, c], 3), minlength=n) for c in range(3)], axis=1)
    tangent -= normals * np.einsum("ij,ij->i", normals, tangent)[:, None]
    length = np.linalg.norm(tangent, axis=1)
    bad = ~(length > 1e-12 * (1.0 + np.abs(points).max(initial=0.0)))
    if bad.any():  # any unit vector perpendicular to the normal
        nb = normals[bad]
        axis = np.where((np.abs(nb[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        tangent[bad] = np.cross(axis, nb)
        length[bad] = np.linalg.norm(tangent[bad], axis=1)
    tangent /= np.where(length > 0, length, 1.0)[:, None]
    w = np.where(np.einsum("ij,ij->i", np.cross(normals, tangent), bitangent) < 0, -1.0, 1.0)
    return np.concatenate([tangent, w[:, None]], axis=1).astype(np.float32)


def material_groups(index: np.ndarray | None, material_of) -> list[tuple[object, int, np.ndarray | None]]:
    """The rows (faces, leaves) of each distinct material: ``(material, its first index, rows)``.

    ``index`` holds the turtle's material index per row (None: every row the
    default, ``material_of(-1)``); ``material_of`` maps an index to its
    :class:`~lsys3d.look.materials.Material`.  Indices that map to the same material
    share a group, in the order of their smallest index; a single group has
    ``rows`` None (all of them).

    >>> material_groups(np.array([0, 3, 0, 5]), lambda i: "red" if i == 5 else "bark")
    [('bark', 0, array([0, 1, 2])), ('red', 5, array([3]))]
    """
    if index is None or not len(index):
        return [(material_of(-1), -1, None)]
    used = unique(index).tolist()
    first: dict = {}
    for i in used:
        first.setdefault(material_of(i), i)
    if len(first) == 1:
        return [(next(iter(first)), used[0], None)]
    rows = {m: np.flatnonzero(isin(index, [i for i in used if material_of(i) == m])) for m in first}
    return [(m, i, rows[m]) for m, i in first.items()]


class TextureFiles:
    """Where a writer puts the texture images it references: one file each, in one folder.

    ``prefix`` is the folder as the file refers to it (``./tree_textures/``
    beside a USD layer, ``textures/`` inside a ``.usdz``).  :meth:`path_of`
    names an image the first time it is asked (its file name, made safe, with
    ``_2``, ``_3``... when two different images share it) and returns the same
    path afterwards; :meth:`files` lists what to write, in that order.

    >>> from lsys3d.images import Image
    >>> files = TextureFiles("./tree_textures/")
    >>> a, b = Image("bark.png", b"1", "image/png", 1, 1, False), Image("bark.png", b"2", "image/png", 1, 1, False)
    >>> files.path_of(a), files.path_of(b), files.path_of(a)
    ('./tree_textures/bark.png', './tree_textures/bark_2.png', './tree_textures/bark.png')
    """

    def __init__(self, prefix: str):
        self.prefix = prefix
        self._names: dict[Image, str] = {}

    def path_of(self, image: Image) -> str:
        if image not in self._names:
            stem = re.sub(r"[^A-Za-z0-9_.-]", "_", image.name.rsplit(".", 1)[0]).strip(".") or "texture"
            name, i = f"{stem}{image.suffix}", 1
            taken = set(self._names.values())
            while name in taken:
                i += 1
                name = f"{stem}_{i}{image.suffix}"
            self._names[image] = name
        return self.prefix + self._names[image]

    def files(self) -> list[tuple[str, bytes]]:
        """``(file name, bytes)`` of every image named so far."""
        return [(name, image.data) for image, name in self._names.items()]


def decompose_transforms(transforms: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split instance transforms into translation, rotation and scale.

    Parameters
    ----------
    transforms : (k, 4, 4) float64
        Rotation times scale in the upper 3x3 (columns may have different
        lengths), translation in the last column.

    Returns
    -------
    translation : (k, 3) float64
    quaternion : (k, 4) float64
        Unit quaternions ``(x, y, z, w)`` with ``w >= 0``.
    scale : (k, 3) float64
        Per-axis scale (negative on x when the frame is mirrored).
    """
    t = np.asarray(transforms, dtype=np.float64)
    if t.ndim != 3 or t.shape[1:] != (4, 4):
        raise ExportError(f"{where}: leaf_transforms has shape {t.shape}, expected (k, 4, 4)")
    if not np.isfinite(t).all():
        raise ExportError(f"{where}: leaf_transforms holds a NaN or infinite value")
    linear = t[:, :3, :3]
    scale = np.linalg.norm(linear, axis=1)  # column lengths
    if (scale <= 0).any():
        raise ExportError(f"{where}: a leaf transform has zero scale")
    rot = linear / scale[:, None, :]
    mirrored = np.linalg.det(rot) < 0
    if mirrored.any():
        scale[mirrored, 0] *= -1
        rot[mirrored, :, 0] *= -1
    # the columns should be orthonormal now; project onto the nearest rotation when they are not quite
    if not np.allclose(np.einsum("kji,kjl->kil", rot, rot), np.eye(3), atol=1e-4):
        raise ExportError(f"{where}: a leaf transform is sheared (not rotation times scale)")
    u, _, vt = np.linalg.svd(rot)
    rot = u @ vt
    return t[:, :3, 3].copy(), _quaternions(rot), scale


def _quaternions(r: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(k, 3, 3)`` to unit quaternions ``(k, 4)`` as ``(x, y, z, w)``, ``w >= 0``."""
    k = r.shape[0]
    q = np.empty((k, 4))
    m00, m11, m22 = r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]
    trace = m00 + m11 + m22
    # pick the numerically largest component for each matrix (Shepperd's method)
    cases = np.argmax(np.stack([trace, m00, m11, m22], axis=1), axis=1)
    i = cases == 0
    s = np.sqrt(1.0 + trace[i]) * 2
    q[i] = np.stack(
        [(r[i, 2, 1] - r[i, 1, 2]) / s, (r[i, 0, 2] - r[i, 2, 0]) / s, (r[i, 1, 0] - r[i, 0, 1]) / s, s / 4], 1
    )
    i = cases == 1
    s = np.sqrt(1.0 + m00[i] - m11[i] - m22[i]) * 2
    q[i] = np.stack(
        [s / 4, (r[i, 0, 1] + r[i, 1, 0]) / s, (r[i, 0, 2] + r[i, 2, 0]) / s, (r[i, 2, 1] - r[i, 1, 2]) / s], 1
    )
    i = cases == 2
    s = np.sqrt(1.0 + m11[i] - m00[i] - m22[i]) * 2
    q[i] = np.stack(
        [(r[i, 0, 1] + r[i, 1, 0]) / s, s / 4, (r[i, 1, 2] + r[i, 2, 1]) / s, (r[i, 0, 2] - r[i, 2, 0]) / s], 1
    )
    i = cases == 3
    s = np.sqrt(1.0 + m22[i] - m00[i] - m11[i]) * 2
    q[i] = np.stack(
        [(r[i, 0, 2] + r[i, 2, 0]) / s, (r[i, 1, 2] + r[i, 2, 1]) / s, s / 4, (r[i, 1, 0] - r[i, 0, 1]) / s], 1
    )
    q[q[:, 3] < 0] *= -1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def frame_transforms(transforms: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Instance transforms ``(k, 4, 4)`` in the file frame: ``F @ T``.

    The instanced model itself is written untouched (model space), so a world
    point ``T x`` becomes ``F T x``: the frame's rotation and unit scale go
    into each instance's rotation, scale and translation.
    """
    t = np.asarray(transforms, dtype=np.float64).copy()
    s = np.cbrt(np.linalg.det(frame))
    rotation = frame / s
    t[:, :3, :3] = s * (rotation @ t[:, :3, :3])
    t[:, :3, 3] = t[:, :3, 3] @ frame.T
    return t


def _jsonable(value, where: str):
    if isinstance(value, dict):
        return {str(k): _jsonable(v, where) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v, where) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist(), where)
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (str, bool, int)):
        return value
    if isinstance(value, float):
        if not np.isfinite(value):
            raise ExportError(f"{where}: the asset's metadata holds a non-finite number")
        return value
    raise ExportError(f"{where}: metadata value of type {type(value).__name__} is not JSON-serialisable")


def metadata_json(tree, where: str) -> dict:
    """The tree's ``lsys3d`` metadata block (:meth:`lsys3d.tree.Tree.metadata`), checked JSON-ready."""
    out = _jsonable(tree.metadata(), where)
    json.dumps(out)  # fail here rather than half-way through a file
    return out
