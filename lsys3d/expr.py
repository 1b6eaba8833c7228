"""Safe arithmetic expressions for conditions and module parameters.

Expressions are data, never code: a small tokenizer and precedence-climbing
parser turn the text into a tree of :class:`Expr` nodes, and evaluation walks
that tree with numpy, one array element per module.  Nothing here calls
``eval``, ``compile`` or ``getattr``; names resolve only to formal parameters,
defines and the constants below, and calls only to the functions in
:data:`FUNCTIONS`.

Grammar (lowest precedence first)::

    or   := and (("or" | "||") and)*
    and  := not (("and" | "&&") not)*
    not  := ("not" | "!") not | cmp
    cmp  := sum (("<" | "<=" | ">" | ">=" | "==" | "!=") sum)?
    sum  := prod (("+" | "-") prod)*
    prod := unary (("*" | "/") unary)*
    unary:= ("-" | "+") unary | power
    power:= atom (("^" | "**") unary)?        # right-associative, -2^2 == -4
    atom := NUMBER | NAME | NAME "(" args ")" | "(" or ")"
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["CONSTANTS", "FUNCTIONS", "EvalError", "Expr", "ExprSyntaxError", "parse_expression"]

MAX_DEPTH = 64
"""Deepest nesting of an expression: each parenthesis, call, prefix operator and operator of the tree is a level.

``1+1+1`` is three levels deep (a chain of operators builds a tree as tall as
the chain); ``((1))`` two.  Raise it by assigning ``lsys3d.expr.MAX_DEPTH``.
"""
MAX_LENGTH = 4096
"""Longest expression text, in characters."""

CONSTANTS = {"pi": math.pi}

NOT_FINITE = "result is not a finite number (overflow or NaN)"


def _domain(mask_bad, what):
    if np.any(mask_bad):
        raise EvalError(what, np.flatnonzero(np.broadcast_to(mask_bad, np.shape(mask_bad)))[:1])


def _sqrt(x):
    _domain(x < 0, "square root of a negative number")
    return np.sqrt(x)


def _log(x):
    _domain(x <= 0, "logarithm of a number <= 0")
    return np.log(x)


def _asin(x):
    _domain(np.abs(x) > 1, "asin of a number outside [-1, 1]")
    return np.arcsin(x)


def _acos(x):
    _domain(np.abs(x) > 1, "acos of a number outside [-1, 1]")
    return np.arccos(x)


# name -> (arity, numpy function); all work elementwise on float64 arrays.
FUNCTIONS = {
    "sqrt": (1, _sqrt),
    "sin": (1, np.sin),
    "cos": (1, np.cos),
    "tan": (1, np.tan),
    "asin": (1, _asin),
    "acos": (1, _acos),
    "atan": (1, np.arctan),
    "atan2": (2, np.arctan2),
    "exp": (1, np.exp),
    "log": (1, _log),
    "floor": (1, np.floor),
    "ceil": (1, np.ceil),
    "abs": (1, np.abs),
    "min": (2, np.minimum),
    "max": (2, np.maximum),
}

_KEYWORDS = {"and", "or", "not"}


class ExprSyntaxError(ValueError):
    """A malformed expression; ``offset`` is the 0-based index of the bad character."""

    def __init__(self, message: str, offset: int):
        super().__init__(message)
        self.offset = offset


class EvalError(ArithmeticError):
    """A numeric error (division by zero, domain) while evaluating.

    ``index`` holds the positions (into the evaluated arrays) of the first bad elements.
    """

    def __init__(self, message: str, index):
        super().__init__(message)
        self.index = np.asarray(index)


@dataclass(frozen=True)
class Expr:
    """An expression tree node.

    ``op`` is one of ``num``, ``name``, ``call``, ``neg``, ``not``, a binary
    operator (``+ - * / ^ < <= > >= == != and or``).  ``value`` holds the number
    or the name; ``args`` the operands.  ``text`` is the source text of the node.
    """

    op: str
    value: float | str | None = None
    args: tuple[Expr, ...] = ()
    text: str = ""

    def names(self) -> set[str]:
        """All variable names the expression reads."""
        found = {self.value} if self.op == "name" else set()
        for a in self.args:
            found |= a.names()
        return found

    @property
    def is_constant(self) -> bool:
        return self.op == "num"

    def evaluate(self, env: dict[str, np.ndarray | float], size: int = 1, finite: bool = True) -> np.ndarray:
        """Evaluate elementwise; ``env`` maps names to arrays of length ``size`` or scalars.

        Returns a float64 array of length ``size`` (comparisons give 1.0/0.0).
        Raises :class:`EvalError` on division by zero, a domain error or, unless
        ``finite`` is False (the caller checks many results at once), a result
        that is infinite or NaN.
        """
        try:
            with np.errstate(all="ignore"):
                out = _eval(self, env)
        except RecursionError:  # only when MAX_DEPTH was raised beyond what Python's stack holds
            raise EvalError(_STACK, np.zeros(0, np.int64)) from None
        out = np.asarray(out, dtype=np.float64)
        if out.shape != (size,):
            out = np.broadcast_to(out, (size,)).copy()
        if finite:
            bad = ~np.isfinite(out)
            if bad.any():
                raise EvalError(NOT_FINITE, np.flatnonzero(bad)[:1])
        return out


def _eval(node: Expr, env):
    op = node.op
    if op == "num":
        return node.value
    if op == "name":
        return env[node.value]
    if op == "neg":
        return -np.asarray(_eval(node.args[0], env), dtype=np.float64)
    if op == "not":
        return np.logical_not(_eval(node.args[0], env)).astype(np.float64)
    if op == "call":
        fn = FUNCTIONS[node.value][1]
        return fn(*(np.asarray(_eval(a, env), dtype=np.float64) for a in node.args))
    a = np.asarray(_eval(node.args[0], env), dtype=np.float64)
    if op == "and":
        return np.logical_and(a != 0, np.asarray(_eval(node.args[1], env)) != 0).astype(np.float64)
    if op == "or":
        return np.logical_or(a != 0, np.asarray(_eval(node.args[1], env)) != 0).astype(np.float64)
    b = np.asarray(_eval(node.args[1], env), dtype=np.float64)
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        _domain(b == 0, "division by zero")
        return a / b
    if op == "^":
        _domain((a == 0) & (b < 0), "zero raised to a negative power")
        _domain((a < 0) & (np.floor(b) != b), "negative number raised to a fractional power")
        return np.power(a, b)
    if op == "<":
        return (a < b).astype(np.float64)
    if op == "<=":
        return (a <= b).astype(np.float64)
    if op == ">":
        return (a > b).astype(np.float64)
    if op == ">=":
        return (a >= b).astype(np.float64)
    if op == "==":
        return (a == b).astype(np.float64)
    if op == "!=":
        return (a != b).astype(np.float64)
    raise AssertionError(op)  # pragma: no cover - the parser makes no other nodes


_TOKEN = re.compile(
    r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z_0-9]*)
  | (?P<op>\*\*|<=|>=|==|!=|&&|\|\||[-+*/^<>!(),])
    """,
    re.VERBOSE,
)


def _tokenize(text: str):
    tokens = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            ch = text[pos]
            hint = " (attribute access is not allowed)" if ch == "." else ""
            raise ExprSyntaxError(f"unexpected character {ch!r} in expression{hint}", pos)
        kind = m.lastgroup
        if kind != "ws":
            value = m.group()
            if kind == "op":
                value = {"**": "^", "&&": "and", "||": "or", "!": "not"}.get(value, value)
            elif kind == "name" and value in _KEYWORDS:
                kind = "op"
            tokens.append((kind, value, m.start()))
        pos = m.end()
    tokens.append(("end", "", len(text)))
    return tokens


class _Parser:
    def __init__(self, text: str, names: frozenset[str] | None, defines: dict[str, float]):
        self.text = text
        self.tokens = _tokenize(text)
        self.i = 0
        self.names = names
        self.defines = defines
        self.depth = 0  # parentheses, calls and prefix operators open around the current token
        self.heights: dict[int, int] = {}  # id(node) -> height of its tree

    def peek(self):
        return self.tokens[self.i]

    def take(self):
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def expect(self, value):
        kind, val, pos = self.take()
        if val != value or (kind == "end" and value):
            found = "end of expression" if kind == "end" else repr(val)
            raise ExprSyntaxError(f"expected {value!r}, found {found}", pos)

    def node(self, op, start, value=None, args=()):
        end = self.tokens[self.i - 1][2] + len(self.tokens[self.i - 1][1]) if self.i else start
        # a chain of operators (1+1+...+1) builds a tree as tall as the chain without nesting
        # the parser; evaluation recurses through that height, so it is limited too
        height = 1 + max((self.heights.get(id(a), 1) for a in args), default=0)
        if height > MAX_DEPTH:  # point at the operand that made it too tall
            raise ExprSyntaxError(_too_deep(), self.tokens[self.i - 1][2] if self.i else start)
        node = Expr(op, value, tuple(args), self.text[start:end].strip())
        self.heights[id(node)] = height
        return node

    def enter(self, pos):
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise ExprSyntaxError(_too_deep(), pos)

    def parse(self) -> Expr:
        if self.peek()[0] == "end":
            raise ExprSyntaxError("empty expression", 0)
        e = self.binary(0)
        kind, val, pos = self.peek()
        if kind != "end":
            raise ExprSyntaxError(f"unexpected {val!r} after expression", pos)
        return e

    _LEVELS = (("or",), ("and",), None, ("<", "<=", ">", ">=", "==", "!="), ("+", "-"), ("*", "/"))

    def binary(self, level: int) -> Expr:
        if level == 2:
            return self.negation()
        if level == len(self._LEVELS):
            return self.unary()
        start = self.peek()[2]
        left = self.binary(level + 1)
        ops = self._LEVELS[level]
        while self.peek()[0] == "op" and self.peek()[1] in ops:
            op = self.take()[1]
            right = self.binary(level + 1)
            left = self.node(op, start, args=(left, right))
            if level == 3 and self.peek()[1] in ops:
                raise ExprSyntaxError("comparisons cannot be chained; use 'and'", self.peek()[2])
        return left

    def negation(self) -> Expr:
        kind, val, pos = self.peek()
        if kind == "op" and val == "not":
            self.take()
            self.enter(pos)
            e = self.node("not", pos, args=(self.negation(),))
            self.depth -= 1
            return e
        return self.binary(3)

    def unary(self) -> Expr:
        kind, val, pos = self.peek()
        if kind == "op" and val in "+-" and val:
            self.take()
            self.enter(pos)
            operand = self.unary()
            self.depth -= 1
            if val == "+":
                return operand
            if operand.op == "num":
                return self.node("num", pos, -operand.value)
            return self.node("neg", pos, args=(operand,))
        return self.power()

    def power(self) -> Expr:
        start = self.peek()[2]
        base = self.atom()
        if self.peek()[0] == "op" and self.peek()[1] == "^":
            self.take()
            self.enter(start)
            exponent = self.unary()
            self.depth -= 1
            return self.node("^", start, args=(base, exponent))
        return base

    def atom(self) -> Expr:
        kind, val, pos = self.take()
        if kind == "num":
            return self.node("num", pos, float(val))
        if kind == "name":
            if self.peek()[1] == "(" and self.peek()[0] == "op":
                return self.call(val, pos)
            if self.names is not None and val in self.names:
                return self.node("name", pos, val)
            if val in self.defines:
                return self.node("num", pos, float(self.defines[val]))
            if val in CONSTANTS:
                return self.node("num", pos, CONSTANTS[val])
            if val in FUNCTIONS:
                raise ExprSyntaxError(f"function {val!r} needs arguments: {val}(...)", pos)
            raise ExprSyntaxError(f"unknown name {val!r}", pos)
        if kind == "op" and val == "(":
            self.enter(pos)
            e = self.binary(0)
            self.expect(")")
            self.depth -= 1
            return e
        if kind == "end":
            raise ExprSyntaxError("expression ends too early", pos)
        raise ExprSyntaxError(f"unexpected {val!r} in expression", pos)

    def call(self, name: str, pos: int) -> Expr:
        if name not in FUNCTIONS:
            raise ExprSyntaxError(f"unknown function {name!r}", pos)
        self.take()  # "("
        self.enter(pos)
        args = []
        if self.peek()[1] != ")":
            args.append(self.binary(0))
            while self.peek()[1] == ",":
                self.take()
                args.append(self.binary(0))
        self.expect(")")
        self.depth -= 1
        arity = FUNCTIONS[name][0]
        if len(args) != arity:
            raise ExprSyntaxError(f"function {name!r} takes {arity} argument(s), got {len(args)}", pos)
        node = self.node("call", pos, name, args)
        if all(a.op == "num" for a in args):
            try:
                return self.node("num", pos, float(node.evaluate({})[0]))
            except EvalError:
                return node  # reported when evaluated, with the rule and module
        return node


def _too_deep() -> str:
    return f"expression nested deeper than {MAX_DEPTH} levels (lsys3d.expr.MAX_DEPTH)"


_STACK = "expression nested too deeply for Python's stack (lower lsys3d.expr.MAX_DEPTH)"


def parse_expression(text: str, names=None, defines=None) -> Expr:
    """Parse ``text`` into an :class:`Expr`.

    Parameters
    ----------
    text : str
        The expression, e.g. ``"l * R"``.
    names : iterable of str, optional
        Variable names the expression may read (formal parameters).
    defines : dict, optional
        Named constants, folded into numbers at parse time.

    Raises
    ------
    ExprSyntaxError
        With ``offset`` pointing into ``text``.

    Examples
    --------
    >>> import numpy as np
    >>> e = parse_expression("l * R + 1", names=["l"], defines={"R": 2})
    >>> e.evaluate({"l": np.array([1.0, 2.0])}, size=2)
    array([3., 5.])
    """
    if len(text) > MAX_LENGTH:
        raise ExprSyntaxError(f"expression longer than {MAX_LENGTH} characters (lsys3d.expr.MAX_LENGTH)", MAX_LENGTH)
    parser = _Parser(text, frozenset(names) if names is not None else frozenset(), dict(defines or {}))
    try:
        return parser.parse()
    except RecursionError:  # only when MAX_DEPTH was raised beyond what Python's stack holds
        raise ExprSyntaxError(_STACK, parser.tokens[min(parser.i, len(parser.tokens) - 1)][2]) from None
