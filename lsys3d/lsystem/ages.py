"""Ages through derivation: when each module of a derived string was born, in the plant's own time.

ABOP chapter 6 ("Animation of plant development") gives every module an age:
a timed L-system rewrites a module when its age reaches its *terminal age*,
and the organ a module draws grows by a smooth *growth function* of its age,
so the plant develops continuously instead of jumping from one generation to
the next.  lsys3d keeps its parallel derivation (every module is rewritten
once a step) and follows each module's clock through it:

* a module of the axiom is born at time 0;
* a rule rewrites a module whose clock reads ``e`` at ``e + terminal_age`` of
  its symbol (1 by default: step ``k`` happens at time ``k``);
* the modules of the successor are born then, less their symbol's
  ``initial_age`` (ABOP's alpha), except the one that *continues* the
  predecessor (the first module at bracket depth 0 with the predecessor's own
  symbol: in ``F(l) -> F(l*r)`` the internode grows on, in ``A -> AB`` the
  apex stays and ``B`` is new), which keeps its birth and moves its clock on;
* decomposition and homomorphism rules are instantaneous: what they make has
  the birth and clock of the module it came from.

So with the defaults a module created at step ``k`` of ``n`` has age ``n - k``.
A module is *mature* (full grown) ``duration`` after its last rewrite (its
clock), ``duration`` defaulting to its terminal age: an internode a rule keeps
rewriting grows on until the last step, one left alone grows for one step.

The grammar's ``[growth]`` table sets it all::

    [growth]
    function = "smooth"       # the growth function: linear, smooth (3x^2 - 2x^3), logistic
    terminal_age = 1.0        # time between two rewrites of a module (ABOP's beta)
    leaf_delay = 0.5          # leaves and organs start unfolding this long after their twig is born
    leaf_duration = 1.0       # and take this long to unfold
    F = { duration = 2.0, function = "logistic" }     # one symbol's own settings
    A = { terminal_age = 0.5, initial_age = 0.25 }

Timing is a time warp of the parallel derivation, not a timed derivation:
a module of terminal age 0.5 is still rewritten once a step, its rewrites are
only spaced by 0.5 in the plant's time (ABOP's timed DOL systems would
rewrite it twice as often).

Examples
--------
>>> from lsys3d import Grammar
>>> g = Grammar(axiom="A", rules=["A -> AB", "B -> A"])
>>> modules, ages = derive_with_ages(g, 4)
>>> str(modules), ages.birth.tolist(), ages.age.tolist()
('ABAABABA', [0.0, 4.0, 4.0, 3.0, 4.0, 2.0, 4.0, 4.0], [4.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0])
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import clip
from .derive import CUT, DEFAULT_MAX_MODULES, PRODUCTION, generations, interpretation
from .grammar import Grammar
from .locations import table_error
from .modules import ModuleString

__all__ = [
    "FUNCTIONS",
    "Ages",
    "GrowthFunction",
    "GrowthTable",
    "SymbolGrowth",
    "derive_with_ages",
    "growth_table",
    "interpretation_ages",
]


@dataclass(frozen=True)
class GrowthFunction:
    """A growth function: the share of its full size an organ has at ``x`` of its growth (0 to 1)."""

    name: str
    formula: str
    f: Callable[[np.ndarray], np.ndarray]
    slope: float  # its steepest slope, for the smoothness of an animation sampled from it


_K = 10.0  # the logistic's steepness
_LOW, _HIGH = 1 / (1 + math.exp(_K / 2)), 1 / (1 + math.exp(-_K / 2))


def _logistic(x):
    return (1 / (1 + np.exp(-_K * (x - 0.5))) - _LOW) / (_HIGH - _LOW)


FUNCTIONS: dict[str, GrowthFunction] = {
    "linear": GrowthFunction("linear", "x", lambda x: x, 1.0),
    "smooth": GrowthFunction(
        "smooth", "3x^2 - 2x^3 (smoothstep: starts and stops gently)", lambda x: x * x * (3 - 2 * x), 1.5
    ),
    "logistic": GrowthFunction(
        "logistic",
        "the logistic curve 1 / (1 + e^(-10 (x - 1/2))), scaled to run from 0 to 1",
        _logistic,
        _K / 4 / (_HIGH - _LOW),
    ),
}
"""The growth functions a ``[growth]`` table may name, by name (ABOP 6.2 uses linear and sigmoid growth)."""
FUNCTION_NAMES = tuple(FUNCTIONS)


@dataclass(frozen=True)
class SymbolGrowth:
    """One symbol's timing: ``terminal_age``, ``initial_age``, ``duration`` (None: its terminal age), ``function``."""

    terminal_age: float
    initial_age: float
    duration: float | None
    function: str


_SYMBOL_KEYS = ("terminal_age", "initial_age", "duration", "function")
_TOP_KEYS = ("function", "terminal_age", "leaf_delay", "leaf_duration")


@dataclass(frozen=True)
class GrowthTable:
    """A grammar's ``[growth]`` table (see the module docstring), with its defaults."""

    function: str = "smooth"
    terminal_age: float = 1.0
    leaf_delay: float = 0.5
    leaf_duration: float = 1.0
    symbols: dict = field(default_factory=dict)  # symbol -> SymbolGrowth

    def of(self, symbol: str) -> SymbolGrowth:
        """The settings of ``symbol`` (the table's defaults when it has none of its own)."""
        return self.symbols.get(symbol) or SymbolGrowth(self.terminal_age, 0.0, None, self.function)

    def per_code(self, alphabet: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(terminal_age, initial_age, duration, function)``, each ``(256,)``, indexed by symbol id.

        ``function`` holds indices into :data:`FUNCTION_NAMES`.
        """
        terminal, initial, duration = np.empty(256), np.empty(256), np.empty(256)
        function = np.empty(256, np.int8)
        for code, name in enumerate(alphabet):
            s = self.of(name)
            terminal[code], initial[code] = s.terminal_age, s.initial_age
            duration[code] = s.terminal_age if s.duration is None else s.duration
            function[code] = FUNCTION_NAMES.index(s.function)
        return terminal, initial, duration, function


def _number(grammar: Grammar, where: str, value, low: float, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < low:
        raise table_error(grammar, "growth", key, f"{where}: must be a number >= {low:g}, not {clip(repr(value))}")
    return float(value)


def _function(grammar: Grammar, where: str, value, key: str) -> str:
    if value not in FUNCTIONS:
        raise table_error(
            grammar,
            "growth",
            key,
            f"{where}: unknown growth function {clip(repr(value))} (known: {', '.join(FUNCTIONS)})",
        )
    return value


def growth_table(grammar: Grammar) -> GrowthTable:
    """The grammar's ``[growth]`` table, checked.

    Raises
    ------
    GrammarError
        An unknown key, a bad number or an unknown growth function, at the key's line.

    Examples
    --------
    >>> g = Grammar.from_text('axiom = "F"\\n[growth]\\nfunction = "linear"\\nF = { terminal_age = 2 }\\n')
    >>> t = growth_table(g)
    >>> t.function, t.of("F").terminal_age, t.of("G").terminal_age
    ('linear', 2.0, 1.0)
    """
    raw = dict(getattr(grammar, "growth", {}) or {})
    top = {k: raw.pop(k) for k in _TOP_KEYS if k in raw and not isinstance(raw[k], dict)}
    function = _function(grammar, "function", top.get("function", "smooth"), "function")
    defaults = {
        key: _number(grammar, key, top[key], 1e-6 if key == "terminal_age" else 0.0, key)
        for key in ("terminal_age", "leaf_delay", "leaf_duration")
        if key in top
    }
    symbols = {}
    for symbol, entry in raw.items():
        if not isinstance(entry, dict):
            known = ", ".join(_TOP_KEYS)
            raise table_error(
                grammar,
                "growth",
                symbol,
                f"{clip(repr(symbol))}: a symbol's entry is a table, e.g. "
                f"{symbol} = {{ terminal_age = 1 }} (the table's own keys: {known})",
            )
        unknown = sorted(set(entry) - set(_SYMBOL_KEYS))
        if unknown:
            raise table_error(
                grammar,
                "growth",
                symbol,
                f"{symbol}: unknown key {clip(repr(unknown[0]))} (known: {', '.join(_SYMBOL_KEYS)})",
            )
        where = f"{symbol}."
        terminal = _number(
            grammar, where + "terminal_age", entry.get("terminal_age", defaults.get("terminal_age", 1.0)), 1e-6, symbol
        )
        initial = _number(grammar, where + "initial_age", entry.get("initial_age", 0.0), 0.0, symbol)
        duration = entry.get("duration")
        if duration is not None:
            duration = _number(grammar, where + "duration", duration, 0.0, symbol)
        fn = _function(grammar, where + "function", entry.get("function", function), symbol)
        symbols[symbol] = SymbolGrowth(terminal, initial, duration, fn)
    return GrowthTable(function=function, symbols=symbols, **defaults)


@dataclass(frozen=True, eq=False)
class Ages:
    """The ages of a module string's modules.

    Attributes
    ----------
    birth : (m,) float64
        When each module was born (the plant's time: step ``k`` at ``k`` with the default terminal ages).
    clock : (m,) float64
        When each module was last rewritten (its birth if never): it is full grown ``duration`` later.
    time : float
        The end of the derivation: its steps times the table's terminal age (``n`` by default), or the latest
        rewrite when a symbol's own terminal age puts it later.
    """

    birth: np.ndarray
    clock: np.ndarray
    time: float

    @property
    def age(self) -> np.ndarray:
        """Each module's age at the end of the derivation, ``(m,) float64``."""
        return self.time - self.birth

    def mature(self, modules: ModuleString, table: GrowthTable) -> np.ndarray:
        """When each module of ``modules`` (the string these ages are of) is full grown, ``(m,) float64``."""
        duration = table.per_code(modules.alphabet)[2]
        return self.clock + duration[modules.symbols]


class _Clock:
    """Follows the births and clocks of a string through the changes a derivation reports (a ``Trace``)."""

    def __init__(self, modules: ModuleString, table: GrowthTable, ages: Ages | None = None):
        self.terminal, self.initial, _, _ = table.per_code(modules.alphabet)
        m = len(modules)
        self.birth = ages.birth.copy() if ages is not None else np.zeros(m)
        self.clock = ages.clock.copy() if ages is not None else np.zeros(m)
        self.time = ages.time if ages is not None else 0.0

    def __call__(self, kind, symbols, new_symbols, rewritten, lengths, persisting) -> None:
        if kind == CUT:
            self.birth, self.clock = self.birth[rewritten], self.clock[rewritten]
            return
        source = np.repeat(np.arange(len(symbols)), lengths)
        birth, clock = self.birth[source], self.clock[source]
        if kind == PRODUCTION:
            rewrite = self.clock + self.terminal[symbols]  # when each module is rewritten
            if rewritten.any():
                self.time = max(self.time, float(rewrite[rewritten].max()))
            new = rewritten[source]
            born = new & ~persisting
            at = rewrite[source]
            birth[born] = at[born] - self.initial[new_symbols[born]]
            clock[born] = birth[born]
            grown = new & persisting
            clock[grown] = at[grown]
        self.birth, self.clock = birth, clock

    def ages(self) -> Ages:
        return Ages(self.birth, self.clock, self.time)


def derive_with_ages(
    grammar: Grammar,
    iterations: int | None = None,
    seed: int | None = None,
    *,
    table: GrowthTable | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
) -> tuple[ModuleString, Ages]:
    """:func:`~lsys3d.lsystem.derive.derive` that also says when each module was born (see the module docstring).

    The same string as ``derive`` (through the general engine: the block expansion of D0L systems keeps no
    lineage), with its :class:`Ages` under ``table`` (default: the grammar's ``[growth]`` table).
    """
    table = growth_table(grammar) if table is None else table
    clock = _Clock(grammar.axiom_modules, table)
    # the last generation; a deque of one keeps no other alive
    last = deque(generations(grammar, iterations, seed, max_modules=max_modules, trace=clock), maxlen=1).pop()
    steps = grammar.iterations if iterations is None else int(iterations)
    clock.time = max(clock.time, steps * table.terminal_age)  # time goes on when nothing is rewritten
    return last, clock.ages()


def interpretation_ages(
    grammar: Grammar,
    modules: ModuleString,
    ages: Ages,
    seed: int | None = None,
    *,
    table: GrowthTable | None = None,
    max_modules: int = DEFAULT_MAX_MODULES,
    iterations: int | None = None,
) -> tuple[ModuleString, Ages]:
    """:func:`~lsys3d.lsystem.derive.interpretation` with the ages carried through the homomorphism rules."""
    table = growth_table(grammar) if table is None else table
    clock = _Clock(modules, table, ages)
    shown = interpretation(grammar, modules, seed, max_modules=max_modules, iterations=iterations, trace=clock)
    return shown, clock.ages()
