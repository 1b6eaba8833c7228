"""The grammar ``lsys3d edit`` edits: its one file, read and saved, never overwritten behind the user's back.

A :class:`Document` is the only file the editor's API reads or writes.  Saving replaces the file atomically
(:func:`lsys3d.exchange.atomic.write_bytes`: a temporary file beside it, renamed over it) and only when the
file on disk is still the one the page opened or last saved (its :class:`Version`: modification time and
SHA-256); otherwise it refuses with :class:`Conflict`, so a change made by another program is never lost.
A bundled preset opens read-only.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from ..errors import ExportError, GrammarError, LSystemError
from ..exchange.atomic import write_bytes
from ..lsystem.dialects import GRAMMAR_SUFFIXES
from ..lsystem.grammar import MAX_GRAMMAR_BYTES
from ..lsystem.presets import list_presets, preset_text

__all__ = ["EDITABLE_SUFFIXES", "Conflict", "Document", "ReadOnly", "Version"]

EDITABLE_SUFFIXES = GRAMMAR_SUFFIXES
"""The suffixes of the files the editor opens: lsys3d's TOML and the native dialects' (the files lsys3d reads)."""


class Conflict(LSystemError):
    """The file changed on disk since the page read it."""


class ReadOnly(LSystemError):
    """The grammar has no file of its own (a bundled preset)."""


@dataclass(frozen=True)
class Version:
    """What the file on disk was when the page read it: modification time (ns) and SHA-256 of its bytes."""

    mtime_ns: int
    sha256: str

    def to_json(self) -> dict:
        return {"mtime_ns": str(self.mtime_ns), "sha256": self.sha256}

    @classmethod
    def from_json(cls, data) -> Version:
        if not isinstance(data, dict):
            raise ValueError("version must be an object {mtime_ns, sha256}")
        try:
            return cls(int(data["mtime_ns"]), str(data["sha256"]))
        except (KeyError, TypeError, ValueError):
            raise ValueError("version must be an object {mtime_ns, sha256}") from None


MISSING = Version(0, "")
"""The version of a file that does not exist yet (``lsys3d edit new.toml`` creates it on the first save)."""


@dataclass(frozen=True)
class Document:
    """The grammar being edited.

    Attributes
    ----------
    path : Path or None
        Its file (absolute); None for a bundled preset.
    name : str
        The file's name, or the preset's.
    suffix : str
        The dialect's suffix: ``.toml``, ``.lpy``, ``.l`` or ``.ls``.
    """

    path: Path | None
    name: str
    suffix: str

    @classmethod
    def open(cls, spec: str) -> Document:
        """The grammar file ``spec`` (made on the first save when missing), or a bundled preset by name."""
        path = Path(spec)
        if path.suffix not in EDITABLE_SUFFIXES and "/" not in spec and spec in list_presets():
            return cls(None, spec, ".toml")
        if path.suffix not in EDITABLE_SUFFIXES:
            raise GrammarError(
                f"the editor opens {', '.join(EDITABLE_SUFFIXES)} files or a bundled preset's name", spec
            )
        path = path.absolute()
        if path.exists() and not path.is_file():
            raise GrammarError("not a regular file", str(path))
        if not path.parent.is_dir():
            raise GrammarError(f"folder {str(path.parent)!r} does not exist", str(path))
        return cls(path, path.name, path.suffix)

    @property
    def folder(self) -> Path:
        """The only folder the grammar's textures and models may be read from."""
        return self.path.parent if self.path is not None else Path.cwd()

    @property
    def source(self) -> str:
        """The name errors give: the file's path, or ``presets/<name>.toml``."""
        return str(self.path) if self.path is not None else f"presets/{self.name}.toml"

    def read(self) -> tuple[str, Version]:
        """The text and its version; a missing file starts from the default preset's text."""
        if self.path is None:
            return preset_text(self.name), MISSING
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return (preset_text("tree3d") if self.suffix == ".toml" else ""), MISSING
        except OSError as exc:
            raise GrammarError(f"cannot read: {exc.strerror or exc}", str(self.path)) from None
        if len(data) > MAX_GRAMMAR_BYTES:
            raise GrammarError(f"larger than {MAX_GRAMMAR_BYTES} bytes", str(self.path))
        return data.decode("utf-8", errors="replace"), self.version_of(data)

    def version_of(self, data: bytes) -> Version:
        return Version(os.stat(self.path).st_mtime_ns, hashlib.sha256(data).hexdigest())

    def current(self) -> Version:
        """The version of the file on disk now."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return MISSING
        return self.version_of(data)

    def save(self, text: str, opened: Version) -> Version:
        """Write ``text`` over the file, atomically, if the file is still ``opened``; the new version.

        Raises
        ------
        ReadOnly
            For a bundled preset.
        Conflict
            When the file changed on disk since ``opened`` (another program wrote it): nothing is written.
        ExportError
            When the file cannot be written (no room, no permission).
        """
        if self.path is None:
            raise ReadOnly(
                f"{self.name}: a bundled preset is read-only; run 'lsys3d edit my-plant.toml' to edit a copy"
            )
        data = text.encode("utf-8")
        if len(data) > MAX_GRAMMAR_BYTES:
            raise ExportError(f"{self.path}: the grammar is larger than {MAX_GRAMMAR_BYTES} bytes")
        now = self.current()
        if now != opened:
            raise Conflict(
                f"{self.path}: the file changed on disk since it was opened; nothing was written "
                "(reload it, or copy your text elsewhere first)"
            )
        write_bytes(self.path, [data])
        return self.version_of(data)
