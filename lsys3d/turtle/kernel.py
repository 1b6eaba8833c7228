"""The turtle's numba kernel: one pass over the modules, writing into preallocated arrays.

Arguments travel in named tuples of arrays (numba compiles them as plain
tuples): :class:`Program` (what each symbol id does, from the command table),
:class:`Modules` (the module string), :class:`Config` (the numeric settings),
:class:`Variation` (per-module random numbers) and the outputs
:class:`SegmentArrays`, :class:`PolygonArrays`, :class:`LeafArrays`.  The kernel switches on
:class:`~lsys3d.turtle.commands.Op`; rotations read their axis and sign from
the program, so a new rotation symbol needs no new branch here.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ..compiling import inner, kernel
from .bending import (
    _AXIS_H,
    _AXIS_L,
    _bend,
    _bend_after,
    _cos_sin,
    _orthonormal,
    _pair,
    _rotate,
    carry_up,
    movement_adjust,
    movement_elasticity,
)
from .commands import N_OPS, Op, Organ
from .scene import Scene, _steer  # the scene as the kernel sees it, and the steering of a segment
from .skeleton import MAX_COORDINATE
from .steering import recall, recalled_steering

__all__ = [
    "MAX_POLYGON_DEPTH",
    "MESSAGES",
    "OK",
    "RARE_OPS",
    "Config",
    "LeafArrays",
    "Modules",
    "OrganArrays",
    "PolygonArrays",
    "Program",
    "QueryArrays",
    "SegmentArrays",
    "Variation",
    "dropped_modules",
    "rare_flag",
    "run",
    "survey",
]

Program = namedtuple("Program", ["op", "axis", "sign", "max_args", "scale", "vertex", "factor", "organ", "world"])
Modules = namedtuple("Modules", ["symbols", "arity", "offsets", "params"])
Config = namedtuple(
    "Config",
    [
        "angle",
        "heading",
        "step",
        "width",
        "width_scale",
        "length_scale",
        "elasticity",
        "tx",
        "ty",
        "tz",
        "far",
        "width_unit",
        "width_increment",
        "angle_scale",
        "bend_angle",
        "length_unit",
        "bend_after",
        "elasticity_increment",
        "polygon_edges",
        "movements",
    ],
)
Variation = namedtuple("Variation", ["angle", "length", "width", "roll", "skipped", "turn"])
SegmentArrays = namedtuple(
    "SegmentArrays",
    ["start", "end", "heading", "left", "up", "width_start", "width_end", "parent", "module", "order", "material"],
)
PolygonArrays = namedtuple("PolygonArrays", ["points", "offsets", "material", "segment"])
LeafArrays = namedtuple("LeafArrays", ["position", "heading", "left", "up", "size", "material", "segment"])
OrganArrays = namedtuple(
    "OrganArrays", ["kind", "position", "heading", "left", "up", "size", "material", "segment", "module"]
)
QueryArrays = namedtuple("QueryArrays", ["module", "state", "cut", "count"])
"""Outputs for derivation's questions: each :data:`Op.QUERY` module's index and turtle state (position, H, L,
U: ``(n, 12)``), the drawing modules the environment cut, and ``count = [queries, cuts]``."""

# numba sees the enums as plain integers
_NONE = int(Op.NONE)
_FORWARD = int(Op.FORWARD)
_MOVE = int(Op.MOVE)
_ROTATE = int(Op.ROTATE)
_TURN_AROUND = int(Op.TURN_AROUND)
_ROLL_HORIZONTAL = int(Op.ROLL_HORIZONTAL)
_PUSH = int(Op.PUSH)
_POP = int(Op.POP)
_WIDTH = int(Op.WIDTH)
_MATERIAL = int(Op.MATERIAL)
_LENGTH = int(Op.LENGTH)
_POLYGON_BEGIN = int(Op.POLYGON_BEGIN)
_POLYGON_VERTEX = int(Op.POLYGON_VERTEX)
_POLYGON_END = int(Op.POLYGON_END)
_LEAF = int(Op.LEAF)
_ORGAN = int(Op.ORGAN)
_WIDTH_ADD = int(Op.WIDTH_ADD)
_WIDTH_FACTOR = int(Op.WIDTH_FACTOR)
_ANGLE_FACTOR = int(Op.ANGLE_FACTOR)
_RANDOM_TURN = int(Op.RANDOM_TURN)
_TROPISM = int(Op.TROPISM)
_ELASTICITY = int(Op.ELASTICITY)
_ELASTICITY_ADD = int(Op.ELASTICITY_ADD)
_CYLINDER_START = int(Op.CYLINDER_START)
_CYLINDER_POINT = int(Op.CYLINDER_POINT)
_CYLINDER_TANGENTS = int(Op.CYLINDER_TANGENTS)
_FORWARD_STEPS = int(Op.FORWARD_STEPS)
_TROPISM_VECTOR = int(Op.TROPISM_VECTOR)
_QUERY = int(Op.QUERY)
_SUB_LSYSTEM = int(Op.SUB_LSYSTEM)
_MOVEMENT_ELASTICITY = int(Op.MOVEMENT_ELASTICITY)
_MOVEMENT_FRAME = int(Op.MOVEMENT_FRAME)
_SIDES = int(Op.SIDES)  # read after the kernel's pass (lsys3d.turtle.sides)

RARE_OPS = (
    Op.MOVEMENT_ELASTICITY,
    Op.MOVEMENT_FRAME,
    Op.FORWARD_STEPS,
    Op.SUB_LSYSTEM,
    Op.QUERY,
    Op.RANDOM_TURN,
    Op.CYLINDER_TANGENTS,
    Op.CYLINDER_START,
    Op.CYLINDER_POINT,
    Op.POLYGON_BEGIN,
    Op.POLYGON_VERTEX,
    Op.POLYGON_END,
    Op.ORGAN,
    Op.TROPISM,
    Op.ELASTICITY,
    Op.ELASTICITY_ADD,
    Op.ANGLE_FACTOR,
    Op.LENGTH,
    Op.TROPISM_VECTOR,
)
"""The ops :func:`run` draws only when called with ``rare`` (:func:`rare_flag`); without it numba compiles the
kernel without their code, and without the environment's and cpfg's movements' (less than half of a first run's
compiling of the turtle, for the many strings that need none of them: of the bundled presets all but bush's
polygons and the queries of the three environment scenes).  The others: F, f, the turns, [ and ], the widths,
leaves, materials, | and $."""
_SURFACE = int(Organ.SURFACE)
_INSTANCE = int(Organ.INSTANCE)

STEP_EPSILON = 1e-5
"""A rest of L-Py's ``nF(length, dlength)`` shorter than this draws no last segment (PlantGL's GEOM_EPSILON)."""

MAX_STEPS = 2**53
CYLINDER_RINGS = 4
"""Pieces of a generalized cylinder between two control points without a number (cpfg's DEFAULT_RINGS)."""
MAX_RINGS = 10_000
"""Most pieces between two control points (``@Gc(n)``)."""
CYLINDER_TANGENT = 1.2
"""cpfg's default tangent parameter of a generalized cylinder (interpret.c)."""
"""Most steps one ``nF`` module, or all of them, count (far above any segment limit: keeps the counts exact
integers that cannot wrap around)."""

MAX_POLYGON_DEPTH = 1000
"""Most polygons open at once: ``{`` inside an open polygon starts a polygon of its own (Lparser's
and cpfg's polygon stack; Lparser's own bound is 1000 too)."""

MAX_SUB_LSYSTEMS = 64
"""Most of cpfg's sub-L-system scales stacked at once (``?(n, s)`` not yet closed by ``$``)."""

# status codes; the message says what went wrong at module `bad`
OK = 0
MESSAGES = {
    1: "nothing to pop: more ']' than '[' so far",
    2: f"more than {MAX_POLYGON_DEPTH} polygons open at once (lsys3d.turtle.kernel.MAX_POLYGON_DEPTH)",
    3: "no polygon is open ('}' without '{')",
    4: "polygon never closed (no matching '}')",
    5: f"the turtle's position left the drawable range of +-{MAX_COORDINATE:g} "
    "(lsys3d.turtle.skeleton.MAX_COORDINATE); "
    "check the step length (F's parameter, step, length_scale, length_jitter)",
    6: f"the width must be a number from 0 to {MAX_COORDINATE:g} (lsys3d.turtle.skeleton.MAX_COORDINATE)",
    7: "the step length must be a finite number >= 0",
    8: "the material index must be >= 0",
    9: f"the leaf size must be a number from 0 to {MAX_COORDINATE:g} (lsys3d.turtle.skeleton.MAX_COORDINATE)",
    10: f"the width with width_jitter is more than {MAX_COORDINATE:g} (lsys3d.turtle.skeleton.MAX_COORDINATE)",
    11: "the rotation angle must be a finite number",
    12: f"the organ's size must be a number from 0 to {MAX_COORDINATE:g} (lsys3d.turtle.skeleton.MAX_COORDINATE)",
    13: f"more than {MAX_SUB_LSYSTEMS} sub-L-systems open at once (lsys3d.turtle.kernel.MAX_SUB_LSYSTEMS)",
    14: "a sub-L-system's scale (the s of ?(n, s)) must be a finite number > 0",
}


@inner()
def _put(a, k, x, y, z):
    a[k, 0] = x
    a[k, 1] = y
    a[k, 2] = z


@inner()
def _add_vertex(points, n, first, x, y, z):
    """Append a polygon vertex unless it repeats the previous one; return the new count."""
    if n > first and points[n - 1, 0] == x and points[n - 1, 1] == y and points[n - 1, 2] == z:
        return n
    points[n, 0] = x
    points[n, 1] = y
    points[n, 2] = z
    return n + 1


@inner()
def _rotate_points(points, base, start, stop):
    """Move rows ``start:stop`` to ``base`` and the rows ``base:start`` after them (a nested polygon closing)."""
    k = stop - start
    inner = np.empty((k, 3))
    for r in range(k):  # loops, not slices: numba compiles slice assignment slowly
        inner[r, 0] = points[start + r, 0]
        inner[r, 1] = points[start + r, 1]
        inner[r, 2] = points[start + r, 2]
    for r in range(start - 1, base - 1, -1):
        points[r + k, 0] = points[r, 0]
        points[r + k, 1] = points[r, 1]
        points[r + k, 2] = points[r, 2]
    for r in range(k):
        points[base + r, 0] = inner[r, 0]
        points[base + r, 1] = inner[r, 1]
        points[base + r, 2] = inner[r, 2]


@kernel(nogil=True)  # nogil as its callers: numba compiles int, min and max once per set of its callers' flags
def _steps(length, dlength):
    """L-Py's ``nF(length, dlength)``: (whole steps, rest, segments drawn), as PlantGL's Turtle::nF counts them.

    ``int(length / dlength)`` steps of ``dlength``, then the rest if it is longer than :data:`STEP_EPSILON`.
    The caller has checked ``length >= 0`` and ``dlength > 0``.
    """
    q = length / dlength
    n = int(q) if q < MAX_STEPS else MAX_STEPS
    rest = length - n * dlength
    return n, rest, n + (1 if rest > STEP_EPSILON else 0)


@kernel(nogil=True)  # (as _steps)
def _rings(has_arg, arg):
    """The pieces of a generalized cylinder's connection: ``@Gc(n)``'s n (at least 1), else the default."""
    if not has_arg:
        return CYLINDER_RINGS
    return max(1, min(MAX_RINGS, int(arg)))


@kernel(nogil=True)
def survey(program, modules):
    """One pass before drawing: how many modules of each op, deepest bracket, bad arguments.

    Returns (counts (N_OPS,), max depth, bad module or -1, 1 too many arguments / 2 not finite / 3 too
    few, or out of range, for L-Py's ``nF`` and ``@Tp``).  The FORWARD count includes the segments of
    the ``nF`` modules, so it is the most segments the string draws.
    """
    counts = np.empty(N_OPS, np.int64)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    counts[:] = 0
    depth = 0
    deepest = 0
    symbols, arity, offsets, params = modules
    for i in range(symbols.shape[0]):
        sym = symbols[i]
        code = program.op[sym]
        counts[code] += 1
        if code == _NONE:
            continue
        if arity[i] > program.max_args[sym]:
            return counts, deepest, i, 1
        if arity[i] > 0 and not math.isfinite(params[offsets[i]]):
            return counts, deepest, i, 2
        if code == _FORWARD_STEPS:
            if arity[i] < 2:
                return counts, deepest, i, 3
            length, dlength = params[offsets[i]], params[offsets[i] + 1]
            if not (length >= 0.0 and dlength > 0.0 and math.isfinite(dlength)):
                return counts, deepest, i, 3
            counts[_FORWARD] = min(counts[_FORWARD] + _steps(length, dlength)[2], MAX_STEPS)  # no wrap-around
        elif code == _CYLINDER_POINT:  # a generalized cylinder's pieces up to this control point
            counts[_FORWARD] += _rings(arity[i] > 0, params[offsets[i]] if arity[i] > 0 else 0.0)
        elif code == _TROPISM_VECTOR:
            if arity[i] != 3:
                return counts, deepest, i, 3
            for k in range(1, 3):
                if not math.isfinite(params[offsets[i] + k]):
                    return counts, deepest, i, 2
        elif code == _PUSH:
            depth += 1
            if depth > deepest:
                deepest = depth
        elif code == _POP:
            depth -= 1
    return counts, deepest, -1, 0


@kernel(nogil=True)
def dropped_modules(program, symbols, drop):
    """Modules inside a dropped branch: from a ``[`` whose ``drop`` is set to its matching ``]`` (or the end)."""
    m = symbols.shape[0]
    out = np.empty(m, np.bool_)
    out[:] = False
    depth = 0  # bracket depth inside the branch being dropped; 0: not dropping
    for i in range(m):
        code = program.op[symbols[i]]
        if depth == 0:
            if code == _PUSH and drop[i]:
                depth = 1
                out[i] = True
            continue
        out[i] = True
        if code == _PUSH:
            depth += 1
        elif code == _POP:
            depth -= 1
    return out


def rare_flag(counts: np.ndarray, config: Config, scene: Scene | None) -> bool | None:
    """:func:`run`'s ``rare``: True when the string holds one of :data:`RARE_OPS` (``counts`` per op, from
    :func:`survey`), the turtle has cpfg's movements or there is an environment; else None."""
    rare = scene is not None or config.movements.shape[0] > 0 or any(counts[int(op)] for op in RARE_OPS)
    return True if rare else None


@kernel(nogil=True)
def run(program, modules, config, variation, max_depth, seg, poly, leaf, organ, query, scene, rare):
    """Run the turtle over the modules, writing segments, polygons, leaves and organs into the preallocated outputs.

    ``query`` receives the state at each query module and the segments ``scene`` cut (a cut segment
    takes the rest of its branch with it: the modules up to the ``]`` that closes it are skipped).
    ``rare`` is None for a string with none of :data:`RARE_OPS`, no environment and no movements
    (:func:`rare_flag`): numba then compiles the kernel without their code, which it does not need
    (and ignores those ops), else the steerings already made in this scene, read there only (a
    :data:`lsys3d.turtle.steering.Steered`, one type: empty arrays when there are none, so it compiles once).

    Returns (status, bad module, segments, polygon points, polygons, leaves, organs, dropped polygons).
    """
    symbols, arity, offsets, params = modules
    n_cap = seg.start.shape[0]
    depth_of = np.empty(n_cap, np.int64)
    first_child = np.empty(n_cap, np.int64)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    same_child = np.empty(n_cap, np.int64)  # first child of the same order
    first_child[:] = same_child[:] = -1
    stack_f = np.empty((max_depth, 30))
    stack_i = np.empty((max_depth, 5), np.int64)

    angle = config.angle
    cos_angle, sin_angle = _cos_sin(angle)
    step = config.step
    width = config.width
    width_scale = config.width_scale
    length_scale = config.length_scale
    angle_scale = config.angle_scale
    width_unit = config.width_unit
    length_unit = config.length_unit
    width_increment = config.width_increment
    elasticity = config.elasticity
    far = config.far  # MAX_COORDINATE
    tx, ty, tz = config.tx, config.ty, config.tz
    bend = tx != 0.0 or ty != 0.0 or tz != 0.0
    by_angle = config.bend_angle
    after = config.bend_after  # cpfg's tropism: the frame bends after each move, not before
    edges = config.polygon_edges  # moves inside a polygon draw segments too (L-System Explorer's turtle)
    elasticity_increment = config.elasticity_increment
    # cpfg's movements (bending.py): their elasticities in this branch, and the frame they carry U from
    n_mov = config.movements.shape[0]
    mov_e = config.movements[:, 6].copy()
    stack_m = np.empty((max_depth, n_mov + 6))
    # cpfg's generalized cylinder (@Gs, @Gc, @Ge): on or off, the last control point (position, heading,
    # width, its tangent parameter) and the tangent parameters of the turtle (@Gt)
    cyl_on = 0.0
    cx0 = cy0 = cz0 = 0.0
    chx = chy = chz = 0.0
    cw0 = 0.0
    ct0 = CYLINDER_TANGENT
    tan_in = CYLINDER_TANGENT
    tan_out = CYLINDER_TANGENT
    cyl_last = np.int64(-1)  # the cylinder's last piece (its next piece's parent: the moves between break no chain)
    # one-shot bends (Lparser's t, Houdini's T) pull toward T, or down when T is not set
    gx, gy, gz = (tx, ty, tz) if bend else (0.0, -1.0, 0.0)
    random_turn = variation.turn.shape[0] > 0
    jitter_angle = variation.angle.shape[0] > 0
    jitter_length = variation.length.shape[0] > 0
    jitter_width = variation.width.shape[0] > 0
    roll_branch = variation.roll.shape[0] > 0
    drop_branch = variation.skipped.shape[0] > 0
    in_scene = scene.params.shape[0] > 0
    if rare is not None:  # the steerings made already (steering.Steered), met in the string's order
        memo_at, memo_row, memo_rows = rare
    memo_k = np.int64(0)
    skipping = np.int64(0)  # > 0: inside a branch the scene cut, that many brackets deep
    hanging = np.int64(0)  # 0 free (never on a support), 1 on a support, 2 hanging: left it over an edge
    n_query = np.int64(0)
    n_cut = np.int64(0)

    px = py = pz = 0.0
    hx, hy = _cos_sin(config.heading)
    hz = 0.0
    lx, ly, lz = -hy, hx, 0.0
    ux, uy, uz = 0.0, 0.0, 1.0
    phx, phy, phz, pux, puy, puz = hx, hy, hz, ux, uy, uz
    material = 0
    last = -1  # parent of the next segment
    anchor = -1  # last segment drawn in this state, for branch order
    depth = 0
    n_seg = np.int64(0)
    # counters typed int64 from the start: a literal 0 here makes numba compile _put and _add_vertex a second
    # time for Literal[int](0) while it infers the loop's types
    n_pts = np.int64(0)
    n_poly = 0
    n_leaf = np.int64(0)
    n_organ = np.int64(0)
    dropped = 0
    poly_open = -1  # module that opened the polygon
    poly_start = np.int64(0)
    poly_mat = 0
    poly_seg = -1
    # the polygons open around the current one: (opening module, first point, material, segment);
    # their points lie in order from the first's start up to the current polygon's start
    poly_stack = np.empty((MAX_POLYGON_DEPTH, 4), np.int64)
    poly_depth = 0
    # cpfg's sub-L-systems: ?(n, s) scales lengths and widths by s until its $ (interpret.c's scale_factor)
    sub_scale = 1.0
    sub_stack = np.empty(MAX_SUB_LSYSTEMS, np.float64)
    sub_top = 0

    m = symbols.shape[0]
    for i in range(m):
        sym = symbols[i]
        code = program.op[sym]
        if code == _NONE:
            continue
        if drop_branch and variation.skipped[i]:
            continue
        if rare is not None and skipping > 0:
            if code == _PUSH:
                skipping += 1
            elif code == _POP:
                skipping -= 1
            if skipping > 0 or code != _POP:
                continue
        has_arg = arity[i] > 0
        arg = params[offsets[i]] if has_arg else 0.0
        if code in (_FORWARD, _MOVE):
            if rare is not None and n_mov:
                hx, hy, hz, lx, ly, lz, ux, uy, uz, phx, phy, phz, pux, puy, puz = movement_adjust(
                    config.movements, mov_e, hx, hy, hz, lx, ly, lz, ux, uy, uz, phx, phy, phz, pux, puy, puz
                )
            if elasticity != 0.0 and bend and not after:
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, elasticity, by_angle
                )
            length = (arg * length_unit if has_arg else step * program.scale[sym]) * sub_scale
            if jitter_length:
                length *= variation.length[i]
            if rare is not None and in_scene and code == _FORWARD and poly_open < 0:
                r, memo_k = recall(
                    memo_at, memo_row, memo_rows, memo_k, i, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length,
                    hanging,
                )  # fmt: skip
                if r >= 0:
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, cut, hanging = recalled_steering(memo_rows, r)
                else:
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, cut, hanging = _steer(
                        scene, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length, hanging
                    )
                if cut:
                    query.cut[n_cut] = i
                    n_cut += 1
                    skipping = np.int64(1)
                    continue
            qx = px + hx * length
            qy = py + hy * length
            qz = pz + hz * length
            if not (abs(qx) <= far and abs(qy) <= far and abs(qz) <= far):  # NaN fails too
                return 5, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            if rare is not None and poly_open >= 0 and program.vertex[sym]:
                n_pts = _add_vertex(poly.points, n_pts, poly_start, qx, qy, qz)
            if code == _FORWARD and (poly_open < 0 or edges):
                s_ = n_seg
                _put(seg.start, s_, px, py, pz)
                _put(seg.end, s_, qx, qy, qz)
                _put(seg.heading, s_, hx, hy, hz)
                _put(seg.left, s_, lx, ly, lz)
                _put(seg.up, s_, ux, uy, uz)
                drawn = width * variation.width[i] if jitter_width else width
                if not drawn <= far:
                    return 10, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                seg.width_start[s_] = drawn
                seg.width_end[s_] = drawn
                if anchor >= 0:
                    rise = depth - depth_of[anchor]
                    order = seg.order[anchor] + (rise if rise > 0 else 0)
                else:
                    order = 0
                seg.parent[s_] = last
                seg.module[s_] = i
                seg.order[s_] = order
                seg.material[s_] = material
                depth_of[s_] = depth
                if last >= 0:
                    if first_child[last] < 0:
                        first_child[last] = s_
                    if same_child[last] < 0 and seg.order[last] == order:
                        same_child[last] = s_
                last = s_
                anchor = s_
                n_seg += 1
            else:
                last = -1
            px, py, pz = qx, qy, qz
            if after and elasticity != 0.0 and bend:
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend_after(
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, elasticity
                )
            if rare is not None and code == _FORWARD:  # cpfg's F and G: the frame the movements carry U from
                phx, phy, phz, pux, puy, puz = hx, hy, hz, ux, uy, uz
        elif code == _ROTATE:
            if jitter_angle:
                c, s = _cos_sin((arg if has_arg else angle) + variation.angle[i])
            elif has_arg:
                c, s = _cos_sin(arg)
            else:
                c, s = cos_angle, sin_angle
            s = s * program.sign[sym]
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _rotate(
                hx, hy, hz, lx, ly, lz, ux, uy, uz, np.int64(program.axis[sym]), c, s
            )
        elif code == _PUSH:
            row = stack_f[depth]
            row[0] = px
            row[1] = py
            row[2] = pz
            row[3] = hx
            row[4] = hy
            row[5] = hz
            row[6] = lx
            row[7] = ly
            row[8] = lz
            row[9] = ux
            row[10] = uy
            row[11] = uz
            row[12] = width
            row[13] = step
            row[14] = angle
            row[15] = elasticity
            row[16] = tx
            row[17] = ty
            row[18] = tz
            stack_i[depth, 0] = material
            stack_i[depth, 1] = last
            stack_i[depth, 2] = anchor
            if rare is not None:  # the state only the rare ops change
                row[19] = cyl_on
                row[20] = cx0
                row[21] = cy0
                row[22] = cz0
                row[23] = chx
                row[24] = chy
                row[25] = chz
                row[26] = cw0
                row[27] = ct0
                row[28] = tan_in
                row[29] = tan_out
                stack_i[depth, 3] = hanging
                stack_i[depth, 4] = cyl_last
                row = stack_m[depth]
                for k in range(n_mov):
                    row[k] = mov_e[k]
                row[n_mov], row[n_mov + 1], row[n_mov + 2] = phx, phy, phz
                row[n_mov + 3], row[n_mov + 4], row[n_mov + 5] = pux, puy, puz
            depth += 1
            if roll_branch:  # the branch starts rolled about H; the saved state is not
                c, s = _cos_sin(variation.roll[i])
                lx, ly, lz, ux, uy, uz = _pair(lx, ly, lz, ux, uy, uz, c, s)
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _POP:
            if depth == 0:
                return 1, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            depth -= 1
            row = stack_f[depth]
            px, py, pz = row[0], row[1], row[2]
            hx, hy, hz = row[3], row[4], row[5]
            lx, ly, lz = row[6], row[7], row[8]
            ux, uy, uz = row[9], row[10], row[11]
            width = row[12]
            step = row[13]
            if angle != row[14]:
                angle = row[14]
                cos_angle, sin_angle = _cos_sin(angle)
            elasticity = row[15]
            tx, ty, tz = row[16], row[17], row[18]
            bend = tx != 0.0 or ty != 0.0 or tz != 0.0
            material = stack_i[depth, 0]
            last = stack_i[depth, 1]
            anchor = stack_i[depth, 2]
            if rare is not None:
                cyl_on = row[19]
                cx0, cy0, cz0 = row[20], row[21], row[22]
                chx, chy, chz = row[23], row[24], row[25]
                cw0 = row[26]
                ct0 = row[27]
                tan_in, tan_out = row[28], row[29]
                hanging = stack_i[depth, 3]
                cyl_last = stack_i[depth, 4]
                row = stack_m[depth]
                for k in range(n_mov):
                    mov_e[k] = row[k]
                phx, phy, phz = row[n_mov], row[n_mov + 1], row[n_mov + 2]
                pux, puy, puz = row[n_mov + 3], row[n_mov + 4], row[n_mov + 5]
        elif code in (_WIDTH, _WIDTH_ADD, _WIDTH_FACTOR):
            if code == _WIDTH:
                width = arg * width_unit if has_arg else width * width_scale
            elif code == _WIDTH_ADD:  # L-Py's '_' and '!', cpfg's '#' and '!': a step, or the width given
                step_width = width_increment * width_unit * sub_scale
                width = arg * width_unit * sub_scale if has_arg else max(0.0, width + program.sign[sym] * step_width)
            else:  # Lparser's and Houdini's factors
                f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else width_scale)
                width = width * f ** program.sign[sym]
            if not (0.0 <= width <= far):
                return 6, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            if last >= 0 and depth_of[last] == depth:
                seg.width_end[last] = width
        elif code == _LEAF:
            size = arg if has_arg else step
            if not (0.0 <= size <= far):
                return 9, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            _put(leaf.position, n_leaf, px, py, pz)
            _put(leaf.heading, n_leaf, hx, hy, hz)
            _put(leaf.left, n_leaf, lx, ly, lz)
            _put(leaf.up, n_leaf, ux, uy, uz)
            leaf.size[n_leaf] = size
            leaf.material[n_leaf] = material
            leaf.segment[n_leaf] = last
            n_leaf += 1
        elif code == _TURN_AROUND:  # 180 degrees about the row's axis (U: '|'; H: Lparser's '%', Houdini's '*')
            axis = program.axis[sym]
            if axis == _AXIS_H:
                lx, ly, lz, ux, uy, uz = -lx, -ly, -lz, -ux, -uy, -uz
            elif axis == _AXIS_L:
                hx, hy, hz, ux, uy, uz = -hx, -hy, -hz, -ux, -uy, -uz
            else:
                hx, hy, hz, lx, ly, lz = -hx, -hy, -hz, -lx, -ly, -lz
        elif code == _ROLL_HORIZONTAL:
            # L = V x H with V = (0, 1, 0)
            norm = math.sqrt(hz * hz + hx * hx)
            if norm > 1e-12:
                lx, ly, lz = hz / norm, 0.0, -hx / norm
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _MATERIAL:
            if has_arg:
                if arg < -0.5:
                    return 8, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                material = round(arg)
            else:
                material = max(0, material + int(program.sign[sym]))
        elif rare is not None:  # the rare ops (RARE_OPS): compiled only for strings that hold them
            if code == _MOVEMENT_ELASTICITY:  # cpfg's @Ts(n, e), @Ti(n, d), @Td(n, d)
                if has_arg:
                    more = arity[i] > 1
                    movement_elasticity(
                        config.movements, mov_e, program.sign[sym], arg, more, params[offsets[i] + 1] if more else 0.0
                    )
            elif code == _MOVEMENT_FRAME and program.sign[sym] > 0:  # cpfg's @Tf: the turtle's frame is the one kept
                phx, phy, phz, pux, puy, puz = hx, hy, hz, ux, uy, uz
            elif code == _MOVEMENT_FRAME:  # cpfg's @Tp: U carried from the frame kept (no twist since the last F)
                hx, hy, hz, lx, ly, lz, ux, uy, uz = carry_up(hx, hy, hz, ux, uy, uz, phx, phy, phz, pux, puy, puz)
            elif code == _FORWARD_STEPS:  # L-Py's nF(length, dlength[, radius]): PlantGL's Turtle::nF
                # each step is the FORWARD above, with its length (kept apart: a loop there slows every F)
                dlength = params[offsets[i] + 1]
                whole, rest, n_rep = _steps(arg, dlength)
                taper = arity[i] >= 3  # the width goes from the current one to the radius given, step by step
                w0 = width
                w1 = params[offsets[i] + 2] * width_unit if taper else width
                dw = (w1 - w0) / arg if taper and arg > 0.0 else 0.0
                for k in range(n_rep):
                    if elasticity != 0.0 and bend and not after:
                        hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                            hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, elasticity, by_angle
                        )
                    length = (dlength if k < whole else rest) * length_unit
                    if jitter_length:
                        length *= variation.length[i]
                    qx = px + hx * length
                    qy = py + hy * length
                    qz = pz + hz * length
                    if not (abs(qx) <= far and abs(qy) <= far and abs(qz) <= far):
                        return 5, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                    if poly_open >= 0:
                        if program.vertex[sym]:
                            n_pts = _add_vertex(poly.points, n_pts, poly_start, qx, qy, qz)
                        last = -1
                    else:
                        s_ = n_seg
                        _put(seg.start, s_, px, py, pz)
                        _put(seg.end, s_, qx, qy, qz)
                        _put(seg.heading, s_, hx, hy, hz)
                        _put(seg.left, s_, lx, ly, lz)
                        _put(seg.up, s_, ux, uy, uz)
                        drawn = width * variation.width[i] if jitter_width else width
                        if not drawn <= far:
                            return 10, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                        seg.width_start[s_] = drawn
                        seg.width_end[s_] = drawn
                        if anchor >= 0:
                            rise = depth - depth_of[anchor]
                            order = seg.order[anchor] + (rise if rise > 0 else 0)
                        else:
                            order = 0
                        seg.parent[s_] = last
                        seg.module[s_] = i
                        seg.order[s_] = order
                        seg.material[s_] = material
                        depth_of[s_] = depth
                        if last >= 0:
                            if first_child[last] < 0:
                                first_child[last] = s_
                            if same_child[last] < 0 and seg.order[last] == order:
                                same_child[last] = s_
                        last = s_
                        anchor = s_
                        n_seg += 1
                    px, py, pz = qx, qy, qz
                    if after and elasticity != 0.0 and bend:
                        hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend_after(
                            hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, elasticity
                        )
                    if taper:  # PlantGL's F(dlength, topradius): the next width, the radius itself after the rest
                        width = w0 + dw * dlength * (k + 1) if k < whole else w1
                        if not (0.0 <= width <= far):
                            return 6, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                        if last >= 0 and depth_of[last] == depth:
                            seg.width_end[last] = width
            elif code == _SUB_LSYSTEM:
                before = sub_scale
                if program.sign[sym] > 0:  # ?(n, s): a sub-L-system starts (a '?' without parameters is none)
                    if not has_arg:
                        continue
                    if sub_top == MAX_SUB_LSYSTEMS:
                        return 13, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                    sub_stack[sub_top] = sub_scale
                    sub_top += 1
                    if arity[i] >= 2:
                        sub_scale = sub_scale * params[offsets[i] + 1]
                    if not (sub_scale > 0.0 and sub_scale <= far):
                        return 14, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                elif sub_top > 0:  # $: it ends (an unmatched $ changes nothing: cpfg warns and goes on)
                    sub_top -= 1
                    sub_scale = sub_stack[sub_top]
                width = width * sub_scale / before
                if not (0.0 <= width <= far):
                    return 6, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            elif code == _QUERY:
                if query.state.shape[0] > 0:  # (a turtle that only draws keeps no answers)
                    row = query.state[n_query]
                    row[0], row[1], row[2] = px, py, pz
                    row[3], row[4], row[5] = hx, hy, hz
                    row[6], row[7], row[8] = lx, ly, lz
                    row[9], row[10], row[11] = ux, uy, uz
                    query.module[n_query] = i
                    n_query += 1
            elif code == _RANDOM_TURN:
                if random_turn:
                    most = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else angle)
                    for k in range(3):
                        c, s = _cos_sin(most * variation.turn[i, k])
                        hx, hy, hz, lx, ly, lz, ux, uy, uz = _rotate(hx, hy, hz, lx, ly, lz, ux, uy, uz, k + 1, c, s)
            elif code == _CYLINDER_TANGENTS:  # @Gt(a, b): the tangents' factors into and out of a control point
                if has_arg:
                    tan_in = arg
                    tan_out = params[offsets[i] + 1] if arity[i] > 1 else arg
            elif code == _CYLINDER_START or (code == _CYLINDER_POINT and cyl_on == 0.0):
                cyl_on = 1.0  # the first control point: nothing drawn yet
                cx0, cy0, cz0, chx, chy, chz, cw0, ct0 = px, py, pz, hx, hy, hz, width, tan_out
                cyl_last = last
                if code == _CYLINDER_POINT and program.sign[sym] < 0:
                    cyl_on = 0.0
            elif code == _CYLINDER_POINT:
                # cpfg's general.c interpolate_connection: a Hermite curve from the last control point to here,
                # tangents the headings times the distance and the tangent parameters, the radius linear
                dx, dy, dz = px - cx0, py - cy0, pz - cz0
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                if dist >= 1e-5 and poly_open < 0:
                    rings = _rings(has_arg, arg)
                    a1, a2 = dist * ct0, dist * tan_in
                    t1x, t1y, t1z = chx * a1, chy * a1, chz * a1
                    t2x, t2y, t2z = hx * a2, hy * a2, hz * a2
                    k2x, k2y, k2z = 3 * dx - 2 * t1x - t2x, 3 * dy - 2 * t1y - t2y, 3 * dz - 2 * t1z - t2z
                    k3x, k3y, k3z = -2 * dx + t1x + t2x, -2 * dy + t1y + t2y, -2 * dz + t1z + t2z
                    ax, ay, az = cx0, cy0, cz0
                    for k in range(1, rings + 1):
                        v = k / rings
                        bx = cx0 + v * (t1x + v * (k2x + v * k3x))
                        by = cy0 + v * (t1y + v * (k2y + v * k3y))
                        bz = cz0 + v * (t1z + v * (k2z + v * k3z))
                        if k == rings:  # the curve ends where the turtle is
                            bx, by, bz = px, py, pz
                        if not (abs(bx) <= far and abs(by) <= far and abs(bz) <= far):
                            return 5, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                        sx, sy, sz = bx - ax, by - ay, bz - az
                        piece = math.sqrt(sx * sx + sy * sy + sz * sz)
                        if piece > 0.0:
                            sx, sy, sz = sx / piece, sy / piece, sz / piece
                        else:
                            sx, sy, sz = hx, hy, hz
                        d = lx * sx + ly * sy + lz * sz  # the piece's frame: L made square to it
                        qlx, qly, qlz = lx - d * sx, ly - d * sy, lz - d * sz
                        if qlx * qlx + qly * qly + qlz * qlz < 1e-12:
                            d = ux * sx + uy * sy + uz * sz
                            qlx, qly, qlz = ux - d * sx, uy - d * sy, uz - d * sz
                        sx, sy, sz, qlx, qly, qlz, qux, quy, quz = _orthonormal(sx, sy, sz, qlx, qly, qlz)
                        s_ = n_seg
                        _put(seg.start, s_, ax, ay, az)
                        _put(seg.end, s_, bx, by, bz)
                        _put(seg.heading, s_, sx, sy, sz)
                        _put(seg.left, s_, qlx, qly, qlz)
                        _put(seg.up, s_, qux, quy, quz)
                        seg.width_start[s_] = cw0 + (width - cw0) * (k - 1) / rings
                        seg.width_end[s_] = cw0 + (width - cw0) * v
                        if not (seg.width_start[s_] <= far and seg.width_end[s_] <= far):
                            return 10, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                        if anchor >= 0:
                            rise = depth - depth_of[anchor]
                            order = seg.order[anchor] + (rise if rise > 0 else 0)
                        else:
                            order = 0
                        seg.parent[s_] = cyl_last
                        seg.module[s_] = i
                        seg.order[s_] = order
                        seg.material[s_] = material
                        depth_of[s_] = depth
                        if cyl_last >= 0:
                            if first_child[cyl_last] < 0:
                                first_child[cyl_last] = s_
                            if same_child[cyl_last] < 0 and seg.order[cyl_last] == order:
                                same_child[cyl_last] = s_
                        last = s_
                        cyl_last = s_
                        anchor = s_
                        n_seg += 1
                        ax, ay, az = bx, by, bz
                cx0, cy0, cz0, chx, chy, chz, cw0, ct0 = px, py, pz, hx, hy, hz, width, tan_out
                if program.sign[sym] < 0:  # @Ge: the cylinder ends here
                    cyl_on = 0.0
            elif code == _POLYGON_BEGIN:
                if poly_open >= 0:  # a polygon inside a polygon: the outer one waits on the stack
                    if poly_depth + 1 == MAX_POLYGON_DEPTH:
                        return 2, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                    poly_stack[poly_depth, 0] = poly_open
                    poly_stack[poly_depth, 1] = poly_start
                    poly_stack[poly_depth, 2] = poly_mat
                    poly_stack[poly_depth, 3] = poly_seg
                    poly_depth += 1
                poly_open = i
                poly_start = n_pts
                poly_mat = material
                poly_seg = last
            elif code == _POLYGON_VERTEX:
                if poly_open >= 0:
                    n_pts = _add_vertex(poly.points, n_pts, poly_start, px, py, pz)
            elif code == _POLYGON_END:
                if poly_open < 0:
                    return 3, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                poly_open = -1
                k = n_pts - poly_start
                if k >= 2:
                    # a polygon walked back to its first vertex lists that vertex once
                    f0 = poly.points[poly_start]
                    fl = poly.points[n_pts - 1]
                    gap = abs(f0[0] - fl[0]) + abs(f0[1] - fl[1]) + abs(f0[2] - fl[2])
                    if gap <= 1e-9 * (1.0 + abs(f0[0]) + abs(f0[1]) + abs(f0[2])):
                        n_pts -= 1
                        k -= 1
                if k >= 3:
                    if poly_depth > 0:  # the open polygons' points come first: move this one's before them
                        base = poly_stack[0, 1]
                        # never a literal 0: one signature
                        _rotate_points(poly.points, base, np.int64(poly_start), n_pts)
                        for d in range(poly_depth):
                            poly_stack[d, 1] += k
                    n_poly += 1
                    poly.offsets[n_poly] = poly.offsets[n_poly - 1] + k
                    poly.material[n_poly - 1] = poly_mat
                    poly.segment[n_poly - 1] = poly_seg
                else:
                    n_pts = poly_start
                    dropped += 1
                if poly_depth > 0:  # back to the polygon this one was opened in
                    poly_depth -= 1
                    poly_open = poly_stack[poly_depth, 0]
                    poly_start = poly_stack[poly_depth, 1]
                    poly_mat = poly_stack[poly_depth, 2]
                    poly_seg = poly_stack[poly_depth, 3]
            elif code == _ORGAN:
                kind = program.organ[sym]
                if kind in (_SURFACE, _INSTANCE):  # a scale
                    size = (arg if has_arg else 1.0) * sub_scale
                else:  # a diameter (sphere, disc, circle, box), in width units; the width when not given
                    size = arg * width_unit if has_arg else width
                if not (0.0 <= size <= far):
                    return 12, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                organ.kind[n_organ] = kind
                _put(organ.position, n_organ, px, py, pz)
                _put(organ.heading, n_organ, hx, hy, hz)
                _put(organ.left, n_organ, lx, ly, lz)
                _put(organ.up, n_organ, ux, uy, uz)
                organ.size[n_organ] = size
                organ.material[n_organ] = material
                organ.segment[n_organ] = last
                organ.module[n_organ] = i
                n_organ += 1
            elif code == _TROPISM:
                e = arg if has_arg else program.factor[sym]
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, gx, gy, gz, e, np.bool_(False)
                )
            elif code == _ELASTICITY:
                elasticity = arg if has_arg else 0.0
            elif code == _ELASTICITY_ADD:
                elasticity = arg if has_arg else elasticity + elasticity_increment
            elif code == _ANGLE_FACTOR:
                f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else angle_scale)
                angle = angle * f ** program.sign[sym]
                if not math.isfinite(angle):
                    return 11, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
                cos_angle, sin_angle = _cos_sin(angle)
            elif code == _LENGTH:
                f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else length_scale)
                step = step * f ** program.sign[sym]
                if not (step >= 0.0 and math.isfinite(step)):
                    return 7, i, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
            elif code == _TROPISM_VECTOR:  # L-Py's @Tp(x, y, z), in the tool's world axes
                base = offsets[i]
                tx = params[base + program.world[sym, 0]]
                ty = params[base + program.world[sym, 1]]
                tz = params[base + program.world[sym, 2]]
                bend = tx != 0.0 or ty != 0.0 or tz != 0.0
    query.count[0] = n_query
    query.count[1] = n_cut
    if poly_open >= 0:
        return 4, poly_open, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
    # width_end: where the chain goes on (the rule of Skeleton.chains), the next width; at a tip, the tip's
    for s_ in range(n_seg):
        nxt = same_child[s_] if same_child[s_] >= 0 else first_child[s_]
        if nxt >= 0:
            seg.width_end[s_] = seg.width_start[nxt]
    return OK, -1, n_seg, n_pts, n_poly, n_leaf, n_organ, dropped
