"""The environment's steering of each segment, remembered by the turtle that answers derivation for the one that draws.

With an environment, every segment is steered by the scene (:func:`lsys3d.turtle.scene._steer`: adhesion,
climbing, deflection, cuts) twice: by the lean pass that answers derivation between its steps
(:mod:`lsys3d.turtle.incremental`) and again by the turtle that draws the last string
(:func:`lsys3d.turtle.kernel.run`).  The lean pass writes each steering it makes as a row of
:data:`ROW` numbers (what went in, what came out); :class:`SteeringMemo` gathers them over the derivation,
and the drawing turtle looks each segment up (:func:`recall`) before it steers: a row whose inputs equal
the turtle's, bit for bit (a ``-0.0`` is not a ``0.0``), gives the answer ``_steer`` would give, since it
reads nothing else (the scene is the same: :meth:`SteeringMemo.recalled` checks).  A segment not found
is steered as before, so the drawing is the same, byte for byte, whatever the memo holds.

The kernel reads the memo as its ``rare`` argument (:func:`lsys3d.turtle.kernel.run`): the steering is
compiled only for strings that need the rare code, so the plain turtle's compilation (``rare`` None) is
not touched, and a :data:`Steered` of empty arrays stands for no memo (one type: the rare code compiles once).

Usage (what :func:`lsys3d.pipeline.draw` does)::

    memo = SteeringMemo()
    modules = derive_answering(grammar, environment=env, steering=memo)
    skeleton = interpret(modules, grammar, scene=env.scene(), steering=memo)
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ..compiling import inner

__all__ = ["MAX_ROWS", "ROW", "Steered", "SteeringMemo", "not_steered", "recall", "recalled_steering", "write_steering"]

IN = 14
"""Numbers that go into a steering: position, H, L, U, the segment's length, whether the branch hangs."""
ROW = IN + 11
"""Numbers in a row: :data:`IN`, then H, L, U after steering, cut (1.0/0.0) and hanging after it."""
AHEAD = 8
"""How many segments ahead :func:`recall` asks the CPU to fetch a row (the rows are met out of their order:
each fetched while the turtle draws the segments before it)."""
MAX_ROWS = 1_000_000
"""The most rows a memo keeps (200 MB); past that it forgets them and the drawing turtle steers again."""

Steered = namedtuple("Steered", ["position", "row", "rows"])
"""The kernel's view of a memo: the modules whose steering it holds (``position (n,) int64``, increasing)
and the row of each (``row (n,) int64``) in the memo's rows (``rows (k, ROW) float64``, not copied)."""


def not_steered() -> Steered:
    """An empty memo: every segment is steered."""
    return Steered(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, ROW)))


@inner(inline="always")
def _same(a, b):
    """Equal, and the same zero."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


@intrinsic
def _prefetch(typingctx, rows, r, c):
    """Ask the CPU to bring ``rows[r, c]`` (a 2D array's) into its caches: LLVM's ``llvm.prefetch`` (read,
    high locality), a hint that changes no result."""
    if not (isinstance(rows, types.Array) and rows.ndim == 2 and isinstance(r, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        row = context.cast(builder, args[1], signature.args[1], types.intp)
        column = context.cast(builder, args[2], signature.args[2], types.intp)
        at = cgutils.get_item_pointer(context, builder, array_type, array, [row, column], wraparound=False)
        byte = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        hint = ir.FunctionType(ir.VoidType(), [byte, i32, i32, i32])
        prefetch = cgutils.get_or_insert_function(builder.module, hint, "llvm.prefetch.p0")
        read, near, data = ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)
        builder.call(prefetch, [builder.bitcast(at, byte), read, near, data])
        return context.get_dummy_value()

    return types.void(rows, r, c), codegen


@inner(inline="always")
def recall(position, at_row, rows, k, i, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length, hanging):
    """The row of ``rows`` that holds module ``i``'s steering (:data:`Steered`'s arrays) if its inputs are
    exactly these, else -1; and the cursor ``k`` moved up to ``i`` (the turtle asks in the string's order)."""
    n = position.shape[0]
    while k < n and position[k] < i:
        k += 1
    if k + AHEAD < n:  # the row of a segment further on, fetched while this one and those before it are drawn
        _prefetch(rows, at_row[k + AHEAD], 0)
    if k == n or position[k] != i:
        return -1, k
    r = at_row[k]
    inputs = (px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length)  # columns 0-12 of a row, bit for bit
    for c in range(len(inputs)):
        if not _same(rows[r, c], inputs[c]):
            return -1, k
    if rows[r, 13] != float(hanging):
        return -1, k
    return r, k


@inner(inline="always")
def recalled_steering(rows, r):
    """What row ``r`` says ``_steer`` returned: H, L, U, cut, hanging."""
    hx, hy, hz, lx, ly, lz = rows[r, 14], rows[r, 15], rows[r, 16], rows[r, 17], rows[r, 18], rows[r, 19]
    return hx, hy, hz, lx, ly, lz, rows[r, 20], rows[r, 21], rows[r, 22], rows[r, 23] > 0.0, np.int64(rows[r, 24])


@inner(_nrt=False)
def write_steering(
    rows, n, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length, hanging, shx, shy, shz, slx, sly, slz, sux, suy,
    suz, cut, steered_hanging,
):  # fmt: skip
    """Write row ``n``: the inputs, then H, L, U, cut and hanging as ``_steer`` returned them."""
    row = rows[n]
    row[0], row[1], row[2] = px, py, pz
    row[3], row[4], row[5] = hx, hy, hz
    row[6], row[7], row[8] = lx, ly, lz
    row[9], row[10], row[11] = ux, uy, uz
    row[12], row[13] = length, hanging
    row[14], row[15], row[16] = shx, shy, shz
    row[17], row[18], row[19] = slx, sly, slz
    row[20], row[21], row[22] = sux, suy, suz
    row[23], row[24] = 1.0 if cut else 0.0, steered_hanging


class SteeringMemo:
    """The steerings of one derivation's lean passes, for the turtle that draws its string (module docstring).

    :class:`lsys3d.turtle.query.Answerer` fills it: :meth:`reset` before a pass over the whole string; before
    each pass, :meth:`room` for the rows it may write (numbered from :attr:`count`); after it, :meth:`add` with
    the rows written and, for every segment of the string, the row that holds its steering.
    :func:`lsys3d.turtle.interpret.interpret` reads it (:meth:`recalled`).
    """

    def __init__(self):
        self.reset(None)

    def reset(self, scene) -> None:
        """Forget every row: a pass over the whole string follows, in this ``scene``."""
        self.scene = scene
        self.rows = np.zeros((0, ROW))  # rows[:count] written, the rest room for the next pass
        self.count = 0
        self.full = False  # past MAX_ROWS, or a pass that lost track of its modules: off until the next reset
        self.steered_at = np.zeros(0, np.int64)  # the last pass's segments (modules of the string it read)
        self.steered_row = np.zeros(0, np.int64)  # and their rows
        self._kept: np.ndarray | None = None  # the string it returned: its modules' indices in the one it read
        self._steered: Steered | None = None
        self._buffers = [np.zeros((2, 0), np.int64), np.zeros((2, 0), np.int64)]  # the last pass's and the next's

    def segments(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Room for the next pass's ``n`` segments: their modules and rows (not the last pass's arrays)."""
        spare = self._buffers[1]
        if spare.shape[1] < n:
            spare = self._buffers[1] = np.empty((2, max(n, 2 * spare.shape[1])), np.int64)
        return spare[0], spare[1]

    def room(self, n: int) -> np.ndarray | None:
        """:attr:`rows`, with room for ``n`` more, or None when the memo is off.  Grown sixteenfold, so its rows
        are seldom copied (the room no pass writes in is pages never touched)."""
        if self.full or self.count + n > MAX_ROWS:
            self._off()
            return None
        if len(self.rows) < self.count + n:
            grown = np.empty((min(max(16 * len(self.rows), 2 * (self.count + n), 1024), MAX_ROWS), ROW))
            grown[: self.count] = self.rows[: self.count]
            self.rows = grown
        return self.rows

    def _off(self) -> None:
        self.full, self.rows, self.count = True, np.zeros((0, ROW)), 0
        self.steered_at, self.steered_row = np.zeros(0, np.int64), np.zeros(0, np.int64)

    def add(self, written: int, steered_at: np.ndarray, steered_row: np.ndarray, kept) -> None:
        """Keep the ``written`` rows of a pass and its segments' rows (``steered_at``, ``steered_row``).
        ``kept``: the modules of the string the pass returned, as indices in the one it read (empty: the same
        string; None: unknown, so nothing can be recalled)."""
        self._steered = None
        if self.full or kept is None:
            self._off()
            return
        self.count += written
        self.steered_at, self.steered_row, self._kept = steered_at, steered_row, kept
        self._buffers.reverse()  # the arrays just given are the last pass's now

    def recalled(self, scene) -> Steered:
        """The kernel's view for the last string returned, when its rows were steered in this ``scene`` (the
        same object), else :func:`not_steered`."""
        if self.scene is not scene or self.full or not self.count:
            return not_steered()
        if self._steered is None:
            at, row = self.steered_at, self.steered_row
            if self._kept is not None and len(self._kept):  # the pass removed modules: number them anew
                copied = np.flatnonzero(self._kept >= 0)  # (a bud left where a segment was cut is new)
                kept = self._kept[copied]
                place = np.minimum(np.searchsorted(kept, at), max(len(kept) - 1, 0))
                found = kept[place] == at if len(kept) else np.zeros(len(at), np.bool_)
                at, row = copied[place[found]], row[found]
            self._steered = Steered(at, row, self.rows)
        return self._steered
