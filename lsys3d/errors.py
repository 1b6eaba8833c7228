"""The exceptions lsys3d raises for user mistakes and impossible geometry.

Every error a user can cause is an :class:`LSystemError`; the CLI prints its
message on one line and exits 1.  Messages read ``where: what``.
"""

from __future__ import annotations

__all__ = [
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
    "PreviewError",
]


def clip(text: str, width: int = 60) -> str:
    """``text`` short enough to quote in a one-line message: at most ``width`` characters, the middle elided.

    >>> clip("F(" + "x+" * 50 + "1)", 20)
    'F(x+x+x+x...x+x+x+1)'
    """
    text = str(text)
    if len(text) <= width:
        return text
    head = (width - 3 + 1) // 2
    return text[:head] + "..." + text[len(text) - (width - 3 - head) :]


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
        self.reason = message
        self.source = source
        self.line = line
        self.col = col
        where = source
        if line is not None:
            where += f":{line}"
            if col is not None:
                where += f":{col}"
        super().__init__(f"{where}: {message}")


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
        self.reason = message
        self.source = source
        self.line = line
        self.col = col
        where = source
        if line is not None:
            where += f":{line}"
            if col is not None:
                where += f":{col}"
        super().__init__(f"{where}: {message}")


class ForestError(LSystemError):
    """A library that cannot be read or a forest that cannot be scattered (the message names the file)."""
