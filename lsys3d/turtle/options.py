"""The turtle's settings: :class:`TurtleOptions`, read from a grammar's ``[turtle]`` table.

Every setting is one field of :class:`TurtleOptions` (default, range, help);
the ``[turtle]`` table, ``GenerateOptions.turtle`` overrides
(:class:`TurtleOverrides`), the CLI's ``--turtle KEY=VALUE`` and the settings
table of ``docs/turtle.md`` (:func:`options_markdown`) all read those fields.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, fields

from ..errors import OptionsError, clip
from ..lsystem import dialects
from ..lsystem.grammar import Grammar, table_error
from ..options import Options, check_value, option, spec_of
from .commands import RENAMEABLE, by_symbol

__all__ = [
    "BENDS",
    "GRAMMAR_KEYS",
    "JITTER_DISTRIBUTIONS",
    "TurtleOptions",
    "TurtleOverrides",
    "options_markdown",
    "parse_setting",
]

BENDS = ("abop", "angle", "cpfg")
"""Values of ``TurtleOptions.bend``."""

JITTER_DISTRIBUTIONS = ("uniform", "normal")
"""Values of ``TurtleOptions.jitter_distribution``."""


@dataclass(frozen=True)
class TurtleOptions(Options):
    """How the turtle draws; every default lives here.

    The ``[turtle]`` table of a grammar sets any field but ``angle`` and
    ``seed``, which come from the grammar's top level (:data:`GRAMMAR_KEYS`
    are the keys it may hold).  Each field's help is in its declaration;
    ``docs/turtle.md`` lists them (:func:`options_markdown`).

    ``tropism`` and ``elasticity`` bend the frame toward T before each move
    by ``e * |H x T|`` radians about ``H x T`` (ABOP 2.8), or with ``bend =
    "angle"`` by ``e`` times the angle between H and T (PlantGL's turtle).  The jitters and
    the branch roll draw ``u`` in [-1, 1]: uniform, or (``jitter_distribution
    = "normal"``) normal with sigma 1/2 truncated by redrawing.
    """

    angle: float = option(90.0, help="default rotation angle, degrees (the grammar's `angle`)", cli=False)
    heading: float = option(90.0, help="initial heading in the XY plane, degrees (90: up along +Y, 0: along +X)")
    step: float = option(1.0, low=0, low_open=True, help="initial step length")
    width: float = option(0.1, low=0, help="initial branch diameter")
    min_width: float = option(
        0.0, low=0, help="smallest branch diameter: a thinner segment is drawn this wide (Lparser's min_thickness)"
    )
    width_scale: float = option(0.7, low=0, low_open=True, help="factor of `!` without argument")
    length_scale: float = option(0.9, low=0, low_open=True, help='factor of `"` without argument')
    width_unit: float = option(
        1.0,
        low=0,
        low_open=True,
        help="what a width given in the grammar (`!(w)`) is worth, as a diameter: 2 for a radius (L-Py), "
        "0.01 for centimetres",
    )
    length_unit: float = option(
        1.0,
        low=0,
        low_open=True,
        help="what a length given in the grammar (`F(l)`, `f(l)`) is worth, in steps of 1: 0.01 for Lparser, "
        "whose step is 100",
    )
    width_increment: float = option(
        1.0, low=0, help="what L-Py's `_` and `!` (cpfg's `#` and `!`) add to or take from the width"
    )
    angle_scale: float = option(0.9, low=0, low_open=True, help="factor of the angle-scaling symbols without argument")
    draw: str = option("F", help='symbols that move drawing a segment, e.g. `"FLR"`')
    move: str = option("f", help="symbols that move without drawing")
    leaf: str = option("~", help="the leaf-instance symbol")
    tropism: tuple[float, float, float] = option((0.0, 0.0, 0.0), help="tropism vector T (ABOP 2.8), `[x, y, z]`")
    elasticity: float = option(0.0, help="before each move the frame turns by e\\|H x T\\| radians about H x T")
    elasticity_increment: float = option(
        0.0, help="what cpfg's `_` adds to the elasticity (the view file's `elasticity increment:`)"
    )
    tropisms: tuple[float, ...] = option(
        (),
        kind="vector",
        cli=False,
        help="cpfg's tropisms and twists (the view file's `tropism:` and `torque:` lines), 7 numbers each: kind (0 "
        "a tropism, 1 a twist), T's x, y, z (its length the intensity), the angle to T (degrees), the elasticity "
        "and its increment; before each move they bend the frame, and `@Ts(n, e)`, `@Ti(n)`, `@Td(n)` set, raise "
        "and lower the n-th's elasticity (docs/dialects/cpfg.md)",
    )
    cylinder_sides: int = option(
        0,
        low=0,
        high=1024,
        cli=False,
        help="the sides of the tubes, spheres and discs where no cpfg `@!(n)` sets them (cpfg's view file: "
        "`contour sides:`, `polygonization level:`); 0: the sweep's `sides` and the organs' own",
    )
    bend: str = option(
        "abop",
        choices=BENDS,
        help='how the elasticity bends: `"abop"` by e\\|H x T\\| radians (ABOP 2.8), `"angle"` by e times the '
        "angle between H and T (PlantGL's turtle, L-Py's default), `\"cpfg\"` after each move, H toward U by the "
        "angle whose sine is e (T.U) and toward L by the one whose sine is e (T.L) (cpfg's view-file tropism)",
    )
    polygon_edges: bool = option(
        False,
        help="moves inside a polygon draw segments too (L-System Explorer's turtle draws every F and G; cpfg's "
        "and ABOP's draw the polygon alone)",
    )
    angle_jitter: float = option(0.0, low=0, help="random change of each rotation angle, up to this many degrees")
    length_jitter: float = option(0.0, low=0, help="random relative change of each step, up to this fraction")
    width_jitter: float = option(0.0, low=0, help="random relative change of each segment's width, up to this fraction")
    branch_roll: float = option(
        0.0, low=0, help="random roll of each new branch about its heading at `[`, up to this many degrees"
    )
    branch_drop: float = option(0.0, low=0, high=1, help="probability that a branch, `[` to its `]`, is left out")
    jitter_distribution: str = option(
        "uniform",
        choices=JITTER_DISTRIBUTIONS,
        help='how jitters and rolls are drawn: `"uniform"` or `"normal"` (see below)',
    )
    seed: int = option(0, low=0, help="seed of the natural variation (the grammar's `seed`)", cli=False)

    def __post_init__(self):
        super().__post_init__()
        _check_symbols(self.draw, self.move, self.leaf)
        rows = self.tropisms
        if len(rows) % 7 or any(kind not in (0.0, 1.0) for kind in rows[::7]):
            raise OptionsError(
                "TurtleOptions.tropisms: 7 numbers a tropism (kind 0 or 1, x, y, z, angle, elasticity, increment), "
                f"not {len(rows)} numbers"
                + ("" if len(rows) % 7 else " with a kind other than 0 (a tropism) or 1 (a twist)")
            )

    @classmethod
    def from_grammar(cls, grammar: Grammar, overrides: Mapping | None = None, **more) -> TurtleOptions:
        """The options of a grammar: its dialect's turtle, its ``[turtle]`` table, ``angle`` and ``seed``.

        Parameters
        ----------
        grammar : Grammar
        overrides : mapping, optional
            Settings to use regardless of the grammar (``GenerateOptions.turtle``).
        **more
            More fields, as keywords (``angle`` and ``seed`` too).

        Raises
        ------
        GrammarError
            An unknown key or a bad value in ``[turtle]``, with the grammar's
            file and the key's line.
        OptionsError
            A bad override.

        Examples
        --------
        >>> from lsys3d import load_preset
        >>> TurtleOptions.from_grammar(load_preset("koch")).heading
        0.0
        """
        values: dict = {"angle": grammar.angle, "seed": grammar.seed}
        values.update(dialects.get(grammar.dialect).turtle)  # the tool's own turtle (L-Py's radii...)
        for key, value in grammar.turtle.items():
            if key not in GRAMMAR_KEYS:
                known = ", ".join(sorted(GRAMMAR_KEYS))
                raise table_error(grammar, "turtle", key, f"unknown key {clip(repr(key))} (known keys: {known})")
            try:
                values[key] = check_value(_SPECS[key], value, key)
            except OptionsError as exc:
                raise table_error(grammar, "turtle", key, str(exc)) from None
        try:
            _check_symbols(values.get("draw", "F"), values.get("move", "f"), values.get("leaf", "~"))
        except OptionsError as exc:
            key = re.match(r"'(\w+)'", str(exc)).group(1)
            raise table_error(grammar, "turtle", key, str(exc)) from None
        values.update(TurtleOverrides(overrides or {}))
        unknown = sorted(set(more) - set(_SPECS))
        if unknown:
            raise OptionsError(f"TurtleOptions.from_grammar: unknown option {clip(repr(unknown[0]))}")
        values.update(more)
        return cls(**values)


_SPECS = {f.name: spec_of(f) for f in fields(TurtleOptions)}

GRAMMAR_KEYS: frozenset[str] = frozenset(_SPECS) - {"angle", "seed"}
"""The keys a grammar's ``[turtle]`` table, ``GenerateOptions.turtle`` and ``--turtle`` accept."""


class TurtleOverrides(Mapping):
    """Turtle settings that override a grammar's ``[turtle]`` table: an immutable, checked mapping.

    Keys are :data:`GRAMMAR_KEYS`; values are checked by the same rules as
    :class:`TurtleOptions`' fields.

    >>> TurtleOverrides({"width_jitter": 0.2})["width_jitter"]
    0.2
    >>> TurtleOverrides({"colour": 3})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
      ...
    lsys3d.errors.OptionsError: turtle: unknown setting 'colour' (known: angle_jitter, angle_scale, ..., width_unit)
    """

    def __init__(self, values: Mapping | Sequence[str] | None = None):
        checked = {}
        if values is None:
            values = {}
        elif isinstance(values, (list, tuple)):  # the command line's form: ["width_jitter=0.2", ...]
            values = dict(parse_setting(v) if isinstance(v, str) else _pair(v) for v in values)
        elif not isinstance(values, Mapping):
            raise OptionsError(f"turtle: expected a table of settings or a list of KEY=VALUE, not {clip(repr(values))}")
        for key, value in dict(values).items():
            if key not in GRAMMAR_KEYS:
                known = ", ".join(sorted(GRAMMAR_KEYS))
                raise OptionsError(f"turtle: unknown setting {clip(repr(key))} (known: {known})")
            checked[key] = check_value(_SPECS[key], value, f"turtle.{key}")
        self._values = dict(sorted(checked.items()))

    def __getitem__(self, key):
        return self._values[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"TurtleOverrides({self._values!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, Mapping) and dict(self) == dict(other)

    def __hash__(self) -> int:
        return hash(tuple(self._values.items()))


def parse_setting(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` (``--turtle``'s form) as ``(key, value)``: the value is TOML (``0.2``, ``"normal"``,
    ``[0, -1, 0]``), a bare word a string.  The value is checked by :class:`TurtleOverrides`.

    >>> parse_setting("tropism = [0, -1, 0]")
    ('tropism', [0, -1, 0])
    """
    key, sep, value = str(text).partition("=")
    key = key.strip()
    if not sep or key not in GRAMMAR_KEYS:
        raise OptionsError(
            f"expected KEY=VALUE with KEY one of {', '.join(sorted(GRAMMAR_KEYS))}, not {clip(repr(text))}"
        )
    try:
        parsed = tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return key, parsed


def _pair(item) -> tuple:
    if isinstance(item, (list, tuple)) and len(item) == 2 and isinstance(item[0], str):
        return tuple(item)
    raise OptionsError(f"turtle: expected KEY=VALUE, not {clip(repr(item))}")


def _check_symbols(draw: str, move: str, leaf: str) -> None:
    """The renameable symbols must be symbols, and none may be another command's or each other's."""
    for key, value in (("draw", draw), ("move", move), ("leaf", leaf)):
        if key == "leaf" and len(value) != 1:
            raise OptionsError(f"'{key}' must be one symbol, not {clip(repr(value))}")
        if any(c.isspace() or c in "()," for c in value):
            raise OptionsError(f"'{key}' holds a character that cannot be a symbol: {clip(repr(value))}")
        for ch in value:
            fixed = by_symbol(ch)
            if fixed is not None:
                raise OptionsError(f"'{key}' symbol {ch!r} is already the turtle command {fixed.name}")
    both = sorted(set(draw) & set(move))
    if both:
        raise OptionsError(f"'move' symbol {both[0]!r} is also a 'draw' symbol")
    if leaf in draw or leaf in move:
        raise OptionsError(f"'leaf' symbol {leaf!r} is also a 'draw' or 'move' symbol")


assert set(RENAMEABLE) <= set(_SPECS)  # the renameable commands' symbols are settings


def options_markdown() -> str:
    """The ``[turtle]`` settings as a Markdown table (in ``docs/turtle.md``; the tests check it)."""
    rows = ["| Key | Default | Meaning |", "|---|---|---|"]
    defaults = TurtleOptions()
    for f in fields(TurtleOptions):
        if f.name not in GRAMMAR_KEYS:
            continue
        value = getattr(defaults, f.name)
        shown = f'`"{value}"`' if isinstance(value, str) else f"`{list(value)}`" if isinstance(value, tuple) else value
        spec = _SPECS[f.name]
        rng = spec.range_text() if spec.low is not None or spec.high is not None else ""
        help_text = spec.help + (f" ({rng})" if rng else "")
        rows.append(f"| `{f.name}` | {shown} | {help_text} |")
    return "\n".join(rows) + "\n"
