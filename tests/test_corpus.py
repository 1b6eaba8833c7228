"""The corpus: native files of L-Py, cpfg, Lparser, Houdini and ABOP, read as they are written.

Each file's expectations (``tests/corpus/expected.toml``) were computed without lsys3d; the sources
of the files are in ``tests/corpus/README.md``.  At least 90% of the files read and match; every
other one is refused with one line naming what it needs.
"""

from __future__ import annotations

import logging
import tomllib
from collections import Counter
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
    return "warns" if "warns" in expected else "match"  # "repaired": read as its tool reads it, and matching


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
    # measured: 30 of 36 read and match (83%), 6 read with a warning, none is refused. Part B (predecessors of
    # several modules, sub-L-systems, macros): Snowflake, Sedge's four files, the two broken webls files (with
    # the repair in a warning). Part A (vlab's functions and curves, the view file's tropism, ring L-systems,
    # generalized cylinders, while loops in a rule's block): JumpingLamp, Lilac, WeepingBirch, Ring and
    # Horneophyton match, and Sedge's leaf and sedge ('_' drawn); TexturedSurfaces and Ridley read with a
    # warning (@Tx, ~l's scales; @!). The view file's surfaces and textures (@Tx) and ~l's three scales:
    # TexturedSurfaces matches (tests/test_cpfg_look.py). cpfg's @! (sides) and the view file's tropisms:
    # GeneralizedCylinder and Ridley match. L-System Explorer's turtle draws every F and G, in polygons too
    # ([turtle] polygon_edges): its polygon files draw what it draws, and the two broken ones (polygon-2,
    # polygon-6a: `repaired`) match with their repair in a warning. Tropisms warns (its @# contour is not drawn).
    assert (outcomes.count("match"), outcomes.count("warns"), outcomes.count("refused")) == (35, 1, 0), outcomes
    assert sum("repaired" in EXPECTED[name][0] for name in FRESH) == 2


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


def model_folder(name: str, expected: dict, folder: Path) -> Path:
    """The file as its model's folder holds it: copied into ``folder`` with the files it ``#include`` s under the
    names it gives them (``includes``: the corpus names each file after its model), and their view files."""
    if "includes" not in expected:
        return CORPUS / name
    path = CORPUS / name
    files = {expected["main"]: path.name, **expected["includes"]}
    for target, corpus_name in files.items():
        for suffix in (".l", ".v"):
            source = (path.parent / corpus_name).with_suffix(suffix)
            if source.is_file():
                (folder / target).with_suffix(suffix).write_bytes(source.read_bytes())
    return folder / expected["main"]


@pytest.mark.parametrize("name", REAL)
def test_each_gathered_file_reads_unmodified_and_matches(name, caplog, tmp_path):
    expected = EXPECTED[name][0]
    path = model_folder(name, expected, tmp_path)
    if "refused" in expected:
        assert_refused_in_one_line(path, expected["refused"])
        return
    grammar = lsys3d.Grammar.from_file(path)
    assert grammar.text == (CORPUS / name).read_bytes().decode("utf-8")  # byte for byte, CRLF kept
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
    if "sides" in expected:  # the sides the grammar sets (cpfg's @!) of the segments drawn
        assert sorted(set(skeleton.sides.tolist())) == expected["sides"]
    if "warns" in expected or "repaired" in expected:
        from lsys3d.pipeline import draw

        with caplog.at_level(logging.WARNING, logger="lsys3d"):
            draw(grammar, grammar.iterations, 0)
        message = expected.get("warns", expected.get("repaired"))
        assert any(message in r.getMessage() for r in caplog.records), caplog.text


@pytest.mark.parametrize("name", ["webls/real/polygons-polygon-2.ls", "webls/real/polygons-polygon-6a.ls"])
def test_strict_refuses_what_a_reader_repaired(name):
    """A file read as its tool reads it, mended (polygon-2's open branch, 6a's stray lines): --strict refuses."""
    from lsys3d.pipeline import draw

    grammar = lsys3d.Grammar.from_file(CORPUS / name)
    assert grammar.repairs and grammar.repairs[0].startswith(str(CORPUS / name) + ":")
    with pytest.raises(GrammarError) as info:
        draw(grammar, grammar.iterations, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    assert "L-System Explorer" in str(info.value) and "--strict" in str(info.value) and "\n" not in str(info.value)


def test_strict_turns_a_fresh_files_warning_into_an_error():
    """Tropisms reads with a warning (its contour, @#, is not drawn); --strict refuses it."""
    from lsys3d.pipeline import draw

    grammar = lsys3d.Grammar.from_file(CORPUS / "cpfg/real/manual-Tropisms-lsystem.l")
    with pytest.raises(GrammarError) as info:
        draw(grammar, grammar.iterations, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    assert "does not draw" in str(info.value) and "--strict" in str(info.value) and "\n" not in str(info.value)


def sedge_model(steps: int = 95) -> tuple[int, dict[str, int]]:
    """vlab's Sedge model (cpfg manual) simulated from its four files' rules, for its expectation; not lsys3d's engine.

    A walk from left to right as cpfg's Derive: the L-system on top of a stack rewrites each module
    (``?(n, s)`` pushes n after it is rewritten, ``$`` pops after), the first rule that matches applies and
    consumes its predecessor's modules (``spikef`` is six, ``leaf(..)`` four).  Returns the derived string's
    length and the count of some symbols.
    """
    rate, stemwidth, stemrate = 1.02, 0.0075, 1.06

    def word(text, last=()):
        return [(c, ()) for c in text[:-1]] + [(text[-1], tuple(last))]

    def main(s, i):
        sym, p = s[i]
        if sym == "A" and p[0] == 30:
            return 1, [("F", (1,)), ("/", (137.5,)), ("?", (3, 1.25)), *word("spikem"), ("$", ())]
        if sym == "A" and p[1] < 10:
            return 1, [("F", (1,)), ("A", (p[0] + 1, p[1] + 1))]
        if sym == "A" and p[1] == 10:
            a = p[0]
            branches = [("[", ()), ("L", (a,)), ("]", ()), ("[", ()), ("S", (a,)), ("]", ())]
            return 1, [("F", (1,)), ("/", (137.5,)), *branches, ("#", (stemwidth,)), ("A", (a + 1, 0))]
        if sym == "#" and p and i > 0 and p[0] < 200:
            return 1, [("#", (p[0] * stemrate,))]
        if sym == "S":
            a = p[0]
            top = [
                ("[", ()),
                ("^", (25,)),
                ("_", (-0.1,)),
                ("!", (0.3,)),
                ("F", ((30 - a) / 5,)),
                ("F", ((30 - a) / 5,)),
            ]
            return 1, [*top, ("_", (0,)), ("?", (2, 1.25)), *word("spikef"), ("$", ()), ("]", ())]
        if sym == "L":
            a = p[0]
            leaf = word("leaf", (a - 10, a, (a - 13) / 100))
            return 1, [("[", ()), ("^", (60,)), ("!", (0.1,)), ("?", (4, 1)), *leaf, ("$", ()), ("]", ())]
        if sym == "F" and len(p) == 1:
            return 1, [("F", (p[0] * rate,))] if p[0] < 2 else [("F", (p[0] * rate / 2,)), ("F", (p[0] * rate / 2,))]
        return 1, None

    def starts(s, i, text, arity):
        names = [m for m, _ in s[i : i + len(text)]]
        return names == list(text) and len(s[i + len(text) - 1][1]) == arity

    def female(s, i):
        sym, p = s[i]
        if starts(s, i, "spikef", 0):
            side = [("[", ()), ("&", (30,)), ("/", (180,)), ("~f", (2.25,)), ("#", (0.1,)), ("F", (0.5,)), ("]", ())]
            return 6, [*side, ("F", (0.1,)), ("/", (180,)), *side, ("/", (137.5,)), ("A", (0,))]
        if sym == "A" and len(p) == 1 and p[0] < 75:
            return 1, [("F", (0.2,)), ("[", ()), ("B", ()), ("]", ()), ("/", (137.5,)), ("A", (p[0] + 1,))]
        if sym == "B":
            seeds = [("[", ()), ("~f", (1,)), ("]", ()), ("/", (180,)), ("[", ()), ("~f", (1,)), ("]", ())]
            return 1, [("&", (35,)), *seeds, ("[", ()), ("~c", (1,)), ("#", (0.1,)), ("F", (0.5,)), ("]", ())]
        if sym == "F" and len(p) == 1 and p[0] < 1:
            return 1, [("F", (p[0] * 1.01,))]
        return 1, None  # &, ~f, ~c grow: the counts do not change

    def male(s, i):
        sym, p = s[i]
        if starts(s, i, "spikem", 0):
            return 6, [("A", (0,))]
        if sym == "A" and len(p) == 1 and p[0] < 55:
            return 1, [("F", (0.2,)), ("[", ()), ("B", ()), ("]", ()), ("/", (137.5,)), ("A", (p[0] + 1,))]
        if sym == "B":
            return 1, [("^", (5,)), ("[", ()), ("~n", (1,)), ("]", ())]
        return 1, None

    def leaf(s, i):
        sym, p = s[i]
        if starts(s, i, "leaf", 3):
            a, turn, t = s[i + 3][1]
            if a > 0:
                return 4, word("leaf", (a - 1, turn, t))
            return 4, [("[", ()), ("A", (a, a + turn, t)), ("]", ()), ("[", ()), ("B", (a, a + turn, t)), ("]", ())]
        if sym in "AB" and len(p) == 3:
            turn = "-" if sym == "A" else "+"
            side = [("[", ()), (turn, (90,)), ("f", (0.05,)), ("]", ())]
            inner = [("{", ()), (".", ()), ("F", (0.16,)), *([("/", (45,))] if p[0] == p[1] else [])]
            piece = [("{", ()), *side, (".", ()), *inner, *side[:3], ("}", ()), (".", ()), ("}", ()), ("]", ())]
            return 1, [*([("_", (p[2],))] if p[0] == p[1] else []), *piece, (",", ()), (sym, (p[0] + 1, *p[1:]))]
        return 1, None

    systems = {1: main, 2: female, 3: male, 4: leaf}
    string = [("/", (30,)), ("+", (10,)), ("#", (stemwidth,)), ("A", (4, 4))]
    for _ in range(steps):
        out, stack, i = [], [1], 0
        while i < len(string):
            sym, p = string[i]
            length, successor = systems[stack[-1]](string, i)
            out += string[i : i + length] if successor is None else successor
            if sym == "?" and p:
                stack.append(int(p[0]))
            elif sym == "$" and len(stack) > 1:
                stack.pop()
            i += length
        string = out
    counts = Counter(m for m, _ in string)
    return len(string), {k: counts[k] for k in ("F", "?", "$", "A", "~f", "~n", "{")}


def test_the_sedge_simulation_gives_the_stored_expectation():
    expected = EXPECTED["cpfg/real/manual-Sedge-sedge.l"][0]
    assert sedge_model() == (expected["modules"], expected["counts"])


def lilac_model() -> tuple[int, int, int, int, int]:
    """vlab's Lilac (cpfg manual) from its rules, for its expectation; not lsys3d's engine.

    The decomposition builds the whole twig from AXIOM (A_SW = 1): A(o,i) with i < max[o]-1 is an internode
    I, two branches A(o+1, max[o+1]-cnt[o][i]) and A(o,i+1); with i == max[o]-1 an internode and a floret K.
    The 13 steps only change the internodes' widths (the pipe model).  Returns the modules, the I, the K, the
    segments (each I's F, O's F, each K's F and G) and the organs (each K's ~c and four ~p).
    """
    most = [13, 7, 2, 1]
    count = [[7, 7, 7, 7, 6, 6, 6, 5, 4, 3, 2, 1, 0], [2, 2, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0], [1] + [0] * 12]
    found = {"I": 0, "K": 0}

    def apex(o: int, i: int) -> int:  # the modules A(o,i) becomes
        if i < most[o] - 1:
            found["I"] += 1
            j = most[o + 1] - count[o][i]
            return 1 + (4 + apex(o + 1, j)) + (4 + apex(o + 1, j)) + 1 + apex(o, i + 1)  # I [+/A] [-/A] /A
        if i == most[o] - 1:
            found["I"] += 1
            found["K"] += 1
            return 2  # I K
        return 1  # an A no rule rewrites

    found["I"] += 1  # O's I(0,0,0)
    modules = 4 + 3 + (5 + apex(0, 0)) + (4 + apex(0, 0))  # ^ / - ; and O's I F ; [/+/A] [-/A]
    segments = found["I"] + 1 + 2 * found["K"]
    return modules, found["I"], found["K"], segments, 5 * found["K"]


def test_the_lilac_model_gives_the_stored_expectation():
    expected = EXPECTED["cpfg/real/manual-Lilac-plant.l"][0]
    counts = expected["counts"]
    assert lilac_model() == (
        expected["modules"],
        counts["I"],
        counts["K"],
        expected["segments"],
        expected["organs"],
    )
