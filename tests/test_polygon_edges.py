"""``[turtle] polygon_edges``: L-System Explorer's turtle draws the moves inside a polygon too (off by default)."""

from __future__ import annotations

import numpy as np

import lsys3d
from lsys3d import Grammar, derive
from lsys3d.turtle import TurtleOptions, interpret


def _both(axiom: str):
    grammar = Grammar(axiom=axiom, angle=90)
    modules = derive(grammar)
    return interpret(modules, grammar), interpret(modules, TurtleOptions.from_grammar(grammar, polygon_edges=True))


def test_moves_in_a_polygon_draw_with_polygon_edges():
    """{.F+F+F} : off, the three F are the polygon's vertices alone; on, each is a segment too, one chain."""
    plain, edged = _both("{.F+F+F}")
    assert (len(plain), len(edged)) == (0, 3)
    assert np.array_equal(plain.polygon_points, edged.polygon_points) and edged.n_polygons == 1
    assert edged.parent.tolist() == [-1, 0, 1]  # drawn one after another: one chain
    assert np.allclose(edged.start[1:], edged.end[:-1])


def test_a_move_without_drawing_breaks_the_chain_in_a_polygon_too():
    plain, edged = _both("{.F+f.+F.}")
    assert (len(plain), len(edged)) == (0, 2)
    assert edged.parent.tolist() == [-1, -1]
    assert len(edged.polygon_points) == len(plain.polygon_points) == 4


def test_outside_polygons_nothing_changes():
    """F[+F]F{.F+F.}F: the four F outside the polygon are the same segments either way; on, the two inside too."""
    plain, edged = _both("F[+F]F{.F+F.}F")
    assert (len(plain), len(edged)) == (4, 6)
    outside = [0, 1, 2, 5]  # in string order: F [+F] F { . F + F . } F
    for name in ("start", "end", "order", "width_start"):
        assert np.array_equal(getattr(plain, name), getattr(edged, name)[outside]), name
    assert np.array_equal(plain.polygon_points, edged.polygon_points)


def test_the_web_form_turns_it_on(tmp_path):
    """The web tools' .ls form is read as cpfg with L-System Explorer's turtle: every F and G draws."""
    path = tmp_path / "leaf.ls"
    path.write_text("delta=90\nstemsize=0.01\nn=0\naxiom: F{.F+F+G.}\n")
    grammar = lsys3d.Grammar.from_file(path)
    assert grammar.dialect == "cpfg" and grammar.turtle["polygon_edges"] is True
    skeleton = interpret(derive(grammar), grammar)
    assert len(skeleton) == 4 and skeleton.n_polygons == 1  # G draws, places no vertex
    assert "polygon_edges" not in lsys3d.Grammar.from_text('axiom = "F"').turtle
