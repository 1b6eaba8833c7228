"""Import a file into Blender (``bpy`` as a module) and print what arrived, as one JSON line.

Run it with the interpreter of the Blender environment (``.venv-bpy``)::

    .venv-bpy/bin/python tools/blender_import.py tree.glb [more.usdc ...]

``.glb``/``.gltf`` go through Blender's glTF importer (with merged vertices, so
a welded mesh comes back welded), ``.usd*`` through its USD importer.  The
report of a file is a line ``LSYS3D-BLENDER ``, then JSON with the Blender version,
the imported objects (type, parent, vertex and face counts, world bounding
box, materials, whether ``Mesh.validate`` had to repair anything), the
materials (Principled BSDF base colour and roughness, and the image textures
wired into its Base Color, Alpha and Normal inputs, with their pixel size),
the world bounding box of everything Blender draws, instances included, and
the actions (frame range, the scene's frames per second, F-curves, keyframes), with how far the skinned
meshes' vertices move between an action's first frame and a quarter of the
way through it.  Several files are imported one after another in one Blender (the
scene emptied to its factory settings before each, as a fresh Blender starts), one
report line each, in their order: a Blender start (half a CPU second) paid once.

Blender crashes on some malformed files: the caller should run this in a
child process and treat a signal as a failure (``tests/validators.py`` does).
"""

import json
import os
import sys

MARK = "LSYS3D-BLENDER "


def _bbox(points, matrix):
    import numpy as np

    if not len(points):
        return None
    m = np.array(matrix)
    w = points @ m[:3, :3].T + m[:3, 3]
    return [w.min(axis=0).tolist(), w.max(axis=0).tolist()]


def _merge(a, b):
    if a is None:
        return b
    if b is None:
        return a
    return [[min(x, y) for x, y in zip(a[0], b[0], strict=True)], [max(x, y) for x, y in zip(a[1], b[1], strict=True)]]


def _points(mesh):
    import numpy as np

    co = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def _images_into(socket):
    """The image textures upstream of a node socket (through normal-map, mix and separate nodes)."""
    out, seen, stack = [], set(), [socket]
    while stack:
        for link in stack.pop().links:
            node = link.from_node
            if node.name in seen:
                continue
            seen.add(node.name)
            if node.type == "TEX_IMAGE" and node.image is not None:
                image = node.image
                space = image.colorspace_settings.name
                out.append({"image": image.name, "size": list(image.size), "colorspace": space})
            stack.extend(i for i in node.inputs if i.is_linked)
    return out


def _actions(bpy):
    """Each action: its frame range, F-curves and keyframes (Blender 4.4+ layered actions, or the legacy list)."""
    out = []
    for action in sorted(bpy.data.actions, key=lambda a: a.name):
        curves = list(getattr(action, "fcurves", None) or [])
        for layer in getattr(action, "layers", []):
            for strip in layer.strips:
                for bag in strip.channelbags:
                    curves.extend(bag.fcurves)
        out.append(
            {
                "name": action.name,
                "frame_range": list(action.frame_range),
                "fps": bpy.context.scene.render.fps / bpy.context.scene.render.fps_base,
                "fcurves": len(curves),
                "keyframes": sum(len(c.keyframe_points) for c in curves),
                "users": [o.name for o in bpy.data.objects if o.animation_data and o.animation_data.action == action],
            }
        )
    return out


def _animated(bpy, actions):
    """How far each deformed mesh moves (metres, its farthest vertex) from an action's start to a quarter in."""
    if not actions:
        return {}
    import numpy as np

    start, end = actions[0]["frame_range"]
    scene = bpy.context.scene
    meshes = [o for o in bpy.data.objects if o.type == "MESH" and o.modifiers]

    def positions():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        out = {}
        for o in meshes:
            evaluated = o.evaluated_get(depsgraph)
            mesh = evaluated.to_mesh()
            out[o.name] = _points(mesh) @ np.array(evaluated.matrix_world)[:3, :3].T
            evaluated.to_mesh_clear()
        return out

    scene.frame_set(round(start))
    before = positions()
    scene.frame_set(round(start + (end - start) / 4))
    after = positions()
    return {name: float(np.linalg.norm(after[name] - before[name], axis=1).max(initial=0.0)) for name in before}


def main(path):
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=path, merge_vertices=True)
    else:
        bpy.ops.wm.usd_import(filepath=path)

    objects = []
    for o in sorted(bpy.data.objects, key=lambda o: o.name):
        entry = {
            "name": o.name,
            "type": o.type,
            "parent": o.parent.name if o.parent else None,
            "collections": sorted(c.name for c in o.users_collection),
            "hidden": bool(o.hide_get() or o.hide_render),
        }
        if o.type == "MESH":
            me = o.data
            entry.update(
                vertices=len(me.vertices),
                unique_positions=len(np.unique(_points(me), axis=0)),
                faces=len(me.polygons),
                edges=len(me.edges),
                uv_layers=[uv.name for uv in me.uv_layers],
                materials=[s.material.name if s.material else None for s in o.material_slots],
                bbox=_bbox(_points(me), o.matrix_world),
                repaired=bool(me.validate(verbose=False, clean_customdata=False)),
            )
        objects.append(entry)

    materials = []
    for m in sorted(bpy.data.materials, key=lambda m: m.name):
        entry = {"name": m.name}
        if m.node_tree:
            bsdf = next((n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
            if bsdf is not None:
                entry["base_color"] = list(bsdf.inputs["Base Color"].default_value)
                entry["roughness"] = bsdf.inputs["Roughness"].default_value
                entry["textures"] = {
                    name: _images_into(bsdf.inputs[name])
                    for name in ("Base Color", "Alpha", "Normal")
                    if bsdf.inputs[name].is_linked and _images_into(bsdf.inputs[name])
                }
        materials.append(entry)

    # what is drawn, instances included: evaluate the dependency graph
    depsgraph = bpy.context.evaluated_depsgraph_get()
    drawn = None
    instances = 0
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        if not inst.show_self:
            continue
        instances += int(inst.is_instance)
        me = ob.data
        drawn = _merge(drawn, _bbox(_points(me), inst.matrix_world))

    actions = _actions(bpy)
    report = {
        "blender": bpy.app.version_string,
        "objects": objects,
        "materials": materials,
        "drawn_bbox": drawn,
        "drawn_instances": instances,
        "actions": actions,
        "animated": _animated(bpy, actions),
    }
    sys.stdout.write("\n" + MARK + json.dumps(report) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.stderr.write(__doc__)
        sys.exit(2)
    rc = 0
    for arg in sys.argv[1:]:  # each file into Blender's empty factory scene, its report line in turn
        rc = rc or main(os.path.abspath(arg))
    os._exit(rc)  # skip Blender's atexit teardown
