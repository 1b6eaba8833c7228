"""Forward kinematics of a growing tree: its skinned vertices at a time of the growth animation (no wind)."""

from __future__ import annotations

import numpy as np


def joint_transforms(rig, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's world position and world (uniform) scale for one frame's local ``scales`` (parents first)."""
    position = np.zeros((len(rig), 3))
    world = np.ones(len(rig))
    local = rig.local
    for j in range(len(rig)):
        up = int(rig.parent[j])
        if up < 0:
            position[j], world[j] = local[j], scales[j]
        else:
            position[j] = position[up] + world[up] * local[j]
            world[j] = world[up] * scales[j]
    return position, world


def skinned(mesh, rig, scales: np.ndarray) -> np.ndarray:
    """The vertices of a skinned ``mesh`` posed by the local ``scales`` of ``rig``'s joints, ``(v, 3)``."""
    position, world = joint_transforms(rig, scales)
    joints = mesh.attributes["skin_joints"].astype(np.int64)
    weights = mesh.attributes["skin_weights"].astype(np.float64)
    v = mesh.vertices[:, None, :]
    moved = position[joints] + world[joints][..., None] * (v - rig.position[joints])
    return (weights[..., None] * moved).sum(axis=1)
