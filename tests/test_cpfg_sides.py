"""cpfg's ``@!(n)``: the sides of the tubes, generalized cylinders, spheres and discs that follow (blackbox.c).

Expectations by hand from blackbox.c (``cylinder_sides = parm1 ? (int)parameter1 : 8``, at least 3; the
turtle's state, so ``[`` saves it and ``]`` restores it) and OpenGL's ``gluSphere(r, n, n / 2 + 1)``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import lsys3d
from lsys3d.look.lod import prune
from lsys3d.look.organs import organs, skeleton_organs, uv_sphere
from lsys3d.lsystem.derive import interpretation
from lsys3d.mesh.sweep.sweep import sweep
from lsys3d.turtle import interpret


def _skeleton(axiom: str):
    text = f"Lsystem: 1\nderivation length: 0\nAxiom: {axiom}\nendlsystem\n"
    grammar = lsys3d.Grammar.from_text(text, source="sides.l")
    return interpret(interpretation(grammar, lsys3d.derive(grammar)), grammar)


def test_the_sides_in_force_follow_the_turtles_stack():
    sk = _skeleton("F @!(5) F [ @!(12) +F @O(1) [ @! F ] F ] F @!(2) F @!(7.9) F @!(5000) F @O(2)")
    assert sk.sides.tolist() == [0, 5, 12, 8, 12, 5, 3, 7, 1024]
    assert sk.organ_sides.tolist() == [12, 1024]


def test_a_grammar_without_sides_keeps_none():
    sk = _skeleton("F [ +F @O(1) ] F")
    assert sk.sides is None and sk.organ_sides is None


def test_the_sweep_gives_each_run_its_sides():
    sk = _skeleton("F F @!(5) F F [ +F @!(11) F ] F")
    tubes = sweep(sk)
    # the axis: 2 segments of the default 8 sides, then 3 of 5; the branch: one of 5, one of 11
    per_tube = sorted(zip(tubes.chain.tolist(), tubes.sides.tolist(), strict=True))
    assert sorted(s for _, s in per_tube) == [5, 5, 8, 11]
    assert len(set(tubes.chain.tolist())) == 2  # two chains, each cut where its sides change


def test_sides_of_zero_sweep_as_no_sides():
    """0 is "the sweep's own": a skeleton whose sides are all 0 sweeps byte for byte as one without."""
    sk = _skeleton("F [ +F F ] F &F")
    plain, zeros = sweep(sk), sweep(replace(sk, sides=np.zeros(len(sk), np.int32)))
    assert np.array_equal(plain.points, zeros.points) and np.array_equal(plain.faces, zeros.faces)
    assert np.array_equal(plain.sides, zeros.sides)


def test_pruning_keeps_the_sides_of_the_kept_segments():
    sk = _skeleton("#(1) @!(6) F [ !(0.01) @!(4) +F ] F")
    pruned = prune(sk, 0.5)
    assert len(pruned) == 2 and pruned.sides.tolist() == [6, 6]


@pytest.mark.parametrize("n", [3, 4, 7, 12, 50])
def test_a_sphere_of_n_sides_is_glu_spheres(n):
    m = uv_sphere(n)
    stacks = n // 2 + 1
    assert len(m.faces) == 2 * n * (stacks - 1)
    assert len(m.vertices) == 2 + n * (stacks - 1)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0


def test_round_organs_get_a_prototype_per_number_of_sides():
    sk = _skeleton("@!(6) @O(1) @c(1) @!(9) @O(1) @O(2) [ @! @o(1) ] ~l(1)")
    built = skeleton_organs(sk)
    faces = {p.name: len(p.mesh.faces) for p in built.prototypes}
    assert faces["sphere-6"] == 2 * 6 * 3 and faces["sphere-9"] == 2 * 9 * 4
    assert faces["disc-6"] == 6 and faces["circle-8"] == 8
    assert "l" in faces  # a surface keeps its name: sides are for spheres and discs
    assert np.bincount(built.prototype).sum() == 6


def test_a_surfaces_entry_named_sphere_replaces_every_sphere():
    from lsys3d.look.leaves import default_leaf

    class Surfaces:  # the one method organs() asks of a SurfaceTable
        leaf = None

        def get(self, name):
            class Entry:
                mesh = default_leaf()
                is_card = False

            return Entry() if name == "sphere" else None

    frame = np.broadcast_to(np.eye(3), (2, 3, 3))
    built = organs(["sphere", "sphere"], np.zeros((2, 3)), frame, [1.0, 1.0], sides=[7, 0], surfaces=Surfaces())
    assert all(len(p.mesh.faces) == len(default_leaf().faces) for p in built.prototypes)


@pytest.mark.parametrize(
    ("line", "sides"), [("contour sides: 7", 7), ("contour sides: 2", 3), ("polygonization level: 3", 16)]
)
def test_the_view_files_sides_are_the_turtles_at_first(tmp_path, line, sides):
    """interpret.c: ``contour sides: n`` (at least 3) or ``polygonization level: k`` (rint(2^(k + 1)))."""
    (tmp_path / "t.l").write_text("Lsystem: 1\nderivation length: 0\nAxiom: F [ @!(5) F ] F @O(1)\nendlsystem\n")
    (tmp_path / "t.v").write_text(f"angle increment: 30\n{line}\n")
    grammar = lsys3d.Grammar.from_file(tmp_path / "t.l")
    sk = interpret(interpretation(grammar, lsys3d.derive(grammar)), grammar)
    assert sk.sides.tolist() == [sides, 5, sides] and sk.organ_sides.tolist() == [sides]


def test_the_form_stage_carries_the_sides_to_its_pieces():
    """A curved segment split into pieces keeps its sides in each (lsys3d.turtle.form)."""
    from lsys3d.turtle.form import FormOptions, form

    sk = _skeleton("F @!(5) F F [ +F @!(11) F ] F")
    curved = form(sk, FormOptions(enabled=True, gnarl=40.0, max_substep_length=0.25), seed=1)
    assert len(curved) > len(sk)
    assert np.array_equal(curved.sides, sk.sides[np.searchsorted(sk.module, curved.module)])
