"""The main job: grammar -> :class:`~lsys3d.tree.Tree`, running every stage in order.

Each stage is a call into its own module; this one only sequences them, times
them and records the provenance that lets an exported asset be regenerated.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np
import trimesh

from .bark import with_bark_colors
from .derive import DEFAULT_MAX_MODULES, derive
from .errors import GeometryError
from .grammar import Grammar
from .leaves import leaves as build_leaves
from .modules import ModuleString
from .presets import load
from .skeleton import Skeleton
from .sweep import DEFAULT_MAX_TRIANGLES, SweepOptions, sweep
from .tree import BARK, Tree
from .turtle import DEFAULT_MAX_SEGMENTS, TurtleOptions, interpret
from .union import UnionOptions, concatenate, union

__all__ = ["STAGES", "GenerateOptions", "draw", "generate", "run_stage"]

log = logging.getLogger("lsys3d")

STAGES = ("derive", "interpret", "sweep", "union", "leaves")
"""The stages :func:`generate` reports to its ``progress`` callback, in order."""


@dataclass(frozen=True)
class GenerateOptions:
    """Everything :func:`generate` needs besides the grammar; defaults in one place.

    Attributes
    ----------
    union : bool
        Merge the tubes into one watertight mesh (False: the tube soup, a fast preview).
    max_modules : int
        Derivation size limit.
    max_segments : int
        Most segments the turtle draws.
    max_tube_triangles : int
        Most triangles the sweep builds (checked before the tubes are allocated).
    sweep : SweepOptions
        Tube sides, minimum width, bend splitting...
    union_options : UnionOptions
        How the manifold union is organised.
    turtle : dict
        Settings that override the grammar's ``[turtle]`` table, e.g.
        ``{"width_jitter": 0.2, "branch_drop": 0.1}`` (any
        :class:`~lsys3d.turtle.TurtleOptions` field but ``angle`` and ``seed``).
    bark_color_variation : float
        Bark colour variation in [0, 1] written as vertex colours after the
        union (:func:`lsys3d.bark.bark_colors`; 0: off, no colours).
    bark_color_frequency : float
        Colour features per metre of that pattern.
    """

    union: bool = True
    max_modules: int = DEFAULT_MAX_MODULES
    max_segments: int = DEFAULT_MAX_SEGMENTS
    max_tube_triangles: int = DEFAULT_MAX_TRIANGLES
    sweep: SweepOptions = field(default_factory=SweepOptions)
    union_options: UnionOptions = field(default_factory=UnionOptions)
    turtle: dict = field(default_factory=dict)
    bark_color_variation: float = 0.0
    bark_color_frequency: float = 2.0

    def __post_init__(self):
        known = {f.name for f in fields(TurtleOptions)} - {"angle", "seed"}
        unknown = sorted(set(self.turtle) - known)
        if unknown:
            raise ValueError(
                f"GenerateOptions.turtle: unknown setting {unknown[0]!r} (known: {', '.join(sorted(known))})"
            )
        if not 0 <= self.bark_color_variation <= 1:
            raise ValueError(f"GenerateOptions.bark_color_variation: {self.bark_color_variation!r} is not in [0, 1]")
        if not self.bark_color_frequency > 0:
            raise ValueError(f"GenerateOptions.bark_color_frequency: {self.bark_color_frequency!r} is not > 0")

    def plain(self) -> dict:
        """The options as JSON-ready nested dicts with sorted keys (tuples as lists): provenance, golden recipes."""
        return _plain(asdict(self))


def _version() -> str:
    from . import __version__

    return __version__


def run_stage(name: str, fn: Callable, *args, progress: Callable[[str, str, float], None] | None = None, **kw):
    """Call ``fn(*args, **kw)`` as stage ``name``: report it to ``progress`` and log its time.

    ``progress(name, "start", 0.0)`` comes first and ``progress(name, "done", seconds)`` last; a long stage
    (the union) may report ``progress(name, "progress", fraction)`` between them, fraction in [0, 1].
    """
    if progress:
        progress(name, "start", 0.0)
    t0 = time.perf_counter()
    result = fn(*args, **kw)
    seconds = time.perf_counter() - t0
    log.info("%-9s %.3f s", name, seconds)
    if progress:
        progress(name, "done", seconds)
    return result


def draw(
    grammar: Grammar,
    iterations: int,
    seed: int,
    options: GenerateOptions | None = None,
    progress: Callable[[str, str, float], None] | None = None,
) -> tuple[ModuleString, Skeleton]:
    """The first two stages: derive the module string and let the turtle draw its skeleton.

    ``options`` gives the size limits and the ``turtle`` overrides of the
    grammar's ``[turtle]`` table; :func:`generate` goes on from here to the meshes.

    Examples
    --------
    >>> from lsys3d import load_preset
    >>> modules, skeleton = draw(load_preset("koch"), 1, 0)
    >>> len(modules), len(skeleton)
    (8, 4)
    """
    options = options or GenerateOptions()
    modules = run_stage("derive", derive, grammar, iterations, seed, max_modules=options.max_modules, progress=progress)
    turtle = TurtleOptions.from_grammar(grammar, **options.turtle) if options.turtle else grammar
    skeleton = run_stage(
        "interpret", interpret, modules, turtle, seed=seed, max_segments=options.max_segments, progress=progress
    )
    return modules, skeleton


def generate(
    grammar: Grammar | str,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    options: GenerateOptions | None = None,
    progress: Callable[[str, str, float], None] | None = None,
    **overrides,
) -> Tree:
    """Grow a plant: derive, interpret, sweep, union and build the leaves.

    Parameters
    ----------
    grammar : Grammar or str
        A grammar, a grammar file path, or the name of a bundled preset.
    iterations, seed : int, optional
        Override the grammar's own.
    options : GenerateOptions, optional
        Defaults to ``GenerateOptions()``; keyword arguments ``union``,
        ``max_modules``, ``sides`` override single fields.
    progress : callable, optional
        Called as ``progress(stage, "start" | "done", seconds)`` for each stage, and as
        ``progress("union", "progress", fraction)`` while the union works (fraction from 0 to 1).

    Returns
    -------
    Tree

    Examples
    --------
    >>> tree = generate("abop-1.24a", iterations=2, sides=5)
    >>> tree.bark.is_watertight, tree.provenance["iterations"]
    (True, 2)
    """
    options = options or GenerateOptions()
    if "sides" in overrides:
        options = replace(options, sweep=replace(options.sweep, sides=overrides.pop("sides")))
    if overrides:
        options = replace(options, **overrides)
    if not isinstance(grammar, Grammar):
        grammar = load(grammar)
    n = grammar.iterations if iterations is None else iterations
    seed = grammar.seed if seed is None else seed

    def stage(name, fn, *args, **kw):
        return run_stage(name, fn, *args, progress=progress, **kw)

    modules, skeleton = draw(grammar, n, seed, options, progress=progress)
    if len(skeleton) == 0 and skeleton.n_leaves == 0:
        raise GeometryError(
            f"{grammar.name or grammar.source}: nothing to mesh: the {len(modules):,} modules after {n} "
            "iterations draw no segment and no leaf (segments are drawn by F, or the [turtle] table's draw symbols)"
        )
    tubes = stage("sweep", sweep, skeleton, options.sweep, max_triangles=options.max_tube_triangles, seed=seed)
    if len(tubes) == 0 and skeleton.n_leaves == 0:
        raise GeometryError(
            f"{grammar.name or grammar.source}: nothing to mesh: all {len(skeleton):,} segments are shorter than "
            f"min_length ({options.sweep.min_length:g}) and there is no leaf"
        )
    if len(tubes) == 0:  # leaves alone (ABOP's polygon figures): an empty bark
        bark = stage("union", lambda _: trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), tubes)
    else:

        def report(fraction: float) -> None:
            progress("union", "progress", fraction)

        def merge(t):
            return union(t, options.union_options, progress=report if progress else None)

        if not options.union:
            merge = concatenate
        if options.bark_color_variation > 0:  # coloured in the union stage: the colours belong to its vertices
            plain = merge
            variation, frequency = options.bark_color_variation, options.bark_color_frequency

            def merge(t):
                return with_bark_colors(plain(t), BARK.base_color, variation, frequency, seed)

        bark = stage("union", merge, tubes)
    leaves = stage("leaves", build_leaves, skeleton)
    counts = {
        "modules": len(modules),
        "segments": len(skeleton),
        "tubes": len(tubes.sides),
        "tube_vertices": len(tubes.points),
        "tube_faces": len(tubes.faces),
    }
    provenance = {
        "generator": f"lsys3d {_version()}",
        "lsys3d_version": _version(),
        "grammar_name": grammar.name,
        "grammar_source": grammar.source,
        "grammar_text": grammar.text if grammar.text is not None else _grammar_as_text(grammar),
        "iterations": int(n),
        "seed": int(seed),
        "options": options.plain(),
        "counts": counts,
    }
    return Tree(
        bark=bark,
        skeleton=skeleton,
        provenance=provenance,
        leaves=leaves.merged,
        leaf_model=leaves.model,
        leaf_transforms=leaves.transforms,
        polygon_leaves=leaves.polygons,
        unioned=options.union,
        modules=modules,
    )


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in sorted(value.items())}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _grammar_as_text(grammar: Grammar) -> str:
    """A TOML rendering of a grammar built from Python (for provenance)."""
    lines = [f"axiom = {json.dumps(grammar.axiom)}"]
    for key in ("name", "description", "ignore"):
        if getattr(grammar, key):
            lines.append(f"{key} = {json.dumps(getattr(grammar, key))}")
    lines.append(f"iterations = {grammar.iterations}")
    lines.append(f"angle = {grammar.angle!r}")
    lines.append(f"seed = {grammar.seed}")
    if grammar.defines:
        lines.append("defines = { " + ", ".join(f"{k} = {v!r}" for k, v in grammar.defines.items()) + " }")
    lines.append("rules = [" + ", ".join(json.dumps(r) for r in grammar.rules) + "]")
    if grammar.turtle:
        lines.append("[turtle]")
        lines.extend(f"{k} = {json.dumps(v)}" for k, v in grammar.turtle.items())
    return "\n".join(lines) + "\n"
