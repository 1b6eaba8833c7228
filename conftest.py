"""The add-on's modules import ``bpy``, which only Blender's Python has: the doctest collection of the package
leaves them out (tests/test_blender_addon.py runs them inside Blender, in a child process)."""

collect_ignore = ["lsys3d/blender"]
