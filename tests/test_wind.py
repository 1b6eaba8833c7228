"""The sample wind animation: keys on the rig's joints, a glTF animation, a UsdSkel.Animation, Blender plays it."""

from __future__ import annotations

import numpy as np
import pytest
import validators
from gltf_files import accessor, read_glb
from pxr import Usd, UsdSkel

import lsys3d
from lsys3d.errors import OptionsError
from lsys3d.exchange import ExportOptions, export
from lsys3d.look.rig import RigOptions, build_rig
from lsys3d.look.wind import WIND, WindOptions, sway
from lsys3d.turtle import interpret
from lsys3d.turtle.hierarchy import hierarchy

# a trunk of 4 segments with a branch from its second joint and a twig on that branch; leaves at every tip
SMALL = lsys3d.Grammar(axiom="!(0.2)F[+!(0.1)FF[-!(0.05)F~]F~]FFF~", angle=45, name="small")


def small(**wind):
    sk = interpret(lsys3d.derive(SMALL, 0), SMALL)
    h = hierarchy(sk)
    rig = build_rig(h, sk, RigOptions(enabled=True))
    return h, rig, sway(rig, h, WindOptions(**{"seconds": 2.0, "fps": 10, **wind}))


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    xyz, w = q[..., :3], q[..., 3:]
    t = 2 * np.cross(xyz, v)
    return v + w * t + np.cross(xyz, t)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    av, aw, bv, bw = a[..., :3], a[..., 3:], b[..., :3], b[..., 3:]
    return np.concatenate([aw * bv + bw * av + np.cross(av, bv), aw * bw - (av * bv).sum(-1, keepdims=True)], -1)


def posed(rig, rotations: np.ndarray) -> np.ndarray:
    """World positions of the joints for one frame's local rotations (forward kinematics, parents first)."""
    position = np.zeros((len(rig), 3))
    orientation = np.tile([0.0, 0.0, 0.0, 1.0], (len(rig), 1))
    local = rig.local
    for j in range(len(rig)):
        up = int(rig.parent[j])
        if up < 0:
            position[j], orientation[j] = local[j], rotations[j]
        else:
            position[j] = position[up] + quat_rotate(orientation[up], local[j])
            orientation[j] = quat_mul(orientation[up], rotations[j])
    return position


def test_keys_loop_and_stay_unit():
    _, rig, anim = small()
    assert len(anim) == 21 and np.allclose(anim.times, np.arange(21) / 10)
    assert anim.rotations.shape == (21, len(rig), 4)
    assert np.allclose(np.linalg.norm(anim.rotations, axis=2), 1, atol=1e-6)
    assert (anim.rotations[:, 0] == [0, 0, 0, 1]).all()  # the root stays
    assert np.allclose(anim.rotations[0], anim.rotations[-1], atol=1e-6)  # whole cycles: it loops
    assert not np.allclose(anim.rotations[0], anim.rotations[5])


def test_branches_lean_into_the_wind_by_depth():
    h, rig, anim = small(strength=10.0)
    rest = posed(rig, anim.rotations[0] * 0 + [0, 0, 0, 1])
    assert np.allclose(rest, rig.position)
    angles = 2 * np.arccos(np.clip(anim.rotations[..., 3], -1, 1))  # each joint's turn at each key
    # a joint never turns more than its share of the strength; the share grows with depth
    share = np.minimum((1 - 0.75 ** (h.depth + 1)) / 0.68, 1.0)
    moving = np.flatnonzero(rig.branch >= 0)
    limit = np.radians(10.0) * share[rig.branch[moving]] / rig.count[rig.branch[moving]]
    assert (angles[:, moving] <= limit + 1e-6).all()
    assert np.allclose(angles[:, moving].max(axis=0), limit, rtol=0.05)  # it reaches it (21 keys over 2 s)
    # every joint moves with the wind (+X), never against it; the twig's tip the most
    downwind = np.array([(posed(rig, anim.rotations[k]) - rig.position) @ WIND for k in range(len(anim))])
    assert (downwind >= -1e-9).all() and downwind.max() > 0
    reach = downwind.max(axis=0)
    assert reach[rig.first[2]] == reach.max() > reach[rig.first[0] + 3]  # the twig's base, not the trunk's top


def test_seeded_and_deterministic():
    a = lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=1, seed=3).animation
    b = lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=1, seed=3).animation
    c = lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=1, seed=4).animation
    assert np.array_equal(a.rotations, b.rotations) and not np.array_equal(a.rotations, c.rotations)


def test_needs_the_rig():
    with pytest.raises(OptionsError, match="needs the rig"):
        lsys3d.generate("abop-1.24a", iterations=2, wind_animation=2)
    with pytest.raises(OptionsError, match=r"WindOptions\.seconds"):
        lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=-1)
    assert lsys3d.generate("abop-1.24a", iterations=2, rig=True).animation is None


@pytest.fixture(scope="module")
def windy():
    return lsys3d.generate("tree3d", iterations=3, rig=True, wind_animation=2, wind_fps=12)


def test_gltf_animation(windy, tmp_path):
    path = export(windy, tmp_path / "windy.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
    doc, binary = read_glb(path)
    (animation,) = doc["animations"]
    joints = doc["skins"][0]["joints"]
    assert len(animation["channels"]) == len(windy.rig) - 1  # every joint but the root
    targets = [c["target"] for c in animation["channels"]]
    assert [t["node"] for t in targets] == joints[1:] and {t["path"] for t in targets} == {"rotation"}
    sampler = animation["samplers"][0]
    assert sampler["interpolation"] == "LINEAR"
    assert np.allclose(accessor(doc, binary, sampler["input"]), windy.animation.times)
    j = 5
    keys = accessor(doc, binary, animation["samplers"][j - 1]["output"])
    assert np.allclose(keys, windy.animation.rotations[:, j])


def test_usd_skel_animation(windy, tmp_path):
    path = export(windy, tmp_path / "windy.usda", ExportOptions(up_axis="Z", units="cm"))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/tree3d/Rig"))
    (source,) = UsdSkel.BindingAPI(skeleton.GetPrim()).GetAnimationSourceRel().GetTargets()
    animation = UsdSkel.Animation(stage.GetPrimAtPath(source))
    assert list(animation.GetJointsAttr().Get()) == list(skeleton.GetJointsAttr().Get())
    rotations = animation.GetRotationsAttr()
    assert rotations.GetTimeSamples() == [float(k) for k in range(len(windy.animation))]
    assert stage.GetTimeCodesPerSecond() == 12 and stage.GetEndTimeCode() == len(windy.animation) - 1
    # Y up metres -> Z up: the rotation axes turn with the frame, (x, y, z) -> (x, -z, y)
    q = np.array([[*r.GetImaginary(), r.GetReal()] for r in rotations.Get(7)])
    expected = windy.animation.rotations[7].astype(np.float64)
    expected = np.column_stack([expected[:, 0], -expected[:, 2], expected[:, 1], expected[:, 3]])
    assert np.allclose(q, expected, atol=1e-6)


@pytest.mark.parametrize("suffix", [".glb", ".usda"])
def test_blender_plays_the_wind(windy, tmp_path, suffix):
    """Blender imports an action with keyframes on the armature, and the skinned bark and leaves move with it."""
    report = validators.blender_import(export(windy, tmp_path / f"windy{suffix}"))
    (action,) = report["actions"]
    start, end = action["frame_range"]
    if suffix == ".glb":  # glTF keys are seconds: Blender places them at its scene's frame rate
        assert start == 0 and end / action["fps"] == pytest.approx(windy.animation.times[-1])
    else:  # USD keys are time codes (frames), kept as frames (Blender keeps its own frame rate)
        assert [start, end] == [0, len(windy.animation) - 1]
    assert action["keyframes"] >= len(windy.animation) * (len(windy.rig) - 1) * 4  # a quaternion per joint per key
    assert any(o["type"] == "ARMATURE" and o["name"] in action["users"] for o in report["objects"])
    moved = report["animated"]
    assert moved["bark"] > 0.01 and moved["leaf"] > 0.01
