"""The dialects: other tools' notations and turtles, and readers for their files.

A grammar names its dialect (``dialect = "lpy"`` in TOML, or the reader of a
native file sets it); the dialect decides how rules are written
(:class:`~lsys3d.lsystem.dialects.common.Notation`), what the turtle does with each
symbol (its command table) and the tool's conventions (default angle, width
unit, the cut symbol).  One module per dialect:

- :mod:`~lsys3d.lsystem.dialects.lsys3d`: lsys3d's own (the default);
- :mod:`~lsys3d.lsystem.dialects.abop`: *The Algorithmic Beauty of Plants*, as printed;
- :mod:`~lsys3d.lsystem.dialects.lpy`: L-Py (``.lpy`` files);
- :mod:`~lsys3d.lsystem.dialects.cpfg`: cpfg / L-studio / vlab (``.l`` files);
- :mod:`~lsys3d.lsystem.dialects.lparser`: Lparser (``.ls`` files; the ABOP-like ``.ls`` of web projects too);
- :mod:`~lsys3d.lsystem.dialects.houdini`: Houdini's L-system SOP (premise and rules in TOML).
"""

from __future__ import annotations

import importlib

from ...errors import GrammarError, clip
from .common import Dialect, Notation

__all__ = [
    "DIALECTS",
    "GRAMMAR_SUFFIXES",
    "SUFFIXES",
    "Dialect",
    "Notation",
    "get",
    "reader_for",
    "suffixes_text",
    "table_markdown",
]

DIALECTS = ("lsys3d", "abop", "lpy", "cpfg", "lparser", "houdini")
"""The names ``dialect = "..."`` accepts; ``lsys3d`` is the default."""

SUFFIXES: dict[str, str] = {".lpy": "lpy", ".l": "cpfg", ".ls": "lparser"}
"""Native file suffixes and the dialect whose reader reads them."""

GRAMMAR_SUFFIXES: tuple[str, ...] = (".toml", *SUFFIXES)
"""Every suffix a grammar file may have: lsys3d's own TOML, then the native files of :data:`SUFFIXES`."""


def suffixes_text() -> str:
    """The grammar files' suffixes in words, for help texts and messages (one home: :data:`SUFFIXES`).

    >>> suffixes_text()
    '.toml, .lpy, .l, .ls'
    """
    return ", ".join(GRAMMAR_SUFFIXES)


_LOADED: dict[str, Dialect] = {}


def get(name: str) -> Dialect:
    """The dialect called ``name`` (a :class:`GrammarError` for an unknown one)."""
    dialect = _LOADED.get(name)
    if dialect is None:
        if not isinstance(name, str) or name not in DIALECTS:
            raise GrammarError(f"unknown dialect {clip(repr(name))} (known: {', '.join(DIALECTS)})")
        dialect = importlib.import_module(f"{__name__}.{name}").DIALECT
        _LOADED[name] = dialect
    return dialect


def reader_for(source: str):
    """The reader of a native file, chosen by the suffix of ``source``; None for TOML (and anything else)."""
    base = source.rsplit("/", 1)[-1]
    suffix = "." + base.rsplit(".", 1)[-1].lower() if "." in base else ""
    name = SUFFIXES.get(suffix)
    return get(name).reader if name is not None else None


_NOTATION = {
    "<": "not a symbol: the left context of a rule",
    ">": "not a symbol: the right context of a rule",
    "%": "cuts the rest of its branch (derivation, not the turtle)",
    "*": "not a command: any module in a context; alone as a successor, nothing",
    ":": "not a symbol: a rule's condition or weight",
    ",": "not a symbol: between parameters",
}
"""What lsys3d's own notation makes of the characters that are not its turtle's commands."""


def table_markdown(name: str) -> str:
    """A dialect's symbols as a Markdown table, each beside what lsys3d's own dialect does with it.

    The tables of ``docs/dialects/*.md`` are this function's output (the tests check it).
    """
    own = {c.symbol: c for c in get("lsys3d").commands}
    dialect = get(name)
    rows = [f"| Symbol | In {dialect.title} | In lsys3d's own dialect |", "|---|---|---|"]

    def cell(text: str) -> str:
        return text.replace("|", "\\|")

    for c in dialect.commands:
        symbol = c.symbol + ("name" if c.prefix else "")
        args = f"({c.args})" if c.args else ""
        ignored = f" (ignores {', '.join(c.ignored)})" if c.ignored else ""
        mine = own.get(c.symbol) if not c.prefix else None
        if c.prefix:
            theirs = "nothing (a symbol of its own)"
        elif c.symbol in _NOTATION:
            theirs = _NOTATION[c.symbol]
        elif mine is None:
            theirs = "no command" if len(c.symbol) == 1 else "no command (not a name lsys3d knows)"
        elif (mine.op, mine.axis, mine.sign) == (c.op, c.axis, c.sign) and mine.factor == c.factor:
            theirs = "the same"
        else:
            theirs = f"{mine.name}: {mine.description}"
        rows.append(
            f"| `{cell(symbol + args)}` | {cell(c.name)}: {cell(c.description)}{cell(ignored)} | {cell(theirs)} |"
        )
    for symbol in sorted(dialect.unsupported):
        rows.append(f"| `{cell(symbol)}` | read, not drawn by lsys3d (a warning names it) | no command |")
    return "\n".join(rows) + "\n"
