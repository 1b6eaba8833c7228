"""Sweep + union speed against the naive mesh pipeline, measured in the same run.

    python benchmarks/bench_mesh.py [--sizes 1000 5000 20000] [--naive-cap 20000] [--quick]

For random trees of about 1k, 5k and 20k segments (turtle-free generator
below: gently curving, tapering chains; a lateral branch at some joints)
prints, per size:

* lsys3d: :func:`lsys3d.mesh.sweep.sweep` + :func:`lsys3d.mesh.union.union.union` (seconds,
  output triangles);
* batch: the same tubes, each its own Manifold, in one
  ``Manifold.batch_boolean`` (manifold's own bounding-box grouping);
* naive: one 8-sided cylinder per segment (``trimesh.creation.cylinder``)
  unioned with ``trimesh.boolean.union(engine="manifold")``;

and the ratios naive / lsys3d, batch / lsys3d.  Naive runs are skipped
above ``--naive-cap`` segments.  Numbers are best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse

import manifold3d
import numpy as np
import trimesh
from timing import best_of

from lsys3d.mesh.sweep import SweepOptions, sweep
from lsys3d.mesh.union.union import UnionOptions, _manifold, union
from lsys3d.turtle.skeleton import Skeleton


def _rotate(v, axis, angle):
    """Rodrigues rotation of rows ``v`` about unit rows ``axis``."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * np.einsum("ij,ij->i", axis, v)[:, None] * (1 - c)


def _perp(d, rng):
    a = np.cross(d, rng.normal(size=d.shape))
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def random_tree(n: int, seed: int = 0) -> Skeleton:
    """A plausible tree of about ``n`` segments (Y up, metres), without the turtle.

    Branches of 4-10 segments bend a few degrees per joint, taper linearly and
    put out a lateral branch (30-65 degrees off, 0.65 of the width) at a third
    of their joints; branches are grown breadth first until ``n`` segments.
    """
    rng = np.random.default_rng(seed)
    start, end, w0, w1, parent, order = [], [], [], [], [], []
    queue = [(np.zeros(3), np.array([0.0, 1.0, 0.0]), 0.4, 1.0, 0, -1)]
    head = 0
    while head < len(queue) and len(start) < n:
        p, d, w, step, o, par = queue[head]
        head += 1
        m = int(rng.integers(4, 11))
        widths = np.linspace(w, w * 0.5, m + 1)
        for i in range(m):
            if len(start) >= n:
                break
            d = _rotate(d[None], _perp(d[None], rng), np.radians(rng.uniform(2, 8, 1)))[0]
            d = d + np.array([0, 0.03, 0])
            d /= np.linalg.norm(d)
            q = p + d * step * rng.uniform(0.8, 1.2)
            start.append(p)
            end.append(q)
            w0.append(widths[i])
            w1.append(widths[i + 1])
            parent.append(par)
            order.append(o)
            par = len(start) - 1
            if i < m - 1 and rng.random() < 0.35:
                cd = _rotate(d[None], _perp(d[None], rng), np.radians(rng.uniform(30, 65, 1)))[0]
                queue.append((q, cd, widths[i + 1] * 0.65, step * 0.8, o + 1, par))
            p = q
    # the left hint of the counts measured before Skeleton.from_segments existed
    return Skeleton.from_segments(start, end, w0, w1, parent, order, left_hint=(0.3, 0.5, 0.81))


def naive(sk: Skeleton, sides: int = 8) -> trimesh.Trimesh:
    """One capped cylinder per segment, all unioned by trimesh's manifold engine."""
    cylinders = []
    for a, b, w in zip(sk.start, sk.end, np.maximum(sk.width_start, 1e-3), strict=True):
        cylinders.append(trimesh.creation.cylinder(radius=w / 2, segment=[a, b], sections=sides))
    return trimesh.boolean.union(cylinders, engine="manifold")


def batch(tubes) -> manifold3d.Manifold:
    parts = [_manifold(tubes.select([i]), "batch") for i in range(len(tubes))]
    result = manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add)
    result.num_tri()
    return result


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 5000, 20000])
    ap.add_argument("--naive-cap", type=int, default=20000, help="skip the naive baseline above this many segments")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sides-step", type=int, default=0, help="SweepOptions.sides_step")
    ap.add_argument(
        "--preset",
        nargs="*",
        default=[],
        metavar="NAME:N",
        help="also time presets derived N steps (needs lsys3d.turtle), e.g. monopodial:14; lsys3d and batch only",
    )
    ap.add_argument("--quick", action="store_true", help="sizes 1000 5000, no naive above 5000, one repeat")
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes, args.naive_cap, args.repeat = [1000, 5000], 5000, 1
    sopt = SweepOptions(sides_step=args.sides_step)
    uopt = UnionOptions()
    # warm up manifold's thread pool and numpy
    union(sweep(random_tree(200, seed=1), sopt), uopt)

    print(
        f"{'segments':>8} {'tubes':>6} {'sweep s':>8} {'union s':>8} {'lsys3d s':>9} {'tris':>8}"
        f" {'batch s':>8} {'naive s':>8} {'naive tris':>10} {'naive/ours':>10} {'batch/ours':>10}"
    )
    rows = []
    for n in args.sizes:
        sk = random_tree(n, seed=n)
        t_sweep, tubes = best_of(lambda sk=sk: sweep(sk, sopt), args.repeat)
        t_union, mesh = best_of(lambda tubes=tubes: union(tubes, uopt), args.repeat)
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
        ours = t_sweep + t_union
        t_batch, _ = best_of(lambda tubes=tubes: batch(tubes), 1)
        if n <= args.naive_cap:
            t_naive, nm = best_of(lambda sk=sk: naive(sk), 1)
            naive_tris = len(nm.faces)
        else:
            t_naive, naive_tris = float("nan"), 0
        rows.append((n, ours))
        print(
            f"{len(sk):>8} {len(tubes):>6} {t_sweep:>8.3f} {t_union:>8.3f} {ours:>9.3f} {len(mesh.faces):>8}"
            f" {t_batch:>8.2f} {t_naive:>8.2f} {naive_tris:>10} {t_naive / ours:>10.1f} {t_batch / ours:>10.1f}"
        )
    for spec in args.preset:
        import lsys3d
        from lsys3d.turtle import interpret

        name, steps = spec.split(":")
        g = lsys3d.load_preset(name)
        sk = interpret(lsys3d.derive(g, int(steps)), g)
        t_sweep, tubes = best_of(lambda sk=sk: sweep(sk, sopt), args.repeat)
        t_union, mesh = best_of(lambda tubes=tubes: union(tubes, uopt), args.repeat)
        t_batch, _ = best_of(lambda tubes=tubes: batch(tubes), 1)
        ours = t_sweep + t_union
        print(
            f"{spec}: {len(sk)} segments, {len(tubes)} tubes, sweep {t_sweep:.3f} s, union {t_union:.3f} s,"
            f" {len(mesh.faces)} triangles; batch {t_batch:.2f} s ({t_batch / ours:.1f}x)"
        )
    if len(rows) > 1:
        (n0, t0), (n1, t1) = rows[0], rows[-1]
        exponent = np.log(t1 / t0) / np.log(n1 / n0)
        print(f"growth: time x{t1 / t0:.1f} for segments x{n1 / n0:.1f} (exponent {exponent:.2f})")


if __name__ == "__main__":
    main()
