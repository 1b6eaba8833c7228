"""Counts and extents of a drawn plant, as plain JSON-ready values."""

from __future__ import annotations

import numpy as np

from .modules import ModuleString
from .skeleton import Skeleton

__all__ = ["skeleton_stats"]


def skeleton_stats(modules: ModuleString, skeleton: Skeleton) -> dict:
    """Summarise a module string and the skeleton the turtle drew from it.

    Parameters
    ----------
    modules : ModuleString
    skeleton : Skeleton

    Returns
    -------
    dict
        Keys in sorted order, values plain ``int``, ``float`` or lists of floats:
        ``bbox_max``, ``bbox_min`` (corners over all segment end points, zeros
        when there are no segments), ``branches`` (number of ``[`` modules),
        ``chains``, ``leaf_instances``, ``leaves`` (polygons plus instances),
        ``max_order`` (-1 without segments), ``modules``, ``polygons``,
        ``segments``, ``total_length``.

    Examples
    --------
    >>> from lsys3d import Grammar, derive
    >>> from lsys3d.turtle import interpret
    >>> g = Grammar(axiom="F[+F]F", angle=90)
    >>> ms = derive(g, 0)
    >>> s = skeleton_stats(ms, interpret(ms, g))
    >>> s["segments"], s["branches"], s["chains"], s["bbox_max"]
    (3, 1, 2, [0.0, 2.0, 0.0])
    """
    n = len(skeleton)
    lo, hi = skeleton.bounds()
    stats = {
        "bbox_max": [float(x) + 0.0 for x in hi],  # + 0.0 turns -0.0 into 0.0
        "bbox_min": [float(x) + 0.0 for x in lo],
        "branches": modules.count("["),
        "chains": len(skeleton.chains) if n else 0,
        "leaf_instances": int(skeleton.leaf_position.shape[0]),
        "leaves": int(skeleton.n_leaves),
        "max_order": int(skeleton.order.max()) if n else -1,
        "modules": len(modules),
        "polygons": int(skeleton.n_polygons),
        "segments": n,
        "total_length": float(np.sum(skeleton.lengths())) if n else 0.0,
    }
    return dict(sorted(stats.items()))
