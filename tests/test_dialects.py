"""The dialects: their symbol tables against the tools' documentation, their readers, and mangled input.

The expected tables below are transcribed from each tool's own documentation (cited per table) and
compared with what the turtle compiles from the dialect's rows, so a row that drifts from the tool
fails here.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lsys3d
from lsys3d import Grammar, GrammarError
from lsys3d.lsystem import dialects
from lsys3d.lsystem.derive import interpretation
from lsys3d.lsystem.modules import ASCII_ALPHABET
from lsys3d.provenance import grammar_text
from lsys3d.turtle import Axis, Op, Organ, interpret, symbol_table

U, L, H = Axis.U, Axis.L, Axis.H

# What each symbol does, as the tool's documentation says: (op, axis, sign) for rotations, op otherwise.
# ABOP: The Algorithmic Beauty of Plants, sections 1.5, 2.2 (tropism), 5.1 (polygons: '{', '.', 'G', '}')
ABOP = {
    "F": Op.FORWARD, "f": Op.MOVE, "G": Op.MOVE,
    "+": (Op.ROTATE, U, +1), "-": (Op.ROTATE, U, -1), "&": (Op.ROTATE, L, -1), "^": (Op.ROTATE, L, +1),
    "\\": (Op.ROTATE, H, -1), "/": (Op.ROTATE, H, +1), "|": Op.TURN_AROUND, "$": Op.ROLL_HORIZONTAL,
    "[": Op.PUSH, "]": Op.POP, "{": Op.POLYGON_BEGIN, ".": Op.POLYGON_VERTEX, "}": Op.POLYGON_END,
    "!": Op.WIDTH, "'": Op.MATERIAL, "~l": Op.ORGAN,
}  # fmt: skip
# L-Py: doc/user/helpcard.rst and src/cpp/predefinedmodules.cpp of openalea/lpy (names and aliases)
LPY = {
    "F": Op.FORWARD, "f": Op.MOVE, "+": (Op.ROTATE, U, +1), "Left": (Op.ROTATE, U, +1),
    "-": (Op.ROTATE, U, -1), "Right": (Op.ROTATE, U, -1), "^": (Op.ROTATE, L, +1), "Up": (Op.ROTATE, L, +1),
    "&": (Op.ROTATE, L, -1), "Down": (Op.ROTATE, L, -1), "/": (Op.ROTATE, H, +1), "RollL": (Op.ROTATE, H, +1),
    "\\": (Op.ROTATE, H, -1), "RollR": (Op.ROTATE, H, -1), "|": Op.TURN_AROUND, "TurnAround": Op.TURN_AROUND,
    "@v": Op.ROLL_HORIZONTAL, "RollToVert": Op.ROLL_HORIZONTAL, "[": Op.PUSH, "SB": Op.PUSH, "]": Op.POP, "EB": Op.POP,
    "{": Op.POLYGON_BEGIN, "BP": Op.POLYGON_BEGIN, "}": Op.POLYGON_END, "EP": Op.POLYGON_END,
    ".": Op.POLYGON_VERTEX, "PP": Op.POLYGON_VERTEX, "_": Op.WIDTH_ADD, "IncWidth": Op.WIDTH_ADD,
    "!": Op.WIDTH_ADD, "DecWidth": Op.WIDTH_ADD, "SetWidth": Op.WIDTH, ";": Op.MATERIAL, "IncColor": Op.MATERIAL,
    ",": Op.MATERIAL, "DecColor": Op.MATERIAL, "SetColor": Op.MATERIAL, "@O": Op.ORGAN, "Sphere": Op.ORGAN,
    "@o": Op.ORGAN, "Circle": Op.ORGAN, "@B": Op.ORGAN, "Box": Op.ORGAN, "~l": Op.ORGAN,
    "@Ts": Op.ELASTICITY, "Elasticity": Op.ELASTICITY, "@Tp": Op.TROPISM_VECTOR, "Tropism": Op.TROPISM_VECTOR,
    "nF": Op.FORWARD_STEPS,
    # query modules (the helpcard's "Query" section): filled by the turtle between the steps
    "?P": Op.QUERY, "?H": Op.QUERY, "?L": Op.QUERY, "?U": Op.QUERY, "?R": Op.QUERY, "GetPos": Op.QUERY,
    "GetHead": Op.QUERY, "GetLeft": Op.QUERY, "GetUp": Op.QUERY, "GetRight": Op.QUERY,
}  # fmt: skip
# cpfg: "Interpreted symbols", appendix of the cpfg 3.0 tutorial (algorithmicbotany.org), and its
# circles-and-spheres page (@c, @O)
CPFG = {
    "F": Op.FORWARD, "f": Op.MOVE, "G": Op.FORWARD, "g": Op.MOVE,
    "+": (Op.ROTATE, U, +1), "-": (Op.ROTATE, U, -1), "&": (Op.ROTATE, L, -1), "^": (Op.ROTATE, L, +1),
    # the rolls as cpfg's interpret.c turns (change_dir: '/' L toward cpfg's U, which is lsys3d's -U: cpfg's
    # frame starts at H = (0, 1, 0), L = (-1, 0, 0), U = (0, 0, -1); tests/test_cpfg_tropisms.py checks the path)
    "\\": (Op.ROTATE, H, +1), "/": (Op.ROTATE, H, -1), "|": Op.TURN_AROUND, "@v": Op.ROLL_HORIZONTAL,
    "[": Op.PUSH, "]": Op.POP, "{": Op.POLYGON_BEGIN, ".": Op.POLYGON_VERTEX, "}": Op.POLYGON_END,
    ";": Op.MATERIAL, ",": Op.MATERIAL, "#": Op.WIDTH_ADD, "!": Op.WIDTH_ADD, "@O": Op.ORGAN, "@c": Op.ORGAN,
    "@o": Op.ORGAN, "~l": Op.ORGAN,
    # cpfg's interpret.c (vlab): '?' stacks a sub-L-system's scale and '$' unstacks it; '$' does not roll
    "?": (Op.SUB_LSYSTEM, Axis.NONE, +1), "$": (Op.SUB_LSYSTEM, Axis.NONE, -1),
    # query and communication modules (Mech and Prusinkiewicz 1996; the cpfg manual's environment section)
    "?P": Op.QUERY, "?H": Op.QUERY, "?L": Op.QUERY, "?U": Op.QUERY, "?E": Op.QUERY,
    # cpfg's interpret.c: '_' adds the view file's elasticity increment, '_(e)' sets the elasticity
    "_": Op.ELASTICITY_ADD,
    # generalized cylinders (blackbox.c, general.c): @Gs starts, @Gc and @Ge set control points, @Gt tangents
    "@Gs": Op.CYLINDER_START, "@Gc": Op.CYLINDER_POINT, "@Ge": (Op.CYLINDER_POINT, Axis.NONE, -1),
    "@Gt": Op.CYLINDER_TANGENTS,
    # blackbox.c: @Tx(n) selects a texture (turtle state, read after the turtle: lsys3d.turtle.selections)
    "@Tx": Op.NONE,
    # blackbox.c: @! the cylinders' sides, @Ts/@Ti/@Td a movement's elasticity (set, +, -), @Tf keeps the frame,
    # @Tp carries U from it
    "@!": Op.SIDES, "@Ts": (Op.MOVEMENT_ELASTICITY, Axis.NONE, 0), "@Ti": (Op.MOVEMENT_ELASTICITY, Axis.NONE, +1),
    "@Td": (Op.MOVEMENT_ELASTICITY, Axis.NONE, -1), "@Tf": (Op.MOVEMENT_FRAME, Axis.NONE, +1),
    "@Tp": (Op.MOVEMENT_FRAME, Axis.NONE, -1),
}  # fmt: skip
# Lparser: lparser.txt (L. Lapre), the symbol table reproduced in the Lparser ports
LPARSER = {
    "F": Op.FORWARD, "Z": Op.FORWARD, "f": Op.MOVE, "z": Op.MOVE, "g": Op.MOVE, ".": Op.POLYGON_VERTEX,
    "+": (Op.ROTATE, U, +1), "-": (Op.ROTATE, U, -1), "&": (Op.ROTATE, L, -1), "^": (Op.ROTATE, L, +1),
    "<": (Op.ROTATE, H, -1), ">": (Op.ROTATE, H, +1), "|": Op.TURN_AROUND, "%": Op.TURN_AROUND,
    "$": Op.ROLL_HORIZONTAL, "~": Op.RANDOM_TURN, "t": Op.TROPISM, "[": Op.PUSH, "]": Op.POP,
    "{": Op.POLYGON_BEGIN, "}": Op.POLYGON_END, '"': Op.LENGTH, "'": Op.LENGTH, ";": Op.ANGLE_FACTOR,
    ":": Op.ANGLE_FACTOR, "?": Op.WIDTH_FACTOR, "!": Op.WIDTH_FACTOR, "c": Op.MATERIAL,
    "_": Op.NONE,  # K-3D's l_parser.cpp (Lapre's code): the default successor, which draws nothing
}  # fmt: skip
# Houdini: the L-System SOP's "Turtle command reference" (SideFX); '&' pitches up, '^' down
HOUDINI = {
    "F": Op.FORWARD, "H": Op.FORWARD, "G": Op.MOVE, "f": Op.MOVE, "h": Op.MOVE, "J": Op.ORGAN, "K": Op.ORGAN,
    "M": Op.ORGAN, "T": Op.TROPISM, "+": (Op.ROTATE, U, +1), "-": (Op.ROTATE, U, -1),
    "&": (Op.ROTATE, L, +1), "^": (Op.ROTATE, L, -1), "\\": (Op.ROTATE, H, -1), "/": (Op.ROTATE, H, +1),
    "|": Op.TURN_AROUND, "*": Op.TURN_AROUND, "~": Op.RANDOM_TURN, '"': Op.LENGTH, "_": Op.LENGTH,
    "!": Op.WIDTH_FACTOR, "?": Op.WIDTH_FACTOR, ";": Op.ANGLE_FACTOR, "@": Op.ANGLE_FACTOR, "'": Op.MATERIAL,
    "$": Op.ROLL_HORIZONTAL, "[": Op.PUSH, "]": Op.POP, "{": Op.POLYGON_BEGIN, ".": Op.POLYGON_VERTEX,
    "}": Op.POLYGON_END,
}  # fmt: skip
DOCUMENTED = {"abop": ABOP, "lpy": LPY, "cpfg": CPFG, "lparser": LPARSER, "houdini": HOUDINI}


def compiled(name: str, symbols):
    """The dialect's table compiled for ``symbols`` (multi-character names get ids from 128 up)."""
    extra = [s for s in symbols if len(s) > 1 or ord(s) >= 128]
    alphabet = ASCII_ALPHABET[:128] + tuple(extra) + ("\0",) * (128 - len(extra))
    table = symbol_table(alphabet, commands=dialects.get(name).commands)
    code = {s: (alphabet.index(s, 128) if s in extra else ord(s)) for s in symbols}
    return table, code


@pytest.mark.parametrize("name", sorted(DOCUMENTED))
def test_symbol_tables_say_what_the_tools_documentation_says(name):
    documented = DOCUMENTED[name]
    table, code = compiled(name, list(documented))
    for symbol, expected in documented.items():
        c = code[symbol]
        got = Op(table.op[c])
        if isinstance(expected, tuple):
            assert (got, Axis(table.axis[c]), int(table.sign[c])) == expected, symbol
        else:
            assert got == expected, symbol
    # and the dialect has no row the documentation does not list (but the default draw/move/leaf symbols)
    rows = {c.symbol for c in dialects.get(name).commands if not c.prefix}
    assert rows - set(documented) <= {"F", "f", "~"}, rows - set(documented)


def test_every_op_has_a_row_in_some_dialect():
    ops = {c.op for name in dialects.DIALECTS for c in dialects.get(name).commands}
    assert ops - {Op.NONE} == set(Op) - {Op.NONE}


def test_the_dialects_differences_are_where_the_tools_differ():
    """The same symbols, drawn in each dialect: '&' pitches down in ABOP and up in Houdini; Lparser's '<' rolls."""

    def tip(dialect, axiom, **turtle):
        g = Grammar(axiom=axiom, dialect=dialect, angle=90, turtle=turtle)
        return interpret(lsys3d.derive(g, 0), g).end[-1].round(6).tolist()

    assert tip("abop", "F&F") == [0.0, 1.0, -1.0]
    assert tip("houdini", "F&F") == [0.0, 1.0, 1.0]
    assert tip("lparser", "F<+F") == tip("abop", "F\\+F")
    assert tip("lpy", "F+F") == tip("abop", "F+(90)F")  # L-Py's default angle is 60 unless the file sets it
    assert Grammar(axiom="F", dialect="lpy").angle == 60.0


def test_widths_and_organs_in_each_dialects_units():
    g = Grammar(axiom="_(0.05)F@O(0.2)", dialect="lpy")  # radii in L-Py
    sk = interpret(lsys3d.derive(g, 0), g)
    assert sk.width_start.tolist() == pytest.approx([0.1]) and sk.organ_size.tolist() == pytest.approx([0.4])
    g = Grammar(axiom="F_F!F", dialect="lpy")  # '_' and '!' step the width by 1 (a radius)
    assert interpret(lsys3d.derive(g, 0), g).width_start.tolist() == pytest.approx([0.2, 2.2, 0.2])
    g = Grammar(axiom="F?F!(0.5)F", dialect="lparser", turtle={"width": 1.0})
    assert interpret(lsys3d.derive(g, 0), g).width_start.tolist() == pytest.approx([1.0, 1.4, 0.7])
    g = Grammar(axiom='FZF"F', dialect="lparser")
    assert interpret(lsys3d.derive(g, 0), g).lengths().tolist() == pytest.approx([1.0, 0.5, 1.0, 1.1])
    g = Grammar(axiom="F~l(2)J(3)", dialect="cpfg")
    sk = interpret(lsys3d.derive(g, 0), g)
    assert sk.organ_kind.tolist() == [Organ.SURFACE] and sk.organ_size.tolist() == [2.0]
    assert sk.organ_name.tolist() == ["~l"]  # the surface's name, kept with the organ
    assert lsys3d.derive(g, 0).symbol(1) == "~l"
    g = Grammar(axiom="FA", dialect="lpy", modules=("A",), homomorphism=["A --> @O(0.1)~l(2)"])
    sk = interpret(interpretation(g, lsys3d.derive(g, 0)), g)  # organs drawn by a homomorphism rule
    assert sk.organ_name.tolist() == ["@O", "~l"] and sk.organ_kind.tolist() == [Organ.SPHERE, Organ.SURFACE]


# ---------------------------------------------------------------- the readers
def lpy(text: str, **overrides) -> Grammar:
    return Grammar.from_text(text, source="plant.lpy", **overrides)


def test_lpy_rule_bodies_become_rules_with_local_variables_and_tests():
    g = lpy(
        """
N = 3
def size(n): return n * 0.5
module Apex, Leaf
Axiom: Apex(0)
derivation length: 4
production:
Apex(n) :
    s = size(n)
    if n < N:
        nproduce F(s)
        produce [+Leaf(n)]Apex(n + 1)
    elif n == N:
        produce F(s)Leaf(n)
    # past N: no produce, the rule does not apply
homomorphism:
Leaf(n) --> ~l(1)
endlsystem
"""
    )
    assert len(g.rules) == 2 and g.modules == ("Apex", "Leaf") and g.defines["N"] == 3
    result = lsys3d.derive(g)
    assert str(result) == "F(0)[+Leaf(0)]F(0.5)[+Leaf(1)]F(1)[+Leaf(2)]F(1.5)Leaf(3)"
    assert str(interpretation(g, result)) == "F(0)[+~l(1)]F(0.5)[+~l(1)]F(1)[+~l(1)]F(1.5)~l(1)"


def test_lpy_random_draws_are_the_same_in_each_branch_of_an_if():
    g = lpy(
        """
Axiom: A A A A A A A A
derivation length: 1
production:
A :
    r = random.random()
    if r < 0.5: produce B(r)
    else: produce C(r)
endlsystem
""",
        seed=5,
    )
    result = lsys3d.derive(g)
    values = [result.module(i) for i in range(len(result))]
    assert {s for s, _ in values} == {"B", "C"}
    assert all((s == "B") == (v[0] < 0.5) for s, v in values)


def test_lpy_settings_scalars_decomposition_cut_and_editor_sections():
    g = lpy(
        """
from math import *
context().turtle.setAngleIncrement(90)
A, B = range(2)
Axiom: X(A)
derivation length: 1
production:
X(k) --> X(k + 1)[F%F]
decomposition:
maximum depth: 3
X(k) : produce I X(k - 1)
endlsystem
###### INITIALISATION ######
__lpy_code_version__ = 1.1
def __initialiseContext__(context):
    scalars = [('STEP', 'Integer', 2, 0, 10), ('ON', 'Bool', True)]
    context["__scalars__"] = scalars
"""
    )
    assert g.angle == 90 and g.defines["B"] == 1 and g.defines["STEP"] == 2 and g.defines["ON"] == 1
    assert g.decomposition_depth == 3
    assert str(lsys3d.derive(g)) == "IIIX(-2)[F%F]"  # decomposed three times; cut at the next step


def _plantgl_path(heading, moves, tropism, elasticity):
    """PlantGL's turtle, written for this test in its own Z-up world: F steps bent by Turtle::_tendTo."""
    h = np.array(heading, float)
    p = np.zeros(3)
    t = np.array(tropism, float)
    for length in moves:
        axis = np.cross(h, t)
        sine = np.linalg.norm(axis)
        if sine > 1e-5:
            axis /= sine
            a = np.arctan2(sine, h @ t) * elasticity
            h = h * np.cos(a) + np.cross(axis, h) * np.sin(a) + axis * (axis @ h) * (1 - np.cos(a))
        p = p + h * length
    return p


def test_lpy_nf_draws_steps_bent_toward_the_tropism_as_plantgl_does():
    g = lpy("Axiom: _(0.05) @Tp(1,0,0) Elasticity(0.05) nF(1, 0.3, 0.01)\nderivation length: 0\n")
    sk = interpret(lsys3d.derive(g), g)
    # PlantGL's Turtle::nF: int(1 / 0.3) = 3 steps of 0.3, then the rest 0.1; the radius 0.05 -> 0.01 by step
    np.testing.assert_allclose(np.linalg.norm(sk.end - sk.start, axis=1), [0.3, 0.3, 0.3, 0.1])
    np.testing.assert_allclose(sk.width_start, 2 * np.array([0.05, 0.038, 0.026, 0.014]))
    assert sk.width_end[-1] == pytest.approx(0.02) and sk.parent.tolist() == [-1, 0, 1, 2]
    tip = _plantgl_path((0, 0, 1), [0.3, 0.3, 0.3, 0.1], (1, 0, 0), 0.05)  # PlantGL's (x, y, z) is our (y, z, x)
    np.testing.assert_allclose(sk.end[-1], tip[[1, 2, 0]], atol=1e-12)
    # without @Tp the tropism is PlantGL's (0, 0, 1): up; a rest under PlantGL's epsilon draws nothing
    g = lpy("Axiom: -(90) Elasticity(0.1) nF(0.6, 0.2)\nderivation length: 0\n")
    sk = interpret(lsys3d.derive(g), g)
    assert len(sk) == 3 and sk.end[-1][1] > 0.05  # bent up
    # and @Tp is part of the state [ ] saves
    g = lpy("Axiom: Elasticity(0.1) [@Tp(0,1,0)] -(90) nF(0.6, 0.2)\nderivation length: 0\n")
    assert interpret(lsys3d.derive(g), g).end[-1][1] > 0.05
    for axiom, message in [
        ("nF(1)", "nF(length, dlength[, radius])"),
        ("nF(1, 0)", "nF(length, dlength[, radius])"),
        ("nF(-1, 0.1)", "nF(length, dlength[, radius])"),
        ("@Tp(1, 0)", "@Tp(x, y, z)"),
    ]:
        g = lpy(f"Axiom: {axiom}\nderivation length: 0\n")
        with pytest.raises(lsys3d.InterpretError, match=re.escape(message)):
            interpret(lsys3d.derive(g), g)


def test_lpy_get_iteration_nb_is_the_derivation_step_as_lpy_counts_it():
    """L-Py's Lsystem::__derive sets it to the step from 0 (decomposition too); interpretation sees the last step's."""
    g = lpy(
        """
def f(x):
    return x + getIterationNb()
Axiom: A(getIterationNb())
derivation length: 3
production:
A(x) --> B(getIterationNb()) A(f(10))
decomposition:
B(x) : produce C(x, getIterationNb())
interpretation:
C(x, y) --> D(x, y, getIterationNb())
endlsystem
"""
    )
    derived = lsys3d.derive(g)
    assert str(derived) == "C(0,0)C(1,1)C(2,2)A(12)"
    assert str(interpretation(g, derived)) == "D(0,0,2)D(1,1,2)D(2,2,2)A(12)"
    assert str(interpretation(g, lsys3d.derive(g, 1), iterations=1)) == "D(0,0,0)A(10)"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("def Start():\n    global x\n    x = 1\nAxiom: A\n", "plant.lpy:1:1: L-Py's Start() hook runs Python code"),
        ("import os\nAxiom: A\n", "plant.lpy:1:1: 'import os': the Python module 'os' is never run"),
        ("Axiom: A\nproduction:\nA :\n    for i in range(3):\n        nproduce F\n", "plant.lpy:4:5: Python's 'for'"),
        ("Axiom: A\nproduction:\nA :\n    print(1)\n    x.y = 3\n", "plant.lpy:5:5: this Python statement"),
        ("v = [1, 2]\nAxiom: F(v)\n", "unknown name 'v': 'v' is Python that lsys3d does not run (line 1"),
        ("Axiom: A\nproduction:\n?F(x,y,z) --> A\n", "?F, ?I and GetFrame queries (the whole frame) are not supported"),
        ("Axiom: A\ngroup 1:\n", "plant.lpy:2:1: 'group 1:' (rules that Python code switches on"),
        ("derivation length: 3\n", "plant.lpy:1:1: no 'Axiom:'"),
        ("Axiom: A\nwhile True:\n    pass\n", "plant.lpy:2:1: Python code ('while True:') is never run"),
        ("Axiom: A\nproduction:\nA << B --> C\n", "'<<' (L-Py's context of the string being built)"),
    ],
)
def test_lpy_refusals_name_the_line_and_the_construct(text, message):
    with pytest.raises(GrammarError, match=re.escape(message)):
        lpy(text)


def test_cpfg_productions_go_on_over_lines():
    """The vlab cpfg course writes the arrow on the next line, and successors over several lines."""
    text = """Lsystem: 1
derivation length: 2
Axiom: A(0)
A(t) : t < 1 {u = t + 1;}
\t--> B(u)
\t[+A(u)]
\tA(u)
B(x) --> F(x)
endlsystem
"""
    g = Grammar.from_text(text, source="p.l")
    assert list(g.rules) == ["A(t) : t < 1 {u = t + 1;} --> B(u) [+A(u)] A(u)", "B(x) --> F(x)"]
    assert str(lsys3d.derive(g)) == "F(1)[+A(1)]A(1)"
    with pytest.raises(GrammarError, match=r"p.l:2:1: expected a production"):
        Grammar.from_text("Axiom: A\nB C\nA --> B\n", source="p.l")


CPFG_PLANT = "Lsystem: 1\nderivation length: 2\naxiom: A\nA --> F[+A][-A]\nendlsystem\n"


@pytest.mark.parametrize(
    ("view", "why"),
    [
        (None, "no view file 'plant.v' beside it"),
        ("box: 1 1 1\n", "its view file 'plant.v' gives no 'angle increment:' (nor 'angle factor:')"),
        ("angle increment: 30\n", None),
    ],
)
def test_cpfg_without_a_view_file_warns_naming_the_default_angle(tmp_path, caplog, view, why):
    """cpfg's .l leaves the angle to its view file: without one the turns are by 90 degrees, and a warning says so."""
    path = tmp_path / "plant.l"
    path.write_text(CPFG_PLANT)
    if view is not None:
        (tmp_path / "plant.v").write_text(view)
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        g = Grammar.from_file(path)
    warnings = [r.getMessage() for r in caplog.records]
    if why is None:
        assert g.angle == 30 and warnings == []
        return
    assert g.angle == 90 and len(warnings) == 1
    assert warnings[0].startswith(f"warning: {path}: {why}, so turns use cpfg's default angle, 90 degrees")
    assert "angle increment: DEGREES" in warnings[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        assert Grammar.from_file(path, angle=45).angle == 45  # an angle given: nothing to warn about
    assert caplog.records == []


def test_abop_like_ls_refusal_lists_the_forms_it_reads(tmp_path):
    from lsys3d.lsystem.dialects.lparser import ABOP_LIKE_FORMS

    path = tmp_path / "plant.ls"
    path.write_text("axiom: F\nangle: 25.7\np1: F -> F[+F]F\n")
    with pytest.raises(GrammarError) as info:
        Grammar.from_file(path)
    message = str(info.value)
    assert (
        message.startswith(f"{path}:2:1: unknown line 'angle: 25.7' (write it 'angle=25.7');") and "\n" not in message
    )
    assert all(form in message for form in ABOP_LIKE_FORMS)
    path.write_text("axiom: F\nangle=25.7\np1: F -> F[+F]F\n")  # the spelling the message gives reads
    assert Grammar.from_file(path).angle == 25.7


def test_cpfg_preprocessor_blocks_include_and_view_file(tmp_path):
    (tmp_path / "sizes.h").write_text("#define LEN 2\n")
    (tmp_path / "plant.v").write_text("angle factor: 12\n")
    path = tmp_path / "plant.l"
    path.write_text(
        """/* a cpfg model */
#include "sizes.h"
#ifdef LEN
#define N 2
#else
#define N 5
#endif
Lsystem: 1
define: { W = LEN * 0.5; }
derivation length: N
Axiom: A(1)
ignore: +-
A(x) : {y = x * LEN;} y < 8 {z = y;} --> F(z)[+A(y)]A(y) : 1
homomorphism
maximum depth: 1
F(x) --> F(x)!(W)
endlsystem
"""
    )
    g = Grammar.from_file(path)
    assert g.dialect == "cpfg" and g.iterations == 2 and g.angle == 30 and g.defines["W"] == 1
    assert str(lsys3d.derive(g)) == "F(2)[+F(4)[+A(4)]A(4)]F(4)[+A(4)]A(4)"
    for text, message in [
        ('#include "../x.h"\n', "only files in the grammar's own folder"),
        ("#define F(x) x\naxiom: F(1,2)\n", "macro F(...) takes 1 arguments, not 2"),
        ("#define F(x) x\naxiom: F(1\n", "the arguments of macro F(...) are not closed on the line"),
        ("Lsystem: 1\naxiom: A\nendlsystem\nLsystem: 2\nStart: {n = 0;}\n", "Start: in a sub-L-system (lsystem: 2)"),
        ("#ifdef X\naxiom: A\n", "#if or #ifdef without #endif"),
        ("Lsystem: 1\nStart: {x[1] = 1;}\naxiom: A\n", "Start: block: arrays ('x[...]') are not supported"),
        ("Lsystem: 1\naxiom: A\nA == B\n", "expected a production"),
    ]:
        bad = tmp_path / "bad.l"
        bad.write_text(text)
        with pytest.raises(GrammarError, match=re.escape(message)):
            Grammar.from_file(bad)


def test_lparser_layouts_and_the_ls_forms_are_recognised():
    numeric = Grammar.from_text("# comment\n4\n25\n50\nAB\nA=+FA\nB=-FB\n@\nignored\n", source="x.ls")
    assert numeric.dialect == "lparser" and str(lsys3d.derive(numeric)) == "+F+F+F+FA-F-F-F-FB"
    keywords = Grammar.from_text("recursion 4\nangle 25\nthickness 50\naxiom AB\nrule A = +FA\nrule B=-FB\n", "x.ls")
    assert str(lsys3d.derive(keywords)) == str(lsys3d.derive(numeric))
    variables = Grammar.from_text("1\n30\n10\nL\na=30\nL={-(a)f+(a)f}\n@\n", source="x.ls")
    assert variables.defines == {"a": 30.0} and str(lsys3d.derive(variables)) == "{-(30)f+(30)f}"
    web = Grammar.from_text("#define R 2\naxiom: A(1)\ndlength: 2\np1: A(x) -> F(x)A(x*R)\n", source="x.ls")
    assert web.dialect == "abop" and str(lsys3d.derive(web)) == "F(1)F(2)A(4)"
    for text, message in [
        ("hello\nworld\n", "cannot tell which .ls format this is"),
        ("4\n25\n", "the file ends before the thickness"),
        ("4\n25\n50\n", "no axiom after the recursion depth, the angle and the thickness"),
        ("4\nX\n50\nA\n", "x.ls:2:1: expected the angle (a number), not 'X'"),
        ("4\n25\n50\nA\nA=B\nA=C\n", "a second rule for 'A' (the first is on line 5)"),
        ("4\n25\n50\nA\nAB=C\n", "expected a rule 'X=...'"),
    ]:
        with pytest.raises(GrammarError, match=re.escape(message)):
            Grammar.from_text(text, source="x.ls")


def test_lparser_rules_leave_a_rewritten_symbols_argument_as_lparser_does(caplog):
    """Lparser rewrites characters: 'f=_' makes f(300) into _(300), nothing; 'A=F' makes A(5) into F(5)."""
    g = Grammar.from_text("2\n30\n10\nf(300)A(5)B(1)C(2)\nf=_\nA=F\nB=[F]\nC=D\nD=F\n@\n", source="x.ls")
    assert g.rules[5:] == ("f(x1)=_", "A(x1)=F(x1)", "B(x1)=[F]", "C(x1)=D(x1)", "D(x1)=F(x1)")
    assert str(lsys3d.derive(g, 1)) == "_F(5)[F]D(2)"
    assert str(lsys3d.derive(g, 2)) == "_F(5)[F]F(2)"
    assert len(interpret(lsys3d.derive(g, 2), g)) == 3  # '_' draws nothing
    from lsys3d.pipeline import draw

    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        draw(g, 2, 0)
    assert "warning" not in caplog.text  # '_' means something in Lparser: no "symbols with no meaning"


def test_lparser_lengths_given_as_arguments_count_in_its_step_of_100():
    """K-3D's l_parser.cpp starts F's distance at 100: F(300) goes three steps, F one, Z half of one."""
    g = Grammar.from_text("0\n90\n10\nF(300)f(50)FZ(100)\n@\n", source="x.ls")
    sk = interpret(lsys3d.derive(g), g)
    np.testing.assert_allclose(np.linalg.norm(sk.end - sk.start, axis=1), [3.0, 1.0, 1.0])
    assert sk.end[-1][1] == pytest.approx(5.5)


def test_houdini_premise_variables_and_signs():
    g = Grammar.from_text(
        'dialect = "houdini"\npremise = "FA(0)"\nrules = ["A(i) : i < 2 = F[&A(i+1)]"]\n', source="h.toml"
    )
    assert str(lsys3d.derive(g, 3)) == "FF[&F[&A(2)]]"
    with pytest.raises(GrammarError, match=r"Houdini's predefined variable t: the age of the symbol"):
        Grammar(axiom="A(1)", rules=["A(x) = F(t)"], dialect="houdini")


def test_abop_labels_arrows_equality_and_empty_successors():
    g = Grammar(
        axiom="A(0)B",
        rules=["p1 : A(t) : t = 2 → [F]", "p2 : A(t) : * → A(t+1)", "p3 : B → *"],
        dialect="abop",
    )
    assert [str(s) for s in lsys3d.generations(g, 3)] == ["A(0)B", "A(1)", "A(2)", "[F]"]


# ---------------------------------------------------------------- mangled input
NATIVE = {
    ".lpy": "from math import *\nR = 2\nAxiom: A(1)\nderivation length: 3\nproduction:\nA(x) :\n  if x < R:\n"
    "    produce F(x)[+A(x*R)]\n  else:\n    produce F\nhomomorphism:\nF --> F\nendlsystem\n",
    ".l": "#define N 3\nLsystem: 1\nderivation length: N\naxiom: A(1)\nA(x) : x < 4 {y = x;} --> F(y)[+A(x+1)]\n"
    "homomorphism\nF --> F\nendlsystem\n",
    ".ls": "4\n25\n50\nA\nA=F[+A]-A\n@\n",
}
PAYLOADS = ["__import__('os').system('touch {canary}')", "open('{canary}', 'w')", "exec('x')", "eval('1')"]


@settings(max_examples=150, deadline=None)
@given(
    st.sampled_from(sorted(NATIVE)),
    st.lists(
        st.tuples(st.integers(0, 400), st.sampled_from([*"()[]{}:=<>-+%*#@!;,.\n \t'\"\\", "-->", "if ", "A("])),
        max_size=8,
    ),
    st.integers(0, 400),
)
def test_mangled_native_files_raise_only_grammar_errors(suffix, edits, cut):
    text = NATIVE[suffix]
    for at, piece in edits:
        at %= len(text) + 1
        text = text[:at] + piece + text[at:]
    text = text[: max(cut, len(text) // 2)]
    try:
        g = Grammar.from_text(text, source=f"mangled{suffix}")
    except GrammarError as exc:
        assert str(exc).startswith(f"mangled{suffix}") and "\n" not in str(exc)
        return
    try:
        lsys3d.derive(g, min(g.iterations, 3), max_modules=10_000)
    except lsys3d.LSystemError as exc:
        assert "\n" not in str(exc)


@pytest.mark.parametrize("suffix", sorted(NATIVE))
@pytest.mark.parametrize("payload", PAYLOADS)
def test_native_files_never_run_what_they_hold(tmp_path, suffix, payload):
    canary = tmp_path / "canary"
    code = payload.format(canary=canary)
    texts = {
        ".lpy": [f"{code}\nAxiom: A\n", f"x = {code}\nAxiom: F(x)\n", f"Axiom: A\nproduction:\nA :\n    {code}\n",
                 f"def f(x): return {code}\nAxiom: F(f(1))\n", f"Axiom: F({code})\n"],
        ".l": [f"#define X {code}\naxiom: A\n", f"axiom: A\nA : {{y = {code};}} --> B\n", f"axiom: F({code})\n"],
        ".ls": [f"2\n30\n10\nF({code})\n@\n", f"2\n30\n10\nA\nA=F({code})\n@\n"],
    }[suffix]  # fmt: skip
    for text in texts:
        try:
            g = Grammar.from_text(text, source=f"x{suffix}")
            lsys3d.derive(g, 1)
        except lsys3d.LSystemError:
            pass
        assert not canary.exists()


def test_the_readers_have_no_door_to_python():
    for name in ("lpy", "cpfg", "lparser", "common"):
        source = (Path(lsys3d.__file__).parent / "lsystem" / "dialects" / f"{name}.py").read_text()
        assert not re.search(r"(?<![\w.])(eval|exec|compile|getattr|__import__)\(|importlib|ast\.", source), name


def test_rules_without_weights_are_alternatives_only_in_lsys3d_notation():
    """In L-Py and cpfg the first rule that matches applies; lsys3d's own notation pools rules without weights."""
    lpy_g = lpy("Axiom: A A A A A A A A\nderivation length: 1\nproduction:\nA --> B\nA --> C\nendlsystem\n")
    assert str(lsys3d.derive(lpy_g)) == "BBBBBBBB"
    cpfg = Grammar.from_text("axiom: AAAAAAAA\nA --> B : 1\nA --> C : 1\nA --> D\n", source="p.l")
    assert set(str(lsys3d.derive(cpfg, 1, seed=2))) == {"B", "C"}  # weighted: stochastic; D never applies
    own = Grammar(axiom="A" * 40, rules=["A -> B", "A -> C"])
    assert set(str(lsys3d.derive(own, 1))) == {"B", "C"}


@pytest.mark.parametrize(
    ("dialect", "axiom"),
    [
        ("lpy", "F;F;(5)F,F@O(0.1)"),
        ("cpfg", "F;F;(5)F,F@O(0.2)"),
        ("lparser", "FcFc(5)F!(1)c(4)F"),
        ("houdini", "F'F'(5)F'(4)F"),
        ("abop", "F'F'(5)F'(4)F"),
    ],
)
def test_colour_commands_pick_the_materials_table(dialect, axiom):
    """Each dialect's colour symbols set the one material index of the turtle, which [materials] colours."""
    text = f"""dialect = "{dialect}"
axiom = "{axiom}"
[materials]
1 = {{ name = "one", base_color = [1, 0, 0] }}
5 = {{ name = "five", base_color = [0, 1, 0] }}
4 = {{ name = "four", base_color = [0, 0, 1] }}
"""
    grammar = Grammar.from_text(text, source=f"{dialect}.toml")
    tree = lsys3d.generate(grammar, sides=6, union=False)
    assert tree.skeleton.material.tolist() == [0, 1, 5, 4]
    assert sorted(set(tree.bark.face_material.tolist())) == [0, 1, 4, 5]
    assert [tree.materials.for_bark(i).name for i in (1, 5, 4)] == ["one", "five", "four"]
    assert tree.skeleton.organ_material.tolist() == ([4] if "@O" in axiom else [])
    again = Grammar.from_text(grammar_text(grammar))  # the provenance's TOML keeps the table
    assert again.materials == grammar.materials and again.dialect == dialect


# ---------------------------------------------------------------- issue 41: web .ls forms, Lparser2's keys
def test_the_web_tools_ls_form_is_recognised_by_its_settings_lines():
    from lsys3d.lsystem.dialects import webls

    text = (
        "/* a bush,\n   ABOP figure 1.24a */\nn=3; delta=25.7; stemsize = 0.2\nstep = 2\n"
        "axiom: F\np1: F -> F[+&(delta/2)F]F[-F]F\n"
    )
    assert webls.recognise(text)
    g = Grammar.from_text(text, source="bush.ls")
    assert (g.dialect, g.iterations, g.angle, g.turtle["width"], g.turtle["step"]) == ("cpfg", 3, 25.7, 0.2, 2.0)
    assert g.rules == ("F -> F[+&(delta/2)F]F[-F]F",)  # the label goes, the variable stays for the rule
    assert str(lsys3d.derive(g, 1)) == "F[+&(12.85)F]F[-F]F"
    # derivation length: wins over n, and 1 is the default
    assert Grammar.from_text("n=7\nderivation length: 2\naxiom: F\n", source="a.ls").iterations == 2
    assert Grammar.from_text("stemsize=1\naxiom: F\n", source="a.ls").iterations == 1
    # settings the older ABOP-like form writes too keep it (dialect abop), as before
    assert Grammar.from_text("delta=30\nn=2\naxiom: F\n", source="a.ls").dialect == "abop"
    # 'name: value' settings, as L-System Explorer also reads them
    colon = Grammar.from_text("Lsystem: 1\nstemsize: 0.3\ndelta: 45\naxiom: F\n", source="c.ls")
    assert (colon.dialect, colon.turtle["width"], colon.angle) == ("cpfg", 0.3, 45.0)
    # the older ABOP-like form (n=..,delta=.. with a comma) keeps its reader
    assert not webls.recognise("n=30,delta=22.5\naxiom: F\n")


def test_the_web_form_reads_blocks_and_refuses_what_it_cannot():
    text = "delta=30\nStart: {\n  k = 0;\n}\nStartEach: {k++;}\naxiom: A\np1: A : k < 3 --> FA\n"
    g = Grammar.from_text(text + "derivation length: 5\n", source="k.ls")
    assert str(lsys3d.derive(g)) == "FFA"
    for bad, fragment in [
        ("a1 = [0, 1]\naxiom: A\n", "holds a JavaScript value"),
        ("delta=30; stemsize=1\naxiom: A\nwhat is this\n", "unknown line 'what is this'"),
        ("delta=30; stemsize=1\nlsystem: 1\naxiom: A\nlsystem: 2\n", "sub-L-systems"),
        ('delta=30; stemsize=1\n#include "more.ls"\naxiom: A\n', "the preprocessor's #include is not supported"),
        ("delta=30; stemsize=1\nStart: n = 1;\naxiom: A\n", "expects a block of statements in braces"),
    ]:
        with pytest.raises(GrammarError) as info:
            Grammar.from_text(bad, source="bad.ls")
        assert fragment in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_lparser2_keys_read_as_lparser2c_does():
    text = (
        "recursion 2\nangle 20\nthickness 50\nmin_thickness 200\nswitch_yz 1\nshape 1\ntrace 0\nno_wait 1\n"
        "color 2 0 128 255\naxiom c(2)FA\nrule A = F!!!!!!!!!!F\n"
    )
    g = Grammar.from_text(text, source="port.ls")
    assert g.turtle["min_width"] == 200 / 1e4 and g.materials["2"] == {"base_color": "#0080ff"}
    _, skeleton = lsys3d.pipeline.draw(g, g.iterations, 0)
    # ten '!' take the width 0.5 to 0.5 * 0.7**10 = 0.014: under the floor, so drawn 0.02 wide
    assert skeleton.width_start.min() == pytest.approx(0.02)
    switched = Grammar.from_text(text.replace("switch_yz 1", "switch_yz 0"), source="port.ls")
    assert str(lsys3d.derive(switched)) == str(lsys3d.derive(g))
    for key, fragment in [("mutation 3", "random changes"), ("poly_limit 500", "a cap"), ("color 1 2", "four")]:
        with pytest.raises(GrammarError, match=fragment) as info:
            Grammar.from_text(text.replace("trace 0", key), source="port.ls")
        assert "\n" not in str(info.value)
    assert Grammar.from_text(text.replace("trace 0", "mutation 0"), source="port.ls").iterations == 2


def test_the_min_width_floor_is_off_by_default():
    g = Grammar(axiom="F!(0.001)F", rules=[])
    _, skeleton = lsys3d.pipeline.draw(g, 0, 0)
    assert skeleton.width_start.min() == pytest.approx(0.001)


def test_an_lparser_polygon_goes_on_after_the_branch_it_was_opened_in(caplog):
    """Lparser2.c: '[' and ']' save and restore the turtle, not the open polygon (poly_on, vcount, ver).

    Lapré's spiral_plant.ls leaves: a=[+a{.].C.}, C=gC.  Each '{' opens a polygon after the branch its a
    grew; the ']' that follows closes the branch around it and the polygon goes on taking vertices there,
    until its '}'.  Lparser writes every polygon with three recorded vertices (vcount > 3): all 5 here.
    Two of them hold one point twice (fewer than three distinct points, no area): lsys3d drops those
    with a warning and keeps the other 3, each with its three vertices.
    """
    g = Grammar.from_text("recursion 5\nangle 20\nthickness 10\naxiom F[a]\nrule a = [+a{.].C.}\nrule C = gC\n",
                          source="leaves.ls")  # fmt: skip
    assert str(lsys3d.derive(g)).count("{") == 5
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        _, skeleton = lsys3d.pipeline.draw(g, g.iterations, 0)
    assert skeleton.n_polygons == 3
    assert np.diff(skeleton.polygon_offsets).tolist() == [3, 3, 3]
    assert "dropped 2 leaf polygon(s)" in caplog.text
    # the vertex after ']' is where ']' put the turtle back: the first point of the polygon's enclosing branch
    first = skeleton.polygon_points[skeleton.polygon_offsets[:-1]]
    second = skeleton.polygon_points[skeleton.polygon_offsets[:-1] + 1]
    assert (np.linalg.norm(first - second, axis=1) > 0.1).all()
