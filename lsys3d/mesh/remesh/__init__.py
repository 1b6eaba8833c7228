"""Local remeshing of a closed triangle mesh: edge collapses, flips and splits that keep it closed.

The numba kernels behind :mod:`lsys3d.mesh.cleanup`, one operation a module: ``halfedge`` (the mesh type, its
building, compacting and walking), ``geometry``, ``collapse``, ``flip``, ``split``, ``clean`` (the driver),
``rescue``, ``collar``, ``fair``, ``normals`` and ``tube_faces``.  The mesh is held as
half-edges in flat arrays (:class:`HalfEdges`): half-edge ``3 f + k`` runs
from corner ``k`` of face ``f`` to corner ``k + 1``; ``opp`` pairs it with
the half-edge running the other way.  Every operation keeps the mesh a
closed, consistently oriented 2-manifold:

* an **edge collapse** merges the two ends of an edge only when their
  neighbourhoods share exactly the two vertices across the edge (the *link
  condition*), both vertices across keep at least three neighbours, and no
  face around turns away from the surface it lies on;
* an **edge flip** replaces the diagonal of the two faces of an edge when the
  other diagonal is not an edge already and the faces do not fold;
* an **edge split** adds a vertex on an edge and two faces.

Faces die by a flag (``face_alive``) and the mesh is compacted at the end
(:func:`compact`), which also says where every surviving vertex came from
(``vertex_origin``: itself, or for a vertex made by a split the nearer end of
the edge it split) and every face (``face_source``: the input face it
descends from).  Those two maps carry per-vertex and per-face attributes
(branch id, order...) from the input to the output: ``attribute[vertex_origin]``.

Vertices carry flags: :data:`SEAM` (on a junction seam), :data:`FEATURE` (on
a sharp rim that must stay: the edge of a tube's flat cap), :data:`ORIGINAL`
(a vertex of the swept tubes, not made by the boolean), :data:`LOCKED`
(never touched: a vertex whose faces do not form one fan) and :data:`PINNED`
(a rim vertex that stays where it is and whose rim stays as it is: the ring
under a temporary cap of the union, which the union stitches back on).
"""

from .clean import Rules, clean, halves
from .collar import collar
from .fair import fair, settle
from .halfedge import (
    FEATURE,
    INDEX_LIMIT,
    LOCKED,
    ORIGINAL,
    PINNED,
    SEAM,
    HalfEdges,
    build,
    compact,
    cut_caps,
    in_two,
    mark,
    opposites,
)
from .normals import corner_normals
from .rescue import rescue
from .tube_faces import tube_faces

__all__ = [
    "FEATURE",
    "INDEX_LIMIT",
    "LOCKED",
    "ORIGINAL",
    "PINNED",
    "SEAM",
    "HalfEdges",
    "Rules",
    "build",
    "clean",
    "collar",
    "compact",
    "corner_normals",
    "cut_caps",
    "fair",
    "halves",
    "in_two",
    "mark",
    "opposites",
    "rescue",
    "settle",
    "tube_faces",
]
