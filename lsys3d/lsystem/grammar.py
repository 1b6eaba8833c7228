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

import codecs
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from dataclasses import replace as _with
from types import MappingProxyType
from typing import ClassVar

from ..errors import GrammarError, clip
from ..external import FileRefused, read_file
from . import dialects
from .blocks import Program, parse_blocks
from .locations import (
    _KEYS,
    _RULE_LISTS,
    TABLES,
    _api_where,
    _key_line,
    _loc,
    _locate_strings,
    _toml_error,
    table_error,
    table_key_line,
)
from .modules import ModuleString
from .rules import (
    MAX_PARAMETERS,
    MAX_SYMBOLS,
    PatternModule,
    Production,
    SuccessorModule,
    _check_arities,
    _check_defines,
    _evaluate_axiom,
    _finite_number,
    _parse_functions,
    _RuleContext,
    _Scanner,
)

__all__ = [
    "MAX_GRAMMAR_BYTES",
    "MAX_PARAMETERS",
    "MAX_SYMBOLS",
    "Grammar",
    "PatternModule",
    "Production",
    "SuccessorModule",
    "table_error",
    "table_key_line",
]

MAX_GRAMMAR_BYTES = 1 << 20
"""Largest grammar file read, in bytes."""
MAX_DEPTH = 1000
"""Largest ``homomorphism_depth`` / ``decomposition_depth`` (L-Py's and cpfg's ``maximum depth``)."""

_NAME = re.compile(r"[A-Za-z_@?~][A-Za-z_0-9@]*\Z")  # a declared module name (Leaf, @Gs, ?P)
_SUB_LSYSTEM = re.compile(r"\s*lsystem\s*:\s*(\d+)\s*\Z")  # cpfg's sub-L-systems in a rule list
_SURROGATE = re.compile("[\ud800-\udfff]")
GROUPS = ("species", "figure", "curve", "scene")
"""What a grammar's ``group`` may say it is: a plant species, a textbook figure, a curve, or a plant growing in
a scene it ships with (``lsys3d presets``)."""


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
    ``ignore``; ``functions`` are pure functions, ``"f(x) = x * 2"``; ``blocks`` are cpfg's C-like
    blocks (``{"start": "{n = 0;}", "start_each": "{n++;}"}``, :mod:`lsys3d.lsystem.blocks`), whose
    globals the rules read: those only ``start`` sets as constants, the others at each step.  ``repairs`` are
    what a native file's reader mended as the file's own tool does (``file:line: what``): each is a warning
    (with ``--strict``, an error) wherever the grammar is drawn (:mod:`lsys3d.turtle.diagnostics`).

    Examples
    --------
    >>> g = Grammar(axiom="F", rules=["F -> F-F++F-F"], angle=60)
    >>> len(g.productions)
    1
    >>> str(Grammar(axiom="A", rules=["A --> B Leaf(1)"], modules=["Leaf"], dialect="lpy").axiom_modules)
    'A'
    """

    TABLES: ClassVar[tuple[str, ...]] = TABLES  # the tables, for code that holds a Grammar (provenance)

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
    environment: Mapping[str, object] = field(default_factory=dict)
    growth: Mapping[str, object] = field(default_factory=dict)
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
    blocks: Mapping[str, str] = field(default_factory=dict)
    repairs: tuple[str, ...] = field(default=(), compare=False)
    # parsed, filled in by __post_init__
    productions: tuple[Production, ...] = field(init=False, repr=False)
    homomorphism_productions: tuple[Production, ...] = field(init=False, repr=False)
    decomposition_productions: tuple[Production, ...] = field(init=False, repr=False)
    axiom_modules: ModuleString = field(init=False, repr=False)
    alphabet: tuple[str, ...] = field(init=False, repr=False)
    ignored: frozenset[str] = field(init=False, repr=False)
    _axiom_parsed: tuple = field(init=False, repr=False, compare=False)
    considered: frozenset[str] | None = field(init=False, repr=False)
    program: Program | None = field(init=False, repr=False, compare=False)
    lsystem_main: int = field(init=False, repr=False, compare=False)  # cpfg's main L-system's number, -1: none
    lsystem_numbers: frozenset[int] = field(init=False, repr=False, compare=False)  # all of cpfg's L-systems
    _where: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        set_ = object.__setattr__
        for key in _RULE_LISTS:
            if isinstance(getattr(self, key), str):
                raise GrammarError(f"'{key}' must be a list of rule strings, not one string", self.source)
        for key in TABLES:
            if not isinstance(getattr(self, key), Mapping):
                raise self._key_error(key, f"must be a table, not {type(getattr(self, key)).__name__}")
        for key in (*_RULE_LISTS, "modules", "functions", "repairs"):
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
        for key in TABLES[1:]:  # the defines once checked (below)
            set_(self, key, MappingProxyType(dict(getattr(self, key))))
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
        program, constants = self._program()
        set_(self, "program", program)
        context = _RuleContext(self.source, {**self.defines, **constants}, scanner, notation, functions, dialect)
        context.globals = program.step_names if program is not None else frozenset()
        where_axiom = self._where.get("axiom") or _api_where("axiom")
        if not self.axiom.strip():
            raise GrammarError("the axiom is empty", *_loc(self.source, where_axiom, 0))
        context.current = self.axiom
        axiom = context.modules(self.axiom, "axiom", (), where_axiom)
        groups = {}
        main, numbers = -1, set()
        for key in _RULE_LISTS:
            productions = []
            wheres = []
            lsystem = -1
            for i, rule in enumerate(getattr(self, key)):
                if not isinstance(rule, str):
                    raise GrammarError(f"{_ordinal(key, i)} must be a string, not {type(rule).__name__}", self.source)
                where = self._where.get((key, i)) or _api_where(f"{key}[{i}]")
                marker = _SUB_LSYSTEM.match(rule) if notation.sub_lsystems else None
                if marker:  # cpfg's 'lsystem: N': the rules after it are sub-L-system N's
                    lsystem = int(marker.group(1))
                    numbers.add(lsystem)
                    main = lsystem if main < 0 and i == 0 and key == "rules" else main
                    continue
                productions.append(_with(context.rule(i, rule, where), lsystem=lsystem))
                wheres.append(where)
            groups[key] = (productions, wheres)
        if any(p.lsystem >= 0 for g in groups.values() for p in g[0]) and main < 0:
            raise GrammarError("rules of a sub-L-system ('lsystem: N') need the main one's first", self.source)
        set_(self, "lsystem_main", main)
        set_(self, "lsystem_numbers", frozenset(numbers))
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

    def _program(self) -> tuple[Program | None, dict[str, float]]:
        """cpfg's blocks parsed, and the globals that stay constant after ``Start`` (constants of the rules)."""
        if not self.blocks:
            return None, {}
        program = parse_blocks(self.blocks, self.defines, self.source, self._where.get("blocks"))
        values, _ = program.run_start(self.seed)
        return program, {k: v for k, v in values.items() if k not in program.step_names}

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
            if len(symbol) == 1 and (symbol in "()" or (symbol == "," and "," in context.notation.reserved)):
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
        places = {k: k for k, _ in texts}
        for key in (*_RULE_LISTS, "modules", "functions"):
            texts += [(f"{key}[{i}]", r) for i, r in enumerate(getattr(self, key)) if isinstance(r, str)]
            places.update({f"{key}[{i}]": (key, i) for i in range(len(getattr(self, key)))})
        for key, text in texts:  # a NUL would pass through to the derived string and cut it short in C readers
            nul = text.find("\0")
            if nul >= 0:
                where = self._where.get(places[key]) or _api_where(key)
                raise GrammarError(f"'{key}' holds a NUL character", *_loc(self.source, where, nul))
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
        for key, kind in [(k, list) for k in (*_RULE_LISTS, "modules", "functions")] + [(k, dict) for k in TABLES]:
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
                *TABLES,
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
                "repairs",
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
    """The text of a grammar file, read no further than :data:`MAX_GRAMMAR_BYTES` (errors as GrammarError).

    Read by :func:`lsys3d.external.read_file` (a regular file only, opened without blocking, its size checked
    before reading).  A UTF-8 byte order mark, which some editors write, is dropped.
    """
    try:
        raw = read_file(path, MAX_GRAMMAR_BYTES, "grammar file", "lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES")
    except FileRefused as exc:
        raise GrammarError(exc.reason, str(path)) from None
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8) :]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise GrammarError(f"grammar file is not UTF-8 text (byte {exc.start})", str(path)) from None


def _ordinal(key: str, i: int) -> str:
    return f"rule {i + 1}" if key == "rules" else f"{key} rule {i + 1}"
