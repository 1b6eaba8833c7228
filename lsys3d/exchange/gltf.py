"""glTF 2.0 writer (``.glb`` and ``.gltf`` + ``.bin``), with numpy and struct only.

Layout of the file::

    scene 0 "<asset name>" (extras: the lsys3d metadata: provenance and counts)
      node "<asset name>"
        node "bark"      mesh "bark"      material "bark"
        node "leaf"      mesh "leaf"      material "leaf"   (all leaves merged; or the leaf model
                                                             with EXT_mesh_gpu_instancing)
        node "leaf_polygons"                                (only with instanced leaves)
        node "skeleton"  mesh "skeleton"  LINES             (only with skeleton_curves)

With levels of detail the root node is ``<asset name>_LOD0`` with the
extension ``MSFT_lod`` naming the nodes ``<asset name>_LOD1`` ... (outside the
scene), each holding its level's ``bark`` and ``leaf`` (see :func:`build`).

glTF is metres and Y up by definition, so ``units`` and ``up_axis`` other
than the defaults are refused.  Vertices are split per unique (position,
normal, uv) corner as glTF requires; texture ``v`` is flipped (glTF's origin
is the top-left corner of the image).  A bark with vertex colours gets a
``COLOR_0`` attribute and a white base colour factor (glTF multiplies the two).
"""

from __future__ import annotations

import json
import struct
from dataclasses import replace
from pathlib import Path
from urllib.parse import quote

import numpy as np

from ..errors import ExportError
from ..materials import Material
from ..tree import Tree
from ..version import __version__
from .atomic import atomic_path, check_target, write_bytes, write_chunks
from .common import ExportOptions, MeshArrays, decompose_transforms, gather_mesh, metadata_json, tangents

__all__ = ["write_glb", "write_gltf"]

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
TRIANGLES, LINES = 4, 1
INSTANCING = "EXT_mesh_gpu_instancing"
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


class _Buffer:
    """Collects bufferViews and accessors; the binary chunks are kept as a list, never joined."""

    def __init__(self):
        self.chunks: list[memoryview] = []
        self.size = 0
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def _view(self, data: np.ndarray, target: int | None) -> int:
        pad = -self.size % 4
        if pad:
            self.chunks.append(memoryview(b"\0" * pad))
            self.size += pad
        raw = memoryview(np.ascontiguousarray(data)).cast("B")
        view = {"buffer": 0, "byteOffset": self.size, "byteLength": raw.nbytes}
        if target is not None:
            view["target"] = target
        self.chunks.append(raw)
        self.size += raw.nbytes
        self.views.append(view)
        return len(self.views) - 1

    def accessor(self, data: np.ndarray, target: int | None = ARRAY_BUFFER, bounds: bool = False) -> int:
        """Add ``data`` ((n,) or (n, c), float32 / uint16 / uint32) as a tightly packed view and accessor."""
        data = np.ascontiguousarray(data)
        if data.dtype == np.float32:
            component = FLOAT
        elif data.dtype == np.uint16:
            component = UNSIGNED_SHORT
        elif data.dtype == np.uint32:
            component = UNSIGNED_INT
        else:  # pragma: no cover - internal misuse
            raise TypeError(data.dtype)
        width = 1 if data.ndim == 1 else data.shape[1]
        acc = {
            "bufferView": self._view(data, target),
            "componentType": component,
            "count": int(data.shape[0]),
            "type": _TYPES[width],
        }
        if bounds:
            two_d = data.reshape(len(data), width)
            acc["min"] = two_d.min(axis=0).tolist()
            acc["max"] = two_d.max(axis=0).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def padded_chunks(self) -> list[memoryview]:
        pad = -self.size % 4
        return self.chunks + ([memoryview(b"\0" * pad)] if pad else [])


def _indices(index: np.ndarray, n_vertices: int) -> np.ndarray:
    # 65535 is the primitive-restart value of UNSIGNED_SHORT, so it may not be used as an index
    return index.astype(np.uint16 if n_vertices < 0xFFFF else np.uint32, copy=False)


def _primitive(buf: _Buffer, arrays: MeshArrays, material: int) -> dict:
    attributes = {
        "POSITION": buf.accessor(arrays.split_points, bounds=True),
        "NORMAL": buf.accessor(arrays.split_normals),
    }
    if arrays.split_uv is not None:
        uv = arrays.split_uv.copy()
        uv[:, 1] = np.float32(1.0) - uv[:, 1]
        attributes["TANGENT"] = buf.accessor(
            tangents(arrays.split_points, arrays.split_index, arrays.split_normals, uv)
        )
        attributes["TEXCOORD_0"] = buf.accessor(uv)
    if arrays.split_colors is not None:  # multiplies the base colour factor, which is white then
        attributes["COLOR_0"] = buf.accessor(arrays.split_colors)
    index = _indices(arrays.split_index, len(arrays.split_points))
    return {
        "attributes": attributes,
        "indices": buf.accessor(index, ELEMENT_ARRAY_BUFFER),
        "material": material,
        "mode": TRIANGLES,
    }


def _material(m: Material) -> dict:
    out = {
        "name": m.name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [float(c) for c in m.base_color],
            "metallicFactor": float(m.metallic),
            "roughnessFactor": float(m.roughness),
        },
    }
    if m.base_color[3] < 1.0:
        out["alphaMode"] = "BLEND"
    if m.double_sided:
        out["doubleSided"] = True
    return out


def _skeleton_lines(tree: Tree) -> tuple[np.ndarray, np.ndarray] | None:
    lines = tree.skeleton.polylines() if len(tree.skeleton) else []
    if not lines:
        return None
    points = np.concatenate(lines).astype(np.float32)
    sizes = np.array([len(p) for p in lines])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    # segment i of a chain joins point i and i + 1; no segment across chains
    first = np.concatenate([np.arange(s, s + n - 1) for s, n in zip(starts.tolist(), sizes.tolist(), strict=True)])
    pairs = np.stack([first, first + 1], axis=1).reshape(-1)
    return points, pairs


LOD = "MSFT_lod"
SCREEN_COVERAGE = (0.4, 0.15, 0.05, 0.01)
"""``MSFT_screencoverage`` hint per level of detail: level ``k`` is drawn while the tree covers more than
this share of the screen (and less than the level before's)."""


def build(tree: Tree, options: ExportOptions, where: str) -> tuple[dict, _Buffer]:
    """Gather ``tree`` into a glTF JSON document and its binary buffer (not yet serialised).

    A tree with levels of detail gets one node per level, ``<name>_LOD0`` ..
    ``<name>_LOD<n>`` (the name convention Unity's and Unreal's importers
    group), each holding that level's parts; the scene holds ``_LOD0``, which
    lists the others with ``MSFT_lod`` and their switching hints in
    ``extras.MSFT_screencoverage``.  A viewer that does not know the
    extension shows level 0 alone.
    """
    if options.units != "m" or options.up_axis != "Y":
        raise ExportError(
            f"{where}: glTF is always metres and Y up; units={options.units!r} and "
            f"up_axis={options.up_axis!r} apply to USD (.usda/.usdc/.usdz) only"
        )
    buf = _Buffer()
    meshes, nodes, materials = [], [], []
    extensions_used = []
    material_cache: dict = {}

    def material_index(m: Material) -> int:
        if m not in material_cache:
            materials.append(_material(m))
            material_cache[m] = len(materials) - 1
        return material_cache[m]

    if tree.lods:
        roots = []
        for i, lod in enumerate(tree.lods):
            nodes.append({"name": f"{tree.name}_LOD{lod.level}", "children": []})
            roots.append(len(nodes) - 1)
            part = tree.at_level(i)
            _add_parts(part, roots[-1], buf, meshes, nodes, material_index, extensions_used, options, where)
        if len(roots) > 1:
            nodes[roots[0]]["extensions"] = {LOD: {"ids": roots[1:]}}
            nodes[roots[0]]["extras"] = {"MSFT_screencoverage": [SCREEN_COVERAGE[lod.level] for lod in tree.lods]}
            extensions_used.append(LOD)
    else:
        nodes.append({"name": tree.name, "children": []})
        _add_parts(tree, 0, buf, meshes, nodes, material_index, extensions_used, options, where)

    metadata = metadata_json(tree, where)
    doc = {"asset": {"version": "2.0", "generator": f"lsys3d {__version__}"}}
    if metadata:
        doc["asset"]["extras"] = metadata
    if extensions_used:
        doc["extensionsUsed"] = sorted(set(extensions_used))
    scene = {"name": tree.name, "nodes": [0]}
    if metadata:
        scene["extras"] = metadata
    doc.update(scene=0, scenes=[scene], nodes=nodes)
    # glTF arrays may not be empty: leave out what a tree without geometry lacks
    for key, value in (("meshes", meshes), ("materials", materials), ("accessors", buf.accessors)):
        if value:
            doc[key] = value
    if buf.views:
        doc.update(bufferViews=buf.views, buffers=[{"byteLength": buf.size + (-buf.size % 4)}])
    return doc, buf


def _add_parts(tree: Tree, parent: int, buf, meshes, nodes, material_index, extensions_used, options, where) -> None:
    """The tree's bark, leaves and skeleton as child nodes of node ``parent``."""
    eye = np.eye(3)

    def add_node(name: str, primitives: list[dict], extensions: dict | None = None):
        meshes.append({"name": name, "primitives": primitives})
        node = {"name": name, "mesh": len(meshes) - 1}
        if extensions:
            node["extensions"] = extensions
        nodes.append(node)
        nodes[parent]["children"].append(len(nodes) - 1)

    if len(tree.bark.faces):  # a tree of polygon leaves alone has no bark
        bark = gather_mesh(tree.bark, eye, f"{where}: bark")
        material = tree.bark_material
        if bark.split_colors is not None:  # COLOR_0 is the colour; glTF multiplies it by the factor
            material = replace(material, base_color=(1.0, 1.0, 1.0, material.base_color[3]))
        add_node("bark", [_primitive(buf, bark, material_index(material))])

    leaves = tree.leaves
    instanced = bool(options.instance_leaves) and leaves.instanced
    if instanced:
        leaf_mat = material_index(tree.leaf_material)
        model = gather_mesh(leaves.model, eye, f"{where}: leaf_model")
        translation, quaternion, scale = decompose_transforms(leaves.transforms, where)
        attributes = {
            "TRANSLATION": buf.accessor(translation.astype(np.float32), target=None),
            "ROTATION": buf.accessor(quaternion.astype(np.float32), target=None),
            "SCALE": buf.accessor(scale.astype(np.float32), target=None),
        }
        add_node("leaf", [_primitive(buf, model, leaf_mat)], {INSTANCING: {"attributes": attributes}})
        extensions_used.append(INSTANCING)
        if leaves.polygons is not None and len(leaves.polygons.faces):
            polygons = gather_mesh(leaves.polygons, eye, f"{where}: polygon_leaves")
            add_node("leaf_polygons", [_primitive(buf, polygons, leaf_mat)])
    else:
        # the merged leaves hold the polygons too; a tree with polygons alone may leave them out
        merged = leaves.merged if leaves.merged is not None else leaves.polygons
        if merged is not None and len(merged.faces):
            arrays = gather_mesh(merged, eye, f"{where}: leaves")
            add_node("leaf", [_primitive(buf, arrays, material_index(tree.leaf_material))])

    if options.skeleton_curves:
        lines = _skeleton_lines(tree)
        if lines is not None:
            points, pairs = lines
            primitive = {
                "attributes": {"POSITION": buf.accessor(points, bounds=True)},
                "indices": buf.accessor(_indices(pairs, len(points)), ELEMENT_ARRAY_BUFFER),
                "mode": LINES,
            }
            add_node("skeleton", [primitive])


def _json_bytes(doc: dict, indent: int | None = None) -> bytes:
    separators = (",", ":") if indent is None else (",", ": ")
    return json.dumps(doc, indent=indent, separators=separators, ensure_ascii=False, allow_nan=False).encode("utf-8")


def write_glb(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as one binary glTF file."""
    doc, buf = build(tree, options, str(path))
    body = _json_bytes(doc)
    body += b" " * (-len(body) % 4)
    chunks = buf.padded_chunks()
    bin_length = sum(c.nbytes for c in chunks)
    total = 12 + 8 + len(body) + (8 + bin_length if "buffers" in doc else 0)
    if total >= 2**32:
        raise ExportError(f"{path}: the asset is {total} bytes, over the 4 GiB limit of a .glb (write .gltf)")
    head = struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(body), b"JSON")
    out = [memoryview(head), memoryview(body)]
    if "buffers" in doc:
        out += [memoryview(struct.pack("<I4s", bin_length, b"BIN\0")), *chunks]
    return write_bytes(path, out, options.no_clobber)


def write_gltf(tree: Tree, path: Path, options: ExportOptions) -> Path:
    """Write ``tree`` as ``path`` (JSON) plus ``path.with_suffix('.bin')`` (the buffer)."""
    bin_path = path.with_suffix(".bin")
    check_target(path, options.no_clobber)
    check_target(bin_path, options.no_clobber)
    doc, buf = build(tree, options, str(path))
    if "buffers" not in doc:  # nothing to store: no .bin
        return write_bytes(path, [memoryview(_json_bytes(doc, indent=1) + b"\n")], options.no_clobber)
    doc["buffers"][0]["uri"] = quote(bin_path.name)
    # both files are complete before either is renamed into place; the buffer goes first
    with atomic_path(path, options.no_clobber) as tmp_json:
        write_chunks(tmp_json, [memoryview(_json_bytes(doc, indent=1) + b"\n")], path)
        with atomic_path(bin_path, options.no_clobber) as tmp_bin:
            write_chunks(tmp_bin, buf.padded_chunks(), bin_path)
    return path
