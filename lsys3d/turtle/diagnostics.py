"""No silent misreading: what a grammar holds that lsys3d will not draw as its author meant.

After derivation and the turtle, :func:`check` looks for

* symbols in the turtle's string that no rule rewrites and that mean nothing to
  the dialect's turtle (an unknown command pasted from another tool, a typo);
* the dialect's turtle commands that lsys3d does not draw (L-Py's ``SetGuide``...);
* modules carrying parameters the turtle ignores (L-Py's ``F(length, topradius)``);
* organs (named surfaces, instances) with no ``[surfaces]`` model, drawn as the leaf;
* a bark much wider than the plant (widths in another unit: ABOP's screen units);

and reports each as one line: a warning logged through ``logging.getLogger("lsys3d")``
(the CLI prints ``lsys3d: warning: ...``), or with ``strict`` (``--strict``) a
:class:`~lsys3d.errors.GrammarError`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import GrammarError, printable
from ..lsystem import dialects
from ..lsystem.grammar import Grammar
from ..lsystem.modules import ModuleString
from ..options import Options, option
from .commands import BUILT_IN_ORGANS, Op
from .options import TurtleOptions
from .selections import surface_findings
from .skeleton import Skeleton, organ_names

__all__ = ["Checks", "check", "findings"]

log = logging.getLogger("lsys3d")

WIDTH_FACTOR = 1.0
"""A bark whose widest branch is wider than this many times the plant's extent is reported."""


@dataclass(frozen=True)
class Checks(Options):
    """What happens to the grammar's findings (:func:`check`)."""

    strict: bool = option(
        False,
        help="make the grammar warnings (symbols with no meaning, ignored parameters, width unit) errors",
    )


def _names(names) -> str:
    return ", ".join(repr(printable(n)) for n in names)


def _present(modules: ModuleString) -> list[int]:
    """The symbol ids of the string, in the order they first appear."""
    if not len(modules):
        return []
    codes, first = np.unique(modules.symbols, return_index=True)
    return codes[np.argsort(first)].tolist()


def findings(grammar: Grammar, shown: ModuleString, skeleton: Skeleton, table) -> list[str]:
    """The findings (one line each, without ``warning:``) for ``shown``, the string the turtle read.

    ``table`` is the :class:`~lsys3d.turtle.commands.SymbolTable` the turtle used.
    """
    dialect = dialects.get(grammar.dialect)
    rewritten = {
        p.predecessor.symbol for group in (grammar.productions, grammar.decomposition_productions) for p in group
    }
    rewritten |= {p.predecessor.symbol for p in grammar.homomorphism_productions}
    out = list(grammar.repairs)  # what the reader mended, as the file's own tool reads it
    present = _present(shown)
    alphabet = shown.alphabet
    unsupported, meaningless = [], []
    for code in present:
        name = alphabet[code]
        if table.command(code) is not None or name in "[]" or name == grammar.cut_symbol or name in rewritten:
            continue
        (unsupported if name in dialect.unsupported else meaningless).append(name)
    if meaningless:
        out.append(f"{grammar.source}: symbols with no rule and no turtle meaning: {_names(meaningless)}")
    if unsupported:
        out.append(
            f"{grammar.source}: {dialect.title} turtle commands that lsys3d does not draw: {_names(unsupported)}"
        )
    ignored = []
    if len(shown):
        most = np.zeros(256, np.int64)
        np.maximum.at(most, shown.symbols, shown.arity.astype(np.int64))
        for code in present:
            command = table.command(code)
            if command is not None and most[code] > command.max_args:
                names = command.ignored[: most[code] - command.max_args]
                ignored.append(f"{alphabet[code]!r} ({', '.join(names)})")
    if ignored:
        out.append(f"{grammar.source}: module parameters the turtle ignores: {printable(', '.join(ignored))}")
    if skeleton.n_organs:
        known = {*BUILT_IN_ORGANS.values(), *grammar.surfaces, "leaf"}
        missing = sorted(set(organ_names(skeleton).tolist()) - known)
        if missing:
            out.append(
                f"{grammar.source}: organs with no [surfaces] model, drawn as the leaf: "
                f"{printable(', '.join(repr(m) for m in missing))} (give each a [surfaces] entry of that name)"
            )
    out += surface_findings(grammar, shown, skeleton)  # cpfg's surfaces that move the turtle
    movements = _movement_finding(grammar, shown, table, present)
    if movements:
        out.append(movements)
    width = _width_finding(grammar, skeleton)
    if width:
        out.append(width)
    return out


def _movement_finding(grammar: Grammar, shown: ModuleString, table, present) -> str | None:
    """cpfg's ``@Ts(n, ...)``, ``@Ti``, ``@Td`` of a tropism the view file does not give: nothing, as in cpfg (which
    says "Movement index out of range!"), named."""
    codes = [c for c in present if (cmd := table.command(c)) is not None and cmd.op == Op.MOVEMENT_ELASTICITY]
    if not codes:
        return None
    given = len(TurtleOptions.from_grammar(grammar).tropisms) // 7
    at = np.flatnonzero(np.isin(shown.symbols, codes) & (shown.arity > 0))
    numbers = np.trunc(shown.params[shown.offsets[at]] - 1.0)
    bad = sorted(
        {
            f"{shown.alphabet[c]}({n + 1:g})"
            for c, n in zip(shown.symbols[at], numbers, strict=True)
            if not 0 <= n < given
        }
    )
    if not bad:
        return None
    return (
        f"{grammar.source}: cpfg tropisms the view file does not give (it gives {given}: its 'tropism:' and "
        f"'torque:' lines): {printable(', '.join(bad[:5]))}{' ...' if len(bad) > 5 else ''} change nothing, as in cpfg"
    )


def _width_finding(grammar: Grammar, skeleton: Skeleton) -> str | None:
    if not len(skeleton):
        return None
    widest = float(max(skeleton.width_start.max(), skeleton.width_end.max()))
    lo, hi = skeleton.bounds()
    extent = float((hi - lo).max())
    if not (widest > WIDTH_FACTOR * extent and widest > 0 and extent > 0):
        return None
    unit = 10.0 ** math.floor(math.log10(extent / (10 * widest)))
    return (
        f"{grammar.source}: the widest branch ({widest:g}) is {widest / extent:.3g} times the size of the plant "
        f"({extent:g}): are its widths in another unit? Set [turtle] width_unit (e.g. width_unit = {unit:g}) "
        "or width"
    )


def check(grammar: Grammar, shown: ModuleString, skeleton: Skeleton, table, options: Checks | None = None) -> list[str]:
    """Log each finding as a warning, or raise the first as a :class:`GrammarError` when ``options.strict``.

    Returns the findings.
    """
    found = findings(grammar, shown, skeleton, table)
    if found and options is not None and options.strict:
        where, _, what = found[0].partition(": ")
        raise GrammarError(f"{what} (an error with --strict)", where)
    for line in found:
        log.warning("warning: %s", line)
    return found
