"""lsys3d's own dialect: the notation of ``docs/grammar.md`` and the turtle of ``docs/turtle.md``."""

from __future__ import annotations

from ...turtle.commands import COMMANDS
from .common import Dialect, Notation

__all__ = ["DIALECT"]

DIALECT = Dialect(
    name="lsys3d",
    title="lsys3d",
    notation=Notation(names=frozenset(c.symbol for c in COMMANDS if len(c.symbol) > 1), unweighted_alternatives=True),
    commands=COMMANDS,
    angle=90.0,
    cut="%",
)
