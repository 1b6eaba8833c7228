"""Forest writers: a scatter of library assets as instances, in USD or in one ``.glb``.

USD (``.usda``, ``.usdc``, ``.usd``)::

    /Forest                     Xform, kind = assembly, defaultPrim; customData lsys3d provenance
        Trees                   PointInstancer: protoIndices, positions, orientations, scales, extent
            Prototypes          Scope
                tree3d_s0       Xform referencing @../lib/tree3d/tree3d_s0.usdc@ (its /Tree)
                ...

The instancer holds four small arrays per instance; each asset's mesh stays
in its own file, so the forest file is a few bytes per instance whatever the
assets weigh.  The extent is computed from the assets' bounding boxes (no
asset is opened).

glTF (``.glb``)::

    scene "forest"
      node "forest"
        node "tree3d_s0"
          node "bark"  mesh, EXT_mesh_gpu_instancing {TRANSLATION, ROTATION, SCALE}
          node "leaf"  mesh, EXT_mesh_gpu_instancing (the same accessors)
        ...

Each asset's meshes, accessors, materials and their images are copied once
from its own ``.glb`` (identical materials are shared); its instances are
three accessors.
"""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from pxr import Gf, Kind, Sdf, Tf, Usd, UsdGeom, Vt

from ..arrays import unique
from ..errors import ExportError, ForestError
from ..external import FileRefused, load_json, read_file
from ..version import __version__
from .atomic import atomic_path, write_bytes
from .common import ExportOptions, decompose_transforms, file_frame, frame_transforms
from .gltf import INSTANCING, _json_bytes

__all__ = ["FOREST_ROOT", "MAX_ASSET_BYTES", "write_forest_glb", "write_forest_usd"]

MAX_ASSET_BYTES = 1 << 31
"""Largest asset ``.glb`` merged into a ``.glb`` forest (each is held in memory while the forest is built)."""

FOREST_ROOT = "/Forest"
_CHUNK = 1 << 18


def _relative(target: Path, folder: Path) -> str:
    rel = Path(os.path.relpath(target.resolve(), folder.resolve())).as_posix()
    return rel if rel.startswith("../") else f"./{rel}"


def _prototype_names(names: Sequence[str]) -> list[str]:
    out: list[str] = []
    for name in names:
        valid = Tf.MakeValidIdentifier(name)
        base, i = valid, 1
        while valid in out:
            i += 1
            valid = f"{base}_{i}"
        out.append(valid)
    return out


def _corners(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return np.array([[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1], (hi if i & 4 else lo)[2]] for i in range(8)])


def write_forest_usd(
    path: Path,
    prototypes: Sequence[tuple[str, Path, Sequence[float], Sequence[float]]],
    scatter,
    provenance: dict,
    frame_options: ExportOptions,
    options,
) -> Path:
    """Write the forest as a PointInstancer over prototypes that reference the assets' files.

    ``prototypes`` are ``(name, usd file, bbox_min, bbox_max)`` (bounds in
    metres, Y up); ``scatter`` a :class:`lsys3d.library.forest.Scatter` indexing
    them; ``frame_options`` the assets' units and up axis, which the forest
    takes too.
    """
    path = Path(path)
    used = unique(scatter.variant)  # prototypes without instances are left out
    remap = np.full(len(prototypes), -1, np.int64)
    remap[used] = np.arange(len(used))
    frame = file_frame(frame_options)
    transforms = scatter.transforms()
    translation, quaternion, scale = decompose_transforms(frame_transforms(transforms, frame), str(path))

    layer = Sdf.Layer.CreateAnonymous(".usda")  # held here: it outlives the stage (see the references below)
    stage = Usd.Stage.Open(layer)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if frame_options.up_axis == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, frame_options.meters_per_unit)
    root = UsdGeom.Xform.Define(stage, FOREST_ROOT).GetPrim()
    stage.SetDefaultPrim(root)
    Usd.ModelAPI(root).SetKind(Kind.Tokens.assembly)
    root.SetCustomDataByKey(
        "lsys3d", {"generator": f"lsys3d {__version__}", "provenance": json.dumps(provenance, sort_keys=True)}
    )
    instancer = UsdGeom.PointInstancer.Define(stage, f"{FOREST_ROOT}/Trees")
    UsdGeom.Scope.Define(stage, f"{FOREST_ROOT}/Trees/Prototypes")
    names = _prototype_names([prototypes[i][0] for i in used])
    targets = [UsdGeom.Xform.Define(stage, f"{FOREST_ROOT}/Trees/Prototypes/{name}").GetPath() for name in names]
    instancer.CreatePrototypesRel().SetTargets(targets)
    instancer.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(remap[scatter.variant].astype(np.int32)))
    instancer.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(translation.astype(np.float32)))
    # Gf.Quath is stored imaginary-first, so (x, y, z, w) rows are its memory layout
    instancer.CreateOrientationsAttr(Vt.QuathArray.FromNumpy(quaternion.astype(np.float16)))
    instancer.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(scale.astype(np.float32)))

    # extent: each instance's asset box, turned and scaled, in the file's frame
    boxes = np.stack([_corners(p[2], p[3]) for p in prototypes])  # (v, 8, 3)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for at in range(0, len(transforms), _CHUNK):  # in pieces: 8 corners of 10 million instances are 1.9 GB
        t = transforms[at : at + _CHUNK]
        corners = np.einsum("nij,nkj->nki", t[:, :3, :3], boxes[scatter.variant[at : at + _CHUNK]]) + t[:, None, :3, 3]
        corners = corners.reshape(-1, 3) @ frame.T
        lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
    instancer.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))

    # the references go in last, on the layer alone: a stage would open every asset to compose them
    del stage
    for target, i in zip(targets, used.tolist(), strict=True):
        reference = Sdf.Reference(_relative(prototypes[i][1], path.parent))
        layer.GetPrimAtPath(target).referenceList.prependedItems.append(reference)

    with atomic_path(path, options.no_clobber) as tmp:
        try:
            ok = layer.Export(str(tmp))
        except Tf.ErrorException as exc:
            raise ExportError(f"{path}: {str(exc).strip().splitlines()[-1]}") from None
        if not ok:
            raise ExportError(f"{path}: USD could not write the file")
    return path


# ---------------------------------------------------------------- glTF


def _read_glb(path: Path) -> tuple[dict, bytes]:
    try:
        data = read_file(path, MAX_ASSET_BYTES, "asset", "lsys3d.exchange.forest.MAX_ASSET_BYTES")
    except FileRefused as exc:
        raise ForestError(str(exc)) from None
    if len(data) < 20 or data[:4] != b"glTF":
        raise ForestError(f"{path}: not a binary glTF file")
    version, total = struct.unpack_from("<II", data, 4)
    length, kind = struct.unpack_from("<I4s", data, 12)
    if version != 2 or kind != b"JSON" or total > len(data):
        raise ForestError(f"{path}: not a glTF 2.0 binary file")
    try:
        doc = load_json(data[20 : 20 + length])
    except ValueError as exc:
        raise ForestError(f"{path}: bad glTF JSON: {exc}") from None
    binary = b""
    at = 20 + length
    if at + 8 <= total:
        size, kind = struct.unpack_from("<I4s", data, at)
        if kind != b"BIN\0":
            raise ForestError(f"{path}: the second chunk is not BIN")
        binary = data[at + 8 : at + 8 + size]
    return doc, binary


_COPIED = {"asset", "scene", "scenes", "nodes", "meshes", "accessors", "bufferViews", "buffers", "materials"}
_COPIED |= {"extensionsUsed", "extras", "images", "textures", "samplers"}
_TEXTURE_SLOTS = ("normalTexture", "occlusionTexture", "emissiveTexture")
_PBR_TEXTURE_SLOTS = ("baseColorTexture", "metallicRoughnessTexture")


def _retextured(material: dict, textures: int) -> dict:
    """``material`` with its texture indices moved by ``textures`` (the textures merged before its asset's)."""
    if not textures:
        return material
    out = dict(material)
    for slot in _TEXTURE_SLOTS:
        if slot in out:
            out[slot] = {**out[slot], "index": out[slot]["index"] + textures}
    if "pbrMetallicRoughness" in out:
        pbr = out["pbrMetallicRoughness"] = dict(out["pbrMetallicRoughness"])
        for slot in _PBR_TEXTURE_SLOTS:
            if slot in pbr:
                pbr[slot] = {**pbr[slot], "index": pbr[slot]["index"] + textures}
    return out


class _Merged:
    """A glTF document being assembled from several assets' documents, with one binary buffer."""

    def __init__(self):
        self.doc = {"accessors": [], "bufferViews": [], "materials": [], "meshes": [], "nodes": []}
        self.doc.update(images=[], textures=[], samplers=[])
        self.chunks: list[bytes | memoryview] = []
        self.size = 0
        self.material_index: dict[str, int] = {}

    def _append(self, data: bytes | memoryview) -> int:
        pad = -self.size % 4
        if pad:
            self.chunks.append(b"\0" * pad)
            self.size += pad
        offset = self.size
        self.chunks.append(data)
        self.size += len(data)
        return offset

    def add_asset(self, name: str, path: Path) -> list[tuple[str, int]]:
        """Copy an asset's meshes (and what they use); returns its mesh nodes as (name, mesh index)."""
        doc, binary = _read_glb(path)
        extra = sorted(set(doc) - _COPIED)
        if extra or INSTANCING in doc.get("extensionsUsed", []):
            what = extra[0] if extra else f"instanced leaves ({INSTANCING})"
            raise ForestError(
                f"{path}: cannot instance an asset with {what}; write the batch's .glb with merged leaves (the default)"
            )
        if len(doc.get("buffers", [])) > 1 or any("uri" in b for b in doc.get("buffers", [])):
            raise ForestError(f"{path}: the asset's buffer must be its BIN chunk")
        base = self._append(memoryview(binary)) if binary else 0
        views = len(self.doc["bufferViews"])
        for view in doc.get("bufferViews", []):
            self.doc["bufferViews"].append({**view, "buffer": 0, "byteOffset": base + view.get("byteOffset", 0)})
        accessors = len(self.doc["accessors"])
        for acc in doc.get("accessors", []):
            self.doc["accessors"].append({**acc, "bufferView": acc["bufferView"] + views})
        images, samplers = len(self.doc["images"]), len(self.doc["samplers"])
        for image in doc.get("images", []):  # embedded in the asset's buffer (lsys3d writes no image URIs)
            if "bufferView" not in image:
                raise ForestError(f"{path}: an image is not in the asset's buffer")
            self.doc["images"].append({**image, "bufferView": image["bufferView"] + views})
        self.doc["samplers"] += doc.get("samplers", [])
        textures = len(self.doc["textures"])
        for texture in doc.get("textures", []):
            moved = {**texture, "source": texture["source"] + images}
            if "sampler" in texture:
                moved["sampler"] = texture["sampler"] + samplers
            self.doc["textures"].append(moved)
        materials = []
        for m in doc.get("materials", []):
            m = _retextured(m, textures)
            key = json.dumps(m, sort_keys=True)
            if key not in self.material_index:
                self.material_index[key] = len(self.doc["materials"])
                self.doc["materials"].append(m)
            materials.append(self.material_index[key])
        meshes = len(self.doc["meshes"])
        for mesh in doc.get("meshes", []):
            primitives = []
            for prim in mesh["primitives"]:
                p = dict(prim)
                p["attributes"] = {k: v + accessors for k, v in prim["attributes"].items()}
                if "indices" in p:
                    p["indices"] += accessors
                if "material" in p:
                    p["material"] = materials[p["material"]]
                primitives.append(p)
            self.doc["meshes"].append({**mesh, "name": f"{name}_{mesh.get('name', 'mesh')}", "primitives": primitives})
        out = []
        for node in doc.get("nodes", []):
            if any(k in node for k in ("matrix", "translation", "rotation", "scale")):
                raise ForestError(f"{path}: node {node.get('name')!r} has a transform; expected an lsys3d asset")
            if "mesh" in node:
                out.append((node.get("name", "mesh"), node["mesh"] + meshes))
        return out

    def add_instances(self, name: str, meshes: list[tuple[str, int]], translation, quaternion, scale) -> int:
        """A node ``name`` whose children draw ``meshes`` at every instance; returns its index."""
        attributes = {}
        for key, array, width in (("TRANSLATION", translation, "VEC3"), ("ROTATION", quaternion, "VEC4")):
            attributes[key] = self._accessor(array, width)
        attributes["SCALE"] = self._accessor(scale, "VEC3")
        children = []
        for mesh_name, mesh in meshes:
            node = {"mesh": mesh, "name": mesh_name, "extensions": {INSTANCING: {"attributes": attributes}}}
            self.doc["nodes"].append(node)
            children.append(len(self.doc["nodes"]) - 1)
        self.doc["nodes"].append({"name": name, "children": children})
        return len(self.doc["nodes"]) - 1

    def _accessor(self, array: np.ndarray, kind: str) -> int:
        data = np.ascontiguousarray(array, dtype=np.float32)
        offset = self._append(memoryview(data).cast("B"))
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": data.nbytes})
        self.doc["accessors"].append(
            {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": 5126, "count": len(data), "type": kind}
        )
        return len(self.doc["accessors"]) - 1


def write_forest_glb(path: Path, prototypes: Sequence[tuple[str, Path]], scatter, provenance: dict, options) -> Path:
    """Write the forest as one ``.glb``: each asset's meshes once (from its ``.glb``), instanced.

    ``prototypes`` are ``(name, .glb file)``; ``scatter`` a
    :class:`lsys3d.library.forest.Scatter` indexing them.
    """
    path = Path(path)
    merged = _Merged()
    translation, quaternion, scale = decompose_transforms(scatter.transforms(), str(path))
    roots = []
    for i in unique(scatter.variant).tolist():
        name, glb = prototypes[i]
        meshes = merged.add_asset(name, Path(glb))
        if not meshes:
            raise ForestError(f"{glb}: the asset has no mesh")
        mine = scatter.variant == i
        roots.append(merged.add_instances(name, meshes, translation[mine], quaternion[mine], scale[mine]))
    nodes = merged.doc["nodes"]
    nodes.append({"name": "forest", "children": roots})
    doc = {
        "asset": {"version": "2.0", "generator": f"lsys3d {__version__}", "extras": provenance},
        "extensionsUsed": [INSTANCING],
        "scene": 0,
        "scenes": [{"name": "forest", "nodes": [len(nodes) - 1]}],
        **{k: v for k, v in merged.doc.items() if v},
        "buffers": [{"byteLength": merged.size + (-merged.size % 4)}],
    }
    body = _json_bytes(doc)
    body += b" " * (-len(body) % 4)
    pad = -merged.size % 4
    bin_length = merged.size + pad
    total = 12 + 8 + len(body) + 8 + bin_length
    if total >= 2**32:
        raise ExportError(f"{path}: the forest is {total} bytes, over the 4 GiB limit of a .glb")
    head = struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(body), b"JSON")
    chunks = [head, body, struct.pack("<I4s", bin_length, b"BIN\0"), *merged.chunks, b"\0" * pad]
    return write_bytes(path, [memoryview(c) for c in chunks], options.no_clobber)
