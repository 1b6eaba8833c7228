"""The incremental answers: bit for bit what a turtle over the whole string gives, generation by generation.

The reference is the answer as it was first built: the full turtle (:func:`interpret_answering`, which
draws the skeleton) over the whole string before every step.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lsys3d import Grammar, load_preset
from lsys3d.lsystem import dialects
from lsys3d.lsystem.derive import cut_mask, generations
from lsys3d.lsystem.modules import ModuleString
from lsys3d.turtle.commands import Op, symbol_table
from lsys3d.turtle.environment import load_environment
from lsys3d.turtle.interpret import interpret_answering
from lsys3d.turtle.options import TurtleOptions
from lsys3d.turtle.query import Answerer
from lsys3d.turtle.scene import FAR_OUTSIDE

_SLICES = {"P": (0, 1.0), "H": (3, 1.0), "L": (6, 1.0), "U": (9, 1.0), "R": (6, -1.0)}


def _full_answer(modules, turtle, commands, seed, environment):
    """The first implementation of :func:`lsys3d.turtle.query.answer`: one full turtle pass."""
    scene = environment.scene() if environment is not None else None
    _, found = interpret_answering(modules, turtle.replace(branch_drop=0.0), seed, commands=commands, scene=scene)
    table = symbol_table(modules.alphabet, turtle.draw, turtle.move, turtle.leaf, commands)
    params = modules.params
    if len(found.module):
        params = params.copy()
        codes = modules.symbols[found.module]
        offsets = modules.offsets[found.module]
        arity = modules.arity[found.module].astype(np.int64)
        for code in np.unique(codes).tolist():
            cmd = table.command(code)
            sel = codes == code
            state = found.state[sel]
            if cmd.query == "E":
                if environment is not None:
                    values = environment.probe(state[:, :3])
                else:
                    values = np.tile([0.0, FAR_OUTSIDE, 1.0], (len(state), 1))
                slots = (0, 1, 2)
            else:
                first, sign = _SLICES[cmd.query]
                values = sign * state[:, first : first + 3]
                slots = cmd.world
            for j, slot in enumerate(slots):
                has = arity[sel] > slot
                params[offsets[sel][has] + slot] = values[has, j]
    symbols, arity_all = modules.symbols, modules.arity
    if len(found.cut):
        keep = cut_mask(table.op[symbols] == Op.PUSH, table.op[symbols] == Op.POP, found.cut)
        bud = environment.options.bud if environment is not None else ""
        code = modules.code(bud) if bud else -1
        if code >= 0:
            symbols, arity_all = symbols.copy(), arity_all.copy()
            symbols[found.cut] = code
            keep[found.cut] = True
            drop = np.zeros(len(modules), bool)
            drop[found.cut] = True
            params = params[np.repeat(keep & ~drop, modules.arity.astype(np.int64))]
            arity_all[found.cut] = 0
        else:
            params = params[np.repeat(keep, modules.arity.astype(np.int64))]
        symbols, arity_all = symbols[keep], arity_all[keep]
    return ModuleString(symbols, arity_all, params, modules.alphabet)


def _same_generations(g: Grammar, n: int, environment=None, seed=None):
    """Derive with the incremental answerer and with full passes; every generation must have the same bytes.
    Returns the answerer (to look at what it did) and the last string."""
    seed = g.seed if seed is None else seed
    turtle = TurtleOptions.from_grammar(g)
    commands = dialects.get(g.dialect).commands
    answerer = Answerer(turtle, commands, seed, environment, grammar=g)
    counted = _Counting(answerer)
    ours = list(generations(g, n, seed, between=counted))
    theirs = list(
        generations(g, n, seed, between=lambda ms, step: _full_answer(ms, turtle, commands, seed, environment))
    )
    assert len(ours) == len(theirs)
    for k, (a, b) in enumerate(zip(ours, theirs, strict=True)):
        assert a.symbols.tobytes() == b.symbols.tobytes(), f"generation {k}: symbols differ"
        assert a.arity.tobytes() == b.arity.tobytes(), f"generation {k}: arities differ"
        assert a.params.tobytes() == b.params.tobytes(), f"generation {k}: parameters differ"
    return counted, ours[-1]


class _Counting:
    """An answerer that counts how many of its passes followed the changes."""

    def __init__(self, answerer: Answerer):
        self.answerer = answerer
        self.followed = 0
        self.calls = 0

    def trace(self, *args):
        self.answerer.trace(*args)

    def __call__(self, ms, step):
        self.calls += 1
        self.followed += self.answerer.origin is not None and self.answerer._records is not None
        return self.answerer(ms, step)


def _wall(tmp_path) -> str:
    wall = trimesh.creation.box(extents=(6, 6, 0.2))
    wall.apply_translation((0, 3, -0.1))
    path = tmp_path / "wall.obj"
    wall.export(path)
    return str(path)


def test_the_benchmark_plant_on_a_wall(tmp_path):
    rules = [
        "A(k) > ?P(x, y, z) : y < 4 && k % 8 == 0 -> F(0.05)[+(60)A(k + 1)?P(0,0,0)][-(60)A(k + 1)?P(0,0,0)]",
        "A(k) > ?P(x, y, z) : y < 4 && k % 8 > 0 -> F(0.05)+(uniform(-10, 10))A(k + 1)?P(0,0,0)",
    ]
    env = {"support": _wall(tmp_path), "distance": 0.3, "adhesion": 0.8, "climb": 0.2, "reach": 0.5}
    g = Grammar(
        axiom="^(90)f(0.05)&(90)A(1)?P(0,0,0)",
        rules=rules,
        seed=1,
        turtle={"heading": 90},
        environment=env,
        source=str(tmp_path / "g.toml"),
    )
    counted, out = _same_generations(g, 40, load_environment(g))
    assert counted.followed == counted.calls - 1  # every pass after the first re-read only what changed
    assert out.count("F") > 200


def test_rewritable_modules_left_as_they_are_between_the_changes(tmp_path):
    # B grows at some steps only (by chance) and is copied at the others, its state recorded; the pass that jumps
    # over the copies between one step's changes takes their records (and steerings) from the last pass, and a
    # B rewritten later starts from that record
    rules = [
        "A(k) -> F(0.1)[+(50)B(0)?P(0,0,0)]/(90)A(k + 1)?P(0,0,0)",
        "B(n) : uniform(0, 1) < 0.3 -> F(0.1)-(10)B(n + 1)?H(0,0,0)",
        "?P(x, y, z) : y > 0.6 ->",
    ]
    env = {"support": _wall(tmp_path), "distance": 0.3, "adhesion": 0.6}
    g = Grammar(
        axiom="A(0)?P(0,0,0)",
        rules=rules,
        turtle={"heading": 90},
        environment=env,
        source=str(tmp_path / "g.toml"),
    )
    answerer = Answerer(TurtleOptions.from_grammar(g), dialects.get(g.dialect).commands, g.seed, None, grammar=g)
    jumped, lost = [], []
    original = answerer._pass

    def listing(*args):
        jumped.append(len(args[-1]) > 0)  # the changes the pass jumps between (empty: it walks the copies)
        found = original(*args)
        lost.append(found is None)  # it lost track of the changes: a pass over the whole string follows
        return found

    answerer._pass = listing
    last = list(generations(g, 12, g.seed, between=answerer))[-1]
    assert sum(jumped) >= 10 and not any(lost)
    assert 0 < last.count("?P") < last.count("A") + last.count("B")  # some query modules rewritten away
    counted, out = _same_generations(g, 12, load_environment(g))
    assert counted.followed == counted.calls - 1
    counted, out = _same_generations(g, 12)
    assert counted.followed == counted.calls - 1
    assert out.count("B") > 10


@pytest.mark.parametrize("name", ["ivy-wall", "topiary", "tree-wall", "vine-post"])
def test_the_scene_presets(name):
    g = load_preset(name)
    counted, _ = _same_generations(g, g.iterations, load_environment(g))
    t = TurtleOptions.from_grammar(g)
    if t.angle_jitter or t.length_jitter or t.width_jitter or t.branch_roll:  # tree-wall's natural variation:
        assert counted.followed == 0  # its numbers follow each module's index, so every pass reads it all
    else:
        assert counted.followed > 0


def test_queries_without_an_environment_and_a_side_branch_that_ends():
    # L -> [...] leaves the state as it was: the turtle stops after it (the copies that follow are known)
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=[
            "A > ?P(x, y, z) : y < 2 -> F(0.1)L[+(40)B?H(0,0,0)]/(137)A",
            "B -> F(0.1)-(5)B",
            "L -> [&(60)F(0.05)~(0.1)]",
        ],
        turtle={"heading": 90},
    )
    counted, out = _same_generations(g, 24)
    assert counted.followed == counted.calls - 1
    assert out.count("?H") > 5


def test_erased_and_rewritten_turns():
    # rules that rewrite turtle commands (a '+' becomes '-', X is erased) and a cut symbol
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=[
            "A > ?P(x, y, z) -> F(0.2)+(10)X(0)[-(30)F(0.1)%F]A",
            "+(a) : a > 5 -> -(a / 2)",
            "X(n) : n > 1 ->",
            "X(n) -> X(n + 1)",
        ],
        turtle={"heading": 90},
    )
    _same_generations(g, 12)


def test_polygons_in_successors():
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=["A -> F(0.2)[{.+(30)f(0.1).-(60)f(0.1).}]&(10)A?U(0,0,0)"],
        turtle={"heading": 90},
    )
    counted, _ = _same_generations(g, 10)
    assert counted.followed == counted.calls - 1


def test_natural_variation_reads_the_whole_string():
    g = Grammar(axiom="A?P(0,0,0)", rules=["A -> F(0.2)[+A?P(0,0,0)]A"], turtle={"heading": 90, "angle_jitter": 10})
    counted, _ = _same_generations(g, 7)
    assert counted.followed == 0


def test_decomposition_and_tropism():
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=["A -> I(0)[+(30)A?H(0,0,0)]I(0)A", "I(n) -> I(n + 1)"],
        decomposition=["I(n) : n > 0 -> F(0.1)/(20)J(n)", "J(n) -> F(0.05)"],
        turtle={"heading": 90, "tropism": [0, -1, 0], "elasticity": 0.1},
    )
    counted, out = _same_generations(g, 8)
    assert counted.followed == counted.calls - 1
    assert out.count("F") > 10


_ALPHABET = ["F", "f", "+", "-", "&", "^", "/", "!", "A", "B", "?P(0,0,0)", "L", "~(0.1)"]


@st.composite
def _successor(draw):
    out, depth = [], 0
    for _ in range(draw(st.integers(0, 9))):
        c = draw(st.sampled_from([*_ALPHABET, "[", "]"]))
        if c == "]" and depth == 0:
            continue
        depth += (c == "[") - (c == "]")
        out.append(c)
    return "".join(out) + "]" * depth


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    a=_successor(),
    b=_successor(),
    l_rule=_successor(),
    wall=st.booleans(),
    seed=st.integers(0, 3),
)
def test_random_grammars(tmp_path_factory, a, b, l_rule, wall, seed):
    rules = [f"A > ?P(x, y, z) : y < 1.5 -> F{a}A", f"A -> {b}", f"B -> {l_rule}B", "L -> [+F]"]
    env = {}
    if wall:
        env = {"support": _wall(tmp_path_factory.mktemp("w")), "distance": 0.3, "adhesion": 0.5}
    source = env["support"].rsplit("/", 1)[0] + "/g.toml" if wall else "random.toml"
    turtle = {"heading": 90, "step": 0.2}
    g = Grammar(axiom="A?P(0,0,0)B", rules=rules, angle=25, seed=seed, turtle=turtle, environment=env, source=source)
    _same_generations(g, 6, load_environment(g))


def test_cpfg_sub_lsystem_scales_and_queries():
    # ?(2, 0.5) halves the lengths up to its $: the drawing turtle answers such strings (it follows the scale)
    text = (
        "Lsystem: 1\nderivation length: 3\nAxiom: A?P(0,0,0)\nA --> F?(2,0.5)F$A\nendlsystem\nLsystem: 2\nendlsystem\n"
    )
    g = Grammar.from_text(text, source="plant.l")
    _, out = _same_generations(g, 3)
    y = [out.module(i)[1][1] for i in range(len(out)) if out.symbol(i) == "?P"]
    assert y == pytest.approx([4.5])  # three steps of 1 + 0.5


@pytest.mark.parametrize(
    "turtle",
    [
        {"tropism": [0.3, -1, 0.2], "elasticity": 0.1, "elasticity_increment": 0.2, "bend": "cpfg"},
        {"tropism": [0.3, -1, 0.2], "elasticity": 0.1},
    ],
)
def test_cpfg_elasticity_increments_cylinders_and_queries(turtle):
    # '_' steps the elasticity, @Gs/@Gc draw a cylinder and bend = "cpfg" bends after each move: the lean
    # pass does not follow them, so the drawing turtle answers (and the answers are what it gives)
    g = Grammar(
        axiom="A?P(0,0,0)",
        rules=["A -> F_@Gs+F@Gc(2)&F@Ge(2)A"],
        turtle=turtle,
        angle=20,
        dialect="cpfg",
    )
    _, out = _same_generations(g, 4)
    y = [out.module(i)[1][1] for i in range(len(out)) if out.symbol(i) == "?P"]
    assert len(y) == 1 and 0 < y[0] < 12


def test_counted_ops_are_a_survey_of_each_string(monkeypatch):
    """When the rules write no op the survey must see, the answerer counts derivation's changes instead of
    surveying every string: its counts are the survey's, and its bracket depth at least the survey's."""
    from lsys3d.turtle import kernel
    from lsys3d.turtle import query as query_module
    from lsys3d.turtle.interpret import kernel_program, surveyed

    g = Grammar(
        axiom="A(1)?P(0,0,0)",
        rules=[
            "A(k) > ?P(x, y, z) : y < 3 && k % 4 == 0 -> F(0.2)[+(40)A(k+1)?P(0,0,0)][-[&(30)A(k+1)]]/A(k+1)?P(0,0,0)",
            "A(k) > ?P(x, y, z) : y < 3 && k % 4 > 0 -> F(0.2)+(uniform(-10, 10))A(k + 1)?P(0,0,0)",
        ],
        turtle={"heading": 90},
    )
    checked = []
    call = query_module.Answerer.__call__

    def checking(self, modules, step=0):
        if self._counts is not None and self.origin is not None:
            table = self._compiled(modules.alphabet)[0]
            arrays = kernel.Modules(modules.symbols, modules.arity, modules.offsets, modules.params)
            counts, depth = surveyed(modules, table, kernel_program(table), arrays, 10**9)
            assert np.array_equal(counts, self._counts) and depth <= self._depth
            checked.append(step)
        return call(self, modules, step)

    monkeypatch.setattr(query_module.Answerer, "__call__", checking)
    query_module.derive_answering(g, 12, seed=3)
    assert len(checked) == 12
