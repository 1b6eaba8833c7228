"""Options: one frozen dataclass per stage, each field declared once with its default, range and help.

A stage's options class lists its fields with :func:`option`::

    @dataclass(frozen=True)
    class SweepOptions(Options):
        sides: int = option(8, low=3, high=1024, help="vertices around the trunk's tubes")

From that one declaration come

* the check: :meth:`Options.__post_init__` runs :func:`check_value` on every
  field (type, finite, inside float range, inside the range) and raises
  :class:`~lsys3d.errors.OptionsError` naming ``Class.field``;
* the command line: :func:`add_arguments` makes ``--sides N`` (with the help,
  the default and the range in its help text), parsed by the same check, and
  :func:`from_arguments` builds the options back from the parsed flags;
* plain data: :meth:`Options.plain` for provenance and golden recipes, and
  :meth:`Options.from_plain` to read them back.

Options classes nest (:class:`~lsys3d.pipeline.GenerateOptions` holds one per
stage).  Every field has a *flat name*, unique over the whole nest (the field's
name, or the ``name`` given to :func:`option`): ``generate(..., sides=6)``,
``GenerateOptions.from_flat(sides=6)``, the CLI's ``--sides`` and a batch
job's ``options = { sides = 6 }`` all mean the same field.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import math
import re
from argparse import SUPPRESS
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from typing import Any

from .errors import OptionsError, clip

__all__ = [
    "Options",
    "Spec",
    "add_arguments",
    "check_value",
    "flat_fields",
    "from_arguments",
    "option",
    "spec_of",
    "unknown_name",
]

_KEY = "lsys3d"


@dataclass(frozen=True)
class Spec:
    """What a field accepts and how it is described (the metadata of :func:`option`).

    Attributes
    ----------
    kind : type or str
        ``bool``, ``int``, ``float``, ``str``, ``"vector"`` (a tuple of
        ``length`` floats), ``"ints"`` (a tuple of ``length`` ints), ``"strings"``
        (a tuple of strings) or ``"options"`` (a nested :class:`Options`).
    help : str
        One line for ``--help`` and the docs.
    low, high : float or None
        Inclusive bounds (exclusive with ``low_open`` / ``high_open``).
    choices : tuple or None
        The allowed values (strings).
    optional : bool
        ``None`` is allowed.
    length : int
        Length of a ``vector`` or ``ints`` value (0: any length; an empty
        default declares a list of any length).
    name : str or None
        Flat and CLI name when it is not the field's own name.
    cli : bool
        Whether :func:`add_arguments` makes a flag for the field.
    metavar : str or None
        Placeholder of the value in ``--help``.
    """

    kind: Any
    help: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple | None = None
    optional: bool = False
    length: int = 0
    name: str | None = None
    cli: bool = True
    metavar: str | None = None

    def range_text(self) -> str:
        """The range as text for help and messages, e.g. ``3..1024``, ``> 0``, ``in [0, 1]``."""
        if self.choices:
            return "one of " + ", ".join(repr(c) if isinstance(c, str) else str(c) for c in self.choices)
        if self.low is not None and self.high is not None:
            left = "(" if self.low_open else "["
            right = ")" if self.high_open else "]"
            return f"in {left}{_num(self.low)}, {_num(self.high)}{right}"
        if self.low is not None:
            return f"{'>' if self.low_open else '>='} {_num(self.low)}"
        if self.high is not None:
            return f"{'<' if self.high_open else '<='} {_num(self.high)}"
        return ""


def _num(x) -> str:
    return f"{x:,}" if isinstance(x, int) and abs(x) >= 10_000 else f"{x:g}"


def option(
    default=MISSING,
    *,
    help: str,
    kind=None,
    low=None,
    high=None,
    low_open: bool = False,
    high_open: bool = False,
    choices=None,
    optional: bool = False,
    name: str | None = None,
    cli: bool = True,
    metavar: str | None = None,
    factory=None,
):
    """A dataclass field with its :class:`Spec`: the one place a setting's default, range and help are written.

    ``kind`` is inferred from the default when not given: ``bool``, ``int``,
    ``float``, ``str``, a tuple of floats (``"vector"``) or of ints (``"ints"``),
    an :class:`Options` instance (``"options"``, give ``factory`` instead);
    ``"strings"`` (a tuple of strings) is given explicitly.
    """
    sample = factory() if factory is not None else default
    length = 0
    if kind is None:
        if isinstance(sample, Options):
            kind = "options"
        elif isinstance(sample, bool):
            kind = bool
        elif isinstance(sample, int):
            kind = int
        elif isinstance(sample, float):
            kind = float
        elif isinstance(sample, str):
            kind = str
        elif isinstance(sample, tuple) and all(isinstance(v, int) for v in sample):
            kind = "ints"
        elif isinstance(sample, tuple):
            kind = "vector"
        else:
            raise TypeError(f"option: give kind= for a default of type {type(sample).__name__}")
    if kind in ("vector", "ints") and isinstance(sample, tuple):
        length = len(sample)
    spec = Spec(
        kind=kind,
        help=help,
        low=low,
        high=high,
        low_open=low_open,
        high_open=high_open,
        choices=tuple(choices) if choices is not None else None,
        optional=optional or (default is None and factory is None),
        length=length,
        name=name,
        cli=cli,
        metavar=metavar,
    )
    if factory is not None:
        return field(default_factory=factory, metadata={_KEY: spec})
    return field(default=default, metadata={_KEY: spec})


def spec_of(f: dataclasses.Field) -> Spec | None:
    """The :class:`Spec` of a dataclass field (None for fields declared without :func:`option`)."""
    return f.metadata.get(_KEY)


def flat_name(f: dataclasses.Field) -> str:
    spec = spec_of(f)
    return spec.name if spec is not None and spec.name else f.name


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _float(value, where: str) -> float:
    try:
        x = float(value)
    except OverflowError:
        raise OptionsError(f"{where}: {clip(repr(value))} is too large for a floating-point number") from None
    if not math.isfinite(x):
        raise OptionsError(f"{where}: must be a finite number, not {clip(repr(value))}")
    return x


def _in_range(x, spec: Spec, where: str):
    low_bad = spec.low is not None and (x < spec.low or (spec.low_open and x == spec.low))
    high_bad = spec.high is not None and (x > spec.high or (spec.high_open and x == spec.high))
    if low_bad or high_bad:
        shown = clip(f"{x:,}" if isinstance(x, int) else f"{x:g}")
        raise OptionsError(f"{where}: must be {spec.range_text()}, not {shown}")


def merge_table(cls, table: Mapping, options, error, *, keys=None, as_tuple=()):
    """Options ``cls`` from a grammar's table, with ``options``' non-default fields over it.

    The one way a grammar's table of settings (``[form]``, ``[leaves]``,
    ``[environment]``) meets the options that the CLI and the API set.

    Parameters
    ----------
    cls : type
        A frozen options dataclass whose fields are declared with :func:`option`.
    table : mapping
        The grammar's table, key -> value as TOML gave them.
    options : cls
        Its fields that differ from ``cls()``'s win over the table.
    error : callable
        ``error(key, what)`` -> the exception to raise for a bad entry
        (:func:`lsys3d.lsystem.locations.table_error`, at the key's line).
    keys : collection of str, optional
        The fields a table may set (default: all).
    as_tuple : collection of str
        Fields that hold a tuple, where the table may write one value.

    Raises
    ------
    Exception
        ``error(key, what)`` for an unknown key, a bad value, or a check across
        fields that names a key of the table; an :class:`OptionsError` that names
        no key of the table (it came from ``options``) is raised as it is.
    """
    specs = {f.name: spec_of(f) for f in fields(cls) if keys is None or f.name in keys}
    values: dict = {}
    for key, value in table.items():
        if key not in specs:
            raise error(key, f"unknown key {clip(repr(key))} (known keys: {', '.join(sorted(specs))})")
        if key in as_tuple and isinstance(value, (int, float, str)) and not isinstance(value, bool):
            value = (value,)
        try:
            values[key] = check_value(specs[key], value, key)
        except OptionsError as exc:
            raise error(key, str(exc)) from None
    defaults = cls()
    values.update(
        {f.name: getattr(options, f.name) for f in fields(cls) if getattr(options, f.name) != getattr(defaults, f.name)}
    )
    try:
        return cls(**values)
    except OptionsError as exc:  # a check across fields: at the key it names, when the table wrote it
        m = re.match(rf"{cls.__name__}\.(\w+)", str(exc))
        if m is None or m.group(1) not in table:
            raise
        raise error(m.group(1), str(exc)) from None


def check_value(spec: Spec, value, where: str):
    """The normalised value of a setting, or :class:`OptionsError` ``where: what``.

    Numbers must be finite and within float range (a huge integer is refused,
    not turned into ``inf``), inside the spec's range; ints must be whole;
    strings one of the choices; vectors the right length of numbers.

    >>> check_value(Spec(int, "sides", low=3), 8, "SweepOptions.sides")
    8
    >>> check_value(Spec(float, "width", low=0), 10**400, "TurtleOptions.width")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
      ...
    lsys3d.errors.OptionsError: TurtleOptions.width: 10000...0000 is too large for a floating-point number
    """
    if value is None:
        if spec.optional:
            return None
        raise OptionsError(f"{where}: a value is required")
    kind = spec.kind
    if kind is bool:
        if not isinstance(value, bool):
            raise OptionsError(f"{where}: must be true or false, not {clip(repr(value))}")
        return value
    if kind is int:
        if isinstance(value, float) and math.isfinite(value) and value == int(value):
            value = int(value)
        if not isinstance(value, int) or isinstance(value, bool):
            raise OptionsError(f"{where}: must be a whole number, not {clip(repr(value))}")
        _in_range(value, spec, where)
        return value
    if kind is float:
        if not _is_number(value):
            raise OptionsError(f"{where}: must be a number, not {clip(repr(value))}")
        x = _float(value, where)
        _in_range(x, spec, where)
        return x
    if kind is str:
        if not isinstance(value, str):
            raise OptionsError(f"{where}: must be a string, not {clip(repr(value))}")
        if spec.choices is not None and value not in spec.choices:
            raise OptionsError(f"{where}: must be {spec.range_text()}, not {clip(repr(value))}")
        return value
    if kind in ("vector", "ints"):
        n = spec.length  # 0: any length
        if not isinstance(value, (list, tuple)) or (n and len(value) != n) or not all(_is_number(v) for v in value):
            what = "whole numbers" if kind == "ints" else "numbers"
            count = f"{n} " if n else ""
            raise OptionsError(f"{where}: must be a list of {count}{what}, not {clip(repr(value))}")
        one = dataclasses.replace(spec, kind=int if kind == "ints" else float, length=0)
        return tuple(check_value(one, v, where) for v in value)
    if kind == "strings":
        if isinstance(value, str) or not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise OptionsError(f"{where}: must be a list of strings, not {clip(repr(value))}")
        return tuple(value)
    if kind == "options":
        return value
    raise TypeError(f"check_value: unknown kind {kind!r}")  # pragma: no cover - a declaration mistake


class Options:
    """Base of the options classes: checks every field on construction; plain-data round trips.

    Subclasses are frozen dataclasses whose fields are declared with :func:`option`.
    """

    def __post_init__(self):
        for f in fields(self):
            spec = spec_of(f)
            if spec is None:
                continue
            value = getattr(self, f.name)
            where = f"{type(self).__name__}.{f.name}"
            if spec.kind == "options":
                if not isinstance(value, type(f.default_factory())):
                    want = type(f.default_factory()).__name__
                    raise OptionsError(f"{where}: must be a {want}, not {type(value).__name__}")
                continue
            object.__setattr__(self, f.name, check_value(spec, value, where))

    def replace(self, **changes):
        """A copy with some fields changed (checked again)."""
        return dataclasses.replace(self, **changes)

    def plain(self) -> dict:
        """The options as JSON-ready nested dicts with sorted keys (tuples as lists)."""
        return _plain({f.name: getattr(self, f.name) for f in fields(self)})

    @classmethod
    def from_plain(cls, data: Mapping, where: str | None = None):
        """Options from the plain dict of some of their fields (nested for nested options).

        Unknown keys are refused with :class:`OptionsError`; a key that is the
        flat name of a nested field (``sides`` for ``sweep.sides``) is accepted too.
        """
        where = where or cls.__name__
        if not isinstance(data, Mapping):
            raise OptionsError(f"{where}: options must be a table, not {type(data).__name__}")
        own = {f.name: f for f in fields(cls)}
        nested: dict[str, dict] = {}
        kwargs = {}
        flat = flat_fields(cls)
        for key, value in data.items():
            f = own.get(key)
            nested_field = f is not None and spec_of(f) is not None and spec_of(f).kind == "options"
            if nested_field and not isinstance(value, Mapping) and key in flat:
                f = None  # ``union: false`` is the flat name of ``union.enabled``, not the union's table
            if f is not None and nested_field:
                sub = type(f.default_factory())
                kwargs[key] = sub.from_plain(value, f"{where}.{key}")
            elif f is not None:
                kwargs[key] = tuple(value) if isinstance(value, list) else value
            elif key in flat and len(flat[key]) > 1:
                head, *rest = flat[key]
                nested.setdefault(head, {})
                _set_path(nested[head], rest, value)
            else:
                known = ", ".join(sorted(own))
                raise OptionsError(f"{where}: unknown option {clip(repr(key))} (known: {known})")
        for head, sub_data in nested.items():
            sub = type(own[head].default_factory())
            base = kwargs.get(head, sub())
            merged = {**base.plain(), **_merge(base.plain(), sub_data)}
            kwargs[head] = sub.from_plain(merged, f"{where}.{head}")
        return cls(**kwargs)

    @classmethod
    def from_flat(cls, **values):
        """Options with fields set by their flat names (``sides=6``, ``union=False``), nested or not.

        >>> from lsys3d.pipeline import GenerateOptions
        >>> GenerateOptions.from_flat(sides=6, union=False).sweep.sides
        6
        """
        return cls().with_flat(**values)

    def with_flat(self, **values):
        """A copy with fields changed by their flat names (see :meth:`from_flat`).

        A field of this class declared without :func:`option` (such as
        ``GenerateOptions.turtle``) is set by its own name.
        """
        flat = flat_fields(type(self))
        direct = {f.name for f in fields(self) if spec_of(f) is None}
        for key in values:
            if key not in flat and key not in direct:
                raise OptionsError(f"{type(self).__name__}: {unknown_name('option', key, [*flat, *direct])}")
        return _with_paths(self, {flat.get(k, (k,)): v for k, v in values.items()})


def unknown_name(what: str, name, known) -> str:
    """``unknown <what> 'name'``, with the closest of the ``known`` names when one is close: not the whole list.

    >>> unknown_name("option", "angle_jiter", ["angle_jitter", "sides", "union"])
    "unknown option 'angle_jiter'; did you mean 'angle_jitter'?"
    >>> unknown_name("option", "colour", ["sides", "union"])
    "unknown option 'colour' (2 known; see docs/architecture.md, 'Where each option lives')"
    """
    text = f"unknown {what} {clip(repr(name))}"
    close = difflib.get_close_matches(str(name), sorted(set(known)), n=1, cutoff=0.6)
    if close:
        return f"{text}; did you mean {close[0]!r}?"
    return f"{text} ({len(set(known))} known; see docs/architecture.md, 'Where each option lives')"


def _merge(base: dict, changes: dict) -> dict:
    out = dict(base)
    for k, v in changes.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _set_path(target: dict, path: list[str], value) -> None:
    for key in path[:-1]:
        target = target.setdefault(key, {})
    target[path[-1]] = value


def _with_paths(obj, changes: dict):
    direct = {p[0]: v for p, v in changes.items() if len(p) == 1}
    deeper: dict[str, dict] = {}
    for p, v in changes.items():
        if len(p) > 1:
            deeper.setdefault(p[0], {})[p[1:]] = v
    for head, sub in deeper.items():
        direct[head] = _with_paths(getattr(obj, head), sub)
    return dataclasses.replace(obj, **direct) if direct else obj


def flat_fields(cls) -> dict[str, tuple[str, ...]]:
    """Flat name -> path of field names, over a nest of options classes.

    >>> from lsys3d.pipeline import GenerateOptions
    >>> flat_fields(GenerateOptions)["sides"]
    ('sweep', 'sides')
    """
    out: dict[str, tuple[str, ...]] = {}
    for f in fields(cls):
        spec = spec_of(f)
        if spec is None:
            continue
        if spec.kind == "options":
            for name, path in flat_fields(type(f.default_factory())).items():
                if name in out:  # pragma: no cover - a declaration mistake, caught by the tests
                    raise TypeError(f"{cls.__name__}: flat name {name!r} declared twice")
                out[name] = (f.name, *path)
        else:
            name = flat_name(f)
            if name in out:  # pragma: no cover
                raise TypeError(f"{cls.__name__}: flat name {name!r} declared twice")
            out[name] = (f.name,)
    return out


def _plain(value):
    if isinstance(value, Options):
        return value.plain()
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in sorted(value.items())}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):  # numpy scalars
        return value.item()
    return value


# ------------------------------------------------------------------ the command line
def _walk(cls, path=()):
    """(field, spec, path) of every leaf field of a nest of options classes, in declaration order."""
    for f in fields(cls):
        spec = spec_of(f)
        if spec is None:
            continue
        if spec.kind == "options":
            yield from _walk(type(f.default_factory()), (*path, f.name))
        else:
            yield f, spec, (*path, f.name)


def _parser_for(spec: Spec, where: str):
    """An argparse ``type``: text -> checked value (a bad value is a usage error)."""

    def parse(text: str):
        try:
            if spec.kind is int:
                try:
                    value = int(text.replace("_", ""))
                except ValueError:
                    raise OptionsError(f"expected a whole number, not {clip(repr(text))}") from None
            elif spec.kind is float:
                try:
                    value = float(text)
                except ValueError:
                    raise OptionsError(f"expected a number, not {clip(repr(text))}") from None
            elif spec.kind in ("vector", "ints"):
                shape = spec.metavar or _metavar(spec)
                parts = re.split(r"[xX,]", text)
                convert = int if spec.kind == "ints" else float
                try:
                    value = [convert(p) for p in parts]
                except ValueError:
                    raise OptionsError(f"expected {shape}, not {clip(repr(text))}") from None
                if len(value) == 1 and spec.length > 1:  # one number for all: 800 is 800x800
                    value = value * spec.length
            else:
                value = text
            return check_value(spec, value, where)
        except OptionsError as exc:
            message = str(exc)
            if message.startswith(where + ": "):
                message = message[len(where) + 2 :]
            raise argparse.ArgumentTypeError(message) from None

    parse.__name__ = {int: "whole number", float: "number"}.get(spec.kind, "value")
    return parse


def _default_text(value) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if value == ():
        return "none"
    if isinstance(value, tuple):
        return "x".join(map(str, value)) if all(isinstance(v, int) for v in value) else ",".join(map(str, value))
    if isinstance(value, int):
        return f"{value:,}"
    return "none" if value is None else str(value)


def add_arguments(parser: argparse.ArgumentParser, cls, only=None, skip=()) -> None:
    """Add a flag for every field of ``cls`` (a nest of options classes) whose spec has ``cli``.

    ``--flat-name VALUE`` for values; for booleans ``--flat-name`` when the
    default is off and ``--no-flat-name`` when it is on.  The help is the
    spec's help, its range and its default.  Flags that are not given leave
    nothing in the namespace, so :func:`from_arguments` changes only what the
    user asked for.  ``only`` / ``skip`` select fields by flat name.
    """
    defaults = cls()
    for f, spec, path in _walk(cls):
        name = flat_name(f)
        if not spec.cli or (only is not None and name not in only) or name in skip:
            continue
        flag = name.replace("_", "-")
        default = _get(defaults, path)
        dest = "opt__" + name
        if spec.kind is bool:
            if default:
                text = f"turn off: {spec.help}"
                parser.add_argument(f"--no-{flag}", dest=dest, action="store_false", default=SUPPRESS, help=text)
            else:
                parser.add_argument(f"--{flag}", dest=dest, action="store_true", default=SUPPRESS, help=spec.help)
            continue
        extra = [x for x in (spec.range_text(), f"default {_default_text(default)}") if x]
        kw = {"choices": list(spec.choices)} if spec.choices else {"type": _parser_for(spec, f"--{flag}")}
        parser.add_argument(
            f"--{flag}",
            dest=dest,
            default=SUPPRESS,
            metavar=spec.metavar or (None if spec.choices else _metavar(spec)),
            help=f"{spec.help} ({'; '.join(extra)})",
            **kw,
        )


def _metavar(spec: Spec) -> str:
    return {int: "N", float: "X", str: "TEXT", "vector": "X,Y,Z", "ints": "WxH"}.get(spec.kind, "VALUE")


def _get(obj, path):
    for key in path:
        obj = getattr(obj, key)
    return obj


def given(args: argparse.Namespace) -> dict:
    """The options flags the user gave, by flat name."""
    return {k[len("opt__") :]: v for k, v in vars(args).items() if k.startswith("opt__")}


def from_arguments(cls, args: argparse.Namespace, base=None):
    """Options of class ``cls`` with the flags of ``args`` that belong to it applied to ``base`` (or defaults)."""
    base = cls() if base is None else base
    flat = flat_fields(cls)
    values = {k: v for k, v in given(args).items() if k in flat}
    return base.with_flat(**values) if values else base
