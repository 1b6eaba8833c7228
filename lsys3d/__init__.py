"""lsys3d: grow 3D plants and fractals from L-systems as clean meshes.

The pipeline, one stage per module (``docs/architecture.md``)::

    text --Grammar--> grammar --derive--> ModuleString --interpret--> Skeleton
         --sweep--> Tubes --union--> Mesh --color--> Mesh --export--> file
"""

from __future__ import annotations

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
)
from .exchange import ExportOptions, export
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
from .version import __version__

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
    "Skeleton",
    "SweepOptions",
    "Tree",
    "TurtleOptions",
    "UnionOptions",
    "__version__",
    "batch",
    "derive",
    "export",
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
