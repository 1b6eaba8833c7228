"""Export speed for a 1M-triangle mesh, against trimesh's own exporter in the same run.

    python benchmarks/bench_export.py [--quick]

Prints seconds per format for lsys3d's writers (.glb with normals and UVs, .usdc,
.usdz) and for trimesh's ``.glb`` export of the same mesh (positions and indices only,
so the baseline does less work than we do), and the ratio.  Vertices in traversal
order and scrambled (as a union returns them).  ``--quick``: a 10,000-triangle
mesh (the test suite's smoke run).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import export_fixtures as fx
from timing import best_of

from lsys3d.exchange import export


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a 10,000-triangle mesh instead of 1M")
    args = ap.parse_args(argv)
    rings, sides = (100, 50) if args.quick else (1000, 500)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scramble in (False, True):
            bark = fx.make_tube(rings, sides, scramble=scramble)
            tree = fx.tree_from_bark(bark)
            label = "scrambled" if scramble else "traversal order"
            print(f"{len(bark.faces):,} triangles, vertices in {label}")
            export(tree, tmp / "warm.glb")
            export(tree, tmp / "warm.usdc")

            positions_only = trimesh.Trimesh(bark.vertices, bark.faces, process=False)

            def trimesh_glb(mesh=positions_only):
                mesh.export(tmp / "trimesh.glb")

            base, _ = best_of(trimesh_glb)
            print(f"  {'trimesh .glb (positions only)':<28} {base:6.3f} s   (baseline)")
            for suffix in (".glb", ".gltf", ".usdc", ".usdz"):
                t, _ = best_of(lambda suffix=suffix, tree=tree: export(tree, tmp / f"out{suffix}"))
                print(f"  {'lsys3d ' + suffix:<28} {t:6.3f} s   {base / t:5.1f}x the baseline's speed")


if __name__ == "__main__":
    main()
