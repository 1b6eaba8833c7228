"""Houdini's L-system SOP: ``dialect = "houdini"`` in TOML, with ``premise`` and ``rules`` as typed in the SOP.

The turtle of the SOP's "Turtle command reference": ``&`` pitches up and ``^`` down (the other way from
ABOP), ``H``/``h`` move half a step, ``G`` moves without recording a vertex, ``J``, ``K`` and ``M``
copy an input geometry (recorded as organs), ``T`` applies the tropism vector once, ``*`` rolls 180
degrees, ``~`` turns at random (up to 180 degrees), ``"``, ``!`` and ``;`` multiply the length, the
thickness and the angle by the SOP's scales (``_``, ``?`` and ``@`` divide), ``'`` steps the colour
index, ``%`` cuts.  Rules read ``[lc<]pred[>rc][:cond]=succ[:prob]``, as lsys3d's.
"""

from __future__ import annotations

from ...turtle.commands import Axis, Command, Op, Organ
from .common import Dialect, Notation

__all__ = ["DIALECT", "UNSUPPORTED", "VARIABLES"]


def _rot(symbol, name, axis, sign, what):
    return Command(symbol, name, Op.ROTATE, "a", 1, what, axis, sign)


def _copy(letter):
    """The SOP's ``J``, ``K``, ``M``: copy the geometry of that input at the turtle (an organ)."""
    what = f"Copy the geometry of input {letter} at the turtle: an organ."
    return Command(letter, f"copy {letter}", Op.ORGAN, "s", 1, what, organ=Organ.INSTANCE, ignored=("x", "a", "b", "c"))


COMMANDS_HOUDINI = (
    Command("F", "forward", Op.FORWARD, "l", 1, "Move forward, creating geometry.", ignored=("w", "s", "d")),
    Command(
        "H",
        "half forward",
        Op.FORWARD,
        "l",
        1,
        "Move forward half the length, creating geometry.",
        scale=0.5,
        ignored=("w", "s", "d"),
    ),
    Command(
        "G",
        "forward, no vertex",
        Op.MOVE,
        "l",
        1,
        "Move forward without recording a vertex.",
        vertex=False,
        ignored=("w", "s", "d"),
    ),
    Command("f", "move", Op.MOVE, "l", 1, "Move forward, no geometry created.", ignored=("w", "s", "d")),
    Command(
        "h",
        "half move",
        Op.MOVE,
        "l",
        1,
        "Move forward half the length, no geometry created.",
        scale=0.5,
        ignored=("w", "s", "d"),
    ),
    *(_copy(letter) for letter in "JKM"),
    Command("T", "tropism", Op.TROPISM, "g", 1, "Bend toward the tropism vector by `g` (default 0.2).", factor=0.2),
    _rot("+", "turn right", Axis.U, +1, "Turn (the SOP's 'right': ABOP's '+')."),
    _rot("-", "turn left", Axis.U, -1, "Turn the other way."),
    _rot("&", "pitch up", Axis.L, +1, "Pitch up: ABOP's '^'."),
    _rot("^", "pitch down", Axis.L, -1, "Pitch down: ABOP's '&'."),
    _rot("\\", "roll clockwise", Axis.H, -1, "Roll around H."),
    _rot("/", "roll counter-clockwise", Axis.H, +1, "Roll around H the other way."),
    Command("|", "turn 180", Op.TURN_AROUND, "", 0, "Turn 180 degrees."),
    Command("*", "roll 180", Op.TURN_AROUND, "", 0, "Roll 180 degrees.", Axis.H),
    Command(
        "~",
        "random turn",
        Op.RANDOM_TURN,
        "a",
        1,
        "Pitch, roll and turn at random, up to `a` degrees (180).",
        factor=180.0,
    ),
    Command('"', "longer", Op.LENGTH, "s", 1, "Multiply the length by `s` (default: length_scale)."),
    Command("_", "shorter", Op.LENGTH, "s", 1, "Divide the length by `s` (default: length_scale).", sign=-1),
    Command("!", "thicker", Op.WIDTH_FACTOR, "s", 1, "Multiply the thickness by `s` (default: width_scale)."),
    Command("?", "thinner", Op.WIDTH_FACTOR, "s", 1, "Divide the thickness by `s` (default: width_scale).", sign=-1),
    Command(";", "wider angle", Op.ANGLE_FACTOR, "s", 1, "Multiply the angle by `s` (default: angle_scale)."),
    Command("@", "narrower angle", Op.ANGLE_FACTOR, "s", 1, "Divide the angle by `s` (default: angle_scale).", sign=-1),
    Command("'", "colour", Op.MATERIAL, "u", 1, "Next colour index (U), or set it to `u`.", sign=+1),
    Command("$", "roll horizontal", Op.ROLL_HORIZONTAL, "", 0, "Roll so that the turtle's up is the world's up."),
    Command("[", "push", Op.PUSH, "", 0, "Push the turtle's state (start a branch)."),
    Command("]", "pop", Op.POP, "", 0, "Pop the turtle's state (end a branch)."),
    Command("{", "begin polygon", Op.POLYGON_BEGIN, "", 0, "Start a polygon."),
    Command(".", "polygon vertex", Op.POLYGON_VERTEX, "", 0, "Make a polygon vertex."),
    Command("}", "end polygon", Op.POLYGON_END, "", 0, "End the polygon."),
)

UNSUPPORTED = frozenset({"#", "g"})
"""The SOP's commands that lsys3d reads but does not draw: ``#`` (colour index V), ``g`` (a primitive group)."""

VARIABLES = {
    "b": "Variable b of the SOP's Values tab: give it as a define, defines = { b = ... }",
    "c": "Variable c of the SOP's Values tab: give it as a define, defines = { c = ... }",
    "d": "Variable d of the SOP's Values tab: give it as a define, defines = { d = ... }",
    "t": "the age of the symbol: lsys3d has no ages (not supported)",
    "g": "the generation of the rule: not supported",
    "i": "the count of the current process: not supported",
    "A": "the arc length from the root: not supported",
    "x": "the turtle's position: not supported in rules",
    "y": "the turtle's position: not supported in rules",
    "z": "the turtle's position: not supported in rules",
}
"""The SOP's predefined variables and what becomes of them in lsys3d."""

DIALECT = Dialect(
    name="houdini",
    title="Houdini",
    notation=Notation(arrows=("=", "->"), star_empty=False),
    commands=COMMANDS_HOUDINI,
    angle=90.0,
    cut="%",
    variables=VARIABLES,
    unsupported=UNSUPPORTED,
)
