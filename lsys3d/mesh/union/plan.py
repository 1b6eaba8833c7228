"""Planning the boolean work: the touching tubes' colours and pairs, the jobs (:mod:`lsys3d.mesh.union.jobs`)
grouped from them, how many workers, the jobs' names and the union's progress."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ...arrays import unique
from . import jobs as union_jobs

_JOB_TRIANGLES = 60_000  # smallest job worth its own boolean (a few tenths of a second in manifold)


def _colour(n: int, pairs: np.ndarray) -> np.ndarray:
    """Greedy colouring of the may-touch graph, largest degree first."""
    colour = np.full(n, -1, np.int64)
    if not len(pairs):
        colour[:] = 0
        return colour
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.argsort(both[:, 0], kind="stable")]
    offsets = np.searchsorted(both[:, 0], np.arange(n + 1))
    nbr = both[:, 1].tolist()
    off = offsets.tolist()
    col = colour.tolist()
    for t in np.argsort(-np.diff(offsets), kind="stable").tolist():
        used = {col[x] for x in nbr[off[t] : off[t + 1]]}
        c = 0
        while c in used:
            c += 1
        col[t] = c
    return np.asarray(col, np.int64)


def _unique_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(k, 2)`` distinct pairs ``(min, max)`` of ``a, b``, without self pairs."""
    keep = a != b
    lo, hi = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    if not len(lo):
        return np.zeros((0, 2), np.int64)
    key = unique(lo * (int(hi.max()) + 1) + hi)
    return np.stack([key // (int(hi.max()) + 1), key % (int(hi.max()) + 1)], axis=1)


class _Progress:
    """The union's progress as one fraction: preparing (to 15%), the boolean jobs (to 75%), stitching and welding."""

    def __init__(self, report: Callable[[float], None] | None):
        self.report = report
        self.last = -1.0

    def __call__(self, fraction: float) -> None:
        if self.report and fraction >= self.last + 0.01:
            self.last = fraction
            self.report(min(fraction, 1.0))

    def boolean(self, fraction: float) -> None:
        self(0.15 + 0.60 * fraction)


def _job_target(total: float) -> float:
    """Triangles per job: about 16 jobs (for the workers and for progress), none too small to pay for itself.

    The same for any number of workers: how the work is split decides the
    result's bytes (manifold3d may triangulate a cut differently in another
    grouping), the number of workers must not.
    """
    return max(total / 16, _JOB_TRIANGLES)


def _plan(weight: np.ndarray, centre: np.ndarray, pairs: np.ndarray) -> union_jobs.Plan:
    """The jobs of a union: :func:`_job_target` triangles each; the merges of up to a quarter of all inner.

    A crowded cluster (the dense fern: one cluster of 582,240 triangles) is
    split in space into leaves whose results are merged pairwise.  A merge
    that goes out to a worker costs a mesh export and two rebuilds besides
    its boolean (the fern's 15 merges: 20 s of 51 s of boolean CPU, 9 s on
    manifold3d's own objects); the merges of up to a quarter of the work are
    done in the job of their leaves, which leaves at least four jobs for the
    workers.  Merged in memory, smaller leaves pay: a crowded cluster's are
    half the job size (the fern's boolean CPU, one worker: 50.5 s before,
    47.7 s with inner merges, 44.5 s with them and half-size leaves, 44.3 s
    with quarter-size ones).  Like the leaves, independent of the number of
    workers.
    """
    total = float(weight.sum())
    target = _job_target(total)
    return union_jobs.plan(weight, centre, pairs[:, 0], pairs[:, 1], target, job=total / 4, leaf=target / 2)


def _use(workers: int, triangles: float, jobs: union_jobs.Plan) -> int:
    """Worker processes for a plan: all of them for big unions, none (this process) for small ones."""
    if workers > 1 and triangles >= union_jobs.POOL_MIN_TRIANGLES and len(jobs.weight) > 1:
        return min(workers, len(jobs.weight))
    return 1


def _namer(jobs: union_jobs.Plan, what: str) -> Callable[[int], str]:
    def name(node: int) -> str:
        if len(jobs.weight) == 1:
            return f"union: {what} 0"
        kind = "job" if node < len(jobs.leaves) else "merge"
        return f"union: {kind} {node} of {len(jobs.weight)}"

    return name
