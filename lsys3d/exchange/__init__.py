"""Export a :class:`~lsys3d.tree.Tree` to a file; the writer is chosen by the file's suffix.

==========================  ====================================================
suffix                      writer
==========================  ====================================================
``.glb``                    binary glTF 2.0 (:mod:`lsys3d.exchange.gltf`)
``.gltf``                   glTF 2.0 JSON plus a ``.bin`` buffer beside it
``.usda`` ``.usdc`` ``.usd``  OpenUSD text / crate (:mod:`lsys3d.exchange.usd`)
``.usdz``                   OpenUSD package holding one ``.usdc``
``.obj`` ``.ply`` ``.stl``  the bark mesh alone, through trimesh
``.svg``                    the skeleton as a 2D line drawing (:mod:`lsys3d.exchange.svg`)
==========================  ====================================================

Every writer is atomic (a temporary file beside the target, renamed over it)
and deterministic (the same tree gives the same bytes).
"""

from __future__ import annotations

import importlib
import io
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import ExportError
from ..tree import Tree
from .atomic import check_target, write_bytes
from .common import ExportOptions, file_frame
from .gltf import check_options, write_glb, write_gltf
from .svg import write_svg

__all__ = ["SUPPORTED_SUFFIXES", "ExportOptions", "check_output", "export", "export_variants", "variant_paths"]


def _usd_writer(name: str) -> Callable:
    """``name`` of :mod:`lsys3d.exchange.usd`, loaded when a USD file is written: usd-core takes a while to
    import, and a run that writes glTF never needs it."""
    return getattr(importlib.import_module(".usd", __name__), name)


def _usd(tree, path, options):
    return _usd_writer("write_usd")(tree, path, options)


def _usdz(tree, path, options):
    return _usd_writer("write_usdz")(tree, path, options)


def _trimesh(tree, path, options):
    """The bark alone, in the file frame, through trimesh's exporters (no provenance: the formats have no place)."""
    import trimesh

    frame = file_frame(options)
    mesh = trimesh.Trimesh(tree.bark.vertices @ frame.T, tree.bark.faces, process=False)
    file_type = path.suffix[1:].lower()
    data = mesh.export(file_type=file_type)
    if isinstance(data, str):
        data = data.encode("utf-8")
    elif isinstance(data, io.BytesIO):  # pragma: no cover - older trimesh
        data = data.getvalue()
    return write_bytes(path, [memoryview(data)], options.no_clobber)


_WRITERS: dict[str, Callable[[Tree, Path, ExportOptions], Path]] = {
    ".glb": write_glb,
    ".gltf": write_gltf,
    ".usda": _usd,
    ".usdc": _usd,
    ".usd": _usd,
    ".usdz": _usdz,
    ".obj": _trimesh,
    ".ply": _trimesh,
    ".stl": _trimesh,
    ".svg": write_svg,
}

#: The file suffixes :func:`export` can write.
SUPPORTED_SUFFIXES: tuple[str, ...] = tuple(_WRITERS)


def check_output(path: str | os.PathLike, options: ExportOptions | None = None) -> Path:
    """Check, before any long work, that :func:`export` could write ``path``.

    Raises :class:`~lsys3d.errors.ExportError` for an unknown suffix, options
    the format cannot honour (glTF in centimetres or Z up), a missing or
    unwritable folder, or an existing file with ``no_clobber``; leaves nothing
    behind (the folder is tested by creating and removing an empty hidden file).

    Examples
    --------
    >>> check_output("tree.fbx")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
      ...
    lsys3d.errors.ExportError: tree.fbx: unknown suffix '.fbx'; supported: .glb, .gltf, .usda, ...
    """
    path = Path(path)
    options = ExportOptions() if options is None else options
    if not isinstance(options, ExportOptions):
        raise ExportError(f"{path}: options must be an ExportOptions, not {type(options).__name__}")
    suffix = path.suffix.lower()
    if suffix not in _WRITERS:
        what = f"unknown suffix {suffix!r}" if suffix else "no suffix"
        raise ExportError(f"{path}: {what}; supported: {', '.join(SUPPORTED_SUFFIXES)}")
    if suffix in (".glb", ".gltf"):
        check_options(options, str(path))
    check_target(path, options.no_clobber)
    return path


def export(tree: Tree, path: str | os.PathLike, options: ExportOptions | None = None) -> Path:
    """Write ``tree`` to ``path`` in the format its suffix names.

    Parameters
    ----------
    tree : Tree
        The asset: bark, leaves, skeleton, materials and provenance.
    path : str or path-like
        Target file; the suffix (case-insensitive) picks the format, see
        :data:`SUPPORTED_SUFFIXES`.  The folder must exist.
    options : ExportOptions, optional
        Units, up axis, leaf instancing, skeleton curves, no_clobber.
        Default: metres, Y up, the format's leaf representation, no curves.

    Returns
    -------
    pathlib.Path
        The file written (for ``.gltf`` the ``.bin`` lies beside it).

    Raises
    ------
    ExportError
        ``path: reason`` for an unknown suffix, a missing or unwritable
        folder, a full disk, an existing file with ``no_clobber``, or a tree
        that cannot be written.  The target is never left half-written.

    Examples
    --------
    >>> from lsys3d.exchange import export, ExportOptions
    >>> export(tree, "tree.usdc", ExportOptions(up_axis="Z"))  # doctest: +SKIP
    PosixPath('tree.usdc')
    """
    path = Path(path)
    options = ExportOptions() if options is None else options
    check_output(path, options)  # fail before the (possibly long) gathering
    if not isinstance(tree, Tree):
        raise ExportError(f"{path}: expected a lsys3d Tree, got {type(tree).__name__}")
    return _WRITERS[path.suffix.lower()](tree, path, options)


_USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")


def variant_paths(path: str | os.PathLike, count: int) -> list[Path]:
    """Where :func:`export_variants` writes ``count`` siblings: one USD file, else ``<stem>_<i><suffix>``.

    Examples
    --------
    >>> [p.name for p in variant_paths("out/tree.glb", 3)]
    ['tree_0.glb', 'tree_1.glb', 'tree_2.glb']
    >>> [p.name for p in variant_paths("tree.usdc", 3)]
    ['tree.usdc']
    """
    path = Path(path)
    if path.suffix.lower() in _USD_SUFFIXES:
        return [path]
    return [path.with_name(f"{path.stem}_{i}{path.suffix}") for i in range(count)]


def export_variants(trees: Sequence[Tree], path: str | os.PathLike, options: ExportOptions | None = None) -> list[Path]:
    """Write siblings of one plant: a USD file with a variant set, or one file per tree.

    Parameters
    ----------
    trees : sequence of Tree
        The siblings, e.g. one grammar grown with seeds 7, 8, 9.
    path : str or path-like
        For a USD suffix, the one file to write: the root prim gets the
        variant set ``seed`` with one variant per tree, named ``seed_<seed>``
        after the tree's provenance (``seed_7``, ``seed_8``...), the first selected.
        For any other suffix, the pattern of the files
        (:func:`variant_paths`): ``tree.glb`` gives ``tree_0.glb``,
        ``tree_1.glb``...
    options : ExportOptions, optional

    Returns
    -------
    list of pathlib.Path
        The files written.

    Raises
    ------
    ExportError
        As :func:`export`; also for no trees or two trees with the same seed
        (their variants would have the same name).  With ``no_clobber`` every
        target is checked before anything is written.
    """
    path = Path(path)
    options = ExportOptions() if options is None else options
    trees = list(trees)
    if not trees or not all(isinstance(t, Tree) for t in trees):
        raise ExportError(f"{path}: expected one or more lsys3d Trees")
    targets = variant_paths(path, len(trees))
    for target in targets:  # the files written, not the pattern (tree.glb itself is not written)
        check_output(target, options)
    if path.suffix.lower() in _USD_SUFFIXES:
        names = [f"seed_{t.provenance.seed if t.provenance is not None else i}" for i, t in enumerate(trees)]
        if len(set(names)) != len(names):
            raise ExportError(f"{path}: two trees have the same seed, so their variants would share a name: {names}")
        return [_usd_writer("write_usd_variants")(trees, names, path, options)]
    return [export(tree, target, options) for tree, target in zip(trees, targets, strict=True)]
