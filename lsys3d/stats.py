"""Counts and extents of a drawn plant, as plain JSON-ready values."""

from __future__ import annotations

import numpy as np

from .modules import ModuleString
from .skeleton import Skeleton

__all__ = ["components", "mesh_stats", "skeleton_stats"]


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


def components(faces: np.ndarray, n_vertices: int) -> int:
    """Number of connected pieces of a triangle mesh (vertices joined by its edges; unused vertices ignored).

    Label propagation with pointer jumping, in numpy: a few passes over the
    edges, whatever the mesh's diameter.

    Examples
    --------
    >>> components(np.array([[0, 1, 2], [2, 3, 4], [5, 6, 7]]), 9)
    2
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return 0
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()
    parent = np.arange(n_vertices, dtype=np.int64)
    while True:
        pa, pb = parent[a], parent[b]
        differ = pa != pb
        if not differ.any():
            break
        lo, hi = np.minimum(pa[differ], pb[differ]), np.maximum(pa[differ], pb[differ])
        np.minimum.at(parent, hi, lo)  # hook each root under the smaller root it touches
        while True:  # compress paths until every vertex points at a root
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped
    return len(np.unique(parent[a]))


def mesh_stats(tree) -> dict:
    """Counts and measures of a generated :class:`~lsys3d.tree.Tree`'s meshes.

    Returns
    -------
    dict
        Sorted keys: ``components`` (connected pieces of the bark), ``faces``,
        ``vertices`` (the bark after the union, or the tube soup without it),
        ``area``, ``volume`` (of the bark), ``watertight``,
        ``winding_consistent``, ``tubes``, ``tube_vertices``, ``tube_faces``
        (before the union), ``leaf_vertices``, ``leaf_faces`` (all leaves
        merged), ``unioned``.
    """
    bark = tree.bark
    counts = tree.provenance.get("counts", {})
    leaves = tree.leaves if tree.leaves is not None else tree.polygon_leaves
    has_bark = len(bark.faces) > 0
    stats = {
        "vertices": len(bark.vertices),
        "faces": len(bark.faces),
        "volume": float(bark.volume) if has_bark else 0.0,
        "area": float(bark.area),
        "watertight": bool(bark.is_watertight) if has_bark else False,
        "winding_consistent": bool(bark.is_winding_consistent) if has_bark else False,
        "components": components(bark.faces, len(bark.vertices)),
        "tubes": int(counts.get("tubes", 0)),
        "tube_vertices": int(counts.get("tube_vertices", 0)),
        "tube_faces": int(counts.get("tube_faces", 0)),
        "leaf_vertices": len(leaves.vertices) if leaves is not None else 0,
        "leaf_faces": len(leaves.faces) if leaves is not None else 0,
        "unioned": bool(tree.unioned),
    }
    return dict(sorted(stats.items()))
