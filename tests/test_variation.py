"""Natural variation and procedural bark: turtle jitters, branch roll and drop, siblings, bark shape and colour."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
import validators
from gltf_files import read_glb
from pxr import Usd, UsdGeom

import lsys3d
from lsys3d import Grammar, GrammarError, derive, load_preset
from lsys3d.cli import main
from lsys3d.errors import ExportError
from lsys3d.exchange import ExportOptions, export, export_variants, variant_paths
from lsys3d.look.bark import bark_colors
from lsys3d.mesh.sweep import SweepOptions, sweep
from lsys3d.mesh.union.union import union
from lsys3d.pipeline import GenerateOptions
from lsys3d.stats import components
from lsys3d.tree import BARK
from lsys3d.turtle import TurtleOptions, interpret
from lsys3d.turtle.interpret import unit_jitter

VARIATION_OFF = dict(
    angle_jitter=0.0,
    length_jitter=0.0,
    width_jitter=0.0,
    branch_roll=0.0,
    branch_drop=0.0,
    jitter_distribution="uniform",
)


def draw(axiom: str, angle: float = 30.0, seed: int = 0, **turtle):
    g = Grammar(axiom=axiom, angle=angle, seed=seed)
    return interpret(derive(g, 0), TurtleOptions.from_grammar(g, **turtle))


def grow(name: str, n: int, seed: int = 0, **turtle):
    g = load_preset(name, iterations=n)
    return interpret(derive(g, seed=seed), TurtleOptions.from_grammar(g, **turtle), seed=seed)


def same_skeleton(a, b) -> bool:
    names = ("start", "end", "width_start", "width_end", "heading", "left", "up", "parent", "order", "leaf_position")
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in names)


# ------------------------------------------------------------------ turtle variation


def test_all_off_changes_nothing():
    for name, n in (("tree3d", 4), ("abop-1.24f", 3), ("bush", 3)):
        assert same_skeleton(grow(name, n), grow(name, n, **VARIATION_OFF))


def test_each_kind_has_its_own_stream():
    """Turning one kind on leaves the random numbers of the others as they were."""
    base = grow("abop-1.24f", 3, angle_jitter=5.0)
    with_width = grow("abop-1.24f", 3, angle_jitter=5.0, width_jitter=0.3)
    assert np.array_equal(base.end, with_width.end) and np.array_equal(base.heading, with_width.heading)
    assert not np.array_equal(base.width_start, with_width.width_start)
    with_length = grow("abop-1.24f", 3, length_jitter=0.2)
    both = grow("abop-1.24f", 3, length_jitter=0.2, angle_jitter=5.0)
    np.testing.assert_allclose(with_length.lengths(), both.lengths(), rtol=1e-12)


@pytest.mark.parametrize("distribution", ["uniform", "normal"])
def test_width_jitter_never_negative(distribution):
    sk = draw("!(0.2)" + "F" * 400, width_jitter=2.5, seed=3, jitter_distribution=distribution)
    assert (sk.width_start >= 0).all() and (sk.width_end >= 0).all()
    assert (sk.width_start == 0).any() and (sk.width_start > 0.2).any()
    assert sk.width_start.max() <= 0.2 * 3.5 + 1e-12


@pytest.mark.parametrize("distribution", ["uniform", "normal"])
def test_width_jitter_bounds_and_continuity(distribution):
    sk = draw("!(0.2)" + "F" * 300, width_jitter=0.25, seed=1, jitter_distribution=distribution)
    w = sk.width_start
    assert w.min() >= 0.2 * 0.75 - 1e-12 and w.max() <= 0.2 * 1.25 + 1e-12 and w.std() > 0.005
    # the taper stays continuous along the chain: each segment ends at the next one's start width
    np.testing.assert_array_equal(sk.width_end[:-1], sk.width_start[1:])


def test_normal_distribution_is_truncated_and_narrower():
    rng = np.random.default_rng(0)
    uniform = unit_jitter(rng, 100_000, "uniform")
    normal = unit_jitter(np.random.default_rng(0), 100_000, "normal")
    assert np.abs(normal).max() <= 1.0 and np.abs(uniform).max() <= 1.0
    # sigma 1/2 truncated at 2 sigma: std 0.44; uniform on [-1, 1]: 0.577
    assert 0.42 < normal.std() < 0.46 and 0.56 < uniform.std() < 0.59
    assert abs(normal.mean()) < 0.01
    # normal puts more weight near zero
    assert (np.abs(normal) < 0.25).mean() > 1.5 * (np.abs(uniform) < 0.25).mean()


def test_angle_jitter_normal_within_bounds():
    plain = draw("F" + "+F" * 300, angle=10)
    jittered = draw("F" + "+F" * 300, angle=10, angle_jitter=4.0, jitter_distribution="normal", seed=2)
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", jittered.heading[:-1], jittered.heading[1:]), -1.0, 1.0)))
    assert turn.min() >= 6.0 - 1e-6 and turn.max() <= 14.0 + 1e-6 and turn.std() > 0.5
    assert np.allclose(
        np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", plain.heading[:-1], plain.heading[1:]), -1, 1))), 10.0
    )


def test_branch_roll_turns_branches_about_their_heading():
    axiom = "F" + "[+F]F" * 40
    plain = draw(axiom)
    rolled = draw(axiom, branch_roll=180.0, seed=5)
    trunk = plain.order == 0
    assert np.array_equal(plain.end[trunk], rolled.end[trunk])  # the saved state is not rolled
    branch = plain.order == 1
    # a roll about H keeps the branch's angle to the trunk (30 degrees) but swings it around the trunk
    cos = np.einsum("ij,j->i", rolled.heading[branch], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(cos, np.cos(np.radians(30.0)), atol=1e-12)
    assert np.ptp(rolled.end[branch][:, 2]) > 0.5 and np.ptp(plain.end[branch][:, 2]) == 0.0


def test_branch_drop_one_removes_every_lateral():
    for name, n in (("tree3d", 5), ("abop-1.24d", 4), ("bush", 3)):
        g = load_preset(name, iterations=n)
        modules = derive(g)
        full = interpret(modules, g)
        trunk_only = interpret(modules, TurtleOptions.from_grammar(g, branch_drop=1.0))
        assert (trunk_only.order == 0).all() and len(trunk_only) < len(full)
        # the segments drawn outside any bracket, counted on the string itself
        text = str(modules)
        depth, outside = 0, 0
        draw_symbols = TurtleOptions.from_grammar(g).draw
        for ch in text:
            depth += (ch == "[") - (ch == "]")
            outside += depth == 0 and ch in draw_symbols
        assert len(trunk_only) == outside


def test_branch_drop_zero_changes_nothing_and_half_drops_some():
    g = load_preset("abop-1.24e", iterations=4)
    modules = derive(g)
    full = interpret(modules, g)
    assert same_skeleton(full, interpret(modules, TurtleOptions.from_grammar(g, branch_drop=0.0)))
    half = interpret(modules, TurtleOptions.from_grammar(g, branch_drop=0.5), seed=3)
    assert (full.order == 0).sum() == (half.order == 0).sum() < len(half) < len(full)
    assert same_skeleton(half, interpret(modules, TurtleOptions.from_grammar(g, branch_drop=0.5), seed=3))
    assert len(interpret(modules, TurtleOptions.from_grammar(g, branch_drop=0.5), seed=4)) != len(half)


def test_branch_drop_takes_leaves_and_polygons_along():
    sk = draw("F[+F~{.f.f.}]F~", branch_drop=1.0)
    assert len(sk) == 2 and sk.n_leaves == 1 and sk.n_polygons == 0


def test_variation_from_the_grammar_table():
    text = """
axiom = "F[+F][-F]F"
angle = 30
seed = 4
[turtle]
width_jitter = 0.2
branch_roll = 45
branch_drop = 0.25
jitter_distribution = "normal"
"""
    g = Grammar.from_text(text)
    opts = TurtleOptions.from_grammar(g)
    assert (opts.width_jitter, opts.branch_roll, opts.branch_drop, opts.jitter_distribution) == (
        0.2,
        45.0,
        0.25,
        "normal",
    )
    assert same_skeleton(interpret(derive(g, 0), g), interpret(derive(g, 0), opts))


@pytest.mark.parametrize(
    ("line", "fragment"),
    [
        ("branch_drop = 1.5", r"branch_drop: must be in \[0, 1\], not 1.5"),
        ("branch_drop = -0.1", r"branch_drop: must be in \[0, 1\], not -0.1"),
        ("width_jitter = -1", "width_jitter: must be >= 0, not -1"),
        ("branch_roll = -5", "branch_roll: must be >= 0, not -5"),
        ('jitter_distribution = "gauss"', "jitter_distribution: must be one of 'uniform', 'normal', not 'gauss'"),
    ],
)
def test_bad_variation_settings(line, fragment):
    g = Grammar.from_text(f'axiom = "F"\n[turtle]\n{line}\n', source="plant.toml")
    with pytest.raises(GrammarError, match=fragment) as info:
        TurtleOptions.from_grammar(g)
    assert str(info.value).startswith("plant.toml:3:")


# ------------------------------------------------------------------ bark displacement


def straight_tube(displacement: float, seed: int = 0):
    from skeletons import make_skeleton

    sk = make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0]], 0.2, [0.2, 0.02])
    # the same rings with and without displacement (displacement alone would add rings of its own)
    options = SweepOptions(sides=12, ring_spacing=1.0, bark_displacement=displacement, bark_frequency=6.0)
    return sk, sweep(sk, options, seed=seed)


def test_displaced_bark_shows_relief_along_a_straight_trunk():
    """A straight span has rings only at its ends; displaced, it gets rings a tube side apart (or half a bump)."""
    from skeletons import make_skeleton

    sk = make_skeleton([[0, 0, 0]], [[0, 3.7, 0]], 0.3)
    plain = sweep(sk, SweepOptions(sides=8))
    bumpy = sweep(sk, SweepOptions(sides=8, bark_displacement=0.3), seed=1)
    assert plain.rings.tolist() == [2]
    side = 0.3 * np.sin(np.pi / 8)  # 2 r sin(pi / S)
    assert bumpy.rings.tolist() == [int(np.ceil(3.7 / max(side, 0.5 / 8.0))) + 1]
    # the radius varies along the trunk, not only around it
    ring = bumpy.points[: bumpy.rings[0] * 8].reshape(-1, 8, 3)
    radius = np.linalg.norm(ring[:, :, [0, 2]], axis=2)
    assert np.ptp(radius[:, 0]) > 0.02 * 0.15


def test_displacement_off_is_the_plain_sweep():
    g = load_preset("tree3d", iterations=4)
    sk = interpret(derive(g), g)
    a, b = sweep(sk), sweep(sk, SweepOptions(bark_displacement=0.0), seed=9)
    for name in ("points", "wedge_normal", "wedge_uv", "faces"):
        assert np.array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize("amount", [0.1, 0.5])
def test_displacement_is_a_fraction_of_the_local_radius(amount):
    _, plain = straight_tube(0.0)
    _, bumpy = straight_tube(amount, seed=2)
    ring = np.ones(len(plain.points), bool)
    ring[-2:] = False  # the two cap centres
    axis = np.array([0.0, 1.0, 0.0])

    def radial(points):
        return np.linalg.norm(points - np.outer(points @ axis, axis), axis=1)

    r, rb = radial(plain.points[ring]), radial(bumpy.points[ring])
    assert np.all(rb >= r * (1 - amount) - 1e-12) and np.all(rb <= r * (1 + amount) + 1e-12)
    assert np.abs(rb / r - 1).max() > amount * 0.1  # it did move
    # only along the radius: heights (and so uv v) are unchanged, thin tips stay thin but alive
    np.testing.assert_allclose(bumpy.points[:, 1], plain.points[:, 1], atol=1e-12)
    assert rb[-12:].min() > 0.01 * (1 - amount) - 1e-12
    # normals follow the bumps: unit, outward, and no longer all radial
    n = bumpy.wedge_normal.astype(float)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    out = bumpy.points[bumpy.wedge_point] - np.outer(bumpy.points[bumpy.wedge_point] @ axis, axis)
    side = np.linalg.norm(out, axis=1) > 1e-9
    side &= np.abs(n[:, 1]) < 0.9  # wall wedges, not caps
    assert np.all(np.einsum("ij,ij->i", n[side], out[side]) > 0)
    assert not np.allclose(n, plain.wedge_normal, atol=1e-3)


# abop-1.24c at 2 generations, not 3: one rule of equal segments at fixed angles, so its 64 segments hold every
# junction its 512 do, and its displaced tubes overlap beyond their junctions too (the union is 89% of their
# volume, 80% at 3); the union of 212,160 tube faces took 4.6 CPU s, of 26,544 0.3 s
@pytest.mark.parametrize(("name", "n"), [("tree3d", 4), ("monopodial", 6), ("abop-1.24c", 2)])
def test_displaced_union_stays_watertight_and_whole(name, n):
    g = load_preset(name, iterations=n)
    sk = interpret(derive(g), g)
    tubes = sweep(sk, SweepOptions(bark_displacement=0.5, bark_frequency=12.0), seed=1)
    bark = union(tubes)
    assert bark.is_watertight and bark.is_winding_consistent
    assert components(bark.faces, len(bark.vertices)) == 1
    assert 0 < bark.volume <= tubes.volumes().sum()


def test_displacement_depends_on_the_seed():
    _, a = straight_tube(0.3, seed=1)
    _, b = straight_tube(0.3, seed=1)
    _, c = straight_tube(0.3, seed=2)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)


def test_bad_sweep_bark_options():
    for kw in ({"bark_displacement": 0.6}, {"bark_displacement": -0.1}, {"bark_frequency": 0}, {"bark_octaves": 0}):
        with pytest.raises(ValueError, match=r"SweepOptions\.bark_"):
            SweepOptions(**kw)


# ------------------------------------------------------------------ bark colour and export


def test_bark_colors_range_and_seed():
    pts = np.random.default_rng(0).uniform(-2, 2, (20_000, 3))
    c = bark_colors(pts, BARK.base_color, 0.8, frequency=3.0, seed=4)
    base = np.array(BARK.base_color[:3], np.float32)
    assert c.dtype == np.float32 and c.shape == (20_000, 3)
    assert (c >= base * 0.2 - 1e-6).all() and (c <= base * 1.8 + 1e-6).all() and (c <= 1).all()
    ratio = c / base
    assert np.allclose(ratio[:, 0], ratio[:, 1], atol=1e-5)  # one brightness pattern, the hue kept
    assert ratio.std() > 0.05 and abs(ratio.mean() - 1) < 0.05
    assert np.array_equal(c, bark_colors(pts, BARK.base_color, 0.8, frequency=3.0, seed=4))
    assert not np.array_equal(c, bark_colors(pts, BARK.base_color, 0.8, frequency=3.0, seed=5))
    assert np.array_equal(bark_colors(pts, BARK.base_color, 0.0), np.broadcast_to(base, c.shape))
    with pytest.raises(ValueError, match="variation"):
        bark_colors(pts, BARK.base_color, 1.5)


BARKY = GenerateOptions.from_flat(
    sides=6,
    bark_displacement=0.3,
    bark_color_variation=0.5,
    turtle={"angle_jitter": 6.0, "width_jitter": 0.2, "branch_roll": 40.0, "branch_drop": 0.1},
)


@pytest.fixture(scope="module")
def barky_tree():
    return lsys3d.generate("tree3d", iterations=4, seed=7, options=BARKY)


def test_generate_with_everything_on(barky_tree):
    tree = barky_tree
    assert tree.bark.is_watertight and components(tree.bark.faces, len(tree.bark.vertices)) == 1
    colors = tree.bark.colors
    assert colors.shape == (len(tree.bark.vertices), 3) and colors.dtype == np.float32
    assert tree.provenance.options["turtle"] == BARKY.turtle
    assert tree.provenance.options["color"]["variation"] == 0.5
    assert tree.provenance.options["sweep"]["bark_displacement"] == 0.3
    plain = lsys3d.generate("tree3d", iterations=4, seed=7, sides=6)
    assert plain.bark.colors is None


@pytest.mark.parametrize("suffix", [".glb", ".usda", ".usdz"])
def test_same_seed_same_bytes(tmp_path, suffix):
    paths = []
    for folder, seed in (("a", 7), ("b", 7), ("c", 8)):  # one file name: a .usdz holds it
        (tmp_path / folder).mkdir()
        tree = lsys3d.generate("tree3d", iterations=4, seed=seed, options=BARKY)
        paths.append(export(tree, tmp_path / folder / f"tree{suffix}"))
    a, b, c = (p.read_bytes() for p in paths)
    assert a == b != c


def test_gltf_vertex_colors_pass_the_validator(barky_tree, tmp_path):
    path = export(barky_tree, tmp_path / "bark.glb")
    report = validators.validate_gltf(path)
    assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
    doc, binary = read_glb(path)
    (bark,) = [m for m in doc["meshes"] if m["name"] == "bark"]
    attributes = bark["primitives"][0]["attributes"]
    accessor = doc["accessors"][attributes["COLOR_0"]]
    assert accessor["type"] == "VEC3" and accessor["componentType"] == 5126
    assert accessor["count"] == doc["accessors"][attributes["POSITION"]]["count"]
    material = doc["materials"][bark["primitives"][0]["material"]]
    assert material["pbrMetallicRoughness"]["baseColorFactor"] == [1.0, 1.0, 1.0, 1.0]
    view = doc["bufferViews"][accessor["bufferView"]]
    colors = np.frombuffer(binary, np.float32, accessor["count"] * 3, view["byteOffset"]).reshape(-1, 3)
    assert colors.min() >= 0 and colors.max() <= 1
    assert set(np.round(colors.mean(axis=0) / np.array(BARK.base_color[:3]), 1)) == {1.0}


def test_default_export_has_no_colors(tmp_path):
    tree = lsys3d.generate("abop-1.24a", iterations=2, sides=5)
    doc, _ = read_glb(export(tree, tmp_path / "plain.glb"))
    assert all("COLOR_0" not in p["attributes"] for m in doc["meshes"] for p in m["primitives"])
    assert doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] == list(BARK.base_color)
    stage = Usd.Stage.Open(str(export(tree, tmp_path / "plain.usda")))
    assert (
        not UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/abop_1_24a/Geom/bark"))
        .GetPrimvar("displayColor")
        .HasAuthoredValue()
    )


def test_usd_display_color(barky_tree, tmp_path):
    path = export(barky_tree, tmp_path / "bark.usdc", ExportOptions(up_axis="Z", units="cm"))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/tree3d/Geom/bark"))
    primvar = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
    assert primvar.GetInterpolation() == UsdGeom.Tokens.vertex
    colors = np.array(primvar.Get())
    assert colors.shape == (len(mesh.GetPointsAttr().Get()), 3) and colors.min() >= 0 and colors.max() <= 1
    reader = stage.GetPrimAtPath("/tree3d/Looks/bark/displayColor")
    assert reader.GetAttribute("info:id").Get() == "UsdPrimvarReader_float3"


# ------------------------------------------------------------------ siblings


@pytest.fixture(scope="module")
def siblings():
    options = GenerateOptions(sweep=SweepOptions(sides=5), turtle={"angle_jitter": 8.0, "length_jitter": 0.1})
    assert options == GenerateOptions.from_flat(sides=5, turtle={"angle_jitter": 8.0, "length_jitter": 0.1})
    return [lsys3d.generate("abop-1.24a", iterations=2, seed=7 + i, options=options) for i in range(4)]


def test_variants_as_files(siblings, tmp_path):
    paths = export_variants(siblings, tmp_path / "tree.glb")
    assert [p.name for p in paths] == ["tree_0.glb", "tree_1.glb", "tree_2.glb", "tree_3.glb"]
    assert paths == variant_paths(tmp_path / "tree.glb", 4)
    data = [p.read_bytes() for p in paths]
    assert len(set(data)) == 4
    points = [read_glb(p)[0]["accessors"][0]["max"] for p in paths]
    assert len({tuple(p) for p in points}) == 4  # different geometry, not just different provenance
    assert validators.gltf_issues(validators.validate_gltf(paths[2]), 0) == []


def test_variants_no_clobber_checks_the_files_written(siblings, tmp_path):
    """The pattern tree.glb is not written, so an existing tree.glb does not stop tree_0.glb..."""
    (tmp_path / "tree.glb").write_bytes(b"precious")
    paths = export_variants(siblings[:2], tmp_path / "tree.glb", ExportOptions(no_clobber=True))
    assert [p.name for p in paths] == ["tree_0.glb", "tree_1.glb"]
    assert (tmp_path / "tree.glb").read_bytes() == b"precious"
    with pytest.raises(ExportError, match=r"tree_0\.glb: file exists"):  # ...but an existing tree_0.glb does
        export_variants(siblings[:2], tmp_path / "tree.glb", ExportOptions(no_clobber=True))


@pytest.mark.parametrize("suffix", [".usda", ".usdc", ".usdz"])
def test_variants_in_one_usd_file(siblings, tmp_path, suffix):
    (path,) = export_variants(siblings, tmp_path / f"trees{suffix}")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    assert root.GetVariantSets().GetNames() == ["seed"]
    variants = root.GetVariantSets().GetVariantSet("seed")
    # USD lists variant names sorted as text
    assert variants.GetVariantNames() == ["seed_10", "seed_7", "seed_8", "seed_9"]
    assert variants.GetVariantSelection() == "seed_7"
    seen = []
    for name in variants.GetVariantNames():
        assert variants.SetVariantSelection(name)
        points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/abop_1_24a/Geom/bark")).GetPointsAttr().Get())
        provenance = json.loads(root.GetCustomDataByKey("lsys3d")["provenance"])
        assert f"seed_{provenance['seed']}" == name
        seen.append(points)
    assert all(not (a.shape == b.shape and np.array_equal(a, b)) for a, b in itertools.pairwise(seen))


def test_variants_need_distinct_seeds(siblings, tmp_path):
    with pytest.raises(lsys3d.ExportError, match="same seed"):
        export_variants([siblings[0], siblings[0]], tmp_path / "twins.usda")


# ------------------------------------------------------------------ command line


def test_cli_variants_files(tmp_path, capsys):
    out = tmp_path / "tree.glb"
    args = ["generate", "abop-1.24a", "-n", "2", "--seed", "7", "--variants", "3", "-o", str(out), "--sides", "4"]
    assert main([*args, "--turtle", "angle_jitter=10", "--turtle", "jitter_distribution=normal"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["tree_0.glb", "tree_1.glb", "tree_2.glb"]
    seeds = [read_glb(tmp_path / n)[0]["asset"]["extras"]["seed"] for n in names]
    assert seeds == [7, 8, 9]
    assert "seed 9" in capsys.readouterr().out


def test_cli_variants_usd_and_bark(tmp_path):
    out = tmp_path / "trees.usda"
    args = ["-q", "generate", "abop-1.24a", "-n", "2", "--variants", "2", "-o", str(out), "--sides", "4"]
    assert (
        main([*args, "--bark-displacement", "0.2", "--bark-color-variation", "0.3", "--turtle", "branch_roll=90"]) == 0
    )
    stage = Usd.Stage.Open(str(out))
    assert stage.GetDefaultPrim().GetVariantSets().GetVariantSet("seed").GetVariantNames() == ["seed_0", "seed_1"]
    options = json.loads(stage.GetDefaultPrim().GetCustomDataByKey("lsys3d")["provenance"])["options"]
    assert options["turtle"] == {"branch_roll": 90}
    assert options["sweep"]["bark_displacement"] == 0.2 and options["color"]["variation"] == 0.3


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--turtle", "wobble=1"], "expected KEY=VALUE with KEY one of"),
        (["--bark-displacement", "0.8"], "must be in [0, 0.5], not 0.8"),
        (["--bark-color-variation", "x"], "expected a number"),
        (["--variants", "0"], "must be at least 1"),
    ],
)
def test_cli_usage_errors(args, fragment, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["generate", "abop-1.24a", "-n", "1", "-o", str(tmp_path / "x.glb"), *args])
    assert info.value.code == 2 and fragment in capsys.readouterr().err


def test_generate_options_reject_unknown_turtle_keys():
    with pytest.raises(lsys3d.OptionsError, match="unknown setting 'wobble'"):
        GenerateOptions(turtle={"wobble": 1})
    with pytest.raises(lsys3d.OptionsError, match=r"BarkColorOptions.variation: must be in \[0, 1\], not 2"):
        GenerateOptions.from_flat(bark_color_variation=2.0)


# ------------------------------------------------------------------ variation from Python (issue 37)


def _grown_bytes(tree, path):
    export(tree, path)
    return path.read_bytes()


def test_a_loop_over_seeds_of_a_seedless_plant_warns_once():
    """generate(tree3d, seed=s) for s in 0..4 grows one plant five times: it says so, once, through warnings."""
    import warnings

    from lsys3d.errors import SeedWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        trees = [lsys3d.generate("tree3d", iterations=2, seed=s, union=False) for s in range(5)]
    seeds = [w for w in caught if issubclass(w.category, SeedWarning)]
    assert len(seeds) == 1, [str(w.message) for w in caught]
    message = str(seeds[0].message)
    assert message.startswith("tree3d grows the same plant from every seed")
    assert "angle_jitter=5" in message and "--turtle" not in message  # generate's own spelling
    assert seeds[0].filename == __file__  # it points at the caller's line, not into lsys3d
    assert len({t.bark.vertices.tobytes() for t in trees}) == 1  # what it warns of: five copies


def test_no_seed_warning_when_the_seed_matters_or_is_the_grammars_own(recwarn):
    from lsys3d.errors import SeedWarning

    lsys3d.generate("tree3d", iterations=2, union=False)  # no seed given
    lsys3d.generate("tree3d", iterations=2, seed=load_preset("tree3d").seed, union=False)  # its own
    lsys3d.generate("tree3d", iterations=2, seed=3, union=False, angle_jitter=8)  # jitter: the seed matters
    lsys3d.generate("koch-stochastic", iterations=2, seed=3, union=False)  # stochastic rules
    assert not [w for w in recwarn if issubclass(w.category, SeedWarning)]


def test_turtle_settings_by_their_keys_from_generate(tmp_path):
    """generate("tree3d", angle_jitter=8): the turtle's settings as --turtle spells them; the seed then varies it."""
    a = lsys3d.generate("tree3d", iterations=2, seed=1, union=False, angle_jitter=8, branch_drop=0.05)
    b = lsys3d.generate("tree3d", iterations=2, seed=2, union=False, angle_jitter=8, branch_drop=0.05)
    assert a.provenance.options["turtle"] == {"angle_jitter": 8.0, "branch_drop": 0.05}
    assert not np.array_equal(a.skeleton.end, b.skeleton.end)
    same = lsys3d.generate("tree3d", iterations=2, seed=1, union=False, turtle={"angle_jitter": 8, "branch_drop": 0.05})
    assert _grown_bytes(a, tmp_path / "a.glb") == _grown_bytes(same, tmp_path / "same.glb")
    # a key overrides the same key of turtle=, the others stay
    options = GenerateOptions.from_flat(turtle={"angle_jitter": 2, "width_jitter": 0.1}, angle_jitter=8)
    assert dict(options.turtle) == {"angle_jitter": 8.0, "width_jitter": 0.1}
    assert GenerateOptions.from_flat(step=2.0).cleanup.step == 2.0  # step stays the cleanup's (a flat name already)


@pytest.mark.parametrize(
    ("name", "closest"),
    [
        ("angle_jiter", "angle_jitter"),
        ("angle-jitter", "angle_jitter"),
        ("sidez", "sides"),
        ("brnch_drop", "branch_drop"),
    ],
)
def test_a_misspelt_option_names_the_closest_one(name, closest):
    with pytest.raises(lsys3d.OptionsError) as info:
        lsys3d.generate("tree3d", iterations=1, **{name: 8})
    message = str(info.value)
    assert message == f"GenerateOptions: unknown option {name!r}; did you mean {closest!r}?"


def test_an_unknown_option_does_not_list_every_name():
    with pytest.raises(lsys3d.OptionsError) as info:
        lsys3d.generate("tree3d", iterations=1, xyzzy=3)
    message = str(info.value)
    assert message.startswith("GenerateOptions: unknown option 'xyzzy' (") and len(message) < 120, message
    assert "docs/architecture.md" in message


def test_export_variants_is_public(tmp_path):
    from lsys3d import exchange

    assert lsys3d.export_variants is exchange.export_variants and "export_variants" in lsys3d.__all__
    trees = [lsys3d.generate("abop-1.24a", iterations=1, seed=s, sides=4, angle_jitter=5) for s in (1, 2)]
    paths = lsys3d.export_variants(trees, tmp_path / "pair.glb")
    assert [p.name for p in paths] == ["pair_0.glb", "pair_1.glb"]


def test_jobs_take_turtle_settings_by_their_keys():
    from lsys3d.library.jobs import options_from_names

    _, options, _ = options_from_names({"angle_jitter": 8, "sides": 5})
    assert dict(options.turtle) == {"angle_jitter": 8.0} and options.sweep.sides == 5


@pytest.mark.parametrize(
    ("extra", "what"),
    [
        (["--seed", "7"], "another seed gives the same plant"),
        (["--seed", "7", "--variants", "3"], "its 3 variants are identical"),
    ],
)
def test_cli_warns_of_a_seed_that_changes_nothing_in_its_own_words(extra, what, tmp_path):
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "lsys3d", "generate", "abop-1.24a", "-n", "1", *extra, "-o", str(tmp_path / "t.glb")],
        capture_output=True,
        text=True,
        check=True,
    )
    lines = out.stderr.splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("lsys3d: abop-1.24a grows the same plant from every seed") and what in lines[0]
    assert "--turtle angle_jitter=5" in lines[0]
