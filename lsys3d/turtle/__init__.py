"""The turtle: a derived module string -> the branch skeleton (and leaves).

One module per job:

- :mod:`~lsys3d.turtle.commands`: the command table (a row per symbol) and its compiled form;
- :mod:`~lsys3d.turtle.options`: :class:`TurtleOptions`, the ``[turtle]`` table of a grammar;
- :mod:`~lsys3d.turtle.kernel`: the numba kernel that walks the modules;
- :mod:`~lsys3d.turtle.interpret`: :func:`interpret`, which prepares the arrays, runs the kernel and
  returns the :class:`~lsys3d.turtle.skeleton.Skeleton`;
- :mod:`~lsys3d.turtle.form`: :func:`form`, the botanical form of a drawn skeleton (:class:`FormOptions`,
  a grammar's ``[form]`` table): pipe-model widths, flare, curvature, irregularity, phyllotaxis, collars;
- :mod:`~lsys3d.turtle.botany`: the botanical measures of a skeleton (pipe model at forks, flare,
  straight chains, seeds) and the goals the species meet.
"""

from __future__ import annotations

from .commands import COMMANDS, Axis, Command, Op, Organ, commands_markdown, symbol_table
from .form import FormOptions, form
from .interpret import DEFAULT_MAX_SEGMENTS, interpret
from .options import GRAMMAR_KEYS, JITTER_DISTRIBUTIONS, TurtleOptions, TurtleOverrides, options_markdown

__all__ = [
    "COMMANDS",
    "DEFAULT_MAX_SEGMENTS",
    "GRAMMAR_KEYS",
    "JITTER_DISTRIBUTIONS",
    "Axis",
    "Command",
    "FormOptions",
    "Op",
    "Organ",
    "TurtleOptions",
    "TurtleOverrides",
    "commands_markdown",
    "form",
    "interpret",
    "options_markdown",
    "symbol_table",
]
