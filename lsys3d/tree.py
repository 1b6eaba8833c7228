"""The generated asset: bark mesh, leaves, skeleton and provenance.

This is the contract between the mesh stages and the writers in
:mod:`lsys3d.exchange`.  The writers know nothing of grammars; everything they
need to reproduce or describe the asset is in :attr:`Tree.provenance`.

Meshes are ``trimesh.Trimesh`` objects with *welded* vertices (so a unioned
bark is watertight) and per-face-corner shading attributes in
``mesh.face_attributes``:

``corner_normals`` : (f, 3, 3) float32
    Unit normal at each corner of each face (smooth around a tube, sharp at caps).
``corner_uv`` : (f, 3, 2) float32
    Texture coordinates at each corner: u around the tube in [0, 1], v along
    the chain in metres.

and, optionally, per-vertex colours in ``mesh.vertex_attributes``:

``vertex_color`` : (v, 3) float32
    Linear RGB in [0, 1] at each vertex (bark colour variation,
    :mod:`lsys3d.bark`).  Where present it is the surface colour in place of
    the material's base colour: glTF ``COLOR_0`` with a white base colour
    factor, USD ``primvars:displayColor`` read by the material.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from .modules import ModuleString
from .skeleton import Skeleton

__all__ = ["Material", "Tree"]


@dataclass(frozen=True)
class Material:
    """A PBR material: linear base colour (RGBA), roughness, double-sidedness."""

    name: str
    base_color: tuple[float, float, float, float]
    roughness: float = 0.8
    metallic: float = 0.0
    double_sided: bool = False


BARK = Material("bark", (0.30, 0.20, 0.12, 1.0), roughness=0.9)
LEAF = Material("leaf", (0.18, 0.45, 0.10, 1.0), roughness=0.6, double_sided=True)


@dataclass(frozen=True, eq=False)
class Tree:
    """One generated plant.

    Attributes
    ----------
    bark : trimesh.Trimesh
        The branches; one watertight 2-manifold when unioned, else the tube soup.
    leaves : trimesh.Trimesh or None
        All leaves merged into one flat mesh (polygon leaves plus every leaf
        instance baked in place): the fallback for formats without instancing.
    leaf_model : trimesh.Trimesh or None
        The one leaf model that ``leaf_transforms`` place (instanced leaves).
    leaf_transforms : (k, 4, 4) float64
        World transforms of the leaf instances (rotation columns = left, up,
        heading scaled by the leaf size; translation = position).
    polygon_leaves : trimesh.Trimesh or None
        The leaves drawn as polygons with ``{ . }`` (not instanced).
    skeleton : Skeleton
        The branch skeleton (for curves and statistics).
    provenance : dict
        JSON-serialisable: grammar name and text, iterations, seed, options,
        lsys3d version; written into every export.
    unioned : bool
        Whether ``bark`` went through the manifold union.
    modules : ModuleString or None
        The derived string the turtle read (None for trees built by hand).
    """

    bark: trimesh.Trimesh
    skeleton: Skeleton
    provenance: dict = field(default_factory=dict)
    leaves: trimesh.Trimesh | None = None
    leaf_model: trimesh.Trimesh | None = None
    leaf_transforms: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    polygon_leaves: trimesh.Trimesh | None = None
    unioned: bool = True
    bark_material: Material = BARK
    leaf_material: Material = LEAF
    modules: ModuleString | None = None
