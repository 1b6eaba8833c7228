"""The expression language's additions for the dialects: modulo, Python's and ABOP's spelling, degrees,
the grammar's own functions and the seeded random functions."""

from __future__ import annotations

import numpy as np
import pytest

from lsys3d.lsystem.expr import EvalError, ExprSyntaxError, Function, Syntax, parse_expression
from lsys3d.streams import Stream, hashed_uniform

PY = Syntax(python=True)


class Draws:
    """Random numbers keyed like the derivation's: by the place of the call and each element's position."""

    def __init__(self, index, seed=0):
        self.index = np.asarray(index)
        self.seed = seed

    def draw(self, site, k):
        return hashed_uniform(self.seed, Stream.GRAMMAR_RANDOM, (site, k), self.index)

    def subset(self, index):
        return Draws(self.index[index], self.seed)


@pytest.mark.parametrize(
    ("text", "syntax", "expected"),
    [
        ("7 % 3", Syntax(), 1),
        ("-7 % 3", Syntax(), 2),  # the sign of the divisor, as Python and numpy
        ("7 // 2", PY, 3),
        ("True + True", PY, 2),
        ("1 if False else 2", PY, 2),
        ("0 < 1 < 2", PY, 1),
        ("0 < 3 < 2", PY, 0),
        ("math.sqrt(16) + math.pi - pi", PY, 4),
        ("2 = 2", Syntax(equals=True), 1),
        ("sin(90) + cos(180) + atan2(1, 1)", Syntax(degrees=True), 45),
        ("int(-2.5) + round(2.4) + sign(-3) + pow(2, 3) + trunc(1.9)", Syntax(), 8),
    ],
)
def test_dialect_spellings(text, syntax, expected):
    assert parse_expression(text, syntax=syntax).evaluate({})[0] == pytest.approx(expected)


@pytest.mark.parametrize(
    ("text", "syntax", "message"),
    [
        ("x = 1", Syntax(), "write '==' to compare"),
        ("1 if x else 2", Syntax(), "unexpected 'if'"),
        ("7 // 2", Syntax(), "unexpected '//'"),
        ("True", Syntax(), "unknown name 'True'"),
        ("os.system(1)", PY, "attribute access"),
        ("math.system(1)", PY, "unknown function 'system'"),
        ("0 < 1 < 2 < 3", PY, "more than two comparisons"),
        ("uniform(1)", Syntax(), "takes 2 argument"),
        ("getIterationNb()", Syntax(), "unknown function 'getIterationNb'"),  # L-Py's name: Python spelling only
        ("getIterationNb(1)", PY, "expected '\\)'"),
    ],
)
def test_what_each_spelling_refuses(text, syntax, message):
    with pytest.raises(ExprSyntaxError, match=message):
        parse_expression(text, names=["x"], syntax=syntax)


def test_the_derivation_step_is_read_from_the_evaluations_env():
    from lsys3d.lsystem.expr import STEP

    e = parse_expression("2 + getIterationNb()", syntax=PY)
    assert e.evaluate({STEP: 3.0}, 2).tolist() == [5.0, 5.0]
    assert e.evaluate({}).tolist() == [2.0]  # no step known (the axiom): 0, as L-Py before its first step


def test_the_untaken_branch_of_a_conditional_is_not_evaluated():
    e = parse_expression("1 / x if x != 0 else 0", names=["x"], syntax=PY)
    assert e.evaluate({"x": np.array([0.0, 2.0, 4.0])}, size=3).tolist() == [0.0, 0.5, 0.25]
    with pytest.raises(EvalError) as info:  # an error in a branch names the element, as a flat expression does
        parse_expression("1 / (x - 2) if x > 0 else 0", names=["x"], syntax=PY).evaluate(
            {"x": np.array([0.0, 1.0, 2.0])}, size=3
        )
    assert info.value.index.tolist() == [2]


def test_a_grammar_function_is_evaluated_with_its_arguments():
    double = Function("double", ("v",), parse_expression("2 * v", names=["v"]))
    e = parse_expression("double(x) + double(1)", names=["x"], functions={"double": double})
    assert e.evaluate({"x": np.array([1.0, 3.0])}, size=2).tolist() == [4.0, 8.0]
    with pytest.raises(ExprSyntaxError, match="takes 1 argument"):
        parse_expression("double(1, 2)", functions={"double": double})


def test_random_functions_are_keyed_by_place_and_position():
    e = parse_expression("uniform(10, 20) + 0 * ran(1)", site=100)
    a = e.evaluate({}, 4, random=Draws(np.arange(4)))
    assert ((a >= 10) & (a < 20)).all() and len(set(a.tolist())) == 4
    # the same positions in another order, or a subset, draw the same numbers
    assert e.evaluate({}, 2, random=Draws([3, 1])).tolist() == [a[3], a[1]]
    # another place in the grammar draws other numbers; another seed too
    other = parse_expression("uniform(10, 20)", site=200)
    assert other.evaluate({}, 4, random=Draws(np.arange(4))).tolist() != a.tolist()
    assert e.evaluate({}, 4, random=Draws(np.arange(4), seed=1)).tolist() != a.tolist()
    assert e.random and not parse_expression("1 + x", names=["x"]).random


def test_normal_draws_have_the_asked_mean_and_spread():
    z = parse_expression("normal(5, 2)").evaluate({}, 20000, random=Draws(np.arange(20000)))
    assert abs(z.mean() - 5) < 0.1 and abs(z.std() - 2) < 0.1


def test_random_functions_need_a_source():
    with pytest.raises(EvalError, match="random function cannot be evaluated here"):
        parse_expression("ran(1)").evaluate({})
