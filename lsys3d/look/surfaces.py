"""Surfaces: the leaf model and the organs' models a grammar's ``[surfaces]`` table binds.

::

    [surfaces]
    leaf = "models/maple_leaf.glb"                       # replaces the built-in blade
    flower = { model = "daisy.obj", rotate = [-90, 0, 0], scale = 0.5 }
    petal = { card = "petal.png", width = 0.4 }          # a textured, alpha-masked card

A key names a surface: ``leaf`` is the leaf the turtle's leaf symbol places;
any other name is a named surface (ABOP's and L-Py's ``~name``, see
:mod:`lsys3d.look.organs`), and the built-in organs ``sphere``, ``disc``,
``circle`` and ``box`` can be replaced the same way.  A value is

* a model file (``.glb``, ``.obj``, ``.ply``, ``.stl``; relative to the grammar
  file, read as bounded bytes by :mod:`lsys3d.external` and parsed by trimesh:
  at most :data:`MAX_MODEL_BYTES` bytes and :data:`MAX_MODEL_TRIANGLES`
  triangles), or a table ``{ model = ..., rotate = [x, y, z], scale = s,
  normalize = true }``;
* a vlab surface file (cpfg's bicubic patches, :mod:`lsys3d.look.patches`):
  ``{ model = "leaf.s", scale = 1, precision = [8, 4], texels = "surface" }``,
  at its own size times ``scale`` (cpfg's view file's ``surface: l leaf.s 1 8 4``
  writes it so for a cpfg file), with cpfg's texture coordinates (``end_point = true``: cpfg moves the
  turtle to the surface's end point after it, which lsys3d names in a warning where it matters);
* a card: ``{ card = "leaf.png", width = w, alpha_cutoff = 0.5 }``: one quad,
  length 1 along ``+z`` and ``w`` wide (default: the image's aspect ratio),
  showing the image (stem at the bottom of the picture, tip at the top), cut
  out by its alpha and double-sided.

Every model ends up in the leaf-model convention of :mod:`lsys3d.look.leaves`: the
turtle's frame at the leaf, ``x`` = left, ``y`` = up, ``z`` = heading; the
model grows from the origin along ``+z``, front facing ``+y``.  A model file
is turned by ``rotate`` (degrees about x, then y, then z) and then, with
``normalize = true`` (the default), scaled uniformly to length 1 along ``z``
and moved so that its base -- the middle of its lowest points along ``z``,
where a stem ends -- is at the origin; finally scaled by ``scale``.  So a
glTF leaf modelled lying flat (facing +Y), stem toward -Z and tip toward +Z is
taken as it is, whatever its size.  With ``normalize = false`` the model is
used at its own size and place (after ``rotate`` and ``scale``): one unit is
one step of the turtle.

Only a model's geometry and texture coordinates are used: its materials come
from the grammar's ``[materials]`` table (give the leaf material a
``texture`` to use the model's uv).  A card brings its own texture: it becomes
the default leaf material's (:func:`with_cards`), with a white base colour
unless ``[materials] leaf`` sets one.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..errors import AssetError, OptionsError, clip
from ..external import grammar_folder, load_scene, read_file, resolve
from ..images import Image, read_image
from ..lsystem.grammar import table_error
from ..mesh.mesh import Mesh
from .materials import Material, MaterialTable
from .patches import MAX_PRECISION, read_patches

__all__ = [
    "MAX_MODEL_BYTES",
    "MAX_MODEL_TRIANGLES",
    "MODEL_SUFFIXES",
    "Surface",
    "SurfaceTable",
    "card",
    "load_model",
    "surface_table",
    "with_cards",
]

log = logging.getLogger("lsys3d")

MAX_MODEL_BYTES = 32 << 20
"""Largest model file read, in bytes."""
MAX_MODEL_TRIANGLES = 200_000
"""Most triangles of one model (each leaf or organ placed copies it)."""
MODEL_SUFFIXES = (".glb", ".obj", ".ply", ".stl")
"""The model files a surface may name (a ``.gltf`` needs its ``.bin`` and images: write ``.glb``)."""

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]{0,63}\Z")
_MODEL_KEYS = ("model", "rotate", "scale", "normalize")
_CARD_KEYS = ("card", "width", "alpha_cutoff")
_PATCH_KEYS = ("model", "scale", "precision", "texels", "end_point")  # a vlab surface (.s): lsys3d.look.patches
MAX_PATCH_BYTES = 1 << 20
"""Largest vlab surface file (``.s``) read, in bytes."""


@dataclass(frozen=True, eq=False)
class Surface:
    """A model bound to a name: its mesh in the leaf-model frame, and a card's image.

    Attributes
    ----------
    name : str
    mesh : Mesh
        In the convention of :mod:`lsys3d.look.leaves` (see the module docstring).
    image : Image or None
        A card's image (None for a model file).
    alpha_cutoff : float or None
        A card's cut-out threshold.
    source : str
        The file it came from.
    """

    name: str
    mesh: Mesh
    image: Image | None = None
    alpha_cutoff: float | None = None
    source: str = ""

    @property
    def is_card(self) -> bool:
        return self.image is not None


@dataclass(frozen=True)
class SurfaceTable:
    """The ``[surfaces]`` of one grammar, by name (empty without a table)."""

    by_name: Mapping[str, Surface] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "by_name", MappingProxyType(dict(self.by_name)))

    @property
    def leaf(self) -> Surface | None:
        """The leaf model, when the table replaces the built-in one."""
        return self.by_name.get("leaf")

    def get(self, name: str) -> Surface | None:
        return self.by_name.get(name)

    def __bool__(self) -> bool:
        return bool(self.by_name)


# ---------------------------------------------------------------- models


def _rotation(degrees) -> np.ndarray:
    """The rotation about x, then y, then z by these angles (degrees): ``Rz @ Ry @ Rx``."""
    ax, ay, az = (math.radians(float(d)) for d in degrees)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def load_model(path, rotate=(0.0, 0.0, 0.0), scale: float = 1.0, normalize: bool = True) -> Mesh:
    """A model file as a :class:`Mesh` in the leaf-model convention (see the module docstring).

    Parameters
    ----------
    path : path-like
        ``.glb``, ``.obj``, ``.ply`` or ``.stl``.
    rotate : 3 floats
        Degrees about x, then y, then z.
    scale : float
        Uniform scale, after normalising.
    normalize : bool
        Scale to length 1 along ``z`` and move the base to the origin.

    Raises
    ------
    AssetError
        ``path: what``: not a model lsys3d reads, unreadable, too large, empty,
        too many triangles, non-finite vertices, no length to normalise.
    """
    path = Path(path)
    shown = clip(str(path), 100)
    suffix = path.suffix.lower()
    if suffix not in MODEL_SUFFIXES:
        raise AssetError(f"{shown}: a model must be {', '.join(MODEL_SUFFIXES)}, not {clip(repr(path.suffix))}")
    data = read_file(path, MAX_MODEL_BYTES, "model", "lsys3d.look.surfaces.MAX_MODEL_BYTES")
    mesh = _parse(data, suffix[1:], shown)
    vertices = np.asarray(mesh.vertices, np.float64)
    faces = np.asarray(mesh.faces, np.int64).reshape(-1, 3)
    if not len(faces):
        raise AssetError(f"{shown}: the model has no triangles")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise AssetError(f"{shown}: the model has a face pointing past its vertices")
    if not np.isfinite(vertices).all() or np.abs(vertices).max() > 1e9:
        raise AssetError(f"{shown}: the model has vertices that are not finite numbers (or beyond 1e9)")
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    uv = np.asarray(uv, np.float64) if uv is not None and len(uv) == len(vertices) else np.zeros((len(vertices), 2))
    if not np.isfinite(uv).all():
        uv = np.zeros((len(vertices), 2))
    normals = _smooth_normals(vertices, faces)
    rotation = _rotation(rotate)
    vertices = vertices @ rotation.T
    normals = normals @ rotation.T
    if normalize:
        lo, hi = vertices[:, 2].min(), vertices[:, 2].max()
        length = hi - lo
        if not length > 1e-12 * max(1.0, float(np.abs(vertices).max())):
            raise AssetError(f"{shown}: the model has no length along z to normalise (rotate it, or normalize = false)")
        base = vertices[vertices[:, 2] <= lo + 0.01 * length].mean(axis=0)
        base[2] = lo
        vertices = (vertices - base) / length
    vertices = vertices * float(scale)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), [0.0, 1.0, 0.0])
    return Mesh(vertices, faces, normals[faces], uv[faces])


def _smooth_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Vertex normals: the faces around each vertex, weighted by area (smooth where the file shares vertices)."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # twice the area, along the normal
    corner = faces.reshape(-1)
    return np.stack([np.bincount(corner, np.repeat(cross[:, c], 3), minlength=len(vertices)) for c in range(3)], axis=1)


def _parse(data: bytes, file_type: str, shown: str):
    """The model's triangles as one trimesh (scene graph transforms applied)."""
    scene = load_scene(data, file_type, shown, MAX_MODEL_TRIANGLES, _too_many)
    return scene.to_geometry() if hasattr(scene, "to_geometry") else scene.dump(concatenate=True)


def _too_many(shown: str, count: int) -> str:
    return (
        f"{shown}: the model has {count:,} triangles, more than {MAX_MODEL_TRIANGLES:,} "
        "(lsys3d.look.surfaces.MAX_MODEL_TRIANGLES): every leaf or organ placed copies it"
    )


def card(width: float = 0.5) -> Mesh:
    """A card: one quad ``width`` wide, from the origin to ``z = 1``, facing ``+y``, uv over the whole image.

    >>> m = card(0.4)
    >>> len(m.faces), m.bounds.round(3).tolist(), np.ptp(m.uv.reshape(-1, 2), axis=0).tolist()
    (2, [[-0.2, 0.0, 0.0], [0.2, 0.0, 1.0]], [1.0, 1.0])
    """
    half = width / 2
    vertices = np.array([[-half, 0, 0], [half, 0, 0], [half, 0, 1], [-half, 0, 1]], np.float64)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.int64)  # counter-clockwise seen from +y
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)[faces]
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0]), (2, 3, 3))
    return Mesh(vertices, faces, normals, uv)


# ---------------------------------------------------------------- the table


def _number(value, where: str, low: float, high: float, what: str) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or not low <= value <= high:
        raise OptionsError(f"{where}: {what} must be a number in [{low:g}, {high:g}], not {clip(repr(value))}")
    return float(value)


def _surface(name: str, entry, folder: Path, where: str) -> Surface:
    if isinstance(entry, str):
        entry = {"model": entry}
    if not isinstance(entry, Mapping):
        raise OptionsError(
            f'{where}: expected a model file ("leaf.glb"), or a table {{ model = ... }} or {{ card = ... }}'
        )
    patch = str(entry.get("model", "")).lower().endswith(".s")
    keys = _CARD_KEYS if "card" in entry else _PATCH_KEYS if patch else _MODEL_KEYS
    unknown = sorted(set(entry) - set(keys))
    if unknown:
        kind = "a card" if "card" in entry else "a model"
        raise OptionsError(f"{where}: unknown key {clip(repr(unknown[0]))} for {kind} (known: {', '.join(keys)})")
    try:
        if "card" in entry:
            image = read_image(resolve(folder, entry["card"], f"{where}: card"))
            width = image.width / image.height
            if "width" in entry:
                width = _number(entry["width"], where, 1e-6, 1e6, "width")
            cutoff = _number(entry.get("alpha_cutoff", 0.5), where, 0.0, 1.0, "alpha_cutoff")
            if not image.alpha:
                raise OptionsError(
                    f"{where}: a card's image needs an alpha channel, and {clip(repr(image.name))} has none"
                )
            return Surface(name, card(width), image, cutoff, image.source)
        if "model" not in entry:
            raise OptionsError(f"{where}: a table needs 'model' (a file) or 'card' (an image)")
        if patch:
            return _patch_surface(name, entry, folder, where)
        rotate = entry.get("rotate", (0.0, 0.0, 0.0))
        if not isinstance(rotate, (list, tuple)) or len(rotate) != 3:
            raise OptionsError(f"{where}: rotate must be 3 angles in degrees [x, y, z], not {clip(repr(rotate))}")
        rotate = tuple(_number(a, where, -360.0, 360.0, "rotate") for a in rotate)
        scale = _number(entry.get("scale", 1.0), where, 1e-6, 1e6, "scale")
        normalize = entry.get("normalize", True)
        if not isinstance(normalize, bool):
            raise OptionsError(f"{where}: normalize must be true or false, not {clip(repr(normalize))}")
        path = resolve(folder, entry["model"], f"{where}: model")
        return Surface(name, load_model(path, rotate, scale, normalize), source=str(path))
    except AssetError as exc:
        text = str(exc)
        raise OptionsError(text if text.startswith(where) else f"{where}: {text}") from None


def _patch_surface(name: str, entry, folder: Path, where: str) -> Surface:
    """A vlab surface file (``{ model = "leaf.s", scale = 1, precision = [8, 4], texels = "surface" }``), at its
    own size times ``scale`` as cpfg's view file sizes it (:mod:`lsys3d.look.patches`).  ``end_point = true``
    says that cpfg moves the turtle to the surface's end point after it, which lsys3d does not (a warning
    names it where a module of the branch follows: :func:`lsys3d.turtle.selections.surface_findings`)."""
    size = _number(entry.get("scale", 1.0), where, 1e-6, 1e6, "scale")
    precision = entry.get("precision", (0, 0))
    ok = isinstance(precision, (list, tuple)) and len(precision) == 2
    if not ok or not all(isinstance(p, int) and not isinstance(p, bool) and 0 <= p <= MAX_PRECISION for p in precision):
        raise OptionsError(
            f"{where}: precision must be two whole numbers [s, t] in [0, {MAX_PRECISION}] (0: the file's), "
            f"not {clip(repr(precision))}"
        )
    if not isinstance(entry.get("end_point", False), bool):
        raise OptionsError(f"{where}: end_point must be true or false (whether cpfg moves the turtle after it)")
    path = resolve(folder, entry["model"], f"{where}: model")
    data = read_file(path, MAX_PATCH_BYTES, "surface file", "lsys3d.look.surfaces.MAX_PATCH_BYTES")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise AssetError(f"{clip(str(path), 100)}: a vlab surface file is text, and this is not UTF-8") from None
    mesh = read_patches(text, clip(str(path), 100), size, precision[0], precision[1], entry.get("texels", "surface"))
    return Surface(name, mesh, source=str(path))


def surface_table(grammar) -> SurfaceTable:
    """The surfaces of a grammar's ``[surfaces]`` table, read (an empty table without one).

    Raises
    ------
    GrammarError
        A bad entry or file, with the grammar's file and the entry's line.
    """
    raw = dict(getattr(grammar, "surfaces", {}) or {})
    if not raw:
        return SurfaceTable()
    folder = grammar_folder(grammar)
    out = {}
    for key, entry in raw.items():
        where = f"surfaces.{key}"
        try:
            if not _NAME.match(str(key)):
                raise OptionsError(f"{where}: a surface's name is a letter or _ then letters, digits, _ . -")
            out[key] = _surface(key, entry, folder, where)
        except OptionsError as exc:
            raise table_error(grammar, "surfaces", str(key), str(exc)) from None
    log.info("surfaces: %s", ", ".join(f"{k} ({len(s.mesh.faces)} triangles)" for k, s in out.items()))
    return SurfaceTable(out)


def with_cards(table: MaterialTable, surfaces: SurfaceTable, grammar=None) -> MaterialTable:
    """``table`` with a leaf card's image as the default leaf material's texture.

    The card's cut-out threshold comes along, and the base colour becomes
    white (the image *is* the colour) unless the grammar's ``[materials] leaf``
    sets ``base_color``, which then tints the image.  A leaf material that has
    a texture of its own keeps it.  Leaves whose material index has its own
    ``[materials]`` entry use that entry as it is.
    """
    leaf = surfaces.leaf
    if leaf is None or not leaf.is_card or table.leaf.texture is not None:
        return table
    entry = dict(getattr(grammar, "materials", {}) or {}).get("leaf", {})
    tinted = isinstance(entry, Mapping) and "base_color" in entry
    base = table.leaf.base_color if tinted else (1.0, 1.0, 1.0, 1.0)
    material: Material = replace(table.leaf, texture=leaf.image, alpha_cutoff=leaf.alpha_cutoff, base_color=base)
    return replace(table, leaf=material)
