"""The branch hierarchy: ids, parents, depths, orders, pivots, t along a branch, leaves' branches."""

from __future__ import annotations

import numpy as np
import pytest

import lsys3d
from lsys3d.turtle import interpret
from lsys3d.turtle.hierarchy import hierarchy


def draw(axiom: str, angle: float = 90.0):
    g = lsys3d.Grammar(axiom=axiom, angle=angle)
    return interpret(lsys3d.derive(g, 0), g)


def test_three_segment_chain_with_a_side_branch_and_leaves():
    # trunk F F F; after the first F a branch [+F F~]; a leaf at the trunk's tip
    sk = draw("F[+FF~]FF~")
    h = hierarchy(sk, seed=3)
    assert len(h) == 2
    assert h.parent.tolist() == [-1, 0] and h.depth.tolist() == [0, 1] and h.order.tolist() == [0, 1]
    assert h.pivot.tolist() == [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    assert h.length.tolist() == [3.0, 2.0]
    # segments in drawing order: trunk 0, branch 1 2, trunk 3 4
    assert h.branch_of.tolist() == [0, 1, 1, 0, 0]
    assert h.t_start.tolist() == pytest.approx([0, 0, 0.5, 1 / 3, 2 / 3])
    assert h.t_end.tolist() == pytest.approx([1 / 3, 0.5, 1, 2 / 3, 1])
    assert h.leaf_branch.tolist() == [1, 0]
    assert ((h.phase >= 0) & (h.phase < 1)).all()
    assert np.array_equal(h.phase, hierarchy(sk, seed=3).phase)
    assert not np.array_equal(h.phase, hierarchy(sk, seed=4).phase)


def test_depth_counts_branches_order_counts_brackets():
    # a branch that starts inside two brackets at once has order 2 but depth 1
    sk = draw("F[[+F]]F")
    h = hierarchy(sk)
    assert h.order.tolist() == [0, 2] and h.depth.tolist() == [0, 1]


def test_a_gap_starts_a_root_and_leaves_without_a_segment_belong_nowhere():
    sk = draw("~F f F~")
    h = hierarchy(sk)
    assert h.parent.tolist() == [-1, -1] and h.leaf_branch.tolist() == [-1, 1]


def test_polygons_belong_to_the_branch_they_grow_from():
    sk = draw("F[+F{.f.+f.}]F{.-f.-f.}", angle=60)
    h = hierarchy(sk)
    assert h.polygon_branch.tolist() == [1, 0]


@pytest.mark.parametrize("name", ["tree3d", "bush", "monopodial"])
def test_presets(name):
    g = lsys3d.load_preset(name)
    sk = interpret(lsys3d.derive(g), g)
    h = hierarchy(sk, g.seed)
    assert (h.parent < np.arange(len(h))).all()  # parents come first
    assert (h.depth[h.parent >= 0] == h.depth[h.parent[h.parent >= 0]] + 1).all()
    tips = sk.chains.segments[sk.chains.offsets[1:] - 1]
    assert np.allclose(h.t_end[tips], 1) and (h.t_start >= 0).all() and (h.t_end <= 1 + 1e-12).all()
    assert (h.leaf_branch >= 0).all() and (h.polygon_branch >= 0).all()
