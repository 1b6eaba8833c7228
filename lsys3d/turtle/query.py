"""Open L-systems: the turtle answers the grammar between derivation steps.

L-Py's query modules (``?P``, ``?H``, ``?L``, ``?U``, ``?R``), cpfg's (``?P``, ``?H``, ``?L``, ``?U``) and
lsys3d's own are filled with the turtle's position or frame vector where they stand, and cpfg's ``?E``
with the environment's answer (:mod:`lsys3d.turtle.environment`), so that the rules of the next step can
condition on them (Mech and Prusinkiewicz 1996).  Before the first step and after every step,
:func:`answer` runs the turtle over the whole string (one pass of the numba kernel: it costs about what
drawing the string costs, and a string is never re-derived) and writes the answers into the
parameters.  A segment the environment cut is removed from the string with the rest of its branch,
as ABOP's ``%`` does, and leaves the environment's ``bud`` symbol behind when one is set: what is
cut does not go on growing.

The turtle reads the string as derived (without the homomorphism rules) and without the natural
variation's branch drops; queries inside a branch the environment cut are left as they were.
Vectors are given in the dialect's world axes (PlantGL's Z-up world for L-Py).
"""

from __future__ import annotations

import numpy as np

from ..lsystem import dialects
from ..lsystem.derive import DEFAULT_MAX_MODULES, cut_mask, derive
from ..lsystem.grammar import Grammar
from ..lsystem.modules import ModuleString
from .commands import Command, Op, symbol_table
from .environment import Environment
from .interpret import DEFAULT_MAX_SEGMENTS, interpret_answering
from .kernel import FAR_OUTSIDE
from .options import TurtleOptions

__all__ = ["answer", "asks_turtle", "derive_answering"]

_SLICES = {"P": (0, 1.0), "H": (3, 1.0), "L": (6, 1.0), "U": (9, 1.0), "R": (6, -1.0)}


def asks_turtle(grammar: Grammar, commands: tuple[Command, ...]) -> bool:
    """Whether the grammar writes a query module of this vocabulary (so derivation needs the turtle)."""
    queries = {c.symbol for c in commands if c.op == Op.QUERY}
    return bool(queries & set(grammar.written_symbols))


def answer(
    modules: ModuleString,
    turtle: TurtleOptions,
    commands: tuple[Command, ...],
    seed: int,
    environment: Environment | None = None,
    *,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
) -> ModuleString:
    """The string with its query modules filled and the branches the environment cut removed.

    Examples
    --------
    Three steps of 1 and a 90-degree turn: the query module stands at (0, 3, 0), heading along -x.

    >>> from lsys3d import Grammar
    >>> from lsys3d.turtle.commands import COMMANDS
    >>> g = Grammar(axiom="FFF+?P(0,0,0)?H(0,0,0)", angle=90, turtle={"heading": 90})
    >>> out = answer(g.axiom_modules, TurtleOptions.from_grammar(g), COMMANDS, 0)
    >>> str(out)
    'FFF+?P(0,3,0)?H(-1,0,0)'
    """
    scene = environment.scene() if environment is not None else None
    _, found = interpret_answering(
        modules, turtle.replace(branch_drop=0.0), seed, max_segments=max_segments, commands=commands, scene=scene
    )
    table = symbol_table(modules.alphabet, turtle.draw, turtle.move, turtle.leaf, commands)
    params = modules.params
    if len(found.module):
        params = params.copy()
        codes = modules.symbols[found.module]
        offsets = modules.offsets[found.module]
        arity = modules.arity[found.module].astype(np.int64)
        for code in np.unique(codes).tolist():
            cmd = table.command(code)
            sel = codes == code
            state = found.state[sel]
            if cmd.query == "E":
                if environment is not None:
                    values = environment.probe(state[:, :3])
                else:  # nothing blocks, no surface near, full light
                    values = np.tile([0.0, FAR_OUTSIDE, 1.0], (len(state), 1))
                slots = (0, 1, 2)
            else:
                first, sign = _SLICES[cmd.query]
                values = sign * state[:, first : first + 3]
                slots = cmd.world
            for j, slot in enumerate(slots):
                has = arity[sel] > slot
                params[offsets[sel][has] + slot] = values[has, j]
    symbols, arity_all = modules.symbols, modules.arity
    keep = None
    if len(found.cut):
        is_open = table.op[symbols] == Op.PUSH
        is_close = table.op[symbols] == Op.POP
        keep = cut_mask(is_open, is_close, found.cut)
        bud = environment.options.bud if environment is not None else ""
        code = modules.code(bud) if bud else -1
        if code >= 0:  # the cut module becomes the bud, without parameters
            symbols = symbols.copy()
            arity_all = arity_all.copy()
            symbols[found.cut] = code
            keep[found.cut] = True
            drop = np.zeros(len(modules), bool)
            drop[found.cut] = True
            params = params[np.repeat(keep & ~drop, modules.arity.astype(np.int64))]
            arity_all[found.cut] = 0
        else:
            params = params[np.repeat(keep, modules.arity.astype(np.int64))]
        symbols, arity_all = symbols[keep], arity_all[keep]
    if params is modules.params and keep is None:
        return modules
    return ModuleString(symbols, arity_all, params, modules.alphabet)


def derive_answering(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    turtle: TurtleOptions | None = None,
    commands: tuple[Command, ...] | None = None,
    environment: Environment | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
) -> ModuleString:
    """:func:`~lsys3d.lsystem.derive.derive`, with the turtle answering between the steps when it is asked.

    The turtle answers (:func:`answer`) when the grammar writes query modules or an environment is
    given; otherwise this is plain derivation.  ``max_segments`` limits each of the turtle's passes.
    """
    seed = grammar.seed if seed is None else seed
    if commands is None:
        commands = dialects.get(grammar.dialect).commands
    if environment is None and not asks_turtle(grammar, commands):
        return derive(grammar, iterations, seed, max_modules=max_modules)
    turtle = turtle or TurtleOptions.from_grammar(grammar)

    def between(ms: ModuleString, step: int) -> ModuleString:
        return answer(ms, turtle, commands, seed, environment, max_segments=max_segments)

    return derive(grammar, iterations, seed, max_modules=max_modules, between=between)
