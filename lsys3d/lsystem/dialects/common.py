"""What a dialect is: how its rules are written (:class:`Notation`) and what its symbols mean (:class:`Dialect`).

Plain records, read by the grammar parser (:mod:`lsys3d.lsystem.grammar`), the turtle
(:mod:`lsys3d.turtle`) and the docs; each dialect module builds one
:class:`Dialect` and, when the tool has its own file format, a reader.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from ...errors import GrammarError
from ..expr import DEFAULT_SYNTAX, Syntax

__all__ = ["Dialect", "Located", "Notation", "fail", "line_where"]


@dataclass(frozen=True)
class Notation:
    """How a dialect writes modules and rules.

    Attributes
    ----------
    names : frozenset of str
        Module names longer than one character that the dialect knows (``@O``,
        ``SetWidth``...); a string is read by longest match against these and the
        grammar's declared ``modules``, else one character is one module.
    surface_prefix : str
        A symbol that takes the next character as its name (cpfg's and L-Py's ``~l``:
        the surface ``l``), unless a declared module name follows it.
    arrows : tuple of str
        The arrows between predecessor and successor, tried in this order.
    contexts : bool
        ``<`` and ``>`` separate the contexts (Lparser: they are roll symbols).
    conditions : bool
        ``:`` separates a condition and a weight (Lparser: it is a symbol).
    labels : bool
        A rule may start with a label ``p1:`` (ABOP's numbering).
    reserved : str
        Characters that can never be symbols (besides parentheses); ``,`` is a symbol in L-Py and cpfg.
    syntax : Syntax
        How expressions are spelled.
    values_in_patterns : bool
        A number in a predecessor or context matches that value (L-Py's ``I(0) --> ...``).
    star_empty : bool
        A successor that is ``*`` alone is empty (ABOP, cpfg, L-Py); Houdini's ``*`` is a turtle command.
    unweighted_alternatives : bool
        Rules without a weight for the same predecessor, contexts and condition are stochastic alternatives
        (lsys3d's own notation); elsewhere only weighted rules are, and the first rule that matches applies,
        as in L-Py, cpfg and the others.
    sequences : bool
        A strict predecessor may be several modules (cpfg: ``XF(x) --> ...`` replaces an ``X`` and the ``F``
        right after it; cpfg's module names are one character, so ``leaf(a) --> ...`` is four modules).
    sub_lsystems : bool
        A rule list may hold cpfg's ``lsystem: N`` lines: the rules after one belong to sub-L-system ``N``
        and rewrite the modules between a ``?(N, ...)`` and its ``$`` (:mod:`lsys3d.lsystem.sequences`).
    branch_skip : str
        A symbol that, in a right context, skips the rest of the branch up to the ``]`` after it (cpfg's
        ``=``: ``A > [B=]C``); then ``]`` in a right context is the next module past ignored symbols and
        whole branches, as cpfg's ``RconDiff`` reads it.  Without it (lsys3d and the others), ``]`` in a
        right context skips the rest of the branch alone.
    """

    names: frozenset[str] = frozenset()
    surface_prefix: str = ""
    arrows: tuple[str, ...] = ("->", "=")
    contexts: bool = True
    conditions: bool = True
    labels: bool = False
    reserved: str = "(),:="
    syntax: Syntax = DEFAULT_SYNTAX
    values_in_patterns: bool = False
    star_empty: bool = True
    unweighted_alternatives: bool = False
    sequences: bool = False
    sub_lsystems: bool = False
    branch_skip: str = ""


@dataclass(frozen=True)
class Dialect:
    """A tool's notation, turtle vocabulary and conventions.

    Attributes
    ----------
    name : str
        What ``dialect = "..."`` says.
    title : str
        The tool's name, for messages and the docs.
    notation : Notation
    commands : tuple of Command
        The turtle's vocabulary in this dialect (rows of :class:`lsys3d.turtle.Command`).
    turtle : mapping
        Defaults of :class:`lsys3d.turtle.TurtleOptions` the tool's turtle starts with (its width unit,
        its initial width...), under a grammar's own ``[turtle]`` table.
    angle : float
        The default rotation angle when a grammar gives none.
    cut : str
        The symbol that cuts the rest of its branch (``%``), or empty.
    suffixes : tuple of str
        File suffixes whose native files this dialect's reader reads.
    reader : callable, optional
        ``reader(text, source, **overrides) -> Grammar`` for the tool's own files.
    variables : mapping
        The tool's predefined variables and what becomes of them in lsys3d (for messages and docs).
    unsupported : frozenset of str
        The tool's turtle commands that lsys3d reads but does not draw: a string holding one is named in a
        warning (:mod:`lsys3d.turtle.diagnostics`).
    arity_check : bool
        A module whose symbol has rules, but none of its number of parameters, is an error (lsys3d's typo
        guard); off where the tool lets such a module simply match no rule (L-Py, cpfg).
    """

    name: str
    title: str
    notation: Notation
    commands: tuple
    turtle: Mapping[str, object] = field(default_factory=dict)
    angle: float = 90.0
    cut: str = "%"
    suffixes: tuple[str, ...] = ()
    reader: Callable | None = field(default=None, compare=False)
    variables: Mapping[str, str] = field(default_factory=dict)
    unsupported: frozenset[str] = frozenset()
    arity_check: bool = True

    def __post_init__(self):
        object.__setattr__(self, "turtle", MappingProxyType(dict(self.turtle)))
        object.__setattr__(self, "variables", MappingProxyType(dict(self.variables)))


class Located:
    """Text assembled from pieces of a file, remembering the line and column each character came from.

    The readers build lsys3d rule strings out of a native file's pieces (an L-Py ``if`` becomes a
    condition); :meth:`where` maps an offset in the built text back to the file, so an error in a
    rule points at the file's own line and column.
    """

    def __init__(self):
        self.pieces: list[str] = []
        self.starts: list[int] = []
        self.places: list[tuple[int, int]] = []
        self.length = 0

    def add(self, piece: str, line: int, col: int) -> Located:
        """Append ``piece``, which stands at ``line``:``col`` of the file (glue text: the place it is about)."""
        self.pieces.append(piece)
        self.starts.append(self.length)
        self.places.append((line, col))
        self.length += len(piece)
        return self

    @property
    def text(self) -> str:
        return "".join(self.pieces)

    def where(self):
        starts, places, pieces = list(self.starts), list(self.places), list(self.pieces)

        def where(offset: int):
            k = max(bisect.bisect_right(starts, max(offset, 0)) - 1, 0)
            line, col = places[k]
            return line, col + min(max(offset - starts[k], 0), max(len(pieces[k]) - 1, 0))

        return where


def line_where(line: int, col: int = 1):
    """Positions in a string that stands on one line of a file from column ``col`` on."""

    def where(offset: int):
        return line, col + max(offset, 0)

    return where


def fail(message: str, source: str, line: int | None = None, col: int | None = None) -> GrammarError:
    """A reader's error: ``file:line:col: message``."""
    return GrammarError(message, source, line, col if line else None)
