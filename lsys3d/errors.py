"""The exceptions lsys3d raises for user mistakes and impossible geometry.

Every error a user can cause is an :class:`LSystemError`; the CLI prints its
message on one line and exits 1.  Messages read ``where: what``.
"""

from __future__ import annotations

import re

__all__ = [
    "AssetError",
    "BatchError",
    "DerivationError",
    "ExportError",
    "ForestError",
    "GeometryError",
    "GoldenError",
    "GrammarError",
    "InterpretError",
    "LSystemError",
    "LimitError",
    "OptionsError",
    "PreviewError",
    "SeedWarning",
]


# C0 and C1 controls (terminal escape sequences start with ESC, 0x1b, or CSI, 0x9b) but tab and newline,
# invisible direction marks and overrides (text that reads differently than it is), and lone surrogates
# (undecodable bytes of a file name, which a UTF-8 terminal cannot print)
_UNPRINTABLE = re.compile(
    "[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069\ud800-\udfff\ufffe\uffff]"
)


def _escape(match: re.Match) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: str) -> str:
    r"""``text`` safe to echo on a terminal: control characters, direction overrides and lone surrogates escaped.

    Every message that quotes user input (a key, a file or preset name, a rule) goes through this, so a
    grammar cannot clear the screen or retitle the terminal of whoever reads its error.  Tabs and line breaks
    stay (the CLI folds lines itself).

    >>> print(printable("tree\x1b[2J.toml"))
    tree\x1b[2J.toml
    """
    return _UNPRINTABLE.sub(_escape, str(text))


def clip(text: str, width: int = 60) -> str:
    """``text`` short enough to quote in a one-line message: at most ``width`` characters, the middle elided.

    Control characters are escaped (:func:`printable`).

    >>> clip("F(" + "x+" * 50 + "1)", 20)
    'F(x+x+x+x...x+x+x+1)'
    """
    text = printable(text)
    if len(text) <= width:
        return text
    head = (width - 3 + 1) // 2
    return text[:head] + "..." + text[len(text) - (width - 3 - head) :]


def os_reason(exc: BaseException) -> str:
    """What an operating-system error means, in one line and lower case, without the file name (callers name it).

    >>> os_reason(OSError(28, "No space left on device", "tree.glb"))
    'no space left on device'
    """
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror[:1].lower() + exc.strerror[1:]
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def _locate(error: Exception, message: str, source: str, line: int | None, col: int | None) -> None:
    """Give ``error`` its ``reason``, ``source``, ``line``, ``col`` and the text ``source:line:col: message``."""
    error.reason, error.source, error.line, error.col = message, source, line, col
    where = source
    if line is not None:
        where += f":{line}"
        if col is not None:
            where += f":{col}"
    Exception.__init__(error, f"{where}: {message}")


class LSystemError(Exception):
    """Base class of every error lsys3d raises for bad input."""


class GrammarError(LSystemError, ValueError):
    """A grammar that cannot be read: the message starts ``file:line:col:``.

    Parameters
    ----------
    message : str
        What is wrong.
    source : str
        File name, or a pseudo-name such as ``<string>`` or ``rules[2]``.
    line, col : int
        1-based position of the offending character, when known.
    """

    def __init__(self, message: str, source: str = "<grammar>", line: int | None = None, col: int | None = None):
        _locate(self, message, source, line, col)


class AssetError(LSystemError, ValueError):
    """A file a grammar names (a texture, a leaf or organ model) that cannot be used: ``path: what``.

    Read through :mod:`lsys3d.external`; the grammar's tables report it as a
    :class:`GrammarError` at the line of the entry that names the file.
    """


class OptionsError(LSystemError, ValueError):
    """A setting out of its range or of the wrong type: ``Class.field: what`` (or ``--flag: what``).

    Every options class (:mod:`lsys3d.options`) raises it, from one checker.
    """


class DerivationError(LSystemError, ArithmeticError):
    """Rewriting failed: a numeric error in a rule, or a result too large."""


class LimitError(DerivationError):
    """A configured resource limit would be exceeded (the message says how to raise it)."""


class InterpretError(LSystemError):
    """The turtle could not read a module string (unbalanced ``]``, open polygon...)."""


class GeometryError(LSystemError):
    """Geometry that cannot be built into a valid mesh."""


class ExportError(LSystemError, OSError):
    """A file could not be written (the message names the file)."""


class PreviewError(LSystemError):
    """A picture could not be rendered: no Blender to render with, or Blender failed (the message says which)."""


class GoldenError(LSystemError):
    """A golden file that cannot be read or used (the message names the file)."""


class BatchError(LSystemError, ValueError):
    """A jobs file that cannot be read, or a batch that cannot run: the message starts ``file:line:col:``.

    Jobs that fail (a grammar that does not parse, a limit hit, a lost worker)
    are not errors of the batch: they are recorded in its manifest.

    Parameters
    ----------
    message : str
        What is wrong.
    source : str
        The jobs file (or the output folder).
    line, col : int
        1-based position of the offending value, when known.
    """

    def __init__(self, message: str, source: str = "<jobs>", line: int | None = None, col: int | None = None):
        _locate(self, message, source, line, col)


class ForestError(LSystemError):
    """A library that cannot be read or a forest that cannot be scattered (the message names the file)."""


class SeedWarning(UserWarning):
    """A seed that changes nothing: the plant grows the same from every seed (``warnings``; the CLI logs it).

    :func:`lsys3d.pipeline.warn_if_identical` is its one home: ``generate(..., seed=s)`` and
    ``lsys3d generate --variants N`` both warn through it.
    """
