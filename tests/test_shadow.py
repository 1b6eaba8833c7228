"""The plant's own shade: ?E's light through a crown sampled on a voxel grid (``[environment] shadow``)."""

from __future__ import annotations

import numpy as np
import pytest

from lsys3d import Grammar
from lsys3d.errors import LimitError
from lsys3d.turtle.environment import EnvironmentOptions, load_environment
from lsys3d.turtle.query import derive_answering
from lsys3d.turtle.shadow import shade

# everything half a voxel off the grid's planes (the voxels lie on multiples of their size): z = -0.05
START = "&(90)f(0.05)^(90)"
LAYER = "[f(1.05)+(90)f(0.05)" + "~(0.2)f(0.1)" * 10 + "]"  # ten leaves in a row 1.05 m up, along -x
BELOW = "[f(0.55)+(90)f(0.45)?E(0,0,0)]"
ABOVE = "[f(1.55)+(90)f(0.45)?E(0,0,0)]"
ASIDE = "[f(0.55)-(90)f(2.05)?E(0,0,0)]"


def _light(out) -> list[float]:
    return [out.module(i)[1][2] for i in range(len(out)) if out.symbol(i) == "?E"]


def _answer(environment: dict):
    g = Grammar(axiom=START + LAYER + BELOW + ABOVE + ASIDE, turtle={"heading": 90}, environment=environment)
    return derive_answering(g, 0, environment=load_environment(g))


def test_a_module_under_a_dense_layer_gets_less_light_than_one_above_it():
    below, above, aside = _light(_answer({"shadow": True, "shadow_voxel": 0.1}))
    # each leaf of 0.2 x 0.2 m fills a voxel of 0.1 m: optical depth 0.5 * 0.04 / 0.01 = 2 in the layer
    assert below == pytest.approx(np.exp(-2.0))
    assert above == 1.0 and aside == 1.0
    # off (the default): full light everywhere
    assert _light(_answer({})) == [1.0, 1.0, 1.0]


def test_the_light_follows_its_direction():
    # light from the side (+x): the layer no longer stands between the module below it and the light
    out = _answer({"shadow": True, "shadow_voxel": 0.1, "light": [1, 0, 0]})
    below, above, aside = _light(out)
    assert below == 1.0 and above == 1.0 and aside == 1.0
    # from -x the row of leaves at y = 1 shades nothing at y = 0.5 either; a module in the row's line does
    g = Grammar(axiom=START + LAYER + "[f(1.05)-(90)f(0.55)?E(0,0,0)]", turtle={"heading": 90},
                environment={"shadow": True, "shadow_voxel": 0.1, "light": [-1, 0, 0]})  # fmt: skip
    (lit,) = _light(derive_answering(g, 0, environment=load_environment(g)))
    assert lit == pytest.approx(np.exp(-20.0), rel=1e-6)  # ten voxels of depth 2


CROWN = Grammar(
    axiom="A?E(0,0,0)",
    rules=[
        # an apex in the light branches; a shaded one rests (as buds do in the self-organising tree models)
        "A > ?E(b, d, l) : l > 0.3 -> F(0.2)[+(40)/(uniform(0, 360))~(0.3)A?E(0,0,0)][-(40)~(0.3)A?E(0,0,0)]A",
    ],
    seed=4,
    turtle={"heading": 90},
    environment={"shadow": True, "shadow_voxel": 0.15},
)


def test_a_shaded_crown_grows_less_and_the_same_every_time():
    shaded = derive_answering(CROWN, 7, environment=load_environment(CROWN))
    again = derive_answering(CROWN, 7, environment=load_environment(CROWN))
    assert shaded == again and shaded.params.tobytes() == again.params.tobytes()
    lit = CROWN.replace(environment={})
    full = derive_answering(lit, 7)
    assert shaded.count("F") < full.count("F")
    assert min(_light(shaded)) < 0.3  # some apices rest in the shade


def test_shade_refuses_a_grid_too_large():
    o = EnvironmentOptions(shadow=True, shadow_voxel=0.001)
    far = np.array([[0.0, 0.0, 0.0, 1.0], [10.0, 10.0, 10.0, 1.0]])
    with pytest.raises(LimitError, match="shadow_voxel"):
        shade(far, np.zeros((1, 3)), o)
