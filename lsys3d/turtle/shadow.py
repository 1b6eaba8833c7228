"""The plant's own shade: a crown's self-shadowing sampled on a voxel grid.

With ``shadow = true`` in ``[environment]``, each turtle pass between derivation steps records where
the plant holds area: every segment at its middle (its length times its width) and every leaf at its
place (its size squared).  :func:`shade` sums that area into voxels of ``shadow_voxel`` metres and
attenuates the light along the direction toward it by Beer-Lambert's law, as the shadow-propagation
models of self-organising trees do (Palubicki et al. 2009, a voxel's shadow cast on the voxels below
it; here ``exp(-k * sum(area density * length))`` over the voxels the ray crosses, a voxel's area
density being its area over ``shadow_voxel`` cubed).  The light a point receives is the transmission along
the ray from it toward the light, leaving out the point's own voxel (a leaf does not shade the bud it
stands by).  ``?E``'s light value ``l``
is this transmission times the scene's own (0 behind a scene mesh): rules that read it let shaded buds
rest, as the bud fates of those models do.
"""

from __future__ import annotations

import math

import numpy as np

from ..compiling import kernel
from ..errors import LimitError

__all__ = ["MAX_SHADOW_VOXELS", "shade"]

MAX_SHADOW_VOXELS = 8_000_000
"""Most voxels of the shade grid (a plant larger than this many voxels of ``shadow_voxel`` is refused)."""


@kernel(nogil=True)
def _occupancy(deposits, origin, voxel, shape):
    grid = np.zeros(shape)
    for k in range(deposits.shape[0]):
        i = int((deposits[k, 0] - origin[0]) / voxel)
        j = int((deposits[k, 1] - origin[1]) / voxel)
        m = int((deposits[k, 2] - origin[2]) / voxel)
        grid[i, j, m] += deposits[k, 3]
    return grid


@kernel(nogil=True)
def _transmission(depth, origin, voxel, points, directions, out):
    """exp(-optical depth) along each point's ray through the voxels (a 3D DDA, Amanatides and Woo 1987):
    each voxel crossed adds its depth per voxel length times the length of the ray inside it; the point's own
    voxel adds nothing."""
    shape = depth.shape
    for k in range(points.shape[0]):
        x = np.empty(3)
        d = np.empty(3)
        for a in range(3):
            x[a] = (points[k, a] - origin[a]) / voxel
            d[a] = directions[k, a]
        t0, t1 = 0.0, np.inf  # the ray's part inside the grid, in voxel lengths
        for a in range(3):
            if d[a] == 0.0:
                if x[a] < 0.0 or x[a] >= shape[a]:
                    t0, t1 = 1.0, 0.0
            else:
                u, v = (0.0 - x[a]) / d[a], (shape[a] - x[a]) / d[a]
                t0 = max(t0, min(u, v))
                t1 = min(t1, max(u, v))
        total = 0.0
        if t0 < t1:
            own = np.empty(3, np.int64)
            cell = np.empty(3, np.int64)
            step = np.empty(3, np.int64)
            t_next = np.empty(3)
            for a in range(3):
                own[a] = math.floor(x[a])
                c = math.floor(x[a] + d[a] * t0)
                cell[a] = min(max(c, 0), shape[a] - 1)
                if d[a] > 0.0:
                    step[a] = 1
                    t_next[a] = (cell[a] + 1 - x[a]) / d[a]
                elif d[a] < 0.0:
                    step[a] = -1
                    t_next[a] = (cell[a] - x[a]) / d[a]
                else:
                    step[a] = 0
                    t_next[a] = np.inf
            t = t0
            while t < t1:
                a = 0
                if t_next[1] < t_next[a]:
                    a = 1
                if t_next[2] < t_next[a]:
                    a = 2
                t_out = min(t_next[a], t1)
                if not (cell[0] == own[0] and cell[1] == own[1] and cell[2] == own[2]):
                    total += depth[cell[0], cell[1], cell[2]] * (t_out - t)
                t = t_out
                cell[a] += step[a]
                if cell[a] < 0 or cell[a] >= shape[a]:
                    break
                t_next[a] += abs(1.0 / d[a])
        out[k] = math.exp(-total)


def shade(deposits: np.ndarray, points: np.ndarray, options) -> np.ndarray:
    """The light each point receives through the plant's own area (1: none in the way).

    Parameters
    ----------
    deposits : (d, 4) float64
        Where the plant holds area (x, y, z) and how much (square metres).
    points : (k, 3) float64
        Where the light is asked for.
    options : EnvironmentOptions
        ``shadow_voxel``, ``shadow_extinction`` and the light (``light`` or ``light_point``; straight up
        without either).

    Examples
    --------
    A square metre of leaves in a voxel of 1 m: below it the light is ``exp(-0.5 * 1 / 1 * 1)``.

    >>> from lsys3d.turtle.environment import EnvironmentOptions
    >>> o = EnvironmentOptions(shadow=True, shadow_voxel=1.0, shadow_extinction=0.5)
    >>> leaves = np.array([[0.5, 1.5, 0.5, 1.0]])
    >>> shade(leaves, np.array([[0.5, 0.5, 0.5], [0.5, 2.5, 0.5], [0.5, 1.5, 0.5]]), o).round(4).tolist()
    [0.6065, 1.0, 1.0]
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    out = np.ones(len(points))
    if not len(points) or not len(deposits):
        return out
    voxel = float(options.shadow_voxel)
    lo = deposits[:, :3].min(axis=0) - voxel
    hi = deposits[:, :3].max(axis=0) + voxel
    origin = np.floor(lo / voxel) * voxel  # voxels on a fixed lattice: the same plant part, the same voxel
    shape = tuple(int(x) for x in np.floor((hi - origin) / voxel).astype(np.int64) + 1)
    if math.prod(shape) > MAX_SHADOW_VOXELS:
        raise LimitError(
            f"[environment] shadow: the plant spans {shape[0]} x {shape[1]} x {shape[2]} voxels of {voxel:g} m, "
            f"more than {MAX_SHADOW_VOXELS:,} (lsys3d.turtle.shadow.MAX_SHADOW_VOXELS): raise shadow_voxel"
        )
    area = _occupancy(deposits, origin, voxel, shape)
    depth = area * (options.shadow_extinction / (voxel * voxel))
    if options.light_point:
        directions = np.asarray(options.light_point, np.float64) - points
    else:
        light = np.asarray(options.light, np.float64) if any(options.light) else np.array([0.0, 1.0, 0.0])
        directions = np.broadcast_to(light, points.shape).copy()
    norm = np.linalg.norm(directions, axis=1, keepdims=True)
    directions = np.where(norm > 0, directions / np.where(norm > 0, norm, 1.0), [0.0, 1.0, 0.0])
    _transmission(depth, origin, voxel, np.ascontiguousarray(points), np.ascontiguousarray(directions), out)
    return out
