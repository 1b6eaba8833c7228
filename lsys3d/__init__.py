"""lsys3d: grow 3D plants and fractals from L-systems as clean meshes.

The pipeline, one stage per module (``docs/architecture.md``)::

    text --Grammar--> grammar --derive--> ModuleString --interpret--> Skeleton
         --sweep--> Tubes --union--> Mesh --color--> Mesh --export--> file
"""

from __future__ import annotations

from .bark import BarkColorOptions
from .batch import batch
from .derive import DEFAULT_MAX_MODULES, derive, generations, predict_length
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
from .forest import ForestOptions, forest
from .grammar import Grammar
from .leaves import Leaves
from .materials import Material
from .mesh import Mesh
from .modules import ModuleString
from .pipeline import GenerateOptions, Limits, generate
from .presets import DEFAULT_PRESET, list_presets, load, load_preset
from .preview import PreviewOptions, preview
from .provenance import Provenance
from .skeleton import Skeleton
from .stats import mesh_stats, skeleton_stats
from .sweep import SweepOptions, sweep
from .tree import Tree
from .turtle import TurtleOptions, interpret
from .union import UnionOptions, union
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
