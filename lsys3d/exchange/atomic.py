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
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import ExportError, os_reason

__all__ = ["atomic_path", "check_target", "scratch_path", "write_bytes", "write_chunks", "write_failure"]


NAME_MAX = 255
"""Longest file name (one path component, in bytes) most file systems take; temporary names stay within it."""


def check_target(path: Path, no_clobber: bool) -> None:
    """Refuse early when ``path`` cannot be written (missing folder, existing file with ``no_clobber``).

    Raises
    ------
    ExportError
        ``path: reason``, the reason from the operating system's error
        number where there is one (a symlink loop, a name too long, no
        permission).
    """
    folder = path.parent
    try:
        if not stat.S_ISDIR(os.stat(folder).st_mode):
            raise ExportError(f"{path}: folder {str(folder)!r} is not a folder")
    except FileNotFoundError:
        raise ExportError(f"{path}: folder {str(folder)!r} does not exist") from None
    except NotADirectoryError:
        raise ExportError(f"{path}: folder {str(folder)!r} is not a folder") from None
    except ValueError:  # a NUL character
        raise ExportError(f"{path}: a file name cannot hold a NUL character") from None
    except OSError as exc:  # a symlink loop, a name too long, no permission to look
        raise ExportError(f"{path}: folder {str(folder)!r}: {os_reason(exc)}") from None
    try:
        is_folder = stat.S_ISDIR(os.stat(path).st_mode)
    except (FileNotFoundError, NotADirectoryError):
        is_folder = False
    except OSError as exc:
        if exc.errno != errno.ELOOP:  # a link that loops is replaced like any other file
            raise ExportError(f"{path}: {os_reason(exc)}") from None
        is_folder = False
    if is_folder:
        raise ExportError(f"{path}: is a folder")
    # Try it rather than ask os.access(), which says yes to root even where the file system refuses (sysfs,
    # read-only mounts), so that a folder nobody can write fails here and not after minutes of work.
    probe = _temp_name(path)
    try:
        os.close(os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except OSError as exc:
        raise ExportError(f"{path}: folder {str(folder)!r} is not writable ({os_reason(exc)})") from None
    _remove(probe)
    if no_clobber and (path.exists() or path.is_symlink()):
        raise ExportError(f"{path}: file exists (no_clobber is set)")


def _temp_name(path: Path, suffix: str | None = None) -> Path:
    """A new hidden name beside ``path``: ``.<stem>.<8 hex digits>.tmp<suffix>``, shortened to fit NAME_MAX.

    In the same folder (so the rename is atomic), ending in the real suffix because some writers (USD)
    choose the file format from it.
    """
    suffix = path.suffix if suffix is None else suffix
    tail = f".{secrets.token_hex(4)}.tmp{suffix}"
    stem = path.stem
    room = NAME_MAX - 16 - 1 - len(os.fsencode(tail))  # 16 to spare: USD makes its own temporary name from ours
    while stem and len(os.fsencode(stem)) > room:
        stem = stem[: len(stem) - max(1, (len(os.fsencode(stem)) - room) // 4)]
    return path.with_name(f".{stem}{tail}")


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
        raise ExportError(f"{path}: {os_reason(exc)}") from exc
    except BaseException:
        _remove(tmp)
        raise


def _remove(tmp: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()


@contextlib.contextmanager
def scratch_path(path: str | os.PathLike, suffix: str) -> Iterator[Path]:
    """A temporary file name beside ``path`` (ending in ``suffix``) for a library that writes only to paths;
    the file is removed on the way out, whatever happens (an error, Ctrl-C, SIGTERM)."""
    tmp = _temp_name(Path(path), suffix)
    try:
        yield tmp
    finally:
        _remove(tmp)


def write_failure(tmp: Path, need: int) -> str | None:
    """Why a library that writes with its own I/O (USD) failed at ``tmp``: the operating system's reason, found by
    trying to reserve ``need`` bytes more than ``tmp`` holds (no space left, file too large, quota), or None.

    The library's own message for a full disk is a C++ internal ("crate file corrupt"); asking the file system
    the same question gives the user the real cause.  ``tmp`` is left for the caller to remove.
    """
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT, 0o600)
        try:
            size = os.fstat(fd).st_size
            if hasattr(os, "posix_fallocate"):
                os.posix_fallocate(fd, size, max(int(need), 1))
            else:  # pragma: no cover - no fallocate: write it
                os.lseek(fd, size, os.SEEK_SET)
                for _ in range(0, max(int(need), 1), 1 << 20):
                    os.write(fd, bytes(1 << 20))
        finally:
            os.close(fd)
    except OSError as exc:
        return os_reason(exc)
    return None


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
        raise ExportError(f"{path}: {os_reason(exc)}") from exc


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
