"""The turtle's frame arithmetic: turns, re-orthonormalising, and the tropisms that bend the frame.

Compiled helpers of :mod:`lsys3d.turtle.kernel` (which imports them from here): the turns about the
frame's own axes, ABOP's and PlantGL's tropism (:func:`_bend`), cpfg's view-file tropism after each move
(:func:`_bend_after`), and cpfg's newer tropisms, its "movements" (cpfg's movements.c: the view file's
``tropism:`` and ``torque:`` lines, each switched by ``@Ts``, ``@Ti``, ``@Td``), with the frame they keep
(``@Tf`` keeps the turtle's; ``@Tp`` carries U from it: :func:`carry_up`).

cpfg's movements, as lsys3d reads them (``TurtleOptions.tropisms``, one row each, in the view file's order:
``@Ts(1, e)`` is the first):

- a tropism ``T`` (``tropism: T: x y z``, its length scaled by ``I:``, at most 1), with an angle ``A:``
  (gamma, degrees; 0 orthotropism, 90 plagiotropism), an initial elasticity ``E:`` and an increment ``S:``;
- a twist (``torque: T: x y z``...), which rolls U (heading kept) toward ``T`` made square to H.

Before each ``F``, ``f``, ``G``, ``g`` (interpret.c), the heading turns about ``H x V`` by ``|H x V|``
radians (at most 1) toward ``V``, the sum over the tropisms of ``cos(gamma) e T`` and, where gamma is
not 0, ``sin(gamma) e T x (H x T) / |H x T|``; U is then the U of the last ``F`` (or of ``@Tf``) carried
along by the smallest rotation from that heading to the new one (turtle.c ``adjust_up_and_left``: a roll
made since is undone, unless ``@Tf`` keeps it).  Then the twists' sum ``W`` rolls U toward ``W`` made
square to H, by ``|U x W'|`` radians (at most 1), and the frame becomes the one ``@Tf`` keeps.

lsys3d's frame is cpfg's with U the other way (cpfg's U is lsys3d's -U, L the same): every step above is
a rotation, the same for U and -U, except the twist's, which turns cpfg's U away from ``W`` (movements.c
``rotate_to_vector``, by its quaternions' order), that is lsys3d's U toward it.
"""

from __future__ import annotations

import math

import numpy as np

from ..compiling import inner, kernel
from .commands import Axis

__all__ = ["MOVEMENT_COLUMNS", "TWIST", "carry_up", "movement_adjust", "movement_elasticity"]

# the turtle's axes as numba sees them (plain integers), declared once here for the turtle's kernels
_AXIS_H = int(Axis.H)
_AXIS_L = int(Axis.L)
_AXIS_U = int(Axis.U)

TWIST = 1.0
"""A movement row's kind: 0 a tropism (``tropism:``), 1 a twist (``torque:``)."""
MOVEMENT_COLUMNS = 8
"""A movement row: kind, T (x, y, z, its length the intensity), cos(gamma), sin(gamma), elasticity, increment."""


@kernel()
def _pair(ax, ay, az, bx, by, bz, c, s):
    """Rotate a frame pair in its plane: a toward b by the angle with cos c, sin s."""
    return ax * c + bx * s, ay * c + by * s, az * c + bz * s, bx * c - ax * s, by * c - ay * s, bz * c - az * s


@inner()
def _orthonormal(hx, hy, hz, lx, ly, lz):
    """Re-orthonormalise a nearly orthonormal H, L and return H, L, U = H x L.

    Keeps rounding from piling up over millions of turns.  The inputs are unit
    vectors to within rounding, so one Newton step ``v * (3 - v.v) / 2`` normalises
    them to full precision without a square root or a division.
    """
    n = 1.5 - 0.5 * (hx * hx + hy * hy + hz * hz)
    hx *= n
    hy *= n
    hz *= n
    d = lx * hx + ly * hy + lz * hz
    lx -= d * hx
    ly -= d * hy
    lz -= d * hz
    n = 1.5 - 0.5 * (lx * lx + ly * ly + lz * lz)
    lx *= n
    ly *= n
    lz *= n
    return hx, hy, hz, lx, ly, lz, hy * lz - hz * ly, hz * lx - hx * lz, hx * ly - hy * lx


@inner()
def _cos_sin(degrees):
    """Cosine and sine of an angle in degrees, exact for multiples of 90 (so +(90) and heading 90 are exact)."""
    r = degrees % 360.0
    if r == 0.0:
        return 1.0, 0.0
    if r == 90.0:
        return 0.0, 1.0
    if r == 180.0:
        return -1.0, 0.0
    if r == 270.0:
        return 0.0, -1.0
    a = math.radians(degrees)
    return math.cos(a), math.sin(a)


@inner(inline="always")
def rodrigues(kx, ky, kz, c, s, vx, vy, vz):
    """The vector v turned about the unit axis k by the angle with cos c, sin s (Rodrigues:
    v' = v c + (k x v) s + k (k.v)(1 - c))."""
    d = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
    return (
        vx * c + (ky * vz - kz * vy) * s + kx * d,
        vy * c + (kz * vx - kx * vz) * s + ky * d,
        vz * c + (kx * vy - ky * vx) * s + kz * d,
    )


@inner()
def _bend(hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, e, by_angle):
    """Bend H toward T about H x T: by e |H x T| radians (ABOP 2.8), or (``by_angle``) by e times the angle
    between H and T (PlantGL's Turtle::_tendTo, which turns about U by e pi when H is opposite T).
    Unchanged when H is along T."""
    cx = hy * tz - hz * ty
    cy = hz * tx - hx * tz
    cz = hx * ty - hy * tx
    norm = math.sqrt(cx * cx + cy * cy + cz * cz)
    if norm <= 1e-12:
        if by_angle and hx * tx + hy * ty + hz * tz < 0.0:
            c, s = math.cos(e * math.pi), math.sin(e * math.pi)
            return _rotate(hx, hy, hz, lx, ly, lz, ux, uy, uz, np.int64(_AXIS_U), c, s)
        return hx, hy, hz, lx, ly, lz, ux, uy, uz
    a = e * (math.atan2(norm, hx * tx + hy * ty + hz * tz) if by_angle else norm)
    kx, ky, kz = cx / norm, cy / norm, cz / norm
    c, s = math.cos(a), math.sin(a)
    nhx, nhy, nhz = rodrigues(kx, ky, kz, c, s, hx, hy, hz)
    nlx, nly, nlz = rodrigues(kx, ky, kz, c, s, lx, ly, lz)
    return _orthonormal(nhx, nhy, nhz, nlx, nly, nlz)


@inner(nogil=True)  # (nogil as its callers: numba compiles min and max once per set of callers' flags)
def _bend_after(hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, e):
    """cpfg's tropism after a move (interpret.c ``bend``): H turns toward U by the angle whose sine is
    e (T.U), then toward L by the angle whose sine is e (T.L) (sines held to [-1, 1])."""
    s = min(1.0, max(-1.0, e * (tx * ux + ty * uy + tz * uz)))
    c = math.sqrt(1.0 - s * s)
    nhx, nhy, nhz = c * hx + s * ux, c * hy + s * uy, c * hz + s * uz
    ux, uy, uz = c * ux - s * hx, c * uy - s * hy, c * uz - s * hz
    s = min(1.0, max(-1.0, e * (tx * lx + ty * ly + tz * lz)))
    c = math.sqrt(1.0 - s * s)
    hx, hy, hz = c * nhx + s * lx, c * nhy + s * ly, c * nhz + s * lz
    lx, ly, lz = c * lx - s * nhx, c * ly - s * nhy, c * lz - s * nhz
    return _orthonormal(hx, hy, hz, lx, ly, lz)


@kernel()
def _rotate(hx, hy, hz, lx, ly, lz, ux, uy, uz, axis, c, s):
    """Rotate the frame about one of its own axes by the angle with cos c and sin s (already signed)."""
    if axis == _AXIS_U:  # turn: H toward L
        hx, hy, hz, lx, ly, lz = _pair(hx, hy, hz, lx, ly, lz, c, s)
    elif axis == _AXIS_L:  # pitch: H toward U
        hx, hy, hz, ux, uy, uz = _pair(hx, hy, hz, ux, uy, uz, c, s)
        lx, ly, lz = uy * hz - uz * hy, uz * hx - ux * hz, ux * hy - uy * hx
    else:  # roll: L toward U
        lx, ly, lz, ux, uy, uz = _pair(lx, ly, lz, ux, uy, uz, c, s)
    return _orthonormal(hx, hy, hz, lx, ly, lz)


@kernel()
def _turn(vx, vy, vz, kx, ky, kz, a):
    """The vector v turned about the unit axis k by a radians (:func:`rodrigues`)."""
    return rodrigues(kx, ky, kz, math.cos(a), math.sin(a), vx, vy, vz)


@kernel()
def _square(hx, hy, hz, ux, uy, uz):
    """H, L, U with L = U x H: the frame of a heading and an up vector nearly square to it."""
    return _orthonormal(hx, hy, hz, uy * hz - uz * hy, uz * hx - ux * hz, ux * hy - uy * hx)


@kernel()
def carry_up(hx, hy, hz, ux, uy, uz, phx, phy, phz, pux, puy, puz):
    """H, L, U with U the kept up vector carried along the smallest rotation from the kept heading to H (turtle.c
    ``adjust_up_and_left``: cpfg's ``@Tp``, and its tropisms after they bend H); U as it is when H is the kept one."""
    rx, ry, rz = phy * hz - phz * hy, phz * hx - phx * hz, phx * hy - phy * hx
    m = math.sqrt(rx * rx + ry * ry + rz * rz)
    if m > 1e-6:
        a = math.asin(min(m, 1.0))
        if hx * phx + hy * phy + hz * phz < 0.0:
            a = math.pi - a
        ux, uy, uz = _turn(pux, puy, puz, rx / m, ry / m, rz / m, a)
    return _square(hx, hy, hz, ux, uy, uz)


@kernel()
def movement_adjust(mov, e, hx, hy, hz, lx, ly, lz, ux, uy, uz, phx, phy, phz, pux, puy, puz):
    """cpfg's movements before a move (movements.c ``movement_adjust``): the frame, and the frame ``@Tf`` keeps.

    ``mov`` holds the movements' rows (:data:`MOVEMENT_COLUMNS`), ``e`` their elasticities in this branch.
    Returns H, L, U and the kept heading and up vector (15 numbers).
    """
    vx = vy = vz = 0.0
    wx = wy = wz = 0.0
    for i in range(mov.shape[0]):
        tx, ty, tz = mov[i, 1], mov[i, 2], mov[i, 3]
        if mov[i, 0] == TWIST:
            wx, wy, wz = wx + e[i] * tx, wy + e[i] * ty, wz + e[i] * tz
            continue
        c = mov[i, 4] * e[i]
        vx, vy, vz = vx + c * tx, vy + c * ty, vz + c * tz
        if mov[i, 5] != 0.0:  # a tropism at an angle: toward the cone of directions gamma from T
            ax, ay, az = hy * tz - hz * ty, hz * tx - hx * tz, hx * ty - hy * tx
            n = math.sqrt(ax * ax + ay * ay + az * az)
            if n < 1e-7:  # H along T: about L
                ax, ay, az, n = lx, ly, lz, 1.0
            f = mov[i, 5] * e[i] / n
            vx += f * (ty * az - tz * ay)
            vy += f * (tz * ax - tx * az)
            vz += f * (tx * ay - ty * ax)
    rx, ry, rz = hy * vz - hz * vy, hz * vx - hx * vz, hx * vy - hy * vx
    n = math.sqrt(rx * rx + ry * ry + rz * rz)
    if n >= 1e-6:
        hx, hy, hz = _turn(hx, hy, hz, rx / n, ry / n, rz / n, min(n, 1.0))
        hx, hy, hz, lx, ly, lz, ux, uy, uz = carry_up(hx, hy, hz, ux, uy, uz, phx, phy, phz, pux, puy, puz)
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if w > 0.0:
        ax, ay, az = (hy * wz - hz * wy) / w, (hz * wx - hx * wz) / w, (hx * wy - hy * wx) / w
        if ax * ax + ay * ay + az * az > 1e-8:  # H not along W: W made square to H, times |W|
            dx, dy, dz = (ay * hz - az * hy) * w, (az * hx - ax * hz) * w, (ax * hy - ay * hx) * w
            rx, ry, rz = uy * dz - uz * dy, uz * dx - ux * dz, ux * dy - uy * dx
            n = math.sqrt(rx * rx + ry * ry + rz * rz)
            if n >= 1e-7:
                ux, uy, uz = _turn(ux, uy, uz, rx / n, ry / n, rz / n, min(n, 1.0))
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _square(hx, hy, hz, ux, uy, uz)
            phx, phy, phz, pux, puy, puz = hx, hy, hz, ux, uy, uz
    return hx, hy, hz, lx, ly, lz, ux, uy, uz, phx, phy, phz, pux, puy, puz


@kernel()
def movement_elasticity(mov, e, sign, n, has_value, value):
    """cpfg's ``@Ts(n, v)`` (``sign`` 0: set, to 0 without ``v``), ``@Ti(n, v)`` (+1) and ``@Td(n, v)`` (-1: add or
    take ``v``, or the movement's increment): blackbox.c, movement ``n`` counted from 1; cpfg leaves a number
    out of range alone (and says so)."""
    i = int(n - 1.0) if abs(n) < 1e9 else -1
    if i < 0 or i >= mov.shape[0]:
        return
    if sign == 0:
        e[i] = value if has_value else 0.0
    else:
        e[i] += sign * (value if has_value else mov[i, 7])
