"""Levels of detail: lighter versions of one tree, all built from its one skeleton.

A real-time engine draws a tree close by with its full mesh and far away with
a few hundred triangles.  Every level here is built from the *same* skeleton
(the same branches in the same places, so nothing jumps when a level
switches), each by the same stages as the tree itself (sweep, union,
cleanup, leaves) with lighter settings:

=====  ==============  ================  ===========  ==================  ========================
level  trunk sides     branches kept     ring merge   leaves              leaf shape
=====  ==============  ================  ===========  ==================  ========================
0      as given        all               as given     all                 as given
1      5/8 (at least   wider than 6% of  5 degrees    half, each 1.41x    2 rows (8 triangles)
       4)              the widest
2      1/2 (at least   wider than 12%    10 degrees   a fifth, 2.24x      1 row (4 triangles)
       3)
3      3 (at least 3)  wider than 30%    20 degrees   cards: one quad     2 triangles
                                                      per cluster
=====  ==============  ================  ===========  ==================  ========================

* **Sides by branch order**: from level 1 on, each branch order has one side
  fewer than its parent's (``SweepOptions.sides_step`` at least 1), down to
  the level's fewest (4, 3, 3): a branch far from the trunk is thin on
  screen.  tree3d's level 1 has a 5-sided trunk and 4-sided branches (bark
  15,210 -> 12,304 triangles against 5 sides all through), which takes a
  fifth off its union and cleanup.

* **Branches kept**: a chain whose base is thinner than the given fraction of
  the skeleton's widest width goes, with everything that grows from it.  Its
  leaves stay where they grew (a twig a few pixels wide is not missed; its
  foliage would be).
* **Leaves thinned** keep every k-th leaf in a low-discrepancy order (spread
  evenly over the crown) and scale each up so the total leaf area, the
  crown's coverage, stays the same.
* **Cards** (level 3): the leaves are grouped into cells of a grid, each cell
  becomes one double-sided quad of the cell's total leaf area at its centre,
  facing away from the trunk's axis (so seen from anywhere around the tree, a
  card faces the camera; an engine may also turn the node ``<name>_LOD3``
  into billboards).

:func:`fit_budget` picks the most detailed level whose triangles (bark and
leaves) fit a budget (``--target-triangles N``).

Examples
--------
>>> import lsys3d
>>> tree = lsys3d.generate("tree3d", iterations=4, lod=(0, 1, 2, 3))
>>> counts = [lod.triangles for lod in tree.lods]
>>> counts == sorted(counts, reverse=True), [lod.level for lod in tree.lods]
(True, [0, 1, 2, 3])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..arrays import unique
from ..errors import LimitError, OptionsError
from ..mesh.mesh import Mesh
from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import Skeleton
from .leaves import LeafOptions, Leaves
from .leaves import leaves as build_leaves

__all__ = [
    "CARDS",
    "LEVELS",
    "Level",
    "Lod",
    "LodOptions",
    "cards",
    "fit_budget",
    "kept_segments",
    "level_hierarchy",
    "level_options",
    "lod_leaves",
    "prune",
    "thin_leaves",
]


@dataclass(frozen=True)
class Level:
    """What one level of detail changes (see the module's table)."""

    sides: float
    """Fraction of the tube sides kept (of ``SweepOptions.sides``)."""
    min_sides: int
    """Fewest sides at this level."""
    prune: float
    """Chains thinner at their base than this fraction of the widest width go."""
    merge_angle: float
    """Degrees: joints straighter than this get no ring (``SweepOptions.merge_angle``)."""
    merge_width: float
    """Relative taper tolerance of that merge (``SweepOptions.merge_width``)."""
    leaf_keep: float
    """Fraction of the leaves kept (their size scaled by ``1 / sqrt(leaf_keep)``)."""
    leaf_rows: int
    """Rows of the built-in leaf (0: as given)."""
    cards: bool
    """Leaves as one card per cluster."""


LEVELS: tuple[Level, ...] = (
    Level(1.0, 3, 0.0, 0.0, 0.0, 1.0, 0, False),
    Level(0.625, 4, 0.06, 5.0, 0.05, 0.5, 2, False),
    Level(0.5, 3, 0.12, 10.0, 0.1, 0.2, 1, False),
    Level(0.0, 3, 0.3, 20.0, 0.2, 1.0, 0, True),
)
"""The levels of detail, finest first (level 0 is the tree as asked for)."""

CARDS = 96
"""How many leaf cards level 3 aims at (more or fewer cells may hold leaves)."""


@dataclass(frozen=True)
class LodOptions(Options):
    """Which levels of detail to build, or a triangle budget to fit; every default, range and help is in its field."""

    levels: tuple[int, ...] = option(
        (),
        kind="ints",
        low=0,
        high=len(LEVELS) - 1,
        name="lod",
        metavar="0,1,2,3",
        help="also build these levels of detail (glTF: MSFT_lod and _LODn nodes; USD: the variant set 'lod')",
    )
    target_triangles: int = option(
        0, low=0, help="build the most detailed level whose bark and leaves fit this many triangles (0: no budget)"
    )

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "levels", tuple(sorted(set(self.levels))))  # a set of levels, finest first
        if self.levels and self.target_triangles:
            raise OptionsError("LodOptions: give levels (--lod) or a budget (--target-triangles), not both")


@dataclass(frozen=True, eq=False)
class Lod:
    """One level of detail of a tree: its bark and leaves (the skeleton is the tree's).

    Attributes
    ----------
    level : int
    bark : Mesh
    leaves : Leaves
    settings : dict
        What the level changed, as plain data (for the files' metadata).
    """

    level: int
    bark: Mesh
    leaves: Leaves = field(default_factory=Leaves)
    settings: dict = field(default_factory=dict)

    @property
    def triangles(self) -> int:
        """Bark and leaf triangles (all leaves merged)."""
        merged = self.leaves.merged if self.leaves.merged is not None else self.leaves.polygons
        return len(self.bark.faces) + (len(merged.faces) if merged is not None else 0)


def level_options(options, level: int):
    """The :class:`~lsys3d.pipeline.GenerateOptions` of a level: sides (by order), ring merging and leaves lightened,
    thick forks not blended (``SweepOptions.fork_blend``)."""
    spec = LEVELS[level]
    sweep = options.sweep
    if level > 0:
        sides = max(spec.min_sides, min(sweep.sides, round(sweep.sides * spec.sides)))
        sweep = sweep.replace(
            sides=sides,
            sides_step=max(sweep.sides_step, 1),
            min_sides=min(max(sweep.min_sides, spec.min_sides), sides),
            merge_angle=max(sweep.merge_angle, spec.merge_angle),
            merge_width=max(sweep.merge_width, spec.merge_width),
            fork_blend=0.0,  # the curves of thick forks cost 3 rings a child: a close-up's detail, level 0's
        )
    leaves = options.leaves
    if spec.leaf_rows:
        leaves = leaves.replace(leaf_points=min(leaves.leaf_points, spec.leaf_rows))
    if leaves.leaf_size > 0 and spec.leaf_keep < 1:  # a size in metres grows with the thinning, as the step's does
        leaves = leaves.replace(leaf_size=leaves.leaf_size / math.sqrt(spec.leaf_keep))
    return options.replace(sweep=sweep, leaves=leaves)


def kept_segments(skeleton: Skeleton, fraction: float) -> np.ndarray:
    """The segments :func:`prune` keeps, ascending, ``(m,) int64``."""
    n = len(skeleton)
    if fraction <= 0 or n == 0:
        return np.arange(n)
    chains = skeleton.chains
    heads = chains.segments[chains.offsets[:-1]]
    widest = float(max(skeleton.width_start.max(), skeleton.width_end.max()))
    keep_chain = skeleton.width_start[heads] >= fraction * widest
    parent = skeleton.parent[heads]
    has = parent >= 0
    parent_chain = np.where(has, chains.chain_of[np.maximum(parent, 0)], -1)
    for _ in range(len(chains)):  # a chain goes when its parent chain goes (parents come first)
        new = keep_chain & np.where(has, keep_chain[np.maximum(parent_chain, 0)], True)
        if np.array_equal(new, keep_chain):
            break
        keep_chain = new
    return np.flatnonzero(keep_chain[chains.chain_of])


def prune(skeleton: Skeleton, fraction: float) -> Skeleton:
    """The skeleton without the chains whose base is thinner than ``fraction`` of its widest width.

    Everything that grows from a removed chain goes too; leaves and polygons
    stay as they are.  Segments keep their order; ``parent`` is renumbered.
    """
    n = len(skeleton)
    kept = kept_segments(skeleton, fraction)
    if len(kept) == n:
        return skeleton
    index = np.full(n, -1, np.int64)
    index[kept] = np.arange(len(kept))
    old_parent = skeleton.parent[kept]
    new_parent = np.where(old_parent >= 0, index[np.maximum(old_parent, 0)], -1)
    fields = {name: getattr(skeleton, name)[kept] for name in _SEGMENT_FIELDS}
    if skeleton.birth is not None:  # the plant's development (lsys3d.turtle.timing)
        fields.update(birth=skeleton.birth[kept], mature=skeleton.mature[kept])
    if skeleton.sides is not None:  # the grammar's sides (cpfg's @!)
        fields.update(sides=skeleton.sides[kept])
    return replace(skeleton, parent=new_parent, **fields)


def level_hierarchy(h: Hierarchy, kept: np.ndarray) -> Hierarchy:
    """The tree's hierarchy ``h`` seen from a pruned skeleton whose segments are the tree's ``kept`` ones.

    The branches stay the tree's own (same ids, pivots, phases), so every
    level's attributes index the one branch table and its skin binds to the
    one rig; only the per-segment rows follow the pruned skeleton.
    """
    return replace(h, branch_of=h.branch_of[kept], t_start=h.t_start[kept], t_end=h.t_end[kept])


_SEGMENT_FIELDS = ("start", "end", "width_start", "width_end", "heading", "left", "up", "order", "material", "module")


def _spread(count: int, keep: float) -> np.ndarray:
    """Indices of about ``keep * count`` of ``count`` items, spread evenly over them (golden-ratio sequence)."""
    if keep >= 1.0:
        return np.arange(count)
    phase = np.mod((np.arange(count) + 0.5) * (math.sqrt(5.0) - 1.0) / 2.0, 1.0)
    chosen = np.flatnonzero(phase < keep)
    return chosen if len(chosen) or not count else np.array([0])


def thin_leaves(skeleton: Skeleton, keep: float) -> Skeleton:
    """The skeleton with a share ``keep`` of its leaves and polygons, each scaled by ``1 / sqrt(keep)``.

    The total leaf area (what the crown covers) stays the same; leaf
    instances grow about their base, polygons about their centre.
    """
    if keep >= 1.0:
        return skeleton
    grow = 1.0 / math.sqrt(keep)
    li = _spread(len(skeleton.leaf_position), keep)
    leaf = {
        "leaf_position": skeleton.leaf_position[li],
        "leaf_heading": skeleton.leaf_heading[li],
        "leaf_left": skeleton.leaf_left[li],
        "leaf_up": skeleton.leaf_up[li],
        "leaf_size": skeleton.leaf_size[li] * grow,
        "leaf_material": skeleton.leaf_material[li],
    }
    if skeleton.leaf_segment is not None and len(skeleton.leaf_segment) == len(skeleton.leaf_position):
        leaf["leaf_segment"] = skeleton.leaf_segment[li]
    offsets = np.asarray(skeleton.polygon_offsets, np.int64)
    pi = _spread(len(offsets) - 1, keep)
    counts = offsets[pi + 1] - offsets[pi]
    idx = np.repeat(offsets[pi], counts) + np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    points = skeleton.polygon_points[idx]
    if len(points):
        owner = np.repeat(np.arange(len(pi)), counts)
        centre = np.zeros((len(pi), 3))
        np.add.at(centre, owner, points)
        centre /= np.maximum(counts, 1)[:, None]
        points = centre[owner] + grow * (points - centre[owner])
    polygons = {
        "polygon_points": points,
        "polygon_offsets": np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        "polygon_material": skeleton.polygon_material[pi],
    }
    if skeleton.polygon_segment is not None and len(skeleton.polygon_segment) == len(offsets) - 1:
        polygons["polygon_segment"] = skeleton.polygon_segment[pi]
    return replace(skeleton, **leaf, **polygons)


def cards(leaves: Mesh | None, trunk_axis_point: np.ndarray, count: int = CARDS) -> Mesh | None:
    """Leaf cards: the leaves grouped into grid cells, each cell one quad of the cell's leaf area.

    Parameters
    ----------
    leaves : Mesh or None
        All leaves merged (:attr:`Leaves.merged`).
    trunk_axis_point : (3,)
        A point of the trunk's (vertical) axis: cards face away from it.
    count : int
        About how many cards (the grid's cell size is chosen for it).

    Returns
    -------
    Mesh or None
        Two triangles per card, ``uv`` the unit square, flat normals.  When
        the leaves carry attributes (:mod:`lsys3d.look.attributes`, the rig's
        skin), a card's four vertices carry those of its cell's largest leaf
        triangle's first corner: the branch it sways with.
    """
    if leaves is None or not len(leaves.faces):
        return None
    tri = leaves.vertices[leaves.faces]
    centre = tri.mean(axis=1)
    area = leaves.face_areas
    lo, hi = centre.min(axis=0), centre.max(axis=0)
    extent = max(float((hi - lo).max()), 1e-9)

    def cells_of(points, size):
        ijk = np.floor((points - lo) / size).astype(np.int64)
        span = np.floor((hi - lo) / size).astype(np.int64) + 1
        return (ijk[:, 0] * span[1] + ijk[:, 1]) * span[2] + ijk[:, 2]

    # the cell size that gives about ``count`` occupied cells: a geometric bisection, counted on a couple of
    # thousand evenly strided triangles (about one per leaf: a leaf's triangles are neighbours in the mesh)
    sample = centre[:: max(1, len(centre) // 2048)]
    small, large = extent / 1000.0, 2.0 * extent
    for _ in range(16):
        size = math.sqrt(small * large)
        if len(unique(cells_of(sample, size))) > count:
            small = size
        else:
            large = size
    _, cell = np.unique(cells_of(centre, large), return_inverse=True)
    cell = cell.reshape(-1)
    k = int(cell.max()) + 1
    weight = np.bincount(cell, weights=area, minlength=k)
    where = np.stack([np.bincount(cell, weights=area * centre[:, c], minlength=k) for c in range(3)], axis=1)
    where /= np.maximum(weight, 1e-300)[:, None]
    half = 0.5 * np.sqrt(weight)  # a square card of the cell's leaf area
    out = where - np.asarray(trunk_axis_point, np.float64)
    out[:, 1] = 0.0  # horizontal: away from the vertical trunk axis
    length = np.linalg.norm(out, axis=1, keepdims=True)
    normal = np.where(length > 1e-9, out / np.maximum(length, 1e-300), [[0.0, 0.0, 1.0]])
    up = np.array([0.0, 1.0, 0.0])
    side = np.cross(up, normal)
    corners = np.stack(
        [
            where - half[:, None] * side - half[:, None] * up,
            where + half[:, None] * side - half[:, None] * up,
            where + half[:, None] * side + half[:, None] * up,
            where - half[:, None] * side + half[:, None] * up,
        ],
        axis=1,
    )
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    faces = (np.arange(k)[:, None, None] * 4 + quad[None]).reshape(-1, 3)
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])[quad]
    card = Mesh.flat(corners.reshape(-1, 3), faces, np.broadcast_to(uv, (k, 2, 3, 2)).reshape(-1, 3, 2))
    if not leaves.attributes:
        return card
    # each cell's largest triangle (ties: the first); its first corner speaks for the card
    by_area = np.lexsort((-np.arange(len(area)), area, cell))
    last = np.flatnonzero(np.append(cell[by_area][1:] != cell[by_area][:-1], True))
    corner = leaves.faces[by_area[last], 0]
    owner = np.repeat(np.arange(k), 4)  # card c's corners are vertices 4c .. 4c + 3
    return card.with_attributes({key: np.asarray(a)[corner][owner] for key, a in leaves.attributes.items()})


def lod_leaves(
    skeleton: Skeleton,
    level: int,
    options: LeafOptions,
    model: Mesh | None = None,
    hierarchy: Hierarchy | None = None,
    attributes=(),
    seed: int = 0,
) -> Leaves:
    """The leaves of one level: thinned (levels 1, 2) or as cards (level 3), from the full skeleton's leaves.

    ``model`` is the leaf model (None: the built-in leaf of ``options``; a
    grammar's ``[surfaces] leaf`` keeps its shape at every level).  With the
    skeleton's ``hierarchy``, the leaves carry the ``attributes`` of the
    branches they grow from, as at level 0.  ``seed`` is the plant's (the leaves' sizes and clusters).
    """
    spec = LEVELS[level]
    kw = {"hierarchy": hierarchy, "attributes": tuple(attributes)} if hierarchy is not None and attributes else {}
    kw["seed"] = seed
    if not spec.cards:
        return build_leaves(thin_leaves(skeleton, spec.leaf_keep), model=model, options=options, **kw)
    full = build_leaves(skeleton, model=model, options=options, **kw)
    axis = skeleton.start[0] if len(skeleton) else np.zeros(3)
    merged = cards(full.merged if full.merged is not None else full.polygons, axis)
    return Leaves(merged=merged, polygons=merged)


def fit_budget(levels_counts, budget: int) -> int:
    """The first (most detailed) level whose triangle count is within ``budget``.

    ``levels_counts`` yields ``(level, triangles)`` in order; raises
    :class:`LimitError` when even the last does not fit.
    """
    last = None
    for level, triangles in levels_counts:
        if triangles <= budget:
            return level
        last = (level, triangles)
    raise LimitError(
        f"--target-triangles {budget:,}: even the lightest level of detail ({last[0]}) has {last[1]:,} triangles; "
        "use fewer iterations or a larger budget"
    )
