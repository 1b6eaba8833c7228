"""What cpfg's turtle keeps that the drawing kernel does not: the texture ``@Tx(n)`` selects, ``~l``'s three scales.

cpfg's turtle state holds a texture (``blackbox.c``: ``@Tx(n)`` selects the n-th texture of the view file,
any other value none; ``[`` and ``]`` save and restore it with the rest of the state); the cylinders,
generalized cylinders and surfaces drawn while it is set show it.  And ``~l(sx, sy, sz)`` scales the
surface by ``sx`` along left, ``sy`` along the heading and ``sz`` along up (``interpret.c``; one or two
parameters: ``sx`` for all three).

The kernel records each segment's and organ's module (:class:`~lsys3d.turtle.skeleton.Skeleton`), so both
are read here from the string the turtle read, after it has drawn: :func:`selections` gives the segments
and surfaces drawn under ``@Tx(n)`` the material index of that texture
(:func:`lsys3d.lsystem.dialects.vlab_look.texture_material`, a material the cpfg reader made from the view
file), and the surfaces their scale along left, up and heading relative to ``sx``.  A string without
``@Tx`` and without a surface of three parameters gives the skeleton back as it is.  Polygons keep the
turtle's colour index (cpfg textures a polygon by its first vertex's texture; lsys3d does not).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ..lsystem.dialects.vlab_look import MAX_TEXTURES, texture_material
from ..lsystem.modules import ModuleString
from .commands import Organ
from .skeleton import Skeleton

__all__ = ["selections", "surface_findings"]


def _code(shown: ModuleString, name: str) -> int | None:
    return shown.alphabet.index(name) if name in shown.alphabet else None


def selections(skeleton: Skeleton, shown: ModuleString, materials: Mapping[str, object]) -> Skeleton:
    """``skeleton`` with cpfg's texture selections as material indices and ``~l``'s three scales.

    Parameters
    ----------
    skeleton : Skeleton
        What the turtle drew from ``shown``.
    shown : ModuleString
        The string the turtle read (after the homomorphism).
    materials : mapping
        The grammar's ``[materials]`` table: ``@Tx(n)`` selects a texture only when it holds the entry of
        ``texture_material(n)`` (the view file's n-th texture was read; cpfg selects none otherwise).
    """
    out = {}
    surface = skeleton.organ_kind == int(Organ.SURFACE)
    if surface.any():
        offsets = shown.offsets
        module = skeleton.organ_module
        arity = shown.arity[module].astype(np.int64)
        three = surface & (arity >= 3)
        if three.any():
            first = offsets[module[three]]
            sx, sy, sz = (shown.params[first + k] for k in range(3))
            scale = np.ones((len(module), 3))
            safe = np.where(sx != 0, sx, 1.0)
            scale[three] = np.stack([np.ones_like(sx), sz / safe, sy / safe], axis=1)  # left, up, heading
            scale[three] = np.where((sx != 0)[:, None], scale[three], 1.0)  # sx = 0: size 0, left out anyway
            out["organ_scale"] = scale
    code = _code(shown, "@Tx")
    if code is not None:
        texture = _texture_before(shown, code, {int(k) for k in materials if str(k).isdigit()})
        if texture is not None:
            at, index = texture
            seg = np.searchsorted(at, skeleton.module, side="left") - 1
            mat = np.where(seg >= 0, index[np.maximum(seg, 0)], -1)
            out["material"] = np.where(mat >= 0, mat, skeleton.material).astype(skeleton.material.dtype)
            if surface.any():
                org = np.searchsorted(at, skeleton.organ_module, side="left") - 1
                got = np.where(org >= 0, index[np.maximum(org, 0)], -1)
                chosen = surface & (got >= 0)
                out["organ_material"] = np.where(chosen, got, skeleton.organ_material).astype(
                    skeleton.organ_material.dtype
                )
    return replace(skeleton, **out) if out else skeleton


def _texture_before(shown: ModuleString, code: int, read: set[int]):
    """The texture state after each ``[``, ``]`` and ``@Tx`` of ``shown``: their places and the material
    index in force after each (-1: none), or None when no ``@Tx`` selects a texture that was read."""
    push, pop = _code(shown, "["), _code(shown, "]")
    kinds = [c for c in (code, push, pop) if c is not None]
    at = np.flatnonzero(np.isin(shown.symbols, kinds))
    symbols = shown.symbols[at]
    offsets, arity, params = shown.offsets, shown.arity, shown.params
    state, stack, index, any_set = -1, [], np.empty(len(at), np.int64), False
    for k, (i, s) in enumerate(zip(at.tolist(), symbols.tolist(), strict=True)):
        if s == code:
            state = -1
            if arity[i] >= 1:
                n = int(params[offsets[i]])  # cpfg: (int)n - 1, the n-th texture read
                chosen = texture_material(n) if 1 <= n <= MAX_TEXTURES else -1
                state = chosen if chosen in read else -1  # cpfg: not a texture that was read -> none
                any_set |= state >= 0
        elif s == push:
            stack.append(state)
        elif stack:  # cpfg's ']' with nothing pushed does nothing
            state = stack.pop()
        index[k] = state
    return (at, index) if any_set else None


def surface_findings(grammar, shown: ModuleString, skeleton: Skeleton) -> list[str]:
    """What cpfg draws that lsys3d does not, after a surface: cpfg moves the turtle to a surface's end point
    (``patches.c``: ``determine_end_point``; the ``[surfaces]`` entry's ``end_point``), lsys3d leaves it at
    the surface's base.  One line when a module other than ``]`` follows such a surface in the string."""
    moving = {
        name
        for name, entry in (grammar.surfaces or {}).items()
        if isinstance(entry, Mapping) and entry.get("end_point")
    }
    if not moving or not skeleton.n_organs:
        return []
    pop = _code(shown, "]")
    followed = set()
    for module, name in zip(skeleton.organ_module.tolist(), skeleton.organ_name.tolist(), strict=True):
        surface = name[1:] if name.startswith("~") else name
        nxt = module + 1
        if surface in moving and nxt < len(shown) and int(shown.symbols[nxt]) != pop:
            followed.add(surface)
    if not followed:
        return []
    names = ", ".join(f"'~{n}'" for n in sorted(followed))
    return [
        f"{grammar.source}: cpfg moves the turtle to the end point of the surface after {names} (its file's END "
        "POINT); lsys3d leaves it where the surface stands, so what follows in the branch is drawn from there"
    ]
