"""Drive the lsys3d add-on inside Blender and print what it made: the Blender side of tests/test_blender_addon.py.

Run by the Python that has ``bpy`` (``.venv-bpy``, with lsys3d's dependencies installed by ``make validators``)::

    .venv-bpy/bin/python tools/blender_addon_check.py SCRATCH_FOLDER

It registers the add-on from this checkout, grows plants with ``bpy.ops.lsys3d.add_plant``, saves and reopens
the file and regrows, asks for a bad grammar, and prints one line ``LSYS3D-ADDON {json}``: the counts read
back from Blender's own data (the evaluated depsgraph for the instances).
"""

import importlib.util
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def _assets():
    """``lsys3d.assets`` is the repository's ``assets/`` folder (pyproject's package-dir): map it as the
    editable install does, for a Python that runs lsys3d from the checkout."""
    try:
        importlib.import_module("lsys3d.assets")
    except ModuleNotFoundError:
        spec = importlib.util.spec_from_file_location(
            "lsys3d.assets", REPO / "assets" / "__init__.py", submodule_search_locations=[str(REPO / "assets")]
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules["lsys3d.assets"] = module
        spec.loader.exec_module(module)


import bpy  # noqa: E402
import numpy as np  # noqa: E402

_assets()
import lsys3d  # noqa: E402
import lsys3d.blender  # noqa: E402
from lsys3d.blender import operators  # noqa: E402
from lsys3d.blender.recipe import RECIPE_KEY  # noqa: E402
from lsys3d.blender.scene import Y_TO_Z  # noqa: E402


def counts(plant) -> dict:
    """The plant's bark, its leaves (instances realised by the depsgraph, and meshes) and what else it has."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    leaves = {"vertices": 0, "faces": 0, "instances": 0}
    parts = {child.name: child.get("lsys3d_part") for child in plant.children_recursive}
    for inst in depsgraph.object_instances:
        owner = inst.parent.original if inst.is_instance else inst.object.original
        part = owner.get("lsys3d_part")
        if part not in ("leaves", "leaf_polygons") or owner.parent != plant:
            continue
        if inst.is_instance or (
            inst.object.type == "MESH" and inst.object.data.attributes.get("lsys3d_transform") is None
        ):
            mesh = inst.object.data
            leaves["vertices"] += len(mesh.vertices)
            leaves["faces"] += len(mesh.polygons)
            leaves["instances"] += int(inst.is_instance)
    data = plant.data
    positions = np.zeros(3 * len(data.vertices), np.float32)
    data.vertices.foreach_get("co", positions)
    out = {
        "name": plant.name,
        "vertices": len(data.vertices),
        "faces": len(data.polygons),
        "leaves": leaves,
        "parts": sorted(set(parts.values())),
        "uv": [layer.name for layer in data.uv_layers],
        "custom_normals": bool(data.has_custom_normals),
        "materials": [m.name for m in data.materials],
        "attributes": sorted(a.name for a in data.attributes if not a.name.startswith(".")),
        "vertex_groups": len(plant.vertex_groups),
        "z_extent": [float(positions[2::3].min()), float(positions[2::3].max())] if len(positions) else [0, 0],
        "position_sum": float(np.abs(positions.astype(np.float64)).sum()),
        "recipe": json.loads(plant[RECIPE_KEY]),
    }
    arms = [c for c in plant.children if c.type == "ARMATURE"]
    if arms:
        out["bones"] = len(arms[0].data.bones)
    return out


def organ_counts(plant) -> dict:
    """The organ instances the depsgraph realises under the plant, and their vertices and faces."""
    out = {"instances": 0, "vertices": 0, "faces": 0}
    for inst in bpy.context.evaluated_depsgraph_get().object_instances:
        owner = inst.parent.original if inst.is_instance else None
        if owner is not None and owner.get("lsys3d_part") == "organs" and owner.parent == plant:
            out["instances"] += 1
            out["vertices"] += len(inst.object.data.vertices)
            out["faces"] += len(inst.object.data.polygons)
    return out


def skinning(plant) -> dict:
    """Pose two trunk bones; the bark Blender deforms against lsys3d's skin (joints and weights per vertex)
    blended by hand with the bones' deform matrices: the vertex groups hold the weights lsys3d computed."""
    tree = operators._state["last"][1]
    armature = next(c for c in plant.children if c.type == "ARMATURE")
    for name in [n for n in tree.rig.names if n.startswith("b0_")][1:3]:
        bone = armature.pose.bones[name]
        bone.rotation_mode = "XYZ"
        bone.rotation_euler = (0.3, 0.0, 0.2)
    bpy.context.view_layer.update()
    mesh = plant.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    posed = np.zeros(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", posed)
    deform = np.array([np.asarray(b.matrix @ b.bone.matrix_local.inverted()) for b in
                       (armature.pose.bones[n] for n in tree.rig.names)])  # fmt: skip
    rest = np.asarray(tree.bark.vertices) @ Y_TO_Z.T
    joints = np.asarray(tree.bark.attributes["skin_joints"], np.int64)
    weights = np.asarray(tree.bark.attributes["skin_weights"], np.float64)
    weights = weights / weights.sum(1, keepdims=True)
    moved = np.einsum("vkij,vj->vki", deform[joints][:, :, :3, :3], rest) + deform[joints][:, :, :3, 3]
    expected = (moved * weights[:, :, None]).sum(1)
    return {
        "max_error": float(np.abs(posed.reshape(-1, 3) - expected).max()),
        "max_moved": float(np.abs(expected - rest).max()),
    }


def wind(plant) -> dict:
    """The wind action's frames, and how far the bark moves from its rest at a quarter of the loop and at its end."""
    armature = next(c for c in plant.children if c.type == "ARMATURE")
    scene = bpy.context.scene

    def bark_at(frame):
        scene.frame_set(frame)
        mesh = plant.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
        out = np.zeros(3 * len(mesh.vertices), np.float32)
        mesh.vertices.foreach_get("co", out)
        return out.reshape(-1, 3)

    start, end = scene.frame_start, scene.frame_end
    rest = bark_at(start)
    quarter = bark_at(start + (end - start) // 4)
    last = bark_at(end)
    return {
        "action": armature.animation_data.action.name,
        "frames": [start, end],
        "fps": scene.render.fps,
        "moved_quarter": float(np.abs(quarter - rest).max()),
        "moved_end": float(np.abs(last - rest).max()),
    }


def _bbox_at(obj, frame):
    bpy.context.scene.frame_set(frame)
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    points = np.zeros(3 * len(mesh.vertices), np.float32)
    mesh.vertices.foreach_get("co", points)
    points = points.reshape(-1, 3) @ np.asarray(obj.matrix_world)[:3, :3].T + np.asarray(obj.matrix_world)[:3, 3]
    return np.concatenate([points.min(0), points.max(0)])


def wind_as_gltf(plant, scratch: Path) -> dict:
    """The plant's bark at a quarter of the wind loop, against the same tree written by lsys3d's glTF writer
    and read by Blender's glTF importer (its own skinning and animation): their boxes, side by side."""
    tree = operators._state["last"][1]
    path = scratch / "wind.glb"
    lsys3d.export(tree, path)
    scene = bpy.context.scene
    frame = scene.frame_start + (scene.frame_end - scene.frame_start) // 4
    ours = _bbox_at(plant, frame)
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=str(path))
    imported = [o for o in set(bpy.data.objects) - before if o.type == "MESH" and len(o.data.vertices)]
    bark = max(imported, key=lambda o: len(o.data.polygons) if "bark" in o.name.lower() else -1)
    scene.frame_start, scene.frame_end = 1, round(tree.animation.times[-1] * tree.animation.fps) + 1
    theirs = _bbox_at(bark, frame - 1)  # the importer keys time 0 on frame 0; the add-on on frame 1, the scene's first
    rest = _bbox_at(plant, scene.frame_start)
    report = {"ours": ours.tolist(), "gltf": theirs.tolist(), "rest": rest.tolist(), "bark": bark.name}
    for obj in set(bpy.data.objects) - before:
        bpy.data.objects.remove(obj)
    return report


def textures(plant) -> dict:
    """The images of the plant's materials (bark and leaf models): name, size and whether packed."""
    images = []
    for obj in [plant, *plant.children_recursive]:
        for material in obj.data.materials if obj.type == "MESH" else ():
            for node in material.node_tree.nodes:
                if node.type == "TEX_IMAGE" and node.image is not None:
                    image = node.image
                    images.append([image.name, list(image.size), image.packed_file is not None])
    return {"name": plant.name, "images": sorted(images)}


def _error(call) -> str:
    try:
        result = call()
    except RuntimeError as exc:  # bpy.ops raises the operator's error reports
        return str(exc)
    return f"no error: {result}"


def doc_examples(scratch: Path) -> int:
    """Run docs/blender.md's ``py`` blocks in order, in one namespace, in ``scratch``; how many ran."""
    import os
    import re

    text = (REPO / "docs" / "blender.md").read_text(encoding="utf-8")
    namespace = {"__name__": "__doc_example__"}
    here = os.getcwd()
    os.chdir(scratch)
    try:
        found = list(re.finditer(r"```py\n(.*?)```", text, re.DOTALL))
        for m in found:
            line = text.count("\n", 0, m.start()) + 2
            exec(compile("\n" * (line - 1) + m.group(1), "docs/blender.md", "exec"), namespace)
    finally:
        os.chdir(here)
    return len(found)


def main(scratch: Path) -> None:
    report = {"doc_examples": doc_examples(scratch), "doc_export": (scratch / "tree3d.glb").is_file()}
    bpy.ops.wm.read_factory_settings(use_empty=True)  # the add-on's classes stay registered
    if not hasattr(bpy.types, "LSYS3D_OT_add_plant"):
        lsys3d.blender.register()
    t0 = time.perf_counter()
    # the menu's click: every property at its default, which is tree3d at seed 0 (the recipe says so, and
    # test_blender_addon.py checks it): the plant the next checks read, grown once
    assert bpy.ops.lsys3d.add_plant() == {"FINISHED"}
    report["add_seconds"] = time.perf_counter() - t0
    report["timings"] = operators.timings()
    tree3d = bpy.context.active_object
    report["default_preset"] = json.loads(tree3d[RECIPE_KEY])["preset"]
    report["tree3d"] = counts(tree3d)
    report["z_up_cursor"] = list(tree3d.location)

    bpy.ops.lsys3d.add_plant(preset="koch-stochastic", seed=0)
    report["stochastic_0"] = counts(bpy.context.active_object)
    bpy.ops.lsys3d.add_plant(preset="koch-stochastic", seed=1)
    report["stochastic_1"] = counts(bpy.context.active_object)

    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0, rig=True, iterations=4)
    report["rigged"] = counts(bpy.context.active_object)
    report["skinning"] = skinning(bpy.context.active_object)
    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0, rig=True, iterations=4, wind=2.0)
    report["wind"] = wind(bpy.context.active_object)
    report["wind_gltf"] = wind_as_gltf(bpy.context.active_object, scratch)
    report["wind_without_rig"] = _error(lambda: bpy.ops.lsys3d.add_plant(preset="tree3d", iterations=3, wind=2.0))

    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0, iterations=4, attributes=True)
    with_attributes = bpy.context.active_object
    report["attributes"] = counts(with_attributes)
    leaves = next(c for c in with_attributes.children if c.get("lsys3d_part") == "leaves")
    report["leaf_point_attributes"] = sorted(a.name for a in leaves.data.attributes if not a.name.startswith("."))

    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0, lod=2)
    report["lod_2"] = counts(bpy.context.active_object)

    # a slow union: the redo panel's change shows the soup, and the timer (run here by hand: a background
    # Blender runs no timers) replaces it by the unioned plant
    operators._state.update(timers=True, union_seconds=10.0)
    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0)
    soup = bpy.context.active_object
    report["soup"] = counts(soup)
    operators._state["settle"]()
    report["settled"] = counts(soup)
    operators._state.update(timers=False)

    organs = scratch / "organs.toml"
    organs.write_text('axiom = "_(0.05)F(1)[+F(1)@O(0.2)][-F(1)@O(0.3)]"\ndialect = "lpy"\niterations = 0\n')
    bpy.ops.lsys3d.add_plant(grammar_file=str(organs))
    report["organs"] = organ_counts(bpy.context.active_object)

    bpy.ops.lsys3d.add_plant(preset="fern", seed=0)
    report["textured"] = textures(bpy.context.active_object)
    bpy.ops.lsys3d.add_plant(preset="fern", seed=0, textures=False)
    report["untextured"] = textures(bpy.context.active_object)

    bad = scratch / "bad.toml"
    bad.write_text('axiom = "F"\niterations = 2\nrules = ["F -> F[+F]F]"]\n')
    report["bad_grammar"] = _error(lambda: bpy.ops.lsys3d.add_plant(grammar_file=str(bad)))
    report["missing_grammar"] = _error(lambda: bpy.ops.lsys3d.add_plant(grammar_file=str(scratch / "none.toml")))

    glb = scratch / "tree3d.glb"
    bpy.context.view_layer.objects.active = tree3d
    assert bpy.ops.lsys3d.export(filepath=str(glb)) == {"FINISHED"}
    report["exported"] = glb.stat().st_size

    blend = scratch / "plants.blend"
    bpy.ops.wm.save_mainfile(filepath=str(blend))
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    plant = bpy.data.objects[report["tree3d"]["name"]]
    report["reopened"] = counts(plant)
    report["textured_reopened"] = textures(bpy.data.objects[report["textured"]["name"]])
    bpy.context.view_layer.objects.active = plant
    t0 = time.perf_counter()
    assert bpy.ops.lsys3d.regrow() == {"FINISHED"}
    report["regrow_seconds"] = time.perf_counter() - t0
    report["regrown"] = counts(plant)
    # the panel's other seed, on the stochastic plant (another seed grows another plant there; tree3d's
    # would cost its union again for the same recipe check)
    stochastic = bpy.data.objects[report["stochastic_1"]["name"]]
    bpy.context.view_layer.objects.active = stochastic
    assert bpy.ops.lsys3d.regrow(seed=5) == {"FINISHED"}
    report["regrown_seed_5"] = counts(stochastic)
    print("LSYS3D-ADDON " + json.dumps(report), flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[-1]))
