"""The growth animation: the plant grows from its seed to the static tree, keyed on the rig's joints.

``lsys3d generate foxglove-growing --growth-animation 5`` scales every joint of
the rig (:mod:`lsys3d.look.rig`; built for the growth when ``--rig`` is not
given, with joints on branches of every depth) from zero at its birth to its
full size, by its growth function of its age (ABOP chapter 6):

    scale_j(t) = g_j((t - begin_j) / (end_j - begin_j)),  clipped to [0, 1]

``begin_j`` is the birth of the earliest segment that starts on the joint's
bone and ``end_j`` when the latest of them is full grown (:mod:`lsys3d.turtle.timing`),
mapped from the plant's time onto the clip's seconds (the last organ full
grown at the last second).  A joint's scale is *local*: a twig is scaled by
its own growth and by that of every joint below it, so a young twig sits on a
young branch; every scale is 1 at the end, so the last frame is the rest pose,
the static tree.  Leaves and organs get joints of their own (one per joint
that carries them, at the mean point they grow from, while the rig's joint
budget lasts), which start ``leaf_delay`` after their twig: they unfold after
it.  A window shorter than ``frames_for(g)`` frames is widened so that no
joint's scale moves by more than 15% of its full size from one frame to the
next.

The writers export it as a glTF animation ``growth`` (a ``scale`` channel per
joint: the smooth function is exactly a cubic Hermite spline between two keys,
``CUBICSPLINE``; linear is two ``LINEAR`` keys; the logistic is sampled every
frame) and as the scales of the ``UsdSkel.Animation`` (sampled every frame).
The wind (:mod:`lsys3d.look.wind`) turns the same joints: both play together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..lsystem.ages import FUNCTION_NAMES, FUNCTIONS
from ..mesh.mesh import Mesh
from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from ..turtle.skeleton import Skeleton
from .rig import Rig

__all__ = ["BIRTH", "Growth", "GrowthOptions", "frames_for", "grow", "plant_span", "segment_at", "with_birth"]

BIRTH = "birth"
"""The per-vertex attribute of the birth (glTF ``_BIRTH``, USD ``primvars:birth``)."""
MAX_STEP = 0.15
"""The most a joint's scale moves between two frames, as a share of its full size."""


@dataclass(frozen=True)
class GrowthOptions(Options):
    """The growth animation (off unless ``seconds`` is above 0) and the birth attribute."""

    seconds: float = option(
        0.0,
        low=0,
        high=600,
        name="growth_animation",
        help="seconds of the plant growing from its seed to the static tree, keyed on the rig's joints (0: none)",
    )
    fps: int = option(24, low=1, high=120, name="growth_fps", help="frames per second the growth is sampled at")
    birth: bool = option(
        False,
        name="birth_attribute",
        help="each vertex's birth, a share of the growth (0: seed, 1: full grown): glTF _BIRTH, USD primvars:birth",
    )

    @property
    def enabled(self) -> bool:
        return self.seconds > 0

    @property
    def timed(self) -> bool:
        """Whether the stages need the plant's times (the animation or the birth attribute)."""
        return self.enabled or self.birth


def frames_for(function: str) -> int:
    """The fewest frames a growth window of ``function`` spans (its steepest slope over :data:`MAX_STEP`)."""
    return math.ceil(FUNCTIONS[function].slope / MAX_STEP)


@dataclass(frozen=True, eq=False)
class Growth:
    """Each joint's growth window, in seconds of the clip.

    Attributes
    ----------
    begin, end : (j,) float64
        When each joint's scale leaves 0 and reaches 1 (``end > begin`` where ``keyed``).
    function : (j,) int8
        Each joint's growth function (an index into :data:`lsys3d.lsystem.ages.FUNCTION_NAMES`).
    keyed : (j,) bool
        Joints that grow (joints carrying nothing stay at scale 1; the root grows with the first joint on it,
        whose base is bound half to it).
    seconds : float
        The clip's length.
    fps : int
        Frames per second.
    span : float
        The plant's time the clip covers (its last organ is full grown then).
    """

    begin: np.ndarray
    end: np.ndarray
    function: np.ndarray
    keyed: np.ndarray
    seconds: float
    fps: int
    span: float

    @property
    def times(self) -> np.ndarray:
        """The frames' times, ``(f,) float64``, 0 to ``seconds``."""
        return np.arange(round(self.seconds * self.fps) + 1) / self.fps

    def scales(self, times: np.ndarray | None = None) -> np.ndarray:
        """Each joint's local scale at ``times`` (default: every frame), ``(f, j) float64``."""
        times = self.times if times is None else np.asarray(times, np.float64)
        width = np.where(self.keyed, self.end - self.begin, 1.0)
        x = np.clip((times[:, None] - self.begin) / width, 0.0, 1.0)
        out = np.ones_like(x)
        for code, name in enumerate(FUNCTION_NAMES):
            mine = self.keyed & (self.function == code)
            if mine.any():
                out[:, mine] = FUNCTIONS[name].f(x[:, mine])
        return np.where(self.keyed, out, 1.0)


def segment_at(skeleton: Skeleton, h: Hierarchy, branch: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The segment of each point ``t`` along ``branch``, ``(v,) int64`` (-1 for branch -1)."""
    branch = np.asarray(branch, np.int64)
    if not len(skeleton):
        return np.full(len(branch), -1, np.int64)
    order = np.lexsort((h.t_start, h.branch_of))
    key = h.branch_of[order] + 0.5 * h.t_start[order]
    query = np.maximum(branch, 0) + 0.5 * np.clip(np.asarray(t, np.float64), 0.0, 1.0)
    i = np.clip(np.searchsorted(key, query, side="right") - 1, 0, len(order) - 1)
    return np.where(branch >= 0, order[i], -1)


def plant_span(skeleton: Skeleton) -> float:
    """The plant's time at which its last segment, leaf or organ is full grown (at least a small positive time)."""
    ends = [a.max() for a in (skeleton.mature, skeleton.leaf_mature, skeleton.organ_mature) if a is not None and len(a)]
    return max([1e-9, *ends])


def with_birth(mesh: Mesh, skeleton: Skeleton, h: Hierarchy, delay: float = 0.0) -> Mesh:
    """``mesh`` with the :data:`BIRTH` of its vertices, a fraction of :func:`plant_span`.

    A vertex is born with the segment it lies on (its ``branch_id`` and ``branch_t``), plus ``delay`` for
    leaves and organs (they unfold after their twig).
    """
    if mesh is None or not len(mesh.vertices) or "branch_id" not in mesh.attributes:
        return mesh
    seg = segment_at(skeleton, h, mesh.attributes["branch_id"], mesh.attributes["branch_t"])
    born = np.where(seg >= 0, skeleton.birth[np.maximum(seg, 0)] if len(skeleton) else 0.0, 0.0) + delay
    return mesh.with_attributes({BIRTH: (born / plant_span(skeleton)).astype(np.float32)})


def _window(times: np.ndarray, joint: np.ndarray, joints: int) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest of ``times`` per joint (inf and -inf where a joint has none)."""
    low, high = np.full(joints, np.inf), np.full(joints, -np.inf)
    np.minimum.at(low, joint, times)
    np.maximum.at(high, joint, times)
    return low, high


def grow(
    rig: Rig,
    h: Hierarchy,
    skeleton: Skeleton,
    options: GrowthOptions,
    function: str = "smooth",
    leaf_windows: tuple[np.ndarray, np.ndarray] | None = None,
) -> Growth:
    """The growth of ``rig``'s joints (see the module docstring); ``skeleton`` carries the times.

    ``leaf_windows`` are the plant-time windows of the leaf joints (:func:`lsys3d.look.rig.leaf_joints`), ``-inf``
    / ``inf`` elsewhere; ``function`` is the growth function of the segments without one of their own.

    Examples
    --------
    >>> import lsys3d
    >>> tree = lsys3d.generate("abop-1.24a", iterations=2, growth_animation=2)
    >>> scales = tree.growth.scales()
    >>> scales.shape == (49, len(tree.rig)), bool((scales[-1] == 1).all()), bool((scales[0] == 0).all())
    (True, True, True)
    """
    j = len(rig)
    n = len(skeleton)
    begin, end = np.full(j, np.inf), np.full(j, -np.inf)
    fn = np.full(j, FUNCTION_NAMES.index(function), np.int8)
    if n:
        b = h.branch_of
        k = rig.count[b]
        own = k > 0  # segments on branches without joints ride their carrier: they grow with it
        # a segment grows from its base: it times the joint whose span its base lies in (a joint whose span no
        # segment starts in stays at 1: the segment over it grows with the joint below)
        at = np.floor(h.t_start * k + 1e-9)
        joint = rig.first[b] + np.minimum(at, np.maximum(k - 1, 0)).astype(np.int64)
        begin, _ = _window(skeleton.birth[own], joint[own], j)
        _, end = _window(skeleton.mature[own], joint[own], j)
        if skeleton.growth_function is not None:  # the function of the first segment each joint carries
            first = np.full(j, n, np.int64)
            np.minimum.at(first, joint[own], np.flatnonzero(own))
            has = first < n
            fn[has] = skeleton.growth_function[first[has]]
    if leaf_windows is not None:
        low, high = leaf_windows
        begin, end = np.minimum(begin, low), np.maximum(end, high)
    keyed = np.isfinite(begin) & np.isfinite(end)
    keyed[0] = False
    first = np.flatnonzero(keyed & (rig.parent == 0))
    if len(first):  # the root grows with the first joint on it: the trunk's base is bound half to it
        k = first[np.argmin(begin[first])]
        begin[0], end[0], fn[0], keyed[0] = begin[k], end[k], fn[k], True
    span = plant_span(skeleton)
    if leaf_windows is not None and np.isfinite(leaf_windows[1]).any():
        span = max(span, float(leaf_windows[1][np.isfinite(leaf_windows[1])].max()))
    scale = options.seconds / span
    begin = np.where(keyed, np.clip(begin * scale, 0.0, options.seconds), 0.0)
    end = np.where(keyed, np.clip(end * scale, 0.0, options.seconds), 0.0)
    if leaf_windows is not None:  # a leaf unfolds after the joint it hangs on starts to grow, never before
        leafy = np.flatnonzero(np.isfinite(leaf_windows[0]) & keyed)
        begin[leafy] = np.maximum(begin[leafy], begin[rig.parent[leafy]])
    # widen short windows (toward the end, then back from it) so that no frame steps too far
    shortest = np.array([frames_for(name) for name in FUNCTION_NAMES])[fn] / options.fps
    shortest = np.minimum(shortest, options.seconds)
    end = np.maximum(end, np.minimum(begin + shortest, options.seconds))
    begin = np.where(end - begin < shortest, np.maximum(end - shortest, 0.0), begin)
    keyed &= end > begin
    begin, end = np.where(keyed, begin, 0.0), np.where(keyed, end, 0.0)
    return Growth(begin, end, fn, keyed, float(options.seconds), int(options.fps), float(span))


def leaf_joints(rig: Rig, h: Hierarchy, skeleton: Skeleton, meshes: list, delay: float, duration: float, limit: int):
    """Joints of the leaves and organs: one per joint that carries some, while the rig stays within ``limit``.

    ``meshes`` are the bound leaf and organ meshes (with ``skin_joints``, ``branch_id``, ``branch_t``).
    Returns ``(rig, joint_map, windows)``: the rig with the new joints (each at the mean point its leaves
    grow from, a child of the joint they were bound to, branch -1), ``joint_map`` ``(j,) int64`` the leaf
    joint of each old joint (-1: none), and ``windows`` (``begin``, ``end``) in the plant's time, per joint
    of the new rig (``inf`` / ``-inf`` for the others).
    """
    j = len(rig)
    count = np.zeros(j)
    point = np.zeros((j, 3))
    low, high = np.full(j, np.inf), np.full(j, -np.inf)
    for mesh in meshes:
        if mesh is None or not len(mesh.vertices) or "skin_joints" not in mesh.attributes:
            continue
        bone = mesh.attributes["skin_joints"][:, 0].astype(np.int64)
        seg = segment_at(skeleton, h, mesh.attributes["branch_id"], mesh.attributes["branch_t"])
        ok = seg >= 0
        s, t = seg[ok], mesh.attributes["branch_t"][ok]
        span = np.where(h.t_end[s] > h.t_start[s], h.t_end[s] - h.t_start[s], 1.0)
        f = np.clip((t - h.t_start[s]) / span, 0.0, 1.0)[:, None]
        np.add.at(point, bone[ok], skeleton.start[s] * (1 - f) + skeleton.end[s] * f)
        np.add.at(count, bone[ok], 1.0)
        a, b = _window(skeleton.birth[s] + delay, bone[ok], j)
        low, high = np.minimum(low, a), np.maximum(high, b + duration)
    carriers = np.flatnonzero(count > 0)[: max(limit - j, 0)]
    joint_map = np.full(j, -1, np.int64)
    joint_map[carriers] = j + np.arange(len(carriers))
    new = len(carriers)
    grown = replace(
        rig,
        names=rig.names + tuple(f"{rig.names[c]}_leaves" for c in carriers.tolist()),
        parent=np.concatenate([rig.parent, carriers]),
        position=np.concatenate([rig.position, point[carriers] / count[carriers, None]]),
        branch=np.concatenate([rig.branch, np.full(new, -1, np.int64)]),
        t=np.concatenate([rig.t, np.zeros(new)]),
    )
    windows = (
        np.concatenate([np.full(j, np.inf), low[carriers]]),
        np.concatenate([np.full(j, -np.inf), high[carriers]]),
    )
    return grown, joint_map, windows


def rebind(mesh: Mesh | None, joint_map: np.ndarray) -> Mesh | None:
    """A rigidly bound leaf or organ ``mesh`` moved onto the leaf joints of ``joint_map``."""
    if mesh is None or not len(mesh.vertices) or "skin_joints" not in mesh.attributes or not len(joint_map):
        return mesh
    joints = mesh.attributes["skin_joints"].copy()
    bone = joints[:, 0].astype(np.int64)
    moved = joint_map[bone]
    joints[:, 0] = np.where(moved >= 0, moved, bone).astype(joints.dtype)
    return mesh.with_attributes({"skin_joints": joints})
