"""The botanical measures (lsys3d/turtle/botany.py) on skeletons small enough to count by hand."""

from __future__ import annotations

import numpy as np
import pytest

from lsys3d.turtle import FormOptions, botany, form
from lsys3d.turtle.skeleton import Skeleton


def y_fork(width=(0.02, 0.01, 0.01)):
    """A trunk that forks into two laterals at (0, 1, 0)."""
    return Skeleton.from_segments(
        [[0, 0, 0], [0, 1, 0], [0, 1, 0]],
        [[0, 1, 0], [0.5, 2, 0], [-0.5, 2, 0]],
        width_start=list(width),
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )


def test_area_ratio_of_a_fork():
    forks, ratios, widest = botany.fork_ratios(y_fork((0.02, 0.01414213562, 0.01414213562)))
    assert forks == 1 and ratios[0] == pytest.approx(1.0) and widest == pytest.approx(0.7071, abs=1e-4)


def test_a_collar_is_measured_at_its_end():
    sk = form(y_fork(), FormOptions(pipe_model=True, tip_width=0.01, branch_collar=1.3))
    _, raw, widest = botany.fork_ratios(sk)
    _, past, _ = botany.fork_ratios(sk, collar=1.3)
    assert past[0] == pytest.approx(1.0)  # the pipe model's area, where the branches leave the trunk
    assert raw[0] == pytest.approx(1.3**2)  # at the collar's start: collar**2 more
    assert widest <= 1.0 + 1e-12  # no collar starts wider than the trunk ends


def test_growth_along_a_chain_and_straight_chains():
    straight = Skeleton.from_segments(
        [[0, i, 0] for i in range(6)], [[0, i + 1, 0] for i in range(6)], width_start=0.1, parent=[-1, 0, 1, 2, 3, 4]
    )
    assert botany.straight_chains(straight) == 1 and botany.chain_growth(straight) == pytest.approx(1.0)
    widening = Skeleton.from_segments(
        [[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0]], width_start=[0.1, 0.12], parent=[-1, 0]
    )
    assert botany.chain_growth(widening) == pytest.approx(1.2)


def test_verdicts_apply_the_goals_by_kind_of_plant():
    m = botany.measure(y_fork((0.02, 0.01414213562, 0.01414213562)), [y_fork(), y_fork()])
    assert m.seeds == 1 and m.forks == 1 and m.within == 100.0
    oak, grass = botany.verdicts("oak", m, n_seeds=2), botany.verdicts("grass", m, n_seeds=2)
    assert oak["pipe"] and oak["child"] and oak["growth"] and oak["seeds"] is False
    assert oak["flare"] is False and grass["flare"] is None and grass["curved"] is None
    assert oak["leaves"] is False and grass["leaves"] is None  # the fork has no leaf: no blade faces the sky
    assert set(oak) == set(botany.GOALS) and np.isfinite(m.trunk_base_diameter)
