"""cpfg / L-studio / vlab (``.l`` files; ``dialect = "cpfg"`` in TOML): the notation, the turtle and the reader.

The turtle of cpfg's "Interpreted symbols" (Mech and Prusinkiewicz, the appendix of the cpfg 3.0
tutorial at algorithmicbotany.org): ``;``/``,`` step the colour index (or set it), ``#``/``!`` step the
line width (or set it), ``@O``, ``@c``, ``@o`` spheres and discs of a diameter (default: the line
width), ``~c`` the predefined surface ``c``, ``@v`` rolls the turtle so that U is closest to up,
``G``/``g`` move like ``F``/``f`` without recording a polygon vertex.  Expressions are C's, with the
trigonometric functions in degrees as cpfg's are.
"""

from __future__ import annotations

from ..expr import Syntax
from ..turtle.commands import Axis, Command, Op, Organ
from .common import Dialect, Notation

__all__ = ["DIALECT", "UNSUPPORTED"]


def _rot(symbol, name, axis, sign, what):
    return Command(symbol, name, Op.ROTATE, "a", 1, what, axis, sign)


COMMANDS_CPFG = (
    Command("F", "forward", Op.FORWARD, "d", 1, "Move forward by `d` (default: the step) drawing a segment."),
    Command("f", "move", Op.MOVE, "d", 1, "Move forward by `d` without drawing."),
    Command("G", "forward, no vertex", Op.FORWARD, "d", 1, "As `F`, without recording a polygon vertex.", vertex=False),
    Command("g", "move, no vertex", Op.MOVE, "d", 1, "As `f`, without recording a polygon vertex.", vertex=False),
    _rot("+", "turn left", Axis.U, +1, "Turn left by `a` degrees around U (default: the angle increment)."),
    _rot("-", "turn right", Axis.U, -1, "Turn right around U."),
    _rot("&", "pitch down", Axis.L, -1, "Pitch down around L."),
    _rot("^", "pitch up", Axis.L, +1, "Pitch up around L."),
    _rot("\\", "roll left", Axis.H, -1, "Roll left around H."),
    _rot("/", "roll right", Axis.H, +1, "Roll right around H."),
    Command("|", "turn around", Op.TURN_AROUND, "", 0, "Turn around 180 degrees around U."),
    Command("@v", "roll to vertical", Op.ROLL_HORIZONTAL, "", 0, "Roll around H so that U is closest to up."),
    Command("$", "roll to horizontal", Op.ROLL_HORIZONTAL, "", 0, "Roll around H so that L is horizontal."),
    Command("[", "push", Op.PUSH, "", 0, "Push the turtle's state."),
    Command("]", "pop", Op.POP, "", 0, "Pop the turtle's state."),
    Command("{", "begin polygon", Op.POLYGON_BEGIN, "", 0, "Start a polygon."),
    Command("}", "end polygon", Op.POLYGON_END, "", 0, "Close the polygon."),
    Command(".", "polygon vertex", Op.POLYGON_VERTEX, "", 0, "Record a polygon vertex."),
    Command(
        ";",
        "next colour",
        Op.MATERIAL,
        "n",
        1,
        "Add 1 to the colour index, or set it to `n`.",
        sign=+1,
        ignored=("n2",),
    ),
    Command(
        ",",
        "previous colour",
        Op.MATERIAL,
        "n",
        1,
        "Take 1 from the colour index, or set it to `n`.",
        sign=-1,
        ignored=("n2",),
    ),
    Command("#", "wider", Op.WIDTH_ADD, "n", 1, "Add the line width increment, or set the width to `n`.", sign=+1),
    Command(
        "!", "narrower", Op.WIDTH_ADD, "n", 1, "Take the line width increment away, or set the width to `n`.", sign=-1
    ),
    Command(
        "@O",
        "sphere",
        Op.ORGAN,
        "d",
        1,
        "A sphere of diameter `d` (default: the line width): an organ.",
        organ=Organ.SPHERE,
    ),
    Command(
        "@c", "disc", Op.ORGAN, "d", 1, "A disc of diameter `d` in the plane of H and L: an organ.", organ=Organ.DISC
    ),
    Command(
        "@o",
        "circle",
        Op.ORGAN,
        "d",
        1,
        "A circle of diameter `d` in the plane of H and L: an organ.",
        organ=Organ.CIRCLE,
    ),
    Command(
        "~",
        "surface",
        Op.ORGAN,
        "s",
        1,
        "`~c(s)`: the predefined surface `c`, scaled by `s`: an organ.",
        organ=Organ.SURFACE,
        prefix=True,
    ),
    Command("@Ts", "elasticity", Op.ELASTICITY, "e", 1, "Set the elasticity of the moves that follow."),
)

UNSUPPORTED = frozenset(
    [
        "@Gs",
        "@Gc",
        "@Ge",
        "@Gt",
        "@Gr",
        "@Tx",
        "@M",
        "@m",
        "@R",
        "@L",
        "@Ls",
        "@D",
        "@Di",
        "@Dd",
        "@b",
        "@H",
        "@#",
        "@Tf",
        "@S",
        "@Ms",
        "@Me",
        "@Mc",
        "@P",
        "@J",
        "@Tp",
    ]
)
"""cpfg turtle commands that lsys3d reads but does not draw (named in a warning)."""

DIALECT = Dialect(
    name="cpfg",
    title="cpfg",
    notation=Notation(
        names=frozenset(c.symbol for c in COMMANDS_CPFG if len(c.symbol) > 1) | UNSUPPORTED,
        surface_prefix="~",
        arrows=("-->", "->"),
        reserved=":=",
        syntax=Syntax(degrees=True),
    ),
    commands=COMMANDS_CPFG,
    turtle={"width_increment": 1.0},
    angle=90.0,
    cut="%",
    suffixes=(".l",),
    unsupported=UNSUPPORTED,
    arity_check=False,
)
