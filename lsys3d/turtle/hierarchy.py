"""The branch hierarchy of a skeleton: what a wind shader or a rig needs to know about each branch.

A *branch* is a chain of the skeleton (:attr:`lsys3d.turtle.skeleton.Skeleton.chains`):
an unbranched run of segments from its base to its tip.  Branch ``b`` has

``parent[b]``
    The branch it grows from (the chain of the parent segment of its first
    segment), -1 for a root.
``depth[b]``
    How many branches lie between it and its root (0 for a root): the
    hierarchy depth that Pivot Painter and SpeedTree-style wind shaders read.
``order[b]``
    The branch order the turtle gave its first segment (bracket nesting).
``pivot[b]``
    Its base point, where it bends from: the start of its first segment.
``length[b]``
    Its length along its segments.
``phase[b]``
    A seeded random number in [0, 1) (stream :attr:`lsys3d.streams.Stream.WIND_PHASE`),
    so that neighbouring branches do not sway in step.

and every segment ``s`` its branch (``branch_of[s]``) and the position of its two
ends along that branch, ``t_start[s]`` and ``t_end[s]`` (0 at the branch's base,
1 at its tip).  Leaves and leaf polygons belong to the branch of the segment they
grow from (:attr:`Skeleton.leaf_segment`), -1 when none.

Examples
--------
>>> import numpy as np
>>> from lsys3d.turtle.skeleton import Skeleton
>>> sk = Skeleton.from_segments(  # a trunk of 3 segments, a branch of 1 from the top of the first
...     [[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0], [0, 3, 0], [1, 2, 0]],
...     parent=[-1, 0, 1, 0], order=[0, 0, 0, 1])
>>> h = hierarchy(sk)
>>> h.parent.tolist(), h.depth.tolist(), h.pivot.tolist()
([-1, 0], [0, 1], [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
>>> h.branch_of.tolist(), np.round(h.t_end, 3).tolist()
([0, 0, 0, 1], [0.333, 0.667, 1.0, 1.0])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..streams import Stream, generator
from .skeleton import Skeleton

__all__ = ["Hierarchy", "hierarchy"]


@dataclass(frozen=True, eq=False)
class Hierarchy:
    """The branches of a skeleton and where each segment, leaf and polygon sits in them (see the module)."""

    parent: np.ndarray  # (b,) int64
    depth: np.ndarray  # (b,) int32
    order: np.ndarray  # (b,) int32
    pivot: np.ndarray  # (b, 3) float64
    length: np.ndarray  # (b,) float64
    phase: np.ndarray  # (b,) float64
    branch_of: np.ndarray  # (n,) int64, per segment
    t_start: np.ndarray  # (n,) float64
    t_end: np.ndarray  # (n,) float64
    leaf_branch: np.ndarray  # (k,) int64, per leaf instance (-1: none)
    polygon_branch: np.ndarray  # (p,) int64, per leaf polygon (-1: none)

    def __len__(self) -> int:
        return len(self.parent)


def hierarchy(skeleton: Skeleton, seed: int = 0) -> Hierarchy:
    """The branch hierarchy of ``skeleton``; ``seed`` seeds the branches' wind phases."""
    chains = skeleton.chains
    n = len(skeleton)
    nb = len(chains)
    first = chains.segments[chains.offsets[:-1]] if nb else np.zeros(0, np.int64)
    parent_segment = skeleton.parent[first] if nb else np.zeros(0, np.int64)
    parent = np.where(parent_segment >= 0, chains.chain_of[np.maximum(parent_segment, 0)], -1).astype(np.int64)
    # chains are numbered in the order their heads were drawn, so a parent comes before its children
    depth = np.zeros(nb, np.int32)
    for b in range(nb):  # one pass, parents first
        if parent[b] >= 0:
            depth[b] = depth[parent[b]] + 1
    lengths = skeleton.lengths()
    along = lengths[chains.segments]  # segment lengths in chain order
    cum = np.cumsum(along)
    base = np.repeat(cum[chains.offsets[:-1]] - along[chains.offsets[:-1]], chains.lengths()) if nb else cum
    end_s = cum - base  # arc length at each segment's end, from its chain's base
    start_s = np.maximum(end_s - along, 0.0)  # rounding may leave -1e-14 at a chain's base
    length = end_s[chains.offsets[1:] - 1] if nb else np.zeros(0)
    safe = np.where(length > 0, length, 1.0)
    owner = chains.chain_of[chains.segments]
    t_start = np.empty(n)
    t_end = np.empty(n)
    t_start[chains.segments] = np.minimum(start_s / safe[owner], 1.0)
    t_end[chains.segments] = np.minimum(end_s / safe[owner], 1.0)
    phase = generator(seed, Stream.WIND_PHASE).random(nb)

    def branch_of_segments(segment: np.ndarray | None, count: int) -> np.ndarray:
        if segment is None or len(segment) != count:
            return np.full(count, -1, np.int64)
        segment = np.asarray(segment, np.int64)
        return np.where(segment >= 0, chains.chain_of[np.clip(segment, 0, max(n - 1, 0))] if n else -1, -1)

    return Hierarchy(
        parent=parent,
        depth=depth,
        order=skeleton.order[first].astype(np.int32) if nb else np.zeros(0, np.int32),
        pivot=skeleton.start[first] if nb else np.zeros((0, 3)),
        length=length,
        phase=phase,
        branch_of=chains.chain_of.copy(),
        t_start=t_start,
        t_end=t_end,
        leaf_branch=branch_of_segments(skeleton.leaf_segment, len(skeleton.leaf_position)),
        polygon_branch=branch_of_segments(skeleton.polygon_segment, skeleton.n_polygons),
    )
