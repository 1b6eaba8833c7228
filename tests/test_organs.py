"""Organs: built-in prototypes, organs from plain arrays, and their export as instances or merged parts."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest
import validators
from gltf_files import node, read_glb
from pxr import Usd, UsdGeom, UsdShade, UsdSkel

import lsys3d
from lsys3d.cli import main
from lsys3d.exchange import ExportOptions, export
from lsys3d.images import png_bytes
from lsys3d.look.organs import OrganOptions, bind_organs, box, disc, organs, sphere
from lsys3d.look.surfaces import surface_table
from lsys3d.turtle.hierarchy import hierarchy

# ---------------------------------------------------------------- prototypes


@pytest.mark.parametrize(("subdivisions", "faces"), [(0, 20), (1, 80), (2, 320)])
def test_sphere(subdivisions, faces):
    m = sphere(subdivisions)
    assert len(m.faces) == faces and m.is_watertight and m.is_winding_consistent
    assert np.allclose(np.linalg.norm(m.vertices, axis=1), 0.5)  # diameter 1
    assert m.volume > 0  # faces outward
    assert np.allclose(m.normals, 2 * m.vertices[m.faces], atol=1e-6)  # smooth: the normal is the position
    u = m.uv[:, :, 0]
    assert (np.abs(u - u[:, :1]) <= 0.5 + 1e-6).all()  # no triangle goes the long way round the seam


def test_disc_and_box():
    d = disc(12)
    assert len(d.faces) == 12 and np.allclose(d.face_normals, [0, 1, 0])  # a sheet facing U
    assert np.allclose(np.linalg.norm(d.vertices[1:], axis=1), 0.5) and not d.is_watertight
    assert d.uv.min() >= 0 and d.uv.max() <= 1
    b = box()
    assert b.is_watertight and b.volume == pytest.approx(1.0) and b.bounds.tolist() == [[-0.5, -0.5, 0], [0.5, 0.5, 1]]
    assert b.uv.min() == 0 and b.uv.max() == 1


# ---------------------------------------------------------------- organs from arrays


def frames(k: int) -> np.ndarray:
    """k turtle frames: left, up, heading as columns; heading turning about the y axis."""
    a = np.linspace(0, np.pi / 2, k)
    heading = np.stack([np.sin(a), np.zeros(k), np.cos(a)], axis=1)
    up = np.tile([0.0, 1.0, 0.0], (k, 1))
    left = np.cross(up, heading)
    return np.stack([left, up, heading], axis=2)


def test_organs_from_arrays():
    position = np.array([[0, 0, 0], [1, 2, 3], [4, 5, 6], [7, 8, 9]], np.float64)
    o = organs(["sphere", "box", "sphere", "disc"], position, frames(4), [0.2, 0.5, 0.4, 1.0], [3, 0, 4, 3])
    assert [p.name for p in o.prototypes] == ["box", "disc", "sphere"]
    assert [p.closed for p in o.prototypes] == [True, False, True]
    assert o.prototype.tolist() == [2, 0, 2, 1] and o.material.tolist() == [3, 0, 4, 3] and len(o) == 4
    # transform: the frame scaled by the size, at the position
    assert np.allclose(o.transforms[1, :3, :3], frames(4)[1] * 0.5) and np.allclose(o.transforms[1, :3, 3], [1, 2, 3])
    spheres = o.merged[2]
    assert len(spheres.faces) == 160 and spheres.face_material.tolist() == [3] * 80 + [4] * 80
    centre = spheres.vertices[: len(spheres.vertices) // 2].mean(axis=0)
    radius = np.linalg.norm(spheres.vertices[: len(spheres.vertices) // 2] - [0, 0, 0], axis=1)
    assert np.allclose(centre, 0, atol=1e-9) and np.allclose(radius, 0.1)  # diameter 0.2 at the origin
    assert organs([], np.zeros((0, 3)), np.zeros((0, 3, 3)), []).prototypes == ()


def test_organ_options_and_zero_sizes():
    o = organs(["sphere"] * 3, np.zeros((3, 3)), frames(3), [0.1, 0.0, 0.2], options=OrganOptions(0, 5))
    assert len(o) == 2 and len(o.merged[0].faces) == 40  # the organ of size 0 is left out
    assert (
        len(organs(["disc"], np.zeros((1, 3)), frames(1), [1], options=OrganOptions(disc_sides=5)).merged[0].faces) == 5
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"position": np.zeros((2, 3))}, r"position has shape \(2, 3\), expected \(1, 3\)"),
        ({"frame": np.zeros((1, 3))}, "frame has shape"),
        ({"size": [np.nan]}, "not a finite number"),
        ({"material": [1, 2]}, "material has shape"),
    ],
)
def test_bad_arrays(kwargs, message):
    args = {"position": np.zeros((1, 3)), "frame": frames(1), "size": [1.0]} | kwargs
    with pytest.raises(lsys3d.GeometryError, match=message):
        organs(["sphere"], args["position"], args["frame"], args["size"], kwargs.get("material"))


def test_organs_are_counted_before_they_are_built():
    with pytest.raises(lsys3d.LimitError, match=r"organs: 10 organs make 800 triangles, more than the limit of 500"):
        organs(["sphere"] * 10, np.zeros((10, 3)), frames(10), np.ones(10), max_triangles=500)


def write_surfaces(folder):
    import trimesh

    star = trimesh.Trimesh([[0, 0, 0], [0.3, 0, 0.5], [0, 0, 1], [-0.3, 0, 0.5]], [[0, 2, 1], [0, 3, 2]])
    (folder / "flower.obj").write_text(star.export(file_type="obj"))
    rgba = np.zeros((8, 8, 4), np.uint8)
    rgba[2:6, 2:6] = (250, 200, 40, 255)
    (folder / "petal.png").write_bytes(png_bytes(rgba))
    (folder / "plant.toml").write_text(
        'axiom = "F[+F]F"\nrules = ["F -> F[-F]F"]\nangle = 40\n\n'
        '[surfaces]\nflower = "flower.obj"\npetal = { card = "petal.png" }\n'
        'sphere = { model = "flower.obj", normalize = false }\n'
    )
    return lsys3d.Grammar.from_file(folder / "plant.toml")


def test_surfaces_and_fallbacks(tmp_path, caplog):
    table = surface_table(write_surfaces(tmp_path))
    with caplog.at_level(logging.INFO, logger="lsys3d"):
        o = organs(["flower", "petal", "l", "sphere", "disc"], np.zeros((5, 3)), frames(5), np.ones(5), surfaces=table)
    by_name = {p.name: p for p in o.prototypes}
    assert len(by_name["flower"].mesh.faces) == 2 and by_name["flower"].material is None
    assert by_name["petal"].material.texture.name == "petal.png" and by_name["petal"].material.alpha_cutoff == 0.5
    assert len(by_name["sphere"].mesh.faces) == 2  # [surfaces] sphere replaces the built-in
    assert len(by_name["disc"].mesh.faces) == 16
    assert o.fallbacks == ("l",) and len(by_name["l"].mesh.faces) == 28  # no model: the leaf blade
    assert "no [surfaces] model for 'l': drawn as the leaf" in caplog.text


def test_attributes_and_rig():
    tree = lsys3d.generate("abop-1.24a", iterations=2, rig=True, attributes="compact", seed=3)
    sk = tree.skeleton
    h = hierarchy(sk, 3)
    segment = np.array([0, len(sk) - 1, -1])
    position = np.array([sk.end[0], sk.end[-1], [5.0, 5.0, 5.0]])
    o = organs(["sphere"] * 3, position, frames(3), [0.1] * 3, segment=segment, hierarchy=h)
    branch = o.instance_attributes["branch_id"]
    assert branch.tolist() == [h.branch_of[0], h.branch_of[len(sk) - 1], -1]
    assert o.instance_attributes["pivot"][2].tolist() == [5, 5, 5]  # no branch: its own position
    assert np.allclose(o.merged[0].attributes["branch_id"], np.repeat(branch, 42))
    bound = bind_organs(o, tree.rig, h)
    weights = bound.merged[0].attributes["skin_weights"]
    assert np.allclose(weights[:, 0], 1) and np.allclose(weights[:, 1:], 0)  # rigid, like leaves


# ---------------------------------------------------------------- export


@pytest.fixture(scope="module")
def flowering(tmp_path_factory):
    """A small plant with a sphere at each segment's end, discs, a model and a card."""
    folder = tmp_path_factory.mktemp("organs")
    grammar = write_surfaces(folder)
    tree = lsys3d.generate(grammar, 2, sides=6)
    sk = tree.skeleton
    kind = np.array(["sphere", "disc", "flower", "petal"])[np.arange(len(sk)) % 4]
    frame = np.stack([sk.left, sk.up, sk.heading], axis=2)
    material = np.arange(len(sk)) % 2
    o = organs(kind, sk.end, frame, np.full(len(sk), 0.3), material, surfaces=surface_table(grammar))
    return replace(tree, organs=o)


def test_gltf_merged_and_instanced(flowering, tmp_path):
    merged = export(flowering, tmp_path / "merged.glb")
    report = validators.validate_gltf(merged)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc, _ = read_glb(merged)
    names = [n["name"] for n in doc["nodes"]]
    assert {"organ_sphere", "organ_disc", "organ_flower", "organ_petal"} <= set(names)
    sphere_mesh = doc["meshes"][node(doc, "organ_sphere")["mesh"]]
    assert len(sphere_mesh["primitives"]) == 1  # both indices map to the default leaf material
    petal = doc["materials"][doc["meshes"][node(doc, "organ_petal")["mesh"]]["primitives"][0]["material"]]
    assert petal["name"] == "petal" and petal["alphaMode"] == "MASK"
    instanced = export(flowering, tmp_path / "instanced.glb", ExportOptions(instance_leaves=True))
    report = validators.validate_gltf(instanced)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, _ = read_glb(instanced)
    counts = {}
    for n in doc["nodes"]:
        if n.get("name", "").startswith("organ_"):
            translation = n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"]
            counts[n["name"]] = doc["accessors"][translation]["count"]
    assert sum(counts.values()) == len(flowering.organs)
    report = validators.blender_import(merged)
    objects = {o["name"] for o in report["objects"]}
    assert {"organ_sphere", "organ_disc", "organ_flower", "organ_petal"} <= objects


def test_usd_instanced_and_merged(flowering, tmp_path):
    path = export(flowering, tmp_path / "plant.usda")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    instancer = UsdGeom.PointInstancer(stage.GetPrimAtPath("/plant/Geom/organs"))
    targets = [t.name for t in instancer.GetPrototypesRel().GetTargets()]
    assert targets == ["disc", "flower", "petal", "sphere"]
    assert len(instancer.GetProtoIndicesAttr().Get()) == len(flowering.organs)
    petal = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/plant/Geom/organs/Prototypes/petal"))
    assert petal.ComputeBoundMaterial()[0].GetPrim().GetName() == "petal"
    path = export(flowering, tmp_path / "merged.usdz", ExportOptions(instance_leaves=False))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    spheres = UsdGeom.Mesh(stage.GetPrimAtPath("/plant/Geom/organ_sphere"))
    assert len(spheres.GetFaceVertexCountsAttr().Get()) == len(flowering.organs.merged[3].faces)
    report = validators.blender_import(path)
    assert {"organ_sphere", "organ_petal"} <= {o["name"] for o in report["objects"]}


def test_rigged_organs_are_skinned(tmp_path):
    tree = lsys3d.generate("abop-1.24a", iterations=2, rig=True, attributes="compact", seed=1)
    sk, h = tree.skeleton, hierarchy(tree.skeleton, 1)
    frame = np.stack([sk.left, sk.up, sk.heading], axis=2)
    keys = ("branch_id", "branch_t")
    o = organs(["sphere"] * len(sk), sk.end, frame, np.full(len(sk), 0.5), segment=np.arange(len(sk)), hierarchy=h)
    o = replace(o, instance_attributes={k: o.instance_attributes[k] for k in keys})
    o = replace(o, merged=tuple(m.keeping(keys) for m in o.merged))
    rigged = replace(tree, organs=bind_organs(o, tree.rig, h))
    path = export(rigged, tmp_path / "rigged.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, _ = read_glb(path)
    organ = node(doc, "organ_sphere")
    assert organ["skin"] == 0 and "JOINTS_0" in doc["meshes"][organ["mesh"]]["primitives"][0]["attributes"]
    path = export(rigged, tmp_path / "rigged.usda")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/abop_1_24a/Geom/organ_sphere"))
    assert binding.GetJointIndicesPrimvar().Get() is not None


def test_the_dialects_organs_grow_through_the_pipeline(tmp_path):
    """L-Py's @O (radius), @o and ~name in a grammar become organs of the tree, exported and validator-clean."""
    import trimesh

    star = trimesh.Trimesh([[0, 0, 0], [0.3, 0, 0.5], [0, 0, 1], [-0.3, 0, 0.5]], [[0, 2, 1], [0, 3, 2]])
    (tmp_path / "flower.obj").write_text(star.export(file_type="obj"))
    (tmp_path / "plant.toml").write_text(
        'dialect = "lpy"\n'
        'axiom = "_(0.05) F(1) [ +(40) F(1) @O(0.1) ] [ -(40) F(1) ~k(0.5) ] F(1) ;(2) @o(0.2)"\n\n'
        '[surfaces]\nk = "flower.obj"\n'
    )
    tree = lsys3d.generate(tmp_path / "plant.toml", seed=0)
    sk, o = tree.skeleton, tree.organs
    assert len(o) == 3 and sorted(p.name for p in o.prototypes) == ["circle", "k", "sphere"]
    by_name = {p.name: i for i, p in enumerate(o.prototypes)}
    sphere_row = int(np.flatnonzero(o.prototype == by_name["sphere"])[0])
    assert np.allclose(o.transforms[sphere_row, :3, 3], sk.organ_position[sphere_row])
    assert np.allclose(np.linalg.norm(o.transforms[sphere_row, :3, :3], axis=0), 0.2)  # L-Py's radius 0.1
    circle_row = int(np.flatnonzero(o.prototype == by_name["circle"])[0])
    assert o.material[circle_row] == 2 and o.fallbacks == ()
    path = export(tree, tmp_path / "plant.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc, _ = read_glb(path)
    assert {"organ_sphere", "organ_circle", "organ_k"} <= {n["name"] for n in doc["nodes"]}
    path = export(tree, tmp_path / "plant.usda")
    assert validators.usd_problems(path) == []
    rigged = lsys3d.generate(tmp_path / "plant.toml", rig=True)
    assert all("skin_weights" in m.attributes and "branch_id" not in m.attributes for m in rigged.organs.merged)


def test_the_cli_counts_organs(tmp_path, capsys):
    (tmp_path / "berry.lpy").write_text("Axiom: _(0.05) F(1) @O(0.1) F(1) @O(0.1)\nderivation length: 0\nendlsystem\n")
    assert main(["generate", str(tmp_path / "berry.lpy"), "-o", str(tmp_path / "berry.glb")]) == 0
    assert ", 0 leaves, 2 organs (" in capsys.readouterr().out
