"""Exact matching of array rows through a 64-bit hash: one 1-D sort instead of sorting rows.

``np.unique(a, axis=0)`` and sorts of ``void`` views compare rows byte by byte
and are several times slower than sorting one ``uint64`` per row.  Rows are
hashed (their 8-byte words mixed by multiplication, wrapping), the hashes sorted,
and every match found through a hash is confirmed on the rows themselves, so a
collision can only cost a match, never make a wrong one.
"""

from __future__ import annotations

import numpy as np

__all__ = ["find_rows", "row_hash"]

_MIX = np.array(
    [0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9, 0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD],
    np.uint64,
)


def row_hash(rows: np.ndarray) -> np.ndarray:
    """``(n,) uint64`` hash of each row of an ``(n, k)`` array of 4- or 8-byte numbers (``-0.0`` and ``0.0`` differ).

    >>> a = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [3.0, 2.0, 1.0]])
    >>> h = row_hash(a); bool(h[0] == h[1]), bool(h[0] == h[2])
    (True, False)
    """
    rows = np.ascontiguousarray(rows)
    words = rows.view(np.uint64 if rows.dtype.itemsize == 8 else np.uint32).astype(np.uint64)
    h = np.zeros(len(rows), np.uint64)
    with np.errstate(over="ignore"):
        for j in range(words.shape[1]):
            h = (h ^ words[:, j]) * _MIX[j % len(_MIX)]
            h ^= h >> np.uint64(29)
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
