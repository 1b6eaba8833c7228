"""The main job: grammar -> :class:`~lsys3d.tree.Tree`, running every stage in order.

Each stage is a call into its own module; this one only sequences them, times
them and records the provenance that lets an exported asset be regenerated::

    derive -> interpret (-> form) -> sweep -> union -> cleanup -> color -> materials -> attributes -> leaves
    -> rig -> wind (-> lod)
"""

from __future__ import annotations

import functools
import logging
import os
import time
import warnings
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from .arrays import release_memory
from .errors import GeometryError, OptionsError, SeedWarning
from .look import bark as bark_stage
from .look import growth as growth_stage
from .look.attributes import VERTEX_KEYS, AttributeOptions, with_attributes
from .look.growth import GrowthOptions
from .look.leaves import LeafOptions
from .look.leaves import leaves as build_leaves
from .look.lod import (
    LEVELS,
    Lod,
    LodOptions,
    fit_budget,
    kept_segments,
    level_hierarchy,
    level_options,
    lod_leaves,
    prune,
)
from .look.materials import material_table, with_face_materials
from .look.organs import OrganOptions, bind_organs, skeleton_organs
from .look.rig import SKIN_KEYS, RigOptions, bind, build_rig
from .look.surfaces import surface_table, with_cards
from .look.wind import WindOptions, sway
from .lsystem import dialects
from .lsystem.ages import derive_with_ages, growth_table, interpretation_ages
from .lsystem.derive import DEFAULT_MAX_MODULES, interpretation
from .lsystem.grammar import Grammar
from .lsystem.modules import ModuleString
from .lsystem.presets import load
from .mesh.cleanup import CleanupOptions, clean_junctions, cleanup
from .mesh.mesh import Mesh
from .mesh.sweep import DEFAULT_MAX_TRIANGLES, SweepOptions, Tubes, sweep
from .mesh.union import jobs as union_jobs
from .mesh.union.union import UnionOptions, concatenate, union, union_cleaning_junctions
from .options import Options, flat_fields, option, unknown_name
from .provenance import Provenance
from .tree import StageCounts, Tree
from .turtle import (
    DEFAULT_MAX_SEGMENTS,
    GRAMMAR_KEYS,
    FormOptions,
    TurtleOptions,
    TurtleOverrides,
    form,
    interpret,
    symbol_table,
)
from .turtle.diagnostics import Checks, check
from .turtle.environment import EnvironmentOptions, load_environment
from .turtle.hierarchy import hierarchy
from .turtle.query import asks_turtle, derive_answering
from .turtle.selections import selections
from .turtle.skeleton import Skeleton
from .turtle.steering import SteeringMemo
from .turtle.timing import timed

__all__ = [
    "STAGES",
    "GenerateOptions",
    "Limits",
    "draw",
    "generate",
    "grow",
    "run_stage",
    "seed_dependence",
    "warn_if_identical",
]

log = logging.getLogger("lsys3d")

STAGES = (
    "derive",
    "interpret",
    "form",
    "sweep",
    "union",
    "cleanup",
    "color",
    "materials",
    "attributes",
    "leaves",
    "organs",
    "rig",
    "wind",
    "growth",
    "lod",
)
"""The stages :func:`generate` reports to its ``progress`` callback, in order."""


@dataclass(frozen=True)
class Limits(Options):
    """The size limits of the stages: each is checked before the memory is taken."""

    max_modules: int = option(
        DEFAULT_MAX_MODULES, low=1, help="size limit of derivation, in modules (predicted before allocating)"
    )
    max_segments: int = option(DEFAULT_MAX_SEGMENTS, low=1, help="most segments the turtle draws")
    max_triangles: int = option(
        DEFAULT_MAX_TRIANGLES,
        low=1,
        help="most tube triangles before the union, and most leaf triangles baked in place (counted before allocating)",
    )


@dataclass(frozen=True)
class GenerateOptions(Options):
    """Everything :func:`generate` needs besides the grammar, its iterations and seed: one options class per stage.

    Attributes
    ----------
    limits : Limits
        Module, segment and tube-triangle limits.
    turtle : TurtleOverrides
        Settings that override the grammar's ``[turtle]`` table, e.g.
        ``{"width_jitter": 0.2, "branch_drop": 0.1}`` (any
        :class:`~lsys3d.turtle.TurtleOptions` field but ``angle`` and ``seed``);
        a dict is accepted and checked.
    form : FormOptions
        The botanical form of the skeleton (pipe-model widths, flare, curvature...), over the grammar's
        ``[form]`` table (:meth:`FormOptions.from_grammar`); all off by default.
    sweep : SweepOptions
        Tube sides, minimum width, bend splitting, bark displacement...
    union : UnionOptions
        Whether (``union=False``: the tube soup, a fast preview) and how the tubes are unioned.
    cleanup : CleanupOptions
        Removing the union's needles and slivers (``cleanup=False``: the raw boolean).
    color : BarkColorOptions
        Bark colour variation written as vertex colours after the union.
    attributes : AttributeOptions
        Hierarchy and wind attributes on the bark's vertices and the leaves (off by default).
    leaves : LeafOptions
        The built-in leaf's shape and resolution (a grammar's ``[surfaces] leaf`` replaces the built-in leaf),
        the leaves' size, clusters, turn to the light, droop and cards; over the grammar's ``[leaves]`` table.
    organs : OrganOptions
        The resolution of the built-in organs (spheres, discs) the dialects' ``@O``, ``@c``, ``@o`` draw.
    rig : RigOptions
        Joints along the branches and the skin that binds bark and leaves to them (off by default).
    wind : WindOptions
        A sample wind animation keyed on the rig's joints (off by default; needs the rig, or the growth).
    growth : GrowthOptions
        The growth animation (the plant growing from its seed, keyed on the rig's joints; builds the rig it
        needs when ``rig`` is off) and the birth attribute (off by default).
    checks : Checks
        Whether the grammar's warnings (:mod:`lsys3d.turtle.diagnostics`) are errors (``strict``).
    lod : LodOptions
        Levels of detail to build as well, or a triangle budget to fit.

    Every field below these has a flat name (``sides``, ``union``,
    ``max_modules``, ``bark_color_variation``...) for :meth:`from_flat`,
    :func:`generate`'s keywords and the CLI's flags.
    """

    limits: Limits = option(factory=Limits, help="size limits")
    turtle: TurtleOverrides = field(default_factory=TurtleOverrides)
    form: FormOptions = option(factory=FormOptions, help="the botanical form")
    sweep: SweepOptions = option(factory=SweepOptions, help="tubes")
    union: UnionOptions = option(factory=UnionOptions, help="the union")
    cleanup: CleanupOptions = option(factory=CleanupOptions, help="the cleanup of the union")
    color: bark_stage.BarkColorOptions = option(factory=bark_stage.BarkColorOptions, help="bark colour")
    attributes: AttributeOptions = option(factory=AttributeOptions, help="hierarchy and wind attributes")
    leaves: LeafOptions = option(factory=LeafOptions, help="leaves")
    organs: OrganOptions = option(factory=OrganOptions, help="organs")
    rig: RigOptions = option(factory=RigOptions, help="the rig")
    wind: WindOptions = option(factory=WindOptions, help="the wind animation")
    growth: GrowthOptions = option(factory=GrowthOptions, help="the growth animation")
    checks: Checks = option(factory=Checks, help="the grammar's warnings")
    lod: LodOptions = option(factory=LodOptions, help="levels of detail")
    environment: EnvironmentOptions = option(factory=EnvironmentOptions, help="the place the plant grows in")

    def __post_init__(self):
        if not isinstance(self.turtle, TurtleOverrides):
            object.__setattr__(self, "turtle", TurtleOverrides(self.turtle))
        super().__post_init__()
        if self.wind.enabled and not self.rig.enabled and not self.growth.enabled:
            raise OptionsError(
                "WindOptions.seconds (--wind-animation): the wind animation moves the rig's joints: "
                "it needs the rig (--rig, or the one --growth-animation builds)"
            )

    def with_flat(self, **values):
        """A copy with fields changed by their flat names, the ``[turtle]`` settings among them.

        A ``[turtle]`` key that is no other field's flat name (``angle_jitter``,
        ``branch_drop``, ``tropism``...; not ``step``, the cleanup's) sets
        that entry of ``turtle``, over the ones it has: the spelling of
        ``--turtle KEY=VALUE``.

        >>> GenerateOptions.from_flat(angle_jitter=8, sides=6).turtle["angle_jitter"]
        8.0
        """
        turtle = {k: values.pop(k) for k in list(values) if k in TURTLE_FLAT_NAMES}
        names = flat_fields(GenerateOptions)
        for key in values:
            if key not in names and key != "turtle":
                known = [*names, *TURTLE_FLAT_NAMES, "turtle"]
                raise OptionsError(f"GenerateOptions: {unknown_name('option', key, known)}")
        options = super().with_flat(**values) if values else self
        if turtle:
            options = options.replace(turtle={**options.turtle, **turtle})
        return options

    def plain(self) -> dict:
        """The options as plain data; ``form`` only when it is not the default (older records did not have it)."""
        data = super().plain()
        if self.form == FormOptions():
            del data["form"]
        if self.environment == EnvironmentOptions():
            del data["environment"]
        if self.growth == GrowthOptions():
            del data["growth"]
        return data

    @property
    def rigging(self) -> RigOptions:
        """The rig the tree gets: ``rig``, or the growth's when only the growth animation asks for one (joints on
        branches of every depth, a quarter of the budget kept for the leaves' joints)."""
        if self.rig.enabled or not self.growth.enabled:
            return self.rig
        return replace(self.rig, enabled=True, max_joints=max(2, self.rig.max_joints * 3 // 4), max_depth=1_000_000)


TURTLE_FLAT_NAMES = frozenset(GRAMMAR_KEYS) - set(flat_fields(GenerateOptions))
"""The ``[turtle]`` settings :meth:`GenerateOptions.with_flat` and :func:`generate` take by their keys."""

_JITTERS = ("angle_jitter", "length_jitter", "width_jitter", "branch_roll", "branch_drop")


def seed_dependence(grammar: Grammar, options: GenerateOptions | None = None) -> tuple[str, ...]:
    """What the seed changes in a plant grown from ``grammar`` with ``options``; empty when nothing does.

    The seed drives stochastic rules (two or more alternatives for one
    predecessor), the turtle's jitters, branch roll and drop, and the bark's
    noise (displacement and colour).

    Examples
    --------
    >>> from lsys3d import load_preset
    >>> seed_dependence(load_preset("tree3d")), seed_dependence(load_preset("koch-stochastic"))
    ((), ('stochastic rules',))
    >>> seed_dependence(load_preset("tree3d"), GenerateOptions.from_flat(bark_displacement=0.2))
    ('bark_displacement',)
    """
    options = options or GenerateOptions()
    found = []
    pools = Counter(p.pool_key() for p in grammar.productions)
    if any(n > 1 for n in pools.values()):
        found.append("stochastic rules")
    turtle = TurtleOptions.from_grammar(grammar, options.turtle)
    found += [name for name in _JITTERS if getattr(turtle, name) > 0]
    found += FormOptions.from_grammar(grammar, options.form).seeded
    if options.sweep.bark_displacement > 0:
        found.append("bark_displacement")
    if options.color.variation > 0:
        found.append("bark_color_variation")
    return tuple(found)


# what the warnings suggest to make siblings differ, spelled for Python (generate's keywords) and the CLI
_ADVICE = {
    False: "angle_jitter=5, width_jitter=0.1, branch_roll=30, bark_displacement=0.2 or bark_color_variation=0.3",
    True: "--turtle angle_jitter=5 --turtle width_jitter=0.1 --turtle branch_roll=30, --bark-displacement 0.2 or "
    "--bark-color-variation 0.3",
}


def warn_if_identical(
    grammar: Grammar, options: GenerateOptions | None, count: int, *, cli: bool = False, stacklevel: int = 2
) -> bool:
    """Warn (:class:`~lsys3d.errors.SeedWarning`) that ``count`` siblings would be identical; whether it did.

    Siblings differ only by their seed: when nothing depends on it
    (:func:`seed_dependence`) they are copies, and the warning names the
    settings that would make them differ, spelled as :func:`generate`'s
    keywords, or with ``cli`` as ``lsys3d generate``'s flags.  The one rule
    behind both: ``generate(..., seed=s)`` with ``s`` other than the grammar's
    own seed warns through it (``count`` 2: that plant and the grammar's own),
    and so does ``lsys3d generate --seed S`` or ``--variants N``.  The message
    does not name the seed, so a loop over seeds warns once (``warnings``'
    default filter shows a message once per place).

    Examples
    --------
    >>> import warnings
    >>> from lsys3d import load_preset
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warn_if_identical(load_preset("tree3d"), None, 5), warn_if_identical(load_preset("oak"), None, 5)
    (True, False)
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    tree3d grows the same plant from every seed (no stochastic rules, turtle jitter or bark noise): ...
    """
    if count < 2 or seed_dependence(grammar, options):
        return False
    name = grammar.name or grammar.source
    what = f"its {count} variants are identical" if count > 2 else "another seed gives the same plant"
    warnings.warn(
        f"{name} grows the same plant from every seed (no stochastic rules, turtle jitter or bark noise): "
        f"{what}; vary them with e.g. {_ADVICE[cli]}",
        SeedWarning,
        stacklevel=stacklevel + 1,
    )
    return True


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
    """The first stages: derive the module string, let the turtle draw its skeleton and give it its form.

    ``options`` gives the size limits, the ``turtle`` overrides of the
    grammar's ``[turtle]`` table and the ``form`` over its ``[form]`` table (the
    form stage runs, as ``"form"``, only when some feature of it is on);
    :func:`generate` goes on from here to the meshes.
    The turtle reads the derived string rewritten by the grammar's homomorphism
    rules (:func:`lsys3d.lsystem.derive.interpretation`), with its dialect's commands;
    what it cannot draw as meant is reported (:mod:`lsys3d.turtle.diagnostics`).

    Examples
    --------
    >>> from lsys3d import load_preset
    >>> modules, skeleton = draw(load_preset("koch"), 1, 0)
    >>> len(modules), len(skeleton)
    (8, 4)
    """
    options = options or GenerateOptions()
    limits = options.limits
    timing = growth_table(grammar) if options.growth.timed else None  # the plant's development: ages
    ages = None
    turtle = TurtleOptions.from_grammar(grammar, options.turtle)
    commands = dialects.get(grammar.dialect).commands
    environment = load_environment(grammar, options.environment)
    scene = environment.scene() if environment is not None else None
    steering = SteeringMemo() if environment is not None else None  # the segments steered while deriving
    if timing is not None and (environment is not None or asks_turtle(grammar, commands)):
        raise OptionsError(
            "GrowthOptions: the timed growth animation does not follow query modules or an environment "
            "(their answers change the string between the steps): grow such a plant without it"
        )
    if timing is None:
        modules = run_stage(
            "derive",
            derive_answering,
            grammar,
            iterations,
            seed,
            turtle=turtle,
            commands=commands,
            environment=environment,
            max_modules=limits.max_modules,
            max_segments=limits.max_segments,
            steering=steering,
            progress=progress,
        )
    else:
        modules, ages = run_stage(
            "derive",
            derive_with_ages,
            grammar,
            iterations,
            seed,
            table=timing,
            max_modules=limits.max_modules,
            progress=progress,
        )
    shape = FormOptions.from_grammar(grammar, options.form)

    def turtle_stage():
        nonlocal ages
        if timing is None:
            shown = interpretation(grammar, modules, seed, max_modules=limits.max_modules, iterations=iterations)
        else:
            shown, ages = interpretation_ages(
                grammar, modules, ages, seed, table=timing, max_modules=limits.max_modules, iterations=iterations
            )
        skeleton = interpret(
            shown,
            turtle,
            seed=seed,
            max_segments=limits.max_segments,
            commands=commands,
            scene=scene,
            steering=steering,
        )
        if grammar.dialect == "cpfg":  # cpfg's texture selection (@Tx) and ~l's three scales
            skeleton = selections(skeleton, shown, grammar.materials)
        return shown, skeleton

    shown, skeleton = run_stage("interpret", turtle_stage, progress=progress)
    table = symbol_table(shown.alphabet, turtle.draw, turtle.move, turtle.leaf, commands)
    check(grammar, shown, skeleton, table, options.checks)
    if shape.active:
        skeleton = run_stage("form", form, skeleton, shape, seed, max_segments=limits.max_segments, progress=progress)
    if timing is not None:
        skeleton = timed(skeleton, shown, ages, timing)
    return modules, skeleton


def _environment_light(grammar: Grammar, options: GenerateOptions, leaves: LeafOptions) -> LeafOptions:
    """The leaves turn (``leaf_light``) to the environment's light direction unless ``[leaves]`` names a light."""
    light = EnvironmentOptions.from_grammar(grammar, options.environment).light
    if not any(light) or "light" in grammar.leaves or leaves.light != LeafOptions().light:
        return leaves
    return replace(leaves, light=tuple(float(x) for x in np.asarray(light) / np.linalg.norm(light)))


def _scene(grammar: Grammar, options: GenerateOptions) -> tuple:
    """The meshes of the place the plant grew in (read again: draw keeps nothing), for ``--scene``."""
    environment = load_environment(grammar, options.environment)
    return environment.meshes if environment is not None else ()


def generate(
    grammar: Grammar | str,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    options: GenerateOptions | None = None,
    progress: Callable[[str, str, float], None] | None = None,
    **overrides,
) -> Tree:
    """Grow a plant: derive, interpret, sweep, union, clean up, colour and build the leaves.

    Parameters
    ----------
    grammar : Grammar or str
        A grammar, a grammar file path, or the name of a bundled preset.
    iterations, seed : int, optional
        Override the grammar's own.  A seed other than the grammar's own, for a
        plant that nothing random shapes (:func:`seed_dependence`), warns
        (:class:`~lsys3d.errors.SeedWarning`, :func:`warn_if_identical`): it
        would grow the same plant.
    options : GenerateOptions, optional
        Defaults to ``GenerateOptions()``.
    progress : callable, optional
        Called as ``progress(stage, "start" | "done", seconds)`` for each stage, and as
        ``progress("union", "progress", fraction)`` while the union works (fraction from 0 to 1).
    **overrides
        Single options by their flat names, over ``options``: ``sides=5``,
        ``union=False``, ``max_modules=10**6``... (:meth:`GenerateOptions.from_flat`),
        and the ``[turtle]`` settings by their keys, as ``--turtle KEY=VALUE``
        spells them: ``angle_jitter=8``, ``branch_drop=0.05`` (the same as
        ``turtle={"angle_jitter": 8}``; the turtle's ``step`` only that way, as
        ``step`` is the cleanup's).  A misspelt name is an
        :class:`~lsys3d.errors.OptionsError` that names the closest one.

    Returns
    -------
    Tree

    Examples
    --------
    >>> tree = generate("abop-1.24a", iterations=2, sides=5)
    >>> tree.bark.is_watertight, tree.provenance.iterations, tree.name
    (True, 2, 'abop-1.24a')
    >>> generate("abop-1.24a", iterations=2, angle_jitter=8).provenance.options["turtle"]
    {'angle_jitter': 8.0}
    """
    options = options or GenerateOptions()
    if overrides:
        options = options.with_flat(**overrides)
    if not isinstance(grammar, Grammar):
        grammar = load(grammar)
    if seed is not None and seed != grammar.seed:
        warn_if_identical(grammar, options, 2)
    return grow(grammar, iterations, seed, options, progress)


def grow(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    options: GenerateOptions | None = None,
    progress: Callable[[str, str, float], None] | None = None,
) -> Tree:
    """The stages in order, from a grammar to a :class:`Tree`: :func:`generate` without its conveniences.

    ``generate`` takes a preset's name or a path, single options by name, and
    warns of a seed that changes nothing; it then calls this, the one sequence
    of the stages.  The batch's workers and the CLI (which warns in its own
    words) call it directly.
    """
    options = options or GenerateOptions()
    n = grammar.iterations if iterations is None else iterations
    seed = grammar.seed if seed is None else seed

    def stage(name, fn, *args, **kw):
        return run_stage(name, fn, *args, progress=progress, **kw)

    table = material_table(grammar)  # a bad [materials], [surfaces] or [leaves] table fails before the work
    surfaces = surface_table(grammar)
    table = with_cards(table, surfaces, grammar)
    leaf_options = _environment_light(grammar, options, LeafOptions.from_grammar(grammar, options.leaves))
    grown = options if leaf_options is options.leaves else options.replace(leaves=leaf_options)

    modules, skeleton = draw(grammar, n, seed, options, progress=progress)
    if len(skeleton) == 0 and skeleton.n_leaves == 0:
        raise GeometryError(
            f"{grammar.name or grammar.source}: nothing to mesh: the {len(modules):,} modules after {n} "
            "iterations draw no segment and no leaf (segments are drawn by F, or the [turtle] table's draw symbols)"
        )
    wanted = options.attributes.keys
    rigging = options.rigging
    # the rig and the birth attribute find a vertex's place by branch and t: they need those two
    needs_place = rigging.enabled or options.growth.birth
    keys = tuple(dict.fromkeys(wanted + (VERTEX_KEYS if needs_place else ())))
    branches = hierarchy(skeleton, seed) if keys or table else None
    rig = build_rig(branches, skeleton, rigging) if rigging.enabled else None
    leaf_model = surfaces.leaf.mesh if surfaces.leaf is not None else None
    timing = growth_table(grammar) if options.growth.timed else None
    look = _Look(
        table,
        leaf_model,
        branches,
        keys,
        wanted,
        rig,
        surfaces,
        timing if options.growth.birth else None,
        leaf_joints=(timing, options.rig.max_joints) if options.growth.enabled else None,
    )
    counts = None

    def tubes_made(tubes: Tubes) -> None:
        nonlocal counts
        if len(tubes) == 0 and skeleton.n_leaves == 0:
            raise GeometryError(
                f"{grammar.name or grammar.source}: nothing to mesh: all {len(skeleton):,} segments are shorter "
                f"than min_length ({options.sweep.min_length:g}) and there is no leaf"
            )
        counts = StageCounts(
            modules=len(modules),
            segments=len(skeleton),
            tubes=len(tubes.sides),
            tube_vertices=len(tubes.points),
            tube_faces=len(tubes.faces),
        )

    union_progress = None
    if progress:

        def union_progress(fraction: float) -> None:
            progress("union", "progress", fraction)

    first = _level(skeleton, 0, grown, seed, look, stage, tubes_made, union_progress)
    bark, leaves, organs = first.bark, first.leaves, first.organs
    development = None
    if options.growth.enabled:
        rig, look = first.rig, replace(look, rig=first.rig, joint_map=first.joint_map)
        development = stage(
            "growth", growth_stage.grow, rig, branches, skeleton, options.growth, timing.function, first.windows
        )
    animation = None
    if rig is not None and options.wind.enabled:
        animation = stage("wind", sway, rig, branches, options.wind)
    lods = ()
    if options.lod.levels or options.lod.target_triangles:
        lods = stage("lod", _levels, skeleton, grown, seed, Lod(0, bark, leaves), look)
        if options.lod.target_triangles:  # the tree is the level that fits; it has no others
            bark, leaves, lods = lods[0].bark, lods[0].leaves, ()
    return Tree(
        bark=bark,
        skeleton=skeleton,
        leaves=leaves,
        provenance=Provenance.of(grammar, n, seed, options),
        counts=counts,
        unioned=options.union.enabled,
        modules=modules,
        hierarchy=branches if options.attributes.enabled else None,
        rig=rig,
        organs=organs,
        materials=table,
        animation=animation,
        growth=development,
        lods=lods,
        scene=_scene(grammar, options),
    )


def _bark(
    held: list, options: GenerateOptions, seed: int, stage, base_color, progress: Callable[[float], None] | None = None
) -> Mesh:
    """The union (and its cleanup) or the tube soup, coloured: the bark of one set of tubes.

    ``held`` is a list holding the tubes alone; it is emptied.  Without the
    cleanup the union is given the only reference, so that it frees the soup
    once it is culled (the 262,143-segment plant's soup is over a gigabyte);
    the cleanup needs the tubes after the union (``Mesh.face_source`` names
    their faces), so with it they are kept until the cleanup is done; the
    union then makes no corner normals and uv (the cleanup makes its own), and
    cleans the junctions itself before it copies them onto repeated ones
    (:func:`lsys3d.mesh.union.union.union_cleaning_junctions`): the cleanup stage then
    makes the normals and uv alone.
    """
    if options.union.enabled and not options.cleanup.enabled and len(held[0]):
        bark = stage("union", _union_of_held, held, options.union, progress)
        return stage("color", bark_stage.color, bark, options.color, base_color, seed)
    tubes = held.pop()
    if len(tubes) == 0:  # leaves alone (ABOP's polygon figures): an empty bark
        bark = stage("union", Mesh.empty)
    elif options.union.enabled:
        # the cleanup shares its passes with a second thread unless the union may use one process only (a
        # batch's tree per core) or this process may run on one core; the same bytes either way
        threads = 1 if options.union.workers == 1 or union_jobs.default_workers() < 2 else 2

        clean = functools.partial(clean_junctions, tubes, options=options.cleanup, threads=threads)
        # tubes kept: the cleanup needs them; no corner normals and uv: the cleanup makes its own
        raw, done = stage("union", union_cleaning_junctions, [tubes], options.union, clean, progress)
        del clean
        bark = stage("cleanup", cleanup, raw, tubes, options.cleanup, threads, done)
        if bark is raw:  # the cleanup left the union as it was (not a closed 2-manifold): it needs the corners
            raw = bark = None
            bark = stage("union", _union_of_held, [tubes], options.union, progress)
        del raw
    else:
        bark = stage("union", concatenate, tubes)
    del tubes
    release_memory()  # the soup (kept for the cleanup) and the cleanup's temporaries: before the export's arrays
    return stage("color", bark_stage.color, bark, options.color, base_color, seed)


def _union_of_held(
    held: list, options: UnionOptions, progress: Callable[[float], None] | None, corners: bool = True
) -> Mesh:
    """``union(held.pop(), options)``: the list is emptied, so the union holds the tube soup alone."""
    return union(held.pop(), options, progress=progress, corners=corners)


@dataclass(frozen=True)
class _Look:
    """What every level of detail shares with the tree: materials, leaf model, branches, attributes, rig."""

    table: object
    leaf_model: Mesh | None
    branches: object  # Hierarchy or None
    keys: tuple  # the attributes the stages compute (the user's, and the rig's own)
    wanted: tuple  # the attributes the user asked for
    rig: object  # Rig or None
    surfaces: object  # the grammar's SurfaceTable (organs' models)
    birth: object = None  # the GrowthTable when the vertices carry their birth (lsys3d.look.growth.with_birth)
    joint_map: object = None  # the leaf joints of the growth (lsys3d.look.growth.leaf_joints), or None
    leaf_joints: object = None  # (GrowthTable, joint budget): level 0 makes the leaf joints of the growth


@dataclass(frozen=True)
class _Grown:
    """What :func:`_level` makes of a skeleton: the bark, the leaves and (level 0 only) the organs, bound."""

    bark: Mesh
    leaves: object  # Leaves
    organs: object  # Organs, or None at a level of detail above 0
    rig: object = None  # level 0 with the growth: the rig with the leaves' joints
    joint_map: object = None  # and the leaf joint of each joint (lsys3d.look.growth.leaf_joints)
    windows: object = None  # and the leaf joints' growth windows


def bulge(options: GenerateOptions) -> float:
    """How far the bark may stand out of its tubes, in radii: the bark noise, and the junction collars
    (:meth:`CleanupOptions.bulge` on the thinnest tube); the stages that find a face's branch by its distance
    from the skeleton (materials, attributes) allow it."""
    return options.sweep.bark_displacement + options.cleanup.bulge(options.sweep.fewest_sides)


def _level(
    skeleton: Skeleton,
    level: int,
    options: GenerateOptions,
    seed: int,
    look: _Look,
    stage,
    tubes_made: Callable | None = None,
    progress: Callable[[float], None] | None = None,
) -> _Grown:
    """The one sequence from a skeleton to a plant's surfaces: sweep -> bark (union, cleanup, color) ->
    materials -> attributes -> leaves (-> organs at level 0) -> bind to the rig.

    :func:`generate` runs it for the tree (level 0) and :func:`_levels` for each level of detail, with
    ``options`` the level's (:func:`level_options`); a level above 0 sweeps the pruned skeleton, and its
    faces find their branches among the kept ones.  ``stage`` runs (and times) each step;
    ``tubes_made(tubes)`` is called with the tube soup before the union takes it.
    """
    table, keys, branches = look.table, look.keys, look.branches
    if level == 0:
        drawn, seen = skeleton, branches
    else:
        spec = LEVELS[level]
        drawn = prune(skeleton, spec.prune)
        seen = level_hierarchy(branches, kept_segments(skeleton, spec.prune)) if branches is not None else None
    tubes = stage(
        "sweep",
        sweep,
        drawn,
        options.sweep,
        max_triangles=options.limits.max_triangles,
        seed=seed,
        uv_tiles=table.uv_tiles(options.sweep.uv_tile),
    )
    if tubes_made is not None:
        tubes_made(tubes)
    swept = len(tubes)
    held, tubes = [tubes], None  # _bark holds the tube soup alone (and hands it on to the union when it can)
    bark = _bark(held, options, seed, stage, table.bark.base_color, progress)
    if table and swept:
        bark = stage("materials", with_face_materials, bark, drawn, seen, bulge(options))
    if keys:
        bark = stage("attributes", with_attributes, bark, drawn, seen, keys, bulge(options))
    if level == 0:
        leaves = stage(
            "leaves",
            build_leaves,
            skeleton,
            model=look.leaf_model,
            hierarchy=branches,
            attributes=keys,
            options=options.leaves,
            max_triangles=options.limits.max_triangles,
            seed=seed,
        )
        organs = stage(
            "organs",
            skeleton_organs,
            skeleton,
            surfaces=look.surfaces,
            options=options.organs,
            hierarchy=branches if keys else None,
            attributes=keys,
            max_triangles=options.limits.max_triangles,
        )
    else:
        leaves = stage(
            "leaves",
            lod_leaves,
            skeleton,
            level,
            options.leaves,
            look.leaf_model,
            branches if keys else None,
            keys,
            seed,
        )
        organs = None
    kept = look.wanted
    if look.birth is not None:  # the birth attribute (leaves and organs unfold after their twig)
        delay = look.birth.leaf_delay
        bark = growth_stage.with_birth(bark, skeleton, branches, 0.0)
        leaves = _leaves_birth(leaves, skeleton, branches, delay)
        if organs is not None:
            organs = replace(
                organs, merged=tuple(growth_stage.with_birth(m, skeleton, branches, delay) for m in organs.merged)
            )
        kept = (*kept, growth_stage.BIRTH)
    if look.rig is not None:
        bark, leaves = stage("rig", bind, bark, leaves, look.rig, branches)
        if organs is not None:
            organs = bind_organs(organs, look.rig, branches)
        joint_map = look.joint_map
        if level == 0 and look.leaf_joints is not None:
            timing, budget = look.leaf_joints
            meshes = [leaves.merged, *(organs.merged if organs is not None else ())]
            rig, joint_map, windows = growth_stage.leaf_joints(
                look.rig, branches, skeleton, meshes, timing.leaf_delay, timing.leaf_duration, budget
            )
        if joint_map is not None:
            leaves = replace(leaves, merged=growth_stage.rebind(leaves.merged, joint_map))
            if organs is not None:
                organs = replace(organs, merged=tuple(growth_stage.rebind(m, joint_map) for m in organs.merged))
        kept = (*kept, *SKIN_KEYS)
    if keys != look.wanted:  # the rig's and the birth's own use of them: not the user's attributes
        bark, leaves, organs = _keep(bark, leaves, organs, kept)
    if level == 0 and look.leaf_joints is not None:
        return _Grown(bark, leaves, organs, rig, joint_map, windows)
    return _Grown(bark, leaves, organs)


def _leaves_birth(leaves, skeleton: Skeleton, branches, delay: float):
    """``leaves`` with the birth attribute on their merged meshes and on their instances."""
    merged = growth_stage.with_birth(leaves.merged, skeleton, branches, delay)
    polygons = growth_stage.with_birth(leaves.polygons, skeleton, branches, delay)
    instance = dict(leaves.instance_attributes)
    if (
        "branch_id" in instance
        and skeleton.leaf_birth is not None
        and len(skeleton.leaf_birth) == len(instance["branch_id"])
    ):
        instance[growth_stage.BIRTH] = (skeleton.leaf_birth / growth_stage.plant_span(skeleton)).astype(np.float32)
    return replace(leaves, merged=merged, polygons=polygons, instance_attributes=instance)


def _levels(skeleton: Skeleton, options: GenerateOptions, seed: int, first: Lod, look: _Look) -> tuple[Lod, ...]:
    """The levels of detail asked for (:mod:`lsys3d.look.lod`), from one skeleton; ``first`` is level 0, built already.

    Every level carries what level 0 does: face materials, the hierarchy and
    wind attributes and the rig's skin, all indexing the tree's own branches
    and joints (a pruned level is the tree's skeleton without some chains, not
    a new plant), so one branch table and one rig serve every level.  With a
    triangle budget, the one level that fits: the most detailed one whose bark
    and leaves stay within it (levels are built until one does).  Each level is
    :func:`_level`, the sequence the tree itself was built by.
    """

    def quiet(name, fn, *args, **kw):
        return fn(*args, **kw)

    def build(level: int) -> Lod:
        if level == 0:
            return first
        opts = level_options(options, level)
        grown = _level(skeleton, level, opts, seed, look, quiet)
        sw = opts.sweep
        settings = {
            "sides": sw.sides,
            "sides_step": sw.sides_step,
            "min_sides": sw.min_sides,
            "prune": LEVELS[level].prune,
            "merge_angle": sw.merge_angle,
        }
        return Lod(level, grown.bark, grown.leaves, settings)

    budget = options.lod.target_triangles
    if budget:
        built: dict[int, Lod] = {}

        def counts():
            for level in range(len(LEVELS)):
                built[level] = build(level)
                yield level, built[level].triangles

        return (built[fit_budget(counts(), budget)],)
    rest = [level for level in options.lod.levels if level != 0]
    threads = min(len(rest), os.cpu_count() or 1)
    if threads < 2:
        return tuple(build(level) for level in options.lod.levels)
    # the other levels at once, one per core: each is its own sweep, union and cleanup of its own arrays (the
    # compiled kernels and manifold3d release the GIL); the same levels, whatever the order they finish in
    with ThreadPoolExecutor(threads, thread_name_prefix="lsys3d-lod") as pool:
        others = dict(zip(rest, pool.map(build, rest), strict=True))
    return tuple(first if level == 0 else others[level] for level in options.lod.levels)


def _keep(bark: Mesh, leaves, organs, keys):
    """``bark``, ``leaves`` and ``organs`` (None: none) with only the attributes ``keys``."""
    merged = leaves.merged.keeping(keys) if leaves.merged is not None else None
    polygons = leaves.polygons.keeping(keys) if leaves.polygons is not None else None
    instance = {k: a for k, a in leaves.instance_attributes.items() if k in keys}
    leaves = replace(leaves, merged=merged, polygons=polygons, instance_attributes=instance)
    if organs is not None:
        organs = replace(
            organs,
            merged=tuple(m.keeping(keys) if m is not None else None for m in organs.merged),
            instance_attributes={k: a for k, a in organs.instance_attributes.items() if k in keys},
        )
    return bark.keeping(keys), leaves, organs
