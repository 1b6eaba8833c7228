"""Botanical measures of a drawn skeleton: the pipe model at forks, width along chains, flare, curvature, seeds.

One home for the measures that ``benchmarks/bench_botany.py`` prints and the tests assert
(``tests/test_species.py``, ``tests/test_form.py``): each takes the
:class:`~lsys3d.turtle.skeleton.Skeleton` the sweep receives (after the form stage) and returns plain
numbers.  :data:`GOALS` states the botany goals of issue 33 and :func:`measure` / :func:`verdicts` apply them
to one plant.

Where a fork is measured: when the form stage swelled the laterals' bases (``[form]
branch_collar``, given as ``collar``), a lateral's first piece (its collar) is taken at its end, where
the collar has faded into the branch's own width and the branch leaves its parent's surface; the
collar's swelling, up to ``branch_collar ** 2`` in area, is the parent's wood around the branch's base,
not a wider branch.  The raw ratio at the children's very start is reported too (``raw_area_median``).
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass

import numpy as np

from .skeleton import Skeleton

__all__ = [
    "BROADLEAVES",
    "GOALS",
    "SKY_LEAVED",
    "TREES",
    "BotanyMeasures",
    "branch_base_width",
    "chain_growth",
    "digest",
    "fork_ratios",
    "measure",
    "sky_share",
    "straight_chains",
    "trunk_flare",
    "verdicts",
]

TREES = frozenset({"oak", "maple", "birch", "weeping-willow", "aspen", "beech", "pine", "spruce", "palm"})
"""The species with a trunk, whose flare is a goal."""

BROADLEAVES = frozenset({"oak", "maple", "birch", "weeping-willow", "aspen", "beech", "hazel", "ivy"})
"""The broadleaf (woody dicot) species, whose chains must bend."""

SKY_LEAVED = BROADLEAVES - {"ivy"}
"""The broadleaf species whose blades must face the sky: the ivy's face its light in front of the wall it
climbs (``+z``), not the sky."""

GOALS = {
    "pipe": "at least 90% of forks have children/parent area within 0.8-1.25",
    "child": "no child starts more than 5% wider than its parent ends",
    "growth": "along a chain the width never grows by more than 2%",
    "flare": "a tree's trunk is at least 1.3x as wide at the ground as at 10% of its height",
    "curved": "no chain of 5 or more segments is straight in a broadleaf species",
    "seeds": "5 seeds give 5 different skeletons",
    "leaves": "at least 70% of a broadleaf species' blades (leaves or leaf cards, as the leaf stage turns them) "
    "face within 60 degrees of the sky (not the ivy: its blades face the light in front of its wall)",
}
"""The botany goals of issue 33, by the names :func:`verdicts` gives them."""


def branch_base_width(sk: Skeleton, collar: float = 1.0) -> np.ndarray:
    """Each segment's diameter where it leaves its parent, ``(n,) float64``.

    A segment's start width; with ``collar > 1`` (the form's ``branch_collar``, which swells the first piece
    of every lateral -- a segment of higher order than its parent -- and tapers it to the branch's own width)
    a lateral's end width, where the collar has faded out.
    """
    w = sk.width_start.copy()
    if collar > 1:
        child = np.flatnonzero(sk.parent >= 0)
        lateral = child[sk.order[child] > sk.order[sk.parent[child]]]
        w[lateral] = sk.width_end[lateral]
    return w


def fork_ratios(sk: Skeleton, collar: float = 1.0) -> tuple[int, np.ndarray, float]:
    """Number of forks, each fork's children/parent area ratio, and the largest child-start / parent-end width.

    A fork is a segment with two children or more; its ratio is the sum of its children's ``d ** 2`` where
    they leave it (:func:`branch_base_width`: past their collars when ``collar > 1``) over its own ``d ** 2``
    at its end.  The largest child/parent width is always taken at the children's very start.

    Examples
    --------
    >>> sk = Skeleton.from_segments([[0, 0, 0], [0, 1, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0], [1, 2, 0]],
    ...                             width_start=[0.02, 0.01, 0.01], parent=[-1, 0, 0], order=[0, 0, 1])
    >>> forks, ratios, widest = fork_ratios(sk)
    >>> forks, ratios.round(3).tolist(), widest
    (1, [0.5], 0.5)
    """
    child = np.flatnonzero(sk.parent >= 0)
    parent = sk.parent[child]
    counts = np.bincount(parent, minlength=len(sk))
    fork = counts >= 2
    base = branch_base_width(sk, collar)
    area = np.bincount(parent, weights=base[child] ** 2, minlength=len(sk))
    ratios = area[fork] / np.maximum(sk.width_end[fork] ** 2, 1e-300)
    widest = float((sk.width_start[child] / np.maximum(sk.width_end[parent], 1e-300)).max()) if len(child) else 0.0
    return int(fork.sum()), ratios, widest


def chain_growth(sk: Skeleton) -> float:
    """The largest width ratio toward the tip along any chain: inside segments and across their joints."""
    inside = sk.width_end / np.maximum(sk.width_start, 1e-300)
    ch = sk.chains
    seg = ch.segments
    same = ch.chain_of[seg[1:]] == ch.chain_of[seg[:-1]]
    joint = sk.width_start[seg[1:]][same] / np.maximum(sk.width_end[seg[:-1]][same], 1e-300)
    return float(max(inside.max(initial=0.0), joint.max(initial=0.0)))


def trunk_flare(sk: Skeleton) -> float:
    """Trunk diameter at the ground over its diameter at 10% of the plant's height (nan without a trunk there)."""
    trunk = np.flatnonzero(sk.order == 0)
    if not len(trunk):
        return float("nan")
    low, high = sk.bounds()[:, 1]
    base = trunk[np.argmin(sk.start[trunk, 1])]
    y = low + 0.1 * (high - low)
    y0, y1 = sk.start[trunk, 1], sk.end[trunk, 1]
    spans = np.flatnonzero((np.minimum(y0, y1) <= y) & (np.maximum(y0, y1) >= y) & (y1 != y0))
    if not len(spans):
        return float("nan")
    s = trunk[spans[0]]
    t = (y - sk.start[s, 1]) / (sk.end[s, 1] - sk.start[s, 1])
    at = sk.width_start[s] + t * (sk.width_end[s] - sk.width_start[s])
    return float(sk.width_start[base] / at)


def straight_chains(sk: Skeleton, min_segments: int = 5, degrees: float = 0.5) -> int:
    """Chains of at least ``min_segments`` segments whose headings all lie within ``degrees`` of the first one."""
    ch = sk.chains
    long = np.flatnonzero(ch.lengths() >= min_segments)
    if not len(long):
        return 0
    seg = ch.segments
    first = np.repeat(seg[ch.offsets[long]], ch.lengths()[long])
    members = np.concatenate([seg[ch.offsets[c] : ch.offsets[c + 1]] for c in long])
    cos = np.einsum("ij,ij->i", sk.heading[members], sk.heading[first])
    bent = cos < np.cos(np.radians(degrees))
    which = np.repeat(np.arange(len(long)), ch.lengths()[long])
    return int(len(long) - np.unique(which[bent]).size)


def sky_share(sk: Skeleton, degrees: float = 60.0) -> float:
    """Percent of leaves whose blade normal is within ``degrees`` of +Y (nan without leaves)."""
    normals = [sk.leaf_up]
    if sk.n_polygons:
        pts, off = sk.polygon_points, sk.polygon_offsets
        poly = np.repeat(np.arange(sk.n_polygons), np.diff(off))
        nxt = np.arange(len(pts)) + 1
        nxt[off[1:] - 1] = off[:-1]
        newell = np.zeros((sk.n_polygons, 3))
        np.add.at(newell, poly, np.cross(pts, pts[nxt]))
        normals.append(newell / np.maximum(np.linalg.norm(newell, axis=1, keepdims=True), 1e-300))
    n = np.concatenate(normals)
    if not len(n):
        return float("nan")
    return float(100.0 * np.mean(n[:, 1] >= np.cos(np.radians(degrees))))


def digest(sk: Skeleton) -> str:
    """A hash of the skeleton's geometry and widths and its leaves' places: equal for equal plants."""
    h = hashlib.sha256()
    for a in (sk.start, sk.end, sk.width_start, sk.width_end, sk.leaf_position):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class BotanyMeasures:
    """The botany measures of one plant (see the functions of the same names)."""

    segments: int
    forks: int
    area_median: float
    """median children/parent area ratio, children measured past their collars"""
    raw_area_median: float
    """the same, children measured at their very start (collar included)"""
    within: float
    """percent of forks whose ratio (past the collars) lies within 0.8-1.25"""
    child_parent: float
    growth: float
    flare: float
    trunk_base_diameter: float
    straight5: int
    sky: float
    seeds: int
    """distinct skeletons among the seeds measured (0 when not measured)"""

    def to_json(self) -> dict:
        return asdict(self)


def measure(
    sk: Skeleton, seeds: list[Skeleton] = (), collar: float = 1.0, blades: Skeleton | None = None
) -> BotanyMeasures:
    """The measures of ``sk`` (forks past collars of ``collar``), and how many of the skeletons ``seeds`` differ.

    ``blades``: the skeleton whose leaf instances are the blades as the leaf stage places them
    (:func:`lsys3d.look.leaf_form.arrange`: clustered, turned to the light, cards); ``sky`` is measured on
    them, or on ``sk``'s own leaves (the turtle's frames) without it.
    """
    forks, ratios, widest = fork_ratios(sk, collar)
    raw = fork_ratios(sk)[1]
    trunk = np.flatnonzero(sk.order == 0)
    base = float(sk.width_start[trunk[np.argmin(sk.start[trunk, 1])]]) if len(trunk) else float("nan")
    return BotanyMeasures(
        segments=len(sk),
        forks=forks,
        area_median=float(np.median(ratios)) if len(ratios) else float("nan"),
        raw_area_median=float(np.median(raw)) if len(raw) else float("nan"),
        within=float(100.0 * np.mean((ratios >= 0.8) & (ratios <= 1.25))) if len(ratios) else float("nan"),
        child_parent=widest,
        growth=chain_growth(sk),
        flare=trunk_flare(sk),
        trunk_base_diameter=base,
        straight5=straight_chains(sk),
        sky=sky_share(sk if blades is None else blades),
        seeds=len({digest(s) for s in seeds}),
    )


def verdicts(name: str, m: BotanyMeasures, n_seeds: int = 5) -> dict[str, bool | None]:
    """Each goal of :data:`GOALS` passed (True), failed (False) or not applicable to ``name`` (None)."""
    return {
        "pipe": bool(m.forks == 0 or m.within >= 90.0),
        "child": bool(m.child_parent <= 1.05),
        "growth": bool(m.growth <= 1.02),
        "flare": bool(m.flare >= 1.3) if name in TREES else None,
        "curved": bool(m.straight5 == 0) if name in BROADLEAVES else None,
        "seeds": bool(m.seeds == n_seeds) if m.seeds else None,
        "leaves": bool(m.sky >= 70.0) if name in SKY_LEAVED else None,
    }
