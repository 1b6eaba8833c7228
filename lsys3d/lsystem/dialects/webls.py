"""The ``.ls`` files of the web L-system tools (the "ABOP-like" form with settings lines), read as cpfg.

Browser and Processing L-system tools that follow *The Algorithmic Beauty of Plants* and cpfg (for
example L-System Explorer, github.com/Lowclouds/lsystem, whose quick reference documents the form) write:

.. code-block:: text

    /* a comment, over lines */
    #define R 1.456
    n=5; delta=22.5; stemsize=0.1     settings: any 'name = expression', several on a line with ';'
    stemsize: 0.1                     or 'name: value'
    derivation length: 4              (or dlength:); wins over n; 1 when neither is given
    axiom: F
    p1: F -> F[+F]F[-F]F               labels, '->' or '-->', contexts, ': condition', '*' for nothing
    ignore: +-F                        (consider: too)
    Start: {i = 0;}                    cpfg's blocks (StartEach:, EndEach:, End:), see lsys3d.lsystem.blocks

The settings are variables the rules may read (``&(delta/2)``); ``delta`` (or ``angle``) is the angle,
``stemsize`` the branch diameter, ``step`` the step length, ``n`` (or ``iterations``) the derivation length
when no ``derivation length:`` line gives it; ``view`` (the camera) is read and left.  A setting that is
no number (a JavaScript array or object, a function) is refused in one line.  The modules are cpfg's
(the tools copy its turtle), so the grammar's dialect is ``cpfg``, with one difference L-System Explorer's
turtle makes: every ``F`` and ``G`` draws, inside a polygon too (``[turtle] polygon_edges = true``).

:func:`recognise` tells this form by content: settings written with ``;`` or that the older ABOP-like
form does not write (``stemsize = 0.1``), or a ``/* ... */`` comment, next to an ``axiom:`` line.
"""

from __future__ import annotations

import re

from ...errors import clip
from ..expr import ExprSyntaxError, parse_expression
from ..grammar import Grammar
from .common import fail, line_where

__all__ = ["read", "recognise"]

_SETTING = re.compile(r"([A-Za-z_]\w*)\s*=(?!=)\s*(.*)\Z", re.DOTALL)
# a setting alone on its line, but for those the older ABOP-like form writes too (n=, delta=, angle=, iterations=)
_ONE_SETTING_LINE = re.compile(
    r"^\s*(?!(?:n|delta|angle|iterations)\s*=)[A-Za-z_]\w*\s*=(?!=)(?!\s*[-+\d.]+\s*,\s*\w+\s*=).*$", re.MULTILINE
)
_SEMICOLONS = re.compile(r"^\s*[A-Za-z_]\w*\s*=(?!=)[^;\n]*;", re.MULTILINE)
_COLON_SETTING = re.compile(r"^\s*(?:stemsize|delta|step|lsystem)\s*:", re.MULTILINE | re.IGNORECASE)
_AXIOM = re.compile(r"^\s*axiom\s*:", re.MULTILINE | re.IGNORECASE)
_KEY = re.compile(
    r"(?P<key>derivation length|dlength|axiom|ignore|consider|lsystem|maximum depth|max depth|homomorphism"
    r"|decomposition|production|endlsystem|start|starteach|endeach|end)\b\s*:?\s*(?P<rest>.*)\Z",
    re.IGNORECASE | re.DOTALL,
)
_BLOCKS = {"start": "start", "starteach": "start_each", "endeach": "end_each", "end": "end"}
_OPENS_BLOCK = re.compile(r"(start|starteach|endeach|end)\s*:", re.IGNORECASE)
_LABEL = re.compile(r"\s*p\d+\s*:\s*")
FORMS = "the web tools' ABOP-like form (n=..; delta=..; stemsize=.., axiom:, p1: A -> B)"


def recognise(text: str) -> bool:
    """Whether ``text`` is in this form: an ``axiom:`` line and settings the older ABOP-like form does not
    write (several on a line with ';', ``stemsize = 0.1``, ``stemsize: 0.1``, a variable of the file's
    own) or ``/* */`` comments; a file whose settings are only ``n=``, ``delta=``, ``angle=`` lines (or
    ``n=30,delta=22.5``) is the older form's, read in ``dialect = "abop"`` as before."""
    if not _AXIOM.search(text):
        return False
    return bool(
        _ONE_SETTING_LINE.search(text) or _SEMICOLONS.search(text) or "/*" in text or _COLON_SETTING.search(text)
    )


def _strip_block_comments(text: str) -> str:
    """``/* ... */`` removed, line breaks kept; ``//`` stays (two roll modules in these tools)."""
    return re.sub(r"/\*.*?(\*/|\Z)", lambda m: re.sub(r"[^\n]", " ", m.group()), text, flags=re.DOTALL)


def _lines(text: str) -> list[tuple[str, int, int]]:
    """``(code, line, column)`` of the lines that hold something; a block (``Start: {``...) joined over lines."""
    out = []
    pending: list[str] = []
    start = (0, 0)
    depth = 0
    for k, raw in enumerate(_strip_block_comments(text).split("\n")):
        code = raw.rstrip()
        if not code.strip() and not pending:
            continue
        if not pending:
            start = (k + 1, len(code) - len(code.lstrip()) + 1)
        pending.append(code.strip())
        if _OPENS_BLOCK.match(pending[0]):  # braces of polygons elsewhere ('{.].') never join lines
            depth += code.count("{") - code.count("}")
        if depth <= 0:
            out.append((" ".join(p for p in pending if p), *start))
            pending, depth = [], 0
    if pending:
        out.append((" ".join(pending), *start))
    return out


def read(text: str, source: str = "<string>", **overrides) -> Grammar:
    """Read a web tool's ``.ls`` file (see the module) into a cpfg :class:`~lsys3d.lsystem.grammar.Grammar`.

    >>> g = read("n=3; delta=25.7; stemsize=0.1\\naxiom: F\\np1: F -> F[+F]F[-F]F\\n", "bush.ls")
    >>> g.dialect, g.iterations, g.angle, g.rules, g.turtle["width"]
    ('cpfg', 3, 25.7, ('F -> F[+F]F[-F]F',), 0.1)
    """
    fields: dict = {"dialect": "cpfg"}
    where: dict = {}
    variables: dict[str, str] = {}
    values: dict[str, float] = {}
    groups: dict[str, list[str]] = {"rules": [], "homomorphism": [], "decomposition": []}
    section = "rules"
    systems = 0
    dlength = None
    skipped: list[tuple[str, int]] = []  # unknown lines before 'axiom:', which L-System Explorer passes over
    for code, number, col in _lines(text):
        if code.startswith("#"):
            m = re.match(r"#\s*define\s+([A-Za-z_]\w*)\s+(.+)\Z", code)
            if m:
                variables[m.group(1)] = m.group(2).strip()
                values[m.group(1)] = _number(m.group(2), values, source, number, col, m.group(1))
            elif re.match(r"#\s*(include|if|ifdef|ifndef)\b", code):
                raise fail(f"{clip(code, 30)!r}: the preprocessor's {code.split()[0]} is not supported here",
                           source, number, col)  # fmt: skip
            continue  # '#' alone starts a comment line in these files
        if "->" in code or "→" in code:
            label = _LABEL.match(code)
            body = code[label.end() :] if label else code
            where[(section, len(groups[section]))] = line_where(number, col + (label.end() if label else 0))
            groups[section].append(body)
            continue
        m = _KEY.match(code)
        if m:
            key, rest = m.group("key").lower(), m.group("rest").strip()
            rest_col = col + m.start("rest")
            if key in ("derivation length", "dlength"):
                dlength = _whole(rest, values, source, number, rest_col, "derivation length")
            elif key == "axiom":
                fields["axiom"] = rest
                where["axiom"] = line_where(number, rest_col)
            elif key in ("ignore", "consider"):
                fields[key] = (fields.get(key, "") + " " + rest).strip()
                where[key] = line_where(number, rest_col)
            elif key == "lsystem":
                systems += 1
                if systems > 1:
                    raise fail("a second 'lsystem:' (sub-L-systems) is not supported", source, number, col)
            elif key in ("maximum depth", "max depth"):
                depth = _whole(rest, values, source, number, rest_col, "maximum depth")
                fields["decomposition_depth" if section == "decomposition" else "homomorphism_depth"] = depth
            elif key in ("homomorphism", "decomposition", "production"):
                section = "rules" if key == "production" else key
            elif key == "endlsystem":
                section = "rules"
            else:
                blocks = fields.setdefault("blocks", {})
                if not rest.startswith("{"):
                    raise fail(f"{m.group('key')}: expects a block of statements in braces", source, number, rest_col)
                blocks[_BLOCKS[key]] = rest
                where.setdefault("blocks", {})[_BLOCKS[key]] = line_where(number, rest_col)
            continue
        if _SETTING.match(code.split(";", 1)[0].strip()):
            _settings(code, number, col, variables, values, fields, source)
            continue
        m = re.match(r"([A-Za-z_]\w*)\s*:\s*(\S.*)\Z", code)
        if m:  # 'stemsize: 0.1': a variable too (L-System Explorer reads 'name: value' lines as globals)
            _settings(f"{m.group(1)} = {m.group(2)}", number, col, variables, values, fields, source)
            continue
        if "axiom" not in fields:  # L-System Explorer's parser logs 'unrecognized statement' and goes on
            skipped.append((code, number))
            continue
        raise fail(f"unknown line {clip(code, 40)!r} (read as {FORMS}: settings, axiom:, derivation length:, "
                   "p1: A -> B, #define, ignore:, Start: {...})", source, number, col)  # fmt: skip
    if "axiom" not in fields:
        raise fail("no 'axiom:' line", source, 1, 1)
    if dlength is not None:
        fields["iterations"] = dlength
    else:  # n, or iterations as the older ABOP-like form also writes it
        for key in ("n", "iterations"):
            if key in values:
                fields["iterations"] = _whole(variables[key], values, source, 1, 1, key)
                break
    for key in ("delta", "angle"):  # angle=25.7: the older form's other name of delta
        if key in values:
            fields["angle"] = values[key]
            break
    # L-System Explorer's turtle draws every F and G, in a polygon too (interpret.js: turtle.forward -> draw,
    # turtle3d.js: drawImmediate whenever the pen is down); its polygons take F's ends and '.' as vertices
    turtle: dict = {"polygon_edges": True}
    if "stemsize" in values:
        turtle["width"] = values["stemsize"]
    if "step" in values:
        turtle["step"] = values["step"]
    fields["turtle"] = turtle
    fields["defines"] = variables
    fields.update(groups)
    repairs = []
    if skipped:
        lines = ", ".join(repr(clip(code, 20)) for code, _ in skipped)
        opener = " (a '/*' split over two lines?)" if any(code.strip() == "/" for code, _ in skipped) else ""
        repairs.append(
            f"{source}:{skipped[0][1]}: lines that are no statement, skipped as L-System Explorer's parser skips "
            f"them before 'axiom:': {lines}{opener}"
        )
    if "axiom" in fields:
        repair = _close_branches(fields, groups, source, where)
        repairs += [repair] if repair else []
    if repairs:
        fields["repairs"] = tuple(repairs)
    fields.update(overrides)
    return Grammar(**fields, source=source, text=text, _where=where)


def _close_branches(fields: dict, groups: dict, source: str, where: dict) -> str | None:
    """An axiom that opens branches it never closes gets its ``]`` at the end, and the note that says so.

    L-System Explorer's turtle leaves such a branch open: the string goes on drawing in it to the end,
    as with the ``]`` at the end.  Only without contexts, whose walks the added ``]`` could change.
    """
    axiom, depth, level = fields["axiom"], 0, 0
    for ch in axiom:
        level += {"(": 1, ")": -1}.get(ch, 0)
        if level == 0 and ch in "[]":
            depth += 1 if ch == "[" else -1
            if depth < 0:
                return None  # a ']' too many: the grammar refuses it
    contexts = any(re.search(r"[<>]", rule.split("->")[0]) for group in groups.values() for rule in group)
    if depth <= 0 or contexts:
        return None
    fields["axiom"] = axiom + "]" * depth
    line, col = where["axiom"](0)
    return (
        f"{source}:{line}:{col}: the axiom opens {depth} branch{'es' if depth > 1 else ''} with '[' and closes "
        f"none: read with {']' * depth} at its end, as L-System Explorer's turtle leaves them open to the end"
    )


def _settings(code, number, col, variables, values, fields, source):
    """``n=5; delta=20; stemsize=0.1``: each a variable the rules may read (``view``, the camera, is left)."""
    offset = 0
    for piece in code.split(";"):
        stripped = piece.strip()
        at = col + offset + len(piece) - len(piece.lstrip())
        offset += len(piece) + 1
        if not stripped:
            continue
        m = _SETTING.match(stripped)
        if m is None:
            raise fail(f"expected 'name = value', not {clip(stripped, 30)!r}", source, number, at)
        name, value = m.group(1), m.group(2).strip()
        if name == "view":  # the camera of the tool's viewer
            continue
        if re.match(r"[\[{'\"]|function\b", value):
            raise fail(f"setting {name!r} holds a JavaScript value ({clip(value, 20)}), not a number; lsys3d reads "
                       "numbers only", source, number, at)  # fmt: skip
        values[name] = _number(value, values, source, number, at, name)
        variables[name] = value


def _number(text: str, values: dict, source: str, line: int, col: int, name: str) -> float:
    try:
        return float(parse_expression(text.strip(), defines=values).evaluate({})[0])
    except (ExprSyntaxError, ArithmeticError) as exc:
        raise fail(f"{name} = {clip(text.strip(), 30)}: {exc}", source, line, col) from None


def _whole(text, values, source, line, col, what) -> int:
    value = _number(str(text), values, source, line, col, what)
    if not (value >= 0 and value.is_integer()):
        raise fail(f"{what} must be a whole number >= 0, not {value:g}", source, line, col)
    return int(value)
