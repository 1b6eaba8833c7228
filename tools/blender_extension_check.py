"""Install lsys3d's extension zip into Blender (``bpy``) and use it: the Blender side of the extension's test.

    BLENDER_USER_RESOURCES=SCRATCH .venv-bpy/bin/python tools/blender_extension_check.py ZIP GRAMMAR

Installs ``ZIP`` as Blender's "Install from Disk" does (``bpy.ops.extensions.package_install_files``, into the
user repository under ``BLENDER_USER_RESOURCES``), then asks the installed add-on for a plant of the bad
``GRAMMAR`` (which fails before any kernel is compiled), and prints ``LSYS3D-EXTENSION {json}``.
"""

import json
import sys

import bpy

archive, grammar = sys.argv[-2], sys.argv[-1]
report = {"install": sorted(bpy.ops.extensions.package_install_files(filepath=archive, repo="user_default"))}
report["enabled"] = "bl_ext.user_default.lsys3d" in bpy.context.preferences.addons
report["operator"] = hasattr(bpy.ops.lsys3d, "add_plant")
try:
    bpy.ops.lsys3d.add_plant(grammar_file=grammar)
    report["error"] = ""
except RuntimeError as exc:
    report["error"] = str(exc)
import lsys3d  # noqa: E402  (the installed wheel's, not a checkout's)

report["lsys3d"] = lsys3d.__file__
print("LSYS3D-EXTENSION " + json.dumps(report), flush=True)
