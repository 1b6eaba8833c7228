"""Pose one joint of a rigged file in Blender and report how far every vertex of every mesh moved.

Run it with the interpreter of the Blender environment (``.venv-bpy``)::

    .venv-bpy/bin/python tools/blender_pose.py tree.glb b3_j0 30

imports the file (glTF or USD), rotates the pose bone named ``b3_j0`` by 30
degrees about its local X axis, lets Blender evaluate the armature deformation
and prints one line, ``LSYS3D-BLENDER `` then JSON: for each mesh object, the
displacement of each vertex (metres, in vertex order), and the armatures found.
"""

import json
import math
import sys

MARK = "LSYS3D-BLENDER "


def _positions(obj, depsgraph):
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    matrix = evaluated.matrix_world
    out = [tuple(matrix @ v.co) for v in mesh.vertices]
    evaluated.to_mesh_clear()
    return out


def main(path: str, bone: str, degrees: float) -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.lower().endswith((".glb", ".gltf")):
        bpy.ops.import_scene.gltf(filepath=path)
    else:
        bpy.ops.wm.usd_import(filepath=path)
    armatures = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    meshes = [o for o in bpy.data.objects if o.type == "MESH" and o.modifiers]
    depsgraph = bpy.context.evaluated_depsgraph_get()
    before = {o.name: _positions(o, depsgraph) for o in meshes}
    found = False
    for armature in armatures:
        pose_bone = armature.pose.bones.get(bone)
        if pose_bone is not None:
            pose_bone.rotation_mode = "XYZ"
            pose_bone.rotation_euler = (math.radians(degrees), 0.0, 0.0)
            found = True
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    moved = {}
    for o in meshes:
        after = _positions(o, depsgraph)
        moved[o.name] = [round(math.dist(a, b), 6) for a, b in zip(before[o.name], after, strict=True)]
    report = {
        "armatures": [{"name": a.name, "bones": len(a.data.bones)} for a in armatures],
        "posed": found,
        "moved": moved,
        "modifiers": {o.name: [m.type for m in o.modifiers] for o in meshes},
    }
    print(MARK + json.dumps(report))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]))
