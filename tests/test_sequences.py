"""cpfg's left-to-right rewriting: predecessors of several modules, sub-L-systems, and the C preprocessor's macros.

Expectations by hand, from cpfg's generate.c (PredDiff, FindProd, CheckPred) as docs/dialects/cpfg.md describes it.
"""

from __future__ import annotations

import numpy as np
import pytest

import lsys3d
from lsys3d import DerivationError, Grammar, GrammarError
from lsys3d.lsystem.dialects.macros import MAX_LENGTH, MacroError, expand, parse_definition
from lsys3d.lsystem.sequences import MAX_NESTING


def cpfg(axiom: str, rules, **fields) -> Grammar:
    return Grammar(axiom=axiom, rules=rules, dialect="cpfg", **fields)


@pytest.mark.parametrize(
    ("axiom", "rules", "expected"),
    [
        ("AXF(3)BXF(1)", ["XF(x) --> G(x)"], "AG(3)BG(1)"),  # both modules replaced by the successor
        ("AAA", ["AA --> B"], "BA"),  # the earlier match wins, the walk goes on after it
        ("AAAA", ["AA --> B"], "BB"),
        ("XXF(2)", ["XF(x) --> G(x)", "X --> Y"], "YG(2)"),  # the first X has no F after it
        ("XF(2)", ["X --> Y", "XF(x) --> G(x)"], "YF(2)"),  # the first rule that matches applies
        ("XF(2)F(1)", ["XF(x) --> G(x)", "F(x) --> H"], "G(2)H"),  # the consumed F is not rewritten alone
        ("X[F(2)]", ["XF(x) --> G(x)"], "X[F(2)]"),  # one for one: no bracket stepped over
        ("XF(1)XF(5)", ["XF(x) : x > 2 --> G(x)"], "XF(1)G(5)"),  # the condition reads every module's parameters
        ("XFGXFH", ["XF > G --> Y"], "YGXFH"),  # the right context follows the whole predecessor
        ("AXFBXF", ["A < XF --> Y"], "AYBXF"),  # and the left context stands before it
        ("leaf(1,2)", ["leaf(a,b) --> F(a+b)"], "F(3)"),  # a cpfg name of four modules
    ],
)
def test_a_predecessor_of_several_modules_matches_as_cpfgs_walk(axiom, rules, expected):
    assert str(lsys3d.derive(cpfg(axiom, rules), 1)) == expected


def test_the_consumed_modules_stay_consumed_over_steps_and_with_a_trace():
    g = cpfg("AB", ["AB --> ABAB"])
    assert str(lsys3d.derive(g, 3)) == "AB" * 8
    from lsys3d.lsystem.ages import derive_with_ages

    modules, _ = derive_with_ages(g, 3, 0)
    assert str(modules) == "AB" * 8


def test_other_dialects_keep_one_module_predecessors():
    with pytest.raises(GrammarError, match="the predecessor must be one module"):
        Grammar(axiom="XF", rules=["XF -> G"])


def test_sub_lsystems_rewrite_the_modules_between_their_call_and_end():
    rules = ["lsystem: 1", "A --> B", "B --> M", "lsystem: 2", "B --> S", "A --> T", "lsystem: 3", "B --> U"]
    g = cpfg("B?(2,1)AB?(3)B$B$B", rules)
    # main: the first B and the last; 2: A and B after ?(2) and the B after the inner $; 3: the B inside
    assert str(lsys3d.derive(g, 1)) == "M?(2,1)TS?(3)U$S$M"


def test_a_sub_lsystems_homomorphism_applies_inside_it_only():
    g = cpfg("F?(2)F$F", ["lsystem: 1"], homomorphism=["F --> G", "lsystem: 2", "F --> H"])
    assert str(lsys3d.lsystem.derive.interpretation(g, g.axiom_modules)) == "G?(2)H$G"


def test_an_unmatched_end_and_an_unknown_sub_lsystem():
    g = cpfg("A$A", ["lsystem: 1", "A --> B", "lsystem: 2", "A --> C"])
    assert str(lsys3d.derive(g, 1)) == "B$B"  # an unmatched $ changes nothing (cpfg warns and stays)
    with pytest.raises(DerivationError, match=r"calls sub-L-system 7, which the grammar does not have \(its L-sys"):
        lsys3d.derive(cpfg("?(7)A", ["lsystem: 1", "A --> B", "lsystem: 2", "A --> C"]), 1)
    with pytest.raises(GrammarError, match="need the main one's first"):
        cpfg("A", ["A --> B", "lsystem: 2", "A --> C"])


def test_sub_lsystems_nest_a_bounded_depth():
    deep = "?(2)" * (MAX_NESTING + 1) + "A"
    with pytest.raises(DerivationError, match="nested more than"):
        lsys3d.derive(cpfg(deep, ["lsystem: 1", "lsystem: 2", "A --> B"]), 1)


def test_a_cpfg_file_with_sub_lsystems_reads_and_renders_as_toml():
    from lsys3d.provenance import grammar_text

    text = (
        "#define CALL ?(2,1)B$\nLsystem: 1\nderivation length: 2\naxiom: A\nA --> F[CALL]A\nendlsystem\n"
        "Lsystem: 2\naxiom: Q\nderivation length: 9\nB --> FB\nendlsystem\n"
    )
    g = Grammar.from_text(text, source="plant.l")
    assert g.axiom == "A" and g.iterations == 2
    assert str(lsys3d.derive(g)) == "F[?(2,1)FB$]F[?(2,1)B$]A"
    again = Grammar.from_text(grammar_text(g), source="again.toml")
    assert str(lsys3d.derive(again)) == str(lsys3d.derive(g))


# ---------------------------------------------------------------- the C preprocessor's macros
def macros(*definitions: str) -> dict:
    return {m.name: m for m in map(parse_definition, definitions)}


@pytest.mark.parametrize(
    ("definitions", "text", "expected"),
    [
        (["S ?(2,1.25)spikef$"], "A --> F S", "A --> F ?(2,1.25)spikef$"),
        (["S x"], "SS S_ 1S 2e5S .5S S", "SS S_ 1S 2e5S .5S x"),  # whole names; a number's letters stay
        (["ang(o,i) (o*10+i)"], "+(ang(1, (2+3)))", "+((1*10+(2+3)))"),  # arguments with parentheses
        (["ang(o) (o)", "B ang(B)"], "B", "(B)"),  # not expanded again inside itself
        (["f(x) [x]"], "f +(f)", "f +(f)"),  # a macro with parameters, named without them, stays
        (["g(x) x", "h(y) g(y)g(y)"], "h(h(1))", "11 11".replace(" ", "")),
    ],
)
def test_macros_expand_as_the_c_preprocessor(definitions, text, expected):
    assert expand(text, macros(*definitions)) == expected


def test_macro_expansion_is_bounded():
    text = "D(" * 24 + "x" + ")" * 24
    with pytest.raises(MacroError, match=r"longer than|more than"):
        expand(text, macros("D(x) x x"))
    assert len(expand("D(D(x))", macros("D(x) x x"))) == 7
    assert MAX_LENGTH >= 1 << 20
    with pytest.raises(MacroError, match="not closed on the line"):
        expand("D(x", macros("D(x) x"))


def test_a_cpfg_file_with_macros_reads_them():
    text = (
        "#define N 4\n#define ang(i) (10*i/(N-1))\n#define APEX A(0)\n"
        "Lsystem: 1\nderivation length: 2\naxiom: APEX\nA(i) --> F[+(ang(i))]A(i+1)\nendlsystem\n"
    )
    g = Grammar.from_text(text, source="plant.l")
    assert g.defines["N"] == 4 and "ang" not in g.defines
    assert str(lsys3d.derive(g)) == "F[+(0)]F[+(3.333333)]A(2)"


# ---------------------------------------------------------------- arrays, '=' in a right context
def test_cpfg_arrays_are_constants_the_rules_index():
    text = (
        "#define M 2\nLsystem: 1\ndefine: { array len[M][3] = {1, 2, 3,\n 4, 5}; array max[2] = {3, 1}; }\n"
        "derivation length: 5\naxiom: A(0,0)\nA(o,i) : i < max[o] --> F(len[o][i])A(o, i+1)\n"
        "A(o,i) : i == max(o, 3) && o < 1 --> [A(o+1, 0)]\nendlsystem\n"
    )
    g = Grammar.from_text(text, source="plant.l")
    assert g.defines["len"].tolist() == [[1, 2, 3], [4, 5, 0]]  # C's: the values missing are 0
    assert str(lsys3d.derive(g)) == "F(1)F(2)F(3)[F(4)A(1,1)]"
    from lsys3d.provenance import grammar_text

    again = Grammar.from_text(grammar_text(g), source="again.toml")
    assert str(lsys3d.derive(again)) == str(lsys3d.derive(g))
    bad = Grammar.from_text(text.replace("i < max[o]", "i < 4"), source="plant.l")
    with pytest.raises(DerivationError, match=r"index 3 of array 'len' outside 0\.\.2 in parameter 'len\[o\]\[i\]'"):
        lsys3d.derive(bad)


@pytest.mark.parametrize(
    ("defines", "message"),
    [
        ({"a": [[1, 2], [3]]}, "must be a list of numbers"),
        ({"a": [1, float("inf")]}, "not finite"),
        ({"a": [0] * 100_001}, "more than 100000"),
        ({"pi": [1, 2]}, "define name 'pi' is reserved"),
    ],
)
def test_array_defines_are_checked(defines, message):
    with pytest.raises(GrammarError, match=message):
        Grammar(axiom="F(a[0])", defines=defines)


def test_an_array_needs_its_indices():
    with pytest.raises(GrammarError, match=r"array 'a' needs 2 index\(es\)"):
        Grammar(axiom="F(a[0])", defines={"a": [[1, 2]]})
    assert str(lsys3d.derive(Grammar(axiom="F(a[0][1])", defines={"a": [[1, 2]]}), 0)) == "F(2)"


def test_equals_in_a_right_context_skips_to_the_branch_end():
    rules = ["A > [B=]E --> X"]
    assert str(lsys3d.derive(cpfg("A[B[C]D]E", rules), 1)) == "X[B[C]D]E"
    assert str(lsys3d.derive(cpfg("A[C]E", rules), 1)) == "A[C]E"
    # without '=', cpfg's ']' is the next module past whole branches: D stands before it (RconDiff)
    strict = ["A > [B]E --> X"]
    assert str(lsys3d.derive(cpfg("A[B[C]D]E", strict), 1)) == "A[B[C]D]E"
    assert str(lsys3d.derive(cpfg("A[B[C]]E", strict), 1)) == "X[B[C]]E"
    own = Grammar(axiom="A[B[C]D]E", rules=["A > [B]E -> X"])  # lsys3d's ']' skips the rest of the branch
    assert str(lsys3d.derive(own, 1)) == "X[B[C]D]E"
    with pytest.raises(GrammarError, match="must come before"):
        cpfg("A", ["A > B= --> X"])
    assert str(lsys3d.derive(cpfg("A=", ["= --> B"]), 1)) == "AB"  # elsewhere '=' is a module


def test_a_cpfg_turn_reads_its_first_parameter():
    from lsys3d.lsystem.derive import interpretation
    from lsys3d.turtle import interpret

    one, two = (cpfg(f"+(90{extra})F", [], angle=30) for extra in ("", ",0"))
    a, b = (interpret(interpretation(g, g.axiom_modules), g) for g in (one, two))
    assert (a.end == b.end).all()


def test_the_cpfg_turtle_scales_a_sub_lsystems_part():
    """interpret.c: ?(n, s) multiplies lengths, widths and surfaces by s (the width at once) until its $."""
    from lsys3d.lsystem.derive import interpretation
    from lsys3d.turtle import interpret

    g = cpfg("#(1)F?(2,2)F(3)#(0.5)~l(1)?(3,0.5)F$F$F", ["lsystem: 1", "lsystem: 2", "lsystem: 3"])
    sk = interpret(interpretation(g, g.axiom_modules), g)
    lengths = np.linalg.norm(sk.end - sk.start, axis=1)
    assert np.allclose(lengths, [1, 6, 1, 2, 1])
    assert np.allclose(sk.width_start, [1, 2, 0.5, 1, 0.5])  # ?(2,2) doubles the width, #(0.5) sets 0.5 * 2
    assert np.allclose(sk.organ_size, [2])
    # without parameters '?' is no call, and an unmatched '$' does nothing: no scale
    plain = cpfg("F?F$F", [])
    assert np.allclose(np.linalg.norm(np.diff(interpret(plain.axiom_modules, plain).end, axis=0), axis=1), [1, 1])
