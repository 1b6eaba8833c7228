"""Forests: Poisson-disk scattering, the USD PointInstancer and the instanced .glb, judged by the validators."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import validators
from batches import small_library
from pxr import Usd, UsdGeom

import lsys3d
from lsys3d.errors import ForestError
from lsys3d.exchange import ExportOptions
from lsys3d.exchange.library import LibraryVariant, read_library, write_library
from lsys3d.library.forest import ForestOptions, forest, scatter


def pair_gaps(s, radius, spacing):
    """Distance between every two trunks minus the spacing they need (all >= 0 for a Poisson-disk scatter)."""
    p = s.position
    r = np.asarray(radius)[s.variant] * s.scale
    d = np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(-1))
    need = spacing * (r[:, None] + r[None, :])
    off = ~np.eye(len(p), dtype=bool)
    return (d - need)[off]


# ---------------------------------------------------------------- scattering


@pytest.mark.parametrize("spacing", [1.0, 0.5])
def test_scatter_keeps_crowns_apart_inside_the_area(spacing):
    radius = [1.0, 2.5, 0.5, 1.5]
    species = ["oak", "oak", "ash", "elm"]
    options = ForestOptions(area=(80, 60), count=300, seed=4, scale=(0.7, 1.3), yaw=(-45, 45), spacing=spacing)
    s = scatter(radius, species, options)
    assert len(s.variant) == 300 and s.position.shape == (300, 2)
    assert (pair_gaps(s, radius, spacing) >= -1e-9).all()
    assert (np.abs(s.position) <= [40, 30]).all()
    assert (s.scale >= 0.7).all() and (s.scale <= 1.3).all() and (s.yaw >= -45).all() and (s.yaw <= 45).all()
    kinds = np.array(species)[s.variant]
    counts = {k: int((kinds == k).sum()) for k in ("oak", "ash", "elm")}
    assert all(70 <= c <= 130 for c in counts.values()), counts  # each species as likely as the others
    assert set(s.variant[kinds == "oak"].tolist()) == {0, 1}  # and each of its assets


def test_scatter_is_reproducible_and_the_seed_matters():
    options = ForestOptions(area=(50, 50), count=100, seed=7)
    a, b = scatter([1.0, 2.0], ["a", "b"], options), scatter([1.0, 2.0], ["a", "b"], options)
    for key in ("variant", "position", "yaw", "scale"):
        assert np.array_equal(getattr(a, key), getattr(b, key))
    c = scatter([1.0, 2.0], ["a", "b"], ForestOptions(area=(50, 50), count=100, seed=8))
    assert not np.array_equal(a.position, c.position)


def test_a_forest_that_does_not_fit_says_how_many_did():
    with pytest.raises(ForestError, match=r"only [\d,]+ of 1,000 instances fit on 20 x 20 m with crown radii"):
        scatter([2.0], ["oak"], ForestOptions(area=(20, 20), count=1000, scale=(1, 1)))
    s = scatter([2.0], ["oak"], ForestOptions(area=(20, 20), count=1000, spacing=0))  # anywhere: always fits
    assert len(s.variant) == 1000


def test_transforms_turn_about_the_up_axis_and_scale():
    s = scatter([1.0], ["oak"], ForestOptions(area=(10, 10), count=5, seed=1))
    t = s.transforms()
    a = np.radians(s.yaw)
    np.testing.assert_allclose(t[:, :3, 1], np.c_[0 * a, s.scale, 0 * a])  # up stays up
    np.testing.assert_allclose(t[:, 0, 0], np.cos(a) * s.scale)
    np.testing.assert_allclose(t[:, [0, 2], 3], s.position)
    np.testing.assert_allclose(t[:, 1, 3], 0)


@pytest.mark.parametrize(
    "kw",
    [
        {"area": (0, 10)},
        {"area": (10,)},
        {"count": 0},
        {"count": 2.5},
        {"seed": -1},
        {"scale": (0, 1)},
        {"scale": (2, 1)},
        {"yaw": (10, 0)},
        {"yaw": (0, float("nan"))},
        {"spacing": -1},
    ],
)
def test_bad_forest_options(kw):
    with pytest.raises(lsys3d.OptionsError, match="ForestOptions"):
        ForestOptions(**kw)


# ---------------------------------------------------------------- USD


@pytest.fixture(scope="module")
def library():
    folder, _ = small_library()
    return folder / "out" / "library.usda"


def test_usd_forest_is_a_point_instancer_over_the_asset_files(library, tmp_path):
    options = ForestOptions(area=(80, 60), count=60, seed=3)
    path = forest(library, tmp_path / "forest.usdc", options)
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    assert root.GetPath() == "/Forest" and Usd.ModelAPI(root).GetKind() == "assembly"
    provenance = json.loads(root.GetCustomDataByKey("lsys3d")["provenance"])
    assert provenance["forest"]["count"] == 60 and provenance["instances"] == 60
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Forest/Trees"))
    indices = np.array(instancer.GetProtoIndicesAttr().Get())
    targets = instancer.GetPrototypesRel().GetTargets()
    assert len(indices) == 60 and indices.max() < len(targets) and len(set(indices.tolist())) == len(targets)
    for target in targets:  # each prototype is a reference to an asset's file, composed from it
        prim = stage.GetPrimAtPath(target)
        refs = prim.GetMetadata("references").prependedItems
        assert len(refs) == 1 and refs[0].assetPath.startswith("../")  # relative to the forest's folder
        assert stage.GetPrimAtPath(target.AppendPath("Geom/bark")).IsA(UsdGeom.Mesh)
    positions = np.array(instancer.GetPositionsAttr().Get())
    assert (np.abs(positions[:, [0, 2]]) <= [40, 30]).all() and (positions[:, 1] == 0).all()
    # the authored extent (from the assets' vertices) is USD's own, which bounds each leaf's box: a little larger
    authored = np.array(instancer.GetExtentAttr().Get())
    computed = np.array(instancer.ComputeExtentAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default()))
    np.testing.assert_allclose(authored, computed, atol=0.1)
    # instances, not copies: a few dozen bytes each
    assert path.stat().st_size < 4000 + 60 * 40


def test_usd_forest_bytes_are_reproducible_and_references_are_relative(library, tmp_path, monkeypatch):
    options = ForestOptions(area=(80, 60), count=25, seed=5)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = forest(library, tmp_path / "a" / "forest.usda", options)
    b = forest(library, tmp_path / "b" / "forest.usda", options)
    assert a.read_bytes() == b.read_bytes()
    assert "@../../" in a.read_text()  # from the forest's folder to the library's assets
    monkeypatch.chdir("/")
    stage = Usd.Stage.Open(str(a))
    targets = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Forest/Trees")).GetPrototypesRel().GetTargets()
    assert all(stage.GetPrimAtPath(t.AppendPath("Geom/bark")).IsValid() for t in targets)


def test_usd_forest_in_the_librarys_units_and_up_axis(tmp_path):
    options = ExportOptions(up_axis="Z", units="cm")
    (tmp_path / "oak").mkdir()
    variants = []
    for seed in (0, 1):
        tree = lsys3d.generate("tree3d", 2, seed, sides=4)
        lsys3d.export(tree, tmp_path / "oak" / f"oak_s{seed}.usdc", options)
        report = lsys3d.stats.report(tree.modules, tree.skeleton, tree)
        box = report["bbox"]
        variants.append(LibraryVariant("oak", seed, f"oak/oak_s{seed}.usdc", None, 1.0, box["min"], box["max"]))
    library = write_library(tmp_path / "library.usda", variants, options)
    assert read_library(tmp_path).options == ExportOptions(up_axis="Z", units="cm")
    path = forest(library, tmp_path / "forest.usdc", ForestOptions(area=(20, 10), count=8, seed=1))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 0.01
    positions = np.array(UsdGeom.PointInstancer(stage.GetPrimAtPath("/Forest/Trees")).GetPositionsAttr().Get())
    assert (positions[:, 2] == 0).all() and (np.abs(positions[:, :2]) <= [1000, 500]).all()
    assert np.abs(positions[:, :2]).max() > 100  # centimetres


@pytest.fixture(scope="module")
def in_blender(library, tmp_path_factory) -> dict:
    """A USD forest (30 trees) and a glTF forest (50) of the library, and Blender's reports of them: one Blender
    imports both, each into an empty scene."""
    folder = tmp_path_factory.mktemp("forests")
    paths = {
        "usdc": forest(library, folder / "forest.usdc", ForestOptions(area=(80, 60), count=30, seed=2)),
        "glb": forest(library, folder / "forest.glb", ForestOptions(area=(80, 60), count=50, seed=3)),
    }
    return {
        kind: (path, report)
        for (kind, path), report in zip(paths.items(), validators.blender_imports(list(paths.values())), strict=True)
    }


def test_blender_opens_the_usd_forest(in_blender):
    _, report = in_blender["usdc"]
    assert not any(o.get("repaired") for o in report["objects"])
    assert report["drawn_instances"] >= 30
    lo, hi = np.array(report["drawn_bbox"])
    assert hi[0] - lo[0] > 40 and hi[1] - lo[1] > 30  # spread over the area (Blender is Z up)


# ---------------------------------------------------------------- glTF


def glb_json(path) -> dict:
    data = path.read_bytes()
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20 : 20 + length])


def test_glb_forest_instances_each_asset_once(in_blender):
    path, imported = in_blender["glb"]
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
    assert {m["code"] for m in report["issues"]["messages"]} <= validators.HARMLESS_INFOS
    doc = glb_json(path)
    assert doc["extensionsUsed"] == ["EXT_mesh_gpu_instancing"]
    instanced = [n for n in doc["nodes"] if "mesh" in n]
    assert all("EXT_mesh_gpu_instancing" in n["extensions"] for n in instanced)
    assert len({n["mesh"] for n in instanced}) == len(instanced) == len(doc["meshes"])  # each mesh once
    per_asset = {}
    for node in instanced:
        translation = node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"]
        per_asset[translation] = doc["accessors"][translation]["count"]
    assert sum(per_asset.values()) == 50
    assert len(doc["materials"]) == 2  # bark and leaf, shared by every asset
    assert not any(o.get("repaired") for o in imported["objects"])
    lo, hi = np.array(imported["drawn_bbox"])
    assert hi[0] - lo[0] > 40 and hi[1] - lo[1] > 30


def test_glb_forest_bytes_are_reproducible(library, tmp_path):
    options = ForestOptions(area=(80, 60), count=20, seed=9)
    a = forest(library, tmp_path / "a.glb", options)
    b = forest(library, tmp_path / "b.glb", options)
    assert a.read_bytes() == b.read_bytes()


# ---------------------------------------------------------------- errors and the command


def test_forest_errors(library, tmp_path):
    with pytest.raises(ForestError, match="no such library"):
        forest(tmp_path / "none.usda", tmp_path / "f.usdc")
    (tmp_path / "other.usda").write_text('#usda 1.0\ndef Xform "Tree" {}\n')
    with pytest.raises(ForestError, match="not an lsys3d library"):
        forest(tmp_path / "other.usda", tmp_path / "f.usdc")
    with pytest.raises(ForestError, match="no species 'pine' in the library"):
        forest(library, tmp_path / "f.usdc", ForestOptions(species=("pine",)))
    with pytest.raises(ForestError, match=r"written as \.usdc, \.usda, \.usd or \.glb"):
        forest(library, tmp_path / "f.obj")
    (tmp_path / "f.usdc").write_text("keep")
    with pytest.raises(lsys3d.ExportError, match="file exists"):
        forest(library, tmp_path / "f.usdc", ForestOptions(no_clobber=True))
    assert (tmp_path / "f.usdc").read_text() == "keep"


def test_a_missing_asset_file_is_an_error(tmp_path):
    variant = LibraryVariant("oak", 0, "oak_s0.usdc", None, 1.0, (0, 0, 0), (1, 1, 1))
    library = write_library(tmp_path / "library.usda", [variant], ExportOptions())
    with pytest.raises(ForestError, match=r"asset oak_s0's file '.*oak_s0\.usdc' is missing"):
        forest(library, tmp_path / "forest.usdc")
    assert not (tmp_path / "forest.usdc").exists()


def test_glb_forest_needs_glb_assets(tmp_path):
    tree = lsys3d.generate("tree3d", 2, 0, sides=4)
    lsys3d.export(tree, tmp_path / "oak_s0.usdc")
    variant = LibraryVariant("oak", 0, "oak_s0.usdc", None, 1.0, (0, 0, 0), (1, 1, 1))
    library = write_library(tmp_path / "library.usda", [variant], ExportOptions())
    with pytest.raises(ForestError, match=r'asset oak_s0 has no \.glb; a \.glb forest needs the batch to write "glb"'):
        forest(library, tmp_path / "forest.glb")


def test_forest_command(library, tmp_path, capsys):
    from lsys3d.cli import main

    out = tmp_path / "forest.glb"
    args = ["forest", str(library.parent), "-o", str(out), "--area", "30x20", "--count", "12", "--seed", "4"]
    assert main([*args, "--scale", "0.9,1.1", "--yaw", "0,90", "--species", "fern"]) == 0
    assert capsys.readouterr().out.strip().startswith(f"wrote {out}: 12 instances on 30 x 20 m")
    provenance = glb_json(out)["asset"]["extras"]["forest"]
    assert provenance == {
        "area": [30.0, 20.0],
        "count": 12,
        "crown_overlap": 0.8,
        "scale": [0.9, 1.1],
        "seed": 4,
        "spacing": 1.0,
        "species": ["fern"],
        "yaw": [0.0, 90.0],
    }
    for bad in (["--count", "0"], ["--area", "ax2"], ["--area", "0x2"], ["--spacing", "-1"]):
        with pytest.raises(SystemExit) as info:  # a value out of its range: a usage error
            main(["forest", str(library), *bad])
        assert info.value.code == 2
    assert main(["forest", str(library), "--scale", "1,0.5"]) == 1  # two values that disagree: the options' error


# ---------------------------------------------------------------- dense stands: crowns that meet (issue 37)


def test_crowns_overlap_where_the_stand_is_dense_and_no_further_than_allowed():
    """Each trunk keeps spacing * (1 - o) * (r_i + r_j) from the others, o at most crown_overlap, and
    instances overlap only when there is no room for them otherwise."""
    radius = [4.0, 6.0]
    options = ForestOptions(area=(60, 60), count=120, seed=2, crown_overlap=0.6)
    s = scatter(radius, ["a", "b"], options)
    assert len(s.variant) == 120
    assert (pair_gaps(s, radius, 1.0 - 0.6) >= -1e-9).all()  # never closer than the largest overlap allows
    assert (pair_gaps(s, radius, 1.0) < 0).sum() > 50  # crowns that meet
    with pytest.raises(ForestError, match=r"overlapping by up to 0%; .* allow more overlap"):
        scatter(radius, ["a", "b"], options.replace(crown_overlap=0.0))
    with pytest.raises(ForestError, match=r"only [\d,]+ of 120 instances fit .* overlapping by up to 10%"):
        scatter(radius, ["a", "b"], options.replace(crown_overlap=0.1))


def test_a_stand_with_room_is_placed_as_without_overlap():
    """The overlap is tried only after a position without it was not found: a forest that fits without it is
    the same, position for position, whatever crown_overlap allows."""
    options = ForestOptions(area=(80, 60), count=60, seed=4)
    a = scatter([1.0, 2.5], ["a", "b"], options)
    b = scatter([1.0, 2.5], ["a", "b"], options.replace(crown_overlap=0.0))
    assert np.array_equal(a.position, b.position) and np.array_equal(a.variant, b.variant)


@pytest.mark.slow  # 500 trees placed by the CLI in a subprocess
def test_the_readme_forest_command_places_500_trees(tmp_path, monkeypatch):
    """The README's commands: a library of its jobs file (tree3d, sides 6, angle jitter 8: crowns of 6-7 m;
    two of its fifty seeds), then `lsys3d forest library/ -o forest.usdc --area 100x100 --count 500 --seed 3`:
    500 instances, the same bytes on a second run."""
    import subprocess
    import sys

    (tmp_path / "jobs.toml").write_text(
        '[[jobs]]\ngrammar = "tree3d"\nseeds = "0-1"\nformats = ["glb", "usdc"]\n'
        "options = { sides = 6, angle_jitter = 8 }\n"
    )
    lsys3d.batch(tmp_path / "jobs.toml", tmp_path / "library", workers=1)
    command = [sys.executable, "-m", "lsys3d", "forest", "library/", "-o", "forest.usdc"]
    command += ["--area", "100x100", "--count", "500", "--seed", "3"]
    first = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    assert first.stdout.startswith("wrote forest.usdc: 500 instances on 100 x 100 m")
    stage = Usd.Stage.Open(str(tmp_path / "forest.usdc"))
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/Forest/Trees"))
    positions = np.array(instancer.GetPositionsAttr().Get())[:, [0, 2]]
    assert len(positions) == 500
    lines = [json.loads(t) for t in (tmp_path / "library" / "manifest.jsonl").read_text().splitlines()]
    radius_of = {line["id"]: line["crown_radius"] for line in lines}
    names = [str(t.name) for t in instancer.GetPrototypesRel().GetTargets()]
    radius = np.array([radius_of[next(i for i in radius_of if i in name)] for name in names])
    scales = np.array(instancer.GetScalesAttr().Get())[:, 0]
    r = radius[np.array(instancer.GetProtoIndicesAttr().Get())] * scales
    d = np.sqrt(((positions[:, None] - positions[None]) ** 2).sum(-1))
    off = ~np.eye(500, dtype=bool)
    assert (d - 0.2 * (r[:, None] + r[None]))[off].min() >= -1e-3  # at most 80% overlap (float32 positions)
    before = (tmp_path / "forest.usdc").read_bytes()
    # the second run in this process (the command line's main): the same bytes from another process too
    from lsys3d.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(command[3:]) == 0 and (tmp_path / "forest.usdc").read_bytes() == before
