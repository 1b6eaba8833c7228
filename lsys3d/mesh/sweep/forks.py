"""Forks: the rings at the base of a thick child blending out of its parent (``SweepOptions.fork_blend``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...arrays import dot
from ...turtle.skeleton import Skeleton
from .options import SweepOptions

FORK_RATIO = 0.5
"""A child at least this fraction of its parent's width gets a blended base (:func:`_fork_bases`)."""
FORK_PIECES = 3
"""Spans of a blended base: its bend turns at most a quarter of the child's lean at each of its rings."""
FORK_WAIST = 0.97
"""A blended base starts this fraction of the parent's inner radius wide (``r cos(pi / sides)``, the middle of
its faces), so it starts inside the parent."""


class Spans(NamedTuple):
    """The straight spans the sweep draws, a row each, chain after chain: the skeleton's kept segments (runs of
    them merged), and the spans of the blended bases :func:`_fork_bases` adds."""

    seg: np.ndarray
    """(k,) int64: the segment each span comes from."""
    chain: np.ndarray
    """(k,) int64: its chain."""
    p0: np.ndarray
    """(k, 3) float64: where it starts."""
    p1: np.ndarray
    """(k, 3) float64: where it ends."""
    v0: np.ndarray
    """(k,) float64: metres along the chain at its start."""
    v1: np.ndarray
    """(k,) float64: and at its end."""
    w0: np.ndarray
    """(k,) float64: its width at the start."""
    w1: np.ndarray
    """(k,) float64: and at the end."""
    tv0: np.ndarray
    """(k,) float64: the texture's v at the start."""
    tv1: np.ndarray
    """(k,) float64: and at the end."""
    rate: np.ndarray
    """(k,) float64: texture v per metre where the radius is 1 (the chain's tiles over its perimeter)."""


def _fork_bases(skeleton: Skeleton, opt: SweepOptions, chain_sides, spans: Spans) -> tuple[Spans, np.ndarray]:
    """The spans with a blended base at the start of each thick child (rows added), and which of them end at a
    ring of a curve (``pinned``: no ``merge_angle`` leaves it out).

    A child as thick as its parent that leans out of it (tree3d's trunk-top
    fork: three children as wide as the trunk, 23 degrees out) makes a ledge:
    its straight tube leaves the parent's wall all at once, turning the
    outline by the whole lean in one crease that no collar of the cleanup is
    wide enough to round.  So the first ``delta = blend * r`` metres of such
    a child are swept along a quadratic Bezier curve instead of the straight
    segment: from ``delta`` back along the parent's heading, through the
    control point at the fork, to ``delta`` along the child, in
    ``FORK_PIECES`` spans.  The child leaves the parent's wall along it and
    bends out ring by ring: the outline turns by a fraction of the lean at
    each ring, which the smooth normals and the collars blend.

    A child that starts a chain begins inside its parent, ``FORK_WAIST`` of
    the parent's inner radius wide; the child that goes on in its parent's chain
    (the continuation, one of the fork's children too) has the last ``delta``
    of its parent's segment replaced by the curve.  Beyond the curve the
    tubes are unchanged; within it the axis stays within ``delta * |c - a| / 4``
    of the straight one.  A child thinner than ``FORK_RATIO`` of its parent or
    than ``fork_blend_min`` of the plant's size (the diagonal of the
    skeleton's box: at 0.002 a child under 2 pixels wide in a 1,000-pixel
    picture of the whole plant, whose ledge cannot be seen), one that does
    not start at its parent's end, one that leans less than a degree or more
    than 90, one whose curve does not fit in 0.45 of its own and its parent's
    segment (short thick segments: a crowd, where curves would only add
    pieces that touch), and a bend where no other branch leaves, are left as
    they are.
    """
    seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate = spans
    k = len(seg)
    none = (spans, np.zeros(k, bool))
    if k == 0:
        return none
    head = np.concatenate([[True], chain[1:] != chain[:-1]])
    parent = skeleton.parent[seg]
    children = np.bincount(parent[parent >= 0], minlength=len(skeleton))
    previous = np.concatenate([[-1], seg[:-1]])
    # a chain's first row, or a row going on from its parent's row at a fork
    on = ~head & (previous == parent) & (children[np.maximum(parent, 0)] > 1)
    rows = np.flatnonzero((parent >= 0) & (head | on))
    if not len(rows):
        return none
    par = parent[rows]
    ps, pe = skeleton.start[par].astype(np.float64), skeleton.end[par].astype(np.float64)
    parent_length = np.linalg.norm(pe - ps, axis=1)
    a = (pe - ps) / np.maximum(parent_length, 1e-300)[:, None]
    length = np.linalg.norm(p1[rows] - p0[rows], axis=1)
    c = (p1[rows] - p0[rows]) / np.maximum(length, 1e-300)[:, None]
    lean = np.degrees(np.arccos(np.clip(dot(a, c), -1.0, 1.0)))
    w_parent = skeleton.width_end[par]
    scale = np.abs(p1).max() + 1.0
    cont = on[rows]
    room = np.where(cont, np.linalg.norm(p1[rows - cont] - p0[rows - cont], axis=1), parent_length)
    # the whole curve fits in 0.45 of either segment (a segment may lose as much at each end: a child that is a
    # fork itself), or there is no blend: segments shorter than a blend are a crowd of short thick pieces (the
    # constant-width fern), where a curve in each would only add pieces that touch (over the union's limit)
    delta = opt.fork_blend * 0.5 * w0[rows]
    fits = delta <= 0.45 * np.minimum(length, room)
    size = float(np.linalg.norm(np.diff(skeleton.bounds(), axis=0)))
    ok = (
        (w0[rows] >= FORK_RATIO * w_parent)
        & (w0[rows] >= opt.fork_blend_min * size)
        & (np.linalg.norm(p0[rows] - pe, axis=1) <= 1e-9 * scale)
        & (lean >= 1.0)
        & (lean <= 90.0)
        & (delta > 0)
        & fits
    )
    if not ok.any():
        return none
    rows, a, c, delta, length, w_parent, cont = rows[ok], a[ok], c[ok], delta[ok], length[ok], w_parent[ok], cont[ok]
    before = rows - 1  # the parent's row, for a continuation
    n, m = len(rows), FORK_PIECES
    t = np.linspace(0.0, 1.0, m + 1)[None, :]
    fork = p0[rows]
    start = fork - delta[:, None] * a
    end = fork + delta[:, None] * c
    tt = t[..., None]
    curve = (1 - tt) ** 2 * start[:, None] + 2 * tt * (1 - tt) * fork[:, None] + tt**2 * end[:, None]  # (n, m+1, 3)
    f = delta / length  # the share of the child's first segment the curve replaces
    w_end = w0[rows] + f * (w1[rows] - w0[rows])
    tv_end = tv0[rows] + f * (tv1[rows] - tv0[rows])
    b = np.where(cont, before, 0)
    g = delta / np.maximum(np.linalg.norm(p1[b] - p0[b], axis=1), 1e-300)  # the share of the parent's row, likewise
    waist = FORK_WAIST * np.cos(np.pi / chain_sides[skeleton.chains.chain_of[par[ok]]]) * w_parent
    w_start = np.where(cont, w1[b] - g * (w1[b] - w0[b]), np.minimum(w0[rows], waist))
    tv_start = np.where(cont, tv1[b] - g * (tv1[b] - tv0[b]), 2 * tv0[rows] - tv_end)
    width = w_start[:, None] + t * (w_end - w_start)[:, None]
    tv = tv_start[:, None] + t * (tv_end - tv_start)[:, None]
    v = (v0[rows] - delta)[:, None] + t * (2 * delta)[:, None]
    # the continuations' parent rows now end where the curve starts
    p1, w1, v1, tv1 = p1.copy(), w1.copy(), v1.copy(), tv1.copy()
    bc = before[cont]
    p1[bc], w1[bc], v1[bc], tv1[bc] = start[cont], w_start[cont], v[cont, 0], tv_start[cont]
    # the m spans of each curve come before what is left of its child's first segment
    is_row = np.zeros(k, np.int64)
    is_row[rows] = 1
    place = np.arange(k) + m * np.cumsum(is_row)
    out = np.empty(k + n * m, np.int64)
    out[place] = np.arange(k)
    first = place[rows]
    spans = (first[:, None] - m + np.arange(m)[None, :]).ravel()
    out[spans] = np.repeat(rows, m)
    seg, chain, rate = seg[out], chain[out], rate[out]
    p0, p1, v0, v1, w0, w1, tv0, tv1 = (x[out] for x in (p0, p1, v0, v1, w0, w1, tv0, tv1))
    p0[spans], p1[spans] = curve[:, :-1].reshape(-1, 3), curve[:, 1:].reshape(-1, 3)
    w0[spans], w1[spans] = width[:, :-1].ravel(), width[:, 1:].ravel()
    v0[spans], v1[spans] = v[:, :-1].ravel(), v[:, 1:].ravel()
    tv0[spans], tv1[spans] = tv[:, :-1].ravel(), tv[:, 1:].ravel()
    p0[first], w0[first], v0[first], tv0[first] = end, w_end, v[:, -1], tv_end
    # the curve's rings (and the one where a continuation's curve starts) are its shape: merge_angle keeps them
    pinned = np.zeros(k + n * m, bool)
    pinned[spans] = True
    pinned[place[bc]] = True
    return Spans(seg, chain, p0, p1, v0, v1, w0, w1, tv0, tv1, rate), pinned
