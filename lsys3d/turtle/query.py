"""Open L-systems: the turtle answers the grammar between derivation steps.

L-Py's query modules (``?P``, ``?H``, ``?L``, ``?U``, ``?R``), cpfg's (``?P``, ``?H``, ``?L``, ``?U``) and
lsys3d's own are filled with the turtle's position or frame vector where they stand, and cpfg's ``?E``
with the environment's answer (:mod:`lsys3d.turtle.environment`), so that the rules of the next step can
condition on them (Mech and Prusinkiewicz 1996).  Before the first step and after every step, an
:class:`Answerer` runs the turtle's state over the string and writes the answers into the parameters.
A segment the environment cut is removed from the string with the rest of its branch, as ABOP's ``%``
does, and leaves the environment's ``bud`` symbol behind when one is set: what is cut does not go on
growing.

The pass is lean and incremental (:mod:`lsys3d.turtle.incremental`): it builds no skeleton, and after
the first step it re-reads only what derivation changed (derivation tells it, :data:`lsys3d.lsystem.derive.Trace`),
starting from the states it recorded; the answers are bit for bit those of a pass over the whole string.

The turtle reads the string as derived (without the homomorphism rules) and without the natural
variation's branch drops; queries inside a branch the environment cut are left as they were.
Vectors are given in the dialect's world axes (PlantGL's Z-up world for L-Py).
"""

from __future__ import annotations

import numpy as np

from ..lsystem import dialects
from ..lsystem.derive import CUT, DEFAULT_MAX_MODULES, cut_mask, derive
from ..lsystem.grammar import Grammar
from ..lsystem.modules import ModuleString
from . import incremental, kernel
from .commands import Command, Op, SymbolTable, symbol_table
from .environment import Environment
from .interpret import (
    DEFAULT_MAX_SEGMENTS,
    NO_SCENE,
    check_segments,
    interpret_answering,
    kernel_program,
    module_error,
    natural_variation,
    surveyed,
    turtle_config,
)
from .options import TurtleOptions
from .scene import FAR_OUTSIDE
from .shadow import shade
from .steering import ROW, SteeringMemo

__all__ = ["Answerer", "answer", "asks_turtle", "derive_answering"]

_SLICES = {"P": (0, 1.0), "H": (3, 1.0), "L": (6, 1.0), "U": (9, 1.0), "R": (6, -1.0)}
_POLYGON_OPS = (Op.POLYGON_BEGIN, Op.POLYGON_END, Op.POLYGON_VERTEX)
_WHOLE = np.zeros(0, np.int64)  # an origin that says nothing: the pass reads the whole string
_NEUTRAL = incremental.neutral_ops()
_NO_PARAMS = np.zeros(0)
_NO_COUNTS = np.zeros(0, np.int64)
_NO_OPS = np.zeros(256, np.int8)
# ops a survey must see (their count depends on parameters, or it checks their arguments) or the lean pass
# does not carry out: a grammar that writes one is surveyed each step
_SURVEYED = {int(o) for o in (Op.RANDOM_TURN, Op.FORWARD_STEPS, Op.TROPISM_VECTOR)} | {
    int(o) for o in Op if o > Op.QUERY
}
_NO_ROWS = np.zeros((0, ROW))  # no steerings kept
_NO_STATES = np.zeros((0, 12))  # no query module listed
_NO_DEPOSITS = np.zeros((0, 4))  # no plant's shade


def asks_turtle(grammar: Grammar, commands: tuple[Command, ...]) -> bool:
    """Whether the grammar writes a query module of this vocabulary (so derivation needs the turtle)."""
    queries = {c.symbol for c in commands if c.op == Op.QUERY}
    return bool(queries & set(grammar.written_symbols))


class Answerer:
    """The turtle that answers derivation between its steps (the ``between`` of
    :func:`~lsys3d.lsystem.derive.derive`): fills the string's query modules and removes what the
    environment cut.

    Given the ``grammar`` it derives, one answerer serves one derivation: it follows derivation's changes
    (:meth:`trace`) and its next pass re-reads only what changed (:mod:`lsys3d.turtle.incremental`).
    Without it, every call reads the whole string.
    """

    def __init__(
        self,
        turtle: TurtleOptions,
        commands: tuple[Command, ...],
        seed: int,
        environment: Environment | None = None,
        *,
        max_segments: int = DEFAULT_MAX_SEGMENTS,
        grammar: Grammar | None = None,
        steering: SteeringMemo | None = None,
    ):
        self.turtle = turtle.replace(branch_drop=0.0)
        self.commands = commands
        self.seed = seed
        self.environment = environment
        self.max_segments = max_segments
        self.scene = environment.scene() if environment is not None else NO_SCENE
        self.config = turtle_config(self.turtle)
        self.grammar = grammar
        o = self.turtle
        varied = o.angle_jitter > 0 or o.length_jitter > 0 or o.width_jitter > 0 or o.branch_roll > 0
        # the natural variation's numbers follow the index; the plant's shade changes every answer
        self.shading = environment is not None and environment.options.shadow
        self.follow = grammar is not None and not varied and not self.shading
        self.varied = varied
        self._tables: dict = {}
        self._last: tuple | None = None  # the alphabet of the last pass (the same tuple each step) and its tables
        self._unvaried: kernel.Variation | None = None  # no natural variation: the same empty arrays each pass
        self._table = None  # the symbol table of the last pass
        self._asked: tuple | None = None  # a table, and whether the environment answers a query module of it
        self._counts: np.ndarray | None = None  # the modules of each op of the string derivation has, when known
        self._depth = 0  # and the most brackets deep it can be
        self._nesting = 0  # the most brackets deeper one rewrite makes the string
        # origin[i]: the index, in the last pass's string, of the module i copies (-1: produced since);
        # None: unknown; empty: the last pass's string itself, its modules unchanged
        self.origin: np.ndarray | None = None
        self._records = None  # the last pass's string's symbols, and the states it recorded (positions, states)
        # the arrays passes record in, in turn: the last pass's records, and room for the next pass's (reused, so
        # a pass writes its records in memory already paged in)
        self._record_room = [(_WHOLE, np.zeros((0, incremental.STATE))), (_WHOLE, np.zeros((0, incremental.STATE)))]
        self.steering = steering if environment is not None else None  # where its steerings are kept
        # derivation made the string of the next pass in this step (trace was told): its arrays are its own,
        # held by no string derivation gave out, so the answers are written into its parameters, not a copy
        self._fresh = False
        self._changes = _WHOLE  # where the changes of the one production step since the last pass start (trace)
        self._cut_room = _WHOLE  # the segments a pass cuts (reused by the passes)
        self._found = np.zeros(6, np.int64)  # what a pass found, counted
        self._carried = False  # whether the lean pass carried out the last string (carries_out)

    def _compiled(self, alphabet) -> tuple[SymbolTable, kernel.Program, np.ndarray, bool, tuple, bool, tuple]:
        if self._last is not None and self._last[0] is alphabet:  # no hashing of its 256 names each step
            return self._last[1]
        found = self._tables.get(alphabet)
        if found is None:
            t = self.turtle
            table = symbol_table(alphabet, t.draw, t.move, t.leaf, self.commands)
            recorded = np.zeros(256, np.bool_)  # the symbols a rule may rewrite: their states are kept
            follow = False
            g = self.grammar
            if self.follow:
                code = {ch: i for i, ch in enumerate(alphabet) if ch != "\0"}

                def op_of(symbol: str) -> Op:
                    return Op(int(table.op[code[symbol]])) if symbol in code else Op.NONE

                follow = incremental.follows(g, op_of)
                for prod in (*g.productions, *g.decomposition_productions):
                    if prod.predecessor.symbol in code:
                        recorded[code[prod.predecessor.symbol]] = True
                if g.cut_symbol and g.cut_symbol in code:
                    recorded[code[g.cut_symbol]] = True
            counted = follow and _counted(g, table, code)
            if counted:
                self._nesting = _nesting(g, op_of)
            recorded_ops = tuple(np.unique(table.op[recorded]).tolist())  # their counts bound the records
            found = (table, kernel_program(table), recorded, follow, answering(table), counted, recorded_ops)
            self._tables[alphabet] = found
        self._last = (alphabet, found)
        return found

    def trace(self, kind, symbols, new_symbols, rewritten, lengths, persisting) -> None:
        """Follow one change derivation made to the string (:data:`lsys3d.lsystem.derive.Trace`)."""
        first = not self._fresh  # the first change since the last pass
        self._fresh = True  # (derivation tells of a change as it makes the new string's arrays)
        self._changes = _WHOLE
        if self.origin is None:
            self._counts = None
            return
        if kind == CUT:
            self._counts = None
            if self._table is None or _removes_polygons(self._table, symbols, rewritten):
                self.origin = None
            else:
                self.origin = incremental.follow_cut(self.origin, rewritten)
        else:
            counts = self._counts if self._counts is not None else _NO_COUNTS
            op = self._table.op if self._table is not None else _NO_OPS
            # one production step from the last pass's string: where its changes start, for the pass to jump to
            changes = np.empty(np.count_nonzero(rewritten) + 1, np.int64) if first and not len(self.origin) else _WHOLE
            self.origin = incremental.follow_production(
                self.origin, rewritten, lengths, op, symbols, new_symbols, counts, changes
            )
            self._changes = changes
            if self._counts is not None:
                self._depth += self._nesting

    trace.persisting = False  # (derivation need not build that mask for it)

    def __call__(self, modules: ModuleString, step: int = 0) -> ModuleString:
        """The string with its query modules filled and the branches the environment cut removed."""
        table, program, recorded, follow, answers, counted, _ = self._compiled(modules.alphabet)
        self._table = table
        fresh, self._fresh = self._fresh, False
        changes, self._changes = self._changes, _WHOLE
        arrays = kernel.Modules(modules.symbols, modules.arity, modules.offsets, modules.params)
        if counted and self._counts is not None and self.origin is not None:
            # derivation's changes were counted (trace): the string needs no survey (what it checks, the
            # rules cannot write: _counted), only its limit; nor can they write an op the lean pass does not carry
            # out (they are surveyed ops), so a string it carried out is followed by one it carries out
            counts, max_depth = self._counts, self._depth
            check_segments(int(counts[Op.FORWARD]), self.max_segments)
            carried = self._carried or incremental.carries_out(counts, self.turtle)
        else:
            counts, max_depth = surveyed(modules, table, program, arrays, self.max_segments)
            carried = incremental.carries_out(counts, self.turtle)
        self._carried = carried
        m = len(modules)
        origin, records = self.origin, self._records
        if not follow or counts[Op.RANDOM_TURN] or origin is None or records is None:
            origin, records = _WHOLE, None
        elif not len(origin):  # derivation changed nothing
            origin = np.arange(m) if len(records[0]) == m else None
        if origin is None or (len(origin) and len(origin) != m):
            origin, records = _WHOLE, None
        if self.varied or counts[Op.RANDOM_TURN]:
            variation = natural_variation(
                m, self.turtle, self.seed, table, modules.symbols, int(counts[Op.RANDOM_TURN])
            )
        else:
            if self._unvaried is None:
                self._unvaried = natural_variation(0, self.turtle, self.seed, table, modules.symbols[:0], 0)
            variation = self._unvaried
        args = (modules, table, program, arrays, max_depth, variation, recorded, counts)
        steering, steerings = self.steering, None
        if not carried:  # the turtle that draws them answers
            follow = False
            found = self._full_pass(modules)
            if steering is not None:
                steering.reset(self.scene)
        else:
            if steering is not None and (not len(origin) or steering.full):
                steering.reset(self.scene)  # a pass over the whole string: it steers every segment again
            found = self._pass(*args, origin, records, fresh, changes if len(origin) else _WHOLE)
            if found is None:  # a change the records cannot follow: the whole string
                if steering is not None:
                    steering.reset(self.scene)
                found = self._pass(*args, _WHOLE, None, fresh, _WHOLE)
            steerings, found = found[-1], found[:-1]
        query_module, query_state, cut, positions, states, deposits, answered = found
        out, origin = _written(
            modules, table, query_module, query_state, cut, self.environment, deposits, answers, answered
        )
        if steering is not None and steerings is not None:
            steering.add(*steerings, origin)
        elif steering is not None:
            steering.add(0, _WHOLE, _WHOLE, None)  # not followed: off until a pass over the whole string
        self._records = (modules.symbols, positions, states) if follow else None
        self.origin = origin if follow else None
        # the counts of the string returned (a cut removed modules: the next pass surveys its string)
        self._counts = counts.copy() if counted and follow and origin is not None and not len(origin) else None
        self._depth = max_depth
        return out

    def _full_pass(self, modules):
        """The answers from the turtle that draws (:func:`~lsys3d.turtle.interpret.interpret_answering`): for
        the strings the lean pass does not carry out (:func:`lsys3d.turtle.incremental.carries_out`)."""
        skeleton, found = interpret_answering(
            modules,
            self.turtle,
            self.seed,
            max_segments=self.max_segments,
            commands=self.commands,
            scene=None if self.environment is None else self.scene,
        )
        deposits = None
        if self.shading:
            mid = 0.5 * (skeleton.start + skeleton.end)
            area = np.linalg.norm(skeleton.end - skeleton.start, axis=1) * skeleton.width_start
            leaves = np.column_stack([skeleton.leaf_position, skeleton.leaf_size**2])
            deposits = np.concatenate([np.column_stack([mid, area]), leaves])
        return found.module, found.state, found.cut, _WHOLE, np.zeros((0, incremental.STATE)), deposits, None

    def _environment_asked(self, table: SymbolTable, first: np.ndarray) -> bool:
        """Whether the alphabet has a query module the environment answers (``?E``), asked once per table."""
        if self._asked is None or self._asked[0] is not table:
            self._asked = (table, bool((first[table.op == Op.QUERY] < 0).any()))
        return self._asked[1]

    def _pass(
        self, modules, table, program, arrays, max_depth, variation, recorded, counts, origin, records, fresh, changes
    ):
        n_query = int(counts[Op.QUERY])
        # the answers from the turtle's state are written into the parameters as the pass meets them: into the
        # string's own when derivation just made them (``fresh``: no other string holds them), else into a copy
        # (a pass that loses track and one over the whole string after it write the same answers where they read)
        if fresh and n_query and modules.params.flags.owndata:
            modules.params.setflags(write=True)
            answered = modules.params.view()  # (a view that writes: the string's array stays read-only)
            modules.params.setflags(write=False)
        else:
            answered = modules.params.copy() if n_query else _NO_PARAMS
        compiled = self._compiled(modules.alphabet)
        first, sign, slots = compiled[4]
        listed = n_query if not len(answered) or self._environment_asked(table, first) else 0  # (only ?E then)
        query_module = np.empty(listed, np.int64) if listed else _WHOLE
        query_state = np.empty((listed, 12)) if listed else _NO_STATES
        n_forward = int(counts[Op.FORWARD]) if self.environment is not None else 0
        if len(self._cut_room) < n_forward:  # (reused: the cut segments found are read before the next pass)
            self._cut_room = np.empty(max(n_forward, 2 * len(self._cut_room)), np.int64)
        cut = self._cut_room[:n_forward]
        # at most: the modules of the ops of the symbols a rule may rewrite, and the cut segments
        n_records = sum(int(counts[op]) for op in compiled[6]) + n_forward
        positions, states = self._record_room[1]
        if len(positions) < n_records:
            size = max(n_records, 2 * len(positions))
            positions, states = self._record_room[1] = (np.empty(size, np.int64), np.empty((size, incremental.STATE)))
        found = self._found
        deposits = np.empty((int(counts[Op.FORWARD] + counts[Op.LEAF]), 4)) if self.shading else _NO_DEPOSITS
        memo = self.steering
        steerings = memo.room(len(cut)) if memo is not None else None
        remembering = steerings is not None
        if not remembering:
            steerings = _NO_ROWS
        steered_at, steered_row = memo.segments(len(cut)) if remembering else (_WHOLE, _WHOLE)
        old_at = memo.steered_at if remembering and records is not None else _WHOLE
        old_row = memo.steered_row if remembering and records is not None else _WHOLE
        if records is None:
            old_symbols, old_positions, old_states = modules.symbols[:0], _WHOLE, states[:0]
        else:
            old_symbols, old_positions, old_states = records
        status, bad = incremental.answer_pass(
            program,
            arrays,
            self.config,
            variation,
            max_depth,
            self.scene,
            recorded,
            _NEUTRAL,
            origin,
            changes,
            old_symbols,
            old_positions,
            old_states,
            len(old_positions),
            query_module,
            query_state,
            cut,
            positions,
            states,
            found,
            deposits,
            first,
            sign,
            slots,
            answered,
            steerings,
            memo.count if remembering else 0,
            old_at,
            old_row,
            steered_at,
            steered_row,
        )
        if status == incremental.FOLLOW_LOST:
            return None
        if status != kernel.OK:
            raise module_error(modules, table, int(bad), kernel.MESSAGES[status])
        self._record_room.reverse()  # this pass's records are the last pass's now
        n_query, n_cut, n_rec, n_dep, n_steer, n_at = found.tolist()
        return (
            query_module[:n_query],
            query_state[:n_query],
            cut[:n_cut],
            positions[:n_rec],
            states[:n_rec],
            deposits[:n_dep] if self.shading else None,
            answered if len(answered) else None,
            (n_steer, steered_at[:n_at], steered_row[:n_at]) if remembering else None,
        )


def _counted(grammar: Grammar, table: SymbolTable, code: dict) -> bool:
    """Whether the counts of the string's ops can follow derivation (:meth:`Answerer.trace`) instead of a survey
    each step: no rule writes an op of :data:`_SURVEYED`, or more arguments than its symbol takes (what the
    survey checks: the parameters derivation writes are finite, it checks them itself)."""
    for prod in (*grammar.productions, *grammar.decomposition_productions):
        for module in prod.successor:
            c = code.get(module.symbol)
            op = int(table.op[c]) if c is not None else -1
            if op < 0 or op in _SURVEYED or (op != Op.NONE and len(module.args) > int(table.max_args[c])):
                return False
    return True


def _nesting(grammar: Grammar, op_of) -> int:
    """The most brackets deep a successor goes (a bound on how much deeper one rewrite makes the string)."""
    most = 0
    for prod in (*grammar.productions, *grammar.decomposition_productions):
        depth = 0
        for module in prod.successor:
            op = op_of(module.symbol)
            depth += (op == Op.PUSH) - (op == Op.POP)
            most = max(most, depth)
    return most


def answering(table: SymbolTable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`lsys3d.turtle.incremental.write_answers` writes for each symbol of ``table``: the first of the
    three state numbers (-1: ``?E``, or no query), their sign, the parameters they go to."""
    first = np.full(256, -1, np.int64)
    sign = np.ones(256, np.float64)
    for code in np.flatnonzero(table.op == Op.QUERY).tolist():
        cmd = table.command(code)
        if cmd.query in _SLICES:
            first[code], sign[code] = _SLICES[cmd.query]
    return first, sign, np.ascontiguousarray(table.world, np.int64)


def _removes_polygons(table: SymbolTable, symbols: np.ndarray, keep: np.ndarray) -> bool:
    return bool(np.isin(table.op[symbols[~keep]], _POLYGON_OPS).any())


def _written(
    modules, table, query_module, query_state, cut, environment, deposits=None, answers=None, answered=None
) -> tuple[ModuleString, np.ndarray | None]:
    """The string with the answers written and the cut branches removed, and where its modules came from
    (:attr:`Answerer.origin`: empty when no module was removed; -1 for a bud; None when a polygon was cut).
    With ``deposits`` (the plant's area, :mod:`lsys3d.turtle.shadow`), ``?E``'s light is shaded by it;
    ``answers`` is :func:`answering`'s of the table, when known; ``answered``, when given, the parameters with
    the answers from the turtle's state already written (``query_module`` then lists only the others)."""
    params = modules.params
    if answered is not None:
        params = answered
        first = (answering(table) if answers is None else answers)[0]
    elif len(query_module):
        params = params.copy()
        first, sign, slots = answering(table) if answers is None else answers
        incremental.write_answers(
            params, modules.symbols, modules.offsets, modules.arity, query_module, query_state, first, sign, slots
        )
    if len(query_module):
        codes = modules.symbols[query_module]
        asked = first[codes] < 0  # ?E: the environment answers
        if asked.any():
            state = query_state[asked][:, :3]
            if environment is not None:
                values = environment.probe(state)
                if deposits is not None:
                    values[:, 2] *= shade(deposits, state, environment.options)
            else:  # nothing blocks, no surface near, full light
                values = np.tile([0.0, FAR_OUTSIDE, 1.0], (len(state), 1))
            offsets = modules.offsets[query_module[asked]]
            arity = modules.arity[query_module[asked]].astype(np.int64)
            for slot in (0, 1, 2):
                has = arity > slot
                params[offsets[has] + slot] = values[has, slot]
    symbols, arity_all = modules.symbols, modules.arity
    if not len(cut):
        same = params is modules.params or params.base is modules.params  # (answered in the string's own)
        out = modules if same else modules.with_params(params)
        return out, _WHOLE
    keep = cut_mask(table.op[symbols] == Op.PUSH, table.op[symbols] == Op.POP, cut)
    bud = environment.options.bud if environment is not None else ""
    code = modules.code(bud) if bud else -1
    origin = np.arange(len(modules))
    removes_polygons = _removes_polygons(table, symbols, keep)
    if code >= 0:  # the cut module becomes the bud, without parameters
        symbols = symbols.copy()
        arity_all = arity_all.copy()
        symbols[cut] = code
        keep[cut] = True
        drop = np.zeros(len(modules), bool)
        drop[cut] = True
        params = params[np.repeat(keep & ~drop, modules.arity.astype(np.int64))]
        arity_all[cut] = 0
        origin[cut] = -1
    else:
        params = params[np.repeat(keep, modules.arity.astype(np.int64))]
    out = ModuleString(symbols[keep], arity_all[keep], params, modules.alphabet)
    return out, None if removes_polygons else origin[keep]


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
    return Answerer(turtle, commands, seed, environment, max_segments=max_segments)(modules)


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
    steering: SteeringMemo | None = None,
) -> ModuleString:
    """:func:`~lsys3d.lsystem.derive.derive`, with the turtle answering between the steps when it is asked.

    The turtle answers (:func:`answer`) when the grammar writes query modules or an environment is
    given; otherwise this is plain derivation.  ``max_segments`` limits each of the turtle's passes.
    ``steering`` (an empty :class:`~lsys3d.turtle.steering.SteeringMemo`) receives how the environment
    steered the segments, for :func:`~lsys3d.turtle.interpret.interpret` to draw the string without
    steering them again (given the same ``steering`` and the environment's scene).
    """
    seed = grammar.seed if seed is None else seed
    if commands is None:
        commands = dialects.get(grammar.dialect).commands
    if environment is None and not asks_turtle(grammar, commands):
        return derive(grammar, iterations, seed, max_modules=max_modules)
    turtle = turtle or TurtleOptions.from_grammar(grammar)

    between = Answerer(
        turtle, commands, seed, environment, max_segments=max_segments, grammar=grammar, steering=steering
    )
    return derive(grammar, iterations, seed, max_modules=max_modules, between=between)
