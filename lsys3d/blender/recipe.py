"""What a plant in Blender was grown from: the recipe the add-on keeps on the plant's object.

A :class:`Recipe` is plain data (no ``bpy``): the grammar (a bundled preset, or a grammar file that overrides
it), iterations, seed, the grammar's ``defines`` as the artist set them, and the options the add-on's panel
shows.  :meth:`Recipe.to_json` is what goes into the object's ``lsys3d_recipe`` custom property (a JSON
string, so it survives a save and reopen as it is), and :func:`grow` grows it with
:func:`lsys3d.pipeline.generate`, the same call the command line makes.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from ..errors import GrammarError, OptionsError
from ..lsystem.grammar import Grammar
from ..lsystem.presets import list_presets, load_preset
from ..pipeline import GenerateOptions, generate
from ..tree import Tree

__all__ = ["RECIPE_KEY", "Recipe", "grammar_of", "grow", "numeric_defines"]

RECIPE_KEY = "lsys3d_recipe"
"""The custom property of a plant's object that holds its recipe (JSON text)."""

LOD_LEVELS = 4
"""Levels of detail the panel offers: 0 (the tree as grown) to 3 (cards)."""


@dataclass(frozen=True)
class Recipe:
    """A plant's grammar, iterations, seed and the options the add-on shows.

    Attributes
    ----------
    preset : str
        A bundled preset (``lsys3d presets``); ignored when ``grammar_file`` is set.
    grammar_file : str
        A grammar file (TOML, or a native ``.lpy`` / ``.l`` / ``.ls``); empty: the preset.
    iterations : int
        Derivation steps; 0: the grammar's own.
    seed : int
        The seed of stochastic rules and jitters.
    defines : dict of str to float
        Values of the grammar's numeric ``defines`` that replace the file's.
    leaves : bool
        Leaves and organs in the scene.
    union : bool
        The watertight union of the tubes (off: the tube soup, fast).
    sides : int
        Tube sides of the trunk; 0: the default (:class:`~lsys3d.mesh.sweep.SweepOptions`).
    lod : int
        The level of detail to show, 0 (as grown) to 3.
    rig : bool
        An armature along the branches, bark and leaves weighted to it.
    textures : bool
        The grammar's textures as image nodes (off: plain colours).
    wind : float
        Seconds of the looping sample wind animation keyed on the rig (0: none; needs ``rig``).
    attributes : bool
        The hierarchy and wind attributes (:mod:`lsys3d.look.attributes`, the ``full`` layout: every one on
        every vertex and leaf) as mesh and point attributes.
    """

    preset: str = "tree3d"
    grammar_file: str = ""
    iterations: int = 0
    seed: int = 0
    defines: dict = field(default_factory=dict)
    leaves: bool = True
    union: bool = True
    sides: int = 0
    lod: int = 0
    rig: bool = False
    textures: bool = True
    attributes: bool = False
    wind: float = 0.0

    def __post_init__(self):
        if self.iterations < 0:
            raise OptionsError(f"iterations: must be 0 (the grammar's own) or more, not {self.iterations}")
        if not 0 <= self.lod < LOD_LEVELS:
            raise OptionsError(f"lod: a level from 0 to {LOD_LEVELS - 1}, not {self.lod}")
        if self.sides and self.sides < 3:
            raise OptionsError(f"sides: 0 (the default) or at least 3, not {self.sides}")
        object.__setattr__(self, "defines", {str(k): float(v) for k, v in sorted(dict(self.defines).items())})

    @property
    def name(self) -> str:
        """The plant's name: the grammar file's stem, or the preset."""
        return Path(self.grammar_file).stem if self.grammar_file else self.preset

    def options(self) -> GenerateOptions:
        """The :class:`~lsys3d.pipeline.GenerateOptions` of this recipe (every other option at its default)."""
        flat = {"union": self.union, "rig": self.rig}
        if self.sides:
            flat["sides"] = self.sides
        if self.lod:
            flat["lod"] = (self.lod,)
        if self.attributes:
            flat["attributes"] = "full"
        if self.wind:
            flat["wind_animation"] = self.wind
        return GenerateOptions.from_flat(**flat)

    def to_json(self) -> str:
        """The recipe as JSON text (keys sorted): the custom property's value."""
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Recipe:
        """The recipe of :meth:`to_json`'s text; unknown keys (a newer add-on's) are refused by name."""
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise OptionsError(f"{RECIPE_KEY}: not a recipe ({exc})") from None
        if not isinstance(data, dict):
            raise OptionsError(f"{RECIPE_KEY}: not a recipe (a JSON object is expected)")
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - known)
        if unknown:
            raise OptionsError(f"{RECIPE_KEY}: unknown keys {unknown} (known: {sorted(known)})")
        return cls(**data)

    def replace(self, **changes) -> Recipe:
        return replace(self, **changes)


def grammar_of(recipe: Recipe, base: str | None = None) -> Grammar:
    """The recipe's grammar with its ``defines`` applied.

    ``base``: the folder a relative ``grammar_file`` is read from (the .blend file's); a define the grammar
    does not have is refused.

    Raises
    ------
    GrammarError
        ``file:line:col: what`` for a bad grammar, ``file: what`` for a missing one.
    """
    if recipe.grammar_file:
        path = Path(recipe.grammar_file)
        if not path.is_absolute() and base:
            path = Path(base) / path
        grammar = Grammar.from_file(path)
    else:
        if recipe.preset not in list_presets():
            raise GrammarError(f"no bundled preset named {recipe.preset!r}", recipe.preset)
        grammar = load_preset(recipe.preset)
    if recipe.defines:
        own = numeric_defines(grammar)
        unknown = sorted(set(recipe.defines) - set(own))
        if unknown:
            raise GrammarError(f"defines {unknown} are not numeric defines of the grammar", grammar.source)
        grammar = grammar.replace(defines={**grammar.defines, **recipe.defines})
    return grammar


def numeric_defines(grammar: Grammar) -> dict[str, float]:
    """The grammar's ``defines`` that are numbers (the sliders the panel shows), by name."""
    return {k: float(v) for k, v in grammar.defines.items() if isinstance(v, int | float) and not isinstance(v, bool)}


def grow(recipe: Recipe, base: str | None = None, progress=None) -> tuple[Tree, int]:
    """The plant of ``recipe``: its tree (at the recipe's level of detail) and the level it is.

    The tree is :func:`lsys3d.pipeline.generate`'s, with the recipe's iterations (0: the grammar's own),
    seed and options; a level of detail above 0 is the tree's :meth:`~lsys3d.tree.Tree.at_level`.
    """
    grammar = grammar_of(recipe, base)
    tree = generate(
        grammar,
        recipe.iterations or None,
        recipe.seed,
        options=recipe.options(),
        progress=progress,
    )
    if recipe.lod and tree.lods:
        levels = [lod.level for lod in tree.lods]
        tree = tree.at_level(levels.index(recipe.lod))
    return tree, recipe.lod
