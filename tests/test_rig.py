"""The rig: joints along the branches, skin weights, glTF skins and UsdSkel, and Blender posing a joint."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
import validators
from gltf_files import accessor, node, read_glb
from pxr import Usd, UsdSkel

import lsys3d
from lsys3d.exchange import ExportOptions, export
from lsys3d.look.rig import BLEND, INFLUENCES, RigOptions, build_rig, skin_weights
from lsys3d.turtle import interpret
from lsys3d.turtle.hierarchy import hierarchy

# a trunk of 4 segments with a branch from its second joint and a twig on that branch; leaves at every tip
SMALL = lsys3d.Grammar(axiom="!(0.2)F[+!(0.1)FF[-!(0.05)F~]F~]FFF~", angle=45, name="small")


def small_rig(**kw):
    sk = interpret(lsys3d.derive(SMALL, 0), SMALL)
    h = hierarchy(sk)
    return sk, h, build_rig(h, sk, RigOptions(enabled=True, **kw))


def test_joints_follow_the_branches():
    _, h, rig = small_rig(joints_per_branch=4)
    assert h.length.tolist() == [4.0, 3.0, 1.0]
    # the trunk gets 4 joints, the branch ceil(4 * 3 / 4) = 3, the twig ceil(4 * 1 / 4) = 1
    assert rig.count.tolist() == [4, 3, 1] and len(rig) == 1 + 8
    assert rig.names == ("root", "b0_j0", "b0_j1", "b0_j2", "b0_j3", "b1_j0", "b1_j1", "b1_j2", "b2_j0")
    assert (rig.parent[1:] < np.arange(1, len(rig))).all()  # parents first
    assert np.allclose(rig.position[1:5], [[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0]])
    # the branch grows from the top of the trunk's first segment: its first joint hangs from b0_j1
    assert rig.names[rig.parent[rig.first[1]]] == "b0_j1" and np.allclose(rig.position[rig.first[1]], [0, 1, 0])
    assert rig.names[rig.parent[rig.first[2]]] == "b1_j2"  # the twig from the branch's third segment's top
    assert rig.local[rig.first[1]].tolist() == [0.0, 0.0, 0.0]


def test_budget_and_depth():
    _, _, rig = small_rig(joints_per_branch=4, max_joints=7)
    assert len(rig) == 7 and rig.count.tolist() == [4, 2, 0]
    assert rig.names[rig.carrier[2]] == "b1_j1"  # the twig rides the branch's joint it grows from
    _, _, shallow = small_rig(max_depth=0)
    assert shallow.count[1:].tolist() == [0, 0] and shallow.names[shallow.carrier[2]] == "b0_j1"


def test_weights():
    _, h, rig = small_rig(joints_per_branch=4)
    t = np.linspace(0, 1, 201)
    for b in range(3):
        joints, weights = skin_weights(rig, h, np.full(len(t), b), t)
        assert joints.shape == (len(t), INFLUENCES) and np.allclose(weights.sum(axis=1), 1)
        assert (weights >= 0).all()
    # the trunk: wholly on b0_j1 in the middle of its bone, half and half at b0_j2, blended over the band
    joints, weights = skin_weights(rig, h, np.zeros(4, int), np.array([0.375, 0.5, 0.5 - BLEND / 8, 0.5 + BLEND / 8]))
    names = [[rig.names[j] for j in row[: int((w > 0).sum())]] for row, w in zip(joints, weights, strict=True)]
    assert names[0] == ["b0_j1"] and weights[0, 0] == 1
    assert names[1] == ["b0_j2", "b0_j1"] and np.allclose(weights[1, :2], 0.5)
    assert names[2] == ["b0_j1", "b0_j2"] and np.allclose(weights[2, :2], [0.75, 0.25])
    assert names[3] == ["b0_j2", "b0_j1"] and np.allclose(weights[3, :2], [0.75, 0.25])
    # a branch's base: half into its parent's joint, so the union's seam bends smoothly
    joints, weights = skin_weights(rig, h, np.array([1]), np.array([0.0]))
    assert [rig.names[j] for j in joints[0, :2]] == ["b1_j0", "b0_j1"] and np.allclose(weights[0, :2], 0.5)
    # rigid (leaves): one joint, weight 1
    joints, weights = skin_weights(rig, h, np.array([2, 1]), np.array([1.0, 0.99]), rigid=True)
    assert [rig.names[j] for j in joints[:, 0]] == ["b2_j0", "b1_j2"] and (weights[:, 0] == 1).all()


@pytest.fixture(scope="module")
def rigged():
    return lsys3d.generate("tree3d", iterations=4, rig=True)


def test_generate_binds_bark_and_leaves(rigged):
    tree = rigged
    assert tree.rig is not None and len(tree.rig) == 79 and tree.hierarchy is None  # attributes not asked for
    assert sorted(tree.bark.attributes) == ["skin_joints", "skin_weights"]
    assert sorted(tree.leaves.merged.attributes) == ["skin_joints", "skin_weights"]
    w = tree.bark.attributes["skin_weights"]
    assert np.allclose(w.sum(axis=1), 1, atol=1e-6) and tree.bark.attributes["skin_joints"].max() < len(tree.rig)
    plain = lsys3d.generate("tree3d", iterations=4)
    assert np.array_equal(plain.bark.vertices, tree.bark.vertices) and plain.rig is None


def test_gltf_skin(rigged, tmp_path):
    path = export(rigged, tmp_path / "rig.glb", ExportOptions(instance_leaves=True))
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, binary = read_glb(path)
    (skin,) = doc["skins"]
    assert len(skin["joints"]) == len(rigged.rig) and doc["nodes"][skin["skeleton"]]["name"] == "root"
    bark, leaf = node(doc, "bark"), node(doc, "leaf")
    assert bark["skin"] == 0 and leaf["skin"] == 0  # leaves are merged to be skinned
    assert "EXT_mesh_gpu_instancing" not in leaf.get("extensions", {})
    roots = doc["scenes"][0]["nodes"]
    assert doc["nodes"].index(bark) in roots and doc["nodes"].index(leaf) in roots  # skinned meshes are roots
    primitive = doc["meshes"][bark["mesh"]]["primitives"][0]["attributes"]
    weights = accessor(doc, binary, primitive["WEIGHTS_0"]).astype(int)
    assert (weights.sum(axis=1) == 255).all()
    inverse = accessor(doc, binary, skin["inverseBindMatrices"]).reshape(-1, 4, 4)
    assert np.allclose(inverse[:, 3, :3], -rigged.rig.position, atol=1e-5)  # column-major: translation last


def test_usd_skel(rigged, tmp_path):
    path = export(rigged, tmp_path / "rig.usdc", ExportOptions(up_axis="Z", units="cm"))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    assert root.IsA(UsdSkel.Root)
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/tree3d/Rig"))
    joints = list(skeleton.GetJointsAttr().Get())
    assert len(joints) == len(rigged.rig) and joints[0] == "root" and joints[1] == "root/b0_j0"
    bind = np.array(skeleton.GetBindTransformsAttr().Get())
    # Y up metres -> Z up centimetres: a joint at (x, y, z) m stands at (x, -z, y) * 100 cm
    expected = rigged.rig.position[:, [0, 2, 1]] * [100, -100, 100]
    assert np.allclose(bind[:, 3, :3], expected, atol=1e-3)
    binding = UsdSkel.BindingAPI(stage.GetPrimAtPath("/tree3d/Geom/bark"))
    assert binding.GetSkeletonRel().GetTargets()[0] == skeleton.GetPath()
    assert binding.GetJointIndicesPrimvar().GetElementSize() == INFLUENCES


def pose(path, bone: str, degrees: float) -> dict:
    python = validators.bpy_python()
    validators.require(python is not None and python.exists(), "Blender (bpy) is not installed")
    script = validators.REPO / "tools" / "blender_pose.py"
    proc = subprocess.run(
        [str(python), str(script), str(path), bone, str(degrees)], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith(validators.BLENDER_MARK)][-1]
    return json.loads(line[len(validators.BLENDER_MARK) :])


def subtree(rig, joint: int) -> set[int]:
    out = {joint}
    for j in range(joint + 1, len(rig)):  # parents come first
        if rig.parent[j] in out:
            out.add(j)
    return out


@pytest.mark.parametrize("suffix", [".glb", ".usda"])
def test_blender_poses_the_rig_and_the_leaves_follow(rigged, tmp_path, suffix):
    """Bend one joint in Blender: exactly the leaves bound below it move, and the bark around it bends."""
    rig = rigged.rig
    joint = rig.first[1]  # the first joint of the first branch off the trunk
    below = subtree(rig, int(joint))
    path = export(rigged, tmp_path / f"rig{suffix}")
    report = pose(path, rig.names[joint], 30)
    assert report["posed"] and report["armatures"][0]["bones"] == len(rig)
    # which leaf vertices should move: read from the file, in the vertex order Blender keeps
    if suffix == ".glb":
        doc, binary = read_glb(path)
        attrs = doc["meshes"][node(doc, "leaf")["mesh"]]["primitives"][0]["attributes"]
        leaf_joints = accessor(doc, binary, attrs["JOINTS_0"])[:, 0]
    else:
        stage = Usd.Stage.Open(str(path))  # held: its prims live as long as the stage
        prim = stage.GetPrimAtPath("/tree3d/Geom/leaf")
        leaf_joints = np.array(UsdSkel.BindingAPI(prim).GetJointIndicesPrimvar().Get()).reshape(-1, INFLUENCES)[:, 0]
    expected = np.isin(leaf_joints, list(below))
    moved = np.array(report["moved"]["leaf"]) > 1e-4
    assert expected.sum() > 20 and np.array_equal(moved, expected)
    bark_moved = np.array(report["moved"]["bark"]) > 1e-4
    assert 0 < bark_moved.sum() < len(bark_moved)


@pytest.mark.parametrize("name", ["dragon", "koch", "snowflake"])
def test_rigged_presets_are_validator_clean(name, tmp_path):
    """Weights that round to 0 in the bytes name joint 0 (the validator warned ACCESSOR_JOINTS_USED_ZERO_WEIGHT)."""
    tree = lsys3d.generate(name, rig=True, attributes="compact")
    report = validators.validate_gltf(export(tree, tmp_path / f"{name}.glb"))
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]["messages"][:3]
    doc, binary = read_glb(tmp_path / f"{name}.glb")
    attrs = doc["meshes"][node(doc, "bark")["mesh"]]["primitives"][0]["attributes"]
    joints, weights = accessor(doc, binary, attrs["JOINTS_0"]), accessor(doc, binary, attrs["WEIGHTS_0"])
    assert (joints[weights == 0] == 0).all() and (weights.astype(int).sum(axis=1) == 255).all()
    assert validators.usd_problems(export(tree, tmp_path / f"{name}.usda")) == []
