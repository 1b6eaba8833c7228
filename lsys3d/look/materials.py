"""Materials: what the bark and the leaves are made of, as the writers need it.

By default a tree has two materials, :data:`BARK` and :data:`LEAF`.  A grammar's
``[materials]`` table gives the turtle's material indices (set with ``'`` and
the dialects' colour symbols) materials of their own::

    [materials]
    0 = { name = "old bark", base_color = [0.25, 0.17, 0.1], roughness = 0.95 }
    2 = { name = "young bark", base_color = "#7a5a33" }
    3 = { name = "leaf", base_color = [0.2, 0.5, 0.1], double_sided = true }
    5 = { name = "blossom", base_color = [0.9, 0.75, 0.8, 1.0], roughness = 0.4, double_sided = true }

``base_color`` is linear RGB (or RGBA) in [0, 1], or an sRGB hex colour
``"#rrggbb"`` as picked in an image editor (converted to linear).  ``texture``
names a PNG or JPEG image for the base colour (multiplied by ``base_color``, as
glTF does), ``normal_texture`` a tangent-space normal map, both relative to the
grammar file (:mod:`lsys3d.external`, checked by :mod:`lsys3d.images`);
``alpha_cutoff`` makes the texture's alpha a cut-out mask (leaf cards): texels
with less alpha are not drawn.  A segment or
a leaf whose index has no entry keeps the default bark or leaf material; the
keys ``bark`` and ``leaf`` replace those defaults.  Leaves are single sheets, so
their materials are always double-sided.  The writers give each
material its own glTF primitive (sharing the mesh's vertices) or USD
``GeomSubset``, so a look-dev artist finds them as separate materials.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

import numpy as np

from ..errors import AssetError, GrammarError, OptionsError, clip
from ..external import grammar_folder, resolve
from ..images import Image, read_image
from ..lsystem.grammar import table_key_line
from .attributes import nearest_branch

__all__ = [
    "BARK",
    "LEAF",
    "MAX_MATERIAL_INDEX",
    "Material",
    "MaterialTable",
    "material_table",
    "with_face_materials",
]

MAX_MATERIAL_INDEX = 255
"""Largest material index a ``[materials]`` table may name."""


@dataclass(frozen=True)
class Material:
    """A PBR material: linear base colour (RGBA), roughness, metallic, double-sidedness, textures.

    ``texture`` (the base colour's image, multiplied by ``base_color``) and
    ``normal_texture`` (a tangent-space normal map) are :class:`~lsys3d.images.Image`;
    ``alpha_cutoff`` (None: opaque, or blended when ``base_color``'s alpha is
    below 1) makes alpha a cut-out mask: texels with less alpha are not drawn.
    """

    name: str
    base_color: tuple[float, float, float, float]
    roughness: float = 0.8
    metallic: float = 0.0
    double_sided: bool = False
    texture: Image | None = None
    normal_texture: Image | None = None
    alpha_cutoff: float | None = None

    @property
    def images(self) -> tuple[Image, ...]:
        """The material's images (base colour first), for the writers to embed or copy."""
        return tuple(i for i in (self.texture, self.normal_texture) if i is not None)


BARK = Material("bark", (0.30, 0.20, 0.12, 1.0), roughness=0.9)
"""The default bark material."""

LEAF = Material("leaf", (0.18, 0.45, 0.10, 1.0), roughness=0.6, double_sided=True)
"""The default leaf material (thin sheets: double-sided)."""


@dataclass(frozen=True)
class MaterialTable:
    """The materials of one tree: the defaults for bark and leaves, and one per material index named.

    ``for_bark(i)`` / ``for_leaf(i)`` give the material of index ``i`` (the default
    when the table has none).
    """

    bark: Material = BARK
    leaf: Material = LEAF
    by_index: Mapping[int, Material] = None

    def __post_init__(self):
        object.__setattr__(self, "by_index", dict(sorted((self.by_index or {}).items())))

    def for_bark(self, index: int) -> Material:
        return self.by_index.get(int(index), self.bark)

    def for_leaf(self, index: int) -> Material:
        """A leaf's material: always double-sided (leaves are single sheets)."""
        m = self.by_index.get(int(index), self.leaf)
        return m if m.double_sided else replace(m, double_sided=True)

    def __bool__(self) -> bool:
        """Whether the table says anything beyond the two defaults."""
        return bool(self.by_index) or self.bark != BARK or self.leaf != LEAF


_FIELDS = {f.name for f in fields(Material)}


def _srgb_to_linear(c: float) -> float:
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _color(value, where: str) -> tuple[float, float, float, float]:
    if isinstance(value, str):
        m = re.fullmatch(r"#([0-9a-fA-F]{6})([0-9a-fA-F]{2})?", value.strip())
        if not m:
            raise OptionsError(f"{where}: expected '#rrggbb' or [r, g, b], not {clip(repr(value))}")
        rgb = [_srgb_to_linear(int(m.group(1)[i : i + 2], 16) / 255) for i in (0, 2, 4)]
        alpha = int(m.group(2), 16) / 255 if m.group(2) else 1.0
        return (*(round(c, 6) for c in rgb), round(alpha, 6))
    if (
        not isinstance(value, (list, tuple))
        or len(value) not in (3, 4)
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        or not all(0 <= v <= 1 for v in value)
    ):
        raise OptionsError(f"{where}: expected 3 or 4 numbers in [0, 1] (linear RGB[A]), not {clip(repr(value))}")
    rgba = [float(v) for v in value] + ([1.0] if len(value) == 3 else [])
    return tuple(rgba)


def _texture(value, folder, where: str) -> Image:
    try:
        return read_image(resolve(folder, value, where))
    except AssetError as exc:
        text = str(exc)
        raise OptionsError(text if text.startswith(where) else f"{where}: {text}") from None


def _material(entry, default: Material, where: str, folder=None) -> Material:
    if not isinstance(entry, Mapping):
        raise OptionsError(f"{where}: expected a table such as {{ base_color = [0.3, 0.2, 0.1] }}")
    unknown = sorted(set(entry) - _FIELDS)
    if unknown:
        raise OptionsError(f"{where}: unknown key {clip(repr(unknown[0]))} (known: {', '.join(sorted(_FIELDS))})")
    values = {}
    for key, value in entry.items():
        if key == "name":
            if not isinstance(value, str) or not value.strip():
                raise OptionsError(f"{where}: name must be a non-empty string, not {clip(repr(value))}")
            values[key] = value.strip()
        elif key == "base_color":
            values[key] = _color(value, f"{where}: base_color")
        elif key in ("roughness", "metallic"):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
                raise OptionsError(f"{where}: {key} must be a number in [0, 1], not {clip(repr(value))}")
            values[key] = float(value)
        elif key == "double_sided":
            if not isinstance(value, bool):
                raise OptionsError(f"{where}: double_sided must be true or false, not {clip(repr(value))}")
            values[key] = value
        elif key in ("texture", "normal_texture"):
            values[key] = _texture(value, folder, f"{where}: {key}")
        elif key == "alpha_cutoff":
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1:
                raise OptionsError(f"{where}: alpha_cutoff must be a number in [0, 1], not {clip(repr(value))}")
            values[key] = float(value)
    texture = values.get("texture", default.texture)
    if "alpha_cutoff" in values and texture is not None and not texture.alpha:
        raise OptionsError(
            f"{where}: alpha_cutoff needs a texture with an alpha channel, and {clip(repr(texture.name))} has none"
        )
    if "name" not in values:
        values["name"] = default.name if where.endswith(("bark", "leaf")) else f"material_{where.split('.')[-1]}"
    return Material(**{**{f: getattr(default, f) for f in _FIELDS}, **values})


def material_table(grammar) -> MaterialTable:
    """The materials of a grammar's ``[materials]`` table (the two defaults when it has none).

    Raises
    ------
    GrammarError
        A bad entry, with the grammar's file and the entry's line.

    Examples
    --------
    >>> from lsys3d import Grammar
    >>> table = material_table(Grammar(axiom="F", materials={"2": {"base_color": "#ff0000", "name": "red"}}))
    >>> table.for_bark(2).name, table.for_bark(2).base_color, table.for_bark(0).name
    ('red', (1.0, 0.0, 0.0, 1.0), 'bark')
    """
    raw = dict(getattr(grammar, "materials", {}) or {})
    bark, leaf, by_index = BARK, LEAF, {}
    folder = grammar_folder(grammar) if raw else None
    for key, entry in raw.items():
        where = f"materials.{key}"
        try:
            if key == "bark":
                bark = _material(entry, BARK, where, folder)
            elif key == "leaf":
                leaf = _material(entry, LEAF, where, folder)
            elif re.fullmatch(r"\d+", str(key)) and int(key) <= MAX_MATERIAL_INDEX:
                by_index[int(key)] = _material(entry, BARK, where, folder)
            else:
                raise OptionsError(
                    f"{where}: a key is a material index 0..{MAX_MATERIAL_INDEX}, 'bark' or 'leaf', "
                    f"not {clip(repr(key))}"
                )
        except OptionsError as exc:
            line = table_key_line(grammar.text, "materials", str(key)) if grammar.text else None
            raise GrammarError(f"[materials] {exc}", grammar.source, line, 1 if line else None) from None
    return MaterialTable(bark, leaf, by_index)


def with_face_materials(bark, skeleton, hierarchy, bulge: float = 0.0):
    """The materials stage: ``bark`` with each face's material index, that of the segment whose tube it lies on.

    The face's centroid is matched to a segment as the attributes match vertices
    (:func:`lsys3d.look.attributes.nearest_branch`: where branches meet, the child's), so the
    faces of a branch take its ``'`` index, and a seam takes the child's.
    """
    if not len(bark.faces) or not len(skeleton):
        return bark
    centroids = bark.vertices[bark.faces].mean(axis=1)
    segment, _ = nearest_branch(centroids, skeleton, hierarchy, bulge=bulge)
    material = np.where(segment >= 0, np.asarray(skeleton.material)[np.maximum(segment, 0)], 0)
    return replace(bark, face_material=material.astype(np.int32))
