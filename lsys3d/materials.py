"""Materials: what the bark and the leaves are made of, as the writers need it."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BARK", "LEAF", "Material"]


@dataclass(frozen=True)
class Material:
    """A PBR material: linear base colour (RGBA), roughness, metallic, double-sidedness."""

    name: str
    base_color: tuple[float, float, float, float]
    roughness: float = 0.8
    metallic: float = 0.0
    double_sided: bool = False


BARK = Material("bark", (0.30, 0.20, 0.12, 1.0), roughness=0.9)
"""The default bark material."""

LEAF = Material("leaf", (0.18, 0.45, 0.10, 1.0), roughness=0.6, double_sided=True)
"""The default leaf material (thin sheets: double-sided)."""
