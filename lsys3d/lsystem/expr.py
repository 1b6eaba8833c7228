"""Safe arithmetic expressions for conditions and module parameters.

Expressions are data, never code: a small tokenizer and precedence-climbing
parser turn the text into a tree of :class:`Expr` nodes, and evaluation walks
that tree with numpy, one array element per module.  Nothing here calls
``eval``, ``compile`` or ``getattr``; names resolve only to formal parameters,
defines and the constants below, and calls only to the functions in
:data:`FUNCTIONS`, the random functions in :data:`RANDOM_FUNCTIONS` and the
grammar's own pure functions (:class:`Function`: parameters and one expression).

Grammar (lowest precedence first)::

    if   := or ("if" or "else" if)?               # Python's conditional, with Syntax.python
    or   := and (("or" | "||") and)*
    and  := not (("and" | "&&") not)*
    not  := ("not" | "!") not | cmp
    cmp  := sum (("<" | "<=" | ">" | ">=" | "==" | "!=") sum)?
    sum  := prod (("+" | "-") prod)*
    prod := unary (("*" | "/" | "%" | "//") unary)*
    unary:= ("-" | "+") unary | power
    power:= atom (("^" | "**") unary)?        # right-associative, -2^2 == -4
    atom := NUMBER | NAME | NAME "(" args ")" | "(" if ")"

What the dialects change (:class:`Syntax`): ``=`` alone as equality (ABOP's
``t = 0``), Python's spelling (``True``/``False``, ``x if c else y``, chained
comparisons, ``math.`` and ``random.`` before a function's name), and
trigonometric functions in degrees (cpfg).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_ARRAY",
    "RANDOM_FUNCTIONS",
    "STEP",
    "EvalError",
    "Expr",
    "ExprSyntaxError",
    "Function",
    "RandomDraws",
    "Syntax",
    "Table",
    "constant_array",
    "parse_expression",
]

MAX_DEPTH = 64
"""Deepest nesting of an expression: each parenthesis, call, prefix operator and operator of the tree is a level.

``1+1+1`` is three levels deep (a chain of operators builds a tree as tall as
the chain); ``((1))`` two.  Raise it by assigning ``lsys3d.lsystem.expr.MAX_DEPTH``.
"""
MAX_LENGTH = 4096
"""Longest expression text, in characters."""

CONSTANTS = {"pi": math.pi}

STEP = "\0step"
"""The key of an evaluation's ``env`` that holds the derivation step (no grammar can write this name).

L-Py's ``getIterationNb()`` reads it (:attr:`Syntax.python`): the derivation sets it, 0 at the first step
(L-Py's ``Lsystem::__derive``); where no derivation step is known (the axiom), the value is 0 too.
"""

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


def _pow(a, b):
    _domain((a == 0) & (b < 0), "zero raised to a negative power")
    _domain((a < 0) & (np.floor(b) != b), "negative number raised to a fractional power")
    return np.power(a, b)


def _mod(a, b):
    _domain(b == 0, "modulo by zero")
    return np.mod(a, b)


def _floordiv(a, b):
    _domain(b == 0, "division by zero")
    return np.floor_divide(a, b)


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
    "fabs": (1, np.abs),  # C's and cpfg's name
    "min": (2, np.minimum),
    "max": (2, np.maximum),
    "trunc": (1, np.trunc),
    "int": (1, np.trunc),
    "round": (1, np.round),
    "sign": (1, np.sign),
    "pow": (2, _pow),
    "fmod": (2, _mod),
}

_DEGREES = {  # Syntax.degrees: the trigonometric functions of cpfg take and give degrees
    "sin": (1, lambda x: np.sin(np.radians(x))),
    "cos": (1, lambda x: np.cos(np.radians(x))),
    "tan": (1, lambda x: np.tan(np.radians(x))),
    "asin": (1, lambda x: np.degrees(_asin(x))),
    "acos": (1, lambda x: np.degrees(_acos(x))),
    "atan": (1, lambda x: np.degrees(np.arctan(x))),
    "atan2": (2, lambda y, x: np.degrees(np.arctan2(y, x))),
}

RANDOM_FUNCTIONS = {
    "ran": 1,  # cpfg: uniform in [0, x)
    "random": 0,  # L-Py (Python's random.random): uniform in [0, 1)
    "uniform": 2,  # uniform in [a, b)
    "normal": 2,  # normal with mean and standard deviation
    "gauss": 2,  # Python's random.gauss
    "normalvariate": 2,  # Python's random.normalvariate
    "nran": 2,  # cpfg: normal with mean and standard deviation
    "bran": 2,  # cpfg: beta with shapes a, b (Cheng's algorithm BA, as cpfg's utility.c brand)
    "biran": 2,  # cpfg: binomial, the successes of n trials of probability p (n at most MAX_TRIALS)
}
"""The random functions and their arities: seeded by the grammar's seed (:func:`lsys3d.streams.hashed_uniform`)."""

_STEP_FUNCTION = "getIterationNb"  # L-Py's: the derivation step (STEP)
_KEYWORDS = {"and", "or", "not"}
_PY_KEYWORDS = {"and", "or", "not", "if", "else"}
_PY_CONSTANTS = {"True": 1.0, "False": 0.0}
_PY_MODULES = ("math.", "random.", "numpy.", "np.")  # a function's module prefix in Python's spelling
_DOTTED = re.compile(r"\.([A-Za-z_][A-Za-z_0-9]*)")


@dataclass(frozen=True)
class Syntax:
    """How a dialect writes expressions (the default is lsys3d's own).

    Attributes
    ----------
    equals : bool
        ``=`` alone is equality (ABOP writes ``t = 0`` in conditions).
    python : bool
        Python's spelling: ``True``/``False``, ``x if c else y``, chained comparisons (``0 < x < 1``),
        ``//`` and a module prefix on a function (``math.sqrt``, ``random.uniform``); and L-Py's
        ``getIterationNb()``, the derivation step (:data:`STEP`).
    degrees : bool
        Trigonometric functions take and give degrees (cpfg).
    """

    equals: bool = False
    python: bool = False
    degrees: bool = False


DEFAULT_SYNTAX = Syntax()


@dataclass(frozen=True)
class Function:
    """A grammar's own pure function: parameter names and one expression over them (L-Py's ``def f(x): return``)."""

    name: str
    params: tuple[str, ...]
    body: Expr


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


class RandomDraws:
    """Where an evaluation's random functions take their numbers: ``draw(site, k)`` gives one per element.

    ``site`` names the place of the call in the grammar and ``k`` the draw of that call (a normal draws
    two); the derivation supplies a source keyed by the seed, the step and each module's position
    (:func:`lsys3d.streams.hashed_uniform`).  Evaluating the same place twice gives the same numbers.
    """

    def draw(self, site: int, k: int) -> np.ndarray:  # pragma: no cover - an interface
        raise NotImplementedError

    def subset(self, index: np.ndarray) -> RandomDraws:  # pragma: no cover - an interface
        raise NotImplementedError


@dataclass(frozen=True)
class Expr:
    """An expression tree node.

    ``op`` is one of ``num``, ``name``, ``call``, ``random``, ``ucall``, ``neg``,
    ``not``, ``if``, a binary operator (``+ - * / % // ^ < <= > >= == != and or``).
    ``value`` holds the number, the name, the function or (``random``) the
    pair ``(function, site)``; ``args`` the operands.  ``text`` is the source
    text of the node.
    """

    op: str
    value: object = None
    args: tuple[Expr, ...] = ()
    text: str = ""
    function: Function | None = field(default=None, compare=False, repr=False)  # ``ucall``: the function called
    degrees: bool = field(default=False, compare=False, repr=False)  # ``call``: trigonometry in degrees

    def names(self) -> set[str]:
        """All variable names the expression reads."""
        found = {self.value} if self.op == "name" else set()
        for a in self.args:
            found |= a.names()
        return found

    @property
    def is_constant(self) -> bool:
        return self.op == "num"

    @property
    def random(self) -> bool:
        """Whether evaluating it draws random numbers (directly or through a function it calls)."""
        todo = [self]  # a loop, not recursion: a chain of operators is as tall as MAX_DEPTH allows
        while todo:
            node = todo.pop()
            if node.op == "random":
                return True
            if node.op == "ucall" and node.function is not None:
                todo.append(node.function.body)
            todo.extend(node.args)
        return False

    def evaluate(
        self,
        env: dict[str, np.ndarray | float],
        size: int = 1,
        finite: bool = True,
        random: RandomDraws | None = None,
    ) -> np.ndarray:
        """Evaluate elementwise; ``env`` maps names to arrays of length ``size`` or scalars.

        Returns a float64 array of length ``size`` (comparisons give 1.0/0.0).
        Raises :class:`EvalError` on division by zero, a domain error or, unless
        ``finite`` is False (the caller checks many results at once), a result
        that is infinite or NaN.  ``random`` gives the numbers of the random
        functions (an expression that calls one cannot be evaluated without it).
        """
        try:
            with np.errstate(all="ignore"):
                out = _eval(self, _Scope(env, size, random, 0))
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


class _Scope:
    """What a node is evaluated in: the names, the size, the random numbers and the salt of function calls."""

    __slots__ = ("env", "random", "salt", "size")

    def __init__(self, env, size, random, salt):
        self.env = env
        self.size = size
        self.random = random
        self.salt = salt

    def subset(self, index: np.ndarray) -> _Scope:
        """The scope of the elements ``index`` only (the taken branch of a conditional)."""
        env = {}
        for k, v in self.env.items():
            a = np.asarray(v)
            env[k] = a[index] if a.ndim == 1 and a.shape[0] == self.size else v
        random = self.random.subset(index) if self.random is not None else None
        return _Scope(env, len(index), random, self.salt)


def _draw(scope: _Scope, site: int, k: int) -> np.ndarray:
    if scope.random is None:
        raise EvalError("a random function cannot be evaluated here (only in rules and the axiom)", np.zeros(0))
    return scope.random.draw(site * 64 + scope.salt, k)


MAX_TRIALS = 1024
"""Most trials of cpfg's ``biran(n, p)`` (one random number each) and rounds of ``bran``'s rejection."""


def _beta(a, b, scope: _Scope, site: int):
    """cpfg's ``bran(a, b)``: Cheng's algorithm BA (utility.c ``brand``), its rounds drawn all at once."""
    _domain(~((a > 0) & (b > 0)), "bran: the shapes a and b must be > 0")
    s = a + b
    low = np.minimum(a, b)
    with np.errstate(all="ignore"):
        lam = np.where(low <= 1, low, np.sqrt((2 * a * b - s) / (s - 2)))
    u_ = a + lam
    out = np.full(np.broadcast(a, b, np.empty(scope.size)).shape, np.nan)
    done = np.zeros(out.shape, np.bool_)
    tiny = 2.0**-53  # erand48 is redrawn at 0: the smallest draw instead
    for r in range(MAX_TRIALS // 2):
        u1 = np.maximum(_draw(scope, site, 2 * r), tiny)
        u2 = np.maximum(_draw(scope, site, 2 * r + 1), tiny)
        v = np.log(u1 / (1 - u1)) / lam
        ym = a * np.exp(v)
        accept = ~done & (s * np.log(s / (b + ym)) + u_ * v - np.log(4.0) >= np.log(u1 * u1 * u2))
        out[accept] = np.broadcast_to(ym / (b + ym), out.shape)[accept]
        done |= accept
        if done.all():
            return out
    _domain(~done, "bran: no draw accepted (lsys3d.lsystem.expr.MAX_TRIALS)")
    return out


def _binomial(n, p, scope: _Scope, site: int):
    """cpfg's ``biran(n, p)``: the number of ``n`` trials below ``p`` (utility.c ``binrand``, O(n))."""
    _domain(~((n >= 0) & (n <= MAX_TRIALS) & (n == np.floor(n))), f"biran: n must be a whole number 0..{MAX_TRIALS}")
    count = np.zeros(np.broadcast(n, p, np.empty(scope.size)).shape)
    for k in range(int(np.max(n)) if np.size(n) else 0):
        count += (_draw(scope, site, k) < p) & (k < n)
    return count


def _random(node: Expr, scope: _Scope):
    name, site = node.value
    args = [np.asarray(_eval(a, scope), dtype=np.float64) for a in node.args]
    if name == "bran":
        return _beta(args[0], args[1], scope, site)
    if name == "biran":
        return _binomial(args[0], args[1], scope, site)
    u = _draw(scope, site, 0)
    if name == "ran":
        return u * args[0]
    if name == "random":
        return u
    if name == "uniform":
        return args[0] + u * (args[1] - args[0])
    # normal: Box-Muller from two uniforms
    _domain(args[1] < 0, f"{name}: negative standard deviation")
    v = _draw(scope, site, 1)
    z = np.sqrt(-2.0 * np.log1p(-u)) * np.cos(2.0 * np.pi * v)
    return args[0] + args[1] * z


MAX_ARRAY = 100_000
"""Most elements one constant array (cpfg's ``array``, a define that is a list) may hold."""


class Table:
    """A constant array an expression indexes (``a[i][j]``), held by identity: its node stays hashable."""

    __slots__ = ("values",)

    def __init__(self, values: np.ndarray):
        self.values = values

    def __repr__(self) -> str:
        return f"Table(shape={self.values.shape})"


def constant_array(value, what: str = "array") -> np.ndarray:
    """``value`` (nested lists of numbers, or an array) as a read-only float64 array, checked.

    Raises ValueError when it is not rectangular, holds something that is not a finite number, has more than
    8 dimensions or more than :data:`MAX_ARRAY` elements.

    >>> constant_array([[1, 2], [3, 4]]).shape
    (2, 2)
    """
    try:
        array = np.array(value, dtype=np.float64)
    except (ValueError, TypeError):
        raise ValueError(f"{what} must be a list of numbers, of lists of the same length...") from None
    if array.ndim == 0 or array.ndim > 8 or 0 in array.shape:
        raise ValueError(f"{what} must have 1 to 8 dimensions, none of them empty")
    if array.size > MAX_ARRAY:
        raise ValueError(f"{what} has {array.size} elements, more than {MAX_ARRAY} (lsys3d.lsystem.expr.MAX_ARRAY)")
    if not np.isfinite(array).all():
        raise ValueError(f"{what} holds a number that is not finite")
    array.setflags(write=False)
    return array


def _index(node: Expr, indices: list, size: int) -> np.ndarray:
    """``a[i][j]``: a constant array's elements (C's indices: truncated toward zero, each within its size)."""
    name, table = node.value[0], node.value[1].values
    shape = table.shape
    flat = np.zeros(size, np.int64)
    for k, value in enumerate(indices):
        i = np.trunc(np.broadcast_to(np.asarray(value, dtype=np.float64), (size,)))
        bad = ~((i >= 0) & (i < shape[k]))
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise EvalError(f"index {i[first]:g} of array '{name}' outside 0..{shape[k] - 1}", [first])
        flat = flat * shape[k] + i.astype(np.int64)
    return table.reshape(-1)[flat]


def _eval(node: Expr, scope: _Scope):
    op = node.op
    if op == "num":
        return node.value
    if op == "name":
        return scope.env[node.value]
    if op == "neg":
        return -np.asarray(_eval(node.args[0], scope), dtype=np.float64)
    if op == "index":
        return _index(node, [_eval(a, scope) for a in node.args], scope.size)
    if op == "not":
        return np.logical_not(_eval(node.args[0], scope)).astype(np.float64)
    if op == "call":
        fn = (_DEGREES if node.degrees else FUNCTIONS)[node.value][1]
        return fn(*(np.asarray(_eval(a, scope), dtype=np.float64) for a in node.args))
    if op == "random":
        return _random(node, scope)
    if op == "step":
        return scope.env.get(STEP, 0.0)
    if op == "ucall":
        fn = node.function
        values = {p: np.asarray(_eval(a, scope), dtype=np.float64) for p, a in zip(fn.params, node.args, strict=True)}
        if STEP in scope.env:
            values[STEP] = scope.env[STEP]
        inner = _Scope(values, scope.size, scope.random, (scope.salt * 31 + hash_site(node)) % 64)
        return _eval(fn.body, inner)
    if op == "if":
        cond = np.broadcast_to(np.asarray(_eval(node.args[0], scope)) != 0, (scope.size,))
        out = np.empty(scope.size)
        for mask, branch in ((cond, node.args[1]), (~cond, node.args[2])):
            index = np.flatnonzero(mask)
            if len(index):
                try:
                    out[index] = _eval(branch, scope.subset(index))
                except EvalError as exc:
                    raise EvalError(str(exc), index[exc.index] if len(exc.index) else exc.index) from None
        return out
    a = np.asarray(_eval(node.args[0], scope), dtype=np.float64)
    if op == "and":
        return np.logical_and(a != 0, np.asarray(_eval(node.args[1], scope)) != 0).astype(np.float64)
    if op == "or":
        return np.logical_or(a != 0, np.asarray(_eval(node.args[1], scope)) != 0).astype(np.float64)
    b = np.asarray(_eval(node.args[1], scope), dtype=np.float64)
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        _domain(b == 0, "division by zero")
        return a / b
    if op == "%":
        return _mod(a, b)
    if op == "//":
        return _floordiv(a, b)
    if op == "^":
        return _pow(a, b)
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


def hash_site(node: Expr) -> int:
    """A small stable number for a function call's place (its text), to tell calls of one function apart."""
    return sum(node.text.encode("utf-8")) % 61 + 1


_TOKEN = re.compile(
    r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z_0-9]*)
  | (?P<op>\*\*|//|<=|>=|==|!=|&&|\|\||[-+*/%^<>!(),=\[\]])
    """,
    re.VERBOSE,
)


def _tokenize(text: str, syntax: Syntax):
    tokens = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            ch = text[pos]
            hint = " (attribute access is not allowed)" if ch == "." else ""
            raise ExprSyntaxError(f"unexpected character {ch!r} in expression{hint}", pos)
        kind = m.lastgroup
        end = m.end()
        if kind != "ws":
            value = m.group()
            if kind == "op":
                if value == "=":
                    if not syntax.equals:
                        raise ExprSyntaxError("unexpected character '=' in expression (write '==' to compare)", pos)
                    value = "=="
                elif value == "//" and not syntax.python:
                    raise ExprSyntaxError("unexpected '//' in expression", pos)
                value = {"**": "^", "&&": "and", "||": "or", "!": "not"}.get(value, value)
            elif kind == "name":
                if syntax.python and value + "." in _PY_MODULES:
                    dotted = _DOTTED.match(text, end)
                    if dotted:  # math.sqrt, random.uniform: the function itself (checked by the parser)
                        value, end = dotted.group(1), dotted.end()
                if value in (_PY_KEYWORDS if syntax.python else _KEYWORDS):
                    kind = "op"
            tokens.append((kind, value, m.start()))
        pos = end
    tokens.append(("end", "", len(text)))
    return tokens


class _Parser:
    def __init__(self, text, names, defines, syntax: Syntax, functions, site: int):
        self.text = text
        self.syntax = syntax
        self.tokens = _tokenize(text, syntax)
        self.i = 0
        self.names = names
        self.defines = defines
        self.functions = functions
        self.site = site
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

    def node(self, op, start, value=None, args=(), **extra):
        end = self.tokens[self.i - 1][2] + len(self.tokens[self.i - 1][1]) if self.i else start
        # a chain of operators (1+1+...+1) builds a tree as tall as the chain without nesting
        # the parser; evaluation recurses through that height, so it is limited too
        height = 1 + max((self.heights.get(id(a), 1) for a in args), default=0)
        if height > MAX_DEPTH:  # point at the operand that made it too tall
            raise ExprSyntaxError(_too_deep(), self.tokens[self.i - 1][2] if self.i else start)
        node = Expr(op, value, tuple(args), self.text[start:end].strip(), **extra)
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

    def conditional(self, start: int, e: Expr) -> Expr:
        """Python's ``e if cond else other``, after ``e`` (read by ``binary(0)``, so nesting costs no extra frame)."""
        self.take()
        self.enter(start)
        cond = self.binary(0)
        self.expect("else")
        other = self.binary(0)
        self.depth -= 1
        return self.node("if", start, args=(cond, e, other))

    _LEVELS = (("or",), ("and",), None, ("<", "<=", ">", ">=", "==", "!="), ("+", "-"), ("*", "/", "%", "//"))

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
                if not self.syntax.python:
                    raise ExprSyntaxError("comparisons cannot be chained; use 'and'", self.peek()[2])
                # Python: a < b < c is (a < b) and (b < c)
                op2 = self.take()[1]
                third = self.binary(level + 1)
                second = self.node(op2, start, args=(right, third))
                left = self.node("and", start, args=(left, second))
                if self.peek()[1] in ops:
                    raise ExprSyntaxError("more than two comparisons in a chain", self.peek()[2])
        if level == 0 and self.syntax.python and self.peek()[0] == "op" and self.peek()[1] == "if":
            return self.conditional(start, left)
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
            if isinstance(self.defines.get(val), np.ndarray):
                return self.element(val, pos)
            if val in self.defines:
                return self.node("num", pos, float(self.defines[val]))
            if val in CONSTANTS:
                return self.node("num", pos, CONSTANTS[val])
            if self.syntax.python and val in _PY_CONSTANTS:
                return self.node("num", pos, _PY_CONSTANTS[val])
            if val in FUNCTIONS or val in RANDOM_FUNCTIONS or val in self.functions:
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

    def element(self, name: str, pos: int) -> Expr:
        """``a[i][j]``: an element of the constant array ``a`` (a define that is an array: cpfg's ``array``)."""
        table = self.defines[name]
        args = []
        for _ in range(table.ndim):
            if self.peek()[1] != "[":
                raise ExprSyntaxError(f"array '{name}' needs {table.ndim} index(es): {name}" + "[i]" * table.ndim, pos)
            self.take()
            self.enter(pos)
            args.append(self.binary(0))
            self.expect("]")
            self.depth -= 1
        node = self.node("index", pos, (name, Table(table)), args)
        if all(a.op == "num" for a in args):
            try:
                return self.node("num", pos, float(node.evaluate({})[0]))
            except EvalError as exc:
                raise ExprSyntaxError(str(exc), pos) from None
        return node

    def call(self, name: str, pos: int) -> Expr:
        if name == _STEP_FUNCTION and self.syntax.python and name not in self.functions:
            self.take()  # "("
            self.expect(")")
            return self.node("step", pos)
        if name not in FUNCTIONS and name not in RANDOM_FUNCTIONS and name not in self.functions:
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
        if name in self.functions:
            fn = self.functions[name]
            if len(args) != len(fn.params):
                raise ExprSyntaxError(f"function {name!r} takes {len(fn.params)} argument(s), got {len(args)}", pos)
            return self.node("ucall", pos, name, args, function=fn)
        if name in RANDOM_FUNCTIONS:
            arity = RANDOM_FUNCTIONS[name]
            if len(args) != arity:
                raise ExprSyntaxError(f"function {name!r} takes {arity} argument(s), got {len(args)}", pos)
            return self.node("random", pos, (name, self.site + pos), args)
        arity = FUNCTIONS[name][0]
        if len(args) != arity:
            raise ExprSyntaxError(f"function {name!r} takes {arity} argument(s), got {len(args)}", pos)
        degrees = self.syntax.degrees and name in _DEGREES
        node = self.node("call", pos, name, args, degrees=degrees)
        if all(a.op == "num" for a in args):
            try:
                return self.node("num", pos, float(node.evaluate({})[0]))
            except EvalError:
                return node  # reported when evaluated, with the rule and module
        return node


def _too_deep() -> str:
    return f"expression nested deeper than {MAX_DEPTH} levels (lsys3d.lsystem.expr.MAX_DEPTH)"


_STACK = "expression nested too deeply for Python's stack (lower lsys3d.lsystem.expr.MAX_DEPTH)"


def parse_expression(
    text: str,
    names=None,
    defines=None,
    *,
    syntax: Syntax = DEFAULT_SYNTAX,
    functions: dict[str, Function] | None = None,
    site: int = 0,
) -> Expr:
    """Parse ``text`` into an :class:`Expr`.

    Parameters
    ----------
    text : str
        The expression, e.g. ``"l * R"``.
    names : iterable of str, optional
        Variable names the expression may read (formal parameters).
    defines : dict, optional
        Named constants, folded into numbers at parse time.
    syntax : Syntax
        The dialect's spelling (default: lsys3d's own).
    functions : dict of Function, optional
        The grammar's own pure functions, by name.
    site : int
        Where the text stands in its grammar (a whole number >= 0): random
        functions are keyed by it plus their offset in ``text``, so each call
        of the grammar draws its own numbers.

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
    >>> parse_expression("7 % 3 + (1 if x == 2 else 0)", names=["x"], syntax=Syntax(python=True)).evaluate({"x": 2.0})
    array([2.])
    """
    if len(text) > MAX_LENGTH:
        raise ExprSyntaxError(
            f"expression longer than {MAX_LENGTH} characters (lsys3d.lsystem.expr.MAX_LENGTH)", MAX_LENGTH
        )
    parser = _Parser(
        text,
        frozenset(names) if names is not None else frozenset(),
        dict(defines or {}),
        syntax,
        dict(functions or {}),
        int(site),
    )
    try:
        return parser.parse()
    except RecursionError:  # only when MAX_DEPTH was raised beyond what Python's stack holds
        raise ExprSyntaxError(_STACK, parser.tokens[min(parser.i, len(parser.tokens) - 1)][2]) from None
