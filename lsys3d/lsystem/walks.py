"""Walks over a bracketed module string that context matching takes (ABOP section 1.8), compiled.

:func:`skip_tables` gives, for every position at once, where a left or right context walk lands (the
tables :class:`lsys3d.lsystem.derive._Context` reads); :func:`walk_right` and :func:`right_plain` walk from
the candidates of a rule alone, which is cheaper when each walk is short (a query module right after its
apex, ``A > ?P(x, y, z)``: the open L-systems of :mod:`lsys3d.turtle.query`, whose strings are walked before
every step) and give up past a budget, so a long walk still costs one pass over the string.
"""

from __future__ import annotations

import numpy as np

from ..compiling import kernel

__all__ = ["landing", "right_plain", "skip_tables", "walk_right"]

_OPEN, _CLOSE = ord("["), ord("]")


@kernel(nogil=True)
def skip_tables(symbols, ignored):
    """Where a context walk lands from each position of a bracketed string, in one pass each way.

    ``ignored[code]`` is True for symbols in the grammar's ignore set.  Each
    table has an extra last entry (index ``m``) for a walk that starts past
    the end.  An unmatched ``[`` or ``]`` ends a walk (no context).

    Returns
    -------
    left : (m + 1,) int64
        The module a left-context walk finds starting at ``p`` and going left:
        ignored symbols and ``[`` (into the parent) are stepped over, a
        ``[...]`` lateral branch ending at ``p`` is skipped; -1 if none.
    right : (m + 1,) int64
        The module a right-context walk finds starting at ``p``: ignored
        symbols and whole ``[...]`` branches are skipped; ``m`` if none.
    kept : (m + 1,) int64
        The first position at or after ``p`` whose symbol is not ignored.
    close : (m + 1,) int64
        The ``]`` that ends the branch holding ``p`` (nested branches
        skipped); ``m`` if the branch runs to the end.
    """
    m = symbols.shape[0]
    match = np.full(m, -1, np.int64)
    stack = np.empty(m, np.int64)
    top = 0
    for i in range(m):
        s = symbols[i]
        if s == _OPEN:
            stack[top] = i
            top += 1
        elif s == _CLOSE and top > 0:
            top -= 1
            match[i] = stack[top]
            match[stack[top]] = i
    left = np.empty(m + 1, np.int64)
    for p in range(m):
        s = symbols[p]
        if s == _CLOSE:
            j = match[p]
            left[p] = left[j - 1] if j > 0 else -1
        elif s == _OPEN or ignored[s]:
            left[p] = left[p - 1] if p > 0 else -1
        else:
            left[p] = p
    left[m] = left[m - 1] if m > 0 else -1
    right = np.empty(m + 1, np.int64)
    kept = np.empty(m + 1, np.int64)
    close = np.empty(m + 1, np.int64)
    right[m] = kept[m] = close[m] = m
    for p in range(m - 1, -1, -1):
        s = symbols[p]
        j = match[p]
        kept[p] = kept[p + 1] if ignored[s] else p
        if s == _OPEN:
            right[p] = right[j + 1] if j >= 0 else m
            close[p] = close[j + 1] if j >= 0 else m
        else:
            right[p] = right[p + 1] if ignored[s] else p
            close[p] = p if s == _CLOSE else close[p + 1]
    return left, right, kept, close


@kernel(nogil=True)
def landing(symbols, ignored, p):
    """:func:`skip_tables`' ``right[p]`` walked (``p <= m``): ignored symbols and whole ``[...]`` branches stepped
    over (a ``[`` without its ``]`` ends the walk at ``m``); and how many modules the walk passed."""
    m = symbols.shape[0]
    work = 0
    while p < m:
        s = symbols[p]
        if s == _OPEN:  # to the module after its ']' (the first where the depth is back to 0), or m
            depth = 1
            q = p + 1
            while q < m and depth > 0:
                c = symbols[q]
                if c == _OPEN:
                    depth += 1
                elif c == _CLOSE:
                    depth -= 1
                q += 1
            work += q - p
            p = q if depth == 0 else m
        elif ignored[s]:
            p += 1
            work += 1
        else:
            break
    return p, work


@kernel(nogil=True)
def walk_right(symbols, ignored, starts, budget):
    """:func:`landing` from each of ``starts``; gives up (False) once more than ``budget`` modules were walked."""
    out = np.empty(starts.shape[0], np.int64)
    work = 0
    for k in range(starts.shape[0]):
        out[k], walked = landing(symbols, ignored, starts[k])
        work += walked
        if work > budget:
            return out, False
    return out, True


@kernel(nogil=True)
def right_plain(symbols, arity, offsets, params, ignored, starts, codes, arities, n_values, budget):
    """A right context of plain modules (``codes``, -1 for ``*``, with ``arities``) matched after each of
    ``starts``: which match, and the values of the pattern's formals (rows), as :meth:`_Context.right` finds
    them.  Gives up (False) once its walks (:func:`landing`) passed more than ``budget`` modules."""
    m = symbols.shape[0]
    n = starts.shape[0]
    ok = np.ones(n, np.bool_)
    values = np.zeros((n_values, n))
    work = 0
    for c in range(n):
        j = starts[c]
        v = 0
        for k in range(codes.shape[0]):
            p, walked = landing(symbols, ignored, min(j, m))
            work += walked
            if work > budget:
                return ok, values, False
            if p >= m or symbols[p] == _CLOSE:
                ok[c] = False
                break
            if codes[k] >= 0:
                if symbols[p] != codes[k] or arity[p] != arities[k]:
                    ok[c] = False
                    break
                for q in range(arities[k]):
                    values[v + q, c] = params[offsets[p] + q]
                v += arities[k]
            j = p + 1
    return ok, values, True
