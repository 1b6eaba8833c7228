"""A rig: joints along the branches, and skin weights that bind the bark and the leaves to them.

Joints follow the branch hierarchy (:mod:`lsys3d.turtle.hierarchy`).  A ``root`` joint
stands at the origin; every rigged branch gets up to
``RigOptions.joints_per_branch`` joints along it (fewer on shorter branches:
as many as its share of the longest branch's length), the first at its base,
parented to the joint of its parent branch that the branch grows from.
Branches are rigged by depth, then length, while the joint budget
``RigOptions.max_joints`` lasts and down to ``RigOptions.max_depth``; a branch
left out follows the joint its nearest rigged ancestor carries it on.

Skin weights (4 joints a vertex at most, summing to 1): a vertex belongs to the
joint below it on its branch, and blends linearly into the next joint over a
band of a quarter of the bone around that joint, so a bend is smooth.  At a
branch's base the weights blend half into the parent's joint, so the seam where
a branch joins its parent (the union's intersection curve) bends smoothly
instead of tearing between two joints.  Leaves are bound whole to the joint of
the point they grow from, so they follow their twig.

Examples
--------
>>> import lsys3d
>>> from lsys3d.turtle.hierarchy import hierarchy
>>> tree = lsys3d.generate("abop-1.24a", iterations=2, sides=4)
>>> rig = build_rig(hierarchy(tree.skeleton), tree.skeleton, RigOptions(enabled=True, joints_per_branch=2))
>>> rig.names[:3], rig.parent[:3].tolist()
(('root', 'b0_j0', 'b0_j1'), [-1, 0, 1])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import Skeleton

__all__ = ["INFLUENCES", "SKIN_KEYS", "Rig", "RigOptions", "bind", "build_rig", "skin_weights"]

INFLUENCES = 4
"""Joints that may move one vertex (glTF's JOINTS_0 / WEIGHTS_0, UsdSkel's elementSize)."""

BLEND = 0.25
"""Half-width of the blend between two joints of a branch, as a fraction of the bone before the joint."""


@dataclass(frozen=True)
class RigOptions(Options):
    """Whether the asset carries a rig, and how many joints it may have."""

    enabled: bool = option(False, name="rig", help="a joint hierarchy along the branches, skinned to bark and leaves")
    max_joints: int = option(256, low=2, high=65536, name="rig_joints", help="most joints, the root included")
    joints_per_branch: int = option(4, low=1, high=256, name="rig_joints_per_branch", help="most joints on a branch")
    max_depth: int = option(
        3,
        low=0,
        high=1_000_000,
        name="rig_depth",
        help="deepest branches with joints (deeper ones ride their parent's)",
    )


@dataclass(frozen=True, eq=False)
class Rig:
    """Joints in their rest pose.

    Attributes
    ----------
    names : tuple of str
        ``root``, then ``b<branch>_j<i>``: unique, stable for a given tree.
    parent : (j,) int64
        Parent joint (-1 for the root); a parent comes before its children.
    position : (j, 3) float64
        Rest position (world, metres); joints are not rotated in the rest pose.
    branch : (j,) int64
        The branch each joint lies on (-1 for the root).
    t : (j,) float64
        Where along its branch (0 at the base).
    first : (b,) int64
        Each branch's first joint (-1 for branches without joints).
    count : (b,) int64
        Each branch's number of joints.
    carrier : (b,) int64
        For a branch without joints, the joint that carries it (on its nearest rigged ancestor).
    attach_t : (b,) float64
        Where along its parent branch each branch grows from.
    """

    names: tuple[str, ...]
    parent: np.ndarray
    position: np.ndarray
    branch: np.ndarray
    t: np.ndarray
    first: np.ndarray
    count: np.ndarray
    carrier: np.ndarray
    attach_t: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    @property
    def local(self) -> np.ndarray:
        """Each joint's rest translation from its parent, ``(j, 3)``."""
        out = self.position.copy()
        has = self.parent >= 0
        out[has] -= self.position[self.parent[has]]
        return out


def _points_along(h: Hierarchy, skeleton: Skeleton, branch: int, ts: np.ndarray) -> np.ndarray:
    """Points at ``ts`` along a branch (its segments' polyline)."""
    segs = np.flatnonzero(h.branch_of == branch)
    segs = segs[np.argsort(h.t_start[segs], kind="stable")]
    t0, t1 = h.t_start[segs], h.t_end[segs]
    k = np.clip(np.searchsorted(t1, ts, side="left"), 0, len(segs) - 1)
    span = np.where(t1[k] > t0[k], t1[k] - t0[k], 1.0)
    f = np.clip((ts - t0[k]) / span, 0.0, 1.0)[:, None]
    s = segs[k]
    return skeleton.start[s] * (1.0 - f) + skeleton.end[s] * f


def build_rig(h: Hierarchy, skeleton: Skeleton, options: RigOptions) -> Rig:
    """The joints of a tree's rig (see the module docstring for the rules)."""
    nb = len(h)
    first = np.full(nb, -1, np.int64)
    count = np.zeros(nb, np.int64)
    carrier = np.zeros(nb, np.int64)
    # where each branch grows from along its parent: the end of its first segment's parent
    attach_t = np.zeros(nb)
    if nb:
        chains = skeleton.chains
        head = chains.segments[chains.offsets[:-1]]
        parent_segment = skeleton.parent[head]
        attach_t = np.where(parent_segment >= 0, h.t_end[np.maximum(parent_segment, 0)], 0.0)
    names, parent, position, jbranch, jt = ["root"], [-1], [np.zeros(3)], [-1], [0.0]
    longest = float(h.length.max()) if nb else 1.0
    budget = options.max_joints - 1
    order = np.lexsort((np.arange(nb), -h.length, h.depth)) if nb else np.zeros(0, np.int64)
    for b in order.tolist():
        p = int(h.parent[b])
        if h.depth[b] > options.max_depth or (p >= 0 and count[p] == 0) or budget <= 0:
            continue
        k = int(np.clip(np.ceil(options.joints_per_branch * h.length[b] / max(longest, 1e-300)), 1, budget))
        k = min(k, options.joints_per_branch)
        ts = np.arange(k) / k
        points = _points_along(h, skeleton, b, ts)
        up = 0 if p < 0 else _joint_at(first[p], count[p], attach_t[b])
        first[b] = len(names)
        count[b] = k
        for i in range(k):
            names.append(f"b{b}_j{i}")
            parent.append(up if i == 0 else len(names) - 2)
            position.append(points[i])
            jbranch.append(b)
            jt.append(ts[i])
        budget -= k
    for b in range(nb):  # branches without joints ride the joint their nearest rigged ancestor carries them on
        if count[b]:
            continue
        p = int(h.parent[b])
        carrier[b] = 0 if p < 0 else (_joint_at(first[p], count[p], attach_t[b]) if count[p] else carrier[p])
    return Rig(
        names=tuple(names),
        parent=np.array(parent, np.int64),
        position=np.array(position, np.float64).reshape(-1, 3),
        branch=np.array(jbranch, np.int64),
        t=np.array(jt, np.float64),
        first=first,
        count=count,
        carrier=carrier,
        attach_t=attach_t,
    )


def _joint_at(first: int, count: int, t: float) -> int:
    """The joint of a rigged branch below ``t`` (its joints sit at i / count)."""
    return int(first + min(int(np.floor(t * count + 1e-9)), count - 1))


def skin_weights(rig: Rig, h: Hierarchy, branch: np.ndarray, t: np.ndarray, rigid: bool = False):
    """Joints and weights of points on ``branch`` at ``t``: ``(v, 4) int64`` and ``(v, 4) float32`` summing to 1.

    ``rigid`` binds each point wholly to the joint below it (leaves, which follow their twig unbent).
    Points without a branch (-1) are bound to the root.
    """
    branch = np.asarray(branch, np.int64)
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)
    v = len(branch)
    joints = np.zeros((v, INFLUENCES), np.int64)
    weights = np.zeros((v, INFLUENCES), np.float64)
    has = branch >= 0
    b = np.where(has, branch, 0)
    if not len(h):
        weights[:, 0] = 1.0
        return joints, weights.astype(np.float32)
    k = np.where(has, rig.count[b], 0)
    rigged = has & (k > 0)
    # points on branches without joints, or without a branch: wholly on their carrier (or the root)
    joints[~rigged, 0] = np.where(has[~rigged], rig.carrier[b[~rigged]], 0)
    weights[~rigged, 0] = 1.0
    idx = np.flatnonzero(rigged)
    if not len(idx):
        return joints, weights.astype(np.float32)
    kk = k[idx].astype(np.float64)
    first = rig.first[b[idx]]
    pos = t[idx] * kk  # in bones: joint i at i
    i = np.minimum(np.floor(pos), kk - 1).astype(np.int64)
    frac = pos - i  # how far along bone i
    own = first + i
    joints[idx, 0] = own
    weights[idx, 0] = 1.0
    if rigid:
        return joints, weights.astype(np.float32)
    # into the next joint of the branch: linear over frac in [1 - BLEND, 1 + BLEND), half at the joint
    nxt = (frac > 1.0 - BLEND) & (i + 1 < kk)
    f = np.clip((frac - (1.0 - BLEND)) / (2 * BLEND), 0.0, 0.5)
    joints[idx[nxt], 1] = own[nxt] + 1
    weights[idx[nxt], 1] = f[nxt]
    weights[idx[nxt], 0] = 1.0 - f[nxt]
    # out of the previous joint (the other side of the same band)
    prv = (frac < BLEND) & (i > 0)
    g = np.clip(0.5 - frac / (2 * BLEND), 0.0, 0.5)
    joints[idx[prv], 1] = own[prv] - 1
    weights[idx[prv], 1] = g[prv]
    weights[idx[prv], 0] = 1.0 - g[prv]
    # at the branch's base: half into the parent joint it grows from (the seam bends smoothly)
    base = (frac < BLEND) & (i == 0)
    up = rig.parent[own[base]]
    joints[idx[base], 1] = up
    weights[idx[base], 1] = g[base]
    weights[idx[base], 0] = 1.0 - g[base]
    return joints, weights.astype(np.float32)


SKIN_KEYS = ("skin_joints", "skin_weights")
"""The skin's per-vertex attributes (``Mesh.attributes``): joint indices (exact small integers) and weights."""


def bind(bark, leaves, rig: Rig, h: Hierarchy):
    """The rig stage's binding: ``bark`` and the merged ``leaves`` with their skins (:data:`SKIN_KEYS`).

    Both meshes must carry ``branch_id`` and ``branch_t`` (:mod:`lsys3d.look.attributes`); leaves are bound
    rigidly to the joint of the point they grow from.  Returns the new ``(bark, leaves)``.
    """
    from dataclasses import replace

    def skinned(mesh, rigid):
        if mesh is None or not len(mesh.vertices):
            return mesh
        joints, weights = skin_weights(rig, h, mesh.attributes["branch_id"], mesh.attributes["branch_t"], rigid)
        return mesh.with_attributes({"skin_joints": joints.astype(np.float32), "skin_weights": weights})

    if leaves.merged is not None:
        leaves = replace(leaves, merged=skinned(leaves.merged, True))
    return skinned(bark, False), leaves
