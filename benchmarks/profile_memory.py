"""Where ``lsys3d generate`` takes its memory: resident memory per stage and per call, nested.

    python benchmarks/profile_memory.py [GRAMMAR] [-n 9] [--no-cleanup] [--no-union] [--wrap module.function ...]

Runs ``lsys3d generate GRAMMAR -n N -o <tmp>.glb`` in this process (the CLI's
own code: generate, then export), with the pipeline's stages and the
functions of the union, the cleanup and the export wrapped.  Each frame
reports the resident memory at its entry and exit and its *peak*: the
kernel's high-water mark (``VmHWM``) while it ran, reset at each frame's
entry and exit (``/proc/self/clear_refs``) and handed on to the caller, so a
frame's peak includes its callees' and nothing before it.  The default
grammar is the 3D plant of ``bench_union_scale.py`` (``n=9``: 262,143
segments).  The union's worker processes are separate processes and are not
counted (``bench_union_scale.py`` reports the largest process of a run).

Linux only (``/proc/self/status``, ``clear_refs``).  The times include the
cost of reading ``/proc`` at every frame (about a millisecond).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import inspect
import sys
import tempfile
import time
from pathlib import Path

WRAPPED = [
    "lsys3d.mesh.sweep.sweep",
    "lsys3d.mesh.union.union.union",
    "lsys3d.mesh.union.union._prepare",
    "lsys3d.mesh.union.touch.duplicate_tubes",
    "lsys3d.mesh.union.touch.pieces",
    "lsys3d.mesh.union.touch.touching",
    "lsys3d.mesh.union.touch.buried_tubes",
    "lsys3d.mesh.union.touch.free_stretches",
    "lsys3d.mesh.union.local._local_union",
    "lsys3d.mesh.union.jobs.run",
    "lsys3d.mesh.union.repeats.find",
    "lsys3d.mesh.union.repeats.with_copies",
    "lsys3d.mesh.union.parts._join",
    "lsys3d.mesh.union.parts._to_mesh",
    "lsys3d.mesh.union.sources._true_sources",
    "lsys3d.mesh.union.weld._weld_float32",
    "lsys3d.mesh.union.weld._separate_float32",
    "lsys3d.mesh.union.sources._sourced",
    "lsys3d.mesh.cleanup.clean_mesh",
    "lsys3d.mesh.cleanup._clean_arrays",
    "lsys3d.mesh.cleanup._drop_crumbs",
    "lsys3d.mesh.cleanup._half_edges",
    "lsys3d.mesh.cleanup._classify",
    "lsys3d.mesh.remesh.build",
    "lsys3d.mesh.cleanup._clean",
    "lsys3d.mesh.remesh.compact",
    "lsys3d.mesh.cleanup.smooth_normals",
    "lsys3d.mesh.cleanup.tube_uv",
    "lsys3d.arrays.release_memory",
    "lsys3d.look.bark.color",
    "lsys3d.exchange.gltf.build",
    "lsys3d.exchange.common.gather_mesh",
    "lsys3d.exchange.atomic.write_bytes",
]


def _status(key: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {key} in /proc/self/status")


def _reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


class Profile:
    """A stack of frames; each finished frame is a row ``(depth, name, entry, peak, exit, seconds)``."""

    def __init__(self):
        self.stack: list[list] = []  # [name, entry rss, peak so far, t0, row index]
        self.rows: list[list] = []
        self.top = 0

    def _charge(self) -> int:
        """The high-water mark since the last reset, charged to every open frame; then reset."""
        hwm = _status("VmHWM:")
        for frame in self.stack:
            frame[2] = max(frame[2], hwm)
        self.top = max(self.top, hwm)
        _reset_peak()
        return hwm

    def enter(self, name: str) -> None:
        self._charge()
        rss = _status("VmRSS:")
        self.rows.append([len(self.stack), name, rss, rss, 0, 0.0])
        self.stack.append([name, rss, rss, time.perf_counter(), len(self.rows) - 1])

    def leave(self) -> None:
        self._charge()
        *_, peak, t0, row = self.stack.pop()
        self.rows[row][3:] = [peak, _status("VmRSS:"), time.perf_counter() - t0]

    def wrap(self, fn, name: str):
        @functools.wraps(fn)
        def wrapper(*args, **kw):
            self.enter(name)
            try:
                return fn(*args, **kw)
            finally:
                self.leave()

        return wrapper

    def stage_runner(self, run_stage):
        @functools.wraps(run_stage)
        def wrapper(name, fn, *args, **kw):
            self.enter(f"[{name}]")
            try:
                return run_stage(name, fn, *args, **kw)
            finally:
                self.leave()

        return wrapper


def install(profile: Profile, names: list[str]) -> None:
    """Wrap each ``module.function`` in ``names``, wherever a module of lsys3d holds it (``from x import f`` too)."""
    import lsys3d.pipeline

    targets = {}
    for dotted in names:
        module, attr = dotted.rsplit(".", 1)
        fn = getattr(importlib.import_module(module), attr)
        if not inspect.isfunction(fn):
            raise SystemExit(f"{dotted} is not a Python function (a numba kernel cannot be wrapped)")
        targets[id(fn)] = profile.wrap(fn, dotted.removeprefix("lsys3d."))
    targets[id(lsys3d.pipeline.run_stage)] = profile.stage_runner(lsys3d.pipeline.run_stage)
    for module in list(sys.modules.values()):
        if getattr(module, "__name__", "").startswith("lsys3d"):
            for attr, value in list(vars(module).items()):
                if id(value) in targets:
                    setattr(module, attr, targets[id(value)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("grammar", nargs="?", help="a grammar file or preset (default: the union benchmark's 3D plant)")
    ap.add_argument("-n", "--iterations", type=int, default=9)
    ap.add_argument("--wrap", nargs="*", default=[], help="more functions to profile, as module.function")
    ap.add_argument("--depth", type=int, default=99, help="print frames down to this depth")
    ap.add_argument("-o", "--output", help="keep the exported file here (default: a temporary file)")
    args, rest = ap.parse_known_args(argv)

    import lsys3d.cli
    import lsys3d.exchange.gltf  # imported lazily by the export: wrap it now
    import lsys3d.mesh.remesh

    profile = Profile()
    with tempfile.TemporaryDirectory() as tmp:
        grammar = args.grammar
        if grammar is None:
            sys.path.insert(0, str(Path(__file__).parent))
            from bench_union_scale import PLANT

            grammar = str(Path(tmp) / "plant3d.toml")
            Path(grammar).write_text(PLANT)
        out = args.output or str(Path(tmp) / "out.glb")
        install(profile, WRAPPED + args.wrap)
        start = _status("VmRSS:")
        _reset_peak()
        t0 = time.perf_counter()
        code = lsys3d.cli.main(["generate", grammar, "-n", str(args.iterations), "-o", out, *rest])
        seconds = time.perf_counter() - t0
        profile._charge()
    if code:
        raise SystemExit(code)
    print(f"{'call':<52} {'entry':>8} {'peak':>8} {'+peak':>8} {'exit':>8} {'seconds':>8}")
    for depth, name, entry, peak, exit_, secs in profile.rows:
        if depth <= args.depth:
            label = "  " * depth + name
            print(
                f"{label:<52} {entry / 2**30:7.2f}G {peak / 2**30:7.2f}G {(peak - entry) / 2**30:+7.2f}G"
                f" {exit_ / 2**30:7.2f}G {secs:8.2f}"
            )
    print(f"\nwhole run: peak {profile.top / 2**30:.2f} GB (imports: {start / 2**30:.2f} GB), {seconds:.1f} s")


if __name__ == "__main__":
    main()
