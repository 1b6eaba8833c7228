"""lsys3d as a Blender add-on: Add > Mesh > L-system plant, regrown live, the plant as Blender data.

Importable only inside Blender (or with the ``bpy`` module)::

    import lsys3d.blender
    lsys3d.blender.register()
    bpy.ops.lsys3d.add_plant(preset="tree3d", seed=0)

:mod:`~lsys3d.blender.recipe` is the plant's recipe (plain data), :mod:`~lsys3d.blender.scene` builds Blender
data from a tree's arrays, :mod:`~lsys3d.blender.operators` holds the operators and the sidebar panel.
``make blender-extension`` packs it as a Blender extension (``tools/blender_extension.py``); docs/blender.md
tells how to use it.
"""

from __future__ import annotations

import bpy

from .operators import CLASSES, menu_add

__all__ = ["register", "unregister"]


def register() -> None:
    """Register the operators, the panel and the Add > Mesh menu entry."""
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.VIEW3D_MT_mesh_add.append(menu_add)


def unregister() -> None:
    """Undo :func:`register`."""
    bpy.types.VIEW3D_MT_mesh_add.remove(menu_add)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
