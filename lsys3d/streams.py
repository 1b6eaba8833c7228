"""The seeded random streams: every use of randomness in lsys3d, one id each.

Each kind of randomness draws from its own numpy PCG64 generator seeded with
``SeedSequence([seed, stream])``, so turning one kind on leaves the numbers of
the others unchanged, and the result depends on nothing but the seed (no
global state, no process, no hash seed).  A new use of randomness takes the
next free id here.

Stochastic rules (:mod:`lsys3d.lsystem.derive`) draw from one stream per generation,
symbol and pool of rules: :func:`rule_generator`.  A grammar's random functions
(``ran``, ``uniform``, ``normal``...) take counter-based numbers instead
(:func:`hashed_uniform`): the number a module draws at a place of the grammar
depends only on the seed, the step, that place and the module's position, so it
is the same however the modules are grouped and however often the place is
evaluated (the two branches of an L-Py ``if`` see the same ``random()``).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

__all__ = ["Stream", "generator", "hashed_uniform", "rule_generator"]


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
    """Hierarchy: the wind phase of each branch (:mod:`lsys3d.turtle.hierarchy`)."""
    GRAMMAR_RANDOM = 9
    """Derivation: the grammar's random functions (``ran``, ``uniform``, ``normal``...), :func:`hashed_uniform`."""
    RANDOM_TURN = 10
    """Turtle: the random turns of Lparser's and Houdini's ``~`` (three angles per module)."""
    TEXTURE = 11
    """Procedural textures: the noises, cells and strokes of a texture's images (:mod:`lsys3d.look.textures`)."""
    FORM_GNARL = 12
    """Form: the noise that bends the branches (``gnarl``, :mod:`lsys3d.turtle.form`)."""
    FORM_VARIATION = 13
    """Form: each lateral's change of branching angle and length (``angle_variation``, ``length_variation``)."""
    LEAF_SIZE = 14
    """Leaves: the relative change of each leaf's size (``leaf_size_variation``, :mod:`lsys3d.look.leaf_form`)."""
    LEAF_CLUSTER = 15
    """Leaves: each cluster's turn about its twig and its leaves' small turns (``leaves_per_cluster``)."""
    BLOCK_RANDOM = 16
    """Derivation: the random functions of cpfg's C blocks (``Start:``, ``StartEach:``...): lsystem.blocks."""


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


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


def hashed_uniform(seed: int, stream: Stream, keys, index: np.ndarray) -> np.ndarray:
    """Numbers in [0, 1), one per entry of ``index``, that depend only on ``seed``, ``stream``, ``keys`` and the entry.

    ``keys`` are whole numbers >= 0 naming the draw (a step, a place in the grammar, a draw number);
    ``index`` are the positions drawn for (a module's place in the string).  The same arguments give the
    same numbers in any process, in any order, in any grouping (splitmix64 of the position, keyed by a
    seed sequence of the rest).

    >>> a = hashed_uniform(7, Stream.GRAMMAR_RANDOM, (1, 2), np.arange(4))
    >>> b = hashed_uniform(7, Stream.GRAMMAR_RANDOM, (1, 2), np.array([3, 1]))
    >>> bool(a[3] == b[0] and a[1] == b[1] and ((0 <= a) & (a < 1)).all())
    True
    """
    key = np.random.SeedSequence([int(seed), int(stream), *(int(k) for k in keys)]).generate_state(1, np.uint64)[0]
    with np.errstate(over="ignore"):
        x = np.asarray(index).astype(np.uint64) * _GOLDEN + key
        x = (x ^ (x >> np.uint64(30))) * _MIX1
        x = (x ^ (x >> np.uint64(27))) * _MIX2
        x = x ^ (x >> np.uint64(31))
    return (x >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)
