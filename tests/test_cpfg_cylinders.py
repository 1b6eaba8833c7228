"""cpfg's generalized cylinders (@Gs, @Gc, @Ge, @Gt): tubes along cpfg's Hermite curves through the control points.

The expectation is general.c's ``interpolate_connection`` written out again: the curve from one control
point to the next has the headings there as tangents, times the distance and the tangent parameters
(1.2 unless ``@Gt`` says otherwise), and ``n`` pieces (``@Gc(n)``, 4 without a number); the width goes
linearly from one control point's to the next one's.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

import lsys3d
from lsys3d.pipeline import draw


def hermite(p1, h1, p2, h2, rings, out_factor=1.2, in_factor=1.2):
    p1, h1, p2, h2 = (np.asarray(v, float) for v in (p1, h1, p2, h2))
    length = np.linalg.norm(p2 - p1)
    t1, t2 = h1 * length * out_factor, h2 * length * in_factor
    d = p2 - p1
    return [
        p1 + t1 * v + (3 * d - 2 * t1 - t2) * v**2 + (-2 * d + t1 + t2) * v**3 for v in np.arange(1, rings + 1) / rings
    ]


def heading(degrees_left_of_up):
    a = math.radians(degrees_left_of_up)
    return np.array([-math.sin(a), math.cos(a), 0.0])


@pytest.mark.parametrize("tangents", ["", "@Gt(0.5,2)"])
def test_a_cylinder_follows_cpfgs_curve(tangents, caplog):
    text = f'axiom = "#(0.2) {tangents} @Gs f(1) +(30) f(1) @Gc(4) -(60) f(2) #(0.4) @Ge(3)"\n'
    grammar = lsys3d.Grammar.from_text('dialect = "cpfg"\n' + text, source="cyl.toml")
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        _, skeleton = draw(grammar, 0, 0)
    assert not caplog.records  # drawn: no warning names @Gs, @Gc, @Ge or @Gt
    out_factor, in_factor = (2.0, 0.5) if tangents else (1.2, 1.2)  # @Gt(a, b): into a point a, out of it b
    p1 = np.array([0.0, 1.0, 0.0]) + heading(30)
    p2 = p1 + 2 * heading(-30)
    want = hermite([0, 0, 0], heading(0), p1, heading(30), 4, out_factor=out_factor, in_factor=in_factor)
    want += hermite(p1, heading(30), p2, heading(-30), 3, out_factor=out_factor, in_factor=in_factor)
    assert len(skeleton) == 7
    assert np.allclose(skeleton.end, want, atol=1e-9)
    assert np.allclose(skeleton.start[1:], skeleton.end[:-1]) and np.allclose(skeleton.start[0], 0)
    assert np.allclose(skeleton.width_end, [0.2] * 4 + [0.2 + 0.2 * k / 3 for k in (1, 2, 3)])
    assert list(skeleton.parent) == [-1, 0, 1, 2, 3, 4, 5]


def test_branches_start_from_the_last_control_point():
    """cpfg's '[' copies the cylinder, so each branch goes on from the point before it (Horneophyton)."""
    text = 'dialect = "cpfg"\naxiom = "@Gs f(1) @Gc(2) [+(90) f(1) @Ge(1)] [-(90) f(1) @Ge(1)] f(1) @Ge(1)"\n'
    _, skeleton = draw(lsys3d.Grammar.from_text(text, source="b.toml"), 0, 0)
    assert len(skeleton) == 5
    assert np.allclose(skeleton.start[2:], [[0, 1, 0]] * 3)
    assert list(skeleton.parent) == [-1, 0, 1, 1, 1]


def test_coincident_points_draw_nothing_and_a_point_without_a_start_starts_one():
    text = 'dialect = "cpfg"\naxiom = "@Gc f(1) @Gc @Gc f(1) @Ge @Ge"\n'
    _, skeleton = draw(lsys3d.Grammar.from_text(text, source="c.toml"), 0, 0)
    assert len(skeleton) == 8  # two connections of the default 4 pieces; the coincident points add none
