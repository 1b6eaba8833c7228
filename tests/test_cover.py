"""Covered tubes (lsys3d.mesh.union.cover, issue 34): the bound on what leaves the boolean, and the union after."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from skeletons import make_skeleton

import lsys3d
from lsys3d.mesh.sweep import sweep
from lsys3d.mesh.union.cover import covered_tubes
from lsys3d.mesh.union.touch import pieces, touching
from lsys3d.mesh.union.union import UnionOptions, union


def apex_cluster(seed: int, n: int = 40, width: float = 0.2):
    """A trunk, then ``n`` short tubes of the trunk's width fanning out near its top (a dense grammar's apex)."""
    rng = np.random.default_rng(seed)
    start, end, parent = [[0.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]], [-1]
    for _ in range(n):
        p = np.array([0.0, rng.uniform(0.6, 1.0), 0.0])
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        start.append(p)
        end.append(p + rng.uniform(0.002, 0.06) * d)
        parent.append(0)
    return sweep(make_skeleton(start, end, width, None, parent, [0] + [1] * n))


def test_off_by_default_and_nothing_covered_at_zero_that_pokes_out():
    assert UnionOptions().cover == 0.0
    tubes = apex_cluster(0)
    pcs = pieces(tubes)
    assert not covered_tubes(tubes, pcs, *touching(pcs), 0.0).any()


def test_a_tube_inside_a_thicker_one_is_covered_at_zero():
    sk = make_skeleton(
        [[0, 0, 0], [0, 0.5, 0], [0, 0.5, 0]],
        [[0, 1, 0], [0.02, 0.55, 0.0], [0.5, 0.9, 0]],
        [0.3, 0.05, 0.05],
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )
    tubes = sweep(sk)
    pcs = pieces(tubes)
    assert covered_tubes(tubes, pcs, *touching(pcs), 0.0).tolist() == [False, True, False]


@pytest.mark.parametrize("cover", [0.1, 0.25, 0.5])
def test_every_point_of_a_dropped_tube_is_within_the_bound_of_the_kept_union(cover):
    tubes = apex_cluster(1)
    pcs = pieces(tubes)
    dropped = covered_tubes(tubes, pcs, *touching(pcs), cover)
    assert dropped.any() and not dropped[0]
    kept = union(tubes.select(~dropped))
    solid = trimesh.Trimesh(kept.vertices, kept.faces, process=False)
    width = 2 * tubes.ring_radius.max()
    for t in np.flatnonzero(dropped):
        points = tubes.points[tubes.point_offsets[t] : tubes.point_offsets[t + 1]]
        # signed distance: positive inside; a point outside is at most cover * width away
        outside = -trimesh.proximity.signed_distance(solid, points)
        assert outside.max() <= cover * width * (1 + 1e-6) + 1e-7


def test_the_union_with_cover_is_closed_deterministic_and_within_its_volume_bound():
    tubes = apex_cluster(2, n=60)
    full = union(tubes)
    opt = UnionOptions(cover=0.25, workers=1)
    first, again = union(tubes, opt), union(tubes, UnionOptions(cover=0.25, workers=2))
    assert first.is_watertight and first.is_winding_consistent
    np.testing.assert_array_equal(first.vertices, again.vertices)
    np.testing.assert_array_equal(first.faces, again.faces)
    assert len(first.faces) < len(full.faces)
    # the union only loses what stuck out by at most a quarter of the width
    assert first.volume <= full.volume * (1 + 1e-6)
    assert first.volume >= full.volume * 0.9


def test_cover_thins_the_crowd_of_a_dense_fern():
    # L-Py's Barnsley-like fern, cut to 8 generations (9,840 segments, 2,187 tubes): its apex tubes nest
    from lsys3d.pipeline import draw

    g = lsys3d.load("tests/corpus/lpy/real/02-fractals_barnsleyfern.lpy")
    _, sk = draw(g, 8, g.seed)
    tubes = sweep(sk)
    pcs = pieces(tubes)
    a, b = touching(pcs, 0.01, 10**9)
    dropped = covered_tubes(tubes, pcs, a, b, 0.25)
    assert 100 < dropped.sum() < len(tubes) / 2 and not dropped[0]
    kept = tubes.select(~dropped)
    assert len(touching(pieces(kept), 0.01, 10**9)[0]) < 0.9 * len(a)


def test_cover_is_in_the_provenance_only_when_on():
    assert "cover" not in UnionOptions().plain()
    assert UnionOptions(cover=0.25).plain()["cover"] == 0.25
    assert UnionOptions.from_plain(UnionOptions(cover=0.25).plain()) == UnionOptions(cover=0.25)
    assert UnionOptions.from_plain(UnionOptions().plain()) == UnionOptions()
