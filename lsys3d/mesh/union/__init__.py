"""The union: overlapping tubes to one watertight mesh.

``union`` drives it; ``touch`` finds what may touch, ``plan`` pairs and groups the work, ``local`` unions only the
runs of pieces that touch and stitches the rest back on, ``parts`` cuts and joins the tubes' faces, ``sources``
keeps each face's tube face true, ``weld`` welds the result as float32, ``repeats`` unions equal junctions once,
``jobs`` plans and runs the boolean work, ``booleans`` is one boolean job (and the worker script, numpy and
manifold3d only).
"""
