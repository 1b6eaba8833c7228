"""Grammar files and rule notation: text -> :class:`Grammar`.

A grammar is a TOML file (see ``docs/grammar.md``)::

    name = "plant"
    axiom = "X"
    iterations = 5
    angle = 20
    rules = [
        "X -> F-[[X]+X]+F[+FX]-X",
        "F -> FF",
    ]

Each rule reads ``[left <] predecessor [> right] [: condition] -> successor [: weight]``;
``=`` may stand for ``->``.  Parameters in predecessors and contexts are formal
names, in successors and the axiom they are expressions (:mod:`lsys3d.expr`).
"""

from __future__ import annotations

import errno
import math
import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from .errors import GrammarError, clip, os_reason
from .expr import CONSTANTS, FUNCTIONS, Expr, ExprSyntaxError, parse_expression
from .modules import ASCII_ALPHABET, ModuleString

__all__ = ["MAX_GRAMMAR_BYTES", "MAX_PARAMETERS", "Grammar", "PatternModule", "Production", "SuccessorModule"]

MAX_GRAMMAR_BYTES = 1 << 20
"""Largest grammar file read, in bytes."""
MAX_PARAMETERS = 32
"""Most parameters one module may carry."""

_RESERVED = set("(),:=")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z_0-9]*\Z")
_SURROGATE = re.compile("[\ud800-\udfff]")
_KEYS = {
    "name",
    "description",
    "axiom",
    "rules",
    "iterations",
    "angle",
    "seed",
    "ignore",
    "defines",
    "turtle",
    "materials",
    "surfaces",
}

# maps an offset in a piece of text to (line, col); line None when unknown
Where = Callable[[int], tuple[int | None, int | None]]


@dataclass(frozen=True)
class PatternModule:
    """A module in a predecessor or context: a symbol and its formal parameter names."""

    symbol: str
    formals: tuple[str, ...] = ()


@dataclass(frozen=True)
class SuccessorModule:
    """A module in a successor or the axiom: a symbol and one expression per parameter."""

    symbol: str
    args: tuple[Expr, ...] = ()
    offset: int = field(default=-1, compare=False)  # where the symbol stands in its text


@dataclass(frozen=True)
class Production:
    """One parsed rule.

    ``left`` and ``right`` are the context patterns (``right`` may hold ``[`` and
    ``]`` modules); ``condition`` is None when the rule always applies; ``weight``
    is None for a rule written without one.
    """

    index: int
    text: str
    location: str
    left: tuple[PatternModule, ...]
    predecessor: PatternModule
    right: tuple[PatternModule, ...]
    condition: Expr | None
    successor: tuple[SuccessorModule, ...]
    weight: float | None

    @property
    def context_sensitive(self) -> bool:
        return bool(self.left or self.right)

    @property
    def formals(self) -> tuple[str, ...]:
        names = [n for m in self.left for n in m.formals]
        names += self.predecessor.formals
        names += [n for m in self.right for n in m.formals]
        return tuple(names)

    def pool_key(self):
        """Rules with equal keys are stochastic alternatives of one another."""
        cond = self.condition.text if self.condition is not None else None
        return (self.left, self.predecessor.symbol, len(self.predecessor.formals), self.right, cond)


@dataclass(frozen=True, eq=False)
class Grammar:
    """An L-system: axiom, productions and the settings read with them.

    Build it from Python with strings, exactly as a grammar file would hold them,
    or read one with :meth:`from_text` / :meth:`from_file`.

    Examples
    --------
    >>> g = Grammar(axiom="F", rules=["F -> F-F++F-F"], angle=60)
    >>> len(g.productions)
    1
    """

    axiom: str
    rules: tuple[str, ...] = ()
    name: str = ""
    description: str = ""
    iterations: int = 1
    angle: float = 90.0
    seed: int = 0
    ignore: str = ""
    defines: Mapping[str, float] = field(default_factory=dict)
    turtle: Mapping[str, object] = field(default_factory=dict)
    materials: Mapping[str, object] = field(default_factory=dict)
    surfaces: Mapping[str, object] = field(default_factory=dict)
    source: str = "<grammar>"
    text: str | None = None
    # parsed, filled in by __post_init__
    productions: tuple[Production, ...] = field(init=False, repr=False)
    axiom_modules: ModuleString = field(init=False, repr=False)
    alphabet: str = field(init=False, repr=False)
    _where: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        if isinstance(self.rules, str):
            raise GrammarError("'rules' must be a list of rule strings, not one string", self.source)
        set_ = object.__setattr__
        for key in ("defines", "turtle", "materials", "surfaces"):
            if not isinstance(getattr(self, key), Mapping):
                raise self._key_error(key, f"must be a table, not {type(getattr(self, key)).__name__}")
        if not isinstance(self.rules, (list, tuple)):
            raise self._key_error("rules", f"must be a list of rule strings, not {type(self.rules).__name__}")
        set_(self, "rules", tuple(self.rules))
        if not isinstance(self.ignore, str):
            if not isinstance(self.ignore, (list, tuple)) or not all(isinstance(c, str) for c in self.ignore):
                raise self._key_error("ignore", f"must be a string of symbols, not {clip(repr(self.ignore))}")
            set_(self, "ignore", "".join(self.ignore))
        set_(
            self,
            "defines",
            MappingProxyType(_check_defines(dict(self.defines), self.source, self._where.get("defines"))),
        )
        set_(self, "turtle", MappingProxyType(dict(self.turtle)))
        set_(self, "materials", MappingProxyType(dict(self.materials)))
        set_(self, "surfaces", MappingProxyType(dict(self.surfaces)))
        self._check_scalars()
        where_axiom = self._where.get("axiom") or _api_where("axiom")
        if not self.axiom.strip():
            raise GrammarError("the axiom is empty", *_loc(self.source, where_axiom, 0))
        alphabet = _Alphabet()
        axiom = _parse_modules(self.axiom, "axiom", (), self.defines, self.source, where_axiom, alphabet)
        productions = []
        wheres = []
        for i, rule in enumerate(self.rules):
            if not isinstance(rule, str):
                raise GrammarError(f"rule {i + 1} must be a string, not {type(rule).__name__}", self.source)
            where = self._where.get(("rules", i)) or _api_where(f"rules[{i}]")
            productions.append(_parse_rule(i, rule, self.defines, self.source, where, alphabet))
            wheres.append(where)
        _check_arities(productions, wheres, axiom, where_axiom, self.source)
        for ch in self.ignore:
            if not ch.isspace():
                alphabet.code(ch)
        set_(self, "productions", tuple(productions))
        set_(self, "alphabet", alphabet.table())
        set_(self, "axiom_modules", _evaluate_axiom(axiom, alphabet, self.source, where_axiom))

    def _key_error(self, key: str, what: str) -> GrammarError:
        """``file:line:1: 'key' what``, with the line of the key when the grammar came from a file."""
        where = self._where.get(("key", key))
        line = where(0)[0] if where else None
        return GrammarError(f"'{key}' {what}", self.source, line, 1 if line else None)

    def _check_scalars(self):
        bad = self._key_error
        it = self.iterations
        if isinstance(it, bool) or not isinstance(it, int) or it < 0:
            raise bad("iterations", f"must be a whole number >= 0, not {clip(repr(it))}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise bad("seed", f"must be a whole number >= 0, not {clip(repr(self.seed))}")
        if not _finite_number(self.angle):
            raise bad("angle", f"must be a number of degrees, not {clip(repr(self.angle))}")
        for key in ("name", "description", "axiom", "ignore"):
            if not isinstance(getattr(self, key), str):
                raise bad(key, f"must be a string, not {type(getattr(self, key)).__name__}")
        for key, text in [(k, getattr(self, k)) for k in ("name", "description", "axiom", "ignore")] + [
            (f"rules[{i}]", r) for i, r in enumerate(self.rules) if isinstance(r, str)
        ]:
            bad_char = _SURROGATE.search(text)
            if bad_char:  # only from Python: TOML text cannot hold one; every file format would refuse it
                raise bad(key, f"is not valid Unicode text (a lone surrogate at character {bad_char.start() + 1})")

    # ---------------------------------------------------------------- readers
    @classmethod
    def from_text(cls, text: str, source: str = "<string>", **overrides) -> Grammar:
        """Read a grammar from TOML text; ``source`` names it in error messages."""
        if len(text.encode("utf-8", "surrogatepass")) > MAX_GRAMMAR_BYTES:
            raise GrammarError(
                f"grammar is larger than {MAX_GRAMMAR_BYTES} bytes (lsys3d.grammar.MAX_GRAMMAR_BYTES)", source
            )
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise _toml_error(exc, source) from None
        except RecursionError:  # tomllib reads nested arrays and tables recursively
            raise GrammarError("TOML syntax error: arrays or tables nested too deeply", source) from None
        unknown = sorted(set(data) - _KEYS)
        if unknown:
            line = _key_line(text, unknown[0])
            raise GrammarError(
                f"unknown key '{clip(unknown[0])}' (known keys: {', '.join(sorted(_KEYS))})",
                source,
                line,
                1 if line else None,
            )
        if "axiom" not in data:
            raise GrammarError("missing 'axiom' (the start string, e.g. axiom = \"F\")", source, 1, 1)
        tables = (("defines", dict), ("turtle", dict), ("materials", dict), ("surfaces", dict))
        for key, kind in (("rules", list), *tables):
            if key in data and not isinstance(data[key], kind):
                line = _key_line(text, key)
                raise GrammarError(
                    f"'{key}' must be a {'list' if kind is list else 'table'}", source, line, 1 if line else None
                )
        where = _locate_strings(text, data)
        fields = dict(data)
        fields.update(overrides)
        return cls(**fields, source=source, text=text, _where=where)

    @classmethod
    def from_file(cls, path, **overrides) -> Grammar:
        """Read a grammar file (TOML)."""
        path = Path(path)
        try:
            if "\0" in str(path):
                raise OSError(errno.EINVAL, "a file name cannot hold a NUL character")
            size = path.stat().st_size
            if size > MAX_GRAMMAR_BYTES:
                raise GrammarError(
                    f"grammar file is {size} bytes, larger than {MAX_GRAMMAR_BYTES} (lsys3d.grammar.MAX_GRAMMAR_BYTES)",
                    str(path),
                )
            with path.open("rb") as f:  # a device or pipe has no size: read no more than the limit
                raw = f.read(MAX_GRAMMAR_BYTES + 1)
            if len(raw) > MAX_GRAMMAR_BYTES:
                raise GrammarError(
                    f"grammar file is larger than {MAX_GRAMMAR_BYTES} bytes (lsys3d.grammar.MAX_GRAMMAR_BYTES)",
                    str(path),
                )
        except FileNotFoundError:
            raise GrammarError("no such grammar file", str(path)) from None
        except OSError as exc:  # a folder, a symlink loop, a name too long, no permission...
            raise GrammarError(f"cannot read grammar file: {os_reason(exc)}", str(path)) from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise GrammarError(f"grammar file is not UTF-8 text (byte {exc.start})", str(path)) from None
        return cls.from_text(text, source=str(path), **overrides)

    def replace(self, **changes) -> Grammar:
        """A copy with some fields changed (e.g. ``iterations``)."""
        fields = {
            k: getattr(self, k)
            for k in (
                "axiom",
                "rules",
                "name",
                "description",
                "iterations",
                "angle",
                "seed",
                "ignore",
                "defines",
                "turtle",
                "materials",
                "surfaces",
                "source",
                "text",
            )
        }
        fields.update(changes)
        return Grammar(**fields, _where=self._where)

    @property
    def parametric(self) -> bool:
        return bool(len(self.axiom_modules.params)) or any(
            p.predecessor.formals or any(m.args for m in p.successor) for p in self.productions
        )


# ------------------------------------------------------------------ alphabet
class _Alphabet:
    def __init__(self):
        self.extra: list[str] = []

    def code(self, ch: str) -> int:
        if ord(ch) < 128:
            return ord(ch)
        if ch not in self.extra:
            if len(self.extra) >= 128:
                raise ValueError("more than 128 distinct non-ASCII symbols")
            self.extra.append(ch)
        return 128 + self.extra.index(ch)

    def table(self) -> str:
        if not self.extra:
            return ASCII_ALPHABET
        return ASCII_ALPHABET[:128] + "".join(self.extra) + "\0" * (128 - len(self.extra))


# ------------------------------------------------------------------ locations
def _api_where(label: str) -> Where:
    """Positions in a string given through the Python API: line 1 of a pseudo-file named ``label``."""

    def where(offset):
        return None, offset + 1

    where.label = label
    return where


def _loc(source: str, where: Where, offset: int):
    line, col = where(offset)
    if line is None:
        label = getattr(where, "label", "<grammar>")
        return (label if source in ("<grammar>", "<string>") else f"{source}:{label}"), 1, col
    return source, line, col


def _error(message: str, source: str, where: Where, offset: int) -> GrammarError:
    return GrammarError(message, *_loc(source, where, offset))


def _toml_error(exc: tomllib.TOMLDecodeError, source: str) -> GrammarError:
    msg = str(exc)
    m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
    if m:
        reason = msg[: m.start()].strip()
        return GrammarError(f"TOML syntax error: {reason}", source, int(m.group(1)), int(m.group(2)))
    m = re.search(r"\(at end of document\)", msg)
    reason = msg[: m.start()].strip() if m else msg
    return GrammarError(f"TOML syntax error: {reason} (at end of file)", source)


def table_key_line(text: str, table: str, key: str) -> int | None:
    """Line of ``key`` inside the TOML table ``[table]`` (or of the table itself), for error positions."""
    start = _key_line(text, table)
    if start is None:
        return None
    lines = text.splitlines()
    pattern = re.compile(rf"^[ \t]*[\"']?{re.escape(key)}[\"']?[ \t]*=")
    for number in range(start + 1, len(lines) + 1):
        line = lines[number - 1]
        if re.match(r"^[ \t]*\[", line):
            break
        if pattern.match(line):
            return number
    return start


def _key_line(text: str, key: str) -> int | None:
    m = re.search(rf"^[ \t]*[\"']?{re.escape(key)}[\"']?[ \t]*=", text, re.MULTILINE)
    if m is None:
        m = re.search(rf"^[ \t]*\[[ \t]*{re.escape(key)}[ \t]*\]", text, re.MULTILINE)
    return text.count("\n", 0, m.start()) + 1 if m else None


_ESCAPES = {"b": "\b", "t": "\t", "n": "\n", "f": "\f", "r": "\r", '"': '"', "\\": "\\", "e": "\x1b"}


def _scan_string(text: str, i: int):
    """Scan the TOML string literal starting at ``text[i]``.

    Returns ``(value, positions, end)`` where ``positions[k]`` is the index in
    ``text`` of the k-th decoded character (plus one entry for the end).
    """
    quote = text[i]
    triple = text.startswith(quote * 3, i)
    delim = quote * 3 if triple else quote
    j = i + len(delim)
    if triple and text.startswith("\n", j):
        j += 1
    elif triple and text.startswith("\r\n", j):
        j += 2
    value, pos = [], []
    while j < len(text):
        if text.startswith(delim, j):
            if triple:  # up to two quotes may end the content
                while text.startswith(delim, j + 1):
                    value.append(quote)
                    pos.append(j)
                    j += 1
            pos.append(j)
            return "".join(value), pos, j + len(delim)
        ch = text[j]
        if ch == "\n" and not triple:
            break
        if quote == '"' and ch == "\\":
            nxt = text[j + 1 : j + 2]
            if nxt in _ESCAPES:
                value.append(_ESCAPES[nxt])
                pos.append(j)
                j += 2
                continue
            if nxt in ("u", "U"):
                n = 4 if nxt == "u" else 8
                try:
                    value.append(chr(int(text[j + 2 : j + 2 + n], 16)))
                except ValueError:
                    break
                pos.append(j)
                j += 2 + n
                continue
            if triple and nxt in " \t\r\n":  # line-ending backslash
                k = j + 1
                while k < len(text) and text[k] in " \t\r\n":
                    k += 1
                j = k
                continue
            break
        value.append(ch)
        pos.append(j)
        j += 1
    return None, None, j


def _string_tokens(text: str):
    """All string literals of a TOML document, in order: ``(value, positions)``."""
    out = []
    i = 0
    n = len(text)
    while i < n:
        ch = text[i]
        if ch == "#":
            k = text.find("\n", i)
            i = n if k < 0 else k
        elif ch in "\"'":
            value, pos, end = _scan_string(text, i)
            if value is not None:
                out.append((value, pos))
            i = max(end, i + 1)
        else:
            i += 1
    return out


def _line_starts(text: str) -> np.ndarray:
    """Offsets at which the lines of ``text`` start."""
    return np.array([0] + [m.end() for m in re.finditer("\n", text)], np.int64)


def _text_where(line_starts: np.ndarray, positions: list[int]) -> Where:
    """Positions in a string literal of the file: ``positions[k]`` is where its k-th character stands."""

    def where(offset: int):
        idx = positions[min(max(offset, 0), len(positions) - 1)]
        line = int(np.searchsorted(line_starts, idx, side="right"))
        return line, idx - int(line_starts[line - 1]) + 1

    return where


def _locate_strings(text: str, data: dict) -> dict:
    """Find where the axiom and each rule string stand in the file, for error positions.

    One pass over the file's string literals; the rules are looked for in order, each after the last one
    found, so the time is linear in the size of the file however many rules there are.
    """
    tokens = _string_tokens(text)
    line_starts = _line_starts(text)
    first = np.array([pos[0] for _, pos in tokens], np.int64)
    token_line = np.searchsorted(line_starts, first, side="right")  # line of each literal's first character
    where: dict = {}
    for key in _KEYS:
        line = _key_line(text, key)
        if line is not None:
            where[("key", key)] = lambda offset, line=line: (line, 1)
    used: set[int] = set()

    def find(value, start: int) -> int | None:
        """The first unused literal from ``start`` on that reads ``value``."""
        for t in range(start, len(tokens)):
            if tokens[t][0] == value and t not in used:
                used.add(t)
                return t
        return None

    def after_line(line: int) -> int:
        return int(np.searchsorted(token_line, line, side="left"))

    axiom = data.get("axiom")
    if isinstance(axiom, str):
        t = find(axiom, after_line(_key_line(text, "axiom") or 1))
        if t is not None:
            where["axiom"] = _text_where(line_starts, tokens[t][1])
    rules = data.get("rules")
    if isinstance(rules, list):
        cursor = after_line(_key_line(text, "rules") or 1)
        for i, rule in enumerate(rules):
            if isinstance(rule, str):
                t = find(rule, cursor)
                if t is None:  # a form the scanner does not follow: the rest keep their list positions
                    break
                where[("rules", i)] = _text_where(line_starts, tokens[t][1])
                cursor = t + 1
    if isinstance(data.get("defines"), dict):
        line = _key_line(text, "defines")
        where["defines"] = (lambda offset, line=line: (line, 1)) if line else None
    return where


# ------------------------------------------------------------------ defines
def _finite_number(value) -> bool:
    """An int or float (not a bool) that is a finite float: TOML integers have no size limit."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)  # converts an int to float: 10**400 overflows
    except OverflowError:
        return False


def _check_defines(defines: dict, source: str, where) -> dict:
    source_where = where or _api_where("defines")
    out = {}
    for name, value in defines.items():
        if not isinstance(name, str) or not _IDENT.match(name):
            raise GrammarError(f"define name {clip(repr(name))} is not a valid name", *_loc(source, source_where, 0))
        if name in FUNCTIONS or name in CONSTANTS or name in ("and", "or", "not"):
            raise GrammarError(f"define name {name!r} is reserved", *_loc(source, source_where, 0))
        if isinstance(value, str):
            try:
                value = float(parse_expression(value, defines=out).evaluate({})[0])
            except (ExprSyntaxError, ArithmeticError) as exc:
                raise GrammarError(f"define {name!r}: {exc}", *_loc(source, source_where, 0)) from None
        if not _finite_number(value):
            raise GrammarError(
                f"define {clip(repr(name))} must be a finite number, not {clip(repr(value))}",
                *_loc(source, source_where, 0),
            )
        out[name] = float(value)
    return out


# ------------------------------------------------------------------ rules
def _top_level(text: str, start: int = 0, stop: int | None = None):
    """Yield (index, char) of characters outside parentheses."""
    depth = 0
    for i in range(start, len(text) if stop is None else stop):
        ch = text[i]
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth = max(depth - 1, 0)
        elif depth == 0:
            yield i, ch


def _find_arrow(rule: str):
    chars = list(_top_level(rule))
    for i, ch in chars:
        if ch == "-" and rule.startswith("->", i):
            return i, 2
    for i, ch in chars:
        if ch == "=":
            prev = rule[i - 1] if i else ""
            nxt = rule[i + 1] if i + 1 < len(rule) else ""
            if prev not in "<>!=" and nxt != "=":
                return i, 1
    return None, 0


def _parse_rule(index, rule, defines, source, where, alphabet) -> Production:
    def err(msg, offset):
        return _error(msg, source, where, offset)

    arrow, width = _find_arrow(rule)
    if arrow is None:
        opened = []
        for i, ch in enumerate(rule):
            if ch == "(":
                opened.append(i)
            elif ch == ")" and opened:
                opened.pop()
        if opened:
            raise err("unclosed '('", opened[-1])
        raise err("malformed rule: expected '->' (or '=') between predecessor and successor", len(rule.rstrip()))
    lhs_end, rhs_start = arrow, arrow + width

    # successor [: weight]
    colons = [i for i, ch in _top_level(rule, rhs_start) if ch == ":"]
    succ_end = colons[-1] if colons else len(rule)
    weight = None
    if colons:
        wtext = rule[succ_end + 1 :]
        if not wtext.strip():
            raise err("empty weight after ':'", succ_end + 1)
        try:
            weight = float(parse_expression(wtext, defines=defines).evaluate({})[0])
        except ExprSyntaxError as exc:
            raise err(f"bad weight: {exc}", succ_end + 1 + exc.offset) from None
        except ArithmeticError as exc:
            raise err(f"bad weight: {exc}", succ_end + 1) from None
        if not weight > 0:
            raise err(f"weight must be positive, got {weight:g}", succ_end + 1 + _lstrip_len(wtext))

    # [left <] pred [> right] [: condition]
    colons = [i for i, ch in _top_level(rule, 0, lhs_end) if ch == ":"]
    ctx_end = colons[0] if colons else lhs_end
    lt = [i for i, ch in _top_level(rule, 0, ctx_end) if ch == "<"]
    gt = [i for i, ch in _top_level(rule, 0, ctx_end) if ch == ">"]
    if len(lt) > 1:
        raise err("more than one '<' in the rule's left side", lt[1])
    if len(gt) > 1:
        raise err("more than one '>' in the rule's left side", gt[1])
    if lt and gt and gt[0] < lt[0]:
        raise err("'>' (right context) must come after '<' (left context)", gt[0])
    pred_start = lt[0] + 1 if lt else 0
    pred_end = gt[0] if gt else ctx_end

    left = _parse_modules(rule, "context", (), defines, source, where, alphabet, 0, lt[0]) if lt else ()
    if any(m.symbol in "[]" for m in left):
        raise err("brackets are not allowed in a left context", rule.index("[") if "[" in rule[: lt[0]] else 0)
    pred = _parse_modules(rule, "predecessor", (), defines, source, where, alphabet, pred_start, pred_end)
    if len(pred) != 1:
        if not pred:
            raise err("missing predecessor before '->'", pred_start + _lstrip_len(rule[pred_start:pred_end]))
        raise err(
            "the predecessor must be one module (use '<' and '>' for context)",
            pred_start + _lstrip_len(rule[pred_start:pred_end]),
        )
    if pred[0].symbol in "[]":
        raise err("a bracket cannot be a predecessor", pred_start + _lstrip_len(rule[pred_start:pred_end]))
    right = _parse_modules(rule, "context", (), defines, source, where, alphabet, gt[0] + 1, ctx_end) if gt else ()
    if gt and not right:
        raise err("empty right context after '>'", gt[0])
    formals: list[str] = []
    for m in (*left, *pred, *right):
        for name in m.formals:
            if name in formals:
                raise err(f"parameter name {name!r} is used twice in the rule", rule.index(name))
            formals.append(name)

    condition = None
    if colons:
        ctext = rule[ctx_end + 1 : lhs_end]
        if not ctext.strip():
            raise err("empty condition after ':'", ctx_end + 1)
        if ctext.strip() != "*":  # ABOP writes '*' for "no condition"
            try:
                condition = parse_expression(ctext, names=formals, defines=defines)
            except ExprSyntaxError as exc:
                raise err(f"bad condition: {exc}", ctx_end + 1 + exc.offset) from None

    successor = _parse_modules(rule, "successor", formals, defines, source, where, alphabet, rhs_start, succ_end)
    return Production(
        index=index,
        text=rule.strip(),
        location="{}:{}:{}".format(*_loc(source, where, _lstrip_len(rule))),
        left=left,
        predecessor=pred[0],
        right=right,
        condition=condition,
        successor=successor,
        weight=weight,
    )


def _lstrip_len(s: str) -> int:
    return len(s) - len(s.lstrip())


def _parse_modules(text, kind, formals, defines, source, where, alphabet, start=0, stop=None):
    """Parse modules in ``text[start:stop]``.

    ``kind`` is ``predecessor``/``context`` (parameters are formal names) or
    ``successor``/``axiom`` (parameters are expressions over ``formals``).
    """
    stop = len(text) if stop is None else stop
    out = []
    stack = []
    i = start
    while i < stop:
        ch = text[i]
        if ch.isspace():
            i += 1
            continue
        if ch in _RESERVED or (kind in ("predecessor", "context") and ch in "<>"):
            hint = ""
            if ch == "(":
                hint = " (parameters must follow a symbol)"
            elif ch == ")":
                hint = " (unbalanced parenthesis)"
            raise _error(f"unexpected {ch!r} in {kind}{hint}", source, where, i)
        try:
            alphabet.code(ch)
        except ValueError as exc:
            raise _error(str(exc), source, where, i) from None
        sym_at = i
        i += 1
        while i < stop and text[i].isspace() and text[i] not in "\n":
            i += 1
        args = ()
        if i < stop and text[i] == "(":
            depth, j = 0, i
            while j < stop:
                if text[j] == "(":
                    depth += 1
                elif text[j] == ")":
                    depth -= 1
                    if depth == 0:
                        break
                j += 1
            if j >= stop:
                raise _error(f"unclosed '(' after {ch!r}", source, where, i)
            args = _parse_args(text, i + 1, j, ch, kind, formals, defines, source, where)
            i = j + 1
        if kind == "predecessor":
            pass  # a bracket predecessor is reported by the caller
        elif ch == "[":
            stack.append(sym_at)
        elif ch == "]":
            if not stack and kind != "context":
                raise _error(f"unbalanced ']' in {kind}: no '[' before it", source, where, sym_at)
            if stack:
                stack.pop()
        if ch in "[]" and args:
            raise _error(f"'{ch}' takes no parameters", source, where, sym_at)
        if kind in ("predecessor", "context"):
            out.append(PatternModule(ch, args))
        else:
            out.append(SuccessorModule(ch, args, sym_at))
    if stack and kind != "context":
        raise _error(f"unbalanced '[' in {kind}: no ']' closes it", source, where, stack[-1])
    if stack:
        raise _error("unbalanced '[' in right context", source, where, stack[-1])
    return tuple(out)


def _parse_args(text, start, stop, symbol, kind, formals, defines, source, where):
    pieces = []
    depth, last = 0, start
    for k in range(start, stop):
        c = text[k]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == "," and depth == 0:
            pieces.append((last, k))
            last = k + 1
    pieces.append((last, stop))
    if len(pieces) > MAX_PARAMETERS:
        raise _error(
            f"module {symbol!r} has {len(pieces)} parameters, more than {MAX_PARAMETERS}", source, where, start
        )
    args = []
    for a, b in pieces:
        piece = text[a:b]
        if not piece.strip():
            raise _error(f"empty parameter in {symbol}(...)", source, where, a)
        if kind in ("predecessor", "context"):
            name = piece.strip()
            if not _IDENT.match(name):
                what = f"parameters of a {kind} must be names, not {clip(repr(name))}"
                raise _error(what, source, where, a + _lstrip_len(piece))
            if name in FUNCTIONS or name in CONSTANTS or name in ("and", "or", "not"):
                raise _error(f"parameter name {name!r} is reserved", source, where, a + _lstrip_len(piece))
            args.append(name)
        else:
            try:
                args.append(parse_expression(piece, names=formals, defines=defines))
            except ExprSyntaxError as exc:
                raise _error(str(exc), source, where, a + exc.offset) from None
    return tuple(args)


def _check_arities(productions, wheres, axiom, where_axiom, source):
    """A module whose symbol has rules, but none of its arity, is almost always a typo."""
    arities: dict[str, set[int]] = {}
    for p in productions:
        arities.setdefault(p.predecessor.symbol, set()).add(len(p.predecessor.formals))
    for modules, where, what in [(axiom, where_axiom, "the axiom")] + [
        (p.successor, w, f"the successor of rule '{clip(p.text)}'") for p, w in zip(productions, wheres, strict=True)
    ]:
        for m in modules:
            expected = arities.get(m.symbol)
            if expected is not None and len(m.args) not in expected:
                want = " or ".join(str(k) for k in sorted(expected))
                raise _error(
                    f"wrong arity: {m.symbol!r} has {len(m.args)} parameter(s) in {what}, but its rules expect {want}",
                    source,
                    where,
                    m.offset,
                )


def _evaluate_axiom(axiom, alphabet, source, where) -> ModuleString:
    codes = np.array([alphabet.code(m.symbol) for m in axiom], dtype=np.uint8)
    arity = np.array([len(m.args) for m in axiom], dtype=np.uint8)
    params = []
    for m in axiom:
        for e in m.args:
            try:
                params.append(float(e.evaluate({})[0]))
            except ArithmeticError as exc:
                raise _error(f"in axiom parameter '{clip(e.text)}': {exc}", source, where, 0) from None
    return ModuleString(codes, arity, np.array(params, dtype=np.float64), alphabet.table())
