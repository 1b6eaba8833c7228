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


def test_the_gathered_files_are_counted_honestly():
    """Issue 14's goal is 90% of real files read and matching; this is where the corpus stands."""
    outcomes = [_outcome(name) for name in REAL]
    assert len(REAL) >= 40
    for dialect in ("lpy", "cpfg", "lparser"):
        assert sum(name.startswith(dialect + "/real/") for name in REAL) >= 10, dialect
    # measured: see README.md; a regression (one more file refused) fails here
    assert outcomes.count("match") >= 51, outcomes.count("match")
    assert outcomes.count("match") >= 0.9 * len(REAL)


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
        skeleton = interpret(interpretation(grammar, derived), grammar)
    if "warns" in expected:
        from lsys3d.pipeline import draw

        with caplog.at_level(logging.WARNING, logger="lsys3d"):
            draw(grammar, grammar.iterations, 0)
        assert any(expected["warns"] in r.getMessage() for r in caplog.records), caplog.text
        return
    if segments is not None:
        assert len(skeleton) == segments
    if "polygons" in expected:
        assert skeleton.n_polygons == expected["polygons"]
