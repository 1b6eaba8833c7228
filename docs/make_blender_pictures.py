"""The pictures of docs/blender.md, made by Blender itself with the add-on (run by the Python with ``bpy``).

    PYTHONPATH=. .venv-bpy/bin/python docs/make_blender_pictures.py [add_plant seeds rig]

Each picture is a fresh scene: the add-on's ``bpy.ops.lsys3d.add_plant`` (or ``regrow``) makes the plants,
exactly as an artist's click would, and Cycles renders them on the CPU with the lighting of ``lsys3d
preview`` (:mod:`lsys3d.render.preview_blender`).
"""

import math
import sys
import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent / "tools"))
import blender_addon_check  # noqa: E402, F401  (the checkout's lsys3d, as the add-on's test runs it)
import bpy  # noqa: E402

import lsys3d.blender  # noqa: E402
from lsys3d.render import preview_blender as look  # noqa: E402

OUT = DOCS / "blender"
WIDTH, HEIGHT, SAMPLES = 960, 540, 24


def fresh():
    bpy.ops.wm.read_factory_settings(use_empty=True)  # the add-on's classes stay registered


def render(name: str, view: str = "iso", margin: float = 0.08) -> None:
    scene = bpy.context.scene
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = WIDTH, HEIGHT, 100
    r.film_transparent = True
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGBA"
    r.dither_intensity = 0.0
    scene.view_settings.view_transform = "Standard"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    scene.cycles.seed = 0
    scene.cycles.use_denoising = getattr(bpy.app.build_options, "openimagedenoise", True)
    look._world(bpy, scene)
    look._sun(bpy, scene)
    look._camera(bpy, scene, view, margin)
    with tempfile.TemporaryDirectory() as scratch:
        rendered = str(Path(scratch) / "rendered.png")
        r.filepath = rendered
        bpy.ops.render.render(write_still=True)
        look._flatten(bpy, scene, rendered, str(OUT / f"{name}.png"), (1.0, 1.0, 1.0))
    print(f"wrote {OUT / name}.png")


def main() -> None:
    OUT.mkdir(exist_ok=True)
    lsys3d.blender.register()
    wanted = set(sys.argv[1:]) or {"add_plant", "seeds", "rig"}
    # 1. Add > Mesh > L-system plant, the defaults: tree3d, its leaves instanced by geometry nodes
    if "add_plant" in wanted:
        fresh()
        bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0)
        render("add_plant")
    # 2. A species with its textures (image nodes), three seeds side by side, as the sidebar's New seed gives
    if "seeds" in wanted:
        fresh()
        for i, seed in enumerate((0, 1, 2)):
            bpy.context.scene.cursor.location = (i * 4.5, 0.0, 0.0)
            bpy.ops.lsys3d.add_plant(preset="hazel", seed=seed)
        render("seeds", view="front", margin=0.04)
    if "rig" not in wanted:
        return
    # 3. The rig: an armature with the skin as vertex groups; two bones turned in pose mode bend the tree
    fresh()
    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0, rig=True)
    armature = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    trunk = [b for b in armature.pose.bones if b.name.startswith("b0_")]  # branch 0: the trunk
    for bone in trunk[1:3]:
        bone.rotation_mode = "XYZ"
        bone.rotation_euler = (0.0, 0.0, math.radians(15.0))
    bpy.context.view_layer.update()
    render("rig", view="front")


if __name__ == "__main__":
    main()
