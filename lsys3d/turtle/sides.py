"""The sides a grammar sets for what the turtle draws next (cpfg's ``@!``), read after the kernel's pass.

cpfg keeps the number of sides of its cylinders, generalized cylinders, spheres and discs in the turtle
(blackbox.c: ``turtle->cylinder_sides = parm1 ? (int)parameter1 : 8``, at least 3), so a ``[`` saves it
and its ``]`` restores it.  Nothing the turtle draws depends on it but the tessellation, so it is not the
kernel's business: this pass walks the string's brackets once and gives each segment and organ the sides
in force at the module that drew it (``Skeleton.sides``, ``Skeleton.organ_sides``; 0 where no ``@!``
stood before it: the sweep's and the organs' own options).  The turtle starts with
``TurtleOptions.cylinder_sides`` (cpfg's view file: ``contour sides:``, ``polygonization level:``).  A
grammar with neither keeps both None, and draws what it drew before.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..compiling import kernel
from .kernel import _POP, _PUSH, _SIDES  # numba sees the ops as these plain integers, declared once in kernel.py
from .skeleton import Skeleton

__all__ = ["DEFAULT_SIDES", "MAX_SIDES", "MIN_SIDES", "sides_in_force", "with_sides"]

DEFAULT_SIDES = 8
"""The sides of a ``@!`` without a parameter (cpfg's blackbox.c)."""
MIN_SIDES = 3
"""Fewest sides: cpfg raises a smaller ``@!(n)`` to 3."""
MAX_SIDES = 1024
"""Most sides (the sweep's own limit, ``SweepOptions.sides``); a larger ``@!(n)`` is held to it."""


@kernel(nogil=True)
def _in_force(op, symbols, arity, offsets, params, max_depth, initial):  # pragma: no cover - compiled
    m = symbols.shape[0]
    out = np.zeros(m, np.int32)
    stack = np.zeros(max_depth + 1, np.int32)
    depth = 0
    sides = initial
    for i in range(m):
        code = op[symbols[i]]
        if code == _SIDES:
            if arity[i] > 0:
                n = params[offsets[i]]
                sides = MAX_SIDES if n >= MAX_SIDES else (MIN_SIDES if n < MIN_SIDES else int(n))
            else:
                sides = DEFAULT_SIDES
        elif code == _PUSH:
            if depth <= max_depth:
                stack[depth] = sides
            depth += 1
        elif code == _POP and depth > 0:
            depth -= 1
            if depth <= max_depth:
                sides = stack[depth]
        out[i] = sides
    return out


def sides_in_force(op: np.ndarray, symbols, arity, offsets, params, max_depth: int, initial: int = 0) -> np.ndarray:
    """``(m,) int32``: the sides in force at each module (0: none set), the kernel's program ``op`` per symbol.

    ``initial`` is the turtle's at the start (``TurtleOptions.cylinder_sides``: cpfg's view file).

    >>> from lsys3d.turtle.commands import Op
    >>> op = np.zeros(4, np.int64); op[1], op[2], op[3] = Op.SIDES, Op.PUSH, Op.POP
    >>> symbols = np.array([1, 2, 1, 0, 3, 0]); arity = np.array([1, 0, 0, 0, 0, 0])
    >>> sides_in_force(op, symbols, arity, np.zeros(6, np.int64), np.array([5.0]), 1).tolist()
    [5, 5, 8, 8, 5, 5]
    """
    return _in_force(
        np.asarray(op, np.int64),
        np.asarray(symbols),
        np.asarray(arity),
        np.asarray(offsets, np.int64),
        np.asarray(params, np.float64),
        int(max_depth),
        np.int32(initial),
    )


def with_sides(skeleton: Skeleton, in_force: np.ndarray) -> Skeleton:
    """``skeleton`` with the sides of each segment and organ: ``in_force`` (:func:`sides_in_force`) at its module."""
    return replace(skeleton, sides=in_force[skeleton.module], organ_sides=in_force[skeleton.organ_module])
