"""The module string: the output of derivation and the input of the turtle.

A string of ``m`` modules is stored as arrays, never as Python objects per module:

``symbols : (m,) uint8``
    Symbol ids.  ASCII symbols use their own code (``ord("F") == 70``); other
    characters get free ids from 128 up, recorded in ``alphabet``.
``arity : (m,) uint8``
    Number of parameters of each module.
``params : (k,) float64``
    All parameters, module after module (``k == arity.sum()``).
``alphabet : tuple of 256 str``
    ``alphabet[id]`` is the name of the module with that id (``"\\0"`` for an id
    no module uses).  Ids below 128 are ASCII symbols, named by their own
    character; the ids from 128 up name everything else: non-ASCII symbols and
    multi-character module names (``Leaf``, ``@O``, ``~l``), so a module is
    still one ``uint8`` however long its name.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

__all__ = ["ASCII_ALPHABET", "ModuleString", "as_alphabet", "format_number"]

UNUSED = "\0"
"""The name of an id that no module uses."""
ASCII_ALPHABET: tuple[str, ...] = tuple(chr(i) for i in range(128)) + (UNUSED,) * 128
"""The alphabet of strings whose symbols are all ASCII characters."""


def as_alphabet(names) -> tuple[str, ...]:
    """``names`` (a 256-character string or a sequence of 256 names) as the tuple a :class:`ModuleString` holds.

    >>> as_alphabet(ASCII_ALPHABET) is ASCII_ALPHABET
    True
    >>> as_alphabet("".join(ASCII_ALPHABET[:128]) + "é" + "\\0" * 127)[128]
    'é'
    """
    if names is ASCII_ALPHABET or _CHECKED.get(id(names)) is names:
        return names
    out = tuple(names)
    try:
        valid = _valid_alphabet(out)
    except TypeError:  # a name that is no string (and cannot be hashed)
        valid = False
    if not valid:
        raise ValueError("an alphabet holds 256 names, one per symbol id")
    if out == ASCII_ALPHABET:
        return ASCII_ALPHABET
    if out is names:  # the same tuple again (every string of a derivation): no hashing of its 256 names
        if len(_CHECKED) >= 64:
            _CHECKED.clear()
        _CHECKED[id(out)] = out
    return out


_CHECKED: dict[int, tuple] = {}
"""Alphabet tuples already checked, by identity (each holds its tuple, so an id is not reused while listed)."""


@lru_cache(maxsize=64)
def _valid_alphabet(names: tuple) -> bool:
    """Checked once per alphabet (every string a derivation builds carries its grammar's)."""
    return len(names) == 256 and all(isinstance(n, str) and n for n in names)


def format_number(x: float) -> str:
    """Canonical text of a parameter: ``%.6f`` without trailing zeros or dot, ``-0`` as ``0``.

    >>> format_number(8 / 7), format_number(2.0), format_number(-1e-9)
    ('1.142857', '2', '0')
    """
    s = f"{x:.6f}"
    s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


@dataclass(frozen=True, eq=False)
class ModuleString:
    """An immutable string of modules (see the module docstring for the arrays)."""

    symbols: np.ndarray
    arity: np.ndarray
    params: np.ndarray
    alphabet: tuple[str, ...] = ASCII_ALPHABET

    def __post_init__(self):
        for name in ("symbols", "arity", "params"):
            getattr(self, name).setflags(write=False)
        object.__setattr__(self, "alphabet", as_alphabet(self.alphabet))

    @classmethod
    def from_symbols(cls, text: str, alphabet=ASCII_ALPHABET) -> ModuleString:
        """A parameterless string from its text (every character one module)."""
        alphabet = as_alphabet(alphabet)
        codes = [alphabet.index(c) if ord(c) >= 128 else ord(c) for c in text]
        m = len(codes)
        return cls(np.array(codes, dtype=np.uint8), np.zeros(m, np.uint8), np.zeros(0, np.float64), alphabet)

    def __len__(self) -> int:
        return int(self.symbols.shape[0])

    @cached_property
    def offsets(self) -> np.ndarray:
        """``(m + 1,) int64``: parameters of module ``i`` are ``params[offsets[i]:offsets[i+1]]``."""
        out = np.zeros(len(self) + 1, dtype=np.int64)
        np.cumsum(self.arity, out=out[1:])
        return out

    def with_params(self, params: np.ndarray) -> ModuleString:
        """The same modules with other parameter values (``params`` of the same length); the offsets, when
        already computed, are kept rather than summed again."""
        if params.shape != self.params.shape:
            raise ValueError(f"with_params: {len(params)} parameters for a string of {len(self.params)}")
        out = ModuleString(self.symbols, self.arity, params, self.alphabet)
        if "offsets" in self.__dict__:
            out.__dict__["offsets"] = self.__dict__["offsets"]
        return out

    def symbol(self, i: int) -> str:
        return self.alphabet[int(self.symbols[i])]

    def module(self, i: int) -> tuple[str, tuple[float, ...]]:
        """Module ``i`` as ``(symbol, parameters)``."""
        o = self.offsets
        return self.symbol(i), tuple(float(x) for x in self.params[o[i] : o[i + 1]])

    def module_text(self, i: int, short: bool = False) -> str:
        """Module ``i`` as text; ``short`` prints numbers with ``%.6g`` (for messages)."""
        sym, args = self.module(i)
        fmt = (lambda x: f"{x:.6g}") if short else format_number
        return sym + ("(" + ",".join(map(fmt, args)) + ")" if args else "")

    def count(self, symbol: str) -> int:
        """How many modules have this symbol."""
        code = ord(symbol) if len(symbol) == 1 and ord(symbol) < 128 else self.code(symbol)
        return int(np.count_nonzero(self.symbols == code)) if code >= 0 else 0

    def code(self, name: str) -> int:
        """The id of the module named ``name``, or -1 if the alphabet has no such name."""
        if len(name) == 1 and ord(name) < 128:
            return ord(name)
        try:
            return self.alphabet.index(name, 128)
        except ValueError:
            return -1

    def symbol_text(self, start: int = 0, stop: int | None = None) -> str:
        """The symbols alone, without parameters (of modules ``start`` to ``stop``)."""
        raw = self.symbols[start:stop].tobytes().decode("latin-1")
        if self.alphabet is ASCII_ALPHABET:
            return raw
        return raw.translate({i: self.alphabet[i] for i in range(128, 256) if self.alphabet[i] != UNUSED})

    def iter_text(self, chunk: int = 1 << 16) -> Iterator[str]:
        """The text of :meth:`__str__` in pieces of ``chunk`` modules, to write a long string without holding it.

        Each distinct parameter value of a piece is formatted once; the piece is then assembled from tokens
        (``F(``, ``1.5,``, ``2)``) gathered by numpy, with no Python loop over modules.

        >>> s = ModuleString.from_symbols("F+F")
        >>> list(s.iter_text(chunk=2))
        ['F+', 'F']
        """
        if chunk < 1:
            raise ValueError(f"chunk must be at least 1, not {chunk}")
        m = len(self)
        if not len(self.params):
            for a in range(0, m, chunk):
                yield self.symbol_text(a, min(a + chunk, m))
            return
        offsets = self.offsets
        # the token of each symbol code without and with parameters: "F", "F("
        opening = np.array([c for c in self.alphabet] + [c + "(" for c in self.alphabet], dtype=object)
        for a in range(0, m, chunk):
            b = min(a + chunk, m)
            p0, p1 = int(offsets[a]), int(offsets[b])
            symbols = self.symbols[a:b].astype(np.intp) + 256 * (self.arity[a:b] > 0)
            if p0 == p1:
                yield "".join(opening[symbols].tolist())
                continue
            values, inverse = np.unique(self.params[p0:p1], return_inverse=True)
            names = [format_number(x) for x in values.tolist()]
            # each distinct value followed by "," and by ")"; a module's last parameter takes the ")"
            endings = np.array([n + "," for n in names] + [n + ")" for n in names], dtype=object)
            local = offsets[a : b + 1] - p0
            last = np.zeros(p1 - p0, np.intp)
            last[local[1:][self.arity[a:b] > 0] - 1] = len(names)
            tokens = np.empty(b - a + p1 - p0, dtype=object)
            at = np.arange(b - a) + local[:-1]  # each module's symbol, then its parameters
            tokens[at] = opening[symbols]
            rest = np.ones(len(tokens), bool)
            rest[at] = False
            tokens[rest] = endings[inverse.reshape(-1) + last]
            yield "".join(tokens.tolist())

    def __str__(self) -> str:
        return "".join(self.iter_text())

    def __repr__(self) -> str:
        s = str(self) if len(self) <= 60 else str(self[:60]) + "..."
        return f"ModuleString({s!r}, modules={len(self)})"

    def __getitem__(self, item: slice) -> ModuleString:
        if not isinstance(item, slice):
            raise TypeError("index a ModuleString with a slice; use .module(i) for one module")
        start, stop, step = item.indices(len(self))
        if step != 1:
            raise ValueError("ModuleString slices must be contiguous")
        o = self.offsets
        return ModuleString(
            self.symbols[start:stop].copy(),
            self.arity[start:stop].copy(),
            self.params[o[start] : o[max(start, stop)]].copy(),
            self.alphabet,
        )

    def __eq__(self, other) -> bool:
        if not isinstance(other, ModuleString):
            return NotImplemented
        return (
            np.array_equal(self.symbols, other.symbols)
            and np.array_equal(self.arity, other.arity)
            and np.array_equal(self.params, other.params)
            and (self.alphabet == other.alphabet or self.symbol_text() == other.symbol_text())
        )

    __hash__ = None
