"""The memory model of ``lsys3d batch`` against measured peaks: predicted and measured bytes per job.

    python benchmarks/bench_memory.py [--cases tree3d:7 bush:8:no-union ...]

Each job runs in a fresh process that has already grown and written a small tree (so
imports and USD's plugins are not counted), as a batch worker would.  The job's peak
is the kernel's high-water mark of resident memory (``VmHWM``, reset before the job)
less the memory before it.  Prints the prediction of :func:`lsys3d.library.jobs.predict_size`,
the measurement, and their ratio (the model should not predict less than it takes).
``--cases``: other jobs than the default ones, as ``PRESET:GENERATIONS`` (``:no-union``
for the tube soup).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile

CASES = [
    ("tree3d", 5, True),
    ("tree3d", 6, True),
    ("tree3d", 7, True),
    ("bush", 6, True),
    ("bush", 7, True),
    ("bush", 8, True),
    ("monopodial", 12, True),
    ("abop-1.24a", 6, True),
    ("abop-1.24d", 8, True),
    ("abop-1.24f", 6, True),
    ("tree3d", 7, False),
    ("bush", 8, False),
]

CHILD = r"""
import gc, json, sys
from pathlib import Path
import lsys3d
from lsys3d.exchange import export
from lsys3d.stats import report

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024

name, n, union, folder = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1", Path(sys.argv[4])
warm = lsys3d.generate("tree3d", 2)
export(warm, folder / "warm.glb"); export(warm, folder / "warm.usdc"); report(warm.modules, warm.skeleton, warm)
del warm; gc.collect()
before = status("VmRSS:")
open("/proc/self/clear_refs", "w").write("5")
tree = lsys3d.generate(name, n, union=union)
counts = report(tree.modules, tree.skeleton, tree)
export(tree, folder / "job.glb"); export(tree, folder / "job.usdc")
print(json.dumps({"bytes": status("VmHWM:") - before, "triangles": int(counts["sweep"]["faces"])}))
"""


def case(text: str) -> tuple[str, int, bool]:
    """``PRESET:GENERATIONS[:no-union]`` -> a case of :data:`CASES`."""
    name, n, *rest = text.split(":")
    if rest not in ([], ["no-union"]):
        raise argparse.ArgumentTypeError(f"{text}: expected PRESET:GENERATIONS[:no-union]")
    return name, int(n), not rest


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", type=case, default=CASES, help="PRESET:GENERATIONS[:no-union] ...")
    args = ap.parse_args(argv)
    import lsys3d
    from lsys3d.library.jobs import predict_size
    from lsys3d.pipeline import GenerateOptions

    print(f"{'job':<22} {'tube tris':>10} {'predicted':>10} {'measured':>10}  ratio")
    with tempfile.TemporaryDirectory() as folder:
        for name, n, union in args.cases:
            size = predict_size(lsys3d.load_preset(name), n, 0, GenerateOptions.from_flat(union=union))
            proc = subprocess.run(
                [sys.executable, "-c", CHILD, name, str(n), "1" if union else "0", folder],
                capture_output=True,
                text=True,
                check=True,
            )
            measured = json.loads(proc.stdout.strip().splitlines()[-1])
            label = f"{name} n={n}{'' if union else ' no-union'}"
            print(
                f"{label:<22} {measured['triangles']:>10,} {size.bytes / 1e6:>8.0f}MB {measured['bytes'] / 1e6:>8.0f}MB"
                f"  {size.bytes / max(measured['bytes'], 1):5.2f}x"
            )


if __name__ == "__main__":
    main()
