"""The cleanup's kernels compiled ahead, in a second process, on a first run (:mod:`lsys3d.compiling`).

On a first run numba compiles the cleanup's kernels (:mod:`lsys3d.mesh.remesh`) when the pipeline reaches the
cleanup, a third of all the compiling.  The helper process (``python -m lsys3d.firstrun``) compiles them
meanwhile on the other core with :func:`run`: it runs the cleanup's own steps
(:func:`lsys3d.mesh.cleanup._half_edges`, ``_clean``) on a small closed tube of two parts with a seam and flat
caps, numpy-made, whose arrays have the types the union's bark has, so numba compiles and caches the signatures
the real cleanup asks for; the main process then loads them from the cache.

The kernels the cleanup calls after the cleaning (the compacting, the normals) are not its own: they are spare
groups of :mod:`lsys3d.firstrun`, for whichever process is idle first; the caps a seam cuts
(:func:`lsys3d.mesh.remesh.cut_caps`) are compiled where they are called, by a tree with flat caps only.

It compiles nothing but kernels of :mod:`lsys3d.mesh.remesh` (its modules import nothing else of lsys3d):
:data:`OWN` says so to :func:`lsys3d.compiling.ahead`, which stops this process at the first other kernel it
would compile, and makes the main process wait for it before compiling one of these itself, so no kernel is
ever compiled by both processes at once (twice the work).
"""

from __future__ import annotations

import numpy as np

from .cleanup import CleanupOptions, _clean, _executor, _half_edges, _Surface
from .remesh.clean import _sides
from .remesh.clean import clean as _clean_kernel
from .remesh.collar import collar
from .remesh.fair import (
    _fair_finish,
    _fair_setup,
    _fair_targets,
    _laplacians,
    _neighbours,
    _valences,
    _vertex_normals,
    settle,
)
from .remesh.halfedge import _leaving, _lock_pinches, _match, mark
from .remesh.rescue import _needs_rescue
from .remesh.tube_faces import _tube_faces

__all__ = ["ENTRIES", "OWN", "run"]

OWN = ("lsys3d.mesh.remesh",)
"""The modules whose kernels this process compiles (prefixes of module names)."""

ENTRIES = (
    _leaving,
    _match,
    _lock_pinches,
    mark,
    _clean_kernel,
    _sides,
    collar,
    _fair_setup,
    _valences,
    _neighbours,
    _vertex_normals,
    _laplacians,
    _fair_targets,
    _fair_finish,
    settle,
    _needs_rescue,
    _tube_faces,
)
"""The kernels :func:`run` calls from Python (the others are compiled into them): when all have cached code,
there is nothing to compile ahead."""

_SIDES, _RINGS = 32, 72
"""The tube's sides and rings: over ``cleanup._HALVES_MIN`` faces, so the first cleaning goes in halves."""


class _Tubes:
    """What the cleanup reads of :class:`lsys3d.mesh.sweep.Tubes`, for a mesh that is its own single tube."""

    def __init__(self, points: np.ndarray, faces: np.ndarray, part: np.ndarray, cap: np.ndarray):
        self.points = points
        self.wedge_point = np.arange(len(points), dtype=np.int64)
        self.faces = faces
        self._part, self._cap = part, cap

    def face_kinds(self, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._part[face], self._cap[face]


def _tube() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A closed tube along y (vertices, faces, each face's part and cap): part 0 below the middle ring, part 1
    above (a seam between), flat caps, and two rings almost on each other (needles for the cleaning)."""
    angle = 2 * np.pi * np.arange(_SIDES) / _SIDES
    y = np.arange(_RINGS, dtype=np.float64)
    y[_RINGS // 2 + 1] = y[_RINGS // 2] + 1e-3  # a ring a hair above the seam: short edges, needles
    ring = np.stack([np.cos(angle), np.zeros(_SIDES), np.sin(angle)], 1)
    wall = (ring[None, :, :] + y[:, None, None] * np.array([0.0, 1.0, 0.0])).reshape(-1, 3)
    points = np.concatenate([wall, [[0.0, y[0], 0.0], [0.0, y[-1], 0.0]]])
    base, tip = len(wall), len(wall) + 1
    r, k = np.meshgrid(np.arange(_RINGS - 1), np.arange(_SIDES), indexing="ij")
    a, b = r * _SIDES + k, r * _SIDES + (k + 1) % _SIDES
    c, d = a + _SIDES, b + _SIDES
    quads = np.stack([np.stack([a, c, b], -1), np.stack([b, c, d], -1)], 2).reshape(-1, 3)
    k = np.arange(_SIDES)
    bottom = np.stack([np.full(_SIDES, base), k, (k + 1) % _SIDES], 1)
    top_ring = (_RINGS - 1) * _SIDES
    top = np.stack([np.full(_SIDES, tip), top_ring + (k + 1) % _SIDES, top_ring + k], 1)
    faces = np.concatenate([quads, bottom, top]).astype(np.int64)
    upper = points[faces].mean(axis=1)[:, 1] > y[_RINGS // 2]
    part = upper.astype(np.int64)
    cap = np.full(len(faces), -1, np.int64)
    cap[len(quads) : len(quads) + _SIDES] = 0  # the base of tube 0
    cap[len(quads) + _SIDES :] = 3  # the tip of tube 1
    return points, faces, part, cap


def run() -> None:
    """Compile (or load) the cleanup's kernels: the cleanup's steps on :func:`_tube`, with two threads."""
    points, faces, part, cap = _tube()
    tubes = _Tubes(points, faces, part, cap)
    source = np.arange(len(faces), dtype=np.int64)
    bark = _Surface(points, faces, source)
    options = CleanupOptions()
    with _executor(2) as pool:
        he = _half_edges(bark, tubes, 1024, pool)
        if isinstance(he, str):  # pragma: no cover - the tube is closed
            raise RuntimeError(f"lsys3d.mesh.precompile: {he}")
        _clean(he, options, 4 * len(faces), pool=pool)
