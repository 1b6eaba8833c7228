"""Procedural bark: the noise pattern of its shape, and the bark colour stage.

Both use :func:`~lsys3d.noise.bark_noise`, the fBm of :mod:`lsys3d.noise` with its contrast
raised (fBm rarely strays far from zero).  The bark's shape gets it in the
sweep (``SweepOptions.bark_displacement``, before the union); its colour gets
it in its own stage after the union (:func:`color`), as linear RGB per vertex:
the material's base colour times ``1 + variation * bark_noise(p)``, clipped to
[0, 1].  The exporters write it as glTF ``COLOR_0`` and USD
``primvars:displayColor`` (:mod:`lsys3d.mesh.mesh` describes the contract).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.mesh import Mesh
from ..noise import CONTRAST, bark_noise
from ..options import Options, option
from ..streams import Stream

__all__ = ["CONTRAST", "BarkColorOptions", "bark_colors", "bark_noise", "color"]

_OCTAVES = 4


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
    n = bark_noise(points, (int(seed), int(Stream.BARK_COLOR)), octaves=_OCTAVES, frequency=frequency)
    return np.clip(base[None, :] * (1.0 + variation * n)[:, None], 0.0, 1.0).astype(np.float32)


@dataclass(frozen=True)
class BarkColorOptions(Options):
    """The bark colour stage (:func:`color`); off by default."""

    variation: float = option(
        0.0,
        low=0,
        high=1,
        name="bark_color_variation",
        metavar="F",
        help="vary the bark colour by noise up to this fraction, as vertex colours (0: off)",
    )
    frequency: float = option(
        2.0, low=0, low_open=True, high=1e6, name="bark_color_frequency", help="bark colour features per metre"
    )


def color(bark: Mesh, options: BarkColorOptions, base_color, seed: int) -> Mesh:
    """The bark colour stage: ``bark`` with vertex colours of :func:`bark_colors` (unchanged when off).

    Examples
    --------
    >>> m = color(Mesh.box(), BarkColorOptions(variation=0.5), (0.3, 0.2, 0.1, 1.0), seed=1)
    >>> m.colors.shape, color(Mesh.box(), BarkColorOptions(), (0.3, 0.2, 0.1, 1.0), seed=1).colors
    ((8, 3), None)
    """
    if options.variation <= 0 or not len(bark.vertices):
        return bark
    return bark.with_colors(bark_colors(bark.vertices, base_color, options.variation, options.frequency, seed))
