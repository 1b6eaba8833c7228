"""The turtle kernel's two compilations: without the rare ops (``rare`` None) and with them."""

from __future__ import annotations

import ast
import inspect
import textwrap

import numpy as np
import pytest

from lsys3d import derive, load_preset
from lsys3d.turtle import Op, TurtleOptions, interpret, kernel
from lsys3d.turtle.interpret import NO_SCENE
from lsys3d.turtle.kernel import rare_flag

IGNORED = {Op.NONE, Op.SIDES}  # the kernel skips these (sides are read after its pass)


def _branches(chain: ast.If):
    """The ``if`` and its ``elif``s of a chain, in order."""
    tests = []
    while True:
        tests.append(chain)
        if len(chain.orelse) == 1 and isinstance(chain.orelse[0], ast.If):
            chain = chain.orelse[0]
        else:
            return tests


def _ops_named(node: ast.AST) -> set[Op]:
    names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
    return {op for op in Op if f"_{op.name}" in names}


def _op_chain():
    source = textwrap.dedent(inspect.getsource(kernel.run.py_func))
    loop = next(n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.For) and ast.unparse(n.target) == "i")
    return next(n for n in loop.body if isinstance(n, ast.If) and "_FORWARD" in ast.unparse(n.test))


def test_the_rare_branch_draws_exactly_the_rare_ops():
    """The ops the kernel draws only with ``rare`` are RARE_OPS, and every other op has a branch of its own."""
    tests = _branches(_op_chain())
    rare = [t for t in tests if ast.unparse(t.test) == "rare is not None"]
    assert len(rare) == 1
    common = set().union(*(_ops_named(t.test) for t in tests if t is not rare[0]))
    inside = set().union(*(_ops_named(t.test) for t in _branches(rare[0].body[0])))
    assert inside == set(kernel.RARE_OPS)
    assert not common & inside
    assert common | inside | IGNORED == set(Op)


def test_rare_flag():
    config = kernel.Config(*([0.0] * 19), np.zeros((0, 8)))
    counts = np.zeros(len(Op), np.int64)
    counts[[Op.FORWARD, Op.ROTATE, Op.PUSH, Op.POP, Op.LEAF, Op.WIDTH]] = 5
    assert kernel.rare_flag(counts, config, None) is None
    for op in kernel.RARE_OPS:
        one = counts.copy()
        one[op] = 1
        assert kernel.rare_flag(one, config, None) is True
    assert kernel.rare_flag(counts, config._replace(movements=np.zeros((1, 8))), None) is True
    assert kernel.rare_flag(counts, config, NO_SCENE) is True


@pytest.mark.parametrize("name", ["oak", "abop-1.24f"])
def test_without_the_rare_ops_the_kernel_draws_the_same(name, monkeypatch):
    """The kernel compiled without the rare ops draws what the one with them draws, array for array."""
    grammar = load_preset(name)
    modules = derive(grammar, min(grammar.iterations, 4), grammar.seed)
    options = TurtleOptions.from_grammar(grammar)
    flags = []
    monkeypatch.setattr(kernel, "rare_flag", lambda *args: flags.append(rare_flag(*args)) or flags[-1])
    plain = interpret(modules, options, grammar.seed)
    assert flags == [None]  # these strings need none of the rare ops
    monkeypatch.setattr(kernel, "rare_flag", lambda *args: True)
    full = interpret(modules, options, grammar.seed)
    arrays = [k for k, v in vars(plain).items() if isinstance(v, np.ndarray)]
    assert {"start", "end", "parent", "order", "leaf_position"} <= set(arrays)
    for field in arrays:
        assert np.array_equal(getattr(plain, field), getattr(full, field)), field
