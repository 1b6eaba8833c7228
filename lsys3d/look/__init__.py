"""The look: what a bark mesh becomes a plant with.

Bark colour, leaves, organs and surfaces, materials, vertex attributes, the rig and its wind, levels of detail.
"""
