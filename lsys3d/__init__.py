"""lsys3d: grow 3D plants and fractals from L-systems as clean meshes.

The pipeline, one stage per module::

    text --Grammar--> grammar --derive--> ModuleString --interpret--> Skeleton
         --sweep--> tubes --union--> Mesh --export--> file
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

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
    PreviewError,
)
from .exchange import ExportOptions, export
from .forest import ForestOptions, forest
from .grammar import Grammar
from .modules import ModuleString
from .pipeline import GenerateOptions, generate
from .presets import DEFAULT_PRESET, list_presets, load, load_preset
from .preview import PreviewOptions, preview
from .skeleton import Skeleton
from .stats import mesh_stats, skeleton_stats
from .sweep import SweepOptions, sweep
from .tree import Tree
from .turtle import TurtleOptions, interpret
from .union import UnionOptions, union

try:
    __version__ = version("lsys3d")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = [
    "DEFAULT_MAX_MODULES",
    "DEFAULT_PRESET",
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
    "LimitError",
    "ModuleString",
    "PreviewError",
    "PreviewOptions",
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
