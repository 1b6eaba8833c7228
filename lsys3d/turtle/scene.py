"""The scene as the turtle's kernel sees it: signed distance grids, their samples, and a segment's steering.

:class:`Scene` holds the environment (:mod:`lsys3d.turtle.environment` builds it) as the kernel reads it;
:func:`_steer` is the environment's say on one segment (light, adhesion, climbing, hanging, deflecting or
cutting), called by the drawing turtle (:func:`lsys3d.turtle.kernel.run`) and by the lean pass that answers
derivation's questions (:func:`lsys3d.turtle.incremental.answer_pass`); :func:`probe` answers ``?E``.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ..compiling import inner, kernel
from .bending import _AXIS_U, _bend, _orthonormal, _rotate, rodrigues

__all__ = ["FAR_OUTSIDE", "SCENE_PARAMS", "Scene", "probe"]

Scene = namedtuple("Scene", ["origin", "cell", "obstacle", "volume", "support", "params"])
"""The environment as the kernel sees it (:mod:`lsys3d.turtle.environment`): signed distance grids (positive
outside the solid; ``(0, 0, 0)`` when the role is absent) sampled from ``origin`` every ``cell``, and
``params`` (the ``SCENE_*`` indices)."""

SCENE_DISTANCE, SCENE_ADHESION, SCENE_CLIMB, SCENE_HANG, SCENE_PHOTOTROPISM = 0, 1, 2, 3, 4
SCENE_LIGHT, SCENE_LIGHT_POINT, SCENE_DEFLECT, SCENE_CLEARANCE, SCENE_SOLID_SUPPORT, SCENE_REACH = 5, 8, 9, 10, 11, 12
SCENE_RELEASE = 13
SCENE_PARAMS = 14
FAR_OUTSIDE = 1e9
"""The signed distance of a point outside a grid: far outside every solid."""


# The environment's helpers below are called, not inlined as numba IR: inlined, numba typed and lowered them again
# inside run (9 of the oak's 25 compile CPU seconds, with _rotate_points' slice assignments); LLVM inlines them.
# Without NRT (they allocate nothing) no call counts references to the scene's arrays (bench_environment: 20 -> 13 ms).
@inner(_nrt=False)
def _sample(grid, origin, cell, x, y, z):
    """The grid's signed distance at a point: trilinear between its nodes, :data:`FAR_OUTSIDE` off the grid."""
    nx, ny, nz = grid.shape
    fx = (x - origin[0]) / cell
    fy = (y - origin[1]) / cell
    fz = (z - origin[2]) / cell
    if not (0.0 <= fx <= nx - 1 and 0.0 <= fy <= ny - 1 and 0.0 <= fz <= nz - 1):
        return FAR_OUTSIDE
    i = min(int(fx), nx - 2)
    j = min(int(fy), ny - 2)
    k = min(int(fz), nz - 2)
    a, b, c = fx - i, fy - j, fz - k
    c00 = grid[i, j, k] * (1 - a) + grid[i + 1, j, k] * a
    c10 = grid[i, j + 1, k] * (1 - a) + grid[i + 1, j + 1, k] * a
    c01 = grid[i, j, k + 1] * (1 - a) + grid[i + 1, j, k + 1] * a
    c11 = grid[i, j + 1, k + 1] * (1 - a) + grid[i + 1, j + 1, k + 1] * a
    return (c00 * (1 - b) + c10 * b) * (1 - c) + (c01 * (1 - b) + c11 * b) * c


@inner(_nrt=False)
def _sample_gradient(grid, origin, cell, x, y, z):
    """The grid's trilinear distance at a point and its gradient (the interpolant's own, from the same eight
    nodes); :data:`FAR_OUTSIDE` and a zero gradient off the grid."""
    nx, ny, nz = grid.shape
    fx = (x - origin[0]) / cell
    fy = (y - origin[1]) / cell
    fz = (z - origin[2]) / cell
    if not (0.0 <= fx <= nx - 1 and 0.0 <= fy <= ny - 1 and 0.0 <= fz <= nz - 1):
        return FAR_OUTSIDE, 0.0, 0.0, 0.0
    i = min(int(fx), nx - 2)
    j = min(int(fy), ny - 2)
    k = min(int(fz), nz - 2)
    a, b, c = fx - i, fy - j, fz - k
    g000, g100 = grid[i, j, k], grid[i + 1, j, k]
    g010, g110 = grid[i, j + 1, k], grid[i + 1, j + 1, k]
    g001, g101 = grid[i, j, k + 1], grid[i + 1, j, k + 1]
    g011, g111 = grid[i, j + 1, k + 1], grid[i + 1, j + 1, k + 1]
    c00 = g000 + (g100 - g000) * a
    c10 = g010 + (g110 - g010) * a
    c01 = g001 + (g101 - g001) * a
    c11 = g011 + (g111 - g011) * a
    c0 = c00 + (c10 - c00) * b
    c1 = c01 + (c11 - c01) * b
    d = c0 + (c1 - c0) * c
    dx0 = (g100 - g000) + ((g110 - g010) - (g100 - g000)) * b
    dx1 = (g101 - g001) + ((g111 - g011) - (g101 - g001)) * b
    gx = (dx0 + (dx1 - dx0) * c) / cell
    gy = ((c10 - c00) + ((c11 - c01) - (c10 - c00)) * c) / cell
    gz = (c1 - c0) / cell
    return d, gx, gy, gz


@inner(_nrt=False)
def _normal(grid, origin, cell, x, y, z):
    """The unit gradient of the grid's distance at a point (the outward normal of the nearest surface)."""
    _, gx, gy, gz = _sample_gradient(grid, origin, cell, x, y, z)
    n = math.sqrt(gx * gx + gy * gy + gz * gz)
    if not (0.0 < n < 1e6):  # flat or off the grid
        return 0.0, 0.0, 0.0
    return gx / n, gy / n, gz / n


@inner()
def _aim(hx, hy, hz, lx, ly, lz, ux, uy, uz, nx, ny, nz):
    """Turn the frame by the smallest rotation that takes H to the unit vector N."""
    cx = hy * nz - hz * ny
    cy = hz * nx - hx * nz
    cz = hx * ny - hy * nx
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    c = hx * nx + hy * ny + hz * nz
    if s <= 1e-12:
        if c > 0.0:
            return hx, hy, hz, lx, ly, lz, ux, uy, uz
        return _rotate(hx, hy, hz, lx, ly, lz, ux, uy, uz, np.int64(_AXIS_U), -1.0, 0.0)
    nlx, nly, nlz = rodrigues(cx / s, cy / s, cz / s, c, s, lx, ly, lz)
    return _orthonormal(nx, ny, nz, nlx, nly, nlz)


@inner(_nrt=False)
def _blocked(scene, x, y, z):
    """How far inside a solid the point is (> 0: inside an obstacle or a solid support, or outside the volume)."""
    o, cell, prm = scene.origin, scene.cell[0], scene.params
    worst = -FAR_OUTSIDE
    clearance = prm[SCENE_CLEARANCE]
    if scene.obstacle.shape[0] > 0:
        worst = max(worst, clearance - _sample(scene.obstacle, o, cell, x, y, z))
    if scene.support.shape[0] > 0 and prm[SCENE_SOLID_SUPPORT] > 0.0:
        worst = max(worst, clearance - _sample(scene.support, o, cell, x, y, z))
    if scene.volume.shape[0] > 0:
        worst = max(worst, _sample(scene.volume, o, cell, x, y, z))
    return worst


@inner(_nrt=False)
def _worst_along(scene, px, py, pz, hx, hy, hz, length):
    """The deepest :func:`_blocked` along a segment, sampled every half cell and at its end, and that point."""
    n = min(64, 1 + int(2.0 * length / scene.cell[0]))
    worst = -FAR_OUTSIDE
    wx, wy, wz = px + hx * length, py + hy * length, pz + hz * length
    for k in range(n, 0, -1):
        t = length * k / n
        x, y, z = px + hx * t, py + hy * t, pz + hz * t
        b = _blocked(scene, x, y, z)
        if b > worst:
            worst, wx, wy, wz = b, x, y, z
    return worst, wx, wy, wz


@inner()
def _release(hx, hy, hz, lx, ly, lz, ux, uy, uz, nx, ny, nz):
    """A climber lets go where its support faces up (``release``: over a top edge, on a ledge): H leans
    halfway out along the support's normal N, so the branch goes out over the edge before it hangs."""
    return _bend(hx, hy, hz, lx, ly, lz, ux, uy, uz, nx, ny, nz, 0.5, np.bool_(True))


@inner(_nrt=False)
def _steer(scene, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length, hanging):
    """The environment's say on one segment from P of this length: the new frame, whether it is cut, and
    whether the branch now hangs.

    Light bends H toward it (phototropism); near a support H is pulled onto the surface (adhesion), up its
    slope (climb) and toward the middle of the band it may use; a branch that was on the support and leaves
    its reach (over an edge), or with ``release`` reaches a part of it that faces up (:func:`_release`), hangs
    (``hanging`` 2; 0: never on a support, 1: on it): from there on it and the branches it bears bend down
    and no longer adhere.  Then a segment whose end would enter a solid slides along its surface (deflect) or
    is cut, and one that ends outside the pruning volume, or farther than the set distance from the support,
    is cut."""
    o, cell, prm = scene.origin, scene.cell[0], scene.params
    photo = prm[SCENE_PHOTOTROPISM]
    if photo > 0.0:
        vx, vy, vz = prm[SCENE_LIGHT], prm[SCENE_LIGHT + 1], prm[SCENE_LIGHT + 2]
        if prm[SCENE_LIGHT_POINT] > 0.0:
            vx, vy, vz = vx - px, vy - py, vz - pz
        n = math.sqrt(vx * vx + vy * vy + vz * vz)
        if n > 1e-12:
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                hx, hy, hz, lx, ly, lz, ux, uy, uz, vx / n, vy / n, vz / n, photo, np.bool_(True)
            )
    distance = prm[SCENE_DISTANCE]
    if scene.support.shape[0] > 0:
        d, nx, ny, nz = _sample_gradient(scene.support, o, cell, px, py, pz)
        if d <= prm[SCENE_REACH] and hanging == 0:
            hanging = np.int64(1)
        elif d > prm[SCENE_REACH] and hanging == 1:
            hanging = np.int64(2)
        n = math.sqrt(nx * nx + ny * ny + nz * nz)
        if hanging == 1 and prm[SCENE_RELEASE] > 0.0 and 0.0 < n < 1e6 and ny > prm[SCENE_RELEASE] * n:
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _release(hx, hy, hz, lx, ly, lz, ux, uy, uz, nx / n, ny / n, nz / n)
            hanging = np.int64(2)
        if hanging == 1 and 0.0 < n < 1e6:
            nx, ny, nz = nx / n, ny / n, nz / n
            hn = hx * nx + hy * ny + hz * nz
            tx, ty, tz = hx - hn * nx, hy - hn * ny, hz - hn * nz
            climb = prm[SCENE_CLIMB]  # world up along the surface
            tx -= climb * ny * nx
            ty += climb * (1.0 - ny * ny)
            tz -= climb * ny * nz
            target = 0.5 * prm[SCENE_REACH]
            if distance > 0.0:
                target = min(target, 0.5 * distance)
            pull = max(-1.0, min(1.0, (d - target) / max(length, 1e-9)))
            tx -= pull * nx
            ty -= pull * ny
            tz -= pull * nz
            t = math.sqrt(tx * tx + ty * ty + tz * tz)
            if t > 1e-12:
                a = prm[SCENE_ADHESION]
                vx = (1.0 - a) * hx + a * tx / t
                vy = (1.0 - a) * hy + a * ty / t
                vz = (1.0 - a) * hz + a * tz / t
                v = math.sqrt(vx * vx + vy * vy + vz * vz)
                if v > 1e-12:
                    hx, hy, hz, lx, ly, lz, ux, uy, uz = _aim(
                        hx, hy, hz, lx, ly, lz, ux, uy, uz, vx / v, vy / v, vz / v
                    )
        if hanging == 2 and prm[SCENE_HANG] > 0.0:
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                hx, hy, hz, lx, ly, lz, ux, uy, uz, 0.0, -1.0, 0.0, prm[SCENE_HANG], np.bool_(True)
            )
    inside, qx, qy, qz = _worst_along(scene, px, py, pz, hx, hy, hz, length)
    if inside > 0.0 and prm[SCENE_DEFLECT] > 0.0:
        # slide: take away the part of H across the surface where the segment went in
        for grid_id in range(3):
            grid = scene.obstacle if grid_id == 0 else (scene.support if grid_id == 1 else scene.volume)
            if grid.shape[0] == 0:
                continue
            sign = -1.0 if grid_id == 2 else 1.0  # the volume's inside is where its distance is negative
            nx, ny, nz = _normal(grid, o, cell, qx, qy, qz)
            nx, ny, nz = sign * nx, sign * ny, sign * nz
            hn = hx * nx + hy * ny + hz * nz
            if hn < 0.0:
                vx, vy, vz = hx - hn * nx, hy - hn * ny, hz - hn * nz
                v = math.sqrt(vx * vx + vy * vy + vz * vz)
                if v > 1e-6:
                    hx, hy, hz, lx, ly, lz, ux, uy, uz = _aim(
                        hx, hy, hz, lx, ly, lz, ux, uy, uz, vx / v, vy / v, vz / v
                    )
                    inside, qx, qy, qz = _worst_along(scene, px, py, pz, hx, hy, hz, length)
                    if inside <= 0.0:
                        break
    cut = inside > 0.0
    if not cut and distance > 0.0 and scene.support.shape[0] > 0:
        cut = _sample(scene.support, o, cell, px + hx * length, py + hy * length, pz + hz * length) > distance
    return hx, hy, hz, lx, ly, lz, ux, uy, uz, cut, hanging


@kernel(nogil=True)
def probe(scene, points, out):
    """Per point: 1 where it is blocked (:func:`_blocked`) else 0, and its distance to the nearest support or
    obstacle surface (:data:`FAR_OUTSIDE` with neither)."""
    o, cell = scene.origin, scene.cell[0]
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        out[k, 0] = 1.0 if _blocked(scene, x, y, z) > 0.0 else 0.0
        d = FAR_OUTSIDE
        if scene.obstacle.shape[0] > 0:
            d = min(d, abs(_sample(scene.obstacle, o, cell, x, y, z)))
        if scene.support.shape[0] > 0:
            d = min(d, abs(_sample(scene.support, o, cell, x, y, z)))
        out[k, 1] = d
