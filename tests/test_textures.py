"""Textures: images checked as data, named by [materials], embedded in glTF, beside or inside USD files."""

from __future__ import annotations

import io
import os
import struct
import threading
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
import validators
from gltf_files import accessor, node, read_glb
from pxr import Sdf, Usd, UsdGeom, UsdShade

import lsys3d
from lsys3d import images
from lsys3d.errors import AssetError, ExportError
from lsys3d.exchange import ExportOptions, export
from lsys3d.exchange.common import gather_mesh, split_tangents
from lsys3d.images import PNG_SIGNATURE, check_image, png_bytes, read_image
from lsys3d.mesh.mesh import Mesh

DATA = Path(__file__).parent / "data"


def chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png(width: int, height: int, raw: bytes, color: int = 6, depth: int = 8, interlace: int = 0, extra=b"") -> bytes:
    head = struct.pack(">IIBBBBB", width, height, depth, color, 0, 0, interlace)
    return PNG_SIGNATURE + chunk(b"IHDR", head) + extra + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def leaf_pixels(h: int = 32, w: int = 16) -> np.ndarray:
    """A leaf silhouette: green inside, transparent outside."""
    y, x = np.mgrid[0:h, 0:w]
    inside = np.abs(x - (w - 1) / 2) / (w / 2) < np.sin(np.pi * (y + 0.5) / h) ** 0.8
    out = np.zeros((h, w, 4), np.uint8)
    out[..., :3] = (40, 150, 30)
    out[..., 3] = inside * 255
    return out


def write_textures(folder: Path) -> None:
    rng = np.random.default_rng(0)
    (folder / "tex").mkdir(exist_ok=True)
    (folder / "tex" / "bark.png").write_bytes(png_bytes((rng.random((16, 16, 3)) * 80 + 60).astype(np.uint8)))
    normal = np.zeros((8, 8, 3), np.uint8)
    normal[...] = (128, 128, 255)
    (folder / "tex" / "bark_normal.png").write_bytes(png_bytes(normal))
    (folder / "tex" / "leaf.png").write_bytes(png_bytes(leaf_pixels()))


TEXTURED = """\
name = "textured"
axiom = "!(0.2)F[+'(1)!(0.1)FF~]F~"
angle = 60

[materials]
bark = { texture = "tex/bark.png", normal_texture = "tex/bark_normal.png" }
leaf = { texture = "tex/leaf.png", alpha_cutoff = 0.4, base_color = [1, 1, 1] }
"""


@pytest.fixture(scope="module")
def textured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("grammar")
    write_textures(folder)
    (folder / "textured.toml").write_text(TEXTURED)
    return lsys3d.generate(folder / "textured.toml", sides=6)


# ---------------------------------------------------------------- images


def test_png_and_jpeg_are_read():
    pixels = leaf_pixels()
    assert check_image(png_bytes(pixels)) == ("image/png", 16, 32, True)
    assert check_image(png_bytes(pixels[..., :3])) == ("image/png", 16, 32, False)
    assert check_image(png_bytes(pixels[..., 0])) == ("image/png", 16, 32, False)
    # a palette image with transparency, and 16-bit grey
    palette = chunk(b"PLTE", bytes(range(6))) + chunk(b"tRNS", b"\x00\xff")
    assert check_image(png(4, 2, b"\0\x01\x00\x01\x00" * 2, color=3, extra=palette)) == ("image/png", 4, 2, True)
    assert check_image(png(2, 2, b"\0" + bytes(4) + b"\0" + bytes(4), color=0, depth=16))[1:] == (2, 2, False)
    image = read_image(DATA / "bark.jpg")
    assert (image.mime, image.width, image.height, image.alpha, image.suffix) == ("image/jpeg", 16, 8, False, ".jpg")


def test_interlaced_png():
    """Adam7: seven passes, each its own rows with their own filter bytes."""
    w, h = 5, 3
    raw = b""
    for x0, y0, dx, dy in (
        (0, 0, 8, 8),
        (4, 0, 8, 8),
        (0, 4, 4, 8),
        (2, 0, 4, 4),
        (0, 2, 2, 4),
        (1, 0, 2, 2),
        (0, 1, 1, 2),
    ):
        cols, rows = len(range(x0, w, dx)), len(range(y0, h, dy))
        if cols and rows:
            raw += (b"\x01" + bytes(3 * cols)) * rows
    assert check_image(png(w, h, raw, color=2, interlace=1)) == ("image/png", 5, 3, False)
    with pytest.raises(AssetError, match="cut short"):
        check_image(png(w, h, raw[:-1], color=2, interlace=1))


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d[:40], "PNG: cut short"),
        (lambda d: d[: d.index(b"IEND") - 4], "no end chunk"),
        (lambda d: d[:60] + bytes([d[60] ^ 1]) + d[61:], "checksum does not match"),
        (lambda d: d + b"junk", "data after the end chunk"),
        (lambda d: b"GIF89a" + d[6:], "not a PNG or JPEG image"),
        (lambda d: PNG_SIGNATURE + d[33:], "the first chunk is not the header"),
    ],
)
def test_broken_png(mutate, message):
    with pytest.raises(AssetError, match=message):
        check_image(mutate(png_bytes(leaf_pixels())))


def test_png_pixels_are_checked():
    good = b"\0" + bytes(8)
    assert check_image(png(2, 1, good))[1:3] == (2, 1)
    with pytest.raises(AssetError, match="unknown filter"):
        check_image(png(2, 1, b"\x07" + bytes(8)))
    with pytest.raises(AssetError, match="cut short"):
        check_image(png(2, 2, good))
    with pytest.raises(AssetError, match="more image data"):
        check_image(png(2, 1, good + good))
    with pytest.raises(AssetError, match="does not inflate"):
        head = struct.pack(">IIBBBBB", 2, 1, 8, 6, 0, 0, 0)
        check_image(
            PNG_SIGNATURE + chunk(b"IHDR", head) + chunk(b"IDAT", b"\x78\x9c\xff\xff\xff\xff") + chunk(b"IEND", b"")
        )
    with pytest.raises(AssetError, match="colour type 2 with bit depth 4"):
        check_image(png(1, 1, b"\0\0", color=2, depth=4))
    with pytest.raises(AssetError, match="palette image without a palette"):
        check_image(png(1, 1, b"\0\0", color=3))
    with pytest.raises(AssetError, match=r"larger than 16384 on a side \(lsys3d.images.MAX_IMAGE_SIDE\)"):
        check_image(png(20000, 1, b""))
    with pytest.raises(AssetError, match="at least one pixel"):
        check_image(png(0, 1, b""))


def test_png_bomb_is_bounded():
    """A small file that inflates to a lot is read in bounded pieces, and refused if it inflates to too much."""
    w = h = 2048
    row = b"\0" + bytes(4 * w)
    data = png(w, h, row * (h + 1))  # one row too many: 16 MB of zeros in 16 kB
    assert len(data) < 64_000
    with pytest.raises(AssetError, match="more image data than its size says"):
        check_image(data)


def test_broken_jpeg():
    data = (DATA / "bark.jpg").read_bytes()
    with pytest.raises(AssetError, match="JPEG: cut short"):
        check_image(data[: len(data) // 2])
    sof = data.index(b"\xff\xc0")
    with pytest.raises(AssetError, match="lossless, hierarchical or arithmetic-coded"):
        check_image(data[:sof] + b"\xff\xc3" + data[sof + 2 :])
    with pytest.raises(AssetError, match="no frame header or no scan"):
        check_image(b"\xff\xd8\xff\xd9")


def test_read_file_refuses_what_is_not_a_plain_file(tmp_path, monkeypatch):
    with pytest.raises(AssetError, match="no such texture file"):
        read_image(tmp_path / "nothing.png")
    with pytest.raises(AssetError, match="is a folder"):
        read_image(tmp_path)
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    done = []

    def read():
        try:
            read_image(fifo)
        except AssetError as exc:
            done.append(str(exc))

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    thread.join(10)
    assert done, "reading a pipe blocked"
    assert "not a regular file" in done[0]
    big = tmp_path / "big.png"
    big.write_bytes(png_bytes(leaf_pixels()))
    monkeypatch.setattr(images, "MAX_IMAGE_BYTES", 100)
    with pytest.raises(AssetError, match=r"more than 100 \(lsys3d.images.MAX_IMAGE_BYTES\)"):
        read_image(big)


# ---------------------------------------------------------------- the [materials] table


def test_textures_are_read_relative_to_the_grammar(textured):
    bark, leaf = textured.materials.bark, textured.materials.leaf
    assert bark.texture.name == "bark.png" and bark.normal_texture.name == "bark_normal.png"
    assert leaf.texture.alpha and leaf.alpha_cutoff == 0.4 and leaf.double_sided
    assert leaf.images == (leaf.texture,)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('bark = { texture = "missing.png" }', "materials.bark: texture: .*missing.png: no such texture file"),
        ('bark = { texture = "tex" }', "materials.bark: texture: .*tex: the texture is a folder"),
        ('bark = { texture = "plant.toml" }', "materials.bark: texture: .*plant.toml: not a PNG or JPEG image"),
        ("bark = { texture = 3 }", "materials.bark: texture must be a file name"),
        ('bark = { texture = "" }', "materials.bark: texture must be a file name"),
        ("leaf = { alpha_cutoff = 2 }", r"alpha_cutoff must be a number in \[0, 1\], not 2"),
        (
            'leaf = { texture = "tex/bark.png", alpha_cutoff = 0.5 }',
            "alpha_cutoff needs a texture with an alpha channel, and 'bark.png' has none",
        ),
    ],
)
def test_bad_textures_name_their_line(tmp_path, entry, message):
    write_textures(tmp_path)
    grammar = tmp_path / "plant.toml"
    grammar.write_text(f'axiom = "F~"\n\n[materials]\n{entry}\n')
    with pytest.raises(lsys3d.GrammarError, match=message) as info:
        lsys3d.generate(grammar)
    assert info.value.line == 4 and str(info.value).startswith(f"{grammar}:4:1: [materials] ")


def test_cli_reports_a_missing_texture(tmp_path, capsys):
    from lsys3d.cli import main

    grammar = tmp_path / "plant.toml"
    grammar.write_text('axiom = "F"\n[materials]\nbark = { texture = "nope.png" }\n')
    assert main(["generate", str(grammar), "-o", str(tmp_path / "plant.glb"), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "plant.toml:3:1: [materials] materials.bark: texture:" in err
    assert not (tmp_path / "plant.glb").exists()


# ---------------------------------------------------------------- glTF


def test_gltf_embeds_the_images(textured, tmp_path):
    path = export(textured, tmp_path / "textured.glb")
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc, binary = read_glb(path)
    bark_material, leaf_material = textured.materials.bark, textured.materials.leaf
    sources = [bark_material.texture, bark_material.normal_texture, leaf_material.texture]
    assert [i["name"] for i in doc["images"]] == [s.name for s in sources]
    for image, source in zip(doc["images"], sources, strict=True):  # each image once, its bytes as they were
        view = doc["bufferViews"][image["bufferView"]]
        assert image["mimeType"] == "image/png" and "target" not in view
        assert binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]] == source.data
    assert doc["samplers"] == [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    materials = {m["name"]: m for m in doc["materials"]}
    bark, leaf = materials["bark"], materials["leaf"]
    assert doc["textures"][bark["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"] == 0
    assert doc["textures"][bark["normalTexture"]["index"]]["source"] == 1
    assert (leaf["alphaMode"], leaf["alphaCutoff"], leaf["doubleSided"]) == ("MASK", 0.4, True)
    # tangents where a normal map needs them: unit length, perpendicular to the normals, w = +-1
    bark_mesh = doc["meshes"][node(doc, "bark")["mesh"]]["primitives"][0]["attributes"]
    tangent = accessor(doc, binary, bark_mesh["TANGENT"])
    normal = accessor(doc, binary, bark_mesh["NORMAL"])
    assert np.allclose(np.linalg.norm(tangent[:, :3], axis=1), 1, atol=1e-5)
    assert np.abs(np.einsum("ij,ij->i", tangent[:, :3], normal)).max() < 1e-4
    assert set(np.unique(tangent[:, 3]).tolist()) <= {-1.0, 1.0}
    leaf_mesh = doc["meshes"][node(doc, "leaf")["mesh"]]["primitives"][0]["attributes"]
    assert "TANGENT" not in leaf_mesh  # no normal map on the leaves


def test_gltf_text_keeps_the_images_in_its_bin(textured, tmp_path):
    path = export(textured, tmp_path / "textured.gltf")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["textured.bin", "textured.gltf"]
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0


def test_tangents_follow_u():
    """A quad in the x-y plane whose u grows along +x and v along +y: tangent +x, w +1; mirrored u: w -1."""
    quad = Mesh.flat([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[quad.faces]
    arrays = gather_mesh(Mesh(quad.vertices, quad.faces, quad.normals, uv), np.eye(3), "quad")
    assert np.allclose(split_tangents(arrays), [[1, 0, 0, 1]] * 4)
    mirrored = uv.copy()
    mirrored[..., 0] = 1 - mirrored[..., 0]
    arrays = gather_mesh(Mesh(quad.vertices, quad.faces, quad.normals, mirrored), np.eye(3), "quad")
    assert np.allclose(split_tangents(arrays), [[-1, 0, 0, -1]] * 4)
    flat = np.zeros_like(uv)  # no uv gradient: some unit vector perpendicular to the normal
    tangents = split_tangents(gather_mesh(Mesh(quad.vertices, quad.faces, quad.normals, flat), np.eye(3), "quad"))
    assert np.allclose(np.linalg.norm(tangents[:, :3], axis=1), 1) and np.allclose(tangents[:, 2], 0)


# ---------------------------------------------------------------- USD


def _inputs(stage, material: str) -> dict:
    surface = UsdShade.Shader(stage.GetPrimAtPath(f"/textured/Looks/{material}/PreviewSurface"))
    out = {}
    for name in ("diffuseColor", "opacity", "normal", "opacityThreshold"):
        i = surface.GetInput(name)
        if not i:
            continue
        source = i.GetConnectedSources()[0]
        out[name] = (source[0].source.GetPath().name, source[0].sourceName) if source else i.Get()
    return out


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_usd_layer_with_textures_beside_it(textured, tmp_path, suffix):
    path = export(textured, tmp_path / f"my tree{suffix}")
    folder = tmp_path / "my_tree_textures"
    assert sorted(p.name for p in folder.iterdir()) == ["bark.png", "bark_normal.png", "leaf.png"]
    assert (folder / "leaf.png").read_bytes() == textured.materials.leaf.texture.data
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    assert _inputs(stage, "bark") == {"diffuseColor": ("baseColorTexture", "rgb"), "normal": ("normalTexture", "rgb")}
    assert _inputs(stage, "leaf") == {
        "diffuseColor": ("baseColorTexture", "rgb"),
        "opacity": ("baseColorTexture", "a"),
        "opacityThreshold": pytest.approx(0.4),
    }
    texture = UsdShade.Shader(stage.GetPrimAtPath("/textured/Looks/bark/baseColorTexture"))
    file = texture.GetInput("file").Get()
    assert file.path == "./my_tree_textures/bark.png" and Path(file.resolvedPath) == folder / "bark.png"
    assert texture.GetInput("sourceColorSpace").Get() == "sRGB" and texture.GetInput("wrapS").Get() == "repeat"
    scale = texture.GetInput("scale").Get()
    assert tuple(scale) == pytest.approx(textured.materials.bark.base_color)  # the base colour times the image
    normal = UsdShade.Shader(stage.GetPrimAtPath("/textured/Looks/bark/normalTexture"))
    assert normal.GetInput("sourceColorSpace").Get() == "raw" and tuple(normal.GetInput("bias").Get()) == (
        -1,
        -1,
        -1,
        0,
    )
    reader = UsdShade.Shader(stage.GetPrimAtPath("/textured/Looks/bark/stReader"))
    assert reader.GetInput("varname").Get() == "st"
    bark = UsdGeom.Mesh(stage.GetPrimAtPath("/textured/Geom/bark"))
    assert UsdGeom.PrimvarsAPI(bark).GetPrimvar("st").GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray


def test_usdz_packs_its_images(textured, tmp_path):
    path = export(textured, tmp_path / "textured.usdz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["textured.usdz"]  # nothing beside it
    data = path.read_bytes()
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        names = z.namelist()
        assert names == ["textured.usdc", "textures/bark.png", "textures/bark_normal.png", "textures/leaf.png"]
        assert z.read("textures/leaf.png") == textured.materials.leaf.texture.data
        for info in z.infolist():  # stored, 64-byte aligned (the usdz specification)
            assert info.compress_type == zipfile.ZIP_STORED
            assert (info.header_offset + 30 + len(info.filename) + len(info.extra)) % 64 == 0
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    file = UsdShade.Shader(stage.GetPrimAtPath("/textured/Looks/leaf/baseColorTexture")).GetInput("file").Get()
    assert file.path == "textures/leaf.png" and "textured.usdz[textures/leaf.png]" in file.resolvedPath
    assert export(textured, path).read_bytes() == data  # the same bytes again


def test_usd_no_clobber_refuses_an_existing_texture_and_writes_nothing(textured, tmp_path):
    folder = tmp_path / "tree_textures"
    folder.mkdir()
    (folder / "leaf.png").write_bytes(b"mine")
    with pytest.raises(ExportError, match=r"leaf\.png: file exists"):
        export(textured, tmp_path / "tree.usda", ExportOptions(no_clobber=True))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tree_textures"]
    assert sorted(p.name for p in folder.iterdir()) == ["leaf.png"] and (folder / "leaf.png").read_bytes() == b"mine"


def test_usd_failed_export_removes_the_folder_it_made(textured, tmp_path, monkeypatch):
    from lsys3d.exchange import usd

    def fail(*args):
        raise ExportError("tree.usdc: no space left on device")

    monkeypatch.setattr(usd, "_export_crate", fail)
    with pytest.raises(ExportError, match="no space left"):
        export(textured, tmp_path / "tree.usdc")
    assert list(tmp_path.iterdir()) == []


def test_without_textures_no_folder(tmp_path):
    export(lsys3d.generate("abop-1.24a", iterations=2), tmp_path / "plain.usda")
    assert [p.name for p in tmp_path.iterdir()] == ["plain.usda"]


# ---------------------------------------------------------------- Blender


@pytest.mark.parametrize("suffix", [".glb", ".usdz", ".usdc"])
def test_blender_connects_the_textures(textured, tmp_path, suffix):
    report = validators.blender_import(export(textured, tmp_path / f"textured{suffix}"))
    materials = {m["name"]: m for m in report["materials"]}
    bark, leaf = materials["bark"]["textures"], materials["leaf"]["textures"]
    assert [t["image"].split(".")[0] for t in bark["Base Color"]] == ["bark"]
    assert bark["Base Color"][0]["size"] == [16, 16] and bark["Base Color"][0]["colorspace"] == "sRGB"
    assert bark["Normal"][0]["colorspace"] == "Non-Color" and bark["Normal"][0]["size"] == [8, 8]
    assert leaf["Base Color"][0]["size"] == [16, 32]
    assert leaf["Alpha"][0]["image"] == leaf["Base Color"][0]["image"]  # the cut-out reads the same image


def test_forest_of_textured_assets(textured, tmp_path):
    """A .glb forest copies each asset's images and textures once; a USD forest's assets find theirs."""
    from lsys3d.exchange.library import LibraryVariant, write_library
    from lsys3d.library.forest import ForestOptions, forest

    plain = lsys3d.generate("abop-1.24a", iterations=2)
    variants = []
    for name, tree in (("textured", textured), ("plain", plain)):
        export(tree, tmp_path / f"{name}.glb")
        export(tree, tmp_path / f"{name}.usdc")
        lo, hi = tree.bark.bounds
        variants.append(LibraryVariant(name, 0, f"{name}.usdc", f"{name}.glb", 1.0, tuple(lo), tuple(hi)))
    library = write_library(tmp_path / "library.usda", variants, ExportOptions())
    options = ForestOptions(area=(30, 30), count=6, seed=1)
    path = forest(library, tmp_path / "forest.glb", options)
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    doc, binary = read_glb(path)
    assert [i["name"] for i in doc["images"]] == ["bark.png", "bark_normal.png", "leaf.png"]
    leaf = next(m for m in doc["materials"] if m["name"] == "leaf" and "baseColorTexture" in m["pbrMetallicRoughness"])
    image = doc["images"][doc["textures"][leaf["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"]]
    view = doc["bufferViews"][image["bufferView"]]
    assert binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]] == textured.materials.leaf.texture.data
    usd = forest(library, tmp_path / "forest.usda", options)
    assert validators.usd_problems(usd) == []
    stage = Usd.Stage.Open(str(usd))
    files = [
        UsdShade.Shader(p).GetInput("file").Get()
        for p in stage.Traverse(Usd.TraverseInstanceProxies())
        if p.GetName() == "baseColorTexture"
    ]
    assert files and all(Path(f.resolvedPath).is_file() for f in files)
