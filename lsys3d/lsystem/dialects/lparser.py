"""Lparser (Laurens Lapré's ``.ls`` files; ``dialect = "lparser"`` in TOML): the notation, the turtle and the reader.

The symbols of ``lparser.txt`` (version 4): ``<`` and ``>`` roll (they are no contexts here), ``%``
rolls 180 degrees (no cut), ``Z``/``z`` move half a step, ``g`` moves without recording a polygon
vertex, ``"`` and ``'`` multiply the length by 1.1 and 0.9 (by ``x`` with an argument), ``;`` and ``:``
the angle, ``?`` and ``!`` the thickness by 1.4 and 0.7, ``c`` steps the colour (sets it with an
argument), ``~`` turns, pitches and rolls at random, ``t`` corrects for gravity, ``_`` draws nothing.
Rules are ``X=...`` with no contexts and no conditions (``:`` is a symbol).  Lparser's step is 100
units, so a length given as an argument counts in hundredths of a step (``f(300)`` moves three steps:
``length_unit = 0.01``).

Lparser rewrites characters, not modules: a rule ``X=s`` rewrites the ``X`` of ``X(300)`` and leaves
``(300)`` where it stands, after ``s``; the ``(300)`` then belongs to the last symbol of ``s`` when that
symbol takes an argument and has none (``A=F`` makes ``A(5)`` into ``F(5)``), and is inert otherwise
(``f=_`` makes ``f(300)`` into ``_(300)``: nothing).  The reader gives each such rule the parametric
twin that does the same (``X(x1)=s`` with ``(x1)`` on its last symbol or dropped), for the symbols the
file writes with arguments.
"""

from __future__ import annotations

import re

from ...errors import clip
from ...turtle.commands import Axis, Command, Op
from ..expr import ExprSyntaxError, parse_expression
from ..grammar import Grammar
from . import webls
from .common import Dialect, Notation, fail, line_where

__all__ = ["ABOP_LIKE_FORMS", "DIALECT", "read"]


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
    Command(
        "_",
        "nothing",
        Op.NONE,
        "",
        0,
        "Draws nothing: Lparser's default successor (a symbol without a rule becomes `_`), written `X=_` to "
        "remove `X`.",
    ),
)

DIALECT = Dialect(
    name="lparser",
    title="Lparser",
    notation=Notation(arrows=("=",), contexts=False, conditions=False, reserved="=,"),
    commands=COMMANDS_LPARSER,
    # Lparser's step is 100 (K-3D's l_parser.cpp: dis = 100): F(300) is three steps
    turtle={"length_unit": 0.01},
    angle=90.0,
    cut="",
    suffixes=(".ls",),
    reader=lambda text, source, **overrides: read(text, source, **overrides),
)


# ---------------------------------------------------------------- the reader of .ls files
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\Z")
_ABOP_LIKE = re.compile(
    r"^\s*(axiom\s*:|p\d+\s*:|dlength\s*:|derivation length\s*:|#\s*define\b|#\s*ignore\b|ignore\s*:"
    r"|n\s*=\s*\d+\s*,|delta\s*=)",
    re.IGNORECASE | re.MULTILINE,
)
_KEYWORDS = re.compile(r"^\s*(recursion|angle|thickness|axiom|rule|var)\b", re.IGNORECASE | re.MULTILINE)


def _content(text: str) -> list[tuple[str, int, int]]:
    """Lparser's lines: ``(content, line, column)`` without '#' comments and blank lines, up to the '@' line."""
    out = []
    for k, raw in enumerate(text.split("\n")):
        code = raw.split("#", 1)[0].rstrip()
        if not code.strip():
            continue
        if code.strip() == "@":
            break
        out.append((code.strip(), k + 1, len(code) - len(code.lstrip()) + 1))
    return out


def read(text: str, source: str = "<string>", **overrides) -> Grammar:
    """Read a ``.ls`` file: Lparser's (either layout) or the ABOP-like form of web L-system projects.

    The content says which: Lparser starts with the recursion depth, the angle and the thickness (or
    names them, ``recursion 12``, ``rule X = ...``); the ABOP-like form has ``axiom:``, ``p1: A -> B``,
    ``#define``, ``dlength:`` or ``n=...,delta=...``.

    >>> g = read("# a bush\\n4\\n25\\n50\\nA\\nA=+FA\\n@\\n", "bush.ls")
    >>> g.dialect, g.iterations, g.angle, g.rules, g.turtle["width"]
    ('lparser', 4, 25.0, ('A=+FA',), 0.5)
    """
    if webls.recognise(text):  # the web tools' form with settings lines and /* */ comments
        return webls.read(text, source, **overrides)
    if _ABOP_LIKE.search(text):
        return _read_abop_like(text, source, **overrides)
    lines = _content(text)
    if lines and _NUMBER.match(lines[0][0]):
        return _read_lparser(lines, [], text, source, overrides)
    if lines and _KEYWORDS.match(lines[0][0]):
        return _read_keywords(lines, text, source, overrides)
    raise fail(
        "cannot tell which .ls format this is: Lparser's starts with the recursion depth, the angle and the "
        "thickness (or 'recursion', 'angle', 'thickness' lines, and Lparser2's 'min_thickness', 'switch_yz'...); "
        "the ABOP-like one has 'axiom:' and rules such as 'p1: A -> B'; the web tools' has settings lines "
        "('n=5; delta=22.5; stemsize=0.1') and 'axiom:'",
        source,
        lines[0][1] if lines else 1,
        1,
    )


def _read_lparser(lines, header, text, source, overrides, names=("recursion depth", "angle", "thickness")):
    """The numeric layout: recursion depth, angle, thickness (% of the length), axiom, ``X=...`` rules."""
    values = []
    if len(lines) < 3:
        raise fail(f"the file ends before the {names[len(lines)]} (Lparser's third line)", source, lines[-1][1], 1)
    for (code, number, col), what in zip(lines[:3], names, strict=True):
        if not _NUMBER.match(code):
            raise fail(f"expected the {what} (a number), not {clip(code, 30)!r}", source, number, col)
        values.append(float(code))
    if len(lines) < 4:
        raise fail("no axiom after the recursion depth, the angle and the thickness", source, lines[-1][1], 1)
    return _lparser_grammar(values, lines[3], lines[4:], text, source, overrides)


def _read_keywords(lines, text, source, overrides):
    """The keyword layout: ``recursion 12``, ``angle 20``, ``thickness 50``, ``axiom X``, ``rule X = ...``.

    Lparser's later versions and ports (Lparser2.c and its JavaScript build) add ``min_thickness``,
    ``switch_yz``, ``shape``, ``color``, ``mutation``, ``trace``, ``poly_limit`` and ``no_wait``
    (:func:`_port_key`).
    """
    settings: dict[str, float] = {"recursion": 1.0, "angle": 90.0, "thickness": 10.0}
    port: dict = {}
    axiom = None
    rules = []
    for code, number, col in lines:
        m = re.match(r"(\w+)\s*[:=]?\s*(.*)\Z", code)
        key, rest = m.group(1).lower(), m.group(2).strip()
        rest_col = col + code.index(rest) if rest else col
        if key in _PORT_KEYS:
            _port_key(key, rest, port, source, number, rest_col)
        elif key in settings:
            if not _NUMBER.match(rest):
                raise fail(f"'{key}' takes a number, not {clip(rest, 30)!r}", source, number, rest_col)
            settings[key] = float(rest)
        elif key == "axiom":
            axiom = (rest, number, rest_col)
        elif key == "rule":
            rules.append((rest, number, rest_col))
        else:
            known = ", ".join(["recursion", "angle", "thickness", "axiom", "rule", *_PORT_KEYS])
            raise fail(f"unknown Lparser line {clip(code, 30)!r} (known: {known})", source, number, col)
    if axiom is None:
        raise fail("no 'axiom' line", source, lines[-1][1], 1)
    values = [settings["recursion"], settings["angle"], settings["thickness"]]
    extra: dict = {}
    if port.get("min_thickness"):  # a percentage of Lparser's unit, 1/100 of a step (Lparser2.c: min_thick /= 100)
        extra["turtle"] = {"min_width": port["min_thickness"] / 1e4}
    if "materials" in port:
        extra["materials"] = port["materials"]
    return _lparser_grammar(values, axiom, rules, text, source, overrides, extra)


_PORT_KEYS = ("min_thickness", "switch_yz", "shape", "color", "mutation", "trace", "poly_limit", "no_wait")
"""The keys of Lparser2.c (L. Lapré's later Lparser, as jvail/L-System's JavaScript build compiles it)."""


def _port_key(key: str, rest: str, port: dict, source: str, line: int, col: int):
    """One key of Lparser2.c's keyword layout: what it does there, and what lsys3d does with it.

    ``min_thickness``: no segment thinner than this percentage of Lparser's unit (``min_width``);
    ``color n r g b``: colour ``n`` of the ``c`` command (a ``[materials]`` entry); ``switch_yz``: swaps
    y and z in the file Lparser writes (z up or y up): lsys3d's plants always stand up along +Y, so
    either value gives the same plant; ``shape``: blocks (0) or attached cylinders (1), lsys3d sweeps
    tubes either way; ``trace``, ``no_wait``: messages and a key press of the program.  ``mutation n``
    (random changes of the rules) and ``poly_limit`` (a cap that stops drawing) change the plant:
    refused unless 0.
    """
    numbers = rest.split()
    ok = numbers and all(_NUMBER.match(n) for n in numbers)
    count = 4 if key == "color" else 1
    if not ok or len(numbers) != count:
        what = "four whole numbers: index red green blue (0-255)" if key == "color" else "a number"
        raise fail(f"'{key}' takes {what}, not {clip(rest, 30)!r}", source, line, col)
    if key == "color":
        index, *rgb = (float(n) for n in numbers)
        if not (index.is_integer() and 0 <= index <= 255 and all(0 <= c <= 255 for c in rgb)):
            raise fail(f"'color' takes an index and red, green, blue from 0 to 255, not {clip(rest, 30)!r}",
                       source, line, col)  # fmt: skip
        hex_color = "#" + "".join(f"{int(c):02x}" for c in rgb)
        port.setdefault("materials", {})[str(int(index))] = {"base_color": hex_color}
        return
    value = float(numbers[0])
    if key == "min_thickness":
        if value < 0:
            raise fail(f"'min_thickness' must be >= 0, not {value:g}", source, line, col)
        port[key] = value
    elif key in ("mutation", "poly_limit") and value != 0:
        what = "random changes of the rules" if key == "mutation" else "a cap on the polygons that stops the drawing"
        raise fail(f"'{key} {numbers[0]}' ({what}) is not supported; 0 is", source, line, col)


def _lparser_grammar(values, axiom, rules, text, source, overrides, extra=None) -> Grammar:
    recursion, angle, thickness = values
    if not (recursion >= 0 and recursion.is_integer()):
        raise fail(f"the recursion depth must be a whole number >= 0, not {recursion:g}", source, 1, 1)
    where = {"axiom": line_where(axiom[1], axiom[2])}
    kept, defines, seen = [], {}, {}
    for code, number, col in rules:
        name, sep, value = code.partition("=")
        name = name.strip()
        if not sep or len(name) != 1:
            raise fail(f"expected a rule 'X=...' (one symbol, '=', its successor), not {clip(code, 40)!r}", source,
                       number, col)  # fmt: skip
        if _NUMBER.match(value.strip()):  # a=30: Lparser's variables are rules whose successor is a number
            defines[name] = float(value)
            continue
        if name in seen:
            raise fail(f"a second rule for {name!r} (the first is on line {seen[name]}); Lparser has one rule "
                       "per symbol", source, number, col)  # fmt: skip
        seen[name] = number
        where[("rules", len(kept))] = line_where(number, col)
        kept.append(code)
    for code, where_rule in _carried_arguments(axiom[0], kept, [where[("rules", k)] for k in range(len(kept))]):
        where[("rules", len(kept))] = where_rule
        kept.append(code)
    fields = {
        "axiom": axiom[0],
        "rules": kept,
        "iterations": int(recursion),
        "angle": angle,
        "defines": defines,
        "turtle": {"width": thickness / 100.0},  # thickness is a percentage of the length (the step, 1)
        "dialect": "lparser",
    }
    for key, table in (extra or {}).items():  # the port keys' settings (_port_key), under the file's own
        fields[key] = {**table, **fields.get(key, {})}
    fields.update(overrides)
    return Grammar(**fields, source=source, text=text, _where=where)


_TOKEN = re.compile(r"(\S)(\([^()]*\))?")
_TAKES_ARGUMENT = frozenset(c.symbol for c in COMMANDS_LPARSER if c.args)
_COMMANDS = frozenset(c.symbol for c in COMMANDS_LPARSER)


def _arities(text: str) -> list[tuple[str, int]]:
    """The symbols of an Lparser string that carry arguments, with how many (``F(1)`` -> ``('F', 1)``)."""
    return [(m.group(1), m.group(2).count(",") + 1) for m in _TOKEN.finditer(text) if m.group(2)]


def _carried_arguments(axiom: str, rules: list[str], wheres: list) -> list[tuple[str, object]]:
    """Rules ``X(x1..)=s'`` for the rules ``X=s`` whose symbol the file writes with arguments.

    Lparser leaves ``X``'s argument text after ``s`` (see the module's docstring): ``s'`` is ``s`` with
    the arguments on its last symbol when it takes one and has none (a symbol without a command
    takes them too, and passes them on when its own rule rewrites it), else ``s``.
    """
    successors = {}
    for k, code in enumerate(rules):
        name, _, value = code.partition("=")
        successors[name.strip()] = (value.strip(), wheres[k])
    carried: set[tuple[str, int]] = set(_arities(axiom))
    for value, _ in successors.values():
        carried.update(_arities(value))
    twins: dict[tuple[str, int], str] = {}
    todo = sorted(carried)
    while todo:
        symbol, n = todo.pop()
        if (symbol, n) in twins or symbol not in successors:
            continue
        value = successors[symbol][0]
        formals = ",".join(f"x{k + 1}" for k in range(n))
        tokens = list(_TOKEN.finditer(value))
        last = tokens[-1].groups() if tokens else ("", "(")
        if not last[1] and (last[0] in _TAKES_ARGUMENT or last[0] not in _COMMANDS):
            value = f"{value}({formals})"
            todo.append((last[0], n))
        twins[symbol, n] = f"{symbol}({formals})={value}"
    order = {symbol: k for k, symbol in enumerate(successors)}
    return [(twins[key], successors[key[0]][1]) for key in sorted(twins, key=lambda key: (order[key[0]], key[1]))]


def _read_abop_like(text, source, **overrides) -> Grammar:
    """The ABOP-like ``.ls`` of web projects: ``#define``, ``axiom:``, ``p1: A -> B``, ``dlength:``, ``n=,delta=``."""
    fields: dict = {"dialect": "abop"}
    where: dict = {}
    defines: dict[str, object] = {}
    rules = []
    lines = []
    for k, raw in enumerate(text.split("\n")):
        code = re.sub(r"//.*", "", raw).rstrip()
        if code.strip():
            lines.append((code.strip(), k + 1, len(code) - len(code.lstrip()) + 1))
    for code, number, col in lines:
        low = code.lower()
        m = re.match(r"#\s*define\s+([A-Za-z_]\w*)\s+(.+)\Z", code) or re.match(
            r"define\s*:\s*\(?([A-Za-z_]\w*)\)?\s+(.+)\Z", code
        )
        if m:
            defines[m.group(1)] = m.group(2).strip()
            continue
        m = re.match(r"(?:#\s*ignore|ignore\s*:)\s*(.*)\Z", code, re.IGNORECASE)
        if m:
            fields["ignore"] = m.group(1).strip()
            continue
        m = re.match(r"(?:axiom|premise)\s*:\s*(.*)\Z", code, re.IGNORECASE)
        if m:
            fields["axiom"] = m.group(1).strip()
            where["axiom"] = line_where(number, col + m.start(1))
            continue
        m = re.match(r"(?:dlength|derivation length)\s*:\s*(.+)\Z", code, re.IGNORECASE)
        if m:
            fields["iterations"] = m.group(1).strip()
            continue
        settings = re.findall(r"\b(n|delta|angle|iterations)\s*=\s*([-+0-9.eE]+)", code)
        if settings and re.fullmatch(r"[\w\s=.,+-]+", code):
            for key, value in settings:
                fields["iterations" if key in ("n", "iterations") else "angle"] = value
            continue
        if re.match(r"(view|stemsize|leafsize|width|color)\s*=", low):
            continue  # a viewer's settings
        if code.startswith("#"):
            continue  # a comment
        if "->" in code or "→" in code:
            where[("rules", len(rules))] = line_where(number, col)
            rules.append(code)
            continue
        raise fail(_unknown_abop_line(code), source, number, col)
    if "axiom" not in fields:
        raise fail("no 'axiom:' line", source, 1, 1)
    try:
        for key in ("iterations",):
            if isinstance(fields.get(key), str):
                value = float(parse_expression(fields[key], defines=_constants(defines, source)).evaluate({})[0])
                fields[key] = int(value) if value.is_integer() else value
        if isinstance(fields.get("angle"), str):
            fields["angle"] = float(fields["angle"])
    except (ExprSyntaxError, ArithmeticError, ValueError) as exc:
        raise fail(f"bad number: {exc}", source, 1, 1) from None
    fields["defines"] = defines
    fields["rules"] = rules
    fields.update(overrides)
    return Grammar(**fields, source=source, text=text, _where=where)


ABOP_LIKE_FORMS = (
    "'axiom: X' (or 'premise:')",
    "rules 'p1: A -> B' (or 'A -> B', 'A → B')",
    "'n=5, delta=25.7' (also 'angle=25.7', 'iterations=5')",
    "'dlength: 5' (or 'derivation length:')",
    "'#define NAME VALUE' (or 'define: NAME VALUE')",
    "'#ignore +-' (or 'ignore:')",
    "a viewer's 'view=', 'stemsize=', 'leafsize=', 'width=', 'color=' (skipped)",
    "comments after '//' or '#'",
)
"""The lines the ABOP-like ``.ls`` reader accepts, as its error for any other line lists them."""


def _unknown_abop_line(code: str) -> str:
    """The error for a line the ABOP-like form does not have: the line, a hint for a near miss, every form read."""
    m = re.match(r"(angle|delta|n|iterations)\s*:\s*(\S+)", code, re.IGNORECASE)
    hint = f" (write it '{m.group(1).lower()}={m.group(2)}')" if m else ""
    return f"unknown line {clip(code, 40)!r}{hint}; the ABOP-like .ls form reads: " + "; ".join(ABOP_LIKE_FORMS)


def _constants(defines: dict, source: str) -> dict:
    out = {}
    for name, value in defines.items():
        try:
            out[name] = float(parse_expression(str(value), defines=out).evaluate({})[0])
        except (ExprSyntaxError, ArithmeticError) as exc:
            raise fail(f"#define {name}: {exc}", source, 1, 1) from None
    return out
