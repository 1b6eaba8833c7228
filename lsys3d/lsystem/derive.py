"""Parallel rewriting: Grammar -> ModuleString.

Two engines, one result:

* **Block expansion** for deterministic, context-free, parameterless grammars
  (D0L systems such as ABOP figure 1.24): the expansion of each symbol after
  ``k`` steps is built once from the expansions after ``k - 1`` steps and
  reused wherever that symbol occurs, so the final string is assembled by
  copying large blocks of memory.
* **Vectorised rewriting** for everything else (parametric, stochastic,
  conditional, context-sensitive): one generation at a time, modules are
  grouped by predecessor, conditions and successor parameters are evaluated
  with numpy over all matching modules at once, and the output is scattered
  into preallocated arrays.  Context is matched through skip tables built
  once per generation (bracket matches, the next module that is not ignored,
  the end of the current branch), so each module's context costs the length
  of its pattern, not of the string.

Size: each generation's module and parameter counts are known before its
arrays are allocated (for grammars whose lengths depend on nothing but the
symbols, before any work, from the modules the axiom can reach), and only
one generation is alive at a time.

Stochastic choice draws, for generation ``g`` and rule pool ``p`` of symbol
``s``, a stream seeded with ``(seed, g, s, p)``: the k-th module rewritten by a
pool takes the k-th number of its stream.  Changing one pool's weights thus
leaves every other pool's choices alone.  The grammar's random functions take
counter-based numbers keyed by the seed, the step, their place in the grammar
and the module's position (:func:`lsys3d.streams.hashed_uniform`).

A step is: cut (the dialect's cut symbol, ``%``, removes itself and the rest of
its branch, as L-Py and cpfg do when they meet it), rewrite with the
productions, then the decomposition rules up to ``decomposition_depth`` times
(each time only what the previous time produced, as L-Py recurses into a
successor).  :func:`interpretation` applies the homomorphism rules the same
way to the derived string, for the turtle only.
"""

from __future__ import annotations

import logging
import math
from collections import Counter, deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..arrays import ranges
from ..compiling import kernel
from ..errors import DerivationError, LimitError, clip
from ..streams import Stream, hashed_uniform, rule_generator
from . import dialects, sequences
from .expr import NOT_FINITE, STEP, EvalError, RandomDraws
from .grammar import Grammar, PatternModule, Production
from .modules import ModuleString
from .rules import MAX_LOOP, _flat
from .walks import right_plain, skip_tables, walk_right

__all__ = [
    "DEFAULT_MAX_MODULES",
    "MAX_ITERATIONS",
    "PARAMETER_COST",
    "Trace",
    "derive",
    "generations",
    "interpretation",
    "predict_counts",
    "predict_length",
]

log = logging.getLogger("lsys3d")

DEFAULT_MAX_MODULES = 50_000_000
"""Largest module string derivation builds (about 50 bytes a module at the peak)."""
PARAMETER_COST = 0.4
"""What one parameter counts for against ``max_modules``, in modules (measured peak bytes per parameter
over peak bytes per module): ``modules + PARAMETER_COST * parameters`` may not exceed the limit."""
MAX_ITERATIONS = 10_000
"""Most generations one derivation runs: a string that stops growing would otherwise rewrite forever.

Raise it by assigning ``lsys3d.lsystem.derive.MAX_ITERATIONS``.
"""

_OPEN, _CLOSE = ord("["), ord("]")


@dataclass
class _Pool:
    """Rules sharing predecessor, arity, contexts and condition: stochastic alternatives."""

    pool_id: int
    code: int
    arity: int
    left: tuple[PatternModule, ...]
    right: tuple[PatternModule, ...]
    condition: object
    alternatives: list[Production]
    cumulative: np.ndarray | None = None  # cumulative weights when stochastic
    steps: tuple = ()  # a condition with local variables: ("let", name, expr) and ("test", expr)
    following: tuple = ()  # the rest of a predecessor of several modules (cpfg: lsystem.sequences)
    lsystem: int = -1  # the sub-L-system whose modules the rules rewrite (cpfg's ?(n) ... $), -1: the main one


class _Plan:
    """One group of the grammar's rules arranged for rewriting: pools per symbol code, in rule order."""

    def __init__(self, grammar: Grammar, productions: tuple[Production, ...] | None = None):
        self.grammar = grammar
        self.alphabet = grammar.alphabet
        self.code = {ch: i for i, ch in enumerate(grammar.alphabet) if ch != "\0" or i == 0}
        if grammar.considered is not None:  # consider: every other symbol is ignored (never brackets)
            self.ignore = frozenset(
                i for ch, i in self.code.items() if ch not in grammar.considered and ch not in ("[", "]", "\0")
            )
        else:
            self.ignore = frozenset(self.code[c] for c in grammar.ignored if c in self.code)
        productions = grammar.productions if productions is None else productions
        pools: dict[tuple, _Pool] = {}
        self.pools_by_code: dict[int, list[_Pool]] = {}
        pooled = dialects.get(grammar.dialect).notation.unweighted_alternatives
        for prod in productions:
            key = prod.pool_key()
            if prod.weight is None and not pooled:  # the first rule that matches applies (L-Py, cpfg...)
                key = (*key, prod.index)
            if key not in pools:
                code = self.code[prod.predecessor.symbol]
                pool = _Pool(
                    len(pools),
                    code,
                    len(prod.predecessor.formals),
                    prod.left,
                    prod.right,
                    prod.condition,
                    [],
                    steps=prod.steps,
                    following=prod.following,
                    lsystem=prod.lsystem,
                )
                pools[key] = pool
                self.pools_by_code.setdefault(code, []).append(pool)
            pools[key].alternatives.append(prod)
        for pool in pools.values():
            if len(pool.alternatives) > 1:
                w = np.array([p.weight if p.weight is not None else 1.0 for p in pool.alternatives])
                # scaled by a power of two (exact, so the choices are those of the unscaled weights) to
                # the largest in [0.5, 1): finite weights whose sum would overflow stay finite
                pool.cumulative = np.cumsum(np.ldexp(w, -math.frexp(float(w.max()))[1]))
        self.random = any(p.random for p in productions)
        self.stochastic = self.random or any(p.cumulative is not None for p in pools.values())
        self.context = any(p.left or p.right for p in pools.values())
        self.ignored = np.zeros(256, np.bool_)  # the symbols context matching skips, by code
        self.ignored[list(self.ignore)] = True
        self.plain_right: dict = {}  # the right contexts' codes and arities, by pattern's id (_Context.right)
        self.sequences = any(p.following for p in pools.values())
        # cpfg's sub-L-systems: which L-system's rules rewrite a module depends on the ?(n) and $ before it
        self.lsystems = grammar.lsystem_main >= 0
        cut = grammar.cut_symbol
        self.cut = self.code[cut] if cut and cut in grammar.written_symbols else -1
        # every module's successor length is known from its symbol and arity alone (and no cut or
        # decomposition changes it afterwards)
        self.predictable = (
            not self.context
            and not self.sequences
            and not self.lsystems
            and self.cut < 0
            and not grammar.decomposition_productions
            and all(p.cumulative is None and p.condition is None and not p.steps for p in pools.values())
        )
        self.d0l = self.predictable and not grammar.parametric and not self.random


def _succ_codes(plan: _Plan, prod: Production) -> np.ndarray:
    return np.array([plan.code[m.symbol] for m in prod.successor], dtype=np.uint8)


# ---------------------------------------------------------------- public API
def predict_length(grammar: Grammar, iterations: int | None = None) -> int | None:
    """Exact module count after ``iterations`` steps, or None when it depends on the derivation.

    Known for grammars without contexts, conditions and stochastic choice
    (parameters allowed: a successor's length does not depend on their values).
    Computed from the growth (Parikh) matrix of the modules the axiom can
    reach, so it costs nothing even when the answer is astronomically large;
    counts from ``2**53`` up are not exact and are returned as ``2**53``.

    >>> from lsys3d import Grammar
    >>> predict_length(Grammar(axiom="A(1)", rules=["A(x) -> A(x)A(x + 1)"]), 40)
    1099511627776
    """
    plan = _Plan(grammar)
    if not plan.predictable:
        return None
    n = _check_iterations(grammar, iterations)
    return int(_growth(plan, n).modules[-1])


def predict_counts(grammar: Grammar, iterations: int | None = None) -> dict[str, int] | None:
    """How many modules of each symbol ``iterations`` steps make, or None when it depends on the derivation.

    Known for the same grammars as :func:`predict_length`, from the same growth
    (Parikh) matrix of the (symbol, arity) pairs the axiom reaches, in floating
    point: exact while a count stays below 2**53, then capped, so it costs next
    to nothing for any size.

    >>> from lsys3d import Grammar
    >>> predict_counts(Grammar(axiom="X", rules=["X -> F[+X]F[-X]+X", "F -> FF"]), 2)
    {'+': 8, '-': 4, 'F': 10, 'X': 9, '[': 8, ']': 8}
    """
    plan = _Plan(grammar)
    if not plan.predictable:
        return None
    n = _check_iterations(grammar, iterations)
    growth = _growth(plan, n)
    out: dict[str, int] = {}
    for code, count in zip(growth.last_code.tolist(), growth.last.tolist(), strict=True):
        if count:
            symbol = plan.alphabet[code]
            out[symbol] = out.get(symbol, 0) + int(count)
    return dict(sorted(out.items()))


def derive(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    start: ModuleString | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
    between: Callable[[ModuleString, int], ModuleString] | None = None,
) -> ModuleString:
    """Rewrite the axiom ``iterations`` times (default: the grammar's own).

    Parameters
    ----------
    grammar : Grammar
    iterations : int, optional
        Number of parallel rewriting steps; ``grammar.iterations`` if None.
    seed : int, optional
        Seed of stochastic choices; ``grammar.seed`` if None.
    start : ModuleString, optional
        Rewrite this string instead of the axiom (e.g. a result of an earlier call).
    max_modules : int
        Refuse (before allocating) to build a string longer than this.
    between : callable, optional
        ``between(string, step) -> string``, called on the string before each step and on the last
        string (``step`` the number of steps made so far): an open L-system's environment, here the
        turtle that fills query modules (:mod:`lsys3d.turtle.query`). The string it returns goes on.
        A ``between`` with a ``trace`` method (a :data:`Trace`) is told of every change derivation makes
        to the string it returned, so it can re-read only what changed.

    Raises
    ------
    LimitError
        The result would exceed ``max_modules`` (the message gives its size).
    DerivationError
        A numeric error in a condition or parameter, naming rule and module.

    Examples
    --------
    >>> from lsys3d import Grammar
    >>> str(derive(Grammar(axiom="A", rules=["A -> AB", "B -> A"]), 4))
    'ABAABABA'
    """
    n = _check_iterations(grammar, iterations)
    plan = _Plan(grammar)
    if (
        plan.predictable and start is None and between is None
    ):  # fail at once, not after building the generations below the limit
        growth = _growth(plan, n, presence=plan.d0l)
        _check_size(growth.modules[n], growth.params[n], max_modules, grammar, n)
        if plan.d0l:  # builds no generation but the last
            return _derive_d0l(plan, n, growth)
        cost = growth.modules + PARAMETER_COST * growth.params
        if (cost > max_modules).any():
            g = int(np.argmax(cost > max_modules))
            _check_size(growth.modules[g], growth.params[g], max_modules, grammar, g)
    # the last generation; a deque of one keeps no other alive
    return deque(generations(grammar, n, seed, start=start, max_modules=max_modules, between=between), maxlen=1).pop()


def generations(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    start: ModuleString | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
    between: Callable[[ModuleString, int], ModuleString] | None = None,
    trace: Trace | None = None,
) -> Iterator[ModuleString]:
    """Yield the axiom (or ``start``) and then every generation up to ``iterations``, one at a time.

    ``trace``, when given, is called at every change of the string with where each new module came from
    (:data:`Trace`; :mod:`lsys3d.lsystem.ages` follows the modules' ages with it).

    >>> from lsys3d import Grammar
    >>> [str(s) for s in generations(Grammar(axiom="D", rules=["D = DGD"]), 2)]
    ['D', 'DGD', 'DGDGDGD']
    """
    n = _check_iterations(grammar, iterations)
    seed = grammar.seed if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DerivationError(f"seed must be a whole number >= 0, not {clip(repr(seed))}")
    plan = _Plan(grammar)
    current = grammar.axiom_modules if start is None else start
    if current.alphabet != plan.alphabet and current.alphabet[128:] != plan.alphabet[128:]:
        raise DerivationError("the start string uses symbols this grammar does not know")
    _check_size(len(current), len(current.params), max_modules, grammar, 0)
    if start is not None:
        _check_finite_start(current)
    if between is not None and trace is not None:  # its cuts and fillings are no rewriting the trace could follow
        raise DerivationError("generations: a trace cannot follow what 'between' changes in the string")
    if between is not None:  # a between that follows the changes (to re-read only what changed) is told of them
        trace = getattr(between, "trace", None)
    if between is not None:
        current = between(current, 0)
    yield current
    decompose = _Plan(grammar, grammar.decomposition_productions) if grammar.decomposition_productions else None
    # cpfg's StartEach/EndEach blocks: the globals each step reads (lsystem.blocks), none without them
    steps = _block_values(grammar, n, seed)[0]
    fixed = False
    for g in range(1, n + 1):
        if not fixed:
            previous = current
            current = previous if plan.cut < 0 else _cut(previous, plan.cut, trace)
            variables = steps[g - 1] if steps else None
            if plan.pools_by_code:
                current = _step(
                    plan,
                    current,
                    (_PRODUCTION, g),
                    int(seed),
                    max_modules,
                    g,
                    step_number=g - 1,
                    trace=trace,
                    variables=variables,
                )[0]
            if decompose is not None:
                current = _passes(
                    decompose,
                    current,
                    grammar.decomposition_depth,
                    _DECOMPOSITION,
                    g,
                    seed,
                    max_modules,
                    step_number=g - 1,
                    variables=variables,
                    trace=trace,
                )
            log.debug("generation %d: %d modules", g, len(current))
            if between is not None:
                current = between(current, g)
            # without chance, a string that rewrites to itself stays itself: the rest is this string
            # (unless the globals the rules read change from step to step)
            fixed = (
                not (plan.stochastic or (decompose is not None and decompose.stochastic) or steps)
                and current == previous
            )
            del previous
        yield current


def interpretation(
    grammar: Grammar,
    modules: ModuleString,
    seed: int | None = None,
    *,
    max_modules: int = DEFAULT_MAX_MODULES,
    iterations: int | None = None,
    trace: Trace | None = None,
) -> ModuleString:
    """The string the turtle reads: ``modules`` cut and rewritten by the homomorphism rules (if any).

    Homomorphism (interpretation) rules apply after derivation, up to
    ``grammar.homomorphism_depth`` times (each time to what the previous time
    produced), and their result is never fed back into the derivation.
    ``iterations`` is how many steps derived ``modules`` (default: the
    grammar's): in these rules L-Py's ``getIterationNb()`` is the last step's
    number, ``iterations - 1`` (0 after none), as in L-Py, whose
    interpretation runs after the derivation's last step set it.

    >>> from lsys3d import Grammar, derive
    >>> g = Grammar(axiom="A", rules=["A -> AB"], homomorphism=["B -> F+"], iterations=2)
    >>> str(derive(g)), str(interpretation(g, derive(g)))
    ('ABB', 'AF+F+')
    """
    seed = grammar.seed if seed is None else seed
    plan = _Plan(grammar, grammar.homomorphism_productions)
    if plan.cut >= 0:
        modules = _cut(modules, plan.cut, trace)
    if plan.pools_by_code:
        if modules.alphabet != plan.alphabet and modules.alphabet[128:] != plan.alphabet[128:]:
            raise DerivationError("the string uses symbols this grammar does not know")
        n = grammar.iterations if iterations is None else iterations
        last = max(int(n) - 1, 0) if isinstance(n, (int, np.integer)) else 0
        final = _block_values(grammar, int(n), seed)[1] if grammar.program is not None else None
        modules = _passes(
            plan,
            modules,
            grammar.homomorphism_depth,
            _HOMOMORPHISM,
            0,
            seed,
            max_modules,
            step_number=last,
            variables=final,
            trace=trace,
        )
        if plan.cut >= 0:
            modules = _cut(modules, plan.cut, trace)
    return modules


_PRODUCTION, _DECOMPOSITION, _HOMOMORPHISM = 0, 1, 2
PRODUCTION, CUT = _PRODUCTION, -1
"""The kinds of change a :data:`Trace` is told of: a production step, the cut (decomposition and homomorphism
passes are the other kinds, instantaneous rewrites)."""

Trace = Callable[[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None], None]
"""``trace(kind, symbols, new_symbols, rewritten, lengths, persisting)``: a change of the string whose
modules had ``symbols`` into one whose modules have ``new_symbols``.  For a cut (``kind == CUT``),
``rewritten`` is the mask of the modules kept and the other two are None.  Otherwise ``rewritten`` is the
mask of the old string's modules a rule rewrote, ``lengths`` how many modules each old module became (1
when copied), and ``persisting`` the mask of the new string's modules that continue their predecessor: in a
successor, the first module at bracket depth 0 with the predecessor's own symbol (``F(l) -> F(l*r)``: the
same internode, grown; ``A -> AB``: the apex stays, ``B`` is new).  A trace with an attribute ``persisting``
that is False (set on the function) is given None instead: it does not read it, and the mask is not built."""


def persisting_index(prod: Production) -> int:
    """The successor module that continues the predecessor (see :data:`Trace`), or -1.

    >>> from lsys3d import Grammar
    >>> [persisting_index(p) for p in Grammar(axiom="A", rules=["A -> [A]B", "B -> FB", "F -> G"]).productions]
    [-1, 1, -1]
    """
    depth = 0
    for j, module in enumerate(prod.successor):
        if module.symbol == "[":
            depth += 1
        elif module.symbol == "]":
            depth -= 1
        elif depth == 0 and module.symbol == prod.predecessor.symbol:
            return j
    return -1


_PHASE = {_PRODUCTION: "generation", _DECOMPOSITION: "decomposition of generation", _HOMOMORPHISM: "homomorphism"}


def _block_values(grammar: Grammar, n: int, seed) -> tuple[list[dict], dict | None]:
    """The globals of cpfg's blocks that change during the derivation: per step, and after the end."""
    program = grammar.program
    if program is None or not program.step_names:
        return [], None
    steps, final = program.steps(n, int(seed))
    keep = program.step_names
    return [{k: v for k, v in s.items() if k in keep} for s in steps], {k: v for k, v in final.items() if k in keep}


def _passes(
    plan: _Plan,
    ms: ModuleString,
    depth: int,
    kind: int,
    generation: int,
    seed,
    max_modules,
    *,
    step_number: int,
    variables: dict | None = None,
    trace: Trace | None = None,
) -> ModuleString:
    """Rewrite ``ms`` with ``plan`` up to ``depth`` times, each time only the modules the previous time produced."""
    eligible = None
    for d in range(depth):
        out, produced = _step(
            plan,
            ms,
            (kind, generation, d),
            int(seed),
            max_modules,
            generation,
            eligible,
            step_number=step_number,
            variables=variables,
            trace=trace,
        )
        if produced is None:  # nothing matched
            break
        ms, eligible = out, produced
    return ms


@kernel(nogil=True)
def cut_mask(is_open, is_close, starts):
    """The modules kept when each of ``starts`` removes itself and the rest of its branch (up to its ``]``):
    ABOP's ``%``, and the turtle's cuts by an environment (:mod:`lsys3d.turtle.query`).  ``is_open`` and
    ``is_close`` mark the brackets; a start inside a branch already cut adds nothing."""
    m = is_open.shape[0]
    keep = np.ones(m, np.bool_)
    i = 0
    for s in np.sort(starts):
        if s < i:  # inside the branch the previous start cut
            continue
        depth = 0
        i = s
        while i < m:
            if is_open[i]:
                depth += 1
            elif is_close[i]:
                if depth == 0:
                    break
                depth -= 1
            keep[i] = False
            i += 1
    return keep


def _cut(ms: ModuleString, cut: int, trace: Trace | None = None) -> ModuleString:
    if not (ms.symbols == cut).any():
        return ms
    symbols = ms.symbols
    keep = cut_mask(symbols == _OPEN, symbols == _CLOSE, np.flatnonzero(symbols == cut))
    if trace is not None:
        trace(CUT, ms.symbols, ms.symbols[keep], keep, None, None)
    return ModuleString(
        ms.symbols[keep], ms.arity[keep], ms.params[np.repeat(keep, ms.arity.astype(np.int64))], ms.alphabet
    )


def _check_iterations(grammar: Grammar, iterations) -> int:
    n = grammar.iterations if iterations is None else iterations
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise DerivationError(f"{grammar.source}: iterations must be a whole number >= 0, not {clip(repr(n))}")
    if n > MAX_ITERATIONS:
        raise LimitError(
            f"{grammar.source}: {clip(f'{n:,}')} iterations, more than the limit of {MAX_ITERATIONS:,} "
            "(lsys3d.lsystem.derive.MAX_ITERATIONS)"
        )
    return int(n)


def _check_finite_start(ms: ModuleString):
    bad = np.flatnonzero(~np.isfinite(ms.params))
    if len(bad):
        i = int(np.searchsorted(ms.offsets, bad[0], side="right")) - 1
        raise DerivationError(
            f"start string: module {ms.module_text(i, short=True)} (#{i}) has a parameter that is not a finite number"
        )


_CAP = float(2**53)  # counts are exact below; from here on they only need to be known as too large


def _count(x: float) -> str:
    return f"{int(x):,}" if x < _CAP else f"more than {int(_CAP):,}"


def _check_size(
    modules: float, params: float, max_modules: int, grammar: Grammar, generation: int, phase: str = "generation"
):
    """Refuse a generation of ``modules`` modules holding ``params`` parameters when it costs more than the limit."""
    if modules + PARAMETER_COST * params <= max_modules:
        return
    what = f"{_count(modules)} modules"
    if modules <= max_modules:  # the parameters tipped it over
        what += f" with {_count(params)} parameters (each counts as {PARAMETER_COST:g} of a module)"
    raise LimitError(
        f"{grammar.source}: {phase} {generation} would have {what}, more than the limit of "
        f"{max_modules:,} modules; use fewer iterations, or raise the limit (--max-modules, or max_modules=)"
    )


# ---------------------------------------------------------------- D0L engine
@dataclass(frozen=True)
class _Growth:
    """Module and parameter counts of every generation of a predictable grammar (exact below 2**53, then capped).

    ``present[g]`` (only when asked for) holds the codes of the modules generation ``g`` contains.
    """

    modules: np.ndarray  # (n + 1,) float64
    params: np.ndarray  # (n + 1,) float64
    present: list[np.ndarray] | None
    last: np.ndarray  # (k,) float64: modules of each reachable (symbol, arity) state in the last generation
    last_code: np.ndarray  # (k,) int64: the symbol code of each state


def _growth(plan: _Plan, n: int, presence: bool = False) -> _Growth:
    """Count the modules of each generation from the growth matrix of the (symbol, arity) pairs the axiom reaches.

    Needs ``plan.predictable``: the first pool of each symbol and arity is the
    one that rewrites every such module.  A pair the axiom never reaches costs
    nothing, however fast it would grow.
    """
    succ: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for code, pools in plan.pools_by_code.items():
        for pool in pools:
            succ.setdefault(
                (code, pool.arity), [(plan.code[m.symbol], len(m.args)) for m in pool.alternatives[0].successor]
            )
    ms = plan.grammar.axiom_modules
    axiom = list(zip(ms.symbols.tolist(), ms.arity.tolist(), strict=True))
    index: dict[tuple[int, int], int] = {}
    todo = list(dict.fromkeys(axiom))
    while todo:
        state = todo.pop()
        if state not in index:
            index[state] = len(index)
            todo.extend(t for t in succ.get(state, [state]) if t not in index)
    src, dst, mult = [], [], []
    for state, i in index.items():
        for target, k in Counter(index[t] for t in succ.get(state, [state])).items():
            src.append(i)
            dst.append(target)
            mult.append(k)
    src, dst, mult = np.array(src, np.int64), np.array(dst, np.int64), np.array(mult, np.float64)
    k = len(index)
    code_of = np.array([state[0] for state in index], np.int64)
    arity_of = np.array([state[1] for state in index], np.float64)
    v = np.bincount(np.array([index[a] for a in axiom], np.int64), minlength=k).astype(np.float64)
    modules, params = np.empty(n + 1), np.empty(n + 1)
    present = [] if presence else None
    for g in range(n + 1):
        if g:
            v = np.minimum(np.bincount(dst, weights=v[src] * mult, minlength=k), _CAP)
        modules[g] = min(v.sum(), _CAP)
        params[g] = min(v @ arity_of, _CAP)
        if presence:
            present.append(code_of[v > 0])
    return _Growth(modules, params, present, v, code_of)


def _derive_d0l(plan: _Plan, n: int, growth: _Growth) -> ModuleString:
    """Expand each symbol once per step, reusing the expansion wherever it occurs.

    After ``k`` steps only the symbols present in generation ``n - k`` need
    their expansion, and those expansions are disjoint pieces of the result:
    no step holds more than the result's size (twice, while the next is built).
    """
    grammar = plan.grammar
    succ = {c: _succ_codes(plan, pools[0].alternatives[0]).tolist() for c, pools in plan.pools_by_code.items()}
    empty = np.zeros(0, np.uint8)
    blocks = {c: np.array([c], dtype=np.uint8) for c in growth.present[n].tolist()}
    for k in range(1, n + 1):
        previous, blocks = blocks, {}
        for c in growth.present[n - k].tolist():
            if c not in succ:
                blocks[c] = previous[c]
            elif succ[c]:
                blocks[c] = np.concatenate([previous[t] for t in succ[c]])
            else:
                blocks[c] = empty
        del previous
    pieces = [blocks[c] for c in grammar.axiom_modules.symbols.tolist()]
    symbols = np.concatenate(pieces) if pieces else empty
    m = len(symbols)
    return ModuleString(symbols, np.zeros(m, np.uint8), np.zeros(0, np.float64), grammar.alphabet)


# ---------------------------------------------------------------- general engine
class _Context:
    """Context matching on one bracketed string (ABOP section 1.8), for all candidate modules at once."""

    def __init__(self, plan: _Plan, ms: ModuleString):
        self.ignored = plan.ignored
        self.plan = plan
        self.ms = ms
        self.m = len(ms)
        self.code = plan.code
        self._tables: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._plain: dict = {}  # a right context of plain modules: the candidates walked from, and what was found
        # cpfg's ring L-systems: a walk that runs off one end of the string goes on from the other
        self.ring = bool(plan.grammar.ring) and self.m > 0
        # cpfg: ']' in a right context is the next ']' (past ignored symbols and whole branches), and '=' skips
        # the rest of the branch up to it (RconDiff); elsewhere ']' alone skips the rest of the branch
        self.skip = dialects.get(plan.grammar.dialect).notation.branch_skip

    @property
    def tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:func:`~lsys3d.lsystem.walks.skip_tables` of the string, made when a walk first needs them (a right
        context of plain modules seldom does: :meth:`right`, :meth:`_right_of`)."""
        if self._tables is None:
            self._tables = skip_tables(self.ms.symbols, self.ignored)
        return self._tables

    left_of = property(lambda self: self.tables[0])
    right_of = property(lambda self: self.tables[1])
    kept = property(lambda self: self.tables[2])
    close = property(lambda self: self.tables[3])

    def _right_of(self, j: np.ndarray) -> np.ndarray:
        """``right_of[j]``: walked from each of ``j`` while the walks stay short (a query module right after
        its apex), else from the tables."""
        if self._tables is None:
            found, done = walk_right(self.ms.symbols, self.ignored, j, 16 * len(j) + 4096)
            if done:
                return found
        return self.right_of[j]

    def _bind(self, j: np.ndarray, ok: np.ndarray, pm: PatternModule, values: list) -> None:
        """Narrow ``ok`` to the candidates whose module ``j`` is ``pm``; append its parameters to ``values``."""
        if pm.symbol == "*":  # any module (its parameters are not bound)
            return
        ms = self.ms
        jj = np.where(ok, j, 0)
        ok &= (ms.symbols[jj] == self.code[pm.symbol]) & (ms.arity[jj] == len(pm.formals))
        for c in range(len(pm.formals)):
            at = np.where(ok, ms.offsets[jj] + c, 0)
            values.append(ms.params[at] if len(ms.params) else np.zeros(len(j)))

    def left(self, sel: np.ndarray, pattern) -> tuple[np.ndarray, list[np.ndarray]]:
        """Which modules ``sel`` have the left context ``pattern``, and the values of its formals."""
        ok = np.ones(len(sel), np.bool_)
        j = sel - 1
        found = []
        for pm in reversed(pattern):
            j = np.where(j >= 0, self.left_of[np.maximum(j, 0)], -1)
            if self.ring:
                j = np.where(j < 0, self.left_of[self.m - 1], j)
            ok &= j >= 0
            values: list = []
            self._bind(j, ok, pm, values)
            found.append(values)
            j = j - 1
        return ok, [v for values in reversed(found) for v in values]

    def right(self, sel: np.ndarray, pattern) -> tuple[np.ndarray, list[np.ndarray]]:
        """Which modules ``sel`` have the right context ``pattern`` (``[`` and ``]`` allowed), and its values."""
        m = self.m
        tables = self.plan.plain_right.get(id(pattern))  # (the plan's patterns live as long as it)
        if tables is None:  # what a pattern of plain modules walks for, made once per derivation
            plain = all(pm.symbol not in ("[", "]", self.skip) for pm in pattern)
            key = tuple((pm.symbol, len(pm.formals)) for pm in pattern)
            codes = np.array([-1 if s == "*" else self.code[s] for s, _ in key] if plain else [], np.int64)
            arities = np.array([0 if s == "*" else n for s, n in key], np.int64)
            tables = self.plan.plain_right[id(pattern)] = (plain, key, codes, arities, int(arities.sum()), pattern)
        plain, key, codes, arities, n_values, _ = tables
        if self._tables is None and not self.ring and plain:
            # plain modules (a query module after its apex): one compiled walk, while the walks stay short
            found = self._plain.get(key)
            if found is not None and len(found[0]) == len(sel) and np.array_equal(found[0], sel):
                return found[1], list(found[2])  # the same walks (a rule before had the same candidates)
            if found is not None and len(found[0]) > len(sel):  # the same walks from more modules (a rule before)
                at = np.searchsorted(found[0], sel)
                if len(at) and at[-1] < len(found[0]) and np.array_equal(found[0][at], sel):
                    return found[1][at], [v[at] for v in found[2]]
            ms = self.ms
            ok, values, done = right_plain(
                ms.symbols, ms.arity, ms.offsets, ms.params, self.ignored, sel + 1, codes, arities, n_values,
                16 * len(sel) + 4096,
            )  # fmt: skip
            if done:
                self._plain[key] = (sel, ok, values)
                return ok, list(values)
        ok = np.ones(len(sel), np.bool_)
        j = sel + 1
        values: list = []
        for pm in pattern:
            j = np.minimum(j, m)
            if pm.symbol == "[":  # a branch starts here (ignored symbols before it skipped)
                j = self.kept[j]
                ok &= (j < m) & (self.ms.symbols[np.minimum(j, m - 1)] == _OPEN)
            elif pm.symbol == "]" and self.skip:  # cpfg: the next module, past branches, is the ']'
                j = self.right_of[j]
                ok &= (j < m) & (self.ms.symbols[np.minimum(j, m - 1)] == _CLOSE)
            elif pm.symbol == "]" or (self.skip and pm.symbol == self.skip):  # the rest of the branch skipped
                j = self.close[j]
                ok &= j < m
                if pm.symbol != "]":  # cpfg's '=': the ']' that follows it in the pattern is this one
                    j = j - 1
            else:
                j = self._right_of(j)
                if self.ring:
                    j = np.where(j >= m, self.right_of[0], j)
                ok &= j < m  # the end of the string, or of a branch, has no right context
                ok &= self.ms.symbols[np.minimum(j, m - 1)] != _CLOSE
                self._bind(j, ok, pm, values)
            j = j + 1
        return ok, values


def _fail(prod: Production, where: str, exc: EvalError, ms: ModuleString, idx: np.ndarray, during: str):
    bad = int(idx[int(exc.index[0])]) if len(exc.index) and len(idx) else int(idx[0]) if len(idx) else -1
    module = f" for module {ms.module_text(bad, short=True)} (#{bad})" if bad >= 0 else ""
    return DerivationError(f"{prod.location}: rule '{clip(prod.text)}': {exc} in {where}{module} while {during}")


def _during(keys: tuple) -> str:
    kind, generation = keys[0], keys[1]
    if kind == _PRODUCTION:
        return f"deriving generation {generation}"
    if kind == _DECOMPOSITION:
        return f"decomposing generation {generation}"
    return "applying the homomorphism rules"


class _Draws(RandomDraws):
    """The random functions' numbers of one step: keyed by the seed, the step and each module's position."""

    def __init__(self, seed: int, keys: tuple, index: np.ndarray):
        self.seed = seed
        self.keys = keys
        self.index = index

    def draw(self, site: int, k: int) -> np.ndarray:
        return hashed_uniform(self.seed, Stream.GRAMMAR_RANDOM, (*self.keys, site, k), self.index)

    def subset(self, index: np.ndarray) -> _Draws:
        return _Draws(self.seed, self.keys, self.index[index])


def _loop(step, env: dict, size: int, draws, fail) -> dict:
    """cpfg's ``while (c) {...}`` in a rule's block: the statements run for the modules whose ``c`` holds, until
    it holds for none (at most ``rules.MAX_LOOP`` rounds).  A variable first set in the loop is 0 where the loop
    does not run (cpfg's variables start at 0)."""
    _, body, cond = step
    env = dict(env)
    for s in _flat(body):
        if s[0] == "let" and s[1] not in env:
            env[s[1]] = np.zeros(size)
    for _ in range(MAX_LOOP):
        try:
            go = np.broadcast_to(cond.evaluate(env, size, random=draws) != 0, (size,))
        except EvalError as exc:
            raise fail(exc, "its while loop's condition", np.arange(size)) from None
        if not go.any():
            return env
        k = np.flatnonzero(go)
        inner = _subset(env, k)
        inner_draws = draws.subset(k)
        for s in body:
            if s[0] == "while":
                inner = _loop(s, inner, len(k), inner_draws, lambda exc, what, j, k=k: fail(exc, what, k[j]))
                continue
            try:
                inner[s[1]] = s[-1].evaluate(inner, len(k), random=inner_draws)
            except EvalError as exc:
                raise fail(exc, f"local variable '{s[1]}'", k) from None
        for name, value in inner.items():
            full = np.array(np.broadcast_to(env[name], (size,)), dtype=np.float64) if name in env else np.zeros(size)
            full[k] = value
            env[name] = full
    raise fail(
        EvalError(f"a while loop ran more than {MAX_LOOP:,} rounds", np.zeros(1, np.int64)),
        "its while loop",
        np.arange(size),
    )


def _narrow(sel, env, draws, ok):
    return sel[ok], _subset(env, ok), draws.subset(np.flatnonzero(ok))


def _subset(env: dict, index) -> dict:
    """The values of ``env`` for some of its modules (scalars, the step and cpfg's globals, for all)."""
    return {k: v if isinstance(v, float) else v[index] for k, v in env.items()}


def _step(
    plan: _Plan,
    ms: ModuleString,
    keys: tuple,
    seed: int,
    max_modules: int,
    generation: int,
    eligible: np.ndarray | None = None,
    *,
    step_number: int = 0,
    variables: dict | None = None,
    trace: Trace | None = None,
) -> tuple[ModuleString, np.ndarray | None]:
    """One parallel rewrite of ``ms`` with ``plan``'s rules: the new string and which of its modules were produced.

    ``keys`` name the step for the random numbers (kind, generation[, pass]); ``eligible`` restricts
    the modules that may be rewritten; ``step_number`` is what L-Py's ``getIterationNb()`` gives (0 at the
    first derivation step); ``variables`` are the globals of cpfg's blocks at this step (scalars).  The
    mask of produced modules is None when nothing matched.
    """
    m = len(ms)
    sym = ms.symbols
    offsets = ms.offsets
    params = ms.params
    matched = np.zeros(m, dtype=bool)
    chosen: list[tuple[Production, np.ndarray, dict, _Draws]] = []
    context = _Context(plan, ms) if plan.context else None
    during = _during(keys)
    active = None
    if plan.lsystems:
        main = plan.grammar.lsystem_main
        codes = plan.code.get("?", -1), plan.code.get("$", -1)
        active = sequences.active_lsystems(ms, *codes, main, plan.grammar.lsystem_numbers)

    for code, pools in plan.pools_by_code.items():
        remaining = np.flatnonzero(sym == code)
        if eligible is not None:
            remaining = remaining[eligible[remaining]]
        for pool in pools:
            if not len(remaining):
                break
            sel = remaining[ms.arity[remaining] == pool.arity]
            if active is not None:
                sel = sel[active[sel] == (pool.lsystem if pool.lsystem >= 0 else plan.grammar.lsystem_main)]
            if pool.following:
                sel = sel[sequences.follows(ms, sel, pool.following, plan.code)]
            if not len(sel):
                continue
            prod0 = pool.alternatives[0]
            env: dict[str, np.ndarray | float] = {STEP: float(step_number), **(variables or {})}
            last = sel + len(pool.following)  # the predecessor's last module: the right context follows it
            if pool.left or pool.right:
                keep = np.ones(len(sel), np.bool_)
                values: list[np.ndarray] = []
                for side, pattern, at in ((context.left, pool.left, sel), (context.right, pool.right, last)):
                    if pattern:
                        ok, found = side(at, pattern)
                        keep &= ok
                        values += found
                names = [n for pm in (*pool.left, *pool.right) for n in pm.formals]
                if keep.all():  # (often: every apex has its query module after it)
                    env.update(zip(names, values, strict=True))
                else:
                    env.update({name: v[keep] for name, v in zip(names, values, strict=True)})
                    sel = sel[keep]
                if not len(sel):
                    continue
            if prod0.predecessor.formals:
                base = offsets[sel]
                for c, name in enumerate(prod0.predecessor.formals):
                    env[name] = params[base + c]
            if pool.following:
                names = [n for pm in pool.following for n in pm.formals]
                env.update(zip(names, sequences.following_values(ms, sel, pool.following), strict=True))
            draws = _Draws(seed, keys, sel)
            if pool.condition is not None:
                try:
                    ok = pool.condition.evaluate(env, len(sel), random=draws) != 0
                except EvalError as exc:
                    raise _fail(prod0, "its condition", exc, ms, sel, during) from None
                sel, env, draws = _narrow(sel, env, draws, ok)
            for step in pool.steps:  # local variables and tests, in order
                if not len(sel):
                    break
                if step[0] == "while":
                    env = _loop(
                        step,
                        env,
                        len(sel),
                        draws,
                        lambda exc, what, k, prod0=prod0, sel=sel: _fail(prod0, what, exc, ms, sel[k], during),
                    )
                    continue
                try:
                    value = step[-1].evaluate(env, len(sel), random=draws)
                except EvalError as exc:
                    what = f"local variable '{step[1]}'" if step[0] == "let" else "its condition"
                    raise _fail(prod0, what, exc, ms, sel, during) from None
                if step[0] == "let":
                    env[step[1]] = value
                else:
                    sel, env, draws = _narrow(sel, env, draws, value != 0)
            if not len(sel):
                continue
            matched[sel] = True
            remaining = remaining[~matched[remaining]]
            if pool.cumulative is None:
                chosen.append((prod0, sel, env, draws))
                continue
            # productions keep the streams they always had; the later passes take their own
            later = 0 if keys[0] == _PRODUCTION else (1 << 20) * (64 * keys[0] + keys[-1] + 1)
            rng = rule_generator(seed, keys[1], code, pool.pool_id + later)
            u = rng.random(len(sel)) * pool.cumulative[-1]
            pick = np.minimum(np.searchsorted(pool.cumulative, u, side="right"), len(pool.alternatives) - 1)
            # group the modules by the alternative they drew: one sort, not one pass per alternative
            order = np.argsort(pick, kind="stable")  # stable: each group keeps the modules in string order
            bounds = np.concatenate([[0], np.cumsum(np.bincount(pick, minlength=len(pool.alternatives)))])
            for a in np.flatnonzero(np.diff(bounds)).tolist():
                take = order[bounds[a] : bounds[a + 1]]
                chosen.append((pool.alternatives[a], sel[take], _subset(env, take), draws.subset(take)))
    if not chosen:
        return ms, None

    out_len = np.ones(m, dtype=np.int64)
    out_arity = ms.arity.astype(np.int64)
    if plan.sequences:  # the modules matches of several modules consume: they become nothing
        chosen, consumed = _consume(chosen, m)
        matched[consumed] = True
        out_len[consumed] = 0
        out_arity[consumed] = 0
    for prod, idx, _, _ in chosen:
        out_len[idx] = len(prod.successor)
        out_arity[idx] = sum(len(s.args) for s in prod.successor)
    mod_off = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(out_len, out=mod_off[1:])
    par_off = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(out_arity, out=par_off[1:])
    total = int(mod_off[-1])
    _check_size(total, int(par_off[-1]), max_modules, plan.grammar, generation, _PHASE[keys[0]])

    new_sym = np.empty(total, dtype=np.uint8)
    new_arity = np.empty(total, dtype=np.uint8)
    new_params = np.empty(int(par_off[-1]), dtype=np.float64)
    _copy_unmatched(matched, sym, ms.arity, offsets, params, mod_off, par_off, new_sym, new_arity, new_params)

    for prod, idx, env, draws in chosen:
        n = len(idx)
        p = 0
        first_module, first_param = mod_off[idx], par_off[idx]
        for j, smod in enumerate(prod.successor):
            pos = first_module + j
            new_sym[pos] = plan.code[smod.symbol]
            new_arity[pos] = len(smod.args)
            for expr in smod.args:
                if expr.op == "num":  # a number (?P(0, 0, 0)): written as evaluate would give it, without the tree walk
                    new_params[first_param + p] = expr.value
                    p += 1
                    continue
                try:
                    values = expr.evaluate(env, n, finite=False, random=draws)  # checked below, all at once
                except EvalError as exc:
                    what = f"parameter '{clip(expr.text)}' of {smod.symbol}"
                    raise _fail(prod, what, exc, ms, idx, during) from None
                new_params[first_param + p] = values
                p += 1
    # Overflow (A(x) -> A(x*1e300)) or NaN: one pass over the whole generation.  The sum is
    # finite exactly when every parameter is, unless finite values overflow it; only then (and
    # on a real error) the elementwise test runs.
    with np.errstate(over="ignore"):
        total_sum = new_params.sum()
    if not np.isfinite(total_sum) and not np.isfinite(new_params).all():
        raise _not_finite(chosen, ms, new_params, par_off, during)
    if trace is not None:
        persisting = None
        if getattr(trace, "persisting", True):
            persisting = np.zeros(total, np.bool_)
            for prod, idx, _, _ in chosen:
                j = persisting_index(prod)
                if j >= 0:
                    persisting[mod_off[idx] + j] = True
        trace(keys[0], sym, new_sym, matched, out_len, persisting)
    produced = np.zeros(total if keys[0] != _PRODUCTION else 0, np.bool_)
    if keys[0] != _PRODUCTION:  # the passes after this one rewrite only what this one produced
        rewritten = np.flatnonzero(matched)
        produced[ranges(mod_off[rewritten], out_len[rewritten])] = True
    return ModuleString(new_sym, new_arity, new_params, plan.alphabet), produced


@kernel(nogil=True)
def _copy_unmatched(matched, sym, arity, offsets, params, mod_off, par_off, new_sym, new_arity, new_params):
    """Copy the modules no rule rewrote, with their parameters, to their places in the new string (one pass,
    no index arrays: most of a long string is copied)."""
    for i in range(sym.shape[0]):
        if matched[i]:
            continue
        j = mod_off[i]
        new_sym[j] = sym[i]
        new_arity[j] = arity[i]
        src = offsets[i]
        dst = par_off[i]
        for c in range(arity[i]):
            new_params[dst + c] = params[src + c]


def _consume(chosen: list, m: int) -> tuple[list, np.ndarray]:
    """The matches that stand after cpfg's left-to-right walk (:func:`sequences.resolve_overlaps`), and the
    modules the matches of several modules consume (no rule rewrites those on their own)."""
    multi = [(idx, len(prod.following) + 1) for prod, idx, _, _ in chosen if prod.following]
    if not multi:
        return chosen, np.zeros(m, np.bool_)
    starts = np.concatenate([idx for idx, _ in multi])
    lengths = np.concatenate([np.full(len(idx), k, np.int64) for idx, k in multi])
    consumed = sequences.resolve_overlaps(m, starts, lengths)
    kept = []
    for prod, idx, env, draws in chosen:
        ok = ~consumed[idx]
        if ok.all():
            kept.append((prod, idx, env, draws))
        elif ok.any():
            kept.append((prod, idx[ok], _subset(env, ok), draws.subset(np.flatnonzero(ok))))
    return kept, consumed


def _not_finite(chosen, ms: ModuleString, new_params, par_off, during: str) -> DerivationError:
    """The error for the first parameter of a generation that is infinite or NaN: its rule and module."""
    k = int(np.flatnonzero(~np.isfinite(new_params))[0])
    i = int(np.searchsorted(par_off, k, side="right")) - 1  # the module it was rewritten from
    for prod, idx, _, _ in chosen:
        pos = int(np.searchsorted(idx, i))
        if pos < len(idx) and idx[pos] == i:
            p = k - int(par_off[i])
            for smod in prod.successor:
                if p < len(smod.args):
                    where = f"parameter '{clip(smod.args[p].text)}' of {smod.symbol}"
                    return _fail(prod, where, EvalError(NOT_FINITE, [pos]), ms, idx, during)
                p -= len(smod.args)
    # copied unchanged: only a start string given from Python can hold such a number
    return DerivationError(
        f"module {ms.module_text(i, short=True)} (#{i}) has a parameter that is not a finite number while {during}"
    )
