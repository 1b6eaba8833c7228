"""What a dialect is: how its rules are written (:class:`Notation`) and what its symbols mean (:class:`Dialect`).

Plain records, read by the grammar parser (:mod:`lsys3d.grammar`), the turtle
(:mod:`lsys3d.turtle`) and the docs; each dialect module builds one
:class:`Dialect` and, when the tool has its own file format, a reader.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from ..expr import DEFAULT_SYNTAX, Syntax

__all__ = ["Dialect", "Notation"]


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
        Characters that can never be symbols.
    syntax : Syntax
        How expressions are spelled.
    """

    names: frozenset[str] = frozenset()
    surface_prefix: str = ""
    arrows: tuple[str, ...] = ("->", "=")
    contexts: bool = True
    conditions: bool = True
    labels: bool = False
    reserved: str = "(),:="
    syntax: Syntax = DEFAULT_SYNTAX


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
        warning (:mod:`lsys3d.diagnostics`).
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

    def __post_init__(self):
        object.__setattr__(self, "turtle", MappingProxyType(dict(self.turtle)))
        object.__setattr__(self, "variables", MappingProxyType(dict(self.variables)))
