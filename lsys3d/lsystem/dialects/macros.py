"""The C preprocessor's macros, as cpfg runs its ``.l`` files through it: text replaced, never run.

cpfg hands an L-system file to the C preprocessor before it reads it, so ``#define`` is C's: a name
whose value is a number is a constant of the rules (lsys3d keeps those as the grammar's ``defines``,
:mod:`lsys3d.lsystem.dialects.cpfg`); any other value is text put where the name stands
(``#define F_SPIKE ?(2,1.25)spikef$``), and a macro with parameters puts its arguments into its body
(``#define br_ang(o,i) (100*func(1,i/(N-1)))``).  As in C, only whole identifiers are replaced, the
arguments are expanded before they are put in, and a macro is not expanded again inside its own
expansion.  Bounded: at most :data:`MAX_EXPANSIONS` replacements and :data:`MAX_LENGTH` characters per
line, so a file cannot make the reader build an endless text.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["MAX_EXPANSIONS", "MAX_LENGTH", "Macro", "MacroError", "expand", "parse_definition"]

MAX_EXPANSIONS = 10_000
"""Most macro replacements in one line of a file."""
MAX_LENGTH = 1 << 20
"""Longest line a macro expansion may build, in characters."""

_IDENT = re.compile(r"[A-Za-z_]\w*")


class MacroError(ValueError):
    """A macro that cannot be expanded: the message says why (the reader adds the file and line)."""


@dataclass(frozen=True)
class Macro:
    """One ``#define``: its name, its parameters (None for a macro without parentheses) and its body."""

    name: str
    parameters: tuple[str, ...] | None
    body: str


def parse_definition(rest: str) -> Macro:
    """The macro of ``#define`` 's rest of line (``NAME body`` or ``NAME(a, b) body``).

    >>> parse_definition("sq(x) ((x)*(x))")
    Macro(name='sq', parameters=('x',), body='((x)*(x))')
    """
    m = re.match(r"([A-Za-z_]\w*)(\(([^()]*)\))?\s*(.*)\Z", rest.strip(), re.DOTALL)
    if m is None:
        raise MacroError("expected a name")
    if m.group(2) is None:
        return Macro(m.group(1), None, m.group(4).strip())
    names = [p.strip() for p in m.group(3).split(",")] if m.group(3).strip() else []
    for p in names:
        if not _IDENT.fullmatch(p):
            raise MacroError(f"parameter {p!r} of {m.group(1)}(...) is not a name")
    if len(set(names)) != len(names):
        raise MacroError(f"a parameter of {m.group(1)}(...) is named twice")
    return Macro(m.group(1), tuple(names), m.group(4).strip())


def _arguments(text: str, start: int, name: str) -> tuple[list[str], int]:
    """The arguments of a call whose ``(`` stands at ``start``, and the index after its ``)``."""
    depth, args, piece = 0, [], start + 1
    for i in range(start, len(text)):
        ch = text[i]
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth == 0:
                args.append(text[piece:i])
                return args, i + 1
        elif ch == "," and depth == 1:
            args.append(text[piece:i])
            piece = i + 1
    raise MacroError(f"the arguments of macro {name}(...) are not closed on the line")


def _in_number(text: str, at: int) -> bool:
    """Whether the identifier at ``at`` goes on a number (``1e5``, ``2x``: one pp-number token in C)."""
    k = at
    while k > 0 and (text[k - 1].isalnum() or text[k - 1] in "_."):
        k -= 1
    run = text[k:at]
    return bool(run) and (run[0].isdigit() or (run[0] == "." and len(run) > 1 and run[1].isdigit()))


def _substitute(body: str, values: dict[str, str]) -> str:
    """``body`` with each parameter's name replaced by its argument (whole names only)."""
    return _IDENT.sub(lambda k: values.get(k.group(), k.group()), body)


class _Budget:
    def __init__(self):
        self.left = MAX_EXPANSIONS

    def spend(self, name: str):
        self.left -= 1
        if self.left < 0:
            raise MacroError(f"more than {MAX_EXPANSIONS} macro expansions in one line (at {name})")


def expand(text: str, macros: dict[str, Macro], *, _disabled: frozenset = frozenset(), _budget=None) -> str:
    """``text`` with the macros replaced, as the C preprocessor does.

    >>> m = {k.name: k for k in map(parse_definition, ["S ?(2,1.25)s$", "ang(i) (10*i)", "T S+(ang(3))"])}
    >>> expand("A --> F T", m)
    'A --> F ?(2,1.25)s$+((10*3))'
    """
    budget = _budget or _Budget()
    out, i, length = [], 0, 0
    while i < len(text):
        m = _IDENT.search(text, i)
        if m is None:
            out.append(text[i:])
            break
        out.append(text[i : m.start()])
        name = m.group()
        macro = macros.get(name)
        i = m.end()
        if macro is None or name in _disabled or _in_number(text, m.start()):
            out.append(name)
            continue
        if macro.parameters is None:
            budget.spend(name)
            out.append(expand(macro.body, macros, _disabled=_disabled | {name}, _budget=budget))
        else:
            j = i
            while j < len(text) and text[j] in " \t":
                j += 1
            if j >= len(text) or text[j] != "(":  # a function-like macro's name alone is left as it is (C)
                out.append(name)
                continue
            budget.spend(name)
            args, i = _arguments(text, j, name)
            if args == [""] and not macro.parameters:
                args = []
            if len(args) != len(macro.parameters):
                raise MacroError(f"macro {name}(...) takes {len(macro.parameters)} arguments, not {len(args)}")
            values = {
                p: expand(a.strip(), macros, _disabled=_disabled, _budget=budget)
                for p, a in zip(macro.parameters, args, strict=True)
            }
            body = _substitute(macro.body, values)
            out.append(expand(body, macros, _disabled=_disabled | {name}, _budget=budget))
        length += len(out[-1])
        if length > MAX_LENGTH:
            raise MacroError(f"a macro expansion longer than {MAX_LENGTH} characters (at {name})")
    return "".join(out)
