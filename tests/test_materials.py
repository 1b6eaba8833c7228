"""Materials from the grammar: the [materials] table, per-face indices, glTF primitives and USD GeomSubsets."""

from __future__ import annotations

import numpy as np
import pytest
import validators
from gltf_files import accessor, node, read_glb
from pxr import Usd, UsdGeom, UsdShade

import lsys3d
from lsys3d.exchange import ExportOptions, export
from lsys3d.look.materials import BARK, LEAF, MaterialTable, material_table

# a trunk of index 0, a branch of index 1 from its middle, a leaf of index 2 on the branch and one of 0 on the trunk
TEXT = """\
name = "painted"
axiom = "!(0.2)F[+'(1)!(0.1)FF'(2)~]F~"
angle = 60

[materials]
0 = { name = "old bark", base_color = [0.25, 0.17, 0.1], roughness = 0.95 }
1 = { name = "young bark", base_color = "#7a5a33" }
2 = { name = "blossom", base_color = [0.9, 0.75, 0.8], roughness = 0.4 }
leaf = { name = "green leaf", base_color = [0.2, 0.5, 0.1] }
"""


@pytest.fixture(scope="module")
def painted():
    return lsys3d.generate(lsys3d.Grammar.from_text(TEXT, source="painted.toml"), sides=8)


def test_table():
    table = material_table(lsys3d.Grammar.from_text(TEXT))
    assert table.for_bark(0).name == "old bark" and table.for_bark(7) == BARK
    assert table.for_bark(1).base_color == pytest.approx((0.194618, 0.102242, 0.033105, 1.0), abs=1e-6)  # sRGB hex
    assert table.for_leaf(9).name == "green leaf" and table.for_leaf(9).double_sided  # leaves: always two-sided
    assert table.for_leaf(2).name == "blossom" and table.for_leaf(2).double_sided
    assert not MaterialTable() and table
    assert not material_table(lsys3d.Grammar(axiom="F"))  # no table: the two defaults
    assert MaterialTable().for_leaf(3) == LEAF


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("0 = { base_color = [2, 0, 0] }", "materials.0: base_color: expected 3 or 4 numbers in [0, 1]"),
        ('0 = { base_color = "red" }', "materials.0: base_color: expected '#rrggbb' or [r, g, b], not 'red'"),
        ("0 = { roughness = 1.5 }", "materials.0: roughness must be a number in [0, 1], not 1.5"),
        ("0 = { shine = 1 }", "materials.0: unknown key 'shine'"),
        ("wood = { roughness = 0.5 }", "a key is a material index 0..255, 'bark' or 'leaf', not 'wood'"),
        ("300 = { roughness = 0.5 }", "not '300'"),
        ("0 = 3", "expected a table"),
    ],
)
def test_bad_entries_name_their_line(entry, message):
    text = f'axiom = "F"\n\n[materials]\n{entry}\n'
    with pytest.raises(lsys3d.GrammarError, match=message.replace("[", r"\[").replace("]", r"\]")) as info:
        lsys3d.generate(lsys3d.Grammar.from_text(text, source="m.toml"))
    assert info.value.line == 4 and str(info.value).startswith("m.toml:4:1: [materials] ")


def test_faces_take_their_segments_index(painted):
    fm = painted.bark.face_material
    v = painted.bark.vertices[painted.bark.faces].mean(axis=1)
    on_trunk = np.hypot(v[:, 0], v[:, 2]) < 0.09
    assert set(np.unique(fm).tolist()) == {0, 1}
    assert (fm[on_trunk & (v[:, 1] > 1.2)] == 0).all()
    assert (fm[v[:, 0] < -0.5] == 1).all()  # the branch, turned left to -x
    assert painted.leaves.merged.face_material.tolist() == [2] * 28 + [0] * 28


def test_gltf_one_primitive_per_material(painted, tmp_path):
    path = export(painted, tmp_path / "painted.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, binary = read_glb(path)
    names = [m["name"] for m in doc["materials"]]
    bark = doc["meshes"][node(doc, "bark")["mesh"]]["primitives"]
    assert [names[p["material"]] for p in bark] == ["old bark", "young bark"]
    assert bark[0]["attributes"] == bark[1]["attributes"]  # the vertices are shared, only the indices differ
    counts = [doc["accessors"][p["indices"]]["count"] // 3 for p in bark]
    assert counts == np.bincount(painted.bark.face_material).tolist()
    leaf = doc["meshes"][node(doc, "leaf")["mesh"]]["primitives"]
    assert [names[p["material"]] for p in leaf] == ["old bark", "blossom"]  # leaves on index 0 and 2
    assert all(doc["materials"][p["material"]].get("doubleSided") for p in leaf)
    young = doc["materials"][bark[1]["material"]]["pbrMetallicRoughness"]["baseColorFactor"]
    assert young == pytest.approx([0.194618, 0.102242, 0.033105, 1.0], abs=1e-6)
    # every face of the bark once
    faces = np.concatenate([accessor(doc, binary, p["indices"]) for p in bark])
    assert len(faces) == 3 * len(painted.bark.faces)


def test_gltf_instanced_leaves_per_material(painted, tmp_path):
    path = export(painted, tmp_path / "painted.glb", ExportOptions(instance_leaves=True))
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, _ = read_glb(path)
    leaf, blossom = node(doc, "leaf"), node(doc, "leaf_2")
    for n, count in ((leaf, 1), (blossom, 1)):
        translation = n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"]
        assert doc["accessors"][translation]["count"] == count


def test_usd_geom_subsets(painted, tmp_path):
    path = export(painted, tmp_path / "painted.usda")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    bark = UsdGeom.Mesh(stage.GetPrimAtPath("/painted/Geom/bark"))
    subsets = UsdGeom.Subset.GetGeomSubsets(bark, UsdGeom.Tokens.face, "materialBind")
    assert [s.GetPrim().GetName() for s in subsets] == ["material_0", "material_1"]
    bound = [UsdShade.MaterialBindingAPI(s.GetPrim()).ComputeBoundMaterial()[0].GetPrim().GetName() for s in subsets]
    assert bound == ["old_bark", "young_bark"]
    assert sum(len(s.GetIndicesAttr().Get()) for s in subsets) == len(painted.bark.faces)
    # the instancer has one leaf prototype per leaf material
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/painted/Geom/leaf"))
    assert len(instancer.GetPrototypesRel().GetTargets()) == 2 and list(instancer.GetProtoIndicesAttr().Get()) == [1, 0]


def test_no_table_no_change(tmp_path):
    """Without [materials] the files are as they were: two materials, one primitive each."""
    tree = lsys3d.generate("bush", iterations=3)
    assert tree.bark.face_material is None and not tree.materials
    doc, _ = read_glb(export(tree, tmp_path / "bush.glb"))
    assert [m["name"] for m in doc["materials"]] == ["bark", "leaf"]
    assert all(len(m["primitives"]) == 1 for m in doc["meshes"])
