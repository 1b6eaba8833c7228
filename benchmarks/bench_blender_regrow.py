"""Regrow latency of the Blender add-on against the CLI's in-process time, for tree3d (issue 36's goal: at most +20%).

It runs in the Python that has ``bpy``: started by another (``make bench``), it runs itself again with
``LSYS3D_BPY_PYTHON`` or ``.venv-bpy/bin/python`` (and says so and stops when there is none)::

    .venv/bin/python benchmarks/bench_blender_regrow.py

In one process, warm (kernels compiled, one growth first), best of ``REPEATS``:

- ``cli``: what ``lsys3d generate tree3d`` does in process: :func:`lsys3d.generate` and the glTF export;
- ``generate``: :func:`lsys3d.generate` alone;
- ``add``: what a change in the redo panel runs, ``bpy.ops.lsys3d.add_plant`` (Blender undoes the last run
  first: that undo is not counted);
- ``regrow``: the sidebar's Regrow (``bpy.ops.lsys3d.regrow``) of the selected plant, in place.

Prints each best time and its ratios to ``cli`` and ``generate``.
"""

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
REPEATS = 5


def in_blender() -> None:
    """Run this file with the Python that has ``bpy``, from the checkout."""
    python = Path(os.environ.get("LSYS3D_BPY_PYTHON") or REPO / ".venv-bpy" / "bin" / "python")
    if not python.exists():
        print("bench_blender_regrow: no Python with bpy (make validators, or set LSYS3D_BPY_PYTHON): not run")
        return
    env = dict(os.environ, PYTHONPATH=str(REPO))
    sys.exit(subprocess.run([str(python), __file__, *sys.argv[1:]], env=env, cwd=REPO).returncode)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="tree3d")
    parser.add_argument("--iterations", type=int, default=0, help="0: the grammar's own")
    parser.add_argument("--repeat", type=int, default=REPEATS)
    args = parser.parse_args()
    sys.path.insert(0, str(REPO / "tools"))
    import blender_addon_check  # noqa: F401  (the checkout's lsys3d and its assets, as the add-on's test runs them)
    import bpy

    import lsys3d
    import lsys3d.blender

    lsys3d.blender.register()
    grammar = lsys3d.load(args.preset)
    n = args.iterations or None
    plant = {"preset": args.preset, "seed": 0, "iterations": args.iterations}
    times = {"cli": [], "generate": [], "add": [], "regrow": []}

    def timed(key, fn):
        t0 = time.perf_counter()
        fn()
        times[key].append(time.perf_counter() - t0)

    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / "plant.glb"
        lsys3d.export(lsys3d.generate(grammar, n, 0), path)  # warm: kernels loaded, caches filled
        bpy.ops.lsys3d.add_plant(**plant)
        grown = bpy.context.active_object
        for _ in range(args.repeat):  # interleaved, so that a busy moment of the machine falls on all of them
            timed("cli", lambda: lsys3d.export(lsys3d.generate(grammar, n, 0), path))
            timed("generate", lambda: lsys3d.generate(grammar, n, 0))
            timed("add", lambda: bpy.ops.lsys3d.add_plant(**plant))
            bpy.context.view_layer.objects.active = grown
            timed("regrow", lambda: bpy.ops.lsys3d.regrow())
    best = {k: min(v) for k, v in times.items()}
    cli = best["cli"]
    print(
        f"{args.preset}, best of {args.repeat}: cli (generate + .glb) {cli:.3f} s, "
        f"generate alone {best['generate']:.3f} s"
    )
    for key, what in (("add", "add_plant (a redo panel change)"), ("regrow", "sidebar regrow")):
        print(f"{what}: {best[key]:.3f} s = {best[key] / cli:.2f} x cli, {best[key] / best['generate']:.2f} x generate")


if __name__ == "__main__":
    if importlib.util.find_spec("bpy") is None:
        in_blender()
    else:
        main()
