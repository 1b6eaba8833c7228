"""Every bundled preset grown in this process, written as .glb and .usdc: CPU seconds each and the files' SHA-256.

    PYTHONPATH=. python benchmarks/preset_bytes.py OUT [--only NAME ...] [--compare OTHER]

For a change that must not change a byte (the pipeline's speed): run it on the code before and after (the same
presets in the same order), then ``--compare`` the two folders' ``hashes.json``. Each preset is grown at its own
iterations and seed (as ``lsys3d generate PRESET`` and ``tests/grown.py``), with the default options; its
``generate`` CPU seconds (``time.process_time``: this process, the union's threads included) are printed, and
the files written to ``OUT/PRESET/`` (textures beside the .usdc included) are listed with their SHA-256 in
``OUT/hashes.json``. Presets that draw nothing (``algae``, ``dog``) are skipped. A first run of a checkout also
compiles the kernels: run twice, or take the second.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

from lsys3d.errors import GeometryError
from lsys3d.exchange import export
from lsys3d.lsystem.presets import list_presets
from lsys3d.pipeline import generate


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="folder for the files and hashes.json")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="these presets (default: all, sorted)")
    ap.add_argument("--compare", type=Path, metavar="OTHER", help="a folder of an earlier run: the files that differ")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    total = 0.0
    for name in args.only or list_presets():
        start = time.process_time()
        try:
            tree = generate(name)
        except GeometryError as exc:
            print(f"{name:18s} skipped: {str(exc)[:70]}")
            continue
        cpu = time.process_time() - start
        total += cpu
        folder = args.out / name
        folder.mkdir(exist_ok=True)
        start = time.process_time()
        export(tree, folder / f"{name}.glb")
        export(tree, folder / f"{name}.usdc")
        print(f"{name:18s} generate {cpu:6.2f} CPU s   export {time.process_time() - start:5.2f}", flush=True)
    hashes = {
        p.relative_to(args.out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(args.out.rglob("*"))
        if p.is_file() and p.name != "hashes.json"
    }
    (args.out / "hashes.json").write_text(json.dumps(hashes, indent=1) + "\n")
    print(f"generate {total:.2f} CPU s in all; {len(hashes)} files")
    if args.compare:
        other = json.loads((args.compare / "hashes.json").read_text())
        differ = sorted(k for k in hashes.keys() | other.keys() if hashes.get(k) != other.get(k))
        print("the same bytes" if not differ else f"{len(differ)} files differ: {', '.join(differ[:20])}")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
