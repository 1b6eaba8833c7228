"""cpfg's C-like blocks (lsys3d.lsystem.blocks) and the derivation steps that read their globals."""

from __future__ import annotations

import inspect
import re

import numpy as np
import pytest

import lsys3d
from lsys3d import GrammarError, LimitError
from lsys3d.lsystem import blocks
from lsys3d.lsystem.blocks import parse_blocks
from lsys3d.lsystem.derive import interpretation


def run(start: str, **more) -> dict[str, float]:
    return parse_blocks({"start": start, **more}).run_start(0)[0]


def test_statements_assign_and_branch_as_c_does():
    values = run(
        "{ a = 7; b = a / 2; a += 1; a *= 2; a -= 6; a /= 5; c = (a > 1 && b < 4) * 10 + (a <= 1) * 20; "
        "n = 0; n++; n++; n--; "
        "if (n == 1) { d = 1; } else d = 2; if (n > 5) e = 1; else if (n > 0) e = 2; else e = 3; "
        "f = floor(7.9) + sqrt(16) + sin(90) + 2^3; }"
    )
    assert values == {"a": 2.0, "b": 3.5, "c": 10.0, "n": 1.0, "d": 1.0, "e": 2.0, "f": 7 + 4 + 1 + 8}


def test_loops_run_to_their_condition():
    values = run(
        "{ s = 0; for (i = 0; i < 10; i++) s += i; w = 1; while (w < 100) w = w * 3; "
        "k = 0; do { k = k + 5; } while (k < 12); t = 0; for (j = 3; j > 0; j--) { t = t + j; } }"
    )
    assert (values["s"], values["i"], values["w"], values["k"], values["t"], values["j"]) == (45, 10, 243, 15, 6, 0)


def test_a_loop_that_never_ends_is_stopped_with_one_line():
    program = parse_blocks({"start": "{ x = 0; while (1) x++; }"})
    with pytest.raises(LimitError) as info:
        program.run_start(0)
    assert "MAX_STATEMENTS" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("{ a[1] = 2; }", "arrays ('a[...]') are not supported"),
        ("{ x = ; }", "expected an expression"),
        ("{ x = y + 1; }", "unknown name 'y'"),
        ("{ foo(1); }", "function 'foo' is not supported in a block"),
        ("{ x = 1 }", "expected ';' after a statement"),
        ("{ if x > 1 y = 2; }", "expected '(' before the condition"),
        ('{ x = "text"; }', "a string is only allowed in printf"),
        ("{ x = 1; } }", "expected a statement, not '}'"),
        ("{ x = 1 / 0; }", "division by zero"),
        ("{ else x = 1; }", "'else' without 'if'"),
        ("{ x = 1; @ }", "unexpected character '@'"),
    ],
)
def test_what_a_block_cannot_do_is_refused_in_one_line(text, fragment):
    with pytest.raises(GrammarError) as info:
        parse_blocks({"start": text}).run_start(0)
    assert fragment in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_the_walker_never_hands_text_to_python():
    source = inspect.getsource(blocks)
    assert not re.search(r"(?<![.\w])(eval|exec|compile|__import__)\(", source)
    # a Python expression is only text the tokenizer does not know
    with pytest.raises(GrammarError):
        parse_blocks({"start": "{ x = __import__('os').getpid(); }"}).run_start(0)


def test_random_numbers_are_seeded_and_the_same_in_any_process():
    program = parse_blocks({"start": "{ srand(7); a = ran(1); b = ran(1); c = nran(10, 2); }"})
    values, seed = program.run_start(0)
    again, _ = parse_blocks({"start": "{ srand(7); a = ran(1); b = ran(1); c = nran(10, 2); }"}).run_start(99)
    other, _ = parse_blocks({"start": "{ srand(8); a = ran(1); b = ran(1); c = nran(10, 2); }"}).run_start(0)
    assert seed == 7 and values == again and values != other
    assert 0 <= values["a"] < 1 and values["a"] != values["b"]
    # a loop draws a new number each time round
    draws = parse_blocks({"start": "{ n = 0; s = 0; while (n < 5) { s = s + ran(1); n++; } }"}).run_start(3)[0]
    assert 0 < draws["s"] < 5


def test_srand_is_read_in_start_only():
    with pytest.raises(GrammarError, match="srand"):
        parse_blocks({"start_each": "{ srand(3); }"})


def test_start_each_and_end_each_frame_every_step():
    program = parse_blocks(
        {
            "start": "{ n = 0; e = 0; }",
            "start_each": "{ n = n + 1; }",
            "end_each": "{ e = n * 10; }",
            "end": "{ n = -1; }",
        }
    )
    steps, final = program.steps(3, seed=0)
    assert [(s["n"], s["e"]) for s in steps] == [(1, 0), (2, 10), (3, 20)]
    assert final == {"n": -1.0, "e": 30.0}
    assert program.step_names == {"n", "e"}


CPFG = """#define STEPS 5
Lsystem: 1
derivation length: STEPS
Start: {n = 0; LEN = 2;}
StartEach: {n = n + 1;}
EndEach: {done = n;}
Axiom: A
A : n < 3 --> F(LEN)A
A : n >= 3 --> F(n)[+B]A
B --> B
homomorphism
B --> F(done)
endlsystem
"""


def test_the_rules_of_each_step_read_the_globals_of_that_step():
    g = lsys3d.Grammar.from_text(CPFG, source="counter.l")
    assert dict(g.blocks) == {"start": "{n = 0; LEN = 2;}", "start_each": "{n = n + 1;}", "end_each": "{done = n;}"}
    derived = lsys3d.derive(g)
    # steps 1 and 2: n < 3; steps 3-5 read n = 3, 4, 5; LEN, set only by Start, is a constant
    assert str(derived) == "F(2)F(2)F(3)[+B]F(4)[+B]F(5)[+B]A"
    # the homomorphism reads the values after the last EndEach: done = 5
    assert str(interpretation(g, derived)).count("F(5)") == 4
    assert str(lsys3d.derive(g, 2)) == "F(2)F(2)A"


def test_the_blocks_survive_toml_and_replace():
    from lsys3d.provenance import grammar_text

    g = lsys3d.Grammar.from_text(CPFG, source="counter.l")
    again = lsys3d.Grammar.from_text(grammar_text(g), source="again.toml")
    assert str(lsys3d.derive(again)) == str(lsys3d.derive(g))
    assert str(lsys3d.derive(g.replace(iterations=3))) == "F(2)F(2)F(3)[+B]A"


def test_a_global_is_not_a_fixed_point():
    """A string that rewrites to itself may change later when the globals do (no early stop)."""
    text = "Lsystem: 1\nderivation length: 4\nStart: {n = 0;}\nStartEach: {n++;}\nAxiom: A\nA : n > 3 --> B\n"
    assert str(lsys3d.derive(lsys3d.Grammar.from_text(text, source="late.l"))) == "B"


def test_seed_lines_and_srand_set_the_derivation_seed():
    base = "Lsystem: 1\nderivation length: 1\n{}Axiom: A\nA --> F(ran(1))\nendlsystem\n"
    seeded = lsys3d.Grammar.from_text(base.format("seed: 2454\n"), source="s.l")
    srand = lsys3d.Grammar.from_text(base.format("#define SEED 2454\nStart: {srand(SEED);}\n"), source="s.l")
    assert seeded.seed == srand.seed == 2454
    assert str(lsys3d.derive(seeded)) == str(lsys3d.derive(srand))
    assert str(lsys3d.derive(seeded)) != str(lsys3d.derive(seeded, seed=1))


def test_a_rule_that_assigns_a_changing_global_is_refused():
    text = "Lsystem: 1\nStartEach: {n = n + 1;}\nAxiom: A\nA : {n = n * 2;} n > 1 --> B\n"
    with pytest.raises(GrammarError, match="assigns the global variable 'n'") as info:
        lsys3d.Grammar.from_text(text, source="p.l")
    assert "\n" not in str(info.value)


def test_block_errors_point_at_the_file():
    with pytest.raises(GrammarError) as info:
        lsys3d.Grammar.from_text("Lsystem: 1\nStart: {a = 1; b = a + ;}\nAxiom: A\n", source="p.l")
    assert str(info.value).startswith("p.l:2:") and "Start: block" in str(info.value)


def test_cpfgs_beta_and_binomial_random_numbers_have_their_distributions():
    """bran(a, b) by Cheng's algorithm BA (cpfg's utility.c brand), biran(n, p) as n trials; seeded."""
    g = lsys3d.Grammar(axiom="A" * 4000, rules=["A --> B(bran(5, 16), biran(10, 0.3), fabs(-2))"], dialect="cpfg")
    params = lsys3d.derive(g, 1).params.reshape(-1, 3)
    beta, binomial = params[:, 0], params[:, 1]
    assert ((beta > 0) & (beta < 1)).all() and abs(beta.mean() - 5 / 21) < 0.01
    assert abs(beta.var() - 5 * 16 / (21**2 * 22)) < 0.001
    assert set(np.unique(binomial)) <= set(range(11)) and abs(binomial.mean() - 3.0) < 0.1
    assert (params[:, 2] == 2).all()
    assert (lsys3d.derive(g, 1).params == params.ravel()).all()  # the same numbers again
    for bad, fragment in [("bran(0, 1)", "bran: the shapes"), ("biran(2.5, 0.5)", "biran: n must be")]:
        with pytest.raises(lsys3d.DerivationError, match=fragment):
            lsys3d.derive(lsys3d.Grammar(axiom="A", rules=[f"A --> B({bad})"], dialect="cpfg"), 1)
