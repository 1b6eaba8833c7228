"""[surfaces]: leaf and organ models from files, cards, their errors at the entry's line, the leaf's resolution."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
import validators
from gltf_files import node, read_glb

import lsys3d
from lsys3d.errors import AssetError
from lsys3d.exchange import ExportOptions, export
from lsys3d.images import png_bytes
from lsys3d.look import surfaces as surfaces_module
from lsys3d.look.leaves import default_leaf
from lsys3d.look.surfaces import card, load_model, surface_table

# a diamond leaf authored 4 units long, lying in the x-z plane facing +y, its stem end at (10, 2, -3)
DIAMOND = np.array([[0, 0, 0], [1, 0, 2], [0, 0, 4], [-1, 0, 2]], np.float64) + np.array([10, 2, -3])
DIAMOND_FACES = np.array([[0, 2, 1], [0, 3, 2]])  # counter-clockwise seen from +y


def write_models(folder: Path) -> None:
    mesh = trimesh.Trimesh(DIAMOND, DIAMOND_FACES, process=False)
    for suffix in ("glb", "obj", "ply", "stl"):
        data = mesh.export(file_type=suffix)
        (folder / f"diamond.{suffix}").write_bytes(data.encode() if isinstance(data, str) else data)
    # the same leaf standing up along +y (a Y-up DCC's "upright" leaf), facing -z
    upright = trimesh.Trimesh(DIAMOND[:, [0, 2, 1]] * [1, 1, -1], DIAMOND_FACES, process=False)
    (folder / "upright.obj").write_text(upright.export(file_type="obj"))
    y, x = np.mgrid[0:20, 0:10]
    rgba = np.zeros((20, 10, 4), np.uint8)
    rgba[..., 1], rgba[..., 3] = 200, (np.abs(x - 4.5) < 5 * np.sin(np.pi * (y + 0.5) / 20)) * 255
    (folder / "card.png").write_bytes(png_bytes(rgba))
    (folder / "opaque.png").write_bytes(png_bytes(rgba[..., :3]))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("surfaces")
    write_models(folder)
    return folder


def grammar(folder: Path, surfaces: str, materials: str = "", axiom: str = "F[+F~]F~") -> lsys3d.Grammar:
    text = f'name = "plant"\naxiom = "{axiom}"\nangle = 45\n\n[surfaces]\n{surfaces}\n'
    if materials:
        text += f"\n[materials]\n{materials}\n"
    path = folder / "plant.toml"
    path.write_text(text)
    return lsys3d.Grammar.from_file(path)


# ---------------------------------------------------------------- models


@pytest.mark.parametrize("suffix", ["glb", "obj", "ply", "stl"])
def test_models_are_normalised_into_the_leaf_frame(folder, suffix):
    model = load_model(folder / f"diamond.{suffix}")
    assert model.bounds.round(9).tolist() == [[-0.25, 0, 0], [0.25, 0, 1]]  # base at the origin, length 1
    assert np.allclose(model.face_normals, [0, 1, 0])  # the front still faces +y
    assert np.allclose(model.normals.reshape(-1, 3), [0, 1, 0], atol=1e-6)


def test_rotate_scale_and_normalize(folder):
    upright = load_model(folder / "upright.obj", rotate=(90, 0, 0))  # +y to +z: back into the convention
    assert upright.bounds.round(9).tolist() == [[-0.25, 0, 0], [0.25, 0, 1]]
    assert np.allclose(upright.face_normals, [0, 1, 0])
    half = load_model(folder / "diamond.obj", scale=0.5)
    assert half.bounds.round(9).tolist() == [[-0.125, 0, 0], [0.125, 0, 0.5]]
    raw = load_model(folder / "diamond.obj", normalize=False)
    assert np.allclose(raw.vertices[raw.faces].reshape(-1, 3).min(0), DIAMOND.min(0))  # as authored
    with pytest.raises(AssetError, match="no length along z"):
        load_model(folder / "diamond.obj", rotate=(90, 0, 0))  # turned flat across z


def test_bad_model_files(folder, tmp_path, monkeypatch):
    (tmp_path / "junk.glb").write_bytes(b"not a glb at all, certainly")
    with pytest.raises(AssetError, match=r"junk\.glb: not a readable \.glb model"):
        load_model(tmp_path / "junk.glb")
    (tmp_path / "empty.obj").write_text("# nothing\n")
    with pytest.raises(AssetError, match="the model has no triangles"):
        load_model(tmp_path / "empty.obj")
    (tmp_path / "nan.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
    with pytest.raises(AssetError, match="not finite"):
        load_model(tmp_path / "nan.obj")
    with pytest.raises(AssetError, match=r"a model must be \.glb, \.obj, \.ply, \.stl, not '\.fbx'"):
        load_model(tmp_path / "leaf.fbx")
    with pytest.raises(AssetError, match="no such model file"):
        load_model(tmp_path / "missing.obj")
    monkeypatch.setattr(surfaces_module, "MAX_MODEL_TRIANGLES", 1)
    with pytest.raises(AssetError, match=r"2 triangles, more than 1 \(lsys3d.look.surfaces.MAX_MODEL_TRIANGLES\)"):
        load_model(folder / "diamond.stl")  # a binary STL: refused from its header
    with pytest.raises(AssetError, match="2 triangles, more than 1"):
        load_model(folder / "diamond.obj")
    monkeypatch.setattr(surfaces_module, "MAX_MODEL_BYTES", 10)
    with pytest.raises(AssetError, match=r"more than 10 \(lsys3d.look.surfaces.MAX_MODEL_BYTES\)"):
        load_model(folder / "diamond.obj")


def test_card():
    quad = card(0.3)
    assert len(quad.faces) == 2 and np.allclose(quad.face_normals, [0, 1, 0])
    assert quad.bounds.round(9).tolist() == [[-0.15, 0, 0], [0.15, 0, 1]]
    # the image's bottom (v = 0) at the base, its top (v = 1) at the tip
    corners = {
        tuple(p): tuple(t)
        for p, t in zip(quad.vertices[quad.faces].reshape(-1, 3), quad.uv.reshape(-1, 2), strict=True)
    }
    assert corners[(-0.15, 0, 0)] == (0, 0) and corners[(0.15, 0, 1)] == (1, 1)


# ---------------------------------------------------------------- the [surfaces] table


def test_leaf_model_replaces_the_blade(folder):
    tree = lsys3d.generate(grammar(folder, 'leaf = "diamond.glb"'), 0)
    assert len(tree.leaves.model.faces) == 2 and len(tree.leaves.merged.faces) == 4
    # each leaf is its model placed by its transform
    first = tree.leaves.merged.vertices[:4]
    t = tree.leaves.transforms[0]
    assert np.allclose(first, tree.leaves.model.vertices @ t[:3, :3].T + t[:3, 3])


def test_card_leaf_is_textured_and_masked(folder, tmp_path):
    tree = lsys3d.generate(grammar(folder, 'leaf = { card = "card.png" }'), 0)
    model, leaf = tree.leaves.model, tree.materials.leaf
    assert model.bounds.round(9).tolist() == [[-0.25, 0, 0], [0.25, 0, 1]]  # the image's aspect: 10 / 20
    assert leaf.texture.name == "card.png" and leaf.alpha_cutoff == 0.5 and leaf.double_sided
    assert leaf.base_color == (1, 1, 1, 1)  # the image is the colour
    tinted = lsys3d.generate(
        grammar(
            folder, 'leaf = { card = "card.png", width = 0.2, alpha_cutoff = 0.3 }', "leaf = { base_color = [1, 0, 0] }"
        ),
        0,
    )
    assert tinted.materials.leaf.base_color == (1, 0, 0, 1) and tinted.materials.leaf.alpha_cutoff == 0.3
    assert tinted.leaves.model.bounds.round(9).tolist() == [[-0.1, 0, 0], [0.1, 0, 1]]
    path = export(tree, tmp_path / "card.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, _ = read_glb(path)
    material = doc["materials"][doc["meshes"][node(doc, "leaf")["mesh"]]["primitives"][0]["material"]]
    assert material["alphaMode"] == "MASK" and "baseColorTexture" in material["pbrMetallicRoughness"]
    assert validators.usd_problems(export(tree, tmp_path / "card.usdz")) == []


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('leaf = "missing.glb"', r"surfaces.leaf: .*missing\.glb: no such model file"),
        ('leaf = "card.png"', r"surfaces.leaf: .*card\.png: a model must be \.glb"),
        ('leaf = { card = "opaque.png" }', "a card's image needs an alpha channel"),
        ('leaf = { card = "card.png", width = 0 }', r"width must be a number in \[1e-06, 1e\+06\]"),
        ('leaf = { model = "diamond.obj", rotate = [1, 2] }', "rotate must be 3 angles"),
        ('leaf = { model = "diamond.obj", scale = -1 }', "scale must be a number"),
        ('leaf = { model = "diamond.obj", normalize = "yes" }', "normalize must be true or false"),
        ('leaf = { model = "diamond.obj", colour = 1 }', "unknown key 'colour' for a model"),
        ('leaf = { card = "card.png", rotate = [0, 0, 0] }', "unknown key 'rotate' for a card"),
        ("leaf = { scale = 2 }", "a table needs 'model'"),
        ("leaf = 3", "expected a model file"),
        ('"9lives" = "diamond.obj"', "a surface's name is a letter"),
    ],
)
def test_bad_entries_name_their_line(folder, entry, message):
    with pytest.raises(lsys3d.GrammarError, match=message) as info:
        lsys3d.generate(grammar(folder, entry), 0)
    assert info.value.line == 6 and str(info.value).startswith(f"{folder / 'plant.toml'}:6:1: [surfaces] ")


def test_surfaces_must_be_a_table():
    with pytest.raises(lsys3d.GrammarError, match="'surfaces' must be a table"):
        lsys3d.Grammar.from_text('axiom = "F"\nsurfaces = 3\n')


def test_named_surfaces_are_read(folder):
    table = surface_table(grammar(folder, 'flower = { model = "diamond.ply", scale = 2 }\nsphere = "diamond.obj"'))
    assert sorted(table.by_name) == ["flower", "sphere"] and table.leaf is None
    assert table.get("flower").mesh.bounds.round(9).tolist() == [[-0.5, 0, 0], [0.5, 0, 2]]


# ---------------------------------------------------------------- the built-in leaf and the limits


def test_leaf_points_option():
    assert len(default_leaf(3).faces) == 12
    tree = lsys3d.generate("tree3d", iterations=2, leaf_points=2)
    assert len(tree.leaves.model.faces) == 8 and tree.provenance.options["leaves"] == {"leaf_points": 2}
    with pytest.raises(lsys3d.OptionsError, match=r"LeafOptions.leaf_points: must be in \[1, 256\], not 0"):
        lsys3d.generate("tree3d", iterations=2, leaf_points=0)


def test_cli_leaf_points(tmp_path, capsys):
    from lsys3d.cli import main

    assert main(["generate", "tree3d", "-n", "2", "--leaf-points", "1", "-o", str(tmp_path / "t.glb"), "-q"]) == 0
    doc, _ = read_glb(tmp_path / "t.glb")
    assert doc["asset"]["extras"]["options"]["leaves"] == {"leaf_points": 1}
    with pytest.raises(SystemExit) as exit_info:
        main(["generate", "tree3d", "--leaf-points", "0", "-o", str(tmp_path / "u.glb")])
    assert exit_info.value.code == 2
    assert "--leaf-points: must be in [1, 256], not 0" in capsys.readouterr().err


def test_baked_leaves_are_counted_before_they_are_built(folder):
    from lsys3d.look.leaves import leaves
    from lsys3d.pipeline import draw

    g = grammar(folder, 'leaf = "diamond.obj"', axiom="F" + "[+F~]" * 20)
    _, skeleton = draw(g, 0, 0)
    model = surface_table(g).leaf.mesh
    with pytest.raises(lsys3d.LimitError, match=r"20 leaves of 2 triangles make 40 triangles, more than .* of 30"):
        leaves(skeleton, model, max_triangles=30)
    assert len(leaves(skeleton, model, max_triangles=40).merged.faces) == 40


def test_instanced_user_leaves_validate(folder, tmp_path):
    tree = lsys3d.generate(grammar(folder, 'leaf = "diamond.glb"'), 0)
    for options in (ExportOptions(instance_leaves=True), ExportOptions()):
        report = validators.validate_gltf(export(tree, tmp_path / "leaf.glb", options))
        assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    assert validators.usd_problems(export(tree, tmp_path / "leaf.usda")) == []
