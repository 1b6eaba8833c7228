"""Leaves: flat meshes for the leaf polygons and the leaf instances of a skeleton.

Leaves are not unioned with the bark; they are thin sheets meant for a
double-sided material (:data:`lsys3d.tree.LEAF`).  Two kinds come out of the
turtle:

* polygons drawn with ``{ . }``: each becomes a flat triangulated mesh in
  world space (:func:`polygon_leaves`);
* leaf instances placed by the leaf symbol: one leaf model (the built-in
  :func:`default_leaf` or the user's) placed by a transform per instance
  (:func:`leaf_transforms`), and baked in place for formats without
  instancing (:func:`instance_leaves`).

Leaf model convention: the model lives in the turtle's frame at the leaf,
``x`` = left, ``y`` = up, ``z`` = heading; the blade starts at the origin and
grows along ``+z`` to ``z = 1``, lying in the ``x``-``z`` plane with its front
facing ``+y``.  ``leaf_transforms`` has rotation columns left, up, heading,
each scaled by the leaf size, and the leaf position as translation -- so a
model of length 1 becomes a leaf one step long.

Every mesh is a :class:`~lsys3d.mesh.mesh.Mesh`: the corner normal is the face
normal (leaves are flat), ``uv`` maps the leaf's box onto [0, 1] x [0, 1].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import manifold3d
import numpy as np

from ..arrays import unique
from ..errors import GeometryError, LimitError
from ..mesh.mesh import Mesh
from ..mesh.sweep import DEFAULT_MAX_TRIANGLES
from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import Skeleton
from .attributes import KEYS, branch_values

__all__ = ["LeafOptions", "Leaves", "default_leaf", "instance_leaves", "leaf_transforms", "leaves", "polygon_leaves"]


@dataclass(frozen=True)
class LeafOptions(Options):
    """How the leaves stage builds the built-in leaf (a grammar's ``[surfaces] leaf`` replaces it)."""

    leaf_points: int = option(
        7, low=1, high=256, help="rows across the built-in leaf blade between base and tip (4 triangles each)"
    )


@dataclass(frozen=True, eq=False)
class Leaves:
    """All leaf geometry of one skeleton (the leaf fields of :class:`lsys3d.tree.Tree`).

    Attributes
    ----------
    merged : Mesh or None
        Polygon leaves plus every instance baked in place: the fallback for
        formats without instancing; None without leaves.
    model : Mesh or None
        The leaf model the transforms place; None without leaf instances.
    transforms : (k, 4, 4) float64
        One transform per leaf instance (see :func:`leaf_transforms`).
    polygons : Mesh or None
        The ``{ . }`` polygons; None without polygons.
    instance_attributes : dict of str to (k,) or (k, 3) float32
        Per-instance attributes (the hierarchy and wind attributes of
        :mod:`lsys3d.look.attributes`; empty unless asked for).  The merged and
        polygon meshes carry the same attributes per vertex.
    """

    merged: Mesh | None = None
    model: Mesh | None = None
    transforms: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    polygons: Mesh | None = None
    instance_attributes: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def instanced(self) -> bool:
        """Whether there are leaf instances (a model and at least one transform)."""
        return self.model is not None and len(self.transforms) > 0


def default_leaf(points: int = 7) -> Mesh:
    """The built-in leaf: a pointed oval blade, length 1 along ``+z``, width 0.5 along ``x``.

    Parameters
    ----------
    points : int
        Rows across the blade between base and tip (at least 1).

    Returns
    -------
    Mesh
        ``4 * points`` triangles facing ``+y``, with corner normals and uv.

    Examples
    --------
    >>> m = default_leaf()
    >>> len(m.faces), m.bounds.round(3).tolist()
    (28, [[-0.25, 0.0, 0.0], [0.25, 0.0, 1.0]])
    """
    if points < 1:
        raise ValueError(f"default_leaf: points must be >= 1, got {points}")
    z = np.linspace(0.0, 1.0, points + 2)[1:-1]
    half = np.sin(np.pi * z) ** 0.8
    half *= 0.25 / half.max()
    # vertices: base, then (left, mid, right) per row, then tip
    verts = np.zeros((3 * points + 2, 3))
    verts[1:-1:3, 0] = -half
    verts[3:-1:3, 0] = half
    verts[1:-1, 2] = np.repeat(z, 3)
    verts[-1, 2] = 1.0
    faces = [[0, 1, 2], [0, 2, 3]]
    for i in range(points - 1):
        a, b = 1 + 3 * i, 4 + 3 * i
        faces += [[a, b, b + 1], [a, b + 1, a + 1], [a + 1, b + 1, b + 2], [a + 1, b + 2, a + 2]]
    a, t = 1 + 3 * (points - 1), len(verts) - 1
    faces += [[a, t, a + 1], [a + 1, t, a + 2]]
    faces = np.array(faces, np.int64)
    # wind every triangle so that the front faces +y
    tri = verts[faces]
    back = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 1] < 0
    faces[back] = faces[back][:, ::-1]
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0], np.float32), (len(faces), 3, 3))
    uv = np.stack([verts[:, 0] / 0.5 + 0.5, verts[:, 2]], axis=1)[faces]
    return Mesh(verts, faces, normals, uv)


def leaf_transforms(skeleton: Skeleton) -> np.ndarray:
    """World transforms of the leaf instances, ``(k, 4, 4) float64``.

    Rotation columns are left, up, heading scaled by ``leaf_size``; the
    translation is ``leaf_position``.
    """
    k = len(skeleton.leaf_position)
    out = np.zeros((k, 4, 4))
    size = np.asarray(skeleton.leaf_size, np.float64)[:, None]
    out[:, :3, 0] = skeleton.leaf_left * size
    out[:, :3, 1] = skeleton.leaf_up * size
    out[:, :3, 2] = skeleton.leaf_heading * size
    out[:, :3, 3] = skeleton.leaf_position
    out[:, 3, 3] = 1.0
    return out


def instance_leaves(
    model: Mesh, transforms: np.ndarray, attributes: Mapping | None = None, material: np.ndarray | None = None
) -> Mesh | None:
    """Copies of ``model`` baked in place by each transform (None when there are none).

    Corner normals follow the rotation (inverse transpose, renormalised); uv
    are copied.  Transforms with a zero scale give degenerate copies, which
    are dropped.  ``attributes`` (per transform) become per-vertex attributes
    of the copies, ``material`` (per transform) their faces' material index.
    """
    transforms = np.asarray(transforms, np.float64)
    if transforms.ndim != 3 or transforms.shape[1:] != (4, 4):
        raise ValueError(f"instance_leaves: transforms must have shape (k, 4, 4), got {transforms.shape}")
    lin = transforms[:, :3, :3]
    det = np.linalg.det(lin)
    ok = np.abs(det) > 1e-30
    transforms, lin, det = transforms[ok], lin[ok], det[ok]
    if not len(transforms):
        return None
    verts, faces, normals, uv = model.vertices, model.faces, model.normals, model.uv
    k, nv = len(transforms), len(verts)
    world = verts[None] @ lin.transpose(0, 2, 1) + transforms[:, None, :3, 3]
    inv = np.linalg.inv(lin)  # normals transform by the inverse transpose: n' = n @ inv
    wn = (np.asarray(normals, np.float64).reshape(1, -1, 3) @ inv).astype(np.float32)
    wn /= np.maximum(np.linalg.norm(wn, axis=-1, keepdims=True), 1e-30)
    wfaces = faces[None] + (np.arange(k) * nv)[:, None, None]
    if (det < 0).any():  # a mirroring transform turns the winding around
        wfaces[det < 0] = wfaces[det < 0][:, :, ::-1]
    per_vertex = {name: np.repeat(np.asarray(a)[ok], nv, axis=0) for name, a in (attributes or {}).items()}
    per_face = None if material is None else np.repeat(np.asarray(material)[ok], len(faces))
    return Mesh(
        world.reshape(-1, 3),
        wfaces.reshape(-1, 3),
        wn.reshape(-1, 3, 3),
        np.broadcast_to(np.asarray(uv), (k, *np.shape(uv))).reshape(-1, 3, 2),
        attributes=per_vertex,
        face_material=per_face,
    )


def _plane_frames(points: np.ndarray, offsets: np.ndarray):
    """Newell normal and an in-plane axis of every polygon."""
    n = len(offsets) - 1
    counts = np.diff(offsets)
    poly = np.repeat(np.arange(n), counts)
    nxt = np.arange(len(points)) + 1
    last = offsets[1:] - 1
    nxt[last] = offsets[:-1]
    normal = np.zeros((n, 3))
    np.add.at(normal, poly, np.cross(points, points[nxt]))
    area2 = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(area2 > 0, area2, 1.0)[:, None]
    edge = points[offsets[:-1] + 1] - points[offsets[:-1]]
    x = edge - np.einsum("ij,ij->i", edge, normal)[:, None] * normal
    x = x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-300)
    return normal, x, np.cross(normal, x), area2 * 0.5, poly


def polygon_leaves(skeleton: Skeleton, attributes: Mapping | None = None) -> Mesh | None:
    """The ``{ . }`` polygons of a skeleton as one flat mesh (None when there are none).

    Each polygon is projected onto its best-fit plane (Newell normal) and
    triangulated (ear clipping by manifold3d, so concave outlines are fine);
    polygons of zero area are dropped.  Vertices are shared within a polygon,
    not between polygons.  ``attributes`` (per polygon) become per-vertex
    attributes.
    """
    offsets = np.asarray(skeleton.polygon_offsets, np.int64)
    points = np.asarray(skeleton.polygon_points, np.float64)
    counts = np.diff(offsets)
    keep = counts >= 3
    if not keep.any():
        return None
    sel = np.flatnonzero(keep)  # the skeleton's polygon of each kept one
    if not keep.all():
        idx = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in sel])
        points, counts = points[idx], counts[sel]
        offsets = np.concatenate([[0], np.cumsum(counts)])
    normal, ax, ay, area, poly = _plane_frames(points, offsets)
    scale = np.abs(points).max() + 1.0
    good = area > 1e-12 * scale * scale
    rel = points - points[offsets[:-1]][poly]
    uv2 = np.stack([np.einsum("ij,ij->i", rel, ax[poly]), np.einsum("ij,ij->i", rel, ay[poly])], axis=1)
    # convex polygons (all turns to the same side) are fans; the rest go to manifold's triangulator
    nxt = np.arange(len(points)) + 1
    nxt[offsets[1:] - 1] = offsets[:-1]
    e = uv2[nxt] - uv2
    turn = e[:, 0] * e[nxt, 1] - e[:, 1] * e[nxt, 0]
    convex = np.ones(len(counts), bool)
    np.logical_and.at(convex, poly, turn >= -1e-12 * scale * scale)
    faces = []
    fan = good & convex
    if fan.any():
        c = counts[fan]
        p = np.repeat(np.flatnonzero(fan), c - 2)
        k = np.arange(int((c - 2).sum())) - np.repeat(np.cumsum(c - 2) - (c - 2), c - 2)
        o = offsets[p]
        faces.append(np.stack([o, o + k + 1, o + k + 2], axis=1))
    for i in np.flatnonzero(good & ~convex).tolist():
        tri = manifold3d.triangulate([np.ascontiguousarray(uv2[offsets[i] : offsets[i + 1]], np.float64)])
        tri = np.asarray(tri, np.int64).reshape(-1, 3)
        if len(tri) != counts[i] - 2:
            raise GeometryError(f"polygon_leaves: polygon {i} could not be triangulated (self-intersecting outline?)")
        faces.append(tri + offsets[i])
    if not faces:
        return None
    faces = np.concatenate(faces)
    fpoly = poly[faces[:, 0]]
    lo = np.full((len(counts), 2), np.inf)
    hi = np.full((len(counts), 2), -np.inf)
    np.minimum.at(lo, poly, uv2)
    np.maximum.at(hi, poly, uv2)
    uv = (uv2 - lo[poly]) / np.maximum(hi - lo, 1e-300)[poly]
    normals = np.repeat(normal[fpoly][:, None, :], 3, axis=1)
    used = unique(faces)
    remap = np.full(len(points), -1, np.int64)
    remap[used] = np.arange(len(used))
    per_vertex = {name: np.asarray(a)[sel[poly[used]]] for name, a in (attributes or {}).items()}
    material = np.asarray(skeleton.polygon_material)[sel[fpoly]] if len(skeleton.polygon_material) else None
    return Mesh(points[used], remap[faces], normals, uv[faces], attributes=per_vertex, face_material=material)


def leaves(
    skeleton: Skeleton,
    model: Mesh | None = None,
    hierarchy: Hierarchy | None = None,
    attributes=None,
    options: LeafOptions | None = None,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
) -> Leaves:
    """Every leaf of a skeleton: polygons, instances (model + transforms) and all merged.

    Parameters
    ----------
    skeleton : Skeleton
    model : Mesh or trimesh.Trimesh, optional
        Leaf model in the convention of this module (default :func:`default_leaf`
        with ``options.leaf_points`` rows; a grammar's ``[surfaces] leaf``,
        :mod:`lsys3d.look.surfaces`).
    hierarchy : Hierarchy, optional
        The skeleton's branch hierarchy: when given, every leaf carries the
        attributes of the branch it grows from (:mod:`lsys3d.look.attributes`), per
        instance and per vertex.
    attributes : sequence of str, optional
        Which attributes (default: all of :data:`lsys3d.look.attributes.ATTRIBUTES`).
    options : LeafOptions, optional
    max_triangles : int
        Most triangles of the leaves baked in place (instances times the model's triangles).

    Raises
    ------
    LimitError
        The baked leaves would have more than ``max_triangles`` triangles (counted before they are built).
    """
    options = options or LeafOptions()
    if model is not None and not isinstance(model, Mesh):
        model = Mesh.from_trimesh(model)
    instance_attrs = polygon_attrs = {}
    if hierarchy is not None:
        k = len(skeleton.leaf_position)
        instance_attrs = _grown_from(hierarchy, skeleton.leaf_segment, k, skeleton.leaf_position, attributes)
        firsts = skeleton.polygon_points[skeleton.polygon_offsets[:-1]] if skeleton.n_polygons else np.zeros((0, 3))
        polygon_attrs = _grown_from(hierarchy, skeleton.polygon_segment, skeleton.n_polygons, firsts, attributes)
    polygons = polygon_leaves(skeleton, polygon_attrs)
    transforms = leaf_transforms(skeleton)
    leaf_model = None
    baked = None
    if len(transforms):
        leaf_model = default_leaf(options.leaf_points) if model is None else model
        total = len(transforms) * len(leaf_model.faces)
        if total > max_triangles:
            raise LimitError(
                f"leaves: {len(transforms):,} leaves of {len(leaf_model.faces):,} triangles make {total:,} triangles, "
                f"more than the limit of {max_triangles:,}; use a smaller leaf model or fewer leaves, or raise the "
                "limit (--max-triangles, or max_triangles=)"
            )
        baked = instance_leaves(leaf_model, transforms, instance_attrs, skeleton.leaf_material)
    parts = [m for m in (polygons, baked) if m is not None]
    merged = Mesh.concatenate(parts) if parts else None
    return Leaves(merged, leaf_model, transforms, polygons, instance_attrs)


def _grown_from(h: Hierarchy, segment, count: int, where: np.ndarray, keys=None) -> dict:
    """The attributes of ``count`` leaves growing from ``segment`` (at its end); no branch: pivot at ``where``."""
    keys = KEYS if keys is None else keys

    if segment is None or len(segment) != count:
        segment = np.full(count, -1, np.int64)
    segment = np.asarray(segment, np.int64)
    has = segment >= 0
    s = np.where(has, segment, 0)
    branch = np.where(has, h.branch_of[s] if len(h.branch_of) else -1, -1)
    t = np.where(has, h.t_end[s] if len(h.t_end) else 0.0, 0.0)
    values = branch_values(h, branch, t, fallback_pivot=where)
    return {key: values[key] for key in keys}
