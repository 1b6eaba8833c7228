"""Where a first run's compiling goes: numba's compile time per kernel, exclusive of the kernels it compiles inside.

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/compile_profile.py [--top 40] -- generate -o /tmp/tree.glb

Runs ``lsys3d`` with the arguments after ``--`` in this process and prints the process's wall and CPU time,
the CPU time of its children (the helper that compiles the cleanup's kernels on a first run,
:func:`lsys3d.compiling.ahead`), the compilations and kernels counted, the CPU time by stage (the kernels'
packages) and the kernels that took longest.  Times are CPU seconds of the compiling thread (``thread_time``), so
they hold on a busy machine; a kernel compiled for several signatures is listed once with its count.  Point
``NUMBA_CACHE_DIR`` at an empty folder, or the kernels come from the cache and nothing is compiled.
"""

from __future__ import annotations

import argparse
import contextlib
import resource
import threading
import time
from collections import Counter

from numba.core import event


class _Profile(event.Listener):
    """Exclusive thread CPU time per compilation, one stack per thread (the cleanup compiles from two)."""

    def __init__(self):
        self.local = threading.local()
        self.rows: list[tuple[float, str]] = []

    def on_start(self, ev: event.Event) -> None:
        stack = self.local.__dict__.setdefault("stack", [])
        stack.append([ev.data["dispatcher"], time.thread_time(), 0.0])

    def on_end(self, ev: event.Event) -> None:
        stack = self.local.stack
        dispatcher, start, inner = stack.pop()
        spent = time.thread_time() - start
        if stack:
            stack[-1][2] += spent
        func = dispatcher.py_func
        self.rows.append((spent - inner, f"{getattr(func, '__module__', '?')}.{func.__qualname__}"))


def _stage(name: str) -> str:
    """The package a kernel belongs to (``lsys3d.mesh.remesh``, ``lsys3d.turtle``...), numba's own as one."""
    if not name.startswith("lsys3d."):
        return name.split(".")[0]
    parts = name.split(".")
    return ".".join(parts[:3]) if parts[1] == "mesh" and len(parts) > 3 else ".".join(parts[:2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=30, help="kernels listed")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the lsys3d command line (after --)")
    ns = parser.parse_args()
    args = ns.args[1:] if ns.args[:1] == ["--"] else ns.args
    profile = _Profile()
    event.register("numba:compile", profile)
    t0, c0 = time.perf_counter(), time.process_time()
    from lsys3d.cli import main as lsys3d_main

    with contextlib.suppress(SystemExit):
        lsys3d_main(args or ["generate", "-o", "tree.glb"])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    counts = Counter(name for _, name in profile.rows)
    spent, stages = Counter(), Counter()
    for seconds, name in profile.rows:
        spent[name] += seconds
        stages[_stage(name)] += seconds
    print(
        f"wall {wall:.1f} s, CPU {cpu:.1f} s (children {children.ru_utime + children.ru_stime:.1f} s); "
        f"{len(profile.rows)} compilations of {len(counts)} kernels, {sum(spent.values()):.1f} CPU s"
    )
    print("by stage: " + ", ".join(f"{stage} {seconds:.1f}" for stage, seconds in stages.most_common()))
    for name, seconds in spent.most_common(ns.top):
        print(f"{seconds:7.2f}  x{counts[name]}  {name}")


if __name__ == "__main__":
    main()
