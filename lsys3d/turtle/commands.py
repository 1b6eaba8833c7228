"""The turtle's vocabulary: one table row per command.

A row says everything about a symbol: what it is called, what the kernel does
with it (:class:`Op`, and for rotations the axis and the sign), the argument it
takes and its documentation.  The interpreter (:mod:`lsys3d.turtle.interpret`),
its error messages and ``docs/turtle.md`` (:func:`commands_markdown`) all read
:data:`COMMANDS`.

Adding a symbol is one row here; a symbol with a new kind of effect is one row
plus one branch of :func:`lsys3d.turtle.kernel.run` for its :class:`Op`.  A
rotation about one of the frame's axes needs no new branch: its row names the
axis and the sign.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

__all__ = ["COMMANDS", "Axis", "Command", "Op", "SymbolTable", "commands_markdown", "symbol_table"]


class Op(IntEnum):
    """What the kernel does with a module; 0 is "nothing" (symbols without a command)."""

    NONE = 0
    FORWARD = 1  # move drawing a segment
    MOVE = 2  # move without drawing
    ROTATE = 3  # rotate about Command.axis by Command.sign * angle
    TURN_AROUND = 4
    ROLL_HORIZONTAL = 5
    PUSH = 6
    POP = 7
    WIDTH = 8
    MATERIAL = 9
    LENGTH = 10
    POLYGON_BEGIN = 11
    POLYGON_VERTEX = 12
    POLYGON_END = 13
    LEAF = 14


N_OPS = len(Op)


class Axis(IntEnum):
    """The frame axis a rotation turns about; the other two turn in their plane."""

    NONE = 0
    U = 1  # turn: H toward L
    L = 2  # pitch: H toward U
    H = 3  # roll: L toward U


@dataclass(frozen=True)
class Command:
    """One turtle command: a row of :data:`COMMANDS`.

    Attributes
    ----------
    symbol : str
        The symbol (``F``, ``f`` and ``~`` are defaults that ``[turtle]``'s
        ``draw``, ``move`` and ``leaf`` can change).
    name : str
        Short name used in error messages and the docs.
    op : Op
        What the kernel does.
    args : str
        The optional argument, as written in a grammar (empty if none).
    max_args : int
        Most parameters the module may carry.
    description : str
        What the command does.
    axis : Axis
        For rotations: the axis turned about.
    sign : int
        For rotations: +1 turns the first axis of the pair toward the second
        (H toward L, H toward U, L toward U), -1 the other way.  For the
        material without an argument: the step of the index (+1 next, -1
        previous; the index never goes below 0).
    """

    symbol: str
    name: str
    op: Op
    args: str
    max_args: int
    description: str
    axis: Axis = Axis.NONE
    sign: int = 1


COMMANDS: tuple[Command, ...] = (
    Command("F", "forward", Op.FORWARD, "l", 1, "Move forward by the step length (or `l`) drawing a segment."),
    Command("f", "move", Op.MOVE, "l", 1, "Move forward by the step length (or `l`) without drawing."),
    Command(
        "+", "turn left", Op.ROTATE, "a", 1, "Rotate about U by +angle (or `a` degrees): H turns toward L.", Axis.U, +1
    ),
    Command("-", "turn right", Op.ROTATE, "a", 1, "Rotate about U by -angle: H turns toward -L.", Axis.U, -1),
    Command("&", "pitch down", Op.ROTATE, "a", 1, "Rotate about L by +angle: H turns toward -U.", Axis.L, -1),
    Command("^", "pitch up", Op.ROTATE, "a", 1, "Rotate about L by -angle: H turns toward U.", Axis.L, +1),
    Command("\\", "roll left", Op.ROTATE, "a", 1, "Rotate about H by -angle: L turns toward -U.", Axis.H, -1),
    Command("/", "roll right", Op.ROTATE, "a", 1, "Rotate about H by +angle: L turns toward U.", Axis.H, +1),
    Command("|", "turn around", Op.TURN_AROUND, "", 0, "Rotate about U by 180 degrees."),
    Command(
        "$",
        "roll to horizontal",
        Op.ROLL_HORIZONTAL,
        "",
        0,
        "Roll about H so that L is horizontal: L = (V x H) / |V x H|, U = H x L, V = (0, 1, 0). "
        "No effect when H is vertical.",
    ),
    Command("[", "push", Op.PUSH, "", 0, "Save the whole turtle state (start a branch)."),
    Command("]", "pop", Op.POP, "", 0, "Restore the state saved by the matching `[` (end a branch)."),
    Command(
        "!", "width", Op.WIDTH, "w", 1, "Set the branch diameter to `w`; without `w` multiply it by `width_scale`."
    ),
    Command("'", "material", Op.MATERIAL, "i", 1, "Set the material index to `i`; without `i` add 1 to it.", sign=+1),
    Command('"', "step length", Op.LENGTH, "s", 1, "Multiply the step length by `s` (default `length_scale`)."),
    Command("{", "begin polygon", Op.POLYGON_BEGIN, "", 0, "Start a leaf polygon; moves inside add vertices."),
    Command(".", "polygon vertex", Op.POLYGON_VERTEX, "", 0, "Add the current position to the open polygon."),
    Command("}", "end polygon", Op.POLYGON_END, "", 0, "Close the open polygon."),
    Command(
        "~", "leaf", Op.LEAF, "s", 1, "Place a leaf instance with the turtle's frame, size the step length (or `s`)."
    ),
)
"""The turtle's commands, in the order the documentation lists them."""

RENAMEABLE = {"draw": Op.FORWARD, "move": Op.MOVE, "leaf": Op.LEAF}
"""The ``[turtle]`` keys that choose the symbols of a command, and the command's op."""


def by_symbol(symbol: str) -> Command | None:
    """The command of a fixed symbol (not ``draw``/``move``/``leaf``, whose symbols are settings)."""
    return _FIXED.get(symbol)


_FIXED = {c.symbol: c for c in COMMANDS if c.op not in RENAMEABLE.values()}
_BY_OP = {c.op: c for c in COMMANDS if c.op in RENAMEABLE.values()}


@dataclass(frozen=True)
class SymbolTable:
    """The command table compiled for one alphabet: what each symbol id does, ``(256,)`` arrays."""

    op: np.ndarray  # int8: Op
    axis: np.ndarray  # int8: Axis of rotations
    sign: np.ndarray  # float64: +1 / -1 of rotations
    max_args: np.ndarray  # int64
    commands: tuple  # the Command of each symbol id (None for no command)

    def command(self, code: int) -> Command | None:
        return self.commands[code]


def symbol_table(
    alphabet: str, draw: str = "F", move: str = "f", leaf: str = "~", commands: tuple[Command, ...] = COMMANDS
) -> SymbolTable:
    """Compile a command table for the symbols of ``alphabet`` (``alphabet[code]`` is the symbol of id ``code``).

    ``draw``, ``move`` and ``leaf`` are the symbols the ``[turtle]`` table gives
    those commands; ``commands`` is the vocabulary (:data:`COMMANDS`, or a
    dialect's own table built from rows of the same kind).

    >>> from lsys3d.modules import ASCII_ALPHABET
    >>> p = symbol_table(ASCII_ALPHABET, draw="FG")
    >>> Op(p.op[ord("G")]).name, Axis(p.axis[ord("&")]).name, float(p.sign[ord("&")])
    ('FORWARD', 'L', -1.0)
    """
    n = 256
    op = np.zeros(n, np.int8)
    axis = np.zeros(n, np.int8)
    sign = np.ones(n, np.float64)
    max_args = np.zeros(n, np.int64)
    per_code: list[Command | None] = [None] * n
    code_of = {ch: i for i, ch in enumerate(alphabet) if ch != "\0"}
    renamed = {c.op: c for c in commands if c.op in RENAMEABLE.values()}
    rows = [(c.symbol, c) for c in commands if c.op not in RENAMEABLE.values()]
    for symbols, o in ((draw, Op.FORWARD), (move, Op.MOVE), (leaf, Op.LEAF)):
        rows += [(ch, renamed.get(o, _BY_OP[o])) for ch in symbols]
    for symbol, c in rows:
        code = code_of.get(symbol)
        if code is None:
            continue
        op[code] = c.op
        axis[code] = c.axis
        sign[code] = c.sign
        max_args[code] = c.max_args
        per_code[code] = c
    return SymbolTable(op, axis, sign, max_args, tuple(per_code))


def commands_markdown() -> str:
    """The command table as Markdown (the table in ``docs/turtle.md``)."""
    rows = ["| Symbol | Name | Argument | What it does |", "|---|---|---|---|"]
    for cmd in COMMANDS:
        symbol = cmd.symbol.replace("|", "\\|")
        arg = f"`{symbol}({cmd.args})`" if cmd.args else ""
        rows.append(f"| `{symbol}` | {cmd.name} | {arg} | {cmd.description.replace('|', chr(92) + '|')} |")
    return "\n".join(rows) + "\n"
