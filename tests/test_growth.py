"""Plants that grow in time: ages through derivation, times on the skeleton, the growth animation and _BIRTH."""

from __future__ import annotations

import functools
import http.server
import json
import shutil
import subprocess
import threading

import numpy as np
import pytest
import validators
from browser import CHROMIUM, CHROMIUM_ARGS, require_browser
from gltf_files import accessor, read_glb
from growing import joint_transforms, skinned
from grown import grown as grown_preset
from hypothesis import given, settings
from hypothesis import strategies as st
from pxr import Usd, UsdGeom, UsdSkel

import lsys3d
from lsys3d.errors import GrammarError, OptionsError
from lsys3d.exchange import export
from lsys3d.lsystem.ages import FUNCTIONS, derive_with_ages, growth_table, interpretation_ages
from lsys3d.lsystem.derive import derive, interpretation
from lsys3d.pipeline import GenerateOptions
from lsys3d.turtle import TurtleOptions, interpret
from lsys3d.turtle.timing import timed

FPS, SECONDS = 24, 5.0


# -- ages through derivation ---------------------------------------------------------------------------------
def test_a_module_created_at_step_k_has_age_n_minus_k():
    """Algae (A -> AB, B -> A), by hand: B is new at every step, A continues A, and B's A is new."""
    g = lsys3d.Grammar(axiom="A", rules=["A -> AB", "B -> A"])
    modules, ages = derive_with_ages(g, 4)
    assert str(modules) == "ABAABABA"
    assert ages.birth.tolist() == [0, 4, 4, 3, 4, 2, 4, 4]
    assert ages.time == 4 and ages.age.tolist() == [4, 0, 0, 1, 0, 2, 0, 0]


@pytest.mark.parametrize("n", [1, 3, 6])
def test_an_apex_lays_down_one_internode_a_step(n):
    """A -> F A: the F made at step k is the k-th from the base, age n - k; the apex stays 0."""
    g = lsys3d.Grammar(axiom="A", rules=["A -> F(1)A"])
    modules, ages = derive_with_ages(g, n)
    assert str(modules) == "F(1)" * n + "A"
    assert ages.age.tolist() == [n - k for k in range(1, n + 1)] + [n]


@pytest.mark.parametrize("name", ["tree3d", "abop-1.24a", "foxglove", "herb-growing", "context-1.31a"])
def test_the_same_string_as_derive(name):
    g = lsys3d.load_preset(name)
    modules, ages = derive_with_ages(g)
    assert modules == derive(g)
    assert len(ages.birth) == len(modules) and (ages.birth >= 0).all() and (ages.birth <= ages.time).all()
    shown, shown_ages = interpretation_ages(g, modules, ages)
    assert shown == interpretation(g, modules) and len(shown_ages.birth) == len(shown)


def naive_births(axiom: str, rules: dict[str, str], n: int) -> list[int]:
    """The textbook rewriter with a birth per character: a successor's characters are born at the step, but for
    the first one at bracket depth 0 with the predecessor's own symbol, which keeps the predecessor's birth."""
    s = [(c, 0) for c in axiom]
    for step in range(1, n + 1):
        out = []
        for c, born in s:
            if c not in rules:
                out.append((c, born))
                continue
            depth, kept = 0, False
            for d in rules[c]:
                if d == "[":
                    depth += 1
                elif d == "]":
                    depth -= 1
                keep = not kept and depth == 0 and d == c
                kept |= keep
                out.append((d, born if keep else step))
        s = out
    return [b for _, b in s]


@st.composite
def d0l_grammars(draw):
    axiom = draw(st.text("ABF+[", min_size=1, max_size=5)).replace("[", "[F]")
    preds = draw(st.lists(st.sampled_from("ABF"), unique=True, min_size=1, max_size=3))
    successors = [draw(st.lists(st.sampled_from(["A", "B", "F", "+", "[A]", "[FB]"]), max_size=4)) for _ in preds]
    return lsys3d.Grammar(axiom=axiom, rules=[f"{p} -> {''.join(s)}" for p, s in zip(preds, successors, strict=True)])


@settings(max_examples=60, deadline=None)
@given(d0l_grammars(), st.integers(0, 4))
def test_ages_match_a_textbook_rewriter(g, n):
    """Any D0L grammar: the births equal an independent rewriter's, and a module born at step k has age n - k."""
    rules = {p.predecessor.symbol: "".join(m.symbol for m in p.successor) for p in g.productions}
    modules, ages = derive_with_ages(g, n, max_modules=100_000)
    expected = naive_births(g.axiom, rules, n)
    assert modules == derive(g, n, max_modules=100_000) and ages.birth.tolist() == expected
    assert ages.time == n and ages.age.tolist() == [n - b for b in expected]


def test_timed_rules_fractional_ages_by_hand():
    """A's terminal age 0.5, B's 1.5 and initial age 0.25: the births follow the clocks, worked out by hand.

    A(0) -> A B at 0.5: B born 0.5 - 0.25 = 0.25.  Step 2: A (clock 0.5) rewritten at 1.0, new B born 0.75;
    B (born 0.25) rewritten at 1.75 into A, born 1.75.  String A B A: births 0, 0.75, 1.75; clocks 1.0, 0.75,
    1.75; the derivation ends at 2 (two steps of the table's terminal age, 1: later than the latest rewrite)."""
    text = (
        'axiom = "A"\nrules = ["A -> AB", "B -> A"]\n[growth]\n'
        "A = { terminal_age = 0.5 }\nB = { terminal_age = 1.5, initial_age = 0.25, duration = 2 }\n"
    )
    g = lsys3d.Grammar.from_text(text)
    modules, ages = derive_with_ages(g, 2)
    assert str(modules) == "ABA"
    assert ages.birth.tolist() == [0.0, 0.75, 1.75]
    assert ages.clock.tolist() == [1.0, 0.75, 1.75]
    assert ages.time == 2.0 and ages.age.tolist() == [2.0, 1.25, 0.25]
    # full grown: A a terminal age (0.5) after its clock, B its duration (2)
    assert ages.mature(modules, growth_table(g)).tolist() == [1.5, 2.75, 2.25]


def test_homomorphism_and_decomposition_keep_the_birth():
    g = lsys3d.Grammar(axiom="A", rules=["A -> [B]A"], decomposition=["B -> CC"], homomorphism=["C -> F"])
    modules, ages = derive_with_ages(g, 2)
    assert str(modules) == "[CC][CC]A"
    assert ages.birth.tolist() == [1, 1, 1, 1, 2, 2, 2, 2, 0]  # the first [CC] is the oldest
    shown, shown_ages = interpretation_ages(g, modules, ages)
    assert str(shown) == "[FF][FF]A" and shown_ages.birth.tolist() == ages.birth.tolist()


def test_the_cut_keeps_the_ages_of_what_stays():
    g = lsys3d.Grammar(axiom="A", rules=["A -> F[%F]FB", "B -> A"])
    modules, ages = derive_with_ages(g, 2)
    assert modules == derive(g, 2)
    assert len(ages.birth) == len(modules)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ("function = 'cubic'", r"unknown growth function 'cubic'"),
        ("terminal_age = 0", r"terminal_age: must be a number >= 1e-06"),
        ("F = { age = 1 }", r"F: unknown key 'age'"),
        ("F = 2", r"'F': a symbol's entry is a table"),
        ("F = { function = 'slow' }", r"F.function: unknown growth function"),
    ],
)
def test_growth_table_errors_point_at_the_key(table, match):
    g = lsys3d.Grammar.from_text(f'axiom = "F"\n[growth]\n{table}\n', source="g.toml")
    with pytest.raises(GrammarError, match=r"^g.toml:3:1: \[growth\] .*" + match):
        growth_table(g)


# -- times on the skeleton -------------------------------------------------------------------------------------
def test_segments_leaves_and_organs_carry_their_times():
    g = lsys3d.Grammar(axiom="A", rules=["A -> F[+F~]A"], iterations=3, growth={"leaf_delay": 0.25})
    modules, ages = derive_with_ages(g)
    table = growth_table(g)
    sk = timed(interpret(modules, TurtleOptions(leaf="~")), modules, ages, table)
    assert sk.birth.tolist() == [1, 1, 2, 2, 3, 3]
    assert sk.mature.tolist() == [2, 2, 3, 3, 4, 4]  # never rewritten: full grown one step after their birth
    assert sk.leaf_birth.tolist() == [1.25, 2.25, 3.25] and sk.leaf_mature.tolist() == [2.25, 3.25, 4.25]
    assert sk.growth_function.tolist() == [list(FUNCTIONS).index("smooth")] * 6


def test_off_by_default():
    tree = lsys3d.generate("abop-1.24a", iterations=2)
    assert tree.growth is None and tree.skeleton.birth is None
    assert "growth" not in GenerateOptions().plain()  # older provenance records are unchanged
    with pytest.raises(OptionsError, match=r"GrowthOptions.seconds: must be in \[0, 600\]"):
        GenerateOptions.from_flat(growth_animation=-1)


# -- the animation ----------------------------------------------------------------------------------------------
@functools.cache
def grown(name: str, **options):
    return lsys3d.generate(name, growth_animation=SECONDS, growth_fps=FPS, **options)


def frames(tree):
    return tree.growth.scales()


@pytest.mark.parametrize("name", ["herb-growing", "tree3d"])
def test_end_frame_is_the_static_tree(name):
    tree = grown(name)
    static = grown_preset(name)  # generate(name), grown once in the run (tests/grown.py)
    assert np.array_equal(tree.bark.vertices, static.bark.vertices)  # the growth changes no geometry
    last = frames(tree)[-1]
    assert (last == 1.0).all()
    size = np.linalg.norm(np.ptp(static.bark.vertices, axis=0))
    for mesh in (tree.bark, tree.leaves.merged):
        assert np.abs(skinned(mesh, tree.rig, last) - mesh.vertices).max() <= 1e-5 * size


@pytest.mark.parametrize("name", ["herb-growing", "tree3d"])
def test_growth_is_monotone_and_smooth(name):
    tree = grown(name)
    scales = frames(tree)
    assert len(scales) == SECONDS * FPS + 1
    step = np.diff(scales, axis=0)
    assert (step >= -1e-12).all()  # every joint only grows
    assert np.abs(step).max() <= 0.2  # no jump over 20% of a joint's full scale between frames
    world = np.array([joint_transforms(tree.rig, s)[1] for s in scales])
    assert (np.diff(world, axis=0) >= -1e-12).all()
    heights = [np.ptp(skinned(tree.bark, tree.rig, s)[:, 1]) for s in scales[::6]]
    assert (np.diff(heights) >= -1e-9).all()


@pytest.mark.parametrize("name", ["herb-growing", "tree3d"])
def test_bark_at_a_tenth_of_the_clip_and_inside_the_final_box(name):
    tree = grown(name)
    scales = frames(tree)
    final = tree.bark.vertices
    height = np.ptp(final[:, 1])
    tenth = skinned(tree.bark, tree.rig, scales[round(0.1 * SECONDS * FPS)])
    assert np.ptp(tenth[:, 1]) <= 0.15 * height
    points = np.concatenate([final, tree.leaves.merged.vertices])
    low, high = points.min(axis=0), points.max(axis=0)
    reach = 0.05 * np.linalg.norm(high - low)
    for s in scales[::4]:
        for mesh in (tree.bark, tree.leaves.merged):
            p = skinned(mesh, tree.rig, s)
            assert (p >= low - reach).all() and (p <= high + reach).all()


def test_leaves_unfold_after_their_twig():
    tree = grown("herb-growing")
    g = tree.growth
    leaf_joints = [j for j, n in enumerate(tree.rig.names) if n.endswith("_leaves")]
    assert leaf_joints
    for j in leaf_joints:
        up = tree.rig.parent[j]
        assert g.keyed[j] and g.begin[j] >= g.begin[up] and g.end[j] > g.begin[j]


def test_wind_and_growth_together():
    tree = grown("herb-growing", wind_animation=2.0)
    assert tree.animation is not None and tree.growth is not None
    assert tree.animation.rotations.shape[1] == len(tree.rig)


def test_birth_attribute():
    tree = lsys3d.generate("herb-growing", birth_attribute=True)
    assert tree.rig is None and tree.growth is None
    bark, leaves = tree.bark.attributes["birth"], tree.leaves.merged.attributes["birth"]
    assert bark.min() >= 0 and bark.max() < 1 and leaves.min() > bark.min()
    assert set(tree.bark.attributes) == {"birth"}  # the branch id and t it was found by are not kept


# -- the files ------------------------------------------------------------------------------------------------------
def test_gltf_growth_animation_and_birth(tmp_path):
    tree = grown("herb-growing", wind_animation=2.0, birth_attribute=True)
    path = export(tree, tmp_path / "herb.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
    doc, binary = read_glb(path)
    animations = {a["name"]: a for a in doc["animations"]}
    assert set(animations) == {"growth", "wind"}
    growth = animations["growth"]
    assert {c["target"]["path"] for c in growth["channels"]} == {"scale"}
    assert len(growth["channels"]) == int(tree.growth.keyed.sum())
    sampler = growth["samplers"][0]
    assert sampler["interpolation"] == "CUBICSPLINE"  # smooth: 3x^2 - 2x^3 is a Hermite spline, flat tangents
    keys = accessor(doc, binary, sampler["input"])
    j = doc["skins"][0]["joints"].index(growth["channels"][0]["target"]["node"])
    assert np.allclose(keys, [tree.growth.begin[j], tree.growth.end[j]])
    values = accessor(doc, binary, sampler["output"])
    assert values.tolist() == [[0, 0, 0]] * 4 + [[1, 1, 1], [0, 0, 0]]
    bark = next(m for m in doc["meshes"] if m["name"] == "bark")
    birth = accessor(doc, binary, bark["primitives"][0]["attributes"]["_BIRTH"])
    assert birth.ndim == 1 and birth.min() >= 0 and birth.max() < 1


def test_gltf_logistic_is_sampled(tmp_path):
    g = lsys3d.load_preset("herb-growing")
    g = g.replace(growth={**g.growth, "function": "logistic"})
    tree = lsys3d.generate(g, growth_animation=2.0)
    path = export(tree, tmp_path / "logistic.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
    doc, binary = read_glb(path)
    (growth,) = doc["animations"]
    sampler = growth["samplers"][0]
    assert sampler["interpolation"] == "LINEAR"
    keys = accessor(doc, binary, sampler["input"])
    j = doc["skins"][0]["joints"].index(growth["channels"][0]["target"]["node"])
    values = accessor(doc, binary, sampler["output"])[:, 0]
    assert np.allclose(values, tree.growth.scales(keys)[:, j], atol=1e-6)


def test_usd_growth_and_birth(tmp_path):
    tree = grown("herb-growing", wind_animation=2.0, birth_attribute=True)
    path = export(tree, tmp_path / "herb.usda")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    skeleton = UsdSkel.Skeleton(stage.GetPrimAtPath("/herb_growing/Rig"))
    (source,) = UsdSkel.BindingAPI(skeleton.GetPrim()).GetAnimationSourceRel().GetTargets()
    animation = UsdSkel.Animation(stage.GetPrimAtPath(source))
    scales = animation.GetScalesAttr()
    assert scales.GetTimeSamples() == [float(k) for k in range(int(SECONDS * FPS) + 1)]
    assert np.allclose(np.array(scales.Get(0))[:, 0], frames(tree)[0], atol=1e-3)
    assert (np.array(scales.Get(SECONDS * FPS)) == 1).all()
    # the wind (2 s) loops over the growth (5 s): one track set
    assert animation.GetRotationsAttr().GetTimeSamples()[-1] == SECONDS * FPS
    assert stage.GetEndTimeCode() == SECONDS * FPS
    birth = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/herb_growing/Geom/bark")).GetPrimvar("birth")
    assert birth.GetInterpolation() == UsdGeom.Tokens.vertex and len(birth.Get()) == len(tree.bark.vertices)


def test_cli(tmp_path):
    from lsys3d.cli import main

    out = tmp_path / "herb.glb"
    assert main(["generate", "herb-growing", "--growth-animation", "2", "--birth-attribute", "-o", str(out)]) == 0
    doc, _ = read_glb(out)
    assert [a["name"] for a in doc["animations"]] == ["growth"]


# -- players ----------------------------------------------------------------------------------------------------
def blender_frames(paths, frames_wanted) -> list[dict]:
    """``tools/blender_growth.py``'s report of each file at the frames wanted: one Blender plays them in turn."""
    return validators.blender_reports(validators.REPO / "tools" / "blender_growth.py", paths, frames_wanted)


def height(box) -> float:
    return box[1][2] - box[0][2]  # Blender: Z up


BLENDER_SUFFIXES = [".glb", ".usda"]


@pytest.fixture(scope="module")
def blender_played(tmp_path_factory) -> dict:
    """herb-growing's growth in each format, played by one Blender at frame 0, a tenth, half and the end."""
    tree = grown("herb-growing")  # (the wind never passes through the rest pose: its lean is never 0)
    folder = tmp_path_factory.mktemp("blender_growth")
    paths = [export(tree, folder / f"herb{suffix}") for suffix in BLENDER_SUFFIXES]
    end = round(SECONDS * FPS)
    return dict(zip(BLENDER_SUFFIXES, blender_frames(paths, [0, round(0.1 * end), end // 2, end]), strict=True))


@pytest.mark.parametrize("suffix", BLENDER_SUFFIXES)
def test_blender_plays_the_growth(blender_played, suffix):
    """Blender imports the growth, and its own armature deformation grows the bark from (almost) nothing to the
    static tree: a tenth into the clip the bark is at most 15% of its height, the last frame is the rest form."""
    report = blender_played[suffix]
    rest = report["rest"]
    size = np.linalg.norm(np.subtract(*rest["bark"]))
    first, tenth, half, last = report["frames"]
    assert height(first["meshes"]["bark"]["bbox"]) <= 0.01 * height(rest["bark"])
    assert height(tenth["meshes"]["bark"]["bbox"]) <= 0.15 * height(rest["bark"])
    assert height(tenth["meshes"]["bark"]["bbox"]) < height(half["meshes"]["bark"]["bbox"])
    for name in ("bark", "leaf"):
        assert last["meshes"][name]["from_rest"] <= 1e-5 * size
    low = np.minimum(*(np.array(rest[n][0]) for n in ("bark", "leaf")))
    high = np.maximum(*(np.array(rest[n][1]) for n in ("bark", "leaf")))
    reach = 0.05 * np.linalg.norm(high - low)
    for frame in report["frames"]:  # no vertex outside the grown plant's box by more than 5% of its size
        for mesh in frame["meshes"].values():
            assert (np.array(mesh["bbox"][0]) >= low - reach).all() and (
                np.array(mesh["bbox"][1]) <= high + reach
            ).all()


SCRIPT = validators.REPO / "tools" / "three_growth.mjs"


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


THREE_PLANTS = ["herb-growing", "tree3d"]


@pytest.fixture(scope="module")
def three_played(tmp_path_factory) -> dict:
    """Each plant's .glb played by three.js, a page each in one headless Chromium: its result, or the failure."""
    require_browser()
    folder = tmp_path_factory.mktemp("three_growth")
    for name in THREE_PLANTS:
        export(grown(name), folder / f"{name}.glb")
    shutil.copy(validators.REPO / "tools" / "three_growth.html", folder / "index.html")
    (folder / "three").symlink_to(validators.REPO / "node_modules" / "three")
    handler = functools.partial(_Quiet, directory=str(folder))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        times = ",".join(map(str, [0.0, 0.1 * SECONDS, 0.5 * SECONDS, SECONDS]))
        base = f"http://127.0.0.1:{server.server_address[1]}/index.html"
        urls = [f"{base}?glb={name}.glb&times={times}" for name in THREE_PLANTS]
        proc = subprocess.run(
            ["node", str(SCRIPT), json.dumps(urls), str(CHROMIUM), json.dumps(CHROMIUM_ARGS)],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=validators.REPO,
        )
    finally:
        server.shutdown()
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()[-len(THREE_PLANTS) :]
    return dict(zip(THREE_PLANTS, map(json.loads, lines), strict=True))


@pytest.mark.parametrize("name", THREE_PLANTS)
def test_three_js_plays_the_growth(three_played, name):
    """three.js (GLTFLoader, AnimationMixer, SkinnedMesh.getVertexPosition) in headless Chromium grows the plant."""
    tree = grown(name)
    result = three_played[name]
    assert "failure" not in result and result["errors"] == [], result
    assert result["clip"] == "growth" and result["duration"] == pytest.approx(SECONDS)
    first, tenth, half, last = result["frames"]
    final = tree.bark.vertices
    size = np.linalg.norm(np.ptp(final, axis=0))
    full = np.ptp(final[:, 1])

    def tall(frame, name="bark"):
        m = frame["meshes"][name]
        return m["max"][1] - m["min"][1]

    assert tall(first) <= 0.01 * full and tall(tenth) <= 0.15 * full and tall(tenth) < tall(half)
    assert "bark" in last["meshes"] and any(n.startswith("leaf") for n in last["meshes"])  # leaf_1, leaf_2...
    for mesh in last["meshes"].values():
        assert mesh["fromRest"] <= 1e-5 * size
    assert np.allclose(last["meshes"]["bark"]["min"], final.min(axis=0), atol=1e-5 * size)
    low = np.minimum.reduce([m["min"] for m in last["meshes"].values()])
    high = np.maximum.reduce([m["max"] for m in last["meshes"].values()])
    reach = 0.05 * np.linalg.norm(high - low)
    for frame in result["frames"]:  # no vertex outside the grown plant's box by more than 5% of its size
        for mesh in frame["meshes"].values():
            assert (np.array(mesh["min"]) >= low - reach).all() and (np.array(mesh["max"]) <= high + reach).all()


def test_levels_of_detail_share_the_growing_rig(tmp_path):
    tree = lsys3d.generate("tree3d", iterations=4, growth_animation=2.0, lod=(0, 1))
    assert len(tree.lods) == 2
    joints = len(tree.rig)
    for lod in tree.lods:
        for mesh in (lod.bark, lod.leaves.merged):
            assert mesh.attributes["skin_joints"].max() < joints
    path = export(tree, tmp_path / "lod.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []


def test_a_long_segment_grows_from_its_base():
    """One segment over four joints grows as one: from the joint its base is on, the joints above it stay at 1."""
    g = lsys3d.Grammar(axiom="!(0.2)A", rules=["A -> F(4)"], iterations=1, name="stem")
    tree = lsys3d.generate(g, growth_animation=2.0, rig_joints_per_branch=4)
    trunk = [j for j, n in enumerate(tree.rig.names) if n.startswith("b0_")]
    assert len(trunk) == 4 and tree.growth.keyed[trunk].tolist() == [True, False, False, False]
    scales = frames(tree)
    tenth = skinned(tree.bark, tree.rig, scales[round(0.1 * len(scales))])
    assert np.ptp(tenth[:, 1]) <= 0.15 * np.ptp(tree.bark.vertices[:, 1])
