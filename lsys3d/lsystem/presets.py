"""The bundled grammars (``assets/presets`` in the source tree, ``lsys3d/presets`` when installed)."""

from __future__ import annotations

import os
import tomllib
from importlib import resources
from pathlib import Path

from ..errors import GrammarError, clip
from .dialects import SUFFIXES
from .grammar import Grammar

__all__ = ["DEFAULT_PRESET", "list_presets", "load", "load_preset", "preset_text"]

DEFAULT_PRESET = "tree3d"
"""The preset the CLI grows when it is given no grammar."""

_GRAMMAR_SUFFIXES = {".toml", *SUFFIXES}


def _folder():
    return resources.files("lsys3d.assets") / "presets"


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


def describe(name: str) -> str:
    """The one-line description of a preset."""
    data = tomllib.loads(preset_text(name))
    return data.get("description", "").strip().splitlines()[0] if data.get("description") else ""


def load(spec, **overrides) -> Grammar:
    """A grammar from a file path or a preset name (a path that exists wins)."""
    if isinstance(spec, Grammar):
        return spec.replace(**overrides) if overrides else spec
    path = Path(spec)
    # lexists() is False for a name too long, and True for a symlink loop: from_file says what is wrong
    if path.suffix in _GRAMMAR_SUFFIXES or "/" in str(spec) or os.sep in str(spec) or os.path.lexists(path):
        return Grammar.from_file(path, **overrides)
    return load_preset(str(spec), **overrides)
