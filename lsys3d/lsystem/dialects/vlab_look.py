"""What a vlab view file says about the look of a cpfg model: its surfaces and its textures.

- ``surface: l leaf.s 1 8 4``: the surface ``~l`` is the vlab surface file ``leaf.s`` (bicubic patches,
  :mod:`lsys3d.look.patches`) at size 1, sampled 8 x 4 per patch: a ``[surfaces]`` entry
  ``l = { model = "leaf.s", scale = 1, precision = [8, 4], texels = ... }``;
- ``texture: F: maple.png E: m R: 1 H: l L: n S:``: cpfg's textures (``textures.c``: ``read_texture``), in
  the order read: ``@Tx(n)`` selects the n-th that was read (cpfg counts only the textures it could
  load), ``S`` maps it over a whole surface (else per patch), ``R`` is the height/width ratio on a
  cylinder.  Each becomes a ``[materials]`` entry at the index :func:`texture_material` gives, with the
  image as its base colour texture on white (cpfg modulates the texture by the colour, and lsys3d gives
  cpfg's colour indices no colours), cut out where its alpha is 0.1 or less (cpfg's alpha test) and one
  tile around a branch (cpfg wraps the image once around a cylinder, and along it a tile per
  circumference: lsys3d's bark ``v``; cpfg's ``R`` and the image's aspect are not applied);
  :mod:`lsys3d.turtle.selections` gives the segments and surfaces drawn after ``@Tx(n)`` that material.

A texture that cannot be read (missing, not PNG or JPEG, a line cpfg refuses) is left out with one line
among the grammar's repairs (a warning; ``--strict``: an error), as cpfg leaves it out with a message.
Files are read from the model's own folder only (:func:`lsys3d.external.inside`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from ...errors import AssetError, GrammarError, clip
from ...external import FileRefused, inside
from ...images import read_image
from ..grammar import read_text
from .vlab import strip_comments

__all__ = ["MAX_TEXTURES", "Look", "read_look", "texture_material"]

MAX_TEXTURES = 16
"""Most textures of one view file (cpfg's ``NUMTEXTURES`` is of this order)."""

_MATERIALS = 256  # lsys3d.look.materials.MAX_MATERIAL_INDEX + 1 (the look stage comes after this one)
_IMAGES = (".png", ".jpg", ".jpeg")


def texture_material(n: int) -> int:
    """The material index of the view file's ``n``-th texture (1 is the first): the top of lsys3d's indices.

    >>> texture_material(1), texture_material(2)
    (255, 254)
    """
    return _MATERIALS - n


@dataclass(frozen=True)
class Look:
    """The ``[materials]`` and ``[surfaces]`` entries a view file makes, and what could not be read."""

    materials: dict = field(default_factory=dict)
    surfaces: dict = field(default_factory=dict)
    repairs: tuple[str, ...] = ()

    def fields(self) -> dict:
        """The grammar's fields these make (none for a view file without surfaces and textures)."""
        out = {"materials": self.materials, "surfaces": self.surfaces, "repairs": self.repairs}
        return {key: value for key, value in out.items() if value}


_LINE = re.compile(r"(?P<key>surface|texture)\s*:\s*(?P<rest>.*)\Z")


def read_look(path: Path) -> Look:
    """The surfaces and textures of the view file beside ``path`` (an empty :class:`Look` without one)."""
    view = path.with_suffix(".v")
    folder = path.parent
    if not view.is_file():
        return Look()
    try:
        text = read_text(inside(folder, view.name, "view file"))
    except (FileRefused, GrammarError):
        return Look()  # the angle's reader says why
    textures, surfaces, repairs = [], {}, []
    for number, raw in enumerate(strip_comments(text).split("\n"), start=1):
        m = _LINE.match(raw.strip())
        if m is None:
            continue
        where = f"{view}:{number}"
        if m.group("key") == "surface":
            entry = _surface(m.group("rest"), folder)
            if entry is not None:
                surfaces.setdefault(entry[0], entry[1])  # cpfg: an id already used is ignored
            continue
        texture, why = _texture(m.group("rest"), folder)
        if texture is None:
            repairs.append(f"{where}: texture not read ({why}): drawn without it, as cpfg draws it")
        elif len(textures) >= MAX_TEXTURES:
            repairs.append(f"{where}: more than {MAX_TEXTURES} textures: this one is left out")
        else:
            textures.append(texture)
    materials = {}
    for n, (name, _per_surface, _ratio, alpha) in enumerate(textures, start=1):
        cut = {"alpha_cutoff": 0.1} if alpha else {}  # cpfg's alpha test: glAlphaFunc(GL_GREATER, 0.1) (control.c)
        materials[str(texture_material(n))] = cut | {
            "name": f"texture_{n}_{Path(name).stem}",
            "texture": name,
            "base_color": [1.0, 1.0, 1.0],
            "double_sided": True,
            "tile_size": 100.0,  # one tile around any branch: cpfg wraps the image once around a cylinder
        }
    # cpfg's texels of a surface: per patch when some texture is per patch, else per surface (patches.c)
    texels = "patch" if any(not texture[1] for texture in textures) else "surface"
    for entry in surfaces.values():
        entry["texels"] = texels
    return Look(materials, surfaces, tuple(repairs))


def _surface(rest: str, folder: Path) -> tuple[str, dict] | None:
    """``l leaf.s 1 8 4``: the id and the ``[surfaces]`` entry (None when cpfg would not read it either)."""
    words = rest.split()
    if len(words) < 3 or len(words[0]) != 1 or not words[1].lower().endswith(".s"):
        return None
    try:
        size = float(words[2])
        precision = [int(w) for w in words[3:5]] if len(words) >= 5 else [0, 0]
    except ValueError:
        return None
    try:
        if not inside(folder, words[1], "surface file").is_file():
            return None
    except FileRefused:
        return None  # cpfg: access() fails, the surface is not defined (lsys3d then warns of the organ)
    size = size if size > 0 else 1.0  # cpfg's read: a size <= 0 is 1
    entry = {"model": words[1], "scale": size, "precision": [max(0, p) for p in precision]}
    if _moves(folder / words[1]):
        entry["end_point"] = True
    return words[0], entry


_POINT = r"X:\s*([-+.\deE]+)\s*Y:\s*([-+.\deE]+)\s*Z:\s*([-+.\deE]+)"


def _moves(path: Path) -> bool:
    """Whether cpfg moves the turtle after drawing the surface: its ``END POINT`` is not its ``CONTACT POINT``
    (``patches.c``: ``determine_end_point``).  A file that does not say is left to the surface's reader."""
    try:
        text = read_text(path)
    except GrammarError:
        return False
    contact = re.search(r"CONTACT POINT\s*" + _POINT, text)
    end = re.search(r"END POINT\s*" + _POINT, text)
    try:
        return bool(contact and end and [float(v) for v in contact.groups()] != [float(v) for v in end.groups()])
    except ValueError:
        return False


def _texture(rest: str, folder: Path) -> tuple[tuple[str, bool, float, bool] | None, str]:
    """cpfg's ``read_texture``: the file, whether it spans a surface, the ratio, whether the image has alpha; or
    None and why not."""
    tokens = [t for t in re.split(r"[\s:,]+", rest) if t]
    name, per_surface, ratio = None, False, 1.0
    i = 0
    while i < len(tokens):
        letter = tokens[i][0]
        if letter == "S":
            per_surface = True
            i += 1
            continue
        if letter not in "FLHER":
            return None, f"cpfg knows F, L, H, E, R and S, not {clip(repr(tokens[i]), 20)}"
        if i + 1 >= len(tokens):
            return None, f"{letter} needs a value"
        value = tokens[i + 1]
        if letter == "F":
            name = value
        elif letter == "R":
            try:
                ratio = float(value)
            except ValueError:
                return None, f"R needs a number, not {clip(repr(value), 20)}"
        i += 2
    if name is None:
        return None, "no file (F: name)"
    if not name.lower().endswith(_IMAGES):
        return None, f"{clip(repr(name), 60)}: lsys3d reads PNG and JPEG textures (convert it to PNG)"
    try:
        image = read_image(inside(folder, name, "texture"))
    except (FileRefused, AssetError) as exc:
        return None, f"{clip(repr(name), 60)}: {getattr(exc, 'reason', None) or exc}"
    return (name, per_surface, ratio, image.alpha), ""
