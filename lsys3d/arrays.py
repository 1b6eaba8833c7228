"""Array helpers shared by the stages: CSR offsets, index ranges, unit vectors, row grouping and hashing,
distinct values and membership by sorting, connected components, handing the memory of freed arrays back
to the system, and keeping numpy's arrays in small pages (:func:`small_pages`).

Every stage stores variable-length groups (the segments of a chain, the rings
of a tube, the points of a polygon) as one flat array plus ``offsets``, like a
CSR matrix: group ``i`` is ``flat[offsets[i]:offsets[i + 1]]``.  The helpers
here build and walk such arrays without Python loops; they live in one place
so that no stage keeps its own copy.

Rows are matched exactly through a 64-bit hash (:func:`row_hash`): one 1-D
sort instead of sorting rows (``np.unique(a, axis=0)`` and ``lexsort`` compare
rows column by column and are several times slower).  Every match found
through a hash is confirmed on the rows themselves, so a collision can only
cost a match, never make a wrong one.

Distinct values and membership (:func:`unique`, :func:`isin`) go through one
sort too: numpy 2.3 and later find ``np.unique``'s values with a hash table
(also inside ``np.isin``, ``np.union1d`` and ``np.setdiff1d``), which is 10 to
80 times slower than sorting on arrays of a million distinct integers (numpy
2.4.6 here: 1.7 s against 0.03 s for 10**6 values, 22 s against 0.26 s for 10**7):
the 262,143-segment plant's union spent 6 s in it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

import numpy as np

from .compiling import inner, kernel

__all__ = [
    "ROW_HASH_MIX",
    "components",
    "dot",
    "dot3",
    "find_rows",
    "first_equal_row",
    "gather",
    "hash_word",
    "isin",
    "local_index",
    "offsets",
    "ranges",
    "release_memory",
    "row_hash",
    "row_table",
    "same_row",
    "search_left",
    "search_right",
    "small_pages",
    "unique",
    "unit",
]

_MIX = np.array(
    [0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9, 0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD],
    np.uint64,
)


def offsets(counts: np.ndarray) -> np.ndarray:
    """CSR offsets of groups of ``counts`` elements, ``(len(counts) + 1,) int64``.

    >>> offsets(np.array([2, 0, 3])).tolist()
    [0, 2, 2, 5]
    """
    out = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(counts, out=out[1:])
    return out


def local_index(counts: np.ndarray) -> np.ndarray:
    """``0 .. counts[i] - 1`` for each group ``i``, concatenated: each element's index inside its group.

    >>> local_index(np.array([2, 0, 3])).tolist()
    [0, 1, 0, 1, 2]
    """
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    return np.arange(int(np.sum(counts))) - starts


def ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``arange(s, s + l)`` for each pair, concatenated, without a Python loop.

    >>> ranges(np.array([5, 0, 9]), np.array([2, 0, 3])).tolist()
    [5, 6, 9, 10, 11]
    """
    lengths = np.asarray(lengths).astype(np.int64)
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    nz = lengths > 0
    starts, lengths = np.asarray(starts)[nz].astype(np.int64), lengths[nz]
    ends = np.cumsum(lengths)
    steps = np.ones(total, np.int64)  # one cumulative sum: +1 inside a range, a jump to the next range's start
    steps[0] = starts[0]
    steps[ends[:-1]] = starts[1:] - (starts[:-1] + lengths[:-1] - 1)
    return np.cumsum(steps)


def gather(offsets_: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The elements of the CSR groups ``which``: their flat indices, the groups' old starts and their new offsets.

    >>> idx, old, new = gather(np.array([0, 2, 2, 5]), np.array([2, 0]))
    >>> idx.tolist(), old.tolist(), new.tolist()
    ([2, 3, 4, 0, 1], [2, 0], [0, 3, 5])
    """
    counts = offsets_[which + 1] - offsets_[which]
    new = offsets(counts)
    old = offsets_[which]
    return ranges(old, counts), old, new


def unique(a) -> np.ndarray:
    """The distinct values of ``a`` (flattened), ascending: ``np.unique(a)`` for integers, by a sort.

    >>> unique(np.array([[3, 1], [3, 2]])).tolist()
    [1, 2, 3]
    """
    s = np.sort(np.asarray(a).ravel())
    keep = np.ones(len(s), bool)
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def isin(a, b) -> np.ndarray:
    """``np.isin(a, b)`` for integers, by a sort of ``b``: whether each element of ``a`` is one of ``b``'s.

    >>> isin(np.array([1, 5, 2]), [2, 3]).tolist()
    [False, False, True]
    """
    a = np.asarray(a)
    values = unique(b)
    if not len(values):
        return np.zeros(a.shape, bool)
    at = np.minimum(np.searchsorted(values, a), len(values) - 1)
    return values[at] == a


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product over the last axis."""
    return np.einsum("...i,...i->...", a, b)


@inner(nogil=True, inline="always")
def dot3(x0, x1, x2, y0, y1, y2):  # pragma: no cover - compiled
    """One dot product of 3-vectors in a compiled kernel, with the bits of :func:`dot` (``np.einsum`` adds x, z,
    then y), so a kernel that replaces numpy rows gives the same answer."""
    return (x0 * y0 + x2 * y2) + x1 * y1


def unit(v: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Rows of ``v`` scaled to unit length; rows not longer than ``eps`` are returned as they are.

    >>> unit(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])).tolist()
    [[0.6, 0.8, 0.0], [0.0, 0.0, 0.0]]
    """
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > eps, n, 1.0)


def row_hash(rows: np.ndarray) -> np.ndarray:
    """``(n,) uint64`` hash of each row of an ``(n, k)`` array of 4- or 8-byte numbers (``-0.0`` and ``0.0`` differ).

    >>> a = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [3.0, 2.0, 1.0]])
    >>> h = row_hash(a); bool(h[0] == h[1]), bool(h[0] == h[2])
    (True, False)
    """
    rows = np.ascontiguousarray(rows)
    return _row_hash(rows.view(np.uint64 if rows.dtype.itemsize == 8 else np.uint32), ROW_HASH_MIX)


ROW_HASH_MIX = _MIX
"""The multipliers of :func:`row_hash`, for a compiled kernel that hashes rows it never stores (:func:`hash_word`)."""


@inner(nogil=True, inline="always")
def hash_word(x, word, j, mix):  # pragma: no cover - compiled
    """One step of :func:`row_hash`: the hash ``x`` of a row's first ``j`` words, with word ``j`` (its bits as
    uint64) added.  A row's hash starts at ``np.uint64(0)``."""
    x = (x ^ np.uint64(word)) * mix[j % len(mix)]
    return x ^ (x >> np.uint64(29))


@kernel(nogil=True)
def _row_hash(words, mix):  # pragma: no cover - compiled
    """:func:`row_hash` of the rows' words (uint32 or uint64), a row at a time: wrapping uint64 arithmetic."""
    h = np.empty(len(words), np.uint64)
    for i in range(len(words)):
        x = np.uint64(0)
        for j in range(words.shape[1]):
            x = hash_word(x, words[i, j], j, mix)
        h[i] = x
    return h


def find_rows(have: np.ndarray, want: np.ndarray) -> np.ndarray:
    """For each row of ``want``, the index of an equal row of ``have`` (exact), or -1.

    >>> find_rows(np.array([[0.0, 1.0], [2.0, 3.0]]), np.array([[2.0, 3.0], [5.0, 5.0]])).tolist()
    [1, -1]
    """
    if not len(have):
        return np.full(len(want), -1, np.int64)
    hh, hw = row_hash(have), row_hash(want)
    order = np.argsort(hh, kind="stable")
    sorted_h = hh[order]
    pos = np.minimum(np.searchsorted(sorted_h, hw), len(have) - 1)
    found = order[pos]
    ok = (sorted_h[pos] == hw) & (have[found] == want).all(axis=1)
    return np.where(ok, found, -1)


def first_equal_row(keys: np.ndarray) -> np.ndarray:
    """For each row of an integer array ``(n, k)``, the index of the first row equal to it.

    What ``np.unique(keys, axis=0, return_index=True, return_inverse=True)``
    gives, from a hash table of the rows (a 64-bit hash; rows sharing one are
    compared): one pass, several times faster than a sort.

    >>> first_equal_row(np.array([[1, 2, 3], [0, 0, 0], [1, 2, 3], [0, 0, 0]])).tolist()
    [0, 1, 0, 1]
    """
    keys = np.ascontiguousarray(keys)
    if keys.dtype.kind in "iu" and keys.dtype.itemsize in (4, 8):  # equal rows are equal bits: signed or not,
        # one compiled signature, int64: 4-byte keys (the union's weld of float32 positions) are widened, a copy,
        # rather than numba compiling the table and the hash a second time on a first run (half a CPU second)
        keys = keys.view(np.int32 if keys.dtype.itemsize == 4 else np.int64).astype(np.int64, copy=False)
    return row_table(keys, row_hash(keys))[1]


@kernel(nogil=True)
def row_table(keys, h):  # pragma: no cover - compiled
    """An open-addressing hash table of the rows of ``keys`` (their :func:`row_hash` ``h``), slot from a hash's
    top bits, in one pass in row order: ``table`` (per slot, a row or -1; of equal rows, the first), ``owner``
    (each row's first equal row: :func:`first_equal_row`) and ``shift`` (row ``i``'s probe starts at slot
    ``h[i] >> shift`` and steps by one).  Rows sharing a hash are compared (:func:`same_row`), so the answer is
    defined by the rows alone: the one a sort gives.  The slots are int32 (half the memory a table of int64
    takes, and of its cache misses): fewer than 2**31 rows."""
    n = len(keys)
    if n >= 2**31:
        raise ValueError("row_table: 2**31 rows or more")
    bits = 1
    while (1 << bits) < 2 * n:
        bits += 1
    size = 1 << bits
    # np.empty and a fill, not np.full (nor np.zeros, np.ones, np.arange) in a kernel: numba compiles those for each
    # type and each set of its callers' flags, with the np.empty they call, a few hundredths of a CPU second each on
    # a first run, where the kernels' own np.empty is compiled already.  The same values.
    table = np.empty(size, np.int32)
    table[:] = -1
    shift = np.uint64(64 - bits)
    owner = np.empty(n, np.int64)
    for i in range(n):
        s = np.int64(h[i] >> shift)
        while True:
            j = table[s]
            if j < 0:
                table[s] = i
                owner[i] = i
                break
            if h[j] == h[i] and same_row(keys, j, keys, i):
                owner[i] = j
                break
            s = (s + 1) & (size - 1)
    return table, owner, shift


@inner(nogil=True, inline="always")
def same_row(a, i, b, j):  # pragma: no cover - compiled
    """Whether row ``i`` of ``a`` equals row ``j`` of ``b``, value by value."""
    same = True
    for c in range(a.shape[1]):
        same &= a[i, c] == b[j, c]
    return same


def components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Connected component of each of ``n`` nodes joined by edges ``a - b``: the smallest node index in it.

    Union-find in one compiled pass over the edges (each root hooked under
    the smaller root, paths halved), then one pass that points every node at
    its root; no temporaries beyond the labels.

    >>> components(6, np.array([0, 4, 2]), np.array([1, 5, 1])).tolist()
    [0, 0, 0, 3, 4, 4]
    """
    # one compiled signature whatever the caller holds (a column of a pair array, int32 faces)
    a, b = np.ascontiguousarray(a, dtype=np.int64), np.ascontiguousarray(b, dtype=np.int64)
    return _components(n, a, b) if len(a) else np.arange(n, dtype=np.int64)


@kernel(nogil=True)
def _components(n, a, b):  # pragma: no cover - compiled
    parent = np.empty(n, np.int64)  # (not np.arange: see row_table)
    for i in range(n):
        parent[i] = i
    for e in range(len(a)):
        x, y = a[e], b[e]
        while parent[x] != x:  # the roots, halving the paths on the way
            parent[x] = parent[parent[x]]
            x = parent[x]
        while parent[y] != y:
            parent[y] = parent[parent[y]]
            y = parent[y]
        if x < y:
            parent[y] = x
        elif y < x:
            parent[x] = y
    # a node's parent is never larger than itself: in order, each node's parent already points at its root
    for i in range(n):
        parent[i] = parent[parent[i]]
    return parent


@kernel(nogil=True)
def sort_between(a, lo, hi):  # pragma: no cover - compiled
    """Sort ``a[lo:hi]`` in place, ascending (a heapsort): for integers in a kernel, what ``np.sort`` gives.

    ``np.sort`` in a kernel makes numba compile its generic quicksort and comparisons (for floats and complex
    numbers too), about 2 CPU seconds on a first run; these few lines compile in a tenth of that.  Equal values
    end in any order: for integers that is the same array.
    """
    n = hi - lo
    for root in range(n // 2 - 1, -1, -1):
        _sift_down(a, lo, root, n)
    for end in range(n - 1, 0, -1):
        a[lo], a[lo + end] = a[lo + end], a[lo]
        _sift_down(a, lo, np.int64(0), end)  # (not the literal 0: numba would compile _sift_down again for it)


@inner(nogil=True)
def _sift_down(a, lo, root, n):  # pragma: no cover - compiled
    """Move ``a[lo + root]`` down the max-heap ``a[lo:lo + n]`` to its place."""
    while True:
        child = 2 * root + 1
        if child >= n:
            return
        if child + 1 < n and a[lo + child] < a[lo + child + 1]:
            child += 1
        if not a[lo + root] < a[lo + child]:
            return
        a[lo + root], a[lo + child] = a[lo + child], a[lo + root]
        root = child


# np.searchsorted in a kernel makes numba compile its generic search with comparisons for floats and complex
# numbers, for each type of array and value (a third of a CPU second each on a first run); a kernel of lsys3d
# searches sorted integers, which these few lines do.


@inner(nogil=True)
def search_left(a, v):  # pragma: no cover - compiled
    """The first index ``i`` of the ascending integers ``a`` with ``a[i] >= v`` (``len(a)`` if none): in a kernel,
    what ``np.searchsorted(a, v)`` gives."""
    lo, hi = 0, len(a)
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@inner(nogil=True)
def search_right(a, v):  # pragma: no cover - compiled
    """The first index ``i`` of the ascending integers ``a`` with ``a[i] > v`` (``len(a)`` if none): in a kernel,
    what ``np.searchsorted(a, v, side="right")`` gives."""
    lo, hi = 0, len(a)
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo


try:  # glibc's malloc_trim, where there is one (Linux)
    _LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6") if sys.platform.startswith("linux") else None
    _LIBC.malloc_trim.argtypes = [ctypes.c_size_t] if _LIBC is not None else None
except (OSError, AttributeError):  # pragma: no cover - not glibc
    _LIBC = None


def release_memory() -> None:
    """Hand the memory freed by the last stage back to the system (glibc keeps freed heap memory otherwise).

    numpy's medium-sized arrays come from the C heap, and glibc returns freed
    heap memory only from its top; after a stage of many temporaries the
    process would keep hundreds of megabytes it no longer uses (the
    262,143-segment plant: 1.5 GB resident after its union, 0.7 GB of them
    the bark).  A no-op where the C library is not glibc.
    """
    if _LIBC is not None:
        _LIBC.malloc_trim(0)


def small_pages() -> None:
    """Stop numpy asking the kernel for transparent huge pages, in this process and the processes it starts.

    numpy marks every array of 4 MB or more ``madvise(MADV_HUGEPAGE)``; where
    the kernel then compacts memory on the page fault (``defrag`` set to
    ``madvise``, the default), touching a fresh array can stall for seconds:
    610 MB took 5-18 s on the 2-core test machine against 1-2 s in small
    pages, and the 65,535-segment plant's ``generate`` took 14.8-24.1 s
    against 10.7-15.3 s (the union 6.9-10.0 s against 3.7-5.1 s).  Called by
    the command line, which owns its process; a library call leaves the
    caller's numpy as it is.  An explicit ``NUMPY_MADVISE_HUGEPAGE`` in the
    environment wins.  The results are the same bytes either way.
    """
    if os.environ.get("NUMPY_MADVISE_HUGEPAGE") is not None:
        return
    os.environ["NUMPY_MADVISE_HUGEPAGE"] = "0"  # the union's worker processes
    setter = getattr(getattr(getattr(np, "_core", None), "multiarray", None), "_set_madvise_hugepage", None)
    if setter is not None:
        setter(False)
