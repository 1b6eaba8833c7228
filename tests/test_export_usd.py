"""USD export: stage layout, usd-core's validators, options, round trip, speed."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import export_fixtures as fx
import numpy as np
import pytest
import trimesh
import validators
from grown import grown, species
from pxr import Sdf, Usd, UsdGeom, UsdShade

from lsys3d.exchange import ExportOptions, export
from lsys3d.exchange.common import file_frame
from lsys3d.lsystem.presets import preset_text

SUFFIXES = [".usda", ".usdc", ".usd", ".usdz"]


@pytest.fixture(scope="module")
def tree():
    return fx.make_tree()


def open_stage(path: Path) -> Usd.Stage:
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    return stage


def world_bounds(stage: Usd.Stage, purposes=(UsdGeom.Tokens.default_,)) -> np.ndarray:
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), list(purposes), useExtentsHint=False)
    box = cache.ComputeWorldBound(stage.GetDefaultPrim()).ComputeAlignedRange()
    return np.array([box.GetMin(), box.GetMax()])


# ---------------------------------------------------------------- validators


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize(
    "options",
    [
        ExportOptions(),
        ExportOptions(instance_leaves=False),
        ExportOptions(up_axis="Z", units="cm", skeleton_curves=True),
    ],
    ids=["default", "merged", "z-cm-curves"],
)
def test_usd_validators(tree, tmp_path, suffix, options):
    path = export(tree, tmp_path / f"tree{suffix}", options)
    assert validators.usd_problems(path) == []


@pytest.mark.parametrize("name", species())
def test_species_usdz_pass_the_usd_validators_with_textures_packed(name, tmp_path):
    path = export(grown(name), tmp_path / f"{name}.usdz")
    assert validators.usd_problems(path) == []
    with zipfile.ZipFile(path) as z:
        pictures = [n for n in z.namelist() if n.endswith(".png")]
    assert bool(pictures) == ("procedural" in preset_text(name))  # a textured species carries its pictures


@pytest.mark.parametrize("name", species())
def test_species_usdz_pass_the_arkit_profile(name, tmp_path):
    """AR Quick Look's USD: usd-core's ComplianceChecker(arkit=True) finds nothing (leaves merged in a .usdz:
    the profile has no PointInstancer), and usd-core 26's validators agree."""
    path = export(grown(name), tmp_path / f"{name}.usdz")
    assert validators.arkit_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    assert not [p for p in stage.Traverse() if p.IsA(UsdGeom.PointInstancer)]


def test_usdz_leaves_merged_unless_asked_and_the_checker_sees_an_instancer(tmp_path):
    """The merged leaves of a .usdz are the instanced leaves of a .usdc, placed; instance_leaves=True still
    writes the instancer, which the ARKit profile refuses (so the checker is no rubber stamp)."""
    tree = grown("oak")
    packed = Usd.Stage.Open(str(export(tree, tmp_path / "oak.usdz")))
    leaf = packed.GetPrimAtPath("/oak/Geom/leaf")
    assert leaf.IsA(UsdGeom.Mesh)
    instanced = Usd.Stage.Open(str(export(tree, tmp_path / "oak.usdc")))
    assert instanced.GetPrimAtPath("/oak/Geom/leaf").IsA(UsdGeom.PointInstancer)
    np.testing.assert_allclose(world_bounds(packed), world_bounds(instanced), atol=1e-3)
    forced = export(tree, tmp_path / "forced.usdz", ExportOptions(instance_leaves=True))
    assert validators.arkit_problems(forced) == [
        "Prim </oak/Geom/leaf> has unsupported type 'PointInstancer'. (fails 'ARKitPrimTypeChecker')"
    ]


def test_usd_validators_tube_soup(tmp_path):
    tree = fx.make_tree(unioned=False, instanced=False)
    assert validators.usd_problems(export(tree, tmp_path / "soup.usdc")) == []


def test_usd_bark_only(tmp_path):
    tree = fx.tree_from_bark(fx.make_tube(16, 4))
    stage = open_stage(export(tree, tmp_path / "bare.usda"))
    assert validators.usd_problems(tmp_path / "bare.usda") == []
    assert [p.GetName() for p in stage.GetPrimAtPath("/synthetic/Geom").GetChildren()] == ["bark"]
    assert [p.GetName() for p in stage.GetPrimAtPath("/synthetic/Looks").GetChildren()] == ["bark"]


# ---------------------------------------------------------------- layout


def test_stage_layout(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usda", ExportOptions(skeleton_curves=True)))
    root = stage.GetDefaultPrim()
    assert root.GetPath() == Sdf.Path("/synthetic") and root.GetTypeName() == "Xform"
    assert Usd.ModelAPI(root).GetKind() == "component"
    assert stage.HasAuthoredMetadata("upAxis") and UsdGeom.GetStageUpAxis(stage) == "Y"
    assert stage.HasAuthoredMetadata("metersPerUnit") and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert Usd.ModelAPI(root).GetAssetName() == "synthetic"

    for prim in stage.Traverse():
        assert prim.GetTypeName(), f"{prim.GetPath()} has no type"
        if prim.IsA(UsdGeom.Boundable):
            assert UsdGeom.Boundable(prim).GetExtentAttr().HasAuthoredValue(), f"{prim.GetPath()} has no extent"
        if prim.IsA(UsdGeom.Mesh):
            check_mesh(UsdGeom.Mesh(prim))
    assert stage.GetPrimAtPath("/synthetic/Looks").GetTypeName() == "Scope"
    assert stage.GetPrimAtPath("/synthetic/Geom").GetTypeName() == "Xform"


def check_mesh(mesh: UsdGeom.Mesh) -> None:
    path = mesh.GetPath()
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    fvi = mesh.GetFaceVertexIndicesAttr().Get()
    assert mesh.GetNormalsInterpolation() == "faceVarying"
    assert len(mesh.GetNormalsAttr().Get()) == len(fvi)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying" and st.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray
    indices = st.GetIndices()
    assert len(indices) == len(fvi) and min(indices) >= 0 and max(indices) < len(st.Get())
    points = np.array(mesh.GetPointsAttr().Get())
    extent = np.array(mesh.GetExtentAttr().Get())
    np.testing.assert_allclose(extent, [points.min(0), points.max(0)], err_msg=str(path))
    prim = mesh.GetPrim()
    assert prim.HasAPI(UsdShade.MaterialBindingAPI)
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    assert material and str(material.GetPath()).startswith("/synthetic/Looks/")
    shader = material.ComputeSurfaceSource()[0]
    assert shader.GetIdAttr().Get() == "UsdPreviewSurface"


def test_materials(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usdc"))
    for name, m in (("bark", tree.bark_material), ("leaf", tree.leaf_material)):
        material = UsdShade.Material(stage.GetPrimAtPath(f"/synthetic/Looks/{name}"))
        shader = material.ComputeSurfaceSource()[0]
        np.testing.assert_allclose(shader.GetInput("diffuseColor").Get(), m.base_color[:3], rtol=1e-6)
        assert shader.GetInput("roughness").Get() == pytest.approx(m.roughness)
    assert UsdGeom.Mesh(stage.GetPrimAtPath("/synthetic/Geom/leaf_polygons")).GetDoubleSidedAttr().Get() is True
    assert not UsdGeom.Mesh(stage.GetPrimAtPath("/synthetic/Geom/bark")).GetDoubleSidedAttr().Get()


def test_point_instancer(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usdc"))
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/synthetic/Geom/leaf"))
    assert instancer
    (proto,) = instancer.GetPrototypesRel().GetTargets()
    assert proto == Sdf.Path("/synthetic/Geom/leaf/Prototypes/leaf_model")
    assert stage.GetPrimAtPath("/synthetic/Geom/leaf/Prototypes").GetTypeName() == "Scope"
    assert instancer.GetOrientationsAttr().GetTypeName() == Sdf.ValueTypeNames.QuathArray
    xforms = instancer.ComputeInstanceTransformsAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    # USD matrices are row-vector style: transpose to compare with the tree's column-vector transforms
    got = np.array([np.array(m).T for m in xforms])
    np.testing.assert_allclose(got, tree.leaves.transforms, atol=2e-3)  # orientations are half floats
    leaf = UsdGeom.Mesh(stage.GetPrimAtPath(proto))
    assert len(leaf.GetPointsAttr().Get()) == len(tree.leaves.model.vertices)


def test_merged_leaves(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usda", ExportOptions(instance_leaves=False)))
    leaves = stage.GetPrimAtPath("/synthetic/Geom/leaf")
    assert leaves.GetTypeName() == "Mesh"
    assert len(UsdGeom.Mesh(leaves).GetFaceVertexCountsAttr().Get()) == len(tree.leaves.merged.faces)
    assert not stage.GetPrimAtPath("/synthetic/Geom/leaf_polygons")


def test_polygon_leaves_without_merged_leaves(tmp_path):
    """A tree whose leaves field is empty still writes its polygon leaves, in both formats."""
    from dataclasses import replace

    tree = fx.make_tree(instanced=False)
    tree = replace(tree, leaves=replace(tree.leaves, merged=None))
    stage = open_stage(export(tree, tmp_path / "tree.usda"))
    faces = UsdGeom.Mesh(stage.GetPrimAtPath("/synthetic/Geom/leaf")).GetFaceVertexCountsAttr().Get()
    assert len(faces) == len(tree.leaves.polygons.faces)
    scene = trimesh.load(export(tree, tmp_path / "tree.glb"), process=False)
    assert len(scene.geometry["leaf"].faces) == len(tree.leaves.polygons.faces)


def test_same_drawn_bounds_with_or_without_instancing(tree, tmp_path):
    instanced = world_bounds(open_stage(export(tree, tmp_path / "a.usdc")))
    merged = world_bounds(open_stage(export(tree, tmp_path / "b.usdc", ExportOptions(instance_leaves=False))))
    np.testing.assert_allclose(instanced, merged, atol=1e-3)


def test_skeleton_curves(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usda", ExportOptions(skeleton_curves=True)))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/synthetic/Geom/skeleton"))
    assert curves.GetTypeAttr().Get() == "linear"
    assert curves.GetPurposeAttr().Get() == "guide"
    counts = list(curves.GetCurveVertexCountsAttr().Get())
    assert counts == [len(p) for p in tree.skeleton.polylines()]
    widths = curves.GetWidthsAttr().Get()
    assert len(widths) == sum(counts) and curves.GetWidthsInterpolation() == "vertex"
    assert max(widths) == pytest.approx(0.2)


def test_no_curves_by_default(tree, tmp_path):
    stage = open_stage(export(tree, tmp_path / "tree.usda"))
    assert not stage.GetPrimAtPath("/synthetic/Geom/skeleton")


@pytest.mark.parametrize("units, scale", [("m", 1.0), ("cm", 100.0)])
@pytest.mark.parametrize("up_axis", ["Y", "Z"])
def test_units_and_up_axis(tree, tmp_path, units, scale, up_axis):
    stage = open_stage(export(tree, tmp_path / "tree.usdc", ExportOptions(units=units, up_axis=up_axis)))
    assert UsdGeom.GetStageUpAxis(stage) == up_axis
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(1 / scale)
    bounds = world_bounds(stage)
    size = bounds[1] - bounds[0]
    up = "XYZ".index(up_axis)
    assert np.argmax(size) == up  # the tree stands along the up axis
    assert bounds[0][up] == pytest.approx(0.0, abs=1e-4)
    assert size[up] == pytest.approx(2.25 * scale, rel=1e-4)  # trunk top plus the polygon leaf
    # the leaves are moved with the bark: same bounds as the merged-leaf export in the same frame
    frame = file_frame(ExportOptions(units=units, up_axis=up_axis))
    corners = np.vstack([tree.bark.vertices, tree.leaves.merged.vertices]) @ frame.T
    np.testing.assert_allclose(bounds, [corners.min(0), corners.max(0)], atol=2e-3 * scale)


# ---------------------------------------------------------------- round trip, determinism, packaging


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_pxr_round_trip(tree, tmp_path, suffix):
    stage = open_stage(export(tree, tmp_path / f"tree{suffix}"))
    bark = UsdGeom.Mesh(stage.GetPrimAtPath("/synthetic/Geom/bark"))
    points = np.array(bark.GetPointsAttr().Get())
    assert len(points) == len(tree.bark.vertices)
    assert len(bark.GetFaceVertexCountsAttr().Get()) == len(tree.bark.faces)
    np.testing.assert_allclose([points.min(0), points.max(0)], tree.bark.bounds, atol=1e-6)
    data = stage.GetDefaultPrim().GetCustomDataByKey("lsys3d")
    assert json.loads(data["provenance"]) == tree.metadata()
    assert data["generator"].startswith("lsys3d ")
    assert Usd.ModelAPI(stage.GetDefaultPrim()).GetAssetName() == "synthetic"


def test_usdz_holds_one_crate_file(tree, tmp_path):
    path = export(tree, tmp_path / "tree.usdz")
    with zipfile.ZipFile(path) as z:
        (info,) = z.infolist()
        assert info.filename == "tree.usdc" and info.compress_type == zipfile.ZIP_STORED
        assert info.date_time == (1980, 1, 1, 0, 0, 0)
        assert z.read(info).startswith(b"PXR-USDC")
    # usdz data must start on a 64-byte boundary
    data = path.read_bytes()
    name_len, extra_len = np.frombuffer(data[26:30], "<u2")
    assert (30 + name_len + extra_len) % 64 == 0
    assert [p.name for p in tmp_path.iterdir()] == ["tree.usdz"]


def test_usd_is_crate(tree, tmp_path):
    assert export(tree, tmp_path / "tree.usd").read_bytes().startswith(b"PXR-USDC")
    assert export(tree, tmp_path / "tree.usda").read_bytes().startswith(b"#usda 1.0")
