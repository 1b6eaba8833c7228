"""Play a tree's growth animation in Blender and report what its skinned meshes look like at some frames.

Run it with the interpreter of the Blender environment (``.venv-bpy``)::

    .venv-bpy/bin/python tools/blender_growth.py tree.glb [tree.usda ...] 0 12 120

imports the file (glTF or USD), makes the growth its armature's action (glTF: the animation named
``growth``; USD: the one animation, wind and growth together), and at each frame given lets Blender
evaluate the armature deformation (glTF keys are seconds, which Blender places at its 24 frames a second;
USD keys are time codes, kept as frames).  Prints one line, ``LSYS3D-BLENDER `` then JSON: the action's
frame range, and per frame and per deformed mesh its world bounding box (Blender's Z up) and the largest
distance of a vertex from where it is in the mesh's rest (unposed) form.  Several files are played one
after another in one Blender (the scene emptied to its factory settings before each), a line each, in order.
"""

import json
import os
import sys

MARK = "LSYS3D-BLENDER "


def _points(obj, depsgraph, np):
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    m = np.array(evaluated.matrix_world)
    return co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]


def main(path, wanted):
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.lower().endswith((".glb", ".gltf")):
        bpy.ops.import_scene.gltf(filepath=path)
    else:
        bpy.ops.wm.usd_import(filepath=path)
    scene = bpy.context.scene
    armatures = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    actions = sorted(bpy.data.actions, key=lambda a: (not a.name.startswith("growth"), a.name))
    action = actions[0]
    for armature in armatures:
        armature.animation_data_create().action = action
        slots = getattr(action, "slots", None)
        if slots:
            armature.animation_data.action_slot = slots[0]
    start, end = action.frame_range
    meshes = [o for o in bpy.data.objects if o.type == "MESH" and o.modifiers]
    rest = {}
    for o in meshes:  # the rest form: the armature modifier off
        for m in o.modifiers:
            m.show_viewport = False
        rest[o.name] = _points(o, bpy.context.evaluated_depsgraph_get(), np)
        for m in o.modifiers:
            m.show_viewport = True
    frames = []
    for f in wanted:
        scene.frame_set(f)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        entry = {"frame": scene.frame_current, "meshes": {}}
        for o in meshes:
            p = _points(o, depsgraph, np)
            entry["meshes"][o.name] = {
                "bbox": [p.min(axis=0).tolist(), p.max(axis=0).tolist()] if len(p) else None,
                "from_rest": float(np.linalg.norm(p - rest[o.name], axis=1).max(initial=0.0)),
            }
        frames.append(entry)
    report = {
        "action": action.name,
        "frame_range": [start, end],
        "rest": {n: [p.min(axis=0).tolist(), p.max(axis=0).tolist()] for n, p in rest.items() if len(p)},
        "frames": frames,
    }
    sys.stdout.write("\n" + MARK + json.dumps(report) + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    args = sys.argv[1:]
    paths = [a for a in args if not a.lstrip("-").isdigit()]  # the files, then the frames (whole numbers)
    for path in paths:
        main(os.path.abspath(path), [int(x) for x in args[len(paths) :]])
    os._exit(0)  # skip Blender's atexit teardown
