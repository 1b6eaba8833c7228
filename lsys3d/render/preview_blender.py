"""Render a ``.glb`` to a PNG inside Blender: the Blender side of :mod:`lsys3d.render.preview`.

This file runs in Blender's Python, not in lsys3d's: it imports only ``bpy``,
the numpy that every Blender bundles and the standard library (never lsys3d,
which Blender's Python need not have).
:func:`lsys3d.render.preview.preview` runs it in a child process, either as

    blender --background --factory-startup --python-exit-code 1 --python preview_blender.py -- JSON

or, with the ``bpy`` module, as ``python preview_blender.py -- JSON``.  ``JSON`` ``-``
reads the job as one line of standard input once ``bpy`` is loaded (so that
Blender starts while lsys3d still grows the tree; end of input without a job:
nothing to do).  The job is one object: ``glb`` (the scene), ``png`` (the image to write), ``width``,
``height``, ``view`` (``front``, ``side`` or ``iso``), ``quality`` (``draft``: the
Workbench engine; ``final``: Cycles), ``samples``, ``denoise``,
``background`` (sRGB, 3 floats in [0, 1]), ``margin`` (fraction of the frame
left around the object), ``threads`` (0: all cores), ``material`` (``asset``,
or ``checker``: the material named ``bark_material`` becomes glossy with a UV
checker), for a close-up ``focus``: ``target``, ``direction`` (towards the
camera) and ``size`` (the picture's width), in glTF's frame, and ``pose``
(optional: joint name -> degrees, each pose bone of a rigged tree turned about
its X axis before the camera is fitted), and ``time`` (optional: seconds into the tree's ``growth`` animation,
pictured with the camera fitted to the grown tree, the animation's last frame).

The scene: the glTF import (Blender turns glTF's Y up into its Z up, so the
tree stands on the XY plane), a perspective camera fitted to every mesh vertex
for the chosen view.  ``draft``: the Workbench engine rasterises it with a
studio light and the colours of the materials' textures (through EGL and a
software OpenGL when there is no GPU), antialiased by FXAA.  ``final``: a sun
and a sky light the object and Cycles
renders on the CPU (it needs no display and no GPU); either with a transparent film,
into a scratch RGBA file beside the ``.glb``; the image is then laid over the
flat ``background`` colour and written as 8-bit RGB.  Colour management is
Blender's "Standard" view, so colours come out as the materials give them.
"""

import array
import json
import math
import os
import sys

#: Camera direction per view, Blender frame (Z up; glTF's front, +Z, is Blender's -Y):
#: (azimuth from -Y towards +X, elevation above the horizon), in degrees.
VIEWS = {"front": (0.0, 4.0), "side": (90.0, 4.0), "iso": (45.0, 30.0)}
LENS_MM = 50.0
SUN_DIRECTION = (-0.45, -0.6, 0.66)  # towards the sun: up, in front, to the left of the camera


def _direction(view):
    azimuth, elevation = (math.radians(a) for a in VIEWS[view])
    # from the object towards the camera
    return (
        math.sin(azimuth) * math.cos(elevation),
        -math.cos(azimuth) * math.cos(elevation),
        math.sin(elevation),
    )


def _mesh_points(bpy):
    """World coordinates of every mesh vertex (instances included), as a flat list."""
    from mathutils import Vector

    depsgraph = bpy.context.evaluated_depsgraph_get()
    coords = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != "MESH":
            continue
        mesh = obj.data
        flat = array.array("f", bytes(4 * 3 * len(mesh.vertices)))
        mesh.vertices.foreach_get("co", flat)
        matrix = inst.matrix_world
        step = 3 * max(1, len(mesh.vertices) // 50000)  # a fit does not need every vertex of a huge mesh
        for i in range(0, len(flat), step):
            coords.extend(matrix @ Vector(flat[i : i + 3]))
    return coords


def _world(bpy, scene):
    """A pale blue sky that lights the object from everywhere (the camera sees through it: film is transparent)."""
    world = bpy.data.worlds.new("preview")
    scene.world = world
    if world.node_tree is None:  # Blender < 5 makes node trees on request; 5.0 deprecates the switch
        world.use_nodes = True
    nodes = world.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputWorld")
    sky = nodes.new("ShaderNodeBackground")
    sky.inputs["Color"].default_value = (0.75, 0.82, 1.0, 1.0)
    sky.inputs["Strength"].default_value = 0.6
    world.node_tree.links.new(sky.outputs["Background"], out.inputs["Surface"])


def _flatten(bpy, scene, rendered, png, background):
    """Lay the transparent render ``rendered`` over the flat sRGB ``background``; write ``png`` as 8-bit RGB.

    Cycles' denoiser speckles even a flat background, so the camera sees
    none (transparent film) and the background colour is put in here, exactly.
    """
    import numpy as np  # every Blender bundles numpy

    image = bpy.data.images.load(rendered)
    width, height = image.size
    rgba = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(rgba)  # straight alpha, sRGB-encoded values of the 8-bit file
    rgba = rgba.reshape(-1, 4)
    alpha = rgba[:, 3:]
    rgba[:, :3] = rgba[:, :3] * alpha + np.asarray(background, np.float32) * (1.0 - alpha)
    rgba[:, 3] = 1.0
    flat = bpy.data.images.new("preview", width, height, alpha=False)
    flat.pixels.foreach_set(rgba.ravel())
    scene.render.image_settings.color_mode = "RGB"
    flat.save_render(png, scene=scene)


def _camera(bpy, scene, view, margin):
    from mathutils import Vector

    data = bpy.data.cameras.new("preview")
    camera = bpy.data.objects.new("preview", data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    direction = Vector(_direction(view))
    camera.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    points = _mesh_points(bpy)
    if not points:
        raise RuntimeError("preview_blender: the scene holds no mesh to frame")
    # Fit with a longer lens, then widen it: the object fills (1 - margin) of the frame.
    data.lens = LENS_MM / (1.0 - margin)
    bpy.context.view_layer.update()
    location, _ = camera.camera_fit_coords(bpy.context.evaluated_depsgraph_get(), points)
    camera.location = location
    data.lens = LENS_MM
    xs, ys, zs = points[0::3], points[1::3], points[2::3]
    size = max(max(xs) - min(xs), max(ys) - min(ys), max(zs) - min(zs), 1e-6)
    distance = (
        Vector(location) - Vector(((max(xs) + min(xs)) / 2, (max(ys) + min(ys)) / 2, (max(zs) + min(zs)) / 2))
    ).length
    data.clip_start = max(distance - 2 * size, distance * 1e-3)
    data.clip_end = distance + 2 * size


def _blender_frame(v):
    """glTF (Y up) to Blender (Z up), as the glTF importer turns the scene."""
    return (v[0], -v[2], v[1])


def _focus_camera(bpy, scene, focus):
    """A camera looking at ``focus['target']`` from ``focus['direction']``, the picture ``focus['size']`` wide."""
    from mathutils import Vector

    data = bpy.data.cameras.new("preview")
    camera = bpy.data.objects.new("preview", data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    data.lens = LENS_MM
    target = Vector(_blender_frame(focus["target"]))
    direction = Vector(_blender_frame(focus["direction"])).normalized()
    half_angle = math.atan(0.5 * data.sensor_width / LENS_MM)
    distance = 0.5 * focus["size"] / math.tan(half_angle)
    camera.location = target + distance * direction
    camera.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    data.clip_start = distance * 1e-3
    data.clip_end = distance * 1e3


def _checker(bpy, name):
    """Give the material ``name`` a glossy surface with a UV checker: 8 x 8 squares per texture tile."""
    material = bpy.data.materials.get(name)
    if material is None:
        return
    if material.node_tree is None:  # Blender < 5 makes node trees on request
        material.use_nodes = True
    nodes = material.node_tree.nodes
    links = material.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    shader = nodes.new("ShaderNodeBsdfPrincipled")
    shader.inputs["Roughness"].default_value = 0.18
    shader.inputs["Metallic"].default_value = 0.0
    checker = nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 8.0
    checker.inputs["Color1"].default_value = (0.85, 0.82, 0.75, 1.0)
    checker.inputs["Color2"].default_value = (0.12, 0.14, 0.2, 1.0)
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["UV"], checker.inputs["Vector"])
    links.new(checker.outputs["Color"], shader.inputs["Base Color"])
    links.new(shader.outputs["BSDF"], out.inputs["Surface"])


def _sun(bpy, scene):
    from mathutils import Vector

    light = bpy.data.lights.new("sun", "SUN")
    light.energy = 3.0
    light.angle = math.radians(8.0)  # soft shadow edges
    sun = bpy.data.objects.new("sun", light)
    scene.collection.objects.link(sun)
    sun.rotation_euler = (-Vector(SUN_DIRECTION)).to_track_quat("-Z", "Y").to_euler()


def _pose(bpy, bends):
    """Turn the pose bones named in ``bends`` (name -> degrees about the bone's X axis)."""
    bones = {}
    for armature in (o for o in bpy.data.objects if o.type == "ARMATURE"):
        for bone in armature.pose.bones:
            bones[bone.name] = bone
    missing = sorted(set(bends) - set(bones))
    if missing:
        raise RuntimeError(f"preview_blender: no joint named {', '.join(missing)} (is the tree rigged?)")
    for name, degrees in bends.items():
        bones[name].rotation_mode = "XYZ"
        bones[name].rotation_euler = (math.radians(degrees), 0.0, 0.0)
    bpy.context.view_layer.update()


def _growth_action(bpy, scene):
    """Make the glTF ``growth`` animation the armature's action; its last frame (None without one)."""
    actions = [a for a in bpy.data.actions if a.name.startswith("growth")]
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    if not actions or not armatures:
        raise RuntimeError("preview_blender: the tree has no growth animation (--growth-animation)")
    for armature in armatures:
        armature.animation_data_create().action = actions[0]
        slots = getattr(actions[0], "slots", None)  # Blender 4.4+: the action's slot for this object
        if slots:
            armature.animation_data.action_slot = slots[0]
    return actions[0].frame_range[1]


def _workbench(bpy, scene):
    """The draft look: Workbench, studio light, the textures' colours (a material without one: its own colour)."""
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.render_aa = "FXAA"  # one sample, smoothed: the multi-sample modes take 2-4 times as long
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "TEXTURE"
    shading.show_backface_culling = False
    for material in bpy.data.materials:  # Workbench shows an untextured material in its viewport colour
        tree = material.node_tree
        shader = tree and next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
        if shader is not None:
            material.diffuse_color = tuple(shader.inputs["Base Color"].default_value)


def _cycles(bpy, scene, job):
    """The final look: Cycles on the CPU, ``samples`` per pixel, denoised; a sun and a sky."""
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = job["samples"]
    cycles.use_adaptive_sampling = True
    cycles.max_bounces = 4
    cycles.diffuse_bounces = 2
    cycles.glossy_bounces = 1
    cycles.transmission_bounces = 2
    cycles.transparent_max_bounces = 4
    cycles.seed = 0  # the same noise on every run
    # OpenImageDenoise is in Blender's builds for x86-64 and arm64; without it, render the noise
    cycles.use_denoising = bool(job["denoise"]) and getattr(bpy.app.build_options, "openimagedenoise", True)
    if cycles.use_denoising:
        cycles.denoiser = "OPENIMAGEDENOISE"
    _world(bpy, scene)
    _sun(bpy, scene)


def _linear(srgb):
    """An sRGB value in [0, 1] as the linear value Blender's colours hold."""
    return srgb / 12.92 if srgb <= 0.04045 else ((srgb + 0.055) / 1.055) ** 2.4


def render(job, fresh=False):
    """Render the job; ``fresh``: Blender's factory settings are loaded already (a started session)."""
    import bpy

    if not fresh:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=job["glb"])
    if not any(o.type == "MESH" for o in scene.objects):
        raise RuntimeError(f"preview_blender: {job['glb']}: Blender imported no mesh")
    for obj in list(scene.objects):  # a pruning volume of the scene (--scene) would hide the plant it shapes
        if obj.type == "MESH" and obj.name.startswith("volume_"):
            bpy.data.objects.remove(obj)
    if job.get("pose"):
        _pose(bpy, job["pose"])
    if job.get("time") is not None:
        scene.frame_set(round(_growth_action(bpy, scene)))  # the camera frames the grown tree

    render = scene.render
    render.resolution_x, render.resolution_y = job["width"], job["height"]
    render.resolution_percentage = 100
    render.film_transparent = True
    render.use_file_extension = False
    if job.get("threads"):
        render.threads_mode = "FIXED"
        render.threads = job["threads"]
    render.image_settings.file_format = "PNG"
    render.image_settings.color_mode = "RGBA"
    render.image_settings.color_depth = "8"
    render.image_settings.compression = 100
    render.dither_intensity = 0.0  # dither noise would defeat the PNG compression and the flat background
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"

    if job.get("material") == "checker":
        _checker(bpy, job.get("bark_material", "bark"))
    if job.get("focus"):
        _focus_camera(bpy, scene, job["focus"])
    else:
        _camera(bpy, scene, job["view"], job["margin"])
    if job.get("time") is not None:
        scene.frame_set(round(job["time"] * scene.render.fps / scene.render.fps_base))
    if job.get("quality", "final") == "final" or job.get("material") == "checker":  # Workbench shows no checker
        _cycles(bpy, scene, job)
    else:
        # Workbench draws the world's colour behind the tree, exactly and without noise: no second pass
        _workbench(bpy, scene)
        render.film_transparent = False
        scene.world = bpy.data.worlds.new("preview")
        scene.world.color = tuple(_linear(c) for c in job["background"])
        render.image_settings.color_mode = "RGB"
        render.image_settings.compression = 15  # a draft: written fast rather than small
        for name in dir(render):  # no metadata (the date, the render time): the same picture, the same bytes
            if name.startswith("use_stamp") and isinstance(getattr(render, name), bool):
                setattr(render, name, False)
        render.filepath = job["png"]
        bpy.ops.render.render(write_still=True)
        return

    rendered = os.path.join(os.path.dirname(job["glb"]), "rendered.png")  # lsys3d's temporary folder
    render.filepath = rendered
    bpy.ops.render.render(write_still=True)
    _flatten(bpy, scene, rendered, job["png"], job["background"])


def main(argv):
    if "--" not in argv:
        raise SystemExit("usage: preview_blender.py -- JSON")
    text = argv[argv.index("--") + 1]
    fresh = text == "-"
    if fresh:  # the job comes once Blender is loaded: lsys3d grows the tree meanwhile
        import bpy  # the slow part of the start

        bpy.ops.wm.read_factory_settings(use_empty=True)
        text = sys.stdin.readline()
        if not text.strip():
            return
    render(json.loads(text), fresh)


if __name__ == "__main__":
    main(sys.argv)
