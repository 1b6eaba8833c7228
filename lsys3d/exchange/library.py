"""``library.usda``: one USD layer over a batch's assets, each a payload, chosen by the variant sets species and seed.

::

    #usda 1.0
    (defaultPrim = "Library", metersPerUnit and upAxis of the assets)

    def Xform "Library" (kind = "component", variantSets = "species", variants = {species = "bush"})
        variantSet "species" = {
            "bush" (variantSets = "seed", variants = {seed = "seed_0"}) {
                variantSet "seed" = {
                    "seed_0" (payload = @./bush/bush_s0.usdc@,
                              customData = {dictionary lsys3d = {species, seed, crown_radius,
                                                                 bbox_min, bbox_max, glb}}) {}
                    ...

A DCC opens the layer without loading a mesh (payloads) and shows the
selected species and seed once loaded; a layout artist references the layer
and switches variants.  The ``customData`` of each seed variant is what
``lsys3d forest`` needs to scatter the asset without opening it: its crown
radius and bounding box (metres, Y up, as :func:`lsys3d.stats.report`
measures them) and the ``.glb`` beside it, if the batch wrote one.  Species
names that USD does not allow as variant names (``abop-1.24a``) have the
characters it refuses replaced by ``_``; ``customData`` keeps the real name.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pxr import Gf, Kind, Sdf, Tf

from ..errors import ExportError, ForestError
from ..external import FileRefused, inside, open_regular
from ..version import __version__
from .atomic import atomic_path
from .common import UNITS, ExportOptions
from .usd import VARIANT_SET

__all__ = ["LIBRARY_ROOT", "SPECIES_SET", "USD_FORMATS", "LibraryVariant", "read_library", "write_library"]

LIBRARY_ROOT = "Library"
SPECIES_SET = "species"
USD_FORMATS = ("usdc", "usda", "usd", "usdz")
MAX_LIBRARY_BYTES = 1 << 30
"""Largest ``library.usda`` read (a variant takes about 600 bytes: over a million assets)."""
"""Formats a library can hold as payloads (the first a job writes is the one used)."""


@dataclass(frozen=True)
class LibraryVariant:
    """One asset of a library.

    Attributes
    ----------
    species : str
        The job's name (the species).
    seed : int
    usd : str
        The USD file, relative to the library's folder (``/``-separated).
    glb : str or None
        The ``.glb`` of the same asset, if there is one.
    crown_radius : float
        Metres from the trunk's axis to the farthest bark or leaf vertex.
    bbox_min, bbox_max : tuple of 3 float
        Bounds of the asset in lsys3d's frame (metres, Y up).
    """

    species: str
    seed: int
    usd: str
    glb: str | None
    crown_radius: float
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]

    @property
    def name(self) -> str:
        """``<species>_s<seed>``: the file stem and job id."""
        return f"{self.species}_s{self.seed}"


def _variant_name(species: str, taken: set[str]) -> str:
    name = re.sub(r"[^A-Za-z0-9_|-]", "_", species) or "species"
    base, i = name, 1
    while name in taken:
        i += 1
        name = f"{base}_{i}"
    taken.add(name)
    return name


def _asset(rel: str) -> str:
    return rel if rel.startswith(("./", "../", "/")) else f"./{rel}"


def build_library(variants: Sequence[LibraryVariant], options: ExportOptions) -> Sdf.Layer:
    """The library layer, in memory (the module docstring shows its layout)."""
    if not variants:
        raise ExportError("library: no variants")
    layer = Sdf.Layer.CreateAnonymous(".usda")
    root = layer.pseudoRoot
    root.SetInfo("upAxis", options.up_axis)
    root.SetInfo("metersPerUnit", options.meters_per_unit)
    root.SetInfo("customLayerData", {"lsys3d": {"generator": f"lsys3d {__version__}", "variants": len(variants)}})
    layer.defaultPrim = LIBRARY_ROOT
    prim = Sdf.PrimSpec(layer, LIBRARY_ROOT, Sdf.SpecifierDef, "Xform")
    prim.SetInfo("kind", Kind.Tokens.component)
    prim.variantSetNameList.prependedItems.append(SPECIES_SET)
    species_set = Sdf.VariantSetSpec(prim, SPECIES_SET)
    by_species: dict[str, list[LibraryVariant]] = {}
    for v in variants:
        by_species.setdefault(v.species, []).append(v)
    taken: set[str] = set()
    first = None
    for species in sorted(by_species):
        name = _variant_name(species, taken)
        first = first or name
        variant = Sdf.VariantSpec(species_set, name).primSpec
        variant.variantSetNameList.prependedItems.append(VARIANT_SET)
        seeds = Sdf.VariantSetSpec(variant, VARIANT_SET)
        members = sorted(by_species[species], key=lambda v: v.seed)
        if len({v.seed for v in members}) != len(members):
            raise ExportError(f"library: species {species!r} has two assets with the same seed")
        for v in members:
            spec = Sdf.VariantSpec(seeds, f"seed_{v.seed}").primSpec
            spec.payloadList.prependedItems.append(Sdf.Payload(_asset(v.usd)))
            data = {
                "species": v.species,
                "seed": int(v.seed),
                "crown_radius": float(v.crown_radius),
                "bbox_min": Gf.Vec3d(*map(float, v.bbox_min)),
                "bbox_max": Gf.Vec3d(*map(float, v.bbox_max)),
            }
            if v.glb:
                data["glb"] = _asset(v.glb)
            spec.customData = {"lsys3d": data}
        variant.variantSelections[VARIANT_SET] = f"seed_{members[0].seed}"
    prim.variantSelections[SPECIES_SET] = first
    return layer


def write_library(path: str | os.PathLike, variants: Sequence[LibraryVariant], options: ExportOptions) -> Path:
    """Write ``library.usda`` (atomically) over ``variants``, whose paths are relative to its folder.

    ``options`` gives the assets' units and up axis, which the layer declares.
    """
    path = Path(path)
    layer = build_library(variants, options)
    with atomic_path(path) as tmp:
        if not layer.Export(str(tmp)):
            raise ExportError(f"{path}: USD could not write the file")
    return path


@dataclass(frozen=True)
class Library:
    """A library read back: its assets and the units and up axis they are written in."""

    path: Path
    variants: tuple[LibraryVariant, ...]
    options: ExportOptions


def read_library(path: str | os.PathLike) -> Library:
    """Read a library written by :func:`write_library` (or the folder holding ``library.usda``).

    Raises
    ------
    ForestError
        ``path: what is wrong``: not there, not a USD layer, not an lsys3d library.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "library.usda"
    if not path.exists():
        raise ForestError(f"{path}: no such library (write one with 'lsys3d batch JOBS.toml -o FOLDER')")
    try:  # a regular file of a bounded size (USD reads it itself: check it the way every file is read)
        os.close(open_regular(path, MAX_LIBRARY_BYTES, "library", "lsys3d.exchange.library.MAX_LIBRARY_BYTES"))
    except FileRefused as exc:
        raise ForestError(str(exc)) from None
    try:
        layer = Sdf.Layer.FindOrOpen(str(path))
    except Tf.ErrorException as exc:
        raise ForestError(f"{path}: not a USD layer: {str(exc).strip().splitlines()[-1]}") from None
    if layer is None:
        raise ForestError(f"{path}: not a USD layer")
    prim = layer.GetPrimAtPath(f"/{LIBRARY_ROOT}")
    species_set = prim.variantSets.get(SPECIES_SET) if prim else None
    if species_set is None:
        raise ForestError(f"{path}: not an lsys3d library (no /{LIBRARY_ROOT} with the variant set {SPECIES_SET!r})")
    variants = []
    for name, species in species_set.variants.items():
        seeds = species.primSpec.variantSets.get(VARIANT_SET)
        for seed_name, seed in seeds.variants.items() if seeds else []:
            data = dict(seed.primSpec.customData).get("lsys3d")
            payloads = list(seed.primSpec.payloadList.prependedItems)
            if not isinstance(data, dict) or not payloads:
                raise ForestError(f"{path}: variant {name}/{seed_name} has no lsys3d customData or no payload")
            try:
                usd, glb = payloads[0].assetPath, data.get("glb")
                for name_, what in ((usd, "USD file"), (glb, ".glb file")):  # the library's own files only
                    if name_ is not None:
                        inside(path.parent, str(name_), f"asset's {what}")
                variants.append(
                    LibraryVariant(
                        species=str(data["species"]),
                        seed=int(data["seed"]),
                        usd=usd,
                        glb=glb,
                        crown_radius=float(data["crown_radius"]),
                        bbox_min=tuple(float(x) for x in data["bbox_min"]),
                        bbox_max=tuple(float(x) for x in data["bbox_max"]),
                    )
                )
            except FileRefused as exc:
                raise ForestError(f"{path}: variant {name}/{seed_name}: {exc}") from None
            except (KeyError, TypeError, ValueError) as exc:
                raise ForestError(f"{path}: variant {name}/{seed_name}: bad lsys3d customData ({exc})") from None
    if not variants:
        raise ForestError(f"{path}: the library holds no variant")
    up = layer.pseudoRoot.GetInfo("upAxis") or "Y"
    meters = float(layer.pseudoRoot.GetInfo("metersPerUnit") or 1.0)
    units = next((u for u, m in UNITS.items() if abs(m - meters) < 1e-12), None)
    if units is None or up not in ("Y", "Z"):
        raise ForestError(f"{path}: unsupported units or up axis (metersPerUnit {meters}, upAxis {up!r})")
    variants.sort(key=lambda v: (v.species, v.seed))
    return Library(path=path, variants=tuple(variants), options=ExportOptions(units=units, up_axis=up))
