"""Counts and extents of a drawn plant, as plain JSON-ready values."""

from __future__ import annotations

import numpy as np

from .arrays import components as _labels
from .arrays import unique
from .lsystem.modules import ModuleString
from .mesh.quality import quality
from .turtle.skeleton import Skeleton
from .version import __version__

__all__ = ["REPORT_FORMAT", "components", "flatten", "mesh_stats", "report", "skeleton_stats", "versions"]

REPORT_FORMAT = 1
"""Version of the layout of :func:`report` (bumped when a key is renamed or removed)."""


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

    Examples
    --------
    >>> components(np.array([[0, 1, 2], [2, 3, 4], [5, 6, 7]]), 9)
    2
    """
    faces = np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return 0
    label = _labels(n_vertices, faces.ravel(), np.roll(faces, -1, axis=1).ravel())
    return len(unique(label[faces[:, 0]]))


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
    counts = tree.counts
    leaves = tree.leaves.merged if tree.leaves.merged is not None else tree.leaves.polygons
    has_bark = len(bark.faces) > 0
    stats = {
        "vertices": len(bark.vertices),
        "faces": len(bark.faces),
        "volume": float(bark.volume) if has_bark else 0.0,
        "area": float(bark.area),
        "watertight": bool(bark.is_watertight) if has_bark else False,
        "winding_consistent": bool(bark.is_winding_consistent) if has_bark else False,
        "components": components(bark.faces, len(bark.vertices)),
        "tubes": counts.tubes,
        "tube_vertices": counts.tube_vertices,
        "tube_faces": counts.tube_faces,
        "leaf_vertices": len(leaves.vertices) if leaves is not None else 0,
        "leaf_faces": len(leaves.faces) if leaves is not None else 0,
        "unioned": bool(tree.unioned),
    }
    return dict(sorted(stats.items()))


def versions() -> dict:
    """Versions of lsys3d and of the libraries whose arithmetic shapes the counts."""
    from importlib.metadata import PackageNotFoundError, version

    found = {"lsys3d": __version__}
    for name in ("manifold3d", "numba", "numpy", "trimesh"):
        try:
            found[name] = version(name)
        except PackageNotFoundError:  # pragma: no cover - all are dependencies
            found[name] = "unknown"
    return dict(sorted(found.items()))


def _rounded(value):
    """Floats to 9 significant digits (and -0.0 to 0.0), so a report reads the same wherever it is printed."""
    if isinstance(value, float):
        return float(f"{value:.9g}") + 0.0
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in sorted(value.items())}
    return value


def report(modules: ModuleString, skeleton: Skeleton, tree=None) -> dict:
    """The stable report of a generated plant: every count per stage, measures and versions.

    This is what ``lsys3d stats --json`` prints and what golden files hold.
    Keys are sorted and stable (see :data:`REPORT_FORMAT`); integers are
    exact, floats are rounded to 9 significant digits.

    Parameters
    ----------
    modules : ModuleString
        The derived string.
    skeleton : Skeleton
        What the turtle drew from it.
    tree : Tree, optional
        The meshes built from them; without it the report holds only the
        ``derive`` and ``interpret`` sections (and ``versions``).

    Returns
    -------
    dict
        ``derive``: ``modules``, ``branches`` (``[`` modules).
        ``interpret``: ``segments``, ``chains``, ``leaves``, ``leaf_instances``,
        ``polygons``, ``max_order``, ``total_length``, ``bbox_min``, ``bbox_max``
        (of the segment end points).
        ``sweep``: ``tubes``, ``vertices``, ``faces`` (the tubes before the union).
        ``bark``: ``vertices``, ``faces``, ``components``, ``volume``, ``area``,
        ``watertight``, ``winding_consistent``, ``unioned`` (after the union, or
        the tube soup without it).
        ``leaves``: ``vertices``, ``faces`` (all leaves merged).
        ``quality``: the bark's :class:`~lsys3d.mesh.quality.Quality`: ``triangles``,
        ``over_100`` and ``over_1000`` (aspect), ``slivers`` (under 1 um),
        ``max_aspect``, ``uv_stretch`` (median; None without uv area).
        ``bbox``: ``min``, ``max`` of everything exported (bark and leaves).
        ``versions``: lsys3d, manifold3d, numba, numpy, trimesh.

    Examples
    --------
    >>> from lsys3d import generate
    >>> tree = generate("abop-1.24a", iterations=1, sides=4)
    >>> r = report(tree.modules, tree.skeleton, tree)
    >>> r["derive"]["modules"], r["interpret"]["segments"], r["sweep"]["tubes"], r["bark"]["components"]
    (11, 5, 3, 1)
    """
    flat = skeleton_stats(modules, skeleton)
    out = {
        "derive": {"branches": flat["branches"], "modules": flat["modules"]},
        "interpret": {k: v for k, v in flat.items() if k not in ("branches", "modules")},
        "versions": versions(),
    }
    if tree is not None:
        m = mesh_stats(tree)
        out["sweep"] = {"faces": m["tube_faces"], "tubes": m["tubes"], "vertices": m["tube_vertices"]}
        bark_keys = ("area", "components", "faces", "unioned", "vertices", "volume", "watertight", "winding_consistent")
        out["bark"] = {k: m[k] for k in bark_keys}
        out["leaves"] = {"faces": m["leaf_faces"], "vertices": m["leaf_vertices"]}
        out["quality"] = quality(tree.bark).to_json()
        points = [tree.bark.vertices]
        leaves = tree.leaves.merged if tree.leaves.merged is not None else tree.leaves.polygons
        if leaves is not None:
            points.append(leaves.vertices)
        points = np.concatenate(points)
        lo, hi = (points.min(axis=0), points.max(axis=0)) if len(points) else (np.zeros(3), np.zeros(3))
        out["bbox"] = {"max": [float(x) for x in hi], "min": [float(x) for x in lo]}
    return _rounded(out)


def flatten(nested: dict, prefix: str = "") -> dict:
    """``{"bark": {"faces": 1}}`` -> ``{"bark.faces": 1}`` (lists stay values), keys sorted.

    >>> flatten({"b": {"y": 1, "x": [0, 1]}, "a": 2})
    {'a': 2, 'b.x': [0, 1], 'b.y': 1}
    """
    flat = {}
    for key, value in nested.items():
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return dict(sorted(flat.items()))
