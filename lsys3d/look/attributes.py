"""Hierarchy and wind attributes: where on the tree each bark vertex and each leaf sits.

A game engine's wind shader bends a vertex about the pivot of its branch, by an
amount that grows along the branch and with the branch's depth, in a rhythm of
its own; an animator's tool needs the same facts.  Every attribute is one row of
:data:`ATTRIBUTES` (its name in lsys3d, in glTF and in USD, its width, its
meaning); the writers and the docs read that table.

Bark vertices get the values of the branch (:mod:`lsys3d.turtle.hierarchy`) whose tube
they lie on: each vertex is matched to the segment whose capsule it is nearest
to, in units of that segment's radius, and where two branches meet -- on the
seam of the union, or on a blending collar -- the vertex takes the *child's*
values (the branch deepest in the hierarchy among the tubes it lies on, see
:func:`nearest_branch`), so a child sways from its own pivot all the way to
where it joins its parent.  The match is geometric, so it holds for
any mesh made from the skeleton: the union, the tube soup, a cleaned or
decimated bark.  Leaves take the values of the branch they grow from
(:attr:`lsys3d.turtle.skeleton.Skeleton.leaf_segment`) at the point they grow from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import offsets, search_left
from ..compiling import kernel
from ..mesh.mesh import Mesh
from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import Skeleton

__all__ = [
    "ATTRIBUTES",
    "GLTF_PACKING",
    "SEAM_TOLERANCE",
    "Attribute",
    "AttributeOptions",
    "attributes_markdown",
    "bark_attributes",
    "branch_table",
    "branch_values",
    "gltf_attributes",
    "nearest_branch",
    "with_attributes",
]

SEAM_TOLERANCE = 0.05
"""A vertex within ``1 + SEAM_TOLERANCE`` radii of a segment lies on its tube (tubes are polygons inside that)."""


@dataclass(frozen=True)
class Attribute:
    """One attribute: a row of :data:`ATTRIBUTES`.

    Attributes
    ----------
    key : str
        Its name in lsys3d (``Mesh.attributes``, ``Leaves.instance_attributes``).
    usd : str
        The USD primvar name (``primvars:<usd>``); glTF packs the attributes into a few vectors
        (:data:`GLTF_PACKING`).
    width : int
        1 (a scalar) or 3 (a point).
    point : bool
        A position: the writers carry it into the file's frame (units, up axis) as they do the vertices.
    per_branch : bool
        One value per branch (the ``compact`` layout keeps it in the branch table, see
        :class:`AttributeOptions`); otherwise it varies along a branch and is always per vertex.
    description : str
    """

    key: str
    usd: str
    width: int
    point: bool
    per_branch: bool
    description: str


ATTRIBUTES: tuple[Attribute, ...] = (
    Attribute("branch_id", "branch_id", 1, False, False, "the branch: 0, 1, ... in drawing order; -1 none"),
    Attribute("branch_t", "branch_t", 1, False, False, "how far along the branch: 0 at its base, 1 at its tip"),
    Attribute("phase", "phase", 1, False, True, "a seeded random number in [0, 1) per branch"),
    Attribute("branch_parent", "branch_parent", 1, False, True, "the parent branch; -1 for a root"),
    Attribute("branch_depth", "branch_depth", 1, False, True, "branches between it and its root (0 for a root)"),
    Attribute("branch_order", "branch_order", 1, False, True, "the turtle's branch order (bracket nesting)"),
    Attribute("pivot", "pivot", 3, True, True, "the branch's base point, in the file's frame and units"),
    Attribute("parent_pivot", "parent_pivot", 3, True, True, "the parent branch's base point (a root's own)"),
    Attribute("branch_length", "branch_length", 1, False, True, "the branch's length, in the file's units"),
)
"""The hierarchy and wind attributes, in the order the writers emit them."""

KEYS = tuple(a.key for a in ATTRIBUTES)

GLTF_PACKING: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("_BRANCH", ("branch_id", "branch_t", "phase")),
    ("_HIERARCHY", ("branch_parent", "branch_depth", "branch_order")),
    ("_PIVOT", ("pivot",)),
    ("_PARENT_PIVOT", ("parent_pivot",)),
)
"""How glTF carries the attributes: application-specific attributes (names start with ``_``), each a vector
of the attributes listed, those present in the layout (``_BRANCH`` is ``(id, t)`` in the compact layout and
``(id, t, phase)`` in the full one).  Vectors rather than one attribute each, because Blender's glTF importer
mixes up custom attributes of different widths in one primitive (Blender 5.0), and fewer accessors load faster.
``branch_length`` is in the branch table only."""
VERTEX_KEYS = tuple(a.key for a in ATTRIBUTES if not a.per_branch)
BRANCH_KEYS = tuple(a.key for a in ATTRIBUTES if a.per_branch)

LAYOUTS = ("off", "compact", "full")
"""Values of ``AttributeOptions.layout``."""


@dataclass(frozen=True)
class AttributeOptions(Options):
    """Whether and how the bark and the leaves carry the hierarchy and wind attributes (:data:`ATTRIBUTES`).

    ``compact`` puts two attributes on every vertex and leaf, the branch id and
    ``t`` along the branch (glTF ``_BRANCH``, USD ``primvars:branch_id`` and
    ``primvars:branch_t``), and the per-branch ones (pivot, parent, depth, phase...) in a
    table of one row per branch (glTF: accessors named in the root node's
    ``extras.lsys3d_branches``; USD: ``constant`` array primvars on the root),
    which a shader or a script indexes by the branch id: 8 bytes a vertex.
    ``full`` puts every attribute on every vertex (and leaf instance): no
    lookup needed, 48 bytes a vertex in glTF.
    """

    layout: str = option(
        "off",
        choices=LAYOUTS,
        name="attributes",
        help="hierarchy and wind attributes on vertices and leaves: branch id and t (compact), also pivots... (full)",
    )

    @property
    def enabled(self) -> bool:
        return self.layout != "off"

    @property
    def keys(self) -> tuple[str, ...]:
        """The attributes each vertex and leaf carries in this layout."""
        return {"off": (), "compact": VERTEX_KEYS, "full": KEYS}[self.layout]


def gltf_attributes(values: dict) -> dict:
    """The attributes in ``values`` packed for glTF (:data:`GLTF_PACKING`): ``name -> (n, k) float32``.

    >>> import numpy as np
    >>> packed = gltf_attributes({"branch_id": np.zeros(4), "branch_t": np.ones(4)})
    >>> list(packed), packed["_BRANCH"].shape
    (['_BRANCH'], (4, 2))
    """
    out = {}
    for name, keys in GLTF_PACKING:
        parts = [np.asarray(values[k], np.float32).reshape(len(values[k]), -1) for k in keys if k in values]
        if parts:
            out[name] = np.ascontiguousarray(np.concatenate(parts, axis=1))
    return out


def branch_table(h: Hierarchy) -> dict:
    """The per-branch attributes, one row per branch: ``key -> (b,) or (b, 3) float32`` (:data:`BRANCH_KEYS`)."""
    values = branch_values(h, np.arange(len(h)), np.zeros(len(h)))
    return {k: values[k] for k in BRANCH_KEYS}


def branch_values(h: Hierarchy, branch: np.ndarray, t: np.ndarray, fallback_pivot: np.ndarray | None = None) -> dict:
    """The attributes of points on ``branch`` at ``t`` along it (``branch`` -1: no branch; pivot ``fallback_pivot``).

    Returns a dict ``key -> (m,) or (m, 3) float32``.
    """
    branch = np.asarray(branch, np.int64)
    m = len(branch)
    has = branch >= 0
    b = np.where(has, branch, 0)
    nb = len(h)
    if nb == 0:
        has = np.zeros(m, bool)
    parent = np.where(has, h.parent[b] if nb else -1, -1)
    pivot = np.where(has[:, None], h.pivot[b] if nb else 0.0, 0.0)
    if fallback_pivot is not None:
        pivot = np.where(has[:, None], pivot, np.asarray(fallback_pivot, np.float64))
    own_or_parent = np.where(parent >= 0, parent, b)
    parent_pivot = np.where(has[:, None], h.pivot[own_or_parent] if nb else 0.0, pivot)
    values = {
        "branch_id": np.where(has, branch, -1),
        "branch_parent": parent,
        "branch_depth": np.where(has, h.depth[b] if nb else 0, 0),
        "branch_order": np.where(has, h.order[b] if nb else 0, 0),
        "pivot": pivot,
        "parent_pivot": parent_pivot,
        "branch_t": np.where(has, np.clip(t, 0.0, 1.0), 0.0),
        "branch_length": np.where(has, h.length[b] if nb else 0.0, 0.0),
        "phase": np.where(has, h.phase[b] if nb else 0.0, 0.0),
    }
    return {k: np.ascontiguousarray(values[k], np.float32) for k in KEYS}


def _grid(lo: np.ndarray, hi: np.ndarray, points: np.ndarray):
    """Boxes hashed into a uniform grid: origin, cell size, dims, the occupied cells' keys and their boxes (CSR)."""
    size = (hi - lo).max(axis=1)
    cell = max(float(np.median(size)), 1e-9)
    origin = np.minimum(lo.min(axis=0), points.min(axis=0))
    for _ in range(30):  # grow the cells until the box-cell entries are modest
        c0 = np.floor((lo - origin) / cell).astype(np.int64)
        c1 = np.floor((hi - origin) / cell).astype(np.int64)
        ext = c1 - c0 + 1
        count = ext.prod(axis=1)
        if count.sum() <= 8 * len(lo) + 10_000:
            break
        cell *= 1.5
    dims = np.maximum(c1.max(axis=0), np.floor((points.max(axis=0) - origin) / cell).astype(np.int64)) + 1
    box = np.repeat(np.arange(len(lo)), count)
    k = np.arange(len(box)) - np.repeat(offsets(count)[:-1], count)
    ex = ext[box]
    ix = c0[box, 0] + k % ex[:, 0]
    iy = c0[box, 1] + (k // ex[:, 0]) % ex[:, 1]
    iz = c0[box, 2] + k // (ex[:, 0] * ex[:, 1])
    key = (iz * dims[1] + iy) * dims[0] + ix
    order = np.argsort(key, kind="stable")
    key, box = key[order], box[order]
    starts = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]])) if len(key) else np.zeros(0, np.int64)
    return origin, cell, dims, key[starts], np.append(starts, len(key)), box


@kernel(nogil=True)
def _match(points, origin, cell, dims, keys, key_offsets, boxes, lo, hi, a, b, w0, w1, depth, surface, tolerance):
    """Per point: the chosen segment (-1: none within reach) and the point's parameter along it (see nearest_branch)."""
    n = points.shape[0]
    segment = np.empty(n, np.int64)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    segment[:] = -1
    param = np.empty(n)
    param[:] = 0.0
    for p in range(n):
        x, y, z = points[p, 0], points[p, 1], points[p, 2]
        cx = np.int64(np.floor((x - origin[0]) / cell))
        cy = np.int64(np.floor((y - origin[1]) / cell))
        cz = np.int64(np.floor((z - origin[2]) / cell))
        key = (cz * dims[1] + cy) * dims[0] + cx
        k = search_left(keys, key)
        if k >= keys.shape[0] or keys[k] != key:
            continue
        best = np.inf
        for pass_ in range(2):
            chosen, chosen_depth, chosen_n, chosen_f = -1, -1, np.inf, 0.0
            for e in range(key_offsets[k], key_offsets[k + 1]):
                s = boxes[e]
                if not (lo[s, 0] <= x <= hi[s, 0] and lo[s, 1] <= y <= hi[s, 1] and lo[s, 2] <= z <= hi[s, 2]):
                    continue
                dx, dy, dz = b[s, 0] - a[s, 0], b[s, 1] - a[s, 1], b[s, 2] - a[s, 2]
                px, py, pz = x - a[s, 0], y - a[s, 1], z - a[s, 2]
                dd = dx * dx + dy * dy + dz * dz
                f = (px * dx + py * dy + pz * dz) / dd if dd > 0 else 0.0
                f = min(max(f, 0.0), 1.0)
                qx, qy, qz = px - f * dx, py - f * dy, pz - f * dz
                r = 0.5 * max(w0[s] + f * (w1[s] - w0[s]), 2e-6)
                norm = np.sqrt(qx * qx + qy * qy + qz * qz) / r
                if pass_ == 0:
                    best = min(best, norm)
                    continue
                if not (norm <= surface or norm <= best + tolerance):
                    continue
                # the deepest branch; then the nearest; then the lowest segment index
                if depth[s] > chosen_depth or (
                    depth[s] == chosen_depth and (norm < chosen_n or (norm == chosen_n and s < chosen))
                ):
                    chosen, chosen_depth, chosen_n, chosen_f = s, depth[s], norm, f
            if pass_ == 1 and chosen >= 0:
                segment[p] = chosen
                param[p] = chosen_f
    return segment, param


def nearest_branch(points: np.ndarray, skeleton: Skeleton, h: Hierarchy, reach: float = 2.0, bulge: float = 0.0):
    """For each point: the segment it belongs to (child first at seams) and its ``t`` along that segment's branch.

    A point lies on a segment's tube when it is within ``1 + SEAM_TOLERANCE + bulge`` radii of the
    segment (``bulge``: how far the bark may stand out, ``SweepOptions.bark_displacement``); of the
    tubes it lies on, the deepest branch's is chosen, so the union's seams go to the child.  ``reach``
    (radii) bounds the search; points farther from every segment take the nearest one found by widening
    the search.  Returns ``(segment (v,) int64, t (v,) float64)``; segment -1 without segments.
    """
    surface = 1.0 + SEAM_TOLERANCE + bulge
    points = np.ascontiguousarray(points, np.float64)
    v = len(points)
    segment = np.full(v, -1, np.int64)
    t = np.zeros(v)
    if not len(skeleton) or not v:
        return segment, t
    a, b = np.ascontiguousarray(skeleton.start, np.float64), np.ascontiguousarray(skeleton.end, np.float64)
    w0 = np.ascontiguousarray(skeleton.width_start, np.float64)
    w1 = np.ascontiguousarray(skeleton.width_end, np.float64)
    radius = 0.5 * np.maximum(np.maximum(w0, w1), 1e-6)
    depth = h.depth[h.branch_of].astype(np.int64)
    scale = float(np.abs(np.concatenate([a, b])).max()) + 1.0
    todo = np.arange(v)
    while len(todo):
        pad = reach * radius[:, None] + 1e-9 * scale
        lo, hi = np.minimum(a, b) - pad, np.maximum(a, b) + pad
        grid = _grid(lo, hi, points[todo])
        seg, f = _match(points[todo], *grid, lo, hi, a, b, w0, w1, depth, surface, SEAM_TOLERANCE)
        found = seg >= 0
        segment[todo[found]] = seg[found]
        s = seg[found]
        t[todo[found]] = h.t_start[s] + f[found] * (h.t_end[s] - h.t_start[s])
        todo = todo[~found]
        reach *= 4.0
        if reach > 1e6:  # pragma: no cover - every point is within some finite reach
            break
    return segment, t


def bark_attributes(points: np.ndarray, skeleton: Skeleton, h: Hierarchy, keys=KEYS, bulge: float = 0.0) -> dict:
    """The attributes ``keys`` of bark vertices at ``points`` (see the module docstring for the rule)."""
    segment, t = nearest_branch(points, skeleton, h, bulge=bulge)
    branch = np.where(segment >= 0, h.branch_of[np.maximum(segment, 0)] if len(skeleton) else -1, -1)
    values = branch_values(h, branch, t, fallback_pivot=points)
    return {k: values[k] for k in keys}


def with_attributes(bark: Mesh, skeleton: Skeleton, h: Hierarchy, keys=KEYS, bulge: float = 0.0) -> Mesh:
    """The attributes stage: ``bark`` with the attributes ``keys`` of its vertices (:data:`KEYS` by default).

    Examples
    --------
    >>> import lsys3d
    >>> from lsys3d.turtle.hierarchy import hierarchy
    >>> tree = lsys3d.generate("abop-1.24a", iterations=1, sides=4)
    >>> full = with_attributes(tree.bark, tree.skeleton, hierarchy(tree.skeleton))
    >>> sorted(full.attributes) == sorted(KEYS), full.attributes["pivot"].shape == (len(full.vertices), 3)
    (True, True)
    >>> compact = with_attributes(tree.bark, tree.skeleton, hierarchy(tree.skeleton), AttributeOptions("compact").keys)
    >>> sorted(compact.attributes)
    ['branch_id', 'branch_t']
    """
    if not len(bark.vertices) or not keys:
        return bark
    return bark.with_attributes(bark_attributes(bark.vertices, skeleton, h, keys, bulge))


def attributes_markdown() -> str:
    """The attribute table of ``docs/engines.md`` (the tests check the page holds it)."""
    rows = ["| name (USD `primvars:<name>`) | per | meaning |", "|---|---|---|"]
    rows += [f"| `{a.usd}` | {'branch' if a.per_branch else 'vertex'} | {a.description} |" for a in ATTRIBUTES]
    return "\n".join(rows) + "\n"
