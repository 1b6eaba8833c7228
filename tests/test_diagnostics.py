"""No silent misreading: the grammar's findings, their exact text, and --strict."""

from __future__ import annotations

import logging
import subprocess
import sys

import pytest

import lsys3d
from lsys3d import Grammar, GrammarError
from lsys3d.pipeline import draw


def warnings_of(grammar: Grammar, caplog, **flat) -> list[str]:
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        draw(grammar, grammar.iterations, 0, lsys3d.GenerateOptions.from_flat(**flat))
    return [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize("name", lsys3d.list_presets())
def test_presets_draw_without_findings(name, caplog):
    """Every preset means what it says (the DOG demonstrations are strings of letters, not plants)."""
    found = warnings_of(lsys3d.load_preset(name), caplog)
    if name in ("dog", "dog-growing"):
        assert found and all("symbols with no rule and no turtle meaning" in f for f in found)
    else:
        assert found == []


def test_the_exact_texts(caplog):
    g = Grammar(axiom="F_[%A]Q", rules=["A -> F"], source="grammar.toml", iterations=1)
    # '%' cuts (it is gone before the turtle); '_' and 'Q' mean nothing here, in the order they appear
    assert warnings_of(g, caplog) == ["warning: grammar.toml: symbols with no rule and no turtle meaning: '_', 'Q'"]
    g = Grammar(axiom="!(10)F(6)", source="abop.toml")
    assert warnings_of(g, caplog) == [
        "warning: abop.toml: the widest branch (10) is 1.67 times the size of the plant (6): are its widths in "
        "another unit? Set [turtle] width_unit (e.g. width_unit = 0.01) or width"
    ]
    g = Grammar(axiom="F@O@c", source="organs.toml")
    assert warnings_of(g, caplog) == []  # spheres and discs are built in
    g = Grammar(axiom="F~l~k@O~l", source="organs.lpy", dialect="lpy", surfaces={"k": {"model": "k.obj"}})
    assert warnings_of(g, caplog) == [
        "warning: organs.lpy: organs with no [surfaces] model, drawn as the leaf: 'l' "
        "(give each a [surfaces] entry of that name)"
    ]
    assert warnings_of(g.replace(turtle={"width_unit": 0.01}, axiom="!(10)F(6)"), caplog) == []


def test_ignored_parameters_and_unsupported_commands_are_named(caplog):
    g = Grammar(axiom="F(1, 0.2)}(1)", dialect="lpy", source="tree.lpy")
    assert warnings_of(g.replace(axiom="F(1, 0.2)"), caplog) == [
        "warning: tree.lpy: module parameters the turtle ignores: 'F' (topradius)"
    ]
    g = Grammar(axiom="F SetGuide(1)", dialect="lpy", source="tree.lpy")
    assert warnings_of(g, caplog) == ["warning: tree.lpy: L-Py turtle commands that lsys3d does not draw: 'SetGuide'"]


def test_strict_makes_the_first_finding_an_error(caplog):
    g = Grammar(axiom="F_", source="grammar.toml")
    with pytest.raises(GrammarError, match=r"^grammar.toml: symbols with no rule and no turtle meaning: '_' \(an "):
        warnings_of(g, caplog, strict=True)


def test_the_cli_prints_warnings_and_strict_exits_1(tmp_path):
    path = tmp_path / "grammar.toml"
    path.write_text('axiom = "F_%"\n')

    def run(*args):
        return subprocess.run([sys.executable, "-m", "lsys3d", *args], capture_output=True, text=True)

    proc = run("stats", str(path))
    assert proc.returncode == 0
    assert proc.stderr == f"lsys3d: warning: {path}: symbols with no rule and no turtle meaning: '_'\n"
    proc = run("stats", str(path), "--strict")
    assert proc.returncode == 1
    assert proc.stderr == (
        f"lsys3d: error: {path}: symbols with no rule and no turtle meaning: '_' (an error with --strict)\n"
    )
    proc = run("stats", "-q", str(path))
    assert proc.returncode == 0 and proc.stderr == ""
