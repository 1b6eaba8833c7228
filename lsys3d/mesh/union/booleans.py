"""One boolean job on plain arrays, in this process or in a worker process.

This file imports numpy and manifold3d only, so that it also runs as a
script: ``python booleans.py`` is a union worker that reads jobs from its
standard input and writes results to its standard output, pickled, until the
input ends (:mod:`lsys3d.mesh.union.jobs` starts and feeds the workers).  A worker
needs no part of lsys3d, so it starts in a fraction of a second, and nothing
of the caller's ``__main__`` is run again in it.

manifold3d holds the GIL while it computes (its Python module never releases
it), so two booleans run at once only in two processes.
"""

from __future__ import annotations

import pickle
import resource
import signal
import sys
import time
from collections.abc import Sequence
from typing import NamedTuple

import manifold3d
import numpy as np


class Part(NamedTuple):
    """A closed mesh for manifold3d, as plain arrays (``MeshGL64``'s fields)."""

    props: np.ndarray  # (n, p) float64: x y z and the properties
    tri: np.ndarray  # (m, 3) int64
    merge_from: np.ndarray  # (k,) int64
    merge_to: np.ndarray  # (k,) int64
    face_id: np.ndarray  # (m,) int64


class BooleanError(Exception):
    """manifold3d reported an error (the message names the part and the status)."""


def check(manifold: manifold3d.Manifold, where: str) -> manifold3d.Manifold:
    """Raise :class:`BooleanError` unless manifold3d reports no error."""
    status = manifold.status()
    if status != manifold3d.Error.NoError:
        raise BooleanError(f"{where}: manifold3d reported {status.name}")
    return manifold


def manifold_of(part: Part, where: str) -> manifold3d.Manifold:
    """A Manifold of the part, its status checked."""
    mesh = manifold3d.Mesh64(
        vert_properties=part.props,
        tri_verts=_unsigned(part.tri),
        merge_from_vert=_unsigned(part.merge_from),
        merge_to_vert=_unsigned(part.merge_to),
        face_id=_unsigned(part.face_id),
    )
    return check(manifold3d.Manifold(mesh), where)


def _unsigned(index: np.ndarray) -> np.ndarray:
    """Indices (>= 0) as the ``uint64`` manifold3d takes: int64's bytes seen as uint64 (no copy), else converted."""
    if index.dtype == np.int64:
        return np.ascontiguousarray(index).view(np.uint64)
    return index.astype(np.uint64)


def part_of(manifold: manifold3d.Manifold) -> Part:
    """The mesh of a Manifold as plain arrays (copies: manifold3d's are read-only views it would not take back)."""
    mesh = manifold.to_mesh64()
    return Part(
        np.array(mesh.vert_properties, np.float64),
        np.array(mesh.tri_verts, np.int64),
        np.array(mesh.merge_from_vert, np.int64),
        np.array(mesh.merge_to_vert, np.int64),
        np.array(mesh.face_id, np.int64),
    )


def run_job(
    groups: Sequence[Sequence[Part]], where: str, tree: Sequence[tuple[int, int]] = ()
) -> tuple[Part, int, float]:
    """Union groups of parts; returns the mesh, this process's peak resident memory in KiB and the CPU seconds taken.

    Each group is unioned with one ``Manifold.batch_boolean`` (nodes
    ``0..len(groups)-1``; a leaf or a merge job is one group), and ``tree[k]``
    unions two earlier nodes into node ``len(groups) + k``, the last one being
    the result: the merges of a crowded cluster's halves done here, on
    manifold3d's own objects, instead of each half going out as a mesh and
    coming back (measured on the dense fern: its 15 merges take 20 s through
    meshes and 9 s here, the export and rebuild of each half costing more than
    the boolean that merges them).

    Raises :class:`BooleanError` for a part manifold3d rejects, a failed
    boolean or an empty result.
    """
    start = time.process_time()
    groups = list(groups)  # emptied as manifold3d takes them
    nodes = []
    for g in range(len(groups)):
        group, groups[g] = groups[g], None  # each group's arrays go as soon as manifold3d holds them
        name = where if len(groups) == 1 else f"{where} (part {g})"
        layers = [manifold_of(p, f"{name} (layer {i})" if len(group) > 1 else name) for i, p in enumerate(group)]
        del group
        nodes.append(_union(layers))
        del layers
        check(nodes[-1], name)
    for x, y in tree:
        nodes.append(_union([nodes[x], nodes[y]]))
        nodes[x] = nodes[y] = None
    result = nodes[-1]
    del nodes
    check(result, where)
    if result.is_empty() or result.num_tri() == 0:
        raise BooleanError(f"{where}: manifold3d returned an empty mesh")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    if sys.platform == "darwin":  # pragma: no cover - bytes there, KiB on Linux
        peak //= 1024
    out = part_of(result)
    return out, peak, time.process_time() - start


def _union(manifolds: list[manifold3d.Manifold]) -> manifold3d.Manifold:
    """The union of the manifolds (one ``batch_boolean``; one manifold is itself)."""
    if len(manifolds) == 1:
        return manifolds[0]
    return manifold3d.Manifold.batch_boolean(manifolds, manifold3d.OpType.Add)


def worker() -> None:
    """Serve jobs: read ``(groups, where, tree)`` (:func:`run_job`'s arguments) from stdin, write
    ``("ok", (part, peak))`` or ``("error", message)``.

    Parts travel as plain tuples of arrays (a :class:`Part` pickled here would
    name this script's ``__main__``, which the caller cannot import).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and ends its workers
    source, sink = sys.stdin.buffer, sys.stdout.buffer
    while True:
        try:
            groups, where, tree = pickle.load(source)
        except EOFError:
            return
        try:
            out, peak, seconds = run_job([[Part(*p) for p in group] for group in groups], where, tree)
            reply = ("ok", (tuple(out), peak, seconds))
        except BooleanError as exc:
            reply = ("error", str(exc))
        except MemoryError:
            reply = ("error", f"{where}: out of memory in a union worker")
        del groups
        pickle.dump(reply, sink, protocol=pickle.HIGHEST_PROTOCOL)
        sink.flush()


if __name__ == "__main__":
    worker()
