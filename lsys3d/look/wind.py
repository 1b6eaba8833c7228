"""A sample wind animation: a few seconds of sway on the rig's joints, looping, by branch depth.

``lsys3d generate tree3d --rig --wind-animation 4`` keys every joint of the rig
(:mod:`lsys3d.look.rig`) ``--wind-fps`` times a second for 4 seconds.  The wind
blows along +X (lsys3d's frame: horizontal, to the tree's right); each joint
turns its branch toward it, about the axis across the branch and the wind:

    angle(t) = amplitude * (0.5 + 0.5 * sin(2 pi (f t + phase)))

so a branch leans into the wind and back, never against it.  The amplitude
is ``--wind-strength`` degrees for a whole branch at depth 3 or deeper, less
for the trunk and the big limbs (a fraction ``1 - 0.75 ** (depth + 1)`` of it
over ``0.68``, capped at 1: 37% for the trunk, 64% for its children, 85%
for theirs), shared out among the branch's joints.  The frequency ``f`` is about 0.5 Hz
for the trunk and faster for deeper branches (``0.5 * (1 + 0.35 * depth)``),
rounded to a whole number of cycles in the animation so it loops without a
jump; ``phase`` is the branch's seeded wind phase
(:attr:`lsys3d.turtle.hierarchy.Hierarchy.phase`), so neighbours do not move in step.

The writers export it as a glTF animation (one ``rotation`` channel per
joint, linear) and a ``UsdSkel.Animation`` (rotations as time samples, the
rest translations, unit scales) bound to the rig's skeleton.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LimitError
from ..options import Options, option
from ..turtle.hierarchy import Hierarchy
from .rig import Rig

__all__ = ["MAX_WIND_KEYS", "WIND", "Animation", "WindOptions", "sway"]

MAX_WIND_KEYS = 16_000_000
"""Most joint keyframes (keyframes times joints) of a wind animation: about 130 bytes each while it is made
and written (``benchmarks``: 17,693 joints x 121 keyframes took 280 MB over the tree), so 2 GB at most.
``--wind-animation 60 --wind-fps 120`` on a rig of 17,693 joints would be 127 million (17 GB)."""

WIND = np.array([1.0, 0.0, 0.0])
"""The direction the sample wind blows (lsys3d's frame: +X, horizontal)."""


@dataclass(frozen=True)
class WindOptions(Options):
    """The sample wind animation of a rigged tree (off unless ``seconds`` is above 0)."""

    seconds: float = option(
        0.0, low=0, high=60, name="wind_animation", help="seconds of looping wind sway keyed on the rig (0: none)"
    )
    strength: float = option(
        6.0, low=0, high=45, name="wind_strength", help="sway of a whole twig in the wind animation, degrees"
    )
    fps: int = option(24, low=1, high=120, name="wind_fps", help="keyframes per second of the wind animation")

    @property
    def enabled(self) -> bool:
        return self.seconds > 0


@dataclass(frozen=True, eq=False)
class Animation:
    """Joint rotations over time.

    Attributes
    ----------
    times : (n,) float64
        Seconds, from 0 to the animation's length; the last pose is the first (it loops).
    rotations : (n, j, 4) float32
        Each joint's rotation relative to its parent, a unit quaternion ``(x, y, z, w)``
        (the root's stays the identity).
    fps : int
        Keyframes per second.
    """

    times: np.ndarray
    rotations: np.ndarray
    fps: int

    def __len__(self) -> int:
        return len(self.times)


def _directions(rig: Rig) -> np.ndarray:
    """Each joint's direction along its branch: toward the next joint of the branch, else from the previous one."""
    j = len(rig.names)
    direction = np.zeros((j, 3))
    for b in np.flatnonzero(rig.count > 0).tolist():
        first, count = int(rig.first[b]), int(rig.count[b])
        joints = np.arange(first, first + count)
        points = rig.position[joints]
        if count > 1:
            step = np.diff(points, axis=0)
            direction[joints[:-1]] = step
            direction[joints[-1]] = step[-1]
        else:  # one joint: from the joint it hangs on
            direction[first] = rig.position[first] - rig.position[rig.parent[first]]
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    return np.where(length > 1e-12, direction / np.where(length > 0, length, 1), [0.0, 1.0, 0.0])


def sway(rig: Rig, h: Hierarchy, options: WindOptions) -> Animation:
    """The sample wind animation of ``rig`` (see the module docstring).

    Examples
    --------
    >>> import lsys3d
    >>> tree = lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=2, wind_fps=12)
    >>> anim = tree.animation
    >>> len(anim), anim.rotations.shape[1] == len(tree.rig), bool(np.allclose(anim.rotations[0], anim.rotations[-1]))
    (25, True, True)
    """
    n = round(options.seconds * options.fps) + 1
    joints = len(rig.names)
    if n * joints > MAX_WIND_KEYS:  # predicted before anything is allocated
        raise LimitError(
            f"wind: {n:,} keyframes for {joints:,} joints would be {n * joints:,} joint keys, more than "
            f"{MAX_WIND_KEYS:,} (lsys3d.look.wind.MAX_WIND_KEYS); lower --wind-animation, --wind-fps or --rig-joints"
        )
    times = np.arange(n) / options.fps
    seconds = times[-1]
    rotations = np.zeros((n, joints, 4), np.float32)
    rotations[:, :, 3] = 1.0
    moving = np.flatnonzero(rig.branch >= 0)
    if not len(moving) or seconds <= 0:
        return Animation(times, rotations, options.fps)
    branch = rig.branch[moving]
    depth = h.depth[branch].astype(np.float64)
    share = np.minimum((1 - 0.75 ** (depth + 1)) / 0.68, 1.0)
    amplitude = np.radians(options.strength) * share / rig.count[branch]
    cycles = np.maximum(1, np.round(seconds * 0.5 * (1 + 0.35 * depth)))  # a whole number: it loops
    axis = np.cross(_directions(rig)[moving], WIND)
    length = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(length > 1e-9, axis / np.where(length > 0, length, 1), [0.0, 0.0, -1.0])  # along the wind
    phase = h.phase[branch]
    angle = amplitude * (0.5 + 0.5 * np.sin(2 * np.pi * (cycles * times[:, None] / seconds + phase)))
    half = angle / 2
    rotations[:, moving, :3] = (np.sin(half)[:, :, None] * axis[None]).astype(np.float32)
    rotations[:, moving, 3] = np.cos(half).astype(np.float32)
    return Animation(times, rotations, options.fps)
