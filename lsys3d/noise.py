"""Seeded 3D gradient noise over arrays of points: Perlin's improved noise and its fBm sum.

:func:`perlin3` is Ken Perlin's improved noise (SIGGRAPH 2002): a hash of the
integer lattice (a permutation of 0..255 drawn from numpy's PCG64 seeded with
``seed``) picks one of 12 gradient directions at each lattice corner; the
eight corner contributions are blended with the quintic fade ``6t^5 - 15t^4 +
10t^3``, so the noise is C2-continuous.  It is zero at every lattice point and
scaled so that ``|perlin3| <= 1`` (:data:`PERLIN_BOUND`).

:func:`fbm3` (fractional Brownian motion) adds octaves of it, each ``lacunarity``
times the frequency and ``gain`` times the amplitude of the one before, and
divides by the sum of the amplitudes, so it stays in ``[-1, 1]`` too.

Everything is vectorised: points are ``(n, 3)`` arrays, evaluated in blocks so
the temporaries stay small.  The values depend only on the points, the seed
and the parameters (numpy's PCG64 and float64 arithmetic), so they are the
same on every run and every machine.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["CONTRAST", "PERLIN_BOUND", "bark_noise", "fbm3", "perlin3"]

# Perlin's 12 edge-midpoint directions of a cube, padded to 16 by repeating four
# (his ``h & 15`` choice: no modulo bias, and no direction favoured along an axis).
_GRADIENTS = np.array(
    [
        [1, 1, 0],
        [-1, 1, 0],
        [1, -1, 0],
        [-1, -1, 0],
        [1, 0, 1],
        [-1, 0, 1],
        [1, 0, -1],
        [-1, 0, -1],
        [0, 1, 1],
        [0, -1, 1],
        [0, 1, -1],
        [0, -1, -1],
        [1, 1, 0],
        [-1, 1, 0],
        [0, -1, 1],
        [0, -1, -1],
    ],
    dtype=np.float64,
)

_GX, _GY, _GZ = (np.ascontiguousarray(_GRADIENTS[:, i]) for i in range(3))

PERLIN_BOUND = 1.0364
"""The largest ``|value|`` the unscaled noise can reach, rounded up; :func:`perlin3` divides by it.

Each corner contributes ``w_i(p) * g_i . (p - c_i)`` with fade weights
``w_i >= 0`` summing to 1, so the value is at most ``max_p sum_i w_i(p) max_g
g . (p - c_i)``, which ``tests/test_noise.py`` maximises over the unit cell
(about 1.036354, at (0.355, 0.481, 0.5) and its mirror images).
"""

# octave k is shifted by k times this (lattice units) so the octaves' zero lattices do not line up
_OCTAVE_SHIFT = np.array([0.3137, 0.6721, 0.4729])

_BLOCK = 1 << 16


def _permutation(seed: list[int]) -> np.ndarray:
    """The lattice hash of ``seed``: a permutation of 0..255, repeated twice ``(512,) int64``."""
    # the length goes last: SeedSequence alone takes (7,) and (7, 0) for the same seed
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([*seed, len(seed)])))
    p = rng.permutation(256).astype(np.int64)
    return np.concatenate([p, p])


def _fade(t: np.ndarray) -> np.ndarray:
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _points(points, where: str) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{where}: points must have shape (n, 3), not {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError(f"{where}: points must be finite")
    return p


def _seed(seed) -> list[int]:
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        seed = [int(seed)]
    if not isinstance(seed, Sequence) or not all(isinstance(s, (int, np.integer)) and s >= 0 for s in seed):
        raise ValueError(f"noise: seed must be a whole number >= 0 or a sequence of them, not {seed!r}")
    return [int(s) for s in seed]


def _corners(c: np.ndarray, period: int) -> tuple[np.ndarray, np.ndarray]:
    """The lattice coordinates of a cell's two corners along one axis, wrapped by ``period`` (0: by 256)."""
    if period:
        c0 = c % period
        return c0, (c0 + 1) % period
    c0 = c & 255
    return c0, c0 + 1


def _improved(p: np.ndarray, perm: np.ndarray, period=(0, 0, 0)) -> np.ndarray:
    """Unscaled improved noise at the rows of ``p`` ``(n, 3)``; the lattice repeats every ``period`` cells (0: 256)."""
    cell = np.floor(p)
    f = p - cell
    c = cell.astype(np.int64)
    xs, ys, zs = (_corners(c[:, i], period[i]) for i in range(3))
    u = _fade(f)
    # each axis's offsets from the cell's two corners and their weights, once (contiguous columns)
    offset = [(np.ascontiguousarray(f[:, i]), f[:, i] - 1) for i in range(3)]
    weight = [(1.0 - u[:, i], np.ascontiguousarray(u[:, i])) for i in range(3)]
    out = np.zeros(len(p))
    for dx, dy in ((0, 0), (0, 1), (1, 0), (1, 1)):
        row = perm[perm[xs[dx]] + ys[dy]]
        wxy = weight[0][dx] * weight[1][dy]
        for dz in (0, 1):
            h = perm[row + zs[dz]] & 15
            d = _GX[h] * offset[0][dx] + _GY[h] * offset[1][dy] + _GZ[h] * offset[2][dz]
            out += wxy * weight[2][dz] * d
    return out


def _period(period, where: str) -> tuple[int, int, int]:
    """Lattice cells after which the noise repeats along each axis (0: 256, Perlin's own)."""
    if period is None:
        return (0, 0, 0)
    p = np.broadcast_to(np.asarray(period, dtype=np.float64), (3,))
    whole = np.round(p)
    if not (np.isfinite(p).all() and (np.abs(p - whole) < 1e-9 * np.maximum(1.0, whole)).all()):
        raise ValueError(f"{where}: period must be whole numbers of lattice cells, not {period!r}")
    if ((whole < 0) | (whole > 256)).any():
        raise ValueError(f"{where}: period must be in 0..256 lattice cells (0: not periodic), not {period!r}")
    return tuple(int(v) for v in whole)


def perlin3(points, seed: int | Sequence[int] = 0, period=None) -> np.ndarray:
    """Improved Perlin noise at each point.

    Parameters
    ----------
    points : (n, 3) array_like
        Where to evaluate, in lattice units (one lattice cell = one feature).
    seed : int or sequence of int
        Seed of the lattice hash: a whole number >= 0 or a sequence of them;
        ``7``, ``(7, 0)`` and ``(7, 1)`` are unrelated noises (``7`` and
        ``(7,)`` are the same).
    period : int or (3,) sequence of int, optional
        Make the noise periodic: ``perlin3(p + period * e_i) == perlin3(p)``
        along each axis ``i`` whose period is not 0 (whole lattice cells,
        1..256), for tileable textures.  None: the lattice's own period of 256.

    Returns
    -------
    (n,) float64
        Values in ``[-1, 1]``; zero at every integer lattice point.

    Examples
    --------
    >>> import numpy as np
    >>> perlin3(np.array([[0.0, 0, 0], [3, -2, 5]])).tolist()
    [0.0, 0.0]
    >>> v = perlin3(np.random.default_rng(0).uniform(-50, 50, (1000, 3)), seed=7)
    >>> bool(np.abs(v).max() <= 1.0), bool(v.std() > 0.1)
    (True, True)
    """
    p = _points(points, "perlin3")
    perm = _permutation(_seed(seed))
    wrap = _period(period, "perlin3")
    out = np.empty(len(p))
    for s in range(0, len(p), _BLOCK):
        out[s : s + _BLOCK] = _improved(p[s : s + _BLOCK], perm, wrap)
    out *= 1.0 / PERLIN_BOUND
    return out


def fbm3(
    points,
    seed: int | Sequence[int] = 0,
    octaves: int = 4,
    lacunarity: float = 2.0,
    gain: float = 0.5,
    frequency: float = 1.0,
    period=None,
) -> np.ndarray:
    """Fractional Brownian motion: ``octaves`` layers of :func:`perlin3`, normalised to ``[-1, 1]``.

    Octave ``k`` (from 0) samples the noise of seed ``(*seed, k)`` at
    ``points * frequency * lacunarity**k`` (shifted by a fixed ``k``-fold
    offset so the octaves' zero lattices do not coincide) with weight
    ``gain**k``; the sum is divided by the sum of the weights.

    Parameters
    ----------
    points : (n, 3) array_like
    seed : int or sequence of int
    octaves : int
        Number of layers (>= 1).
    lacunarity : float
        Frequency ratio of neighbouring octaves (> 0; 2 doubles it).
    gain : float
        Amplitude ratio of neighbouring octaves (> 0; 0.5 halves it).
    frequency : float
        Features per unit length of the first octave (> 0).
    period : float or (3,) sequence of float, optional
        Make the sum periodic with this period in ``points``' units along each
        axis whose period is not 0 (tileable textures): each octave's lattice
        then repeats every ``period * frequency * lacunarity**k`` cells, which
        must be whole numbers (a whole ``lacunarity`` and ``period * frequency``).

    Returns
    -------
    (n,) float64
        Values in ``[-1, 1]``.

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.random.default_rng(1).uniform(0, 10, (2000, 3))
    >>> v = fbm3(pts, seed=3, octaves=5, frequency=0.5)
    >>> bool(np.abs(v).max() <= 1.0), np.array_equal(v, fbm3(pts, seed=3, octaves=5, frequency=0.5))
    (True, True)
    """
    p = _points(points, "fbm3")
    base = _seed(seed)
    if isinstance(octaves, bool) or not isinstance(octaves, (int, np.integer)) or octaves < 1:
        raise ValueError(f"fbm3: octaves must be a whole number >= 1, not {octaves!r}")
    for name, value in (("lacunarity", lacunarity), ("gain", gain), ("frequency", frequency)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"fbm3: {name} must be a finite number > 0, not {value!r}")
    span = None if period is None else np.broadcast_to(np.asarray(period, dtype=np.float64), (3,))
    out = np.zeros(len(p))
    total = 0.0
    f, w = float(frequency), 1.0
    for k in range(int(octaves)):
        cells = None if span is None else _period(span * f, "fbm3")
        out += w * perlin3(p * f + k * _OCTAVE_SHIFT, (*base, k), cells)
        total += w
        f *= lacunarity
        w *= gain
    out *= 1.0 / total
    return out


CONTRAST = 2.0
"""How much :func:`bark_noise` spreads the fBm: ``tanh(CONTRAST n) / tanh(CONTRAST)``."""


def bark_noise(points, seed, octaves: int = 4, frequency: float = 1.0) -> np.ndarray:
    """The bark pattern at each point: :func:`~lsys3d.noise.fbm3` with its contrast raised, in [-1, 1].

    fBm's values bunch near zero (standard deviation about 0.15 for 4
    octaves); ``tanh(2 n) / tanh(2)`` about doubles their spread (0.3) while
    staying smooth and within [-1, 1], so a setting of ``bark_displacement``
    or ``bark_color_variation`` shows at about a third of its value on most
    of the bark and at its full value on the peaks.

    Examples
    --------
    >>> import numpy as np
    >>> v = bark_noise(np.random.default_rng(0).uniform(0, 20, (5000, 3)), seed=1)
    >>> bool(np.abs(v).max() <= 1.0), bool(0.2 < v.std() < 0.45)
    (True, True)
    """
    n = fbm3(points, seed, octaves=octaves, frequency=frequency)
    return np.tanh(CONTRAST * n) * (1.0 / np.tanh(CONTRAST))
