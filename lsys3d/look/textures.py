"""Procedural textures: tileable bark and alpha-cut leaf images, made with numpy from a seed.

Every kind is one row of :data:`KINDS` (name, group, generator, default colours, what it looks like) and one
generator function below, which returns the fields of one image -- height, linear colour, roughness and, for leaves,
coverage -- over a square grid.  :func:`procedural` turns them into the PNG images a
:class:`~lsys3d.look.materials.Material` carries (:class:`TextureSet`):

* ``albedo``: the base colour, sRGB (RGB for bark; RGBA for leaves, whose alpha is the cut-out);
* ``normal``: a tangent-space normal map from the height field's slopes, in glTF's convention (OpenGL: ``+X`` along
  ``u``, ``+Y`` up the image, ``+Z`` out of the surface);
* ``roughness`` (bark only): glTF's metallic-roughness packing, roughness in G, metallic (0) in B, R unused (255).

**Bark** images wrap: every noise is periodic over the tile (:func:`lsys3d.noise.fbm3`'s ``period``), and every cell
pattern wraps its cells, so the left column continues the right one and the top the bottom. The image's columns run
around a branch (the sweep's ``u``) and its rows along it (``v``), so furrows and fibres run down the image and ring
scars across it.  ``tile_size`` is the metres of bark one image covers: features keep their size in metres (an oak's
ridges stay some 5 cm apart) and a larger tile holds more of them; the material takes it as its
:attr:`~lsys3d.look.materials.Material.tile_size`, which the sweep uses for the tubes' texture coordinates.

**Leaf** images show one leaf, frond, spray or flower on a transparent background, its base at the bottom centre
(``v = 0``) and its tip at the top, as the leaf models' uv ``[0, 1]^2`` expect.

The images depend only on the kind and the parameters (numpy's PCG64 seeded through :class:`lsys3d.streams.Stream`,
float64 arithmetic, the deterministic PNG encoder of :mod:`lsys3d.images`), so the same seed gives the same bytes;
:func:`procedural` keeps the sets it made in the process.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..images import Image, png_image
from ..noise import perlin3
from ..streams import Stream

__all__ = [
    "KINDS",
    "MAX_RESOLUTION",
    "MIN_RESOLUTION",
    "Fields",
    "TextureKind",
    "TextureSet",
    "kinds_markdown",
    "normal_map",
    "procedural",
]

MIN_RESOLUTION = 16
"""Smallest side of a procedural image, in pixels."""
_PNG_LEVEL = 6
"""zlib level of the images (level 9 took up to three times as long here, for files at most 2% smaller)."""
MAX_RESOLUTION = 2048
"""Largest side of a procedural image, in pixels (about 4 s of numpy at 2048)."""


@dataclass(frozen=True)
class Fields:
    """What a generator returns: the fields of one square image, row 0 at the top.

    Attributes
    ----------
    height : (n, n) float64
        Relief in [0, 1] (1: highest), for the normal map.
    color : (n, n, 3) float64
        Linear RGB in [0, 1].
    roughness : (n, n) float64 or None
        In [0, 1] (bark); None for leaves.
    alpha : (n, n) float64 or None
        Coverage in [0, 1] (leaves); None for bark (opaque).
    relief : float
        The depth of the relief, in tile units (metres of depth over
        ``tile_size`` for bark): :func:`normal_map`'s slope scale.
    """

    height: np.ndarray
    color: np.ndarray
    roughness: np.ndarray | None
    alpha: np.ndarray | None
    relief: float


@dataclass(frozen=True)
class TextureKind:
    """One row of :data:`KINDS`: a kind's name, group (``bark`` or ``leaf``), generator and default colours.

    ``make(grid, colors, tile_size)`` returns the :class:`Fields`; ``colors``
    are linear RGB triples, as many as ``default_colors`` (sRGB hex, as
    picked in an image editor), each painting what ``roles`` names;
    ``tile_size`` is metres (bark only).
    """

    name: str
    group: str
    make: Callable
    default_colors: tuple[str, ...]
    roles: tuple[str, ...]
    doc: str
    leaf_length: float | None = None
    """Spray kinds: a leaf's mean length over the picture's height (a card ``c`` metres long shows leaves of
    about ``c * leaf_length`` metres); None for the others."""


@dataclass(frozen=True)
class TextureSet:
    """The images of one procedural texture: base colour, normal map and (bark) roughness.

    ``tile_size`` is the metres of bark the images cover (None for leaves).
    """

    kind: str
    albedo: Image
    normal: Image
    roughness: Image | None
    tile_size: float | None


# ---------------------------------------------------------------- grid, noise, cells


class _Grid:
    """Pixel centres of an ``n x n`` image and the random draws of one texture.

    ``u`` ``(1, n)`` runs across (columns) and ``v`` ``(n, 1)`` up the image
    (row 0 at the top has ``v`` near 1), both in ``[0, 1)``.
    """

    def __init__(self, n: int, seed: int):
        self.n, self.seed = n, seed
        c = (np.arange(n) + 0.5) / n
        self.u = c[None, :]
        self.v = (1.0 - c)[:, None]

    def rng(self, layer: int) -> np.random.Generator:
        """The generator of one layer of the texture (one id per use)."""
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence([self.seed, int(Stream.TEXTURE), layer])))

    def noise(self, layer: int, fu: int, fv: int, octaves: int = 4, gain: float = 0.5) -> np.ndarray:
        """Periodic fBm over the tile, ``fu`` x ``fv`` features in its first octave, scaled to unit deviation.

        Each octave of :func:`~lsys3d.noise.perlin3` (periodic over the tile)
        is evaluated on a grid of at most 8 samples per lattice cell and
        interpolated to the pixels (bilinear, wrapping): the low octaves cost
        little, and the result still tiles.
        """
        n = self.n
        out = np.zeros((n, n))
        w = 1.0
        for k in range(octaves):
            cu, cv = min(256, fu << k), min(256, fv << k)
            su, sv = min(n, 8 * cu), min(n, 8 * cv)
            x = np.arange(su) / su * cu
            y = np.arange(sv) / sv * cv
            pts = np.empty((sv, su, 3))
            pts[..., 0] = x[None, :]
            pts[..., 1] = y[:, None]
            pts[..., 2] = 0.37 + 1.7 * k
            field = perlin3(pts.reshape(-1, 3), (self.seed, int(Stream.TEXTURE), layer, k), (cu, cv, 0))
            out += w * _resample(field.reshape(sv, su), n)
            w *= gain
        out -= out.mean()
        return out / max(out.std(), 1e-12)

    def cells(self, layer: int, nu: int, nv: int, warp_u=0.0, warp_v=0.0, jitter: float = 0.8):
        """Periodic Worley cells: ``nu`` across by ``nv`` along, one jittered point each.

        Distances are in cell units (a cell is a unit square however long it
        is), so ``nu > nv`` gives cells long down the image.  Returns ``f1``,
        ``f2`` (distance to the nearest and second nearest point), ``cell`` (the
        nearest's index, ``row * nu + column``) and ``du``, ``dv`` (the offset
        from the nearest point).
        """
        point = 0.5 + jitter * (self.rng(layer).random((nv, nu, 2)) - 0.5)
        px, py = np.ascontiguousarray(point[..., 0]).reshape(-1), np.ascontiguousarray(point[..., 1]).reshape(-1)
        x = (self.u + warp_u) * nu + np.zeros((self.n, 1))
        y = (self.v + warp_v) * nv + np.zeros((1, self.n))
        ix, iy = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
        fx, fy = x - ix, y - iy
        f1, f2 = np.full(x.shape, np.inf), np.full(x.shape, np.inf)
        cell, index, closer = np.zeros(x.shape, np.int64), np.empty(x.shape, np.int64), np.empty(x.shape, bool)
        du, dv = np.zeros(x.shape), np.zeros(x.shape)
        columns, rows = _wrapped(ix, nu), {dy: r * nu for dy, r in _wrapped(iy, nv).items()}  # then updated in place
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                np.add(rows[dy], columns[dx], out=index)
                ox = fx - (dx + px[index])
                oy = fy - (dy + py[index])
                d = np.hypot(ox, oy)
                np.less(d, f1, out=closer)
                np.minimum(f2, d, out=f2)
                for field, new in ((f2, f1), (f1, d), (cell, index), (du, ox), (dv, oy)):  # f2 before f1 changes
                    np.copyto(field, new, where=closer)
        return f1, f2, cell, du, dv


def _wrapped(i: np.ndarray, n: int) -> dict[int, np.ndarray]:
    """``(i + d) % n`` for ``d`` in -1, 0, 1 (one modulo, then the ends wrapped)."""
    i = i % n
    return {-1: np.where(i == 0, n - 1, i - 1), 0: i, 1: np.where(i == n - 1, 0, i + 1)}


def _resample(field: np.ndarray, n: int) -> np.ndarray:
    """A periodic ``(sv, su)`` field sampled at ``i / s`` interpolated at ``n`` pixel centres a side (wrapping)."""
    for axis in (0, 1):
        s = field.shape[axis]
        if s == n:
            continue
        t = (np.arange(n) + 0.5) / n * s
        i0 = np.floor(t).astype(np.int64)
        w = t - i0
        a, b = np.take(field, i0 % s, axis=axis), np.take(field, (i0 + 1) % s, axis=axis)
        w = w[:, None] if axis == 0 else w[None, :]
        field = a + (b - a) * w
    # v runs up the image: the first sample row is v = 0, at the bottom
    return field[::-1] if field.shape[0] > 1 else field


def _smoothstep(a: float, b: float, x):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _mix(a, b, t):
    """``a`` to ``b`` (colours ``(3,)``) by ``t`` ``(n, n)``: ``(n, n, 3)``."""
    t = np.asarray(t)[..., None]
    return np.asarray(a) * (1.0 - t) + np.asarray(b) * t


def _count(tile_size: float, feature: float, least: int = 1) -> int:
    """Whole features of ``feature`` metres in a tile of ``tile_size`` metres (the tile must hold a whole number)."""
    return max(least, min(256, round(tile_size / feature)))


# ---------------------------------------------------------------- bark


def furrowed(g: _Grid, colors, tile_size: float) -> Fields:
    """Oak, pine, ash: ridges and deep narrow furrows running along the trunk, wandering, merging, cross-cracked."""
    furrow, ridge, top = colors
    nu = _count(tile_size, 0.04, 3)  # ridges a few centimetres apart around the trunk
    nv = _count(tile_size, 0.1, 2)
    # a ridge's place across: whole ridges around the tile, wandering along it (periodic: nu is whole)
    phase = g.u * nu + 0.5 * g.noise(1, 1, 1, 3) + 0.22 * g.noise(2, max(1, nu // 3), 2, 3)
    ridge_index = np.floor(phase).astype(np.int64) % nu
    side = np.minimum(phase - np.floor(phase), np.ceil(phase) - phase) * 2.0  # 0 in a furrow, 1 on a ridge's crest
    width = 0.5 + 0.2 * g.noise(3, 3, 3, 3)  # furrows widen and close along the trunk
    height = _smoothstep(0.05, np.clip(width, 0.1, 0.9), side)
    # here and there a furrow closes and two ridges merge
    bridge = _smoothstep(0.7, 1.5, g.noise(8, max(1, nu // 2), 2 * nv, 3))
    height = np.maximum(height, 0.85 * bridge * _smoothstep(0.0, 0.4, side + 0.3))
    # each ridge breaks into plates: a crack across it every ~10 cm, at heights of its own
    rng = g.rng(4)
    offset = rng.random(nu)[ridge_index]
    t = g.v * nv + offset + 0.15 * g.noise(5, 4, 2, 2)
    crack = 1.0 - _smoothstep(0.0, 0.07, np.minimum(t - np.floor(t), np.ceil(t) - t))
    height = height * (1.0 - 0.75 * crack * _smoothstep(0.3, 0.8, side))
    fine = g.noise(6, 4 * nu, 8, 3)
    height = np.clip(height * (0.88 + 0.08 * fine) + 0.03 * fine, 0.0, 1.0)
    tint = rng.uniform(-1, 1, nu)[ridge_index]
    color = _mix(furrow, ridge, _smoothstep(0.05, 0.5, height))
    color = _mix(color, top, np.clip(_smoothstep(0.5, 0.95, height) * (0.6 + 0.2 * tint + 0.15 * fine), 0, 1))
    color *= (1.0 + 0.1 * g.noise(7, 3, 2, 3))[..., None]
    rough = 0.97 - 0.12 * height
    return Fields(height, color, rough, None, 0.02 / tile_size)


def plated(g: _Grid, colors, tile_size: float) -> Fields:
    """Old pine, plane: irregular flat plates split by dark fissures, each plate its own shade, flaking in layers."""
    fissure, plate_a, plate_b = colors
    nu, nv = _count(tile_size, 0.08, 2), _count(tile_size, 0.14, 2)
    wu = 0.12 / nu * g.noise(1, 4, 4, 3)
    wv = 0.12 / nv * g.noise(2, 4, 4, 3)
    f1, f2, cell, du, dv = g.cells(3, nu, nv, wu, wv, jitter=0.9)
    crack = _smoothstep(0.04, 0.2, f2 - f1)
    # flakes: a finer pattern whose edges step the plate down in layers
    g1, g2, sub, _, _ = g.cells(4, 3 * nu, 3 * nv, wu, wv)
    step = _smoothstep(0.0, 0.12, g2 - g1)
    rng = g.rng(5)
    shade = rng.random(nu * nv)[cell]
    tilt_u, tilt_v = rng.uniform(-1, 1, (2, nu * nv))[:, cell]
    layer = rng.random(9 * nu * nv)[sub]
    fine = g.noise(6, 24, 24, 3)
    height = crack * (0.7 + 0.1 * (tilt_u * du + tilt_v * dv) + 0.12 * layer * step + 0.04 * fine)
    height = np.clip(height, 0.0, 1.0)
    color = _mix(plate_a, plate_b, np.clip(0.7 * shade + 0.3 * layer + 0.08 * fine, 0, 1))
    color = _mix(fissure, color, _smoothstep(0.1, 0.7, crack) * (0.75 + 0.25 * step))
    rough = 0.95 - 0.15 * crack
    return Fields(height, color, rough, None, 0.025 / tile_size)


def smooth(g: _Grid, colors, tile_size: float) -> Fields:
    """Beech, aspen, young cherry: smooth grey bark, mottled, with small horizontal lenticels."""
    base, light, dark = colors
    mottle = g.noise(1, 3, 3, 5, 0.55)
    color = _mix(base, light, _smoothstep(-1.0, 1.5, mottle))
    color = _mix(color, dark, 0.35 * _smoothstep(0.8, 2.2, g.noise(2, 4, 6, 4)))
    nu, nv = _count(tile_size, 0.025, 4), _count(tile_size, 0.012, 4)
    _, _, cell, du, dv = g.cells(3, nu, nv, jitter=0.6)
    size = g.rng(4).uniform(0.15, 0.42, nu * nv)[cell]
    keep = g.rng(5).random(nu * nv)[cell] < 0.5
    lenticel = keep * (1.0 - _smoothstep(0.6, 1.0, np.hypot(du / size, dv / (0.33 * size))))
    color = _mix(color, dark, 0.8 * lenticel)
    height = 0.5 + 0.05 * mottle + 0.3 * lenticel
    rough = 0.6 + 0.25 * lenticel + 0.03 * mottle
    return Fields(np.clip(height, 0, 1), color, np.clip(rough, 0, 1), None, 0.004 / tile_size)


def birch(g: _Grid, colors, tile_size: float) -> Fields:
    """Birch: chalk-white bark with dark horizontal lenticels and black fissured patches; peels in bands."""
    white, grey, black = colors
    band = g.noise(1, 1, _count(tile_size, 0.02, 4), 4)  # horizontal peel bands: many features along, one across
    color = _mix(white, grey, 0.3 * _smoothstep(0.2, 2.0, band) + 0.25 * _smoothstep(0.5, 2.5, g.noise(2, 3, 3, 4)))
    # lenticels: thin dark dashes across the trunk
    nu, nv = _count(tile_size, 0.07, 3), _count(tile_size, 0.015, 6)
    _, _, cell, du, dv = g.cells(3, nu, nv, jitter=0.7)
    rng = g.rng(4)
    length = rng.uniform(0.25, 0.8, nu * nv)[cell]
    keep = rng.random(nu * nv)[cell] < 0.6
    dash = keep * (1.0 - _smoothstep(0.6, 1.0, np.hypot(du / length, dv / 0.1)))
    # black patches: rough, wide, flattened horizontally
    patch_noise = g.noise(5, 3, _count(tile_size, 0.1, 3), 5, 0.55)
    patch = _smoothstep(1.3, 1.8, patch_noise + 0.4 * g.noise(6, 12, 24, 3))
    mark = np.maximum(dash, patch)
    color = _mix(color, black, 0.92 * mark)
    height = np.clip(0.6 + 0.04 * band - 0.25 * dash - 0.35 * patch * (0.6 + 0.2 * g.noise(7, 16, 16, 2)), 0, 1)
    rough = 0.55 + 0.35 * mark
    return Fields(height, color, rough, None, 0.006 / tile_size)


def ringed(g: _Grid, colors, tile_size: float) -> Fields:
    """Palm trunks (and cherry's banding): horizontal ring scars at regular steps, fibres between."""
    between, scar, light = colors
    rings = _count(tile_size, 0.07, 2)
    wobble = 0.18 * g.noise(1, 2, 1, 3)
    t = g.v * rings + wobble
    frac = t - np.floor(t)
    ridge = np.exp(-(((frac - 0.1) / 0.06) ** 2))  # the raised lip of the scar
    groove = np.exp(-(((frac - 0.22) / 0.07) ** 2))  # and the dark groove above it
    fibre = g.noise(2, _count(tile_size, 0.008, 8), rings, 3)
    swell = np.sin(np.pi * frac) ** 0.6  # each ring's section bulges a little between the scars
    height = np.clip(0.45 + 0.2 * swell + 0.35 * ridge - 0.35 * groove + 0.04 * fibre, 0, 1)
    color = _mix(between, light, np.clip(0.4 * ridge + 0.15 * fibre + 0.2 * swell, 0, 1))
    color = _mix(color, scar, 0.8 * groove)
    color *= (1.0 + 0.1 * g.noise(3, 2, rings, 3))[..., None]
    rough = 0.85 + 0.1 * groove - 0.1 * ridge
    return Fields(height, color, np.clip(rough, 0, 1), None, 0.012 / tile_size)


def fibrous(g: _Grid, colors, tile_size: float) -> Fields:
    """Cedar, cypress, old willow: long stringy fibres along the trunk, peeling in strips, a few fissures."""
    dark, red, grey = colors
    nu = _count(tile_size, 0.01, 8)
    warp = 0.6 / nu * g.noise(1, 3, 2, 3)
    strand = g.noise(2, nu, 2, 3)  # features every centimetre across, tens of centimetres along
    ridged = 1.0 - np.abs(np.tanh(0.8 * strand))
    f1, f2, _, _, _ = g.cells(3, _count(tile_size, 0.07, 2), 1, warp)
    fissure = 1.0 - _smoothstep(0.0, 0.18, f2 - f1)
    height = np.clip(0.25 + 0.6 * ridged - 0.45 * fissure, 0, 1)
    weather = _smoothstep(-0.3, 1.2, g.noise(4, 6, 1, 4))  # grey weathering in long streaks
    color = _mix(red, grey, 0.8 * weather)
    color = _mix(dark, color, np.clip(0.35 + 0.65 * height, 0, 1))
    rough = 0.9 + 0.08 * fissure
    return Fields(height, color, np.clip(rough, 0, 1), None, 0.015 / tile_size)


# ---------------------------------------------------------------- leaves


def _leaf_coords(g: _Grid) -> tuple[np.ndarray, np.ndarray]:
    """Leaf coordinates: ``x`` across from the middle (``[-0.5, 0.5]``), ``y`` up from the base (``[0, 1]``)."""
    shape = (g.n, g.n)
    return np.broadcast_to(g.u - 0.5, shape), np.broadcast_to(g.v, shape)


def _edge(distance, n: float) -> np.ndarray:
    """Coverage from a signed distance (positive inside; ``n`` pixels a unit): a pixel and a half of anti-aliasing."""
    return np.clip(0.5 + np.asarray(distance) * n / 1.5, 0.0, 1.0)


def _segment_distance(x, y, a, b):
    """Distance from points to the segment ``a``-``b``, and the share of the way along it."""
    ex, ey = b[0] - a[0], b[1] - a[1]
    t = np.clip(((x - a[0]) * ex + (y - a[1]) * ey) / max(ex * ex + ey * ey, 1e-18), 0.0, 1.0)
    return np.hypot(x - a[0] - t * ex, y - a[1] - t * ey), t


# A single leaf's outline is a function of leaf coordinates (x across from the middle, y up from the base, the
# leaf's picture the unit square) and n, the pixels per leaf unit; it returns the leaf's masks (blade, petiole,
# veins) and `across`, 0 on the midrib to 1 at the edge.  The single-leaf kinds draw one over the whole image;
# the spray kinds (below) draw several, each in its own frame.


def _blade_masks(x, y, n, width: Callable, veins: int, vein_angle: float, y0: float = 0.08):
    """A pinnate leaf: half-width ``width(t)`` at ``t`` of the blade, midrib, ``veins`` veins a side, petiole."""
    t = (y - y0) / (0.97 - y0)
    w = np.where((t > 0) & (t < 1), width(np.clip(t, 0, 1)), 0.0)
    blade = _edge(w - np.abs(x), n) * (t > -0.01)
    petiole = _edge(0.008 - np.abs(x), n) * (y > 0.005) * (t < 0.05)
    # veins: the midrib, and veins leaving it toward the tip at vein_angle
    ax = np.abs(x)
    s = (t - ax * math.tan(math.radians(90 - vein_angle)) / (0.97 - y0)) * veins
    vein_line = np.abs(s - np.round(s))
    vein = (
        (1.0 - _smoothstep(0.02, 0.06, vein_line)) * (s > 0.5) * (1.0 - _smoothstep(0.6, 1.0, ax / np.maximum(w, 1e-9)))
    )
    midrib = 1.0 - _smoothstep(0.004, 0.010, ax)
    veins_all = np.maximum(vein * 0.7, midrib)
    return blade, petiole, veins_all, ax / np.maximum(w, 1e-9)


def _ovate_masks(x, y, n):
    return _blade_masks(x, y, n, lambda t: 0.3 * np.sin(np.pi * t**0.75) ** 0.85, 8, 45)


def _willow_masks(x, y, n):
    def width(t):
        return 0.1 * np.sin(np.pi * t**0.9) ** 0.9 * (1.0 - 0.06 * np.abs(np.sin(np.pi * 40 * t)))

    return _blade_masks(x, y, n, width, 16, 35, y0=0.04)


def _birch_masks(x, y, n):
    def width(t):
        teeth = 1.0 - 0.07 * (np.abs(np.sin(np.pi * 14 * t)) + 0.5 * np.abs(np.sin(np.pi * 28 * t)))
        return 0.36 * np.sin(np.pi * t**0.55) ** 0.7 * (1.0 - 0.25 * t) * teeth

    return _blade_masks(x, y, n, width, 7, 50, y0=0.12)


def _oak_masks(x, y, n):
    def width(t):
        lobes = 0.5 + 0.5 * np.cos(2 * np.pi * (4.5 * t**0.9 - 0.2))
        return 0.36 * np.sin(np.pi * t**1.15) ** 0.6 * (0.45 + 0.55 * lobes**0.45)

    return _blade_masks(x, y, n, width, 5, 40, y0=0.06)


def _maple_masks(x, y, n):
    cx, cy = 0.0, 0.36
    r = np.hypot(x - cx, y - cy)
    theta = np.arctan2(x - cx, y - cy)  # 0 up, positive to the right
    lobes = ((0.0, 0.58), (1.0, 0.52), (-1.0, 0.52), (2.05, 0.3), (-2.05, 0.3))
    reach = np.zeros_like(r)
    for angle, length in lobes:
        d = np.abs(np.angle(np.exp(1j * (theta - angle))))
        # a broad lobe narrowing to its point; two big teeth on each of its sides
        profile = np.clip(1.0 - d / 0.75, 0.0, 1.0) ** 0.9
        teeth = 1.0 - 0.12 * np.abs(np.sin(d / 0.75 * 3.0 * np.pi)) * (d < 0.75)
        reach = np.maximum(reach, length * profile * teeth)
    outline = np.maximum(0.2, reach)  # the sinuses stop short of the centre
    blade = _edge(outline - r, n)
    petiole = _edge(0.009 - np.abs(x), n) * (y > 0.005) * (y < cy)
    vein = np.zeros_like(r)
    for angle, length in lobes:
        ux, uy = math.sin(angle), math.cos(angle)
        d, t = _segment_distance(x, y, (cx, cy), (cx + ux * length, cy + uy * length))
        vein = np.maximum(vein, (1.0 - _smoothstep(0.003, 0.009 * (1.2 - t), d)) * (t < 0.95))
        # secondary veins: every few centimetres of a primary vein, at 45 degrees toward the lobe's edges
        along = (x - cx) * ux + (y - cy) * uy
        side = (x - cx) * uy - (y - cy) * ux
        s = (along - 0.8 * np.abs(side)) * 16
        second = (1.0 - _smoothstep(0.03, 0.08, np.abs(s - np.round(s)))) * (s > 0.6) * (np.abs(side) < 0.16)
        vein = np.maximum(vein, 0.55 * second * (np.abs(np.angle(np.exp(1j * (theta - angle)))) < 0.55))
    across = np.clip(r / np.maximum(outline, 1e-9), 0, 1)
    return blade, petiole, vein, across


def _ivy_masks(x, y, n):
    """Hedera helix: three or five broad, untoothed, triangular lobes, shallow sinuses, a heart at the base."""
    r, theta = np.hypot(x, y - 0.34), np.arctan2(x, y - 0.34)  # theta: 0 up, positive to the right
    lobes = ((0.0, 0.62), (1.05, 0.46), (-1.05, 0.46), (2.1, 0.33), (-2.1, 0.33))
    reach = np.max(
        [b * np.clip(1 - np.abs(np.angle(np.exp(1j * (theta - a)))) / 1.05, 0, 1) ** 0.75 for a, b in lobes], 0
    )
    outline = np.maximum(0.27, reach) * (1.0 - 0.25 * _smoothstep(2.6, 3.1, np.abs(theta)))
    vein = np.zeros_like(r)
    for a, b in lobes:  # pale main veins from the petiole to each lobe
        d, t = _segment_distance(x, y, (0.0, 0.34), (0.8 * b * math.sin(a), 0.34 + 0.8 * b * math.cos(a)))
        vein = np.maximum(vein, (1.0 - _smoothstep(0.003, 0.009 * (1.2 - t), d)) * (t < 0.97))
    petiole = _edge(0.01 - np.abs(x), n) * (y > 0.005) * (y < 0.34)
    return _edge(outline - r, n), petiole, vein, np.clip(r / np.maximum(outline, 1e-9), 0, 1)


_LEAF_OUTLINES: dict[str, tuple[Callable, float]] = {
    "ovate": (_ovate_masks, 0.004),
    "willow": (_willow_masks, 0.003),
    "birch_leaf": (_birch_masks, 0.004),
    "oak_leaf": (_oak_masks, 0.004),
    "maple": (_maple_masks, 0.004),
    "ivy": (_ivy_masks, 0.004),
}
"""The single-leaf kinds' outlines and reliefs, by kind: what the single-leaf and the spray kinds draw."""


def _leaf_paint(tone, leaf, vein_color, stalk, blade, petiole, veins, across):
    """Colour, height and coverage of a leaf from its masks and a tone noise (unit deviation)."""
    color = np.asarray(leaf) * (1.0 + 0.12 * tone + 0.1 * (1.0 - np.clip(across, 0, 1)))[..., None]
    color = _mix(color, vein_color, 0.75 * veins)
    color = _mix(color, np.asarray(leaf) * 0.6, 0.5 * _smoothstep(0.8, 1.0, np.clip(across, 0, 1)))  # darker rim
    color = _mix(color, stalk, petiole * (1.0 - blade))
    alpha = np.maximum(blade, petiole)
    bulge = np.sqrt(np.clip(1.0 - np.clip(across, 0, 1) ** 2, 0, 1))
    height = np.clip(blade * (0.5 + 0.25 * bulge - 0.2 * veins + 0.03 * tone) + petiole * 0.6, 0, 1)
    return color, alpha, height


def _single(g: _Grid, colors, kind: str) -> Fields:
    """One leaf of ``kind`` (a key of :data:`_LEAF_OUTLINES`) over the whole image."""
    outline, relief = _LEAF_OUTLINES[kind]
    x, y = _leaf_coords(g)
    masks = outline(x, y, g.n)
    color, alpha, height = _leaf_paint(g.noise(20, 4, 4, 4), *colors, *masks)
    return Fields(height, np.clip(color, 0, 1), None, alpha, relief)


def ovate(g: _Grid, colors, tile_size: float) -> Fields:
    """Ovate leaf (beech, aspen, lime): widest below the middle, a pointed tip, pinnate veins."""
    return _single(g, colors, "ovate")


def willow(g: _Grid, colors, tile_size: float) -> Fields:
    """Lanceolate leaf (willow, olive): long and narrow, a long tip, finely toothed."""
    return _single(g, colors, "willow")


def birch_leaf(g: _Grid, colors, tile_size: float) -> Fields:
    """Birch leaf: triangular-ovate with a doubly serrate margin and a pointed tip."""
    return _single(g, colors, "birch_leaf")


def oak_leaf(g: _Grid, colors, tile_size: float) -> Fields:
    """Oak leaf: obovate with four or five deep rounded lobes a side."""
    return _single(g, colors, "oak_leaf")


def maple(g: _Grid, colors, tile_size: float) -> Fields:
    """Maple leaf: palmate, five pointed, toothed lobes from one point, veins radiating to their tips."""
    return _single(g, colors, "maple")


def ivy(g: _Grid, colors, tile_size: float) -> Fields:
    """Ivy leaf (Hedera helix): three to five broad, smooth, triangular lobes, dark and glossy, pale veins."""
    return _single(g, colors, "ivy")


def _strokes(g: _Grid, strokes, canvas_color, canvas_alpha, canvas_height):
    """Paint tapered strokes in order: ``(a, b, width_at_a, width_at_b, color_a, color_b)``, in tile units.

    Each stroke is evaluated only in its bounding box, so thousands cost little.
    """
    n = g.n
    for a, b, wa, wb, ca, cb in strokes:
        pad = max(wa, wb) + 2.0 / n
        c0 = max(0, int((min(a[0], b[0]) + 0.5 - pad) * n))
        c1 = min(n, int((max(a[0], b[0]) + 0.5 + pad) * n) + 2)
        r0 = max(0, int((1.0 - max(a[1], b[1]) - pad) * n))
        r1 = min(n, int((1.0 - min(a[1], b[1]) + pad) * n) + 2)
        if c0 >= c1 or r0 >= r1:
            continue
        x = (np.arange(c0, c1) + 0.5)[None, :] / n - 0.5
        y = 1.0 - (np.arange(r0, r1) + 0.5)[:, None] / n
        d, t = _segment_distance(x, y, a, b)
        w = wa + (wb - wa) * t
        cover = np.clip(0.5 + (w - d) * n / 1.2, 0.0, 1.0)
        across = np.clip(d / np.maximum(w, 1e-9), 0, 1)
        color = _mix(ca, cb, t) * (1.15 - 0.35 * across)[..., None]  # rounded: lighter along the middle
        box = (slice(r0, r1), slice(c0, c1))
        canvas_color[box] = canvas_color[box] * (1.0 - cover[..., None]) + color * cover[..., None]
        canvas_alpha[box] = np.maximum(canvas_alpha[box], cover)
        canvas_height[box] = np.maximum(canvas_height[box], cover * (0.45 + 0.5 * np.sqrt(1.0 - across**2)))


def _canvas(g: _Grid):
    return np.zeros((g.n, g.n, 3)), np.zeros((g.n, g.n)), np.zeros((g.n, g.n))


def _painted(g: _Grid, strokes, relief: float) -> Fields:
    color, alpha, height = _canvas(g)
    _strokes(g, strokes, color, alpha, height)
    return Fields(height, np.clip(color, 0, 1), None, alpha, relief)


def needle(g: _Grid, colors, tile_size: float) -> Fields:
    """A needle spray (pine, spruce, fir): a twig with needles all along it, on a transparent background."""
    needle_color, tip_color, twig = colors
    rng = g.rng(1)
    strokes = []
    bend = rng.uniform(-0.06, 0.06)
    twig_points = [(bend * math.sin(math.pi * s), 0.02 + 0.95 * s) for s in np.linspace(0, 1, 9)]
    needles = []
    for k in range(150):
        s = (k + rng.random()) / 150
        if s > 0.98:
            continue
        px, py = bend * math.sin(math.pi * s), 0.02 + 0.95 * s
        side = 1 if k % 2 else -1
        angle = math.radians(rng.uniform(35, 65)) * side + rng.normal(0, 0.08)
        length = (0.17 + 0.1 * rng.random()) * (0.55 + 0.45 * math.sin(math.pi * min(1.0, 0.15 + s)))
        if rng.random() < 0.3:  # needles pointing at the viewer look shorter
            length *= rng.uniform(0.35, 0.7)
        end = (px + length * math.sin(angle), py + length * math.cos(angle))
        shade = rng.uniform(0.75, 1.15)
        needles.append(((px, py), end, 0.0055, 0.0025, np.asarray(needle_color) * shade, np.asarray(tip_color) * shade))
    order = rng.permutation(len(needles))
    strokes += [needles[i] for i in order[: len(order) // 2]]
    strokes += [(a, b, 0.012, 0.009, twig, twig) for a, b in itertools.pairwise(twig_points)]
    strokes += [needles[i] for i in order[len(order) // 2 :]]
    return _painted(g, strokes, 0.004)


@dataclass(frozen=True)
class _Spray:
    """How a spray kind lays its leaves along its twig (all lengths in image heights)."""

    leaf: str
    """The single-leaf kind it draws (a key of :data:`_LEAF_OUTLINES`)."""
    count: tuple[int, int]
    """Fewest and most leaves (the seed picks)."""
    length: float
    """A leaf's mean length, its picture's height (the leaves shrink a little toward the twig's tip)."""
    petiole: float
    """Stalk from the twig to the leaf's picture."""
    angle: tuple[float, float]
    """Degrees between a leaf and the twig, near the base and near the tip."""
    arrangement: str
    """``alternate`` (two-ranked, sides taking turns), ``opposite`` (pairs) or ``tip`` (crowded at the tip)."""
    twig: float
    """How far up the picture the twig reaches."""
    bend: float
    """Sideways bow of the twig."""


def _twig_point(layout: _Spray, bend: float, s: float) -> tuple[float, float, float, float]:
    """The twig's point at ``s`` (0 base, 1 tip) and its unit direction there."""
    y0, y1 = 0.02, layout.twig
    x = bend * math.sin(math.pi * s)
    y = y0 + (y1 - y0) * s
    dx, dy = bend * math.pi * math.cos(math.pi * s), y1 - y0
    norm = math.hypot(dx, dy)
    return x, y, dx / norm, dy / norm


def _spray_leaves(layout: _Spray, rng: np.random.Generator):
    """Where the leaves of a spray go: the twig's bow, and per leaf its point on the twig, its base (the stalk's
    end), direction, length, width factor (a leaf at a slant is narrower), underside, tint and mirroring."""
    count = int(rng.integers(layout.count[0], layout.count[1] + 1))
    bend = rng.uniform(-1.0, 1.0) * layout.bend
    leaves = []
    for i in range(count):
        q = i / max(count - 1, 1)
        if layout.arrangement == "opposite":
            pair = i // 2
            pairs = (count + 1) // 2
            s = 0.2 + 0.8 * (pair + 1) / pairs
            side = 1 if i % 2 else -1
        elif layout.arrangement == "tip":
            s = 1.0 - 0.55 * q**1.2
            side = 1 if i % 2 else -1
        else:
            s = 0.12 + 0.88 * (i + 0.5 + 0.3 * rng.uniform(-1, 1)) / count
            side = 1 if i % 2 else -1
        s = min(max(s, 0.0), 1.0)
        px, py, tx, ty = _twig_point(layout, bend, s)
        angle = math.radians(layout.angle[0] + (layout.angle[1] - layout.angle[0]) * s + rng.uniform(-12, 12))
        if layout.arrangement == "tip" and i == 0:
            angle = math.radians(rng.uniform(-8, 8))  # the leading leaf carries the twig on
        a = math.atan2(tx, ty) + side * angle
        dx, dy = math.sin(a), math.cos(a)
        length = layout.length * rng.uniform(0.8, 1.2) * (1.12 - 0.25 * s)
        squash = rng.uniform(0.6, 1.0) if rng.random() < 0.45 else 1.0  # seen at a slant
        stalk = layout.petiole * rng.uniform(0.7, 1.2)
        bx, by = px + dx * stalk, py + dy * stalk
        # shrink a leaf whose picture would cross the image's edge (its outline fills most of its unit square)
        for _ in range(8):
            corners = [
                (bx + dx * v * length + dy * u * length * squash, by + dy * v * length - dx * u * length * squash)
                for u in (-0.45, 0.45)
                for v in (0.0, 0.97)
            ]
            if all(-0.49 < cx < 0.49 and 0.01 < cy < 0.99 for cx, cy in corners):
                break
            length *= 0.85
        under = rng.random() < 0.2
        tint = np.array([rng.uniform(-0.06, 0.06), rng.uniform(-0.04, 0.06), rng.uniform(-0.05, 0.03)])
        leaves.append(((px, py), (bx, by), (dx, dy), length, squash, under, tint, rng.random() < 0.5))
    return bend, leaves


def _spray(g: _Grid, colors, layout: _Spray) -> Fields:
    """A twig carrying leaves of ``layout.leaf``: each leaf drawn by that kind's outline in its own frame.

    The leaves turn to both sides at their angles, vary in size and shade, and some are foreshortened (seen
    at a slant) or show their paler underside; those drawn first (behind) are darker.  Everything stays
    inside the picture; the twig starts at the bottom centre.
    """
    leaf_color, vein_color, twig_color = (np.asarray(c) for c in colors)
    outline, relief = _LEAF_OUTLINES[layout.leaf]
    rng = g.rng(1)
    n = g.n
    bend, leaves = _spray_leaves(layout, rng)
    count = len(leaves)
    color, alpha, height = _canvas(g)
    # the twig and the stalks first: the blades cover them where they meet
    points = [_twig_point(layout, bend, t)[:2] for t in np.linspace(0.0, 1.0, 10)]
    strokes = [
        (p, q, 0.011 - 0.005 * k / 9, 0.010 - 0.005 * k / 9, twig_color, twig_color)
        for k, (p, q) in enumerate(itertools.pairwise(points))
    ]
    strokes += [(p, b, 0.0045, 0.0035, twig_color, leaf_color * 0.8) for p, b, *_ in leaves]
    _strokes(g, strokes, color, alpha, height)
    tone_all = g.noise(20, 4, 4, 4)
    order = rng.permutation(count)
    for rank, i in enumerate(order):
        _, (bx, by), (dx, dy), length, squash, under, tint, flip = leaves[i]
        # the leaf's unit square in the image, and the pixels it covers
        wx, wy = length * squash, length
        cxs = [bx + dx * v * wy + dy * u * wx for u in (-0.5, 0.5) for v in (0.0, 1.0)]
        cys = [by + dy * v * wy - dx * u * wx for u in (-0.5, 0.5) for v in (0.0, 1.0)]
        c0, c1 = max(0, int((min(cxs) + 0.5) * n) - 1), min(n, int((max(cxs) + 0.5) * n) + 2)
        r0, r1 = max(0, int((1.0 - max(cys)) * n) - 1), min(n, int((1.0 - min(cys)) * n) + 2)
        if c0 >= c1 or r0 >= r1:
            continue
        x = (np.arange(c0, c1) + 0.5)[None, :] / n - 0.5 - bx
        y = 1.0 - (np.arange(r0, r1) + 0.5)[:, None] / n - by
        lx = (x * dy - y * dx) / wx * (-1.0 if flip else 1.0)
        ly = (x * dx + y * dy) / wy
        inside = (np.abs(lx) <= 0.5) & (ly >= 0.0) & (ly <= 1.0)
        masks = outline(lx, ly, n * wx)
        base = leaf_color * (1.0 + tint)
        if under:  # the underside: paler and greyer
            base = _mix(base, np.full(3, base.mean() * 1.25 + 0.03), np.array(0.45))
        shade = 0.85 + 0.2 * rank / max(count - 1, 1)  # behind (drawn first): darker
        box = (slice(r0, r1), slice(c0, c1))
        c, a, h = _leaf_paint(tone_all[box], base * shade, vein_color * shade, twig_color, *masks)
        a = a * inside
        color[box] = color[box] * (1.0 - a[..., None]) + c * a[..., None]
        alpha[box] = np.maximum(alpha[box], a)
        height[box] = height[box] * (1.0 - a) + (0.15 + 0.85 * h) * a
    return Fields(np.clip(height, 0, 1), np.clip(color, 0, 1), None, alpha, relief)


_SPRAYS: dict[str, _Spray] = {
    "oak_spray": _Spray("oak_leaf", (7, 10), 0.42, 0.012, (80.0, 35.0), "tip", 0.45, 0.06),
    "maple_spray": _Spray("maple", (6, 8), 0.38, 0.07, (75.0, 45.0), "opposite", 0.5, 0.03),
    "birch_spray": _Spray("birch_leaf", (10, 14), 0.22, 0.035, (65.0, 40.0), "alternate", 0.88, 0.08),
    "willow_spray": _Spray("willow", (12, 15), 0.34, 0.01, (38.0, 22.0), "alternate", 0.92, 0.06),
    "beech_spray": _Spray("ovate", (8, 11), 0.28, 0.015, (80.0, 50.0), "alternate", 0.85, 0.05),
    "ovate_spray": _Spray("ovate", (8, 12), 0.25, 0.06, (70.0, 40.0), "alternate", 0.8, 0.07),
}
"""The spray kinds' layouts, by kind."""


def oak_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """An oak shoot: six to nine lobed leaves on short stalks crowded at the tip of a short twig."""
    return _spray(g, colors, _SPRAYS["oak_spray"])


def maple_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """A maple shoot: three or four opposite pairs of palmate leaves on long stalks."""
    return _spray(g, colors, _SPRAYS["maple_spray"])


def birch_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """A birch twig: ten to fourteen small serrate leaves alternating along a slender, bowed twig."""
    return _spray(g, colors, _SPRAYS["birch_spray"])


def willow_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """A willow whip: twelve to fifteen long narrow leaves alternating close to a long twig."""
    return _spray(g, colors, _SPRAYS["willow_spray"])


def beech_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """A beech spray: eight to eleven ovate leaves in two ranks, alternating wide of the twig."""
    return _spray(g, colors, _SPRAYS["beech_spray"])


def ovate_spray(g: _Grid, colors, tile_size: float) -> Fields:
    """A twig of ovate leaves on long stalks (aspen, hazel, lime): eight to twelve, alternating."""
    return _spray(g, colors, _SPRAYS["ovate_spray"])


def grass(g: _Grid, colors, tile_size: float) -> Fields:
    """A grass blade: a long strap tapering to a point, parallel veins, darker at the base."""
    base, tip, vein_color = colors
    x, y = _leaf_coords(g)
    lean = 0.06 * y**2
    w = 0.07 * (1.0 - y**1.6) ** 0.7
    xx = x - lean
    blade = _edge(w - np.abs(xx), g.n) * (y > 0.01)
    across = np.abs(xx) / np.maximum(w, 1e-9)
    stripes = 0.5 + 0.5 * np.cos(np.pi * 7 * np.clip(across, 0, 1))
    color = _mix(base, tip, _smoothstep(0.0, 1.0, y))
    color = _mix(color, vein_color, 0.25 * stripes + 0.6 * (1.0 - _smoothstep(0.05, 0.15, across)))
    color *= (1.0 + 0.08 * g.noise(1, 2, 8, 3))[..., None]
    height = blade * (0.5 + 0.1 * stripes + 0.3 * (1.0 - _smoothstep(0.05, 0.2, across)))
    return Fields(np.clip(height, 0, 1), np.clip(color, 0, 1), None, blade, 0.003)


def fern(g: _Grid, colors, tile_size: float) -> Fields:
    """A fern frond: a rachis with alternate pinnae, each cut into rounded pinnules, shrinking to the tip."""
    leaf, young, stalk = colors
    rng = g.rng(1)
    strokes = []
    pairs = 17
    for k in range(2 * pairs):
        s = 0.06 + 0.9 * (k + 0.5 * (k % 2)) / (2 * pairs)
        side = 1 if k % 2 else -1
        length = 0.44 * math.sin(math.pi * min(1.0, 0.12 + 0.95 * s)) ** 0.8 * (1.0 - 0.75 * s)
        angle = math.radians(68 - 25 * s) * side
        ox, oy = 0.0, s
        ux, uy = math.sin(angle), math.cos(angle)
        pinnules = max(3, int(length / 0.022))
        for j in range(pinnules):
            q = (j + 0.5) / pinnules
            cx, cy = ox + ux * q * length, oy + uy * q * length
            size = 0.022 * (1.0 - 0.7 * q) + 0.004
            # each pinnule: a short rounded lobe on both sides of the pinna's axis, pointing a little forward
            for sgn in (-1, 1):
                px, py = -uy * sgn, ux * sgn
                tipx = cx + (px * 0.9 + ux * 0.5) * size * 1.4
                tipy = cy + (py * 0.9 + uy * 0.5) * size * 1.4
                shade = np.asarray(leaf) * rng.uniform(0.85, 1.1)
                strokes.append(((cx, cy), (tipx, tipy), size * 0.75, size * 0.45, shade, np.asarray(young)))
        strokes.append(((ox, oy), (ox + ux * length, oy + uy * length), 0.004, 0.0015, stalk, leaf))
    strokes.append(((0.0, 0.0), (0.0, 0.985), 0.007, 0.002, stalk, stalk))
    return _painted(g, strokes, 0.004)


def palm(g: _Grid, colors, tile_size: float) -> Fields:
    """A palm frond (pinnate, coconut or date): a rachis with long narrow leaflets, drooping, shorter to the tip."""
    leaf, young, stalk = colors
    rng = g.rng(1)
    strokes = []
    count = 34
    for k in range(2 * count):
        s = 0.12 + 0.85 * (k // 2) / count
        side = 1 if k % 2 else -1
        length = 0.48 * math.sin(math.pi * min(1.0, 0.1 + 0.9 * s)) ** 0.6 * (1.0 - 0.6 * s)
        angle = math.radians(rng.uniform(45, 60)) * side
        ux, uy = math.sin(angle), math.cos(angle)
        mid = (ux * length * 0.5, s + uy * length * 0.5 - 0.03 * length)
        end = (ux * length, s + uy * length - 0.12 * length)  # leaflets droop toward their tips
        shade = np.asarray(leaf) * rng.uniform(0.85, 1.1)
        strokes.append(((0.0, s), mid, 0.009, 0.011, shade, shade))
        strokes.append((mid, end, 0.011, 0.001, shade, np.asarray(young)))
    strokes.append(((0.0, 0.0), (0.0, 0.99), 0.011, 0.003, stalk, stalk))
    return _painted(g, strokes, 0.004)


def flower(g: _Grid, colors, tile_size: float) -> Fields:
    """A flower seen from above: five rounded petals, notched, veined, a yellow centre with stamens."""
    petal, throat, center = colors
    x, y = _leaf_coords(g)
    cy = 0.5
    r = np.hypot(x, y - cy)
    theta = np.arctan2(x, y - cy)
    k = 5
    phase = np.angle(np.exp(1j * k * theta)) / k  # angle from the nearest petal's middle
    petal_shape = 0.47 * (np.cos(phase * k / 2) ** 0.45) * (1.0 - 0.1 * np.exp(-((phase / 0.05) ** 2)))
    blade = _edge(petal_shape - r, g.n)
    rr = np.clip(r / np.maximum(petal_shape, 1e-9), 0, 1)
    veins = (1.0 - _smoothstep(0.2, 0.6, np.abs(np.sin(theta * 40)))) * _smoothstep(0.2, 0.5, rr) * 0.35
    color = _mix(throat, petal, _smoothstep(0.12, 0.6, rr))
    color = _mix(color, np.asarray(throat) * 0.9, veins)
    disc = _edge(0.085 - r, g.n)
    dots = g.rng(1).random((24, 2))
    stamen = np.zeros_like(r)
    for a, d in dots:
        angle = 2 * math.pi * a
        px, py = 0.06 * d * math.sin(angle), cy + 0.06 * d * math.cos(angle)
        stamen = np.maximum(stamen, 1.0 - _smoothstep(0.006, 0.012, np.hypot(x - px, y - py)))
    color = _mix(color, center, disc)
    color = _mix(color, np.asarray(center) * 0.55, stamen * disc)
    color *= (1.0 + 0.06 * g.noise(2, 4, 4, 3))[..., None]
    cup = np.clip(rr, 0, 1) ** 2
    height = np.clip(blade * (0.4 + 0.3 * cup - 0.1 * veins) + disc * 0.2 + 0.2 * stamen * disc, 0, 1)
    return Fields(height, np.clip(color, 0, 1), None, blade, 0.004)


KINDS: dict[str, TextureKind] = {
    k.name: k
    for k in (
        TextureKind(
            "furrowed",
            "bark",
            furrowed,
            ("#2a1e16", "#5c4a3b", "#8d8073"),
            ("furrow", "ridge", "ridge top"),
            furrowed.__doc__,
        ),
        TextureKind(
            "plated",
            "bark",
            plated,
            ("#24170f", "#8a4b2c", "#6e625a"),
            ("fissure", "plate", "second plate shade"),
            plated.__doc__,
        ),
        TextureKind(
            "smooth",
            "bark",
            smooth,
            ("#8c8a84", "#a9a7a0", "#4c4842"),
            ("bark", "light mottle", "lenticels, dark mottle"),
            smooth.__doc__,
        ),
        TextureKind(
            "birch", "bark", birch, ("#ebe7dd", "#b9b2a4", "#1f1b18"), ("white", "grey", "marks"), birch.__doc__
        ),
        TextureKind(
            "ringed",
            "bark",
            ringed,
            ("#7a6d5e", "#3a3129", "#a09482"),
            ("trunk", "scar groove", "scar lip"),
            ringed.__doc__,
        ),
        TextureKind(
            "fibrous",
            "bark",
            fibrous,
            ("#2e1e15", "#8a4f34", "#8e857b"),
            ("between fibres", "fibre", "weathered"),
            fibrous.__doc__,
        ),
        TextureKind(
            "ovate", "leaf", ovate, ("#4d8a2a", "#9cc06a", "#6b7a2e"), ("blade", "veins", "stalk"), ovate.__doc__
        ),
        TextureKind(
            "oak_leaf",
            "leaf",
            oak_leaf,
            ("#47782a", "#a3be6e", "#6b6a2e"),
            ("blade", "veins", "stalk"),
            oak_leaf.__doc__,
        ),
        TextureKind(
            "maple", "leaf", maple, ("#4f8c2c", "#a6c777", "#8a5a2a"), ("blade", "veins", "stalk"), maple.__doc__
        ),
        TextureKind("ivy", "leaf", ivy, ("#1f4a1a", "#b4c49a", "#5a4a2a"), ("blade", "veins", "stalk"), ivy.__doc__),
        TextureKind(
            "willow", "leaf", willow, ("#6a9a48", "#c2d49a", "#7a8a40"), ("blade", "veins", "stalk"), willow.__doc__
        ),
        TextureKind(
            "birch_leaf",
            "leaf",
            birch_leaf,
            ("#5a9a30", "#b2d080", "#6a7a30"),
            ("blade", "veins", "stalk"),
            birch_leaf.__doc__,
        ),
        TextureKind(
            "needle",
            "leaf",
            needle,
            ("#2f5a28", "#6f9a4a", "#5a3e28"),
            ("needle", "needle tip", "twig"),
            needle.__doc__,
        ),
        TextureKind(
            "oak_spray",
            "leaf",
            oak_spray,
            ("#5a8a34", "#a3be6e", "#5e4a36"),
            ("leaf", "veins", "twig"),
            oak_spray.__doc__,
            _SPRAYS["oak_spray"].length,
        ),
        TextureKind(
            "maple_spray",
            "leaf",
            maple_spray,
            ("#4f8c2c", "#a6c777", "#8a5a2a"),
            ("leaf", "veins", "twig"),
            maple_spray.__doc__,
            _SPRAYS["maple_spray"].length,
        ),
        TextureKind(
            "birch_spray",
            "leaf",
            birch_spray,
            ("#5a9a30", "#b2d080", "#4a3a30"),
            ("leaf", "veins", "twig"),
            birch_spray.__doc__,
            _SPRAYS["birch_spray"].length,
        ),
        TextureKind(
            "willow_spray",
            "leaf",
            willow_spray,
            ("#6a9a48", "#c2d49a", "#8a7a40"),
            ("leaf", "veins", "twig"),
            willow_spray.__doc__,
            _SPRAYS["willow_spray"].length,
        ),
        TextureKind(
            "beech_spray",
            "leaf",
            beech_spray,
            ("#4d8a2a", "#9cc06a", "#5a4a3a"),
            ("leaf", "veins", "twig"),
            beech_spray.__doc__,
            _SPRAYS["beech_spray"].length,
        ),
        TextureKind(
            "ovate_spray",
            "leaf",
            ovate_spray,
            ("#5a8e34", "#a8c878", "#6a5a3a"),
            ("leaf", "veins", "twig"),
            ovate_spray.__doc__,
            _SPRAYS["ovate_spray"].length,
        ),
        TextureKind("grass", "leaf", grass, ("#3e7326", "#a8c060", "#2f5a1c"), ("base", "tip", "veins"), grass.__doc__),
        TextureKind(
            "fern", "leaf", fern, ("#4a8a2e", "#8cbc52", "#5a5a28"), ("leaflet", "leaflet tip", "stalk"), fern.__doc__
        ),
        TextureKind(
            "palm", "leaf", palm, ("#4f7f2a", "#a2b860", "#7a6a3a"), ("leaflet", "leaflet tip", "stalk"), palm.__doc__
        ),
        TextureKind(
            "flower", "leaf", flower, ("#f4c6d6", "#c2306a", "#f2c230"), ("petal", "throat", "centre"), flower.__doc__
        ),
    )
}
"""Every procedural kind by name: the vocabulary of ``procedural = { kind = ... }`` in ``[materials]``."""


def kinds_markdown() -> str:
    """The table of :data:`KINDS` in docs/textures.md (a test checks the page holds it as written here)."""
    lines = ["| kind | group | what it looks like | colours: what each paints (default) |", "|---|---|---|---|"]
    for name, row in KINDS.items():
        picture = f'<img src="textures/{name}.png" width="128" alt="{name}">'
        colors = ", ".join(f"{role} `{c}`" for role, c in zip(row.roles, row.default_colors, strict=True))
        lines.append(f"| `{name}`<br>{picture} | {row.group} | {row.doc.splitlines()[0]} | {colors} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- images


def _srgb8(linear: np.ndarray) -> np.ndarray:
    c = np.clip(linear, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)


def _linear(hex_color: str) -> tuple[float, float, float]:
    rgb = [int(hex_color[i : i + 2], 16) / 255 for i in (1, 3, 5)]
    return tuple(c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb)


def normal_map(height: np.ndarray, relief: float) -> np.ndarray:
    """A tangent-space normal map ``(n, n, 3) uint8`` from a height field ``(n, n)`` (row 0 at the top).

    The slopes are central differences that wrap (a tiling height gives a
    tiling map); ``relief`` is the depth of a unit of ``height`` in tile
    units (the image's side is 1), so the slopes do not depend on the
    resolution.  OpenGL/glTF convention: red is
    ``+u`` (right), green ``+v`` (up the image), blue out of the surface.

    >>> flat = normal_map(np.zeros((4, 4)), 1.0)
    >>> flat[0, 0].tolist()
    [128, 128, 255]
    """
    scale = relief * height.shape[0]
    right = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) * 0.5 * scale
    down = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) * 0.5 * scale
    n = np.stack([-right, down, np.ones_like(height)], axis=-1)  # d/d(up) = -d/d(down)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n * 0.5 + 0.5) * 255.0).astype(np.uint8)


def _image(name: str, pixels: np.ndarray) -> Image:
    return png_image(name, pixels, _PNG_LEVEL, "procedural")


def _key(kind: str, seed: int, resolution: int, colors, tile_size) -> str:
    tile = "" if tile_size is None else f"_{tile_size:g}m"
    return f"{kind}_s{seed}_{resolution}{tile}"


@lru_cache(maxsize=64)
def _make(kind: str, seed: int, resolution: int, colors: tuple, tile_size: float | None) -> TextureSet:
    row = KINDS[kind]
    fields = row.make(_Grid(resolution, seed), colors, tile_size)
    name = _key(kind, seed, resolution, colors, tile_size)
    color = _srgb8(fields.color)
    if fields.alpha is not None:
        # the colour bleeds under the transparent texels, so filtering at the edge does not darken it
        inside = fields.alpha > 0.5
        mean = color[inside].mean(axis=0) if inside.any() else np.zeros(3)
        color = np.where((fields.alpha > 0)[..., None], color, np.round(mean).astype(np.uint8))
        albedo = np.concatenate([color, _srgb8_alpha(fields.alpha)[..., None]], axis=-1)
    else:
        albedo = color
    normal = normal_map(fields.height, fields.relief)
    rough = None
    if fields.roughness is not None:
        packed = np.zeros((resolution, resolution, 3), np.uint8)
        packed[..., 0] = 255
        packed[..., 1] = np.round(np.clip(fields.roughness, 0, 1) * 255.0).astype(np.uint8)
        rough = _image(f"{name}_roughness.png", packed)
    return TextureSet(
        kind,
        _image(f"{name}_albedo.png", albedo),
        _image(f"{name}_normal.png", normal),
        rough,
        tile_size,
    )


def _srgb8_alpha(alpha: np.ndarray) -> np.ndarray:
    return np.round(np.clip(alpha, 0.0, 1.0) * 255.0).astype(np.uint8)


def procedural(
    kind: str,
    seed: int = 0,
    resolution: int = 512,
    colors: Sequence[Sequence[float]] | None = None,
    tile_size: float | None = None,
) -> TextureSet:
    """The images of a procedural texture (made once per process for the same arguments).

    Parameters
    ----------
    kind : str
        A name of :data:`KINDS`: bark ``furrowed``, ``plated``, ``smooth``,
        ``birch``, ``ringed``, ``fibrous``; leaves ``ovate``, ``oak_leaf``,
        ``maple``, ``willow``, ``birch_leaf``, ``needle``, ``grass``, ``fern``,
        ``palm``, ``flower``; leaf sprays ``oak_spray``, ``maple_spray``,
        ``birch_spray``, ``willow_spray``, ``beech_spray``, ``ovate_spray``.
    seed : int
        Seed of the pattern (>= 0).
    resolution : int
        Pixels a side, :data:`MIN_RESOLUTION` to :data:`MAX_RESOLUTION`.
    colors : sequence of (r, g, b), optional
        Linear RGB colours replacing the kind's defaults, as many as
        ``KINDS[kind].default_colors`` (what each is: the generator's docstring
        and ``docs/textures.md``).
    tile_size : float, optional
        Bark: metres of bark one image covers (default 0.5). Leaves: ignored.

    Returns
    -------
    TextureSet

    Raises
    ------
    ValueError
        ``procedural: what``: an unknown kind, or a parameter out of range.

    Examples
    --------
    >>> t = procedural("furrowed", seed=3, resolution=64, tile_size=0.6)
    >>> t.albedo.width, t.albedo.alpha, t.normal.name, t.tile_size
    (64, False, 'furrowed_s3_64_0.6m_normal.png', 0.6)
    >>> procedural("maple", resolution=64).albedo.alpha, procedural("maple", resolution=64).roughness
    (True, None)
    """
    if kind not in KINDS:
        raise ValueError(f"procedural: unknown kind {kind!r} (known: {', '.join(KINDS)})")
    row = KINDS[kind]
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"procedural: seed must be a whole number >= 0, not {seed!r}")
    if (
        isinstance(resolution, bool)
        or not isinstance(resolution, (int, np.integer))
        or not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION
    ):
        raise ValueError(
            f"procedural: resolution must be a whole number in {MIN_RESOLUTION}..{MAX_RESOLUTION}, not {resolution!r}"
        )
    if colors is None:
        colors = tuple(_linear(c) for c in row.default_colors)
    else:
        colors = tuple(tuple(float(c) for c in rgb[:3]) for rgb in colors)
        if len(colors) != len(row.default_colors) or any(len(c) != 3 for c in colors):
            raise ValueError(
                f"procedural: {kind} takes {len(row.default_colors)} colours ({', '.join(row.roles)}; "
                f"defaults {', '.join(row.default_colors)}), not {len(colors)}"
            )
        if not all(0.0 <= c <= 1.0 and math.isfinite(c) for rgb in colors for c in rgb):
            raise ValueError("procedural: colours must be linear RGB in [0, 1]")
    if row.group == "bark":
        tile_size = 0.5 if tile_size is None else float(tile_size)
        if not (math.isfinite(tile_size) and 0.01 <= tile_size <= 100.0):
            raise ValueError(f"procedural: tile_size must be metres in 0.01..100, not {tile_size!r}")
    else:
        tile_size = None
    return _make(kind, int(seed), int(resolution), colors, tile_size)
