"""What the growth animation costs: generate time and .glb size against the same tree without it.

    python benchmarks/bench_growth.py [--preset tree3d] [--iterations N] [--repeat 5] [--seconds 5]

The issue's budget (issue 40): the growth animation adds at most 25% to generate's time and 30% to the .glb on
tree3d.  Each setting is grown ``--repeat`` times, interleaved with the baseline so that a busy machine slows
all alike; the best time of each is compared with the plain one's, and each .glb's size with the plain .glb's.
The rigged rows compare with ``--rig`` alone too (what the growth adds to a tree that is rigged anyway).
``--iterations`` grows the preset at fewer (or more) generations than its own (the suite's smoke run: a small
tree through the same settings).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import lsys3d


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="tree3d")
    ap.add_argument("--iterations", type=int, default=None, help="generations (default: the preset's own)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args(argv)
    s = args.seconds
    settings = {
        "plain": {},
        "growth": {"growth_animation": s},
        "growth + birth attribute": {"growth_animation": s, "birth_attribute": True},
        "birth attribute": {"birth_attribute": True},
        "rig": {"rig": True},
        "rig + growth": {"rig": True, "growth_animation": s},
        "rig + wind + growth": {"rig": True, "wind_animation": 2.0, "growth_animation": s},
    }
    lsys3d.generate(args.preset, args.iterations)  # compile and warm every cache first
    best = {name: float("inf") for name in settings}
    trees = {}
    for _ in range(args.repeat):
        for name, options in settings.items():
            t0 = time.perf_counter()
            trees[name] = lsys3d.generate(args.preset, args.iterations, **options)
            best[name] = min(best[name], time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as folder:
        sizes = {name: lsys3d.export(tree, Path(folder) / f"{i}.glb").stat().st_size for i, (name, tree) in
                 enumerate(trees.items())}  # fmt: skip
    print(f"{args.preset}: best of {args.repeat}, interleaved; growth {s:g} s")
    head = f"{'generate s':>10} {'vs plain':>9} {'vs rig':>8} {'.glb bytes':>11} {'vs plain':>9} {'vs rig':>8}"
    print(f"  {'setting':<26} {head}")
    for name in settings:
        t, b = best[name], sizes[name]
        rigged = name.startswith("rig")
        vs_rig_t = f"{t / best['rig'] - 1:+8.1%}" if rigged else " " * 8
        vs_rig_s = f"{b / sizes['rig'] - 1:+8.1%}" if rigged else " " * 8
        print(
            f"  {name:<26} {t:10.3f} {t / best['plain'] - 1:+9.1%} {vs_rig_t} {b:11,d} "
            f"{b / sizes['plain'] - 1:+9.1%} {vs_rig_s}"
        )


if __name__ == "__main__":
    main()
