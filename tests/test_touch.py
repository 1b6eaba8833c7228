"""The union's broad phase (lsys3d.mesh.union.touch): compiled kernels against plain numpy references."""

from __future__ import annotations

import numpy as np
import pytest
from skeletons import make_skeleton

from lsys3d.arrays import offsets
from lsys3d.errors import LimitError
from lsys3d.mesh.sweep import SweepOptions, sweep
from lsys3d.mesh.union.touch import _pairwise_sum, _rings, pieces, segment_distance, touching


def bushy_tubes(seed: int, n: int, sides: int = 8):
    """``n`` segments, each from the end of a random earlier one: many junctions and crossings."""
    rng = np.random.default_rng(seed)
    start, end, parent = [np.zeros(3)], [np.array([0.0, 1.0, 0.0])], [-1]
    for i in range(1, n):
        p = int(rng.integers(0, i))
        d = end[p] - start[p]
        d = d / np.linalg.norm(d) + rng.normal(scale=0.6, size=3)
        start.append(end[p])
        end.append(end[p] + rng.uniform(0.05, 0.6) * d / np.linalg.norm(d))
        parent.append(p)
    width = rng.uniform(0.03, 0.15, n)
    skeleton = make_skeleton(start, end, width, 0.7 * width, parent, [0] * n)
    return sweep(skeleton, SweepOptions(sides=sides, min_sides=min(sides, 8)))


def segment_distance_rows(p1, q1, p2, q2):
    """The closest points of two segments, clamped (Ericson 5.1.9), written with numpy rows."""

    def dot(a, b):
        return np.einsum("...i,...i->...", a, b)

    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f, c, b = dot(d1, d1), dot(d2, d2), dot(d2, r), dot(d1, r), dot(d1, d2)
    tiny = 1e-300
    denom = a * e - b * b
    s = np.where(denom > tiny, np.clip((b * f - c * e) / np.maximum(denom, tiny), 0, 1), 0.0)
    t = np.where(e > tiny, (b * s + f) / np.maximum(e, tiny), 0.0)
    s = np.where(
        t < 0, np.clip(-c / np.maximum(a, tiny), 0, 1), np.where(t > 1, np.clip((b - c) / np.maximum(a, tiny), 0, 1), s)
    )
    t = np.clip(t, 0, 1)
    return np.linalg.norm(p1 + d1 * s[:, None] - p2 - d2 * t[:, None], axis=1)


def test_segment_distance_is_the_numpy_rows_bit_for_bit():
    rng = np.random.default_rng(3)
    p1, q1, p2, q2 = rng.normal(size=(4, 5000, 3))
    q1[::7] = p1[::7]  # points, not segments
    q2[::5] = p2[::5]
    p2[::11], q2[::11] = p1[::11] + 0.5, q1[::11] + 0.5  # parallel
    assert segment_distance(p1, q1, p2, q2).tobytes() == segment_distance_rows(p1, q1, p2, q2).tobytes()
    # and it is a distance: two crossing segments touch, parallel ones are their offset apart
    x = np.array([[-1.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, -1, 0]]), np.array([[0.0, 1, 0]])
    assert segment_distance(*x)[0] == 0.0
    assert segment_distance(x[0], x[1], x[0] + [0, 0, 2.0], x[1] + [0, 0, 2.0])[0] == pytest.approx(2.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_touching_is_the_brute_force_search(seed):
    tubes = bushy_tubes(seed, 60)
    pcs = pieces(tubes)
    margin = 0.01
    a, b = touching(pcs, margin)
    # every pair of pieces of different tubes whose padded boxes overlap and capsules are within reach
    scale = float(np.abs(np.concatenate([pcs.lo, pcs.hi])).max()) + 1.0
    pad = margin * (pcs.hi - pcs.lo).max(axis=1, keepdims=True) + 1e-9 * scale
    lo, hi = pcs.lo - pad, pcs.hi + pad
    i, j = np.triu_indices(len(pcs), 1)
    ok = (pcs.tube[i] != pcs.tube[j]) & ((lo[i] <= hi[j]) & (lo[j] <= hi[i])).all(axis=1)
    i, j = i[ok], j[ok]
    reach = (pcs.radius[i] + pcs.radius[j]) * (1.0 + margin) + 1e-9 * scale
    ok = segment_distance_rows(pcs.p[i], pcs.q[i], pcs.p[j], pcs.q[j]) <= reach
    assert len(a) > 20
    assert np.array_equal(a, i[ok]) and np.array_equal(b, j[ok])  # both in (a, b) order
    with pytest.raises(LimitError, match="pairs of tube pieces"):
        touching(pcs, margin, max_pairs=len(a) - 1)
    assert len(touching(pcs, margin, max_pairs=len(a))[0]) == len(a)


@pytest.mark.parametrize("n", [1, 2, 7, 8, 9, 15, 16, 17, 127, 128, 129, 130, 300, 1000])
def test_pairwise_sum_is_numpys(n):
    """The rings' centres rely on adding as numpy's add.reduceat does."""
    points = np.random.default_rng(n).normal(size=(n + 1, 3)) * 10.0 ** np.arange(-4, 5, 4)
    for j in range(3):
        want = np.add.reduceat(points, [0], axis=0)[0, j]
        assert points[0, j] + _pairwise_sum(points, 1, n, j) == want


@pytest.mark.parametrize("sides", [3, 8, 13, 200])
def test_rings_and_pieces_are_the_numpy_numbers(sides):
    tubes = bushy_tubes(7, 25, sides)
    first, centre, radius, lo, hi = _rings(tubes.points, tubes.point_offsets, tubes.rings, tubes.sides)
    ring_sides = np.repeat(tubes.sides, tubes.rings)
    ring_tube = np.repeat(np.arange(len(tubes)), tubes.rings)
    ring_local = np.arange(len(ring_tube)) - offsets(tubes.rings)[ring_tube]
    assert np.array_equal(first, tubes.point_offsets[ring_tube] + ring_local * ring_sides)  # cap centres skipped
    pts = tubes.points[np.concatenate([np.arange(f, f + s) for f, s in zip(first, ring_sides, strict=True)])]
    starts = offsets(ring_sides)[:-1]
    want = np.add.reduceat(pts, starts, axis=0) / ring_sides[:, None]
    assert centre.tobytes() == want.tobytes()
    dist = np.linalg.norm(pts - np.repeat(want, ring_sides, axis=0), axis=1)
    assert radius.tobytes() == np.maximum.reduceat(dist, starts).tobytes()
    assert lo.tobytes() == np.minimum.reduceat(pts, starts, axis=0).tobytes()
    assert hi.tobytes() == np.maximum.reduceat(pts, starts, axis=0).tobytes()
    # every piece's capsule holds its rings' points, and its box is theirs
    pcs = pieces(tubes)
    ring_start = offsets(tubes.rings)
    for k in range(len(pcs)):
        g0, g1 = ring_start[pcs.tube[k]] + pcs.first[k], ring_start[pcs.tube[k]] + pcs.last[k]
        mine = np.concatenate([np.arange(first[g], first[g] + ring_sides[g]) for g in range(g0, g1 + 1)])
        x = tubes.points[mine]
        assert np.array_equal(pcs.lo[k], x.min(axis=0)) and np.array_equal(pcs.hi[k], x.max(axis=0))
        assert np.array_equal(pcs.p[k], centre[g0]) and np.array_equal(pcs.q[k], centre[g1])
        d = segment_distance_rows(x, x, np.repeat(pcs.p[k : k + 1], len(x), 0), np.repeat(pcs.q[k : k + 1], len(x), 0))
        assert d.max() <= pcs.radius[k] * (1 + 1e-12)
