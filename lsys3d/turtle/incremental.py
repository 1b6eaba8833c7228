"""The turtle between derivation steps: state only, and only where the string changed.

Query modules and an environment make derivation ask the turtle before every step
(:mod:`lsys3d.turtle.query`).  Drawing the whole string each time (:func:`lsys3d.turtle.kernel.run`) would
cost a skeleton per step; :func:`answer_pass` instead propagates the turtle's state (position, frame,
width, step, angle, tropism, the stack) and writes only what derivation reads: the state at each query
module and the segments the scene cuts.  No segment, polygon, leaf or organ array is built.

It is incremental.  Derivation tells the answerer where every module of the new string came from
(:data:`lsys3d.lsystem.derive.Trace`): ``origin[i]`` is the index, in the string of the last pass, of
the module ``i`` copies, or -1 for a module a rule produced.  A copy whose path from the root (the modules
before it outside closed branches) holds only copies has the state it had in the last pass, so its query
already holds the right answer and its segment was already steered and kept.  The pass therefore walks
the copies without a turtle and starts one only at a change: from the state recorded, in the last pass,
before the module that was rewritten (every module a rule can rewrite, and every segment the scene cut,
has its state recorded).  That turtle runs to the end of the branch holding the change, or stops
earlier where the string is a copy again and its state equals the recorded one (a rewritten ``A``
whose successor is a closed branch ``[...]``: the state after it is the state before it).

Everything is bit for bit what a pass over the whole string gives (the same helpers, on the same
numbers, in the same order).  A pass goes over the whole string (``origin`` empty) for the first step,
with the natural variation (its numbers follow the module's index), and when a change cannot be
followed (:data:`FOLLOW_LOST`): the grammar's :func:`follows` check refuses rules that rewrite
brackets or polygons or produce unbalanced ones.
"""

from __future__ import annotations

import math

import numpy as np

from ..arrays import search_left
from ..compiling import inner, kernel
from ..lsystem.grammar import Grammar
from .bending import _AXIS_H, _AXIS_L
from .commands import Op
from .kernel import (  # numba sees the ops as these plain integers, declared once in kernel.py
    _ANGLE_FACTOR,
    _ELASTICITY,
    _FORWARD,
    _FORWARD_STEPS,
    _INSTANCE,
    _LEAF,
    _LENGTH,
    _MATERIAL,
    _MOVE,
    _NONE,
    _ORGAN,
    _POLYGON_BEGIN,
    _POLYGON_END,
    _POLYGON_VERTEX,
    _POP,
    _PUSH,
    _QUERY,
    _RANDOM_TURN,
    _ROLL_HORIZONTAL,
    _ROTATE,
    _SURFACE,
    _TROPISM,
    _TROPISM_VECTOR,
    _TURN_AROUND,
    _WIDTH,
    _WIDTH_ADD,
    _WIDTH_FACTOR,
    MAX_POLYGON_DEPTH,
    _bend,
    _cos_sin,
    _orthonormal,
    _pair,
    _rotate,
    _steps,
)
from .scene import _steer
from .steering import write_steering

__all__ = [
    "FOLLOW_LOST",
    "STATE",
    "answer_pass",
    "carries_out",
    "follow_cut",
    "follow_production",
    "follows",
    "neutral_ops",
    "write_answers",
]

STATE = 22
"""Numbers in a recorded state: position, H, L, U (12), width, step, angle, elasticity, tropism vector (3),
whether the branch hangs from a support, bracket depth, open polygons."""
FOLLOW_LOST = -1
""":func:`answer_pass`'s status when a change cannot be followed from the last pass: run it over the whole string."""


_NEUTRAL = (Op.NONE, Op.QUERY, Op.LEAF, Op.ORGAN)
"""Ops that leave the turtle's state as it was (a module of these rewritten away changes nothing after it)."""
_STRUCTURAL = (Op.PUSH, Op.POP, Op.POLYGON_BEGIN, Op.POLYGON_END)


# the ops answer_pass steps through: NONE .. QUERY (the ops after it came later; a new Op is drawn until it does)
_FIRST_NOT_CARRIED_OUT = int(Op.QUERY) + 1


def carries_out(counts: np.ndarray, turtle) -> bool:
    """Whether :func:`answer_pass` carries out a string of these op ``counts`` (``kernel.survey``'s) as the turtle
    that draws would: no op it does not step through (cpfg's sub-L-system scales, ``_``, generalized cylinders,
    or any op added to :class:`Op` after ``QUERY``), and not cpfg's bend after each move nor its newer tropisms
    (``tropisms``: they bend before each move whether or not the string switches them)."""
    return not counts[_FIRST_NOT_CARRIED_OUT:].any() and turtle.bend != "cpfg" and not turtle.tropisms


def neutral_ops() -> np.ndarray:
    """``(N_OPS,) bool``: the ops after which the state is the state before."""
    out = np.zeros(len(Op), np.bool_)
    out[[int(o) for o in _NEUTRAL]] = True
    return out


def follows(grammar: Grammar, op_of) -> bool:
    """Whether derivation's changes of this grammar's strings can be followed (see the module docstring).

    ``op_of(symbol)`` is the turtle's :class:`Op` of a symbol.  No rule may rewrite a bracket or a polygon's
    start or end, and every successor keeps its brackets and polygons balanced.
    """
    for prod in (*grammar.productions, *grammar.decomposition_productions):
        consumed = (prod.predecessor, *getattr(prod, "following", ()))  # cpfg: predecessors of several modules
        if any(op_of(module.symbol) in _STRUCTURAL for module in consumed):
            return False
        depth = poly = 0
        for module in prod.successor:
            op = op_of(module.symbol)
            depth += (op == Op.PUSH) - (op == Op.POP)
            poly += (op == Op.POLYGON_BEGIN) - (op == Op.POLYGON_END)
            if depth < 0 or poly < 0:
                return False
        if depth or poly:
            return False
    return True


@kernel(nogil=True)
def follow_production(origin, rewritten, lengths, op, symbols, new_symbols, counts, changes):
    """The new string's origins after a production step (``origin`` empty: the old string was the last pass's).

    ``rewritten`` and ``lengths`` as :data:`lsys3d.lsystem.derive.Trace` gives them: a copied module keeps
    its origin, a produced one gets -1.  ``counts`` (when not empty: the old string's modules of each op, by
    ``op[symbol]``) becomes the new string's: a rewritten module's op counted out, its successor's in.
    ``changes`` (when not empty: one more than the modules rewritten) receives where each rewritten module's
    successor starts in the new string, in order, then the new string's length (:func:`answer_pass`'s ``changes``).
    """
    m = rewritten.shape[0]
    total = 0
    for i in range(m):
        total += lengths[i]
    out = np.empty(total, np.int64)
    identity = origin.shape[0] == 0
    counting = counts.shape[0] > 0
    listing = changes.shape[0] > 0
    n_changes = 0
    k = 0
    for i in range(m):
        if rewritten[i]:
            if listing:
                changes[n_changes] = k
                n_changes += 1
            if counting:
                counts[op[symbols[i]]] -= 1
            for _ in range(lengths[i]):
                if counting:
                    counts[op[new_symbols[k]]] += 1
                out[k] = -1
                k += 1
        else:
            out[k] = i if identity else origin[i]
            k += 1
    if listing:
        changes[n_changes] = total
    return out


def follow_cut(origin: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The origins after a cut that kept the modules ``keep`` (a mask of the old string)."""
    return np.flatnonzero(keep) if not len(origin) else origin[keep]


@inner()
def _neutral_range(op, neutral, old_symbols, a, b):
    """Whether the old modules ``a:b`` leave the state as it was: neutral ops (``op`` by symbol), and closed
    branches."""
    depth = 0
    for j in range(a, b):
        code = op[old_symbols[j]]
        if code == _PUSH:
            depth += 1
        elif code == _POP:
            depth -= 1
            if depth < 0:
                return False
        elif code in (_POLYGON_BEGIN, _POLYGON_END, _POLYGON_VERTEX) or (depth == 0 and not neutral[code]):
            return False
    return depth == 0


@inner()
def _carry(old_at, old_rows, k, count, lo, hi, shift, at, rows, n):
    """The last pass's entries at old modules ``lo:hi`` (``old_at[:count]``, sorted, from ``k`` on) carried into
    ``at`` and ``rows`` from ``n`` on, their modules moved by ``shift``: where the copies' records and steerings
    are in the new string.  Returns where the next search starts and the new ``n``."""
    while k < count and old_at[k] < lo:
        k += 1
    while k < count and old_at[k] < hi:
        at[n] = old_at[k] + shift
        rows[n] = old_rows[k]
        n += 1
        k += 1
    return k, n


@inner()
def _find(positions, count, j):
    """The row of ``positions[:count]`` (sorted) that holds ``j``, or -1."""
    k = search_left(positions[:count], j)
    if k < count and positions[k] == j:
        return k
    return -1


@inner(inline="always")
def _deposit(deposits, n, px, py, pz, qx, qy, qz, area):
    """Record an area the plant casts shade with, at the middle of P and Q."""
    row = deposits[n]
    row[0], row[1], row[2], row[3] = 0.5 * (px + qx), 0.5 * (py + qy), 0.5 * (pz + qz), area
    return n + 1


@inner(inline="always")
def _same(a, b):
    """Equal, and the same zero (a -0.0 and a 0.0 can part ways later: atan2, copysign)."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


@inner(inline="always")
def _write_state(
    row,
    px,
    py,
    pz,
    hx,
    hy,
    hz,
    lx,
    ly,
    lz,
    ux,
    uy,
    uz,
    width,
    step,
    angle,
    elasticity,
    tx,
    ty,
    tz,
    hanging,
    depth,
    n_poly,
):
    """Write the turtle's state into ``row`` (:data:`STATE` numbers, in the order ``states`` records them)."""
    row[0], row[1], row[2] = px, py, pz
    row[3], row[4], row[5] = hx, hy, hz
    row[6], row[7], row[8] = lx, ly, lz
    row[9], row[10], row[11] = ux, uy, uz
    row[12], row[13], row[14], row[15] = width, step, angle, elasticity
    row[16], row[17], row[18] = tx, ty, tz
    row[19], row[20], row[21] = hanging, depth, n_poly


@inner(inline="always")
def _is_state(
    row, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, width, step, angle, elasticity, tx, ty, tz, hanging, depth,
    n_poly,
):  # fmt: skip
    """Whether ``row`` holds this state (:func:`_write_state`'s numbers), bit for bit (:func:`_same`)."""
    return (
        _same(row[0], px) and _same(row[1], py) and _same(row[2], pz)
        and _same(row[3], hx) and _same(row[4], hy) and _same(row[5], hz)
        and _same(row[6], lx) and _same(row[7], ly) and _same(row[8], lz)
        and _same(row[9], ux) and _same(row[10], uy) and _same(row[11], uz)
        and _same(row[12], width) and _same(row[13], step) and _same(row[14], angle) and _same(row[15], elasticity)
        and _same(row[16], tx) and _same(row[17], ty) and _same(row[18], tz)
        and _same(row[19], float(hanging)) and _same(row[20], float(depth)) and _same(row[21], float(n_poly))
    )  # fmt: skip


@kernel(nogil=True)
def answer_pass(
    program,
    modules,
    config,
    variation,
    max_depth,
    scene,
    recorded,
    neutral,
    origin,
    changes,
    old_symbols,
    old_positions,
    old_states,
    old_count,
    query_module,
    query_state,
    cuts,
    positions,
    states,
    counts,
    deposits,
    answer_first,
    answer_sign,
    answer_slots,
    answered,
    steerings,
    first_row,
    old_steered_at,
    old_steered_row,
    steered_at,
    steered_row,
):
    """One pass of the turtle's state over the string: the state at each query module that may have changed,
    the segments the scene cuts, and the state before every module ``recorded`` marks (and every cut).

    ``origin`` (empty: the whole string) and the last pass's records (``old_positions[:old_count]``,
    ``old_states``, over ``old_symbols``) say what is known (module docstring).  Outputs: ``query_module``,
    ``query_state`` (position, H, L, U), ``cuts``, ``positions`` and ``states`` (:data:`STATE` numbers),
    ``deposits`` (when not empty: each segment's middle and its length x width, each leaf's place and its
    size squared, the plant's shade of :mod:`lsys3d.turtle.shadow`).  With ``answered`` (not empty: a copy of the
    parameters), the query modules that ``answer_first``, ``answer_sign`` and ``answer_slots`` answer from the
    turtle's state (:func:`write_answers`' tables) are answered in it here, and only the others (``?E``)
    listed in ``query_module``.  ``steerings`` (when not empty): each steering by the scene it makes, a row of
    :func:`lsys3d.turtle.steering.write_steering` from row ``first_row`` on; and for every segment steered now or
    in the last pass, in order, its module (``steered_at``) and its row (``steered_row``; the last pass's:
    ``old_steered_at``, ``old_steered_row``).
    ``counts`` = [queries, cuts, records, deposits, steerings, steered segments].  Returns (status, bad
    module): :data:`lsys3d.turtle.kernel.MESSAGES`' codes, or :data:`FOLLOW_LOST`.
    """
    symbols, arity, offsets, params = modules
    m = symbols.shape[0]
    stack = np.empty((max(max_depth, 1), 20))
    poly_open = np.empty(MAX_POLYGON_DEPTH, np.int64)  # the module that opened each polygon (-1: before the run)

    width_scale = config.width_scale
    length_scale = config.length_scale
    angle_scale = config.angle_scale
    width_unit = config.width_unit
    length_unit = config.length_unit
    width_increment = config.width_increment
    far = config.far
    by_angle = config.bend_angle
    bend0 = config.tx != 0.0 or config.ty != 0.0 or config.tz != 0.0
    gx, gy, gz = (config.tx, config.ty, config.tz) if bend0 else (0.0, -1.0, 0.0)
    random_turn = variation.turn.shape[0] > 0
    jitter_angle = variation.angle.shape[0] > 0
    jitter_length = variation.length.shape[0] > 0
    jitter_width = variation.width.shape[0] > 0
    roll_branch = variation.roll.shape[0] > 0
    in_scene = scene.params.shape[0] > 0
    shading = deposits.shape[0] > 0  # the plant's own shade (lsys3d.turtle.shadow): where its area is
    n_dep = np.int64(0)
    answering = answered.shape[0] > 0
    remembering = steered_at.shape[0] > 0
    n_steer = n_at = old_steer = np.int64(0)
    following = origin.shape[0] > 0
    # where the changes start (the last entry: m), when derivation listed them: the copies between are jumped
    jumping = following and changes.shape[0] > 0
    next_change = np.int64(0)

    initial = np.empty(STATE)
    hx0, hy0 = _cos_sin(config.heading)
    initial[0:3] = 0.0
    initial[3], initial[4], initial[5] = hx0, hy0, 0.0
    initial[6], initial[7], initial[8] = -hy0, hx0, 0.0
    initial[9], initial[10], initial[11] = 0.0, 0.0, 1.0
    initial[12], initial[13], initial[14], initial[15] = config.width, config.step, config.angle, config.elasticity
    initial[16], initial[17], initial[18] = config.tx, config.ty, config.tz
    initial[19] = initial[20] = initial[21] = 0.0

    n_query = n_cut = n_rec = np.int64(0)
    old_row = np.int64(0)  # the last pass's records are met in order along the copies
    running = not following  # a turtle runs (else: copies, known from the last pass)
    resynced = -1  # the copy a turtle stopped at: not a change
    last_copy = np.int64(-1)  # the origin of the last copy the turtle passed
    rel = 0  # the turtle's bracket depth since it started
    entry_poly = 0
    skipping = np.int64(0)
    # the turtle's state, loaded from `initial` or a record when it starts
    px = py = pz = hx = hy = hz = lx = ly = lz = ux = uy = uz = 0.0
    width = step = angle = elasticity = tx = ty = tz = 0.0
    cos_angle = sin_angle = 0.0
    cos_of = math.nan  # the angle cos_angle and sin_angle are of (a turtle that starts with it needs no cosine)
    bend = False
    hanging = np.int64(0)
    depth = 0
    n_poly = 0
    start = -2  # the record a turtle starts from: -1 the initial state, >= 0 a row of old_states
    start_at = start_row = np.int64(-1)  # the old module the last turtle started before, and its record's row
    seek = np.int64(0)  # where the search for the next start's record begins
    if running:
        start = -1
    i = 0
    while i < m:
        sym = symbols[i]
        code = program.op[sym]
        if not running:
            o = origin[i]
            change = o < 0 or (o != 0 if i == 0 else o != origin[i - 1] + 1)
            if not change or i == resynced:
                first = i
                if recorded[sym]:
                    old_row, n_rec = _carry(
                        old_positions, old_states, old_row, old_count, o, o + 1, first - o, positions, states, n_rec
                    )
                i += 1
                if jumping:  # the copies up to the next change (changes): their records are the last pass's
                    while next_change < changes.shape[0] - 1 and changes[next_change] <= first:
                        next_change += 1
                    end = changes[next_change]
                    old_row, n_rec = _carry(
                        old_positions, old_states, old_row, old_count, o + 1, o + (end - first), first - o, positions,
                        states, n_rec,
                    )  # fmt: skip
                    i = end
                # the copies after it that keep their order and have no record: nothing to do (most of the string)
                while i < m and origin[i] == origin[i - 1] + 1 and not recorded[symbols[i]]:
                    i += 1
                if remembering:  # the steerings of the copies' segments: where the last pass found them
                    old_steer, n_at = _carry(
                        old_steered_at, old_steered_row, old_steer, old_steered_at.shape[0], o, o + (i - first),
                        first - o, steered_at, steered_row, n_at,
                    )  # fmt: skip
                continue
            if i == 0:
                start = -1
            else:
                # the changes come in the string's order, so do their records: sought on from the last one found
                target = origin[i - 1] + 1
                while seek < old_count and old_positions[seek] < target:
                    seek += 1
                start = (
                    seek
                    if seek < old_count and old_positions[seek] == target
                    else _find(old_positions, old_count, target)
                )
                if start < 0:
                    return FOLLOW_LOST, i
                start_at, start_row = target, start  # (where the change ends, it is often sought again)
            last_copy = origin[i - 1] if i > 0 else np.int64(-1)
        if start >= -1:  # a turtle starts here
            loaded = initial if start == -1 else old_states[start]
            px, py, pz = loaded[0], loaded[1], loaded[2]
            hx, hy, hz = loaded[3], loaded[4], loaded[5]
            lx, ly, lz = loaded[6], loaded[7], loaded[8]
            ux, uy, uz = loaded[9], loaded[10], loaded[11]
            width, step, angle, elasticity = loaded[12], loaded[13], loaded[14], loaded[15]
            tx, ty, tz = loaded[16], loaded[17], loaded[18]
            hanging = np.int64(loaded[19])
            depth = int(loaded[20])
            n_poly = int(loaded[21])
            for k in range(min(n_poly, MAX_POLYGON_DEPTH)):
                poly_open[k] = -1
            if angle != cos_of:  # (equal angles, even 0.0 and -0.0, have the same cosine and sine)
                cos_angle, sin_angle = _cos_sin(angle)
                cos_of = angle
            bend = tx != 0.0 or ty != 0.0 or tz != 0.0
            rel = 0
            entry_poly = n_poly
            skipping = np.int64(0)
            running = True
            start = -2
        if following:
            o = origin[i]
            if o >= 0:
                if rel == 0 and skipping == 0 and o != last_copy + 1:
                    # a change ends here: where the state is what it was, the copies from here on are known
                    a = last_copy + 1
                    row = -1 if a == 0 else start_row if a == start_at else _find(old_positions, old_count, a)
                    # (the state compared first: it seldom is the same, and then the modules need no look)
                    if (a == 0 or row >= 0) and _is_state(
                        initial if a == 0 else old_states[row], px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, width,
                        step, angle, elasticity, tx, ty, tz, hanging, depth, n_poly,
                    ) and _neutral_range(program.op, neutral, old_symbols, a, o):  # fmt: skip
                        running = False
                        resynced = i
                        continue
                last_copy = o
        if skipping > 0:
            if code == _PUSH:
                skipping += 1
            elif code == _POP:
                skipping -= 1
            if skipping > 0 or code != _POP:
                i += 1
                continue
        if recorded[sym]:
            _write_state(
                states[n_rec],
                px,
                py,
                pz,
                hx,
                hy,
                hz,
                lx,
                ly,
                lz,
                ux,
                uy,
                uz,
                width,
                step,
                angle,
                elasticity,
                tx,
                ty,
                tz,
                hanging,
                depth,
                n_poly,
            )
            positions[n_rec] = i
            n_rec += 1
        if code == _NONE:
            i += 1
            continue
        has_arg = arity[i] > 0
        arg = params[offsets[i]] if has_arg else 0.0
        if code in (_FORWARD, _MOVE):
            h0x, h0y, h0z, l0x, l0y, l0z, u0x, u0y, u0z = hx, hy, hz, lx, ly, lz, ux, uy, uz
            if elasticity != 0.0 and bend:
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                    hx, hy, hz, lx, ly, lz, ux, uy, uz, tx, ty, tz, elasticity, by_angle
                )
            length = arg * length_unit if has_arg else step * program.scale[sym]
            if jitter_length:
                length *= variation.length[i]
            if in_scene and code == _FORWARD and n_poly == 0:
                hanging0 = hanging
                shx, shy, shz, slx, sly, slz, sux, suy, suz = hx, hy, hz, lx, ly, lz, ux, uy, uz
                hx, hy, hz, lx, ly, lz, ux, uy, uz, cut, hanging = _steer(
                    scene, px, py, pz, hx, hy, hz, lx, ly, lz, ux, uy, uz, length, hanging
                )
                if remembering:
                    write_steering(
                        steerings, first_row + n_steer, px, py, pz, shx, shy, shz, slx, sly, slz, sux, suy, suz, length,
                        hanging0, hx, hy, hz, lx, ly, lz, ux, uy, uz, cut, hanging,
                    )  # fmt: skip
                    steered_at[n_at] = i
                    steered_row[n_at] = first_row + n_steer
                    n_at += 1
                    n_steer += 1
                if cut:
                    cuts[n_cut] = i
                    n_cut += 1
                    if not recorded[sym]:  # the state before the cut segment: where its bud starts
                        positions[n_rec] = i
                        row = states[n_rec]
                        _write_state(
                            row,
                            px,
                            py,
                            pz,
                            h0x,
                            h0y,
                            h0z,
                            l0x,
                            l0y,
                            l0z,
                            u0x,
                            u0y,
                            u0z,
                            width,
                            step,
                            angle,
                            elasticity,
                            tx,
                            ty,
                            tz,
                            hanging0,
                            depth,
                            n_poly,
                        )
                        n_rec += 1
                    skipping = np.int64(1)
                    i += 1
                    continue
            qx = px + hx * length
            qy = py + hy * length
            qz = pz + hz * length
            if not (abs(qx) <= far and abs(qy) <= far and abs(qz) <= far):
                return 5, i
            if n_poly == 0 and code == _FORWARD:
                drawn = width * variation.width[i] if jitter_width else width
                if not drawn <= far:
                    return 10, i
            if shading and n_poly == 0 and code == _FORWARD:
                n_dep = _deposit(deposits, n_dep, px, py, pz, qx, qy, qz, length * width)
            px, py, pz = qx, qy, qz
        elif code == _FORWARD_STEPS:
            dlength = params[offsets[i] + 1]
            whole, rest, n_rep = _steps(arg, dlength)
            taper = arity[i] >= 3
            w0 = width
            w1 = params[offsets[i] + 2] * width_unit if taper else width
            dw = (w1 - w0) / arg if taper and arg > 0.0 else 0.0
            for k in range(n_rep):
                if elasticity != 0.0 and bend:
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
                    return 5, i
                if n_poly == 0:
                    drawn = width * variation.width[i] if jitter_width else width
                    if not drawn <= far:
                        return 10, i
                if shading and n_poly == 0:
                    n_dep = _deposit(deposits, n_dep, px, py, pz, qx, qy, qz, length * width)
                px, py, pz = qx, qy, qz
                if taper:
                    width = w0 + dw * dlength * (k + 1) if k < whole else w1
                    if not (0.0 <= width <= far):
                        return 6, i
        elif code == _QUERY and answering and answer_first[sym] >= 0:  # written here (write_answers' numbers)
            f = answer_first[sym]
            if f == 0:
                a0, a1, a2 = px, py, pz
            elif f == 3:
                a0, a1, a2 = hx, hy, hz
            elif f == 6:
                a0, a1, a2 = lx, ly, lz
            else:
                a0, a1, a2 = ux, uy, uz
            sign = answer_sign[sym]
            base = offsets[i]
            if arity[i] > answer_slots[sym, 0]:
                answered[base + answer_slots[sym, 0]] = sign * a0
            if arity[i] > answer_slots[sym, 1]:
                answered[base + answer_slots[sym, 1]] = sign * a1
            if arity[i] > answer_slots[sym, 2]:
                answered[base + answer_slots[sym, 2]] = sign * a2
        elif code == _QUERY:
            row = query_state[n_query]
            row[0], row[1], row[2] = px, py, pz
            row[3], row[4], row[5] = hx, hy, hz
            row[6], row[7], row[8] = lx, ly, lz
            row[9], row[10], row[11] = ux, uy, uz
            query_module[n_query] = i
            n_query += 1
        elif code == _TROPISM_VECTOR:
            base = offsets[i]
            tx = params[base + program.world[sym, 0]]
            ty = params[base + program.world[sym, 1]]
            tz = params[base + program.world[sym, 2]]
            bend = tx != 0.0 or ty != 0.0 or tz != 0.0
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
        elif code == _TURN_AROUND:
            axis = program.axis[sym]
            if axis == _AXIS_H:
                lx, ly, lz, ux, uy, uz = -lx, -ly, -lz, -ux, -uy, -uz
            elif axis == _AXIS_L:
                hx, hy, hz, ux, uy, uz = -hx, -hy, -hz, -ux, -uy, -uz
            else:
                hx, hy, hz, lx, ly, lz = -hx, -hy, -hz, -lx, -ly, -lz
        elif code == _RANDOM_TURN:
            if random_turn:
                most = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else angle)
                for k in range(3):
                    c, s = _cos_sin(most * variation.turn[i, k])
                    hx, hy, hz, lx, ly, lz, ux, uy, uz = _rotate(hx, hy, hz, lx, ly, lz, ux, uy, uz, k + 1, c, s)
        elif code == _TROPISM:
            e = arg if has_arg else program.factor[sym]
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _bend(
                hx, hy, hz, lx, ly, lz, ux, uy, uz, gx, gy, gz, e, np.bool_(False)
            )
        elif code == _ELASTICITY:
            elasticity = arg if has_arg else 0.0
        elif code == _ANGLE_FACTOR:
            f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else angle_scale)
            angle = angle * f ** program.sign[sym]
            if not math.isfinite(angle):
                return 11, i
            cos_angle, sin_angle = _cos_sin(angle)
            cos_of = angle
        elif code == _ROLL_HORIZONTAL:
            norm = math.sqrt(hz * hz + hx * hx)
            if norm > 1e-12:
                lx, ly, lz = hz / norm, 0.0, -hx / norm
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _PUSH:
            row = stack[rel]
            row[0], row[1], row[2] = px, py, pz
            row[3], row[4], row[5] = hx, hy, hz
            row[6], row[7], row[8] = lx, ly, lz
            row[9], row[10], row[11] = ux, uy, uz
            row[12], row[13], row[14], row[15] = width, step, angle, elasticity
            row[16], row[17], row[18] = tx, ty, tz
            row[19] = hanging
            rel += 1
            depth += 1
            if roll_branch:
                c, s = _cos_sin(variation.roll[i])
                lx, ly, lz, ux, uy, uz = _pair(lx, ly, lz, ux, uy, uz, c, s)
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _POP:
            if depth == 0:
                return 1, i
            if following and rel == 0:  # the branch the change was in ends: the state is known again
                if origin[i] < 0 or n_poly != entry_poly:
                    return FOLLOW_LOST, i
                running = False
                i += 1
                continue
            rel -= 1
            depth -= 1
            row = stack[rel]
            px, py, pz = row[0], row[1], row[2]
            hx, hy, hz = row[3], row[4], row[5]
            lx, ly, lz = row[6], row[7], row[8]
            ux, uy, uz = row[9], row[10], row[11]
            width = row[12]
            step = row[13]
            if angle != row[14]:
                angle = row[14]
                cos_angle, sin_angle = _cos_sin(angle)
                cos_of = angle
            elasticity = row[15]
            tx, ty, tz = row[16], row[17], row[18]
            hanging = np.int64(row[19])
            bend = tx != 0.0 or ty != 0.0 or tz != 0.0
        elif code in (_WIDTH, _WIDTH_ADD, _WIDTH_FACTOR):
            if code == _WIDTH:
                width = arg * width_unit if has_arg else width * width_scale
            elif code == _WIDTH_ADD:
                width = (
                    arg * width_unit if has_arg else max(0.0, width + program.sign[sym] * width_increment * width_unit)
                )
            else:
                f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else width_scale)
                width = width * f ** program.sign[sym]
            if not (0.0 <= width <= far):
                return 6, i
        elif code == _MATERIAL:
            if has_arg and arg < -0.5:
                return 8, i
        elif code == _LENGTH:
            f = arg if has_arg else (program.factor[sym] if program.factor[sym] != 0.0 else length_scale)
            step = step * f ** program.sign[sym]
            if not (step >= 0.0 and math.isfinite(step)):
                return 7, i
        elif code == _POLYGON_BEGIN:
            if n_poly > 0 and n_poly == MAX_POLYGON_DEPTH:
                return 2, i
            poly_open[n_poly] = i
            n_poly += 1
        elif code == _POLYGON_END:
            if n_poly == 0:
                return 3, i
            n_poly -= 1
        elif code == _LEAF:
            size = arg if has_arg else step
            if not (0.0 <= size <= far):
                return 9, i
            if shading:
                n_dep = _deposit(deposits, n_dep, px, py, pz, px, py, pz, size * size)
        elif code == _ORGAN:
            kind = program.organ[sym]
            if kind in (_SURFACE, _INSTANCE):
                size = arg if has_arg else 1.0
            else:
                size = arg * width_unit if has_arg else width
            if not (0.0 <= size <= far):
                return 12, i
        i += 1
    counts[0] = n_query
    counts[1] = n_cut
    counts[2] = n_rec
    counts[3] = n_dep
    counts[4] = n_steer
    counts[5] = n_at
    if running and n_poly > 0:
        if poly_open[n_poly - 1] < 0:  # opened before the change: a pass over the whole string names it
            return FOLLOW_LOST, m
        return 4, poly_open[n_poly - 1]
    return 0, -1


@kernel(nogil=True)
def write_answers(params, symbols, offsets, arity, query_module, query_state, first, sign, slots):
    """Write the answers of the query modules the turtle reads without the environment into ``params``.

    Row ``r`` of ``query_state`` (position, H, L, U) is the state at module ``query_module[r]``; a symbol
    ``s`` answers ``sign[s]`` times the three numbers from ``first[s]`` into its parameters ``slots[s]`` (those
    it has), or nothing when ``first[s] < 0`` (``?E``: the environment answers it).
    """
    for r in range(query_module.shape[0]):
        i = query_module[r]
        s = symbols[i]
        f = first[s]
        if f < 0:
            continue
        base = offsets[i]
        a = arity[i]
        for j in range(3):
            slot = slots[s, j]
            if a > slot:
                params[base + slot] = sign[s] * query_state[r, f + j]
