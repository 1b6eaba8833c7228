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
holding the whole layout above (:func:`build_variant_stage`).  Points are numbered in the order faces first use them,
which keeps the crate file's integer compression fast.
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
import zlib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from pxr import Gf, Kind, Sdf, Tf, Usd, UsdGeom, UsdShade, UsdSkel, Vt

from ..attributes import ATTRIBUTES, branch_table
from ..errors import ExportError
from ..materials import Material
from ..rig import INFLUENCES
from ..tree import Tree
from ..version import __version__
from .atomic import atomic_path, check_target, scratch_path, write_bytes, write_failure
from .common import (
    POINT_ATTRIBUTES,
    ExportOptions,
    MeshArrays,
    decompose_transforms,
    file_frame,
    frame_transforms,
    gather_mesh,
    metadata_json,
    to_float32,
)

__all__ = [
    "VARIANT_SET",
    "build_stage",
    "build_variant_stage",
    "usdz_chunks",
    "write_usd",
    "write_usd_variants",
    "write_usdz",
]

VARIANT_SET = "seed"
"""The variant set of a stage of siblings (:func:`build_variant_stage`)."""


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


class _Looks:
    """The stage's materials under ``Looks``, each authored once however many meshes use it (names kept distinct)."""

    def __init__(self, stage: Usd.Stage, path: str):
        self.stage, self.path = stage, path
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
            self.made[key] = _material(self.stage, self.path, name, m, vertex_colors)
        return self.made[key]


def _subsets(mesh: UsdGeom.Mesh, face_material: np.ndarray | None, material_of, looks: _Looks, colors: bool) -> None:
    """One ``GeomSubset`` (family ``materialBind``) per material index of the faces, each bound to its material."""
    if face_material is None:
        return
    indices = np.unique(face_material)
    if len(indices) < 2 and material_of(int(indices[0])) == material_of(-1):
        return  # one material, the mesh's own
    for index in indices.tolist():
        faces = np.flatnonzero(face_material == index).astype(np.int32)
        subset = UsdGeom.Subset.CreateGeomSubset(
            mesh, f"material_{index}", UsdGeom.Tokens.face, Vt.IntArray.FromNumpy(faces), "materialBind"
        )
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(looks.get(material_of(index), colors))
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
    """The hierarchy and wind attributes as ``vertex`` primvars (one value per point, or per instance)."""
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


def _leaf_instancer(stage: Usd.Stage, path: str, tree: Tree, frame: np.ndarray, looks: _Looks, where: str) -> None:
    """Leaves as a ``PointInstancer``: one prototype of the leaf model per leaf material used."""
    instancer = UsdGeom.PointInstancer.Define(stage, path)
    UsdGeom.Scope.Define(stage, f"{path}/Prototypes")
    model = gather_mesh(tree.leaves.model, np.eye(3), f"{where}: leaf_model")
    k = len(tree.leaves.transforms)
    index = np.asarray(tree.skeleton.leaf_material, np.int64) if tree.materials else np.zeros(0, np.int64)
    if len(index) != k:
        index = np.zeros(k, np.int64)
    used, proto_index = np.unique(index, return_inverse=True)
    prototypes = []
    for n, i in enumerate(used.tolist()):
        m = tree.materials.for_leaf(i)
        name = "leaf_model" if n == 0 else f"leaf_model_{i}"
        prototypes.append(_mesh(stage, f"{path}/Prototypes/{name}", model, looks.get(m), m.double_sided).GetPath())
    instancer.CreatePrototypesRel().SetTargets(prototypes)
    transforms = frame_transforms(tree.leaves.transforms, frame)
    translation, quaternion, scale = decompose_transforms(transforms, where)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(proto_index.reshape(-1).astype(np.int32)))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(to_float32(translation, "leaf positions", where)))
    # Gf.Quath is stored imaginary-first, so (x, y, z, w) rows are its memory layout
    instancer.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(quaternion.astype(np.float16)))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(to_float32(scale, "leaf sizes", where)))
    per_instance = {
        k: (np.asarray(v, np.float64) @ frame.T).astype(np.float32) if k in POINT_ATTRIBUTES else v
        for k, v in tree.leaves.instance_attributes.items()
    }
    _attribute_primvars(UsdGeom.PrimvarsAPI(instancer), per_instance)
    extent = instancer.ComputeExtentAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())
    instancer.CreateExtentAttr(extent)


def build_stage(tree: Tree, options: ExportOptions, where: str = "<stage>") -> Usd.Stage:
    """Build the tree's stage in memory (see the module docstring for its layout)."""
    stage, prim = _new_stage(options, tree.identifier, tree.rig is not None)
    _author_tree(stage, prim, tree, options, where)
    return stage


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
    stage, prim = _new_stage(options, trees[0].identifier, any(t.rig is not None for t in trees))
    variants = prim.GetVariantSets().AddVariantSet(VARIANT_SET)
    for name, tree in zip(names, trees, strict=True):
        variants.AddVariant(name)
        variants.SetVariantSelection(name)
        with variants.GetVariantEditContext():
            _author_tree(stage, prim, tree, options, f"{where}: variant {name}")
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
    shading = _Looks(stage, looks)
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
        _leaf_instancer(stage, f"{geom}/leaf", tree, frame, shading, where)
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
    return skeleton


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


def write_usd(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as ``.usda`` (text), ``.usdc`` (crate) or ``.usd`` (crate)."""
    return _write_layer(build_stage(tree, options, str(path)), path, options)


def write_usd_variants(trees: Sequence[Tree], names: Sequence[str], path: Path, options: ExportOptions) -> Path:
    """Write the trees as the variants of one stage (:func:`build_variant_stage`), any USD suffix."""
    stage = build_variant_stage(trees, names, options, str(path))
    if path.suffix.lower() == ".usdz":
        return _write_package(stage, path, options)
    return _write_layer(stage, path, options)


def write_usdz(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as a ``.usdz`` package holding one ``.usdc`` layer (no external files)."""
    return _write_package(build_stage(tree, options, str(path)), path, options)


def _write_layer(stage: Usd.Stage, path: Path, options: ExportOptions) -> Path:
    if path.suffix.lower() == ".usda":  # text: built in memory, written by lsys3d (every OS error checked)
        return write_bytes(path, [stage.GetRootLayer().ExportToString().encode("utf-8")], options.no_clobber)
    with atomic_path(path, options.no_clobber) as tmp:
        _export_crate(stage, tmp, path)
    return path


def _write_package(stage: Usd.Stage, path: Path, options: ExportOptions) -> Path:
    """A ``.usdz``: USD writes the crate beside the target, lsys3d packs it (:func:`usdz_chunks`) and writes that."""
    check_target(path, options.no_clobber)
    inner = f"{Tf.MakeValidIdentifier(path.stem)}.usdc"
    with scratch_path(path, ".usdc") as crate:
        _export_crate(stage, crate, path)
        data = crate.read_bytes()
    return write_bytes(path, usdz_chunks([(inner, data)], str(path)), options.no_clobber)


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
