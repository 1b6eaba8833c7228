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
with less alpha are not drawn.  ``roughness_texture`` is glTF's
metallic-roughness image (roughness in G, metallic in B), ``tile_size`` the
metres of bark one texture tile covers (the sweep's ``uv_tile`` for the
branches of that material).

``procedural`` makes the images instead of reading them
(:mod:`lsys3d.look.textures`)::

    bark = { procedural = { kind = "furrowed", seed = 3, tile_size = 0.6 } }
    leaf = { procedural = { kind = "maple", colors = ["#c0501c", "#e8a040", "#6a3a1a"] } }

It fills ``texture``, ``normal_texture`` and (bark) ``roughness_texture``
(a key the entry names itself wins), ``tile_size`` (bark), a white
``base_color``, ``roughness = 1`` (bark: the image is the roughness) and
``alpha_cutoff = 0.5`` (leaves) unless the entry says otherwise.  Its keys:
``kind`` (required), ``seed``, ``resolution``, ``tile_size``, ``colors``.
A segment or
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

from ..errors import AssetError, OptionsError, clip
from ..external import grammar_folder, resolve
from ..images import Image, read_image
from ..lsystem.grammar import table_error
from .attributes import nearest_branch
from .textures import KINDS, MAX_RESOLUTION, MIN_RESOLUTION, procedural

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

    ``texture`` (the base colour's image, multiplied by ``base_color``),
    ``normal_texture`` (a tangent-space normal map) and ``roughness_texture``
    (roughness in G and metallic in B, multiplied by ``roughness`` and
    ``metallic``) are :class:`~lsys3d.images.Image`; ``alpha_cutoff`` (None:
    opaque, or blended when ``base_color``'s alpha is below 1) makes alpha a
    cut-out mask: texels with less alpha are not drawn.  ``tile_size``
    (metres, None: the sweep's ``uv_tile``) is how much bark one tile of the
    textures covers, around and along a branch.
    """

    name: str
    base_color: tuple[float, float, float, float]
    roughness: float = 0.8
    metallic: float = 0.0
    double_sided: bool = False
    texture: Image | None = None
    normal_texture: Image | None = None
    alpha_cutoff: float | None = None
    roughness_texture: Image | None = None
    tile_size: float | None = None

    @property
    def images(self) -> tuple[Image, ...]:
        """The material's images (base colour, normal, roughness), for the writers to embed or copy."""
        return tuple(i for i in (self.texture, self.normal_texture, self.roughness_texture) if i is not None)


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

    def uv_tiles(self, uv_tile: float) -> np.ndarray | None:
        """Metres of bark a texture tile covers by material index ``(MAX_MATERIAL_INDEX + 1,)``, for the sweep.

        ``uv_tile`` where a material has no :attr:`Material.tile_size`; None
        when none has one (the sweep then uses its own ``uv_tile``).

        >>> MaterialTable().uv_tiles(0.5) is None
        True
        >>> MaterialTable(replace(BARK, tile_size=0.8), by_index={2: BARK}).uv_tiles(0.5)[[0, 2, 9]].tolist()
        [0.8, 0.5, 0.8]
        """
        if self.bark.tile_size is None and all(m.tile_size is None for m in self.by_index.values()):
            return None
        out = np.full(MAX_MATERIAL_INDEX + 1, self.bark.tile_size or uv_tile, np.float64)
        for i, m in self.by_index.items():
            out[i] = m.tile_size or uv_tile
        return out


_FIELDS = {f.name for f in fields(Material)}
_KEYS = _FIELDS | {"procedural"}
_PROCEDURAL_KEYS = ("kind", "seed", "resolution", "tile_size", "colors")


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


def _procedural(spec, where: str) -> dict:
    """The material fields a ``procedural = { kind = ... }`` table makes (:mod:`lsys3d.look.textures`)."""
    if not isinstance(spec, Mapping):
        raise OptionsError(f'{where}: expected a table such as {{ kind = "furrowed", seed = 1 }}')
    unknown = sorted(set(spec) - set(_PROCEDURAL_KEYS))
    if unknown:
        raise OptionsError(f"{where}: unknown key {clip(repr(unknown[0]))} (known: {', '.join(_PROCEDURAL_KEYS)})")
    kind = spec.get("kind")
    if kind not in KINDS:
        known = ", ".join(f"{k} ({v.group})" for k, v in KINDS.items())
        raise OptionsError(f"{where}: kind must be one of {known}; not {clip(repr(kind))}")
    row = KINDS[kind]
    seed, resolution = spec.get("seed", 0), spec.get("resolution", 512)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise OptionsError(f"{where}: seed must be a whole number >= 0, not {clip(repr(seed))}")
    if (
        isinstance(resolution, bool)
        or not isinstance(resolution, int)
        or not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION
    ):
        raise OptionsError(
            f"{where}: resolution must be a whole number of pixels in {MIN_RESOLUTION}..{MAX_RESOLUTION}, "
            f"not {clip(repr(resolution))}"
        )
    tile_size = spec.get("tile_size")
    if tile_size is not None:
        if row.group != "bark":
            raise OptionsError(f"{where}: tile_size is for bark kinds; {kind} is a leaf image (its uv spans the leaf)")
        tile_size = _tile_size(tile_size, f"{where}: tile_size")
    colors = spec.get("colors")
    if colors is not None:
        n = len(row.default_colors)
        if not isinstance(colors, (list, tuple)) or len(colors) != n:
            raise OptionsError(
                f"{where}: colors must be a list of {n} colours for {kind} ({', '.join(row.roles)}; "
                f"defaults {list(row.default_colors)}), not {clip(repr(colors))}"
            )
        colors = tuple(_color(c, f"{where}: colors[{i}]")[:3] for i, c in enumerate(colors))
    images = procedural(kind, seed, resolution, colors, tile_size)
    out = {"texture": images.albedo, "normal_texture": images.normal}
    if images.roughness is not None:
        out.update(roughness_texture=images.roughness, tile_size=images.tile_size, roughness=1.0)
    else:
        out.update(alpha_cutoff=0.5)
    return out


def _tile_size(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.01 <= value <= 100:
        raise OptionsError(f"{where} must be metres in 0.01..100, not {clip(repr(value))}")
    return float(value)


def _material(entry, default: Material, where: str, folder=None) -> Material:
    if not isinstance(entry, Mapping):
        raise OptionsError(f"{where}: expected a table such as {{ base_color = [0.3, 0.2, 0.1] }}")
    unknown = sorted(set(entry) - _KEYS)
    if unknown:
        raise OptionsError(f"{where}: unknown key {clip(repr(unknown[0]))} (known: {', '.join(sorted(_KEYS))})")
    values = {}
    if "procedural" in entry:
        # what the entry names itself wins over what the procedural texture makes
        made = _procedural(entry["procedural"], f"{where}: procedural")
        if "tile_size" in entry and "tile_size" in entry["procedural"]:
            raise OptionsError(f"{where}: tile_size is given twice (in the entry and in procedural)")
        values.update({k: v for k, v in made.items() if k not in entry}, base_color=(1.0, 1.0, 1.0, 1.0))
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
        elif key in ("texture", "normal_texture", "roughness_texture"):
            values[key] = _texture(value, folder, f"{where}: {key}")
        elif key == "tile_size":
            values[key] = _tile_size(value, f"{where}: tile_size")
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
            raise table_error(grammar, "materials", str(key), str(exc)) from None
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
