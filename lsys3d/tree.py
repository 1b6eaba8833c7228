"""The generated asset: bark mesh, leaves, skeleton, counts and provenance.

This is the contract between the mesh stages and the writers in
:mod:`lsys3d.exchange`.  The writers know nothing of grammars: what they need
to name, describe or regrow the asset is :meth:`Tree.metadata` and
:attr:`Tree.name`.  Meshes are :class:`~lsys3d.mesh.mesh.Mesh` (welded vertices,
corner normals and uv, optional vertex colours).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

from .look.growth import Growth
from .look.leaves import Leaves
from .look.materials import BARK, LEAF, Material, MaterialTable
from .look.organs import Organs
from .look.rig import Rig
from .look.wind import Animation
from .lsystem.modules import ModuleString
from .mesh.mesh import Mesh
from .provenance import DEFAULT_NAME, Provenance, asset_identifier
from .turtle.hierarchy import Hierarchy
from .turtle.skeleton import Skeleton

__all__ = ["BARK", "LEAF", "Material", "StageCounts", "Tree"]


@dataclass(frozen=True)
class StageCounts:
    """What the stages before the mesh produced: modules, segments and the tubes before the union."""

    modules: int = 0
    segments: int = 0
    tubes: int = 0
    tube_vertices: int = 0
    tube_faces: int = 0

    def to_json(self) -> dict:
        return dict(sorted(asdict(self).items()))


@dataclass(frozen=True, eq=False)
class Tree:
    """One generated plant.

    Attributes
    ----------
    bark : Mesh
        The branches; one watertight 2-manifold when unioned, else the tube soup.
    skeleton : Skeleton
        The branch skeleton (for curves and statistics).
    leaves : Leaves
        Leaf polygons, the leaf model and its instance transforms, and all
        leaves merged (the fallback for formats without instancing).
    provenance : Provenance or None
        How it was grown (None for a tree assembled by hand).
    counts : StageCounts
        Modules, segments and tubes of the stages before the mesh.
    unioned : bool
        Whether ``bark`` went through the manifold union.
    modules : ModuleString or None
        The derived string: what :func:`lsys3d.derive` gives, before the homomorphism
        (interpretation) rules, the string whose length the reports count as
        ``derive.modules`` (None for trees built by hand).  The turtle reads
        ``lsys3d.lsystem.derive.interpretation(grammar, modules)``, and ``skeleton.module``
        indexes that string; the two are the same string when the grammar has no
        homomorphism rules.
    materials : MaterialTable
        The bark's and the leaves' materials, by the turtle's material index
        (:mod:`lsys3d.look.materials`; the two defaults unless the grammar has a
        ``[materials]`` table).
    hierarchy : Hierarchy or None
        The branch hierarchy, when the tree carries hierarchy and wind
        attributes (the writers write its per-branch table).
    rig : Rig or None
        The joints, when the tree is rigged; the bark and the merged leaves
        then carry their skins (:data:`lsys3d.look.rig.SKIN_KEYS`).
    organs : Organs
        Spheres, discs, boxes and named surfaces (:mod:`lsys3d.look.organs`): their
        prototypes and instances, and each prototype's organs merged.
    animation : Animation or None
        The sample wind animation of the rig's joints (:mod:`lsys3d.look.wind`), when asked for.
    growth : Growth or None
        The growth animation of the rig's joints (:mod:`lsys3d.look.growth`), when asked for.
    lods : tuple of lsys3d.look.lod.Lod
        Its levels of detail when asked for (``lod=(0, 1, 2, 3)``), level 0
        being ``bark`` and ``leaves`` themselves; empty otherwise.
    """

    bark: Mesh
    skeleton: Skeleton
    leaves: Leaves = field(default_factory=Leaves)
    provenance: Provenance | None = None
    counts: StageCounts = field(default_factory=StageCounts)
    unioned: bool = True
    modules: ModuleString | None = None
    materials: MaterialTable = field(default_factory=MaterialTable)
    hierarchy: Hierarchy | None = None
    rig: Rig | None = None
    organs: Organs = field(default_factory=Organs)
    animation: Animation | None = None
    growth: Growth | None = None
    lods: tuple = ()
    scene: tuple = ()

    @property
    def bark_material(self) -> Material:
        """The bark's default material (its segments' index without an entry of its own)."""
        return self.materials.bark

    @property
    def leaf_material(self) -> Material:
        """The leaves' default material."""
        return self.materials.leaf

    @property
    def name(self) -> str:
        """The asset's name (:attr:`Provenance.asset_name`; ``tree`` without provenance)."""
        return self.provenance.asset_name if self.provenance is not None else DEFAULT_NAME

    @property
    def identifier(self) -> str:
        """The asset's name as an identifier (USD prim names): ``abop-1.24a`` -> ``abop_1_24a``."""
        return asset_identifier(self.name)

    def metadata(self) -> dict:
        """The ``lsys3d`` block every writer records: provenance and counts, JSON-ready (empty without provenance).

        With levels of detail, ``lods`` lists each level's number and triangles.
        """
        if self.provenance is None:
            return {}
        out = {**self.provenance.to_json(), "counts": self.counts.to_json()}
        if self.lods:
            out["lods"] = [{"level": lod.level, "triangles": lod.triangles} for lod in self.lods]
        return out

    def _repr_html_(self) -> str:
        """The editor's 3D viewer showing the tree, for Jupyter: offline, three.js and the .glb inlined
        (:func:`lsys3d.edit.notebook.viewer_html`)."""
        return _notebook().viewer_html(self)

    def show(self, height: int = 480):
        """Show the tree in the editor's 3D viewer: inline in a notebook, else in the default browser
        (:func:`lsys3d.edit.notebook.show`; returns the HTML file written then, or None)."""
        return _notebook().show(self, height)

    def at_level(self, index: int) -> Tree:
        """The tree with the bark and leaves of ``lods[index]`` and no levels: what a writer writes per level."""
        lod = self.lods[index]
        return replace(self, bark=lod.bark, leaves=lod.leaves, lods=())


def _notebook():
    """:mod:`lsys3d.edit.notebook`, loaded when a tree is shown: the viewer comes after the writers."""
    from .edit import notebook

    return notebook
