"""The plant's development on its skeleton: when each segment, leaf and organ is born and full grown.

The derivation says when each module was born (:mod:`lsys3d.lsystem.ages`);
the turtle drew each segment from a module (``Skeleton.module``) and recorded
each organ's module (``Skeleton.organ_module``).  :func:`timed` gives the
skeleton those times as plain arrays (``birth``, ``mature``, ``leaf_birth``...):

* a segment is born with its module and is full grown when the module is
  (its last rewrite plus its ``duration``);
* a leaf unfolds after its twig: it starts ``leaf_delay`` after the segment
  it grows from is born and takes ``leaf_duration``;
* an organ (a flower, a fruit) starts at the later of its own module's birth
  and its twig's birth plus ``leaf_delay``, and takes ``leaf_duration``.

A leaf or organ without a twig starts at ``leaf_delay``.  The times stay in the
plant's time units (steps, with the default terminal ages); the animation maps
them onto seconds (:mod:`lsys3d.look.growth`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..lsystem.ages import Ages, GrowthTable
from ..lsystem.modules import ModuleString
from .skeleton import Skeleton

__all__ = ["timed"]


def timed(skeleton: Skeleton, shown: ModuleString, ages: Ages, table: GrowthTable) -> Skeleton:
    """``skeleton`` with the times of its segments, leaves and organs (see the module docstring).

    ``shown`` is the string the turtle read and ``ages`` its modules' ages
    (:func:`lsys3d.lsystem.ages.interpretation_ages`).

    Examples
    --------
    >>> from lsys3d import Grammar
    >>> from lsys3d.lsystem.ages import derive_with_ages, growth_table
    >>> from lsys3d.turtle import TurtleOptions, interpret
    >>> g = Grammar(axiom="F", rules=["F -> F[+F]"], iterations=2)
    >>> modules, ages = derive_with_ages(g)
    >>> sk = timed(interpret(modules, TurtleOptions()), modules, ages, growth_table(g))
    >>> sk.birth.tolist(), sk.mature.tolist()
    ([0.0, 2.0, 1.0, 2.0], [3.0, 3.0, 3.0, 3.0])
    """
    mature = ages.mature(shown, table)
    birth_of = ages.birth[skeleton.module]
    mature_of = np.maximum(mature[skeleton.module], birth_of)

    def twig_birth(segment: np.ndarray | None, count: int) -> np.ndarray:
        if segment is None or len(segment) != count or not len(skeleton):
            return np.zeros(count)
        segment = np.asarray(segment, np.int64)
        return np.where(segment >= 0, birth_of[np.clip(segment, 0, len(skeleton) - 1)], 0.0)

    k = len(skeleton.leaf_position)
    leaf_birth = twig_birth(skeleton.leaf_segment, k) + table.leaf_delay
    organ_birth = np.maximum(
        twig_birth(skeleton.organ_segment, skeleton.n_organs) + table.leaf_delay,
        ages.birth[skeleton.organ_module] if skeleton.n_organs else np.zeros(0),
    )
    return replace(
        skeleton,
        birth=birth_of,
        mature=mature_of,
        leaf_birth=leaf_birth,
        leaf_mature=leaf_birth + table.leaf_duration,
        organ_birth=organ_birth,
        organ_mature=organ_birth + table.leaf_duration,
        growth_function=table.per_code(shown.alphabet)[3][shown.symbols[skeleton.module]],
    )
