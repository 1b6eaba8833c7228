"""cpfg's look from a vlab view file: surfaces (``surface:``, ``.s`` patches), textures (``texture:``, ``@Tx``), and
``~l(sx, sy, sz)``'s three scales.  Expectations are worked out from the files and cpfg's rules, not from lsys3d."""

from __future__ import annotations

import logging
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import validators
from gltf_files import read_glb
from pxr import Usd, UsdShade

import lsys3d
from lsys3d import GrammarError
from lsys3d.exchange import export
from lsys3d.look.patches import read_patches
from lsys3d.pipeline import draw

REAL = Path(__file__).parent / "corpus" / "cpfg" / "real"
TEXTURED = REAL / "manual-TexturedSurfaces-plant.l"
CYLINDER = REAL / "manual-GeneralizedCylinder-fractal.l"


def _control_points(text: str) -> np.ndarray:
    """The 16 control points of a one-patch ``.s`` file: the 48 numbers after its ``BL:`` line."""
    rest = text[text.index("BL:") :].split("\n", 1)[1]
    return np.array([float(w) for w in rest.split()][:48]).reshape(4, 4, 3)


def test_the_leaf_surface_is_sampled_as_cpfg_samples_it():
    """leaf.s: one bicubic patch; a Bezier patch passes through its four corner control points.  The file's
    heading is +y and its up -z, so cpfg's left is heading x up = -x: a point (x, y, z), less the contact
    point, is (-x, y, -z) along (left, heading, up), which the leaf-model frame orders left, up, heading."""
    text = (REAL / "leaf.s").read_text()
    contact = np.array([0.02, -1.66, 0.0])  # CONTACT POINT of the file
    points = _control_points(text) - contact
    model = np.stack([-points[..., 0], -points[..., 2], points[..., 1]], axis=-1)  # (left, up, heading)
    mesh = read_patches(text, "leaf.s", 1.0, 8, 4)
    assert len(mesh.faces) == 2 * 8 * 4 and len(mesh.vertices) == 9 * 5
    for corner in (model[0, 0], model[0, 3], model[3, 0], model[3, 3]):
        assert np.min(np.linalg.norm(mesh.vertices - corner, axis=1)) < 1e-9
    # per surface (the view file's texture has S): t along the heading over the surface's box, the stem end at 0
    uv = mesh.uv.reshape(-1, 2)
    corners = mesh.vertices[mesh.faces].reshape(-1, 3)
    heading = corners[:, 2]
    assert np.allclose(uv[:, 1], (heading - heading.min()) / np.ptp(heading))
    left = corners[:, 0]
    assert np.allclose(uv[:, 0], (left - left.min()) / np.ptp(left))
    twice = read_patches(text, "leaf.s", 2.0, 8, 4)  # size 2: twice as large
    assert np.allclose(twice.vertices, 2 * mesh.vertices)
    per_patch = read_patches(text, "leaf.s", 1.0, 8, 4, texels="patch")
    assert sorted(set(np.round(per_patch.uv[..., 1].reshape(-1), 6))) == [0.0, 0.25, 0.5, 0.75, 1.0]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 2 3\n", "box's six numbers"),
        ("0 1 0 1 0 1\nCONTACT POINT X: 0 Y: 0 Z: 0\nEND POINT X: 0 Y: 0 Z: 0\nHEADING X: 0 Y: 1 Z: 0\n", "'UP'"),
        (
            "0 1 0 1 0 1\nCONTACT POINT X: 0 Y: 0 Z: 0\nEND POINT X: 0 Y: 0 Z: 0\nHEADING X: 0 Y: 1 Z: 0\n"
            "UP X: 0 Y: 1 Z: 0\nSIZE: 1\n",
            "parallel",
        ),
    ],
)
def test_a_broken_surface_file_is_one_line(text, message):
    with pytest.raises(lsys3d.errors.AssetError) as info:
        read_patches(text, "bad.s")
    assert message in str(info.value) and "\n" not in str(info.value) and str(info.value).startswith("bad.s: ")


def test_textured_surfaces_draws_its_leaves_with_the_maple_texture_and_three_scales(caplog):
    """The homomorphism L(t) --> &(ang);(col) @Tx(1) ~l(1.0*wid, 0.75*len, len) inside [L] and [/(180)L]: every
    one of the 44 leaves is textured and none of the 22 internodes (drawn outside those branches); each leaf is
    0.75 times as long along the heading (sy) as it is along up (sz)."""
    grammar = lsys3d.Grammar.from_file(TEXTURED)
    assert grammar.repairs == ()
    leaf = {"model": "leaf.s", "scale": 1.0, "precision": [8, 4], "end_point": True, "texels": "surface"}
    assert grammar.surfaces == {"l": leaf}  # END POINT is not CONTACT POINT: cpfg moves the turtle after ~l
    assert grammar.materials["255"]["texture"] == "maple.png"
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        _, skeleton = draw(grammar, grammar.iterations, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    # no warning left (and --strict draws it) but cpfg's default angle, by which no turn of this file turns
    assert all("default angle" in r.getMessage() for r in caplog.records), caplog.text
    assert len(skeleton) == 22 and skeleton.n_organs == 44
    assert (skeleton.organ_material == 255).all() and not (skeleton.material == 255).any()
    up, heading = skeleton.organ_scale[:, 1], skeleton.organ_scale[:, 2]
    assert np.allclose(heading / up, 0.75) and (skeleton.organ_scale[:, 0] == 1).all()


def test_textured_surfaces_exports_its_texture(tmp_path):
    tree = lsys3d.generate(TEXTURED, seed=0)
    (prototype,) = tree.organs.prototypes
    assert prototype.name == "l" and len(prototype.mesh.faces) == 64  # leaf.s, not the built-in blade
    transforms = tree.organs.transforms[:, :3, :3]
    lengths = np.linalg.norm(transforms, axis=1)  # along left, up, heading
    assert np.allclose(lengths[:, 2] / lengths[:, 1], 0.75)
    path = export(tree, tmp_path / "plant.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0, report["issues"]
    doc, _ = read_glb(path)
    (material,) = [m for m in doc["materials"] if m["name"] == "texture_1_maple"]
    assert "baseColorTexture" in material["pbrMetallicRoughness"] and material["alphaMode"] == "MASK"
    assert material["alphaCutoff"] == pytest.approx(0.1)  # cpfg's alpha test
    assert [image["name"] for image in doc["images"]] == ["maple.png"]
    usd = export(tree, tmp_path / "plant.usda")
    assert validators.usd_problems(usd) == []
    stage = Usd.Stage.Open(str(usd))
    files = [
        str(s.GetInput("file").Get())
        for prim in stage.Traverse()
        if (s := UsdShade.Shader(prim)) and s.GetIdAttr().Get() == "UsdUVTexture"
    ]
    assert any("maple" in f for f in files), files


def test_generalized_cylinder_selects_its_second_texture():
    """@Tx(TEXTURE) with TEXTURE 2 stands in the axiom before @Gs: every segment shows circles.png, the view file's
    second texture; what is left is '@!' (the cylinders' sides)."""
    grammar = lsys3d.Grammar.from_file(CYLINDER)
    assert [grammar.materials[str(255 - k)]["texture"] for k in range(4)] == [
        "squares.png",
        "circles.png",
        "arrow.png",
        "text.png",
    ]
    _, skeleton = draw(grammar, grammar.iterations, 0)
    assert len(skeleton) == 320 and (skeleton.material == 254).all()


def _model(tmp_path: Path, lsystem: str, view: str) -> Path:
    (tmp_path / "plant.l").write_text(f"Lsystem: 1\nderivation length: 0\nAxiom: {lsystem}\nendlsystem\n")
    (tmp_path / "plant.v").write_text("angle increment: 30\n" + view)
    return tmp_path / "plant.l"


def test_a_branch_keeps_its_texture_and_a_missing_one_is_one_warning(tmp_path, caplog):
    """cpfg's texture index counts the textures it could read: with the first missing, @Tx(1) is the second
    file; @Tx(2) then names none and selects no texture; '[' and ']' save and restore it."""
    shutil.copy(REAL / "squares.png", tmp_path / "squares.png")
    path = _model(
        tmp_path, "F @Tx(1) F [ @Tx(2) F ] F [ @Tx F ] F", "texture: F: missing.png S:\ntexture: F: squares.png\n"
    )
    grammar = lsys3d.Grammar.from_file(path)
    (repair,) = grammar.repairs
    assert re.match(rf"{re.escape(str(path.with_suffix('.v')))}:2: texture not read \('missing.png': ", repair)
    assert list(grammar.materials) == ["255"] and grammar.materials["255"]["texture"] == "squares.png"
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        _, skeleton = draw(grammar, 0, 0)
    assert skeleton.material.tolist() == [0, 255, 0, 255, 0, 255]
    assert sum("missing.png" in r.getMessage() for r in caplog.records) == 1
    with pytest.raises(GrammarError) as info:
        draw(grammar, 0, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    assert "missing.png" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("line", "why"),
    [
        ("texture: F: bark.rgb", "reads PNG and JPEG"),
        ("texture: E: m", "no file"),
        ("texture: F: squares.png Q: 1", "not 'Q'"),
    ],
)
def test_a_texture_line_lsys3d_cannot_use_is_named(tmp_path, line, why):
    shutil.copy(REAL / "squares.png", tmp_path / "squares.png")
    grammar = lsys3d.Grammar.from_file(_model(tmp_path, "@Tx(1) F", line + "\n"))
    (repair,) = grammar.repairs
    assert why in repair and grammar.materials == {}


def test_three_scales_of_a_surface(tmp_path):
    """~l(sx, sy, sz): sx along left, sy along the heading, sz along up (cpfg's interpret.c and iGlPredefinedSurface);
    one parameter scales all three by it."""
    shutil.copy(REAL / "leaf.s", tmp_path / "leaf.s")
    path = _model(tmp_path, "F ~l(1, 2, 3) f ~l(2)", "surface: l leaf.s 1 8 4\n")
    tree = lsys3d.generate(path)
    lengths = np.linalg.norm(tree.organs.transforms[:, :3, :3], axis=1)  # left, up, heading
    first, second = lengths / lengths[:, :1]
    assert np.allclose(first, [1, 3, 2]) and np.allclose(second, [1, 1, 1])
    assert np.allclose(lengths[1, 0] / lengths[0, 0], 2.0)


def test_a_surface_that_moves_cpfg_turtle_is_named_where_it_matters(tmp_path, caplog):
    """leaf.s's END POINT (0, 0, 0) is not its CONTACT POINT (0.02, -1.66, 0): cpfg moves the turtle there after
    ~l (patches.c determine_end_point), lsys3d does not.  Last in its branch (TexturedSurfaces) that changes
    nothing; followed by a module of the branch, a warning (--strict: an error) names it."""
    shutil.copy(REAL / "leaf.s", tmp_path / "leaf.s")
    quiet = lsys3d.Grammar.from_file(_model(tmp_path, "F [~l(1)] F", "surface: l leaf.s 1 8 4\n"))
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        draw(quiet, 0, 0)
    assert not caplog.records, caplog.text
    moved = lsys3d.Grammar.from_file(_model(tmp_path, "F ~l(1) F", "surface: l leaf.s 1 8 4\n"))
    with pytest.raises(GrammarError) as info:
        draw(moved, 0, 0, lsys3d.GenerateOptions.from_flat(strict=True))
    assert "end point of the surface after '~l'" in str(info.value) and "\n" not in str(info.value)
