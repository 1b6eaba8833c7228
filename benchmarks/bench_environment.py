"""What query modules and an environment cost: a 50k-segment derivation and its turtle, with them and without.

    python benchmarks/bench_environment.py [--repeat 3] [--iterations 101]

Both grammars grow the same plant: apices that step forward every generation and fork every 8th.  The
open one asks the turtle where each apex is (``A(k) > ?P(x, y, z) : y < 1000``, true everywhere, so the
plants match segment for segment) and grows on a 40 x 40 m support wall (adhesion and climbing steer every
segment); the closed one has neither.  Each is derived and drawn ``--repeat`` times, interleaved, and the
best times are compared: derivation and the turtle (the environment loaded and its grid sampled before
the clock starts), and the pipeline's :func:`~lsys3d.pipeline.draw`, which reads the scene and samples its
grid itself.
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
from lsys3d.turtle.interpret import interpret
from lsys3d.turtle.query import derive_answering

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


def _stages(g: Grammar, env) -> tuple[int, int]:
    """Derive (the turtle answering between the steps when asked) and draw: what the ratio measures."""
    modules = derive_answering(g, g.iterations, g.seed, environment=env)
    skeleton = interpret(modules, g, scene=env.scene() if env is not None else None)
    return len(modules), len(skeleton)


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
        env = load_environment(answered)
        env.scene()
        grid = time.perf_counter() - t0
        best = {
            "plain": float("inf"),
            "answered": float("inf"),
            "plain draw": float("inf"),
            "answered draw": float("inf"),
        }
        sizes = {}
        for _ in range(args.repeat):
            for name, g, e in (("plain", plain, None), ("answered", answered, env)):
                t0 = time.perf_counter()
                sizes[name] = _stages(g, e)
                best[name] = min(best[name], time.perf_counter() - t0)
                t0 = time.perf_counter()  # the pipeline's first stages: the scene read and its grid sampled too
                draw(g, g.iterations, g.seed, options)
                best[name + " draw"] = min(best[name + " draw"], time.perf_counter() - t0)
    print(f"{'':24}{'modules':>10}{'segments':>10}{'seconds':>10}{'draw()':>10}")
    for name, label in (("plain", "without"), ("answered", "?P + environment")):
        m, s = sizes[name]
        print(f"{label:24}{m:>10,}{s:>10,}{best[name]:>10.3f}{best[name + ' draw']:>10.3f}")
    print(f"scene grid (once):      {grid:.3f} s")
    print(f"ratio (derive + turtle): {best['answered'] / best['plain']:.2f}x")
    print(f"ratio (draw(), the scene read and gridded in it): {best['answered draw'] / best['plain draw']:.2f}x")


if __name__ == "__main__":
    main()
