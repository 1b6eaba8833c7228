"""L-Py (``.lpy`` files; ``dialect = "lpy"`` in TOML): the notation, the turtle and the reader.

The turtle is PlantGL's, as L-Py's documentation lists its predefined modules
(``doc/user/helpcard.rst`` and ``src/cpp/predefinedmodules.cpp`` of openalea/lpy): each name and alias
below is one row.  Widths are radii (``width_unit = 2``: lsys3d's widths are diameters), the
default width is 0.1 and the default angle 60 degrees.  Module names are read as L-Py reads them: the
longest predefined or declared name, else one character; ``~`` takes the next character as the
surface's name (``~l``).
"""

from __future__ import annotations

from dataclasses import replace

from ..expr import Syntax
from ..turtle.commands import Axis, Command, Op, Organ
from .common import Dialect, Notation

__all__ = ["DIALECT", "UNSUPPORTED"]


def _rot(symbol, name, axis, sign, what):
    return Command(symbol, name, Op.ROTATE, "a", 1, what, axis, sign)


_BASE = (
    Command(
        "F",
        "F",
        Op.FORWARD,
        "l",
        1,
        "Move forward by `l` (default: the step) drawing a cylinder.",
        ignored=("topradius",),
    ),
    Command("f", "f", Op.MOVE, "l", 1, "Move forward by `l` without drawing."),
    _rot("+", "Left", Axis.U, +1, "Turn left around U by `a` degrees (default: the angle)."),
    _rot("-", "Right", Axis.U, -1, "Turn right around U."),
    _rot("^", "Up", Axis.L, +1, "Pitch up around L."),
    _rot("&", "Down", Axis.L, -1, "Pitch down around L."),
    _rot("/", "RollL", Axis.H, +1, "Roll around H (PlantGL's rollL: L toward U)."),
    _rot("\\", "RollR", Axis.H, -1, "Roll around H the other way."),
    Command("|", "TurnAround", Op.TURN_AROUND, "", 0, "Turn around 180 degrees around U."),
    Command("@v", "RollToVert", Op.ROLL_HORIZONTAL, "", 0, "Roll around H so that H and U lie in a vertical plane."),
    Command("[", "SB", Op.PUSH, "", 0, "Push the turtle's state."),
    Command("]", "EB", Op.POP, "", 0, "Pop the turtle's state."),
    Command("{", "BP", Op.POLYGON_BEGIN, "", 0, "Start a polygon."),
    Command("}", "EP", Op.POLYGON_END, "", 0, "Close the polygon.", ignored=("concavetest",)),
    Command(".", "PP", Op.POLYGON_VERTEX, "", 0, "Add a point to the polygon."),
    Command(
        "_",
        "IncWidth",
        Op.WIDTH_ADD,
        "w",
        1,
        "Add the width increment to the width, or set it to `w` (a radius).",
        sign=+1,
    ),
    Command(
        "!", "DecWidth", Op.WIDTH_ADD, "w", 1, "Take the width increment from the width, or set it to `w`.", sign=-1
    ),
    Command("SetWidth", "SetWidth", Op.WIDTH, "w", 1, "Set the width (a radius) to `w`."),
    Command(";", "IncColor", Op.MATERIAL, "i", 1, "Next material index, or set it to `i`.", sign=+1),
    Command(",", "DecColor", Op.MATERIAL, "i", 1, "Previous material index, or set it to `i`.", sign=-1),
    Command("SetColor", "SetColor", Op.MATERIAL, "i", 1, "Set the material index to `i`."),
    Command(
        "@O", "Sphere", Op.ORGAN, "r", 1, "A sphere of radius `r` (default: the width): an organ.", organ=Organ.SPHERE
    ),
    Command(
        "@o", "Circle", Op.ORGAN, "r", 1, "A circle of radius `r` (default: the width): an organ.", organ=Organ.CIRCLE
    ),
    Command("@B", "Box", Op.ORGAN, "l", 1, "A box of edge `l`: an organ.", organ=Organ.BOX, ignored=("topradius",)),
    Command(
        "~",
        "surface",
        Op.ORGAN,
        "s",
        1,
        "`~l(s)`: the predefined surface `l`, scaled by `s`: an organ.",
        organ=Organ.SURFACE,
        prefix=True,
    ),
    Command("@Ts", "Elasticity", Op.ELASTICITY, "e", 1, "Set the elasticity of the moves that follow."),
)

# every alias is a row of its own: L-Py reads "Left" as "+"
_ALIASED = {"+": "Left", "-": "Right", "^": "Up", "&": "Down", "/": "RollL", "\\": "RollR", "|": "TurnAround",
            "@v": "RollToVert", "[": "SB", "]": "EB", "{": "BP", "}": "EP", ".": "PP", "_": "IncWidth",
            "!": "DecWidth", ";": "IncColor", ",": "DecColor", "@O": "Sphere", "@o": "Circle", "@B": "Box",
            "@Ts": "Elasticity"}  # fmt: skip
COMMANDS_LPY = _BASE + tuple(replace(c, symbol=_ALIASED[c.symbol]) for c in _BASE if c.symbol in _ALIASED)

UNSUPPORTED = frozenset(
    [
        "nF",
        "@Gc",
        "StartGC",
        "@Ge",
        "EndGC",
        "LineTo",
        "OLineTo",
        "LineRel",
        "OLineRel",
        "Pinpoint",
        "PinpointRel",
        "@R",
        "SetHead",
        "EulerAngles",
        "iRollL",
        "iRollR",
        "@h",
        "RollToHorizontal",
        "LeftReflection",
        "UpReflection",
        "HeadingReflection",
        "@M",
        "MoveTo",
        "MoveRel",
        "@2D",
        "StartScreenProjection",
        "@3D",
        "EndScreenProjection",
        "@Dd",
        "DivScale",
        "@Di",
        "MultScale",
        "@D",
        "SetScale",
        "@b",
        "Quad",
        "@L",
        "Label",
        "surface",
        "@g",
        "PglShape",
        "Frame",
        "Arrow",
        "SetContour",
        "SectionResolution",
        "SetGuide",
        "EndGuide",
        "Sweep",
        "PositionOnGuide",
        "@Tp",
        "Tropism",
        "InterpolateColors",
        "TextureBaseColor",
        "InterpolateTextureBaseColors",
        "TextureScale",
        "TextureUScale",
        "TextureVScale",
        "TextureVCoeff",
        "TextureTranslation",
        "TextureRotation",
        "TextureTransformation",
    ]
)
"""PlantGL turtle commands that lsys3d reads but does not draw (named in a warning)."""

_QUERIES = frozenset(
    ["?P", "?H", "?U", "?L", "?R", "?F", "?I", "GetPos", "GetHead", "GetUp", "GetLeft", "GetRight", "GetFrame"]
)
"""L-Py's query modules: filled by the turtle during derivation, which lsys3d's derivation has no turtle for."""

DIALECT = Dialect(
    name="lpy",
    title="L-Py",
    notation=Notation(
        names=frozenset(c.symbol for c in COMMANDS_LPY if len(c.symbol) > 1) | UNSUPPORTED | _QUERIES,
        surface_prefix="~",
        arrows=("-->", "->"),
        syntax=Syntax(python=True),
    ),
    commands=COMMANDS_LPY,
    turtle={"width": 0.2, "width_unit": 2.0, "width_increment": 1.0, "tropism": (0.0, -1.0, 0.0)},
    angle=60.0,
    cut="%",
    suffixes=(".lpy",),
    unsupported=UNSUPPORTED,
)
