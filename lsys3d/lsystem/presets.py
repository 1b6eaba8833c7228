"""The bundled grammars (``assets/presets`` in the source tree, ``lsys3d/presets`` when installed)."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..errors import GrammarError, clip
from .dialects import GRAMMAR_SUFFIXES
from .grammar import GROUPS, Grammar

__all__ = [
    "DEFAULT_PRESET",
    "GROUPS",
    "PresetInfo",
    "bundled_folder",
    "list_presets",
    "load",
    "load_preset",
    "preset_info",
    "preset_text",
]

DEFAULT_PRESET = "oak"
"""The preset the CLI grows when it is given no grammar."""


def _folder():
    return resources.files("lsys3d.assets") / "presets"


def bundled_folder(grammar) -> Path | None:
    """The presets' folder when ``grammar`` is a bundled preset (files it names are found there), else None."""
    source = str(getattr(grammar, "source", "") or "")
    m = re.fullmatch(r"presets/([A-Za-z0-9_.-]+)\.toml", source)
    if not m or m.group(1) not in list_presets():
        return None
    return Path(str(_folder()))


def list_presets() -> list[str]:
    """Names of the bundled presets, sorted."""
    return sorted(p.name[: -len(".toml")] for p in _folder().iterdir() if p.name.endswith(".toml"))


def preset_text(name: str) -> str:
    """The TOML text of a bundled preset."""
    if not isinstance(name, str) or name not in list_presets():  # never a path out of the presets folder
        raise GrammarError(f"no bundled preset named {clip(repr(name))} (see 'lsys3d presets')", clip(name))
    return (_folder() / f"{name}.toml").read_text(encoding="utf-8")


def load_preset(name: str, **overrides) -> Grammar:
    """Load a bundled preset by name, e.g. ``load_preset("koch")``."""
    return Grammar.from_text(preset_text(name), source=f"presets/{name}.toml", **overrides)


@dataclass(frozen=True)
class PresetInfo:
    """What ``lsys3d presets`` says of one bundled preset.

    Attributes
    ----------
    name : str
        The preset's name (its file's stem).
    group : str
        One of :data:`GROUPS`: ``species`` (a plant grown to its real size), ``figure`` (a textbook figure),
        ``curve``.
    description : str
        The first line of its ``description``.
    """

    name: str
    group: str
    description: str

    def to_json(self) -> dict:
        return {"name": self.name, "group": self.group, "description": self.description}


def preset_info(name: str) -> PresetInfo:
    """The name, group and description of a bundled preset.

    The group is the file's ``group`` key. A preset without one (the figures written before species came)
    is a ``curve`` when its strings never branch (no ``[`` in the axiom or any rule: ABOP chapter 1's curves
    and plain strings), else a ``figure``.

    >>> preset_info("koch").group, preset_info("tree3d").group
    ('curve', 'figure')
    """
    grammar = load_preset(name)  # checks the group
    group = grammar.group or ("figure" if "[" in grammar.written_symbols else "curve")
    description = grammar.description.strip()
    return PresetInfo(name, group, description.splitlines()[0] if description else "")


def load(spec, **overrides) -> Grammar:
    """A grammar from a file path or a preset name (a path that exists wins)."""
    if isinstance(spec, Grammar):
        return spec.replace(**overrides) if overrides else spec
    path = Path(spec)
    # lexists() is False for a name too long, and True for a symlink loop: from_file says what is wrong
    if path.suffix in GRAMMAR_SUFFIXES or "/" in str(spec) or os.sep in str(spec) or os.path.lexists(path):
        return Grammar.from_file(path, **overrides)
    return load_preset(str(spec), **overrides)
