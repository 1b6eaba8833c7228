"""A :class:`~lsys3d.tree.Tree` as Blender data, built from its arrays (no file in between).

What the plant becomes, all of it parented to the bark's object (the *plant*):

- the bark: a mesh with the tree's welded vertices, its faces, custom normals from the corner normals (the
  ``custom_normal`` float attribute of Blender 4.5+, exactly the tree's; encoded split normals before), the
  ``UVMap`` layer from the corner uv, the bark colours as the ``Col`` colour attribute, the hierarchy and wind
  attributes as mesh attributes of the same names (``branch_id``...), one material slot per material the
  faces use;
- the leaves: instances of one leaf model, placed by a geometry nodes modifier (:func:`instancer_group`) on
  a points mesh whose ``lsys3d_transform`` attribute holds each instance's matrix (and the per-instance
  attributes beside it); the ``{ . }`` polygons as a mesh of their own.  A rigged tree's leaves are the merged
  mesh instead, weighted to the bones, as the USD writer does (instances cannot be skinned);
- organs: one instancer per prototype and material, like the leaves;
- the rig: an armature (one bone per joint, named as the joints), vertex groups of the same names holding the
  skin weights, and an Armature modifier on each skinned mesh; the wind animation, when grown, as the
  armature's action (quaternion keys of the pose bones).

lsys3d's frame is metres and Y up; Blender's is Z up: every point, normal and transform is turned +90
degrees about X (:data:`Y_TO_Z`, the turn USD's ``up_axis="Z"`` makes), and Blender's unit is the metre.
Materials are Principled BSDF node trees: base colour, roughness, metallic, the textures as Image Texture
nodes (images packed into the .blend from the tree's own bytes), a normal map through a Normal Map node,
alpha cut-outs through the BSDF's alpha.
"""

from __future__ import annotations

import hashlib

import bpy
import numpy as np
from mathutils import Matrix, Quaternion

from ..exchange.common import POINT_ATTRIBUTES, ExportOptions, file_frame
from ..look.materials import Material
from ..look.rig import SKIN_KEYS
from ..mesh.mesh import Mesh
from ..tree import Tree

__all__ = ["INSTANCE_GROUP", "TRANSFORM_ATTRIBUTE", "Y_TO_Z", "build", "instancer_group", "remove_plant"]

Y_TO_Z = file_frame(ExportOptions(up_axis="Z"))
"""lsys3d's frame (metres, Y up) to Blender's (metres, Z up): ``(x, y, z) -> (x, -z, y)``."""

TRANSFORM_ATTRIBUTE = "lsys3d_transform"
"""The point attribute (4x4 matrix) an instancer's points carry: each instance's transform."""

INSTANCE_GROUP = "lsys3d instances"
"""The geometry nodes group that places an object's geometry on the points by their transforms."""

PART_KEY = "lsys3d_part"
"""Custom property naming what an object of a plant is: ``bark``, ``leaves``, ``leaf_model``, ``rig``..."""

FREE_NORMALS = bpy.app.version >= (4, 5, 0)
"""Whether Blender stores custom normals as a float ``custom_normal`` corner attribute ("free" normals)."""

_Y_TO_Z_4 = np.eye(4)
_Y_TO_Z_4[:3, :3] = Y_TO_Z


def _points(values: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values, np.float64) @ Y_TO_Z.T, np.float32)


def mesh_data(name: str, mesh: Mesh, slots: list[bpy.types.Material] | None = None, slot_of=None) -> bpy.types.Mesh:
    """A Blender mesh of ``mesh``: vertices, triangles, custom normals, uv, colours and attributes.

    ``slots`` are the materials appended in order; ``slot_of`` maps the mesh's ``face_material`` (an int
    array) to slot indices (None: every face slot 0).  Skin attributes (:data:`~lsys3d.look.rig.SKIN_KEYS`)
    are left out: they become vertex groups (:func:`_weights`).
    """
    data = bpy.data.meshes.new(name)
    nv, nf = len(mesh.vertices), len(mesh.faces)
    data.vertices.add(nv)
    data.vertices.foreach_set("co", _points(mesh.vertices).ravel())
    data.loops.add(3 * nf)
    data.loops.foreach_set("vertex_index", np.ascontiguousarray(mesh.faces, np.int32).ravel())
    data.polygons.add(nf)
    data.polygons.foreach_set("loop_start", np.arange(0, 3 * nf, 3, dtype=np.int32))
    data.update(calc_edges=True)
    if nf:
        data.polygons.foreach_set("use_smooth", np.ones(nf, bool))
        uv = data.uv_layers.new(name="UVMap")
        uv.data.foreach_set("uv", np.ascontiguousarray(mesh.uv, np.float32).ravel())
        normals = _points(mesh.normals.reshape(-1, 3))
        if FREE_NORMALS:  # the corner normals as they are, a float attribute set at once (Blender 4.5+)
            free = data.attributes.new("custom_normal", "FLOAT_VECTOR", "CORNER")
            free.data.foreach_set("vector", normals.ravel())
        else:  # encoded by Blender: it reads the normals as a sequence, 0.25 s for tree3d's 113,460 corners
            data.normals_split_custom_set(normals)
    if mesh.colors is not None:
        colors = data.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
        rgba = np.ones((nv, 4), np.float32)
        rgba[:, :3] = mesh.colors
        colors.data.foreach_set("color", rgba.ravel())
    _attributes(data, mesh.attributes, "POINT")
    for material in slots or ():
        data.materials.append(material)
    if slot_of is not None and mesh.face_material is not None and nf:
        data.polygons.foreach_set("material_index", np.asarray(slot_of(mesh.face_material), np.int32))
    return data


def _attributes(data, attributes, domain: str) -> None:
    """Per-element float attributes as Blender attributes of the same names (positions turned Z up)."""
    for key, values in attributes.items():
        if key in SKIN_KEYS:
            continue
        a = np.asarray(values, np.float32)
        if a.ndim == 1:
            data.attributes.new(key, "FLOAT", domain).data.foreach_set("value", a)
        elif a.shape[1] == 3:
            if key in POINT_ATTRIBUTES:
                a = _points(a)
            data.attributes.new(key, "FLOAT_VECTOR", domain).data.foreach_set("vector", a.ravel())
        elif a.shape[1] == 2:
            data.attributes.new(key, "FLOAT2", domain).data.foreach_set("vector", a.ravel())
        else:
            for i in range(a.shape[1]):
                data.attributes.new(f"{key}_{i}", "FLOAT", domain).data.foreach_set("value", a[:, i].copy())


# ---------------------------------------------------------------- materials


def _image(picture) -> bpy.types.Image:
    """The tree's image as a Blender image packed from its bytes (one per distinct image)."""
    for existing in bpy.data.images:
        if existing.get("lsys3d_digest") == _digest(picture):
            return existing
    image = bpy.data.images.new(picture.name, picture.width, picture.height, alpha=picture.alpha)
    image.pack(data=picture.data, data_len=len(picture.data))  # the file's bytes, kept in the .blend
    image.source = "FILE"  # read from the packed bytes (a file path would be looked for on disk)
    image["lsys3d_digest"] = _digest(picture)
    return image


def _digest(picture) -> str:
    return hashlib.sha1(picture.data).hexdigest()


def material(m: Material, textures: bool = True, vertex_colors: bool = False) -> bpy.types.Material:
    """A Principled BSDF material of ``m``; its textures as Image Texture nodes when ``textures``.

    ``vertex_colors``: the mesh's ``Col`` attribute is the surface colour (the bark's colour variation,
    which stands in for the base colour as in the writers).
    """
    mat = bpy.data.materials.new(m.name)
    if mat.node_tree is None:  # Blender < 5 makes node trees on request
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    r, g, b, a = m.base_color
    bsdf.inputs["Base Color"].default_value = (r, g, b, 1.0)
    bsdf.inputs["Roughness"].default_value = m.roughness
    bsdf.inputs["Metallic"].default_value = m.metallic
    bsdf.inputs["Alpha"].default_value = a
    mat.diffuse_color = (r, g, b, a)
    mat.roughness = m.roughness
    mat.use_backface_culling = not m.double_sided
    color = None
    if vertex_colors:
        attribute = nodes.new("ShaderNodeVertexColor")
        attribute.layer_name = "Col"
        attribute.location = (-700, 300)
        color = attribute.outputs["Color"]
    if textures and m.texture is not None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(m.texture)
        tex.location = (-700, 500)
        tint = nodes.new("ShaderNodeMix")
        tint.data_type = "RGBA"
        tint.blend_type = "MULTIPLY"
        tint.inputs["Factor"].default_value = 1.0
        tint.location = (-300, 400)
        links.new(tex.outputs["Color"], tint.inputs["A"])
        if color is not None:
            links.new(color, tint.inputs["B"])
        else:
            tint.inputs["B"].default_value = (r, g, b, 1.0)
        color = tint.outputs["Result"]
        if m.alpha_cutoff is not None or m.texture.alpha:
            alpha = tex.outputs["Alpha"]
            if m.alpha_cutoff is not None:
                cut = nodes.new("ShaderNodeMath")
                cut.operation = "GREATER_THAN"
                cut.inputs[1].default_value = m.alpha_cutoff
                cut.location = (-300, 100)
                links.new(alpha, cut.inputs[0])
                alpha = cut.outputs[0]
            links.new(alpha, bsdf.inputs["Alpha"])
    if color is not None:
        links.new(color, bsdf.inputs["Base Color"])
    if textures and m.normal_texture is not None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(m.normal_texture)
        tex.image.colorspace_settings.name = "Non-Color"
        tex.location = (-700, -300)
        normal = nodes.new("ShaderNodeNormalMap")
        normal.location = (-300, -300)
        links.new(tex.outputs["Color"], normal.inputs["Color"])
        links.new(normal.outputs["Normal"], bsdf.inputs["Normal"])
    if textures and m.roughness_texture is not None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(m.roughness_texture)
        tex.image.colorspace_settings.name = "Non-Color"
        tex.location = (-1000, 0)
        split = nodes.new("ShaderNodeSeparateColor")
        split.location = (-700, 0)
        links.new(tex.outputs["Color"], split.inputs["Color"])
        for channel, socket, factor in (("Green", "Roughness", m.roughness), ("Blue", "Metallic", m.metallic)):
            scale = nodes.new("ShaderNodeMath")
            scale.operation = "MULTIPLY"
            scale.inputs[1].default_value = factor
            scale.location = (-450, -100 if socket == "Roughness" else -200)
            links.new(split.outputs[channel], scale.inputs[0])
            links.new(scale.outputs[0], bsdf.inputs[socket])
    see_through = a < 1.0 or m.alpha_cutoff is not None or (textures and m.texture is not None and m.texture.alpha)
    if see_through and hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "DITHERED"
    return mat


MATERIAL_KEY = "lsys3d_material"
"""Custom property of a material the add-on made: what it was made from (:func:`material_key`)."""


def material_key(m: Material, textures: bool, vertex_colors: bool) -> str:
    """A digest of everything :func:`material` reads: equal keys, the same Blender material."""
    images = [_digest(i) for i in m.images] if textures else []
    return hashlib.sha1(repr((m, images, textures, vertex_colors)).encode()).hexdigest()


class _Materials:
    """The Blender materials of one tree: ``of(material)`` reuses the file's material made from the same
    settings (by growing another plant, or this one before a regrow), so regrowing leaves no copies behind
    and plants of one grammar share their materials, as an artist's own would be shared."""

    def __init__(self, textures: bool):
        self.textures = textures
        self.made: dict = {}

    def of(self, m: Material, vertex_colors: bool = False) -> bpy.types.Material:
        key = material_key(m, self.textures, vertex_colors)
        if key not in self.made:
            found = next((x for x in bpy.data.materials if x.get(MATERIAL_KEY) == key), None)
            if found is None:
                found = material(m, self.textures, vertex_colors)
                found[MATERIAL_KEY] = key
            self.made[key] = found
        return self.made[key]

    def slots(self, index: np.ndarray | None, material_of, vertex_colors: bool = False):
        """The slots of a mesh whose faces have material ``index`` (None: all the default), and the map to them."""
        if index is None or not len(index):
            return [self.of(material_of(-1), vertex_colors)], None
        used = np.unique(index)
        slots, where = [], {}
        for i in used.tolist():
            mat = self.of(material_of(i), vertex_colors)
            if mat not in slots:
                slots.append(mat)
            where[i] = slots.index(mat)
        lookup = np.zeros(int(used.max()) + 1, np.int32)
        for i, s in where.items():
            lookup[i] = s
        return slots, lambda face_material: lookup[np.asarray(face_material, np.int64)]


# ---------------------------------------------------------------- instances


def instancer_group() -> bpy.types.NodeTree:
    """The geometry nodes group (made once a file): the ``Instance`` object's geometry on every point,
    each instance given the point's ``lsys3d_transform`` matrix (shear and all, as the tree has it)."""
    group = bpy.data.node_groups.get(INSTANCE_GROUP)
    if group is not None:
        return group
    group = bpy.data.node_groups.new(INSTANCE_GROUP, "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    group.interface.new_socket("Instance", in_out="INPUT", socket_type="NodeSocketObject")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = group.nodes, group.links
    inputs, outputs = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    info = nodes.new("GeometryNodeObjectInfo")
    info.transform_space = "ORIGINAL"
    on_points = nodes.new("GeometryNodeInstanceOnPoints")
    matrix = nodes.new("GeometryNodeInputNamedAttribute")
    matrix.data_type = "FLOAT4X4"
    matrix.inputs["Name"].default_value = TRANSFORM_ATTRIBUTE
    place = nodes.new("GeometryNodeSetInstanceTransform")
    for i, node in enumerate((inputs, info, on_points, place, outputs)):
        node.location = (200 * i, 0)
    matrix.location = (400, -200)
    links.new(inputs.outputs["Geometry"], on_points.inputs["Points"])
    links.new(inputs.outputs["Instance"], info.inputs["Object"])
    links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    links.new(on_points.outputs["Instances"], place.inputs["Instances"])
    links.new(matrix.outputs["Attribute"], place.inputs["Transform"])
    links.new(place.outputs["Instances"], outputs.inputs["Geometry"])
    return group


def _instancer(name: str, transforms: np.ndarray, attributes) -> bpy.types.Mesh:
    """A points mesh: one vertex per instance at its position, its matrix and attributes as point attributes."""
    t = _Y_TO_Z_4 @ np.asarray(transforms, np.float64) @ _Y_TO_Z_4.T
    data = bpy.data.meshes.new(name)
    data.vertices.add(len(t))
    data.vertices.foreach_set("co", np.ascontiguousarray(t[:, :3, 3], np.float32).ravel())
    # Blender's matrices are column-major: each matrix's columns, one after another
    matrices = np.ascontiguousarray(t.transpose(0, 2, 1), np.float32).ravel()
    data.attributes.new(TRANSFORM_ATTRIBUTE, "FLOAT4X4", "POINT").data.foreach_set("value", matrices)
    _attributes(data, attributes, "POINT")
    data.update()
    return data


def _place(name, part, parent, model_mesh, transforms, attributes, collection):
    """A hidden model object and the instancer object that places it (both children of ``parent``)."""
    model = _object(f"{name}_model", model_mesh, f"{part}_model", parent, collection)
    model.hide_viewport = model.hide_render = True
    model.hide_set(True)
    points = _object(name, _instancer(name, transforms, attributes), part, parent, collection)
    modifier = points.modifiers.new("lsys3d instances", "NODES")
    group = instancer_group()
    modifier.node_group = group
    modifier[group.interface.items_tree["Instance"].identifier] = model
    return points


def _object(name, data, part: str, parent, collection) -> bpy.types.Object:
    obj = bpy.data.objects.new(name, data)
    obj[PART_KEY] = part
    collection.objects.link(obj)
    if parent is not None:
        obj.parent = parent
    return obj


# ---------------------------------------------------------------- rig


def _armature(name: str, rig, parent, collection) -> bpy.types.Object:
    """One bone per joint, head at the joint, pointing at its first child (else along its parent's bone)."""
    arm = bpy.data.armatures.new(name)
    obj = _object(name, arm, "rig", parent, collection)
    heads = _points(rig.position).astype(np.float64)
    children: dict[int, int] = {}
    for j, p in enumerate(rig.parent.tolist()):
        if p >= 0:
            children.setdefault(p, j)
    tails = heads.copy()
    for j in range(len(rig)):
        if j in children:
            tails[j] = heads[children[j]]
    length = np.linalg.norm(tails - heads, axis=1)
    for j in range(len(rig)):  # a leaf joint (or one on its child): along its parent's bone, 0.1 m long at least
        if length[j] < 1e-4:
            p = int(rig.parent[j])
            d = heads[j] - heads[p] if p >= 0 else np.array([0.0, 0.0, 1.0])
            n = np.linalg.norm(d)
            d = d / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
            tails[j] = heads[j] + d * max(0.1, 0.25 * (n if p >= 0 else 1.0))
    view_layer = bpy.context.view_layer
    previous = view_layer.objects.active
    view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    bones = []
    for j, joint in enumerate(rig.names):
        bone = arm.edit_bones.new(joint)
        bone.head, bone.tail = heads[j].tolist(), tails[j].tolist()
        bones.append(bone)
    for j, p in enumerate(rig.parent.tolist()):
        if p >= 0:
            bones[j].parent = bones[p]
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = previous
    obj.show_in_front = True
    return obj


def _weights(obj: bpy.types.Object, mesh: Mesh, rig, armature: bpy.types.Object) -> None:
    """The mesh's skin (joints and weights per vertex) as vertex groups, and an Armature modifier."""
    joints = np.asarray(mesh.attributes["skin_joints"], np.int64)
    weights = np.asarray(mesh.attributes["skin_weights"], np.float64)
    groups = [obj.vertex_groups.new(name=n) for n in rig.names]
    vertex, slot = np.nonzero(weights > 0)
    joint, weight = joints[vertex, slot], weights[vertex, slot]
    order = np.lexsort((weight, joint))
    vertex, joint, weight = vertex[order], joint[order], weight[order]
    # one call per run of equal (joint, weight): rigid leaves share a weight of 1 on their joint
    cut = np.flatnonzero((np.diff(joint) != 0) | (np.diff(weight) != 0)) + 1
    for run in np.split(np.arange(len(vertex)), cut):
        if len(run):
            groups[joint[run[0]]].add(vertex[run].tolist(), float(weight[run[0]]), "REPLACE")
    modifier = obj.modifiers.new("lsys3d rig", "ARMATURE")
    modifier.object = armature


def _wind(armature: bpy.types.Object, names, animation) -> bpy.types.Action:
    """The wind animation as quaternion keys of the pose bones, one key per sample, looping.

    lsys3d's joints are unrotated at rest and each sample turns a joint by ``R`` relative to its parent; a
    Blender bone's pose rotation is in the bone's own rest frame ``B`` (along it, head to tail), so the key is
    ``B^T R' B`` with ``R'`` the turn in Blender's Z-up frame: the bones then move the skin exactly as the
    joints do in the glTF and USD files.
    """
    scene = bpy.context.scene
    scene.render.fps = animation.fps
    frames = np.rint(np.asarray(animation.times) * animation.fps).astype(np.float64) + 1.0
    scene.frame_start, scene.frame_end = 1, int(frames[-1])
    action = bpy.data.actions.new(f"{armature.name}_wind")
    armature.animation_data_create().action = action
    fcurves = _fcurves(action, armature)
    turn = Matrix(Y_TO_Z.tolist())
    for j, name in enumerate(names):  # by name: Blender keeps the pose bones in an order of its own
        bone = armature.pose.bones[name]
        bone.rotation_mode = "QUATERNION"
        rest = bone.bone.matrix_local.to_3x3()
        keys = np.empty((len(frames), 4))
        for k, (x, y, z, w) in enumerate(animation.rotations[:, j].tolist()):
            r = turn @ Quaternion((w, x, y, z)).to_matrix() @ turn.transposed()
            keys[k] = (rest.transposed() @ r @ rest).to_quaternion()
        path = bone.path_from_id("rotation_quaternion")
        for i in range(4):
            curve = (
                fcurves.new(path, index=i, action_group=bone.name) if _LEGACY_ACTIONS else fcurves.new(path, index=i)
            )
            curve.keyframe_points.add(len(frames))
            curve.keyframe_points.foreach_set("co", np.column_stack([frames, keys[:, i]]).ravel().astype(np.float32))
            curve.update()
    return action


_LEGACY_ACTIONS = "slots" not in bpy.types.Action.bl_rna.properties


def _fcurves(action, obj):
    """Where an action's F-curves are made: the action itself before Blender 4.4, else its slot's channelbag."""
    if _LEGACY_ACTIONS:
        return action.fcurves
    from bpy_extras.anim_utils import action_ensure_channelbag_for_slot  # Blender 4.4+

    slot = action.slots.new(id_type="OBJECT", name=obj.name)
    obj.animation_data.action_slot = slot
    return action_ensure_channelbag_for_slot(action, slot).fcurves


# ---------------------------------------------------------------- the plant


def build(
    tree: Tree,
    name: str,
    collection: bpy.types.Collection,
    *,
    leaves: bool = True,
    textures: bool = True,
    plant: bpy.types.Object | None = None,
) -> bpy.types.Object:
    """Put ``tree`` in ``collection``: the bark's object (the plant) with the leaves, organs and rig as its children.

    ``plant``: an object of an earlier growth to regrow in place (its mesh is replaced, its children removed,
    its transform, name and custom properties kept).  ``leaves=False`` leaves leaves and organs out;
    ``textures=False`` makes plain-colour materials.  Returns the plant's object.
    """
    table = tree.materials
    made = _Materials(textures)
    bark = tree.bark
    slots, slot_of = made.slots(bark.face_material, table.for_bark, bark.colors is not None)
    data = mesh_data(f"{name}_bark", bark, slots, slot_of)
    if plant is None:
        plant = _object(name, data, "bark", None, collection)
    else:
        remove_children(plant)
        old, plant.data = plant.data, data
        if old.users == 0:
            bpy.data.meshes.remove(old)
    armature = None
    if tree.rig is not None:
        armature = _armature(f"{name}_rig", tree.rig, plant, collection)
        if "skin_joints" in bark.attributes:
            _weights(plant, bark, tree.rig, armature)
        if tree.animation is not None:
            _wind(armature, tree.rig.names, tree.animation)
    if leaves:
        _leaves(tree, name, plant, collection, made, armature)
        _organs(tree, name, plant, collection, made)
    return plant


def _leaves(tree: Tree, name, plant, collection, made: _Materials, armature) -> None:
    table, lv = tree.materials, tree.leaves
    if lv.instanced and armature is None:
        own = lv.instance_material if lv.instance_material is not None else tree.skeleton.leaf_material
        own = np.asarray(own, np.int64)
        groups = [(-1, np.arange(len(lv.transforms)))]
        if table and len(own) == len(lv.transforms):
            groups = [(i, np.flatnonzero(own == i)) for i in np.unique(own).tolist()]
        for i, rows in groups:
            model = mesh_data(f"{name}_leaf", lv.model, [made.of(table.for_leaf(i))])
            attrs = {k: np.asarray(a)[rows] for k, a in lv.instance_attributes.items()}
            suffix = "" if len(groups) == 1 else f"_{i}"
            _place(f"{name}_leaves{suffix}", "leaves", plant, model, lv.transforms[rows], attrs, collection)
        if lv.polygons is not None and len(lv.polygons.faces):
            slots, slot_of = made.slots(lv.polygons.face_material, table.for_leaf)
            _object(f"{name}_leaf_polygons", mesh_data(f"{name}_leaf_polygons", lv.polygons, slots, slot_of),
                    "leaf_polygons", plant, collection)  # fmt: skip
        return
    merged = lv.merged if lv.merged is not None else lv.polygons
    if merged is None or not len(merged.faces):
        return
    slots, slot_of = made.slots(merged.face_material, table.for_leaf)
    obj = _object(f"{name}_leaves", mesh_data(f"{name}_leaves", merged, slots, slot_of), "leaves", plant, collection)
    if armature is not None and "skin_joints" in merged.attributes:
        _weights(obj, merged, tree.rig, armature)


def _organs(tree: Tree, name, plant, collection, made: _Materials) -> None:
    organs, table = tree.organs, tree.materials
    for p, prototype in enumerate(organs.prototypes):
        rows = organs.of(p)
        if not len(rows):
            continue
        for i in np.unique(organs.material[rows]).tolist():
            mine = rows[organs.material[rows] == i]
            m = prototype.material or (table.for_bark(i) if prototype.closed else table.for_leaf(i))
            model = mesh_data(f"{name}_{prototype.name}", prototype.mesh, [made.of(m)])
            attrs = {k: np.asarray(a)[mine] for k, a in organs.instance_attributes.items()}
            _place(f"{name}_{prototype.name}_{i}", "organs", plant, model, organs.transforms[mine], attrs, collection)


def remove_children(plant: bpy.types.Object) -> None:
    """Remove what an earlier growth put under ``plant`` (instancers, models, the rig) and its modifiers."""
    for modifier in list(plant.modifiers):
        if modifier.name == "lsys3d rig":
            plant.modifiers.remove(modifier)
    plant.vertex_groups.clear()
    for child in list(plant.children_recursive):
        if PART_KEY in child:
            data = child.data
            bpy.data.objects.remove(child)
            if data is not None and data.users == 0:
                if isinstance(data, bpy.types.Mesh):
                    bpy.data.meshes.remove(data)
                elif isinstance(data, bpy.types.Armature):
                    bpy.data.armatures.remove(data)


def remove_plant(plant: bpy.types.Object) -> None:
    """Remove the plant's object and everything an lsys3d growth put under it."""
    remove_children(plant)
    data = plant.data
    bpy.data.objects.remove(plant)
    if data is not None and data.users == 0:
        bpy.data.meshes.remove(data)
