"""The 3D turtle: commands, known figures, errors, jitter, invariants."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lsys3d import Grammar, GrammarError, InterpretError, ModuleString, derive, load_preset
from lsys3d.errors import OptionsError
from lsys3d.lsystem.modules import ASCII_ALPHABET
from lsys3d.stats import skeleton_stats
from lsys3d.turtle import (
    COMMANDS,
    Axis,
    Op,
    TurtleOptions,
    commands_markdown,
    interpret,
    options_markdown,
    symbol_table,
)

ROOT = Path(__file__).resolve().parents[1]


def draw(axiom: str, angle: float = 90.0, seed: int = 0, **turtle):
    grammar = Grammar(axiom=axiom, angle=angle, seed=seed, turtle=turtle)
    return interpret(grammar.axiom_modules, grammar)


def grow(name: str, n: int | None = None, **overrides):
    grammar = load_preset(name)
    modules = derive(grammar, n)
    return modules, interpret(modules, TurtleOptions.from_grammar(grammar, **overrides))


def assert_orthonormal(sk):
    for frame in (sk.heading, sk.left, sk.up):
        np.testing.assert_allclose(np.linalg.norm(frame, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", sk.heading, sk.left), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.cross(sk.heading, sk.left), sk.up, atol=1e-9)


H0, L0, U0 = np.array([0.0, 1.0, 0.0]), np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


# ------------------------------------------------------------------ single commands
def test_initial_frame_and_forward():
    sk = draw("F")
    assert len(sk) == 1
    np.testing.assert_array_equal(sk.start[0], 0.0)
    np.testing.assert_allclose(sk.end[0], H0, atol=1e-15)
    np.testing.assert_allclose([sk.heading[0], sk.left[0], sk.up[0]], [H0, L0, U0], atol=1e-15)
    assert sk.parent.tolist() == [-1] and sk.order.tolist() == [0] and sk.module.tolist() == [0]
    sk.validate()


@pytest.mark.parametrize("heading", [0, 30, 85, 90, 200])
def test_heading_setting(heading):
    a = math.radians(heading)
    sk = draw("F(2)", heading=heading)
    np.testing.assert_allclose(sk.end[0], [2 * math.cos(a), 2 * math.sin(a), 0], atol=1e-12)
    np.testing.assert_allclose(sk.left[0], [-math.sin(a), math.cos(a), 0], atol=1e-12)


@pytest.mark.parametrize("deg", [30, 90, 137.5])
@pytest.mark.parametrize(
    ("text", "axis_from", "toward", "field"),
    [
        ("+", H0, L0, "heading"),  # turn left: H toward L
        ("-", H0, -L0, "heading"),
        ("&", H0, -U0, "heading"),  # pitch down: H toward -U
        ("^", H0, U0, "heading"),
        ("/", L0, U0, "left"),  # roll right: L toward U
        ("\\", L0, -U0, "left"),
    ],
)
def test_rotations(deg, text, axis_from, toward, field):
    a = math.radians(deg)
    expected = math.cos(a) * axis_from + math.sin(a) * toward
    by_param = draw(f"{text}({deg})F")
    by_angle = draw(f"{text}F", angle=deg)
    for sk in (by_param, by_angle):
        np.testing.assert_allclose(getattr(sk, field)[0], expected, atol=1e-12)
        assert_orthonormal(sk)


def test_rotation_keeps_its_axis():
    sk = draw("+(40)F")
    np.testing.assert_allclose(sk.up[0], U0, atol=1e-15)
    sk = draw("&(40)F")
    np.testing.assert_allclose(sk.left[0], L0, atol=1e-15)
    sk = draw("/(40)F")
    np.testing.assert_allclose(sk.heading[0], H0, atol=1e-15)


def test_turn_around():
    sk = draw("|F")
    np.testing.assert_allclose([sk.heading[0], sk.left[0], sk.up[0]], [-H0, -L0, U0], atol=1e-15)
    np.testing.assert_allclose(sk.end[0], -H0, atol=1e-15)


def test_roll_to_horizontal():
    tilted = draw("&(30)+(20)/(40)F")
    rolled = draw("&(30)+(20)/(40)$F")
    np.testing.assert_allclose(rolled.heading, tilted.heading, atol=1e-12)
    assert abs(rolled.left[0, 1]) < 1e-12  # L is horizontal
    assert_orthonormal(rolled)
    # L = V x H / |V x H|
    v_cross_h = np.cross([0, 1, 0], rolled.heading[0])
    np.testing.assert_allclose(rolled.left[0], v_cross_h / np.linalg.norm(v_cross_h), atol=1e-12)


def test_roll_to_horizontal_is_noop_when_vertical():
    a, b = draw("/(30)F"), draw("/(30)$F")
    for name in ("heading", "left", "up", "end"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_full_turn_leaves_frame_unchanged():
    a, b = draw("&(20)F"), draw("&(20)+(360)&(360)/(360)F")
    for name in ("heading", "left", "up", "end"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), atol=1e-12)


def test_brackets_restore_state_exactly():
    a = draw("F&(10)/(20)!(0.3)'(2)\"(0.5)F")
    b = draw("F&(10)/(20)!(0.3)'(2)\"(0.5)[+(33)^(12)F(3)!(0.01)'(7)\"(9)f[-F]$|F]F")
    for name in ("start", "end", "heading", "left", "up", "width_start", "material"):
        np.testing.assert_array_equal(getattr(b, name)[-1], getattr(a, name)[-1])
    assert b.parent[-1] == 0 and b.order[-1] == 0


def test_width_material_step_commands():
    sk = draw("F!F!(0.5)F", width=0.1, width_scale=0.7)
    np.testing.assert_allclose(sk.width_start, [0.1, 0.07, 0.5])
    sk = draw("F'F'(5)F'F")
    assert sk.material.tolist() == [0, 1, 5, 6]
    sk = draw('F"F"(2)F F(4)', length_scale=0.9)
    np.testing.assert_allclose(sk.lengths(), [1, 0.9, 1.8, 4])
    sk = draw("FF", step=0.25)
    np.testing.assert_allclose(sk.end[-1], 0.5 * H0, atol=1e-15)


def test_width_taper_along_chain():
    sk = draw("!(0.4)F!(0.3)F[+F!(0.05)]!(0.2)F!(0.1)")
    np.testing.assert_allclose(sk.width_start, [0.4, 0.3, 0.3, 0.2])
    # trunk 0 -> 1 -> 3 is one chain; the branch tapers to the width set at its end
    np.testing.assert_allclose(sk.width_end, [0.3, 0.2, 0.05, 0.1])


@pytest.mark.parametrize("name", ["monopodial", "ternary", "bush"])
def test_width_continuous_along_chains(name):
    _, sk = grow(name)
    ch = sk.chains
    for c in range(len(ch)):
        segs = ch.segments[ch.offsets[c] : ch.offsets[c + 1]]
        np.testing.assert_array_equal(sk.width_end[segs[:-1]], sk.width_start[segs[1:]])


def test_move_breaks_connection_but_keeps_order():
    sk = draw("FfF")
    assert sk.parent.tolist() == [-1, -1]
    sk = draw("F[+fF]F")
    assert sk.parent.tolist() == [-1, -1, 0]
    assert sk.order.tolist() == [0, 1, 0]
    np.testing.assert_allclose(sk.start[1], H0 + L0, atol=1e-15)


def test_parent_and_order():
    sk = draw("F[+F[-F]F]F[[F]]")
    assert sk.parent.tolist() == [-1, 0, 1, 1, 0, 4]
    assert sk.order.tolist() == [0, 1, 2, 1, 0, 2]
    assert draw("[F][F]").order.tolist() == [0, 0]


def test_inert_symbols_and_custom_draw_move():
    assert len(draw("XAFYB")) == 1
    sk = draw("LfRMG", draw="LR", move="fM")
    assert len(sk) == 2 and sk.parent.tolist() == [-1, -1]
    np.testing.assert_allclose(sk.end[-1], 3 * H0, atol=1e-15)
    assert len(draw("FfG", draw="G")) == 1


def test_tropism_bends_toward_t():
    e = 0.2
    sk = draw("FFFFFFFFFFFF", heading=0, tropism=[0, -1, 0], elasticity=e)
    # the first move already turns by e * |H x T| = e
    np.testing.assert_allclose(sk.heading[0], [math.cos(e), -math.sin(e), 0], atol=1e-12)
    assert np.all(np.diff(sk.heading[:, 1]) < 0)  # H keeps bending down
    assert sk.heading[-1, 1] > -1  # but never past T
    assert_orthonormal(sk)


def test_tropism_tree_sags():
    _, straight = grow("ternary", elasticity=0.0)
    _, bent = grow("ternary")
    assert len(straight) == len(bent)
    assert bent.end[:, 1].mean() < straight.end[:, 1].mean()
    assert bent.heading[:, 1].mean() < straight.heading[:, 1].mean()


def test_leaf_instances():
    sk = draw('F+~"(0.5)~~(0.3)')
    assert sk.n_leaves == 3 and sk.n_polygons == 0
    np.testing.assert_allclose(sk.leaf_position, [H0] * 3, atol=1e-15)
    np.testing.assert_allclose(sk.leaf_heading, [L0] * 3, atol=1e-15)
    np.testing.assert_allclose(sk.leaf_up, [U0] * 3, atol=1e-15)
    np.testing.assert_allclose(sk.leaf_size, [1, 0.5, 0.3])
    assert draw("FL", leaf="L").n_leaves == 1


def test_polygons():
    sk = draw("F{.f+f+f+f}F")
    assert len(sk) == 2 and sk.parent.tolist() == [-1, -1]
    assert sk.n_polygons == 1
    pts = sk.polygon_points[sk.polygon_offsets[0] : sk.polygon_offsets[1]]
    np.testing.assert_allclose(pts, [H0, 2 * H0, 2 * H0 + L0, H0 + L0], atol=1e-12)
    # drawing symbols inside a polygon draw no segment; repeated vertices are skipped
    sk = draw("['(3){.F.+F.+F.}]F")
    assert len(sk) == 1 and sk.parent.tolist() == [-1]
    assert np.diff(sk.polygon_offsets).tolist() == [4] and sk.polygon_material.tolist() == [3]


def test_nested_polygons_close_each_as_its_own_polygon():
    """A polygon stack (Lparser's and cpfg's): '{' inside a polygon starts another; '}' closes the innermost."""
    sk = draw("{.f+.'(2){.f+.f+.f}f+.}")
    assert sk.n_polygons == 2 and sk.polygon_offsets.tolist() == [0, 4, 7]
    inner = sk.polygon_points[0:4]
    np.testing.assert_allclose(inner, [H0, H0 + L0, L0, [0, 0, 0]], atol=1e-12)
    outer = sk.polygon_points[4:7]  # its vertices before and after the inner polygon, in order
    np.testing.assert_allclose(outer, [[0, 0, 0], H0, -L0], atol=1e-12)
    assert sk.polygon_material.tolist() == [2, 0]  # each keeps the material it was opened with
    # three levels: the innermost has two vertices and the outermost walks back to its start (two
    # again): both are dropped, and the middle one keeps its vertices from before and after the innermost
    sk = draw("{.f+.{.f+.{.f.}f+.f}+f.}")
    assert sk.n_polygons == 1 and sk.polygon_offsets.tolist() == [0, 4]
    np.testing.assert_allclose(sk.polygon_points, [H0, H0 + L0, L0 - H0, -H0], atol=1e-12)


def test_bush_polygons():
    modules, sk = grow("bush", 4)
    assert sk.n_polygons == modules.count("{")
    assert np.all(np.diff(sk.polygon_offsets) == 6)
    assert len(sk) == modules.count("F")


# ------------------------------------------------------------------ known figures
def test_koch_island_closes():
    for n in (1, 2, 3):
        _, sk = grow("koch-island", n)
        assert len(sk) == 4 * 8**n
        np.testing.assert_allclose(sk.end[-1], sk.start[0], atol=1e-9)
        assert np.all(sk.parent[1:] == np.arange(len(sk) - 1))


@pytest.mark.parametrize("n", [1, 2])
def test_hilbert3d_visits_lattice(n):
    _, sk = grow("hilbert3d", n)
    points = np.concatenate([sk.start[:1], sk.end])
    lattice = np.rint(points)
    np.testing.assert_allclose(points, lattice, atol=1e-9)
    assert len(points) == 8**n
    assert len(np.unique(lattice, axis=0)) == 8**n
    steps = np.abs(np.diff(lattice, axis=0))
    assert np.all(steps.sum(axis=1) == 1)  # unit steps along one axis
    assert np.all(np.ptp(lattice, axis=0) == 2**n - 1)  # fills a 2^n cube
    assert_orthonormal(sk)


@pytest.mark.parametrize("n", range(0, 13))
def test_dragon_end_point(n):
    # With L_n = L_{n-1} + R_{n-1} + and R_n = - L_{n-1} - R_{n-1}, both strings turn by
    # +180 / -180 degrees in total, so their displacements satisfy d(L_n) = d(L_{n-1}) - i d(R_{n-1})
    # and d(R_n) = -d(L_n); hence d(L_n) = (1 + i) d(L_{n-1}) = (1 + i)^n, starting along +X
    # with '+' turning counter-clockwise.
    _, sk = grow("dragon", n)
    assert len(sk) == 2**n
    z = (1 + 1j) ** n
    np.testing.assert_allclose(sk.end[-1], [z.real, z.imag, 0], atol=1e-9 * abs(z))


@pytest.mark.parametrize("name", ["abop-1.24a", "abop-1.24b", "abop-1.24c", "abop-1.24d", "abop-1.24e", "abop-1.24f"])
def test_figure_124_segments(name):
    modules, sk = grow(name)
    assert len(sk) == modules.count("F")
    sk.validate()
    assert sk.bounds()[0, 1] >= 0  # grows up from the origin
    assert_orthonormal(sk)


@pytest.mark.parametrize(("name", "heading"), [("koch", 0), ("snowflake", 0), ("tree", 85), ("plant", 90)])
def test_seed_examples_are_planar(name, heading):
    _, sk = grow(name)
    for field in ("start", "end", "heading", "left"):
        assert np.all(getattr(sk, field)[:, 2] == 0)
    a = math.radians(heading)
    np.testing.assert_allclose(sk.heading[0], [math.cos(a), math.sin(a), 0], atol=1e-15)


# ------------------------------------------------------------------ errors
def test_pop_with_empty_stack():
    # the grammar refuses an unbalanced axiom, so build the string directly
    with pytest.raises(InterpretError, match=r"^module 3 '\]' \(pop\): nothing to pop"):
        interpret(ModuleString.from_symbols("F[]]F"), TurtleOptions())


def test_bracket_with_argument():
    modules = ModuleString(np.array([ord("F"), ord("[")], np.uint8), np.array([0, 1], np.uint8), np.array([1.0]))
    with pytest.raises(InterpretError, match=r"^module 1 '\[\(1\)' \(push\): takes no argument"):
        interpret(modules, TurtleOptions())


@pytest.mark.parametrize(
    ("axiom", "message"),
    [
        ("F{.f.f", r"^module 1 '\{' \(begin polygon\): polygon never closed"),
        ("F.f}", r"^module 3 '\}' \(end polygon\): no polygon is open"),
        ("{.f{.f}", r"^module 0 '\{' \(begin polygon\): polygon never closed"),
        ("{" * 1001, r"^module 1000 '\{' \(begin polygon\): more than 1000 polygons open at once"),
        ("F!(-1)F", r"^module 1 '!\(-1\)' \(width\): the width must be"),
        ('F"(-1)F', r"^module 1 '\"\(-1\)' \(step length\)"),
        ("+(1,2)F", r"^module 0 '\+\(1,2\)' \(turn left\): takes at most 1 argument"),
        ("F(6e8)F(6e8)", r"^module 1 'F\(6e\+08\)' \(forward\): the turtle's position left the drawable range"),
        ("F!(2e9)F", r"^module 1 '!\(2e\+09\)' \(width\): the width must be a number from 0 to 1e\+09"),
        ("F~(2e9)", r"^module 1 '~\(2e\+09\)' \(leaf\): the leaf size must be a number from 0 to 1e\+09"),
    ],
)
def test_interpret_errors(axiom, message):
    with pytest.raises(InterpretError, match=message):
        draw(axiom)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_non_finite_parameter(value):
    modules = ModuleString(
        np.array([ord("F"), ord("+"), ord("F")], np.uint8), np.array([0, 1, 0], np.uint8), np.array([value])
    )
    with pytest.raises(InterpretError, match=r"^module 1 '\+\((nan|inf)\)' \(turn left\): parameter is not a finite"):
        interpret(modules, TurtleOptions())


TOML = """name = "t"
axiom = "F"
angle = 30

[turtle]
heading = 90
{line}
width = 0.1
"""


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("colour = 3", "unknown key"),
        ("step = -1", "step: must be > 0, not -1"),
        ("step = 0", "step: must be > 0, not 0"),
        ('step = "long"', "step: must be a number, not 'long'"),
        ("width_scale = true", "width_scale: must be a number, not True"),
        ("tropism = [0, -1]", r"tropism: must be a list of 3 numbers, not \[0, -1\]"),
        ('draw = "F+"', "'draw' symbol '\\+' is already the turtle command turn left"),
        ('move = "F"', "'move' symbol 'F' is also a 'draw' symbol"),
        ('leaf = "ab"', "'leaf' must be one symbol"),
        ("angle_jitter = -2", "angle_jitter: must be >= 0, not -2"),
        ("elasticity = nan", "elasticity: must be a finite number, not nan"),
    ],
)
def test_bad_turtle_keys(line, message):
    grammar = Grammar.from_text(TOML.format(line=line), source="plant.toml")
    with pytest.raises(GrammarError, match=message) as info:
        interpret(grammar.axiom_modules, grammar)
    assert info.value.source == "plant.toml" and info.value.line == 7
    assert str(info.value).startswith("plant.toml:7:1: [turtle] ")


def test_options_from_python():
    with pytest.raises(OptionsError, match=r"TurtleOptions\.step: must be > 0, not -1"):
        TurtleOptions(step=-1)
    with pytest.raises(OptionsError, match="unknown option 'stepp'"):
        TurtleOptions.from_grammar(load_preset("koch"), stepp=2)
    opts = TurtleOptions.from_grammar(load_preset("tree"), step=2)
    assert (opts.heading, opts.angle, opts.step, opts.tropism) == (85.0, 22.0, 2.0, (0.0, 0.0, 0.0))


# ------------------------------------------------------------------ jitter
def _digest(sk) -> list[float]:
    return [float(sk.end.sum()), float(sk.heading.sum()), float(sk.lengths().sum())]


def test_jitter_off_by_default():
    _, a = grow("abop-1.24a", 3)
    _, b = grow("abop-1.24a", 3, angle_jitter=0.0, length_jitter=0.0, seed=99)
    np.testing.assert_array_equal(a.end, b.end)


def test_jitter_reproducible_and_seeded():
    grammar = load_preset("abop-1.24f", iterations=4)
    modules = derive(grammar)
    opts = TurtleOptions.from_grammar(grammar, angle_jitter=5, length_jitter=0.1)
    a, b = interpret(modules, opts), interpret(modules, opts)
    np.testing.assert_array_equal(a.end, b.end)
    np.testing.assert_array_equal(interpret(modules, opts, seed=7).end, interpret(modules, opts.replace(seed=7)).end)
    c = interpret(modules, opts, seed=1)
    assert not np.array_equal(a.end, c.end)
    plain = interpret(modules, grammar)
    lengths = a.lengths()
    assert np.all((lengths >= 0.9 - 1e-12) & (lengths <= 1.1 + 1e-12))
    turned = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a.heading, plain.heading), -1, 1)))
    assert turned.max() > 1  # the angles did change


def test_jitter_same_in_another_process():
    code = (
        "from lsys3d import load_preset, derive; from lsys3d.turtle import TurtleOptions, interpret;"
        "g = load_preset('abop-1.24f', iterations=3); ms = derive(g);"
        "sk = interpret(ms, TurtleOptions.from_grammar(g, angle_jitter=5, length_jitter=0.1), seed=3);"
        "print(repr([float(sk.end.sum()), float(sk.heading.sum()), float(sk.lengths().sum())]))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    grammar = load_preset("abop-1.24f", iterations=3)
    sk = interpret(derive(grammar), TurtleOptions.from_grammar(grammar, angle_jitter=5, length_jitter=0.1), seed=3)
    assert out.strip() == repr(_digest(sk))


def test_jittered_lengths_never_negative():
    sk = draw("F" * 200, length_jitter=3.0, seed=5)
    lengths = sk.lengths()
    assert np.all(lengths >= 0) and np.any(lengths == 0) and np.any(lengths > 1)
    # the segment is still drawn along H, never backwards
    d = sk.end - sk.start
    assert np.all(np.einsum("ij,ij->i", d, sk.heading) >= 0)


# ------------------------------------------------------------------ properties
TOKENS = [*"F+-&^/\\|f", "[", "]"]


@st.composite
def bracketed(draw_):
    tokens = draw_(st.lists(st.sampled_from(TOKENS), max_size=80))
    out, depth = [], 0
    for t in tokens:
        if t == "]":
            if depth == 0:
                continue
            depth -= 1
        elif t == "[":
            depth += 1
        out.append(t)
    return "".join(out) + "]" * depth


@settings(max_examples=150, deadline=None)
@given(bracketed(), st.sampled_from([13.0, 90.0, 137.5]))
def test_random_bracket_strings(text, angle):
    sk = draw(text or "X", angle=angle, width=0.1)
    assert len(sk) == text.count("F")
    sk.validate()
    if len(sk):
        assert_orthonormal(sk)
        np.testing.assert_allclose(sk.lengths(), 1.0, atol=1e-12)
        has = sk.parent >= 0
        np.testing.assert_allclose(sk.start[has], sk.end[sk.parent[has]], atol=1e-12)
        assert np.all(sk.order >= 0)
        assert np.all(sk.order[has] >= sk.order[sk.parent[has]])


@settings(max_examples=60, deadline=None)
@given(bracketed(), bracketed())
def test_branch_leaves_no_trace(before, branch):
    a = draw(before + "F", angle=21)
    b = draw(before + "[" + branch + "]F", angle=21)
    for name in ("start", "end", "heading", "left", "up", "order"):
        np.testing.assert_array_equal(getattr(b, name)[-1], getattr(a, name)[-1])


# ------------------------------------------------------------------ stats and docs
def test_skeleton_stats():
    modules, sk = grow("abop-1.24d", 4)
    stats = skeleton_stats(modules, sk)
    assert list(stats) == sorted(stats)
    assert json.loads(json.dumps(stats)) == stats
    assert stats["modules"] == len(modules)
    assert stats["segments"] == len(sk) == modules.count("F")
    assert stats["branches"] == modules.count("[")
    assert stats["chains"] == len(sk.chains)
    assert stats["leaves"] == 0
    assert stats["max_order"] == int(sk.order.max())
    assert stats["total_length"] == pytest.approx(len(sk))
    lo, hi = sk.bounds()
    assert stats["bbox_min"] == pytest.approx(lo.tolist()) and stats["bbox_max"] == pytest.approx(hi.tolist())
    assert stats["bbox_min"][1] == 0.0
    for key in ("modules", "segments", "chains", "branches", "leaves", "max_order"):
        assert type(stats[key]) is int


def test_skeleton_stats_empty():
    grammar = Grammar(axiom="X")
    stats = skeleton_stats(grammar.axiom_modules, interpret(grammar.axiom_modules, grammar))
    assert stats["segments"] == 0 and stats["bbox_min"] == [0.0, 0.0, 0.0] and stats["max_order"] == -1


def test_command_table():
    symbols = [c.symbol for c in COMMANDS]
    assert len(symbols) == len(set(symbols))
    assert set("Ff+-&^\\/|$[]!'\"{.}~") | {"@O", "@c", "@o", "?P", "?H", "?L", "?U", "?E"} == set(symbols)
    # one row per behaviour; rotations say their axis and sign, queries what they ask (the other ops are the
    # dialects': test_dialects)
    assert len({(c.op, c.axis, c.sign, c.organ, c.query) for c in COMMANDS}) == len(COMMANDS)
    assert {c.op for c in COMMANDS} <= set(Op) - {Op.NONE}
    assert all((c.axis != Axis.NONE) == (c.op == Op.ROTATE) and c.sign in (1, -1) for c in COMMANDS)
    table = symbol_table(ASCII_ALPHABET, draw="FG", move="fg", leaf="L")
    assert (
        Op(table.op[ord("G")]) == Op.FORWARD and Op(table.op[ord("g")]) == Op.MOVE and Op(table.op[ord("L")]) == Op.LEAF
    )
    assert Op(table.op[ord("~")]) == Op.NONE and table.command(ord("&")).name == "pitch down"


def test_docs_table_and_example():
    text = (ROOT / "docs" / "turtle.md").read_text(encoding="utf-8")
    assert commands_markdown() in text
    assert options_markdown() in text
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert blocks
    for block in blocks:
        exec(compile(block, "docs/turtle.md", "exec"), {})


def test_a_new_symbol_is_one_table_row():
    """What the dialects need first -- cpfg's colour symbols and Houdini's opposite pitch -- are rows, not code."""
    from dataclasses import replace

    from lsys3d.turtle.commands import Command

    colours = (
        Command(";", "next colour", Op.MATERIAL, "i", 1, "Set the colour index to `i`; without `i` add 1.", sign=+1),
        # cpfg's ',' (the grammar notation reserves ',' until the dialect readers map it), here '?'
        Command("?", "previous colour", Op.MATERIAL, "i", 1, "Without `i` take 1 from the colour index.", sign=-1),
    )
    table = tuple(replace(c, sign=-c.sign) if c.symbol in "&^" else c for c in COMMANDS) + colours
    g = Grammar(axiom="F;F;F?F??F;(7)F&F", angle=90)
    sk = interpret(derive(g, 0), g, commands=table)
    assert sk.material.tolist() == [0, 1, 2, 1, 0, 7, 7]  # '?' stops at 0
    default = interpret(derive(g, 0), g)
    assert default.material.tolist() == [0] * 7  # ';' and '?' mean nothing in lsys3d's own dialect
    # '&' with the opposite sign pitches up instead of down
    assert sk.end[-1, 2] - sk.start[-1, 2] == pytest.approx(1.0) and default.end[-1, 2] - default.start[-1, 2] == -1.0


# ---------------------------------------------------------------- the ops the dialects brought
def _row(symbol, name, op, **kw):
    from lsys3d.turtle.commands import Command

    return Command(symbol, name, op, kw.pop("args", "x"), kw.pop("max_args", 1), name + ".", **kw)


def test_organs_are_recorded_with_their_frame_and_segment():
    from lsys3d.turtle import Organ

    g = Grammar(axiom="F@O(0.5)F[+@c]@o!(0.3)@O", angle=90)
    sk = interpret(derive(g, 0), g)
    assert sk.organ_kind.tolist() == [Organ.SPHERE, Organ.DISC, Organ.CIRCLE, Organ.SPHERE]
    assert sk.organ_size.tolist() == pytest.approx([0.5, 0.1, 0.1, 0.3])  # the width when not given
    assert sk.organ_segment.tolist() == [0, 1, 1, 1] and sk.organ_module.tolist() == [1, 5, 7, 9]
    assert sk.organ_position[0].tolist() == pytest.approx([0, 1, 0]) and sk.n_organs == 4
    assert sk.organ_heading[1].tolist() == pytest.approx([-1, 0, 0])  # the frame of the turtle in its branch


def test_width_unit_scales_the_widths_a_grammar_gives():
    g = Grammar(axiom="!(2)F@O(4)", turtle={"width_unit": 0.5})
    sk = interpret(derive(g, 0), g)
    assert sk.width_start.tolist() == [1.0] and sk.organ_size.tolist() == [2.0]


def test_moves_with_a_step_factor_and_without_a_vertex():
    rows = (
        *COMMANDS,
        _row("Z", "half forward", Op.FORWARD, scale=0.5),
        _row("G", "move, no vertex", Op.MOVE, vertex=False),
    )
    g = Grammar(axiom="FZ{.G+G+G.f.}", angle=90)
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.lengths().tolist() == pytest.approx([1.0, 0.5])
    # the polygon's vertices: the two dots and the f move, not the G moves
    assert sk.polygon_offsets.tolist() == [0, 3]


def test_width_and_angle_factors_and_steps():
    rows = (
        *COMMANDS,
        _row("?", "thicker", Op.WIDTH_FACTOR, factor=1.4),
        _row("_", "wider", Op.WIDTH_ADD, sign=+1),
        _row(";", "angle up", Op.ANGLE_FACTOR, factor=2.0),
        _row("a", "angle down", Op.ANGLE_FACTOR, sign=-1),
        _row("*", "length down", Op.LENGTH, sign=-1, factor=2.0),
    )
    g = Grammar(axiom="F?F?(3)F_F_(0.5)F", turtle={"width_increment": 0.25})
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.width_start.tolist() == pytest.approx([0.1, 0.14, 0.42, 0.67, 0.5])
    g = Grammar(axiom=";+Fa(4)-F*F", angle=10, turtle={"heading": 0})
    sk = interpret(derive(g, 0), g, commands=rows)
    directions = np.degrees(np.arctan2(sk.heading[:, 1], sk.heading[:, 0]))
    assert directions.tolist() == pytest.approx([20, 15, 15]) and sk.lengths().tolist() == pytest.approx([1, 1, 0.5])


def test_turn_around_about_each_axis_and_a_branch_restores_the_angle():
    rows = (*COMMANDS, _row("%", "roll around", Op.TURN_AROUND, axis=Axis.H, max_args=0, args=""))
    g = Grammar(axiom="F%&F", angle=90)
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.end[-1].tolist() == pytest.approx([0, 1, 1])  # the roll flipped U: '&' pitches toward +Z
    rows += (_row(";", "angle up", Op.ANGLE_FACTOR, factor=2.0),)
    g = Grammar(axiom="[;]+F", angle=45, turtle={"heading": 0})
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.end[0].tolist() == pytest.approx([np.sqrt(0.5), np.sqrt(0.5), 0])


def test_random_turns_depend_on_the_seed_only():
    rows = (*COMMANDS, _row("~", "random turn", Op.RANDOM_TURN, factor=30.0))
    g = Grammar(axiom="~F~F~F")
    a = interpret(derive(g, 0), g, seed=1, commands=rows)
    assert np.array_equal(a.end, interpret(derive(g, 0), g, seed=1, commands=rows).end)
    b = interpret(derive(g, 0), g, seed=2, commands=rows)
    assert not np.allclose(a.end, b.end)
    # at most 30 degrees about each axis: the first heading stays within 60 degrees of up
    assert a.heading[0, 1] > np.cos(np.radians(60))


def test_one_shot_tropism_and_elasticity():
    rows = (*COMMANDS, _row("t", "gravity", Op.TROPISM, factor=0.2), _row("E", "elasticity", Op.ELASTICITY))
    g = Grammar(axiom="+(90)tF", turtle={"heading": 90})
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.heading[0, 1] == pytest.approx(-np.sin(0.2))  # bent toward -Y by 0.2 rad
    g = Grammar(axiom="+(90)FE(0.2)FE F", turtle={"heading": 90, "tropism": [0, -1, 0]})
    sk = interpret(derive(g, 0), g, commands=rows)
    assert sk.heading[0, 1] == pytest.approx(0, abs=1e-12) and sk.heading[1, 1] < 0
    assert sk.heading[2].tolist() == pytest.approx(sk.heading[1].tolist())  # E without argument: 0


def test_parameters_a_row_ignores_are_accepted():
    rows = (*tuple(c for c in COMMANDS if c.symbol != "F"), _row("F", "forward", Op.FORWARD, ignored=("topradius",)))
    g = Grammar(axiom="F(2, 0.1)")
    assert interpret(derive(g, 0), g, commands=rows).lengths().tolist() == [2.0]
    with pytest.raises(InterpretError, match="takes at most 2 argument"):
        interpret(derive(Grammar(axiom="F(2, 0.1, 3)"), 0), g, commands=rows)
