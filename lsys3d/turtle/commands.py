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

__all__ = [
    "BUILT_IN_ORGANS",
    "COMMANDS",
    "ENVIRONMENT_QUERY",
    "Axis",
    "Command",
    "Op",
    "Organ",
    "SymbolTable",
    "commands_markdown",
    "queries",
    "symbol_table",
]


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
    ORGAN = 15  # record an organ (sphere, disc, surface...) in the skeleton: Command.organ says which
    WIDTH_ADD = 16  # add Command.sign * width_increment to the width; with an argument, set it
    WIDTH_FACTOR = 17  # multiply the width by the argument (or Command.factor, or width_scale), ** sign
    ANGLE_FACTOR = 18  # multiply the rotation angle by the argument (or Command.factor, or angle_scale), ** sign
    RANDOM_TURN = 19  # turn, pitch and roll by random angles up to the argument (or Command.factor, or angle)
    TROPISM = 20  # bend the frame once toward the tropism vector by the argument (or Command.factor)
    ELASTICITY = 21  # set the elasticity of the moves that follow (0 without an argument)
    FORWARD_STEPS = 22  # move a length drawing a segment per step of a given length (L-Py's nF)
    TROPISM_VECTOR = 23  # set the tropism vector T of the moves that follow (L-Py's @Tp)
    QUERY = 24  # record the turtle's state here: a query module (?P, ?H...) or cpfg's ?E, filled between steps
    SUB_LSYSTEM = 25  # cpfg's ?(n, s) (sign +1) and $ (sign -1): push and pop the scale of lengths and widths
    ELASTICITY_ADD = 26  # add the elasticity increment to the elasticity (cpfg's _); with an argument, set it
    CYLINDER_START = 27  # start a generalized cylinder: its first control point (cpfg's @Gs)
    CYLINDER_POINT = 28  # a control point: the tube from the last one to here (@Gc; Command.sign -1 ends it: @Ge)
    CYLINDER_TANGENTS = 29  # the tangent factors of the control points that follow (cpfg's @Gt)
    SIDES = 30  # the sides of the tubes and the round organs that follow (cpfg's @!): read after the kernel's pass
    MOVEMENT_ELASTICITY = 31  # cpfg's @Ts (sign 0: set), @Ti (+1), @Td (-1): the elasticity of movement n
    MOVEMENT_FRAME = 32  # cpfg's @Tf: the frame the movements carry U from is the turtle's now


N_OPS = len(Op)


class Organ(IntEnum):
    """What an :data:`Op.ORGAN` command records (the organ's kind in the skeleton)."""

    NONE = 0
    SPHERE = 1  # cpfg's and L-Py's @O
    DISC = 2  # cpfg's @c: a filled disc in the plane of H and L
    CIRCLE = 3  # L-Py's @o
    SURFACE = 4  # a named surface: cpfg's and L-Py's ~l
    INSTANCE = 5  # Houdini's J, K, M: a copy of an input geometry
    BOX = 6  # L-Py's @B


BUILT_IN_ORGANS = {Organ.SPHERE: "sphere", Organ.DISC: "disc", Organ.CIRCLE: "circle", Organ.BOX: "box"}
"""The organ kinds with a built-in prototype, by name (a ``[surfaces]`` entry of the same name replaces one)."""


class Axis(IntEnum):
    """The frame axis a rotation turns about; the other two turn in their plane."""

    NONE = 0
    U = 1  # turn: H toward L
    L = 2  # pitch: H toward U
    H = 3  # roll: L toward U


@dataclass(frozen=True)
class Command:
    """One turtle command: a row of :data:`COMMANDS` (or of a dialect's table).

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
        Most parameters the command uses.
    description : str
        What the command does.
    axis : Axis
        For rotations: the axis turned about.
    sign : int
        For rotations: +1 turns the first axis of the pair toward the second
        (H toward L, H toward U, L toward U), -1 the other way.  For the
        material without an argument: the step of the index (+1 next, -1
        previous; the index never goes below 0).  For the factors (length,
        width, angle): +1 multiplies, -1 divides; for ``WIDTH_ADD``: adds or takes away.
    ignored : tuple of str
        Parameters after the used ones that the command accepts and lsys3d
        ignores (L-Py's ``F(length, topradius)``); a module carrying them is
        named in a warning.
    scale : float
        For moves without an argument: the step length's factor (Lparser's ``Z``: 0.5).
    vertex : bool
        For moves inside a polygon: whether the position becomes a vertex (ABOP's ``G``: no).
    factor : float
        The default factor or amount when the module has no argument (0: the
        options' ``length_scale``, ``width_scale``, ``angle_scale`` or ``angle``).
    organ : Organ
        For :data:`Op.ORGAN`: what is recorded.
    prefix : bool
        The row applies to every name that starts with ``symbol`` and is longer
        (cpfg's surfaces: ``~l``, ``~k``...).
    world : tuple of int
        For :data:`Op.TROPISM_VECTOR`: which of the module's parameters gives lsys3d's x, y and z
        (the tool's world axes: PlantGL's Z-up world is ``(1, 2, 0)``); for :data:`Op.QUERY`, which
        parameter each of lsys3d's x, y and z is written to.
    query : str
        For :data:`Op.QUERY`: what the module's parameters are filled with after each derivation step
        (:mod:`lsys3d.turtle.query`): ``P`` the position, ``H``, ``L``, ``U`` the frame's vectors, ``R``
        the right vector (-L), ``E`` the environment's answer (:mod:`lsys3d.turtle.environment`).
    """

    symbol: str
    name: str
    op: Op
    args: str
    max_args: int
    description: str
    axis: Axis = Axis.NONE
    sign: int = 1
    ignored: tuple[str, ...] = ()
    scale: float = 1.0
    vertex: bool = True
    factor: float = 0.0
    organ: Organ = Organ.NONE
    prefix: bool = False
    world: tuple[int, int, int] = (0, 1, 2)
    query: str = ""

    @property
    def accepts(self) -> int:
        """Most parameters a module of this command may carry (used and ignored)."""
        return self.max_args + len(self.ignored)


def queries(letters: str = "PHLU", world: tuple[int, int, int] = (0, 1, 2)) -> tuple[Command, ...]:
    """The query modules ``?P``, ``?H``... (L-Py's and cpfg's): one row each, in the tool's world axes."""
    what = {"P": "position", "H": "heading", "L": "left vector", "U": "up vector", "R": "right vector (-L)"}
    return tuple(
        Command(
            f"?{k}",
            f"query {what[k].split()[0]}",
            Op.QUERY,
            "x, y, z",
            3,
            f"Query module: after each derivation step the turtle fills `x, y, z` with its {what[k]} here.",
            world=world,
            query=k,
        )
        for k in letters
    )


QUERY_COMMANDS = queries("PHLU")
"""lsys3d's own query modules (the world axes of lsys3d, Y up)."""

ENVIRONMENT_QUERY = Command(
    "?E",
    "environment",
    Op.QUERY,
    "b, d, l",
    3,
    "Environment query (cpfg's), filled after each derivation step: `b` 1 where the turtle is blocked (inside "
    "an obstacle or outside the pruning volume) else 0, `d` the distance to the nearest support or obstacle, "
    "`l` the light received (0 or 1). See docs/environment.md.",
    query="E",
)
"""cpfg's ``?E``, answered by the environment (:mod:`lsys3d.turtle.environment`)."""

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
    Command(
        "@O",
        "sphere",
        Op.ORGAN,
        "d",
        1,
        "Place a sphere of diameter `d` (default: the width) at the turtle: an organ (`lsys3d.look.organs`).",
        organ=Organ.SPHERE,
    ),
    Command(
        "@c",
        "disc",
        Op.ORGAN,
        "d",
        1,
        "Place a disc of diameter `d` (default: the width) in the plane of H and L: an organ (`lsys3d.look.organs`).",
        organ=Organ.DISC,
    ),
    Command(
        "@o",
        "circle",
        Op.ORGAN,
        "d",
        1,
        "Place a circle of diameter `d` (default: the width) in the plane of H and L: an organ (`lsys3d.look.organs`).",
        organ=Organ.CIRCLE,
    ),
    *QUERY_COMMANDS,
    ENVIRONMENT_QUERY,
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
    sign: np.ndarray  # float64: +1 / -1 of rotations and factors
    max_args: np.ndarray  # int64: parameters accepted (used and ignored)
    commands: tuple  # the Command of each symbol id (None for no command)
    scale: np.ndarray = None  # float64: step factor of moves without an argument
    vertex: np.ndarray = None  # bool: moves inside a polygon record a vertex
    factor: np.ndarray = None  # float64: default factor or amount (0: the options')
    organ: np.ndarray = None  # int8: Organ
    world: np.ndarray = None  # (256, 3) int64: the parameters that give x, y, z (TROPISM_VECTOR)

    def command(self, code: int) -> Command | None:
        return self.commands[code]


def symbol_table(
    alphabet, draw: str = "F", move: str = "f", leaf: str = "~", commands: tuple[Command, ...] = COMMANDS
) -> SymbolTable:
    """Compile a command table for the symbols of ``alphabet`` (``alphabet[code]`` is the symbol of id ``code``).

    ``draw``, ``move`` and ``leaf`` are the symbols the ``[turtle]`` table gives
    those commands; ``commands`` is the vocabulary (:data:`COMMANDS`, or a
    dialect's own table built from rows of the same kind).  A row of the
    vocabulary with another symbol wins over a ``draw``, ``move`` or ``leaf``
    symbol (Lparser's ``~`` turns at random, whatever ``leaf`` says).

    >>> from lsys3d.lsystem.modules import ASCII_ALPHABET
    >>> p = symbol_table(ASCII_ALPHABET, draw="FG")
    >>> Op(p.op[ord("G")]).name, Axis(p.axis[ord("&")]).name, float(p.sign[ord("&")])
    ('FORWARD', 'L', -1.0)
    """
    n = 256
    op = np.zeros(n, np.int8)
    axis = np.zeros(n, np.int8)
    sign = np.ones(n, np.float64)
    max_args = np.zeros(n, np.int64)
    scale = np.ones(n, np.float64)
    vertex = np.ones(n, np.bool_)
    factor = np.zeros(n, np.float64)
    organ = np.zeros(n, np.int8)
    world = np.tile(np.arange(3, dtype=np.int64), (n, 1))
    per_code: list[Command | None] = [None] * n
    code_of = {ch: i for i, ch in enumerate(alphabet) if ch != "\0"}
    defaults = {o: _BY_OP[o].symbol for o in RENAMEABLE.values()}
    base = {c.op: c for c in commands if c.op in RENAMEABLE.values() and c.symbol == defaults[c.op]}
    fixed = [c for c in commands if not (c.op in RENAMEABLE.values() and c.symbol == defaults[c.op])]
    taken = {c.symbol for c in fixed if not c.prefix}
    rows = []
    for symbols, o in ((draw, Op.FORWARD), (move, Op.MOVE), (leaf, Op.LEAF)):
        rows += [(ch, base.get(o, _BY_OP[o])) for ch in symbols if ch not in taken]
    rows += [(c.symbol, c) for c in fixed if not c.prefix]
    prefixed = [c for c in fixed if c.prefix]
    if prefixed:
        rows += [
            (name, c) for name in code_of for c in prefixed if len(name) > len(c.symbol) and name.startswith(c.symbol)
        ]
    for symbol, c in rows:
        code = code_of.get(symbol)
        if code is None:
            continue
        op[code] = c.op
        axis[code] = c.axis
        sign[code] = c.sign
        max_args[code] = c.accepts
        scale[code] = c.scale
        vertex[code] = c.vertex
        factor[code] = c.factor
        organ[code] = c.organ
        world[code] = c.world
        per_code[code] = c
    return SymbolTable(op, axis, sign, max_args, tuple(per_code), scale, vertex, factor, organ, world)


def commands_markdown() -> str:
    """The command table as Markdown (the table in ``docs/turtle.md``)."""
    rows = ["| Symbol | Name | Argument | What it does |", "|---|---|---|---|"]
    for cmd in COMMANDS:
        symbol = cmd.symbol.replace("|", "\\|")
        arg = f"`{symbol}({cmd.args})`" if cmd.args else ""
        rows.append(f"| `{symbol}` | {cmd.name} | {arg} | {cmd.description.replace('|', chr(92) + '|')} |")
    return "\n".join(rows) + "\n"
