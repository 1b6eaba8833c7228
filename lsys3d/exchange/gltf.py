"""glTF 2.0 writer (``.glb`` and ``.gltf`` + ``.bin``), with numpy and struct only.

Layout of the file::

    scene 0 "<asset name>" (extras: the lsys3d metadata: provenance and counts)
      node "<asset name>"
        node "bark"      mesh "bark"      material "bark"
        node "leaf"      mesh "leaf"      material "leaf"   (all leaves merged; or the leaf model
                                                             with EXT_mesh_gpu_instancing)
        node "leaf_polygons"                                (only with instanced leaves)
        node "organ_<name>"                                 (organs of one kind: merged, or instanced)
        node "skeleton"  mesh "skeleton"  LINES             (only with skeleton_curves)

With levels of detail the root node is ``<asset name>_LOD0`` with the
extension ``MSFT_lod`` naming the nodes ``<asset name>_LOD1`` ... (outside the
scene), each holding its level's ``bark`` and ``leaf`` (see :func:`build`).
A rigged tree's levels are each one skinned node ``<asset name>_LOD<k>`` (a
mesh with a primitive per part, all bound to the one rig; glTF ignores a
skinned mesh's parents, so they cannot sit under a level's node); level 0's is
a scene root with ``MSFT_lod``, and the node ``<asset name>`` holds the joints.

glTF is metres and Y up by definition, so ``units`` and ``up_axis`` other
than the defaults are refused.  Vertices are split per unique (position,
normal, uv) corner as glTF requires; texture ``v`` is flipped (glTF's origin
is the top-left corner of the image).  A bark with vertex colours gets a
``COLOR_0`` attribute and a white base colour factor (glTF multiplies the two).
A material's images (:attr:`lsys3d.look.materials.Material.images`) are embedded in
the binary buffer (``images[].bufferView``; in the ``.bin`` of a ``.gltf``),
each once, sampled with repeat and mipmaps; ``alpha_cutoff`` is
``alphaMode: MASK``.
"""

from __future__ import annotations

import json
import struct
from dataclasses import replace
from pathlib import Path
from urllib.parse import quote

import numpy as np

from ..errors import ExportError
from ..images import Image
from ..look.attributes import branch_table, gltf_attributes
from ..look.growth import BIRTH
from ..look.materials import Material
from ..lsystem.ages import FUNCTION_NAMES
from ..tree import Tree
from ..version import __version__
from .atomic import atomic_path, check_target, write_bytes, write_chunks
from .common import (
    ExportOptions,
    MeshArrays,
    decompose_transforms,
    gather_mesh,
    material_groups,
    metadata_json,
    scene_meshes,
    split_tangents,
    to_float32,
)

__all__ = ["check_options", "write_glb", "write_gltf"]

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
TRIANGLES, LINES = 4, 1
INSTANCING = "EXT_mesh_gpu_instancing"
_TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}
UNSIGNED_BYTE = 5121
LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT = 9729, 9987, 10497
_EYE = np.eye(3)  # the glTF frame is the tree's
SAMPLER = {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR, "wrapS": REPEAT, "wrapT": REPEAT}
"""The one sampler of every texture: bark uv run past 1 (along a branch, in metres), so they repeat."""


class _Buffer:
    """Collects bufferViews and accessors; the binary chunks are kept as a list, never joined."""

    def __init__(self):
        self.chunks: list[memoryview] = []
        self.size = 0
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def image(self, data: bytes) -> int:
        """A bufferView holding an image file's bytes (``images[].bufferView``)."""
        return self._view(np.frombuffer(data, np.uint8), None)

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

    def accessor(
        self, data: np.ndarray, target: int | None = ARRAY_BUFFER, bounds: bool = False, normalized: bool = False
    ) -> int:
        """Add ``data`` ((n,) or (n, c), float32 / uint8 / uint16 / uint32) as a tightly packed view and accessor."""
        data = np.ascontiguousarray(data)
        if data.dtype == np.float32:
            component = FLOAT
        elif data.dtype == np.uint8:
            component = UNSIGNED_BYTE
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
        if normalized:
            acc["normalized"] = True
        if bounds:
            low, high = _bounds(data.reshape(len(data), width))
            acc["min"], acc["max"] = low.tolist(), high.tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def packed(self, arrays: list[np.ndarray], bounds: bool = False) -> list[int]:
        """Accessors of float32 ``arrays`` of one width, all in one buffer view (animation keys: few rows each)."""
        if not arrays:
            return []
        view = self._view(np.concatenate([a.reshape(-1) for a in arrays]), None)
        out, offset = [], 0
        for a in arrays:
            width = 1 if a.ndim == 1 else a.shape[1]
            acc = {"bufferView": view, "componentType": FLOAT, "count": int(a.shape[0]), "type": _TYPES[width]}
            if offset:
                acc["byteOffset"] = offset
            if bounds:
                low, high = _bounds(a.reshape(len(a), width))
                acc["min"], acc["max"] = low.tolist(), high.tolist()
            self.accessors.append(acc)
            out.append(len(self.accessors) - 1)
            offset += a.nbytes
        return out

    def padded_chunks(self) -> list[memoryview]:
        pad = -self.size % 4
        return self.chunks + ([memoryview(b"\0" * pad)] if pad else [])


def _bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each column's least and greatest value, as ``rows.min(axis=0)`` and ``rows.max(axis=0)`` give them.

    Column by column (numpy's reduction over an axis of three columns is slow: 0.5 s for a 4.6
    million-vertex bark; a column's own reduction takes a twentieth of that, as fast as a compiled pass).
    """
    columns = range(rows.shape[1])
    low = np.array([rows[:, c].min() for c in columns], rows.dtype)
    high = np.array([rows[:, c].max() for c in columns], rows.dtype)
    return low, high


def _indices(index: np.ndarray, n_vertices: int) -> np.ndarray:
    # 65535 is the primitive-restart value of UNSIGNED_SHORT, so it may not be used as an index
    return index.astype(np.uint16 if n_vertices < 0xFFFF else np.uint32, copy=False)


def quantized_weights(weights: np.ndarray) -> np.ndarray:
    """Skin weights as normalized unsigned bytes whose every row sums to exactly 255 (largest remainders round up).

    >>> quantized_weights(np.array([[0.5, 0.5, 0, 0], [1 / 3, 1 / 3, 1 / 3, 0]], np.float32)).tolist()
    [[128, 127, 0, 0], [85, 85, 85, 0]]
    """
    scaled = np.asarray(weights, np.float64) * 255.0
    q = np.floor(scaled).astype(np.int64)
    short = 255 - q.sum(axis=1)
    rank = np.argsort(-(scaled - q), axis=1, kind="stable")
    bump = np.arange(weights.shape[1])[None, :] < short[:, None]
    np.add.at(q, (np.repeat(np.arange(len(q)), weights.shape[1])[bump.ravel()], rank[bump]), 1)
    return q.astype(np.uint8)


def _vertex_attributes(buf: _Buffer, arrays: MeshArrays, joints: int | None = None, tangents: bool = False) -> dict:
    """The accessors of a gathered mesh's split vertices, shared by all its primitives."""
    attributes = {
        "POSITION": buf.accessor(arrays.split_points, bounds=True),
        "NORMAL": buf.accessor(arrays.split_normals),
    }
    if tangents:  # a normal map needs them; generated at run time they may differ between viewers
        attributes["TANGENT"] = buf.accessor(split_tangents(arrays))
    if arrays.split_uv is not None:
        uv = arrays.split_uv.copy()
        uv[:, 1] = np.float32(1.0) - uv[:, 1]
        attributes["TEXCOORD_0"] = buf.accessor(uv)
    if arrays.split_colors is not None:  # multiplies the base colour factor, which is white then
        attributes["COLOR_0"] = buf.accessor(arrays.split_colors)
    for name, values in gltf_attributes(arrays.split_attributes).items():  # hierarchy and wind
        attributes[name] = buf.accessor(values)
    if BIRTH in arrays.split_attributes:  # the birth (lsys3d.look.growth), for shader-driven growth
        attributes["_BIRTH"] = buf.accessor(np.ascontiguousarray(arrays.split_attributes[BIRTH], np.float32))
    if joints is not None and "skin_joints" in arrays.split_attributes:
        weights = quantized_weights(arrays.split_attributes["skin_weights"])
        # a weight that rounds to 0 names joint 0, as glTF asks (ACCESSOR_JOINTS_USED_ZERO_WEIGHT otherwise)
        ids = np.where(weights > 0, arrays.split_attributes["skin_joints"], 0)
        attributes["JOINTS_0"] = buf.accessor(ids.astype(np.uint8 if joints <= 256 else np.uint16))
        attributes["WEIGHTS_0"] = buf.accessor(weights, normalized=True)
    return attributes


def _mesh_primitives(
    buf: _Buffer, arrays: MeshArrays, groups, joints: int | None = None, tangents: bool = False
) -> list[dict]:
    """One primitive per ``(material index, faces)`` group (faces None: all), sharing the vertex accessors."""
    attributes = _vertex_attributes(buf, arrays, joints, tangents)
    index = _indices(arrays.split_index, len(arrays.split_points)).reshape(-1, 3)
    return [
        {
            "attributes": attributes,
            "indices": buf.accessor((index if faces is None else index[faces]).reshape(-1), ELEMENT_ARRAY_BUFFER),
            "material": material,
            "mode": TRIANGLES,
        }
        for material, faces in groups
    ]


def _material(m: Material, texture_index) -> dict:
    """A glTF material; ``texture_index(image)`` gives the texture of each of its images."""
    pbr = {
        "baseColorFactor": [float(c) for c in m.base_color],
        "metallicFactor": float(m.metallic),
        "roughnessFactor": float(m.roughness),
    }
    if m.texture is not None:
        pbr["baseColorTexture"] = {"index": texture_index(m.texture)}
    if m.roughness_texture is not None:  # roughness in G, metallic in B, times the factors
        pbr["metallicRoughnessTexture"] = {"index": texture_index(m.roughness_texture)}
    out = {"name": m.name, "pbrMetallicRoughness": pbr}
    if m.normal_texture is not None:
        out["normalTexture"] = {"index": texture_index(m.normal_texture)}
    if m.alpha_cutoff is not None:
        out["alphaMode"] = "MASK"
        out["alphaCutoff"] = float(m.alpha_cutoff)
    elif m.base_color[3] < 1.0:
        out["alphaMode"] = "BLEND"
    if m.double_sided:
        out["doubleSided"] = True
    return out


def _skeleton_lines(tree: Tree) -> tuple[np.ndarray, np.ndarray] | None:
    lines = tree.skeleton.polylines() if len(tree.skeleton) else []
    if not lines:
        return None
    points = to_float32(np.concatenate(lines), "the skeleton", "skeleton")
    sizes = np.array([len(p) for p in lines])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    # segment i of a chain joins point i and i + 1; no segment across chains
    first = np.concatenate([np.arange(s, s + n - 1) for s, n in zip(starts.tolist(), sizes.tolist(), strict=True)])
    pairs = np.stack([first, first + 1], axis=1).reshape(-1)
    return points, pairs


def check_options(options: ExportOptions, where: str) -> None:
    """Refuse options glTF cannot honour: it is always metres and Y up."""
    if options.units != "m" or options.up_axis != "Y":
        raise ExportError(
            f"{where}: glTF is always metres and Y up; units={options.units!r} and "
            f"up_axis={options.up_axis!r} apply to USD (.usda/.usdc/.usdz) only"
        )


LOD = "MSFT_lod"
SCREEN_COVERAGE = (0.4, 0.15, 0.05, 0.01)
"""``MSFT_screencoverage`` hint per level of detail: level ``k`` is drawn while the tree covers more than
this share of the screen (and less than the level before's)."""


class _Gather:
    """The glTF objects gathered from one tree, each kind by its own ``gather_*`` method (Blender's glTF-IO
    gathers its objects first, then writes), in the order they reach the buffer: the bytes depend on it."""

    def __init__(self, tree: Tree, options: ExportOptions, where: str):
        self.tree, self.options, self.where = tree, options, where
        self.buf = _Buffer()
        self.meshes: list[dict] = []
        self.nodes: list[dict] = []
        self.materials: list[dict] = []
        self.images: list[dict] = []
        self.textures: list[dict] = []
        self.skins: list[dict] = []
        self.animations: list[dict] = []
        self.extensions_used: list[str] = []
        self.rig = tree.rig
        self.joints = len(self.rig) if self.rig is not None else None
        self.table = tree.materials
        self.roots = [0]  # scene roots: the asset's node, and skinned meshes (glTF ignores a skinned mesh's parents)
        self.asset = 0  # the node the parts go under: the asset's, or the level's
        self.level_parts: list[dict] | None = None  # a rigged level's skinned primitives, gathered into one node
        self.joint_base = 0  # the node of the first joint
        self._made: dict[Material, int] = {}
        self._texture_of: dict[Image, int] = {}

    # textures and images
    def gather_texture(self, image: Image) -> int:
        """The texture of an image, embedding the image once."""
        if image not in self._texture_of:
            self.images.append({"name": image.name, "bufferView": self.buf.image(image.data), "mimeType": image.mime})
            self.textures.append({"sampler": 0, "source": len(self.images) - 1})
            self._texture_of[image] = len(self.textures) - 1
        return self._texture_of[image]

    # materials
    def gather_material(self, m: Material) -> int:
        """The glTF material of ``m``, made once."""
        if m not in self._made:
            self.materials.append(_material(m, self.gather_texture))
            self._made[m] = len(self.materials) - 1
        return self._made[m]

    def material_groups(self, face_material, material_of, white: bool = False) -> list[tuple[int, np.ndarray | None]]:
        """(glTF material, faces) of each material index the faces use; one group of all faces without a table."""

        def index_of(m: Material) -> int:  # vertex colours: the colour is COLOR_0, glTF multiplies it by the factor
            return self.gather_material(replace(m, base_color=(1.0, 1.0, 1.0, m.base_color[3])) if white else m)

        index = face_material if self.table else None
        return [(index_of(m), faces) for m, _, faces in material_groups(index, material_of)]

    # meshes and their primitives
    def gather_primitives(self, arrays, groups, joints=None) -> list[dict]:
        """The primitives of one mesh, with tangents when a material has a normal map."""
        tangents = any("normalTexture" in self.materials[material] for material, _ in groups)
        return _mesh_primitives(self.buf, arrays, groups, joints, tangents)

    def gather_mesh_node(self, name: str, primitives: list[dict], extensions: dict | None = None, skinned=False):
        """A mesh of ``primitives`` and its node, under the asset's (or the level's) node; a skinned one in the
        scene (or, in a rigged level, among the level's parts)."""
        if self.level_parts is not None and skinned:  # the rest (the skeleton curves) go under the asset's node
            self.level_parts.extend(primitives)
            return
        self.meshes.append({"name": name, "primitives": primitives})
        node = {"name": name, "mesh": len(self.meshes) - 1}
        if extensions:
            node["extensions"] = extensions
        self.nodes.append(node)
        if skinned:
            node["skin"] = 0
            self.roots.append(len(self.nodes) - 1)
        else:
            self.nodes[self.asset]["children"].append(len(self.nodes) - 1)

    def gather_instanced(self, base: str, model_mesh, transforms, index, instance_attributes, material_of):
        """One node per material of the instances, each drawing ``model_mesh`` at its instances' transforms."""
        buf, where = self.buf, self.where
        model = gather_mesh(model_mesh, _EYE, f"{where}: {base} model")
        translation, quaternion, scale = decompose_transforms(transforms, where)
        extra = gltf_attributes(instance_attributes)  # the branch each instance grows from
        for n, (m, i, rows) in enumerate(material_groups(index, material_of)):
            sel = slice(None) if rows is None else rows
            attributes = {
                "TRANSLATION": buf.accessor(to_float32(translation[sel], f"{base} positions", where), target=None),
                "ROTATION": buf.accessor(quaternion[sel].astype(np.float32), target=None),
                "SCALE": buf.accessor(to_float32(scale[sel], f"{base} sizes", where), target=None),
            }
            for name, values in extra.items():
                attributes[name] = buf.accessor(np.ascontiguousarray(values[sel]), target=None)
            if BIRTH in instance_attributes:
                birth = np.asarray(instance_attributes[BIRTH], np.float32)[sel]
                attributes["_BIRTH"] = buf.accessor(np.ascontiguousarray(birth), target=None)
            primitives = self.gather_primitives(model, [(self.gather_material(m), None)])
            self.gather_mesh_node(
                base if n == 0 else f"{base}_{i}", primitives, {INSTANCING: {"attributes": attributes}}
            )
        if INSTANCING not in self.extensions_used:
            self.extensions_used.append(INSTANCING)

    def gather_merged(self, name: str, mesh, material_of) -> None:
        """One mesh node of ``mesh`` (None or empty: none), its faces grouped by material."""
        if mesh is None or not len(mesh.faces):
            return
        arrays = gather_mesh(mesh, _EYE, f"{self.where}: {name}")
        skinned = self.rig is not None and "skin_joints" in mesh.attributes
        groups = self.material_groups(mesh.face_material, material_of)
        self.gather_mesh_node(
            name, self.gather_primitives(arrays, groups, self.joints if skinned else None), skinned=skinned
        )

    def gather_parts(self, part: Tree, first: bool) -> None:
        """The meshes of ``part``: bark, leaves, organs (and for the first level the skeleton curves)."""
        table, rig = self.table, self.rig
        if len(part.bark.faces):  # a tree of polygon leaves alone has no bark
            bark = gather_mesh(part.bark, _EYE, f"{self.where}: bark")
            bark_groups = self.material_groups(
                part.bark.face_material, table.for_bark, white=bark.split_colors is not None
            )
            self.gather_mesh_node(
                "bark", self.gather_primitives(bark, bark_groups, self.joints), skinned=rig is not None
            )
        leaves = part.leaves
        instanced = bool(self.options.instance_leaves) and rig is None  # skinned leaves and organs are merged
        if instanced and leaves.instanced:
            k = len(leaves.transforms)
            own = leaves.instance_material if leaves.instance_material is not None else part.skeleton.leaf_material
            per_leaf = np.asarray(own, np.int64) if table else np.zeros(0, np.int64)
            if len(per_leaf) != k:
                per_leaf = np.zeros(k, np.int64)
            self.gather_instanced(
                "leaf", leaves.model, leaves.transforms, per_leaf, leaves.instance_attributes, table.for_leaf
            )
            if leaves.polygons is not None and len(leaves.polygons.faces):
                self.gather_merged("leaf_polygons", leaves.polygons, table.for_leaf)
        else:
            # the merged leaves hold the polygons too; a tree with polygons alone may leave them out
            self.gather_merged("leaf", leaves.merged if leaves.merged is not None else leaves.polygons, table.for_leaf)

        organs = part.organs
        for p, proto in enumerate(organs.prototypes):  # a part per kind of organ: organ_sphere, organ_flower...
            material_of = table.for_leaf if proto.material is None else (lambda i, m=proto.material: m)
            if instanced:
                mine = organs.of(p)
                if len(mine):
                    attributes = {key: a[mine] for key, a in organs.instance_attributes.items()}
                    index = organs.material[mine] if table else None
                    self.gather_instanced(
                        f"organ_{proto.name}", proto.mesh, organs.transforms[mine], index, attributes, material_of
                    )
            else:
                self.gather_merged(f"organ_{proto.name}", organs.merged[p], material_of)
        if first:
            self.gather_branch_table(part)
            if self.options.skeleton_curves:
                self.gather_skeleton_curves()

    def gather_skeleton_curves(self) -> None:
        """The skeleton as a mesh of lines."""
        lines = _skeleton_lines(self.tree)
        if lines is not None:
            points, pairs = lines
            primitive = {
                "attributes": {"POSITION": self.buf.accessor(points, bounds=True)},
                "indices": self.buf.accessor(_indices(pairs, len(points)), ELEMENT_ARRAY_BUFFER),
                "mode": LINES,
            }
            self.gather_mesh_node("skeleton", [primitive])

    # extras
    def gather_branch_table(self, part: Tree) -> None:
        """The per-branch attributes in the asset node's extras, a row per branch, indexed by _BRANCH_ID
        (:mod:`lsys3d.look.attributes`)."""
        if part.hierarchy is not None and len(part.hierarchy):
            branches = {"count": len(part.hierarchy)}
            for key, values in branch_table(part.hierarchy).items():
                branches[key] = self.buf.accessor(np.ascontiguousarray(values, np.float32), target=None)
            self.nodes[self.asset].setdefault("extras", {})["lsys3d_branches"] = branches

    # nodes
    def gather_nodes(self) -> None:
        """The asset's node and its parts; with levels of detail a node per level, named for the importers that
        group ``_LOD<n>`` nodes, level 0 naming the others with ``MSFT_lod``."""
        tree, nodes = self.tree, self.nodes
        if not tree.lods:
            nodes.append({"name": tree.name, "children": []})
            self.gather_parts(tree, True)
            return
        level_nodes = []
        if self.rig is not None:
            # a skinned mesh ignores its parents: each level is one skinned node of all its parts, level 0 in the
            # scene; the asset's node holds the joints (and the branch table, the skeleton curves)
            nodes.append({"name": tree.name, "children": []})
            for i, lod in enumerate(tree.lods):
                self.level_parts = []
                self.gather_parts(tree.at_level(i), i == 0)
                self.meshes.append({"name": f"{tree.name}_LOD{lod.level}", "primitives": self.level_parts})
                nodes.append({"name": f"{tree.name}_LOD{lod.level}", "mesh": len(self.meshes) - 1, "skin": 0})
                level_nodes.append(len(nodes) - 1)
            self.level_parts = None
            self.roots.append(level_nodes[0])
        else:
            for i, lod in enumerate(tree.lods):
                nodes.append({"name": f"{tree.name}_LOD{lod.level}", "children": []})
                self.asset = len(nodes) - 1
                level_nodes.append(self.asset)
                self.gather_parts(tree.at_level(i), i == 0)
            self.asset = 0
        if len(level_nodes) > 1:  # the scene holds level 0; it names the others
            nodes[level_nodes[0]]["extensions"] = {LOD: {"ids": level_nodes[1:]}}
            coverage = [SCREEN_COVERAGE[lod.level] for lod in tree.lods]
            nodes[level_nodes[0]].setdefault("extras", {})["MSFT_screencoverage"] = coverage
            self.extensions_used.append(LOD)

    # skins
    def gather_skin(self) -> None:
        """The rig's joints under the asset's node, each translated from its parent (no rotation), and its skin."""
        rig, nodes, where = self.rig, self.nodes, self.where
        if rig is None:
            return
        base = self.joint_base = len(nodes)
        local = to_float32(rig.local, "joint positions", where)
        for i, name in enumerate(rig.names):
            nodes.append({"name": name, "translation": local[i].tolist()})
        for i, up in enumerate(rig.parent.tolist()):
            if up >= 0:
                nodes[base + up].setdefault("children", []).append(base + i)
        nodes[0]["children"].append(base)
        inverse_bind = np.zeros((len(rig), 16), np.float32)
        inverse_bind[:, [0, 5, 10, 15]] = 1.0
        inverse_bind[:, 12:15] = -to_float32(rig.position, "joint positions", where)  # column-major translation
        self.skins.append(
            {
                "name": "rig",
                "joints": list(range(base, base + len(rig))),
                "skeleton": base,
                "inverseBindMatrices": self.buf.accessor(inverse_bind, target=None),
            }
        )

    # animations
    def gather_growth(self) -> None:
        """The growth: a scale channel per growing joint, its two keys (smooth: a cubic Hermite spline with flat
        tangents, exactly 3x^2 - 2x^3; linear: linear) or its frames (logistic) in one pair of buffer views."""
        growth = self.tree.growth
        if self.rig is None or growth is None or not growth.keyed.any():
            return
        joints = np.flatnonzero(growth.keyed)
        inputs, outputs, kinds = [], [], []
        frames = growth.times
        for j in joints.tolist():
            name = FUNCTION_NAMES[growth.function[j]]
            b, e = float(growth.begin[j]), float(growth.end[j])
            if name == "logistic":
                # the keys as the file stores them (float32), each once: two times apart in float64 may not be
                times = np.unique(np.concatenate([[b, e], frames[(frames > b) & (frames < e)]]).astype(np.float32))
                values = np.repeat(growth.scales(times.astype(np.float64))[:, j : j + 1], 3, axis=1)
                kinds.append("LINEAR")
            elif name == "smooth":  # (in-tangent, value, out-tangent) per key; flat tangents
                times = np.array([b, e])
                values = np.zeros((6, 3))
                values[4] = 1.0
                kinds.append("CUBICSPLINE")
            else:
                times, values = np.array([b, e]), np.array([[0.0] * 3, [1.0] * 3])
                kinds.append("LINEAR")
            inputs.append(times.astype(np.float32))
            outputs.append(values.astype(np.float32))
        time_accessors = self.buf.packed(inputs, bounds=True)
        value_accessors = self.buf.packed(outputs)
        samplers, channels = [], []
        for k, j in enumerate(joints.tolist()):
            samplers.append({"input": time_accessors[k], "interpolation": kinds[k], "output": value_accessors[k]})
            channels.append({"sampler": k, "target": {"node": self.joint_base + j, "path": "scale"}})
        self.animations.append({"name": "growth", "channels": channels, "samplers": samplers})

    def gather_animations(self) -> None:
        """The wind: a rotation channel per joint but the root."""
        rig, anim = self.rig, self.tree.animation
        if rig is None or anim is None:
            return
        times = self.buf.accessor(anim.times.astype(np.float32), target=None, bounds=True)
        samplers, channels = [], []
        for i in range(1, len(rig)):
            output = self.buf.accessor(np.ascontiguousarray(anim.rotations[:, i], np.float32), target=None)
            samplers.append({"input": times, "interpolation": "LINEAR", "output": output})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": self.joint_base + i, "path": "rotation"}})
        if channels:
            self.animations.append({"name": "wind", "channels": channels, "samplers": samplers})

    def gather_scene(self) -> None:
        """The scene the plant grew in (``--scene``): a node ``scene`` under the asset's, a mesh per scene mesh."""
        meshes = scene_meshes(self.tree, self.options, self.where)
        if not meshes:
            return
        children = []
        for name, points, faces, _, look in meshes:
            position = self.buf.accessor(to_float32(points, f"scene {name}", self.where), bounds=True)
            indices = self.buf.accessor(faces.reshape(-1).astype(np.uint32), target=ELEMENT_ARRAY_BUFFER)
            primitive = {
                "attributes": {"POSITION": position},
                "indices": indices,
                "material": self.gather_material(look),
            }
            self.meshes.append({"name": name, "primitives": [primitive]})
            self.nodes.append({"name": name, "mesh": len(self.meshes) - 1})
            children.append(len(self.nodes) - 1)
        self.nodes.append({"name": "scene", "children": children})
        self.nodes[0].setdefault("children", []).append(len(self.nodes) - 1)

    # the document
    def document(self) -> dict:
        """The glTF JSON of what was gathered, the tree's metadata in the asset's and the scene's extras."""
        tree, buf = self.tree, self.buf
        metadata = metadata_json(tree, self.where)
        doc = {"asset": {"version": "2.0", "generator": f"lsys3d {__version__}"}}
        if metadata:
            doc["asset"]["extras"] = metadata
        if self.extensions_used:
            doc["extensionsUsed"] = self.extensions_used
        scene = {"name": tree.name, "nodes": self.roots}
        if metadata:
            scene["extras"] = metadata
        doc.update(scene=0, scenes=[scene], nodes=self.nodes)
        # glTF arrays may not be empty: leave out what a tree without geometry lacks
        samplers = [SAMPLER] if self.textures else []
        parts = (("meshes", self.meshes), ("materials", self.materials), ("textures", self.textures))
        parts += (("images", self.images), ("samplers", samplers), ("skins", self.skins))
        parts += (("animations", self.animations), ("accessors", buf.accessors))
        for key, value in parts:
            if value:
                doc[key] = value
        if buf.views:
            doc.update(bufferViews=buf.views, buffers=[{"byteLength": buf.size + (-buf.size % 4)}])
        return doc


def build(tree: Tree, options: ExportOptions, where: str) -> tuple[dict, _Buffer]:
    """Gather ``tree`` into a glTF JSON document and its binary buffer (not yet serialised).

    A tree with levels of detail gets one node per level, ``<name>_LOD0`` ..
    ``<name>_LOD<n>`` (the name convention Unity's and Unreal's importers
    group), each holding that level's parts; the scene holds ``_LOD0``, which
    lists the others with ``MSFT_lod`` and their switching hints in
    ``extras.MSFT_screencoverage``.  A viewer that does not know the
    extension shows level 0 alone.
    """
    check_options(options, where)
    gathered = _Gather(tree, options, where)
    gathered.gather_nodes()  # meshes, their materials and textures, as the parts are reached
    gathered.gather_scene()
    gathered.gather_skin()
    gathered.gather_growth()
    gathered.gather_animations()
    return gathered.document(), gathered.buf


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
