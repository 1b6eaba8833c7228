"""The main job on every bundled preset: one watertight tree, valid files, upright in Blender."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
import validators
from grown import grown

import lsys3d
from lsys3d.errors import GeometryError
from lsys3d.exchange import ExportOptions, export
from lsys3d.mesh.sweep import sweep
from lsys3d.mesh.union.union import concatenate
from lsys3d.pipeline import GenerateOptions, generate
from lsys3d.stats import components, mesh_stats

DRAWING_PRESETS = [name for name in lsys3d.list_presets() if name not in ("algae", "dog", "dog-growing")]


#: presets whose axiom plants several shoots apart (moved to by ``f``, not drawn to): how many
PLANTS = {"ivy-wall": 4}  # the climbing ivy and three shoots planted on the window's sill


@pytest.mark.parametrize("name", DRAWING_PRESETS)
def test_every_preset_is_one_watertight_solid(name):
    tree = grown(name)
    bark = tree.bark
    assert bark.is_watertight and bark.is_winding_consistent
    assert bark.volume > 0
    # the union never adds volume (at most the sum of the tube volumes); the junction collars of the cleanup
    # fill the creases: up to 7% more on the flat drawings, whose every right-angled corner is a junction
    # (koch), 1-2.5% on the trees (the union alone: tests/test_cleanup.py)
    soup = concatenate(sweep(tree.skeleton))
    assert bark.volume <= soup.volume * 1.08
    # every preset draws one connected plant (no crumbs left by the boolean), or as many as its axiom plants
    assert components(bark.faces, len(bark.vertices)) == PLANTS.get(name, 1)
    # normals and UVs for every corner
    assert bark.normals.shape == (len(bark.faces), 3, 3)
    assert bark.uv.shape == (len(bark.faces), 3, 2)
    np.testing.assert_allclose(np.linalg.norm(bark.normals, axis=-1), 1, atol=1e-4)


@pytest.mark.parametrize("name", DRAWING_PRESETS)
def test_bark_stays_closed_when_welded_by_position(name):
    """What a reader that merges vertices by position (Blender's glTF import, mesh checkers) sees.

    manifold3d leaves distinct vertices micrometres apart where tubes meet almost tangentially, and
    where coplanar tubes cross in the flat presets; stored as float32, or welded by trimesh within
    1e-8, they would fall together and make edges non-manifold.  The union welds or separates them.
    """
    bark = grown(name).bark
    v32 = np.asarray(bark.vertices, np.float32)
    assert len(np.unique(v32, axis=0)) == len(v32)
    welded = trimesh.Trimesh(v32.astype(np.float64), bark.faces, process=False)
    welded.merge_vertices()  # trimesh's own weld, within its default tolerance
    assert len(welded.vertices) == len(v32)
    assert welded.is_watertight and welded.is_winding_consistent


@pytest.mark.parametrize("name", DRAWING_PRESETS)
def test_every_preset_passes_the_khronos_validator(name, tmp_path):
    tree = grown(name)
    report = validators.validate_gltf(export(tree, tmp_path / f"{name}.glb"))
    assert validators.gltf_issues(report, 0) == []
    assert validators.gltf_issues(report, 1) == []
    assert {i.split(" ")[0] for i in validators.gltf_issues(report, 2)} <= validators.HARMLESS_INFOS
    leaves = 0 if tree.leaves.merged is None else len(tree.leaves.merged.faces)
    assert report["info"]["totalTriangleCount"] == len(tree.bark.faces) + leaves


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
@pytest.mark.parametrize("name", DRAWING_PRESETS)
def test_every_preset_passes_the_usd_validators(name, suffix, tmp_path):
    path = export(grown(name), tmp_path / f"{name}{suffix}", ExportOptions(skeleton_curves=True))
    assert validators.usd_problems(path) == []


@pytest.mark.parametrize("name", ["tree3d.glb", "tree3d.usdc"])
def test_default_tree_stands_upright_in_blender(name, tmp_path):
    tree = grown("tree3d")
    report = validators.blender_import(export(tree, tmp_path / name))
    bark = {o["name"]: o for o in report["objects"]}["bark"]
    assert bark["faces"] == len(tree.bark.faces)
    lo, hi = np.array(bark["bbox"])
    # our Y up is Blender's Z up: the trunk starts on the ground and the crown is on top
    expected = np.asarray(tree.bark.bounds)[:, [0, 2, 1]] * [1, -1, 1]
    np.testing.assert_allclose([lo, hi], np.sort(expected, axis=0), atol=1e-3)
    assert lo[2] == pytest.approx(0.0, abs=1e-3) and hi[2] > 5.0


def test_generate_records_provenance_and_counts():
    tree = grown("tree3d")
    p = tree.provenance
    assert p.grammar_name == tree.name == "tree3d" and p.iterations == 6 and p.seed == 0
    assert "A -> " in p.grammar_text
    assert p == lsys3d.Provenance.of(lsys3d.load_preset("tree3d"), 6, 0, GenerateOptions())
    assert tree.counts.segments == len(tree.skeleton) and tree.counts.modules == len(tree.modules)
    assert tree.metadata()["counts"]["segments"] == len(tree.skeleton)
    stats = mesh_stats(tree)
    assert stats["components"] == 1 and stats["watertight"]
    assert stats["leaf_faces"] == len(tree.leaves.merged.faces) > 0
    assert list(stats) == sorted(stats)


def test_tree_modules_is_the_derived_string_and_skeleton_module_indexes_the_string_the_turtle_read():
    """Tree.modules is derive()'s string, before the homomorphism; skeleton.module indexes interpretation()'s."""
    from lsys3d.lsystem.derive import interpretation

    g = lsys3d.Grammar(axiom="A", rules=["A -> I[+A]IA"], homomorphism=["I -> FF"], iterations=3, angle=30)
    tree = generate(g, union=False)
    derived = lsys3d.derive(g)
    assert tree.modules == derived and tree.counts.modules == len(derived) == len(tree.modules)
    shown = interpretation(g, tree.modules)
    assert len(shown) > len(tree.modules)  # each I became two F
    assert {shown.symbol(i) for i in tree.skeleton.module.tolist()} == {"F"}
    assert len(tree.skeleton) == 2 * tree.modules.count("I")


def test_generate_is_deterministic_to_the_byte(tmp_path):
    a = generate("bush", 3, seed=5)
    b = generate("bush", 3, seed=5)
    assert np.array_equal(a.bark.vertices, b.bark.vertices) and np.array_equal(a.bark.faces, b.bark.faces)
    assert export(a, tmp_path / "a.glb").read_bytes() == export(b, tmp_path / "b.glb").read_bytes()


def test_no_union_gives_the_tube_soup():
    tree = generate("abop-1.24a", 2, union=False)
    stats = mesh_stats(tree)
    assert not stats["unioned"]
    assert stats["faces"] == stats["tube_faces"] and stats["components"] == stats["tubes"]


def test_sides_option():
    few = mesh_stats(generate("abop-1.24a", 1, union=False, sides=4))
    many = mesh_stats(generate("abop-1.24a", 1, union=False, sides=12))
    assert many["tube_vertices"] > few["tube_vertices"]


def test_options_object_and_keywords_agree():
    a = generate("koch", 1, options=GenerateOptions(union=lsys3d.UnionOptions(enabled=False)))
    b = generate("koch", 1, union=False)
    assert GenerateOptions.from_flat(union=False) == GenerateOptions(union=lsys3d.UnionOptions(enabled=False))
    assert np.array_equal(a.bark.faces, b.bark.faces)


@pytest.mark.parametrize("name", ["algae", "dog"])
def test_a_grammar_that_draws_nothing_is_a_clear_error(name):
    with pytest.raises(GeometryError, match="nothing to mesh"):
        generate(name)


def test_polygon_leaves_alone_make_a_tree_without_bark(tmp_path):
    g = lsys3d.Grammar(axiom="{.f.+f.+f.}", angle=120, turtle={"move": "f"})
    tree = generate(g)
    assert len(tree.bark.faces) == 0 and len(tree.leaves.polygons.faces) == 1
    report = validators.validate_gltf(export(tree, tmp_path / "leaf.glb"))
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    assert validators.usd_problems(export(tree, tmp_path / "leaf.usda")) == []


def test_components_counts_pieces():
    a = trimesh.creation.box()
    b = trimesh.creation.box()
    b.apply_translation([5, 0, 0])
    both = trimesh.util.concatenate([a, b])
    assert components(both.faces, len(both.vertices)) == 2
    assert components(a.faces, len(a.vertices) + 10) == 1  # unused vertices do not count
    assert components(np.zeros((0, 3), int), 0) == 0
