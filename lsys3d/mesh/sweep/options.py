"""The sweep's options: sides, rings, forks, bark and texture (:class:`SweepOptions`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...options import Options, option

DEFAULT_MAX_TRIANGLES = 10_000_000
"""Most tube triangles :func:`sweep` builds (about 50 bytes a triangle in the tubes, more in the union)."""


@dataclass(frozen=True)
class SweepOptions(Options):
    """How chains become tubes; every default, range and help is in its field.

    ``sides_step`` drops sides per branch order: a chain of order ``k`` gets
    ``max(min_sides, sides - k * sides_step)`` sides.  A joint that turns less
    than ``merge_angle`` with a width that tapers linearly through it (within
    ``merge_width``) gets no ring.  ``bark_displacement`` moves every ring
    vertex along its radial direction by ``bark_displacement * r * n(p)``, a
    fraction of the local tube radius ``r``; ``n``
    (:func:`lsys3d.noise.bark_noise`, fBm with its contrast raised) lies in
    [-1, 1] and is evaluated at the undisplaced world position, so tubes that
    meet at a junction carry the same bark pattern.  Runs of segments shorter
    than the tube is wide merge into one ring span while the merged axis stays
    within ``merge_deviation`` of the radius of every joint it skips.

    Examples
    --------
    >>> SweepOptions(sides=6, sides_step=1, min_sides=4).sides_for_order([0, 1, 2, 5]).tolist()
    [6, 5, 4, 4]
    """

    sides: int = option(8, low=3, high=1024, help="vertices around the trunk's tubes (branch order 0)")
    sides_step: int = option(0, low=0, high=1024, help="sides dropped per branch order (0: all the same)")
    min_sides: int = option(3, low=3, high=1024, help="fewest sides of any tube")
    min_width: float = option(1e-3, low=0, low_open=True, help="smallest tube diameter; thinner widths are clamped")
    min_length: float = option(1e-9, low=0, help="segments shorter than this are dropped", cli=False)
    max_bend: float = option(
        120.0, low=0, high=180, low_open=True, high_open=True, help="degrees: a chain turning more is split there"
    )
    merge_angle: float = option(
        0.01, low=0, high=90, high_open=True, help="degrees: a straighter joint with a linear taper gets no ring"
    )
    merge_width: float = option(1e-6, low=0, help="relative tolerance of the linear taper of merge_angle", cli=False)
    merge_deviation: float = option(
        0.02,
        low=0,
        high=0.5,
        help="steps shorter than the tube is wide merge while within this fraction of its radius (0: off)",
    )
    bark_displacement: float = option(
        0.0, low=0, high=0.5, help="procedural bark: displace the tubes by noise up to this fraction of their radius"
    )
    bark_frequency: float = option(8.0, low=0, low_open=True, high=1e6, help="bark features per metre")
    bark_octaves: int = option(3, low=1, high=16, help="octaves of the bark noise")
    ring_spacing: float = option(
        0.0,
        low=0,
        high=1e6,
        help="rings at most this many tube sides apart (0: only at joints; 1 with bark displacement)",
    )
    elbow_angle: float = option(
        45.0,
        low=0,
        high=180,
        low_open=True,
        help="degrees: a joint turning more gets a ring on each side of its mitre (180: never)",
    )
    fork_blend: float = option(
        1.5,
        low=0,
        high=10,
        help="a child at least half as wide as its parent leaves it along the parent's heading and bends out over "
        "this many of its radii (0: off)",
    )
    fork_blend_min: float = option(
        0.002,
        low=0,
        high=1,
        help="fork_blend only for children at least this fraction of the plant's size wide (0: every thick fork)",
    )
    uv_tile: float = option(
        0.5,
        low=0,
        low_open=True,
        high=1e6,
        help="metres of bark around a branch one texture tile covers (a whole number of tiles goes around)",
    )

    def sides_for_order(self, order) -> np.ndarray:
        """Sides of the rings of chains of branch order ``order``, ``int64``."""
        order = np.asarray(order, np.int64)
        return np.maximum(self.fewest_sides, self.sides - order * self.sides_step)

    @property
    def fewest_sides(self) -> int:
        """The fewest sides any tube has: ``min_sides``, or ``sides`` when that is fewer."""
        return min(self.min_sides, self.sides)

    @property
    def spacing(self) -> tuple[float, float]:
        """The ring spacing in effect: (tube sides, metres); a span longer than both gets rings.

        ``ring_spacing`` sides when given; with bark displacement and no
        ``ring_spacing``, one side (square quads) but no closer than half the
        bark's feature size (``1 / bark_frequency``: two rings per bump of the
        noise's first octave); (0, 0): rings only at joints.
        """
        if self.ring_spacing > 0:
            return self.ring_spacing, 0.0
        if self.bark_displacement > 0:
            return 1.0, 0.5 / self.bark_frequency
        return 0.0, 0.0
