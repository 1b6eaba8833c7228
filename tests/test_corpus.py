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
from lsys3d import GrammarError
from lsys3d.derive import interpretation
from lsys3d.turtle import interpret

CORPUS = Path(__file__).parent / "corpus"
EXPECTED = tomllib.loads((CORPUS / "expected.toml").read_text(encoding="utf-8"))
GRAMMARS = sorted(
    p.relative_to(CORPUS).as_posix() for p in CORPUS.glob("*/*") if p.suffix in (".lpy", ".l", ".ls", ".toml")
)


def test_every_file_has_its_expectations_and_the_corpus_is_large_enough():
    assert sorted(EXPECTED) == GRAMMARS
    assert len(GRAMMARS) >= 40
    refused = [name for name in GRAMMARS if "refused" in EXPECTED[name][0]]
    assert len(refused) <= 0.1 * len(GRAMMARS), refused
    for dialect in ("lpy", "cpfg", "lparser", "houdini", "abop"):
        assert sum(name.startswith(dialect + "/") for name in GRAMMARS) >= 5, dialect


@pytest.mark.parametrize("name", GRAMMARS)
def test_each_file_reads_as_written_and_matches(name, caplog):
    expected = EXPECTED[name][0]
    path = CORPUS / name
    if "refused" in expected:
        with pytest.raises(GrammarError) as info:
            lsys3d.Grammar.from_file(path)
        message = str(info.value)
        assert expected["refused"] in message and "\n" not in message, message
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
