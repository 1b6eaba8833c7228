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
  ``elasticity_increment`` and ``bend = "cpfg"``; ``_`` adds the increment, ``_(e)`` sets it).

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

    def turtle(self) -> dict:
        """The grammar's ``[turtle]`` entries of cpfg's tropism (none without a tropism that bends)."""
        if self.tropism is None or (self.elasticity == 0 and self.elasticity_increment == 0):
            return {}
        return {
            "tropism": list(self.tropism),
            "elasticity": self.elasticity,
            "elasticity_increment": self.elasticity_increment,
            "bend": "cpfg",
        }


def strip_comments(text: str) -> str:
    """``/* ... */`` and ``// ...`` blanked out, line breaks kept."""
    text = re.sub(r"/\*.*?(\*/|\Z)", lambda m: re.sub(r"[^\n]", " ", m.group()), text, flags=re.DOTALL)
    return re.sub(r"//[^\n]*", "", text)


_LINE = re.compile(
    r"(?P<key>function set|function|curve|tropism direction|initial elasticity|elasticity increment)\s*:\s*"
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
    return View(tuple(functions), tuple(curves), names, **settings)


def _numbers(text: str, count: int) -> list[float] | None:
    words = [w for w in re.split(r"[\s,]+", text) if w]
    try:
        values = [float(w) for w in words[:count]]
    except ValueError:
        return None
    return values if len(values) == count and all(math.isfinite(v) for v in values) else None
