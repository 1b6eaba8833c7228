"""Frames along a chain: parallel transport by double reflection (Wang et al. 2008), the frame of a span,
the seam's side and the mean of inverse radii the texture's v runs by."""

from __future__ import annotations

import numpy as np

from ...arrays import dot, unit
from ...compiling import inner
from ...turtle.skeleton import Skeleton


@inner(nogil=True)
def _span_frame(center, tangent, axis, r0, r1):  # pragma: no cover - compiled
    """The chart's frame of the span from ring ``r0`` to ``r1``: ring ``r0``'s axis carried onto the span's
    direction by the minimal rotation (two reflections), and the direction's cross product with it."""
    dx, dy, dz = center[r1, 0] - center[r0, 0], center[r1, 1] - center[r0, 1], center[r1, 2] - center[r0, 2]
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length > 0:
        dx, dy, dz = dx / length, dy / length, dz / length
    else:
        dx, dy, dz = tangent[r0, 0], tangent[r0, 1], tangent[r0, 2]
    ux, uy, uz = axis[r0, 0], axis[r0, 1], axis[r0, 2]
    nx, ny, nz = tangent[r0, 0] + dx, tangent[r0, 1] + dy, tangent[r0, 2] + dz
    f = 2.0 * (ux * nx + uy * ny + uz * nz) / max(nx * nx + ny * ny + nz * nz, 1e-30)
    ux, uy, uz = ux - f * nx, uy - f * ny, uz - f * nz
    f = 2.0 * (ux * dx + uy * dy + uz * dz)
    ux, uy, uz = ux - f * dx, uy - f * dy, uz - f * dz
    f = ux * dx + uy * dy + uz * dz
    ux, uy, uz = ux - f * dx, uy - f * dy, uz - f * dz
    f = np.sqrt(ux * ux + uy * uy + uz * uz)
    if f > 0:
        ux, uy, uz = ux / f, uy / f, uz / f
    return ux, uy, uz, dy * uz - dz * uy, dz * ux - dx * uz, dx * uy - dy * ux


def _reflect_transport(u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Carry ``u`` (perpendicular to unit ``a``) to unit ``b`` by the minimal rotation.

    The rotation is the product of two reflections: in the plane normal to
    ``a + b`` (which maps ``a`` to ``-b``) and in the plane normal to ``b``.
    """
    n = a + b
    u = u - (2.0 * dot(u, n) / np.maximum(dot(n, n), 1e-30))[:, None] * n
    u = u - (2.0 * dot(u, b))[:, None] * b
    # remove drift so the frame stays orthonormal over long chains
    return unit(u - dot(u, b)[:, None] * b)


def _perpendicular(d: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """``hint`` made perpendicular to unit ``d`` and unit (any perpendicular if parallel)."""
    u = hint - dot(hint, d)[:, None] * d
    bad = np.linalg.norm(u, axis=1) < 1e-6
    if bad.any():
        axis = np.where(np.abs(d[bad, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        u[bad] = np.cross(d[bad], axis)
    return unit(u)


def _transport(u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`_reflect_transport`, and ``u`` itself where ``b`` turns right back along ``a`` (a split chain)."""
    back = dot(a, b) < -1.0 + 1e-9
    if not back.any():
        return _reflect_transport(u, a, b)
    out = np.empty_like(u)
    out[~back] = _reflect_transport(u[~back], a[~back], b[~back])
    out[back] = _perpendicular(b[back], u[back])
    return out


def _seam_side(skeleton: Skeleton, seg: np.ndarray) -> np.ndarray:
    """Where the seam (``u = 0``) of the chains whose first kept segments are ``seg`` starts: the turtle's down.

    The seam of a texture rarely matches perfectly; it goes where it is least
    seen.  It is placed by the plant's own frame, not the world's, so that
    congruent parts of a plant (the same junction drawn again, turned) get
    congruent texture coordinates, and :mod:`lsys3d.mesh.union.repeats` unions them
    once.  The seam faces the turtle's down (``-U``) at the base of each
    chain; the twist-free frame carries it along the chain.  For the default
    turtle (heading +Y, up +Z) that is -Z at the trunk: the back of a glTF
    asset, whose front is +Z.  Turns (``+``, ``-``) keep ``U``, so a plant drawn
    in a plane has every seam at its back; a branch pitched down (``&``) from
    an upright stem has ``U`` tilted to the sky and its seam underneath, one
    pitched up (``^``) has it on top.
    """
    return -skeleton.up[seg]


def _inverse_mean(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """The mean of ``1 / r`` over a linear taper from ``r0`` to ``r1``: ``log(r1 / r0) / (r1 - r0)``."""
    x = (r1 - r0) / r0
    small = np.abs(x) < 1e-6
    return np.where(small, 1.0 - 0.5 * x, np.log1p(np.where(small, 0.0, x)) / np.where(small, 1.0, x)) / r0
