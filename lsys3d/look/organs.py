"""Organs: spheres, discs, boxes and named surfaces placed by the turtle, as instanced prototypes.

The dialects record organs in the skeleton -- cpfg's and L-Py's ``@O``
(sphere), ``@c``/``@o`` (disc, circle), L-Py's ``@B`` (box) and the named
surfaces ``~name`` -- each with a position, a turtle frame, a size and a
material index.  :func:`organs` turns such a record, given as plain arrays,
into geometry: one *prototype* mesh per kind, placed by a transform per organ,
exactly as leaves are (:mod:`lsys3d.look.leaves`); the writers export them as
instances (USD ``PointInstancer`` prototypes, glTF ``EXT_mesh_gpu_instancing``)
or merged, one part per prototype (``organ_sphere``, ``organ_flower``...).

Prototypes live in the leaf-model frame (``x`` = left, ``y`` = up, ``z`` =
heading), and an organ's ``size`` scales its prototype uniformly:

========== ======================================================================= ============
name       prototype                                                                size means
========== ======================================================================= ============
``sphere`` an icosphere of diameter 1 centred on the turtle (closed)               diameter
``disc``   a disc of diameter 1 centred on the turtle, in the plane of H and L,    diameter
           facing U (``+y``), like a leaf (a sheet)
``circle`` the same disc (L-Py's ``@o``)                                            diameter
``box``    a cube of edge 1 standing on the turtle, along H (closed)                edge
any other the grammar's ``[surfaces]`` model of that name (:mod:`lsys3d.look.surfaces`);  scale
           without one, the leaf model (the grammar's or the built-in blade)
========== ======================================================================= ============

A ``[surfaces]`` entry named ``sphere``, ``disc``, ``circle`` or ``box``
replaces that built-in.  Organs take the leaf materials (the turtle's index,
:meth:`lsys3d.look.materials.MaterialTable.for_leaf`); a card surface brings its
own textured material.  With the skeleton's branch hierarchy, organs carry the
attributes of the branch they grow from (:mod:`lsys3d.look.attributes`), and a rig
binds them rigidly like leaves (:func:`bind_organs`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import GeometryError, LimitError
from ..mesh.mesh import Mesh, face_normals
from ..mesh.sweep import DEFAULT_MAX_TRIANGLES
from ..options import Options, option
from ..turtle.commands import BUILT_IN_ORGANS
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import organ_names
from .leaves import _grown_from, default_leaf, instance_leaves
from .materials import Material
from .rig import skin_weights

__all__ = [
    "BUILT_IN",
    "OrganOptions",
    "Organs",
    "Prototype",
    "bind_organs",
    "box",
    "disc",
    "organs",
    "skeleton_organs",
    "sphere",
    "uv_sphere",
]

log = logging.getLogger("lsys3d")


@dataclass(frozen=True)
class OrganOptions(Options):
    """The resolution of the built-in organ prototypes."""

    sphere_subdivisions: int = option(
        1, low=0, high=5, help="subdivisions of the organs' icosphere (0: 20 triangles, 1: 80, 2: 320)"
    )
    disc_sides: int = option(16, low=3, high=256, help="sides of the organs' disc")


# ---------------------------------------------------------------- prototypes


def sphere(subdivisions: int = 1) -> Mesh:
    """An icosphere of diameter 1 centred at the origin: ``20 * 4**subdivisions`` triangles, smooth normals.

    uv: longitude and latitude (``u`` around ``z`` from ``+x``, ``v`` from the ``-z`` pole to the ``+z`` one),
    with the seam's corners on the far side of 1 so no triangle smears the image.

    >>> m = sphere(1)
    >>> len(m.faces), m.is_watertight, round(float(np.linalg.norm(m.vertices, axis=1).max()), 6)
    (80, True, 0.5)
    """
    t = (1 + 5**0.5) / 2
    v = np.array(
        [
            *([-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t]),
            *([0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]),
        ],
        np.float64,
    )
    f = np.array(
        [
            *([0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2]),
            *([10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5]),
            *([2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]),
        ],
        np.int64,
    )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):  # split each triangle in four, midpoints shared between neighbours
        edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = v[unique].mean(axis=1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = (len(v) + inverse.reshape(-1, 3)).astype(np.int64)
        v = np.concatenate([v, mid])
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
        f = np.concatenate([np.stack(x, axis=1) for x in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))], axis=0)
    if (np.einsum("ij,ij->i", face_normals(v, f), v[f].mean(axis=1)) < 0).any():  # pragma: no cover
        raise AssertionError("sphere: a face turns inward")
    normals = v[f]  # a unit sphere: the normal is the position
    return Mesh(v * 0.5, f, normals, _sphere_uv(v, f))


def _sphere_uv(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Each corner's uv on a unit sphere: longitude (``u``, 0 to 1 about ``z``) and latitude (``v``, 0 at the
    ``-z`` pole), each triangle's ``u`` continuous from its first corner, so none spans the seam the long way
    round."""
    u = (np.arctan2(v[:, 1], v[:, 0]) / (2 * np.pi)) % 1.0
    lat = np.arcsin(np.clip(v[:, 2], -1, 1)) / np.pi + 0.5
    uv = np.stack([u, lat], axis=1)[f]
    uv[:, 1:, 0] = uv[:, :1, 0] + (uv[:, 1:, 0] - uv[:, :1, 0] + 0.5) % 1.0 - 0.5
    uv[uv[:, :, 0].min(axis=1) < 0, :, 0] += 1.0
    return uv


def uv_sphere(slices: int) -> Mesh:
    """cpfg's sphere of ``@!(slices)``: OpenGL's ``gluSphere`` of diameter 1, ``slices`` around the ``z`` axis and
    ``slices // 2 + 1`` stacks from pole to pole, ``2 slices (stacks - 1)`` triangles, smooth normals.

    >>> m = uv_sphere(7)
    >>> len(m.faces), m.is_watertight, round(float(np.linalg.norm(m.vertices, axis=1).max()), 6)
    (42, True, 0.5)
    """
    stacks = slices // 2 + 1
    theta = np.pi * np.arange(1, stacks) / stacks  # from the +z pole: the rings between the poles
    phi = 2 * np.pi * np.arange(slices) / slices
    ring = np.stack(
        [
            np.outer(np.sin(theta), np.cos(phi)),
            np.outer(np.sin(theta), np.sin(phi)),
            np.repeat(np.cos(theta), slices).reshape(-1, slices),
        ],
        axis=2,
    ).reshape(-1, 3)
    v = np.concatenate([[[0.0, 0.0, 1.0]], ring, [[0.0, 0.0, -1.0]]])
    i = np.arange(slices)
    j = (i + 1) % slices
    south = len(v) - 1
    faces = [np.stack([np.zeros(slices, np.int64), 1 + i, 1 + j], axis=1)]  # the +z cap, counter-clockwise outside
    for r in range(stacks - 2):
        a, b = 1 + r * slices, 1 + (r + 1) * slices
        faces.append(np.stack([a + i, b + i, b + j], axis=1))
        faces.append(np.stack([a + i, b + j, a + j], axis=1))
    last = 1 + (stacks - 2) * slices
    faces.append(np.stack([np.full(slices, south), last + j, last + i], axis=1))
    f = np.concatenate(faces).astype(np.int64)
    if (np.einsum("ij,ij->i", face_normals(v, f), v[f].mean(axis=1)) < 0).any():  # pragma: no cover
        raise AssertionError("uv_sphere: a face turns inward")
    return Mesh(v * 0.5, f, v[f], _sphere_uv(v, f))


def disc(sides: int = 16) -> Mesh:
    """A disc of diameter 1 centred at the origin in the ``x``-``z`` plane, facing ``+y``: ``sides`` triangles.

    >>> m = disc(8)
    >>> len(m.faces), m.bounds.round(3).tolist(), bool((m.face_normals[:, 1] > 0.999).all())
    (8, [[-0.5, 0.0, -0.5], [0.5, 0.0, 0.5]], True)
    """
    angle = 2 * np.pi * np.arange(sides) / sides
    rim = np.stack([0.5 * np.sin(angle), np.zeros(sides), 0.5 * np.cos(angle)], axis=1)
    vertices = np.concatenate([[[0.0, 0.0, 0.0]], rim])
    i = np.arange(sides)
    faces = np.stack([np.zeros(sides, np.int64), 1 + i, 1 + (i + 1) % sides], axis=1)  # counter-clockwise from +y
    uv = (vertices[:, [0, 2]] + 0.5)[faces]
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (sides, 3, 3))
    return Mesh(vertices, faces, normals, uv)


def box() -> Mesh:
    """A cube of edge 1 standing on the origin along ``+z`` (``x``, ``y`` in [-0.5, 0.5]), flat shaded.

    >>> m = box()
    >>> len(m.faces), m.is_watertight, m.bounds.tolist()
    (12, True, [[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]])
    """
    cube = Mesh.box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    # each face's uv: its two in-plane axes, over [0, 1]
    tri = cube.vertices[cube.faces]
    axis = np.abs(cube.face_normals).argmax(axis=1)
    plane = np.array([[1, 2], [0, 2], [0, 1]])[axis]
    lo = np.array([-0.5, -0.5, 0.0])
    uv = np.take_along_axis(tri - lo, plane[:, None, :].repeat(3, axis=1), axis=2)
    return replace(cube, uv=uv)


BUILT_IN = tuple(BUILT_IN_ORGANS.values())
"""The organs with built-in prototypes (a ``[surfaces]`` entry of the same name replaces one)."""


def _built_in(name: str, options: OrganOptions, sides: int = 0) -> Mesh:
    """The built-in prototype ``name``; ``sides`` > 0: the grammar's (cpfg's ``@!``) for a sphere or disc."""
    if name == "sphere":
        return uv_sphere(sides) if sides else sphere(options.sphere_subdivisions)
    if name in ("disc", "circle"):
        return disc(sides or options.disc_sides)
    return box()


_ROUND = ("sphere", "disc", "circle")
"""The built-in organs a grammar's sides (cpfg's ``@!``) tessellate; their prototype is named ``sphere-12``."""


def _with_sides(kind: np.ndarray, sides) -> np.ndarray:
    """Each round organ's name with the grammar's sides (``sphere-12``): one prototype per number of sides."""
    if sides is None:
        return kind
    sides = np.asarray(sides, np.int64).reshape(-1)
    if sides.shape != kind.shape:
        raise GeometryError(f"organs: sides has shape {sides.shape}, expected {kind.shape} (one per organ)")
    round_ = np.isin(kind, _ROUND) & (sides > 0)
    if not round_.any():
        return kind
    named = np.char.add(np.char.add(kind, "-"), sides.astype(str))
    return np.where(round_, named, kind)


def _split_sides(name: str) -> tuple[str, int]:
    """``sphere-12`` -> (``sphere``, 12); any other name -> (name, 0)."""
    base, _, n = name.rpartition("-")
    return (base, int(n)) if base in _ROUND and n.isdigit() else (name, 0)


# ---------------------------------------------------------------- organs


@dataclass(frozen=True, eq=False)
class Prototype:
    """One kind of organ: its name, its mesh (leaf-model frame), whether it is a closed solid, a card's material.

    ``material`` is None unless the surface is a card, whose textured material
    every organ of this kind then uses (instead of its material index's).
    """

    name: str
    mesh: Mesh
    closed: bool
    material: Material | None = None


@dataclass(frozen=True, eq=False)
class Organs:
    """Every organ of a tree: prototypes, and per organ its prototype, transform and material index.

    Attributes
    ----------
    prototypes : tuple of Prototype
    prototype : (k,) int64
        Which prototype each organ is.
    transforms : (k, 4, 4) float64
        Rotation columns left, up, heading scaled by the size; translation the position.
    material : (k,) int32
        The turtle's material index of each organ.
    instance_attributes : dict of str to (k,) or (k, 3) float32
        The hierarchy and wind attributes of the branch each organ grows from (empty unless asked for).
    merged : tuple of (Mesh or None)
        Per prototype, its organs baked in place (face_material set): the parts
        written when organs are not instanced.
    fallbacks : tuple of str
        Named surfaces without a ``[surfaces]`` entry, drawn as the leaf model.
    """

    prototypes: tuple[Prototype, ...] = ()
    prototype: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    transforms: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    material: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    instance_attributes: Mapping[str, np.ndarray] = field(default_factory=dict)
    merged: tuple[Mesh | None, ...] = ()
    fallbacks: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.prototype)

    def of(self, p: int) -> np.ndarray:
        """The organs of prototype ``p`` (indices)."""
        return np.flatnonzero(self.prototype == p)


def organs(
    kind: Sequence[str],
    position,
    frame,
    size,
    material=None,
    *,
    surfaces=None,
    options: OrganOptions | None = None,
    segment=None,
    hierarchy: Hierarchy | None = None,
    attributes=None,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    scale=None,
    sides=None,
) -> Organs:
    """Build the organs recorded by the turtle, from plain arrays.

    Parameters
    ----------
    kind : (k,) str
        Each organ's name: ``sphere``, ``disc``, ``circle``, ``box``, or a
        surface's name (``flower`` for ``~flower``).
    position : (k, 3) float
    frame : (k, 3, 3) float
        The turtle's frame at each organ, as columns left, up, heading
        (``np.stack([left, up, heading], axis=2)``).
    size : (k,) float
        The scale of each prototype (the diameter of a sphere or disc, the edge
        of a box, the scale of a surface); organs of size 0 are left out.
    material : (k,) int, optional
        The turtle's material index of each organ (default 0).
    surfaces : SurfaceTable, optional
        The grammar's ``[surfaces]`` (:func:`lsys3d.look.surfaces.surface_table`).
    options : OrganOptions, optional
        The built-in prototypes' resolution.
    segment : (k,) int, optional
        The segment each organ grows from (-1: none), for the attributes.
    hierarchy : Hierarchy, optional
        The skeleton's branch hierarchy: organs then carry its attributes.
    attributes : sequence of str, optional
        Which attributes (default all).
    max_triangles : int
        Most triangles of the organs baked in place.
    scale : (k, 3) float, optional
        Each organ's scale along left, up and heading relative to ``size`` (cpfg's ``~l(sx, sy, sz)``);
        default uniform.
    sides : (k,) int, optional
        The grammar's sides of each organ (cpfg's ``@!``; 0: the options'): a sphere of ``n`` sides is
        cpfg's ``n`` slices by ``n // 2 + 1`` stacks (:func:`uv_sphere`), a disc or circle ``n`` sides; its
        prototype is named ``sphere-n`` (a ``[surfaces]`` entry ``sphere`` replaces it all the same).

    Raises
    ------
    GeometryError
        Arrays of the wrong shape, or positions, frames or sizes that are not finite.
    LimitError
        The baked organs would have more than ``max_triangles`` triangles.

    Examples
    --------
    >>> frame = np.broadcast_to(np.eye(3), (3, 3, 3))
    >>> o = organs(["sphere", "disc", "sphere"], np.zeros((3, 3)), frame, [0.1, 0.2, 0.3])
    >>> [p.name for p in o.prototypes], o.prototype.tolist(), [len(m.faces) for m in o.merged]
    (['disc', 'sphere'], [1, 0, 1], [16, 160])
    """
    options = options or OrganOptions()
    kind = _with_sides(np.asarray(kind, dtype=str).reshape(-1), sides)
    k = len(kind)
    position = np.asarray(position, np.float64)
    frame = np.asarray(frame, np.float64)
    size = np.asarray(size, np.float64).reshape(-1)
    material = np.zeros(k, np.int32) if material is None else np.asarray(material, np.int32).reshape(-1)
    shapes = {"position": (position.shape, (k, 3)), "frame": (frame.shape, (k, 3, 3))}
    shapes |= {"size": (size.shape, (k,)), "material": (material.shape, (k,))}
    axes = np.ones((k, 3)) if scale is None else np.asarray(scale, np.float64)
    shapes["scale"] = (axes.shape, (k, 3))
    for name, (got, want) in shapes.items():
        if got != want:
            raise GeometryError(f"organs: {name} has shape {got}, expected {want} (one per organ)")
    finite = np.isfinite(position).all() and np.isfinite(frame).all() and np.isfinite(size).all()
    if not (finite and np.isfinite(axes).all()):
        raise GeometryError("organs: a position, frame or size is not a finite number")
    keep = size > 0
    if not keep.all():
        log.info("organs: %d of size 0 left out", int((~keep).sum()))
    idx = np.flatnonzero(keep)
    kind, position, frame, size, material = kind[idx], position[idx], frame[idx], size[idx], material[idx]
    axes = axes[idx]
    instance_attributes = {}
    if hierarchy is not None:
        seg = None if segment is None else np.asarray(segment, np.int64).reshape(-1)[idx]
        instance_attributes = _grown_from(hierarchy, seg, len(idx), position, attributes)

    names, which = np.unique(kind, return_inverse=True)
    prototypes, fallbacks = [], []
    leaf = surfaces.leaf if surfaces is not None else None
    for name in names.tolist():
        base, n_sides = _split_sides(name)
        surface = surfaces.get(base) if surfaces is not None else None
        if surface is not None:
            mesh, card = surface.mesh, surface
        elif base in BUILT_IN:
            mesh, card = _built_in(base, options, n_sides), None
        else:  # a named surface without a model: drawn as the leaf (ABOP's predefined surfaces are leaves, petals)
            fallbacks.append(name)  # with the leaf materials, a leaf card's texture among them (with_cards)
            mesh, card = (leaf.mesh if leaf is not None else default_leaf()), None
        material_of_card = None
        if card is not None and card.is_card:
            material_of_card = Material(
                name, (1.0, 1.0, 1.0, 1.0), 0.6, 0.0, True, texture=card.image, alpha_cutoff=card.alpha_cutoff
            )
        closed = mesh.is_watertight and mesh.is_winding_consistent
        prototypes.append(Prototype(name, mesh, closed, material_of_card))
    if fallbacks:  # lsys3d.turtle.diagnostics warns of them once, with the grammar's name (--strict: an error)
        log.info("organs: no [surfaces] model for %s: drawn as the leaf", ", ".join(repr(f) for f in sorted(fallbacks)))

    transforms = np.zeros((len(idx), 4, 4))
    transforms[:, :3, :3] = frame * (size[:, None] * axes)[:, None, :]
    transforms[:, :3, 3] = position
    transforms[:, 3, 3] = 1.0
    counts = np.bincount(which, minlength=len(prototypes))
    total = int(sum(int(c) * len(p.mesh.faces) for c, p in zip(counts, prototypes, strict=True)))
    if total > max_triangles:
        raise LimitError(
            f"organs: {len(idx):,} organs make {total:,} triangles, more than the limit of {max_triangles:,}; "
            "use smaller models or fewer organs, or raise the limit (--max-triangles, or max_triangles=)"
        )
    merged = []
    for p, proto in enumerate(prototypes):
        mine = np.flatnonzero(which == p)
        attrs = {key: np.asarray(a)[mine] for key, a in instance_attributes.items()}
        merged.append(instance_leaves(proto.mesh, transforms[mine], attrs, material[mine]))
    return Organs(
        prototypes=tuple(prototypes),
        prototype=which.astype(np.int64),
        transforms=transforms,
        material=material,
        instance_attributes=instance_attributes,
        merged=tuple(merged),
        fallbacks=tuple(sorted(fallbacks)),
    )


def bind_organs(organs_: Organs, rig, h: Hierarchy) -> Organs:
    """``organs_`` with skins on their merged meshes, each organ bound rigidly to its branch's joint (as leaves).

    The merged meshes must carry ``branch_id`` and ``branch_t`` (build the organs with the hierarchy).
    """
    merged = []
    for mesh in organs_.merged:
        if mesh is None or not len(mesh.vertices) or "branch_id" not in mesh.attributes:
            merged.append(mesh)
            continue
        joints, weights = skin_weights(rig, h, mesh.attributes["branch_id"], mesh.attributes["branch_t"], rigid=True)
        merged.append(mesh.with_attributes({"skin_joints": joints.astype(np.float32), "skin_weights": weights}))
    return replace(organs_, merged=tuple(merged))


def skeleton_organs(
    skeleton,
    *,
    surfaces=None,
    options: OrganOptions | None = None,
    hierarchy: Hierarchy | None = None,
    attributes: Sequence[str] | None = None,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
) -> Organs:
    """The organs the turtle recorded in ``skeleton`` (its ``organ_*`` arrays), built by :func:`organs`."""
    if not skeleton.n_organs:
        return Organs()
    frame = np.stack([skeleton.organ_left, skeleton.organ_up, skeleton.organ_heading], axis=2)
    return organs(
        organ_names(skeleton),
        skeleton.organ_position,
        frame,
        skeleton.organ_size,
        skeleton.organ_material,
        surfaces=surfaces,
        options=options,
        segment=skeleton.organ_segment,
        hierarchy=hierarchy,
        attributes=attributes,
        max_triangles=max_triangles,
        scale=skeleton.organ_scale,
        sides=skeleton.organ_sides,
    )
