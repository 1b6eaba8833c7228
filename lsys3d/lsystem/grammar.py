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
names, in successors and the axiom they are expressions (:mod:`lsys3d.lsystem.expr`).
A condition may hold blocks of local variables, ``{y = x * 2}``, evaluated in
order with its tests.  ``*`` alone as a context matches anything, ``*`` alone
as a successor deletes.

``dialect = "..."`` (:mod:`lsys3d.lsystem.dialects`) chooses how rules are written and
what the turtle does with each symbol; the native files of L-Py, cpfg and
Lparser are read by their dialects' readers (:meth:`Grammar.from_file` picks
one by the file's suffix) into the same :class:`Grammar`.
"""

from __future__ import annotations

import errno
import math
import re
import tomllib
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..errors import GrammarError, clip, os_reason
from . import dialects
from .expr import CONSTANTS, FUNCTIONS, RANDOM_FUNCTIONS, Expr, ExprSyntaxError, Function, parse_expression
from .modules import ASCII_ALPHABET, ModuleString

__all__ = [
    "MAX_GRAMMAR_BYTES",
    "MAX_PARAMETERS",
    "MAX_SYMBOLS",
    "Grammar",
    "PatternModule",
    "Production",
    "SuccessorModule",
]

MAX_GRAMMAR_BYTES = 1 << 20
"""Largest grammar file read, in bytes."""
MAX_PARAMETERS = 32
"""Most parameters one module may carry."""
MAX_SYMBOLS = 128
"""Most distinct symbols beyond ASCII (non-ASCII characters and multi-character names) one grammar may use."""
MAX_DEPTH = 1000
"""Largest ``homomorphism_depth`` / ``decomposition_depth`` (L-Py's and cpfg's ``maximum depth``)."""

_IDENT = re.compile(r"[A-Za-z_][A-Za-z_0-9]*\Z")
_NAME = re.compile(r"[A-Za-z_@?~][A-Za-z_0-9@]*\Z")  # a declared module name (Leaf, @Gs, ?P)
_SURROGATE = re.compile("[\ud800-\udfff]")
_KEYS = {
    "name",
    "description",
    "group",
    "dialect",
    "axiom",
    "premise",
    "rules",
    "homomorphism",
    "homomorphism_depth",
    "decomposition",
    "decomposition_depth",
    "iterations",
    "angle",
    "seed",
    "ignore",
    "consider",
    "modules",
    "defines",
    "functions",
    "turtle",
    "form",
    "materials",
    "surfaces",
    "leaves",
}
_RULE_LISTS = ("rules", "decomposition", "homomorphism")
GROUPS = ("species", "figure", "curve")
"""What a grammar's ``group`` may say it is: a plant species, a textbook figure, or a curve (``lsys3d presets``)."""
_WORDS = ("and", "or", "not", "if", "else")

# maps an offset in a piece of text to (line, col); line None when unknown
Where = Callable[[int], tuple[int | None, int | None]]


@dataclass(frozen=True)
class PatternModule:
    """A module in a predecessor or context: a symbol and its formal parameter names.

    The symbol ``*`` in a context matches any one module (its parameters are not bound).
    """

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
    is None for a rule written without one.  ``steps`` holds a condition with
    local variables: ``("let", name, expr)`` and ``("test", expr)`` in the order
    written, each test narrowing the modules the later steps see (then
    ``condition`` is None).
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
    steps: tuple[tuple, ...] = ()

    @property
    def context_sensitive(self) -> bool:
        return bool(self.left or self.right)

    @property
    def formals(self) -> tuple[str, ...]:
        names = [n for m in self.left for n in m.formals]
        names += self.predecessor.formals
        names += [n for m in self.right for n in m.formals]
        return tuple(names)

    @property
    def random(self) -> bool:
        """Whether applying the rule draws random numbers (a random function in its condition or successor)."""
        exprs = [s[-1] for s in self.steps] + ([self.condition] if self.condition is not None else [])
        exprs += [a for m in self.successor for a in m.args]
        return any(e.random for e in exprs)

    def pool_key(self):
        """Rules with equal keys are stochastic alternatives of one another."""
        cond = self.condition.text if self.condition is not None else None
        steps = tuple((s[0], s[1] if s[0] == "let" else "", s[-1].text) for s in self.steps)
        return (self.left, self.predecessor.symbol, len(self.predecessor.formals), self.right, cond, steps)


@dataclass(frozen=True, eq=False)
class Grammar:
    """An L-system: axiom, productions and the settings read with them.

    Build it from Python with strings, exactly as a grammar file would hold them,
    or read one with :meth:`from_text` / :meth:`from_file`.

    ``homomorphism`` rules rewrite the derived string for the turtle only (after
    derivation, up to ``homomorphism_depth`` times, never fed back);
    ``decomposition`` rules rewrite it after each step (up to
    ``decomposition_depth`` times).  ``modules`` declares names longer than one
    character (``["Leaf", "Apex"]``); ``consider`` is the complement of
    ``ignore``; ``functions`` are pure functions, ``"f(x) = x * 2"``.

    Examples
    --------
    >>> g = Grammar(axiom="F", rules=["F -> F-F++F-F"], angle=60)
    >>> len(g.productions)
    1
    >>> str(Grammar(axiom="A", rules=["A --> B Leaf(1)"], modules=["Leaf"], dialect="lpy").axiom_modules)
    'A'
    """

    axiom: str
    rules: tuple[str, ...] = ()
    name: str = ""
    description: str = ""
    group: str = ""
    iterations: int = 1
    angle: float | None = None
    seed: int = 0
    ignore: str = ""
    defines: Mapping[str, float] = field(default_factory=dict)
    turtle: Mapping[str, object] = field(default_factory=dict)
    form: Mapping[str, object] = field(default_factory=dict)
    materials: Mapping[str, object] = field(default_factory=dict)
    surfaces: Mapping[str, object] = field(default_factory=dict)
    leaves: Mapping[str, object] = field(default_factory=dict)
    source: str = "<grammar>"
    text: str | None = None
    dialect: str = "lsys3d"
    homomorphism: tuple[str, ...] = ()
    homomorphism_depth: int = 1
    decomposition: tuple[str, ...] = ()
    decomposition_depth: int = 1
    consider: str = ""
    modules: tuple[str, ...] = ()
    functions: tuple[str, ...] = ()
    # parsed, filled in by __post_init__
    productions: tuple[Production, ...] = field(init=False, repr=False)
    homomorphism_productions: tuple[Production, ...] = field(init=False, repr=False)
    decomposition_productions: tuple[Production, ...] = field(init=False, repr=False)
    axiom_modules: ModuleString = field(init=False, repr=False)
    alphabet: tuple[str, ...] = field(init=False, repr=False)
    ignored: frozenset[str] = field(init=False, repr=False)
    _axiom_parsed: tuple = field(init=False, repr=False, compare=False)
    considered: frozenset[str] | None = field(init=False, repr=False)
    _where: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        set_ = object.__setattr__
        for key in _RULE_LISTS:
            if isinstance(getattr(self, key), str):
                raise GrammarError(f"'{key}' must be a list of rule strings, not one string", self.source)
        for key in ("defines", "turtle", "form", "materials", "surfaces", "leaves"):
            if not isinstance(getattr(self, key), Mapping):
                raise self._key_error(key, f"must be a table, not {type(getattr(self, key)).__name__}")
        for key in (*_RULE_LISTS, "modules", "functions"):
            value = getattr(self, key)
            if not isinstance(value, (list, tuple)):
                raise self._key_error(key, f"must be a list of strings, not {type(value).__name__}")
            set_(self, key, tuple(value))
        for key in ("ignore", "consider"):
            value = getattr(self, key)
            if not isinstance(value, str):
                if not isinstance(value, (list, tuple)) or not all(isinstance(c, str) for c in value):
                    raise self._key_error(key, f"must be a string of symbols, not {clip(repr(value))}")
                set_(self, key, " ".join(value))
        dialect = self._dialect()
        if self.angle is None:
            set_(self, "angle", dialect.angle)
        set_(self, "turtle", MappingProxyType(dict(self.turtle)))
        set_(self, "form", MappingProxyType(dict(self.form)))
        set_(self, "materials", MappingProxyType(dict(self.materials)))
        set_(self, "surfaces", MappingProxyType(dict(self.surfaces)))
        set_(self, "leaves", MappingProxyType(dict(self.leaves)))
        self._check_scalars()
        notation = dialect.notation
        names = self._declared_names(notation)
        scanner = _Scanner(notation, names)
        functions = _parse_functions(self.functions, self.source, self._where, notation)
        set_(
            self,
            "defines",
            MappingProxyType(
                _check_defines(dict(self.defines), self.source, self._where.get("defines"), notation, functions)
            ),
        )
        context = _RuleContext(self.source, self.defines, scanner, notation, functions, dialect)
        where_axiom = self._where.get("axiom") or _api_where("axiom")
        if not self.axiom.strip():
            raise GrammarError("the axiom is empty", *_loc(self.source, where_axiom, 0))
        context.current = self.axiom
        axiom = context.modules(self.axiom, "axiom", (), where_axiom)
        groups = {}
        for key in _RULE_LISTS:
            productions = []
            wheres = []
            for i, rule in enumerate(getattr(self, key)):
                if not isinstance(rule, str):
                    raise GrammarError(f"{_ordinal(key, i)} must be a string, not {type(rule).__name__}", self.source)
                where = self._where.get((key, i)) or _api_where(f"{key}[{i}]")
                productions.append(context.rule(i, rule, where))
                wheres.append(where)
            groups[key] = (productions, wheres)
        derived = groups["rules"][0] + groups["decomposition"][0]
        if dialect.arity_check:
            _check_arities(derived, groups["rules"][1] + groups["decomposition"][1], axiom, where_axiom, self.source)
        set_(self, "ignored", self._symbol_set("ignore", scanner, context))
        considered = self._symbol_set("consider", scanner, context) if self.consider.strip() else None
        set_(self, "considered", considered)
        set_(self, "productions", tuple(groups["rules"][0]))
        set_(self, "decomposition_productions", tuple(groups["decomposition"][0]))
        set_(self, "homomorphism_productions", tuple(groups["homomorphism"][0]))
        set_(self, "_axiom_parsed", axiom)
        set_(self, "alphabet", context.alphabet.table())
        set_(self, "axiom_modules", _evaluate_axiom(axiom, context.alphabet, self.source, where_axiom))

    def _dialect(self):
        if not isinstance(self.dialect, str):
            raise self._key_error("dialect", f"must be a string, not {type(self.dialect).__name__}")
        try:
            return dialects.get(self.dialect)
        except GrammarError as exc:
            raise self._key_error("dialect", exc.reason) from None

    def _declared_names(self, notation) -> frozenset[str]:
        declared = set()
        for name in self.modules:
            if not isinstance(name, str) or not _NAME.match(name) or len(name) > 64:
                raise self._key_error("modules", f"{clip(repr(name))} is not a module name (letters, digits, _, @)")
            declared.add(name)
        return frozenset(n for n in notation.names | declared if len(n) > 1)

    def _symbol_set(self, key: str, scanner: _Scanner, context: _RuleContext) -> frozenset[str]:
        """The symbols of ``ignore`` or ``consider``: modules without parameters, separated or not by blanks."""
        text = getattr(self, key)
        where = self._where.get(key) or _api_where(key)
        found = set()
        i = 0
        while i < len(text):
            if text[i].isspace():
                i += 1
                continue
            symbol = scanner.name(text, i, len(text))
            if symbol in "()," and len(symbol) == 1:
                raise GrammarError(f"'{key}' holds {symbol!r}, which cannot be a symbol", *_loc(self.source, where, i))
            try:
                context.alphabet.code(symbol)
            except ValueError as exc:
                raise GrammarError(str(exc), *_loc(self.source, where, i)) from None
            found.add(symbol)
            i += len(symbol)
        return frozenset(found)

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
        for key in ("homomorphism_depth", "decomposition_depth"):
            depth = getattr(self, key)
            if isinstance(depth, bool) or not isinstance(depth, int) or not 1 <= depth <= MAX_DEPTH:
                raise bad(key, f"must be a whole number from 1 to {MAX_DEPTH}, not {clip(repr(depth))}")
        if not _finite_number(self.angle):
            raise bad("angle", f"must be a number of degrees, not {clip(repr(self.angle))}")
        for key in ("name", "description", "group", "axiom", "ignore", "consider"):
            if not isinstance(getattr(self, key), str):
                raise bad(key, f"must be a string, not {type(getattr(self, key)).__name__}")
        texts = [(k, getattr(self, k)) for k in ("name", "description", "axiom", "ignore", "consider")]
        for key in (*_RULE_LISTS, "modules", "functions"):
            texts += [(f"{key}[{i}]", r) for i, r in enumerate(getattr(self, key)) if isinstance(r, str)]
        if self.group not in ("", *GROUPS):
            raise bad("group", f"must be one of {', '.join(map(repr, GROUPS))}, not {clip(repr(self.group))}")
        for key, text in texts:
            bad_char = _SURROGATE.search(text)
            if bad_char:  # only from Python: TOML text cannot hold one; every file format would refuse it
                raise bad(key, f"is not valid Unicode text (a lone surrogate at character {bad_char.start() + 1})")

    # ---------------------------------------------------------------- readers
    @classmethod
    def from_text(cls, text: str, source: str = "<string>", **overrides) -> Grammar:
        """Read a grammar from its text; ``source`` names it in error messages.

        The text is TOML, unless ``source`` ends in a native file's suffix
        (``.lpy``, ``.l``, ``.ls``): then that dialect's reader reads it.
        """
        if len(text.encode("utf-8", "surrogatepass")) > MAX_GRAMMAR_BYTES:
            raise GrammarError(
                f"grammar is larger than {MAX_GRAMMAR_BYTES} bytes (lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES)", source
            )
        reader = dialects.reader_for(source)
        if reader is not None:
            return reader(text, source, **overrides)
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
        if "premise" in data:  # Houdini's name of the axiom
            if "axiom" in data:
                line = _key_line(text, "premise")
                raise GrammarError("both 'axiom' and 'premise' (Houdini's name of the axiom)", source, line, 1)
            data["axiom"] = data.pop("premise")
        if "axiom" not in data:
            raise GrammarError("missing 'axiom' (the start string, e.g. axiom = \"F\")", source, 1, 1)
        tables = (
            ("defines", dict),
            ("turtle", dict),
            ("form", dict),
            ("materials", dict),
            ("surfaces", dict),
            ("leaves", dict),
        )
        for key, kind in [(k, list) for k in (*_RULE_LISTS, "modules", "functions")] + list(tables):
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
        """Read a grammar file: TOML, or a native file of L-Py (``.lpy``), cpfg (``.l``) or Lparser (``.ls``)."""
        text = read_text(path)
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
                "group",
                "iterations",
                "angle",
                "seed",
                "ignore",
                "defines",
                "turtle",
                "form",
                "materials",
                "surfaces",
                "leaves",
                "source",
                "text",
                "dialect",
                "homomorphism",
                "homomorphism_depth",
                "decomposition",
                "decomposition_depth",
                "consider",
                "modules",
                "functions",
            )
        }
        fields.update(changes)
        return Grammar(**fields, _where=self._where)

    @property
    def parametric(self) -> bool:
        return bool(len(self.axiom_modules.params)) or any(
            p.predecessor.formals or any(m.args for m in p.successor)
            for p in self.productions + self.decomposition_productions
        )

    @property
    def written_symbols(self) -> frozenset[str]:
        """Every symbol the axiom and the successors of all rules hold (what a derivation can ever contain)."""
        found = {m.symbol for m in self._axiom_parsed}
        for group in (self.productions, self.decomposition_productions, self.homomorphism_productions):
            for p in group:
                found.update(m.symbol for m in p.successor)
        return frozenset(found)

    @property
    def cut_symbol(self) -> str:
        """The symbol that cuts the rest of its branch in this grammar's dialect (``%``), or empty."""
        return dialects.get(self.dialect).cut


def read_text(path) -> str:
    """The text of a grammar file, read no further than :data:`MAX_GRAMMAR_BYTES` (errors as GrammarError)."""
    path = Path(path)
    try:
        if "\0" in str(path):
            raise OSError(errno.EINVAL, "a file name cannot hold a NUL character")
        size = path.stat().st_size
        if size > MAX_GRAMMAR_BYTES:
            raise GrammarError(
                f"grammar file is {size} bytes, larger than {MAX_GRAMMAR_BYTES} "
                "(lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES)",
                str(path),
            )
        with path.open("rb") as f:  # a device or pipe has no size: read no more than the limit
            raw = f.read(MAX_GRAMMAR_BYTES + 1)
        if len(raw) > MAX_GRAMMAR_BYTES:
            raise GrammarError(
                f"grammar file is larger than {MAX_GRAMMAR_BYTES} bytes (lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES)",
                str(path),
            )
    except FileNotFoundError:
        raise GrammarError("no such grammar file", str(path)) from None
    except OSError as exc:  # a folder, a symlink loop, a name too long, no permission...
        raise GrammarError(f"cannot read grammar file: {os_reason(exc)}", str(path)) from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise GrammarError(f"grammar file is not UTF-8 text (byte {exc.start})", str(path)) from None


def _ordinal(key: str, i: int) -> str:
    return f"rule {i + 1}" if key == "rules" else f"{key} rule {i + 1}"


# ------------------------------------------------------------------ alphabet
class _Alphabet:
    def __init__(self):
        self.extra: list[str] = []
        self.index: dict[str, int] = {}

    def code(self, name: str) -> int:
        if len(name) == 1 and ord(name) < 128:
            return ord(name)
        code = self.index.get(name)
        if code is None:
            if len(self.extra) >= MAX_SYMBOLS:
                raise ValueError(f"more than {MAX_SYMBOLS} distinct non-ASCII symbols and multi-character names")
            code = 128 + len(self.extra)
            self.extra.append(name)
            self.index[name] = code
        return code

    def table(self) -> tuple[str, ...]:
        if not self.extra:
            return ASCII_ALPHABET
        return ASCII_ALPHABET[:128] + tuple(self.extra) + ("\0",) * (128 - len(self.extra))


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
        t = find(axiom, after_line(_key_line(text, "axiom") or _key_line(text, "premise") or 1))
        if t is not None:
            where["axiom"] = _text_where(line_starts, tokens[t][1])
    for key in ("ignore", "consider"):
        value = data.get(key)
        if isinstance(value, str):
            t = find(value, after_line(_key_line(text, key) or 1))
            if t is not None:
                where[key] = _text_where(line_starts, tokens[t][1])
    for key in (*_RULE_LISTS, "functions"):
        rules = data.get(key)
        if not isinstance(rules, list):
            continue
        cursor = after_line(_key_line(text, key) or 1)
        for i, rule in enumerate(rules):
            if isinstance(rule, str):
                t = find(rule, cursor)
                if t is None:  # a form the scanner does not follow: the rest keep their list positions
                    break
                where[(key, i)] = _text_where(line_starts, tokens[t][1])
                cursor = t + 1
    if isinstance(data.get("defines"), dict):
        line = _key_line(text, "defines")
        where["defines"] = (lambda offset, line=line: (line, 1)) if line else None
    return where


# ------------------------------------------------------------------ defines and functions
def _finite_number(value) -> bool:
    """An int or float (not a bool) that is a finite float: TOML integers have no size limit."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)  # converts an int to float: 10**400 overflows
    except OverflowError:
        return False


def _reserved(name: str) -> bool:
    return name in FUNCTIONS or name in CONSTANTS or name in RANDOM_FUNCTIONS or name in _WORDS


def _check_defines(defines: dict, source: str, where, notation, functions=None) -> dict:
    source_where = where or _api_where("defines")
    out = {}
    for name, value in defines.items():
        if not isinstance(name, str) or not _IDENT.match(name):
            raise GrammarError(f"define name {clip(repr(name))} is not a valid name", *_loc(source, source_where, 0))
        if _reserved(name):
            raise GrammarError(f"define name {name!r} is reserved", *_loc(source, source_where, 0))
        if isinstance(value, str):
            try:
                expr = parse_expression(value, defines=out, syntax=notation.syntax, functions=functions)
                if expr.random:
                    raise ExprSyntaxError("random functions are not allowed in a define (a define is a constant)", 0)
                value = float(expr.evaluate({})[0])
            except (ExprSyntaxError, ArithmeticError) as exc:
                raise GrammarError(f"define {name!r}: {exc}", *_loc(source, source_where, 0)) from None
        if not _finite_number(value):
            raise GrammarError(
                f"define {clip(repr(name))} must be a finite number, not {clip(repr(value))}",
                *_loc(source, source_where, 0),
            )
        out[name] = float(value)
    return out


_FUNCTION = re.compile(r"\s*([A-Za-z_][A-Za-z_0-9]*)\s*\(([^()]*)\)\s*=(?!=)")


def _parse_functions(texts, source: str, wheres: dict, notation) -> dict[str, Function]:
    """``"name(a, b) = expression"``: each may call the functions before it (so none can call itself)."""
    out: dict[str, Function] = {}
    for i, text in enumerate(texts):
        where = wheres.get(("functions", i)) or _api_where(f"functions[{i}]")
        if not isinstance(text, str):
            raise GrammarError(f"function {i + 1} must be a string, not {type(text).__name__}", source)
        m = _FUNCTION.match(text)
        if m is None:
            raise _error("a function reads 'name(parameters) = expression'", source, where, _lstrip_len(text))
        name = m.group(1)
        params = tuple(p.strip() for p in m.group(2).split(",")) if m.group(2).strip() else ()
        if _reserved(name) or name in out:
            what = "is reserved" if _reserved(name) else "is defined twice"
            raise _error(f"function name {name!r} {what}", source, where, m.start(1))
        for p in params:
            if not _IDENT.match(p) or _reserved(p):
                raise _error(f"{clip(repr(p))} cannot be a parameter name", source, where, m.start(2))
        if len(set(params)) != len(params):
            raise _error(f"function {name!r} names a parameter twice", source, where, m.start(2))
        try:
            body = parse_expression(text[m.end() :], names=params, syntax=notation.syntax, functions=out)
        except ExprSyntaxError as exc:
            raise _error(str(exc), source, where, m.end() + exc.offset) from None
        out[name] = Function(name, params, body)
    return out


# ------------------------------------------------------------------ rules
class _Scanner:
    """Where a module name ends: the longest known multi-character name, a surface name, or one character."""

    def __init__(self, notation, names: frozenset[str]):
        self.names = names
        self.prefix = notation.surface_prefix
        by_first: dict[str, set[int]] = {}
        for n in names:
            by_first.setdefault(n[0], set()).add(len(n))
        self.lengths = {ch: sorted(ls, reverse=True) for ch, ls in by_first.items()}

    def longest(self, text: str, i: int, stop: int) -> str | None:
        for length in self.lengths.get(text[i], ()):
            if i + length <= stop and text[i : i + length] in self.names:
                return text[i : i + length]
        return None

    def name(self, text: str, i: int, stop: int) -> str:
        found = self.longest(text, i, stop)
        if found is not None:
            return found
        ch = text[i]
        if self.prefix and ch == self.prefix and i + 1 < stop and (text[i + 1].isalnum() or text[i + 1] == "_"):
            declared = self.longest(text, i + 1, stop)  # ~Leaf: a declared name; else one character, ~l
            return ch + (declared if declared is not None else text[i + 1])
        return ch


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


def _outside_blocks(text: str, start: int, stop: int, conditions: bool):
    """Top-level characters, with the ``{...}`` blocks of a condition (after its ':') skipped."""
    in_condition = False
    braces = 0
    for i, ch in _top_level(text, start, stop):
        if braces:
            braces += {"{": 1, "}": -1}.get(ch, 0)
            continue
        if conditions and ch == ":":
            in_condition = True
        elif in_condition and ch == "{":
            braces = 1
            continue
        yield i, ch


def _open_block(rule: str, start: int, conditions: bool) -> int | None:
    """Where a condition's ``{`` that nothing closes stands, if one does."""
    opened = None
    in_condition = False
    for i, ch in _top_level(rule, start):
        if conditions and ch == ":" and opened is None:
            in_condition = True
        elif in_condition and ch == "{" and opened is None:
            opened = i
        elif ch == "}" and opened is not None:
            opened = None
    return opened


def _find_arrow(rule: str, start: int, notation):
    chars = list(_outside_blocks(rule, start, len(rule), notation.conditions))
    for arrow in notation.arrows:
        for i, ch in chars:
            if ch != arrow[0] or not rule.startswith(arrow, i):
                continue
            if arrow == "=":
                prev = rule[i - 1] if i else ""
                nxt = rule[i + 1] if i + 1 < len(rule) else ""
                if prev in "<>!=" or nxt == "=":
                    continue
            return i, len(arrow)
    return None, 0


_LABEL = re.compile(r"\s*p\d+\s*:")
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\Z")
_STATEMENT = re.compile(r"\s*([A-Za-z_][A-Za-z_0-9]*)\s*([-+*/]?)=(?!=)")


class _RuleContext:
    """What parsing a grammar's strings needs: names, defines, functions, the notation and the alphabet so far."""

    def __init__(self, source, defines, scanner: _Scanner, notation, functions, dialect):
        self.source = source
        self.dialect = dialect
        self.defines = defines
        self.scanner = scanner
        self.notation = notation
        self.syntax = notation.syntax
        self.functions = functions
        self.alphabet = _Alphabet()
        self.constants: list[tuple[str, float]] = []  # the values a rule's patterns match (A(0))
        self.current = ""  # the text being parsed (random functions are keyed by what precedes them)

    def expression(self, text: str, names, where: Where, offset: int, what: str = "") -> Expr:
        # a random function is keyed by the text of its rule before it: the same place in the same rule
        # draws the same numbers wherever the rule came from (a file, TOML, an L-Py if's two branches)
        site = zlib.crc32(self.current[:offset].encode("utf-8", "surrogatepass"))
        try:
            return parse_expression(
                text, names=names, defines=self.defines, syntax=self.syntax, functions=self.functions, site=site
            )
        except ExprSyntaxError as exc:
            message = f"{what}{exc}"
            known = re.match(r"unknown name '(\w+)'", str(exc))
            if known and known.group(1) in self.dialect.variables:  # Houdini's t, g, b...
                name = known.group(1)
                message += f" ({self.dialect.title}'s predefined variable {name}: {self.dialect.variables[name]})"
            raise _error(message, self.source, where, offset + exc.offset) from None

    def rule(self, index: int, rule: str, where: Where) -> Production:
        source, notation = self.source, self.notation
        self.current = rule

        def err(msg, offset):
            return _error(msg, source, where, offset)

        self.constants = []
        begin = 0
        if notation.labels:
            label = _LABEL.match(rule)
            if label:
                begin = label.end()
        arrow, width = _find_arrow(rule, begin, notation)
        if arrow is None:
            opened = []
            for i, ch in enumerate(rule):
                if ch == "(":
                    opened.append(i)
                elif ch == ")" and opened:
                    opened.pop()
            if opened:
                raise err("unclosed '('", opened[-1])
            brace = _open_block(rule, begin, notation.conditions)
            if brace is not None:
                raise err("'{' without '}' in the condition", brace)
            arrows = " or ".join(repr(a) for a in notation.arrows)
            raise err(f"malformed rule: expected {arrows} between predecessor and successor", len(rule.rstrip()))
        lhs_end, rhs_start = arrow, arrow + width

        # successor [: weight]
        colons = [i for i, ch in _top_level(rule, rhs_start) if ch == ":"] if notation.conditions else []
        succ_end = colons[-1] if colons else len(rule)
        weight = None
        if colons:
            wtext = rule[succ_end + 1 :]
            if not wtext.strip():
                raise err("empty weight after ':'", succ_end + 1)
            expr = self.expression(wtext, (), where, succ_end + 1, "bad weight: ")
            if expr.random:
                raise err("bad weight: random functions are not allowed in a weight", succ_end + 1)
            try:
                weight = float(expr.evaluate({})[0])
            except ArithmeticError as exc:
                raise err(f"bad weight: {exc}", succ_end + 1) from None
            if not weight > 0:
                raise err(f"weight must be positive, got {weight:g}", succ_end + 1 + _lstrip_len(wtext))

        # [left <] pred [> right] [: condition]
        colons = [i for i, ch in _top_level(rule, begin, lhs_end) if ch == ":"] if notation.conditions else []
        ctx_end = colons[0] if colons else lhs_end
        if notation.contexts:
            lt = [i for i, ch in _top_level(rule, begin, ctx_end) if ch == "<"]
            gt = [i for i, ch in _top_level(rule, begin, ctx_end) if ch == ">"]
            for marks in (lt, gt):
                if len(marks) > 1 and marks[1] == marks[0] + 1:
                    raise err(
                        f"'{rule[marks[0]] * 2}' (L-Py's context of the string being built) is not supported; "
                        f"use '{rule[marks[0]]}'",
                        marks[0],
                    )
        else:
            lt = gt = []
        if len(lt) > 1:
            raise err("more than one '<' in the rule's left side", lt[1])
        if len(gt) > 1:
            raise err("more than one '>' in the rule's left side", gt[1])
        if lt and gt and gt[0] < lt[0]:
            raise err("'>' (right context) must come after '<' (left context)", gt[0])
        pred_start = lt[0] + 1 if lt else begin
        pred_end = gt[0] if gt else ctx_end

        left = self.modules(rule, "context", (), where, begin, lt[0]) if lt else ()
        if any(m.symbol in "[]" for m in left):
            raise err("brackets are not allowed in a left context", rule.index("[") if "[" in rule[: lt[0]] else 0)
        pred = self.modules(rule, "predecessor", (), where, pred_start, pred_end)
        at = pred_start + _lstrip_len(rule[pred_start:pred_end])
        if len(pred) != 1:
            if not pred:
                raise err("missing predecessor before the arrow", at)
            raise err("the predecessor must be one module (use '<' and '>' for context)", at)
        if pred[0].symbol in "[]":
            raise err("a bracket cannot be a predecessor", at)
        if pred[0].symbol == "*":
            raise err("'*' (any module) can stand in a context, not as the predecessor", at)
        right = self.modules(rule, "context", (), where, gt[0] + 1, ctx_end) if gt else ()
        if gt and not right:
            raise err("empty right context after '>'", gt[0])
        # '*' alone is no context at all (ABOP's '* < + > * -> -')
        left = () if len(left) == 1 and left[0].symbol == "*" else left
        right = () if len(right) == 1 and right[0].symbol == "*" else right
        formals: list[str] = []
        for m in (*left, *pred, *right):
            for name in m.formals:
                if name in formals:
                    raise err(f"parameter name {name!r} is used twice in the rule", rule.index(name))
                formals.append(name)

        condition, steps, names = None, (), list(formals)
        if colons:
            condition, steps, names = self.condition(rule, ctx_end + 1, lhs_end, formals, where)
        if self.constants:  # the values the patterns match are the first tests
            tests = [
                ("test", Expr("==", None, (Expr("name", n, (), n), Expr("num", v, (), f"{v:g}")), f"{n} == {v:g}"))
                for n, v in self.constants
            ]
            rest = list(steps) or ([("test", condition)] if condition is not None else [])
            condition, steps = None, tuple(tests + rest)
            if len(steps) == 1:
                condition, steps = steps[0][1], ()

        succ_text = rule[rhs_start:succ_end]
        if succ_text.strip() == "*" and notation.star_empty:  # ABOP's and cpfg's empty successor
            successor = ()
        else:
            successor = self.modules(rule, "successor", names, where, rhs_start, succ_end)
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
            steps=steps,
        )

    def condition(self, rule: str, start: int, stop: int, formals: list[str], where: Where):
        """A condition: tests and ``{name = expression; ...}`` blocks, in order; ``*`` or nothing is none."""
        text = rule[start:stop]
        if not text.strip():
            raise _error("empty condition after ':'", self.source, where, start)
        if text.strip() == "*":  # ABOP writes '*' for "no condition"
            return None, (), list(formals)
        names = list(formals)
        steps = []
        i = start
        piece = start  # where the current test began
        depth = 0
        while i <= stop:
            ch = rule[i] if i < stop else "{"  # the end closes the last test
            if ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
            elif ch == "}" and depth == 0:
                raise _error("'}' without '{' in the condition", self.source, where, i)
            elif ch == "{" and depth == 0:
                test = rule[piece:i]
                if test.strip() and test.strip() != "*":
                    expr = self.expression(test, names, where, piece, "bad condition: ")
                    steps.append(("test", expr))
                if i == stop:
                    break
                close = rule.find("}", i + 1, stop)
                if close < 0:
                    raise _error("'{' without '}' in the condition", self.source, where, i)
                steps += self.block(rule, i + 1, close, names, where)
                i = piece = close + 1
                continue
            i += 1
        if len(steps) == 1 and steps[0][0] == "test":
            return steps[0][1], (), names
        return None, tuple(steps), names

    def block(self, rule: str, start: int, stop: int, names: list[str], where: Where):
        """``name = expression`` statements separated by ';' or line breaks (``+=`` and the like too)."""
        steps = []
        at = start
        for statement in re.split(r"[;\n]", rule[start:stop]):
            if statement.strip():
                m = _STATEMENT.match(statement)
                if m is None:
                    raise _error(
                        "in a '{...}' block each statement reads 'name = expression'",
                        self.source,
                        where,
                        at + _lstrip_len(statement),
                    )
                name, op = m.group(1), m.group(2)
                if _reserved(name):
                    raise _error(f"{name!r} is reserved and cannot be assigned", self.source, where, at + m.start(1))
                body = statement[m.end() :]
                offset = at + m.end()
                if not body.strip():
                    raise _error(f"nothing assigned to {name!r}", self.source, where, offset)
                if op and name not in names:
                    raise _error(f"{name!r} {op}= before {name!r} has a value", self.source, where, at + m.start(1))
                expr = self.expression(body, names, where, offset)
                if op:  # x += e is x = x + (e)
                    expr = Expr(op, None, (Expr("name", name, (), name), expr), f"{name} {op} ({expr.text})")
                steps.append(("let", name, expr))
                if name not in names:
                    names.append(name)
            at += len(statement) + 1
        return steps

    def modules(self, text, kind, formals, where, start=0, stop=None):
        """Parse modules in ``text[start:stop]``.

        ``kind`` is ``predecessor``/``context`` (parameters are formal names) or
        ``successor``/``axiom`` (parameters are expressions over ``formals``).
        """
        source = self.source
        notation = self.notation
        stop = len(text) if stop is None else stop
        pattern = kind in ("predecessor", "context")
        out = []
        stack = []
        i = start
        while i < stop:
            ch = text[i]
            if ch.isspace():
                i += 1
                continue
            if ch in "()" or ch in notation.reserved or (pattern and notation.contexts and ch in "<>"):
                hint = ""
                if ch == "(":
                    hint = " (parameters must follow a symbol)"
                elif ch == ")":
                    hint = " (unbalanced parenthesis)"
                raise _error(f"unexpected {ch!r} in {kind}{hint}", source, where, i)
            symbol = self.scanner.name(text, i, stop)
            try:
                self.alphabet.code(symbol)
            except ValueError as exc:
                raise _error(str(exc), source, where, i) from None
            sym_at = i
            i += len(symbol)
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
                    raise _error(f"unclosed '(' after {symbol!r}", source, where, i)
                args = self.args(text, i + 1, j, symbol, kind, formals, where)
                i = j + 1
            if kind == "predecessor":
                pass  # a bracket predecessor is reported by the caller
            elif symbol == "[":
                stack.append(sym_at)
            elif symbol == "]":
                if not stack and kind != "context":
                    raise _error(f"unbalanced ']' in {kind}: no '[' before it", source, where, sym_at)
                if stack:
                    stack.pop()
            if symbol in "[]" and args:
                raise _error(f"'{symbol}' takes no parameters", source, where, sym_at)
            if symbol == "*" and args and pattern:
                raise _error("'*' (any module) takes no parameters", source, where, sym_at)
            if pattern:
                out.append(PatternModule(symbol, args))
            else:
                out.append(SuccessorModule(symbol, args, sym_at))
        if stack and kind != "context":
            raise _error(f"unbalanced '[' in {kind}: no ']' closes it", source, where, stack[-1])
        if stack:
            raise _error("unbalanced '[' in right context", source, where, stack[-1])
        return tuple(out)

    def args(self, text, start, stop, symbol, kind, formals, where):
        source = self.source
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
                if self.notation.values_in_patterns and _NUMBER.match(name):  # L-Py's A(0): a test of the value
                    constant = f"_{a}"
                    self.constants.append((constant, float(name)))
                    args.append(constant)
                    continue
                if not _IDENT.match(name):
                    what = f"parameters of a {kind} must be names, not {clip(repr(name))}"
                    raise _error(what, source, where, a + _lstrip_len(piece))
                if _reserved(name):
                    raise _error(f"parameter name {name!r} is reserved", source, where, a + _lstrip_len(piece))
                args.append(name)
            else:
                expr = self.expression(piece, formals, where, a)
                if expr.random and kind == "axiom":
                    raise _error("random functions are not allowed in the axiom", source, where, a + _lstrip_len(piece))
                args.append(expr)
        return tuple(args)


def _lstrip_len(s: str) -> int:
    return len(s) - len(s.lstrip())


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
