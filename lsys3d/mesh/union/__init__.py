"""The union: overlapping tubes to one watertight mesh.

``union`` drives it; ``touch`` finds what may touch, ``repeats`` unions equal junctions once, ``jobs`` plans and
runs the boolean work, ``booleans`` is one boolean job (and the worker script, numpy and manifold3d only).
"""
