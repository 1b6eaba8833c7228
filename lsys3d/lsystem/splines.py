"""vlab's graphically defined functions: the files of its function editor, and ``func(id, x)`` evaluated as cpfg does.

vlab's function editor (``funcedit``, and ``gallery`` for a set of them) saves a function of ``x`` in
[0, 1] as the control points of a cubic B-spline curve ``(x(u), y(u))``.  cpfg reads them from the view
file (``function: leaf.func 100`` once per function, the first being ``func(1, x)``, or ``function set:
functions.fset``, a gallery whose functions are named: each name is a ``#define`` of its number) and a
production calls ``func(id, x)`` (cpfg's ``splinefun.cpp``):

- the curve is the clamped uniform cubic B-spline of the control points (knots ``0,0,0,0,1,...,n-3,n-3,
  n-3,n-3``); a control point written with a third number (``0.5 0.2 3``) counts that many times;
- ``func(id, x)`` is ``y`` where the curve's ``x`` equals ``x`` (``x`` held to [0, 1]), found by halving
  the curve's parameter until ``x`` is within 0.001;
- with ``samples: N`` (the file's, or the view file's ``function: name.func N``) cpfg finds ``y`` so at
  ``N`` evenly spaced ``x`` once, and ``func`` interpolates linearly between them.

Two file formats: ``fver 1 1`` (``name:``, ``samples:``, ``flip:``, ``points:``, the points; a function
set is ``funcgalleryver 1 1``, ``items: N`` and N of them) and the older ``range: 0 1`` (``points:``,
the points; its samples come from the view file).

>>> f = read_function("range: 0 1\\npoints: 4\\n0 0\\n0.33 0.33\\n0.67 0.67\\n1 1\\n", "line.func")
>>> [round(float(v), 2) for v in f.evaluate(np.array([0.0, 0.25, 0.5]))]
[0.0, 0.25, 0.5]
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import GrammarError, clip
from .expr import EvalError, Function

__all__ = [
    "MAX_POINTS",
    "MAX_SAMPLES",
    "Curve",
    "SplineFunction",
    "from_table",
    "native_functions",
    "read_curve",
    "read_function",
    "read_function_set",
    "to_table",
]

MAX_POINTS = 1024
"""Most control points of one function (multiplicities counted)."""
MAX_SAMPLES = 100_000
"""Most samples of one function."""
TOLERANCE = 0.001
"""cpfg's MaxError: how close the curve's ``x`` comes to the asked ``x``."""
_HALVINGS = 64  # the parameter halved at most this often (cpfg halves until within TOLERANCE)


@dataclass(frozen=True)
class SplineFunction:
    """One function of vlab's function editor: control points of its curve and cpfg's number of samples.

    Attributes
    ----------
    name : str
        Its name (a function set's ``name:``, or the file's name without ``.func``).
    points : tuple of (x, y)
        The control points, each as many times as its multiplicity says (at least 4).
    samples : int
        cpfg's precomputed values (``> 2``), or 0: each value found on the curve when asked.
    """

    name: str
    points: tuple[tuple[float, float], ...]
    samples: int = 0

    def curve(self, d: np.ndarray) -> np.ndarray:
        """The curve's points at parameters ``d`` in [0, 1): ``(len(d), 2)`` (cpfg's ``SplineFunction::P``)."""
        pts = np.asarray(self.points, np.float64)
        n = len(pts) - 1
        u = np.asarray(d, np.float64) * (n - 2)
        knots = np.array([0 if j < 4 else (n - 2 if j > n else j - 3) for j in range(n + 5)], np.float64)
        # Cox-de Boor, order 1 to 4, on all the basis functions at once
        basis = ((knots[:-1, None] <= u) & (u < knots[1:, None])).astype(np.float64)  # (n + 4, len(u))
        for t in range(2, 5):
            k = np.arange(basis.shape[0] - 1)
            span_a = knots[k + t - 1] - knots[k]
            span_b = knots[k + t] - knots[k + 1]
            with np.errstate(divide="ignore", invalid="ignore"):
                a = np.where(span_a[:, None] != 0, (u - knots[k, None]) / span_a[:, None], 0.0) * basis[:-1]
                b = np.where(span_b[:, None] != 0, (knots[k + t, None] - u) / span_b[:, None], 0.0) * basis[1:]
            basis = a + b
        return basis[: n + 1].T @ pts

    def find(self, x: np.ndarray) -> np.ndarray:
        """``y`` where the curve's ``x`` is within :data:`TOLERANCE` of ``x`` (cpfg's halving search)."""
        x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
        low, high = np.zeros_like(x), np.ones_like(x)
        out = np.zeros_like(x)
        todo = np.ones(x.shape, np.bool_)
        for _ in range(_HALVINGS):
            check = (low + high) / 2.0
            point = self.curve(check)
            above = point[:, 0] > x
            high = np.where(todo & above, check, high)
            low = np.where(todo & ~above, check, low)
            done = todo & (np.abs(point[:, 0] - x) <= TOLERANCE)
            out[todo] = point[todo, 1]
            todo &= ~done
            if not todo.any():
                break
        return out

    @cached_property
    def table(self) -> np.ndarray | None:
        """cpfg's precomputed values at ``samples`` evenly spaced ``x`` (None without samples)."""
        if self.samples <= 2:
            return None
        return self.find(np.arange(self.samples) / (self.samples - 1))

    def evaluate(self, x) -> np.ndarray:
        """``func(id, x)``: the function at ``x`` (held to [0, 1]), as cpfg computes it."""
        x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
        table = self.table
        if table is None:
            return self.find(x)
        index = x * (self.samples - 1)
        i = np.minimum(np.floor(index).astype(np.int64), self.samples - 1)
        w = index - i
        nxt = np.minimum(i + 1, self.samples - 1)
        return (1.0 - w) * table[i] + w * table[nxt]


def _fail(source: str, line: int, what: str) -> GrammarError:
    return GrammarError(what, source, line, 1)


def _points(lines: list[tuple[int, str]], at: int, count: int, source: str) -> tuple[list, int]:
    if not 4 <= count <= MAX_POINTS:
        raise _fail(source, lines[at - 1][0] if at else 1, f"a function needs 4 to {MAX_POINTS} points, not {count}")
    out: list[tuple[float, float]] = []
    for k in range(count):
        if at + k >= len(lines):
            raise _fail(source, lines[-1][0] if lines else 1, f"{count} points announced, {k} found")
        number, text = lines[at + k]
        words = text.split()
        try:
            values = [float(w) for w in words]
        except ValueError:
            raise _fail(source, number, f"a point reads 'x y' or 'x y multiplicity', not {clip(text, 40)!r}") from None
        if len(values) not in (2, 3) or not all(np.isfinite(values)):
            raise _fail(source, number, f"a point reads 'x y' or 'x y multiplicity', not {clip(text, 40)!r}")
        times = int(values[2]) if len(values) == 3 else 1  # cpfg's stof, then int
        if not 1 <= times <= MAX_POINTS or len(out) + times > MAX_POINTS:
            raise _fail(source, number, f"a point's multiplicity must be 1 to {MAX_POINTS} in all, not {times}")
        out += [(values[0], values[1])] * times
    return out, at + count


def _field(lines, at: int, key: str, source: str) -> str:
    if at >= len(lines):
        raise _fail(source, lines[-1][0] if lines else 1, f"'{key}:' expected, the file ends")
    number, text = lines[at]
    m = re.match(rf"{key}\s*:\s*(.*)\Z", text)
    if m is None:
        raise _fail(source, number, f"'{key}:' expected, not {clip(text, 40)!r}")
    return m.group(1).strip()


def _whole(text: str, lines, at: int, key: str, source: str, high: int) -> int:
    if not re.fullmatch(r"[+-]?\d+", text) or not 0 <= int(text) <= high:
        raise _fail(source, lines[at][0], f"'{key}:' must be a whole number from 0 to {high}, not {clip(text, 40)!r}")
    return int(text)


def _lines(text: str) -> list[tuple[int, str]]:
    return [(k + 1, line.strip()) for k, line in enumerate(text.splitlines()) if line.strip()]


def _read_0101(lines, at: int, source: str) -> tuple[SplineFunction, int]:
    """One ``fver 1 1`` function from ``lines[at]`` (the line after ``fver``), as cpfg's ``_Load0101``."""
    name = _field(lines, at, "name", source)
    samples = _whole(_field(lines, at + 1, "samples", source), lines, at + 1, "samples", source, MAX_SAMPLES)
    at += 2
    if at < len(lines) and lines[at][1].startswith("b"):  # a background image: two lines, not read
        at += 2
    if at < len(lines) and lines[at][1].startswith("markers"):
        markers = _whole(_field(lines, at, "markers", source), lines, at, "markers", source, MAX_POINTS)
        at += 1 + markers
    _field(lines, at, "flip", source)  # the editor's, not cpfg's
    count = _whole(_field(lines, at + 1, "points", source), lines, at + 1, "points", source, MAX_POINTS)
    points, at = _points(lines, at + 2, count, source)
    return SplineFunction(name, tuple(points), samples if samples > 2 else 0), at


def read_function(text: str, source: str, samples: int = 0) -> SplineFunction:
    """A ``.func`` file (``fver 1 1`` or the older ``range:`` format) into a :class:`SplineFunction`.

    ``samples`` is the view file's (``function: leaf.func 100``): the older format's only source of it;
    an ``fver`` file names its own, as in cpfg.
    """
    lines = _lines(text)
    if not lines:
        raise _fail(source, 1, "an empty function file")
    name = re.sub(r"\.func\Z", "", source.replace("\\", "/").rsplit("/", 1)[-1])
    first = lines[0][1]
    if re.match(r"range\s*:", first):
        count = _whole(_field(lines, 1, "points", source), lines, 1, "points", source, MAX_POINTS)
        points, _ = _points(lines, 2, count, source)
        return SplineFunction(name, tuple(points), samples if samples > 2 else 0)
    if re.fullmatch(r"fver\s+1\s+1", first):
        function, _ = _read_0101(lines, 1, source)
        return function
    raise _fail(source, lines[0][0], f"not a function file of vlab's ('fver 1 1' or 'range:'), {clip(first, 40)!r}")


def read_function_set(text: str, source: str) -> tuple[SplineFunction, ...]:
    """A function set (``.fset``, vlab's gallery: ``funcgalleryver 1 1``) into its functions, in order."""
    lines = _lines(text)
    if not lines or not re.fullmatch(r"funcgalleryver\s+1\s+1", lines[0][1]):
        raise _fail(source, lines[0][0] if lines else 1, "not a function set of vlab's ('funcgalleryver 1 1')")
    items = _whole(_field(lines, 1, "items", source), lines, 1, "items", source, MAX_POINTS)
    at = 2
    out = []
    for _ in range(items):
        if at >= len(lines) or not re.fullmatch(r"fver\s+1\s+1", lines[at][1]):
            raise _fail(source, lines[min(at, len(lines) - 1)][0], "'fver 1 1' expected: the next function")
        function, at = _read_0101(lines, at + 1, source)
        out.append(function)
    return tuple(out)


@dataclass(frozen=True)
class Curve:
    """A curve of vlab's curve editor (a ``.con`` file of type ``bspline``), for cpfg's ``curveX(id, t)``...

    ``t`` in [0, 1] is the arc length along the curve, as a fraction of its whole length (cpfg's
    ``CCurveXYZ::calcAValue``: the curve sampled at ``samples`` evenly spaced parameters, the lengths of the
    polyline between them, the parameter of ``t`` interpolated between the two samples around it);
    ``curveGAL(id)`` is the polyline's whole length.  The curve is the uniform cubic B-spline of the
    control points (each as many times as its multiplicity says).
    """

    name: str
    points: tuple[tuple[float, float, float], ...]
    samples: int = 100

    def at(self, u: np.ndarray) -> np.ndarray:
        """The curve's points at parameters ``u`` in [0, 1]: ``(len(u), 3)`` (cpfg's ``calcPValue``, bspline)."""
        pts = np.asarray(self.points, np.float64)
        size = len(pts)
        u = np.asarray(u, np.float64)
        i = 3 + (u * (size - 3.000001)).astype(np.int64)
        v = (3.0 + u * (size - 3.000001)) - i  # the local parameter in [0, 1)
        weights = (
            (1 - v) ** 3 / 6,
            (3 * v**3 - 6 * v**2 + 4) / 6,
            (-3 * v**3 + 3 * v**2 + 3 * v + 1) / 6,
            v**3 / 6,
        )
        return sum(w[:, None] * pts[i - 3 + k] for k, w in enumerate(weights))

    @cached_property
    def lengths(self) -> tuple[np.ndarray, float]:
        """The samples' arc lengths as fractions of the whole, and the whole (cpfg's ``createAPoints``)."""
        points = self.at(np.arange(self.samples) / (self.samples - 1))
        steps = np.sqrt((np.diff(points, axis=0) ** 2).sum(axis=1))
        total = float(steps.sum())
        cumulative = np.concatenate([[0.0], np.cumsum(steps)])
        return (cumulative / total if total > 0 else cumulative), total

    def point(self, t) -> np.ndarray:
        """The point at the fraction ``t`` of the arc length (held to [0, 1]): ``(len(t), 3)``."""
        t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)
        frac, _ = self.lengths
        n = self.samples
        # cpfg's halving search for the two samples around t: the last min with frac[min] <= t
        low = np.clip(np.searchsorted(frac, t, side="right") - 1, 0, n - 2)
        high = low + 1
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (low + (t - frac[low]) / (frac[high] - frac[low])) / (n - 1)
        return self.at(np.clip(np.nan_to_num(u), 0.0, 1.0))


def read_curve(text: str, source: str, samples: int = 100) -> Curve:
    """A curve file of vlab's (``.con``: ``points:``, ``dimension:``, ``type:`` and the points) into a :class:`Curve`.

    Only the ``bspline`` type (cpfg's default) and one level of points are read; other types are refused in
    one line naming them.
    """
    lines = _lines(text)
    count = dimension = None
    kind = "bspline"
    out: list[tuple[float, float, float]] = []
    name = re.sub(r"\.con\Z", "", source.replace("\\", "/").rsplit("/", 1)[-1])
    for number, line in lines:
        m = re.match(r"([a-z ]+):\s*(.*)\Z", line)
        if m:
            key, rest = m.group(1).strip(), m.group(2).strip()
            if key == "points":
                if count is not None:
                    raise _fail(source, number, "curves of curves (a second 'points:') are not supported")
                count = _whole(rest, lines, [n for n, _ in lines].index(number), key, source, MAX_POINTS)
            elif key in ("dimension", "dim"):
                dimension = _whole(rest, lines, [n for n, _ in lines].index(number), key, source, 4)
            elif key == "type":
                kind = rest
            continue
        if count is None:
            raise _fail(source, number, f"a point before 'points:': {clip(line, 40)!r}")
        try:
            values = [float(w) for w in line.split()]
        except ValueError:
            raise _fail(source, number, f"a point reads numbers, not {clip(line, 40)!r}") from None
        if len(values) != (dimension or 2) or not all(np.isfinite(values)):
            raise _fail(source, number, f"a point of {dimension or 2} numbers expected, not {clip(line, 40)!r}")
        times = int(values[3]) if len(values) > 3 else 1
        if not 1 <= times <= MAX_POINTS or len(out) + times > MAX_POINTS:
            raise _fail(source, number, f"a point's multiplicity must be 1 to {MAX_POINTS} in all, not {times}")
        z = values[2] if len(values) > 2 else 0.0
        out += [(values[0], values[1], z)] * times
    if kind != "bspline":
        raise _fail(source, 1, f"curve type {clip(kind, 30)!r} is not supported (only 'bspline')")
    if count is None or len(out) < 4:
        raise _fail(source, 1, "a curve needs 'points:' and at least 4 points")
    if not 2 <= samples <= MAX_SAMPLES:
        raise _fail(source, 1, f"a curve's samples must be 2 to {MAX_SAMPLES}, not {samples}")
    return Curve(name, tuple(out), samples)


def to_table(functions, curves=()) -> dict[str, dict]:
    """Functions and curves as a grammar's ``[splines]`` table.

    ``"1" = { name = "rho", samples = 100, points = [[x, y], ...] }`` for ``func(1, x)``, and ``"curve 1" =
    { name = "profile", samples = 100, points = [[x, y, z], ...] }`` for ``curveX(1, t)``...
    """
    out = {
        str(i + 1): {"name": f.name, "samples": f.samples, "points": [list(p) for p in f.points]}
        for i, f in enumerate(functions)
    }
    for i, c in enumerate(curves):
        out[f"curve {i + 1}"] = {"name": c.name, "samples": c.samples, "points": [list(p) for p in c.points]}
    return out


def from_table(table: Mapping, source: str) -> tuple[dict[int, SplineFunction], dict[int, Curve]]:
    """A grammar's ``[splines]`` table back into its functions and curves, by number (a :class:`GrammarError`
    if malformed)."""
    functions, curves = {}, {}
    for key, entry in table.items():
        where = f"[splines] {clip(str(key), 20)}"
        m = re.fullmatch(r"(curve )?([1-9]\d{0,5})", str(key))
        if m is None or not isinstance(entry, Mapping):
            raise GrammarError(f"{where}: expected 'NUMBER' or 'curve NUMBER' = {{ name, samples, points }}", source)
        width = 3 if m.group(1) else 2
        points = entry.get("points")
        samples = entry.get("samples", 0)
        ok = isinstance(points, (list, tuple)) and 4 <= len(points) <= MAX_POINTS
        ok = ok and all(
            isinstance(p, (list, tuple))
            and len(p) == width
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in p)
            for p in points
        )
        if not ok:
            raise GrammarError(f"{where}: 'points' must be 4 to {MAX_POINTS} lists of {width} numbers", source)
        low = 2 if width == 3 else 0
        if isinstance(samples, bool) or not isinstance(samples, int) or not low <= samples <= MAX_SAMPLES:
            raise GrammarError(f"{where}: 'samples' must be a whole number from {low} to {MAX_SAMPLES}", source)
        name = entry.get("name", "")
        if not isinstance(name, str):
            raise GrammarError(f"{where}: 'name' must be a string", source)
        if width == 3:
            curves[int(m.group(2))] = Curve(name, tuple(tuple(float(v) for v in p) for p in points), samples)
        else:
            functions[int(m.group(2))] = SplineFunction(name, tuple((float(x), float(y)) for x, y in points), samples)
    return functions, curves


def native_functions(table: Mapping, source: str) -> dict[str, Function]:
    """cpfg's ``func(id, x)`` over a grammar's ``[splines]`` table (nothing when the table is empty)."""
    if not table:
        return {}
    functions, curves = from_table(table, source)

    def each(name: str, table: dict, ids: np.ndarray, what):
        noun = "function" if name == "func" else "curve"
        ids = np.trunc(ids)  # cpfg's (int)
        out = np.zeros(len(ids))
        for number in np.unique(ids):
            index = np.flatnonzero(ids == number)
            found = table.get(int(number)) if np.isfinite(number) else None
            if found is None:
                known = ", ".join(str(k) for k in sorted(table)) or "none"
                raise EvalError(f"{name}({number:g}, ...): no such {noun} (the view file's are {known})", index[:1])
            out[index] = what(found, index)
        return out

    out = {}
    if functions:
        out["func"] = Function(
            "func", ("id", "x"), None, native=lambda ids, x: each("func", functions, ids, lambda f, k: f.evaluate(x[k]))
        )
    if curves:
        for axis, name in enumerate(("curveX", "curveY", "curveZ")):
            out[name] = Function(
                name,
                ("id", "t"),
                None,
                native=lambda ids, t, axis=axis, name=name: each(
                    name, curves, ids, lambda c, k: c.point(t[k])[:, axis]
                ),
            )
        out["curveGAL"] = Function(
            "curveGAL", ("id",), None, native=lambda ids: each("curveGAL", curves, ids, lambda c, k: c.lengths[1])
        )
    return out
