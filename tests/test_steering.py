"""The steering memo: the turtle that draws takes the environment's steering from the one that answered derivation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from lsys3d import Grammar
from lsys3d.lsystem.derive import derive
from lsys3d.turtle.environment import load_environment
from lsys3d.turtle.interpret import interpret
from lsys3d.turtle.query import derive_answering
from lsys3d.turtle.steering import SteeringMemo

BUSH = [
    "A -> F(0.2)[+(uniform(20, 40))/(uniform(0, 360))A][-(uniform(20, 40))/(uniform(0, 360))A]&(uniform(-10, 10))A",
]
IVY = ["A -> F(0.05)[+(uniform(40, 80))A]A : 0.1", "A -> F(0.05)+(uniform(-20, 20))A : 0.9"]


def _box(tmp_path, name, lo, hi) -> str:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    path = tmp_path / f"{name}.obj"
    m.export(path)
    return str(path)


def _grammar(tmp_path, case: str) -> Grammar:
    """A climber held within 10 cm of a wall (cut past it), a bush pruned by a cube, a hedge clipped to a box
    (each cut bud marked: the string loses modules), and ``?P`` asked behind every apex on the wall."""
    if case == "topiary":
        box = _box(tmp_path, "box", (-0.5, 0.05, -0.5), (0.5, 1.0, 0.5))
        env, axiom, rules, n = {"volume": box, "bud": "B"}, "f(0.1)A", BUSH, 9
    elif case == "obstacle":
        cube = _box(tmp_path, "cube", (-0.6, 1.0, -0.6), (0.6, 1.8, 0.6))
        env, axiom, rules, n = {"obstacle": cube, "mode": "prune", "resolution": 48}, "A", BUSH, 7
    else:
        wall = _box(tmp_path, "wall", (-2, 0, -0.2), (2, 3, 0))
        env, axiom, rules, n = {"support": wall, "distance": 0.1, "climb": 0.3}, "^(90)f(0.05)&(90)A", IVY, 40
        if case == "query":  # an apex stops at 2.5 m: asked by ?P before each step
            rules = [
                "A > ?P(x, y, z) : y < 2.5 -> F(0.05)[+(uniform(40, 80))A?P(0, 0, 0)]A?P(0, 0, 0) : 0.1",
                "A > ?P(x, y, z) : y < 2.5 -> F(0.05)+(uniform(-20, 20))A?P(0, 0, 0) : 0.9",
            ]
            axiom += "?P(0, 0, 0)"
    return Grammar(
        axiom=axiom,
        rules=rules,
        iterations=n,
        seed=4,
        angle=25,
        turtle={"heading": 90},
        environment=env,
        source=str(tmp_path / "plant.toml"),
    )


def _same_arrays(a, b) -> bool:
    """Every array of two skeletons equal, byte for byte."""
    for field in dataclasses.fields(a):
        x, y = getattr(a, field.name), getattr(b, field.name)
        if isinstance(x, np.ndarray) and (x.shape != y.shape or x.tobytes() != y.tobytes()):
            return False
    return True


@pytest.mark.parametrize("case", ["climber", "obstacle", "topiary", "query"])
def test_drawing_with_the_memo_is_drawing_without_it_byte_for_byte(tmp_path, case):
    g = _grammar(tmp_path, case)
    env = load_environment(g)
    scene = env.scene()
    memo = SteeringMemo()
    modules = derive_answering(g, environment=env, steering=memo)
    again = interpret(modules, g, scene=scene)
    recalled = interpret(modules, g, scene=scene, steering=memo)
    assert len(again) > 50
    assert _same_arrays(again, recalled)
    # every segment drawn was steered by the lean passes: the memo holds it, at its module
    steered = memo.recalled(scene)
    assert set(again.module.tolist()) <= set(steered.position.tolist())
    # and the drawing turtle takes it from there: a heading changed in the memo shows in the drawing
    steered.rows[:, 14] += 0.25
    assert not np.array_equal(interpret(modules, g, scene=scene, steering=memo).heading, again.heading)


def test_the_memo_answers_only_the_string_and_scene_it_was_made_for(tmp_path):
    g = _grammar(tmp_path, "climber")
    env = load_environment(g)
    scene = env.scene()
    memo = SteeringMemo()
    derive_answering(g, environment=env, steering=memo)
    # another string: the rows at its modules' places were steered from other states, so none is taken
    other = derive(g.replace(environment={}), 25, 4)
    assert _same_arrays(interpret(other, g, scene=scene, steering=memo), interpret(other, g, scene=scene))
    # another scene: nothing is recalled
    elsewhere = load_environment(g.replace(environment={"support": g.environment["support"]})).scene()
    assert len(memo.recalled(elsewhere).position) == 0
    assert len(memo.recalled(scene).position) > 0


def test_pipeline_draw_gives_the_same_bytes_as_steering_twice(tmp_path):
    from lsys3d.pipeline import GenerateOptions, draw

    g = _grammar(tmp_path, "topiary")
    modules, skeleton = draw(g, g.iterations, g.seed, GenerateOptions())
    env = load_environment(g)
    assert _same_arrays(skeleton, interpret(derive_answering(g, environment=env), g, scene=env.scene()))
    assert str(modules) == str(derive_answering(g, environment=env))


def test_the_turtle_kernel_compiles_its_rare_code_for_one_type(tmp_path):
    """The memo rides in kernel.run's ``rare``: a Steered of empty arrays when there is none, so the rare
    code (a polygon without a scene, a scene without a memo, a scene with one) is one compilation."""
    from numba.core import types

    from lsys3d.turtle import kernel

    g = _grammar(tmp_path, "climber")
    env = load_environment(g)
    scene = env.scene()
    memo = SteeringMemo()
    modules = derive_answering(g, environment=env, steering=memo)
    interpret(modules, g, scene=scene, steering=memo)
    interpret(modules, g, scene=scene)
    polygon = Grammar(axiom="F{.f+f+f+f}F")
    assert len(interpret(polygon.axiom_modules, polygon)) == 2
    rare = {signature[-1] for signature in kernel.run.signatures} - {types.none}
    assert len(rare) == 1
    assert [t.dtype for t in next(iter(rare)).types] == [types.int64, types.int64, types.float64]
