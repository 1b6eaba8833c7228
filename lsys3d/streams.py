"""The seeded random streams: every use of randomness in lsys3d, one id each.

Each kind of randomness draws from its own numpy PCG64 generator seeded with
``SeedSequence([seed, stream])``, so turning one kind on leaves the numbers of
the others unchanged, and the result depends on nothing but the seed (no
global state, no process, no hash seed).  A new use of randomness takes the
next free id here.

Stochastic rules (:mod:`lsys3d.derive`) draw from one stream per generation,
symbol and pool of rules: :func:`rule_generator`.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

__all__ = ["Stream", "generator", "rule_generator"]


class Stream(IntEnum):
    """Ids of the random streams (the second entry of their seed sequence)."""

    ANGLE_JITTER = 1
    """Turtle: offsets of rotation angles (``angle_jitter``)."""
    LENGTH_JITTER = 2
    """Turtle: factors of steps (``length_jitter``)."""
    WIDTH_JITTER = 3
    """Turtle: factors of segment widths (``width_jitter``)."""
    BRANCH_ROLL = 4
    """Turtle: roll of each branch about its heading (``branch_roll``)."""
    BRANCH_DROP = 5
    """Turtle: whether a branch is left out (``branch_drop``)."""
    BARK_DISPLACEMENT = 6
    """Sweep: the noise pattern that displaces the bark (``bark_displacement``)."""
    BARK_COLOR = 7
    """Bark colour: the noise pattern of the vertex colours (``bark_color_variation``)."""
    WIND_PHASE = 8
    """Hierarchy: the wind phase of each branch (:mod:`lsys3d.hierarchy`)."""


def generator(seed: int, stream: Stream) -> np.random.Generator:
    """The generator of one stream for one seed.

    >>> a = generator(7, Stream.ANGLE_JITTER).random()
    >>> a == generator(7, Stream.ANGLE_JITTER).random() != generator(7, Stream.LENGTH_JITTER).random()
    True
    """
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), int(stream)])))


def rule_generator(seed: int, generation: int, symbol: int, pool: int) -> np.random.Generator:
    """The generator a stochastic rule pool draws from: one per seed, generation, symbol code and pool."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, generation, symbol, pool])))
