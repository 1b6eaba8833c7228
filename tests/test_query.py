"""Query modules: the turtle's position and frame handed back to the grammar between derivation steps."""

from __future__ import annotations

import numpy as np
import pytest

from lsys3d import Grammar, derive
from lsys3d.lsystem import dialects
from lsys3d.turtle.commands import COMMANDS
from lsys3d.turtle.interpret import interpret
from lsys3d.turtle.options import TurtleOptions
from lsys3d.turtle.query import answer, asks_turtle, derive_answering


def _params(ms, symbol):
    return [ms.module(i)[1] for i in range(len(ms)) if ms.symbol(i) == symbol]


def test_a_turn_after_three_steps_puts_the_query_where_hand_computed():
    # heading 90: H = (0, 1, 0), L = (-1, 0, 0), U = (0, 0, 1); '+' turns H toward L
    g = Grammar(axiom="FFF+(90)?P(0,0,0)?H(0,0,0)?L(0,0,0)?U(0,0,0)F?P(0,0,0)", turtle={"heading": 90})
    out = answer(g.axiom_modules, TurtleOptions.from_grammar(g), COMMANDS, 0)
    (p0, p1), (h,), (l,), (u,) = _params(out, "?P"), _params(out, "?H"), _params(out, "?L"), _params(out, "?U")
    assert p0 == pytest.approx((0.0, 3.0, 0.0))
    assert h == pytest.approx((-1.0, 0.0, 0.0))
    assert l == pytest.approx((0.0, -1.0, 0.0))
    assert u == pytest.approx((0.0, 0.0, 1.0))
    assert p1 == pytest.approx((-1.0, 3.0, 0.0))


def test_queries_inside_branches_and_with_fewer_parameters():
    g = Grammar(axiom="F[+(90)F?P(0,0)]F?P(0)", turtle={"heading": 90})
    out = answer(g.axiom_modules, TurtleOptions.from_grammar(g), COMMANDS, 0)
    assert _params(out, "?P") == [pytest.approx((-1.0, 1.0)), pytest.approx((0.0,))]


def test_rules_condition_on_the_position_stop_above_a_height():
    # the apex grows one step a generation until its query says it is at 3 or above
    g = Grammar(axiom="A?P(0,0,0)", rules=["A > ?P(x, y, z) : y < 3 -> FA"], turtle={"heading": 90})
    assert asks_turtle(g, COMMANDS)
    out = derive_answering(g, 10)
    assert out.count("F") == 3
    assert _params(out, "?P") == [pytest.approx((0.0, 3.0, 0.0))]
    # without the turtle the query stays at the origin and the apex never stops
    assert derive(g, 10).count("F") == 10


def test_grow_toward_a_point():
    # each step turns the apex by the angle between its heading and the target (2D, in the x-y plane)
    g = Grammar(
        axiom="A?P(0,0,0)?H(0,0,0)",
        rules=[
            "A > ?P(x, y, z) ?H(hx, hy, hz) -> "
            "+(atan2(hx * (3 - y) - hy * (2 - x), hx * (2 - x) + hy * (3 - y)) * 180 / pi)F(0.25)A"
        ],
        turtle={"heading": 0},
    )
    out = derive_answering(g, 20)
    (p,) = _params(out, "?P")
    # the apex reaches the target (2, 3) and circles close to it
    assert np.hypot(p[0] - 2, p[1] - 3) < 0.5


def test_every_step_sees_the_string_of_that_step():
    """L-Py fills the queries before each step: the axiom's query is filled before the first one."""
    g = Grammar(axiom="FF?P(0,0,0)", rules=["?P(x, y, z) -> ?P(x, y, z)F(y)"], turtle={"heading": 90})
    out = derive_answering(g, 1)
    assert [m for m in str(out).split("?P") if m] == ["FF", "(0,2,0)F(2)"]


def test_lpy_query_modules_read_and_come_back_in_plantgl_axes():
    text = "Axiom: FF?P(0,0,0)GetHead(0,0,0)\nderivation length: 0\n"
    g = Grammar.from_text(text, source="tree.lpy")
    out = derive_answering(g)
    # PlantGL's world has Z up: two steps up are z = 2; the heading is (0, 0, 1)
    assert _params(out, "?P") == [pytest.approx((0.0, 0.0, 2.0 * TurtleOptions.from_grammar(g).step))]
    assert _params(out, "GetHead") == [pytest.approx((0.0, 0.0, 1.0))]


def test_lpy_open_lsystem_bounded_by_an_ellipse():
    """The shape of L-Py's own example (share/training/17-open-lsystem-simple-growth.lpy): growth stops
    where the tips leave an ellipse, written as a query module's rule."""
    text = (
        "Axiom: A\nderivation length: 24\nproduction:\n\n"
        "A :\n\tproduce [+(60)B][-(60)B]F?P(0,0,0)A\n\n"
        "B :\n\tproduce F?P(0,0,0)@O(0.2)B\n\n"
        "?P(x,y,z) :\n    if 4*y*y +(z-10)**2 > 100:\n        produce [+(2*z)F][-(2*z)F]%\n"
        "    else:\n        produce *\n"
    )
    g = Grammar.from_text(text, source="open.lpy")
    out = derive_answering(g)
    sk = interpret(out, g, commands=dialects.get("lpy").commands)
    ends = sk.end[sk.order == 0]  # the main axis: lsys3d's y is PlantGL's z
    # the axis stops at its 21st F: the query after it, at z = 21, is the first with (z - 10)^2 > 100, and
    # its rule's % cuts the apex that follows
    assert ends[:, 1].max() == pytest.approx(21.0)
    # every apex that stopped was outside the ellipse by less than one step
    e = sk.end
    assert (4 * e[:, 0] ** 2 + (e[:, 1] - 10) ** 2).max() < 4 * 7**2 + 12**2


def test_cpfg_reads_query_and_environment_modules():
    text = "Lsystem: 1\nderivation length: 1\nAxiom: F?P(0,0,0)?E(1,1,1)\nendlsystem\n"
    g = Grammar.from_text(text, source="plant.l")
    out = derive_answering(g)
    assert _params(out, "?P") == [pytest.approx((0.0, 1.0, 0.0))]
    b, d, light = _params(out, "?E")[0]
    assert b == 0 and d > 1e6 and light == 1  # no environment: nothing blocks, nothing near, full light


def test_queries_are_deterministic_and_respect_limits():
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=["A > ?P(x, y, z) : y < 4 -> F(uniform(0.5, 1))[+(uniform(10, 50))A?P(0,0,0)]A"],
        turtle={"heading": 90},
    )
    a, b = derive_answering(g, 8, seed=5), derive_answering(g, 8, seed=5)
    assert str(a) == str(b)
    from lsys3d.errors import LimitError

    with pytest.raises(LimitError):
        derive_answering(g, 8, seed=5, max_segments=3)


@pytest.mark.parametrize("name", ["lsys3d", "lpy", "cpfg"])
def test_dialects_declare_their_query_modules(name):
    symbols = {c.symbol for c in dialects.get(name).commands if c.query}
    assert {"?P", "?H", "?L", "?U"} <= symbols
    if name == "lpy":
        assert {"?R", "GetPos", "GetRight"} <= symbols
    if name == "cpfg":
        assert "?E" in symbols
