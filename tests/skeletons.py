"""Skeletons built from bare segments, for the sweep and union tests."""

from __future__ import annotations

from lsys3d.turtle.skeleton import Skeleton


def make_skeleton(start, end, width_start, width_end=None, parent=None, order=None) -> Skeleton:
    """A Skeleton from bare segments; turtle frames follow the segment directions."""
    return Skeleton.from_segments(start, end, width_start, width_end, parent, order)
