"""Skeletons built from bare segments, for the sweep and union tests."""

from __future__ import annotations

import numpy as np

from lsys3d.skeleton import Skeleton


def make_skeleton(start, end, width_start, width_end=None, parent=None, order=None) -> Skeleton:
    """A Skeleton from bare segments; turtle frames follow the segment directions."""
    start = np.asarray(start, float).reshape(-1, 3)
    end = np.asarray(end, float).reshape(-1, 3)
    n = len(start)
    w0 = np.broadcast_to(np.asarray(width_start, float), (n,)).copy()
    w1 = w0.copy() if width_end is None else np.broadcast_to(np.asarray(width_end, float), (n,)).copy()
    parent = np.arange(n) - 1 if parent is None else np.asarray(parent, np.int64)
    order = np.zeros(n, np.int32) if order is None else np.asarray(order, np.int32)
    h = end - start
    norm = np.linalg.norm(h, axis=1, keepdims=True)
    h = np.where(norm > 0, h / np.where(norm > 0, norm, 1), [[0.0, 1.0, 0.0]])
    left = np.cross([0.31, 0.52, 0.79], h)
    left /= np.linalg.norm(left, axis=1, keepdims=True)
    return Skeleton(
        start=start,
        end=end,
        width_start=w0,
        width_end=w1,
        heading=h,
        left=left,
        up=np.cross(h, left),
        parent=parent,
        order=order,
        material=np.zeros(n, np.int32),
        module=np.arange(n),
    )
