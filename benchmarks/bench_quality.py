"""The cleanup's cost and effect: generate with and without it, per preset, measured in the same run.

    python benchmarks/bench_quality.py [--presets tree3d bush ...] [--repeat 3] [--lod] [--export]

For each preset (default: every preset that draws a mesh) prints the time of
``lsys3d.generate`` without the cleanup (``cleanup=False``: the union's raw
bark) and with it (the default), their ratio, and the bark's quality both
ways (:mod:`lsys3d.mesh.quality`: triangles, above aspect 100 and 1,000, under
1 um high, median uv stretch) and the cleaned bark's volume against the raw
union's (the collars must blend, not inflate: within 0.5%).  With ``--export``,
also the time of the command line's whole job both ways (``lsys3d generate
PRESET -o tree.glb``: generate and write the .glb, in this process) and its
ratio: the cleaned bark has fewer triangles to write.  With ``--lod``, also the time of tree3d's four
levels of detail against level 0 alone, on the wall clock and in CPU seconds
(steadier on a busy machine; the union's worker processes are not counted, and
tree3d's union is too small to use them).  Times are the best of ``--repeat``
runs (the first run of a process compiles the numba kernels: one warm-up
run is not counted).  numpy's arrays are kept in small pages, as the command
line keeps them (:func:`lsys3d.arrays.small_pages`).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from timing import best_of, best_of_each

import lsys3d
from lsys3d.arrays import small_pages
from lsys3d.mesh.quality import quality

SKIP = ("algae", "dog", "dog-growing")  # no mesh: a string, a 2D drawing


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="*", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lod", action="store_true", help="also time tree3d's levels 0-3 against level 0 alone")
    ap.add_argument("--export", action="store_true", help="also time generate + writing the .glb, both ways")
    args = ap.parse_args(argv)
    small_pages()  # as the command line does (numpy's huge pages stall on a fault here): both ways alike
    names = args.presets or [n for n in lsys3d.list_presets() if n not in SKIP]
    lsys3d.generate("abop-1.24a", iterations=3)  # compile the kernels
    print(
        f"{'preset':>14} {'raw s':>7} {'clean s':>8} {'ratio':>6} {'raw tris':>9} {'>100':>7} {'>1000':>7}"
        f" {'<1um':>6} {'stretch':>7} {'tris':>8} {'>100':>5} {'>1000':>5} {'<1um':>5} {'stretch':>7} {'volume':>8}"
        + (f" {'+glb raw':>8} {'+glb clean':>10} {'ratio':>6}" if args.export else "")
    )
    out = Path(tempfile.mkdtemp(prefix="bench_quality_")) / "tree.glb"
    for name in names:
        # raw and clean in turn: a drifting machine drifts under both alike
        (t_raw, raw), (t_clean, clean) = best_of_each(
            [lambda name=name: lsys3d.generate(name, cleanup=False), lambda name=name: lsys3d.generate(name)],
            args.repeat,
        )
        a, b = quality(raw.bark), quality(clean.bark)
        job = ""
        if args.export:
            (e_raw, _), (e_clean, _) = best_of_each(
                [
                    lambda name=name: lsys3d.export(lsys3d.generate(name, cleanup=False), out),
                    lambda name=name: lsys3d.export(lsys3d.generate(name), out),
                ],
                args.repeat,
            )
            job = f" {e_raw:>8.2f} {e_clean:>10.2f} {e_clean / e_raw:>6.2f}"
        print(
            f"{name:>14} {t_raw:>7.2f} {t_clean:>8.2f} {t_clean / t_raw:>6.2f} {a.triangles:>9}"
            f" {a.over_100:>7} {a.over_1000:>7} {a.slivers:>6} {a.uv_stretch or 0:>7.2f} {b.triangles:>8}"
            f" {b.over_100:>5} {b.over_1000:>5} {b.slivers:>5} {b.uv_stretch or 0:>7.2f}"
            f" {100 * (clean.bark.volume / raw.bark.volume - 1) if raw.bark.volume else 0:>+7.3f}%{job}"
        )
    if args.lod:
        for label, clock in (("wall", time.perf_counter), ("CPU", time.process_time)):
            t0, _ = best_of(lambda: lsys3d.generate("tree3d"), args.repeat, clock)
            t4, tree = best_of(lambda: lsys3d.generate("tree3d", lod=(0, 1, 2, 3)), args.repeat, clock)
            counts = ", ".join(f"LOD{lod.level} {lod.triangles:,}" for lod in tree.lods)
            print(f"tree3d levels 0-3: {t4:.2f} {label} s against level 0 alone {t0:.2f} s: {t4 / t0:.2f}x ({counts})")


if __name__ == "__main__":
    main()
