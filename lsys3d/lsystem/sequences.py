"""cpfg's rewriting that reads the string from left to right: predecessors of several modules, sub-L-systems.

lsys3d rewrites every module at once (:mod:`lsys3d.lsystem.derive`); cpfg walks the string from left to
right, and two of its features depend on that walk:

* **A strict predecessor of several modules** (``XF(x) --> ...``; cpfg's module names are one character,
  so ``spikef --> ...`` is six).  The first rule (in the file's order) whose predecessor, contexts and
  condition match at a module applies there and consumes the modules of its predecessor; the walk goes on
  after them, so two matches never overlap and the earlier one wins.  cpfg compares the predecessor's
  modules with the string's next modules one for one (``PredDiff`` in its ``generate.c``): no ignored
  symbols or brackets are stepped over.
* **Sub-L-systems** (``?(n, s) ... $``): a module ``?`` with parameters pushes L-system ``n`` and ``$``
  pops it, so the modules after a ``?(n)`` up to its ``$`` are rewritten by the rules of ``lsystem: n``
  (``CheckPred``/``ProcessSubLsystems`` in ``generate.c``); the ``?`` itself by the rules around it,
  the ``$`` by those of the L-system it closes.

The derivation engine calls these helpers on whole arrays; only the resolution of overlapping matches
walks, over the matches alone.
"""

from __future__ import annotations

import numpy as np

from ..compiling import kernel
from ..errors import DerivationError
from .modules import ModuleString

__all__ = ["MAX_NESTING", "active_lsystems", "following_values", "follows", "resolve_overlaps"]

MAX_NESTING = 64
"""Deepest nesting of sub-L-systems (``?(n) ... ?(k) ... $ ... $``) in one string."""


def follows(ms: ModuleString, sel: np.ndarray, following, code: dict) -> np.ndarray:
    """Which modules ``sel`` have ``following`` (pattern modules) right after them, one for one.

    >>> from lsys3d import Grammar
    >>> from lsys3d.lsystem.rules import PatternModule
    >>> g = Grammar(axiom="XF(1)FX", rules=["X --> X"], dialect="cpfg")
    >>> code = {ch: i for i, ch in enumerate(g.alphabet)}
    >>> follows(g.axiom_modules, np.array([0, 3]), (PatternModule("F", ("x",)),), code).tolist()
    [True, False]
    """
    m = len(ms)
    ok = np.ones(len(sel), np.bool_)
    for k, pm in enumerate(following, start=1):
        j = sel + k
        ok &= j < m
        jj = np.where(ok, j, 0)
        ok &= (ms.symbols[jj] == code[pm.symbol]) & (ms.arity[jj] == len(pm.formals))
    return ok


def following_values(ms: ModuleString, sel: np.ndarray, following) -> list[np.ndarray]:
    """The parameters of the modules after ``sel`` that ``following`` binds, one array per formal, in order."""
    values = []
    for k, pm in enumerate(following, start=1):
        base = ms.offsets[sel + k]
        values += [ms.params[base + c] for c in range(len(pm.formals))]
    return values


@kernel(nogil=True)
def _walk(starts, lengths, m):
    covered = np.zeros(m, np.bool_)
    end = 0
    for k in range(starts.shape[0]):
        p = starts[k]
        if p < end:  # inside the modules an earlier match consumed: cpfg's walk never stands here
            continue
        end = p + lengths[k]
        for q in range(p + 1, end):
            covered[q] = True
    return covered


def resolve_overlaps(m: int, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The modules consumed by matches of several modules, walking from the left (an earlier match wins).

    ``starts`` are where each match begins (any order), ``lengths`` how many modules it takes.  A match that
    starts inside an earlier one's modules is no match (cpfg's walk never stands there); its own first
    module is consumed by the earlier match.

    >>> resolve_overlaps(6, np.array([3, 0, 1]), np.array([2, 2, 2])).tolist()
    [False, True, False, False, True, False]
    """
    order = np.argsort(starts, kind="stable")
    return _walk(starts[order].astype(np.int64), lengths[order].astype(np.int64), m)


@kernel(nogil=True)
def _active(symbols, arity, offsets, params, question, dollar, main, max_nesting):
    m = symbols.shape[0]
    out = np.empty(m, np.int64)
    stack = np.empty(max_nesting + 1, np.int64)
    top = 0
    stack[0] = main
    for i in range(m):
        out[i] = stack[top]
        s = symbols[i]
        if s == question and arity[i] > 0:
            if top == max_nesting:
                return out, i
            top += 1
            stack[top] = np.int64(np.floor(params[offsets[i]]))
        elif s == dollar and top > 0:  # an unmatched '$' changes nothing (cpfg warns and stays)
            top -= 1
    return out, -1


def active_lsystems(ms: ModuleString, question: int, dollar: int, main: int, known=None) -> np.ndarray:
    """The number of the L-system whose rules rewrite each module: ``main`` outside every ``?(n) ... $``.

    ``question`` and ``dollar`` are the codes of ``?`` and ``$`` in the string's alphabet (-1: absent);
    ``known``, when given, the L-systems' numbers: a ``?(n)`` of another is an error, as in cpfg.

    >>> from lsys3d import Grammar
    >>> g = Grammar(axiom="A?(2,1)BC$D", dialect="cpfg")
    >>> code = {ch: i for i, ch in enumerate(g.alphabet)}
    >>> active_lsystems(g.axiom_modules, code["?"], code["$"], 1).tolist()
    [1, 1, 2, 2, 2, 1]
    """
    out, deepest = _active(
        ms.symbols, ms.arity, ms.offsets, ms.params, np.int64(question), np.int64(dollar), np.int64(main), MAX_NESTING
    )
    if deepest >= 0:
        raise DerivationError(
            f"module {ms.module_text(deepest, short=True)} (#{deepest}): sub-L-systems nested more than "
            f"{MAX_NESTING} deep (lsys3d.lsystem.sequences.MAX_NESTING)"
        )
    if known is not None and question >= 0:
        calls = np.flatnonzero((ms.symbols == question) & (ms.arity > 0))
        numbers = np.floor(ms.params[ms.offsets[calls]]) if len(calls) else np.zeros(0)
        bad = np.flatnonzero(~np.isin(numbers, sorted(known)))
        if len(bad):
            i = int(calls[bad[0]])
            raise DerivationError(
                f"module {ms.module_text(i, short=True)} (#{i}) calls sub-L-system {numbers[bad[0]]:g}, which the "
                f"grammar does not have (its L-systems: {', '.join(str(n) for n in sorted(known))})"
            )
    return out
