"""Files a grammar names -- textures, leaf and organ models -- found beside the grammar and read as bounded bytes.

A grammar's ``[materials]`` and ``[surfaces]`` tables may name files::

    [materials]
    bark = { texture = "textures/bark.png" }

    [surfaces]
    leaf = "models/maple_leaf.glb"

A relative name is taken relative to the folder of the grammar file (the
current folder for a grammar built in Python or read from a string); an
absolute name as it is.  The file is read here, once, as bytes: only regular
files (never a device or a pipe, which could block or never end), at most a
given number of bytes, checked before anything is allocated.  What the bytes
mean is decided by their readers (:mod:`lsys3d.images`, :mod:`lsys3d.look.surfaces`),
which parse them as data: nothing a file holds is ever run.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import stat
from collections.abc import Iterator
from pathlib import Path

from .errors import AssetError, clip, os_reason

__all__ = ["confined_to", "grammar_folder", "read_file", "resolve"]


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


_CONFINED: contextvars.ContextVar[Path | None] = contextvars.ContextVar("lsys3d_confined_to", default=None)


@contextlib.contextmanager
def confined_to(folder: str | os.PathLike) -> Iterator[Path]:
    """Within the block, :func:`read_file` reads only files inside ``folder`` (symlinks resolved).

    The editor's server (``lsys3d edit``) grows grammars sent over HTTP: the files they name must stay in the
    folder of the grammar being edited.  A context variable, so that other threads are not affected.
    """
    root = Path(folder).resolve()
    token = _CONFINED.set(root)
    try:
        yield root
    finally:
        _CONFINED.reset(token)


def _check_confined(path: Path, what: str, shown: str) -> None:
    root = _CONFINED.get()
    if root is None:
        return
    try:
        inside = Path(path).resolve().is_relative_to(root)
    except (OSError, RuntimeError):  # a symlink loop
        inside = False
    if not inside:
        raise AssetError(f"{shown}: the {what} is outside the grammar's folder {clip(str(root), 100)}")


def read_file(path: Path, limit: int, what: str, limit_name: str) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them.

    Parameters
    ----------
    path : Path
    limit : int
        Largest size accepted, in bytes.
    what : str
        What the file is, for messages (``texture``, ``leaf model``).
    limit_name : str
        Where the limit is set, for messages (``lsys3d.images.MAX_IMAGE_BYTES``).

    Raises
    ------
    AssetError
        ``path: what`` -- no such file, not a regular file, too large, unreadable.
    """
    shown = clip(str(path), 100)
    _check_confined(path, what, shown)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)  # non-blocking: opening a pipe with no writer must not hang
    except FileNotFoundError:
        raise AssetError(f"{shown}: no such {what} file") from None
    except OSError as exc:
        raise AssetError(f"{shown}: cannot read the {what}: {os_reason(exc)}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise AssetError(f"{shown}: the {what} is a folder, not a file")
        if not stat.S_ISREG(info.st_mode):
            raise AssetError(f"{shown}: the {what} is not a regular file (a device, pipe or socket)")
        if info.st_size > limit:
            raise AssetError(f"{shown}: the {what} is {info.st_size:,} bytes, more than {limit:,} ({limit_name})")
        chunks, size = [], 0
        while size <= limit:  # a file that grows while read still stops at the limit
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise AssetError(f"{shown}: the {what} is more than {limit:,} bytes ({limit_name})")
        return b"".join(chunks)
    except OSError as exc:
        raise AssetError(f"{shown}: cannot read the {what}: {os_reason(exc)}") from None
    finally:
        os.close(fd)
