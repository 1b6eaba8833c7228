"""Pictures of a tree: ``preview`` renders a PNG through Blender running ``preview_blender.py``."""
