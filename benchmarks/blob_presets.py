"""Every bundled preset with and without the union's level sets (``UnionOptions.blobs``, issue 34), side by side.

    PYTHONPATH=. python benchmarks/blob_presets.py [--repeats 2] [--only NAME ...] [--blobs 0.25]

For each preset at its own iterations and seed (the golden files' recipe), grown with ``blobs=0`` and with
``blobs`` (alternating, ``--repeats`` times each, best taken; ``workers=1`` so that the union and its cleanup run
in this process and their CPU time is this process's): the union's and the cleanup's CPU seconds, how many
tubes went to level sets, the bark's faces and volume, and whether the bark's arrays are the same.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import re
import time

import numpy as np

from lsys3d.lsystem.presets import list_presets, load_preset
from lsys3d.mesh.union.union import UnionOptions
from lsys3d.pipeline import GenerateOptions, draw, generate


class _Blobs(logging.Handler):
    """Counts the tubes the union meshed as level sets (its debug line)."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.tubes = 0

    def emit(self, record):
        m = re.match(r"union: (\d+) tubes meshed as level sets", record.getMessage())
        if m:
            self.tubes += int(m.group(1))


def _volume(mesh) -> float:
    tri = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces)]
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)


def _run(name: str, blobs: float, handler: _Blobs) -> dict:
    grammar = load_preset(name)
    options = GenerateOptions().replace(union=UnionOptions(blobs=blobs, workers=1))
    cpu: dict[str, float] = {}
    started: dict[str, float] = {}

    def progress(stage, what, _value):
        if stage in ("union", "cleanup") and what == "start":
            started[stage] = time.process_time()
        elif stage in started and what == "done":
            cpu[stage] = cpu.get(stage, 0.0) + time.process_time() - started.pop(stage)

    handler.tubes = 0
    tree = generate(grammar, grammar.iterations, grammar.seed, options=options, progress=progress)
    bark = tree.bark
    digest = hashlib.sha256(np.ascontiguousarray(bark.vertices).tobytes() + np.ascontiguousarray(bark.faces).tobytes())
    return {
        "union": cpu.get("union", 0.0),
        "cleanup": cpu.get("cleanup", 0.0),
        "faces": len(bark.faces),
        "volume": _volume(bark) if len(bark.faces) else 0.0,
        "blob_tubes": handler.tubes,
        "sha": digest.hexdigest()[:12],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--only", nargs="*")
    parser.add_argument("--blobs", type=float, default=0.25)
    args = parser.parse_args()
    handler = _Blobs()
    log = logging.getLogger("lsys3d")
    log.addHandler(handler)
    log.setLevel(logging.DEBUG)
    log.propagate = False
    names = args.only or list_presets()
    print(
        "| preset | tubes to level sets | union CPU s off / on | cleanup CPU s off / on | faces off / on | "
        "volume off / on | same bark |"
    )
    print("|---|---|---|---|---|---|---|")
    for name in names:
        grammar = load_preset(name)
        if not len(draw(grammar, grammar.iterations, grammar.seed)[1]):
            continue  # a symbol-only grammar: nothing to mesh
        best: dict[float, dict] = {}
        for _ in range(args.repeats):
            for blobs in (0.0, args.blobs):
                r = _run(name, blobs, handler)
                b = best.get(blobs)
                if b is None or r["union"] + r["cleanup"] < b["union"] + b["cleanup"]:
                    best[blobs] = r
        off, on = best[0.0], best[args.blobs]
        print(
            f"| {name} | {on['blob_tubes']} | {off['union']:.3f} / {on['union']:.3f} | "
            f"{off['cleanup']:.3f} / {on['cleanup']:.3f} | {off['faces']:,} / {on['faces']:,} | "
            f"{off['volume']:.6g} / {on['volume']:.6g} | {'yes' if off['sha'] == on['sha'] else 'NO'} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
