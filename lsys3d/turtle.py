"""The 3D turtle: ModuleString -> :class:`~lsys3d.skeleton.Skeleton`.

The turtle reads a module string left to right (ABOP chapter 1.5, Y-up world
as in glTF).  Its state is a position and an orthonormal frame -- heading
``H``, left ``L``, up ``U`` with ``H x L = U`` -- plus the branch width, the
material index and the step length.  ``[`` saves the whole state, ``]``
restores it.

Every command the turtle knows is one row of :data:`COMMANDS`; the
interpreter, the error messages and ``docs/turtle.md``
(:func:`commands_markdown`) all read that table.  Symbols that are not
commands (``X``, ``A``...) have no geometric effect.

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
    three vertices are dropped with a warning.  Polygons do not nest.
Natural variation
    With ``angle_jitter`` (degrees) each rotation angle of ``+ - & ^ \\ /`` gets
    an offset ``u * angle_jitter``; with ``length_jitter`` each move is scaled
    by ``max(0, 1 + u * length_jitter)``, with ``width_jitter`` each segment's
    width by ``max(0, 1 + u * width_jitter)``; with ``branch_roll`` every ``[``
    rolls the new branch about H by ``u * branch_roll`` degrees.  ``u`` lies in
    ``[-1, 1]``: uniform, or (``jitter_distribution = "normal"``) normal with
    sigma 1/2, redrawn while outside.  With ``branch_drop`` each ``[`` is,
    with that probability, skipped together with everything up to its ``]``.
    Each kind has its own PCG64 stream seeded with ``SeedSequence([seed,
    stream])`` and module ``i`` takes number ``i`` of it, so the result
    depends only on the seed and the module string, and turning one kind on
    leaves the numbers of the others unchanged.
"""

from __future__ import annotations

import logging
import math
import re
import time
from dataclasses import dataclass, fields, replace

import numba
import numpy as np

from .errors import GrammarError, InterpretError, LimitError, clip
from .grammar import Grammar, _key_line
from .modules import ModuleString
from .skeleton import MAX_COORDINATE, Skeleton

__all__ = ["COMMANDS", "DEFAULT_MAX_SEGMENTS", "Command", "TurtleOptions", "commands_markdown", "interpret"]

log = logging.getLogger("lsys3d")

DEFAULT_MAX_SEGMENTS = 1_000_000
"""Most segments :func:`interpret` draws (about 200 bytes a segment in the turtle, far more once swept)."""

# ------------------------------------------------------------------ opcodes
# The numba kernel switches on these; the table below is the only place that
# ties them to symbols.
_NONE = 0
_FORWARD = 1
_MOVE = 2
_TURN_LEFT = 3
_TURN_RIGHT = 4
_PITCH_DOWN = 5
_PITCH_UP = 6
_ROLL_LEFT = 7
_ROLL_RIGHT = 8
_TURN_AROUND = 9
_ROLL_HORIZONTAL = 10
_PUSH = 11
_POP = 12
_WIDTH = 13
_MATERIAL = 14
_LENGTH = 15
_POLYGON_BEGIN = 16
_POLYGON_VERTEX = 17
_POLYGON_END = 18
_LEAF = 19


@dataclass(frozen=True)
class Command:
    """One turtle command: a row of :data:`COMMANDS`.

    Attributes
    ----------
    symbol : str
        The default symbol (``F``, ``f`` and ``~`` can be changed in ``[turtle]``
        with ``draw``, ``move`` and ``leaf``).
    name : str
        Short name used in error messages.
    opcode : int
        What the interpreter's kernel does.
    args : str
        The optional argument, as written in a grammar (empty if none).
    max_args : int
        Most parameters the module may carry.
    description : str
        What the command does.
    """

    symbol: str
    name: str
    opcode: int
    args: str
    max_args: int
    description: str


COMMANDS: tuple[Command, ...] = (
    Command("F", "forward", _FORWARD, "l", 1, "Move forward by the step length (or `l`) drawing a segment."),
    Command("f", "move", _MOVE, "l", 1, "Move forward by the step length (or `l`) without drawing."),
    Command("+", "turn left", _TURN_LEFT, "a", 1, "Rotate about U by +angle (or `a` degrees): H turns toward L."),
    Command("-", "turn right", _TURN_RIGHT, "a", 1, "Rotate about U by -angle: H turns toward -L."),
    Command("&", "pitch down", _PITCH_DOWN, "a", 1, "Rotate about L by +angle: H turns toward -U."),
    Command("^", "pitch up", _PITCH_UP, "a", 1, "Rotate about L by -angle: H turns toward U."),
    Command("\\", "roll left", _ROLL_LEFT, "a", 1, "Rotate about H by -angle: L turns toward -U."),
    Command("/", "roll right", _ROLL_RIGHT, "a", 1, "Rotate about H by +angle: L turns toward U."),
    Command("|", "turn around", _TURN_AROUND, "", 0, "Rotate about U by 180 degrees."),
    Command(
        "$",
        "roll to horizontal",
        _ROLL_HORIZONTAL,
        "",
        0,
        "Roll about H so that L is horizontal: L = (V x H) / |V x H|, U = H x L, V = (0, 1, 0). "
        "No effect when H is vertical.",
    ),
    Command("[", "push", _PUSH, "", 0, "Save the whole turtle state (start a branch)."),
    Command("]", "pop", _POP, "", 0, "Restore the state saved by the matching `[` (end a branch)."),
    Command("!", "width", _WIDTH, "w", 1, "Set the branch diameter to `w`; without `w` multiply it by `width_scale`."),
    Command("'", "material", _MATERIAL, "i", 1, "Set the material index to `i`; without `i` add 1 to it."),
    Command('"', "step length", _LENGTH, "s", 1, "Multiply the step length by `s` (default `length_scale`)."),
    Command("{", "begin polygon", _POLYGON_BEGIN, "", 0, "Start a leaf polygon; moves inside add vertices."),
    Command(".", "polygon vertex", _POLYGON_VERTEX, "", 0, "Add the current position to the open polygon."),
    Command("}", "end polygon", _POLYGON_END, "", 0, "Close the open polygon."),
    Command(
        "~",
        "leaf",
        _LEAF,
        "s",
        1,
        "Place a leaf instance with the turtle's frame, size the step length (or `s`).",
    ),
)
"""The turtle's commands, in the order the documentation lists them."""

_BY_OPCODE = {c.opcode: c for c in COMMANDS}

JITTER_DISTRIBUTIONS = ("uniform", "normal")
"""Values of ``TurtleOptions.jitter_distribution``."""


# ------------------------------------------------------------------ options
@dataclass(frozen=True)
class TurtleOptions:
    """How the turtle draws; every default lives here.

    The ``[turtle]`` table of a grammar sets any field but ``angle`` and
    ``seed``, which come from the grammar's top level.

    Attributes
    ----------
    angle : float
        Default rotation angle, degrees (the grammar's ``angle``).
    heading : float
        Initial heading in the XY plane, degrees: 90 grows up along +Y, 0 along +X.
    step : float
        Initial step length (> 0).
    width : float
        Initial branch diameter (>= 0).
    width_scale : float
        Factor of ``!`` without argument (> 0).
    length_scale : float
        Factor of ``"`` without argument (> 0).
    draw, move : str
        Symbols that move drawing a segment / without drawing.
    leaf : str
        The symbol that places a leaf instance.
    tropism : tuple of 3 float
        Tropism vector T (ABOP 2.8); ``(0, 0, 0)`` for none.
    elasticity : float
        Susceptibility e to tropism: before each move the frame turns by
        ``e * |H x T|`` radians about ``H x T``.
    angle_jitter : float
        Largest random change of a rotation angle, degrees (0: off).
    length_jitter : float
        Largest random relative change of a step (0: off).
    width_jitter : float
        Largest random relative change of a segment's width (0: off).
    branch_roll : float
        Largest random roll about the heading at the start of a branch
        (``[``), degrees (0: off; 180 rolls each branch to any angle).
    branch_drop : float
        Probability in [0, 1] that a branch (``[`` up to its ``]``) is left
        out entirely (0: off).
    jitter_distribution : {"uniform", "normal"}
        Distribution of the jitters and of the branch roll: ``"uniform"`` in
        plus or minus the setting, or ``"normal"`` with standard deviation
        half the setting, truncated to plus or minus the setting.
    seed : int
        Seed of the jitter (the grammar's ``seed``).
    """

    angle: float = 90.0
    heading: float = 90.0
    step: float = 1.0
    width: float = 0.1
    width_scale: float = 0.7
    length_scale: float = 0.9
    draw: str = "F"
    move: str = "f"
    leaf: str = "~"
    tropism: tuple[float, float, float] = (0.0, 0.0, 0.0)
    elasticity: float = 0.0
    angle_jitter: float = 0.0
    length_jitter: float = 0.0
    width_jitter: float = 0.0
    branch_roll: float = 0.0
    branch_drop: float = 0.0
    jitter_distribution: str = "uniform"
    seed: int = 0

    def __post_init__(self):
        for f in fields(self):
            try:
                value = _check_option(f.name, getattr(self, f.name))
            except ValueError as exc:
                raise GrammarError(f"turtle option {exc}", "TurtleOptions") from None
            object.__setattr__(self, f.name, value)
        try:
            _check_symbols(self.draw, self.move, self.leaf)
        except ValueError as exc:
            raise GrammarError(f"turtle option {exc}", "TurtleOptions") from None

    @classmethod
    def from_grammar(cls, grammar: Grammar, **overrides) -> TurtleOptions:
        """The options of a grammar: its ``[turtle]`` table, ``angle`` and ``seed``.

        Parameters
        ----------
        grammar : Grammar
        **overrides
            Fields to set regardless of the grammar.

        Raises
        ------
        GrammarError
            An unknown key or a bad value in ``[turtle]``, with the grammar's
            file and the key's line.

        Examples
        --------
        >>> from lsys3d import load_preset
        >>> TurtleOptions.from_grammar(load_preset("koch")).heading
        0.0
        """
        known = {f.name for f in fields(cls)} - {"angle", "seed"}
        values: dict = {"angle": grammar.angle, "seed": grammar.seed}
        for key, value in grammar.turtle.items():
            if key not in known:
                known_keys = ", ".join(sorted(known))
                raise _turtle_error(grammar, key, f"unknown key {clip(repr(key))} (known keys: {known_keys})")
            try:
                values[key] = _check_option(key, value)
            except ValueError as exc:
                raise _turtle_error(grammar, key, str(exc)) from None
        try:
            _check_symbols(values.get("draw", "F"), values.get("move", "f"), values.get("leaf", "~"))
        except ValueError as exc:
            key = re.match(r"'(\w+)'", str(exc)).group(1)
            raise _turtle_error(grammar, key, str(exc)) from None
        unknown = set(overrides) - {f.name for f in fields(cls)}
        if unknown:
            raise TypeError(f"TurtleOptions.from_grammar: unknown option {sorted(unknown)[0]!r}")
        values.update(overrides)
        return cls(**values)

    def replace(self, **changes) -> TurtleOptions:
        """A copy with some fields changed."""
        return replace(self, **changes)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_option(key: str, value):
    """The normalised value of an option, or ValueError('key' what)."""
    if key in ("draw", "move", "leaf"):
        if not isinstance(value, str):
            raise ValueError(f"'{key}' must be a string of symbols, not {clip(repr(value))}")
        if key == "leaf" and len(value) != 1:
            raise ValueError(f"'{key}' must be one symbol, not {value!r}")
        if any(c.isspace() or c in "()," for c in value):
            raise ValueError(f"'{key}' holds a character that cannot be a symbol: {clip(repr(value))}")
        return value
    if key == "tropism":
        if not isinstance(value, (list, tuple)) or len(value) != 3 or not all(_is_number(v) for v in value):
            raise ValueError(f"'tropism' must be a list of three numbers [x, y, z], not {clip(repr(value))}")
        return tuple(float(v) for v in value)
    if key == "jitter_distribution":
        if value not in JITTER_DISTRIBUTIONS:
            raise ValueError(f"'{key}' must be one of {', '.join(map(repr, JITTER_DISTRIBUTIONS))}, not {value!r}")
        return value
    if key == "seed":
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ValueError(f"'seed' must be a whole number >= 0, not {value!r}")
        return value
    if not _is_number(value):
        raise ValueError(f"'{key}' must be a finite number, not {clip(repr(value))}")
    value = float(value)
    lower = {"step": (0, False), "width_scale": (0, False), "length_scale": (0, False), "width": (0, True)}
    lower.update({"angle_jitter": (0, True), "length_jitter": (0, True)})
    lower.update({"width_jitter": (0, True), "branch_roll": (0, True), "branch_drop": (0, True)})
    if key in lower:
        bound, inclusive = lower[key]
        if value < bound or (value == bound and not inclusive):
            raise ValueError(f"'{key}' must be {'>=' if inclusive else '>'} {bound}, not {value:g}")
    if key == "branch_drop" and value > 1:
        raise ValueError(f"'{key}' is a probability: it must be <= 1, not {value:g}")
    return value


def _check_symbols(draw: str, move: str, leaf: str):
    fixed = {c.symbol for c in COMMANDS if c.opcode not in (_FORWARD, _MOVE, _LEAF)}
    for key, symbols in (("draw", draw), ("move", move), ("leaf", leaf)):
        clash = sorted(set(symbols) & fixed)
        if clash:
            raise ValueError(f"'{key}' symbol {clash[0]!r} is already the turtle command {_command_name(clash[0])}")
    both = sorted(set(draw) & set(move))
    if both:
        raise ValueError(f"'move' symbol {both[0]!r} is also a 'draw' symbol")
    if leaf in draw or leaf in move:
        raise ValueError(f"'leaf' symbol {leaf!r} is also a 'draw' or 'move' symbol")


def _command_name(symbol: str) -> str:
    return next(c.name for c in COMMANDS if c.symbol == symbol)


def _turtle_error(grammar: Grammar, key: str, what: str) -> GrammarError:
    line = _turtle_key_line(grammar.text, key) if grammar.text else None
    return GrammarError(f"[turtle] {what}", grammar.source, line, 1 if line else None)


def _turtle_key_line(text: str, key: str) -> int | None:
    """Line of ``key`` inside the ``[turtle]`` table (or of the table itself)."""
    table = _key_line(text, "turtle")
    if table is None:
        return None
    lines = text.splitlines()
    pattern = re.compile(rf"^[ \t]*[\"']?{re.escape(key)}[\"']?[ \t]*=")
    for number in range(table + 1, len(lines) + 1):
        line = lines[number - 1]
        if re.match(r"^[ \t]*\[", line):
            break
        if pattern.match(line):
            return number
    return table


# ------------------------------------------------------------------ kernel
# status codes of the kernel; the message says what went wrong at module `bad`
_OK = 0
_MESSAGES = {
    1: "nothing to pop: more ']' than '[' so far",
    2: "a polygon is already open (polygons do not nest)",
    3: "no polygon is open ('}' without '{')",
    4: "polygon never closed (no matching '}')",
    5: f"the turtle's position left the drawable range of +-{MAX_COORDINATE:g} (lsys3d.skeleton.MAX_COORDINATE); "
    "check the step length (F's parameter, step, length_scale, length_jitter)",
    6: f"the width must be a number from 0 to {MAX_COORDINATE:g} (lsys3d.skeleton.MAX_COORDINATE)",
    7: "the step length must be a finite number >= 0",
    8: "the material index must be >= 0",
    9: f"the leaf size must be a number from 0 to {MAX_COORDINATE:g} (lsys3d.skeleton.MAX_COORDINATE)",
    10: f"the width with width_jitter is more than {MAX_COORDINATE:g} (lsys3d.skeleton.MAX_COORDINATE)",
}


@numba.njit(cache=True, inline="always")
def _pair(ax, ay, az, bx, by, bz, c, s):
    """Rotate a frame pair in its plane: a toward b by the angle with cos c, sin s."""
    return ax * c + bx * s, ay * c + by * s, az * c + bz * s, bx * c - ax * s, by * c - ay * s, bz * c - az * s


@numba.njit(cache=True, inline="always")
def _orthonormal(hx, hy, hz, lx, ly, lz):
    """Re-orthonormalise a nearly orthonormal H, L and return H, L, U = H x L.

    Keeps rounding from piling up over millions of turns.  The inputs are unit
    vectors to within rounding, so one Newton step ``v * (3 - v.v) / 2`` normalises
    them to full precision without a square root or a division.
    """
    n = 1.5 - 0.5 * (hx * hx + hy * hy + hz * hz)
    hx *= n
    hy *= n
    hz *= n
    d = lx * hx + ly * hy + lz * hz
    lx -= d * hx
    ly -= d * hy
    lz -= d * hz
    n = 1.5 - 0.5 * (lx * lx + ly * ly + lz * lz)
    lx *= n
    ly *= n
    lz *= n
    return hx, hy, hz, lx, ly, lz, hy * lz - hz * ly, hz * lx - hx * lz, hx * ly - hy * lx


@numba.njit(cache=True, inline="always")
def _cos_sin(degrees):
    """Cosine and sine of an angle in degrees, exact for multiples of 90 (so +(90) and heading 90 are exact)."""
    r = degrees % 360.0
    if r == 0.0:
        return 1.0, 0.0
    if r == 90.0:
        return 0.0, 1.0
    if r == 180.0:
        return -1.0, 0.0
    if r == 270.0:
        return 0.0, -1.0
    a = math.radians(degrees)
    return math.cos(a), math.sin(a)


@numba.njit(cache=True, inline="always")
def _put(a, k, x, y, z):
    a[k, 0] = x
    a[k, 1] = y
    a[k, 2] = z


@numba.njit(cache=True, inline="always")
def _add_vertex(points, n, first, x, y, z):
    """Append a polygon vertex unless it repeats the previous one; return the new count."""
    if n > first and points[n - 1, 0] == x and points[n - 1, 1] == y and points[n - 1, 2] == z:
        return n
    points[n, 0] = x
    points[n, 1] = y
    points[n, 2] = z
    return n + 1


@numba.njit(cache=True, nogil=True)
def _survey(table, symbols, arity, offsets, params, max_args):
    """One pass before drawing: how many modules of each command, deepest bracket, bad arguments.

    Returns (counts (32,), max depth, bad module or -1, 1 too many arguments / 2 not finite).
    """
    counts = np.zeros(32, np.int64)
    depth = 0
    deepest = 0
    for i in range(symbols.shape[0]):
        code = table[symbols[i]]
        counts[code] += 1
        if code == _NONE:
            continue
        if arity[i] > max_args[code]:
            return counts, deepest, i, 1
        if arity[i] > 0 and not math.isfinite(params[offsets[i]]):
            return counts, deepest, i, 2
        if code == _PUSH:
            depth += 1
            if depth > deepest:
                deepest = depth
        elif code == _POP:
            depth -= 1
    return counts, deepest, -1, 0


@numba.njit(cache=True, nogil=True)
def _kernel(
    table,
    symbols,
    arity,
    offsets,
    params,
    config,
    tropism,
    angle_noise,
    length_factor,
    width_factor,
    roll_noise,
    skipped,
    stack_f,
    stack_i,
    seg_frame,
    seg_width,
    seg_index,
    seg_class,
    poly_points,
    poly_offsets,
    poly_material,
    leaf_frame,
    leaf_size,
    leaf_material,
):
    """Run the turtle over the modules, writing into the preallocated outputs.

    ``config`` = angle (degrees), heading (degrees), step, width, width_scale,
    length_scale, elasticity.  Segment outputs are the tuples ``seg_frame`` =
    (start, end, heading, left, up), ``seg_width`` = (width_start, width_end),
    ``seg_index`` = (parent, module), ``seg_class`` = (order, material); leaf
    instances ``leaf_frame`` = (position, heading, left, up).

    Returns (status, bad module, segments, points, polygons, leaves, dropped polygons).
    """
    start, end, seg_h, seg_l, seg_u = seg_frame
    width_start, width_end = seg_width
    parent, module = seg_index
    seg_order, seg_material = seg_class
    leaf_p, leaf_h, leaf_l, leaf_u = leaf_frame
    n_cap = start.shape[0]
    depth_of = np.empty(n_cap, np.int64)
    first_child = np.full(n_cap, -1, np.int64)
    same_child = np.full(n_cap, -1, np.int64)  # first child of the same order

    angle = config[0]
    cos_angle, sin_angle = _cos_sin(angle)
    step = config[2]
    width = config[3]
    width_scale = config[4]
    length_scale = config[5]
    elasticity = config[6]
    far = config[7]  # MAX_COORDINATE
    tx, ty, tz = tropism[0], tropism[1], tropism[2]
    bend = elasticity != 0.0 and (tx != 0.0 or ty != 0.0 or tz != 0.0)
    jitter_angle = angle_noise.shape[0] > 0
    jitter_length = length_factor.shape[0] > 0
    jitter_width = width_factor.shape[0] > 0
    roll_branch = roll_noise.shape[0] > 0
    drop_branch = skipped.shape[0] > 0

    px = py = pz = 0.0
    hx, hy = _cos_sin(config[1])
    hz = 0.0
    lx, ly, lz = -hy, hx, 0.0
    ux, uy, uz = 0.0, 0.0, 1.0
    material = 0
    last = -1  # parent of the next segment
    anchor = -1  # last segment drawn in this state, for branch order
    depth = 0
    n_seg = 0
    n_pts = 0
    n_poly = 0
    n_leaf = 0
    dropped = 0
    poly_open = -1  # module that opened the polygon
    poly_start = 0
    poly_mat = 0

    m = symbols.shape[0]
    for i in range(m):
        code = table[symbols[i]]
        if code == _NONE:
            continue
        if drop_branch and skipped[i]:
            continue
        has_arg = arity[i] > 0
        arg = params[offsets[i]] if has_arg else 0.0
        if code in (_FORWARD, _MOVE):
            if bend:
                # H x T: rotate the frame about it by e * |H x T| so H bends toward T
                cx = hy * tz - hz * ty
                cy = hz * tx - hx * tz
                cz = hx * ty - hy * tx
                norm = math.sqrt(cx * cx + cy * cy + cz * cz)
                if norm > 1e-12:
                    a = elasticity * norm
                    kx, ky, kz = cx / norm, cy / norm, cz / norm
                    c, s = math.cos(a), math.sin(a)
                    # Rodrigues: v' = v c + (k x v) s + k (k.v)(1 - c), for H and L
                    d = (kx * hx + ky * hy + kz * hz) * (1.0 - c)
                    nhx = hx * c + (ky * hz - kz * hy) * s + kx * d
                    nhy = hy * c + (kz * hx - kx * hz) * s + ky * d
                    nhz = hz * c + (kx * hy - ky * hx) * s + kz * d
                    d = (kx * lx + ky * ly + kz * lz) * (1.0 - c)
                    nlx = lx * c + (ky * lz - kz * ly) * s + kx * d
                    nly = ly * c + (kz * lx - kx * lz) * s + ky * d
                    nlz = lz * c + (kx * ly - ky * lx) * s + kz * d
                    hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(nhx, nhy, nhz, nlx, nly, nlz)
            length = arg if has_arg else step
            if jitter_length:
                length *= length_factor[i]
            qx = px + hx * length
            qy = py + hy * length
            qz = pz + hz * length
            if not (abs(qx) <= far and abs(qy) <= far and abs(qz) <= far):  # NaN fails too
                return 5, i, n_seg, n_pts, n_poly, n_leaf, dropped
            if poly_open >= 0:
                n_pts = _add_vertex(poly_points, n_pts, poly_start, qx, qy, qz)
                last = -1
            elif code == _FORWARD:
                s_ = n_seg
                _put(start, s_, px, py, pz)
                _put(end, s_, qx, qy, qz)
                _put(seg_h, s_, hx, hy, hz)
                _put(seg_l, s_, lx, ly, lz)
                _put(seg_u, s_, ux, uy, uz)
                drawn = width * width_factor[i] if jitter_width else width
                if not drawn <= far:
                    return 10, i, n_seg, n_pts, n_poly, n_leaf, dropped
                width_start[s_] = drawn
                width_end[s_] = drawn
                if anchor >= 0:
                    rise = depth - depth_of[anchor]
                    order = seg_order[anchor] + (rise if rise > 0 else 0)
                else:
                    order = 0
                parent[s_] = last
                module[s_] = i
                seg_order[s_] = order
                seg_material[s_] = material
                depth_of[s_] = depth
                if last >= 0:
                    if first_child[last] < 0:
                        first_child[last] = s_
                    if same_child[last] < 0 and seg_order[last] == order:
                        same_child[last] = s_
                last = s_
                anchor = s_
                n_seg += 1
            else:
                last = -1
            px, py, pz = qx, qy, qz
        elif code <= _ROLL_RIGHT:
            if jitter_angle:
                c, s = _cos_sin((arg if has_arg else angle) + angle_noise[i])
            elif has_arg:
                c, s = _cos_sin(arg)
            else:
                c, s = cos_angle, sin_angle
            if code in (_TURN_RIGHT, _PITCH_DOWN, _ROLL_LEFT):
                s = -s
            if code <= _TURN_RIGHT:  # about U: H toward L
                hx, hy, hz, lx, ly, lz = _pair(hx, hy, hz, lx, ly, lz, c, s)
            elif code <= _PITCH_UP:  # about L: H toward U (pitch up)
                hx, hy, hz, ux, uy, uz = _pair(hx, hy, hz, ux, uy, uz, c, s)
                lx, ly, lz = uy * hz - uz * hy, uz * hx - ux * hz, ux * hy - uy * hx
            else:  # about H: L toward U (roll right)
                lx, ly, lz, ux, uy, uz = _pair(lx, ly, lz, ux, uy, uz, c, s)
            hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _TURN_AROUND:
            hx, hy, hz = -hx, -hy, -hz
            lx, ly, lz = -lx, -ly, -lz
        elif code == _ROLL_HORIZONTAL:
            # L = V x H with V = (0, 1, 0)
            norm = math.sqrt(hz * hz + hx * hx)
            if norm > 1e-12:
                lx, ly, lz = hz / norm, 0.0, -hx / norm
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
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
            stack_i[depth, 0] = material
            stack_i[depth, 1] = last
            stack_i[depth, 2] = anchor
            depth += 1
            if roll_branch:  # the branch starts rolled about H; the saved state is not
                c, s = _cos_sin(roll_noise[i])
                lx, ly, lz, ux, uy, uz = _pair(lx, ly, lz, ux, uy, uz, c, s)
                hx, hy, hz, lx, ly, lz, ux, uy, uz = _orthonormal(hx, hy, hz, lx, ly, lz)
        elif code == _POP:
            if depth == 0:
                return 1, i, n_seg, n_pts, n_poly, n_leaf, dropped
            depth -= 1
            row = stack_f[depth]
            px, py, pz = row[0], row[1], row[2]
            hx, hy, hz = row[3], row[4], row[5]
            lx, ly, lz = row[6], row[7], row[8]
            ux, uy, uz = row[9], row[10], row[11]
            width = row[12]
            step = row[13]
            material = stack_i[depth, 0]
            last = stack_i[depth, 1]
            anchor = stack_i[depth, 2]
        elif code == _WIDTH:
            width = arg if has_arg else width * width_scale
            if not (0.0 <= width <= far):
                return 6, i, n_seg, n_pts, n_poly, n_leaf, dropped
            if last >= 0 and depth_of[last] == depth:
                width_end[last] = width
        elif code == _MATERIAL:
            if has_arg:
                if arg < -0.5:
                    return 8, i, n_seg, n_pts, n_poly, n_leaf, dropped
                material = round(arg)
            else:
                material += 1
        elif code == _LENGTH:
            step = step * (arg if has_arg else length_scale)
            if not (step >= 0.0 and math.isfinite(step)):
                return 7, i, n_seg, n_pts, n_poly, n_leaf, dropped
        elif code == _POLYGON_BEGIN:
            if poly_open >= 0:
                return 2, i, n_seg, n_pts, n_poly, n_leaf, dropped
            poly_open = i
            poly_start = n_pts
            poly_mat = material
        elif code == _POLYGON_VERTEX:
            if poly_open >= 0:
                n_pts = _add_vertex(poly_points, n_pts, poly_start, px, py, pz)
        elif code == _POLYGON_END:
            if poly_open < 0:
                return 3, i, n_seg, n_pts, n_poly, n_leaf, dropped
            poly_open = -1
            k = n_pts - poly_start
            if k >= 2:
                # a polygon walked back to its first vertex lists that vertex once
                f0 = poly_points[poly_start]
                fl = poly_points[n_pts - 1]
                gap = abs(f0[0] - fl[0]) + abs(f0[1] - fl[1]) + abs(f0[2] - fl[2])
                if gap <= 1e-9 * (1.0 + abs(f0[0]) + abs(f0[1]) + abs(f0[2])):
                    n_pts -= 1
                    k -= 1
            if k >= 3:
                n_poly += 1
                poly_offsets[n_poly] = n_pts
                poly_material[n_poly - 1] = poly_mat
            else:
                n_pts = poly_start
                dropped += 1
        elif code == _LEAF:
            size = arg if has_arg else step
            if not (0.0 <= size <= far):
                return 9, i, n_seg, n_pts, n_poly, n_leaf, dropped
            _put(leaf_p, n_leaf, px, py, pz)
            _put(leaf_h, n_leaf, hx, hy, hz)
            _put(leaf_l, n_leaf, lx, ly, lz)
            _put(leaf_u, n_leaf, ux, uy, uz)
            leaf_size[n_leaf] = size
            leaf_material[n_leaf] = material
            n_leaf += 1
    if poly_open >= 0:
        return 4, poly_open, n_seg, n_pts, n_poly, n_leaf, dropped
    # width_end: where the chain goes on (the rule of Skeleton.chains), the next width; at a tip, the tip's
    for s_ in range(n_seg):
        nxt = same_child[s_] if same_child[s_] >= 0 else first_child[s_]
        if nxt >= 0:
            width_end[s_] = width_start[nxt]
    return _OK, -1, n_seg, n_pts, n_poly, n_leaf, dropped


# ------------------------------------------------------------------ interpret
def _opcode_table(modules: ModuleString, options: TurtleOptions) -> np.ndarray:
    """The command of each symbol id, ``(256,) int8`` (0 for symbols without effect)."""
    table = np.zeros(256, np.int8)
    code_of = {ch: i for i, ch in enumerate(modules.alphabet) if ch != "\0"}
    for cmd in COMMANDS:
        if cmd.opcode not in (_FORWARD, _MOVE, _LEAF):
            table[ord(cmd.symbol)] = cmd.opcode
    for symbols, opcode in ((options.draw, _FORWARD), (options.move, _MOVE), (options.leaf, _LEAF)):
        for ch in symbols:
            if ch in code_of:
                table[code_of[ch]] = opcode
    return table


_MAX_ARGS = np.zeros(32, np.int64)
for _cmd in COMMANDS:
    _MAX_ARGS[_cmd.opcode] = _cmd.max_args


def _module_error(modules: ModuleString, table: np.ndarray, i: int, what: str) -> InterpretError:
    cmd = _BY_OPCODE.get(int(table[modules.symbols[i]]))
    name = f" ({cmd.name})" if cmd else ""
    return InterpretError(f"module {i} '{modules.module_text(i, short=True)}'{name}: {what}")


# one random stream per kind of variation, so turning one on leaves the others' numbers alone
_ANGLE_STREAM, _LENGTH_STREAM, _WIDTH_STREAM, _ROLL_STREAM, _DROP_STREAM = 1, 2, 3, 4, 5


def _stream(seed: int, stream: int) -> np.random.Generator:
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, stream])))


def _unit_jitter(rng: np.random.Generator, m: int, distribution: str) -> np.ndarray:
    """``m`` numbers in [-1, 1]: uniform, or normal with sigma 1/2 truncated to [-1, 1] (redrawn outside)."""
    if distribution == "uniform":
        return rng.uniform(-1.0, 1.0, m)
    z = rng.normal(0.0, 0.5, m)
    bad = np.flatnonzero(np.abs(z) > 1.0)
    while bad.size:
        z[bad] = rng.normal(0.0, 0.5, bad.size)
        bad = bad[np.abs(z[bad]) > 1.0]
    return z


def _jitter(m: int, options: TurtleOptions, seed: int):
    """Per-module random arrays of the natural variation; an empty array for each kind that is off.

    Returns angle offsets (degrees), length factors, width factors, branch
    rolls (degrees) and whether a ``[`` there starts a dropped branch (bool).
    """
    noise = np.zeros(0)
    factor = np.zeros(0)
    width = np.zeros(0)
    roll = np.zeros(0)
    drop = np.zeros(0, np.bool_)
    dist = options.jitter_distribution
    if options.angle_jitter > 0 and m:
        noise = _unit_jitter(_stream(seed, _ANGLE_STREAM), m, dist) * options.angle_jitter
    if options.length_jitter > 0 and m:
        factor = np.maximum(0.0, 1.0 + options.length_jitter * _unit_jitter(_stream(seed, _LENGTH_STREAM), m, dist))
    if options.width_jitter > 0 and m:
        width = np.maximum(0.0, 1.0 + options.width_jitter * _unit_jitter(_stream(seed, _WIDTH_STREAM), m, dist))
    if options.branch_roll > 0 and m:
        roll = _unit_jitter(_stream(seed, _ROLL_STREAM), m, dist) * options.branch_roll
    if options.branch_drop > 0 and m:
        drop = _stream(seed, _DROP_STREAM).random(m) < options.branch_drop
    return noise, factor, width, roll, drop


@numba.njit(cache=True, nogil=True)
def _dropped_modules(table, symbols, drop):
    """Modules inside a dropped branch: from a ``[`` whose ``drop`` is set to its matching ``]`` (or the end)."""
    m = symbols.shape[0]
    out = np.zeros(m, np.bool_)
    depth = 0  # bracket depth inside the branch being dropped; 0: not dropping
    for i in range(m):
        code = table[symbols[i]]
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


def interpret(
    modules: ModuleString,
    options: TurtleOptions | Grammar,
    seed: int | None = None,
    *,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
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
    if isinstance(options, Grammar):
        options = TurtleOptions.from_grammar(options)
    elif not isinstance(options, TurtleOptions):
        raise TypeError(f"interpret: options must be TurtleOptions or Grammar, not {type(options).__name__}")
    if seed is None:
        seed = options.seed
    t0 = time.perf_counter()
    m = len(modules)
    table = _opcode_table(modules, options)
    counts, max_depth, bad, why = _survey(
        table, modules.symbols, modules.arity, modules.offsets, modules.params, _MAX_ARGS
    )
    if why == 1:
        n = int(_MAX_ARGS[table[modules.symbols[bad]]])
        raise _module_error(modules, table, bad, f"takes {'no argument' if n == 0 else f'at most {n} argument'}")
    if why == 2:
        raise _module_error(modules, table, bad, "parameter is not a finite number")
    n_seg = int(counts[_FORWARD])
    if n_seg > max_segments:
        raise LimitError(
            f"interpret: the module string would draw up to {n_seg:,} segments, more than the limit of "
            f"{max_segments:,}; use fewer iterations, or raise the limit (--max-segments, or max_segments=)"
        )
    n_poly = int(counts[_POLYGON_BEGIN])
    n_pts = int(counts[_FORWARD] + counts[_MOVE] + counts[_POLYGON_VERTEX]) if n_poly else 0
    n_leaf = int(counts[_LEAF])
    config = np.array(
        [
            options.angle,
            options.heading,
            options.step,
            options.width,
            options.width_scale,
            options.length_scale,
            options.elasticity,
            MAX_COORDINATE,
        ]
    )
    noise, factor, width_factor, roll, drop = _jitter(m, options, seed)
    skipped = _dropped_modules(table, modules.symbols, drop) if len(drop) else drop
    stack_f = np.empty((max_depth, 14))
    stack_i = np.empty((max_depth, 3), np.int64)
    seg_frame = tuple(np.empty((n_seg, 3)) for _ in range(5))
    seg_width = (np.empty(n_seg), np.empty(n_seg))
    seg_index = (np.empty(n_seg, np.int64), np.empty(n_seg, np.int64))
    seg_class = (np.empty(n_seg, np.int32), np.empty(n_seg, np.int32))
    poly_points = np.empty((n_pts, 3))
    poly_offsets = np.zeros(n_poly + 1, np.int64)
    poly_material = np.empty(n_poly, np.int32)
    leaf_frame = tuple(np.empty((n_leaf, 3)) for _ in range(4))
    leaf_size = np.empty(n_leaf)
    leaf_material = np.empty(n_leaf, np.int32)
    status, bad, n_seg, n_pts, n_poly, n_leaf, dropped = _kernel(
        table,
        modules.symbols,
        modules.arity,
        modules.offsets,
        modules.params,
        config,
        np.array(options.tropism, np.float64),
        noise,
        factor,
        width_factor,
        roll,
        skipped,
        stack_f,
        stack_i,
        seg_frame,
        seg_width,
        seg_index,
        seg_class,
        poly_points,
        poly_offsets,
        poly_material,
        leaf_frame,
        leaf_size,
        leaf_material,
    )
    if status != _OK:
        raise _module_error(modules, table, int(bad), _MESSAGES[status])
    if dropped:
        log.warning("turtle: dropped %d leaf polygon(s) with fewer than 3 distinct vertices", dropped)

    # capacities are exact unless drawing symbols stood inside polygons or polygons were dropped
    start, end, heading, left, up = (a[:n_seg] for a in seg_frame)
    skeleton = Skeleton(
        start=start,
        end=end,
        width_start=seg_width[0][:n_seg],
        width_end=seg_width[1][:n_seg],
        heading=heading,
        left=left,
        up=up,
        parent=seg_index[0][:n_seg],
        order=seg_class[0][:n_seg],
        material=seg_class[1][:n_seg],
        module=seg_index[1][:n_seg],
        polygon_points=poly_points[:n_pts],
        polygon_offsets=poly_offsets[: n_poly + 1],
        polygon_material=poly_material[:n_poly],
        leaf_position=leaf_frame[0][:n_leaf],
        leaf_heading=leaf_frame[1][:n_leaf],
        leaf_left=leaf_frame[2][:n_leaf],
        leaf_up=leaf_frame[3][:n_leaf],
        leaf_size=leaf_size[:n_leaf],
        leaf_material=leaf_material[:n_leaf],
    )
    log.debug(
        "interpret: %d modules -> %d segments, %d polygons, %d leaves in %.3f s",
        m,
        n_seg,
        n_poly,
        n_leaf,
        time.perf_counter() - t0,
    )
    return skeleton


# ------------------------------------------------------------------ docs
def commands_markdown() -> str:
    """The command table as Markdown (the table in ``docs/turtle.md``)."""
    rows = ["| Symbol | Name | Argument | What it does |", "|---|---|---|---|"]
    for cmd in COMMANDS:
        symbol = cmd.symbol.replace("|", "\\|")
        arg = f"`{symbol}({cmd.args})`" if cmd.args else ""
        rows.append(f"| `{symbol}` | {cmd.name} | {arg} | {cmd.description.replace('|', chr(92) + '|')} |")
    return "\n".join(rows) + "\n"
