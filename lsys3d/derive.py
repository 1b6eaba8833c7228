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
  into preallocated arrays.  Only context matching walks module by module.

Stochastic choice draws, for generation ``g`` and rule pool ``p`` of symbol
``s``, a stream seeded with ``(seed, g, s, p)``: the k-th module rewritten by a
pool takes the k-th number of its stream.  Changing one pool's weights thus
leaves every other pool's choices alone.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from .errors import DerivationError, LimitError, clip
from .expr import NOT_FINITE, EvalError
from .grammar import Grammar, PatternModule, Production
from .modules import ModuleString

__all__ = ["DEFAULT_MAX_MODULES", "MAX_ITERATIONS", "derive", "generations", "predict_counts", "predict_length"]

log = logging.getLogger("lsys3d")

DEFAULT_MAX_MODULES = 50_000_000
"""Largest module string derivation builds (about 50 bytes a module at the peak)."""
MAX_ITERATIONS = 10_000
"""Most generations one derivation runs: a string that stops growing would otherwise rewrite forever.

Raise it by assigning ``lsys3d.derive.MAX_ITERATIONS``.
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


class _Plan:
    """The grammar arranged for rewriting: pools per symbol code, in rule order."""

    def __init__(self, grammar: Grammar):
        self.grammar = grammar
        self.alphabet = grammar.alphabet
        self.code = {ch: i for i, ch in enumerate(grammar.alphabet) if ch != "\0" or i == 0}
        self.ignore = frozenset(self.code[c] for c in grammar.ignore if c in self.code)
        pools: dict[tuple, _Pool] = {}
        self.pools_by_code: dict[int, list[_Pool]] = {}
        for prod in grammar.productions:
            key = prod.pool_key()
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
                )
                pools[key] = pool
                self.pools_by_code.setdefault(code, []).append(pool)
            pools[key].alternatives.append(prod)
        for pool in pools.values():
            if len(pool.alternatives) > 1:
                w = np.array([p.weight if p.weight is not None else 1.0 for p in pool.alternatives])
                pool.cumulative = np.cumsum(w)
        self.context = any(p.left or p.right for p in pools.values())
        # every module's successor length is known from its symbol and arity alone
        self.predictable = not self.context and all(
            p.cumulative is None and p.condition is None for p in pools.values()
        )
        self.d0l = self.predictable and not grammar.parametric


def _succ_codes(plan: _Plan, prod: Production) -> np.ndarray:
    return np.array([plan.code[m.symbol] for m in prod.successor], dtype=np.uint8)


# ---------------------------------------------------------------- public API
def predict_length(grammar: Grammar, iterations: int | None = None) -> int | None:
    """Exact module count after ``iterations`` steps, or None when it depends on the derivation.

    Known for grammars without contexts, conditions and stochastic choice
    (parameters allowed: a successor's length does not depend on their values).
    Computed with Python integers from the growth (Parikh) matrix, so it costs
    nothing even when the answer is astronomically large.

    >>> from lsys3d import Grammar
    >>> predict_length(Grammar(axiom="A(1)", rules=["A(x) -> A(x)A(x + 1)"]), 40)
    1099511627776
    """
    plan = _Plan(grammar)
    if not plan.predictable:
        return None
    n = grammar.iterations if iterations is None else iterations
    return _d0l_lengths(plan, n)[1]


def predict_counts(grammar: Grammar, iterations: int | None = None) -> dict[str, int] | None:
    """How many modules of each symbol ``iterations`` steps make, or None when it depends on the derivation.

    Known for the same grammars as :func:`predict_length`.  The count vector
    is multiplied by the growth (Parikh) matrix once per step, in floating
    point: exact while a count stays below 2**53, and saturating at 2**62
    (far beyond any limit), so it costs next to nothing for any size.

    >>> from lsys3d import Grammar
    >>> predict_counts(Grammar(axiom="X", rules=["X -> F[+X]F[-X]+X", "F -> FF"]), 2)
    {'+': 8, '-': 4, 'F': 10, 'X': 9, '[': 8, ']': 8}
    """
    plan = _Plan(grammar)
    if not plan.predictable:
        return None
    n = _check_iterations(grammar, iterations)
    succ = _successor_keys(plan)
    axiom = _axiom_keys(plan)
    keys = sorted(set(axiom) | set(succ) | {t for s in succ.values() for t in s})
    index = {k: i for i, k in enumerate(keys)}
    growth = np.zeros((len(keys), len(keys)))
    for k in keys:
        for t in succ.get(k, [k]):  # a module without a rule stays itself
            growth[index[k], index[t]] += 1
    counts = np.zeros(len(keys))
    for k in axiom:
        counts[index[k]] += 1
    cap = float(1 << 62)
    for _ in range(n):
        counts = np.minimum(counts @ growth, cap)
    out: dict[str, int] = {}
    for (code, _arity), count in zip(keys, counts.tolist(), strict=True):
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
    if plan.d0l and start is None:
        return _derive_d0l(plan, n, max_modules)
    if plan.predictable and start is None:  # fail at once, not after building the generations below the limit
        _check_size(_d0l_lengths(plan, n)[1], max_modules, grammar, n)
    *_, result = generations(grammar, n, seed, start=start, max_modules=max_modules)
    return result


def generations(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    start: ModuleString | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
) -> Iterator[ModuleString]:
    """Yield the axiom (or ``start``) and then every generation up to ``iterations``, one at a time.

    >>> from lsys3d import Grammar
    >>> [str(s) for s in generations(Grammar(axiom="D", rules=["D = DGD"]), 2)]
    ['D', 'DGD', 'DGDGDGD']
    """
    n = _check_iterations(grammar, iterations)
    seed = grammar.seed if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DerivationError(f"seed must be a whole number >= 0, not {seed!r}")
    plan = _Plan(grammar)
    current = grammar.axiom_modules if start is None else start
    if current.alphabet != plan.alphabet and current.alphabet[128:] != plan.alphabet[128:]:
        raise DerivationError("the start string uses symbols this grammar does not know")
    _check_size(len(current), max_modules, grammar, 0)
    if start is not None:
        _check_finite_start(current)
    yield current
    for g in range(1, n + 1):
        current = _step(plan, current, g, int(seed), max_modules)
        log.debug("generation %d: %d modules", g, len(current))
        yield current


def _check_iterations(grammar: Grammar, iterations) -> int:
    n = grammar.iterations if iterations is None else iterations
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise DerivationError(f"{grammar.source}: iterations must be a whole number >= 0, not {n!r}")
    if n > MAX_ITERATIONS:
        raise LimitError(
            f"{grammar.source}: {n:,} iterations, more than the limit of {MAX_ITERATIONS:,} "
            "(lsys3d.derive.MAX_ITERATIONS)"
        )
    return int(n)


def _check_finite_start(ms: ModuleString):
    bad = np.flatnonzero(~np.isfinite(ms.params))
    if len(bad):
        i = int(np.searchsorted(ms.offsets, bad[0], side="right")) - 1
        raise DerivationError(
            f"start string: module {ms.module_text(i, short=True)} (#{i}) has a parameter that is not a finite number"
        )


def _check_size(total: int, max_modules: int, grammar: Grammar, generation: int):
    if total > max_modules:
        raise LimitError(
            f"{grammar.source}: generation {generation} would have {total:,} modules, more than the limit of "
            f"{max_modules:,}; use fewer iterations, or raise the limit (--max-modules, or max_modules=)"
        )


# ---------------------------------------------------------------- D0L engine
def _successor_keys(plan: _Plan) -> dict[tuple[int, int], list[tuple[int, int]]]:
    """The (symbol code, arity) of each successor module, per (symbol code, arity) with a rule.

    Needs ``plan.predictable``: the first pool of each symbol and arity is the
    one that rewrites every such module.
    """
    succ = {}
    for code, pools in plan.pools_by_code.items():
        for pool in pools:
            key = (code, pool.arity)
            if key not in succ:
                succ[key] = [(plan.code[m.symbol], len(m.args)) for m in pool.alternatives[0].successor]
    return succ


def _axiom_keys(plan: _Plan) -> list[tuple[int, int]]:
    ms = plan.grammar.axiom_modules
    return list(zip(ms.symbols.tolist(), ms.arity.tolist(), strict=True))


def _d0l_lengths(plan: _Plan, n: int):
    """Module counts per (symbol, arity) after each step, and the final total (Python ints).

    Needs ``plan.predictable``: the first pool of each symbol and arity is the
    one that rewrites every such module.
    """
    succ = _successor_keys(plan)
    axiom = _axiom_keys(plan)
    lengths = {c: 1 for c in set(axiom) | set(succ) | {t for s in succ.values() for t in s}}
    history = [lengths]
    for _ in range(n):
        lengths = {c: (sum(lengths[t] for t in succ[c]) if c in succ else 1) for c in lengths}
        history.append(lengths)
        if sum(lengths[c] for c in axiom) > 1 << 62:  # no need to count further
            return history, sum(lengths[c] for c in axiom)
    return history, sum(lengths[c] for c in axiom)


def _derive_d0l(plan: _Plan, n: int, max_modules: int) -> ModuleString:
    grammar = plan.grammar
    history, total = _d0l_lengths(plan, n)
    _check_size(total, max_modules, grammar, n)
    axiom = grammar.axiom_modules.symbols.tolist()
    succ = {c: _succ_codes(plan, pools[0].alternatives[0]).tolist() for c, pools in plan.pools_by_code.items()}
    constant = {c: np.array([c], dtype=np.uint8) for c, _ in history[0]}  # D0L: every arity is 0
    blocks = dict(constant)
    for _ in range(n):
        blocks = {
            c: (np.concatenate([blocks[t] for t in succ[c]]) if succ[c] else np.zeros(0, np.uint8))
            if c in succ
            else constant[c]
            for c in blocks
        }
    pieces = [blocks[c] for c in axiom]
    symbols = np.concatenate(pieces) if pieces else np.zeros(0, np.uint8)
    m = len(symbols)
    return ModuleString(symbols, np.zeros(m, np.uint8), np.zeros(0, np.float64), grammar.alphabet)


# ---------------------------------------------------------------- general engine
def _ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenated ``arange(s, s + l)`` for each pair, without a Python loop."""
    lengths = lengths.astype(np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    nz = lengths > 0
    starts, lengths = starts[nz].astype(np.int64), lengths[nz]
    ends = np.cumsum(lengths)
    out = np.ones(total, np.int64)
    out[0] = starts[0]
    out[ends[:-1]] = starts[1:] - (starts[:-1] + lengths[:-1] - 1)
    return np.cumsum(out)


def _bracket_match(symbols: np.ndarray) -> np.ndarray:
    """``match[i]`` is the index of the bracket matching bracket ``i`` (else -1)."""
    is_open = symbols == _OPEN
    is_close = symbols == _CLOSE
    depth = np.cumsum(is_open.astype(np.int64) - is_close)
    idx = np.flatnonzero(is_open | is_close)
    key = np.where(is_open[idx], depth[idx], depth[idx] + 1)
    order = idx[np.lexsort((idx, key))]
    match = np.full(len(symbols), -1, np.int64)
    match[order[0::2]] = order[1::2]
    match[order[1::2]] = order[0::2]
    return match


class _Context:
    """Context matching on one bracketed string (ABOP section 1.8)."""

    def __init__(self, plan: _Plan, ms: ModuleString):
        self.sym = ms.symbols.tolist()
        self.arity = ms.arity.tolist()
        self.offsets = ms.offsets
        self.params = ms.params
        self.match = _bracket_match(ms.symbols).tolist()
        self.ignore = plan.ignore
        self.code = plan.code

    def _bind(self, j, pm, values):
        if self.sym[j] != self.code[pm.symbol] or self.arity[j] != len(pm.formals):
            return False
        o = int(self.offsets[j])
        values.extend(self.params[o : o + len(pm.formals)].tolist())
        return True

    def left(self, i: int, pattern) -> list | None:
        sym, match, ignore = self.sym, self.match, self.ignore
        j = i - 1
        found = []
        for pm in reversed(pattern):
            while j >= 0:
                s = sym[j]
                if s == _CLOSE:  # skip a complete lateral branch
                    j = match[j] - 1
                elif s == _OPEN or s in ignore:  # step out to the parent / skip
                    j -= 1
                else:
                    break
            if j < 0:
                return None
            values: list = []
            if not self._bind(j, pm, values):
                return None
            found.append(values)
            j -= 1
        return [v for vals in reversed(found) for v in vals]

    def right(self, i: int, pattern) -> list | None:
        sym, match, ignore = self.sym, self.match, self.ignore
        m = len(sym)
        j = i + 1
        values: list = []
        for pm in pattern:
            if pm.symbol == "[":
                while j < m and sym[j] in ignore:
                    j += 1
                if j >= m or sym[j] != _OPEN:
                    return None
                j += 1
            elif pm.symbol == "]":  # the rest of the current branch is skipped
                while j < m and sym[j] != _CLOSE:
                    j = match[j] + 1 if sym[j] == _OPEN else j + 1
                if j >= m:
                    return None
                j += 1
            else:
                while j < m:
                    s = sym[j]
                    if s == _OPEN:  # skip a lateral branch
                        j = match[j] + 1
                    elif s in ignore:
                        j += 1
                    else:
                        break
                if j >= m or sym[j] == _CLOSE:  # the end of a branch has no right context
                    return None
                if not self._bind(j, pm, values):
                    return None
                j += 1
        return values


def _fail(prod: Production, where: str, exc: EvalError, ms: ModuleString, idx: np.ndarray, generation: int):
    bad = int(idx[int(exc.index[0])]) if len(exc.index) and len(idx) else int(idx[0]) if len(idx) else -1
    module = f" for module {ms.module_text(bad, short=True)} (#{bad})" if bad >= 0 else ""
    return DerivationError(
        f"{prod.location}: rule '{clip(prod.text)}': {exc} in {where}{module} while deriving generation {generation}"
    )


def _step(plan: _Plan, ms: ModuleString, generation: int, seed: int, max_modules: int) -> ModuleString:
    m = len(ms)
    sym = ms.symbols
    offsets = ms.offsets
    params = ms.params
    matched = np.zeros(m, dtype=bool)
    chosen: list[tuple[Production, np.ndarray, dict]] = []
    context = _Context(plan, ms) if plan.context else None

    for code, pools in plan.pools_by_code.items():
        remaining = np.flatnonzero(sym == code)
        for pool in pools:
            if not len(remaining):
                break
            sel = remaining[ms.arity[remaining] == pool.arity]
            if not len(sel):
                continue
            prod0 = pool.alternatives[0]
            env: dict[str, np.ndarray] = {}
            if pool.left or pool.right:
                keep = np.zeros(len(sel), dtype=bool)
                lvals, rvals = [], []
                for k, i in enumerate(sel.tolist()):
                    lv = context.left(i, pool.left) if pool.left else []
                    if lv is None:
                        continue
                    rv = context.right(i, pool.right) if pool.right else []
                    if rv is None:
                        continue
                    keep[k] = True
                    lvals.append(lv)
                    rvals.append(rv)
                sel = sel[keep]
                lnames = [n for pm in pool.left for n in pm.formals]
                rnames = [n for pm in pool.right for n in pm.formals]
                for names, vals in ((lnames, lvals), (rnames, rvals)):
                    if names:
                        arr = np.array(vals, dtype=np.float64).reshape(len(sel), len(names))
                        env.update({name: arr[:, c] for c, name in enumerate(names)})
                if not len(sel):
                    continue
            for c, name in enumerate(prod0.predecessor.formals):
                env[name] = params[offsets[sel] + c]
            if pool.condition is not None:
                try:
                    ok = pool.condition.evaluate(env, len(sel)) != 0
                except EvalError as exc:
                    raise _fail(prod0, "its condition", exc, ms, sel, generation) from None
                sel = sel[ok]
                env = {k: v[ok] for k, v in env.items()}
                if not len(sel):
                    continue
            matched[sel] = True
            remaining = remaining[~matched[remaining]]
            if pool.cumulative is None:
                chosen.append((prod0, sel, env))
                continue
            rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, generation, code, pool.pool_id])))
            u = rng.random(len(sel)) * pool.cumulative[-1]
            pick = np.minimum(np.searchsorted(pool.cumulative, u, side="right"), len(pool.alternatives) - 1)
            for a, prod in enumerate(pool.alternatives):
                take = pick == a
                if take.any():
                    chosen.append((prod, sel[take], {k: v[take] for k, v in env.items()}))

    out_len = np.ones(m, dtype=np.int64)
    out_arity = ms.arity.astype(np.int64)
    for prod, idx, _ in chosen:
        out_len[idx] = len(prod.successor)
        out_arity[idx] = sum(len(s.args) for s in prod.successor)
    total = int(out_len.sum())
    _check_size(total, max_modules, plan.grammar, generation)
    mod_off = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(out_len, out=mod_off[1:])
    par_off = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(out_arity, out=par_off[1:])

    new_sym = np.empty(total, dtype=np.uint8)
    new_arity = np.empty(total, dtype=np.uint8)
    new_params = np.empty(int(par_off[-1]), dtype=np.float64)
    copy = np.flatnonzero(~matched)
    new_sym[mod_off[copy]] = sym[copy]
    new_arity[mod_off[copy]] = ms.arity[copy]
    if len(params):
        with_params = copy[ms.arity[copy] > 0]
        lengths = ms.arity[with_params]
        new_params[_ranges(par_off[with_params], lengths)] = params[_ranges(offsets[with_params], lengths)]

    for prod, idx, env in chosen:
        n = len(idx)
        p = 0
        for j, smod in enumerate(prod.successor):
            pos = mod_off[idx] + j
            new_sym[pos] = plan.code[smod.symbol]
            new_arity[pos] = len(smod.args)
            for expr in smod.args:
                try:
                    values = expr.evaluate(env, n, finite=False)  # checked below, all at once
                except EvalError as exc:
                    what = f"parameter '{clip(expr.text)}' of {smod.symbol}"
                    raise _fail(prod, what, exc, ms, idx, generation) from None
                new_params[par_off[idx] + p] = values
                p += 1
    # Overflow (A(x) -> A(x*1e300)) or NaN: one pass over the whole generation.  The sum is
    # finite exactly when every parameter is, unless finite values overflow it; only then (and
    # on a real error) the elementwise test runs.
    with np.errstate(over="ignore"):
        total = new_params.sum()
    if not np.isfinite(total) and not np.isfinite(new_params).all():
        raise _not_finite(chosen, ms, new_params, par_off, generation)
    return ModuleString(new_sym, new_arity, new_params, plan.alphabet)


def _not_finite(chosen, ms: ModuleString, new_params, par_off, generation: int) -> DerivationError:
    """The error for the first parameter of a generation that is infinite or NaN: its rule and module."""
    k = int(np.flatnonzero(~np.isfinite(new_params))[0])
    i = int(np.searchsorted(par_off, k, side="right")) - 1  # the module it was rewritten from
    for prod, idx, _ in chosen:
        pos = int(np.searchsorted(idx, i))
        if pos < len(idx) and idx[pos] == i:
            p = k - int(par_off[i])
            for smod in prod.successor:
                if p < len(smod.args):
                    where = f"parameter '{clip(smod.args[p].text)}' of {smod.symbol}"
                    return _fail(prod, where, EvalError(NOT_FINITE, [pos]), ms, idx, generation)
                p -= len(smod.args)
    # copied unchanged: only a start string given from Python can hold such a number
    return DerivationError(
        f"module {ms.module_text(i, short=True)} (#{i}) has a parameter that is not a finite number "
        f"while deriving generation {generation}"
    )
