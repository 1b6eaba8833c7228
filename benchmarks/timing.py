"""What every benchmark shares: timing a call, best of a few runs.

The benchmarks are scripts (``python benchmarks/bench_x.py``), so this module is imported by its
name from the scripts' own folder.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def best_of(
    fn: Callable[[], Any], repeat: int = 3, clock: Callable[[], float] = time.perf_counter
) -> tuple[float, Any]:
    """The shortest of ``repeat`` times of ``fn()`` on ``clock`` (the wall clock), in seconds, and its last result.

    ``clock=time.process_time`` counts this process's CPU seconds: steadier than the wall clock on a busy
    machine, for work that runs in this process alone.
    """
    return best_of_each([fn], repeat, clock)[0]


def best_of_each(
    fns: list[Callable[[], Any]], repeat: int = 3, clock: Callable[[], float] = time.perf_counter
) -> list[tuple[float, Any]]:
    """:func:`best_of` of each of ``fns``, run in turn (one of each, ``repeat`` times over): a machine that drifts
    (its memory, its other jobs) drifts under all of them alike, so their ratios are fairer than timed apart."""
    best, results = [float("inf")] * len(fns), [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = clock()
            results[i] = fn()
            best[i] = min(best[i], clock() - t0)
    return list(zip(best, results, strict=True))
