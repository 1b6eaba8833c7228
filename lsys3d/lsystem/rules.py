"""A grammar's rules read from their text: productions (predecessor, contexts, condition, successor, weight),
defines and functions, the alphabet they use and the axiom (:mod:`lsys3d.lsystem.grammar` builds a
:class:`~lsys3d.lsystem.grammar.Grammar` of them)."""

from __future__ import annotations

import math
import re
import zlib
from dataclasses import dataclass, field

import numpy as np

from ..errors import GrammarError, clip
from .expr import (
    CONSTANTS,
    FUNCTIONS,
    RANDOM_FUNCTIONS,
    Expr,
    ExprSyntaxError,
    Function,
    constant_array,
    parse_expression,
)
from .locations import Where, _api_where, _error, _loc
from .modules import ASCII_ALPHABET, ModuleString

MAX_PARAMETERS = 32
"""Most parameters one module may carry."""
MAX_SYMBOLS = 128
"""Most distinct symbols beyond ASCII (non-ASCII characters and multi-character names) one grammar may use."""
_IDENT = re.compile(r"[A-Za-z_][A-Za-z_0-9]*\Z")
_WORDS = ("and", "or", "not", "if", "else")


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
    ``condition`` is None).  ``following`` holds the rest of a strict predecessor of
    several modules (cpfg's ``XF(x) --> ...``, :attr:`Notation.sequences`): the modules
    that must stand right after ``predecessor``, all replaced by the successor.
    ``lsystem`` is the number of the cpfg sub-L-system the rule belongs to (-1: the main one).
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
    following: tuple[PatternModule, ...] = ()
    lsystem: int = -1

    @property
    def context_sensitive(self) -> bool:
        return bool(self.left or self.right)

    @property
    def formals(self) -> tuple[str, ...]:
        names = [n for m in self.left for n in m.formals]
        names += self.predecessor.formals
        names += [n for m in self.following for n in m.formals]
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
        pred = (self.predecessor.symbol, len(self.predecessor.formals))
        following = tuple((m.symbol, len(m.formals)) for m in self.following)
        return (self.left, *pred, self.right, cond, steps, following, self.lsystem)


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
        array = isinstance(value, (list, tuple, np.ndarray))
        # an array may take a function's name (cpfg's 'array max[M]'): max[i] is the one, max(a, b) the other
        if _reserved(name) and not (array and name not in CONSTANTS and name not in _WORDS):
            raise GrammarError(f"define name {name!r} is reserved", *_loc(source, source_where, 0))
        if array:  # a constant array: cpfg's 'array a[3] = {...}'
            try:
                out[name] = constant_array(value, f"define {name!r}")
            except ValueError as exc:
                raise GrammarError(str(exc), *_loc(source, source_where, 0)) from None
            continue
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
        self.globals: frozenset[str] = frozenset()  # cpfg's globals that change at each step (lsystem.blocks)

    def expression(self, text: str, names, where: Where, offset: int, what: str = "") -> Expr:
        # a random function is keyed by the text of its rule before it: the same place in the same rule
        # draws the same numbers wherever the rule came from (a file, TOML, an L-Py if's two branches)
        site = zlib.crc32(self.current[:offset].encode("utf-8", "surrogatepass"))
        try:
            return parse_expression(
                text,
                names=[*self.globals, *names],
                defines=self.defines,
                syntax=self.syntax,
                functions=self.functions,
                site=site,
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
            if not notation.sequences:
                raise err("the predecessor must be one module (use '<' and '>' for context)", at)
        if any(m.symbol in "[]" for m in pred):
            raise err("a bracket cannot be a predecessor", at)
        if any(m.symbol == "*" for m in pred):
            raise err("'*' (any module) can stand in a context, not as the predecessor", at)
        right = self.modules(rule, "context", (), where, gt[0] + 1, ctx_end) if gt else ()
        if notation.branch_skip and any(m.symbol == notation.branch_skip for m in right):
            right = self.skip_to_branch_end(right, rule, gt[0], err)
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
            following=tuple(pred[1:]),
            right=right,
            condition=condition,
            successor=successor,
            weight=weight,
            steps=steps,
        )

    def skip_to_branch_end(self, right, rule: str, at: int, err):
        """cpfg's ``=`` in a right context skips the rest of the branch up to the ``]`` that must follow it
        (generate.c's ``RconDiff``; the derivation walks it: :class:`lsys3d.lsystem.derive._Context`)."""
        skip = self.notation.branch_skip
        for k, m in enumerate(right):
            if m.symbol == skip and (k + 1 == len(right) or right[k + 1].symbol != "]"):
                raise err(f"{skip!r} in a right context (the rest of the branch skipped) must come before ']'", at)
        return right

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
                if name in self.globals:
                    raise _error(
                        f"a rule assigns the global variable {name!r} that the StartEach/EndEach blocks change: cpfg "
                        "runs such rules one module after another, which lsys3d's parallel derivation does not",
                        self.source,
                        where,
                        at + m.start(1),
                    )
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
