"""Lparser (Laurens Lapré's ``.ls`` files; ``dialect = "lparser"`` in TOML): the notation, the turtle and the reader.

The symbols of ``lparser.txt`` (version 4): ``<`` and ``>`` roll (they are no contexts here), ``%``
rolls 180 degrees (no cut), ``Z``/``z`` move half a step, ``g`` moves without recording a polygon
vertex, ``"`` and ``'`` multiply the length by 1.1 and 0.9 (by ``x`` with an argument), ``;`` and ``:``
the angle, ``?`` and ``!`` the thickness by 1.4 and 0.7, ``c`` steps the colour (sets it with an
argument), ``~`` turns, pitches and rolls at random, ``t`` corrects for gravity.  Rules are ``X=...``
with no contexts and no conditions (``:`` is a symbol).
"""

from __future__ import annotations

from ..turtle.commands import Axis, Command, Op
from .common import Dialect, Notation

__all__ = ["DIALECT"]


def _rot(symbol, name, axis, sign, what):
    return Command(symbol, name, Op.ROTATE, "x", 1, what, axis, sign)


COMMANDS_LPARSER = (
    Command("F", "draw", Op.FORWARD, "x", 1, "Move forward a full length (or `x`) drawing."),
    Command("Z", "draw half", Op.FORWARD, "x", 1, "Move forward half a length (or `x`) drawing.", scale=0.5),
    Command("f", "move", Op.MOVE, "x", 1, "Move forward a full length (or `x`)."),
    Command("z", "move half", Op.MOVE, "x", 1, "Move forward half a length (or `x`).", scale=0.5),
    Command(
        "g",
        "move, no vertex",
        Op.MOVE,
        "x",
        1,
        "Move forward a full length without recording a polygon vertex.",
        vertex=False,
    ),
    _rot("+", "turn left", Axis.U, +1, "Turn left around U (by `x` degrees)."),
    _rot("-", "turn right", Axis.U, -1, "Turn right around U."),
    _rot("&", "pitch down", Axis.L, -1, "Pitch down around L."),
    _rot("^", "pitch up", Axis.L, +1, "Pitch up around L."),
    _rot("<", "roll left", Axis.H, -1, "Roll left (counter-clockwise) around H."),
    _rot(">", "roll right", Axis.H, +1, "Roll right (clockwise) around H."),
    Command("|", "turn 180", Op.TURN_AROUND, "", 0, "Turn 180 degrees around U."),
    Command("%", "roll 180", Op.TURN_AROUND, "", 0, "Roll 180 degrees around H.", Axis.H),
    Command("$", "roll horizontal", Op.ROLL_HORIZONTAL, "", 0, "Roll until horizontal."),
    Command(
        "~",
        "random turn",
        Op.RANDOM_TURN,
        "x",
        1,
        "Turn, pitch and roll at random, at most `x` degrees each (default 90).",
        factor=90.0,
    ),
    Command("t", "gravity", Op.TROPISM, "x", 1, "Correct for gravity with 0.2 (or `x`).", factor=0.2),
    Command("[", "push", Op.PUSH, "", 0, "Push the current state."),
    Command("]", "pop", Op.POP, "", 0, "Pop the current state."),
    Command("{", "begin polygon", Op.POLYGON_BEGIN, "", 0, "Start a polygon shape."),
    Command("}", "end polygon", Op.POLYGON_END, "", 0, "End the polygon shape."),
    Command(".", "vertex", Op.POLYGON_VERTEX, "", 0, "Record a vertex without moving."),
    Command('"', "longer", Op.LENGTH, "x", 1, "Multiply the length by 1.1 (or `x`).", factor=1.1),
    Command("'", "shorter", Op.LENGTH, "x", 1, "Multiply the length by 0.9 (or `x`).", factor=0.9),
    Command(";", "wider angle", Op.ANGLE_FACTOR, "x", 1, "Multiply the angle by 1.1 (or `x`).", factor=1.1),
    Command(":", "narrower angle", Op.ANGLE_FACTOR, "x", 1, "Multiply the angle by 0.9 (or `x`).", factor=0.9),
    Command("?", "thicker", Op.WIDTH_FACTOR, "x", 1, "Multiply the thickness by 1.4 (or `x`).", factor=1.4),
    Command("!", "thinner", Op.WIDTH_FACTOR, "x", 1, "Multiply the thickness by 0.7 (or `x`).", factor=0.7),
    Command("c", "colour", Op.MATERIAL, "x", 1, "Next colour index, or set it to `x`.", sign=+1),
)

DIALECT = Dialect(
    name="lparser",
    title="Lparser",
    notation=Notation(arrows=("=",), contexts=False, conditions=False, reserved="=,"),
    commands=COMMANDS_LPARSER,
    angle=90.0,
    cut="",
    suffixes=(".ls",),
)
