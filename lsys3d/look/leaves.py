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
from functools import partial

import manifold3d
import numpy as np

from ..arrays import unique
from ..errors import GeometryError, LimitError, OptionsError
from ..lsystem.grammar import table_error
from ..mesh.mesh import Mesh
from ..mesh.sweep import DEFAULT_MAX_TRIANGLES
from ..options import Options, merge_table, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import MAX_COORDINATE, Skeleton
from .attributes import KEYS, branch_values
from .leaf_form import CARDS, PHYLLOTAXIS, SHAPES, arrange, blade, card_aspect, leaf_count, spray_card

__all__ = ["LeafOptions", "Leaves", "default_leaf", "instance_leaves", "leaf_transforms", "leaves", "polygon_leaves"]


@dataclass(frozen=True)
class LeafOptions(Options):
    """How the leaves stage builds and places the leaves; every option but ``leaf_points`` is off by default.

    A grammar's ``[leaves]`` table sets any of these (:meth:`from_grammar`); an option given to
    :func:`~lsys3d.pipeline.generate` or on the command line that differs from its default wins over the
    table.  A grammar's ``[surfaces] leaf`` replaces the built-in blade (``leaf_shape``, ``petiole_length``).
    """

    leaf_points: int = option(
        7, low=1, high=256, help="rows across the built-in leaf blade between base and tip (4 triangles each)"
    )
    leaf_shape: str = option(
        "default",
        choices=SHAPES,
        help="outline of the built-in blade: default, ovate, lanceolate, lobed (oak), palmate (maple), needle, "
        "blade (grass)",
    )
    leaf_size: float = option(
        0.0, low=0, high=MAX_COORDINATE, help="length of every blade in metres (0: the turtle's step in force)"
    )
    leaf_size_variation: float = option(
        0.0, low=0, high=0.9, help="random relative change of each leaf's size, up to this fraction (seeded)"
    )
    leaves_per_cluster: int = option(
        1, low=1, high=64, help="leaves each leaf symbol grows: a cluster fanned along the end of its twig"
    )
    cluster_spread: float = option(45.0, low=0, high=90, help="degrees between a clustered leaf and its twig")
    cluster_length: float = option(
        0.15, low=0, high=MAX_COORDINATE, help="metres of twig, back from its tip, that a cluster's leaves grow along"
    )
    cluster_phyllotaxis: str = option(
        "spiral",
        choices=PHYLLOTAXIS,
        help="turn between a cluster's leaves: spiral (golden angle), alternate (half a turn), opposite (pairs)",
    )
    petiole_length: float = option(
        0.0, low=0, high=4, help="stalk of the built-in leaf, in blade lengths (0: none); the blade sits on it"
    )
    leaf_light: float = option(
        0.0, low=0, high=1, help="how far each blade's front turns toward the light (0: not at all, 1: facing it)"
    )
    light: tuple[float, float, float] = option(
        (0.0, 1.0, 0.0), help="direction toward the light that leaf_light turns the blades to"
    )
    leaf_droop: float = option(0.0, low=0, high=90, help="degrees each blade's tip hangs toward the ground")
    leaf_card: str = option(
        "none",
        choices=CARDS,
        help="none: single leaves; spray: one textured quad per cluster; cross: two crossed quads per cluster; "
        "twigs: a textured quad in each leaf's place, showing a twig of leaves",
    )
    card_length: float = option(
        3.0,
        low=0.1,
        high=100,
        help="twigs cards: a card's length in leaf lengths (leaf_size), as its picture draws them",
    )
    card_aspect: float = option(
        0.0, low=0, high=20, help="width over length of a card (0: spray and cross the cluster's fan, twigs 1)"
    )
    leaf_outward: float = option(
        0.0,
        low=0,
        high=1,
        help="how far the light that leaf_light turns the blades to leans out from the crown's axis (0: not at all, "
        "1: horizontal)",
    )

    def __post_init__(self):
        super().__post_init__()
        if not np.linalg.norm(self.light) > 0:
            raise OptionsError(f"LeafOptions.light: must be a direction, not {list(self.light)}")

    def plain(self) -> dict:
        """The options as plain data, leaving out the leaf-form options that are at their defaults.

        A plant grown without them records what it always recorded, so its files keep their bytes.
        """
        out = super().plain()
        defaults = Options.plain(LeafOptions())
        return {k: v for k, v in out.items() if k == "leaf_points" or v != defaults[k]}

    @classmethod
    def from_grammar(cls, grammar, options: LeafOptions | None = None) -> LeafOptions:
        """The leaf options of a grammar's ``[leaves]`` table, with ``options``' non-default fields over it.

        Raises
        ------
        GrammarError
            An unknown key or a bad value in ``[leaves]``, with the grammar's file and the key's line.

        Examples
        --------
        >>> from lsys3d import Grammar
        >>> g = Grammar(axiom="F~", leaves={"leaf_size": 0.1, "leaf_light": 0.5})
        >>> o = LeafOptions.from_grammar(g, LeafOptions(leaf_light=0.8))
        >>> o.leaf_size, o.leaf_light
        (0.1, 0.8)
        """
        options = options or cls()
        table = dict(getattr(grammar, "leaves", {}) or {})
        if not table:
            return options
        return merge_table(cls, table, options, partial(table_error, grammar, "leaves"))


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
    instance_material : (k,) int32 or None
        The material index of each instance, when the instances are not the
        skeleton's own (clusters, cards: :func:`lsys3d.look.leaf_form.arrange`);
        None: the skeleton's ``leaf_material``.
    """

    merged: Mesh | None = None
    model: Mesh | None = None
    transforms: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    polygons: Mesh | None = None
    instance_attributes: Mapping[str, np.ndarray] = field(default_factory=dict)
    instance_material: np.ndarray | None = None

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
    return blade("default", points)  # one home for the blade's rows: leaf_form


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
    seed: int = 0,
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
        The built-in blade's shape and resolution, and how the instances are
        sized, clustered, turned to the light and drooped, or shown as cards
        (:func:`lsys3d.look.leaf_form.arrange`).
    max_triangles : int
        Most triangles of the leaves baked in place (instances times the model's triangles).
    seed : int
        The plant's seed: the leaves' size variation and the clusters' turns.

    Raises
    ------
    LimitError
        The baked leaves would have more than ``max_triangles`` triangles (counted before they are built).
    """
    options = options or LeafOptions()
    if model is not None and not isinstance(model, Mesh):
        model = Mesh.from_trimesh(model)
    k = len(skeleton.leaf_position)
    leaf_model = None
    arranged = skeleton
    count = 0
    if k:
        leaf_model = _model(skeleton, model, options)
        count = leaf_count(k, options)
        total = count * len(leaf_model.faces)
        if total > max_triangles:
            raise LimitError(
                f"leaves: {count:,} leaves of {len(leaf_model.faces):,} triangles make {total:,} triangles, "
                f"more than the limit of {max_triangles:,}; use a smaller leaf model or fewer leaves, or raise the "
                "limit (--max-triangles, or max_triangles=)"
            )
        arranged = arrange(skeleton, options, seed)
    instance_attrs = polygon_attrs = {}
    if hierarchy is not None:
        instance_attrs = _grown_from(hierarchy, arranged.leaf_segment, count, arranged.leaf_position, attributes)
        firsts = skeleton.polygon_points[skeleton.polygon_offsets[:-1]] if skeleton.n_polygons else np.zeros((0, 3))
        polygon_attrs = _grown_from(hierarchy, skeleton.polygon_segment, skeleton.n_polygons, firsts, attributes)
    polygons = polygon_leaves(skeleton, polygon_attrs)
    transforms = leaf_transforms(arranged)
    baked = None
    if len(transforms):
        baked = instance_leaves(leaf_model, transforms, instance_attrs, arranged.leaf_material)
    parts = [m for m in (polygons, baked) if m is not None]
    merged = Mesh.concatenate(parts) if parts else None
    material = None if arranged is skeleton else np.asarray(arranged.leaf_material, np.int32)
    return Leaves(merged, leaf_model, transforms, polygons, instance_attrs, material)


def _model(skeleton: Skeleton, model: Mesh | None, options: LeafOptions) -> Mesh:
    """The mesh every leaf instance copies: a cluster card, the grammar's model or the built-in blade."""
    if options.leaf_card != "none":
        return spray_card(card_aspect(skeleton, options), crossed=options.leaf_card == "cross")
    if model is not None:
        return model
    if options.leaf_shape == "default" and options.petiole_length == 0:
        return default_leaf(options.leaf_points)
    return blade(options.leaf_shape, options.leaf_points, options.petiole_length)


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
