"""Where a first run's compiling goes: numba's compile time per kernel, exclusive of the kernels it compiles inside.

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/compile_profile.py [--timeline] -- generate -o /tmp/tree.glb

Runs ``lsys3d`` with the arguments after ``--`` in this process and prints the process's wall and CPU time,
the CPU time of its children (the helper that compiles the cleanup's kernels on a first run,
:func:`lsys3d.compiling.ahead`), the compilations and kernels counted, the CPU time by stage (the kernels'
packages) and the kernels that took longest.  Times are CPU seconds of the compiling thread (``thread_time``), so
they hold on a busy machine; a kernel compiled for several signatures is listed once with its count.  Point
``NUMBA_CACHE_DIR`` at an empty folder, or the kernels come from the cache and nothing is compiled.

``--timeline`` also prints when things happen, in wall-clock seconds from the start: each stage's start and end
with the CPU seconds the main process spent compiling in it, when the helper process started and ended, and
how long the main process waited for it (where a first run's wall-clock time goes).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
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
        self.top = 0.0  # CPU seconds of the outermost compilations so far (all threads)
        self.since: Counter = Counter()  # CPU seconds per kernel since the timeline's last stage

    def on_start(self, ev: event.Event) -> None:
        stack = self.local.__dict__.setdefault("stack", [])
        stack.append([ev.data["dispatcher"], time.thread_time(), 0.0])

    def on_end(self, ev: event.Event) -> None:
        stack = self.local.stack
        dispatcher, start, inner = stack.pop()
        spent = time.thread_time() - start
        if stack:
            stack[-1][2] += spent
        else:
            self.top += spent
        func = dispatcher.py_func
        name = f"{getattr(func, '__module__', '?')}.{func.__qualname__}"
        self.rows.append((spent - inner, name))
        self.since[name] += spent - inner


def _stage(name: str) -> str:
    """The package a kernel belongs to (``lsys3d.mesh.remesh``, ``lsys3d.turtle``...), numba's own as one."""
    if not name.startswith("lsys3d."):
        return name.split(".")[0]
    parts = name.split(".")
    return ".".join(parts[:3]) if parts[1] == "mesh" and len(parts) > 3 else ".".join(parts[:2])


class _Timeline(logging.Handler):
    """Wall-clock times of the stages (``run_stage``'s log lines), the helper's start and end and the main
    process's waits for it, with the compile CPU seconds spent in each stage."""

    def __init__(self, profile: _Profile, t0: float):
        super().__init__(logging.INFO)
        self.profile, self.t0, self.c0 = profile, t0, time.process_time()
        self.events: list[tuple[float, str]] = []
        self.mark = 0.0  # profile.top at the last stage's end

    def at(self, what: str) -> None:
        cpu = time.process_time() - self.c0
        self.events.append((time.perf_counter() - self.t0, f"[main CPU {cpu:5.1f} s]  {what}"))

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if record.name == "lsys3d" and message.startswith("compiling: waited"):
            self.at(f"main {message[len('compiling: ') :]}")
        elif record.name == "lsys3d" and message.endswith(" s") and len(message.split()) == 3:
            name, seconds = message.split()[:2]
            compiled, self.mark = self.profile.top - self.mark, self.profile.top
            top = ", ".join(f"{k.removeprefix('lsys3d.')} {v:.2f}" for k, v in self.profile.since.most_common(6))
            self.profile.since.clear()
            self.at(
                f"end {name} ({float(seconds):.2f} s wall, {compiled:.2f} CPU s compiling{': ' if top else ''}{top})"
            )

    def watch_helpers(self) -> None:
        """Note each helper's start and end (:class:`lsys3d.compiling.Helper`, polled from a thread)."""
        from lsys3d import compiling

        start = compiling.Helper.__init__

        def init(helper, *args, **kw):
            start(helper, *args, **kw)
            self.at(f"helper {helper.module} started")

            def poll():
                while helper.process.poll() is None:
                    time.sleep(0.02)
                used = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu = used.ru_utime + used.ru_stime
                self.at(f"helper {helper.module} ended ({helper.process.returncode}, {cpu:.1f} CPU s)")

            threading.Thread(target=poll, daemon=True).start()

        compiling.Helper.__init__ = init

    def print(self) -> None:
        for seconds, what in sorted(self.events):
            print(f"{seconds:7.2f}  {what}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=30, help="kernels listed")
    parser.add_argument("--timeline", action="store_true", help="print when each stage and the helper end")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the lsys3d command line (after --)")
    ns = parser.parse_args()
    args = ns.args[1:] if ns.args[:1] == ["--"] else ns.args
    profile = _Profile()
    event.register("numba:compile", profile)
    t0, c0 = time.perf_counter(), time.process_time()
    timeline = _Timeline(profile, t0)
    if ns.timeline:
        logger = logging.getLogger("lsys3d")
        logger.addHandler(timeline)
        logger.setLevel(logging.INFO)  # for the stages' times, which the command line itself would not print
        logger.propagate = False  # so its warnings only
        warnings = logging.StreamHandler()
        warnings.setLevel(logging.WARNING)
        warnings.setFormatter(logging.Formatter("lsys3d: %(message)s"))
        logger.addHandler(warnings)
        timeline.watch_helpers()
    from lsys3d.cli import main as lsys3d_main

    with contextlib.suppress(SystemExit):
        lsys3d_main(args or ["generate", "-o", "tree.glb"])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if ns.timeline:
        timeline.at(f"done ({profile.top - timeline.mark:.2f} CPU s compiling after the last stage)")
        timeline.print()
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
