"""The C preprocessor's object-like macros whose text is not a constant, put in place as ``cpp`` does.

cpfg runs its ``.l`` files through the C preprocessor.  ``#define N 5`` and ``#define A (N * 2)`` are
constants, which the cpfg reader folds into the expressions (``Grammar.defines``); a ``#define`` whose
text is not a constant (``#define angle1 100*func(Ang_1,t)``: a call of a graphically defined function
of a global variable) is kept as text and put in place of its name on every later line, one identifier
at a time, as ``cpp`` does: never inside a longer identifier, and a macro's name inside its own
expansion stays as it is.
"""

from __future__ import annotations

import re

__all__ = ["MAX_EXPANDED", "MacroError", "expand"]

MAX_EXPANDED = 1 << 16
"""Longest line after expansion, in characters (macros of macros can grow a line fast)."""

_IDENTIFIER = re.compile(r"[A-Za-z_]\w*")


class MacroError(ValueError):
    """A line whose macros expand past :data:`MAX_EXPANDED` characters."""


def expand(text: str, macros: dict[str, str]) -> str:
    """``text`` with each identifier that names a macro replaced by its (expanded) text.

    >>> expand("F(len) + lenx", {"len": "2*func(1,t)"})
    'F(2*func(1,t)) + lenx'
    >>> expand("a", {"a": "b + a", "b": "a * 2"})
    'a * 2 + a'
    """
    if not macros:
        return text
    return _expand(text, macros, frozenset())


def _expand(text: str, macros: dict[str, str], active: frozenset[str]) -> str:
    def one(m: re.Match) -> str:
        name = m.group()
        if name not in macros or name in active:
            return name
        return _expand(macros[name], macros, active | {name})

    out = _IDENTIFIER.sub(one, text)
    if len(out) > MAX_EXPANDED:
        raise MacroError(f"a line's macros expand past {MAX_EXPANDED} characters (lsys3d.lsystem.dialects.macros)")
    return out
