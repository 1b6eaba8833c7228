"""Array helpers shared by the stages: CSR offsets, index ranges, unit vectors, row grouping, mesh pieces.

Every stage stores variable-length groups (the segments of a chain, the rings
of a tube, the points of a polygon) as one flat array plus ``offsets``, like a
CSR matrix: group ``i`` is ``flat[offsets[i]:offsets[i + 1]]``.  The helpers
here build and walk such arrays without Python loops; they live in one place
so that no stage keeps its own copy.
"""

from __future__ import annotations

import numpy as np

__all__ = ["component_labels", "dot", "first_equal_row", "gather", "local_index", "offsets", "ranges", "unit"]


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
    starts = np.asarray(starts).astype(np.int64)
    return np.repeat(starts, lengths) + local_index(lengths)


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


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product over the last axis."""
    return np.einsum("...i,...i->...", a, b)


def unit(v: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Rows of ``v`` scaled to unit length; rows not longer than ``eps`` are returned as they are.

    >>> unit(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])).tolist()
    [[0.6, 0.8, 0.0], [0.0, 0.0, 0.0]]
    """
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > eps, n, 1.0)


def first_equal_row(keys: np.ndarray) -> np.ndarray:
    """For each row of an integer array ``(n, k)``, the index of the first row equal to it.

    What ``np.unique(keys, axis=0, return_index=True, return_inverse=True)``
    gives, from one stable ``lexsort`` of the columns (several times faster).

    >>> first_equal_row(np.array([[1, 2, 3], [0, 0, 0], [1, 2, 3], [0, 0, 0]])).tolist()
    [0, 1, 0, 1]
    """
    order = np.lexsort(keys.T[::-1])  # stable: equal rows keep their order, the first comes first
    ranked = keys[order]
    starts = np.ones(len(keys), bool)
    starts[1:] = (ranked[1:] != ranked[:-1]).any(axis=1)
    owner = np.empty(len(keys), np.int64)
    owner[order] = order[np.flatnonzero(starts)][np.cumsum(starts) - 1]
    return owner


def component_labels(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """For each vertex, the smallest vertex index of the connected piece it is in (vertices joined by edges).

    Label propagation with pointer jumping, in numpy: a few passes over the
    edges, whatever the mesh's diameter.  An unused vertex is its own piece.

    >>> component_labels(np.array([[0, 1, 2], [2, 3, 4], [5, 6, 7]]), 9).tolist()
    [0, 0, 0, 0, 0, 5, 5, 5, 8]
    """
    faces = np.asarray(faces, dtype=np.int64)
    parent = np.arange(n_vertices, dtype=np.int64)
    if len(faces) == 0:
        return parent
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()
    while True:
        pa, pb = parent[a], parent[b]
        differ = pa != pb
        if not differ.any():
            break
        lo, hi = np.minimum(pa[differ], pb[differ]), np.maximum(pa[differ], pb[differ])
        np.minimum.at(parent, hi, lo)  # hook each root under the smaller root it touches
        while True:  # compress paths until every vertex points at a root
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped
    return parent
