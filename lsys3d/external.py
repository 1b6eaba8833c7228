"""Every file lsys3d reads, read one way; every path it follows, followed by one rule.

**One reader.**  Grammar files, cpfg ``#include`` and view files, jobs files,
batch manifests, libraries, textures and models are all opened by
:func:`open_regular`: without blocking (``O_NONBLOCK``: opening a pipe with no
writer must not hang), then checked with ``fstat`` on the open descriptor (so a
file swapped after a check cannot slip through): a regular file only, never a
folder, device, pipe or socket, and no larger than the caller's limit before
a byte is read.  :func:`read_file` reads such a file as bounded bytes,
:func:`read_lines` as bounded lines (a manifest), and :func:`load_json`
parses JSON whose nesting is checked first (a deeply nested line is refused
with one line, never a ``RecursionError``).  What the bytes mean is decided
by their readers (:mod:`lsys3d.images`, :mod:`lsys3d.look.surfaces`, the
dialects), which parse them as data: nothing a file holds is ever run.

**One rule for paths.**  A path the user gives on the command line or to a
function is taken as it is.  A path that a file names (a cpfg ``#include``, a
library's asset, a manifest's file) is resolved, symlinks too, and must stay
inside the folder the user named (:func:`inside`): a symlink or an absolute
name cannot lead a reader out of it.

A grammar's ``[materials]`` and ``[surfaces]`` tables may name files::

    [materials]
    bark = { texture = "textures/bark.png" }

    [surfaces]
    leaf = "models/maple_leaf.glb"

A relative name is taken relative to the folder of the grammar file (the
current folder for a grammar built in Python or read from a string); an
absolute name as it is (a grammar is the user's own file, like a command line).
"""

from __future__ import annotations

import contextlib
import contextvars
import io
import json
import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import AssetError, clip, os_reason

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = [
    "MAX_JSON_DEPTH",
    "FileRefused",
    "confined_to",
    "grammar_folder",
    "inside",
    "json_depth",
    "load_json",
    "load_scene",
    "open_regular",
    "read_file",
    "read_lines",
    "resolve",
]

MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays and objects :func:`load_json` parses (lsys3d writes at most 6)."""


class FileRefused(AssetError):
    """A file that cannot be read (``path: reason``); ``path`` and ``reason`` are kept apart for callers that
    report it in their own terms (a grammar's ``file:line:col``, a jobs file's entry)."""

    def __init__(self, path, reason: str):
        self.path, self.reason = path, reason
        super().__init__(f"{clip(str(path), 100)}: {reason}")


def grammar_folder(grammar) -> Path:
    """The folder relative names in ``grammar`` are taken from: its file's folder, else the current folder.

    >>> from lsys3d import Grammar
    >>> grammar_folder(Grammar(axiom="F", source="plants/oak.toml")).as_posix()
    'plants'
    >>> grammar_folder(Grammar(axiom="F")) == Path.cwd()
    True
    """
    source = str(getattr(grammar, "source", "") or "")
    if not source or source.startswith("<"):
        return Path.cwd()
    return Path(source).parent


def resolve(folder: Path, name, what: str) -> Path:
    """The path of the file ``name`` (a string from a grammar) relative to ``folder``.

    Raises
    ------
    AssetError
        ``name`` is not a non-empty string, or holds a NUL character.
    """
    if not isinstance(name, str) or not name.strip():
        raise AssetError(f"{what} must be a file name (a non-empty string), not {clip(repr(name))}")
    if "\0" in name:
        raise AssetError(f"{what}: a file name cannot hold a NUL character")
    path = Path(name)
    return path if path.is_absolute() else folder / path


def inside(folder: str | os.PathLike, name: str | os.PathLike, what: str) -> Path:
    """``folder / name`` resolved (every symlink followed), refused unless it is inside ``folder`` (resolved).

    The rule for a path a file names: a cpfg ``#include``, an asset of a
    library, a file of a manifest.  ``name`` may be relative (to ``folder``)
    or absolute; either way the file it leads to must be in ``folder`` or
    below.  It need not exist.

    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> inside(root, "a/b.usdc", "asset") == root.resolve() / "a" / "b.usdc"
    True
    >>> try:
    ...     inside(root, "../b.usdc", "asset")
    ... except FileRefused as exc:
    ...     print(exc.reason.split(" the folder")[0])
    the asset is outside

    Raises
    ------
    FileRefused
        ``name: the what is outside the folder FOLDER`` (also for a NUL or a symlink loop).
    """
    name = os.fspath(name)
    if "\0" in str(name):
        raise FileRefused(name, f"the {what}'s name holds a NUL character")
    try:
        root = Path(folder).resolve()
        path = (root / name).resolve()
    except (OSError, RuntimeError) as exc:  # a symlink loop (RuntimeError before Python 3.13)
        raise FileRefused(name, f"cannot follow the {what}'s path: {os_reason(exc)}") from None
    if path != root and root not in path.parents:
        raise FileRefused(name, f"the {what} is outside the folder {clip(str(root), 80)} (symlinks followed)")
    return path


_CONFINED: contextvars.ContextVar[Path | None] = contextvars.ContextVar("lsys3d_confined_to", default=None)


@contextlib.contextmanager
def confined_to(folder: str | os.PathLike) -> Iterator[Path]:
    """Within the block, :func:`open_regular` (so every reader) opens only files inside ``folder`` (symlinks
    resolved).

    The editor's server (``lsys3d edit``) grows grammars sent over HTTP: the files they name must stay in the
    folder of the grammar being edited.  A context variable, so that other threads are not affected.
    """
    root = Path(folder).resolve()
    token = _CONFINED.set(root)
    try:
        yield root
    finally:
        _CONFINED.reset(token)


def _check_confined(path, what: str) -> None:
    root = _CONFINED.get()
    if root is None:
        return
    try:
        within = Path(path).resolve().is_relative_to(root)
    except (OSError, RuntimeError):  # a symlink loop
        within = False
    if not within:
        raise FileRefused(path, f"the {what} is outside the grammar's folder {clip(str(root), 100)}")


def open_regular(path: str | os.PathLike, limit: int, what: str, limit_name: str, *, follow: bool = True) -> int:
    """A file descriptor open for reading on the regular file ``path`` of at most ``limit`` bytes.

    Opened with ``O_NONBLOCK`` (a pipe with no writer must not hang the
    open), then checked with ``fstat`` on the descriptor: a folder, device,
    pipe or socket is refused, and so is a file over ``limit`` bytes, before
    anything is read.  ``follow=False`` refuses a symlink (``O_NOFOLLOW``).
    The caller closes the descriptor.

    Raises
    ------
    FileRefused
        ``path: reason``: no such file, a symlink (``follow=False``), a
        folder, not a regular file, too large, unreadable.
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    if not follow:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    if "\0" in os.fspath(path):
        raise FileRefused(path, "a file name cannot hold a NUL character")
    _check_confined(path, what)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise FileRefused(path, f"no such {what if what.endswith('file') else what + ' file'}") from None
    except OSError as exc:
        if not follow and os.path.islink(path):
            raise FileRefused(path, f"the {what} is a symlink; lsys3d reads and writes it only as a file") from None
        raise FileRefused(path, f"cannot read the {what}: {os_reason(exc)}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise FileRefused(path, f"the {what} is a folder, not a file")
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused(path, f"the {what} is not a regular file (a device, pipe or socket)")
        if info.st_size > limit:
            raise FileRefused(path, f"the {what} is {info.st_size:,} bytes, more than {limit:,} ({limit_name})")
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_file(path: str | os.PathLike, limit: int, what: str, limit_name: str, *, follow: bool = True) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them (:func:`open_regular`).

    Parameters
    ----------
    path : path-like
    limit : int
        Largest size accepted, in bytes.
    what : str
        What the file is, for messages (``texture``, ``leaf model``, ``grammar file``).
    limit_name : str
        Where the limit is set, for messages (``lsys3d.images.MAX_IMAGE_BYTES``).
    follow : bool
        Whether a symlink is followed.

    Raises
    ------
    FileRefused
        ``path: reason`` -- no such file, not a regular file, too large, unreadable.
    """
    fd = open_regular(path, limit, what, limit_name, follow=follow)
    try:
        chunks, size = [], 0
        while size <= limit:  # a file that grows while read still stops at the limit
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise FileRefused(path, f"the {what} is more than {limit:,} bytes ({limit_name})")
        return b"".join(chunks)
    except OSError as exc:
        raise FileRefused(path, f"cannot read the {what}: {os_reason(exc)}") from None
    finally:
        os.close(fd)


def read_lines(
    path: str | os.PathLike, limit: int, line_limit: int, what: str, limit_name: str, *, follow: bool = True
) -> Iterator[tuple[int, bytes | None]]:
    """The lines of the regular file ``path`` (at most ``limit`` bytes), one at a time: ``(number, bytes)``.

    A line longer than ``line_limit`` bytes is given as ``(number, None)``
    without being held; the trailing newline is left out.  Memory stays
    within ``line_limit`` whatever the file's size.

    Raises
    ------
    FileRefused
        As :func:`open_regular`.
    """
    fd = open_regular(path, limit, what, limit_name, follow=follow)
    try:
        with os.fdopen(fd, "rb", closefd=False) as f:
            number, total = 0, 0
            while total <= limit:
                raw = f.readline(line_limit + 1)
                if not raw:
                    return
                total += len(raw)
                number += 1
                if len(raw) > line_limit and not raw.endswith(b"\n"):
                    while raw and not raw.endswith(b"\n") and total <= limit:  # skip the rest of the long line
                        raw = f.readline(1 << 20)
                        total += len(raw)
                    yield number, None
                    continue
                yield number, raw.rstrip(b"\r\n")
    except OSError as exc:
        raise FileRefused(path, f"cannot read the {what}: {os_reason(exc)}") from None
    finally:
        os.close(fd)


_OPEN = np.zeros(256, np.int8)
_OPEN[[ord("["), ord("{")]] = 1
_OPEN[[ord("]"), ord("}")]] = -1


def json_depth(text: str | bytes) -> int:
    """How deep arrays and objects nest in the JSON ``text`` (brackets inside strings not counted).

    >>> json_depth('{"a": [1, [2, "]]]"]], "b": {}}')
    3
    """
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    codes = np.frombuffer(data, np.uint8)
    if not len(codes):
        return 0
    quote = codes == ord('"')
    if quote.any():  # a quote escaped by an odd run of backslashes does not end a string
        slash = (codes == ord("\\")).astype(np.int64)
        run = np.cumsum(slash)
        last_reset = np.maximum.accumulate(np.where(slash == 0, run, 0))
        before = np.concatenate(([0], (run - last_reset)[:-1]))  # backslashes right before each byte
        quote &= before % 2 == 0
    in_string = (np.cumsum(quote) - quote) % 2 == 1
    steps = np.where(in_string | quote, 0, _OPEN[codes]).astype(np.int64)
    return int(np.cumsum(steps).max(initial=0))


def load_json(text: str | bytes, max_depth: int = MAX_JSON_DEPTH):
    """``json.loads(text)``, refused with a ``ValueError`` when it nests deeper than ``max_depth``.

    >>> load_json("[" * 100 + "]" * 100)
    Traceback (most recent call last):
    ...
    ValueError: JSON nested 100 deep, more than 64 (lsys3d.external.MAX_JSON_DEPTH)
    """
    depth = json_depth(text)
    if depth > max_depth:
        raise ValueError(f"JSON nested {depth} deep, more than {max_depth} (lsys3d.external.MAX_JSON_DEPTH)")
    return json.loads(text)


def load_scene(data: bytes, file_type: str, shown: str, max_triangles: int, too_many: Callable[[str, int], str]):
    """A model file's bytes as a ``trimesh.Scene`` with triangles, parsed as data: one clear line when it is not.

    ``too_many(shown, count)`` words the error for more than ``max_triangles`` triangles (a binary STL
    is refused from its header, before parsing).

    Raises
    ------
    AssetError
        ``shown: what``: not a readable model of that type, no triangles, too many.
    """
    import trimesh

    if file_type == "stl" and len(data) >= 84 and data[:5].lower() != b"solid":
        (count,) = np.frombuffer(data[80:84], "<u4")
        if count > max_triangles:  # binary STL says its size up front: refuse before parsing
            raise AssetError(too_many(shown, int(count)))
    try:
        scene = trimesh.load(io.BytesIO(data), file_type=file_type, process=False, force="scene")
        meshes = {k: g for k, g in scene.geometry.items() if hasattr(g, "faces") and len(g.faces)}
        if not meshes:
            raise AssetError(f"{shown}: the model has no triangles")
        # flattening copies each mesh once per node that places it: count the copies before making them
        placed = scene.graph.geometry_nodes
        triangles = sum(len(g.faces) * max(len(placed.get(k, ())), 1) for k, g in meshes.items())
        if triangles > max_triangles:
            raise AssetError(too_many(shown, triangles))
    except AssetError:
        raise
    except Exception as exc:  # trimesh's readers raise anything on a damaged file: one line, never a traceback
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise AssetError(f"{shown}: not a readable .{file_type} model ({clip(reason, 80)})") from None
    return scene
