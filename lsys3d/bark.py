"""Procedural bark: the noise pattern of its shape and its vertex colours.

Both use :func:`bark_noise`, the fBm of :mod:`lsys3d.noise` with its contrast
raised (fBm rarely strays far from zero).  The bark's shape gets it in the
sweep (``SweepOptions.bark_displacement``, before the union); its colour gets
it here, after the union, as linear RGB per vertex: the material's base colour
times ``1 + variation * bark_noise(p)``, clipped to [0, 1].  The exporters
write it as glTF ``COLOR_0`` and USD ``primvars:displayColor``
(:mod:`lsys3d.tree` describes the contract).
"""

from __future__ import annotations

import numpy as np
import trimesh

from .noise import fbm3

__all__ = ["BARK_COLOR_STREAM", "CONTRAST", "bark_colors", "bark_noise", "with_bark_colors"]

BARK_COLOR_STREAM = 7
"""The colour noise has seed ``(seed, BARK_COLOR_STREAM)``: unrelated to the displacement's and the turtle's."""

_OCTAVES = 4

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


def bark_colors(points, base_color, variation: float, frequency: float = 2.0, seed: int = 0) -> np.ndarray:
    """Linear RGB colour of the bark at each point.

    Parameters
    ----------
    points : (v, 3) array_like
        Bark vertices (metres).
    base_color : sequence of 3 or 4 float
        The bark material's linear base colour (alpha ignored).
    variation : float
        Largest relative change of the colour, in [0, 1]: ``base * (1 + variation * n)``
        with ``n = bark_noise(points)`` in [-1, 1] (4 octaves).
    frequency : float
        Colour features per metre of the noise's first octave.
    seed : int
        Seed of the pattern.

    Returns
    -------
    (v, 3) float32
        Colours in [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> c = bark_colors(np.random.default_rng(0).uniform(0, 1, (500, 3)), (0.3, 0.2, 0.1, 1.0), 0.5, seed=1)
    >>> ratio = c / np.array([0.3, 0.2, 0.1], np.float32)
    >>> c.shape, bool((ratio >= 0.5 - 1e-6).all() and (ratio <= 1.5 + 1e-6).all())
    ((500, 3), True)
    """
    if not 0 <= variation <= 1:
        raise ValueError(f"bark_colors: variation must be in [0, 1], not {variation!r}")
    base = np.asarray(base_color, dtype=np.float64)[:3]
    n = bark_noise(points, (int(seed), BARK_COLOR_STREAM), octaves=_OCTAVES, frequency=frequency)
    return np.clip(base[None, :] * (1.0 + variation * n)[:, None], 0.0, 1.0).astype(np.float32)


def with_bark_colors(bark: trimesh.Trimesh, base_color, variation: float, frequency: float, seed: int):
    """``bark`` with the ``vertex_color`` vertex attribute set by :func:`bark_colors` (the mesh is changed in place)."""
    bark.vertex_attributes["vertex_color"] = bark_colors(bark.vertices, base_color, variation, frequency, seed)
    return bark
