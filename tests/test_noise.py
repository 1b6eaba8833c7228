"""Gradient noise: lattice zeros, bounded range, continuity, reproducibility, fBm normalisation."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from lsys3d.noise import _GRADIENTS, PERLIN_BOUND, _fade, fbm3, perlin3

RNG = np.random.default_rng(20260101)
POINTS = RNG.uniform(-300.0, 300.0, (200_000, 3))


@pytest.mark.parametrize("seed", [0, 1, 12345, (7, 2)])
def test_zero_at_lattice_points(seed):
    lattice = RNG.integers(-1000, 1000, (5000, 3)).astype(float)
    assert np.array_equal(perlin3(lattice, seed), np.zeros(len(lattice)))


@pytest.mark.parametrize("seed", [0, 3, 99])
def test_bounded(seed):
    v = perlin3(POINTS, seed)
    assert np.abs(v).max() <= 1.0
    # and not degenerate: values spread over much of the range, centred on zero
    assert np.abs(v).max() > 0.7 and 0.15 < v.std() < 0.4 and abs(v.mean()) < 0.01


def _corner_bound(p: np.ndarray) -> np.ndarray:
    """Upper bound of the unscaled noise at cell offsets ``p``: each corner picks its best gradient."""
    directions = np.unique(_GRADIENTS, axis=0)
    u = _fade(p)
    total = np.zeros(len(p))
    for corner in np.ndindex(2, 2, 2):
        c = np.array(corner, float)
        w = np.prod(np.where(c == 1, u, 1.0 - u), axis=1)
        total += w * ((p - c) @ directions.T).max(axis=1)
    return total


def test_bound_constant_covers_the_worst_case():
    """PERLIN_BOUND is at least the largest value any hash can give (so |perlin3| <= 1 holds everywhere)."""
    g = np.linspace(0.0, 1.0, 41)
    grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    values = _corner_bound(grid)
    best, worst = values.max(), grid[values.argmax()]
    local = np.random.default_rng(0)
    step = 0.03
    for _ in range(60):  # refine around the best grid point
        trial = np.clip(worst + local.uniform(-step, step, (4000, 3)), 0.0, 1.0)
        t = _corner_bound(trial)
        if t.max() > best:
            best, worst = t.max(), trial[t.argmax()]
        step *= 0.93
    assert 1.0363 < best <= PERLIN_BOUND


def test_continuous_across_cell_faces():
    """Just below and just above an integer coordinate give nearly the same value (the right corners are used)."""
    base = RNG.uniform(-50, 50, (20_000, 3))
    axis = RNG.integers(0, 3, len(base))
    rows = np.arange(len(base))
    base[rows, axis] = np.round(base[rows, axis])
    eps = 1e-9
    below, above = base.copy(), base.copy()
    below[rows, axis] -= eps
    above[rows, axis] += eps
    assert np.abs(perlin3(below, 5) - perlin3(above, 5)).max() < 1e-7


def test_lipschitz():
    """Small steps make small changes: |n(p + d) - n(p)| <= L |d|.

    Each partial derivative of the unscaled noise is at most 2 * 1.875 * 2 (fade
    slope times the spread of two corner values) + 1 (the gradients themselves) = 8.5,
    so L = 8.5 * sqrt(3) / PERLIN_BOUND < 15.
    """
    p = POINTS[:50_000]
    d = RNG.normal(size=p.shape)
    d *= 1e-4 / np.linalg.norm(d, axis=1, keepdims=True)
    ratio = np.abs(perlin3(p + d, 11) - perlin3(p, 11)) / 1e-4
    assert ratio.max() < 15.0
    assert ratio.mean() > 0.1  # it does vary


def test_reproducible_and_seeded():
    p = POINTS[:10_000]
    a = perlin3(p, 42)
    assert np.array_equal(a, perlin3(p, 42))
    assert np.array_equal(a, perlin3(p, [42]))
    for other in (43, (42, 0), (42, 1), (0, 42)):
        assert np.abs(a - perlin3(p, other)).max() > 0.1
    assert not np.array_equal(perlin3(p, (42, 1)), perlin3(p, (42, 2)))


def test_same_values_in_another_process():
    code = (
        "import numpy as np; from lsys3d.noise import fbm3;"
        "p = np.random.default_rng(3).uniform(-9, 9, (1000, 3));"
        "print(repr(fbm3(p, 8, octaves=3).tolist()))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    p = np.random.default_rng(3).uniform(-9, 9, (1000, 3))
    assert out.strip() == repr(fbm3(p, 8, octaves=3).tolist())


def test_known_values():
    """The pattern itself is part of the output (bark shape and colour): freeze a few values."""
    p = np.array([[0.5, 0.25, 0.75], [-3.3, 7.1, 0.9], [100.01, -0.5, 2.5]])
    np.testing.assert_allclose(perlin3(p, 0), KNOWN_PERLIN, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fbm3(p, 0), KNOWN_FBM, rtol=0, atol=1e-12)


KNOWN_PERLIN = [0.10812480400906985, 0.2211053789270551, 0.12301365891403052]
KNOWN_FBM = [-0.20829157140161292, 0.02073475690600408, -0.2952781763972567]


@pytest.mark.parametrize(
    ("octaves", "lacunarity", "gain", "frequency"),
    [(1, 2.0, 0.5, 1.0), (4, 2.0, 0.5, 0.05), (6, 1.9, 0.7, 3.0), (3, 3.0, 1.5, 0.2)],
)
def test_fbm_normalised(octaves, lacunarity, gain, frequency):
    p = POINTS[:50_000]
    v = fbm3(p, 1, octaves=octaves, lacunarity=lacunarity, gain=gain, frequency=frequency)
    assert np.abs(v).max() <= 1.0 and v.std() > 0.05
    assert np.array_equal(v, fbm3(p, 1, octaves=octaves, lacunarity=lacunarity, gain=gain, frequency=frequency))


def test_fbm_one_octave_is_perlin():
    p = POINTS[:1000]
    np.testing.assert_array_equal(fbm3(p, 4, octaves=1, frequency=2.5), perlin3(p * 2.5, (4, 0)))


def test_fbm_is_the_documented_sum():
    """Octave k: weight gain**k, frequency * lacunarity**k, shifted by k * _OCTAVE_SHIFT, seed (*seed, k)."""
    from lsys3d.noise import _OCTAVE_SHIFT

    p = POINTS[:1000] * 0.1
    two = fbm3(p, 4, octaves=2, lacunarity=3.0, gain=0.4, frequency=0.7)
    one = fbm3(p, 4, octaves=1, frequency=0.7)
    second = perlin3(p * (0.7 * 3.0) + _OCTAVE_SHIFT, (4, 1))
    np.testing.assert_allclose(two * 1.4, one + 0.4 * second, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: perlin3(np.zeros((3, 2))), "shape"),
        (lambda: perlin3([[0.0, np.nan, 0.0]]), "finite"),
        (lambda: perlin3(np.zeros((1, 3)), seed=-1), "seed"),
        (lambda: perlin3(np.zeros((1, 3)), seed=1.5), "seed"),
        (lambda: fbm3(np.zeros((1, 3)), octaves=0), "octaves"),
        (lambda: fbm3(np.zeros((1, 3)), gain=0.0), "gain"),
        (lambda: fbm3(np.zeros((1, 3)), frequency=np.inf), "frequency"),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_empty_and_large_blocks():
    assert perlin3(np.zeros((0, 3))).shape == (0,)
    # more points than one evaluation block: the blocks join seamlessly
    p = POINTS[:150_000]
    whole = perlin3(p, 9)
    np.testing.assert_array_equal(whole[70_000:70_010], perlin3(p[70_000:70_010], 9))
