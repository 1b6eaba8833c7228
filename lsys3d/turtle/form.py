"""Form: botanical shape for a drawn skeleton (pipe-model widths, flare, curvature, irregularity, phyllotaxis, collars).

The stage runs between the turtle and the sweep: :func:`form` takes the
:class:`~lsys3d.turtle.skeleton.Skeleton` the turtle drew and returns a reshaped one,
with the same branches, leaves and organs.  Every feature is off by default
(:class:`FormOptions`); a grammar turns them on with a ``[form]`` table, the
CLI and :func:`lsys3d.generate` by their flat names (``--pipe-model``,
``flare=1.6``...).  What each feature does, in the order the stage applies them:

1. **Phyllotaxis** (``phyllotaxis``): every lateral (a segment of higher order
   than its parent) is rolled about its parent's heading so that successive
   laterals of one axis stand at the pattern's divergence; the grammar's own
   ``/`` rolls between them are replaced.  The first lateral of an axis keeps
   its azimuth.
2. **Irregularity** (``angle_variation``, ``length_variation``, per order): each
   lateral's subtree turns about its base in its branching plane by up to the
   order's angle, and its lengths are scaled by ``1 +- variation`` (seeded).
3. **Curvature** (``gnarl``, ``gravitropism``, ``phototropism``,
   ``plagiotropism``): segments are split into sub-segments of at most
   ``max_substep_length`` (at most ``substeps`` a segment), and each
   sub-segment turns at its start by fBm noise along the branch plus the
   tropisms.  The whole downstream subtree turns with it (forward kinematics:
   a segment's rotation is its parent's composed with its own), so children
   stay attached, and leaves, leaf polygons and organs move with their segment.
4. **Widths**: the pipe model (``pipe_model``), the trunk flare (``flare``) and
   the branch collars (``branch_collar``), see :func:`pipe_widths` and :class:`FormOptions`.

Everything is deterministic per seed: the noise is :func:`lsys3d.noise.fbm3`
seeded by :attr:`lsys3d.streams.Stream.FORM_GNARL`, the variation draws from
:attr:`~lsys3d.streams.Stream.FORM_VARIATION`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields, replace
from functools import partial

import numpy as np

from ..arrays import dot, local_index, unit
from ..compiling import inner, kernel
from ..errors import LimitError, OptionsError, clip
from ..lsystem.grammar import Grammar, table_error
from ..noise import fbm3
from ..options import Options, merge_table, option, spec_of
from ..streams import Stream, generator
from .interpret import DEFAULT_MAX_SEGMENTS
from .skeleton import Skeleton

__all__ = [
    "GOLDEN_ANGLE",
    "GRAMMAR_KEYS",
    "PHYLLOTAXIS",
    "FormOptions",
    "form",
    "options_markdown",
    "pipe_widths",
    "tip_counts",
]

GOLDEN_ANGLE = 180.0 * (3.0 - math.sqrt(5.0))
"""The golden angle, 137.507... degrees: the divergence of ``phyllotaxis = "golden"``."""

PHYLLOTAXIS = ("none", "golden", "distichous", "opposite", "decussate", "whorl:N")
"""Values of ``FormOptions.phyllotaxis`` (``whorl:N`` with N from 2 to 16)."""

_WHORL = re.compile(r"whorl:(\d+)\Z")
_MAX_PIECES = 256  # most sub-segments one segment is split into (substeps, flare and collar together)


@dataclass(frozen=True)
class FormOptions(Options):
    """How the form stage reshapes a skeleton; every feature off by default.

    Widths: with ``pipe_model`` every segment's diameter is ``tip_width *
    tips ** (1 / pipe_exponent)``, where ``tips`` counts the terminal segments
    (segments without children) it carries (a terminal segment: one, itself);
    so at every fork the parent's ``d ** e`` is the sum of its children's, and
    a chain never grows toward its tip.  A segment keeps its diameter to its end (where its
    only child starts with the same one); a tip keeps ``tip_width``.  ``flare``
    widens the trunk (order 0) toward its base: ``1 + (flare - 1) * (1 - h /
    flare_height) ** 3`` at distance ``h`` from its base along it (smooth: no
    step where it ends), its segments split so that the curve is sampled.
    ``branch_collar`` swells each lateral's base by that factor, tapering back over
    ``branch_collar_length`` of its diameters, never wider than its parent's end.
    With any of the three, no child starts wider than its parent ends.

    Per-order tuples (``gravitropism``, ``angle_variation``,
    ``length_variation``): entry ``k`` is for order ``k`` (gravitropism) or for
    laterals of order ``k + 1`` (the variations), the last entry for every
    higher order; a single number is a tuple of one.
    """

    enabled: bool = option(
        True,
        name="form",
        help="apply the form stage (off: the skeleton as the turtle drew it, whatever the grammar's [form] says)",
    )
    pipe_model: bool = option(False, help="pipe-model widths from the tips each segment carries (Shinozaki)")
    pipe_exponent: float = option(
        2.0, low=2, high=3, help="exponent e of the pipe model: the parent's d^e is the sum of its children's"
    )
    tip_width: float = option(0.01, low=0, low_open=True, high=1e6, help="diameter of a terminal segment, metres")
    flare: float = option(1.0, low=1, high=10, help="trunk diameter at the ground over its unflared diameter (1: off)")
    flare_height: float = option(
        1.0, low=0, low_open=True, high=1e6, help="metres along the trunk over which the flare fades out"
    )
    gnarl: float = option(0.0, low=0, high=3600, help="bending by fBm noise along the branches, degrees per metre")
    gnarl_frequency: float = option(
        0.5, low=0, low_open=True, high=1e3, help="features of the gnarl noise per metre of branch"
    )
    max_substep_length: float = option(
        0.25, low=0, low_open=True, high=1e6, help="curved segments are split into pieces at most this long, metres"
    )
    substeps: int = option(8, low=1, high=64, help="most pieces one segment is split into for its curvature")
    gravitropism: tuple = option(
        (),
        kind="vector",
        metavar="X[,X...]",
        low=-3600,
        high=3600,
        help="degrees per metre toward the sky (negative: toward the ground) per branch order, the last for "
        "higher orders",
    )
    phototropism: float = option(0.0, low=0, high=3600, help="degrees per metre toward `phototropism_light`")
    phototropism_light: tuple[float, float, float] = option(
        (0.0, 1.0, 0.0), help="direction toward the light the branches turn to, `[x, y, z]`"
    )
    plagiotropism: float = option(
        0.0, low=0, high=3600, help="degrees per metre by which laterals (order >= 1) turn toward the horizontal"
    )
    angle_variation: tuple = option(
        (),
        kind="vector",
        metavar="X[,X...]",
        low=0,
        high=90,
        help="random change of each lateral's branching angle, up to degrees, per order",
    )
    length_variation: tuple = option(
        (),
        kind="vector",
        metavar="X[,X...]",
        low=0,
        high=0.9,
        help="random relative change of each lateral's lengths, per order",
    )
    phyllotaxis: str = option(
        "none",
        help='divergence between successive laterals of an axis: "none", "golden" (137.5 deg), "distichous" (180), '
        '"opposite" (pairs at 180, pairs aligned), "decussate" (pairs at 180, pairs 90 apart), "whorl:N" (N at '
        "360/N, whorls 180/N apart)",
    )
    branch_collar: float = option(
        1.0, low=1, high=2, help="a lateral's base swells by this factor into its parent (1: off)"
    )
    branch_collar_length: float = option(
        1.5, low=0, low_open=True, high=10, help="the collar fades out over this many of the lateral's diameters"
    )

    def __post_init__(self):
        for name in _PER_ORDER:  # one number: a tuple of one
            value = getattr(self, name)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                object.__setattr__(self, name, (value,))
        super().__post_init__()
        if not _phyllotaxis_ok(self.phyllotaxis):
            raise OptionsError(
                f"FormOptions.phyllotaxis: must be one of {', '.join(map(repr, PHYLLOTAXIS))}, "
                f"not {clip(repr(self.phyllotaxis))}"
            )
        if not math.hypot(*self.phototropism_light) > 0:
            raise OptionsError("FormOptions.phototropism_light: must not be the zero vector")

    @property
    def curved(self) -> bool:
        """Whether the segments bend (noise or a tropism)."""
        return bool(self.gnarl > 0 or any(self.gravitropism) or self.phototropism > 0 or self.plagiotropism > 0)

    @property
    def active(self) -> bool:
        """Whether :func:`form` changes anything."""
        return self.enabled and bool(
            self.pipe_model
            or self.flare > 1
            or self.curved
            or any(self.angle_variation)
            or any(self.length_variation)
            or self.phyllotaxis != "none"
            or self.branch_collar > 1
        )

    @property
    def seeded(self) -> tuple[str, ...]:
        """The settings that make the form depend on the seed."""
        if not self.enabled:
            return ()
        names = ("gnarl", "angle_variation", "length_variation")
        return tuple(n for n in names if any(np.atleast_1d(getattr(self, n))))

    @classmethod
    def from_grammar(cls, grammar: Grammar, options: FormOptions | None = None) -> FormOptions:
        """The form of a grammar: its ``[form]`` table, with the fields ``options`` sets away from the defaults over it.

        A field of ``options`` (``GenerateOptions.form``: the CLI's flags,
        :func:`~lsys3d.generate`'s keywords) that differs from its default wins
        over the table; ``options.enabled`` off (``--no-form``) turns the whole
        stage off.

        Raises
        ------
        GrammarError
            An unknown key or a bad value in ``[form]``, at the key's line and column.

        Examples
        --------
        >>> g = Grammar.from_text('axiom = "F"\\n[form]\\npipe_model = true\\nflare = 1.5\\n')
        >>> f = FormOptions.from_grammar(g)
        >>> f.pipe_model, f.flare, FormOptions.from_grammar(g, FormOptions(flare=2.0)).flare
        (True, 1.5, 2.0)
        """
        options = options if options is not None else cls()
        if not options.enabled:
            return options
        table = getattr(grammar, "form", {})
        error = partial(table_error, grammar, "form")
        return merge_table(cls, table, options, error, keys=GRAMMAR_KEYS, as_tuple=_PER_ORDER)


_PER_ORDER = ("gravitropism", "angle_variation", "length_variation")
_SPECS = {f.name: spec_of(f) for f in fields(FormOptions)}

GRAMMAR_KEYS: frozenset[str] = frozenset(_SPECS) - {"enabled"}
"""The keys a grammar's ``[form]`` table accepts."""


def options_markdown() -> str:
    """The ``[form]`` keys as a Markdown table (in ``docs/form.md``; the tests check it)."""
    rows = ["| Key | Default | Meaning |", "|---|---|---|"]
    defaults = FormOptions()
    for f in fields(FormOptions):
        if f.name not in GRAMMAR_KEYS:
            continue
        value = getattr(defaults, f.name)
        if isinstance(value, bool):
            shown = f"`{str(value).lower()}`"
        elif isinstance(value, str):
            shown = f'`"{value}"`'
        else:
            shown = f"`{list(value)}`" if isinstance(value, tuple) else f"`{value}`"
        spec = _SPECS[f.name]
        rng = spec.range_text() if spec.low is not None or spec.high is not None else ""
        rows.append(f"| `{f.name}` | {shown} | {spec.help}" + (f" ({rng})" if rng else "") + " |")
    return "\n".join(rows) + "\n"


def _phyllotaxis_ok(value: str) -> bool:
    if value in PHYLLOTAXIS[:-1]:
        return True
    m = _WHORL.match(value)
    return m is not None and 2 <= int(m.group(1)) <= 16


def _per_order(values: tuple, order: np.ndarray, shift: int = 0) -> np.ndarray:
    """``values[order - shift]`` with the last entry for higher orders (zeros when ``values`` is empty)."""
    if not values:
        return np.zeros(len(order))
    table = np.asarray(values, np.float64)
    return table[np.clip(order.astype(np.int64) - shift, 0, len(table) - 1)]


# ------------------------------------------------------------------ tree walks (parents come before children)
@kernel(nogil=True)
def _tip_counts(parent):  # pragma: no cover - compiled
    n = len(parent)
    children = np.empty(n, np.int64)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    children[:] = 0
    for i in range(n):
        if parent[i] >= 0:
            children[parent[i]] += 1
    count = np.empty(n, np.int64)
    count[:] = 0
    for i in range(n - 1, -1, -1):
        if children[i] == 0:
            count[i] += 1
        if parent[i] >= 0:
            count[parent[i]] += count[i]
    return count


def tip_counts(parent: np.ndarray) -> np.ndarray:
    """How many terminal segments (segments without children) each segment carries, itself included.

    ``parent : (n,) int64`` with ``parent[s] < s``; returns ``(n,) int64``.

    >>> tip_counts(np.array([-1, 0, 1, 1, 0])).tolist()
    [3, 2, 1, 1, 1]
    """
    return _tip_counts(np.ascontiguousarray(parent, np.int64))


def pipe_widths(parent: np.ndarray, tip_width: float, exponent: float) -> np.ndarray:
    """Pipe-model diameters: ``tip_width * tips ** (1 / exponent)`` (:func:`tip_counts`), ``(n,) float64``.

    At a fork the parent's ``d ** exponent``
    is the sum of its children's:

    >>> d = pipe_widths(np.array([-1, 0, 0]), 0.01, 2.0)
    >>> bool(np.isclose(d[0] ** 2, d[1] ** 2 + d[2] ** 2))
    True
    """
    return tip_width * tip_counts(parent).astype(np.float64) ** (1.0 / exponent)


@kernel(nogil=True)
def _along(parent, length, same):  # pragma: no cover - compiled
    """Distance from each segment's start to the base of its run of ``same`` segments (a parent not ``same``: 0)."""
    n = len(parent)
    out = np.empty(n)  # (np.empty and a fill: see lsys3d.arrays.row_table)
    out[:] = 0.0
    for i in range(n):
        p = parent[i]
        if p >= 0 and same[i] and same[p]:
            out[i] = out[p] + length[p]
    return out


@kernel(nogil=True)
def _rotation(wx, wy, wz, r):  # pragma: no cover - compiled
    """The rotation matrix of the rotation vector ``w`` (Rodrigues), into ``r``."""
    angle = math.sqrt(wx * wx + wy * wy + wz * wz)
    if angle < 1e-15:
        for a in range(3):
            for b in range(3):
                r[a, b] = 1.0 if a == b else 0.0
        return
    x, y, z = wx / angle, wy / angle, wz / angle
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    r[0, 0], r[0, 1], r[0, 2] = c + x * x * t, x * y * t - z * s, x * z * t + y * s
    r[1, 0], r[1, 1], r[1, 2] = y * x * t + z * s, c + y * y * t, y * z * t - x * s
    r[2, 0], r[2, 1], r[2, 2] = z * x * t - y * s, z * y * t + x * s, c + z * z * t


@inner(nogil=True)
def _toward(hx, hy, hz, tx, ty, tz, rate, w):  # pragma: no cover - compiled
    """Add to rotation vector ``w`` the turn of heading ``h`` toward ``t`` by ``rate`` radians (no overshoot)."""
    if rate < 0:
        tx, ty, tz, rate = -tx, -ty, -tz, -rate
    cx, cy, cz = hy * tz - hz * ty, hz * tx - hx * tz, hx * ty - hy * tx
    sn = math.sqrt(cx * cx + cy * cy + cz * cz)
    if sn < 1e-12 or rate == 0.0:
        return
    angle = min(rate * sn, math.atan2(sn, hx * tx + hy * ty + hz * tz))
    w[0] += cx / sn * angle
    w[1] += cy / sn * angle
    w[2] += cz / sn * angle


@inner(nogil=True)
def _matvec(m, v, out):  # pragma: no cover - compiled
    for a in range(3):
        out[a] = m[a, 0] * v[0] + m[a, 1] * v[1] + m[a, 2] * v[2]


@inner(nogil=True)
def _matmul(a, b, out):  # pragma: no cover - compiled
    """``out = a @ b`` for 3x3 matrices (``out`` may not be ``a`` or ``b``)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@inner(nogil=True)
def _copy3(a, out):  # pragma: no cover - compiled
    """``out[:, :] = a`` for 3x3 matrices, as a loop (numba compiles a slice assignment much more slowly)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, j]


@kernel(nogil=True)
def _place(
    seg, ppiece, t0, t1, offset, start, vec, heading, left, up, turn, scale, noise, grav, plagio, photo, light
):  # pragma: no cover - compiled
    """Forward kinematics over the pieces, in order: each piece's rotation and scale, start and end.

    A piece's rotation is its parent piece's, then (first piece of a segment) the
    segment's own turn ``turn[s]``, then its bend: the noise about its left and
    up axes and the tropisms, computed from the heading it has by then.
    """
    n = len(seg)
    q = np.empty((n, 3, 3))  # (np.empty and a fill: see lsys3d.arrays.row_table)
    q[:] = 0.0
    sc = np.empty(n)
    sc[:] = 1.0
    p0 = np.empty((n, 3))
    p1 = np.empty((n, 3))
    cur = np.empty((3, 3))
    tmp = np.empty((3, 3))
    bend = np.empty((3, 3))
    w = np.empty(3)
    w[:] = 0.0
    h = np.empty(3)
    lv = np.empty(3)
    uv = np.empty(3)
    d = np.empty(3)
    for i in range(n):
        s = seg[i]
        p = ppiece[i]
        first = i == 0 or seg[i - 1] != s
        if p >= 0:
            for a in range(3):
                for b in range(3):
                    cur[a, b] = q[p, a, b]
            k = sc[p]
            for a in range(3):
                p0[i, a] = p1[p, a] + k * (
                    cur[a, 0] * offset[i, 0] + cur[a, 1] * offset[i, 1] + cur[a, 2] * offset[i, 2]
                )
        else:
            for a in range(3):
                for b in range(3):
                    cur[a, b] = 1.0 if a == b else 0.0
            k = 1.0
            for a in range(3):
                p0[i, a] = start[s, a]
        if first:
            _matmul(cur, turn[s], tmp)
            _copy3(tmp, cur)
            k *= scale[s]
        length = k * (t1[i] - t0[i]) * math.sqrt(vec[s, 0] ** 2 + vec[s, 1] ** 2 + vec[s, 2] ** 2)
        _matvec(cur, heading[s], h)
        w[0] = w[1] = w[2] = 0.0
        if noise[i, 0] != 0.0 or noise[i, 1] != 0.0:
            _matvec(cur, left[s], lv)
            _matvec(cur, up[s], uv)
            for a in range(3):
                w[a] += (noise[i, 0] * lv[a] + noise[i, 1] * uv[a]) * length
        if grav[i] != 0.0:
            _toward(h[0], h[1], h[2], 0.0, 1.0, 0.0, grav[i] * length, w)
        if photo != 0.0:
            _toward(h[0], h[1], h[2], light[0], light[1], light[2], photo * length, w)
        if plagio[i] != 0.0:
            horizontal = math.sqrt(h[0] * h[0] + h[2] * h[2])
            if horizontal > 1e-12:
                _toward(h[0], h[1], h[2], h[0] / horizontal, 0.0, h[2] / horizontal, plagio[i] * length, w)
        _rotation(w[0], w[1], w[2], bend)
        _matmul(bend, cur, tmp)
        _copy3(tmp, cur)
        for a in range(3):
            for b in range(3):
                q[i, a, b] = cur[a, b]
        sc[i] = k
        _matvec(cur, vec[s], d)
        for a in range(3):
            p1[i, a] = p0[i, a] + d[a] * k * (t1[i] - t0[i])
    return q, sc, p0, p1


def _axis_rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotations by ``angle`` radians about unit ``axis`` (Rodrigues, vectorised)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    return np.stack(
        [
            np.stack([c + x * x * t, x * y * t - z * s, x * z * t + y * s], -1),
            np.stack([y * x * t + z * s, c + y * y * t, y * z * t - x * s], -1),
            np.stack([z * x * t - y * s, z * y * t + x * s, c + z * z * t], -1),
        ],
        1,
    )


def _laterals(skeleton: Skeleton) -> np.ndarray:
    """Segments of higher order than their parent (the bases of the lateral branches), ascending."""
    p = skeleton.parent
    has = np.flatnonzero(p >= 0)
    return has[skeleton.order[has] > skeleton.order[p[has]]]


def _azimuth_targets(skeleton: Skeleton, lateral: np.ndarray, pattern: str) -> tuple[np.ndarray, np.ndarray]:
    """For each lateral, the unit axis it rolls about (its parent's heading) and the roll in radians."""
    parent = skeleton.parent[lateral]
    hp = unit(skeleton.heading[parent])
    hc = skeleton.heading[lateral]
    chain = skeleton.chains.chain_of[parent]
    # the reference direction of an axis: its base segment's left, made perpendicular to each parent segment
    base = skeleton.chains.segments[skeleton.chains.offsets[chain]]
    ref = skeleton.left[base] - dot(skeleton.left[base], hp)[:, None] * hp
    weak = np.linalg.norm(ref, axis=1) < 1e-6
    alt = skeleton.up[base] - dot(skeleton.up[base], hp)[:, None] * hp
    ref = unit(np.where(weak[:, None], alt, ref))
    side = np.cross(hp, ref)
    v = hc - dot(hc, hp)[:, None] * hp
    defined = np.linalg.norm(v, axis=1) > 1e-9
    azimuth = np.arctan2(dot(v, side), dot(v, ref))
    # rank of each lateral along its axis (laterals ascend: the drawing order is the order along the axis)
    by_axis = np.lexsort((lateral, chain))
    chain_s, parent_s = chain[by_axis], parent[by_axis]
    new_axis = np.ones(len(lateral), bool)
    new_axis[1:] = chain_s[1:] != chain_s[:-1]
    new_node = new_axis.copy()
    new_node[1:] |= parent_s[1:] != parent_s[:-1]
    axis_id = np.cumsum(new_axis) - 1
    node_id = np.cumsum(new_node) - 1
    k = local_index(np.bincount(axis_id))  # rank of the lateral on its axis
    node_first = np.flatnonzero(new_node)
    node_rank = local_index(np.bincount(axis_id[node_first]))[node_id]  # rank of its node on the axis
    r = local_index(np.bincount(node_id))  # rank inside its node
    if pattern == "golden":
        div = k * GOLDEN_ANGLE
    elif pattern == "distichous":
        div = k * 180.0
    elif pattern == "opposite":
        div = r * 180.0
    elif pattern == "decussate":
        div = node_rank * 90.0 + r * 180.0
    else:
        count = int(_WHORL.match(pattern).group(1))
        div = node_rank * (180.0 / count) + r * (360.0 / count)
    target = np.empty(len(lateral))
    first_az = azimuth[by_axis][np.flatnonzero(new_axis)][axis_id]
    target[by_axis] = first_az + np.radians(div)
    roll = np.where(defined, target - azimuth, 0.0)
    roll = (roll + np.pi) % (2 * np.pi) - np.pi
    return hp, roll


def _turns(skeleton: Skeleton, options: FormOptions, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Each segment's own turn about its start ``(n, 3, 3)`` and length scale ``(n,)``: phyllotaxis and variation."""
    n = len(skeleton)
    turn = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    scale = np.ones(n)
    lateral = _laterals(skeleton)
    if not len(lateral):
        return turn, scale
    hc = skeleton.heading[lateral]
    if options.phyllotaxis != "none":
        axis, roll = _azimuth_targets(skeleton, lateral, options.phyllotaxis)
        turn[lateral] = _axis_rotations(axis, roll)
        hc = np.einsum("nij,nj->ni", turn[lateral], hc)
    av = _per_order(options.angle_variation, skeleton.order[lateral], 1)
    lv = _per_order(options.length_variation, skeleton.order[lateral], 1)
    if av.any() or lv.any():
        u = generator(seed, Stream.FORM_VARIATION).uniform(-1.0, 1.0, (n, 2))[lateral]
        hp = unit(skeleton.heading[skeleton.parent[lateral]])
        plane = np.cross(hp, hc)
        sin = np.linalg.norm(plane, axis=1)
        angle = np.arctan2(sin, dot(hp, hc))
        change = np.radians(av) * u[:, 0]
        change = np.clip(angle + change, 0.0, np.pi) - angle  # stays a branching angle in [0, 180]
        change = np.where(sin > 1e-9, change, 0.0)
        vary = _axis_rotations(unit(plane), change)
        turn[lateral] = np.einsum("nij,njk->nik", vary, turn[lateral])
        scale[lateral] = 1.0 + lv * u[:, 1]
    return turn, scale


def _cuts(skeleton: Skeleton, options: FormOptions, length: np.ndarray, base_width: np.ndarray):
    """Where the segments are split: ``(segment, t)`` of every cut, sorted, ``t`` in (0, 1)."""
    n = len(skeleton)
    seg_parts, t_parts = [], []
    if options.curved:
        m = np.clip(np.ceil(length / options.max_substep_length), 1, options.substeps).astype(np.int64)
        s = np.repeat(np.arange(n), m - 1)
        seg_parts.append(s)
        t_parts.append((local_index(m - 1) + 1) / m[s])
    if options.flare > 1:
        trunk = skeleton.order == 0
        h0 = _along(skeleton.parent, length, trunk)
        step = options.flare_height / 8.0
        rows = np.flatnonzero(trunk & (h0 < options.flare_height) & (length > 0))
        first = np.floor(h0[rows] / step).astype(np.int64) + 1  # the first curve sample past each start
        last = np.minimum(np.ceil(np.minimum(h0[rows] + length[rows], options.flare_height) / step), 8).astype(np.int64)
        count = np.maximum(last - first + 1, 0)
        s = np.repeat(rows, count)
        at = (np.repeat(first, count) + local_index(count)) * step
        seg_parts.append(s)
        t_parts.append((at - h0[s]) / length[s])
    if options.branch_collar > 1:
        lateral = _laterals(skeleton)
        t = options.branch_collar_length * base_width[lateral] / np.maximum(length[lateral], 1e-300)
        keep = t < 0.5
        seg_parts.append(lateral[keep])
        t_parts.append(t[keep])
    if not seg_parts:
        return np.zeros(0, np.int64), np.zeros(0)
    s = np.concatenate(seg_parts)
    t = np.concatenate(t_parts)
    ok = (t > 1e-6) & (t < 1 - 1e-6)
    s, t = s[ok], t[ok]
    key = np.lexsort((t, s))
    s, t = s[key], t[key]
    keep = np.ones(len(s), bool)
    keep[1:] = (s[1:] != s[:-1]) | (t[1:] - t[:-1] > 1e-6)
    s, t = s[keep], t[keep]
    # at most _MAX_PIECES pieces a segment
    keep = local_index(np.bincount(s, minlength=n)) < _MAX_PIECES - 1
    return s[keep], t[keep]


def form(
    skeleton: Skeleton, options: FormOptions, seed: int = 0, *, max_segments: int = DEFAULT_MAX_SEGMENTS
) -> Skeleton:
    """The skeleton reshaped by ``options`` (see the module's description); the same skeleton when nothing is on.

    Parameters
    ----------
    skeleton : Skeleton
        As the turtle drew it (``parent[s] < s``).
    options : FormOptions
    seed : int
        Seed of the noise and the variation.
    max_segments : int
        Most segments the reshaped skeleton may have (:class:`~lsys3d.errors.LimitError` before the
        memory is taken): the turtle's limit, ``Limits.max_segments``.

    Returns
    -------
    Skeleton
        Segments split into pieces (each piece keeps its segment's order,
        material and module), moved, turned and widened; leaf instances,
        leaf polygons and organs carried along with their segments.

    Examples
    --------
    >>> sk = Skeleton.from_segments([[0, 0, 0], [0, 1, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0], [1, 2, 0]],
    ...                             parent=[-1, 0, 0], order=[0, 0, 1])
    >>> out = form(sk, FormOptions(pipe_model=True, tip_width=0.01))
    >>> out.width_start.round(4).tolist()
    [0.0141, 0.01, 0.01]
    """
    if not options.active or len(skeleton) == 0:
        return skeleton
    n = len(skeleton)
    vec = skeleton.end - skeleton.start
    length = np.linalg.norm(vec, axis=1)
    parent = skeleton.parent
    if options.pipe_model:
        base_width = pipe_widths(parent, options.tip_width, options.pipe_exponent)
        width0, width1 = base_width, base_width
    else:
        width0, width1 = skeleton.width_start, skeleton.width_end
        base_width = width0
    turn, scale = _turns(skeleton, options, seed)
    cut_seg, cut_t = _cuts(skeleton, options, length, base_width)

    if n + len(cut_seg) > max_segments:
        raise LimitError(
            f"form: the curvature, flare and collars would split the {n:,} segments into {n + len(cut_seg):,}, "
            f"more than the limit of {max_segments:,}; raise max_substep_length or lower substeps, or raise the "
            "limit (--max-segments, or max_segments=)"
        )
    # ---- pieces: segment s becomes pieces first[s] .. first[s] + count[s] - 1, in order
    count = 1 + np.bincount(cut_seg, minlength=n)
    first = np.zeros(n + 1, np.int64)
    np.cumsum(count, out=first[1:])
    total = int(first[-1])
    seg = np.repeat(np.arange(n), count)
    t0 = np.zeros(total)
    t1 = np.ones(total)
    rank = local_index(np.bincount(cut_seg, minlength=n))
    t1[first[cut_seg] + rank] = cut_t
    t0[first[cut_seg] + rank + 1] = cut_t
    last = first[1:] - 1
    is_first = np.zeros(total, bool)
    is_first[first[:-1]] = True
    ppiece = np.arange(total, dtype=np.int64) - 1
    ppiece[first[:-1]] = np.where(parent >= 0, last[np.maximum(parent, 0)], -1)
    offset = np.zeros((total, 3))
    has = parent >= 0
    offset[first[:-1][has]] = skeleton.start[has] - skeleton.end[parent[has]]

    # ---- curvature: noise per piece along each chain of the drawn skeleton
    noise = np.zeros((total, 2))
    grav = np.zeros(total)
    plagio = np.zeros(total)
    if options.curved:
        order = skeleton.order[seg]
        grav = np.radians(_per_order(options.gravitropism, order))
        plagio = np.where(order > 0, math.radians(options.plagiotropism), 0.0)
        if options.gnarl > 0:
            chains = skeleton.chains
            arc = np.zeros(n)
            lengths = length[chains.segments]
            cum = np.cumsum(lengths) - lengths
            arc[chains.segments] = cum - np.repeat(cum[chains.offsets[:-1]], chains.lengths())
            along = arc[seg] + 0.5 * (t0 + t1) * length[seg]
            points = np.stack(
                [along * options.gnarl_frequency, chains.chain_of[seg] * 2.173 + 0.37, np.full(total, 0.61)], 1
            )
            rate = math.radians(options.gnarl)
            for k in range(2):
                noise[:, k] = rate * fbm3(points, seed=(int(seed), int(Stream.FORM_GNARL), k), octaves=3)
    light = unit(np.asarray(options.phototropism_light, np.float64)[None])[0]
    q, piece_scale, p0, p1 = _place(
        seg,
        ppiece,
        t0,
        t1,
        offset,
        skeleton.start,
        vec,
        skeleton.heading,
        skeleton.left,
        skeleton.up,
        turn,
        scale,
        noise,
        grav,
        plagio,
        math.radians(options.phototropism),
        light,
    )
    heading = unit(np.einsum("nij,nj->ni", q, skeleton.heading[seg]))
    left = np.einsum("nij,nj->ni", q, skeleton.left[seg])
    left = unit(left - dot(left, heading)[:, None] * heading)
    up = np.cross(heading, left)

    # ---- widths
    w0 = width0[seg] + (width1[seg] - width0[seg]) * t0
    w1 = width0[seg] + (width1[seg] - width0[seg]) * t1
    if options.flare > 1:
        trunk = skeleton.order[seg] == 0
        piece_len = np.linalg.norm(p1 - p0, axis=1)
        h0 = _along(ppiece, piece_len, trunk)

        def flare(h):
            x = np.clip(1.0 - h / options.flare_height, 0.0, 1.0)
            return np.where(trunk, 1.0 + (options.flare - 1.0) * x**3, 1.0)

        w0 = w0 * flare(h0)
        w1 = w1 * flare(h0 + piece_len)
    if options.branch_collar > 1:
        lateral = _laterals(skeleton)
        w0[first[lateral]] *= options.branch_collar
    if options.pipe_model or options.flare > 1 or options.branch_collar > 1:
        child = np.flatnonzero(is_first & (ppiece >= 0))
        w0[child] = np.minimum(w0[child], w1[ppiece[child]])  # no child starts wider than its parent ends

    # ---- leaves, polygons and organs ride on the last piece of their segment
    def carried(segment, points, *frames):
        if segment is None or not len(segment):
            return segment, points, frames
        at = np.flatnonzero(segment >= 0)
        piece = last[segment[at]]
        points = points.copy()
        points[at] = p1[piece] + piece_scale[piece][:, None] * np.einsum(
            "nij,nj->ni", q[piece], points[at] - skeleton.end[segment[at]]
        )
        moved = []
        for f in frames:
            f = f.copy()
            f[at] = np.einsum("nij,nj->ni", q[piece], f[at])
            moved.append(f)
        return np.where(segment >= 0, last[np.maximum(segment, 0)], -1), points, moved

    leaf_segment, leaf_position, (leaf_heading, leaf_left, leaf_up) = carried(
        skeleton.leaf_segment, skeleton.leaf_position, skeleton.leaf_heading, skeleton.leaf_left, skeleton.leaf_up
    )
    organ_segment, organ_position, (organ_heading, organ_left, organ_up) = carried(
        skeleton.organ_segment, skeleton.organ_position, skeleton.organ_heading, skeleton.organ_left, skeleton.organ_up
    )
    polygon_segment, polygon_points = skeleton.polygon_segment, skeleton.polygon_points
    if polygon_segment is not None and len(polygon_segment):
        per_point = np.repeat(polygon_segment, np.diff(skeleton.polygon_offsets))
        _, polygon_points, _ = carried(per_point, polygon_points)
        polygon_segment = np.where(polygon_segment >= 0, last[np.maximum(polygon_segment, 0)], -1)
    return replace(
        skeleton,
        start=p0,
        end=p1,
        width_start=w0,
        width_end=w1,
        heading=heading,
        left=left,
        up=up,
        parent=ppiece,
        order=skeleton.order[seg],
        material=skeleton.material[seg],
        module=skeleton.module[seg],
        sides=None if skeleton.sides is None else skeleton.sides[seg],
        polygon_points=polygon_points,
        leaf_position=leaf_position,
        leaf_heading=leaf_heading,
        leaf_left=leaf_left,
        leaf_up=leaf_up,
        polygon_segment=polygon_segment,
        leaf_segment=leaf_segment,
        organ_position=organ_position,
        organ_heading=organ_heading,
        organ_left=organ_left,
        organ_up=organ_up,
        organ_segment=organ_segment,
    )
