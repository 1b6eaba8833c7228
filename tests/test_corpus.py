"""The corpus: native files of L-Py, cpfg, Lparser, Houdini and ABOP, read as they are written.

Each file's expectations (``tests/corpus/expected.toml``) were computed without lsys3d; the sources
of the files are in ``tests/corpus/README.md``.  At least 90% of the files read and match; every
other one is refused with one line naming what it needs.
"""

from __future__ import annotations

import logging
import tomllib
from pathlib import Path

import pytest

import lsys3d
from lsys3d import GrammarError, LSystemError
from lsys3d.lsystem.derive import interpretation
from lsys3d.turtle import interpret

CORPUS = Path(__file__).parent / "corpus"
EXPECTED = tomllib.loads((CORPUS / "expected.toml").read_text(encoding="utf-8"))
GRAMMARS = sorted(
    p.relative_to(CORPUS).as_posix() for p in CORPUS.glob("*/*") if p.suffix in (".lpy", ".l", ".ls", ".toml")
)
# files gathered verbatim from public repositories (README.md: where each comes from, and its licence)
REAL = sorted(p.relative_to(CORPUS).as_posix() for p in CORPUS.glob("*/real/*") if p.suffix in (".lpy", ".l", ".ls"))


def test_every_file_has_its_expectations_and_the_corpus_is_large_enough():
    assert sorted(EXPECTED) == sorted(GRAMMARS + REAL)
    assert len(GRAMMARS) >= 40
    refused = [name for name in GRAMMARS if "refused" in EXPECTED[name][0]]
    assert len(refused) <= 0.1 * len(GRAMMARS), refused
    for dialect in ("lpy", "cpfg", "lparser", "houdini", "abop"):
        assert sum(name.startswith(dialect + "/") for name in GRAMMARS) >= 5, dialect


def assert_refused_in_one_line(path, fragment: str) -> None:
    """Reading ``path`` raises GrammarError with one line that contains ``fragment``."""
    with pytest.raises(GrammarError) as info:
        lsys3d.Grammar.from_file(path)
    message = str(info.value)
    assert fragment in message and "\n" not in message, message


@pytest.mark.parametrize("name", GRAMMARS)
def test_each_file_reads_as_written_and_matches(name, caplog):
    expected = EXPECTED[name][0]
    path = CORPUS / name
    if "refused" in expected:
        assert_refused_in_one_line(path, expected["refused"])
        return
    grammar = lsys3d.Grammar.from_file(path)
    assert grammar.text == path.read_text(encoding="utf-8")  # read unmodified: the provenance is the file
    derived = lsys3d.derive(grammar)
    if "string" in expected:
        assert str(derived) == expected["string"]
    if "modules" in expected:
        assert len(derived) == expected["modules"]
    for symbol, count in expected.get("counts", {}).items():
        assert derived.count(symbol) == count, symbol
    with caplog.at_level(logging.ERROR, logger="lsys3d"):
        skeleton = interpret(interpretation(grammar, derived), grammar)
    assert len(skeleton) == expected["segments"]
    assert skeleton.n_polygons == expected.get("polygons", 0)
    assert skeleton.n_organs == expected.get("organs", 0)


def test_a_corpus_file_grows_through_the_cli(tmp_path):
    from lsys3d.cli import main

    out = tmp_path / "tree.glb"
    assert main(["generate", str(CORPUS / "lpy" / "binary_tree.lpy"), "-n", "5", "--no-union", "-o", str(out)]) == 0
    assert out.stat().st_size > 0


@pytest.mark.parametrize("name", [n for n in GRAMMARS if "refused" not in EXPECTED[n][0]])
def test_a_file_rendered_as_toml_grows_the_same_string(name):
    """What golden recipes and provenance keep of a native grammar gives the same plant back."""
    from lsys3d.provenance import grammar_text

    grammar = lsys3d.Grammar.from_file(CORPUS / name)
    again = lsys3d.Grammar.from_text(grammar_text(grammar), source="rendered.toml")
    assert again.dialect == grammar.dialect
    assert str(lsys3d.derive(again, seed=3)) == str(lsys3d.derive(grammar, seed=3))


def test_random_draws_do_not_depend_on_where_the_rule_stands():
    text = "Axiom: A A A A\nderivation length: 1\nproduction:\nA :\n    r = random.uniform(1, 2)\n    produce F(r)\n"
    a = lsys3d.Grammar.from_text(text, source="a.lpy")
    b = lsys3d.Grammar.from_text("\n\n# moved down\n" + text, source="b.lpy")
    assert str(lsys3d.derive(a, seed=9)) == str(lsys3d.derive(b, seed=9))


def naive_derive(axiom: str, rules: dict[str, str], n: int, names=()) -> list[str]:
    """Parallel rewriting of module names, written for these checks and nothing else.

    A module is one of ``names`` (longest first) or one character; an argument list after it is
    dropped, so the counts are exact only for unconditional rules, which is what it is used for.
    """
    names = sorted(names, key=len, reverse=True)

    def tokens(text: str) -> list[str]:
        out, i = [], 0
        while i < len(text):
            if text[i].isspace():
                i += 1
                continue
            name = next((m for m in names if text.startswith(m, i)), text[i])
            out.append(name)
            i += len(name)
            if text.startswith("(", i):
                depth = 0
                while True:
                    depth += {"(": 1, ")": -1}.get(text[i], 0)
                    i += 1
                    if depth == 0:
                        break
        return out

    successors = {k: tokens(v) for k, v in rules.items()}
    string = tokens(axiom)
    for _ in range(n):
        string = [t for m in string for t in successors.get(m, [m])]
    return string


def test_the_naive_rewriter_knows_a_textbook_count():
    dragon = naive_derive("FX", {"X": "X+YF+", "Y": "-FX-Y"}, 10)
    assert (dragon.count("F"), dragon.count("X"), len(dragon)) == (1024, 512, 4094)
    assert naive_derive("F(1)Frame(2)", {}, 0, names=["Frame"]) == ["F", "Frame"]


def _outcome(name: str) -> str:
    expected = EXPECTED[name][0]
    if "refused" in expected or "interpret_refused" in expected:
        return "refused"
    return "warns" if "warns" in expected else "match"


# issue 41's fresh sample: every L-system file of vlab's cpfg manual models and of L-System Explorer's
# brackets/ and polygons/ examples (README.md), gathered after the rest
FRESH = [n for n in REAL if n.startswith("cpfg/real/manual-") or n.startswith("webls/real/")]


def test_the_gathered_files_are_counted_honestly():
    """Issue 14's goal is 90% of real files read and matching; this is where the corpus stands."""
    first = [name for name in REAL if name not in FRESH]
    outcomes = [_outcome(name) for name in first]
    assert len(first) >= 40
    for dialect in ("lpy", "cpfg", "lparser"):
        assert sum(name.startswith(dialect + "/real/") for name in first) >= 10, dialect
    # measured: see README.md; a regression (one more file refused) fails here
    assert outcomes.count("match") >= 51, outcomes.count("match")
    assert outcomes.count("match") >= 0.9 * len(first)


def test_the_fresh_sample_is_counted_honestly():
    """Issue 41's fresh sample: 36 files; README.md gives the rate before and after (the goal, 90%, is not met)."""
    outcomes = [_outcome(name) for name in FRESH]
    assert len(FRESH) == 36
    # measured: 24 of 36 read and match (67%), 4 read with a warning, 8 are refused in one line (Horneophyton's
    # ?H, refused by the reader when the sample was gathered, reads since query modules came, and matches since
    # generalized cylinders are drawn; JumpingLamp and TexturedSurfaces read since vlab's functions, WeepingBirch
    # matches since the view file's tropism, Ring since ring L-systems, Ridley reads since curves and while
    # loops in a rule's block, with a warning for @!)
    assert (outcomes.count("match"), outcomes.count("warns"), outcomes.count("refused")) == (24, 4, 8), outcomes


def shedding_model(steps: int = 320) -> tuple[int, int, int, int]:
    """vlab's Shedding model (cpfg manual) simulated from its rules, for its expectation; not lsys3d's engine.

    Start: age = 0, StartEach: age = age + 1; returns the derived string's length, the F the cut leaves
    (segments), the K (one polygon each in the homomorphism) and the U (one @o organ each).
    """
    plastochron, colour, angle, turn, lifetime, max_age, stem, leaf = 5, 255, 0, 0.78, 120, 260, 4, 4

    def cut(string):
        out, i = [], 0
        while i < len(string):
            if string[i][0] != "%":
                out.append(string[i])
                i += 1
                continue
            depth = 0
            while i < len(string) and not (string[i][0] == "]" and depth == 0):
                depth += {"[": 1, "]": -1}.get(string[i][0], 0)
                i += 1
        return out

    string = [("!", (stem,)), ("A", (0,))]
    for age in range(1, steps + 1):
        out = []
        for symbol, p in cut(string):
            if symbol == "A" and p[0] < plastochron and age < max_age:
                out += [("F", ()), ("A", (p[0] + 1,))]
            elif symbol == "A" and age < max_age:
                leaf_branch = [("[", ()), ("X", (lifetime,)), ("-", (angle,)), ("!", (leaf,)), ("B", ()), ("]", ())]
                out += [("F", ()), *leaf_branch, ("/", (180,)), ("A", (0,))]
            elif symbol == "A":
                out.append(("K", (0,)))
            elif symbol == "K":
                out.append(("K", (p[0] + 1,)))
            elif symbol == "B":
                out += [(",", (colour,)), ("F", ()), ("B", ())]
            elif symbol == "X":
                out += [("X", (p[0] - 1,))] if p[0] > 0 else [("U", ()), ("%", ())]
            elif symbol == "," and p:
                out.append((",", (p[0] - 1,)))
            elif symbol in "+-" and p:
                out.append((symbol, (p[0] + turn,)))
            else:
                out.append((symbol, p))
        string = out
    drawn = cut(string)
    return (
        len(string),
        sum(m[0] == "F" for m in drawn),
        sum(m[0] == "K" for m in drawn),
        sum(m[0] == "U" for m in drawn),
    )


def test_the_shedding_simulation_gives_the_stored_expectation():
    expected = EXPECTED["cpfg/real/manual-Shedding-fractal.l"][0]
    assert shedding_model() == (expected["modules"], expected["segments"], expected["polygons"], expected["organs"])


@pytest.mark.parametrize("name", REAL)
def test_each_gathered_file_reads_unmodified_and_matches(name, caplog):
    expected = EXPECTED[name][0]
    path = CORPUS / name
    if "refused" in expected:
        assert_refused_in_one_line(path, expected["refused"])
        return
    grammar = lsys3d.Grammar.from_file(path)
    assert grammar.text == path.read_bytes().decode("utf-8")  # byte for byte, CRLF kept
    derived = lsys3d.derive(grammar)
    if "naive" in expected:
        naive = expected["naive"]
        string = naive_derive(naive["axiom"], naive["rules"], naive["n"], naive.get("names", ()))
        assert len(derived) == len(string)
        for symbol in set(string):
            assert derived.count(symbol) == string.count(symbol), symbol
        segments = sum(string.count(symbol) for symbol in expected["draws"]) if "draws" in expected else None
    elif "string" in expected:
        assert str(derived) == expected["string"]
        segments = None
    elif "between" in expected:  # a stochastic model: bounds that hold whatever the draws
        for symbol, (low, high) in expected["between"].items():
            assert low <= derived.count(symbol) <= high, symbol
        segments = sum(derived.count(symbol) for symbol in expected["draws"])
        if "per_polygon" in expected:  # each polygon's moves place its vertices: they are no segments
            segments -= expected["per_polygon"] * derived.count("{")
            expected = {**expected, "polygons": derived.count("{")}
    else:
        assert len(derived) == expected["modules"]
        for symbol, count in expected["counts"].items():
            assert derived.count(symbol) == count, symbol
        segments = None
    segments = expected.get("segments", segments)
    if "interpret_refused" in expected:
        with pytest.raises(LSystemError) as info:
            interpret(interpretation(grammar, derived), grammar)
        assert expected["interpret_refused"] in str(info.value) and "\n" not in str(info.value)
        return
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        if expected.get("queries"):  # query modules: the turtle's answers fed back between the steps
            from lsys3d.pipeline import draw

            skeleton = draw(grammar, grammar.iterations, 0)[1]
        else:
            skeleton = interpret(interpretation(grammar, derived), grammar)
    if segments is not None:
        assert len(skeleton) == segments
    if "polygons" in expected:
        assert skeleton.n_polygons == expected["polygons"]
    if "organs" in expected:
        assert skeleton.n_organs == expected["organs"]
    if "warns" in expected:
        from lsys3d.pipeline import draw

        with caplog.at_level(logging.WARNING, logger="lsys3d"):
            draw(grammar, grammar.iterations, 0)
        assert any(expected["warns"] in r.getMessage() for r in caplog.records), caplog.text


def test_strict_turns_a_fresh_files_warning_into_an_error():
    """GeneralizedCylinder reads with a warning (its generalized cylinders are not drawn); --strict refuses it."""
    from lsys3d.pipeline import draw

    grammar = lsys3d.Grammar.from_file(CORPUS / "cpfg/real/manual-GeneralizedCylinder-fractal.l")
    with pytest.raises(GrammarError) as info:
        draw(grammar, grammar.iterations, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    assert "does not draw" in str(info.value) and "--strict" in str(info.value) and "\n" not in str(info.value)
