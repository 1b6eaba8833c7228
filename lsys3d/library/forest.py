"""Forests: instances of a library's assets scattered over an area, written as instances (not copies).

::

    library.usda --read_library--> variants --scatter--> Scatter (arrays) --write--> forest.usdc | forest.glb

:func:`scatter` draws, for each instance, a species (all equally likely), one
of its seeds, a yaw and a scale, then places the instances one after the
other (largest crown first) by dart throwing: a position is accepted when the
trunk stands at least ``spacing * (1 - o) * (r_i + r_j)`` from every other
trunk, ``r`` being each instance's crown radius times its scale -- Poisson-disk
spacing with a radius per instance.  ``o``, how far two crowns may overlap (a
fraction of the sum of their radii), is as small as lets the instance find
room: 0 (crowns touch at most) for its first :data:`ATTEMPTS` positions, then
raised in :data:`OVERLAP_STEPS` equal steps, :data:`STEP_ATTEMPTS` positions
each, up to ``crown_overlap``.  So crowns meet where the stand is dense and
keep apart where there is room, as in a real stand, and a forest that fits
without overlap is placed exactly as with ``crown_overlap=0``.  Everything
comes from the seed, so a forest is the same in every run.  :func:`forest` writes it: a ``UsdGeomPointInstancer``
whose prototypes reference the assets' USD files, or one ``.glb`` holding each
asset once with ``EXT_mesh_gpu_instancing`` (:mod:`lsys3d.exchange.forest`).
"""

from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..compiling import inner, kernel
from ..errors import ForestError, OptionsError
from ..exchange.atomic import check_target
from ..exchange.forest import write_forest_glb, write_forest_usd
from ..exchange.library import read_library
from ..options import Options, option

__all__ = ["MAX_INSTANCES", "ForestOptions", "Scatter", "forest", "scatter"]

log = logging.getLogger("lsys3d")

MAX_INSTANCES = 1_000_000
"""Most instances of one forest: about 800 bytes and 40 microseconds each while scattered and written (1,000,000
took 0.93 GB and 38 s as .usdc, 0.80 GB and 17 s as .glb; 2,000,000 1.6 GB and 155 s on a busy machine), so the
most ends within a minute and 1 GB.  It was 10,000,000, which ran out of memory at 4.7 GB."""

ATTEMPTS = 400
"""Random positions tried for each instance with crowns that do not overlap."""

OVERLAP_STEPS = 8
"""Steps in which the crowns' overlap is raised, up to ``crown_overlap``, for an instance that found no room."""

STEP_ATTEMPTS = 50
"""Random positions tried at each step of overlap before the next (and, after the last, the forest is full)."""


@dataclass(frozen=True)
class ForestOptions(Options):
    """How :func:`forest` scatters a library's assets; every default, range and help is in its field.

    Trunks stand at least ``spacing * (1 - o) * (r_i + r_j)`` apart (``r``:
    crown radius times scale; ``o``: the crowns' overlap, 0 where there is
    room, raised up to ``crown_overlap`` for an instance that finds none, see
    :mod:`lsys3d.library.forest`): ``spacing`` 1 lets crowns touch, 0.5 lets
    them overlap by half, 0 places instances anywhere.  The area is centred on
    the origin, along X and along the horizontal axis that is not up.
    """

    area: tuple[float, float] = option(
        (100.0, 100.0), low=0, low_open=True, high=1e9, metavar="WxD", help="width x depth in metres"
    )
    count: int = option(500, low=1, high=MAX_INSTANCES, help="instances to place (all of them, or the forest fails)")
    seed: int = option(0, low=0, high=2**64 - 1, help="seed of every random choice")
    scale: tuple[float, float] = option(
        (0.8, 1.2), low=0, low_open=True, high=1e9, metavar="LO,HI", help="scale of each instance, drawn in LO..HI"
    )
    yaw: tuple[float, float] = option(
        (0.0, 360.0), low=-1e9, high=1e9, metavar="LO,HI", help="turn about the up axis in degrees, drawn in LO..HI"
    )
    spacing: float = option(
        1.0, low=0, high=100, metavar="F", help="trunks at least F times the sum of two crown radii apart"
    )
    crown_overlap: float = option(
        0.8,
        low=0,
        high=1,
        high_open=True,
        metavar="F",
        help="crowns may overlap by up to F of the sum of their radii where the stand is too dense for them to "
        "keep apart (each instance overlaps as little as it can; 0: crowns never overlap)",
    )
    species: tuple[str, ...] = option(
        (), kind="strings", cli=False, help="scatter only these species (default: every species of the library)"
    )
    no_clobber: bool = option(False, help="refuse to overwrite an existing file")

    def __post_init__(self):
        super().__post_init__()
        for name in ("scale", "yaw"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise OptionsError(f"ForestOptions.{name}: the lower bound {lo:g} is above the upper {hi:g}")

    def plain(self) -> dict:
        """The options as JSON-ready values (for the forest's provenance)."""
        return {
            "area": list(self.area),
            "count": self.count,
            "crown_overlap": self.crown_overlap,
            "scale": list(self.scale),
            "seed": self.seed,
            "spacing": self.spacing,
            "species": list(self.species),
            "yaw": list(self.yaw),
        }


@dataclass(frozen=True)
class Scatter:
    """Where the instances stand.

    Attributes
    ----------
    variant : (n,) int64
        Index of each instance's asset in the variant list given to :func:`scatter`.
    position : (n, 2) float64
        Trunk position in metres: x, and the other horizontal axis (z when Y is up).
    yaw : (n,) float64
        Degrees about the up axis.
    scale : (n,) float64
    """

    variant: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    scale: np.ndarray

    def transforms(self) -> np.ndarray:
        """``(n, 4, 4)`` transforms in lsys3d's frame (metres, Y up): translate, turn about Y, scale."""
        n = len(self.variant)
        t = np.zeros((n, 4, 4))
        a = np.radians(self.yaw)
        c, s = np.cos(a) * self.scale, np.sin(a) * self.scale
        t[:, 0, 0], t[:, 0, 2] = c, s
        t[:, 1, 1] = self.scale
        t[:, 2, 0], t[:, 2, 2] = -s, c
        t[:, 0, 3], t[:, 2, 3] = self.position[:, 0], self.position[:, 1]
        t[:, 3, 3] = 1.0
        return t


@inner(inline="always")
def _uniform(seed, i, j):
    """A uniform double in [0, 1) from (seed, i, j): splitmix64 of a counter, the same in every process."""
    z = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(i) * np.uint64(0xD1B54A32D192ED03)
    z += np.uint64(j) * np.uint64(0x8CB92BA72F3D8DD7) + np.uint64(0x632BE59BD9B4E019)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@kernel(nogil=True)
def _place(order, radius, spacing, width, depth, seed, attempts, cell, overlap, steps, step_attempts):
    """Dart throwing with a grid of ``cell``-sized buckets; returns positions, each one's overlap, how many fit.

    Each instance tries ``attempts`` positions with crowns that do not
    overlap, then ``step_attempts`` at each of ``steps`` overlaps up to
    ``overlap``.  An instance that finds no free position is left out, and
    the others still get their chance, so that the count tells how full the
    area is.
    """
    n = order.shape[0]
    nx = max(1, math.ceil(width / cell))
    nz = max(1, math.ceil(depth / cell))
    head = np.full(nx * nz, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    position = np.zeros((n, 2))
    used = np.zeros(n)
    placed = 0
    total = attempts + (steps * step_attempts if overlap > 0 else 0)
    for k in range(n):
        i = order[k]
        ok = False
        for attempt in range(total):
            o = 0.0
            if attempt >= attempts:
                o = overlap * ((attempt - attempts) // step_attempts + 1) / steps
            factor = spacing * (1.0 - o)
            x = _uniform(seed, i, 2 * attempt) * width
            z = _uniform(seed, i, 2 * attempt + 1) * depth
            cx = min(int(x / cell), nx - 1)
            cz = min(int(z / cell), nz - 1)
            ok = True
            for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                for gz in range(max(cz - 1, 0), min(cz + 2, nz)):
                    j = head[gx * nz + gz]
                    while j >= 0:
                        d = factor * (radius[i] + radius[j])
                        dx = position[j, 0] - x
                        dz = position[j, 1] - z
                        if dx * dx + dz * dz < d * d:
                            ok = False
                            break
                        j = nxt[j]
                    if not ok:
                        break
                if not ok:
                    break
            if ok:
                position[i, 0] = x
                position[i, 1] = z
                used[i] = o
                g = cx * nz + cz
                nxt[i] = head[g]
                head[g] = i
                placed += 1
                break
    return position, used, placed


def scatter(crown_radius, species, options: ForestOptions) -> Scatter:
    """Scatter ``options.count`` instances of the assets with these crown radii (metres).

    Parameters
    ----------
    crown_radius : (v,) float
        Crown radius of each asset.
    species : (v,) sequence of str
        The species of each asset: each species is drawn as often as the
        others, then one of its assets.
    options : ForestOptions

    Raises
    ------
    ForestError
        When the instances do not all fit (the message says how many did).

    Examples
    --------
    >>> s = scatter([1.0, 2.0], ["oak", "ash"], ForestOptions(area=(50, 50), count=20, seed=1))
    >>> len(s.variant), bool((np.abs(s.position) <= 25).all())
    (20, True)
    """
    radius_of = np.asarray(crown_radius, dtype=np.float64)
    names = list(species)
    if radius_of.ndim != 1 or not len(radius_of) or len(names) != len(radius_of):
        raise ForestError("forest: need one crown radius and one species per asset, and at least one asset")
    if not (np.isfinite(radius_of).all() and (radius_of >= 0).all()):
        raise ForestError("forest: crown radii must be finite and >= 0")
    rng = np.random.default_rng(options.seed)
    kinds = sorted(set(names))
    members = [np.flatnonzero([s == k for s in names]) for k in kinds]
    n = options.count
    kind = rng.integers(0, len(kinds), n)
    pick = rng.random(n)
    variant = np.empty(n, np.int64)
    for k, m in enumerate(members):
        chosen = kind == k
        variant[chosen] = m[np.minimum((pick[chosen] * len(m)).astype(np.int64), len(m) - 1)]
    scale = rng.uniform(*options.scale, n)  # the bounds themselves when they are equal
    yaw = rng.uniform(*options.yaw, n)
    radius = radius_of[variant] * scale
    width, depth = options.area
    reach = 2.0 * options.spacing * float(radius.max())
    cell = max(reach, math.sqrt(width * depth / n), 1e-9 * max(width, depth))
    order = np.argsort(-radius, kind="stable")
    position, used, placed = _place(
        order,
        radius,
        float(options.spacing),
        width,
        depth,
        options.seed,
        ATTEMPTS,
        cell,
        float(options.crown_overlap),
        OVERLAP_STEPS,
        STEP_ATTEMPTS,
    )
    if placed < n:
        lo, hi = float(radius.min()), float(radius.max())
        raise ForestError(
            f"forest: only {placed:,} of {n:,} instances fit on {width:g} x {depth:g} m with crown radii "
            f"{lo:.3g}-{hi:.3g} m, spacing {options.spacing:g} and crowns overlapping by up to "
            f"{options.crown_overlap:.0%}; lower the count, enlarge the area, lower the spacing or allow more "
            "overlap (crown_overlap, --crown-overlap)"
        )
    position -= (width / 2, depth / 2)
    if used.max() > 0:
        log.info(
            "forest: %d of %d instances with overlapping crowns (by up to %.0f%%)",
            int((used > 0).sum()),
            n,
            100 * used.max(),
        )
    return Scatter(variant=variant, position=position, yaw=yaw, scale=scale)


_USD = (".usda", ".usdc", ".usd")


def forest(library: str | os.PathLike, output: str | os.PathLike, options: ForestOptions | None = None) -> Path:
    """Scatter a library's assets and write the forest: USD (``.usda``/``.usdc``/``.usd``) or ``.glb``.

    Parameters
    ----------
    library : path-like
        A ``library.usda`` written by ``lsys3d batch`` (or its folder).
    output : path-like
        ``.usdc``, ``.usda``, ``.usd``: a ``UsdGeomPointInstancer`` whose
        prototypes reference the assets' USD files (paths relative to the
        forest), in the library's units and up axis.  ``.glb``: the assets'
        ``.glb`` files merged into one, each mesh once, placed by
        ``EXT_mesh_gpu_instancing``.
    options : ForestOptions, optional

    Returns
    -------
    pathlib.Path
        The file written (atomically).

    Raises
    ------
    ForestError
        A library that cannot be read, an unknown species, instances that do
        not fit, a ``.glb`` forest from assets written without ``.glb``.
    ExportError
        The file cannot be written.
    """
    options = options or ForestOptions()
    output = Path(output)
    suffix = output.suffix.lower()
    if suffix not in (*_USD, ".glb"):
        raise ForestError(f"{output}: a forest is written as .usdc, .usda, .usd or .glb, not {suffix or 'no suffix'!r}")
    check_target(output, options.no_clobber)
    lib = read_library(library)
    variants = list(lib.variants)
    if options.species:
        known = sorted({v.species for v in variants})
        unknown = [s for s in options.species if s not in known]
        if unknown:
            raise ForestError(f"{lib.path}: no species {unknown[0]!r} in the library (it has: {', '.join(known)})")
        variants = [v for v in variants if v.species in options.species]
    t0 = time.perf_counter()
    placed = scatter([v.crown_radius for v in variants], [v.species for v in variants], options)
    provenance = {
        "forest": options.plain(),
        "library": os.path.relpath(lib.path.resolve(), output.resolve().parent),
        "instances": len(placed.variant),
    }
    folder = lib.path.resolve().parent
    if suffix == ".glb":
        missing = next((v for v in variants if not v.glb), None)
        if missing is not None:
            raise ForestError(
                f'{lib.path}: asset {missing.name} has no .glb; a .glb forest needs the batch to write "glb" too'
            )
        path = write_forest_glb(output, [(v.name, folder / v.glb) for v in variants], placed, provenance, options)
    else:
        prototypes = [(v.name, folder / v.usd, v.bbox_min, v.bbox_max) for v in variants]
        missing = next((p for p in prototypes if not p[1].is_file()), None)
        if missing is not None:
            raise ForestError(f"{lib.path}: asset {missing[0]}'s file {str(missing[1])!r} is missing")
        path = write_forest_usd(output, prototypes, placed, provenance, lib.options, options)
    log.info("forest %d instances in %.3f s", len(placed.variant), time.perf_counter() - t0)
    return path
