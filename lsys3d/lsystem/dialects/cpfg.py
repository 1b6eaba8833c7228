"""cpfg / L-studio / vlab (``.l`` files; ``dialect = "cpfg"`` in TOML): the notation, the turtle and the reader.

The turtle of cpfg's "Interpreted symbols" (Mech and Prusinkiewicz, the appendix of the cpfg 3.0
tutorial at algorithmicbotany.org): ``;``/``,`` step the colour index (or set it), ``#``/``!`` step the
line width (or set it), ``@O``, ``@c``, ``@o`` spheres and discs of a diameter (default: the line
width), ``~c`` the predefined surface ``c``, ``@v`` rolls the turtle so that U is closest to up,
``G``/``g`` move like ``F``/``f`` without recording a polygon vertex.  Expressions are C's, with the
trigonometric functions in degrees as cpfg's are.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import numpy as np

from ...errors import GrammarError, clip
from ...external import FileRefused, inside
from ...turtle.commands import ENVIRONMENT_QUERY, Axis, Command, Op, Organ, queries
from ..expr import MAX_ARRAY, ExprSyntaxError, Syntax, constant_array, parse_expression
from ..grammar import MAX_PARAMETERS, Grammar, read_text
from ..splines import to_table
from . import vlab, vlab_look
from .common import Dialect, Notation, fail, line_where
from .macros import Macro, MacroError, expand, parse_definition

__all__ = ["DIALECT", "MAX_INCLUDES", "UNSUPPORTED", "read"]

_SYNTAX = Syntax(degrees=True)

log = logging.getLogger("lsys3d")


def _rot(symbol, name, axis, sign, what):
    # cpfg's interpret.c turns by the first parameter and reads no other (vlab's Lilac writes +(20,0))
    what += " Further parameters are read and left, as cpfg's interpret.c does."
    return Command(symbol, name, Op.ROTATE, "a, ...", MAX_PARAMETERS, what, axis, sign)


_STATE = (
    " Further parameters are the rules' (a state the productions carry, ABOP's growth rate `r` of `G(s,r)`): "
    "the turtle reads `d` only, as cpfg's interpret.c does."
)

COMMANDS_CPFG = (
    Command(
        "F",
        "forward",
        Op.FORWARD,
        "d, ...",
        MAX_PARAMETERS,
        "Move forward by `d` (default: the step) drawing a segment." + _STATE,
    ),
    Command("f", "move", Op.MOVE, "d, ...", MAX_PARAMETERS, "Move forward by `d` without drawing." + _STATE),
    Command(
        "G",
        "forward, no vertex",
        Op.FORWARD,
        "d, ...",
        MAX_PARAMETERS,
        "As `F`, without recording a polygon vertex." + _STATE,
        vertex=False,
    ),
    Command(
        "g",
        "move, no vertex",
        Op.MOVE,
        "d, ...",
        MAX_PARAMETERS,
        "As `f`, without recording a polygon vertex." + _STATE,
        vertex=False,
    ),
    _rot("+", "turn left", Axis.U, +1, "Turn left by `a` degrees around U (default: the angle increment)."),
    _rot("-", "turn right", Axis.U, -1, "Turn right around U."),
    _rot("&", "pitch down", Axis.L, -1, "Pitch down around L."),
    _rot("^", "pitch up", Axis.L, +1, "Pitch up around L."),
    # cpfg's frame has H x L = -U (interpret.c starts it at H = (0, 1, 0), L = (-1, 0, 0), U = (0, 0, -1)); lsys3d's
    # U is its -U, so cpfg's '/' (change_dir(left, up): L toward cpfg's U) turns L away from lsys3d's U
    _rot(
        "\\", "roll left", Axis.H, +1, "Roll left around H: L toward lsys3d's U (cpfg's -U: its frame has H x L = -U)."
    ),
    _rot("/", "roll right", Axis.H, -1, "Roll right around H: L toward lsys3d's -U (cpfg's U)."),
    Command("|", "turn around", Op.TURN_AROUND, "", 0, "Turn around 180 degrees around U."),
    Command("@v", "roll to vertical", Op.ROLL_HORIZONTAL, "", 0, "Roll around H so that U is closest to up."),
    Command(
        "?",
        "sub-L-system",
        Op.SUB_LSYSTEM,
        "n, s",
        2,
        "`?(n, s)`: sub-L-system `n` rewrites what follows up to its `$`; the turtle scales lengths and widths "
        "by `s` there (interpret.c's scale factor; the width at once). Without parameters, nothing.",
        sign=+1,
    ),
    Command(
        "$",
        "end of sub-L-system",
        Op.SUB_LSYSTEM,
        "",
        0,
        "The end of the sub-L-system of the last `?(n, s)`: its scale undone (cpfg's `$` does not roll, as "
        "ABOP's does; an unmatched `$` does nothing).",
        sign=-1,
    ),
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
        "A circle of diameter `d` (default: the line width): an organ. cpfg draws it facing the viewer "
        "(blackbox.c: a 2D circle); lsys3d in the plane of H and L.",
        organ=Organ.CIRCLE,
    ),
    Command(
        "~",
        "surface",
        Op.ORGAN,
        "sx, sy, sz",
        3,
        "`~c(s)`: the predefined surface `c` (the view file's `surface: c file.s size`), scaled by `s`: an "
        "organ. `~c(sx, sy, sz)` scales it by `sx` along left, `sy` along the heading, `sz` along up "
        "(lsys3d.turtle.selections).",
        organ=Organ.SURFACE,
        prefix=True,
    ),
    Command(
        "@Tx",
        "texture",
        Op.NONE,
        "n",
        1,
        "Select the view file's `n`-th texture (`texture: F: file.png ...`) for the cylinders and surfaces "
        "that follow (none: `@Tx` or an `n` that names no texture read); `[` and `]` keep it "
        "(lsys3d.turtle.selections).",
    ),
    Command(
        "_",
        "elasticity",
        Op.ELASTICITY_ADD,
        "e",
        1,
        "Add the elasticity increment (the view file's `elasticity increment:`) to the elasticity of the "
        "tropism (`tropism direction:`, `initial elasticity:`), or set it to `e`.",
    ),
    Command(
        "@Gs",
        "start generalized cylinder",
        Op.CYLINDER_START,
        "",
        0,
        "Start a generalized cylinder here: its first control point.",
    ),
    Command(
        "@Gc",
        "generalized cylinder point",
        Op.CYLINDER_POINT,
        "n",
        1,
        "A control point: a tube from the last one to here along cpfg's Hermite curve (the headings are its "
        "tangents), in `n` straight pieces (default 4), its width going from the last point's to this one's.",
    ),
    Command(
        "@Ge",
        "end generalized cylinder",
        Op.CYLINDER_POINT,
        "n",
        1,
        "The last control point, as `@Gc(n)`: the cylinder ends here.",
        sign=-1,
    ),
    Command(
        "@Gt",
        "cylinder tangents",
        Op.CYLINDER_TANGENTS,
        "a, b",
        2,
        "The factors of the tangents into (`a`) and out of (`b`, default `a`) the control points that follow "
        "(times the distance between two points; 1.2 at first).",
    ),
    Command(
        "@!",
        "sides",
        Op.SIDES,
        "n",
        1,
        "The sides of the tubes, generalized cylinders, spheres and discs that follow (cpfg's blackbox.c: the "
        "turtle's `cylinder_sides`, at least 3; 8 without a parameter): a sphere becomes cpfg's `n` slices by "
        "`n / 2 + 1` stacks, a disc `n` sides.",
    ),
    Command(
        "@Ts",
        "set tropism",
        Op.MOVEMENT_ELASTICITY,
        "n, e",
        2,
        "Set the elasticity of tropism `n` (the view file's `tropism:` and `torque:` lines, from 1) to `e` "
        "(0 without it); a number the view file does not have changes nothing, as in cpfg.",
        sign=0,
    ),
    Command(
        "@Ti",
        "raise tropism",
        Op.MOVEMENT_ELASTICITY,
        "n, d",
        2,
        "Add `d` (default: its `S:` increment) to the elasticity of tropism `n`.",
    ),
    Command(
        "@Td",
        "lower tropism",
        Op.MOVEMENT_ELASTICITY,
        "n, d",
        2,
        "Take `d` (default: its `S:` increment) from the elasticity of tropism `n`.",
        sign=-1,
    ),
    Command(
        "@Tf",
        "keep frame",
        Op.MOVEMENT_FRAME,
        "",
        0,
        "The turtle's frame now is the one the tropisms carry U from (cpfg's blackbox.c: a roll made since the "
        "last `F` is kept, not undone by the next bend).",
    ),
    Command(
        "@Tp",
        "untwist",
        Op.MOVEMENT_FRAME,
        "",
        0,
        "U carried from the frame of the last `F` (or `@Tf`) along the smallest rotation to the heading now: "
        "the rolls made since undone (cpfg's turtle.c `adjust_up_and_left`).",
        sign=-1,
    ),
    *queries("PHLU"),  # cpfg's world is lsys3d's: Y up
    ENVIRONMENT_QUERY,
)

UNSUPPORTED = frozenset(
    [
        "@Gr",
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
        "@S",
        "@Ms",
        "@Me",
        "@Mc",
        "@P",
        "@J",
        # the rest of cpfg's blackbox.c: patches, objects, bounded circles, cuts
        "@I",
        "@PS",
        "@PC",
        "@PD",
        "@mo",
        "@mc",
        "@bo",
        "@bc",
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
        reserved=":",  # '=' is a module (cpfg's lexer reads any character as one: vlab's Lilac writes I(o,i,w)=)
        syntax=_SYNTAX,
        sequences=True,
        sub_lsystems=True,
        branch_skip="=",
    ),
    commands=COMMANDS_CPFG,
    turtle={"width_increment": 1.0},
    angle=90.0,
    cut="%",
    suffixes=(".l",),
    reader=lambda text, source, **overrides: read(text, source, **overrides),
    unsupported=UNSUPPORTED,
    arity_check=False,
)


# ---------------------------------------------------------------- the reader of .l files
MAX_INCLUDES = 16
"""Most files one grammar may include (``#include``), nested or not."""

_DIRECTIVE = re.compile(r"#\s*(define|include|ifdef|ifndef|if|else|elif|endif|undef)\b\s*(.*)\Z")
_KEY = re.compile(
    r"(?P<key>[Ll]system|[Dd]erivation length|[Aa]xiom|[Ii]gnore|[Cc]onsider|maximum depth|[Dd]efine|homomorphism"
    r"|decomposition|production|[Ee]ndlsystem|[Ss]tart|[Ss]tartEach|[Ee]nd|[Ee]ndEach|seed)\b\s*:?"
)


def _strip_comments(text: str) -> str:
    """``/* ... */`` and ``// ...`` removed, line breaks kept (so line numbers stay the file's)."""
    out = []
    i = 0
    while i < len(text):
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            end = len(text) if end < 0 else end + 2
            out.append(re.sub(r"[^\n]", " ", text[i:end]))
            i = end
        elif text.startswith("//", i):
            end = text.find("\n", i)
            end = len(text) if end < 0 else end
            out.append(" " * (end - i))
            i = end
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


class _Reader:
    def __init__(self, text: str, source: str):
        self.text = text
        self.source = source
        self.defines: dict[str, float] = {}
        self.macros: set[str] = set()  # names #define'd (with or without a value), for #ifdef
        self.text_macros: dict[str, Macro] = {}  # the C preprocessor's text macros (lsystem.dialects.macros)
        self.included = 0
        self.lines: list[tuple[str, int]] = []  # (text, line of the main file)

    def error(self, line: int, what: str, col: int | None = 1) -> GrammarError:
        return fail(what, self.source, line, col)

    # ------------------------------------------------------------ the preprocessor
    def preprocess(self, text: str, folder: Path | None, at: int | None):
        active = [True]
        for k, raw in enumerate(_strip_comments(text).split("\n")):
            number = at if at is not None else k + 1
            line = raw.strip()
            m = _DIRECTIVE.match(line)
            if m:
                word, rest = m.group(1), m.group(2).strip()
                if word in ("ifdef", "ifndef"):
                    active.append(active[-1] and ((rest in self.macros) == (word == "ifdef")))
                elif word == "if":
                    active.append(active[-1] and self.constant(self.expanded(rest, number), number) != 0)
                elif word in ("else", "elif"):
                    if len(active) < 2:
                        raise self.error(number, f"#{word} without #if")
                    if word == "elif":
                        raise self.error(number, "#elif is not supported; nest #if ... #else ... #endif")
                    active[-1] = active[-2] and not active[-1]
                elif word == "endif":
                    if len(active) < 2:
                        raise self.error(number, "#endif without #if")
                    active.pop()
                elif not active[-1]:
                    continue
                elif word == "define":
                    self.define(rest, number)
                elif word == "undef":
                    self.macros.discard(rest)
                    self.defines.pop(rest, None)
                    self.text_macros.pop(rest, None)
                elif word == "include":
                    self.include(rest, folder, number)
                continue
            if active[-1] and line:
                self.lines.append((self.expanded(raw.rstrip(), number), number))
        if len(active) != 1:
            raise self.error(at or 1, "#if or #ifdef without #endif")

    def constant(self, text: str, line: int) -> float:
        try:
            return float(parse_expression(text, defines=self.defines, syntax=_SYNTAX).evaluate({})[0])
        except (ExprSyntaxError, ArithmeticError) as exc:
            raise self.error(line, f"{clip(text, 40)!r}: {exc}") from None

    def expanded(self, text: str, line: int) -> str:
        """``text`` with the text macros replaced (the C preprocessor's part: :mod:`.macros`)."""
        if not self.text_macros:
            return text
        try:
            return expand(text, self.text_macros)
        except MacroError as exc:
            raise self.error(line, str(exc)) from None

    def define(self, rest: str, line: int):
        """``#define``: a number is a constant of the rules (``defines``); other text, a macro (as C's)."""
        try:
            macro = parse_definition(rest)
        except MacroError as exc:
            raise self.error(line, f"#define {clip(rest, 40)!r}: {exc}") from None
        name, value = macro.name, macro.body
        self.macros.add(name)
        self.defines.pop(name, None)
        self.text_macros.pop(name, None)
        if macro.parameters is None and value:
            value = self.expanded(value, line)
            try:
                self.defines[name] = float(
                    parse_expression(value, defines=self.defines, syntax=_SYNTAX).evaluate({})[0]
                )
                return
            except (ExprSyntaxError, ArithmeticError):
                pass  # not a constant: text put where the name stands, as the C preprocessor does
        if value or macro.parameters is not None:
            self.text_macros[name] = macro

    def include(self, rest: str, folder: Path | None, line: int):
        m = re.match(r"""["<]([^">]+)[">]\Z""", rest)
        if m is None:
            raise self.error(line, f"#include {clip(rest, 40)}: expected a file name in quotes")
        name = m.group(1)
        if folder is None:
            raise self.error(line, f"#include {name!r}: the grammar is not a file, so it has no folder to include from")
        if Path(name).is_absolute() or ".." in Path(name).parts:
            raise self.error(line, f"#include {name!r}: only files in the grammar's own folder are included")
        self.included += 1
        if self.included > MAX_INCLUDES:
            raise self.error(
                line, f"more than {MAX_INCLUDES} #include files (lsys3d.lsystem.dialects.cpfg.MAX_INCLUDES)"
            )
        try:
            text = read_text(inside(folder, name, "#include file"))
        except FileRefused as exc:
            raise self.error(line, f"#include {name!r}: {exc.reason}") from None
        except GrammarError as exc:
            raise self.error(line, f"#include {name!r}: {exc.reason}") from None
        self.preprocess(text, folder, line)

    # ------------------------------------------------------------ the L-system
    def read(self, **overrides) -> Grammar:
        path = Path(self.source)
        folder = path.parent if self.source and not self.source.startswith("<") and path.is_file() else None
        view = vlab.read_view(path) if folder is not None else vlab.View()
        for name, number in view.names.items():  # a function set's names: cpfg's -DNAME=NUMBER
            self.macros.add(name)
            self.defines[name] = float(number)
        self.preprocess(self.text, folder, None)
        fields: dict = {"dialect": "cpfg"}
        where: dict = {}
        section = "rules"
        groups = {"rules": [], "homomorphism": [], "decomposition": []}
        depth = None
        systems, label = 0, 0
        lines = self.joined()
        # cpfg's sub-L-systems: every L-system's rules go into the same lists, each after an 'lsystem: N' line
        # (the Grammar's rule lists read them so: lsys3d.lsystem.sequences); only the first gives the axiom
        several = sum(1 for text, _ in lines if (k := _KEY.match(text.strip())) and k.group("key") in _SYSTEM) > 1
        head = None  # a predecessor and condition whose arrow is on the next line
        last_key = None
        for index, (text, number) in enumerate(lines):
            code = text.strip()
            col = len(text) - len(text.lstrip()) + 1
            if head is not None:
                code, number, col = f"{head[0]} {code}", head[1], head[2]
                head = None
            m = _KEY.match(code)
            if m and not _is_rule(code):
                key = last_key = m.group("key")
                rest = code[m.end() :].strip()
                rest_col = col + len(code) - len(code[m.end() :].lstrip())
                key = _KEY_NAMES.get(key, key)
                if systems > 1 and key in _MAIN_ONLY:
                    raise self.error(number, f"{key}: in a sub-L-system (lsystem: {label}) is not supported")
                if key == "Lsystem":
                    systems += 1
                    if several:
                        label = self.whole(rest, number, "the L-system's number")
                        for name, group in groups.items():
                            where[(name, len(group))] = line_where(number, col)
                            group.append(f"lsystem: {label}")
                    section = "rules"
                elif systems > 1 and key in ("derivation length", "Axiom", "axiom"):
                    continue  # cpfg derives from the main L-system's axiom, its length (lsys_input.y)
                elif key == "derivation length":
                    fields["iterations"] = self.whole(rest, number, key)
                elif key in ("Axiom", "axiom"):
                    fields["axiom"] = rest
                    where["axiom"] = line_where(number, rest_col)
                elif key in ("ignore", "consider"):
                    fields[key] = (fields.get(key, "") + " " + rest).strip()
                    where[key] = line_where(number, rest_col)
                elif key == "maximum depth":
                    depth = self.whole(rest, number, key)
                    fields["decomposition_depth" if section == "decomposition" else "homomorphism_depth"] = depth
                elif key in ("homomorphism", "decomposition", "production"):
                    section = "rules" if key == "production" else key
                elif key == "define":
                    self.define_block(rest, number)
                elif key == "endlsystem":
                    section = None
                elif key == "seed":
                    fields["seed"] = self.whole(rest, number, "seed")
                else:  # Start:, StartEach:, EndEach:, End: C-like statements (lsys3d.lsystem.blocks)
                    self.block(key, rest, number, rest_col, fields, where)
                continue
            if section is None:
                raise self.error(number, f"{clip(code, 40)!r} after endlsystem")
            group = groups[section]
            if not _is_rule(code):
                # cpfg reads a production across lines: its arrow may open the next line, and a
                # successor may go on over the lines that follow (the vlab course's files do both)
                following = lines[index + 1][0].strip() if index + 1 < len(lines) else ""
                if re.match(r"-?->", following):
                    head = (code, number, col)
                    continue
                if group and not _KEY.match(code):
                    group[-1] = f"{group[-1]} {code}"
                    continue
                axiom_goes_on = last_key in ("Axiom", "axiom") and text[:1].isspace()  # indented, as vlab's Tropisms
                if axiom_goes_on and not any(groups.values()) and not _KEY.match(code):
                    fields["axiom"] = f"{fields['axiom']} {code}"
                    continue
                if re.fullmatch(r"ring\s+lsystem\s*:?", code, re.IGNORECASE):  # the ends are neighbours
                    fields["ring"] = True
                    continue
                raise self.error(number, f"expected a production ('predecessor --> successor'), not {clip(code, 40)!r}")
            where[(section, len(group))] = line_where(number, col)
            group.append(code)
        if "axiom" not in fields:
            raise fail("no axiom: (the start string)", self.source, 1, 1)
        if depth is not None:
            fields.setdefault("decomposition_depth", depth)
            fields.setdefault("homomorphism_depth", depth)
        fields.update(groups)
        fields["defines"] = dict(self.defines)
        if view.functions or view.curves:
            fields["splines"] = to_table(view.functions, view.curves)
        if view.turtle():
            fields["turtle"] = view.turtle()
        if folder is not None:  # the view file's surfaces and textures (@Tx)
            fields.update(vlab_look.read_look(path).fields())
        if folder is not None and "angle" not in overrides:
            angle, missing = _view_angle(path)
            if angle is not None:
                fields["angle"] = angle
            else:  # cpfg's own default would turn by 90 degrees without a word: say so
                log.warning(
                    "warning: %s: %s, so turns use cpfg's default angle, %g degrees (write 'angle increment: "
                    "DEGREES' in %s, as cpfg's view file does)",
                    self.source,
                    missing,
                    DIALECT.angle,
                    path.with_suffix(".v").name,
                )
        fields.update(overrides)
        return Grammar(**fields, source=self.source, text=self.text, _where=where)

    def joined(self) -> list[tuple[str, int]]:
        """Lines joined while a parenthesis or a brace is open, or a line ends with a backslash."""
        out = []
        pending, start, depth = [], 0, 0
        for text, number in self.lines:
            if not pending:
                start = number
            piece = text[:-1] if text.rstrip().endswith("\\") else text
            pending.append(piece if not pending else piece.strip())
            depth += text.count("(") + text.count("{") - text.count(")") - text.count("}")
            if depth <= 0 and not text.rstrip().endswith("\\"):
                out.append((" ".join(pending), start))
                pending, depth = [], 0
        if pending:
            out.append((" ".join(pending), start))
        return out

    def block(self, key: str, rest: str, line: int, col: int, fields: dict, where: dict):
        """``Start: { n = 0; }`` and the like: the statements, run by :mod:`lsys3d.lsystem.blocks`."""
        name = _BLOCKS[key]
        blocks = fields.setdefault("blocks", {})
        if name in blocks:
            raise self.error(line, f"a second {key}: block")
        if not rest.startswith("{") or not rest.rstrip().rstrip(";").endswith("}"):
            raise self.error(line, f"{key}: expects a block of statements in braces, not {clip(rest, 40)!r}", col)
        blocks[name] = rest
        where.setdefault("blocks", {})[name] = line_where(line, col)
        if name == "start":  # srand(seed) in Start: the seed of the whole derivation (a constant), as in cpfg
            m = re.search(r"\bsrand\s*\(([^;{}]*)\)\s*;", rest)
            if m:
                fields["seed"] = int(abs(self.constant(m.group(1), line))) & 0xFFFFFFFF

    def whole(self, text: str, line: int, what: str) -> int:
        value = self.constant(text.rstrip(";").strip(), line)
        if not (value >= 0 and float(value).is_integer()):
            raise self.error(line, f"{what} must be a whole number >= 0, not {value:g}")
        return int(value)

    def define_block(self, rest: str, line: int):
        """``define: { a = 1; b = a * 2; }``: named constants."""
        body = rest.strip().strip("{}").strip()
        for statement in body.split(";"):
            if statement.strip():
                if re.match(r"\s*array\b", statement):
                    self.array(statement.strip(), line)
                    continue
                name, sep, value = statement.partition("=")
                if not sep or not re.fullmatch(r"\s*[A-Za-z_]\w*\s*", name):
                    raise self.error(line, f"define: {clip(statement.strip(), 40)!r}: expected 'name = value'")
                self.defines[name.strip()] = self.constant(value, line)

    def array(self, statement: str, line: int):
        """``array len[M][N] = {1, 2, ...};`` in ``define:``: a constant array (C's: missing values are 0)."""
        m = re.fullmatch(r"array\s+([A-Za-z_]\w*)\s*((?:\[[^\[\]]*\]\s*)+)(?:=\s*(.*))?", statement, re.DOTALL)
        if m is None:
            raise self.error(line, f"define: {clip(statement, 40)!r}: expected 'array name[size] = {{values}}'")
        name = m.group(1)
        shape = [self.whole(d, line, f"the size of array {name!r}") for d in re.findall(r"\[([^\]]*)\]", m.group(2))]
        size = math.prod(shape)
        if not 0 < size <= MAX_ARRAY:
            raise self.error(line, f"define: array {name!r} of {size} elements (1 to {MAX_ARRAY}: expr.MAX_ARRAY)")
        text = (m.group(3) or "").strip()
        if text and not (text.startswith("{") and text.endswith("}")):
            raise self.error(line, f"define: array {name!r}: its values go in braces, not {clip(text, 30)!r}")
        pieces = [p for p in re.sub(r"[{}]", " ", text).split(",")] if text else []
        if pieces and not pieces[-1].strip():  # {1, 2, 3,}: C allows the last comma
            pieces.pop()
        if len(pieces) > size:
            raise self.error(line, f"define: array {name!r} has {size} elements, not {len(pieces)} values")
        values = [self.constant(p, line) for p in pieces] + [0.0] * (size - len(pieces))
        self.defines[name] = constant_array(np.reshape(values, shape), f"array {name!r}")


_KEY_NAMES = {
    "Derivation length": "derivation length",
    "lsystem": "Lsystem",
    "Endlsystem": "endlsystem",
    "Ignore": "ignore",
    "Consider": "consider",
    "Define": "define",
    "start": "Start",
    "startEach": "StartEach",
    "end": "End",
    "endEach": "EndEach",
}
"""Spellings cpfg accepts besides the manual's (vlab's models write ``lsystem:`` and ``Endlsystem``)."""


_SYSTEM = frozenset({"Lsystem", "lsystem"})
_MAIN_ONLY = frozenset({"ignore", "consider", "Start", "StartEach", "EndEach", "End", "seed", "maximum depth"})
"""What a sub-L-system may not set: lsys3d keeps one of each for the whole grammar."""

_BLOCKS = {"Start": "start", "StartEach": "start_each", "EndEach": "end_each", "End": "end"}


def _is_rule(code: str) -> bool:
    return "-->" in code or re.search(r"(?<!-)->", code) is not None


def _view_angle(path: Path) -> tuple[float | None, str]:
    """The angle of the view file beside ``path`` (``plant.v``: ``angle increment: 30``, ``angle factor: 12``).

    Returns the angle, or None and why there is none (no view file, an unreadable one, no angle in it).  A view
    file that leads out of the grammar's folder (a symlink) is not read (:func:`lsys3d.external.inside`).
    """
    view = path.with_suffix(".v")
    if not view.is_file():
        return None, f"no view file {view.name!r} beside it"
    try:
        text = read_text(inside(path.parent, view.name, "view file"))
    except FileRefused as exc:
        return None, f"its view file {view.name!r} cannot be read ({exc.reason})"
    except GrammarError as exc:
        return None, f"its view file {view.name!r} cannot be read ({exc.reason})"
    m = re.search(r"^\s*angle increment\s*:\s*([-+0-9.eE]+)", text, re.MULTILINE)
    if m:
        return float(m.group(1)), ""
    m = re.search(r"^\s*angle factor\s*:\s*([-+0-9.eE]+)", text, re.MULTILINE)
    if m and float(m.group(1)) != 0:
        return 360.0 / float(m.group(1)), ""
    return None, f"its view file {view.name!r} gives no 'angle increment:' (nor 'angle factor:')"


def read(text: str, source: str = "<string>", **overrides) -> Grammar:
    """Read a cpfg L-system file's text into a :class:`~lsys3d.lsystem.grammar.Grammar` (dialect ``cpfg``).

    ``#include`` reads files beside ``source`` (at most :data:`MAX_INCLUDES`); the angle comes from the
    view file beside it (``plant.v``); without one (or without an angle in it) a warning names cpfg's
    default angle, 90 degrees, which the turns then use.

    >>> g = read("#define N 3\\nLsystem: 1\\nderivation length: N\\naxiom: A\\nA --> F[+A][-A]\\nendlsystem\\n", "p.l")
    >>> g.dialect, g.iterations, g.rules
    ('cpfg', 3, ('A --> F[+A][-A]',))
    """
    return _Reader(text, source).read(**overrides)
