"""Provenance: how an asset was grown, recorded in every file it is written to.

:class:`Provenance` is built in one place (:meth:`Provenance.of`, called by
the pipeline and by the tests' fixtures alike) and read by every writer through
:meth:`lsys3d.tree.Tree.metadata`.  Its JSON form is the ``lsys3d`` block of an
exported file (glTF ``extras``, USD ``customData``, SVG ``<metadata>``); the
asset's name (:attr:`Provenance.asset_name`) names the USD root prim, the glTF
scene and root node and the SVG title, so a scene that references several
lsys3d assets can tell them apart.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import PurePath

from .version import __version__

__all__ = ["Provenance", "asset_identifier", "grammar_text"]

DEFAULT_NAME = "tree"
"""The name of an asset whose grammar has none (and no file name to take one from)."""


@dataclass(frozen=True)
class Provenance:
    """How an asset was grown: enough to grow it again, and to name it.

    Attributes
    ----------
    grammar_name : str
        The grammar's ``name`` (may be empty).
    grammar_source : str
        Where the grammar came from: a file path, ``presets/<name>.toml``, or ``<string>``.
    grammar_text : str
        The grammar's text (TOML); a grammar built in Python is rendered as TOML.
    iterations, seed : int
    options : dict
        The :class:`~lsys3d.pipeline.GenerateOptions` as plain nested data.
    lsys3d_version : str
        The version of lsys3d that grew it.
    """

    grammar_name: str
    grammar_source: str
    grammar_text: str
    iterations: int
    seed: int
    options: dict = field(default_factory=dict)
    lsys3d_version: str = __version__

    @classmethod
    def of(cls, grammar, iterations: int, seed: int, options) -> Provenance:
        """The provenance of ``grammar`` grown ``iterations`` steps with ``seed`` and ``options`` (GenerateOptions)."""
        return cls(
            grammar_name=grammar.name,
            grammar_source=grammar.source,
            grammar_text=grammar.text if grammar.text is not None else grammar_text(grammar),
            iterations=int(iterations),
            seed=int(seed),
            options=options.plain(),
        )

    @property
    def generator(self) -> str:
        """``lsys3d <version>``: the generator string of glTF's ``asset`` and USD's metadata."""
        return f"lsys3d {self.lsys3d_version}"

    @property
    def asset_name(self) -> str:
        """The asset's name: the grammar's name, else its file's stem, else ``tree``.

        >>> Provenance("bush", "presets/bush.toml", "", 4, 0).asset_name
        'bush'
        >>> Provenance("", "plants/my oak.toml", "", 4, 0).asset_name
        'my oak'
        """
        if self.grammar_name.strip():
            return self.grammar_name.strip()
        source = self.grammar_source
        if source and not source.startswith("<"):
            stem = PurePath(source).stem
            if stem:
                return stem
        return DEFAULT_NAME

    def to_json(self) -> dict:
        """The JSON-ready form (sorted keys), with ``generator``."""
        data = {
            "generator": self.generator,
            "grammar_name": self.grammar_name,
            "grammar_source": self.grammar_source,
            "grammar_text": self.grammar_text,
            "iterations": self.iterations,
            "lsys3d_version": self.lsys3d_version,
            "options": self.options,
            "seed": self.seed,
        }
        return dict(sorted(data.items()))

    @classmethod
    def from_json(cls, data: dict) -> Provenance:
        """Read back :meth:`to_json` (extra keys such as ``generator`` and ``counts`` are ignored)."""
        return cls(
            grammar_name=str(data.get("grammar_name", "")),
            grammar_source=str(data.get("grammar_source", "")),
            grammar_text=str(data.get("grammar_text", "")),
            iterations=int(data["iterations"]),
            seed=int(data["seed"]),
            options=dict(data.get("options", {})),
            lsys3d_version=str(data.get("lsys3d_version", "")),
        )


def asset_identifier(name: str) -> str:
    """``name`` as an identifier (letters, digits, ``_``; not starting with a digit): USD prim names.

    >>> asset_identifier("abop-1.24a"), asset_identifier("bush"), asset_identifier("3 oaks"), asset_identifier("")
    ('abop_1_24a', 'bush', '_3_oaks', 'tree')
    """
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name.strip())
    if not ident:
        return DEFAULT_NAME
    return "_" + ident if ident[0].isdigit() else ident


def grammar_text(grammar) -> str:
    """A TOML rendering of a grammar (for provenance and golden recipes of grammars built in Python).

    Every field that differs from its default is written, the dialect first, so that reading the text
    back gives the same grammar (a native file's rules are written in its dialect's notation).
    """
    lines = [f"axiom = {json.dumps(grammar.axiom)}"]
    if grammar.dialect != "lsys3d":
        lines.insert(0, f"dialect = {json.dumps(grammar.dialect)}")
    for key in ("name", "description", "group", "ignore", "consider"):
        if getattr(grammar, key):
            lines.append(f"{key} = {json.dumps(getattr(grammar, key))}")
    lines.append(f"iterations = {grammar.iterations}")
    lines.append(f"angle = {grammar.angle!r}")
    lines.append(f"seed = {grammar.seed}")
    if grammar.defines:
        lines.append("defines = { " + ", ".join(f"{k} = {_define(v)}" for k, v in grammar.defines.items()) + " }")
    for key in ("modules", "functions", "rules", "homomorphism", "decomposition"):
        values = getattr(grammar, key)
        if values or key == "rules":
            lines.append(f"{key} = [" + ", ".join(json.dumps(r) for r in values) + "]")
    for key in ("homomorphism_depth", "decomposition_depth"):
        if getattr(grammar, key) != 1:
            lines.append(f"{key} = {getattr(grammar, key)}")
    for table in type(grammar).TABLES[1:]:  # the defines are written above
        if getattr(grammar, table):
            lines.append(f"[{table}]")
            lines.extend(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in getattr(grammar, table).items())
    return "\n".join(lines) + "\n"


def _define(value) -> str:
    """A define's TOML value: a number, or a constant array as nested lists."""
    return _toml_value(value.tolist()) if hasattr(value, "tolist") else repr(value)


def _toml_key(key) -> str:
    """A TOML key: bare when it can be, quoted otherwise."""
    key = str(key)
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key)


def _toml_value(value) -> str:
    """A TOML value for a table entry (a material's inline table; strings, numbers, booleans and lists as JSON)."""
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return json.dumps(value)
