"""The mesh stage: a skeleton to one clean, watertight bark mesh.

``sweep`` turns segments into tubes, ``union/`` joins them, ``cleanup`` (kernels in ``remesh``) removes needles
and slivers, ``quality`` measures the result; ``mesh`` holds the ``Mesh`` type every later stage passes on.
"""
