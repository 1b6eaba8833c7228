"""Where things are in a grammar's text: offsets to lines and columns, the TOML file's strings located, and
:class:`~lsys3d.errors.GrammarError` built with ``file:line:col`` (:mod:`lsys3d.lsystem.grammar`
reads files with it)."""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable

import numpy as np

from ..errors import GrammarError

TABLES = ("defines", "turtle", "form", "materials", "surfaces", "leaves", "environment", "blocks", "growth")
"""A grammar's tables (TOML ``[name]``), in the order recipes and provenance write them: the one list of them."""

_KEYS = {
    "name",
    "description",
    "group",
    "dialect",
    "axiom",
    "premise",
    "rules",
    "homomorphism",
    "homomorphism_depth",
    "decomposition",
    "decomposition_depth",
    "iterations",
    "angle",
    "seed",
    "ignore",
    "consider",
    "modules",
    "functions",
    *TABLES,
}


_RULE_LISTS = ("rules", "decomposition", "homomorphism")


# maps an offset in a piece of text to (line, col); line None when unknown
Where = Callable[[int], tuple[int | None, int | None]]


def _api_where(label: str) -> Where:
    """Positions in a string given through the Python API: line 1 of a pseudo-file named ``label``."""

    def where(offset):
        return None, offset + 1

    where.label = label
    return where


def _loc(source: str, where: Where, offset: int):
    line, col = where(offset)
    if line is None:
        label = getattr(where, "label", "<grammar>")
        return (label if source in ("<grammar>", "<string>") else f"{source}:{label}"), 1, col
    return source, line, col


def _error(message: str, source: str, where: Where, offset: int) -> GrammarError:
    return GrammarError(message, *_loc(source, where, offset))


def _toml_error(exc: tomllib.TOMLDecodeError, source: str) -> GrammarError:
    msg = str(exc)
    m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
    if m:
        reason = msg[: m.start()].strip()
        return GrammarError(f"TOML syntax error: {reason}", source, int(m.group(1)), int(m.group(2)))
    m = re.search(r"\(at end of document\)", msg)
    reason = msg[: m.start()].strip() if m else msg
    return GrammarError(f"TOML syntax error: {reason} (at end of file)", source)


def table_key_line(text: str, table: str, key: str) -> int | None:
    """Line of ``key`` inside the TOML table ``[table]`` (or of the table itself), for error positions."""
    start = _key_line(text, table)
    if start is None:
        return None
    lines = text.splitlines()
    pattern = re.compile(rf"^[ \t]*[\"']?{re.escape(key)}[\"']?[ \t]*=")
    for number in range(start + 1, len(lines) + 1):
        line = lines[number - 1]
        if re.match(r"^[ \t]*\[", line):
            break
        if pattern.match(line):
            return number
    return start


def table_error(grammar, table: str, key: str, what: str) -> GrammarError:
    """``[table] what`` at the line and column where ``key`` is written in the grammar's ``[table]``.

    The table's own line when the key is not written there; no position for a
    grammar without text (built in Python).  The one error of a bad entry in
    any of a grammar's tables (:data:`TABLES`), ``[turtle]`` too.

    >>> g = type("G", (), {"text": '[form]\\n  flare = "x"\\n', "source": "g.toml"})()
    >>> str(table_error(g, "form", "flare", "flare: must be a number"))
    'g.toml:2:3: [form] flare: must be a number'
    """
    text = getattr(grammar, "text", None)
    line = table_key_line(text, table, str(key)) if text else None
    col = None
    if line is not None:
        written = text.splitlines()[line - 1]
        col = len(written) - len(written.lstrip()) + 1  # where the key (or the table's header) starts
    return GrammarError(f"[{table}] {what}", grammar.source, line, col)


def _key_line(text: str, key: str) -> int | None:
    m = re.search(rf"^[ \t]*[\"']?{re.escape(key)}[\"']?[ \t]*=", text, re.MULTILINE)
    if m is None:
        m = re.search(rf"^[ \t]*\[[ \t]*{re.escape(key)}[ \t]*\]", text, re.MULTILINE)
    return text.count("\n", 0, m.start()) + 1 if m else None


_ESCAPES = {"b": "\b", "t": "\t", "n": "\n", "f": "\f", "r": "\r", '"': '"', "\\": "\\", "e": "\x1b"}


def _scan_string(text: str, i: int):
    """Scan the TOML string literal starting at ``text[i]``.

    Returns ``(value, positions, end)`` where ``positions[k]`` is the index in
    ``text`` of the k-th decoded character (plus one entry for the end).
    """
    quote = text[i]
    triple = text.startswith(quote * 3, i)
    delim = quote * 3 if triple else quote
    j = i + len(delim)
    if triple and text.startswith("\n", j):
        j += 1
    elif triple and text.startswith("\r\n", j):
        j += 2
    value, pos = [], []
    while j < len(text):
        if text.startswith(delim, j):
            if triple:  # up to two quotes may end the content
                while text.startswith(delim, j + 1):
                    value.append(quote)
                    pos.append(j)
                    j += 1
            pos.append(j)
            return "".join(value), pos, j + len(delim)
        ch = text[j]
        if ch == "\n" and not triple:
            break
        if quote == '"' and ch == "\\":
            nxt = text[j + 1 : j + 2]
            if nxt in _ESCAPES:
                value.append(_ESCAPES[nxt])
                pos.append(j)
                j += 2
                continue
            if nxt in ("u", "U"):
                n = 4 if nxt == "u" else 8
                try:
                    value.append(chr(int(text[j + 2 : j + 2 + n], 16)))
                except ValueError:
                    break
                pos.append(j)
                j += 2 + n
                continue
            if triple and nxt in " \t\r\n":  # line-ending backslash
                k = j + 1
                while k < len(text) and text[k] in " \t\r\n":
                    k += 1
                j = k
                continue
            break
        value.append(ch)
        pos.append(j)
        j += 1
    return None, None, j


def _string_tokens(text: str):
    """All string literals of a TOML document, in order: ``(value, positions)``."""
    out = []
    i = 0
    n = len(text)
    while i < n:
        ch = text[i]
        if ch == "#":
            k = text.find("\n", i)
            i = n if k < 0 else k
        elif ch in "\"'":
            value, pos, end = _scan_string(text, i)
            if value is not None:
                out.append((value, pos))
            i = max(end, i + 1)
        else:
            i += 1
    return out


def _line_starts(text: str) -> np.ndarray:
    """Offsets at which the lines of ``text`` start."""
    return np.array([0] + [m.end() for m in re.finditer("\n", text)], np.int64)


def _text_where(line_starts: np.ndarray, positions: list[int]) -> Where:
    """Positions in a string literal of the file: ``positions[k]`` is where its k-th character stands."""

    def where(offset: int):
        idx = positions[min(max(offset, 0), len(positions) - 1)]
        line = int(np.searchsorted(line_starts, idx, side="right"))
        return line, idx - int(line_starts[line - 1]) + 1

    return where


def _locate_strings(text: str, data: dict) -> dict:
    """Find where the axiom and each rule string stand in the file, for error positions.

    One pass over the file's string literals; the rules are looked for in order, each after the last one
    found, so the time is linear in the size of the file however many rules there are.
    """
    tokens = _string_tokens(text)
    line_starts = _line_starts(text)
    first = np.array([pos[0] for _, pos in tokens], np.int64)
    token_line = np.searchsorted(line_starts, first, side="right")  # line of each literal's first character
    where: dict = {}
    for key in _KEYS:
        line = _key_line(text, key)
        if line is not None:
            where[("key", key)] = lambda offset, line=line: (line, 1)
    used: set[int] = set()

    def find(value, start: int) -> int | None:
        """The first unused literal from ``start`` on that reads ``value``."""
        for t in range(start, len(tokens)):
            if tokens[t][0] == value and t not in used:
                used.add(t)
                return t
        return None

    def after_line(line: int) -> int:
        return int(np.searchsorted(token_line, line, side="left"))

    axiom = data.get("axiom")
    if isinstance(axiom, str):
        t = find(axiom, after_line(_key_line(text, "axiom") or _key_line(text, "premise") or 1))
        if t is not None:
            where["axiom"] = _text_where(line_starts, tokens[t][1])
    for key in ("ignore", "consider"):
        value = data.get(key)
        if isinstance(value, str):
            t = find(value, after_line(_key_line(text, key) or 1))
            if t is not None:
                where[key] = _text_where(line_starts, tokens[t][1])
    for key in (*_RULE_LISTS, "functions"):
        rules = data.get(key)
        if not isinstance(rules, list):
            continue
        cursor = after_line(_key_line(text, key) or 1)
        for i, rule in enumerate(rules):
            if isinstance(rule, str):
                t = find(rule, cursor)
                if t is None:  # a form the scanner does not follow: the rest keep their list positions
                    break
                where[(key, i)] = _text_where(line_starts, tokens[t][1])
                cursor = t + 1
    if isinstance(data.get("defines"), dict):
        line = _key_line(text, "defines")
        where["defines"] = (lambda offset, line=line: (line, 1)) if line else None
    return where
