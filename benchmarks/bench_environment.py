"""What query modules and an environment cost: a 50k-segment derivation and its turtle, with them and without.

    python benchmarks/bench_environment.py [--repeat 3] [--iterations 101]

Both grammars grow the same plant: apices that step forward every generation and fork every 8th.  The
open one asks the turtle where each apex is (``A(k) > ?P(x, y, z) : y < 1000``, true everywhere, so the
plants match segment for segment) and grows on a 40 x 40 m support wall (adhesion and climbing steer every
segment); the closed one has neither.  Each is derived and drawn ``--repeat`` times, interleaved, and the
best times are compared; the scene's grid, sampled once per environment, is reported apart and in a
second ratio.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import trimesh

from lsys3d import Grammar
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.turtle.environment import load_environment

RULES = [
    "A(k) {} : k % 8 == 0 -> F(0.05)[+(60)A(k + 1){q}][-(60)A(k + 1){q}]",
    "A(k) {} : k % 8 > 0 -> F(0.05)+(uniform(-10, 10))A(k + 1){q}",
]


def grammar(open_: bool, iterations: int, wall: str) -> Grammar:
    context = "> ?P(x, y, z)" if open_ else ""
    q = "?P(0,0,0)" if open_ else ""
    rules = [r.format(context, q=q) for r in RULES]
    environment = {"support": wall, "distance": 0.0, "adhesion": 0.8, "climb": 0.2, "reach": 0.5} if open_ else {}
    if open_:
        rules = [r.replace(": k %", ": y < 1000 && k %") for r in rules]
    return Grammar(
        axiom="^(90)f(0.05)&(90)A(1)" + q,
        rules=rules,
        iterations=iterations,
        seed=1,
        turtle={"heading": 90},
        environment=environment,
        source=str(Path(wall).parent / "bench.toml"),
    )


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--iterations", type=int, default=101)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        wall = trimesh.creation.box(extents=(40, 40, 0.3))
        wall.apply_translation((0, 20, -0.15))
        path = str(Path(folder) / "wall.obj")
        wall.export(path)
        plain, answered = grammar(False, args.iterations, path), grammar(True, args.iterations, path)
        options = GenerateOptions()
        draw(plain, 4, 1), draw(answered, 4, 1)  # compile every kernel first
        t0 = time.perf_counter()
        load_environment(answered).scene()
        grid = time.perf_counter() - t0
        best = {"plain": float("inf"), "answered": float("inf")}
        sizes = {}
        for _ in range(args.repeat):
            for name, g in (("plain", plain), ("answered", answered)):
                env = load_environment(g)
                if env is not None:
                    env.scene()  # sampled before the clock starts: reported above
                t0 = time.perf_counter()
                modules, skeleton = draw(g, g.iterations, g.seed, options)
                best[name] = min(best[name], time.perf_counter() - t0)
                sizes[name] = (len(modules), len(skeleton))
    print(f"{'':24}{'modules':>10}{'segments':>10}{'seconds':>10}")
    for name, label in (("plain", "without"), ("answered", "?P + environment")):
        m, s = sizes[name]
        print(f"{label:24}{m:>10,}{s:>10,}{best[name]:>10.3f}")
    print(f"scene grid (once):      {grid:.3f} s")
    print(f"ratio (derive + turtle): {best['answered'] / best['plain']:.2f}x")
    print(f"ratio (with the grid):   {(best['answered'] + grid) / best['plain']:.2f}x")


if __name__ == "__main__":
    main()
