"""L-Py (``.lpy`` files; ``dialect = "lpy"`` in TOML): the notation, the turtle and the reader.

The turtle is PlantGL's, as L-Py's documentation lists its predefined modules
(``doc/user/helpcard.rst`` and ``src/cpp/predefinedmodules.cpp`` of openalea/lpy): each name and alias
below is one row.  Widths are radii (``width_unit = 2``: lsys3d's widths are diameters), the
default width is 0.1 and the default angle 60 degrees.  PlantGL's world has Z up: its (x, y, z) is
lsys3d's (y, z, x) (the turtle starts heading up, H = (0, 0, 1), L = (0, -1, 0), U = (1, 0, 0)), so
its default tropism (0, 0, 1), which ``@Tp`` changes, is lsys3d's (0, 1, 0); the elasticity turns H
toward T by ``e`` times their angle (PlantGL's ``Turtle::_tendTo``).  Module names are read as L-Py reads them: the
longest predefined or declared name, else one character; ``~`` takes the next character as the
surface's name (``~l``).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

from ...errors import GrammarError, clip
from ...turtle.commands import Axis, Command, Op, Organ, queries
from ..expr import ExprSyntaxError, Function, Syntax, parse_expression
from ..grammar import Grammar
from .common import Dialect, Located, Notation, fail, line_where

__all__ = ["DIALECT", "INITIALISATION", "UNSUPPORTED", "read"]

_SYNTAX = Syntax(python=True)


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
    Command(
        "@Tp",
        "Tropism",
        Op.TROPISM_VECTOR,
        "x, y, z",
        3,
        "Set the tropism vector (PlantGL's world: Z up) that the elasticity bends the moves toward.",
        world=(1, 2, 0),
    ),
    Command(
        "nF",
        "nF",
        Op.FORWARD_STEPS,
        "l, dl, r",
        3,
        "Move forward by `l` in steps of `dl` (and a last step of the rest), a cylinder each, the elasticity "
        "bending each; with `r`, the radius goes from the width to `r` step by step.",
        ignored=("radiusvariation",),
    ),
)

# every alias is a row of its own: L-Py reads "Left" as "+"
_ALIASED = {"+": "Left", "-": "Right", "^": "Up", "&": "Down", "/": "RollL", "\\": "RollR", "|": "TurnAround",
            "@v": "RollToVert", "[": "SB", "]": "EB", "{": "BP", "}": "EP", ".": "PP", "_": "IncWidth",
            "!": "DecWidth", ";": "IncColor", ",": "DecColor", "@O": "Sphere", "@o": "Circle", "@B": "Box",
            "@Ts": "Elasticity", "@Tp": "Tropism"}  # fmt: skip
_QUERY_ROWS = queries("PHLUR", world=(1, 2, 0))  # PlantGL's Z-up world: its (x, y, z) is lsys3d's (y, z, x)
_QUERY_ALIASES = {"?P": "GetPos", "?H": "GetHead", "?L": "GetLeft", "?U": "GetUp", "?R": "GetRight"}
COMMANDS_LPY = (
    _BASE
    + tuple(replace(c, symbol=_ALIASED[c.symbol]) for c in _BASE if c.symbol in _ALIASED)
    + _QUERY_ROWS
    + tuple(replace(c, symbol=_QUERY_ALIASES[c.symbol]) for c in _QUERY_ROWS)
)

UNSUPPORTED = frozenset(
    [
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

_QUERIES = frozenset(["?F", "?I", "GetFrame"])
"""L-Py's query modules lsys3d does not fill (the whole frame, the interpretation's state); ``?P``, ``?H``,
``?L``, ``?U``, ``?R`` and their ``Get...`` names are rows of the table, filled between the steps
(:mod:`lsys3d.turtle.query`)."""

DIALECT = Dialect(
    name="lpy",
    title="L-Py",
    notation=Notation(
        names=frozenset(c.symbol for c in COMMANDS_LPY if len(c.symbol) > 1) | UNSUPPORTED | _QUERIES,
        surface_prefix="~",
        arrows=("-->", "->"),
        reserved=":=",
        values_in_patterns=True,
        syntax=_SYNTAX,
    ),
    commands=COMMANDS_LPY,
    # PlantGL's turtle: its tropism (0, 0, 1) is up (lsys3d's (0, 1, 0)), its elasticity bends by an angle
    turtle={"width": 0.2, "width_unit": 2.0, "width_increment": 1.0, "tropism": (0.0, 1.0, 0.0), "bend": "angle"},
    angle=60.0,
    cut="%",
    suffixes=(".lpy",),
    reader=lambda text, source, **overrides: read(text, source, **overrides),
    unsupported=UNSUPPORTED,
    arity_check=False,
)


# ---------------------------------------------------------------- the reader of .lpy files
INITIALISATION = "###### INITIALISATION ######"
"""L-Py's tag before the editor's settings (materials, scalars, curves) at the end of a file."""

MAX_PATHS = 256
"""Most ways through one rule's ifs that produce (each becomes an lsys3d rule)."""
MAX_WALK = 100_000
"""Most statements visited while following every way through one rule's ifs (the work, not only the
rules made: ``if``/``else`` blocks one after another double the ways each, producing or not)."""

_KEYWORD = re.compile(
    r"(?P<key>Axiom|axiom|derivation length|production|homomorphism|interpretation|decomposition|maximum depth"
    r"|ignore|consider|group\s+\d+|endgroup|endlsystem|module)\b\s*(?P<colon>:?)"
)
_KNOWN_IMPORTS = ("math", "random", "numpy", "openalea", "copy", "sys", "os.path")
_HOOKS = {"Start", "End", "StartEach", "EndEach", "StartInterpretation", "EndInterpretation", "PostDraw"}
_HARMLESS = re.compile(r"(pass|(np\.|numpy\.)?random\.seed\s*\(.*\)|seed\s*\(.*\)|print\b.*|global\s.*)\Z")
_WORD = re.compile(r"(n?produce|if|elif|else|return|pass|for|while|with|try|def|class|global|lambda|yield)\b")
_ASSIGN = re.compile(r"([A-Za-z_][A-Za-z_0-9]*)\s*([-+*/%]?)=(?!=)\s*(.*)\Z", re.DOTALL)
_DEF = re.compile(r"def\s+([A-Za-z_][A-Za-z_0-9]*)\s*\(([^()]*)\)\s*:\s*(.*)\Z", re.DOTALL)
_STRING = re.compile(r"""[rRbBuU]?("{3}[\s\S]*?"{3}|'{3}[\s\S]*?'{3}|"[^"\n]*"|'[^'\n]*')\Z""")
_CALL_ANGLE = re.compile(
    r"(?:exec)?[cC]ontext\(\)\.turtle\.(setAngleIncrement|setWidth|setWidthIncrement|setDefaultStep)\((.*)\)\Z"
)


class _Line:
    """A logical line of the file: its number, its indentation and its code (comments removed)."""

    __slots__ = ("code", "col", "indent", "number")

    def __init__(self, number: int, indent: int, code: str, col: int):
        self.number = number
        self.indent = indent
        self.code = code
        self.col = col  # the column of the code's first character


def _logical_lines(text: str, first_line: int = 1) -> list[_Line]:
    """Physical lines joined while a bracket or a triple-quoted string is open; comments removed."""
    out: list[_Line] = []
    depth = 0
    quote = ""
    start_number, start_indent, start_col, parts = 0, 0, 1, []
    for k, raw in enumerate(text.split("\n")):
        number = first_line + k
        line = raw.rstrip("\r")
        code = []
        i = 0
        while i < len(line):
            ch = line[i]
            if quote:
                if line.startswith(quote, i):
                    code.append(quote)
                    i += len(quote)
                    quote = ""
                    continue
                code.append(ch)
                i += 1
                continue
            if ch == "#":
                break
            if line.startswith(('"""', "'''"), i):
                quote = line[i : i + 3]
                code.append(quote)
                i += 3
                continue
            if ch in "\"'":
                end = line.find(ch, i + 1)
                end = len(line) - 1 if end < 0 else end
                code.append(line[i : end + 1])
                i = end + 1
                continue
            if ch in "([{":
                depth += 1
            elif ch in ")]}":
                depth = max(depth - 1, 0)
            code.append(ch)
            i += 1
        piece = "".join(code)
        if not parts:
            if not piece.strip() and not quote:
                continue
            start_number = number
            start_indent = len(piece) - len(piece.lstrip())
            start_col = start_indent + 1
            parts = [piece.strip()]
        else:
            parts.append(piece.strip())
        continued = piece.rstrip().endswith("\\")
        if continued:
            parts[-1] = parts[-1].rstrip()[:-1]
        if depth == 0 and not quote and not continued:
            out.append(_Line(start_number, start_indent, " ".join(p for p in parts if p), start_col))
            parts = []
    if parts:
        out.append(_Line(start_number, start_indent, " ".join(p for p in parts if p), start_col))
    return out


def _top_split(text: str, sep: str) -> list[str]:
    """``text`` split at ``sep`` outside brackets and strings."""
    out, depth, last, quote = [], 0, 0, ""
    for i, ch in enumerate(text):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif depth == 0 and text.startswith(sep, i):
            out.append(text[last:i])
            last = i + len(sep)
    out.append(text[last:])
    return out


def _colon(text: str) -> int:
    """Where the ':' that ends a header (``if x:``, ``A(x) :``) stands, outside brackets; -1 if none."""
    depth = 0
    for i, ch in enumerate(text):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == ":" and depth == 0:
            return i
    return -1


class _Reader:
    def __init__(self, text: str, source: str):
        self.text = text
        self.source = source
        self.defines: dict[str, float] = {}
        self.functions: dict[str, Function] = {}
        self.function_texts: list[tuple[str, int]] = []
        self.unavailable: dict[str, str] = {}  # global name -> why lsys3d cannot compute it
        self.walked = 0  # statements followed through the current rule's ifs (bounded by MAX_WALK)
        self.axiom: tuple[str, object] | None = None
        self.iterations: tuple[str, int] | None = None
        self.groups = {"rules": [], "homomorphism": [], "decomposition": []}
        self.depths: dict[str, int] = {}
        self.modules: list[str] = []
        self.symbols = {"ignore": "", "consider": ""}  # ignore: and consider:
        self.turtle: dict[str, object] = {}
        self.angle: float | None = None
        self.where: dict = {}

    def error(self, line: _Line, what: str, col: int | None = None) -> GrammarError:
        return fail(what, self.source, line.number, col or line.col)

    # ------------------------------------------------------------ the file
    def read(self):
        body, _, init = self.text.partition(INITIALISATION)
        self.scalars(init)
        lines = _logical_lines(body)
        section = None  # None: Python; else "rules", "homomorphism", "decomposition"
        i = 0
        while i < len(lines):
            line = lines[i]
            if line.indent:
                raise self.error(line, "unexpected indentation (a block with nothing that opens it)")
            m = _KEYWORD.match(line.code)
            if m and (m.group("colon") or m.group("key") in ("endgroup", "endlsystem", "module")):
                i, section = self.keyword(lines, i, m, section)
                continue
            i = self.python(lines, i) if section is None else self.rule(lines, i, section)
        if self.axiom is None:
            raise fail("no 'Axiom:' (the start string)", self.source, 1, 1)

    def block(self, lines: list[_Line], i: int) -> tuple[list[_Line], int]:
        """The lines indented under line ``i`` (the body of a def, a rule, an Axiom)."""
        j = i + 1
        while j < len(lines) and lines[j].indent > lines[i].indent:
            j += 1
        return lines[i + 1 : j], j

    def keyword(self, lines, i, m, section):
        line = lines[i]
        key = m.group("key")
        rest = line.code[m.end() :].strip()
        rest_col = line.col + m.end() + (len(line.code[m.end() :]) - len(line.code[m.end() :].lstrip()))
        body, nxt = self.block(lines, i)
        if key in ("Axiom", "axiom"):
            if body:
                rest = self.axiom_block(body, rest)
            self.axiom = (rest, line_where(line.number, rest_col))
            return nxt, section
        if body:
            raise self.error(body[0], f"unexpected indentation after '{key}'")
        if key == "derivation length":
            self.iterations = (self.whole(line, rest, "derivation length"), line.number)
        elif key in ("production", "homomorphism", "interpretation", "decomposition"):
            section = {"production": "rules", "interpretation": "homomorphism"}.get(key, key)
        elif key == "maximum depth":
            depth = self.whole(line, rest, "maximum depth")
            targets = ("homomorphism", "decomposition") if section in (None, "rules") else (section,)
            for target in targets:
                self.depths[target] = depth
        elif key == "module":
            for part in _top_split(line.code[m.end() :].split(":", 1)[0], ","):
                name = part.strip().split("(", 1)[0].strip()
                if name:
                    self.modules.append(name)
        elif key in ("ignore", "consider"):
            self.symbols[key] = (self.symbols[key] + " " + rest).strip()
            self.where[key] = line_where(line.number, rest_col)
        elif key.startswith("group"):
            if int(key.split()[1]) != 0:
                raise self.error(line, f"'{key}:' (rules that Python code switches on with useGroup) is not supported")
        elif key == "endlsystem":
            section = None
        return nxt, section

    def whole(self, line: _Line, text: str, what: str) -> int:
        try:
            value = parse_expression(text, defines=self.defines, syntax=_SYNTAX, functions=self.functions).evaluate({})
        except (ExprSyntaxError, ArithmeticError) as exc:
            raise self.unknown(self.error(line, f"{what}: {exc}")) from None
        if not (value[0] >= 0 and float(value[0]).is_integer()):
            raise self.error(line, f"{what} must be a whole number >= 0, not {value[0]:g}")
        return int(value[0])

    def axiom_block(self, body: list[_Line], rest: str) -> str:
        """``Axiom:`` with an indented block: ``produce``/``nproduce`` lines only (no loops)."""
        pieces = [rest] if rest else []
        for line in body:
            word, _, arg = line.code.partition(" ")
            if word not in ("produce", "nproduce"):
                raise self.error(line, f"an Axiom computed by Python code ({clip(line.code, 40)!r}) is not supported")
            pieces.append(arg)
        return " ".join(pieces)

    # ------------------------------------------------------------ Python outside the rules
    def python(self, lines: list[_Line], i: int) -> int:
        line = lines[i]
        code = line.code
        body, nxt = self.block(lines, i)
        first = code.split(None, 1)[0] if code.split() else ""
        if first in ("import", "from"):
            module = code.split()[1]
            if not module.startswith(_KNOWN_IMPORTS):
                raise self.error(
                    line,
                    f"'{clip(code, 50)}': the Python module {module!r} is never run (only math and random are known)",
                )
            return nxt
        if _STRING.match(code) or _HARMLESS.match(code) or code.startswith("assert "):
            return nxt  # a docstring, a print, a check: nothing the plant depends on
        m = _CALL_ANGLE.match(code)
        if m:
            value = self.value(line, m.group(2))
            key = {"setAngleIncrement": "angle", "setWidth": "width", "setWidthIncrement": "width_increment",
                   "setDefaultStep": "step"}[m.group(1)]  # fmt: skip
            if key == "angle":
                self.angle = value
            else:
                self.turtle[key] = value * 2 if key == "width" else value  # L-Py's widths are radii
            return nxt
        m = _DEF.match(code)
        if m:
            self.function(line, m, body)
            return nxt
        if body or code.endswith(":"):
            raise self.error(
                line, f"Python code ({clip(code, 40)!r}) is never run; a file that needs it is not supported"
            )
        m = re.match(r"extern\((.*)\)\Z", code)
        if m:
            for part in _top_split(m.group(1), ","):
                name, _, value = part.partition("=")
                self.assign(line, name.strip(), value.strip(), part)
            return nxt
        m = _ASSIGN.match(code)
        if m:
            value = m.group(3) if not m.group(2) else f"{m.group(1)} {m.group(2)} ({m.group(3)})"
            self.assign(line, m.group(1), value, code)
            return nxt
        names, _, values = code.partition("=")
        if _ and "," in names and not values.startswith("="):
            targets, exprs = _top_split(names, ","), _top_split(values, ",")
            count = re.fullmatch(r"\s*range\s*\(\s*(?:(\d+)\s*,\s*)?(\d+)\s*\)\s*", values)
            if count:  # A, B, C = range(3) (or range(1, 4)): an enumeration
                low = int(count.group(1) or 0)
                if int(count.group(2)) - low == len(targets):
                    exprs = [str(low + k) for k in range(len(targets))]
            if len(targets) == len(exprs):
                for name, value in zip(targets, exprs, strict=True):
                    self.assign(line, name.strip(), value.strip(), code)
                return nxt
        raise self.error(line, f"Python code ({clip(code, 40)!r}) is never run; a file that needs it is not supported")

    def value(self, line: _Line, text: str) -> float:
        try:
            return float(
                parse_expression(text, defines=self.defines, syntax=_SYNTAX, functions=self.functions).evaluate({})[0]
            )
        except (ExprSyntaxError, ArithmeticError) as exc:
            raise self.unknown(self.error(line, f"{clip(text, 40)!r}: {exc}")) from None

    def assign(self, line: _Line, name: str, text: str, code: str):
        if not re.fullmatch(r"[A-Za-z_][A-Za-z_0-9]*", name):
            raise self.error(
                line, f"Python code ({clip(code, 40)!r}) is never run; a file that needs it is not supported"
            )
        if _STRING.match(text):  # metadata: __authors__ = "..."
            return
        try:
            expr = parse_expression(text, defines=self.defines, syntax=_SYNTAX, functions=self.functions)
            if expr.random:
                raise ExprSyntaxError("it draws a random number once, when L-Py loads the file", 0)
            value = float(expr.evaluate({})[0])
        except (ExprSyntaxError, ArithmeticError) as exc:
            self.unavailable[name] = f"line {line.number}: {clip(text, 40)!r}: {exc}"
            self.defines.pop(name, None)
            return
        if not math.isfinite(value) or name in ("and", "or", "not", "if", "else"):
            self.unavailable[name] = f"line {line.number}: not a finite number"
            return
        self.unavailable.pop(name, None)
        self.defines[name] = value

    def function(self, line: _Line, m: re.Match, body: list[_Line]):
        name, params = m.group(1), tuple(p.strip() for p in m.group(2).split(",") if p.strip())
        statements = ([m.group(3)] if m.group(3).strip() else []) + [b.code for b in body]
        statements = [s for s in statements if not _STRING.match(s)]
        if name in _HOOKS or name == "__initialiseContext__":
            if name in _HOOKS and not all(_HARMLESS.match(s) for s in statements):
                raise self.error(line, f"L-Py's {name}() hook runs Python code, which lsys3d never runs")
            return
        if (
            len(statements) == 1
            and statements[0].startswith("return ")
            and all(re.fullmatch(r"\w+", p) for p in params)
        ):
            text = statements[0][len("return ") :]
            try:
                expr = parse_expression(
                    text, names=params, defines=self.defines, syntax=_SYNTAX, functions=self.functions
                )
            except ExprSyntaxError as exc:
                self.unavailable[name] = f"line {line.number}: def {name}: {exc}"
                return
            self.functions[name] = Function(name, params, expr)
            self.function_texts.append((f"{name}({', '.join(params)}) = {text}", line.number))
            return
        self.unavailable[name] = f"line {line.number}: def {name}() is more than 'return expression'"

    def scalars(self, init: str):
        """The L-Py editor's scalars (``scalars = [('N', 'Integer', 5, 0, 10), ...]``): globals with a value."""
        m = re.search(r"scalars\s*=\s*\[(.*?)\]\s*\n", init, re.DOTALL)
        if not m:
            return
        for item in re.finditer(r"\(\s*'([A-Za-z_]\w*)'\s*,\s*(?:'(\w+)'\s*,\s*)?([^,()]+)", m.group(1)):
            name, kind, value = item.group(1), item.group(2), item.group(3).strip()
            if kind == "Category":
                continue
            number = {"True": 1.0, "False": 0.0}.get(value)
            try:
                number = float(value) if number is None else number
            except ValueError:
                continue
            if name not in self.defines:
                self.defines[name] = number

    # ------------------------------------------------------------ rules
    def rule(self, lines: list[_Line], i: int, section: str) -> int:
        line = lines[i]
        code = line.code
        body, nxt = self.block(lines, i)
        for arrow in ("-->", "->"):
            at = _arrow_at(code, arrow)
            if at >= 0:
                self.no_queries(line, code[:at])
                if body:
                    raise self.error(body[0], "unexpected indentation after a one-line rule")
                self.add_rule(section, Located().add(code, line.number, line.col))
                return nxt
        colon = _colon(code)
        if colon < 0:
            raise self.error(line, f"expected a rule ('pattern --> successor' or 'pattern :'), not {clip(code, 40)!r}")
        header = code[:colon].rstrip()
        inline = code[colon + 1 :].strip()
        if inline:
            body = [_Line(line.number, line.indent + 1, inline, line.col + code.index(inline, colon)), *body]
        self.no_queries(line, header)
        statements = self.statements(body, 0, len(body))
        paths: list = []
        self.walked = 0
        self.walk(statements, [], [], paths, line)
        for steps, successor in paths:
            text = Located().add(header, line.number, line.col)
            if steps:
                text.add(" : ", line.number, line.col + colon)
                pending_test = False
                for kind, piece, place in steps:
                    if kind == "let":
                        text.add("{", *place).add(piece, *place).add("}", *place)
                        pending_test = False
                    else:
                        if pending_test:
                            text.add("{}", *place)
                        text.add("(", *place).add(piece, *place).add(")", *place)
                        pending_test = True
            text.add(" --> ", line.number, line.col + colon)
            if successor:
                for piece, place in successor:
                    text.add(piece, *place).add(" ", *place)
            else:
                text.add("*", line.number, line.col + colon)
            self.add_rule(section, text)
        return nxt

    def no_queries(self, line: _Line, pattern: str):
        if any(q in pattern for q in _QUERIES if q.startswith("?")) or re.search(r"\bGetFrame\b", pattern):
            raise self.error(line, "L-Py's ?F, ?I and GetFrame queries (the whole frame) are not supported")

    def add_rule(self, section: str, text: Located):
        group = self.groups[section]
        self.where[(section, len(group))] = text.where()
        group.append(text.text)

    def statements(self, body: list[_Line], start: int, stop: int) -> list:
        """The statements of a rule's body: ('let', ...), ('produce', ...), ('if', branches, else), ('return',)."""
        out = []
        i = start
        while i < stop:
            line = body[i]
            code = line.code
            # the lines indented under this one
            j = i + 1
            while j < stop and body[j].indent > line.indent:
                j += 1
            m = _WORD.match(code)
            word = m.group(1) if m else ""
            if word in ("if", "elif", "else"):
                if word != "if":
                    raise self.error(line, f"'{word}' without 'if'")
                branches = []
                otherwise = None
                if_indent = line.indent
                while True:
                    colon = _colon(code)
                    if colon < 0:
                        raise self.error(line, f"'{word}' needs a ':'")
                    cond = code[len(word) : colon].strip()
                    inline = code[colon + 1 :].strip()
                    nested = self.statements(body, i + 1, j)
                    if inline:
                        at = line.col + code.index(inline, colon)
                        nested = self.statements([_Line(line.number, line.indent + 1, inline, at)], 0, 1) + nested
                    if word == "else":
                        otherwise = nested
                    else:
                        branches.append(((cond, (line.number, line.col + len(word) + 1)), nested))
                    i = j
                    if i >= stop or otherwise is not None:
                        break
                    line = body[i]
                    code = line.code
                    m = _WORD.match(code)
                    word = m.group(1) if m else ""
                    if word not in ("elif", "else") or line.indent != if_indent:
                        break
                    j = i + 1
                    while j < stop and body[j].indent > line.indent:
                        j += 1
                out.append(("if", branches, otherwise))
                continue
            if word in ("for", "while", "with", "try", "def", "class", "global", "lambda", "yield"):
                raise self.error(line, f"Python's '{word}' in a rule is not supported (rules are read, never run)")
            if j > i + 1:
                raise self.error(body[i + 1], f"unexpected indentation (a {clip(code, 30)!r} block is not supported)")
            if word in ("produce", "nproduce"):
                rest = code[len(word) :]
                at = line.col + len(word) + (len(rest) - len(rest.lstrip()))
                out.append((word, rest.strip(), (line.number, at)))
            elif word == "return" and code.strip() == "return":
                out.append(("return",))
            elif word == "pass" or _STRING.match(code) or (_HARMLESS.match(code) and word != "global"):
                pass
            else:
                m = _ASSIGN.match(code)
                if not m:
                    raise self.error(line, f"this Python statement in a rule is not supported: {clip(code, 40)!r}")
                name, op, value = m.group(1), m.group(2), m.group(3)
                place = (line.number, line.col + m.start(3))
                out.append(("let", f"{name} {op}= {value}" if op else f"{name} = {value}", place))
            i = j
        return out

    def walk(self, statements, steps, pieces, paths, line, k: int = 0):
        """Every way through the statements: (steps, successor) for each path that produces."""
        while k < len(statements):
            self.walked += 1
            if self.walked > MAX_WALK:
                raise self.error(
                    line,
                    f"the rule's 'if's have too many ways through (more than {MAX_WALK:,} statements to follow; "
                    "lsys3d.lsystem.dialects.lpy.MAX_WALK)",
                )
            s = statements[k]
            kind = s[0]
            if kind == "let":
                steps = [*steps, ("let", s[1], s[2])]
            elif kind == "nproduce":
                pieces = [*pieces, (s[1], s[2])]
            elif kind == "produce":
                paths.append((steps, [*pieces, (s[1], s[2])]))
                if len(paths) > MAX_PATHS:
                    raise self.error(line, f"more than {MAX_PATHS} ways through the rule's 'if's")
                return
            elif kind == "return":
                break
            elif kind == "if":
                _, branches, otherwise = s
                rest = statements[k + 1 :]
                taken = []
                for (cond, place), nested in branches:
                    test = " and ".join([f"not ({c})" for c in taken] + [f"({cond})"])
                    self.walk(nested + rest, [*steps, ("test", test, place)], pieces, paths, line)
                    taken.append(cond)
                if taken:
                    test = " and ".join(f"not ({c})" for c in taken)
                    place = branches[-1][0][1]
                    steps = [*steps, ("test", test, place)]
                if otherwise is not None:
                    self.walk(otherwise + rest, steps, pieces, paths, line)
                    return
                if len(paths) > MAX_PATHS:
                    raise self.error(line, f"more than {MAX_PATHS} ways through the rule's 'if's")
            k += 1
        if pieces:  # nproduce without produce: applied with what was produced
            paths.append((steps, pieces))
        if len(paths) > MAX_PATHS:
            raise self.error(line, f"more than {MAX_PATHS} ways through the rule's 'if's")

    # ------------------------------------------------------------ the grammar
    def unknown(self, exc: GrammarError) -> GrammarError:
        """A better message for a name the file computes with Python lsys3d cannot follow."""
        m = re.search(r"unknown (?:name|function) '(\w+)'", exc.reason)
        if m and m.group(1) in self.unavailable:
            return GrammarError(
                f"{exc.reason}: '{m.group(1)}' is Python that lsys3d does not run ({self.unavailable[m.group(1)]})",
                exc.source,
                exc.line,
                exc.col,
            )
        return exc

    def grammar(self, **overrides) -> Grammar:
        axiom, where_axiom = self.axiom
        self.where["axiom"] = where_axiom
        for k, (_, number) in enumerate(self.function_texts):
            self.where[("functions", k)] = line_where(number, 1)
        fields = {
            "axiom": axiom,
            "rules": self.groups["rules"],
            "homomorphism": self.groups["homomorphism"],
            "decomposition": self.groups["decomposition"],
            "homomorphism_depth": self.depths.get("homomorphism", 1),
            "decomposition_depth": self.depths.get("decomposition", 1),
            "iterations": self.iterations[0] if self.iterations else 1,
            "defines": dict(self.defines),
            "functions": [t for t, _ in self.function_texts],
            "modules": sorted(set(self.modules)),
            "ignore": self.symbols["ignore"],
            "consider": self.symbols["consider"],
            "turtle": dict(self.turtle),
            "dialect": "lpy",
        }
        if self.angle is not None:
            fields["angle"] = self.angle
        fields.update(overrides)
        try:
            return Grammar(**fields, source=self.source, text=self.text, _where=self.where)
        except GrammarError as exc:
            raise self.unknown(exc) from None


def _arrow_at(code: str, arrow: str) -> int:
    depth = 0
    for i, ch in enumerate(code):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif depth == 0 and code.startswith(arrow, i):
            return i
    return -1


def read(text: str, source: str = "<string>", **overrides) -> Grammar:
    """Read an L-Py file's text into a :class:`~lsys3d.lsystem.grammar.Grammar` (dialect ``lpy``); nothing is run.

    >>> g = read("Axiom: A\\nderivation length: 2\\nproduction:\\nA --> F[+A]A\\nendlsystem\\n", "tree.lpy")
    >>> g.dialect, g.iterations, g.angle, g.rules
    ('lpy', 2, 60.0, ('A --> F[+A]A',))
    """
    reader = _Reader(text, source)
    reader.read()
    return reader.grammar(**overrides)
