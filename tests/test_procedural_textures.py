"""Procedural textures: bark that tiles, leaves with alpha, the same bytes per seed, [materials] procedural, export."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import validators
from gltf_files import read_glb
from pxr import Usd, UsdShade

import lsys3d
from lsys3d.images import png_pixels
from lsys3d.look.materials import material_table
from lsys3d.look.textures import KINDS, normal_map, procedural
from lsys3d.mesh.sweep import SweepOptions, sweep
from lsys3d.noise import fbm3, perlin3

BARK = [k for k, row in KINDS.items() if row.group == "bark"]
LEAVES = [k for k, row in KINDS.items() if row.group == "leaf"]
RES = 128


# ---------------------------------------------------------------- noise


def test_periodic_noise_repeats_and_the_plain_noise_is_unchanged():
    p = np.random.default_rng(3).uniform(0, 4, (2000, 3))
    shift = np.array([3.0, -6.0, 0.0])
    a = perlin3(p, 9, period=(3, 2, 0))
    assert np.allclose(a, perlin3(p + shift, 9, period=(3, 2, 0)), atol=1e-12)
    assert not np.allclose(perlin3(p, 9), perlin3(p + shift, 9))  # without a period it does not repeat
    f = fbm3(p, 4, octaves=5, frequency=2.0, period=(1.5, 1.0, 0))
    assert np.allclose(
        f, fbm3(p + np.array([1.5, 3.0, 0.0]), 4, octaves=5, frequency=2.0, period=(1.5, 1.0, 0)), atol=1e-12
    )
    # a period of 256 cells is the lattice's own: the same numbers as no period
    assert np.array_equal(perlin3(p, 9, period=256), perlin3(p, 9))
    with pytest.raises(ValueError, match="whole numbers of lattice cells"):
        perlin3(p, 9, period=2.5)
    with pytest.raises(ValueError, match="whole numbers of lattice cells"):
        fbm3(p, 9, frequency=1.3, period=1)


# ---------------------------------------------------------------- images


@pytest.mark.parametrize("kind", BARK)
def test_bark_tiles(kind):
    """The last column continues into the first (and the bottom row into the top) as smoothly as any two neighbours."""
    t = procedural(kind, seed=4, resolution=RES)
    for image in (t.albedo, t.normal, t.roughness):
        a = png_pixels(image.data).astype(np.float64)
        for axis in (0, 1):
            b = np.moveaxis(a, axis, 0)
            neighbours = np.abs(np.diff(b, axis=0)).mean(axis=(1, 2))
            wrap = np.abs(b[0] - b[-1]).mean()
            # the seam is one more pair of neighbours: no larger than all but the largest 1% of the others
            assert wrap <= np.quantile(neighbours, 0.99) + 0.5, (image.name, axis, wrap, neighbours.mean())


@pytest.mark.parametrize("kind", BARK)
def test_bark_images(kind):
    t = procedural(kind, seed=1, resolution=RES, tile_size=0.8)
    assert t.tile_size == 0.8 and t.albedo.mime == "image/png" and not t.albedo.alpha
    albedo = png_pixels(t.albedo.data)
    assert albedo.shape == (RES, RES, 3) and albedo.std() > 5  # a pattern, not a flat colour
    packed = png_pixels(t.roughness.data)
    assert (packed[..., 0] == 255).all() and (packed[..., 2] == 0).all()  # glTF: roughness G, metallic B (0)
    assert 0.3 < packed[..., 1].mean() / 255 < 1.0 and packed[..., 1].std() > 1


@pytest.mark.parametrize("kind", [*BARK, *LEAVES])
def test_normal_maps_are_unit_and_face_out(kind):
    t = procedural(kind, seed=2, resolution=RES)
    n = png_pixels(t.normal.data).astype(np.float64) / 255 * 2 - 1
    length = np.linalg.norm(n, axis=-1)
    assert np.abs(length - 1).max() < 0.015  # unit vectors, to 8-bit rounding
    assert n[..., 2].min() > 0.05  # never facing into the surface
    assert np.abs(n[..., :2]).max() > 0.1  # and some relief


def test_normal_map_convention():
    """OpenGL/glTF: a ramp rising to the right tilts the normal left (-x); rising up the image tilts it down (-y)."""
    x = np.linspace(0, 1, 16)
    right = normal_map(np.tile(x, (16, 1)), 1.0).astype(float)[4:12, 4:12] / 255 * 2 - 1
    assert (right[..., 0] < -0.5).all() and np.abs(right[..., 1]).max() < 0.01
    up = normal_map(np.tile(x[::-1, None], (1, 16)), 1.0).astype(float)[4:12, 4:12] / 255 * 2 - 1  # row 0 highest
    assert (up[..., 1] < -0.5).all() and np.abs(up[..., 0]).max() < 0.01


@pytest.mark.parametrize("kind", LEAVES)
def test_leaf_images(kind):
    t = procedural(kind, seed=0, resolution=RES)
    assert t.albedo.alpha and t.roughness is None and t.tile_size is None
    rgba = png_pixels(t.albedo.data)
    alpha = rgba[..., 3]
    assert alpha[0, 0] == alpha[0, -1] == 0  # transparent around the leaf
    assert (alpha > 128).mean() > 0.03 and (alpha == 0).mean() > 0.2
    assert alpha[-4:, RES // 2 - 3 : RES // 2 + 3].max() > 128 or kind == "flower"  # attached at the bottom centre
    green = rgba[alpha == 255][:, :3].astype(int)
    assert green.std(axis=0).max() > 3  # veins and variation
    if kind != "flower":
        assert np.median(green[:, 1]) > np.median(green[:, 2])  # green leaves by default


def test_same_seed_same_bytes_in_another_process_other_seed_other_bytes():
    a = procedural("plated", seed=7, resolution=64)
    b = procedural("plated", seed=8, resolution=64)
    assert a is procedural("plated", seed=7, resolution=64)  # made once per process
    assert a.albedo.data != b.albedo.data and a.normal.data != b.normal.data
    code = (
        "import hashlib\nfrom lsys3d.look.textures import procedural\n"
        "t = procedural('plated', seed=7, resolution=64)\n"
        "print(hashlib.sha256(t.albedo.data + t.normal.data + t.roughness.data).hexdigest())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    import hashlib

    assert out == hashlib.sha256(a.albedo.data + a.normal.data + a.roughness.data).hexdigest()
    leaf = procedural("maple", seed=1, resolution=64)
    assert leaf.albedo.data != procedural("maple", seed=1, resolution=64, colors=[(0.6, 0.1, 0.02)] * 3).albedo.data


def test_tile_size_keeps_features_in_metres():
    """A tile twice as large holds about twice as many ring scars (the palm's rings are ~7 cm apart)."""

    def rings(tile_size: float) -> int:
        height = png_pixels(procedural("ringed", seed=1, resolution=256, tile_size=tile_size).albedo.data)
        column = height[:, 0, :].astype(float).mean(axis=1)
        dark = column < np.quantile(column, 0.1)
        return int(np.count_nonzero(dark & ~np.roll(dark, 1)))

    small, large = rings(0.35), rings(0.7)
    assert 4 <= small <= 6 and 9 <= large <= 11, (small, large)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("bark",), "unknown kind 'bark'"),
        (("smooth", -1), "seed must be a whole number"),
        (("smooth", 0, 8), r"resolution must be a whole number in 16..2048"),
        (("smooth", 0, 64, [(1, 1, 1)]), "smooth takes 3 colours"),
        (("smooth", 0, 64, None, 0.0), "tile_size must be metres"),
    ],
)
def test_bad_arguments(args, message):
    with pytest.raises(ValueError, match=f"procedural: {message}"):
        procedural(*args)


# ---------------------------------------------------------------- [materials]

GRAMMAR = """\
name = "procedural"
axiom = "!(0.3)F[+'(1)!(0.15)FF~][-!(0.12)F~]F~"
angle = 40

[materials]
bark = { procedural = { kind = "furrowed", seed = 3, tile_size = 0.6, resolution = 64 } }
1 = { name = "birch bark", procedural = { kind = "birch", resolution = 64 }, roughness = 0.7 }
leaf = { procedural = { kind = "maple", resolution = 64, colors = ["#c0501c", "#e8a040", "#6a3a1a"] } }
"""


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    path = tmp_path_factory.mktemp("procedural") / "procedural.toml"
    path.write_text(GRAMMAR)
    return lsys3d.generate(path, sides=8)


def test_grammar_makes_the_materials(tree):
    bark, birch, leaf = tree.materials.bark, tree.materials.for_bark(1), tree.materials.leaf
    assert bark.texture.name == "furrowed_s3_64_0.6m_albedo.png" and bark.tile_size == 0.6
    assert bark.base_color == (1.0, 1.0, 1.0, 1.0) and bark.roughness == 1.0
    assert bark.images == (bark.texture, bark.normal_texture, bark.roughness_texture)
    assert birch.name == "birch bark" and birch.roughness == 0.7 and birch.tile_size == 0.5  # the entry's own wins
    assert leaf.alpha_cutoff == 0.5 and leaf.texture.alpha and leaf.roughness_texture is None and leaf.double_sided
    assert leaf.texture.data != procedural("maple", resolution=64).albedo.data  # its own colours
    uv = material_table(lsys3d.Grammar.from_text(GRAMMAR)).uv_tiles(0.5)
    assert uv[0] == uv[7] == 0.6 and uv[1] == 0.5


def test_tile_size_sets_the_tubes_texture_scale(tree):
    """A material's tile_size plays the sweep's uv_tile for the chains of that material."""
    skeleton = tree.skeleton
    tiles = np.full(256, 0.6)
    assert np.array_equal(
        sweep(skeleton, SweepOptions(sides=8), uv_tiles=tiles).tiles,
        sweep(skeleton, SweepOptions(sides=8, uv_tile=0.6)).tiles,
    )
    by_material = sweep(skeleton, SweepOptions(sides=8), uv_tiles=np.where(np.arange(256) == 1, 0.02, 0.6)).tiles
    plain = sweep(skeleton, SweepOptions(sides=8, uv_tile=0.6)).tiles
    assert (by_material >= plain).all() and (by_material > plain).any()  # the birch branch: many small tiles


def test_glb_passes_the_validator(tree, tmp_path):
    path = lsys3d.export(tree, tmp_path / "procedural.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc, binary = read_glb(path)
    bark = next(m for m in doc["materials"] if m["name"] == "bark")["pbrMetallicRoughness"]
    image = doc["images"][doc["textures"][bark["metallicRoughnessTexture"]["index"]]["source"]]
    view = doc["bufferViews"][image["bufferView"]]
    data = binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
    assert data == tree.materials.bark.roughness_texture.data and bark["roughnessFactor"] == 1.0
    assert len(doc["images"]) == 8  # three images for each of the two barks, albedo and normal map for the leaf


def test_usdz_passes_the_validators(tree, tmp_path):
    path = lsys3d.export(tree, tmp_path / "procedural.usdz")
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    surface = UsdShade.Shader(stage.GetPrimAtPath("/procedural/Looks/bark/PreviewSurface"))
    (source,), _ = surface.GetInput("roughness").GetConnectedSources()
    assert (source.source.GetPath().name, source.sourceName) == ("metallicRoughnessTexture", "g")
    (source,), _ = surface.GetInput("metallic").GetConnectedSources()
    assert source.sourceName == "b"
    texture = UsdShade.Shader(stage.GetPrimAtPath("/procedural/Looks/bark/metallicRoughnessTexture"))
    assert texture.GetInput("sourceColorSpace").Get() == "raw"
    assert texture.GetInput("file").Get().path == "textures/furrowed_s3_64_0.6m_roughness.png"


def test_without_procedural_nothing_changes():
    """A grammar without procedural textures: no tile sizes for the sweep, the same materials as before."""
    table = material_table(lsys3d.Grammar.from_text('axiom = "F"\n[materials]\nbark = { base_color = "#402010" }\n'))
    assert table.uv_tiles(0.5) is None and table.bark.roughness_texture is None and table.bark.images == ()


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('bark = { procedural = { kind = "oak" } }', "procedural: kind must be one of furrowed"),
        ('bark = { procedural = { kind = "smooth", size = 2 } }', "procedural: unknown key 'size'"),
        ('bark = { procedural = "furrowed" }', "procedural: expected a table"),
        ('bark = { procedural = { kind = "smooth", seed = -2 } }', "seed must be a whole number >= 0"),
        ('bark = { procedural = { kind = "smooth", resolution = 5000 } }', r"resolution must be .* 16..2048"),
        ('bark = { procedural = { kind = "smooth", tile_size = 0 } }', r"tile_size must be metres in 0.01..100"),
        ('leaf = { procedural = { kind = "maple", tile_size = 1 } }', "tile_size is for bark kinds"),
        ('leaf = { procedural = { kind = "maple", colors = ["#ff0000"] } }', "colors must be a list of 3 colours"),
        ('leaf = { procedural = { kind = "maple", colors = ["#ff0000", "red", "#00ff00"] } }', r"colors\[1\]"),
        (
            'bark = { tile_size = 1, procedural = { kind = "smooth", tile_size = 1 } }',
            "tile_size is given twice",
        ),
        (
            'bark = { procedural = { kind = "smooth" }, alpha_cutoff = 0.5 }',
            "alpha_cutoff needs a texture with an alpha",
        ),
        ("bark = { roughness_texture = 3 }", "roughness_texture must be a file name"),
    ],
)
def test_bad_procedural_entries_name_their_line(tmp_path, entry, message):
    grammar = tmp_path / "plant.toml"
    grammar.write_text(f'axiom = "F~"\n\n[materials]\n{entry}\n')
    with pytest.raises(lsys3d.GrammarError, match=message) as info:
        lsys3d.generate(grammar)
    assert str(info.value).startswith(f"{grammar}:4:1: [materials] materials.")


def test_a_material_gives_tile_size_for_its_own_images(tmp_path):
    from test_textures import write_textures

    write_textures(tmp_path)
    path = tmp_path / "plant.toml"
    path.write_text('axiom = "F"\n[materials]\nbark = { texture = "tex/bark.png", tile_size = 0.8 }\n')
    table = material_table(lsys3d.load(path))
    assert table.bark.tile_size == 0.8 and table.uv_tiles(0.5)[0] == 0.8


def test_the_docs_show_every_kind():
    """docs/textures.md holds the table of KINDS as written from it, and a swatch under 100 kB for each kind."""
    from pathlib import Path

    from lsys3d.look.textures import kinds_markdown

    docs = Path(__file__).resolve().parent.parent / "docs"
    assert kinds_markdown() in (docs / "textures.md").read_text(encoding="utf-8")
    for kind in KINDS:
        swatch = docs / "textures" / f"{kind}.png"
        assert swatch.is_file() and swatch.stat().st_size < 100_000, kind


# ---------------------------------------------------------------- leaf sprays

SPRAYS = [k for k, row in KINDS.items() if row.leaf_length is not None]


def test_the_sprays_are_the_kinds_with_a_leaf_length():
    assert SPRAYS == ["oak_spray", "maple_spray", "birch_spray", "willow_spray", "beech_spray", "ovate_spray"]
    assert all(KINDS[k].group == "leaf" for k in SPRAYS)


@pytest.mark.parametrize("kind", SPRAYS)
def test_a_spray_carries_six_to_fifteen_leaves_of_its_length_inside_the_picture(kind):
    from lsys3d.look.textures import _SPRAYS, _spray_leaves

    layout = _SPRAYS[kind]
    lengths = []
    for seed in range(8):
        _, leaves = _spray_leaves(layout, np.random.default_rng(seed))
        assert 6 <= len(leaves) <= 15
        for _, (bx, by), (dx, dy), length, squash, *_ in leaves:
            tip = (bx + dx * 0.97 * length, by + dy * 0.97 * length)
            assert -0.5 < tip[0] < 0.5 and 0 < tip[1] < 1
            assert 0.6 <= squash <= 1.0
            lengths.append(length)
    # the kind's leaf_length is what a card's leaves measure, in picture heights
    assert np.mean(lengths) == pytest.approx(KINDS[kind].leaf_length, rel=0.2)


@pytest.mark.parametrize("kind", SPRAYS)
def test_a_spray_draws_its_leaf_kinds_outline(kind, monkeypatch):
    """The spray's leaves come from the single-leaf kind's outline: without it only the twig and stalks remain."""
    from lsys3d.look import textures

    leaf = textures._SPRAYS[kind].leaf
    full = png_pixels(procedural(kind, seed=2, resolution=RES).albedo.data)[..., 3]
    outline, relief = textures._LEAF_OUTLINES[leaf]
    # the leaf kind's own single-leaf image is unchanged by being drawn in sprays (made before the outline is
    # patched out below: procedural() keeps its images for the process, so this must not depend on test order)
    assert png_pixels(procedural(leaf, seed=2, resolution=RES).albedo.data)[..., 3].max() == 255

    def bare(x, y, n):
        blade, petiole, veins, across = outline(x, y, n)
        return np.zeros_like(blade), petiole, veins, across

    monkeypatch.setitem(textures._LEAF_OUTLINES, leaf, (bare, relief))
    twig = textures._spray(textures._Grid(RES, 2), [(0.1, 0.3, 0.1)] * 3, textures._SPRAYS[kind]).alpha
    assert (full > 128).mean() > 3 * (twig > 0.5).mean()
