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
            organs              PointInstancer of Prototypes/<kind>...  -- or organ_<kind> Meshes, merged
            skeleton            BasisCurves, linear, widths, purpose guide (only with skeleton_curves)
        Looks                   Scope
            bark, leaf          Material with a UsdPreviewSurface (and UsdUVTextures reading the images in
                                <stem>_textures/ beside the layer, or textures/ inside a .usdz)

The parts have the same names as in glTF (``bark``, ``leaf``, ``leaf_polygons``,
``skeleton``), so a DCC shows the same objects whichever format it read.
``upAxis`` and ``metersPerUnit`` follow :class:`~lsys3d.exchange.ExportOptions`;
the geometry is turned and scaled to match, so every DCC sees the tree upright
at its true size.  Siblings (the same grammar grown with several seeds) go into
one stage as the variants of the variant set ``seed`` on the root prim, each
holding the whole layout above (:func:`build_variant_stage`).  Levels of detail
are the variants ``LOD0`` .. ``LOD3`` of the variant set ``lod`` on the root
prim (``LOD0`` selected), each holding the layout above for its level; a
rigged tree's levels each hold the same ``Rig`` and bind to it.
Points are numbered in the order faces first use them,
which keeps the crate file's integer compression fast.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import struct
import zlib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from pxr import Gf, Kind, Sdf, Tf, Usd, UsdGeom, UsdShade, UsdSkel, Vt

from ..errors import ExportError, os_reason
from ..look.attributes import ATTRIBUTES, branch_table
from ..look.growth import BIRTH
from ..look.materials import Material
from ..look.rig import INFLUENCES
from ..tree import Tree
from ..version import __version__
from .atomic import atomic_path, check_target, scratch_path, write_bytes, write_chunks, write_failure
from .common import (
    POINT_ATTRIBUTES,
    ExportOptions,
    MeshArrays,
    TextureFiles,
    decompose_transforms,
    file_frame,
    frame_transforms,
    gather_mesh,
    material_groups,
    metadata_json,
    scene_meshes,
    to_float32,
)

__all__ = [
    "LOD_SET",
    "VARIANT_SET",
    "build_stage",
    "build_variant_stage",
    "package_options",
    "texture_folder",
    "usdz_chunks",
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


def _texture(stage: Usd.Stage, path: str, st, file: str, color: bool, scale, bias=None) -> UsdShade.Shader:
    """A ``UsdUVTexture`` reading ``file`` at the mesh's ``st``, repeating, ``scale * texel + bias``."""
    texture = UsdShade.Shader.Define(stage, path)
    texture.CreateIdAttr("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(file))
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(st)
    for wrap in ("wrapS", "wrapT"):
        texture.CreateInput(wrap, Sdf.ValueTypeNames.Token).Set("repeat")
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB" if color else "raw")
    texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(*map(float, scale)))
    if bias is not None:
        texture.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(*map(float, bias)))
    return texture


def _material(
    stage: Usd.Stage,
    looks: str,
    name: str,
    m: Material,
    vertex_colors: bool = False,
    textures: TextureFiles | None = None,
) -> UsdShade.Material:
    material = UsdShade.Material.Define(stage, f"{looks}/{name}")
    shader = UsdShade.Shader.Define(stage, f"{looks}/{name}/PreviewSurface")
    shader.CreateIdAttr("UsdPreviewSurface")
    r, g, b, a = (float(c) for c in m.base_color)
    diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    st = None
    if m.images:  # the mesh's uv, read once for every texture of the material
        reader = UsdShade.Shader.Define(stage, f"{looks}/{name}/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        st = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    if m.texture is not None:
        # the image times the base colour, as glTF multiplies baseColorTexture by baseColorFactor
        path = f"{looks}/{name}/baseColorTexture"
        texture = _texture(stage, path, st, textures.path_of(m.texture), True, (r, g, b, a))
        diffuse.ConnectToSource(texture.CreateOutput("rgb", Sdf.ValueTypeNames.Float3))
        if m.alpha_cutoff is not None:
            opacity = shader.CreateInput("opacity", Sdf.ValueTypeNames.Float)
            opacity.ConnectToSource(texture.CreateOutput("a", Sdf.ValueTypeNames.Float))
            shader.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(float(m.alpha_cutoff))
    elif vertex_colors:
        # the mesh's displayColor primvar is the colour; the base colour is the fallback where it is missing
        reader = UsdShade.Shader.Define(stage, f"{looks}/{name}/displayColor")
        reader.CreateIdAttr("UsdPrimvarReader_float3")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
        reader.CreateInput("fallback", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(r, g, b))
        diffuse.ConnectToSource(reader.CreateOutput("result", Sdf.ValueTypeNames.Float3))
    else:
        diffuse.Set(Gf.Vec3f(r, g, b))
    if m.normal_texture is not None:  # a tangent-space map: texel * 2 - 1
        path = f"{looks}/{name}/normalTexture"
        file = textures.path_of(m.normal_texture)
        normal = _texture(stage, path, st, file, False, (2, 2, 2, 1), (-1, -1, -1, 0))
        shader.CreateInput("normal", Sdf.ValueTypeNames.Normal3f).ConnectToSource(
            normal.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        )
    roughness = shader.CreateInput("roughness", Sdf.ValueTypeNames.Float)
    metallic = shader.CreateInput("metallic", Sdf.ValueTypeNames.Float)
    if m.roughness_texture is not None:  # glTF's packing: roughness in G, metallic in B, times the factors
        path = f"{looks}/{name}/metallicRoughnessTexture"
        file = textures.path_of(m.roughness_texture)
        packed = _texture(stage, path, st, file, False, (1, float(m.roughness), float(m.metallic), 1))
        roughness.ConnectToSource(packed.CreateOutput("g", Sdf.ValueTypeNames.Float))
        metallic.ConnectToSource(packed.CreateOutput("b", Sdf.ValueTypeNames.Float))
    else:
        roughness.Set(float(m.roughness))
        metallic.Set(float(m.metallic))
    if a < 1.0 and not (m.texture is not None and m.alpha_cutoff is not None):
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(a)
        if m.alpha_cutoff is not None:
            shader.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(float(m.alpha_cutoff))
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


class _Looks:
    """The stage's materials under ``Looks``, each authored once however many meshes use it (names kept distinct)."""

    def __init__(self, stage: Usd.Stage, path: str, textures: TextureFiles | None = None):
        self.stage, self.path, self.textures = stage, path, textures
        self.made: dict[tuple[Material, bool], UsdShade.Material] = {}
        self.names: set[str] = set()

    def get(self, m: Material, vertex_colors: bool = False) -> UsdShade.Material:
        key = (replace(m, double_sided=False), vertex_colors)  # in USD sidedness belongs to the mesh
        if key not in self.made:
            name = base = Tf.MakeValidIdentifier(m.name or "material")
            i = 1
            while name in self.names:
                i += 1
                name = f"{base}_{i}"
            self.names.add(name)
            self.made[key] = _material(self.stage, self.path, name, m, vertex_colors, self.textures)
        return self.made[key]


def _subsets(mesh: UsdGeom.Mesh, face_material: np.ndarray | None, material_of, looks: _Looks, colors: bool) -> None:
    """One ``GeomSubset`` (family ``materialBind``) per material of the faces, each bound to its material.

    Indices that map to the same material share a subset (named after the smallest); faces of one material
    alone need none (the mesh's own binding).
    """
    groups = material_groups(face_material, material_of)
    if len(groups) == 1 and groups[0][0] == material_of(-1):
        return
    for m, index, faces in groups:
        faces = np.arange(len(face_material)) if faces is None else faces
        subset = UsdGeom.Subset.CreateGeomSubset(
            mesh,
            f"material_{index}",
            UsdGeom.Tokens.face,
            Vt.IntArray.FromNumpy(faces.astype(np.int32)),
            "materialBind",
        )
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(looks.get(m, colors))
    UsdGeom.Subset.SetFamilyType(mesh, "materialBind", UsdGeom.Tokens.partition)


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
    _attribute_primvars(UsdGeom.PrimvarsAPI(mesh), arrays.attributes)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(_extent(arrays.points))
    if double_sided:
        mesh.CreateDoubleSidedAttr(True)
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    return mesh


def _attribute_primvars(primvars: UsdGeom.PrimvarsAPI, values: dict) -> None:
    """The hierarchy and wind attributes, and the birth, as ``vertex`` primvars (one value per point, or per
    instance)."""
    if BIRTH in values:  # lsys3d.look.growth: for shader-driven growth
        birth = Vt.FloatArray.FromNumpy(np.ascontiguousarray(values[BIRTH], np.float32))
        primvars.CreatePrimvar(BIRTH, Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex).Set(birth)
    for a in ATTRIBUTES:
        if a.key not in values:
            continue
        data = np.ascontiguousarray(values[a.key], np.float32)
        if a.width == 3:
            kind, array = Sdf.ValueTypeNames.Point3fArray, Vt.Vec3fArray.FromNumpy(data)
        else:
            kind, array = Sdf.ValueTypeNames.FloatArray, Vt.FloatArray.FromNumpy(data)
        primvars.CreatePrimvar(a.usd, kind, UsdGeom.Tokens.vertex).Set(array)


def _branch_table(prim: Usd.Prim, tree: Tree, frame: np.ndarray) -> None:
    """The per-branch attributes, a row per branch indexed by ``branch_id``: constant primvars ``branches:<key>``."""
    primvars = UsdGeom.PrimvarsAPI(prim)
    table = branch_table(tree.hierarchy)
    for a in ATTRIBUTES:
        if a.key not in table:
            continue
        data = np.asarray(table[a.key], np.float64)
        if a.point:
            data = data @ frame.T
        data = np.ascontiguousarray(data, np.float32)
        if a.width == 3:
            kind, array = Sdf.ValueTypeNames.Point3fArray, Vt.Vec3fArray.FromNumpy(data)
        else:
            kind, array = Sdf.ValueTypeNames.FloatArray, Vt.FloatArray.FromNumpy(data)
        primvars.CreatePrimvar(f"branches:{a.usd}", kind, UsdGeom.Tokens.constant).Set(array)


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
    pts = Vt.Vec3fArray.FromNumpy(to_float32(points, "the skeleton", path))
    w = Vt.FloatArray.FromNumpy(to_float32(widths, "the skeleton's widths", path))
    curves.CreatePointsAttr(pts)
    curves.CreateWidthsAttr(w)
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    curves.CreatePurposeAttr(UsdGeom.Tokens.guide)
    curves.CreateExtentAttr(UsdGeom.Curves.ComputeExtent(pts, w))


def _instancer(
    stage: Usd.Stage, path: str, parts, transforms, index, instance_attributes, frame, looks: _Looks, where: str
) -> None:
    """A ``PointInstancer`` over ``parts``: one prototype per part and material used by its instances.

    ``parts`` are ``(prototype name, model Mesh, the instances of it, material_of)``; ``index`` holds the
    material index of every instance (None: all the default).
    """
    instancer = UsdGeom.PointInstancer.Define(stage, path)
    UsdGeom.Scope.Define(stage, f"{path}/Prototypes")
    proto_index = np.zeros(len(transforms), np.int32)
    prototypes = []
    for name, model_mesh, members, material_of in parts:
        model = gather_mesh(model_mesh, np.eye(3), f"{where}: {name}")
        own = None if index is None else index[members]
        for n, (m, i, rows) in enumerate(material_groups(own, material_of)):
            proto = name if n == 0 else f"{name}_{i}"
            prototypes.append(_mesh(stage, f"{path}/Prototypes/{proto}", model, looks.get(m), m.double_sided).GetPath())
            proto_index[members if rows is None else members[rows]] = len(prototypes) - 1
    instancer.CreatePrototypesRel().SetTargets(prototypes)
    translation, quaternion, scale = decompose_transforms(frame_transforms(transforms, frame), where)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(proto_index))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(to_float32(translation, "instance positions", where)))
    # Gf.Quath is stored imaginary-first, so (x, y, z, w) rows are its memory layout
    instancer.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(quaternion.astype(np.float16)))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(to_float32(scale, "instance sizes", where)))
    per_instance = {
        k: (np.asarray(v, np.float64) @ frame.T).astype(np.float32) if k in POINT_ATTRIBUTES else v
        for k, v in instance_attributes.items()
    }
    _attribute_primvars(UsdGeom.PrimvarsAPI(instancer), per_instance)
    extent = instancer.ComputeExtentAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    instancer.CreateExtentAttr(extent)


def _prim_names(names) -> list[str]:
    """Valid, distinct prim names for ``names`` (``a-b`` -> ``a_b``; a repeat gets ``_2``...)."""
    out: list[str] = []
    for name in names:
        valid = base = Tf.MakeValidIdentifier(name)
        i = 1
        while valid in out:
            i += 1
            valid = f"{base}_{i}"
        out.append(valid)
    return out


def build_stage(
    tree: Tree, options: ExportOptions, where: str = "<stage>", textures: TextureFiles | None = None
) -> Usd.Stage:
    """Build the tree's stage in memory (see the module docstring for its layout).

    ``textures`` says where the materials' images are referenced from
    (default ``./textures/<name>``); afterwards its :meth:`~TextureFiles.files`
    are the images the stage refers to, for the caller to write.
    """
    stage, prim = _new_stage(options, tree.identifier, tree.rig is not None)
    _author_levels(stage, prim, tree, options, where, textures or TextureFiles("./textures/"))
    _author_scene(stage, prim, tree, options, where)
    return stage


def _author_scene(stage: Usd.Stage, prim: Usd.Prim, tree: Tree, options: ExportOptions, where: str) -> None:
    """The scene the plant grew in (``--scene``): ``<root>/scene``, a Mesh prim per scene mesh."""
    meshes = scene_meshes(tree, options, where)
    if not meshes:
        return
    root = f"{prim.GetPath().pathString}/scene"
    UsdGeom.Xform.Define(stage, root)
    looks = _Looks(stage, f"{root}/Looks")
    for name, points, faces, role, look in meshes:
        mesh = UsdGeom.Mesh.Define(stage, f"{root}/{name}")
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.astype(np.float32)))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1).astype(np.int32)))
        mesh.CreateExtentAttr(_extent(points))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        if look.double_sided:
            mesh.CreateDoubleSidedAttr(True)
        if role == "volume":  # the shape the plant was pruned to: a guide, not a solid of the set
            mesh.CreatePurposeAttr(UsdGeom.Tokens.guide)
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(looks.get(look))


def _author_levels(
    stage: Usd.Stage, prim: Usd.Prim, tree: Tree, options: ExportOptions, where: str, textures: TextureFiles
) -> None:
    """The tree, or with levels of detail each level as a variant ``LOD<k>`` of the variant set ``lod``."""
    if not tree.lods:
        _author_tree(stage, prim, tree, options, where, textures)
        return
    levels = prim.GetVariantSets().AddVariantSet(LOD_SET)
    names = [f"LOD{lod.level}" for lod in tree.lods]
    for i, name in enumerate(names):
        levels.AddVariant(name)
        levels.SetVariantSelection(name)
        with levels.GetVariantEditContext():
            _author_tree(stage, prim, tree.at_level(i), options, f"{where}: {name}", textures)
    levels.SetVariantSelection(names[0])


def build_variant_stage(
    trees: Sequence[Tree],
    names: Sequence[str],
    options: ExportOptions,
    where: str = "<stage>",
    textures: TextureFiles | None = None,
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
    stage, prim = _new_stage(options, trees[0].identifier, any(t.rig is not None for t in trees))
    variants = prim.GetVariantSets().AddVariantSet(VARIANT_SET)
    textures = textures or TextureFiles("./textures/")
    for name, tree in zip(names, trees, strict=True):
        variants.AddVariant(name)
        variants.SetVariantSelection(name)
        with variants.GetVariantEditContext():
            _author_levels(stage, prim, tree, options, f"{where}: variant {name}", textures)
    variants.SetVariantSelection(names[0])
    return stage


def _new_stage(options: ExportOptions, name: str, rigged: bool = False) -> tuple[Usd.Stage, Usd.Prim]:
    """An in-memory stage with its axis, units and the root component ``/<name>`` (the default prim).

    A rigged tree's root is a ``SkelRoot``, so its skeleton and skinned meshes are one skeletal asset.
    """
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if options.up_axis == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, options.meters_per_unit)
    root = (UsdSkel.Root if rigged else UsdGeom.Xform).Define(stage, f"/{name}")
    prim = root.GetPrim()
    stage.SetDefaultPrim(prim)
    Usd.ModelAPI(prim).SetKind(Kind.Tokens.component)
    return stage, prim


def _author_tree(
    stage: Usd.Stage, prim: Usd.Prim, tree: Tree, options: ExportOptions, where: str, textures: TextureFiles
) -> None:
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
    shading = _Looks(stage, looks, textures)
    table = tree.materials
    skeleton = _rig(stage, f"{root}/Rig", tree, frame, where) if tree.rig is not None else None
    if len(tree.bark.faces):  # a tree of polygon leaves alone has no bark
        bark = gather_mesh(tree.bark, frame, f"{where}: bark")
        colors = bark.colors is not None
        mesh = _mesh(stage, f"{geom}/bark", bark, shading.get(table.bark, colors), table.bark.double_sided)
        if table:
            _subsets(mesh, tree.bark.face_material, table.for_bark, shading, colors)
        _bind(mesh, bark, skeleton)

    leaves = tree.leaves
    instanced = options.instance_leaves is not False and leaves.instanced and skeleton is None  # skinned: merged
    has_polygons = leaves.polygons is not None and len(leaves.polygons.faces) > 0
    # the merged leaves hold the polygons too; a tree with polygons alone may leave them out
    merged = leaves.merged if leaves.merged is not None else leaves.polygons
    has_merged = merged is not None and len(merged.faces) > 0
    leaf_default = table.for_leaf(-1)
    if instanced:
        k = len(leaves.transforms)
        own = leaves.instance_material if leaves.instance_material is not None else tree.skeleton.leaf_material
        index = np.asarray(own, np.int64) if table else None
        if index is not None and len(index) != k:
            index = None
        parts = [("leaf_model", leaves.model, np.arange(k), table.for_leaf)]
        _instancer(
            stage, f"{geom}/leaf", parts, leaves.transforms, index, leaves.instance_attributes, frame, shading, where
        )
        if has_polygons:
            polygons = gather_mesh(leaves.polygons, frame, f"{where}: polygon_leaves")
            mesh = _mesh(stage, f"{geom}/leaf_polygons", polygons, shading.get(leaf_default), True)
            if table:
                _subsets(mesh, leaves.polygons.face_material, table.for_leaf, shading, False)
    elif has_merged:
        arrays = gather_mesh(merged, frame, f"{where}: leaves")
        mesh = _mesh(stage, f"{geom}/leaf", arrays, shading.get(leaf_default), True)
        if table:
            _subsets(mesh, merged.face_material, table.for_leaf, shading, False)
        _bind(mesh, arrays, skeleton)

    organs = tree.organs
    if len(organs):
        names = _prim_names(p.name for p in organs.prototypes)
        materials = [table.for_leaf if p.material is None else (lambda i, m=p.material: m) for p in organs.prototypes]
        if options.instance_leaves is not False and skeleton is None:  # one instancer, a prototype per kind
            parts = [
                (names[p], proto.mesh, organs.of(p), materials[p])
                for p, proto in enumerate(organs.prototypes)
                if len(organs.of(p))
            ]
            index = organs.material if table else None
            transforms, attributes = organs.transforms, organs.instance_attributes
            _instancer(stage, f"{geom}/organs", parts, transforms, index, attributes, frame, shading, where)
        else:
            for p, mesh_of in enumerate(organs.merged):
                if mesh_of is None or not len(mesh_of.faces):
                    continue
                arrays = gather_mesh(mesh_of, frame, f"{where}: organ_{names[p]}")
                material_of = materials[p]
                mesh = _mesh(stage, f"{geom}/organ_{names[p]}", arrays, shading.get(material_of(-1)), True)
                if table:
                    _subsets(mesh, mesh_of.face_material, material_of, shading, False)
                _bind(mesh, arrays, skeleton)

    if tree.hierarchy is not None and len(tree.hierarchy):
        _branch_table(prim, tree, frame)

    if options.skeleton_curves:
        _skeleton(stage, f"{geom}/skeleton", tree, frame)


def _rig(stage: Usd.Stage, path: str, tree: Tree, frame: np.ndarray, where: str) -> UsdSkel.Skeleton:
    """The tree's joints as a ``Skeleton``: joint paths, bind (world) and rest (local) transforms, in the file frame."""
    rig = tree.rig
    names = []
    for i, name in enumerate(rig.names):  # parents come first, so their paths are known
        up = int(rig.parent[i])
        names.append(name if up < 0 else f"{names[up]}/{name}")
    world = to_float32(rig.position @ frame.T, "joint positions", where).astype(np.float64)
    local = world.copy()
    has = rig.parent >= 0
    local[has] -= world[rig.parent[has]]

    def translations(points):
        return Vt.Matrix4dArray([Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(*map(float, p))) for p in points])

    skeleton = UsdSkel.Skeleton.Define(stage, path)
    skeleton.CreateJointsAttr(Vt.TokenArray(names))
    skeleton.CreateJointNamesAttr(Vt.TokenArray(list(rig.names)))
    skeleton.CreateBindTransformsAttr(translations(world))
    skeleton.CreateRestTransformsAttr(translations(local))
    if tree.animation is not None or tree.growth is not None:
        _wind(stage, f"{path}/Wind", skeleton, names, local, tree.animation, frame, tree.growth)
    return skeleton


def _wind(stage, path: str, skeleton, joints, local: np.ndarray, anim, frame: np.ndarray, growth=None) -> None:
    """The wind and the growth as one ``UsdSkel.Animation`` bound to ``skeleton`` (the one track set a skeleton
    plays): the wind's rotations and the growth's scales sampled at each frame, the wind looping over the growth
    when the growth is longer; time codes are the frames of the wind (or of the growth without wind)."""
    animation = UsdSkel.Animation.Define(stage, path)
    animation.CreateJointsAttr(Vt.TokenArray(joints))
    animation.CreateTranslationsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(local, np.float32)))
    fps = anim.fps if anim is not None else growth.fps
    last = 0.0
    if growth is None:
        animation.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((len(joints), 3), np.float16)))
    else:
        scales = growth.scales()
        attribute = animation.CreateScalesAttr()
        for k, t in enumerate(growth.times.tolist()):
            rows = np.repeat(scales[k][:, None], 3, axis=1).astype(np.float16)
            attribute.Set(Vt.Vec3hArray.FromNumpy(np.ascontiguousarray(rows)), t * fps)
        last = growth.times[-1] * fps
    attribute = animation.CreateRotationsAttr()
    if anim is None:
        identity = np.zeros((len(joints), 4), np.float32)
        identity[:, 3] = 1.0
        attribute.Set(Vt.QuatfArray.FromNumpy(identity))
    else:
        rotation = frame / np.cbrt(np.linalg.det(frame))  # turns the axes of the rotations into the file's frame
        quaternions = anim.rotations.astype(np.float64)
        quaternions[..., :3] = quaternions[..., :3] @ rotation.T
        loop = len(anim) - 1
        total = max(loop, int(np.ceil(last)))
        for code in range(total + 1):  # Gf.Quatf is stored imaginary-first: (x, y, z, w) rows are its memory layout
            k = code % loop if loop and code > loop else min(code, loop)
            attribute.Set(Vt.QuatfArray.FromNumpy(np.ascontiguousarray(quaternions[k], np.float32)), float(code))
        last = max(last, float(total))
    UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets([animation.GetPath()])
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(last)


def _bind(mesh: UsdGeom.Mesh, arrays: MeshArrays, skeleton: UsdSkel.Skeleton | None) -> None:
    """Bind a mesh to the skeleton with its skin (4 joints a point; nothing without a rig or a skin)."""
    if skeleton is None or "skin_joints" not in arrays.attributes:
        return
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    joints = np.ascontiguousarray(arrays.attributes["skin_joints"], np.int32).reshape(-1)
    weights = np.ascontiguousarray(arrays.attributes["skin_weights"], np.float32).reshape(-1)
    binding.CreateJointIndicesPrimvar(False, INFLUENCES).Set(Vt.IntArray.FromNumpy(joints))
    binding.CreateJointWeightsPrimvar(False, INFLUENCES).Set(Vt.FloatArray.FromNumpy(weights))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))


def texture_folder(path: Path) -> Path:
    """Where a ``.usda``/``.usdc``/``.usd`` file's texture images go: the folder ``<stem>_textures`` beside it.

    >>> texture_folder(Path("out/my oak.usdc")).as_posix()
    'out/my_oak_textures'
    """
    return path.with_name(re.sub(r"[^A-Za-z0-9_.-]", "_", path.stem) + "_textures")


def _textures_for(path: Path) -> TextureFiles:
    """Images beside a layer (``./<stem>_textures/``) or inside a package (``textures/``)."""
    if path.suffix.lower() == ".usdz":
        return TextureFiles("textures/")
    return TextureFiles(f"./{texture_folder(path).name}/")


def write_usd(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as ``.usda`` (text), ``.usdc`` or ``.usd`` (crate); its images go in :func:`texture_folder`."""
    textures = _textures_for(path)
    return _write_layer(build_stage(tree, options, str(path), textures), path, options, textures)


def write_usd_variants(trees: Sequence[Tree], names: Sequence[str], path: Path, options: ExportOptions) -> Path:
    """Write the trees as the variants of one stage (:func:`build_variant_stage`), any USD suffix."""
    textures = _textures_for(path)
    if path.suffix.lower() == ".usdz":
        options = package_options(options)
        return _write_package(build_variant_stage(trees, names, options, str(path), textures), path, options, textures)
    return _write_layer(build_variant_stage(trees, names, options, str(path), textures), path, options, textures)


def package_options(options: ExportOptions) -> ExportOptions:
    """The options of a ``.usdz``: leaves and organs merged into meshes unless ``instance_leaves`` says otherwise.

    A ``.usdz`` is what AR Quick Look and RealityKit open, and ARKit's profile
    of USD has no ``PointInstancer`` (usd-core's ``ComplianceChecker(arkit=True)``:
    "unsupported type 'PointInstancer'"); the merged leaves draw the same.
    ``instance_leaves=True`` still writes instancers, for a ``.usdz`` not meant for AR.
    """
    return options.replace(instance_leaves=False) if options.instance_leaves is None else options


def write_usdz(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as a ``.usdz`` package holding one ``.usdc`` layer and its images (no external files);
    leaves and organs merged, as ARKit's profile wants (:func:`package_options`)."""
    textures = _textures_for(path)
    options = package_options(options)
    return _write_package(build_stage(tree, options, str(path), textures), path, options, textures)


def _write_layer(stage: Usd.Stage, path: Path, options: ExportOptions, textures: TextureFiles) -> Path:
    """Write the layer, and its images into :func:`texture_folder`: every file complete before any is renamed."""
    images = textures.files()
    folder = texture_folder(path)
    made_folder = False
    if images:
        check_target(path, options.no_clobber)  # the layer's folder first: a missing one is named as such
        try:
            folder.mkdir()
            made_folder = True
        except FileExistsError:
            pass
        except OSError as exc:
            raise ExportError(f"{path}: cannot make the texture folder {str(folder)!r}: {os_reason(exc)}") from None
    try:
        with contextlib.ExitStack() as stack:
            for name, data in images:
                tmp = stack.enter_context(atomic_path(folder / name, options.no_clobber))
                write_chunks(tmp, [data], folder / name)
            if path.suffix.lower() == ".usda":  # text: built in memory, written by lsys3d (every OS error checked)
                tmp = stack.enter_context(atomic_path(path, options.no_clobber))
                write_chunks(tmp, [stage.GetRootLayer().ExportToString().encode("utf-8")], path)
            else:
                tmp = stack.enter_context(atomic_path(path, options.no_clobber))
                _export_crate(stage, tmp, path)
    except BaseException:
        if made_folder:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when it is empty: nothing of ours is in it
        raise
    return path


def _write_package(stage: Usd.Stage, path: Path, options: ExportOptions, textures: TextureFiles) -> Path:
    """A ``.usdz``: USD writes the crate beside the target, lsys3d packs it (:func:`usdz_chunks`) with the
    images and writes that."""
    check_target(path, options.no_clobber)
    inner = f"{Tf.MakeValidIdentifier(path.stem)}.usdc"
    with scratch_path(path, ".usdc") as crate:
        _export_crate(stage, crate, path)
        data = crate.read_bytes()
    files = [(inner, data)] + [(f"{textures.prefix}{name}", image) for name, image in textures.files()]
    return write_bytes(path, usdz_chunks(files, str(path)), options.no_clobber)


def _export_crate(stage: Usd.Stage, tmp: Path, path: Path) -> None:
    """Let USD write the stage's crate file at ``tmp`` and check that it is whole.

    USD writes with its own I/O and does not report the operating system's reason: on a full disk or past
    ``ulimit -f`` it fails with an internal message, or (inside a package) not at all.  So the file is checked
    (the crate's table of contents must lie inside it), and on failure the file system is asked why
    (:func:`~lsys3d.exchange.atomic.write_failure`).
    """
    layer = stage.GetRootLayer()
    try:
        ok = layer.Export(str(tmp))
        usd_message = "USD could not write the file"
    except Tf.ErrorException as exc:
        ok = False
        usd_message = f"USD could not write the file: {str(exc).strip().splitlines()[-1].strip()}"
    if ok and _whole_crate(tmp):
        return
    reason = write_failure(tmp, max(_size_of(tmp) + (1 << 20), _authored_bytes(stage)))
    raise ExportError(f"{path}: {reason or usd_message}")


def _size_of(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


def _whole_crate(path: Path) -> bool:
    """Is ``path`` a crate file whose table of contents lies inside it (not cut short by a full disk)?"""
    try:
        with path.open("rb") as f:
            head = f.read(24)
            size = os.fstat(f.fileno()).st_size
    except OSError:
        return False
    if len(head) < 24 or head[:8] != b"PXR-USDC":
        return False
    (toc,) = struct.unpack_from("<q", head, 16)
    return toc >= 24 and toc + 8 <= size


def _authored_bytes(stage: Usd.Stage) -> int:
    """About how many bytes the stage's arrays take: what a crate file of it needs on disk."""
    total = 0
    for prim in stage.TraverseAll():
        for attr in prim.GetAttributes():
            value = attr.Get()
            if hasattr(value, "__len__") and not isinstance(value, str):
                with contextlib.suppress(TypeError, ValueError):
                    total += np.asarray(value).nbytes
    return total


# ---------------------------------------------------------------- usdz packaging
_ZIP_DATE_1980_01_01 = (0 << 9) | (1 << 5) | 1  # DOS date: the earliest a zip can hold, so bytes never vary
_PADDING_ID = 0x1986  # the extra field USD's own zip writer pads with


def usdz_chunks(files: Sequence[tuple[str, bytes]], where: str = "usdz") -> list[memoryview]:
    """A ``.usdz`` package of ``files`` (name, data), the first one its default layer, as chunks of bytes.

    The layout of the USDZ specification, the one USD's own writer produces: a zip archive whose entries are
    stored (not compressed), each entry's data starting on a multiple of 64 bytes (padded with an extra
    field in the local header), every date 1980-01-01 00:00.  Built in memory so that writing it is one
    checked, atomic write like any other file.

    >>> chunks = usdz_chunks([("tree.usdc", b"PXR-USDC" + bytes(16))])
    >>> import io, zipfile
    >>> data = b"".join(chunks)
    >>> zipfile.ZipFile(io.BytesIO(data)).read("tree.usdc")[:8], data.index(b"PXR-USDC") % 64
    (b'PXR-USDC', 0)
    """
    local: list[memoryview] = []
    central: list[bytes] = []
    offset = 0
    for name, data in files:
        raw_name = name.encode("utf-8")
        pad = -(offset + 30 + len(raw_name)) % 64
        if 0 < pad < 4:  # an extra field is at least its 4-byte header
            pad += 64
        extra = struct.pack("<HH", _PADDING_ID, pad - 4) + bytes(pad - 4) if pad else b""
        crc = zlib.crc32(data)
        size = len(data)
        if offset + 30 + len(raw_name) + len(extra) + size >= 1 << 32:
            raise ExportError(f"{where}: the package would be over the 4 GiB a .usdz (zip without zip64) can hold")
        fields = (0, 0, 0, _ZIP_DATE_1980_01_01, crc, size, size, len(raw_name), len(extra))
        header = struct.pack("<IHHHHHIIIHH", 0x04034B50, 10, *fields) + raw_name + extra
        central.append(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 0, 10, *fields, 0, 0, 0, 0, offset))
        central[-1] += raw_name + extra
        local += [memoryview(header), memoryview(data)]
        offset += len(header) + size
    directory = b"".join(central)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(files), len(files), len(directory), offset, 0)
    return [*local, memoryview(directory + end)]
