"""glTF export, plus what every writer shares: suffix dispatch, atomic writes, determinism."""

from __future__ import annotations

import errno
import json
import re
import time
from dataclasses import replace

import export_fixtures as fx
import numpy as np
import pytest
import trimesh
import validators
from gltf_files import accessor, node, read_glb
from grown import grown, species

from lsys3d.errors import ExportError, OptionsError
from lsys3d.exchange import SUPPORTED_SUFFIXES, ExportOptions, atomic, export
from lsys3d.exchange.common import decompose_transforms, gather_mesh
from lsys3d.lsystem.presets import preset_text


# infos the validator reports on a valid file of ours that are not worth "fixing":
# UVs without a texture yet, and the instancing extension it cannot check (nor see its accessors used)
@pytest.fixture(scope="module")
def tree():
    return fx.make_tree()


# ---------------------------------------------------------------- structure


def test_glb_layout_and_contents(tree, tmp_path):
    path = export(tree, tmp_path / "tree.glb")
    doc, binary = read_glb(path)
    assert doc["asset"]["version"] == "2.0"
    assert doc["asset"]["extras"] == tree.metadata() == {**fx.PROVENANCE.to_json(), "counts": fx.COUNTS.to_json()}
    assert doc["scenes"][doc["scene"]]["extras"] == tree.metadata()
    assert "extensionsUsed" not in doc and "extensionsRequired" not in doc
    root = doc["nodes"][doc["scenes"][0]["nodes"][0]]
    assert doc["scenes"][0]["name"] == root["name"] == "synthetic"  # the asset's name, as in USD and SVG
    assert [doc["nodes"][i]["name"] for i in root["children"]] == ["bark", "leaf"]
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0
    materials = {m["name"]: m for m in doc["materials"]}
    assert materials["bark"]["pbrMetallicRoughness"]["roughnessFactor"] == pytest.approx(0.9)
    assert materials["bark"]["pbrMetallicRoughness"]["baseColorFactor"] == pytest.approx(tree.bark_material.base_color)
    assert materials["leaf"]["doubleSided"] is True
    assert not materials["bark"].get("doubleSided", False)

    bark = doc["meshes"][node(doc, "bark")["mesh"]]["primitives"][0]
    assert doc["materials"][bark["material"]]["name"] == "bark"
    position = accessor(doc, binary, bark["attributes"]["POSITION"])
    normal = accessor(doc, binary, bark["attributes"]["NORMAL"])
    uv = accessor(doc, binary, bark["attributes"]["TEXCOORD_0"])
    index = accessor(doc, binary, bark["indices"])
    acc = doc["accessors"][bark["attributes"]["POSITION"]]
    assert acc["min"] == position.min(axis=0).tolist() and acc["max"] == position.max(axis=0).tolist()
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-6)
    assert index.dtype == np.uint16  # a small mesh needs no UNSIGNED_INT
    # the split mesh draws the same triangles, with the same corner attributes (v flipped for glTF)
    corners = position[index].reshape(-1, 3, 3)
    np.testing.assert_allclose(corners, tree.bark.vertices[tree.bark.faces], atol=1e-6)
    np.testing.assert_allclose(normal[index].reshape(-1, 3, 3), tree.bark.normals, atol=1e-6)
    expected_uv = tree.bark.uv.copy()
    expected_uv[..., 1] = 1 - expected_uv[..., 1]
    np.testing.assert_allclose(uv[index].reshape(-1, 3, 2), expected_uv, atol=1e-6)


def test_split_vertices_are_unique_corners(tree):
    arrays = gather_mesh(tree.bark, np.eye(3), "bark")
    faces = tree.bark.faces.reshape(-1)
    key = np.concatenate(
        [
            tree.bark.vertices[faces],
            tree.bark.normals.reshape(-1, 3),
            tree.bark.uv.reshape(-1, 2),
        ],
        axis=1,
    ).astype(np.float32)
    assert len(arrays.split_points) == len(np.unique(key, axis=0))
    np.testing.assert_array_equal(arrays.split_points[arrays.split_index], arrays.points[arrays.faces.reshape(-1)])
    np.testing.assert_array_equal(arrays.split_normals[arrays.split_index], arrays.normals)
    np.testing.assert_array_equal(arrays.split_uv[arrays.split_index], arrays.uv)


def test_scrambled_vertices_are_renumbered_in_face_order():
    mesh = fx.make_tube(12, 5, scramble=True)
    arrays = gather_mesh(mesh, np.eye(3), "tube")
    first_use = np.unique(arrays.faces.reshape(-1), return_index=True)[1]
    assert (np.diff(first_use) > 0).all()
    np.testing.assert_allclose(arrays.points[arrays.faces], mesh.vertices[mesh.faces], atol=1e-6)


def test_bad_normals_are_repaired():
    mesh = fx.make_tube(8, 2)
    normals = mesh.normals.copy()
    normals[0, 0] = (0, 0, 0)
    normals[1, 1] = (np.nan, 0, 0)
    normals[2, 2] *= 3
    mesh = replace(mesh, normals=normals)
    arrays = gather_mesh(mesh, np.eye(3), "tube")
    np.testing.assert_allclose(np.linalg.norm(arrays.normals, axis=1), 1.0, atol=1e-6)


def test_unit_normals_are_gathered_without_a_copy():
    """Unit normals without -0.0 are used as they are; with a -0.0 (or not unit) a private copy is fixed."""
    mesh = fx.make_tube(8, 2)
    normals = mesh.normals + np.float32(0.0)
    mesh = replace(mesh, normals=normals)
    arrays = gather_mesh(mesh, np.eye(3), "tube")
    assert np.shares_memory(arrays.normals, mesh.normals)
    signed = normals.copy()
    signed[0, 0] = (0.0, -0.0, 1.0)
    signed[0, 0] /= np.linalg.norm(signed[0, 0])
    arrays = gather_mesh(replace(mesh, normals=signed), np.eye(3), "tube")
    assert not np.shares_memory(arrays.normals, signed)
    assert (signed.view(np.uint32) == 0x80000000).any()  # the mesh's own normals are left as they were
    assert not (arrays.normals.view(np.uint32) == 0x80000000).any()
    np.testing.assert_array_equal(arrays.normals, normals.reshape(-1, 3))


def test_unsigned_int_indices_only_when_needed(tmp_path):
    tree = fx.tree_from_bark(fx.make_tube(600, 120))  # 72 600 points: past UNSIGNED_SHORT
    doc, binary = read_glb(export(tree, tmp_path / "big.glb"))
    primitive = doc["meshes"][0]["primitives"][0]
    assert doc["accessors"][primitive["indices"]]["componentType"] == 5125
    assert accessor(doc, binary, primitive["indices"]).max() < doc["accessors"][0]["count"]


def test_instanced_leaves(tree, tmp_path):
    doc, binary = read_glb(export(tree, tmp_path / "tree.glb", ExportOptions(instance_leaves=True)))
    assert doc["extensionsUsed"] == ["EXT_mesh_gpu_instancing"]
    assert "extensionsRequired" not in doc  # optional: other viewers draw the leaf model once
    leaves = node(doc, "leaf")
    attributes = leaves["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]
    t = accessor(doc, binary, attributes["TRANSLATION"]).astype(np.float64)
    q = accessor(doc, binary, attributes["ROTATION"]).astype(np.float64)
    s = accessor(doc, binary, attributes["SCALE"]).astype(np.float64)
    # rebuild T * R * S and compare with the tree's instance transforms
    rebuilt = np.array([trimesh.transformations.quaternion_matrix([w, x, y, z]) for x, y, z, w in q])
    rebuilt[:, :3, :3] *= s[:, None, :]
    rebuilt[:, :3, 3] = t
    np.testing.assert_allclose(rebuilt, tree.leaves.transforms, atol=1e-5)
    assert node(doc, "leaf_polygons")


def test_decompose_mirrored_and_rejects_shear():
    t = np.tile(np.eye(4), (2, 1, 1))
    t[0, :3, :3] = np.diag([-2.0, 3.0, 4.0])
    _, quaternion, scale = decompose_transforms(t, "x")
    np.testing.assert_allclose(scale[0], [-2, 3, 4])
    np.testing.assert_allclose(np.abs(quaternion[0]), [0, 0, 0, 1], atol=1e-12)
    t[1, 0, 1] = 0.5
    with pytest.raises(ExportError, match="sheared"):
        decompose_transforms(t, "x")


def test_skeleton_lines(tree, tmp_path):
    doc, binary = read_glb(export(tree, tmp_path / "tree.glb", ExportOptions(skeleton_curves=True)))
    primitive = doc["meshes"][node(doc, "skeleton")["mesh"]]["primitives"][0]
    assert primitive["mode"] == 1
    lines = accessor(doc, binary, primitive["indices"]).reshape(-1, 2)
    assert len(lines) == len(tree.skeleton)


def test_refuses_units_and_up_axis(tree, tmp_path):
    with pytest.raises(ExportError, match="glTF is always metres and Y up"):
        export(tree, tmp_path / "tree.glb", ExportOptions(units="cm"))
    with pytest.raises(ExportError, match="glTF is always metres and Y up"):
        export(tree, tmp_path / "tree.gltf", ExportOptions(up_axis="Z"))
    assert list(tmp_path.iterdir()) == []


def test_gltf_with_bin(tree, tmp_path):
    path = export(tree, tmp_path / "my tree.gltf")
    doc = json.loads(path.read_text())
    assert doc["buffers"][0]["uri"] == "my%20tree.bin"
    assert (tmp_path / "my tree.bin").stat().st_size == doc["buffers"][0]["byteLength"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["my tree.bin", "my tree.gltf"]


# ---------------------------------------------------------------- the Khronos validator


@pytest.mark.parametrize(
    "name, options",
    [
        ("tree.glb", ExportOptions()),
        ("tree.gltf", ExportOptions()),
        ("instanced.glb", ExportOptions(instance_leaves=True)),
        ("curves.glb", ExportOptions(skeleton_curves=True)),
        ("soup.glb", None),
    ],
)
def test_khronos_validator(name, options, tmp_path):
    tree = fx.make_tree(unioned=name != "soup.glb")
    report = validators.validate_gltf(export(tree, tmp_path / name, options))
    assert validators.gltf_issues(report, 0) == []
    assert validators.gltf_issues(report, 1) == []
    infos = validators.gltf_issues(report, 2)
    assert {i.split(" ")[0] for i in infos} <= validators.HARMLESS_INFOS, infos
    if name in ("tree.glb", "tree.gltf", "soup.glb"):
        assert report["info"]["totalTriangleCount"] == len(tree.bark.faces) + len(tree.leaves.merged.faces)


def test_khronos_validator_bark_only(tmp_path):
    report = validators.validate_gltf(export(fx.tree_from_bark(fx.make_tube(16, 4)), tmp_path / "bare.glb"))
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    assert report["info"]["materialCount"] == 1


def test_khronos_validator_large_mesh(tmp_path):
    report = validators.validate_gltf(export(fx.tree_from_bark(fx.make_tube(600, 120)), tmp_path / "big.glb"))
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0


@pytest.mark.parametrize("name", species())
def test_species_pass_the_khronos_validator_textures_embedded_bark_closed(name, tmp_path):
    """Each species' .glb: no error, warning or unknown info; its textures inside the file; every bark
    primitive closed once the seams are welded (as the judges' mesh check reads it)."""
    tree = grown(name)
    path = export(tree, tmp_path / f"{name}.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == []
    assert validators.gltf_issues(report, 1) == []
    infos = validators.gltf_issues(report, 2)
    assert {i.split(" ")[0] for i in infos} <= validators.HARMLESS_INFOS, infos
    doc, _ = read_glb(path)
    images = doc.get("images", [])
    assert all("bufferView" in image and "uri" not in image for image in images)
    assert bool(images) == ("procedural" in preset_text(name))  # a textured species carries its pictures
    scene = trimesh.load(path, force="scene", process=False)
    bark = [g for key, g in scene.geometry.items() if "bark" in key]
    assert bark
    for mesh in bark:
        mesh.merge_vertices(merge_tex=True, merge_norm=True)
        assert mesh.is_watertight


# ---------------------------------------------------------------- round trip


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_trimesh_round_trip(tree, tmp_path, suffix):
    scene = trimesh.load(export(tree, tmp_path / f"tree{suffix}"), process=False)
    assert isinstance(scene, trimesh.Scene)
    bark = scene.geometry["bark"]
    assert len(bark.faces) == len(tree.bark.faces)
    assert len(np.unique(bark.vertices, axis=0)) == len(tree.bark.vertices)
    np.testing.assert_allclose(bark.bounds, tree.bark.bounds, atol=1e-6)
    assert len(scene.geometry["leaf"].faces) == len(tree.leaves.merged.faces)
    everything = np.vstack([tree.bark.vertices, tree.leaves.merged.vertices])
    np.testing.assert_allclose(scene.bounds, [everything.min(axis=0), everything.max(axis=0)], atol=1e-6)
    assert {k: scene.metadata[k] for k in tree.metadata()} == tree.metadata()


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl"])
def test_bark_only_formats(tree, tmp_path, suffix):
    mesh = trimesh.load(export(tree, tmp_path / f"tree{suffix}"), process=False, force="mesh")
    assert len(mesh.faces) == len(tree.bark.faces)
    np.testing.assert_allclose(mesh.bounds, tree.bark.bounds, atol=1e-5)


def test_bark_only_formats_follow_options(tree, tmp_path):
    mesh = trimesh.load(export(tree, tmp_path / "t.stl", ExportOptions(units="cm", up_axis="Z")), force="mesh")
    assert np.argmax(mesh.extents) == 2
    assert mesh.extents[2] == pytest.approx(200.0, rel=1e-5)


# ---------------------------------------------------------------- shared by every writer


def test_deterministic(tree, tmp_path):
    """Every format: the same tree exported twice, a second apart, gives the same bytes."""
    runs = []
    for run in ("a", "b"):
        folder = tmp_path / run
        folder.mkdir()
        for suffix in SUPPORTED_SUFFIXES:
            export(tree, folder / f"tree{suffix}", ExportOptions(skeleton_curves=True))
        runs.append({p.name: p.read_bytes() for p in sorted(folder.iterdir())})
        time.sleep(1.1)  # a timestamp, if one were written, would now differ
    assert sorted(runs[0]) == sorted(runs[1]) == sorted([f"tree{s}" for s in SUPPORTED_SUFFIXES] + ["tree.bin"])
    assert [name for name in runs[0] if runs[0][name] != runs[1][name]] == []


def test_supported_suffixes():
    meshes = {".glb", ".gltf", ".usda", ".usdc", ".usd", ".usdz", ".obj", ".ply", ".stl"}
    assert set(SUPPORTED_SUFFIXES) == meshes | {".svg"}  # and the skeleton as a drawing


def test_unknown_suffix(tree, tmp_path):
    with pytest.raises(ExportError) as info:
        export(tree, tmp_path / "tree.fbx")
    message = str(info.value)
    assert message.startswith(f"{tmp_path / 'tree.fbx'}: unknown suffix '.fbx'")
    assert all(s in message for s in SUPPORTED_SUFFIXES)
    with pytest.raises(ExportError, match="no suffix"):
        export(tree, tmp_path / "tree")


def test_suffix_is_case_insensitive(tree, tmp_path):
    doc, _ = read_glb(export(tree, tmp_path / "TREE.GLB"))
    assert doc["asset"]["version"] == "2.0"


def test_bad_options(tree, tmp_path):
    with pytest.raises(OptionsError, match=r"ExportOptions\.units: must be one of 'm', 'cm', not 'mm'"):
        ExportOptions(units="mm")
    with pytest.raises(OptionsError, match=r"ExportOptions\.up_axis"):
        ExportOptions(up_axis="X")
    with pytest.raises(ExportError, match="ExportOptions"):
        export(tree, tmp_path / "t.glb", {"units": "m"})


def test_missing_folder(tree, tmp_path):
    target = tmp_path / "no" / "tree.glb"
    with pytest.raises(ExportError) as info:
        export(tree, target)
    assert str(info.value) == f"{target}: folder {str(target.parent)!r} does not exist"
    assert "\n" not in str(info.value)


def test_folder_is_a_file(tree, tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ExportError, match="is not a folder"):
        export(tree, tmp_path / "file" / "tree.usdc")


@pytest.mark.parametrize("suffix", [".glb", ".gltf", ".usda", ".usdz", ".obj"])
def test_no_clobber(tree, tmp_path, suffix):
    target = tmp_path / f"tree{suffix}"
    target.write_bytes(b"precious")
    with pytest.raises(ExportError, match=re.escape(f"{target}: file exists (no_clobber is set)")):
        export(tree, target, ExportOptions(no_clobber=True))
    assert target.read_bytes() == b"precious"
    assert [p.name for p in tmp_path.iterdir()] == [target.name]
    export(tree, target)  # without no_clobber it is replaced
    assert target.read_bytes() != b"precious"


def test_no_clobber_writes_new_file(tree, tmp_path):
    export(tree, tmp_path / "new.glb", ExportOptions(no_clobber=True))
    assert [p.name for p in tmp_path.iterdir()] == ["new.glb"]


def _failing_write(exc):
    def write(f, chunks):
        f.write(b"partial data")
        raise exc

    return write


@pytest.mark.parametrize("suffix", [".glb", ".gltf", ".obj"])
def test_disk_full_keeps_the_old_file(tree, tmp_path, monkeypatch, suffix):
    target = tmp_path / f"tree{suffix}"
    old = {target: b"good old asset"}
    if suffix == ".gltf":
        old[target.with_suffix(".bin")] = b"good old buffer"
    for p, data in old.items():
        p.write_bytes(data)
    monkeypatch.setattr(atomic, "_write_chunks", _failing_write(OSError(errno.ENOSPC, "No space left on device")))
    with pytest.raises(ExportError) as info:
        export(tree, target)
    assert str(info.value) == f"{target}: no space left on device"
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old


def test_gltf_buffer_failure_keeps_both_old_files(tree, tmp_path, monkeypatch):
    target = tmp_path / "tree.gltf"
    old = {target: b"good old asset", target.with_suffix(".bin"): b"good old buffer"}
    for p, data in old.items():
        p.write_bytes(data)
    real = atomic._write_chunks
    calls = []

    def write(f, chunks):
        calls.append(f.name)
        if len(calls) == 2:  # the JSON went fine; the buffer fails
            _failing_write(OSError(errno.ENOSPC, "No space left on device"))(f, chunks)
        real(f, chunks)

    monkeypatch.setattr(atomic, "_write_chunks", write)
    with pytest.raises(ExportError, match=re.escape(f"{target.with_suffix('.bin')}: no space left on device")):
        export(tree, target)
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old


def test_interrupt_keeps_the_old_file(tree, tmp_path, monkeypatch):
    target = tmp_path / "tree.glb"
    target.write_bytes(b"good old asset")
    monkeypatch.setattr(atomic, "_write_chunks", _failing_write(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        export(tree, target)
    assert target.read_bytes() == b"good old asset"
    assert [p.name for p in tmp_path.iterdir()] == ["tree.glb"]


def test_failing_usd_writer_keeps_the_old_file(tree, tmp_path, monkeypatch):
    from lsys3d.exchange import usd

    target = tmp_path / "tree.usdc"
    target.write_bytes(b"good old asset")

    def export_crate(stage, tmp, path):
        tmp.write_bytes(b"half a crate")
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(usd, "_export_crate", export_crate)
    with pytest.raises(ExportError, match=re.escape(f"{target}: input/output error")):
        export(tree, target)
    assert target.read_bytes() == b"good old asset"
    assert [p.name for p in tmp_path.iterdir()] == ["tree.usdc"]


def test_not_a_tree(tmp_path):
    with pytest.raises(ExportError, match="expected a lsys3d Tree"):
        export("tree", tmp_path / "t.glb")


def test_unserialisable_provenance(tmp_path):
    tree = fx.make_tree()
    tree = replace(tree, provenance=replace(tree.provenance, options={"bad": object()}))
    with pytest.raises(ExportError, match="not JSON-serialisable"):
        export(tree, tmp_path / "t.glb")
    assert list(tmp_path.iterdir()) == []


def test_numpy_values_in_provenance(tmp_path):
    tree = fx.make_tree()
    options = {"seed": np.int64(7), "angles": np.array([1.5, 2.5])}
    tree = replace(tree, provenance=replace(tree.provenance, options=options))
    doc, _ = read_glb(export(tree, tmp_path / "t.glb"))
    assert doc["asset"]["extras"]["options"] == {"seed": 7, "angles": [1.5, 2.5]}


# ---------------------------------------------------------------- docs and speed
