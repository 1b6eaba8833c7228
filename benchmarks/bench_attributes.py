"""What hierarchy and wind attributes, the rig and materials cost: generate time and file size against plain.

    python benchmarks/bench_attributes.py [--preset tree3d] [--repeat 5]

Each setting is grown ``--repeat`` times, interleaved with the plain run so that a busy machine slows all
alike; the best time of each is compared with the plain one, and each .glb's size with the plain .glb's.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import lsys3d

SETTINGS = {
    "plain": {},
    "attributes compact": {"attributes": "compact"},
    "attributes full": {"attributes": "full"},
    "rig": {"rig": True},
    "attributes compact + rig": {"attributes": "compact", "rig": True},
}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="tree3d")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    lsys3d.generate(args.preset)  # compile and warm every cache first
    best = {name: float("inf") for name in SETTINGS}
    trees = {}
    for _ in range(args.repeat):
        for name, settings in SETTINGS.items():
            t0 = time.perf_counter()
            trees[name] = lsys3d.generate(args.preset, **settings)
            best[name] = min(best[name], time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as folder:
        sizes = {name: lsys3d.export(tree, Path(folder) / f"{i}.glb").stat().st_size for i, (name, tree) in
                 enumerate(trees.items())}  # fmt: skip
    base_t, base_s = best["plain"], sizes["plain"]
    print(f"{args.preset}: best of {args.repeat}, interleaved")
    print(f"  {'setting':<28} {'generate s':>10} {'vs plain':>9} {'.glb MB':>9} {'vs plain':>9}")
    for name in SETTINGS:
        t, s = best[name], sizes[name]
        print(f"  {name:<28} {t:10.3f} {t / base_t - 1:+9.1%} {s / 1e6:9.2f} {s / base_s - 1:+9.1%}")


if __name__ == "__main__":
    main()
