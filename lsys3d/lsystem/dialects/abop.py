"""*The Algorithmic Beauty of Plants* as printed: ``dialect = "abop"`` in lsys3d's TOML.

The notation of Prusinkiewicz and Lindenmayer (1990): productions ``p1: pred : cond -> succ`` (labels and
``→`` accepted), ``*`` for "no condition", any context or the empty successor, ``=`` as equality in
conditions (``t = 0``), ``%`` cut.  The turtle of chapters 1, 2 and 5: ``G`` moves without recording a
polygon vertex (chapter 5's leaves record vertices only at ``.`` and at ``f``), ``~`` followed by a
name incorporates a predefined surface (recorded as an organ), ``!`` sets the width in the book's
units (screen units: set ``[turtle] width_unit``).
"""

from __future__ import annotations

from ...turtle.commands import COMMANDS, Command, Op, Organ
from ..expr import Syntax
from .common import Dialect, Notation

__all__ = ["DIALECT"]

_ROWS = (
    Command(
        "G",
        "move, no vertex",
        Op.MOVE,
        "l",
        1,
        "Move forward without drawing and without recording a polygon vertex.",
        vertex=False,
    ),
    Command(
        "~",
        "surface",
        Op.ORGAN,
        "s",
        1,
        "`~name`: the predefined surface `name`, scaled by `s`: an organ (its `[surfaces]` model, else the leaf).",
        organ=Organ.SURFACE,
        prefix=True,
    ),
)

# the book's symbols: lsys3d's own, but for the step-length and organ symbols ABOP does not have
COMMANDS_ABOP = tuple(c for c in COMMANDS if c.symbol not in ("~", '"', "@O", "@c", "@o") and not c.query) + _ROWS

DIALECT = Dialect(
    name="abop",
    title="ABOP",
    notation=Notation(
        names=frozenset(c.symbol for c in COMMANDS_ABOP if len(c.symbol) > 1 and not c.prefix),
        surface_prefix="~",
        arrows=("-->", "->", "→"),
        labels=True,
        syntax=Syntax(equals=True),
    ),
    commands=COMMANDS_ABOP,
    angle=90.0,
    cut="%",
)
