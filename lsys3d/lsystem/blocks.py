"""cpfg's C-like blocks: ``Start:``, ``StartEach:``, ``EndEach:`` and ``End:``, read and run without Python's eval.

cpfg (the cpfg manual, "L-system file": *Start*, *StartEach*, *EndEach*, *End*) runs a block of C-like
statements before the derivation, before and after each derivation step, and after the last one.  The
statements set global variables that the productions' conditions and parameters read: a step
counter, a flag, a random seed.  This module reads such a block into a tree of statements (its own
small tokenizer and recursive-descent parser; each expression is parsed by
:func:`lsys3d.lsystem.expr.parse_expression`, with its limits) and runs the tree with its own walker:

- statements: ``name = expr;``, ``name += expr;`` (and ``-= *= /=``), ``name++;``/``name--;``
  (``++name;``/``--name;``), ``{ ... }``, ``if (c) s [else s]``, ``while (c) s``, ``do s while (c);``,
  ``for (init; c; step) s``, ``;``; the calls ``srand(seed);`` and ``printf(...);``/``fprintf(...);``
  (which print nothing here);
- expressions: cpfg's (C's operators, ``^`` for the power, the trigonometry in degrees), with the
  built-in functions of :data:`lsys3d.lsystem.expr.FUNCTIONS` and the random ``ran(x)``, ``nran(m, s)``;
- every variable is global and starts at 0, as cpfg's; at most :data:`MAX_STATEMENTS` statements run in
  one block (a loop that never ends is an error, not a hang).

What is not C that cpfg knows is refused in one line: arrays, user functions, strings outside
``printf``, pointers.  The random functions draw from :attr:`lsys3d.streams.Stream.BLOCK_RANDOM`, keyed
by the seed (``srand``'s argument once it has run, else the grammar's seed), the block, the step and
the number of draws before: the same file gives the same numbers in any process.  The globals only
``Start`` sets are computed once, when the grammar is read (with the grammar's seed), and become
constants of its rules and axiom; the others are computed for each derivation (with its seed).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import GrammarError, LimitError, clip
from ..streams import Stream, hashed_uniform
from .expr import EvalError, Expr, ExprSyntaxError, RandomDraws, Syntax, parse_expression

__all__ = ["BLOCKS", "MAX_STATEMENTS", "Program", "parse_blocks"]

BLOCKS = ("start", "start_each", "end_each", "end")
"""The blocks, in the order of the cpfg manual: before the derivation, before and after each step, at the end."""

MAX_STATEMENTS = 100_000
"""Most statements one run of one block may execute (loops included)."""

_SYNTAX = Syntax(degrees=True)
_KEYWORDS = frozenset({"if", "else", "while", "for", "do"})
_CALLS = frozenset({"srand", "printf", "fprintf", "fflush"})
_TOKEN = re.compile(
    r"""(?P<space>\s+)
    |(?P<string>"(?:[^"\\\n]|\\.)*")
    |(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)
    |(?P<name>[A-Za-z_]\w*)
    |(?P<op>\+\+|--|\+=|-=|\*=|/=|==|!=|<=|>=|&&|\|\||[-+*/%^<>=!?:(){};,\[\]&.|])""",
    re.VERBOSE,
)


@dataclass(frozen=True)
class _Token:
    kind: str  # name, number, string, op, end
    text: str
    at: int  # offset in the block's text


@dataclass(frozen=True)
class Statement:
    """One statement of a block (a node of the tree the walker runs).

    ``kind`` is ``assign`` (``name``, ``op`` one of ``= += -= *= /=``, ``expr``), ``block`` (``body``),
    ``if`` (``expr``, ``body`` = then, else), ``while`` (``expr``, ``body``), ``do`` (``body``, ``expr``),
    ``for`` (``body`` = init, step, statement; ``expr`` the condition or None), ``srand`` (``expr``) or
    ``nothing`` (``;``, ``printf``).
    """

    kind: str
    at: int
    name: str = ""
    op: str = ""
    expr: Expr | None = None
    body: tuple = ()


def _tokenize(text: str, fail) -> list[_Token]:
    out = []
    i = 0
    while i < len(text):
        m = _TOKEN.match(text, i)
        if m is None:
            raise fail(f"unexpected character {text[i]!r}", i)
        kind = m.lastgroup
        if kind != "space":
            out.append(_Token(kind, m.group(), i))
        i = m.end()
    out.append(_Token("end", "", len(text)))
    return out


class _Parser:
    """Recursive descent over the tokens of one block; expressions are cut out and given to parse_expression."""

    def __init__(self, text, tokens: list[_Token], names: frozenset[str], defines: Mapping, fail, site: int, block):
        self.block = block
        self.text = text
        self.tokens = tokens
        self.i = 0
        self.names = names
        self.defines = defines
        self.fail = fail
        self.site = site
        self.functions: dict = {}

    def peek(self, k: int = 0) -> _Token:
        return self.tokens[min(self.i + k, len(self.tokens) - 1)]

    def take(self) -> _Token:
        t = self.peek()
        self.i += 1
        return t

    def expect(self, text: str, what: str) -> _Token:
        t = self.take()
        if t.text != text or t.kind not in ("op",):
            shown = repr(t.text) if t.kind != "end" else "the end of the block"
            raise self.fail(f"expected {text!r} {what}, not {shown}", t.at)
        return t

    def statements(self) -> tuple[Statement, ...]:
        out = []
        while self.peek().kind != "end":
            out.append(self.statement())
        return tuple(out)

    def statement(self) -> Statement:
        t = self.peek()
        if t.kind == "op" and t.text == "{":
            self.take()
            body = []
            while not (self.peek().kind == "op" and self.peek().text == "}"):
                if self.peek().kind == "end":
                    raise self.fail("'{' without its '}'", t.at)
                body.append(self.statement())
            self.take()
            return Statement("block", t.at, body=tuple(body))
        if t.kind == "op" and t.text == ";":
            self.take()
            return Statement("nothing", t.at)
        if t.kind == "name" and t.text in _KEYWORDS:
            return getattr(self, "_" + t.text)()
        if t.kind == "name" and t.text in _CALLS and self.peek(1).text == "(":
            return self.call()
        statement = self.simple()
        self.expect(";", "after a statement")
        return statement

    def simple(self) -> Statement:
        """An assignment or an increment, without its ';' (also the parts of a for)."""
        t = self.peek()
        if t.kind == "op" and t.text in ("++", "--"):
            self.take()
            name = self.take()
            if name.kind != "name":
                raise self.fail(f"{t.text} needs a variable name", name.at)
            return self._increment(name, t.text)
        if t.kind != "name":
            shown = repr(t.text) if t.kind != "end" else "the end of the block"
            raise self.fail(f"expected a statement, not {shown}", t.at)
        self.take()
        op = self.peek()
        if op.kind == "op" and op.text in ("++", "--"):
            self.take()
            return self._increment(t, op.text)
        if op.kind == "op" and op.text == "[":
            raise self.fail(f"arrays ('{t.text}[...]') are not supported", op.at)
        if op.kind == "op" and op.text == "(":
            raise self.fail(f"function {t.text!r} is not supported in a block (known: srand, printf)", t.at)
        if not (op.kind == "op" and op.text in ("=", "+=", "-=", "*=", "/=")):
            shown = repr(op.text) if op.kind != "end" else "the end of the block"
            raise self.fail(f"expected '=' after {t.text!r}, not {shown}", op.at)
        self.take()
        if t.text in _KEYWORDS or t.text in _CALLS:
            raise self.fail(f"{t.text!r} cannot be assigned", t.at)
        return Statement("assign", t.at, name=t.text, op=op.text, expr=self.expression())

    def _increment(self, name: _Token, op: str) -> Statement:
        one = parse_expression("1")
        return Statement("assign", name.at, name=name.text, op="+=" if op == "++" else "-=", expr=one)

    def expression(self) -> Expr:
        """The tokens up to a ';' (or ')' or ',') outside parentheses, parsed as one cpfg expression."""
        start = self.peek()
        depth = 0
        while True:
            t = self.peek()
            if t.kind == "end":
                break
            if t.kind == "op":
                if t.text in ("(", "["):
                    depth += 1
                elif t.text in (")", "]"):
                    if depth == 0:
                        break
                    depth -= 1
                elif depth == 0 and (t.text in (";", ",", "{", "}") or t.text in ("=", "+=", "-=", "*=", "/=")):
                    break
            if t.kind == "string":
                raise self.fail("a string is only allowed in printf(...)", t.at)
            self.take()
        end = self.peek().at
        text = self.text[start.at : end]
        if not text.strip():
            raise self.fail("expected an expression", start.at)
        try:
            return parse_expression(
                text,
                names=self.names,
                defines=self.defines,
                syntax=_SYNTAX,
                site=self.site + start.at,
                functions=self.functions,
            )
        except ExprSyntaxError as exc:
            raise self.fail(str(exc), start.at + exc.offset) from None

    def condition(self) -> Expr:
        self.expect("(", "before the condition")
        e = self.expression()
        self.expect(")", "after the condition")
        return e

    def call(self) -> Statement:
        t = self.take()
        self.expect("(", f"after {t.text}")
        if t.text == "srand":
            if self.block != "start":
                raise self.fail("srand(...) is read in Start: only (the seed of the whole derivation)", t.at)
            e = self.expression()
            self.expect(")", "after srand's argument")
            self.expect(";", "after a statement")
            return Statement("srand", t.at, expr=e)
        depth = 1  # printf, fprintf, fflush: the arguments are read, nothing is printed
        while depth:
            u = self.take()
            if u.kind == "end":
                raise self.fail(f"{t.text}( without its ')'", t.at)
            if u.kind == "op" and u.text == "(":
                depth += 1
            elif u.kind == "op" and u.text == ")":
                depth -= 1
        self.expect(";", "after a statement")
        return Statement("nothing", t.at)

    def _if(self) -> Statement:
        t = self.take()
        test = self.condition()
        then = self.statement()
        other = ()
        if self.peek().kind == "name" and self.peek().text == "else":
            self.take()
            other = (self.statement(),)
        return Statement("if", t.at, expr=test, body=((then,), other))

    def _else(self) -> Statement:
        raise self.fail("'else' without 'if'", self.peek().at)

    def _while(self) -> Statement:
        t = self.take()
        test = self.condition()
        return Statement("while", t.at, expr=test, body=(self.statement(),))

    def _do(self) -> Statement:
        t = self.take()
        body = self.statement()
        w = self.take()
        if w.text != "while":
            raise self.fail("expected 'while' after the body of 'do'", w.at)
        test = self.condition()
        self.expect(";", "after do ... while (...)")
        return Statement("do", t.at, expr=test, body=(body,))

    def _for(self) -> Statement:
        t = self.take()
        self.expect("(", "after for")
        init = () if self.peek().text == ";" else (self.simple(),)
        self.expect(";", "after the start of a for")
        test = None if self.peek().text == ";" else self.expression()
        self.expect(";", "after the condition of a for")
        step = () if self.peek().text == ")" else (self.simple(),)
        self.expect(")", "after the step of a for")
        return Statement("for", t.at, expr=test, body=(init, step, (self.statement(),)))


_ASSIGNING = ("=", "+=", "-=", "*=", "/=", "++", "--")


def _assigned(tokens: list[_Token]) -> set[str]:
    """Every name a block assigns (``x =``, ``x +=``, ``x++``, ``++x``)."""
    out = set()
    for k, t in enumerate(tokens):
        if t.kind != "name" or t.text in _KEYWORDS:
            continue
        after = tokens[k + 1] if k + 1 < len(tokens) else None
        before = tokens[k - 1] if k else None
        assigns = after is not None and after.kind == "op" and after.text in _ASSIGNING
        if assigns or (before is not None and before.kind == "op" and before.text in ("++", "--")):
            out.add(t.text)
    return out


class _BlockDraws(RandomDraws):
    """The random numbers of one run of a block: keyed by the seed, the block, the step and the draws so far."""

    def __init__(self, seed: int, block: int, step: int):
        self.seed = seed
        self.block = block
        self.step = step
        self.count = 0

    def draw(self, site: int, k: int) -> np.ndarray:
        self.count += 1
        keys = (self.block, self.step, site, k)
        return hashed_uniform(self.seed, Stream.BLOCK_RANDOM, keys, np.array([self.count]))

    def subset(self, index: np.ndarray) -> _BlockDraws:  # one element: the whole
        return self


@dataclass(frozen=True)
class Program:
    """The parsed blocks of one grammar.

    Attributes
    ----------
    blocks : mapping of str to tuple of Statement
        The statements of each block (:data:`BLOCKS`) the file has.
    names : frozenset of str
        Every global variable the blocks assign.
    step_names : frozenset of str
        The globals assigned after ``Start`` (in ``StartEach``, ``EndEach`` or ``End``): they change during
        the derivation, so the productions read them at each step.  The others are constants after ``Start``.
    """

    blocks: Mapping[str, tuple]
    names: frozenset[str]
    step_names: frozenset[str]
    source: str = field(default="<grammar>", compare=False)
    places: Mapping[str, object] = field(default_factory=dict, compare=False, repr=False)

    def run_start(self, seed: int) -> tuple[dict[str, float], int]:
        """The globals after ``Start`` and the seed then in force (``srand``'s argument, else ``seed``)."""
        state = _State(self, seed)
        state.run("start", 0)
        return dict(state.values), state.seed

    def steps(self, n: int, seed: int) -> tuple[list[dict[str, float]], dict[str, float]]:
        """The globals each of ``n`` steps reads (after its ``StartEach``), and those after the last ``End``.

        ``steps[g - 1]`` is what step ``g`` reads; the second value is what the homomorphism reads.
        """
        state = _State(self, seed)
        state.run("start", 0)
        out = []
        for g in range(1, n + 1):
            state.run("start_each", g)
            out.append(dict(state.values))
            state.run("end_each", g)
        state.run("end", n + 1)
        return out, dict(state.values)


class _State:
    """The walker: the globals, the seed, and a count of the statements run against MAX_STATEMENTS."""

    def __init__(self, program: Program, seed: int):
        self.program = program
        self.values = dict.fromkeys(sorted(program.names), 0.0)
        self.seed = int(seed)
        self.count = 0
        self.block = ""
        self.draws: _BlockDraws | None = None

    def run(self, block: str, step: int):
        statements = self.program.blocks.get(block)
        if not statements:
            return
        self.block = block
        self.count = 0
        self.draws = _BlockDraws(self.seed, BLOCKS.index(block), step)
        for s in statements:
            self.execute(s)

    def fail(self, s: Statement, what: str) -> GrammarError:
        where = self.program.places.get(self.block)
        line, col = where(s.at) if where else (None, None)
        return GrammarError(f"{_TITLE[self.block]}: block: {what}", self.program.source, line, col)

    def value(self, s: Statement, e: Expr) -> float:
        try:
            return float(e.evaluate(self.values, 1, random=self.draws)[0])
        except EvalError as exc:
            raise self.fail(s, f"{clip(e.text, 40)!r}: {exc}") from None

    def tick(self):
        self.count += 1
        if self.count > MAX_STATEMENTS:
            raise LimitError(
                f"{self.program.source}: {_TITLE[self.block]}: block ran more than {MAX_STATEMENTS:,} statements "
                "(a loop that does not end?) (lsys3d.lsystem.blocks.MAX_STATEMENTS)"
            )

    def execute(self, s: Statement):
        self.tick()
        kind = s.kind
        if kind == "assign":
            v = self.value(s, s.expr)
            old = self.values.get(s.name, 0.0)
            if s.op == "+=":
                v = old + v
            elif s.op == "-=":
                v = old - v
            elif s.op == "*=":
                v = old * v
            elif s.op == "/=":
                if v == 0:
                    raise self.fail(s, f"{s.name} /= 0: division by zero")
                v = old / v
            if not np.isfinite(v):
                raise self.fail(s, f"{s.name}: result is not a finite number")
            self.values[s.name] = v
        elif kind == "block":
            for t in s.body:
                self.execute(t)
        elif kind == "if":
            then, other = s.body
            for t in then if self.value(s, s.expr) != 0 else other:
                self.execute(t)
        elif kind == "while":
            while self.value(s, s.expr) != 0:
                self.execute(s.body[0])
                self.tick()
        elif kind == "do":
            while True:
                self.execute(s.body[0])
                self.tick()
                if self.value(s, s.expr) == 0:
                    break
        elif kind == "for":
            init, step, (body,) = s.body
            for t in init:
                self.execute(t)
            while s.expr is None or self.value(s, s.expr) != 0:
                self.execute(body)
                for t in step:
                    self.execute(t)
                self.tick()
        elif kind == "srand":
            self.seed = int(abs(self.value(s, s.expr))) & 0xFFFFFFFF
            self.draws = _BlockDraws(self.seed, BLOCKS.index(self.block), self.draws.step)


def parse_blocks(
    blocks: Mapping[str, str],
    defines: Mapping | None = None,
    source: str = "<grammar>",
    places=None,
    functions: Mapping | None = None,
) -> Program:
    """Read the blocks of a grammar (``{"start": "{n = 0;}", "start_each": "{n = n + 1;}"}``) into a Program.

    ``places`` maps a block to ``where(offset) -> (line, column)`` in the file, for messages.

    >>> p = parse_blocks({"start": "{ n = 0; }", "start_each": "{ n++; if (n > 2) flag = 1; }"})
    >>> sorted(p.names), sorted(p.step_names)
    (['flag', 'n'], ['flag', 'n'])
    >>> [v["n"] for v in p.steps(3, seed=0)[0]], p.steps(3, seed=0)[1]["flag"]
    ([1.0, 2.0, 3.0], 1.0)
    """
    places = dict(places or {})
    unknown = sorted(set(blocks) - set(BLOCKS))
    if unknown:
        raise GrammarError(f"unknown block {unknown[0]!r} (known: {', '.join(BLOCKS)})", source)
    tokens: dict[str, list[_Token]] = {}
    for name in BLOCKS:
        text = blocks.get(name)
        if text is None:
            continue
        if not isinstance(text, str):
            raise GrammarError(f"block {name!r} must be a string of statements, not {type(text).__name__}", source)

        def fail(what, at, name=name):
            where = places.get(name)
            line, col = where(at) if where else (None, None)
            return GrammarError(f"{_TITLE[name]}: block: {what}", source, line, col)

        tokens[name] = (_tokenize(text, fail), fail)
    names = set()
    later = set()
    for name, (toks, _) in tokens.items():
        assigned = _assigned(toks)
        names |= assigned
        if name != "start":
            later |= assigned
    parsed = {}
    for k, (name, (toks, fail)) in enumerate(tokens.items()):
        parser = _Parser(blocks[name], toks, frozenset(names), dict(defines or {}), fail, (k + 1) << 24, name)
        parser.functions = dict(functions or {})  # vlab's func, curveX...: the grammar's graphically defined ones
        parsed[name] = parser.statements()
    return Program(parsed, frozenset(names), frozenset(later), source, places)


_TITLE = {"start": "Start", "start_each": "StartEach", "end_each": "EndEach", "end": "End"}
