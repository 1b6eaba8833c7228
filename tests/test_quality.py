"""Quality measures: aspect, height, uv stretch, and the Quality record."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lsys3d.mesh.mesh import Mesh
from lsys3d.mesh.quality import Quality, aspect_ratios, heights, quality, uv_stretch

TRIANGLE = np.array([[0, 1, 2]])


def tri(*points):
    return np.array(points, float)


@pytest.mark.parametrize(
    ("points", "expected"),
    [
        (tri([0, 0, 0], [1, 0, 0], [0.5, math.sqrt(3) / 2, 0]), 1.0),  # equilateral
        # right isosceles: longest sqrt(2), inradius 1 / (2 + sqrt(2))
        (tri([0, 0, 0], [1, 0, 0], [0, 1, 0]), math.sqrt(2) * (2 + math.sqrt(2)) / (2 * math.sqrt(3))),
        (tri([0, 0, 0], [100, 0, 0], [50, 1, 0]), None),  # a cap: far above 1
    ],
)
def test_aspect_of_known_triangles(points, expected):
    aspect = aspect_ratios(points, TRIANGLE)[0]
    if expected is None:
        # longest 100, inradius = area / half perimeter = 50 / (100 + 2 * 50.01) / 2
        inradius = 50.0 / ((100 + 2 * math.hypot(50, 1)) / 2)
        assert aspect == pytest.approx(100 / (2 * math.sqrt(3) * inradius))
    else:
        assert aspect == pytest.approx(expected, abs=1e-4)


def test_degenerate_triangle_is_infinitely_bad_and_flat():
    points = tri([0, 0, 0], [1, 0, 0], [2, 0, 0])
    assert aspect_ratios(points, TRIANGLE)[0] == math.inf
    assert heights(points, TRIANGLE)[0] == 0.0


def test_height_is_the_smallest_altitude():
    points = tri([0, 0, 0], [4, 0, 0], [2, 1, 0])  # longest edge 4, area 2
    assert heights(points, TRIANGLE)[0] == pytest.approx(1.0)


def test_uv_stretch_is_one_for_a_similar_map_and_the_ratio_otherwise():
    points = tri([0, 0, 0], [2, 0, 0], [0, 2, 0])
    square = np.array([[[0, 0], [1, 0], [0, 1]]], float)
    assert uv_stretch(points, TRIANGLE, square)[0] == pytest.approx(1.0)
    rotated = np.array([[[0, 0], [0, 3], [-3, 0]]], float)  # rotated and scaled: still square texels
    assert uv_stretch(points, TRIANGLE, rotated)[0] == pytest.approx(1.0)
    long = np.array([[[0, 0], [5, 0], [0, 1]]], float)
    assert uv_stretch(points, TRIANGLE, long)[0] == pytest.approx(5.0)
    flat_uv = np.zeros((1, 3, 2))
    assert np.isnan(uv_stretch(points, TRIANGLE, flat_uv)[0])


def test_quality_record_counts_and_json():
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.8, 0], [0, 0, 0], [1000, 0, 0], [500, 1e-7, 0]], float)
    f = np.array([[0, 1, 2], [3, 4, 5]])
    q = quality(Mesh.flat(v, f, uv=np.array([[[0, 0], [1, 0], [0.5, 0.8]]] * 2)))
    assert (q.triangles, q.over_100, q.over_1000, q.slivers) == (2, 1, 1, 1)
    assert q.max_aspect > 1e9
    data = q.to_json()
    assert sorted(data) == sorted(Quality.__dataclass_fields__) and data["triangles"] == 2
    assert quality(Mesh.empty()).to_json()["uv_stretch"] is None
