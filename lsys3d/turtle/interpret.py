"""The 3D turtle: ModuleString -> :class:`~lsys3d.turtle.skeleton.Skeleton`.

The turtle reads a module string left to right (ABOP chapter 1.5, Y-up world
as in glTF).  Its state is a position and an orthonormal frame -- heading
``H``, left ``L``, up ``U`` with ``H x L = U`` -- plus the branch width, the
material index and the step length.  ``[`` saves the whole state, ``]``
restores it.  What each symbol does is its row of
:data:`~lsys3d.turtle.commands.COMMANDS`; symbols that are not commands
(``X``, ``A``...) have no geometric effect.

Design choices
--------------
Connection (``parent``)
    A segment's parent is the last segment drawn in the current branch state:
    it starts where its parent ends.  A move that draws nothing (``f``, or any
    move inside a polygon) breaks the connection, so the next segment has
    ``parent == -1``.  ``[`` ... ``]`` restores the parent saved by ``[``.
Branch order (``order``)
    ``order[s] = order[parent] + max(0, depth(s) - depth(parent))`` where depth
    is the bracket depth.  A segment after a gap (``f``) has no parent but
    keeps the order of the branch it is in (measured from the last segment
    drawn in its state); segments with nothing drawn before them in their
    state are roots, order 0.
Width taper (``width_start``, ``width_end``)
    ``width_start`` is the width in force when the segment is drawn.
    ``width_end`` is the ``width_start`` of the segment that continues the
    segment's chain (the rule of :attr:`Skeleton.chains`: first child of the
    same order, else first child), so the width is continuous along every
    chain and a grammar that changes ``!`` between segments gets a smooth
    taper.  At the tip of a chain ``width_end`` is the last width set in the
    segment's own branch state after it (``F!(0.01)]`` tapers to 0.01),
    otherwise its ``width_start``.
Polygons
    ``{`` opens a polygon, ``.`` and every move inside it append the turtle's
    position (a vertex equal to the previous one is skipped, and a last vertex
    equal to the first is dropped), ``}`` closes it.  Polygons with fewer than
    three vertices are dropped with a warning.  Polygons nest, as in Lparser's
    and cpfg's polygon stack: ``{`` inside an open polygon starts a polygon of
    its own, ``}`` closes the innermost and the one around it goes on taking
    vertices (at most ``kernel.MAX_POLYGON_DEPTH`` open at once).
Natural variation
    With ``angle_jitter`` (degrees) each rotation angle gets an offset
    ``u * angle_jitter``; with ``length_jitter`` each move is scaled by
    ``max(0, 1 + u * length_jitter)``, with ``width_jitter`` each segment's
    width by ``max(0, 1 + u * width_jitter)``; with ``branch_roll`` every ``[``
    rolls the new branch about H by ``u * branch_roll`` degrees.  ``u`` lies in
    ``[-1, 1]``: uniform, or (``jitter_distribution = "normal"``) normal with
    sigma 1/2, redrawn while outside.  With ``branch_drop`` each ``[`` is,
    with that probability, skipped together with everything up to its ``]``.
    Each kind has its own stream (:class:`lsys3d.streams.Stream`) and module
    ``i`` takes number ``i`` of it, so the result depends only on the seed
    and the module string, and turning one kind on leaves the numbers of the
    others unchanged.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InterpretError, LimitError
from ..lsystem import dialects
from ..lsystem.grammar import Grammar
from ..lsystem.modules import ModuleString
from ..streams import Stream, generator
from . import kernel
from .commands import COMMANDS, Command, Op, SymbolTable, symbol_table
from .options import TurtleOptions
from .scene import Scene
from .sides import sides_in_force, with_sides
from .skeleton import MAX_COORDINATE, Skeleton
from .steering import SteeringMemo, not_steered

__all__ = [
    "DEFAULT_MAX_SEGMENTS",
    "NO_SCENE",
    "Answers",
    "check_segments",
    "interpret",
    "interpret_answering",
    "kernel_program",
    "module_error",
    "natural_variation",
    "surveyed",
    "turtle_config",
    "unit_jitter",
]

log = logging.getLogger("lsys3d")

DEFAULT_MAX_SEGMENTS = 1_000_000
"""Most segments :func:`interpret` draws (about 200 bytes a segment in the turtle, far more once swept)."""


def module_error(modules: ModuleString, table: SymbolTable, i: int, what: str) -> InterpretError:
    cmd = table.command(int(modules.symbols[i]))
    name = f" ({cmd.name})" if cmd else ""
    return InterpretError(f"module {i} '{modules.module_text(i, short=True)}'{name}: {what}")


def unit_jitter(rng: np.random.Generator, m: int, distribution: str) -> np.ndarray:
    """``m`` numbers in [-1, 1]: uniform, or normal with sigma 1/2 truncated to [-1, 1] (redrawn outside)."""
    if distribution == "uniform":
        return rng.uniform(-1.0, 1.0, m)
    z = rng.normal(0.0, 0.5, m)
    bad = np.flatnonzero(np.abs(z) > 1.0)
    while bad.size:
        z[bad] = rng.normal(0.0, 0.5, bad.size)
        bad = bad[np.abs(z[bad]) > 1.0]
    return z


def natural_variation(
    m: int, options: TurtleOptions, seed: int, table: SymbolTable, symbols, random_turns: int
) -> kernel.Variation:
    """Per-module random arrays of the natural variation; an empty array for each kind that is off."""
    angle = length = width = roll = np.zeros(0)
    turn = np.zeros((0, 3))
    if m and random_turns:  # Lparser's and Houdini's '~': three numbers in [-1, 1] per module
        turn = generator(seed, Stream.RANDOM_TURN).uniform(-1.0, 1.0, (m, 3))
    skipped = np.zeros(0, np.bool_)
    dist = options.jitter_distribution
    if m and options.angle_jitter > 0:
        angle = unit_jitter(generator(seed, Stream.ANGLE_JITTER), m, dist) * options.angle_jitter
    if m and options.length_jitter > 0:
        u = unit_jitter(generator(seed, Stream.LENGTH_JITTER), m, dist)
        length = np.maximum(0.0, 1.0 + options.length_jitter * u)
    if m and options.width_jitter > 0:
        width = np.maximum(0.0, 1.0 + options.width_jitter * unit_jitter(generator(seed, Stream.WIDTH_JITTER), m, dist))
    if m and options.branch_roll > 0:
        roll = unit_jitter(generator(seed, Stream.BRANCH_ROLL), m, dist) * options.branch_roll
    if m and options.branch_drop > 0:
        drop = generator(seed, Stream.BRANCH_DROP).random(m) < options.branch_drop
        skipped = kernel.dropped_modules(kernel_program(table), symbols, drop)
    return kernel.Variation(angle, length, width, roll, skipped, turn)


def kernel_program(table: SymbolTable) -> kernel.Program:
    return kernel.Program(
        table.op,
        table.axis,
        table.sign,
        table.max_args,
        table.scale,
        table.vertex,
        table.factor,
        table.organ,
        table.world,
    )


def surveyed(
    modules: ModuleString, table: SymbolTable, program: kernel.Program, arrays: kernel.Modules, max_segments: int
) -> tuple[np.ndarray, int]:
    """:func:`lsys3d.turtle.kernel.survey`'s counts of each op and deepest bracket, its findings raised.

    Raises
    ------
    InterpretError
        A module with too many arguments, or one that is not a finite number.
    LimitError
        More than ``max_segments`` segments.
    """
    counts, max_depth, bad, why = kernel.survey(program, arrays)
    if why == 1:
        n = int(table.max_args[modules.symbols[bad]])
        raise module_error(modules, table, bad, f"takes {'no argument' if n == 0 else f'at most {n} argument'}")
    if why == 2:
        raise module_error(modules, table, bad, "parameter is not a finite number")
    if why == 3:
        what = {
            Op.FORWARD_STEPS: "takes a length >= 0 and a step > 0: nF(length, dlength[, radius])",
            Op.TROPISM_VECTOR: "takes the tropism vector's three coordinates: @Tp(x, y, z)",
        }[Op(table.op[modules.symbols[bad]])]
        raise module_error(modules, table, bad, what)
    check_segments(int(counts[Op.FORWARD]), max_segments)
    return counts, int(max_depth)


def check_segments(n_seg: int, max_segments: int) -> None:
    """Raise :class:`~lsys3d.errors.LimitError` when a string would draw more than ``max_segments`` segments."""
    if n_seg > max_segments:
        raise LimitError(
            f"interpret: the module string would draw up to {n_seg:,} segments, more than the limit of "
            f"{max_segments:,}; use fewer iterations, or raise the limit (--max-segments, or max_segments=)"
        )


def turtle_config(options: TurtleOptions) -> kernel.Config:
    """The kernel's numeric settings from the turtle's options."""
    tx, ty, tz = options.tropism
    return kernel.Config(
        options.angle,
        options.heading,
        options.step,
        options.width,
        options.width_scale,
        options.length_scale,
        options.elasticity,
        tx,
        ty,
        tz,
        MAX_COORDINATE,
        options.width_unit,
        options.width_increment,
        options.angle_scale,
        options.bend == "angle",
        options.length_unit,
        options.bend == "cpfg",
        options.elasticity_increment,
        options.polygon_edges,
        movement_rows(options.tropisms),
    )


def movement_rows(tropisms) -> np.ndarray:
    """``(m, 8)``: cpfg's movements (``TurtleOptions.tropisms``, 7 numbers each) as the kernel reads them
    (:data:`lsys3d.turtle.bending.MOVEMENT_COLUMNS`: the angle as its cosine and sine)."""
    rows = np.asarray(tropisms, np.float64).reshape(-1, 7)
    gamma = np.radians(rows[:, 4])
    return np.column_stack([rows[:, :4], np.cos(gamma), np.sin(gamma), rows[:, 5:]])


NO_SCENE = Scene(np.zeros(3), np.ones(1), *(np.zeros((0, 0, 0)),) * 3, np.zeros(0))
"""The kernel's scene when there is no environment."""


@dataclass(frozen=True)
class Answers:
    """What one turtle pass tells derivation: the state at each query module and the cut segments.

    Attributes
    ----------
    module : (q,) int64
        The query modules' indices in the string.
    state : (q, 12) float64
        Position, H, L and U at each.
    cut : (c,) int64
        The drawing modules the environment cut (each with the rest of its branch).
    """

    module: np.ndarray
    state: np.ndarray
    cut: np.ndarray


def interpret(
    modules: ModuleString,
    options: TurtleOptions | Grammar,
    seed: int | None = None,
    *,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
    commands: tuple[Command, ...] | None = None,
    scene: Scene | None = None,
    steering: SteeringMemo | None = None,
) -> Skeleton:
    """Draw a module string with the 3D turtle.

    Parameters
    ----------
    modules : ModuleString
        The derived string.
    options : TurtleOptions or Grammar
        How to draw; a grammar stands for ``TurtleOptions.from_grammar(grammar)``.
    seed : int, optional
        Seed of the natural variation (the ``*_jitter`` and ``branch_*``
        options); the options' (grammar's) seed if None.
    max_segments : int
        Refuse (before drawing) a string with more drawing modules than this.
    commands : tuple of Command, optional
        The vocabulary: by default the grammar's dialect's when ``options`` is a
        grammar, else :data:`~lsys3d.turtle.commands.COMMANDS`.

    Returns
    -------
    Skeleton
        Segments, leaf polygons and leaf instances (see the module docstring
        for ``parent``, ``order`` and the width taper).

    Raises
    ------
    InterpretError
        ``]`` with nothing saved, a polygon left open or closed twice, a
        parameter or turtle state that is not finite; the message names the
        module's index and text.
    GrammarError
        Bad ``[turtle]`` settings in the grammar.
    LimitError
        More than ``max_segments`` segments (the message gives the count).

    ``scene`` (:func:`lsys3d.turtle.environment.Environment.scene`) lets an environment steer and cut
    the segments (``docs/environment.md``); ``steering``, the memo the derivation that answered in the same
    scene filled (:func:`lsys3d.turtle.query.derive_answering`), saves steering each segment again
    (:mod:`lsys3d.turtle.steering`: the skeleton is the same).

    Examples
    --------
    >>> from lsys3d import Grammar, derive
    >>> g = Grammar(axiom="F[+F]F", angle=90)
    >>> sk = interpret(derive(g, 0), g)
    >>> len(sk), sk.parent.tolist(), sk.order.tolist()
    (3, [-1, 0, 0], [0, 1, 0])
    >>> sk.end[1].round(6).tolist()
    [-1.0, 1.0, 0.0]
    """
    return interpret_answering(
        modules, options, seed, max_segments=max_segments, commands=commands, scene=scene, steering=steering,
        answers=False,
    )[0]  # fmt: skip


def interpret_answering(
    modules: ModuleString,
    options: TurtleOptions | Grammar,
    seed: int | None = None,
    *,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
    commands: tuple[Command, ...] | None = None,
    scene: Scene | None = None,
    steering: SteeringMemo | None = None,
    answers: bool = True,
) -> tuple[Skeleton, Answers]:
    """:func:`interpret`, and what the pass tells derivation: query states and cut segments (:class:`Answers`).
    Without ``answers`` the query states are not kept (:func:`interpret`: the answers go unread)."""
    if isinstance(options, Grammar):
        if commands is None:
            commands = dialects.get(options.dialect).commands
        options = TurtleOptions.from_grammar(options)
    elif not isinstance(options, TurtleOptions):
        raise TypeError(f"interpret: options must be TurtleOptions or Grammar, not {type(options).__name__}")
    if seed is None:
        seed = options.seed
    if commands is None:
        commands = COMMANDS
    t0 = time.perf_counter()
    m = len(modules)
    table = symbol_table(modules.alphabet, options.draw, options.move, options.leaf, commands)
    program = kernel_program(table)
    arrays = kernel.Modules(modules.symbols, modules.arity, modules.offsets, modules.params)
    counts, max_depth = surveyed(modules, table, program, arrays, max_segments)
    n_seg = int(counts[Op.FORWARD])
    n_poly = int(counts[Op.POLYGON_BEGIN])
    n_pts = int(counts[Op.FORWARD] + counts[Op.MOVE] + counts[Op.POLYGON_VERTEX]) if n_poly else 0
    n_leaf = int(counts[Op.LEAF])
    n_organ = int(counts[Op.ORGAN])
    config = turtle_config(options)
    variation = natural_variation(m, options, seed, table, modules.symbols, int(counts[Op.RANDOM_TURN]))

    def frames(k: int, count: int):
        return tuple(np.empty((k, 3)) for _ in range(count))

    seg = kernel.SegmentArrays(
        *frames(n_seg, 5),
        np.empty(n_seg),
        np.empty(n_seg),
        np.empty(n_seg, np.int64),
        np.empty(n_seg, np.int64),
        np.empty(n_seg, np.int32),
        np.empty(n_seg, np.int32),
    )
    poly = kernel.PolygonArrays(
        np.empty((n_pts, 3)), np.zeros(n_poly + 1, np.int64), np.empty(n_poly, np.int32), np.empty(n_poly, np.int64)
    )
    leaf = kernel.LeafArrays(
        *frames(n_leaf, 4), np.empty(n_leaf), np.empty(n_leaf, np.int32), np.empty(n_leaf, np.int64)
    )
    organ = kernel.OrganArrays(
        np.empty(n_organ, np.int8),
        *frames(n_organ, 4),
        np.empty(n_organ),
        np.empty(n_organ, np.int32),
        np.empty(n_organ, np.int64),
        np.empty(n_organ, np.int64),
    )
    n_query = int(counts[Op.QUERY]) if answers else 0
    query = kernel.QueryArrays(
        np.empty(n_query, np.int64),
        np.empty((n_query, 12)),
        np.empty(int(counts[Op.FORWARD]) if scene is not None else 0, np.int64),
        np.zeros(2, np.int64),
    )
    rare = None  # numba compiles (and runs) the kernel without the rare ops: one type when it has them
    if kernel.rare_flag(counts, config, scene):
        rare = steering.recalled(scene) if steering is not None and scene is not None else not_steered()
    status, bad, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped = kernel.run(
        program, arrays, config, variation, max_depth, seg, poly, leaf, organ, query, scene or NO_SCENE, rare
    )
    if status != kernel.OK:
        raise module_error(modules, table, int(bad), kernel.MESSAGES[status])
    if dropped:
        log.warning("turtle: dropped %d leaf polygon(s) with fewer than 3 distinct vertices", dropped)

    width_start, width_end = seg.width_start[:n_seg], seg.width_end[:n_seg]
    if options.min_width > 0:  # Lparser's min_thickness: no segment thinner than this
        width_start, width_end = np.maximum(width_start, options.min_width), np.maximum(width_end, options.min_width)
    # capacities are exact unless drawing symbols stood inside polygons or polygons were dropped
    skeleton = Skeleton(
        start=seg.start[:n_seg],
        end=seg.end[:n_seg],
        width_start=width_start,
        width_end=width_end,
        heading=seg.heading[:n_seg],
        left=seg.left[:n_seg],
        up=seg.up[:n_seg],
        parent=seg.parent[:n_seg],
        order=seg.order[:n_seg],
        material=seg.material[:n_seg],
        module=seg.module[:n_seg],
        polygon_points=poly.points[:n_pts],
        polygon_offsets=poly.offsets[: n_poly + 1],
        polygon_material=poly.material[:n_poly],
        polygon_segment=poly.segment[:n_poly],
        leaf_position=leaf.position[:n_leaf],
        leaf_heading=leaf.heading[:n_leaf],
        leaf_left=leaf.left[:n_leaf],
        leaf_up=leaf.up[:n_leaf],
        leaf_size=leaf.size[:n_leaf],
        leaf_material=leaf.material[:n_leaf],
        leaf_segment=leaf.segment[:n_leaf],
        organ_kind=organ.kind[:n_organ],
        organ_position=organ.position[:n_organ],
        organ_heading=organ.heading[:n_organ],
        organ_left=organ.left[:n_organ],
        organ_up=organ.up[:n_organ],
        organ_size=organ.size[:n_organ],
        organ_material=organ.material[:n_organ],
        organ_segment=organ.segment[:n_organ],
        organ_module=organ.module[:n_organ],
        organ_name=np.array([modules.symbol(i) for i in organ.module[:n_organ]], dtype=str).reshape(n_organ),
    )
    if counts[Op.SIDES] or options.cylinder_sides:  # cpfg's @! and view file: the tessellation, not the path
        in_force = sides_in_force(
            program.op,
            modules.symbols,
            modules.arity,
            modules.offsets,
            modules.params,
            max_depth,
            options.cylinder_sides,
        )
        skeleton = with_sides(skeleton, in_force)
    log.debug(
        "interpret: %d modules -> %d segments, %d polygons, %d leaves, %d organs in %.3f s",
        m,
        n_seg,
        n_poly,
        n_leaf,
        n_organ,
        time.perf_counter() - t0,
    )
    n_query, n_cut = (int(c) for c in query.count)
    return skeleton, Answers(query.module[:n_query], query.state[:n_query], query.cut[:n_cut])
