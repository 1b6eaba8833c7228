"""Levels of detail: budgets from one skeleton, monotone counts, closed bark, MSFT_lod and the USD 'lod' set."""

from __future__ import annotations

import json

import numpy as np
import pytest
from grown import grown

import lsys3d
from lsys3d.errors import LimitError, OptionsError
from lsys3d.exchange import export
from lsys3d.look.lod import LodOptions, fit_budget, prune, thin_leaves
from lsys3d.mesh.quality import quality
from lsys3d.stats import components


@pytest.fixture(scope="module")
def tree3d_lods():
    return lsys3d.generate("tree3d", lod=(0, 1, 2, 3))


def test_tree3d_levels_fit_the_issue_budgets(tree3d_lods):
    """LOD0 <= 60k, LOD1 <= 20k, LOD2 <= 6k, LOD3 <= 1.5k triangles, leaves included; each bark one closed solid."""
    counts = [lod.triangles for lod in tree3d_lods.lods]
    assert [lod.level for lod in tree3d_lods.lods] == [0, 1, 2, 3]
    for count, budget in zip(counts, (60_000, 20_000, 6_000, 1_500), strict=True):
        assert count <= budget, counts
    assert counts == sorted(counts, reverse=True) and len(set(counts)) == 4
    for lod in tree3d_lods.lods:
        bark = lod.bark
        assert bark.is_watertight and bark.is_winding_consistent
        assert components(bark.faces, len(bark.vertices)) == 1
        q = quality(bark)
        assert q.over_1000 == 0 and q.slivers == 0, (lod.level, q)


def test_level_zero_is_the_tree(tree3d_lods):
    assert tree3d_lods.lods[0].bark is tree3d_lods.bark
    plain = grown("tree3d")  # generate("tree3d"), grown once in the run (tests/grown.py)
    assert np.array_equal(plain.bark.faces, tree3d_lods.bark.faces)


def test_levels_built_at_once_are_the_levels_built_one_after_another(tree3d_lods, monkeypatch):
    """The levels after level 0 are built one thread per core; on one core, one after another: the same bytes."""
    monkeypatch.setattr("lsys3d.pipeline.os.cpu_count", lambda: 1)
    alone = lsys3d.generate("tree3d", lod=(0, 1, 3))
    assert [lod.level for lod in alone.lods] == [0, 1, 3]
    for lod in alone.lods:
        threaded = tree3d_lods.lods[lod.level]
        for name in ("vertices", "faces", "normals", "uv", "face_source"):
            assert np.array_equal(getattr(lod.bark, name), getattr(threaded.bark, name)), (lod.level, name)


def test_levels_keep_the_silhouette(tree3d_lods):
    """Every level is grown from the one skeleton: bark and leaves span the same box (no pop when switching).

    A pruned twig's leaves stay where they grew, so the crown keeps its extent (the thinned leaves, grown
    to keep their area, push it out by up to about 5%).
    """

    def points(lod):
        leaves = lod.leaves.merged if lod.leaves.merged is not None else lod.leaves.polygons
        return np.concatenate([lod.bark.vertices, leaves.vertices])

    top = points(tree3d_lods.lods[0])
    size = np.ptp(top, axis=0).max()
    for lod in tree3d_lods.lods[1:]:
        v = points(lod)
        assert np.abs(v.min(axis=0) - top.min(axis=0)).max() < 0.08 * size, lod.level
        assert np.abs(v.max(axis=0) - top.max(axis=0)).max() < 0.08 * size, lod.level


def test_target_triangles_picks_the_richest_level_that_fits(tree3d_lods):
    counts = [lod.triangles for lod in tree3d_lods.lods]
    budget = (counts[1] + counts[2]) // 2  # between LOD1 and LOD2: LOD2 fits
    tree = lsys3d.generate("tree3d", target_triangles=budget)
    assert not tree.lods
    assert np.array_equal(tree.bark.faces, tree3d_lods.lods[2].bark.faces)
    pairs = list(enumerate(counts))
    assert fit_budget(pairs, budget) == 2
    assert fit_budget(pairs, 10**9) == 0
    with pytest.raises(LimitError, match="even the lightest level"):
        fit_budget(pairs, 1)


def test_prune_drops_thin_chains_with_what_grows_from_them():
    sk = grown("tree3d").skeleton
    widest = max(sk.width_start.max(), sk.width_end.max())
    pruned = prune(sk, 0.3)
    assert 0 < len(pruned) < len(sk)
    heads = pruned.chains.segments[pruned.chains.offsets[:-1]]
    assert (pruned.width_start[heads] >= 0.3 * widest).all()
    assert (pruned.parent < np.arange(len(pruned))).all()  # parents renumbered, still before their children
    assert pruned.n_leaves == sk.n_leaves  # the leaves stay where they grew
    assert prune(sk, 0.0) is sk


def test_thinned_leaves_keep_their_area():
    sk = grown("tree3d").skeleton
    thin = thin_leaves(sk, 0.2)
    assert 0 < thin.n_leaves < sk.n_leaves
    area = (np.asarray(sk.leaf_size) ** 2).sum()
    assert (np.asarray(thin.leaf_size) ** 2).sum() == pytest.approx(area, rel=0.1)


def test_lod_options_are_checked():
    with pytest.raises(OptionsError):
        LodOptions(levels=(0, 7))
    with pytest.raises(OptionsError):
        LodOptions(target_triangles=-1)


def test_gltf_names_the_levels_and_lists_them_with_msft_lod(tmp_path):
    tree = lsys3d.generate("tree3d", iterations=4, lod=(0, 1, 2, 3))
    path = export(tree, tmp_path / "t.gltf")
    doc = json.loads(path.read_text())
    names = [n.get("name") for n in doc["nodes"]]
    levels = [f"{tree.name}_LOD{k}" for k in range(4)]
    assert all(name in names for name in levels)
    root = doc["nodes"][doc["scenes"][0]["nodes"][0]]
    assert root["name"] == levels[0]
    assert [doc["nodes"][i]["name"] for i in root["extensions"]["MSFT_lod"]["ids"]] == levels[1:]
    assert "MSFT_lod" in doc["extensionsUsed"]


def test_usd_levels_are_a_variant_set(tmp_path):
    pxr = pytest.importorskip("pxr")
    tree = lsys3d.generate("tree3d", iterations=4, lod=(0, 1, 2, 3))
    path = export(tree, tmp_path / "t.usda")
    stage = pxr.Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    lod = root.GetVariantSets().GetVariantSet("lod")
    assert lod.GetVariantNames() == ["LOD0", "LOD1", "LOD2", "LOD3"]
    assert lod.GetVariantSelection() == "LOD0"

    def faces():
        return sum(
            len(pxr.UsdGeom.Mesh(p).GetFaceVertexCountsAttr().Get() or [])
            for p in stage.Traverse()
            if p.IsA(pxr.UsdGeom.Mesh)
        )

    top = faces()
    lod.SetVariantSelection("LOD3")
    assert 0 < faces() < top


# ---------------------------------------------------------------- levels with attributes and the rig


@pytest.fixture(scope="module")
def rigged_lods():
    return lsys3d.generate("tree3d", iterations=4, lod=(0, 1, 2, 3), rig=True, wind_animation=2.0, attributes="full")


def test_every_level_carries_the_attributes_of_the_trees_own_branches(rigged_lods):
    tree = rigged_lods
    branches = len(tree.hierarchy)
    for lod in tree.lods:
        leaves = lod.leaves.merged
        for mesh in (lod.bark, leaves):
            assert set(mesh.attributes) >= {"branch_id", "branch_t", "pivot", "skin_joints", "skin_weights"}
            ids = np.asarray(mesh.attributes["branch_id"])
            assert ids.min() >= 0 and ids.max() < branches  # one branch table for every level
            np.testing.assert_allclose(np.asarray(mesh.attributes["skin_weights"]).sum(axis=1), 1.0, atol=1e-5)
            assert np.asarray(mesh.attributes["skin_joints"]).max() < len(tree.rig)  # one rig for every level
    # a kept branch keeps its id and its pivot: the bark vertices of a branch of level 2 sway about level 0's pivot
    top, low = tree.lods[0].bark, tree.lods[2].bark
    pivot = {int(b): p for b, p in zip(top.attributes["branch_id"], top.attributes["pivot"], strict=True)}
    for b, p in zip(low.attributes["branch_id"][::50], low.attributes["pivot"][::50], strict=True):
        if int(b) in pivot:
            np.testing.assert_allclose(p, pivot[int(b)], atol=1e-6)


def test_cards_carry_the_attributes_of_their_largest_leaf(rigged_lods):
    cards = rigged_lods.lods[3].leaves.merged
    assert len(cards.faces) == 2 * len(cards.vertices) // 4
    ids = np.asarray(cards.attributes["branch_id"]).reshape(-1, 4)
    assert (ids == ids[:, :1]).all()  # one branch per card, all four corners
    joints = np.asarray(cards.attributes["skin_joints"]).reshape(-1, 4, np.shape(cards.attributes["skin_joints"])[1])
    assert (joints == joints[:, :1]).all()


def test_without_rig_or_attributes_the_levels_carry_none():
    tree = lsys3d.generate("tree3d", iterations=3, lod=(0, 2))
    assert not tree.lods[1].bark.attributes
    compact = lsys3d.generate("tree3d", iterations=3, lod=(0, 2), attributes="compact")
    assert sorted(compact.lods[1].bark.attributes) == ["branch_id", "branch_t"]
    rigged = lsys3d.generate("tree3d", iterations=3, lod=(0, 2), rig=True)
    assert sorted(rigged.lods[1].bark.attributes) == ["skin_joints", "skin_weights"]  # the rig's own use is dropped


def test_rigged_levels_are_one_skinned_node_each_in_gltf(rigged_lods, tmp_path):
    from validators import HARMLESS_INFOS, gltf_issues, validate_gltf

    path = export(rigged_lods, tmp_path / "t.glb")
    report = validate_gltf(path)
    assert gltf_issues(report, 0) == [] and gltf_issues(report, 1) == []
    assert [i for i in gltf_issues(report, 2) if i.split(" ")[0] not in HARMLESS_INFOS] == []
    gltf = export(rigged_lods, tmp_path / "t.gltf")
    doc = json.loads(gltf.read_text())
    nodes = doc["nodes"]
    levels = [next(i for i, n in enumerate(nodes) if n.get("name") == f"{rigged_lods.name}_LOD{k}") for k in range(4)]
    assert all(nodes[i].get("skin") == 0 for i in levels)  # every level bound to the one rig
    scene = doc["scenes"][0]["nodes"]
    assert levels[0] in scene and not any(i in scene for i in levels[1:])
    assert nodes[levels[0]]["extensions"]["MSFT_lod"]["ids"] == levels[1:]
    # bark and leaves: a primitive each, with their joints and weights
    for i in levels:
        primitives = doc["meshes"][nodes[i]["mesh"]]["primitives"]
        assert len(primitives) >= 2
        assert all({"JOINTS_0", "WEIGHTS_0"} <= set(p["attributes"]) for p in primitives)
    assert len(doc["animations"]) == 1  # the wind, once, on the shared joints


def test_rigged_levels_in_usd_bind_to_the_rig(rigged_lods, tmp_path):
    pxr = pytest.importorskip("pxr")
    from validators import usd_problems

    path = export(rigged_lods, tmp_path / "t.usda")
    assert usd_problems(path) == []
    stage = pxr.Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    assert root.IsA(pxr.UsdSkel.Root)
    lod = root.GetVariantSets().GetVariantSet("lod")
    for name in ("LOD0", "LOD1", "LOD2", "LOD3"):
        lod.SetVariantSelection(name)
        meshes = [p for p in stage.Traverse() if p.IsA(pxr.UsdGeom.Mesh)]
        assert meshes
        for prim in meshes:
            binding = pxr.UsdSkel.BindingAPI(prim)
            assert binding.GetSkeletonRel().GetTargets(), (name, prim.GetPath())
            assert binding.GetJointIndicesPrimvar().IsDefined()
