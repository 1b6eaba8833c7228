"""What a vlab model folder gives a cpfg ``.l`` file besides it: the view file's functions and tropism.

cpfg reads the view file (``plant.v`` beside ``plant.l``) for its drawing settings.  Besides the angle
(:func:`lsys3d.lsystem.dialects.cpfg.read`), lsys3d reads from it:

- ``curve: profile.con`` (one line a curve, ``curveX(1, t)``... the first): vlab's curves, which
  ``curveX``, ``curveY``, ``curveZ`` and ``curveGAL`` read;
- ``function: leaf.func 100`` (one line per function: ``func(1, x)`` is the first) and ``function set:
  functions.fset`` (vlab's gallery of named functions: each name is a ``#define`` of its number, as cpfg's
  preprocessor is given them): the files of vlab's function editor, read from the model's folder
  (:mod:`lsys3d.lsystem.splines`);
- ``tropism direction: x,y,z``, ``initial elasticity: e`` and ``elasticity increment: d``: cpfg's tropism,
  which bends the turtle after each move (the grammar's ``[turtle]`` ``tropism``, ``elasticity``,
  ``elasticity_increment`` and ``bend = "cpfg"``; ``_`` adds the increment, ``_(e)`` sets it);
- ``tropism: T: x y z A: gamma E: e S: d I: i`` and ``torque: T: x y z E: e S: d``: cpfg's newer tropisms
  and twists (its movements.c), numbered from 1 in the file's order, which ``@Ts(n, e)``, ``@Ti(n, d)``
  and ``@Td(n, d)`` switch (the grammar's ``[turtle]`` ``tropisms``: :mod:`lsys3d.turtle.bending`);
- ``contour sides: n`` and ``polygonization level: k`` (``2^(k + 1)`` sides): the sides of the tubes,
  spheres and discs where no ``@!`` sets them (the grammar's ``[turtle]`` ``cylinder_sides``).

Every file is read as data (:func:`lsys3d.external.inside`: only files of the model's own folder).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ...errors import GrammarError, clip
from ...external import FileRefused, inside
from ..grammar import read_text
from ..splines import Curve, SplineFunction, read_curve, read_function, read_function_set

__all__ = ["View", "read_view", "strip_comments"]


@dataclass(frozen=True)
class View:
    """The settings of a view file that change what lsys3d grows (functions and the tropism)."""

    functions: tuple[SplineFunction, ...] = ()
    curves: tuple[Curve, ...] = ()
    names: dict[str, int] = field(default_factory=dict)  # a function set's names and their numbers
    tropism: tuple[float, float, float] | None = None
    elasticity: float = 0.0
    elasticity_increment: float = 0.0
    tropisms: tuple[float, ...] = ()  # cpfg's movements: 7 numbers each (TurtleOptions.tropisms)
    cylinder_sides: int = 0  # contour sides: / polygonization level: (0: none given)

    def turtle(self) -> dict:
        """The grammar's ``[turtle]`` entries of cpfg's tropisms (the old one only when it bends)."""
        out: dict = {"tropisms": list(self.tropisms)} if self.tropisms else {}
        if self.cylinder_sides:
            out["cylinder_sides"] = self.cylinder_sides
        if self.tropism is None or (self.elasticity == 0 and self.elasticity_increment == 0):
            return out
        return {
            "tropism": list(self.tropism),
            "elasticity": self.elasticity,
            "elasticity_increment": self.elasticity_increment,
            "bend": "cpfg",
            **out,
        }


def strip_comments(text: str) -> str:
    """``/* ... */`` and ``// ...`` blanked out, line breaks kept."""
    text = re.sub(r"/\*.*?(\*/|\Z)", lambda m: re.sub(r"[^\n]", " ", m.group()), text, flags=re.DOTALL)
    return re.sub(r"//[^\n]*", "", text)


_LINE = re.compile(
    r"(?P<key>function set|function|curve|tropism direction|initial elasticity|elasticity increment|tropism|torque"
    r"|contour sides|polygonization level)\s*:\s*"
    r"(?P<rest>.*)\Z"
)


def read_view(path: Path) -> View:
    """The functions and the tropism of the view file beside ``path`` (an empty :class:`View` without one).

    A file it names that cannot be read, or is not what cpfg reads, is a :class:`GrammarError` naming the
    view file's line.
    """
    view = path.with_suffix(".v")
    if not view.is_file():
        return View()
    folder = path.parent
    try:
        text = read_text(inside(folder, view.name, "view file"))
    except (FileRefused, GrammarError):
        return View()  # the angle's reader says why (cpfg.read warns)
    functions: list[SplineFunction] = []
    curves: list[Curve] = []
    names: dict[str, int] = {}
    settings: dict = {}
    movements: list[float] = []
    for number, raw in enumerate(strip_comments(text).split("\n"), start=1):
        m = _LINE.match(raw.strip())
        if m is None:
            continue
        key, rest = m.group("key"), m.group("rest").strip()

        def fail(what: str, number=number) -> GrammarError:
            return GrammarError(what, str(view), number, 1)

        if key in ("function", "function set", "curve"):
            words = rest.split()
            if not words or len(words) > (1 if key == "function set" else 2):
                raise fail(f"{key}: expects a file name{'' if key == 'function set' else ' and the samples'}")
            name = words[0]
            samples = 100 if key == "curve" else 0  # cpfg's default for a curve (interpret.c)
            if len(words) == 2:
                if not re.fullmatch(r"\d{1,6}", words[1]):
                    raise fail(f"{key}: the samples must be a whole number, not {clip(words[1], 20)!r}")
                samples = int(words[1])
            try:
                content = read_text(inside(folder, name, "function file"))
            except (FileRefused, GrammarError) as exc:
                raise fail(f"{key}: {clip(name, 60)!r}: {exc.reason}") from None
            source = str(folder / name)
            if key == "curve":
                curves.append(read_curve(content, source, samples))
            elif key == "function":
                functions.append(read_function(content, source, samples))
            else:  # cpfg's ReadFunctionSet: the set replaces the functions read before it
                functions = list(read_function_set(content, source))
                names = {f.name: i + 1 for i, f in enumerate(functions)}
        elif key in ("contour sides", "polygonization level"):
            values = _numbers(rest, 1)
            if not values or values[0] != int(values[0]) or not -1 <= values[0] <= 1024:
                raise fail(f"{key}: expects a whole number, not {clip(rest, 40)!r}")
            # interpret.c: the sides, or 2^(level + 1) (rint), at least 3; lsys3d holds them to 1,024 as @!
            n = int(values[0]) if key == "contour sides" else min(1024, round(2.0 ** (values[0] + 1)))
            settings["cylinder_sides"] = min(1024, max(3, n))
        elif key in ("tropism", "torque"):
            row = _movement(rest, key == "torque")
            if isinstance(row, str):
                raise fail(f"{key}: {row}")
            movements += row
        elif key == "tropism direction":
            values = _numbers(rest, 3)
            length = math.sqrt(sum(v * v for v in values)) if values else 0.0
            if not values or not length > 0:
                raise fail(f"tropism direction: expects three numbers x,y,z not all 0, not {clip(rest, 40)!r}")
            settings["tropism"] = tuple(v / length for v in values)
        else:
            values = _numbers(rest, 1)
            if not values:
                raise fail(f"{key}: expects a number, not {clip(rest, 40)!r}")
            settings["elasticity" if key == "initial elasticity" else "elasticity_increment"] = values[0]
    return View(tuple(functions), tuple(curves), names, **settings, tropisms=tuple(movements))


def _movement(text: str, twist: bool) -> list[float] | str:
    """One of cpfg's movements (movements.c ``read_movement``) as ``TurtleOptions.tropisms``' seven numbers, or
    what is wrong with it.

    ``T: x y z`` its vector (made a unit vector), ``I: i`` scales it (the scale held to [-1, 1]), ``A: gamma``
    its angle, ``E: e`` the initial elasticity, ``S: d`` the increment; cpfg leaves out a line it cannot read
    (so the numbers of the ones after it change): lsys3d refuses it.

    >>> _movement("T: 0.0  1.0 0.0  A:90", False)
    [0.0, 0.0, 1.0, 0.0, 90.0, 0.0, 0.0]
    >>> _movement("T: 0 2 0 I: 0.5 E: 0.1", True)
    [1.0, 0.0, 0.5, 0.0, 0.0, 0.1, 0.0]
    """
    words = [w for w in re.split(r"[\s,:]+", text) if w]
    vector, scale, gamma, elasticity, increment = None, 0.0, 0.0, 0.0, 0.0
    i = 0
    try:
        while i < len(words):
            letter = words[i][0]
            if letter == "T":
                vector = [float(w) for w in words[i + 1 : i + 4]]
                length = math.sqrt(sum(v * v for v in vector))
                if len(vector) != 3 or not length > 0 or not math.isfinite(length):
                    return f"T: expects three numbers not all 0, not {clip(' '.join(words[i + 1 : i + 4]), 40)!r}"
                scale = 1.0 / length
                i += 4
                continue
            if letter not in "IAES" or i + 1 >= len(words):
                return f"unknown or incomplete entry {clip(words[i], 20)!r} (cpfg reads T:, I:, A:, E:, S:)"
            value = float(words[i + 1])
            if not math.isfinite(value):
                return f"{letter}: expects a number, not {clip(words[i + 1], 20)!r}"
            if letter == "I":
                scale = max(-1.0, min(1.0, scale * value))
            elif letter == "A":
                gamma = value
            elif letter == "E":
                elasticity = value
            else:
                increment = value
            i += 2
    except ValueError:
        return f"expects numbers after T:, I:, A:, E:, S:, not {clip(text, 40)!r}"
    if vector is None:
        return "expects its vector (T: x y z)"
    if scale == 0:
        return "its intensity (I:) is 0"
    return [1.0 if twist else 0.0, *(v * scale for v in vector), gamma, elasticity, increment]


def _numbers(text: str, count: int) -> list[float] | None:
    words = [w for w in re.split(r"[\s,]+", text) if w]
    try:
        values = [float(w) for w in words[:count]]
    except ValueError:
        return None
    return values if len(values) == count and all(math.isfinite(v) for v in values) else None
