"""OpenUSD writer (``.usda``, ``.usdc``, ``.usd``, ``.usdz``) with usd-core's ``pxr``.

The stage (``<asset>`` is the asset's name as an identifier: ``bush``, ``abop_1_24a``)::

    /<asset>                    Xform, kind = component, defaultPrim, assetInfo:name = the grammar's name;
                                customData lsys3d: the metadata block (provenance and counts)
        Geom                    Xform
            bark                Mesh (subdivisionScheme none, faceVarying normals, indexed primvars:st;
                                vertex primvars:displayColor with bark colour variation)
            leaf                PointInstancer of Prototypes/leaf_model  -- or all leaves merged in a Mesh
                Prototypes      Scope
                    leaf_model  Mesh (model space)
            leaf_polygons       Mesh (leaves drawn as polygons; only with instancing)
            skeleton            BasisCurves, linear, widths, purpose guide (only with skeleton_curves)
        Looks                   Scope
            bark, leaf          Material with a UsdPreviewSurface

The parts have the same names as in glTF (``bark``, ``leaf``, ``leaf_polygons``,
``skeleton``), so a DCC shows the same objects whichever format it read.
``upAxis`` and ``metersPerUnit`` follow :class:`~lsys3d.exchange.ExportOptions`;
the geometry is turned and scaled to match, so every DCC sees the tree upright
at its true size.  Siblings (the same grammar grown with several seeds) go into
one stage as the variants of the variant set ``seed`` on the root prim, each
holding the whole layout above (:func:`build_variant_stage`).  Levels of detail
are the variants ``LOD0`` .. ``LOD3`` of the variant set ``lod`` on the root
prim (``LOD0`` selected), each holding the layout above for its level.
Points are numbered in the order faces first use them,
which keeps the crate file's integer compression fast.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from pxr import Gf, Kind, Sdf, Tf, Usd, UsdGeom, UsdShade, Vt

from ..errors import ExportError
from ..materials import Material
from ..tree import Tree
from ..version import __version__
from .atomic import atomic_path
from .common import (
    ExportOptions,
    MeshArrays,
    decompose_transforms,
    file_frame,
    frame_transforms,
    gather_mesh,
    metadata_json,
)

__all__ = [
    "LOD_SET",
    "VARIANT_SET",
    "build_stage",
    "build_variant_stage",
    "write_usd",
    "write_usd_variants",
    "write_usdz",
]

VARIANT_SET = "seed"
"""The variant set of a stage of siblings (:func:`build_variant_stage`)."""

LOD_SET = "lod"
"""The variant set of a tree's levels of detail (``LOD0`` .. ``LOD3``, the first selected); siblings with levels
hold it inside each ``seed`` variant."""


def _extent(points: np.ndarray) -> Vt.Vec3fArray:
    lo, hi = points.min(axis=0), points.max(axis=0)
    return Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))])


def _material(stage: Usd.Stage, looks: str, name: str, m: Material, vertex_colors: bool = False) -> UsdShade.Material:
    material = UsdShade.Material.Define(stage, f"{looks}/{name}")
    shader = UsdShade.Shader.Define(stage, f"{looks}/{name}/PreviewSurface")
    shader.CreateIdAttr("UsdPreviewSurface")
    r, g, b, a = (float(c) for c in m.base_color)
    diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    if vertex_colors:
        # the mesh's displayColor primvar is the colour; the base colour is the fallback where it is missing
        reader = UsdShade.Shader.Define(stage, f"{looks}/{name}/displayColor")
        reader.CreateIdAttr("UsdPrimvarReader_float3")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
        reader.CreateInput("fallback", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(r, g, b))
        diffuse.ConnectToSource(reader.CreateOutput("result", Sdf.ValueTypeNames.Float3))
    else:
        diffuse.Set(Gf.Vec3f(r, g, b))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(m.roughness))
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(m.metallic))
    if a < 1.0:
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(a)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def _mesh(stage: Usd.Stage, path: str, arrays: MeshArrays, material: UsdShade.Material, double_sided: bool):
    mesh = UsdGeom.Mesh.Define(stage, path)
    n_faces = len(arrays.faces)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(arrays.points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(n_faces, 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(arrays.faces.reshape(-1).astype(np.int32, copy=False)))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(arrays.normals))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    if arrays.uv is not None:
        # indexed by the split vertices: each distinct (point, normal, uv) corner's uv once
        st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        st.Set(Vt.Vec2fArray.FromNumpy(arrays.split_uv))
        st.SetIndices(Vt.IntArray.FromNumpy(arrays.split_index.astype(np.int32)))
    if arrays.colors is not None:
        mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex).Set(Vt.Vec3fArray.FromNumpy(arrays.colors))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(_extent(arrays.points))
    if double_sided:
        mesh.CreateDoubleSidedAttr(True)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    return mesh


def _skeleton(stage: Usd.Stage, path: str, tree: Tree, frame: np.ndarray) -> None:
    sk = tree.skeleton
    ch = sk.chains
    if not len(ch):
        return
    points = np.concatenate(sk.polylines()) @ frame.T
    widths = []
    for c in range(len(ch)):
        segs = ch.segments[ch.offsets[c] : ch.offsets[c + 1]]
        widths.append(np.concatenate([sk.width_start[segs[:1]], sk.width_end[segs]]))
    widths = np.concatenate(widths) * float(np.cbrt(np.linalg.det(frame)))
    curves = UsdGeom.BasisCurves.Define(stage, path)
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy((np.diff(ch.offsets) + 1).astype(np.int32)))
    pts = Vt.Vec3fArray.FromNumpy(points.astype(np.float32))
    w = Vt.FloatArray.FromNumpy(widths.astype(np.float32))
    curves.CreatePointsAttr(pts)
    curves.CreateWidthsAttr(w)
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    curves.CreatePurposeAttr(UsdGeom.Tokens.guide)
    curves.CreateExtentAttr(UsdGeom.Curves.ComputeExtent(pts, w))


def _leaf_instancer(stage: Usd.Stage, path: str, tree: Tree, frame: np.ndarray, material, where: str) -> None:
    instancer = UsdGeom.PointInstancer.Define(stage, path)
    UsdGeom.Scope.Define(stage, f"{path}/Prototypes")
    model = gather_mesh(tree.leaves.model, np.eye(3), f"{where}: leaf_model")
    proto = _mesh(stage, f"{path}/Prototypes/leaf_model", model, material, tree.leaf_material.double_sided)
    instancer.CreatePrototypesRel().SetTargets([proto.GetPath()])
    transforms = frame_transforms(tree.leaves.transforms, frame)
    translation, quaternion, scale = decompose_transforms(transforms, where)
    k = len(translation)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(np.zeros(k, np.int32)))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(translation.astype(np.float32)))
    # Gf.Quath is stored imaginary-first, so (x, y, z, w) rows are its memory layout
    instancer.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(quaternion.astype(np.float16)))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(scale.astype(np.float32)))
    extent = instancer.ComputeExtentAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    instancer.CreateExtentAttr(extent)


def _names(materials: list[Material]) -> list[str]:
    """Valid, distinct prim names for the materials."""
    out = []
    for m in materials:
        name = Tf.MakeValidIdentifier(m.name or "material")
        base, i = name, 1
        while name in out:
            i += 1
            name = f"{base}_{i}"
        out.append(name)
    return out


def build_stage(tree: Tree, options: ExportOptions, where: str = "<stage>") -> Usd.Stage:
    """Build the tree's stage in memory (see the module docstring for its layout)."""
    stage, prim = _new_stage(options, tree.identifier)
    _author_levels(stage, prim, tree, options, where)
    return stage


def _author_levels(stage: Usd.Stage, prim: Usd.Prim, tree: Tree, options: ExportOptions, where: str) -> None:
    """The tree, or with levels of detail each level as a variant ``LOD<k>`` of the variant set ``lod``."""
    if not tree.lods:
        _author_tree(stage, prim, tree, options, where)
        return
    levels = prim.GetVariantSets().AddVariantSet(LOD_SET)
    names = [f"LOD{lod.level}" for lod in tree.lods]
    for i, name in enumerate(names):
        levels.AddVariant(name)
        levels.SetVariantSelection(name)
        with levels.GetVariantEditContext():
            _author_tree(stage, prim, tree.at_level(i), options, f"{where}: {name}")
    levels.SetVariantSelection(names[0])


def build_variant_stage(
    trees: Sequence[Tree], names: Sequence[str], options: ExportOptions, where: str = "<stage>"
) -> Usd.Stage:
    """One stage whose root prim holds every tree as a variant of the variant set ``seed``.

    Variant ``names[i]`` holds all that :func:`build_stage` authors under the
    root for ``trees[i]`` (parts, materials, metadata); the selection is the
    first variant.  The root prim is named after the first tree.  A layout
    artist switches siblings in place.
    """
    if not trees or len(trees) != len(names):
        raise ExportError(f"{where}: variants need one name per tree, and at least one tree")
    bad = [n for n in names if not Tf.IsValidIdentifier(n)]
    if bad or len(set(names)) != len(names):
        raise ExportError(f"{where}: variant names must be distinct identifiers, not {list(names)!r}")
    stage, prim = _new_stage(options, trees[0].identifier)
    variants = prim.GetVariantSets().AddVariantSet(VARIANT_SET)
    for name, tree in zip(names, trees, strict=True):
        variants.AddVariant(name)
        variants.SetVariantSelection(name)
        with variants.GetVariantEditContext():
            _author_levels(stage, prim, tree, options, f"{where}: variant {name}")
    variants.SetVariantSelection(names[0])
    return stage


def _new_stage(options: ExportOptions, name: str) -> tuple[Usd.Stage, Usd.Prim]:
    """An in-memory stage with its axis, units and the root component ``/<name>`` (the default prim)."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if options.up_axis == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, options.meters_per_unit)
    root = UsdGeom.Xform.Define(stage, f"/{name}")
    prim = root.GetPrim()
    stage.SetDefaultPrim(prim)
    Usd.ModelAPI(prim).SetKind(Kind.Tokens.component)
    return stage, prim


def _author_tree(stage: Usd.Stage, prim: Usd.Prim, tree: Tree, options: ExportOptions, where: str) -> None:
    """Author the tree under the root prim at the stage's edit target: metadata, parts, materials."""
    frame = file_frame(options)
    root = prim.GetPath().pathString
    geom, looks = f"{root}/Geom", f"{root}/Looks"
    metadata = metadata_json(tree, where)
    Usd.ModelAPI(prim).SetAssetName(tree.name)
    prim.SetCustomDataByKey(
        "lsys3d", {"generator": f"lsys3d {__version__}", "provenance": json.dumps(metadata, sort_keys=True)}
    )
    UsdGeom.Xform.Define(stage, geom)
    UsdGeom.Scope.Define(stage, looks)
    bark_name, leaf_name = _names([tree.bark_material, tree.leaf_material])
    if len(tree.bark.faces):  # a tree of polygon leaves alone has no bark
        bark = gather_mesh(tree.bark, frame, f"{where}: bark")
        bark_material = _material(stage, looks, bark_name, tree.bark_material, vertex_colors=bark.colors is not None)
        _mesh(stage, f"{geom}/bark", bark, bark_material, tree.bark_material.double_sided)

    leaves = tree.leaves
    instanced = options.instance_leaves is not False and leaves.instanced
    has_polygons = leaves.polygons is not None and len(leaves.polygons.faces) > 0
    # the merged leaves hold the polygons too; a tree with polygons alone may leave them out
    merged = leaves.merged if leaves.merged is not None else leaves.polygons
    has_merged = merged is not None and len(merged.faces) > 0
    if instanced or has_merged:
        leaf_material = _material(stage, looks, leaf_name, tree.leaf_material)
        double = tree.leaf_material.double_sided
        if instanced:
            _leaf_instancer(stage, f"{geom}/leaf", tree, frame, leaf_material, where)
            if has_polygons:
                polygons = gather_mesh(leaves.polygons, frame, f"{where}: polygon_leaves")
                _mesh(stage, f"{geom}/leaf_polygons", polygons, leaf_material, double)
        else:
            arrays = gather_mesh(merged, frame, f"{where}: leaves")
            _mesh(stage, f"{geom}/leaf", arrays, leaf_material, double)

    if options.skeleton_curves:
        _skeleton(stage, f"{geom}/skeleton", tree, frame)


def _export_layer(layer: Sdf.Layer, tmp: Path, path: Path) -> None:
    try:
        ok = layer.Export(str(tmp))
    except Tf.ErrorException as exc:
        raise ExportError(f"{path}: {str(exc).strip().splitlines()[-1]}") from None
    if not ok:
        raise ExportError(f"{path}: USD could not write the file")


def write_usd(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as ``.usda`` (text), ``.usdc`` (crate) or ``.usd`` (crate)."""
    return _write_layer(build_stage(tree, options, str(path)), path, options)


def write_usd_variants(trees: Sequence[Tree], names: Sequence[str], path: Path, options: ExportOptions) -> Path:
    """Write the trees as the variants of one stage (:func:`build_variant_stage`), any USD suffix."""
    stage = build_variant_stage(trees, names, options, str(path))
    if path.suffix.lower() == ".usdz":
        return _write_package(stage, path, options)
    return _write_layer(stage, path, options)


def _write_layer(stage: Usd.Stage, path: Path, options: ExportOptions) -> Path:
    with atomic_path(path, options.no_clobber) as tmp:
        _export_layer(stage.GetRootLayer(), tmp, path)
    return path


def write_usdz(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as a ``.usdz`` package holding one ``.usdc`` layer (no external files)."""
    return _write_package(build_stage(tree, options, str(path)), path, options)


def _write_package(stage: Usd.Stage, path: Path, options: ExportOptions) -> Path:
    inner = f"{Tf.MakeValidIdentifier(path.stem)}.usdc"
    with atomic_path(path, options.no_clobber) as tmp, tempfile.TemporaryDirectory(prefix="lsys3d-") as folder:
        layer_path = Path(folder) / inner
        _export_layer(stage.GetRootLayer(), layer_path, path)
        # the zip entry's date is the file's modification time, in local time: pin it to the
        # earliest date a zip can hold so the package's bytes depend on nothing but the tree
        stamp = time.mktime((1980, 1, 1, 0, 0, 0, 0, 0, -1))
        os.utime(layer_path, (stamp, stamp))
        try:
            writer = Sdf.ZipFileWriter.CreateNew(str(tmp))
            writer.AddFile(str(layer_path), inner)
            writer.Save()
        except Tf.ErrorException as exc:
            raise ExportError(f"{path}: {str(exc).strip().splitlines()[-1]}") from None
    return path
