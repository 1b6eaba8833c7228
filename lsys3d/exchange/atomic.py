"""Atomic file replacement: write beside the target, then rename over it.

Every writer in :mod:`lsys3d.exchange` goes through :func:`atomic_path` or
:func:`write_bytes`, so that an error, a full disk or Ctrl-C never leaves a
truncated asset where a good one was, and never leaves a temporary file
behind.  Operating-system errors become :class:`~lsys3d.errors.ExportError`
with a one-line ``path: reason`` message; ``KeyboardInterrupt`` is cleaned up
after and re-raised as it is.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import ExportError

__all__ = ["atomic_path", "check_target", "write_bytes", "write_chunks"]


def _reason(exc: BaseException) -> str:
    """One line describing an OS error, without the file name (we print our own)."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror[:1].lower() + exc.strerror[1:]
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def check_target(path: Path, no_clobber: bool) -> None:
    """Refuse early when ``path`` cannot be written (missing folder, existing file with ``no_clobber``).

    Raises
    ------
    ExportError
        ``path: reason``.
    """
    folder = path.parent
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise ExportError(f"{path}: folder {str(folder)!r} {what}")
    if path.is_dir():
        raise ExportError(f"{path}: is a folder")
    # Try it rather than ask os.access(), which says yes to root even where the file system refuses (sysfs,
    # read-only mounts), so that a folder nobody can write fails here and not after minutes of work.
    probe = _temp_name(path)
    try:
        os.close(os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except OSError as exc:
        raise ExportError(f"{path}: folder {str(folder)!r} is not writable ({_reason(exc)})") from None
    _remove(probe)
    if no_clobber and (path.exists() or path.is_symlink()):
        raise ExportError(f"{path}: file exists (no_clobber is set)")


def _temp_name(path: Path) -> Path:
    # Hidden, in the same folder (so the rename is atomic), ending in the real suffix because
    # some writers (USD) choose the file format from it.
    return path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")


def _publish(tmp: Path, path: Path, no_clobber: bool) -> None:
    if no_clobber:
        # link() fails if the target exists: no window where another writer's file is replaced
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise ExportError(f"{path}: file exists (no_clobber is set)") from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
                raise
            # file systems without hard links: check, then rename (a small race is acceptable)
            if path.exists():
                raise ExportError(f"{path}: file exists (no_clobber is set)") from None
            os.replace(tmp, path)
        else:
            os.unlink(tmp)
    else:
        os.replace(tmp, path)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, no_clobber: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it over ``path``.

    The body writes the temporary file by any means (a library that only
    writes to a path, such as USD, included).  When the body raises, the
    temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : path-like
        The final file.
    no_clobber : bool
        Refuse (``ExportError``) when ``path`` already exists.

    Raises
    ------
    ExportError
        When the folder is missing or unwritable, the disk is full, or
        ``path`` exists and ``no_clobber`` is set.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "a.txt") as tmp:
    ...     _ = tmp.write_text("hello")
    >>> sorted(p.name for p in folder.iterdir())
    ['a.txt']
    """
    path = Path(path)
    check_target(path, no_clobber)
    tmp = _temp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise ExportError(f"{path}: the writer produced no file")
        _publish(tmp, path, no_clobber)
    except ExportError:
        _remove(tmp)
        raise
    except OSError as exc:
        _remove(tmp)
        raise ExportError(f"{path}: {_reason(exc)}") from exc
    except BaseException:
        _remove(tmp)
        raise


def _remove(tmp: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()


def _write_chunks(f, chunks: Iterable[bytes | memoryview]) -> None:
    """Write every chunk to the open binary file ``f`` (a seam for tests that simulate a full disk)."""
    for chunk in chunks:
        f.write(chunk)


def write_chunks(tmp: Path, chunks: Iterable[bytes | memoryview], path: Path) -> None:
    """Write ``chunks`` into the new file ``tmp``; errors name ``path``, the file the user asked for."""
    try:
        with open(tmp, "xb") as f:
            _write_chunks(f, chunks)
    except OSError as exc:
        raise ExportError(f"{path}: {_reason(exc)}") from exc


def write_bytes(path: str | os.PathLike, chunks: Iterable[bytes | memoryview], no_clobber: bool = False) -> Path:
    """Write ``chunks`` (bytes-like, in order) to ``path`` atomically.

    Chunks are written one after the other without joining them, so a large
    binary buffer is never copied.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    with atomic_path(path, no_clobber) as tmp:
        write_chunks(tmp, chunks, path)
    return path
