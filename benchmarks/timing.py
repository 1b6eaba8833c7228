"""What every benchmark shares: timing a call, best of a few runs.

The benchmarks are scripts (``python benchmarks/bench_x.py``), so this module is imported by its
name from the scripts' own folder.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """The shortest of ``repeat`` wall-clock times of ``fn()``, in seconds, and its last result."""
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result
