"""Parsing grammar files and rule notation, with the positions of every error."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import lsys3d
from lsys3d import Grammar, GrammarError
from lsys3d.lsystem.expr import EvalError, ExprSyntaxError, parse_expression


def write(tmp_path: Path, text: str, name: str = "g.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# -- rule notation -------------------------------------------------------------------------------------------
def test_arrow_and_equals_are_the_same():
    a = Grammar(axiom="F", rules=["F -> F-F++F-F"])
    b = Grammar(axiom="F", rules=["F = F-F++F-F"])
    assert a.productions[0].successor == b.productions[0].successor


def test_blanks_between_modules_are_insignificant():
    spaced = Grammar(axiom="F [ + F ] F", rules=["F -> F [ +F ] F"])
    tight = Grammar(axiom="F[+F]F", rules=["F -> F[+F]F"])
    assert str(lsys3d.derive(spaced, 2)) == str(lsys3d.derive(tight, 2))


def test_rule_parts():
    g = Grammar(axiom="A(1)", rules=["B(a) < A(x) > C(c) : x > 1 && a < c -> A(x - 1)B(a) : 2"])
    p = g.productions[0]
    assert p.left[0].symbol == "B" and p.left[0].formals == ("a",)
    assert p.predecessor.symbol == "A" and p.predecessor.formals == ("x",)
    assert p.right[0].symbol == "C"
    assert p.condition is not None and p.weight == 2.0
    assert [m.symbol for m in p.successor] == ["A", "B"]
    assert p.formals == ("a", "x", "c")


def test_star_condition_means_always():
    g = Grammar(axiom="A(1)", rules=["A(x) : * -> A(x + 1)"])
    assert g.productions[0].condition is None
    assert str(lsys3d.derive(g, 3)) == "A(4)"


def test_empty_successor_deletes():
    g = Grammar(axiom="ABA", rules=["B ->"])
    assert str(lsys3d.derive(g, 1)) == "AA"


def test_defines_fold_into_expressions():
    g = Grammar(axiom="A(1)", rules=["A(l) -> A(l * R)"], defines={"R": 1.5, "S": "R * 2"})
    assert g.defines["S"] == 3.0
    assert str(lsys3d.derive(g, 2)) == "A(2.25)"


def test_non_ascii_symbols():
    g = Grammar(axiom="αβ", rules=["α -> αβ", "β -> α"])
    assert str(lsys3d.derive(g, 3)) == "αβααβαβα"


def test_from_text_and_from_file_agree(tmp_path):
    text = 'axiom = "X"\niterations = 3\nangle = 25\nrules = ["X -> F[+X]F[-X]+X", "F -> FF"]\n'
    a = Grammar.from_text(text)
    b = Grammar.from_file(write(tmp_path, text))
    assert str(lsys3d.derive(a)) == str(lsys3d.derive(b))
    assert a.iterations == 3 and a.angle == 25


def test_turtle_table_is_kept():
    g = Grammar.from_text('axiom = "F"\n[turtle]\nheading = 0\ndraw = "FG"\n')
    assert g.turtle["heading"] == 0 and g.turtle["draw"] == "FG"


# -- expressions ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1 + 2 * 3", 7),
        ("(1 + 2) * 3", 9),
        ("2 ^ 3 ^ 2", 512),
        ("2 ** 3", 8),
        ("-2 ^ 2", -4),
        ("7 / 2", 3.5),
        ("1 < 2 and 3 >= 3", 1),
        ("1 < 2 && 3 > 3", 0),
        ("0 || 2 == 2", 1),
        ("not 0", 1),
        ("!1", 0),
        ("1 != 1 or not (2 <= 1)", 1),
        ("sqrt(16) + abs(-2) + floor(1.5) + ceil(1.2)", 9),
        ("min(3, 4) * max(3, 4)", 12),
        ("atan2(1, 1) * 4 / pi", 1),
        ("exp(log(5))", 5),
        ("sin(pi / 2) + cos(0) + tan(0) + asin(1) * 2 / pi + acos(1) + atan(0)", 3),
        ("1e3 + .5", 1000.5),
    ],
)
def test_expression_values(text, expected):
    assert parse_expression(text).evaluate({})[0] == pytest.approx(expected)


def test_expressions_are_vectorised():
    e = parse_expression("x > 1 and y < 2", names=["x", "y"])
    out = e.evaluate({"x": np.array([0.0, 2.0, 3.0]), "y": np.array([1.0, 1.0, 5.0])}, size=3)
    assert out.tolist() == [0.0, 1.0, 0.0]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("__import__('os').system('touch x')", "unexpected character"),
        ("x.__class__", "attribute access"),
        ("lambda: 1", "unexpected character ':'"),
        ("[i for i in range(3)]", "unexpected"),
        ("open(1)", "unknown function 'open'"),
        ("eval(x)", "unknown function 'eval'"),
        ("1 +", "ends too early"),
        ("(1", r"expected '\)', found end"),
        ("1 < 2 < 3", "cannot be chained"),
        ("sqrt(1, 2)", "takes 1 argument"),
        ("sqrt", "needs arguments"),
        ("(" * 100 + "1" + ")" * 100, "nested deeper"),
        ("1+" * 3000 + "1", "longer than"),
        ("", "empty expression"),
    ],
)
def test_expressions_reject_code(text, message):
    with pytest.raises(ExprSyntaxError, match=message):
        parse_expression(text, names=["x"])


@pytest.mark.parametrize(
    ("text", "message"),
    [("1 / 0", "division by zero"), ("sqrt(-1)", "square root"), ("log(0)", "logarithm"), ("10 ^ 400", "finite")],
)
def test_expression_numeric_errors(text, message):
    with pytest.raises(EvalError, match=message):
        parse_expression(text).evaluate({})


def test_grammar_file_never_runs_code(tmp_path):
    canary = tmp_path / "canary"
    payloads = [
        f"__import__('os').system('touch {canary}')",
        f"open('{canary}', 'w')",
        "().__class__.__bases__[0].__subclasses__()",
        "(lambda: 1)()",
        "[x for x in (1, 2)]",
    ]
    for payload in payloads:
        text = f"axiom = \"F(1)\"\nrules = ['F(x) -> F({payload})']\n"
        with pytest.raises(GrammarError):
            Grammar.from_text(text)
        with pytest.raises(GrammarError):
            Grammar(axiom="F(1)", rules=[f"F(x) : {payload} -> F"])
    assert not canary.exists()


# -- errors with file:line:col -------------------------------------------------------------------------------
ERROR_CASES = [
    # (file text, line, col, message fragment)
    ('axiom = "F"\nrules = [\n  "F -> F[+F",\n]\n', 3, 10, "unbalanced '['"),
    ('axiom = "F"\nrules = [\n  "F -> F]+F",\n]\n', 3, 10, "unbalanced ']'"),
    ('axiom = "F[F"\n', 1, 11, "unbalanced '[' in axiom"),
    ('axiom = "F"\nrules = ["F F"]\n', 2, 14, "expected '->'"),
    ('axiom = "A(1)"\nrules = [\n    "A(x) -> B(y)",\n]\n', 3, 16, "unknown name 'y'"),
    ('axiom = "A(1,2)"\nrules = ["A(x) -> B"]\n', 1, 10, "wrong arity"),
    ('axiom = "A(1)"\nrules = ["A(x) -> A(x)A(1,2)"]\n', 2, 23, "wrong arity"),
    ('axiom = "F"\nrules = ["F -> F : 0"]\n', 2, 20, "weight must be positive"),
    ('axiom = "F"\nrules = ["F -> F : -1"]\n', 2, 20, "weight must be positive"),
    ('axiom = "F\nrules = []\n', 1, 11, "TOML syntax error"),
    ('rules = ["F -> F"]\n', 1, 1, "missing 'axiom'"),
    ('axiom = ""\n', 1, 10, "axiom is empty"),
    ('axiom = "F"\nrulez = []\n', 2, 1, "unknown key 'rulez'"),
    ('axiom = "F"\nrules = ["A B -> C"]\n', 2, 11, "predecessor must be one module"),
    ('axiom = "F"\nrules = ["-> C"]\n', 2, 11, "missing predecessor"),
    ('axiom = "F"\nrules = ["A(1) -> C"]\n', 2, 13, "must be names"),
    ('axiom = "F"\nrules = ["A(x) : -> C"]\n', 2, 17, "empty condition"),
    ('axiom = "F"\nrules = ["A(x) : x >> 1 -> C"]\n', 2, 21, "bad condition"),
    ('axiom = "F"\nrules = ["A(x, x) -> C"]\n', 2, 13, "used twice"),
    ('axiom = "F"\nrules = ["A(x -> C"]\n', 2, 12, "unclosed '('"),
    ('axiom = "F"\nrules = ["[ -> C"]\n', 2, 11, "bracket cannot be a predecessor"),
    ('axiom = "F"\nrules = ["A > -> C"]\n', 2, 13, "empty right context"),
    ('axiom = "F"\niterations = -1\n', 2, 1, "'iterations' must be"),
    ('axiom = "F"\nangle = "x"\n', 2, 1, "'angle' must be"),
    ('axiom = "F"\nrules = "F -> F"\n', 2, 1, "must be a list"),
    ('axiom = "F(1/0)"\n', 1, 10, "division by zero"),
]


@pytest.mark.parametrize(("text", "line", "col", "message"), ERROR_CASES)
def test_errors_point_at_file_line_col(tmp_path, text, line, col, message):
    path = write(tmp_path, text)
    with pytest.raises(GrammarError) as info:
        Grammar.from_file(path)
    err = info.value
    assert message in str(err)
    assert str(err).startswith(f"{path}:{line}:{col}: "), str(err)
    assert (err.line, err.col) == (line, col)


def test_error_positions_from_python_api():
    with pytest.raises(GrammarError, match=r"^rules\[1\]:1:11: unknown name 'q'"):
        Grammar(axiom="A(1)", rules=["A(x) -> A(x)", "A(x) -> B(q)"])


def test_escaped_toml_strings_keep_columns(tmp_path):
    # the \" escape takes two characters in the file but one in the value
    path = write(tmp_path, 'axiom = "F"\nrules = ["F -> F\\"(y)"]\n')
    with pytest.raises(GrammarError) as info:
        Grammar.from_file(path)
    assert (info.value.line, info.value.col) == (2, 20)


def test_grammar_size_limit(tmp_path):
    path = write(tmp_path, 'axiom = "F"\n' + "#" * (lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES + 1))
    with pytest.raises(GrammarError, match="more than"):
        Grammar.from_file(path)


def test_parameter_count_limit():
    args = ",".join(["1"] * (lsys3d.lsystem.grammar.MAX_PARAMETERS + 1))
    with pytest.raises(GrammarError, match="parameters, more than"):
        Grammar(axiom=f"A({args})")


def test_missing_file_is_a_grammar_error(tmp_path):
    with pytest.raises(GrammarError, match=r"nope\.toml: no such grammar file"):
        Grammar.from_file(tmp_path / "nope.toml")
    with pytest.raises(GrammarError, match="the grammar file is a folder"):
        Grammar.from_file(tmp_path)


# -- presets -------------------------------------------------------------------------------------------------
def test_presets_are_found_through_importlib_resources():
    names = lsys3d.list_presets()
    for required in ("dog", "dog-growing", "koch", "snowflake", "tree", "plant", "koch-stochastic"):
        assert required in names
    for required in ("abop-1.24a", "abop-1.24f", "hilbert3d", "bush", "monopodial", "context-1.31a"):
        assert required in names
    assert lsys3d.DEFAULT_PRESET in names


@pytest.mark.parametrize("name", lsys3d.list_presets())
def test_every_preset_parses(name):
    g = lsys3d.load_preset(name)
    assert g.name == name
    assert g.description


def test_load_prefers_an_existing_path(tmp_path):
    path = write(tmp_path, 'axiom = "Q"\n', name="koch.toml")
    assert str(lsys3d.derive(lsys3d.load(path))) == "Q"
    assert lsys3d.load("koch").name == "koch"
    with pytest.raises(GrammarError, match="no bundled preset"):
        lsys3d.load("no-such-preset")


# ---------------------------------------------------------------- what the dialects brought to every grammar
def test_condition_blocks_hold_local_variables_between_tests():
    g = Grammar(axiom="A(1)", rules=["A(x) : {y = x * 2; z = y + 1} z > 2 {w = z * 10} -> B(w)"])
    p = g.productions[0]
    assert p.condition is None and [s[0] for s in p.steps] == ["let", "let", "test", "let"]
    assert str(lsys3d.derive(g, 1)) == "B(30)"
    # x += e is x = x + (e); a test over a local narrows what the rest sees
    g = Grammar(axiom="A(1)A(5)", rules=["A(x) : {y = x; y += 10} y < 12 -> B(y)"])
    assert str(lsys3d.derive(g, 1)) == "B(11)A(5)"


@pytest.mark.parametrize(
    ("rule", "message"),
    [
        ("A(x) : {y == 1} -> B", "each statement reads 'name = expression'"),
        ("A(x) : {y = } -> B", "nothing assigned to 'y'"),
        ("A(x) : {y += 1} -> B", "'y' += before 'y' has a value"),
        ("A(x) : {sin = 1} -> B", "'sin' is reserved"),
        ("A(x) : {y = 1 -> B", "'{' without '}'"),
        ("A(x) : y } -> B", "'}' without '{'"),
        ("A(x) : {y = 1} q > 1 -> B", "unknown name 'q'"),
        ("A(x) -> B(uniform(1, 2)) : uniform(1, 2)", "random functions are not allowed in a weight"),
        ("* -> B", "'*' (any module) can stand in a context, not as the predecessor"),
        ("A << B -> C", "'<<' (L-Py's context of the string being built) is not supported"),
    ],
)
def test_condition_block_errors(rule, message):
    with pytest.raises(GrammarError, match=re.escape(message)):
        Grammar(axiom="A(1)", rules=[rule])


def test_star_is_any_module_in_a_context_and_nothing_as_a_successor():
    g = Grammar(axiom="F+F-+F", rules=["* < + > * -> -", "* < - > F -> +", "A -> *"])
    assert str(lsys3d.derive(g, 1)) == "F-F--F"  # every "+"; "-" only before F
    assert str(lsys3d.derive(Grammar(axiom="+F", rules=["* < + > * -> -"]), 1)) == "-F"
    assert len(lsys3d.derive(Grammar(axiom="AB", rules=["A -> *", "B -> * : 2"]), 1)) == 0
    g = Grammar(axiom="XAY", rules=["X < A > * -> B"])
    assert str(lsys3d.derive(g, 1)) == "XBY"


def test_declared_module_names_are_read_by_longest_match():
    g = Grammar(axiom="FLeaf(1)LeafyA", rules=["Leaf(x) -> Leaf(x + 1)"], modules=["Leaf", "Leafy"])
    assert g.axiom_modules.symbol(1) == "Leaf" and g.axiom_modules.symbol(2) == "Leafy"
    assert str(lsys3d.derive(g, 2)) == "FLeaf(3)LeafyA"
    with pytest.raises(GrammarError, match="is not a module name"):
        Grammar(axiom="F", modules=["Le af"])


def test_ignore_and_consider_take_names():
    g = Grammar(axiom="B Leaf A", rules=["B < A -> C"], ignore="Leaf", modules=["Leaf"])
    assert str(lsys3d.derive(g, 1)) == "BLeafC"
    g = Grammar(axiom="B Leaf + A", rules=["B < A -> C"], consider="AB", modules=["Leaf"])
    assert str(lsys3d.derive(g, 1)) == "BLeaf+C"


def test_functions_are_pure_expressions():
    g = Grammar(axiom="A(2)", rules=["A(x) -> A(twice(x) + k)"], functions=["twice(v) = 2 * v"], defines={"k": 1})
    assert str(lsys3d.derive(g, 2)) == "A(11)"
    for bad, message in [
        ("f(x) = ", "empty expression"),
        ("sin(x) = x", "'sin' is reserved"),
        ("f(x, x) = x", "names a parameter twice"),
        ("f(x) = g(x)", "unknown function 'g'"),
        ("f = 1", "name(parameters) = expression"),
    ]:
        with pytest.raises(GrammarError, match=re.escape(message)):
            Grammar(axiom="A", functions=[bad])


def test_random_functions_are_refused_where_a_constant_is_needed():
    with pytest.raises(GrammarError, match="not allowed in the axiom"):
        Grammar(axiom="A(ran(1))")
    with pytest.raises(GrammarError, match="a define is a constant"):
        Grammar(axiom="A", defines={"k": "uniform(0, 1)"})


def test_toml_keys_of_the_dialects(tmp_path):
    text = """
dialect = "houdini"
premise = "A"
rules = ["A = AB"]
homomorphism = ["B -> F"]
homomorphism_depth = 2
decomposition = ["C -> D"]
decomposition_depth = 3
consider = "AB"
modules = ["Leaf"]
functions = ["f(x) = x"]
"""
    g = Grammar.from_text(text)
    assert g.axiom == "A" and g.dialect == "houdini" and g.homomorphism_depth == 2 and g.decomposition_depth == 3
    for bad, message in [
        ('axiom = "A"\npremise = "B"\n', "both 'axiom' and 'premise'"),
        ('axiom = "A"\ndialect = "fractint"\n', "unknown dialect 'fractint' (known: lsys3d, abop, lpy"),
        ('axiom = "A"\ndecomposition_depth = 0\n', "'decomposition_depth' must be a whole number from 1 to 10000"),
        ('axiom = "A"\nhomomorphism = "B -> F"\n', "'homomorphism' must be a list"),
    ]:
        with pytest.raises(GrammarError, match=re.escape(message)):
            Grammar.from_text(bad, source="plant.toml")
