"""The union at scale: full pipeline against the tube soup, growth, memory, and the other pipelines.

    python benchmarks/bench_union_scale.py [--plant 5 6 7 8 9] [--fern] [--repeat 1]
        [--compare 7] [--no-naive] [--blender .venv-bpy/bin/python] [--hostile] [--no-cleanup-too]
        [--dense] [--dense-only] [--only NAME] [--volume] [--extra=--union-blobs=0]

Each run is its own process (``lsys3d -v generate``), timed from outside, its
peak resident memory read with ``getrusage(RUSAGE_CHILDREN)`` by a wrapper
process started for that run alone (the largest process of the run: lsys3d or
one of its union workers).  Cases:

* the 3D plant ``X -> F[!+X][!&X]F[!-X]/X``, ``F -> FF``, 22.5 degrees,
  width_scale 0.7, at 5..9 generations: full (derive, turtle, sweep, union,
  export ``.glb``) against the soup (``--no-union``: the same without the
  boolean), and how time and memory grow; the full run includes the cleanup
  of the union's bark (its own column), and ``--no-cleanup-too`` adds a row
  per case without it (``--no-cleanup``, the union handed the only reference
  to the tube soup);
* a dense constant-width fern (width 0.01; segments 0.0005-0.04 long, most
  much shorter than wide; about 88k segments): alternate pinnae along a rachis
  that curls in at its tip, pinnules on the pinnae, and so on;
* at ``--compare`` generations, the sweep + union against the naive pipeline
  (one 8-sided ``trimesh.creation.cylinder`` per segment,
  ``trimesh.boolean.union(engine="manifold")``, as in ``bench_mesh.py``) and
  Blender's geometry nodes (Curve to Mesh with an 8-sided circle, filled caps,
  then Mesh Boolean union with the Manifold solver), run with the ``bpy``
  wheel's Python;
* ``--dense``: the set of real dense grammars of issue 34 (``DENSE``: public
  grammar files that draw more than 20k segments, most shorter than their
  width; where they come from: ``benchmarks/dense/README.md``), each full
  against its soup, with the time of every stage and the peak RSS;
  ``--dense-only`` runs that set alone, ``--only TEXT`` the cases whose name
  holds the text, ``--volume`` also prints the volume of each full run's bark
  (trimesh, from its ``.glb``);
* ``--hostile``: the pathological unions of issue 18 (500 parallel
  overlapping branches, 1,000 branches from one point, 5,000 coincident
  branches): the time each takes to finish or to be refused.

Every number of one table comes from the same run; ratios compare runs made
side by side.  The machine is shared: expect +-20% between runs (the CPU
seconds of a run, its own and its union workers', and the load average
beside each line show how much).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import re
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

PLANT = """\
name = "plant3d"
description = "3D plant of the union benchmark (after ABOP 1.24f in three dimensions)."
axiom = "X"
iterations = 7
angle = 22.5
rules = ["X -> F[!+X][!&X]F[!-X]/X", "F -> FF"]

[turtle]
heading = 90
width_scale = 0.7
"""

FERN = """\
name = "fern"
description = "A fern frond of constant width: alternate pinnae along a rachis that curls in at its tip."
axiom = "!(0.01)A(0.04)"
iterations = 75
angle = 60
rules = ["A(l) : l >= 0.0005 -> F(l)[+A(l*0.3)]-(4)F(l)[-A(l*0.3)]-(4)A(l*0.9415)"]

[turtle]
heading = 90
"""

ROOT = Path(__file__).parents[1]
# the dense set (issue 34): (name, grammar file, generations or None for the file's own); benchmarks/dense/README.md
DENSE = [
    ("lpy barnsleyfern", ROOT / "tests/corpus/lpy/real/02-fractals_barnsleyfern.lpy", None),
    ("lpy barnsleyfern3", ROOT / "tests/corpus/lpy/real/02-fractals_barnsleyfern3.lpy", None),
    ("lpy peanocurve n=4", ROOT / "tests/corpus/lpy/real/02-fractals_peanocurve.lpy", 4),
    ("webls param-004 n=14", ROOT / "benchmarks/dense/webls/parametric-param-004.ls", 14),
    ("nylki tree25d n=7", ROOT / "benchmarks/dense/nylki/tree25d.toml", 7),
]
DENSE_LIMIT = "--max-union-pairs=100000000"  # the real ferns cross the default refusal (400,000 pairs)

# a fresh process per run, so that RUSAGE_CHILDREN holds that run alone
WRAPPER = textwrap.dedent(
    """
    import json, resource, subprocess, sys, time
    t = time.perf_counter()
    out = subprocess.run(sys.argv[1:], capture_output=True, text=True)
    seconds = time.perf_counter() - t
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    peak = usage.ru_maxrss * (1 if sys.platform == "darwin" else 1024)
    cpu = usage.ru_utime + usage.ru_stime  # the run and its union workers
    log = out.stderr + out.stdout
    print(json.dumps({"seconds": seconds, "cpu": cpu, "peak": peak, "code": out.returncode, "stderr": log}))
    """
)

BLENDER = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    import bpy
    data = np.load(sys.argv[-1])
    points, radius, offsets = data["points"], data["radius"], data["offsets"]
    t0 = time.perf_counter()
    curve = bpy.data.curves.new("skeleton", "CURVE")
    curve.dimensions = "3D"
    for i in range(len(offsets) - 1):
        a, b = int(offsets[i]), int(offsets[i + 1])
        spline = curve.splines.new("POLY")
        spline.points.add(b - a - 1)
        co = np.ones((b - a, 4))
        co[:, :3] = points[a:b]
        spline.points.foreach_set("co", co.ravel())
        spline.points.foreach_set("radius", radius[a:b])
    obj = bpy.data.objects.new("skeleton", curve)
    bpy.context.scene.collection.objects.link(obj)
    tree = bpy.data.node_groups.new("union", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    group_in, group_out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    circle = nodes.new("GeometryNodeCurvePrimitiveCircle")
    circle.inputs["Resolution"].default_value = 8
    circle.inputs["Radius"].default_value = 1.0
    to_mesh = nodes.new("GeometryNodeCurveToMesh")
    to_mesh.inputs["Fill Caps"].default_value = True
    boolean = nodes.new("GeometryNodeMeshBoolean")
    boolean.operation = "UNION"
    boolean.solver = "MANIFOLD"
    scale = nodes.new("GeometryNodeInputRadius")  # the profile scaled by each point's radius
    links.new(scale.outputs[0], to_mesh.inputs["Scale"])
    # one operand per chain: the Manifold solver unions separate geometries, not the pieces of one
    split = nodes.new("GeometryNodeSplitToInstances")
    split.domain = "CURVE"
    index = nodes.new("GeometryNodeInputIndex")
    links.new(group_in.outputs[0], split.inputs["Geometry"])
    links.new(index.outputs[0], split.inputs["Group ID"])
    links.new(split.outputs["Instances"], to_mesh.inputs["Curve"])
    links.new(circle.outputs["Curve"], to_mesh.inputs["Profile Curve"])
    links.new(to_mesh.outputs["Mesh"], boolean.inputs["Mesh 2"])
    links.new(boolean.outputs["Mesh"], group_out.inputs[0])
    modifier = obj.modifiers.new("union", "NODES")
    modifier.node_group = tree
    t1 = time.perf_counter()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(depsgraph).to_mesh()
    mesh.calc_loop_triangles()
    t2 = time.perf_counter()
    print("BLENDER", t2 - t1, t2 - t0, len(mesh.loop_triangles))
    """
)


def measure(cmd: list[str], env=None) -> dict:
    out = subprocess.run([sys.executable, "-c", WRAPPER, *cmd], capture_output=True, text=True, env=env)
    result = json.loads(out.stdout)
    result["stages"] = {m[1]: float(m[2]) for m in re.finditer(r"lsys3d: (\w+) +([\d.]+) s", result["stderr"])}
    if result["code"] != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{result['stderr']}")
    return result


def best(cmd: list[str], repeat: int) -> dict:
    runs = [measure(cmd) for _ in range(repeat)]
    return min(runs, key=lambda r: r["seconds"])


def lsys3d_cmd(grammar: Path, n: int | None, out: Path, *extra: str) -> list[str]:
    cmd = [sys.executable, "-m", "lsys3d", "-v", "generate", str(grammar), "-o", str(out), *extra]
    return cmd + (["-n", str(n)] if n is not None else [])


def gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.2f} GB"


STAGES = ("derive", "interpret", "sweep", "union", "cleanup", "export")


def bark_volume(glb: Path) -> float:
    """The enclosed volume of the bark of a ``.glb`` (its largest mesh by faces: the leaves are separate meshes)."""
    import trimesh

    scene = trimesh.load(glb, force="scene")
    meshes = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh)]
    return float(max(meshes, key=lambda m: len(m.faces)).volume)


def full_vs_soup(rows, repeat: int, tmp: Path, extra: tuple[str, ...] = (), stages: bool = False, volume: bool = False):
    print(
        f"{'case':<24} {'segments':>9} {'faces':>10} {'full s':>7} {'union s':>8} {'cleanup s':>9} {'soup s':>7}"
        f" {'full/soup':>9} {'RSS full':>9} {'RSS soup':>9} {'CPU full':>8} {'CPU soup':>8} {'load':>5}"
    )
    table = []
    for name, grammar, n, *more in rows:
        out = tmp / f"{name}.glb"
        full = best(lsys3d_cmd(grammar, n, out, *more, *extra), repeat)
        faces = int(re.search(r"wrote .*?: [\d,]+ vertices, ([\d,]+) faces", full["stderr"])[1].replace(",", ""))
        soup = best(lsys3d_cmd(grammar, n, tmp / f"{name}-soup.glb", "--no-union"), repeat)
        segments = _segments(grammar, n)
        if not more:
            table.append((name, segments, full, soup))
        print(
            f"{name:<24} {segments:>9,} {faces:>10,} {full['seconds']:>7.2f} {full['stages'].get('union', 0):>8.2f}"
            f" {full['stages'].get('cleanup', 0):>9.2f} {soup['seconds']:>7.2f}"
            f" {full['seconds'] / soup['seconds']:>8.1f}x {gib(full['peak']):>9} {gib(soup['peak']):>9}"
            f" {full['cpu']:>8.2f} {soup['cpu']:>8.2f} {os.getloadavg()[0]:>5.1f}",
            flush=True,
        )
        if stages:
            print("    stages, s: " + "  ".join(f"{k} {full['stages'][k]:.2f}" for k in STAGES if k in full["stages"]))
        if volume:
            print(f"    volume of the bark: {bark_volume(out):.6g}")
    return table


def _segments(grammar: Path, n: int | None) -> int:
    import lsys3d
    from lsys3d.pipeline import draw

    g = lsys3d.load(grammar)
    return len(draw(g, g.iterations if n is None else n, g.seed)[1])


def growth(table):
    plants = [(int(name.split("=")[1]), seg, full) for name, seg, full, _ in table if name.startswith("plant")]
    if len(plants) < 2:
        return
    print("\ngrowth of the full run from one generation to the next (segments x4 each):")
    for (n0, s0, f0), (n1, s1, f1) in itertools.pairwise(plants):
        t, m = f1["seconds"] / f0["seconds"], f1["peak"] / f0["peak"]
        exponent = np.log(t) / np.log(s1 / s0)
        print(f"  n={n0} -> {n1}: time x{t:.2f} (segments^{exponent:.2f}), peak RSS x{m:.2f}")


def compare(grammar: Path, n: int, repeat: int, naive: bool, blender: str | None, tmp: Path):
    import lsys3d
    from lsys3d.mesh.sweep import sweep
    from lsys3d.mesh.union.union import union
    from lsys3d.pipeline import draw

    g = lsys3d.Grammar.from_file(grammar)
    _, sk = draw(g, n, g.seed)
    print(f"\nsweep + union of the plant at n={n} ({len(sk):,} segments), against the other pipelines:")
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        mesh = union(sweep(sk))
        times.append(time.perf_counter() - t0)
    ours = min(times)
    print(
        f"  lsys3d sweep + union        {ours:8.2f} s  {len(mesh.faces):>10,} triangles"
        f"  watertight {mesh.is_watertight}"
    )
    if blender:
        chains = sk.chains
        lines = sk.polylines()
        radius = []
        for c in range(len(chains)):
            seg = chains.segments[chains.offsets[c] : chains.offsets[c + 1]]
            radius.append(np.concatenate([sk.width_start[seg[:1]], sk.width_end[seg]]) / 2)
        npz = tmp / "skeleton.npz"
        np.savez(
            npz,
            points=np.concatenate(lines),
            radius=np.concatenate(radius),
            offsets=np.cumsum([0] + [len(p) for p in lines]),
        )
        script = tmp / "blender_union.py"
        script.write_text(BLENDER)
        best_b = None
        for _ in range(repeat):
            out = subprocess.run([blender, str(script), str(npz)], capture_output=True, text=True)
            m = re.search(r"BLENDER ([\d.]+) ([\d.]+) (\d+)", out.stdout)
            if not m:
                print(f"  Blender: failed ({out.stderr.strip().splitlines()[-1:]})")
                break
            if best_b is None or float(m[1]) < best_b[0]:
                best_b = (float(m[1]), float(m[2]), int(m[3]))
        if best_b:
            print(
                f"  Blender 5 nodes (Manifold)  {best_b[0]:8.2f} s  {best_b[2]:>10,} triangles"
                f"  (with building the curve: {best_b[1]:.2f} s)   lsys3d / Blender = {ours / best_b[0]:.2f}x"
            )
    if naive:
        sys.path.insert(0, str(Path(__file__).parent))
        from bench_mesh import naive as naive_union

        t0 = time.perf_counter()
        nm = naive_union(sk)
        tn = time.perf_counter() - t0
        print(
            f"  naive trimesh per segment   {tn:8.2f} s  {len(nm.faces):>10,} triangles  watertight {nm.is_watertight}"
            f"   lsys3d / naive = {ours / tn:.3f}x"
        )


def hostile():
    sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
    from skeletons import make_skeleton

    from lsys3d.errors import LSystemError
    from lsys3d.mesh.sweep import SweepOptions, sweep
    from lsys3d.mesh.union.union import union

    def parallel(n=500):
        x = np.arange(n) * 0.01 / n
        return make_skeleton(np.c_[x, 0 * x, 0 * x], np.c_[x, 0 * x + 1, 0 * x], 0.1, parent=[-1] * n), 3

    def star(n=1000):
        k = np.arange(n) + 0.5
        phi, th = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
        d = np.c_[np.cos(th) * np.sin(phi), np.cos(phi), np.sin(th) * np.sin(phi)]
        return make_skeleton(np.zeros((n, 3)), d, 0.1, parent=[-1] * n), 8

    def coincident(n=5000):
        return make_skeleton(np.zeros((n, 3)), np.tile([[0, 1.0, 0]], (n, 1)), 0.1, parent=[-1] * n), 8

    print("\npathological unions (issue 18):")
    for name, make in (
        ("500 parallel overlapping", parallel),
        ("1,000 from one point", star),
        ("5,000 coincident", coincident),
    ):
        sk, sides = make()
        tubes = sweep(sk, SweepOptions(sides=sides))
        t0 = time.perf_counter()
        try:
            mesh = union(tubes)
            outcome = f"{len(mesh.faces):,} triangles, watertight {mesh.is_watertight}"
        except LSystemError as exc:
            outcome = f"refused: {type(exc).__name__}: {str(exc)[:90]}..."
        print(f"  {name:<26} {len(tubes.faces):>7,} tube triangles  {time.perf_counter() - t0:6.2f} s  {outcome}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", type=int, nargs="*", default=[5, 6, 7, 8, 9], help="generations of the 3D plant")
    ap.add_argument("--no-fern", dest="fern", action="store_false", help="skip the fern")
    ap.add_argument("--repeat", type=int, default=1, help="best of this many runs")
    ap.add_argument("--compare", type=int, default=7, help="plant generations compared with naive and Blender (0: no)")
    ap.add_argument("--no-naive", dest="naive", action="store_false")
    default_blender = Path(__file__).parents[1] / ".venv-bpy" / "bin" / "python"
    ap.add_argument(
        "--blender",
        default=str(default_blender) if default_blender.exists() else None,
        help="a Python with the bpy wheel (default: .venv-bpy/bin/python if there)",
    )
    ap.add_argument("--hostile", action="store_true", help="also time the pathological unions of issue 18")
    ap.add_argument("--no-cleanup-too", dest="raw", action="store_true", help="also run each case without the cleanup")
    ap.add_argument("--dense", action="store_true", help="also the set of real dense grammars (issue 34)")
    ap.add_argument("--dense-only", action="store_true", help="the set of real dense grammars alone")
    ap.add_argument("--only", help="run only the cases whose name contains this text (with --dense-only)")
    ap.add_argument("--volume", action="store_true", help="also print the volume of each full run's bark")
    ap.add_argument("--extra", action="append", default=[], help="an option given to every full run (repeatable)")
    args = ap.parse_args(argv)
    print(f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plant, fern = tmp / "plant3d.toml", tmp / "fern.toml"
        plant.write_text(PLANT)
        fern.write_text(FERN)
        if args.dense_only:
            chosen = [row for row in DENSE if args.only is None or args.only in row[0]]
            rows = [(*row, DENSE_LIMIT) for row in chosen]
            full_vs_soup(rows, args.repeat, tmp, tuple(args.extra), stages=True, volume=args.volume)
            return
        rows = [(f"plant n={n}", plant, n) for n in args.plant]
        if args.dense:
            rows += [(*row, DENSE_LIMIT) for row in DENSE]
        if args.fern:
            rows.append(("fern", fern, None))
        if args.raw:
            rows = [r for row in rows for r in (row, (f"{row[0]} --no-cleanup", *row[1:], "--no-cleanup"))]
        table = full_vs_soup(rows, args.repeat, tmp, tuple(args.extra), stages=args.dense, volume=args.volume)
        growth(table)
        if args.compare:
            compare(plant, args.compare, args.repeat, args.naive, args.blender, tmp)
        if args.hostile:
            hostile()


if __name__ == "__main__":
    main()
