"""The mesh that passes between the stages: welded triangles with per-corner shading attributes.

The union, the bark colouring and the leaves produce :class:`Mesh`; the
writers in :mod:`lsys3d.exchange` read it.  It is plain arrays and nothing
else: trimesh appears only at the edges, where trimesh does the work
(:meth:`Mesh.to_trimesh` for its OBJ/PLY/STL writers and for users' tools).

Vertices are *welded* (a unioned bark is watertight by its face indices) and
the shading attributes live on the face corners, so a seam or a crease needs no
duplicated vertex:

``normals`` : (f, 3, 3) float32
    Unit normal at each corner of each face (smooth around a tube, sharp at caps).
``uv`` : (f, 3, 2) float32
    Texture coordinates at each corner (bark: u around the tube in [0, 1], v
    along the chain in metres; leaves: the leaf's box mapped onto [0, 1]^2).
``colors`` : (v, 3) float32 or None
    Linear RGB in [0, 1] per vertex (bark colour variation, :mod:`lsys3d.look.bark`).
    Where present it is the surface colour in place of the material's base
    colour: glTF ``COLOR_0`` with a white base colour factor, USD
    ``primvars:displayColor`` read by the material.
``face_material`` : (f,) int32 or None
    The turtle's material index of each face (:mod:`lsys3d.look.materials`); None
    when the tree has one material per mesh.
``attributes`` : mapping of name to (v,) or (v, 3) float32
    Per-vertex data the writers carry as they are: the hierarchy and wind
    attributes of :mod:`lsys3d.look.attributes` (glTF ``_BRANCH_ID``..., USD
    ``primvars:branch_id``...).  Empty by default.
``face_source`` : (f,) int64 or None
    For a bark: the face of :attr:`lsys3d.mesh.sweep.Tubes.faces` each triangle is a
    piece of (the union carries manifold3d's face ids through the boolean), so
    later stages know the tube, span and branch of every triangle
    (:mod:`lsys3d.mesh.cleanup` finds the junction seams by it).  None when unknown.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType

import numpy as np

from ..arrays import components

__all__ = ["Mesh"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """Welded triangles with corner normals, corner uv and optional vertex colours.

    Attributes
    ----------
    vertices : (v, 3) float64
    faces : (f, 3) int64
        Counter-clockwise seen from outside.
    normals : (f, 3, 3) float32
    uv : (f, 3, 2) float32
    colors : (v, 3) float32 or None
    attributes : dict of str to (v,) or (v, 3) float32
    face_material : (f,) int32 or None
    face_source : (f,) int64 or None
    face_box_uv : (f,) float32 or None
        Tiles per metre of the box projection that gives a face its uv, 0 where its uv is
        its source tube's chart (a blob's crowd, :mod:`lsys3d.mesh.union.blob_uv`); None: no face has one.

    Examples
    --------
    >>> m = Mesh.box()
    >>> len(m.vertices), len(m.faces), m.is_watertight, m.is_winding_consistent, round(m.volume, 6)
    (8, 12, True, True, 1.0)
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    colors: np.ndarray | None = None
    attributes: Mapping[str, np.ndarray] = field(default_factory=dict)
    face_material: np.ndarray | None = None
    face_source: np.ndarray | None = None
    face_box_uv: np.ndarray | None = None

    def __post_init__(self):
        v = np.asarray(self.vertices, np.float64).reshape(-1, 3)
        f = np.asarray(self.faces, np.int64).reshape(-1, 3)
        n = np.asarray(self.normals, np.float32).reshape(len(f), 3, 3)
        uv = np.asarray(self.uv, np.float32).reshape(len(f), 3, 2)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "normals", n)
        object.__setattr__(self, "uv", uv)
        if self.colors is not None:
            c = np.asarray(self.colors, np.float32)
            if c.shape != (len(v), 3):
                raise ValueError(f"Mesh.colors has shape {c.shape}, expected ({len(v)}, 3)")
            object.__setattr__(self, "colors", c)
        attributes = {}
        for name, values in dict(self.attributes).items():
            a = np.ascontiguousarray(values, np.float32)
            if a.shape[:1] != (len(v),) or a.ndim > 2:
                raise ValueError(
                    f"Mesh.attributes[{name!r}] has shape {a.shape}, expected ({len(v)},) or ({len(v)}, k)"
                )
            attributes[name] = a
        object.__setattr__(self, "attributes", MappingProxyType(attributes))
        if self.face_material is not None:
            fm = np.asarray(self.face_material, np.int32)
            if fm.shape != (len(f),):
                raise ValueError(f"Mesh.face_material has shape {fm.shape}, expected ({len(f)},)")
            object.__setattr__(self, "face_material", fm)
        if self.face_source is not None:
            s = np.asarray(self.face_source, np.int64)
            if s.shape != (len(f),):
                raise ValueError(f"Mesh.face_source has shape {s.shape}, expected ({len(f)},)")
            object.__setattr__(self, "face_source", s)
        if self.face_box_uv is not None:
            d = np.asarray(self.face_box_uv, np.float32)
            if d.shape != (len(f),):
                raise ValueError(f"Mesh.face_box_uv has shape {d.shape}, expected ({len(f)},)")
            object.__setattr__(self, "face_box_uv", d)

    # ---------------------------------------------------------------- construction
    @classmethod
    def empty(cls) -> Mesh:
        """A mesh without vertices or faces (the bark of a tree of polygon leaves alone)."""
        return cls(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3, 3)), np.zeros((0, 3, 2)))

    @classmethod
    def flat(cls, vertices, faces, uv=None) -> Mesh:
        """A mesh whose corners take their face's normal (flat shading); uv 0 unless given."""
        vertices = np.asarray(vertices, np.float64)
        faces = np.asarray(faces, np.int64)
        fn = face_normals(vertices, faces)
        normals = np.repeat(fn[:, None, :], 3, axis=1)
        return cls(vertices, faces, normals, np.zeros((len(faces), 3, 2)) if uv is None else uv)

    @classmethod
    def box(cls, lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)) -> Mesh:
        """An axis-aligned box, flat shaded (for tests and examples)."""
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        corner = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], np.float64)
        vertices = lo + corner * (hi - lo)
        faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1]]
        faces += [[2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
        return cls.flat(vertices, faces)

    @classmethod
    def concatenate(cls, meshes) -> Mesh:
        """Several meshes as one (indices shifted; colours kept only when every part has them, face sources never)."""
        meshes = [m for m in meshes if m is not None]
        if not meshes:
            return cls.empty()
        if len(meshes) == 1:
            return meshes[0]
        shift = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        colors = None
        if all(m.colors is not None for m in meshes):
            colors = np.concatenate([m.colors for m in meshes])
        shared = set.intersection(*(set(m.attributes) for m in meshes))
        face_material = None
        if any(m.face_material is not None for m in meshes):
            face_material = np.concatenate(
                [m.face_material if m.face_material is not None else np.zeros(len(m.faces), np.int32) for m in meshes]
            )
        return cls(
            np.concatenate([m.vertices for m in meshes]),
            np.concatenate([m.faces + s for m, s in zip(meshes, shift, strict=True)]),
            np.concatenate([m.normals for m in meshes]),
            np.concatenate([m.uv for m in meshes]),
            colors,
            {k: np.concatenate([m.attributes[k] for m in meshes]) for k in sorted(shared)},
            face_material,
        )

    @classmethod
    def from_trimesh(cls, mesh) -> Mesh:
        """A ``trimesh.Trimesh`` (a user's leaf model, say) as a Mesh.

        Its ``corner_normals`` / ``corner_uv`` face attributes are kept when it
        has them; otherwise corners take their face's normal (flat shading) and
        the per-vertex uv of its texture visuals (or 0).
        """
        vertices = np.asarray(mesh.vertices, np.float64)
        faces = np.asarray(mesh.faces, np.int64)
        attrs = getattr(mesh, "face_attributes", None) or {}
        normals = attrs.get("corner_normals")
        if normals is None:
            normals = np.repeat(face_normals(vertices, faces)[:, None, :], 3, axis=1)
        uv = attrs.get("corner_uv")
        if uv is None:
            vertex_uv = getattr(getattr(mesh, "visual", None), "uv", None)
            uv = np.asarray(vertex_uv)[faces] if vertex_uv is not None and len(vertex_uv) == len(vertices) else None
        return cls(vertices, faces, normals, np.zeros((len(faces), 3, 2)) if uv is None else uv)

    def with_colors(self, colors) -> Mesh:
        """A copy with vertex colours (arrays are shared, not copied)."""
        return replace(self, colors=colors)

    def with_attributes(self, attributes: Mapping[str, np.ndarray]) -> Mesh:
        """A copy with these per-vertex attributes added (arrays are shared, not copied)."""
        return replace(self, attributes={**self.attributes, **attributes})

    def keeping(self, keys) -> Mesh:
        """A copy with only the attributes ``keys`` (of those it has)."""
        return replace(self, attributes={k: a for k, a in self.attributes.items() if k in keys})

    # ---------------------------------------------------------------- measures
    @property
    def is_empty(self) -> bool:
        return len(self.faces) == 0

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 3)``: min and max corner of the vertices (zeros when empty)."""
        if not len(self.vertices):
            return np.zeros((2, 3))
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def face_areas(self) -> np.ndarray:
        """Area of each triangle, ``(f,) float64``."""
        tri = self.vertices[self.faces]
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @property
    def area(self) -> float:
        """Surface area."""
        return float(self.face_areas.sum())

    @property
    def volume(self) -> float:
        """Enclosed volume (divergence theorem; meaningful for a closed, outward mesh)."""
        if self.is_empty:
            return 0.0
        tri = self.vertices[self.faces]
        return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)

    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Undirected edge keys sorted, and for each the direction it was used in (+1 low->high, -1 back)."""
        e = self.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        lo, hi = e.min(axis=1), e.max(axis=1)
        n = max(len(self.vertices), 1)
        key = lo * n + hi
        order = np.argsort(key, kind="stable")
        return key[order], np.where(e[order, 0] < e[order, 1], 1, -1)

    @property
    def is_watertight(self) -> bool:
        """Every edge shared by exactly two faces (the meaning trimesh gives it)."""
        if self.is_empty:
            return False
        key, _ = self._edges()
        _, counts = np.unique(key, return_counts=True)
        return bool((counts == 2).all())

    @property
    def is_winding_consistent(self) -> bool:
        """Every edge shared by two faces is walked in opposite directions by them."""
        if self.is_empty:
            return False
        key, direction = self._edges()
        _, first, counts = np.unique(key, return_index=True, return_counts=True)
        pairs = first[counts == 2]
        return bool((direction[pairs] + direction[pairs + 1] == 0).all())

    @property
    def face_normals(self) -> np.ndarray:
        """Unit normal of each face, ``(f, 3) float64`` (zero for degenerate faces)."""
        return face_normals(self.vertices, self.faces)

    # ---------------------------------------------------------------- edges of the house
    def to_trimesh(self):
        """A ``trimesh.Trimesh`` of the same vertices and faces (attributes as ``face_attributes``)."""
        import trimesh

        mesh = trimesh.Trimesh(
            self.vertices,
            self.faces,
            face_attributes={"corner_normals": self.normals, "corner_uv": self.uv},
            process=False,
            validate=False,
        )
        if self.colors is not None:
            mesh.vertex_attributes["vertex_color"] = self.colors
        return mesh


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normal of each triangle, ``(f, 3) float64``; zero for degenerate triangles."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


_CRUMB_CHUNK = 1 << 16
"""Faces per chunk of :func:`crumbs`' sums (no (f, 3, 3) temporaries)."""


def crumbs(vertices: np.ndarray, faces: np.ndarray, smallest: float, inside_out: bool = False) -> np.ndarray:
    """``(f,) bool``: the faces of the closed pieces of a mesh that enclose (almost) nothing: a boolean's crumbs.

    Where several tubes meet at almost one point, or coplanar tubes cross,
    a boolean can leave beside the plant a few separate pieces of 4-6
    triangles that enclose no volume.  A piece is a crumb when it is both
    small (area under ``smallest`` times the whole mesh's) and flat (volume
    under 1e-3 area^1.5, where a thin tube's ratio is near 0.2 sqrt(r / L)):
    real parts of a plant (a separate branch after an ``f`` move) stay.  With
    ``inside_out``, a piece of negative volume counts as flat too.
    """
    faces = np.asarray(faces)
    label = components(len(vertices), faces.ravel(), np.roll(faces, -1, axis=1).ravel())
    piece = label[faces[:, 0]]
    if not len(piece) or (piece == piece[0]).all():  # one piece (most meshes): no sort
        return np.zeros(len(faces), bool)
    names, face_piece = np.unique(piece, return_inverse=True)
    volume, area = np.zeros(len(names)), np.zeros(len(names))
    for start in range(0, len(faces), _CRUMB_CHUNK):
        part = slice(start, start + _CRUMB_CHUNK)
        tri = np.asarray(vertices, np.float64)[faces[part]]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
        volume += np.bincount(face_piece[part], weights=six / 6.0, minlength=len(names))
        area += np.bincount(face_piece[part], weights=0.5 * np.linalg.norm(cross, axis=1), minlength=len(names))
    flat = (volume if inside_out else np.abs(volume)) < 1e-3 * area**1.5
    return ((area < smallest * area.sum()) & flat)[face_piece]
