"""What query modules and an environment cost: a 50k-segment derivation and its turtle, with them and without.

    python benchmarks/bench_environment.py [--repeat 3] [--iterations 101]

Both grammars grow the same plant: apices that step forward every generation and fork every 8th.  The
open one asks the turtle where each apex is (``A(k) > ?P(x, y, z) : y < 1000``, true everywhere, so the
plants match segment for segment) and grows on a 40 x 40 m support wall (adhesion and climbing steer every
segment); the closed one has neither.  Each is derived and drawn ``--repeat`` times, interleaved, and the
best times are compared: derivation and the turtle (the environment loaded and its grid sampled before
the clock starts), and the pipeline's :func:`~lsys3d.pipeline.draw`, which reads the scene and samples its
grid itself (the process's grid cache cleared before each such run), and ``draw()`` once more with the
grid kept from the run before (a scene drawn again in the same process, as the editor and levels of detail
do: :func:`lsys3d.turtle.environment.clear_grid_cache` not called).  A third grammar adds ``?E`` at every
apex and ``shadow = true`` (the plant's own shade, :mod:`lsys3d.turtle.shadow`) without the wall, to give
what self-shadowing costs, and a fourth is the open one with its query modules rewritten away each step
(``?P(x, y, z) ->``: the apex writes a new one, so they do not pile up behind it) to show what the piling
costs.  Both the wall-clock and the process's CPU time are given: on a machine shared
with other jobs the CPU time is the steadier measure.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import trimesh

from lsys3d import Grammar
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.turtle.environment import clear_grid_cache, load_environment
from lsys3d.turtle.interpret import interpret
from lsys3d.turtle.query import derive_answering
from lsys3d.turtle.steering import SteeringMemo

RULES = [
    "A(k) {} : k % 8 == 0 -> F(0.05)[+(60)A(k + 1){q}][-(60)A(k + 1){q}]",
    "A(k) {} : k % 8 > 0 -> F(0.05)+(uniform(-10, 10))A(k + 1){q}",
]


def grammar(open_: bool, iterations: int, wall: str, shadow: bool = False, consumed: bool = False) -> Grammar:
    context = "> ?P(x, y, z)" if open_ else ""
    q = ("?P(0,0,0)?E(0,0,0)" if shadow else "?P(0,0,0)") if open_ else ""
    rules = [r.format(context, q=q) for r in RULES]
    environment = {"support": wall, "distance": 0.0, "adhesion": 0.8, "climb": 0.2, "reach": 0.5} if open_ else {}
    if shadow:  # the plant's own shade, read by ?E (no wall: ?E's exact distances to it are not what is measured)
        environment = {"shadow": True, "shadow_voxel": 0.5}
    if open_:
        rules = [r.replace(": k %", ": y < 1000 && k %") for r in rules]
    if consumed:
        rules.append("?P(x, y, z) ->")
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
    steering = SteeringMemo() if env is not None else None  # as draw() does: each segment steered once
    modules = derive_answering(g, g.iterations, g.seed, environment=env, steering=steering)
    skeleton = interpret(modules, g, scene=env.scene() if env is not None else None, steering=steering)
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
        shaded = grammar(True, args.iterations, path, shadow=True)
        consumed = grammar(True, args.iterations, path, consumed=True)
        options = GenerateOptions()
        draw(plain, 4, 1), draw(answered, 4, 1)  # compile every kernel first
        clear_grid_cache()
        t0 = time.perf_counter()
        env = load_environment(answered)
        env.scene()
        grid = time.perf_counter() - t0
        shaded_env = load_environment(shaded)
        shaded_env.scene()
        best: dict[str, tuple[float, float]] = {}
        sizes = {}

        def clock(key: str, run):
            t0, c0 = time.perf_counter(), time.process_time()
            out = run()
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            old = best.get(key, (float("inf"), float("inf")))
            best[key] = (min(old[0], wall), min(old[1], cpu))
            return out

        for _ in range(args.repeat):
            runs = (("plain", plain, None), ("answered", answered, env), ("shaded", shaded, shaded_env))
            for name, g, e in (*runs, ("consumed", consumed, env)):
                sizes[name] = clock(name, lambda g=g, e=e: _stages(g, e))
                # the pipeline's first stages: the scene read and its grid sampled too
                clear_grid_cache()
                clock(name + " draw", lambda g=g: draw(g, g.iterations, g.seed, options))
                # and again, the grid kept in the process from the run before
                clock(name + " cached", lambda g=g: draw(g, g.iterations, g.seed, options))
    print(
        f"{'':20}{'modules':>10}{'segments':>10}{'seconds':>10}{'CPU s':>8}{'draw()':>9}{'CPU s':>8}"
        f"{'cached':>9}{'CPU s':>8}"
    )
    labels = (("plain", "without"), ("answered", "?P + environment"), ("shaded", "?P ?E, shadow"))
    for name, label in (*labels, ("consumed", "?P rewritten away")):
        m, s = sizes[name]
        (w, c), (dw, dc), (cw, cc) = best[name], best[name + " draw"], best[name + " cached"]
        print(f"{label:20}{m:>10,}{s:>10,}{w:>10.3f}{c:>8.3f}{dw:>9.3f}{dc:>8.3f}{cw:>9.3f}{cc:>8.3f}")
    print(f"scene grid (once):      {grid:.3f} s")
    ratio = [best["answered"][k] / best["plain"][k] for k in (0, 1)]
    ratio_draw = [best["answered draw"][k] / best["plain draw"][k] for k in (0, 1)]
    print(f"ratio (derive + turtle): {ratio[0]:.2f}x (CPU time {ratio[1]:.2f}x)")
    print(f"ratio (draw(), the scene read and gridded in it): {ratio_draw[0]:.2f}x (CPU time {ratio_draw[1]:.2f}x)")
    ratio_kept = [best["answered cached"][k] / best["plain cached"][k] for k in (0, 1)]
    print(f"ratio (draw(), the grid kept from the run before): {ratio_kept[0]:.2f}x (CPU time {ratio_kept[1]:.2f}x)")
    shaded_ratio = [best["shaded"][k] / best["plain"][k] for k in (0, 1)]
    print(f"ratio with ?E and the plant's shade: {shaded_ratio[0]:.2f}x (CPU time {shaded_ratio[1]:.2f}x)")
    consumed_ratio = [best["consumed"][k] / best["plain"][k] for k in (0, 1)]
    print(f"ratio, ?P rewritten away each step: {consumed_ratio[0]:.2f}x (CPU time {consumed_ratio[1]:.2f}x)")


if __name__ == "__main__":
    main()
