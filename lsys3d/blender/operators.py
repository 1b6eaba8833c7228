"""The add-on's operators and panel: Add > Mesh > L-system plant, regrow, export.

- ``lsys3d.add_plant`` (:class:`LSYS3D_OT_add_plant`): grows a plant from a preset or a grammar file and puts it
  at the 3D cursor.  Its redo panel regrows it on every change; when the union took long the last time
  (:data:`SOUP_SECONDS`), a change shows the tube soup at once and the unioned asset replaces it once the
  artist has stopped changing values for :data:`SETTLE_SECONDS` (a timer).
- ``lsys3d.regrow`` (:class:`LSYS3D_OT_regrow`): the selected plant again from its recipe (kept on the object,
  :data:`~lsys3d.blender.recipe.RECIPE_KEY`), with another seed or iterations.
- ``lsys3d.export`` (:class:`LSYS3D_OT_export`): the selected plant through lsys3d's own writers (.glb, .usd*).
- The sidebar panel (N panel, tab ``lsys3d``, :class:`LSYS3D_PT_plant`) shows the selected plant's recipe and
  those three buttons.

A user's error (a bad grammar, a missing file, a size limit) is reported as Blender reports errors, with
lsys3d's ``file:line:col: what`` message, and the operator is cancelled; no traceback reaches the user.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import bpy
from bpy.props import BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from ..errors import LSystemError
from ..exchange import SUPPORTED_SUFFIXES, export
from ..lsystem.presets import list_presets, preset_info
from . import scene
from .recipe import LOD_LEVELS, RECIPE_KEY, Recipe, grammar_of, grow, numeric_defines

__all__ = ["CLASSES", "menu_add", "timings"]

log = logging.getLogger("lsys3d")

FIRST_PRESET = "tree3d"
"""The preset Add > Mesh > L-system plant grows unless another is chosen."""

SOUP_SECONDS = 0.5
"""A union slower than this makes the redo panel show the tube soup first."""

SETTLE_SECONDS = 0.6
"""How long the redo panel's values must stay still before the soup is replaced by the unioned plant."""

_state = {"union_seconds": 0.0, "pending": 0, "last": None, "timers": not bpy.app.background, "settle": None}
"""The last union's time, the pending full growth's ticket, the last grown ``(recipe JSON, tree)``, whether
timers run (not in a background Blender, which has no event loop) and the last timer's function."""


def timings() -> dict:
    """The last growth's seconds: ``grow`` (lsys3d), ``scene`` (building Blender data) and ``total``."""
    return dict(_state.get("timings", {}))


def _preset_items(self, context):
    # kept referenced: Blender's enum callbacks must not return strings Python may free
    if "items" not in _state:  # the first item is the default: the textbook tree, quick to grow
        names = sorted(list_presets(), key=lambda name: name != FIRST_PRESET)
        _state["items"] = [(name, name, preset_info(name).description) for name in names]
    return _state["items"]


def _blend_folder() -> str | None:
    return str(Path(bpy.data.filepath).parent) if bpy.data.filepath else None


def _grammar_path(path: str) -> str:
    return bpy.path.abspath(path) if path.startswith("//") else path


def _grow_into(recipe: Recipe, collection, plant=None, location=None):
    """Grow ``recipe`` and build (or rebuild) its plant; the plant's object."""
    t0 = time.perf_counter()
    stage_seconds = {}

    def progress(stage, event, seconds):
        if event == "done":
            stage_seconds[stage] = stage_seconds.get(stage, 0.0) + seconds

    tree, _ = grow(recipe, _blend_folder(), progress=progress)
    t1 = time.perf_counter()
    if recipe.union:
        _state["union_seconds"] = stage_seconds.get("union", 0.0) + stage_seconds.get("cleanup", 0.0)
    _state["last"] = (recipe.to_json(), tree)
    obj = scene.build(tree, recipe.name, collection, leaves=recipe.leaves, textures=recipe.textures, plant=plant)
    obj[RECIPE_KEY] = recipe.to_json()
    if location is not None:
        obj.location = location
    t2 = time.perf_counter()
    _state["timings"] = {"grow": t1 - t0, "scene": t2 - t1, "total": t2 - t0, "stages": stage_seconds}
    log.info("lsys3d: %s grown in %.3f s, built in Blender in %.3f s", recipe.name, t1 - t0, t2 - t1)
    return obj


def _report_error(op, exc: Exception) -> set:
    if isinstance(exc, LSystemError):
        op.report({"ERROR"}, str(exc))
    else:  # a bug of lsys3d's: said in one line; the traceback goes to the console's log
        log.exception("lsys3d: unexpected error")
        op.report({"ERROR"}, f"lsys3d: unexpected {type(exc).__name__}: {exc} (the console has the details)")
    return {"CANCELLED"}


def _select(context, obj) -> None:
    for other in context.selected_objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj


def _settle(name: str, recipe_json: str, ticket: int):
    """The timer that replaces the redo panel's soup by the unioned plant once the values stay still."""

    def finish():
        if _state["pending"] != ticket:  # the artist changed something since: that growth will do it
            return None
        obj = bpy.data.objects.get(name)
        if obj is None or obj.get(RECIPE_KEY) != Recipe.from_json(recipe_json).replace(union=False).to_json():
            return None
        recipe = Recipe.from_json(recipe_json)
        try:
            _grow_into(recipe, obj.users_collection[0], plant=obj)
        except LSystemError as exc:
            log.error("lsys3d: %s", exc)
        return None

    return finish


class LSYS3D_Define(bpy.types.PropertyGroup):
    """One numeric ``define`` of the grammar, as a slider."""

    name: StringProperty(name="Name")
    integer: BoolProperty(name="Integer", default=False)
    value: FloatProperty(name="Value", soft_min=-1000.0, soft_max=1000.0, precision=3)
    whole: IntProperty(name="Value", soft_min=0, soft_max=1000)
    grammar_value: FloatProperty(options={"HIDDEN"})

    def chosen(self) -> float | None:
        """The slider's value when the artist moved it, else None (the grammar's own value, exactly: a
        Blender float property is single precision, and 0.707 stored in one is not the file's 0.707)."""
        if self.integer:
            return None if self.whole == self.grammar_value else self.whole
        return None if self.value == self.grammar_value else self.value


_RECIPE_FIELDS = (
    "preset",
    "grammar_file",
    "iterations",
    "seed",
    "leaves",
    "union",
    "sides",
    "lod",
    "rig",
    "textures",
    "attributes",
    "wind",
)


class _RecipeProperties:
    """The recipe's properties, shared by the add and regrow operators."""

    preset: EnumProperty(name="Preset", items=_preset_items, description="A bundled preset or species")
    grammar_file: StringProperty(
        name="Grammar file", subtype="FILE_PATH", default="", description="A grammar file; overrides the preset"
    )
    iterations: IntProperty(name="Iterations", min=0, soft_max=12, default=0, description="0: the grammar's own")
    seed: IntProperty(name="Seed", min=0, default=0, description="Seed of stochastic rules and jitters")
    leaves: BoolProperty(name="Leaves", default=True, description="Leaves and organs")
    union: BoolProperty(name="Union", default=True, description="One watertight bark (off: the tube soup, fast)")
    sides: IntProperty(name="Sides", min=0, max=64, default=0, description="Tube sides of the trunk; 0: default")
    lod: IntProperty(name="LOD", min=0, max=LOD_LEVELS - 1, default=0, description="Level of detail (0: full)")
    rig: BoolProperty(name="Rig", default=False, description="An armature along the branches, with weights")
    textures: BoolProperty(name="Textures", default=True, description="The grammar's textures as image nodes")
    attributes: BoolProperty(
        name="Wind attributes",
        default=False,
        description="Hierarchy and wind attributes (branch_id, branch_t, phase, pivot...) on vertices and leaves",
    )
    wind: FloatProperty(
        name="Wind seconds",
        min=0.0,
        max=60.0,
        default=0.0,
        description="A looping sample wind animation keyed on the rig, this long (0: none; needs Rig)",
    )
    defines: CollectionProperty(type=LSYS3D_Define)
    defines_of: StringProperty(options={"HIDDEN", "SKIP_SAVE"})

    def recipe(self, with_defines: bool = True) -> Recipe:
        defines = {}
        if with_defines:
            defines = {d.name: d.chosen() for d in self.defines if d.chosen() is not None}
        return Recipe(
            preset=self.preset,
            grammar_file=_grammar_path(self.grammar_file),
            iterations=self.iterations,
            seed=self.seed,
            defines=defines,
            leaves=self.leaves,
            union=self.union,
            sides=self.sides,
            lod=self.lod,
            rig=self.rig,
            textures=self.textures,
            attributes=self.attributes,
            wind=self.wind,
        )

    def sync_defines(self) -> None:
        """Fill the define sliders from the grammar when the grammar changed (the first run, a new preset)."""
        plain = self.recipe(with_defines=False)
        key = plain.grammar_file or plain.preset
        if self.defines_of == key:
            return
        self.defines.clear()
        for name, value in numeric_defines(grammar_of(plain, _blend_folder())).items():
            item = self.defines.add()
            item.name = name
            item.integer = float(value).is_integer() and abs(value) < 2**31
            item.grammar_value = value
            if item.integer:
                item.whole = int(value)
            else:
                item.value = value
        self.defines_of = key

    def set_from(self, recipe: Recipe) -> None:
        for key in _RECIPE_FIELDS[2:]:
            setattr(self, key, getattr(recipe, key))
        if recipe.preset in list_presets():
            self.preset = recipe.preset
        self.grammar_file = recipe.grammar_file
        self.defines_of = ""
        self.sync_defines()
        for item in self.defines:
            if item.name in recipe.defines:
                value = recipe.defines[item.name]
                if item.integer:
                    item.whole = int(value)
                else:
                    item.value = value

    def draw_recipe(self, layout) -> None:
        col = layout.column()
        col.prop(self, "preset")
        col.prop(self, "grammar_file")
        col.prop(self, "iterations")
        col.prop(self, "seed")
        row = col.row(align=True)
        row.prop(self, "leaves", toggle=True)
        row.prop(self, "union", toggle=True)
        row.prop(self, "rig", toggle=True)
        row.prop(self, "textures", toggle=True)
        col.prop(self, "attributes")
        sub = col.row()
        sub.active = self.rig
        sub.prop(self, "wind")
        col.prop(self, "sides")
        col.prop(self, "lod")
        if len(self.defines):
            box = col.box()
            box.label(text="Defines")
            for item in self.defines:
                box.prop(item, "whole" if item.integer else "value", text=item.name)


class LSYS3D_OT_add_plant(_RecipeProperties, bpy.types.Operator):
    """Grow a plant from an L-system (a bundled preset or a grammar file)"""

    bl_idname = "lsys3d.add_plant"
    bl_label = "L-system plant"
    bl_options = {"REGISTER", "UNDO"}  # noqa: RUF012 (Blender reads the class attribute)

    def draw(self, context):
        self.draw_recipe(self.layout)

    def execute(self, context):
        try:
            self.sync_defines()
            recipe = self.recipe()
            soup = recipe.union and _state["union_seconds"] > SOUP_SECONDS and _state["timers"]
            shown = recipe.replace(union=False) if soup else recipe
            obj = _grow_into(shown, context.collection, location=context.scene.cursor.location.copy())
        except Exception as exc:
            return _report_error(self, exc)
        _select(context, obj)
        _state["pending"] += 1
        if soup:  # the unioned plant once the values stay still
            _state["settle"] = _settle(obj.name, recipe.to_json(), _state["pending"])
            bpy.app.timers.register(_state["settle"], first_interval=SETTLE_SECONDS)
        return {"FINISHED"}


def _plant(context):
    """The selected plant's object (an object with a recipe, or a part of one), or None."""
    obj = context.active_object
    while obj is not None and RECIPE_KEY not in obj:
        obj = obj.parent
    return obj


class LSYS3D_OT_regrow(_RecipeProperties, bpy.types.Operator):
    """Grow the selected plant again from its recipe, with this seed and these iterations"""

    bl_idname = "lsys3d.regrow"
    bl_label = "Regrow plant"
    bl_options = {"REGISTER", "UNDO"}  # noqa: RUF012 (Blender reads the class attribute)

    seed_step: IntProperty(options={"HIDDEN", "SKIP_SAVE"}, default=0)
    iterations_step: IntProperty(options={"HIDDEN", "SKIP_SAVE"}, default=0)

    @classmethod
    def poll(cls, context):
        return _plant(context) is not None

    def draw(self, context):
        self.draw_recipe(self.layout)

    def invoke(self, context, event):
        try:
            recipe = Recipe.from_json(_plant(context)[RECIPE_KEY])
            self.set_from(recipe)
        except Exception as exc:
            return _report_error(self, exc)
        self.seed = max(0, recipe.seed + self.seed_step)
        self.iterations = max(0, recipe.iterations + self.iterations_step)
        if self.iterations_step and not recipe.iterations:  # from the grammar's own
            own = grammar_of(recipe.replace(defines={}), _blend_folder()).iterations
            self.iterations = max(1, own + self.iterations_step)
        return self.execute(context)

    def execute(self, context):
        plant = _plant(context)
        try:
            if not self.defines_of:  # run without invoke (a script): the plant's recipe, then the values given
                given = {k: getattr(self, k) for k in _RECIPE_FIELDS if self.properties.is_property_set(k)}
                self.set_from(Recipe.from_json(plant[RECIPE_KEY]))
                for key, value in given.items():
                    setattr(self, key, value)
            self.sync_defines()
            collection = plant.users_collection[0] if plant.users_collection else context.collection
            _grow_into(self.recipe(), collection, plant=plant)
        except Exception as exc:
            return _report_error(self, exc)
        return {"FINISHED"}


_FORMATS = [(s, s, f"lsys3d's {s} writer") for s in (".glb", ".gltf", ".usdc", ".usda", ".usdz")]


class LSYS3D_OT_export(bpy.types.Operator, ExportHelper):
    """Write the selected plant with lsys3d's own writers (glTF binary or USD), for pipelines"""

    bl_idname = "lsys3d.export"
    bl_label = "Export plant"
    filename_ext = ".glb"
    filter_glob: StringProperty(default="*.glb;*.gltf;*.usdc;*.usda;*.usdz", options={"HIDDEN"})
    file_format: EnumProperty(name="Format", items=_FORMATS, default=".glb")

    @classmethod
    def poll(cls, context):
        return _plant(context) is not None

    def check(self, context):
        self.filename_ext = self.file_format
        return super().check(context)

    def execute(self, context):
        try:
            text = _plant(context)[RECIPE_KEY]
            last = _state["last"]
            tree = last[1] if last is not None and last[0] == text else grow(Recipe.from_json(text), _blend_folder())[0]
            path = Path(self.filepath)
            if path.suffix.lower() not in SUPPORTED_SUFFIXES:
                path = path.with_suffix(self.file_format)
            written = export(tree, path)
        except Exception as exc:
            return _report_error(self, exc)
        self.report({"INFO"}, f"lsys3d: wrote {written}")
        return {"FINISHED"}


class LSYS3D_PT_plant(bpy.types.Panel):
    """The sidebar panel: the selected plant's recipe, regrow and export."""

    bl_idname = "LSYS3D_PT_plant"
    bl_label = "L-system plant"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "lsys3d"

    def draw(self, context):
        layout = self.layout
        plant = _plant(context)
        if plant is None:
            layout.label(text="Select a plant, or add one:")
            layout.operator(LSYS3D_OT_add_plant.bl_idname, icon="ADD")
            return
        try:
            recipe = Recipe.from_json(plant[RECIPE_KEY])
        except LSystemError as exc:
            layout.label(text=str(exc), icon="ERROR")
            return
        col = layout.column(align=True)
        col.label(text=f"{recipe.name}", icon="OUTLINER_OB_MESH")
        col.label(text=f"Seed {recipe.seed}, iterations {recipe.iterations or 'as the grammar'}")
        row = layout.row(align=True)
        row.operator(LSYS3D_OT_regrow.bl_idname, text="Regrow", icon="FILE_REFRESH")
        step = row.operator(LSYS3D_OT_regrow.bl_idname, text="New seed", icon="MOD_NOISE")
        step.seed_step = 1
        row = layout.row(align=True)
        less = row.operator(LSYS3D_OT_regrow.bl_idname, text="Iterations -", icon="REMOVE")
        less.iterations_step = -1
        more = row.operator(LSYS3D_OT_regrow.bl_idname, text="Iterations +", icon="ADD")
        more.iterations_step = 1
        layout.operator(LSYS3D_OT_export.bl_idname, icon="EXPORT")


def menu_add(self, context):
    """Add > Mesh > L-system plant."""
    self.layout.operator(LSYS3D_OT_add_plant.bl_idname, text="L-system plant", icon="OUTLINER_OB_MESH")


CLASSES = (LSYS3D_Define, LSYS3D_OT_add_plant, LSYS3D_OT_regrow, LSYS3D_OT_export, LSYS3D_PT_plant)
"""Registered in this order (the define item before the operators that hold it)."""
