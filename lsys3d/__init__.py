"""lsys3d: grow 3D plants and fractals from L-systems as clean meshes.

The pipeline, one stage per module (``docs/architecture.md``)::

    text --Grammar--> grammar --derive--> ModuleString --interpret--> Skeleton
         --sweep--> Tubes --union--> Mesh --color--> Mesh --export--> file
"""

from __future__ import annotations

import importlib
import importlib.machinery
from typing import TYPE_CHECKING

from . import cachelock
from .errors import (
    BatchError,
    DerivationError,
    ExportError,
    ForestError,
    GeometryError,
    GrammarError,
    InterpretError,
    LimitError,
    LSystemError,
    OptionsError,
    PreviewError,
    SeedWarning,
)
from .version import __version__

cachelock.install()  # two processes compiling one kernel at once must not mix up numba's cache entries

# Where each public name lives.  ``import lsys3d`` loads only the errors and the version; a name's module is
# imported the first time the name is used (``lsys3d.generate`` loads the pipeline, numba and all), so a
# command that does not need numba, usd-core, dask or trimesh never pays for them.
_HOMES = {
    "BarkColorOptions": "look.bark",
    "batch": "library.batch",
    "DEFAULT_MAX_MODULES": "lsystem.derive",
    "derive": "lsystem.derive",
    "generations": "lsystem.derive",
    "predict_length": "lsystem.derive",
    "ExportOptions": "exchange",
    "export": "exchange",
    "export_variants": "exchange",
    "ForestOptions": "library.forest",
    "forest": "library.forest",
    "Grammar": "lsystem.grammar",
    "Leaves": "look.leaves",
    "Material": "look.materials",
    "Mesh": "mesh.mesh",
    "ModuleString": "lsystem.modules",
    "GenerateOptions": "pipeline",
    "Limits": "pipeline",
    "generate": "pipeline",
    "DEFAULT_PRESET": "lsystem.presets",
    "list_presets": "lsystem.presets",
    "load": "lsystem.presets",
    "load_preset": "lsystem.presets",
    "PreviewOptions": "render.preview",
    "preview": "render.preview",
    "Provenance": "provenance",
    "Skeleton": "turtle.skeleton",
    "mesh_stats": "stats",
    "skeleton_stats": "stats",
    "SweepOptions": "mesh.sweep",
    "sweep": "mesh.sweep",
    "Tree": "tree",
    "TurtleOptions": "turtle",
    "interpret": "turtle",
    "UnionOptions": "mesh.union.union",
    "union": "mesh.union.union",
}


def __getattr__(name: str):
    """A public name, imported from its module on first use; a submodule (``lsys3d.pipeline``) likewise."""
    home = _HOMES.get(name)
    if home is not None:
        value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
        globals()[name] = value  # the next use finds it without calling __getattr__
        return value
    # a module of this folder only (not one another finder on sys.meta_path would supply under this name)
    if not name.startswith("__") and importlib.machinery.PathFinder.find_spec(f"{__name__}.{name}", __path__):
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})


if TYPE_CHECKING:  # what the names are, for type checkers and editors
    from .exchange import ExportOptions, export, export_variants
    from .library.batch import batch
    from .library.forest import ForestOptions, forest
    from .look.bark import BarkColorOptions
    from .look.leaves import Leaves
    from .look.materials import Material
    from .lsystem.derive import DEFAULT_MAX_MODULES, derive, generations, predict_length
    from .lsystem.grammar import Grammar
    from .lsystem.modules import ModuleString
    from .lsystem.presets import DEFAULT_PRESET, list_presets, load, load_preset
    from .mesh.mesh import Mesh
    from .mesh.sweep import SweepOptions, sweep
    from .mesh.union.union import UnionOptions, union
    from .pipeline import GenerateOptions, Limits, generate
    from .provenance import Provenance
    from .render.preview import PreviewOptions, preview
    from .stats import mesh_stats, skeleton_stats
    from .tree import Tree
    from .turtle import TurtleOptions, interpret
    from .turtle.skeleton import Skeleton

__all__ = [
    "DEFAULT_MAX_MODULES",
    "DEFAULT_PRESET",
    "BarkColorOptions",
    "BatchError",
    "DerivationError",
    "ExportError",
    "ExportOptions",
    "ForestError",
    "ForestOptions",
    "GenerateOptions",
    "GeometryError",
    "Grammar",
    "GrammarError",
    "InterpretError",
    "LSystemError",
    "Leaves",
    "LimitError",
    "Limits",
    "Material",
    "Mesh",
    "ModuleString",
    "OptionsError",
    "PreviewError",
    "PreviewOptions",
    "Provenance",
    "SeedWarning",
    "Skeleton",
    "SweepOptions",
    "Tree",
    "TurtleOptions",
    "UnionOptions",
    "__version__",
    "batch",
    "derive",
    "export",
    "export_variants",
    "forest",
    "generate",
    "generations",
    "interpret",
    "list_presets",
    "load",
    "load_preset",
    "mesh_stats",
    "predict_length",
    "preview",
    "skeleton_stats",
    "sweep",
    "union",
]
