"""Leaf form: the built-in blades' outlines, and where and how each leaf of a skeleton sits.

The turtle places one leaf instance per leaf symbol, one step long, in the
turtle's frame.  This module turns those instances into foliage a crown reads
as (all of it off by default, :class:`~lsys3d.look.leaves.LeafOptions`):

* :func:`blade`: the built-in leaf model in one of :data:`SHAPES` (flat,
  triangulated, front facing ``+y``, uv the blade's box on [0, 1]^2), with an
  optional petiole: a narrow strip from the attachment point to the blade's
  base, the blade moved up by it;
* :func:`spray_card`: one quad (or a crossed pair) for a whole cluster, to be
  shown with an alpha-cut texture of a spray of needles or leaves; or
  (``leaf_card = "twigs"``) one quad in the place of each leaf of a cluster,
  showing a twig of many leaves, so a crown of a few thousand clusters carries
  a hundred thousand leaves in two triangles each;
* :func:`arrange`: the leaf instances of a skeleton with a size in metres,
  each grown into a cluster of leaves fanned along the last part of its twig,
  turned toward the light and drooping -- a new skeleton, plain data, that
  :func:`lsys3d.look.leaves.leaves` places the model on.

Random draws come from their own streams (:class:`lsys3d.streams.Stream`
``LEAF_SIZE`` and ``LEAF_CLUSTER``): the same seed gives the same leaves.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..arrays import dot, unit
from ..mesh.mesh import Mesh
from ..streams import Stream, generator
from ..turtle.skeleton import Skeleton

__all__ = [
    "CARDS",
    "PHYLLOTAXIS",
    "SHAPES",
    "arrange",
    "blade",
    "card_aspect",
    "droop",
    "leaf_count",
    "spray_card",
    "toward_light",
]

SHAPES = ("default", "ovate", "lanceolate", "lobed", "palmate", "needle", "blade")
"""The built-in blade outlines (``LeafOptions.leaf_shape``): ``default`` is the original pointed oval."""

CARDS = ("none", "spray", "cross", "twigs")
"""``LeafOptions.leaf_card``: single leaves, one quad per cluster, two crossed quads per cluster, or a quad per
leaf of a cluster (each showing a leafy twig, ``card_length`` leaves long)."""

PHYLLOTAXIS = ("spiral", "alternate", "opposite")
"""How the leaves of a cluster turn around their twig: by the golden angle, by half a turn, or in pairs a
quarter turn apart (``LeafOptions.cluster_phyllotaxis``)."""

PETIOLE_HALF_WIDTH = 0.012
"""Half the width of the petiole strip, in blade lengths (a 10 cm leaf has a 2.4 mm stalk)."""

_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
_DOWN = np.array([0.0, -1.0, 0.0])


# ---------------------------------------------------------------- models


def _rows_blade(z: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A blade of rows (left, midrib, right) at heights ``z`` between a base point at 0 and a tip at 1."""
    points = len(z)
    verts = np.zeros((3 * points + 2, 3))
    verts[1:-1:3, 0] = -half
    verts[3:-1:3, 0] = half
    verts[1:-1, 2] = np.repeat(z, 3)
    verts[-1, 2] = 1.0
    faces = [[0, 1, 2], [0, 2, 3]]
    for i in range(points - 1):
        a, b = 1 + 3 * i, 4 + 3 * i
        faces += [[a, b, b + 1], [a, b + 1, a + 1], [a + 1, b + 1, b + 2], [a + 1, b + 2, a + 2]]
    a, t = 1 + 3 * (points - 1), len(verts) - 1
    faces += [[a, t, a + 1], [a + 1, t, a + 2]]
    return verts, np.array(faces, np.int64)


def _profile(t: np.ndarray, a: float, b: float, width: float) -> np.ndarray:
    """Half-widths ``t^a (1 - t)^b`` scaled so that the blade is ``width`` wide at its widest (t in (0, 1))."""
    h = t**a * (1.0 - t) ** b
    peak = (a / (a + b)) ** a * (b / (a + b)) ** b
    return h * (width / 2 / peak)


def _outline(shape: str, points: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (in the x-z plane) and faces of a blade from the origin to ``z = 1`` (palmate: see below)."""
    if shape == "palmate":
        return _palmate(points)
    if shape == "default":
        z = np.linspace(0.0, 1.0, points + 2)[1:-1]
        half = np.sin(np.pi * z) ** 0.8
        return _rows_blade(z, half * (0.25 / half.max()))
    if shape == "lobed":
        # rows at every eighth of the length fall on the lobes' tips and the sinuses between them
        rows = 8 * max(1, round(points / 3)) - 1
        z = np.linspace(0.0, 1.0, rows + 2)[1:-1]
        sinus = (0.5 + 0.5 * np.cos(2 * np.pi * 4 * z)) ** 1.5  # 1 at the sinuses (z = 1/4, 1/2, 3/4), 0 at the lobes
        return _rows_blade(z, _profile(z, 0.7, 0.5, 0.64) * (1.0 - 0.5 * sinus))
    if shape == "needle":  # a needle is a strip: two rows do
        rows = min(points, 2)
        z = np.linspace(0.0, 1.0, rows + 2)[1:-1]
        return _rows_blade(z, 0.02 * np.minimum(1.0, (1.0 - z) / 0.3))
    z = np.linspace(0.0, 1.0, points + 2)[1:-1]
    if shape == "ovate":
        return _rows_blade(z, _profile(z, 0.6, 1.0, 0.6))
    if shape == "lanceolate":
        return _rows_blade(z, _profile(z, 0.5, 1.2, 0.2))
    if shape == "blade":  # grass: widest near the base, tapering along its length
        return _rows_blade(z, 0.05 * np.minimum(1.0, z / 0.08) ** 0.5 * (1.0 - z) ** 0.7)
    raise ValueError(f"blade: shape must be one of {', '.join(SHAPES)}, not {shape!r}")


def _palmate(points: int) -> tuple[np.ndarray, np.ndarray]:
    """A maple-like blade: five pointed lobes around a centre, a fan of triangles; the petiole's notch at the origin.

    The outline is a radius per direction about the centre (``10 * points`` directions and the lobes' tips);
    the lower lobes reach below the notch, as a maple's do.
    """
    samples = 10 * max(1, points)
    lobes = np.radians([0.0, 60.0, -60.0, 125.0, -125.0])
    length = np.array([1.0, 0.82, 0.82, 0.45, 0.45])
    theta = -np.pi + 2 * np.pi * np.arange(samples) / samples  # from +z (the tip), counter-clockwise seen from +y
    theta = np.unique(np.concatenate([theta, lobes]))  # the lobes' tips are vertices
    sinus = 0.3
    r = np.full(len(theta), sinus)
    for centre, reach in zip(lobes, length, strict=True):
        d = np.abs((theta - centre + np.pi) % (2 * np.pi) - np.pi)  # angular distance to the lobe's axis
        peak = np.clip(1.0 - d / (0.16 * np.pi), 0.0, 1.0) ** 1.2
        r = np.maximum(r, sinus + (reach - sinus) * peak)
    r[np.isclose(np.abs(theta), np.pi)] = 0.6 * sinus  # the notch the petiole comes in at
    samples = len(theta)
    outline = np.stack([r * np.sin(theta), np.zeros(samples), r * np.cos(theta)], axis=1)
    verts = np.concatenate([np.zeros((1, 3)), outline])
    notch = outline[np.argmin(np.abs(np.abs(theta) - np.pi))]
    verts = (verts - notch) / (outline[:, 2].max() - notch[2])  # notch at the origin, top lobe's tip at z = 1
    j = np.arange(samples)
    faces = np.stack([np.zeros(samples, np.int64), 1 + j, 1 + (j + 1) % samples], axis=1)
    return verts, faces


def _flat_mesh(verts: np.ndarray, faces: np.ndarray, uv_of_vertex: np.ndarray) -> Mesh:
    """A flat mesh in the x-z plane, every triangle wound to face ``+y``."""
    tri = verts[faces]
    back = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 1] < 0
    faces = faces.copy()
    faces[back] = faces[back][:, ::-1]
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0], np.float32), (len(faces), 3, 3))
    return Mesh(verts, faces, normals, uv_of_vertex[faces])


def blade(shape: str = "default", points: int = 7, petiole: float = 0.0) -> Mesh:
    """The built-in leaf model: a flat blade of length 1 in the leaf-model convention, with an optional petiole.

    Parameters
    ----------
    shape : str
        One of :data:`SHAPES`: ``default`` (a pointed oval, :func:`lsys3d.look.leaves.default_leaf`), ``ovate``,
        ``lanceolate``, ``lobed`` (oak-like, four lobes a side), ``palmate`` (maple-like, five lobes),
        ``needle`` (a thin strip, at most two rows) or ``blade`` (grass).
    points : int
        The resolution: rows across the blade (``lobed``: a multiple of eight rows near ``2 * points``;
        ``palmate``: ``10 * points + 4`` outline points).
    petiole : float
        Length of the stalk, in blade lengths (0: none).  The stalk is one quad ``2 *``
        :data:`PETIOLE_HALF_WIDTH` wide from the origin to ``z = petiole``; the blade starts where it ends.

    Returns
    -------
    Mesh
        Facing ``+y``, flat corner normals; ``uv`` maps the blade's box onto [0, 1]^2 (the petiole takes a
        thin column at the bottom middle of the image, where a leaf picture's stem is).

    Examples
    --------
    >>> m = blade("ovate", 4, petiole=0.25)
    >>> len(m.faces), m.bounds[:, 2].round(3).tolist()
    (18, [0.0, 1.25])
    >>> from lsys3d.look.leaves import default_leaf
    >>> bool(blade("default").vertices.tolist() == default_leaf().vertices.tolist())
    True
    """
    if points < 1:
        raise ValueError(f"blade: points must be >= 1, got {points}")
    if not petiole >= 0:
        raise ValueError(f"blade: petiole must be >= 0, got {petiole}")
    verts, faces = _outline(shape, points)
    lo, hi = verts[:, [0, 2]].min(axis=0), verts[:, [0, 2]].max(axis=0)
    uv = (verts[:, [0, 2]] - lo) / (hi - lo)
    if petiole > 0:
        w = PETIOLE_HALF_WIDTH
        stalk = np.array([[-w, 0, 0], [w, 0, 0], [w, 0, petiole], [-w, 0, petiole]])
        du = w / (hi[0] - lo[0])
        stalk_uv = np.array([[0.5 - du, 0.0], [0.5 + du, 0.0], [0.5 + du, 0.02], [0.5 - du, 0.02]])
        verts = np.concatenate([verts + np.array([0.0, 0.0, petiole]), stalk])
        n = len(uv)
        faces = np.concatenate([faces, [[n, n + 1, n + 2], [n, n + 2, n + 3]]])
        uv = np.concatenate([uv, stalk_uv])
    return _flat_mesh(verts, faces, uv)


def spray_card(aspect: float = 0.5, crossed: bool = False) -> Mesh:
    """A card for a whole cluster: a quad ``aspect`` wide from the origin to ``z = 1``, facing ``+y``.

    ``crossed`` adds a second quad turned a quarter about ``z`` (facing ``+x``), so that the spray has
    width from the side too.  Each quad's uv covers [0, 1]^2: the picture's bottom at the twig, its top at
    the cluster's tip.

    >>> m = spray_card(0.4, crossed=True)
    >>> len(m.faces), m.bounds.round(3).tolist()
    (4, [[-0.2, -0.2, 0.0], [0.2, 0.2, 1.0]])
    """
    h = aspect / 2
    quad = np.array([[-h, 0, 0], [h, 0, 0], [h, 0, 1], [-h, 0, 1]], np.float64)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.int64)  # counter-clockwise seen from +y
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    normal = np.broadcast_to(np.array([0.0, 1.0, 0.0], np.float32), (2, 3, 3))
    if not crossed:
        return Mesh(quad, faces, normal, uv[faces])
    side = np.array([[0, h, 0], [0, -h, 0], [0, -h, 1], [0, h, 1]], np.float64)
    verts = np.concatenate([quad, side])
    all_faces = np.concatenate([faces, faces + 4])
    normals = np.concatenate([normal, np.broadcast_to(np.array([1.0, 0.0, 0.0], np.float32), (2, 3, 3))])
    return Mesh(verts, all_faces, normals, np.concatenate([uv, uv])[all_faces])


# ---------------------------------------------------------------- frames


def _rotate(v: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rows of ``v`` turned about the unit rows of ``axis`` by ``angle`` radians (Rodrigues)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * dot(axis, v)[:, None] * (1.0 - c)


def _frame_with_up(heading: np.ndarray, left: np.ndarray, up: np.ndarray):
    """The frame whose up is ``up`` (unit rows) and whose heading is as close as can be to ``heading``."""
    h = heading - dot(heading, up)[:, None] * up
    n = np.linalg.norm(h, axis=1)
    fallback = np.cross(left, up)  # the heading points along the new up: turn it as the frame turns
    h = np.where((n > 1e-9)[:, None], h, fallback)
    h = unit(h)
    return h, np.cross(up, h), up


def toward_light(heading, left, up, light, fraction: float):
    """Frames turned so that their up (the blade's front) moves ``fraction`` of the way toward ``light``.

    The new up is the old one turned toward the light by ``fraction`` of the angle between them; the new
    heading is the old one's projection onto the plane across the new up, the smallest change of heading that
    allows it (the leaf twists on its stalk, then bends only as much as it must).

    Parameters
    ----------
    heading, left, up : (k, 3) float64
        Orthonormal frames (``H x L = U``).
    light : 3 floats or (k, 3) float64
        Direction toward the light (any length but 0), or one per frame.
    fraction : float
        0: unchanged; 1: every blade faces the light.

    Examples
    --------
    >>> h, l, u = toward_light(np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]), np.array([[0, 0, 1.0]]), (0, 1, 0), 1)
    >>> h.round(6).tolist(), u.round(6).tolist()
    ([[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    """
    heading, left, up = (np.asarray(a, np.float64).reshape(-1, 3) for a in (heading, left, up))
    if fraction <= 0 or not len(up):
        return heading, left, up
    target = np.asarray(light, np.float64)
    target = target / np.linalg.norm(target, axis=-1, keepdims=True)
    cos = np.clip(dot(up, np.broadcast_to(target, up.shape)), -1.0, 1.0)
    angle = np.arccos(cos)
    axis = np.cross(up, target)
    n = np.linalg.norm(axis, axis=1)
    axis = np.where((n > 1e-9)[:, None], axis / np.where(n > 1e-9, n, 1.0)[:, None], heading)  # facing away: roll
    new_up = unit(_rotate(up, axis, fraction * angle))
    return _frame_with_up(heading, left, new_up)


def droop(heading, left, up, degrees: float):
    """Frames pitched so that the heading (the blade's tip) hangs ``degrees`` toward the ground (-Y), no further.

    The whole frame turns about ``heading x down``; a heading already closer than ``degrees`` to straight
    down ends pointing down.
    """
    heading, left, up = (np.asarray(a, np.float64).reshape(-1, 3) for a in (heading, left, up))
    if degrees <= 0 or not len(heading):
        return heading, left, up
    axis = np.cross(heading, _DOWN)
    n = np.linalg.norm(axis, axis=1)
    ok = n > 1e-9
    axis = axis / np.where(ok, n, 1.0)[:, None]
    to_down = np.arccos(np.clip(heading @ _DOWN, -1.0, 1.0))
    angle = np.where(ok, np.minimum(math.radians(degrees), to_down), 0.0)
    return unit(_rotate(heading, axis, angle)), unit(_rotate(left, axis, angle)), unit(_rotate(up, axis, angle))


# ---------------------------------------------------------------- arranging the instances


def leaf_count(k: int, options) -> int:
    """How many instances :func:`arrange` makes of ``k`` (one card per cluster, else a leaf per cluster member)."""
    return k if options.leaf_card in ("spray", "cross") else k * options.leaves_per_cluster


def _back_along_twig(skeleton: Skeleton, segment: np.ndarray, position: np.ndarray, heading, distance):
    """Points ``distance`` back from ``position`` along the twig (its segment, then its parents), and the twig's
    direction there (toward the tip).  Leaves without a segment go back along their own heading."""
    pos = position - heading * distance[:, None]
    tangent = heading.copy()
    has = segment >= 0
    if not has.any():
        return pos, tangent
    pos[has] = position[has]
    cur = segment.copy()
    remaining = np.where(has, distance, 0.0)
    start, end, parent = skeleton.start, skeleton.end, skeleton.parent
    tangent[has] = unit(end[cur[has]] - start[cur[has]], 1e-300)
    for _ in range(len(skeleton) + 1):
        active = np.flatnonzero(remaining > 0)
        if not len(active):
            break
        s = cur[active]
        toward_base = start[s] - pos[active]
        length = np.linalg.norm(toward_base, axis=1)
        take = np.minimum(remaining[active], length)
        step = toward_base / np.where(length > 0, length, 1.0)[:, None]
        pos[active] += step * take[:, None]
        remaining[active] -= take
        along = end[s] - start[s]
        tangent[active] = np.where((np.linalg.norm(along, axis=1) > 0)[:, None], unit(along, 1e-300), tangent[active])
        more = remaining[active] > 0
        up_one = parent[s]
        stop = more & (up_one < 0)
        remaining[active[stop]] = 0.0  # the root: the cluster ends at the plant's base
        go = more & (up_one >= 0)
        cur[active[go]] = up_one[go]
    return pos, tangent


def _cluster_slots(count: int, phyllotaxis: str) -> tuple[np.ndarray, np.ndarray]:
    """Node (0 = at the tip) and azimuth (radians) of each leaf of a cluster of ``count``, and the node count."""
    i = np.arange(count)
    if phyllotaxis == "opposite":
        node = (i + 1) // 2
        azimuth = node * (np.pi / 2) + (i % 2 == 0) * np.pi
    else:
        node = i
        azimuth = i * (_GOLDEN_ANGLE if phyllotaxis == "spiral" else np.pi)
    return node, azimuth


def arrange(skeleton: Skeleton, options, seed: int = 0) -> Skeleton:
    """The skeleton's leaf instances as the leaves stage places them: sized, clustered, lit, drooping.

    Parameters
    ----------
    skeleton : Skeleton
    options : LeafOptions
        ``leaf_size`` (metres of blade; 0: the turtle's step) and ``leaf_size_variation``;
        ``leaves_per_cluster``, ``cluster_spread``, ``cluster_length``, ``cluster_phyllotaxis``;
        ``leaf_light``, ``light``, ``leaf_droop``; ``leaf_card``.
    seed : int
        The plant's seed (the leaves' sizes and the clusters' turns).

    Returns
    -------
    Skeleton
        The same skeleton with new leaf-instance arrays (``leaf_position``, ``leaf_heading``, ``leaf_left``,
        ``leaf_up``, ``leaf_size``, ``leaf_material``, ``leaf_segment``): each cluster's leaves one after the
        other, the leaf at the twig's tip first.  With ``leaf_card`` one instance per cluster: the card's
        base where the cluster starts, heading along the twig, size its length.  The skeleton itself when
        every option is neutral.

    Examples
    --------
    >>> from lsys3d.look.leaves import LeafOptions
    >>> sk = Skeleton.from_segments([[0, 0, 0]], [[0, 1, 0]], leaf_position=[[0, 1, 0]], leaf_heading=[[0, 1, 0]],
    ...     leaf_left=[[1, 0, 0]], leaf_up=[[0, 0, -1]], leaf_size=[0.5], leaf_material=[0], leaf_segment=[0])
    >>> out = arrange(sk, LeafOptions(leaves_per_cluster=3, cluster_length=0.2, leaf_size=0.1))
    >>> out.leaf_position[:, 1].round(3).tolist(), out.leaf_size.tolist()
    ([1.0, 0.9, 0.8], [0.1, 0.1, 0.1])
    """
    o = options
    k = len(skeleton.leaf_position)
    if not k or not _active(o):
        return skeleton
    n = o.leaves_per_cluster
    per = 1 if o.leaf_card in ("spray", "cross") else n
    heading = np.asarray(skeleton.leaf_heading, np.float64)
    left = np.asarray(skeleton.leaf_left, np.float64)
    up = np.asarray(skeleton.leaf_up, np.float64)
    position = np.asarray(skeleton.leaf_position, np.float64)
    segment = skeleton.leaf_segment
    if segment is None or len(segment) != k:
        segment = np.full(k, -1, np.int64)
    segment = np.asarray(segment, np.int64)
    size = np.full(k, o.leaf_size) if o.leaf_size > 0 else np.asarray(skeleton.leaf_size, np.float64).copy()
    owner = np.repeat(np.arange(k), per)
    m = k * per
    if o.leaf_size_variation > 0:
        u = generator(seed, Stream.LEAF_SIZE).uniform(-1.0, 1.0, m)
        size = size[owner] * (1.0 + o.leaf_size_variation * u)
    else:
        size = size[owner]
    length = o.cluster_length if n > 1 else 0.0
    if o.leaf_card in ("spray", "cross"):
        # the card spans the cluster: from where it starts on the twig to the tips of the leaves at the top
        base, axis = _back_along_twig(skeleton, segment, position, heading, np.full(k, length))
        along = unit(position - base, 1e-12)
        twig = np.where((np.linalg.norm(position - base, axis=1) > 1e-12)[:, None], along, axis)
        h, lf, uu = _frame_with_up(twig, left, unit(up - dot(up, twig)[:, None] * twig, 1e-12))
        bad = np.linalg.norm(uu, axis=1) < 0.5  # the leaf's up along the twig: keep the leaf's own frame
        h, lf, uu = (np.where(bad[:, None], a, b) for a, b in ((heading, h), (left, lf), (up, uu)))
        spread = math.cos(math.radians(o.cluster_spread)) if n > 1 else 1.0
        size = length + (1.0 + o.petiole_length) * size * spread
        pos = base
    else:
        node, azimuth = _cluster_slots(n, o.cluster_phyllotaxis)
        nodes = max(int(node.max()), 1)
        node, azimuth = np.tile(node, k), np.tile(azimuth, k)
        h, lf, uu = heading[owner], left[owner], up[owner]
        pos = position[owner]
        if n > 1:
            rng = generator(seed, Stream.LEAF_CLUSTER)
            phase = rng.uniform(0.0, 2 * np.pi, k)[owner]
            jitter = rng.uniform(-1.0, 1.0, (2, m))
            distance = length * node / nodes
            pos, twig = _back_along_twig(skeleton, segment[owner], position[owner], heading[owner], distance)
            ref = uu - dot(uu, twig)[:, None] * twig
            ref = np.where((np.linalg.norm(ref, axis=1) > 1e-9)[:, None], ref, lf)
            e1 = unit(ref - dot(ref, twig)[:, None] * twig, 1e-300)
            e2 = np.cross(twig, e1)
            phi = phase + azimuth + np.radians(10.0) * jitter[0]
            radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
            spread = np.radians(o.cluster_spread) * (1.0 + 0.15 * jitter[1])
            fan_h = np.cos(spread)[:, None] * twig + np.sin(spread)[:, None] * radial
            # the blade's front faces the twig's tip (the upper side of a leaf faces its shoot's apex)
            fan_u = twig - dot(twig, fan_h)[:, None] * fan_h
            fan_u = np.where((np.linalg.norm(fan_u, axis=1) > 1e-9)[:, None], fan_u, -radial)
            fan_u = unit(fan_u, 1e-300)
            tip = node == 0
            h = np.where(tip[:, None], h, fan_h)
            uu = np.where(tip[:, None], uu, fan_u)
            lf = np.where(tip[:, None], lf, np.cross(fan_u, fan_h))
    if o.leaf_card == "twigs":
        size = size * o.card_length  # a twig card is card_length of its leaves long
    h, lf, uu = toward_light(h, lf, uu, _light_targets(o, pos, position), o.leaf_light)
    h, lf, uu = droop(h, lf, uu, o.leaf_droop)
    return replace(
        skeleton,
        leaf_position=np.ascontiguousarray(pos),
        leaf_heading=np.ascontiguousarray(h),
        leaf_left=np.ascontiguousarray(lf),
        leaf_up=np.ascontiguousarray(uu),
        leaf_size=np.ascontiguousarray(size),
        leaf_material=np.asarray(skeleton.leaf_material)[owner],
        leaf_segment=segment[owner],
    )


def _light_targets(o, pos: np.ndarray, instances: np.ndarray):
    """What each blade turns to: the light, or with ``leaf_outward`` the light tilted away from the crown's axis.

    The axis is the vertical line through the mean of the skeleton's leaf ``instances``; a blade's outward
    direction is horizontal, from the axis to the blade, and its target ``(1 - w) light + w outward``.
    """
    light = np.asarray(o.light, np.float64)
    light = light / np.linalg.norm(light)
    if o.leaf_outward <= 0 or not len(pos):
        return light
    out = pos - instances.mean(axis=0)
    out[:, 1] = 0.0
    out = unit(out, 1e-12)
    target = (1.0 - o.leaf_outward) * light + o.leaf_outward * out
    ok = np.linalg.norm(target, axis=1) > 1e-9
    return np.where(ok[:, None], unit(target, 1e-12), light)


def card_aspect(skeleton: Skeleton, options) -> float:
    """Width over length of the cards of :func:`arrange`: ``card_aspect``, else for ``spray`` and ``cross`` cards
    the cluster fan's width over the cluster's length, for ``twigs`` cards 1 (a square picture).

    A cluster of leaves ``s`` long fanned ``cluster_spread`` off its twig is about ``2 s sin(spread)`` wide
    plus a blade's width (``s / 2``), and ``cluster_length + (1 + petiole) s cos(spread)`` long (one leaf:
    the leaf's own box); ``s`` is the plant's mean leaf size.
    """
    o = options
    if o.card_aspect > 0:
        return float(o.card_aspect)
    if o.leaf_card == "twigs":
        return 1.0
    s = o.leaf_size if o.leaf_size > 0 else float(np.mean(skeleton.leaf_size)) if len(skeleton.leaf_size) else 1.0
    clustered = o.leaves_per_cluster > 1
    spread = math.radians(o.cluster_spread) if clustered else 0.0
    width = 2 * s * math.sin(spread) + 0.5 * s
    length = (o.cluster_length if clustered else 0.0) + (1.0 + o.petiole_length) * s * math.cos(spread)
    return float(np.clip(width / max(length, 1e-12), 0.05, 20.0))


def _active(o) -> bool:
    """Whether any option changes where or how the instances sit."""
    return bool(
        o.leaf_size > 0
        or o.leaf_size_variation > 0
        or o.leaves_per_cluster > 1
        or o.leaf_light > 0
        or o.leaf_droop > 0
        or o.leaf_card != "none"
    )
