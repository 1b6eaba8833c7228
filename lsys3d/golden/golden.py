"""Golden files: a generated asset's recipe and its report, to regression-test counts.

A golden file is JSON::

    {
      "lsys3d_golden": 1,
      "recipe": {"preset": "tree3d", "iterations": 6, "seed": 0, "mesh": true,
                 "options": {"sweep": {"sides": 6}}, "grammar_sha256": "..."},
      "report": {... what lsys3d.stats.report() gives ...}
    }

The recipe names the grammar (a bundled ``preset``, a ``file`` relative to the
golden file's folder, or the grammar ``text`` itself), the iterations and seed,
and the options that differ from :class:`~lsys3d.pipeline.GenerateOptions`'
defaults.  :func:`check` regrows the asset and compares the new report with the
recorded one (:func:`compare`): counts exactly, floats within a relative
tolerance, and the union's counts exactly only when the installed manifold3d is
the version that recorded them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import GoldenError, LSystemError, OptionsError, clip, os_reason
from ..exchange.atomic import write_bytes
from ..external import FileRefused, load_json, read_file
from ..lsystem import dialects
from ..lsystem.grammar import Grammar
from ..lsystem.presets import list_presets, load_preset
from ..pipeline import GenerateOptions, draw, generate
from ..provenance import grammar_text
from ..stats import flatten, report
from ..tree import Tree

__all__ = [
    "GOLDEN_FORMAT",
    "CheckResult",
    "Difference",
    "Recipe",
    "check",
    "compare",
    "format_changes",
    "format_differences",
    "grow",
    "make_folder",
    "preset_recipe",
    "read_golden",
    "recipe_for",
    "summarize",
    "write_golden",
]

GOLDEN_FORMAT = 1

MAX_GOLDEN_BYTES = 16 << 20
"""Largest golden file read, in bytes (a recipe may hold a grammar's whole text)."""

RTOL = 1e-6
"""Relative tolerance of floating values (volume, area, lengths, bounding boxes)."""

UNION_RTOL = 0.02
"""Relative tolerance of the union's counts and measures when manifold3d's version differs from the recorded one."""

# counts and measures that depend on manifold3d's arithmetic
_UNION_KEYS = {
    "bark.vertices",
    "bark.faces",
    "bark.volume",
    "bark.area",
    "bbox.max",
    "bbox.min",
    # the cleanup works on the union's result: its counts follow the union's
    "quality.triangles",
    "quality.over_100",
    "quality.over_1000",
    "quality.slivers",
    "quality.max_aspect",
    "quality.uv_stretch",
}


@dataclass(frozen=True)
class Recipe:
    """How to regrow an asset: exactly one of ``preset``, ``file``, ``text`` names the grammar.

    Attributes
    ----------
    preset : str or None
        A bundled preset's name.
    file : str or None
        A grammar file, relative to the golden file's folder (or absolute).
    text : str or None
        The grammar's TOML text itself (for grammars built in Python).
    iterations, seed : int
    mesh : bool
        Build the meshes (sweep, union, leaves); False for symbol-only grammars.
    options : dict
        :class:`~lsys3d.pipeline.GenerateOptions` fields that differ from the defaults, nested.
    grammar_sha256 : str
        Hash of the grammar text when recorded; a change is reported, not failed.
    """

    iterations: int
    seed: int
    preset: str | None = None
    file: str | None = None
    text: str | None = None
    mesh: bool = True
    options: dict = field(default_factory=dict)
    grammar_sha256: str = ""

    def describe(self) -> str:
        name = self.preset or self.file or "inline grammar"
        extra = " " + json.dumps(self.options, sort_keys=True) if self.options else ""
        return f"{name} n={self.iterations} seed={self.seed}{'' if self.mesh else ' (no mesh)'}{extra}"

    def as_json(self) -> dict:
        data = dataclasses.asdict(self)
        return {k: v for k, v in sorted(data.items()) if v is not None}


@dataclass(frozen=True)
class Difference:
    """One key whose value changed; ``failed`` when the change is outside its tolerance."""

    key: str
    expected: object
    actual: object
    failed: bool
    note: str = ""

    def change(self) -> str:
        e, a = self.expected, self.actual
        if _is_number(e) and _is_number(a):
            delta = a - e
            text = f"{delta:+,}" if isinstance(delta, int) else f"{delta:+.3g}"
            return text + (f" ({delta / e * 100:+.3g}%)" if e else "")
        return self.note or "changed"

    @property
    def is_count(self) -> bool:
        """Whether the key holds a count or a flag (compared exactly), not a floating value (within a tolerance)."""
        return _exact(self.expected) and _exact(self.actual)


@dataclass
class CheckResult:
    """What :func:`check` found for one golden file.

    ``missing``: there was no such file (``recipe`` is None unless ``update`` recorded one: ``created``).
    """

    path: Path
    recipe: Recipe | None
    differences: list[Difference]
    warnings: list[str]
    report: dict
    updated: bool = False
    missing: bool = False
    created: bool = False

    @property
    def ok(self) -> bool:
        return (not self.missing or self.created) and not any(d.failed for d in self.differences)


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# what each recipe field holds, checked before anything is grown (a golden file is data from anywhere)
_RECIPE_FIELDS = {
    "iterations": (int, "a whole number >= 0"),
    "seed": (int, "a whole number >= 0"),
    "preset": (str, "a preset's name"),
    "file": (str, "a file name (without NUL characters)"),
    "text": (str, "the grammar's text"),
    "mesh": (bool, "true or false"),
    "options": (dict, "a table of options"),
    "grammar_sha256": (str, "a text"),
}


# ---------------------------------------------------------------- options <-> plain dicts


def _delta(values: dict, defaults: dict) -> dict:
    """The entries of nested ``values`` that differ from ``defaults``."""
    out = {}
    for key, value in sorted(values.items()):
        default = defaults.get(key)
        if isinstance(value, dict) and isinstance(default, dict):
            if sub := _delta(value, default):
                out[key] = sub
        elif value != default:
            out[key] = value
    return out


# ---------------------------------------------------------------- recipes


def recipe_for(
    grammar,
    iterations: int | None = None,
    seed: int | None = None,
    options=None,
    mesh: bool = True,
    golden_path: str | os.PathLike = ".",
) -> Recipe:
    """The recipe that regrows a grammar's asset, for a golden file at ``golden_path``.

    ``grammar`` is a :class:`~lsys3d.lsystem.grammar.Grammar`, or a :class:`~lsys3d.tree.Tree`
    (its provenance gives everything, and ``iterations``, ``seed``, ``options``
    are ignored); ``iterations`` and ``seed`` default to the grammar's.  A
    bundled preset is named, a grammar file is referred to by its path relative
    to the golden file's folder, a grammar built in Python is stored as text.
    """
    if isinstance(grammar, Tree):
        prov = grammar.provenance
        if prov is None:
            raise GoldenError("recipe_for: the tree has no provenance (it was not grown by lsys3d.generate)")
        source, text = prov.grammar_source, prov.grammar_text
        iterations, seed, plain = prov.iterations, prov.seed, prov.options
    else:
        source = grammar.source or ""
        text = grammar.text if grammar.text is not None else grammar_text(grammar)
        iterations = grammar.iterations if iterations is None else iterations
        seed = grammar.seed if seed is None else seed
        plain = (options or GenerateOptions()).plain()
    kind: dict = {}
    name = source[len("presets/") : -len(".toml")] if source.startswith("presets/") else None
    if name in list_presets():
        kind["preset"] = name
    elif source and not source.startswith("<") and Path(source).is_file():
        folder = Path(golden_path).resolve().parent
        kind["file"] = Path(os.path.relpath(Path(source).resolve(), folder)).as_posix()
    else:
        if dialects.reader_for(source) is not None:  # a native file no longer there: its grammar as TOML
            text = grammar_text(Grammar.from_text(text, source=source))
        kind["text"] = text
    return Recipe(
        iterations=int(iterations),
        seed=int(seed),
        mesh=bool(mesh),
        options=_delta(plain, GenerateOptions().plain()),
        grammar_sha256=_sha256(text),
        **kind,
    )


def _grammar(recipe: Recipe, folder: Path):
    if recipe.preset is not None:
        return load_preset(recipe.preset)
    if recipe.file is not None:
        return Grammar.from_file(folder / recipe.file)
    return Grammar.from_text(recipe.text, source="<golden recipe>")


def grow(recipe: Recipe, folder: str | os.PathLike = ".") -> dict:
    """Regrow the asset a recipe names and return its :func:`~lsys3d.stats.report`."""
    return _grow(recipe, _grammar(recipe, Path(folder)))


def _generate_options(recipe: Recipe, where: str):
    try:
        return GenerateOptions.from_plain(recipe.options, "recipe options")
    except OptionsError as exc:  # the option classes' own checks
        what = str(exc) if str(exc).startswith("recipe options") else f"recipe options: {exc}"
        raise GoldenError(f"{where}: {what}") from None


def _grow(recipe: Recipe, grammar, where: str = "recipe") -> dict:
    options = _generate_options(recipe, where)
    if recipe.mesh:
        tree = generate(grammar, recipe.iterations, recipe.seed, options=options)
        return report(tree.modules, tree.skeleton, tree)
    return report(*draw(grammar, recipe.iterations, recipe.seed, options))


# ---------------------------------------------------------------- files


def read_golden(path: str | os.PathLike) -> tuple[Recipe, dict]:
    """Read a golden file: its recipe and its recorded report.

    Raises
    ------
    GoldenError
        ``path: what is wrong`` for a missing, unreadable or malformed file.
    """
    path = Path(path)
    try:
        raw_bytes = read_file(path, MAX_GOLDEN_BYTES, "golden file", "lsys3d.golden.golden.MAX_GOLDEN_BYTES")
    except FileRefused as exc:
        raise GoldenError(str(exc)) from None
    try:
        data = load_json(raw_bytes.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise GoldenError(f"{path}: not a golden file: {exc}") from None
    except ValueError as exc:  # bad JSON, or arrays and objects nested too deeply
        reason = str(exc).replace("JSON nested", "arrays or objects nested too deeply:")
        raise GoldenError(f"{path}: not a golden file: {reason}") from None
    if not isinstance(data, dict) or data.get("lsys3d_golden") != GOLDEN_FORMAT:
        raise GoldenError(f'{path}: not a golden file (no "lsys3d_golden": {GOLDEN_FORMAT})')
    raw, recorded = data.get("recipe"), data.get("report")
    if not isinstance(raw, dict) or not isinstance(recorded, dict):
        raise GoldenError(f'{path}: a golden file needs a "recipe" and a "report" table')
    known = {f.name for f in dataclasses.fields(Recipe)}
    if unknown := sorted(set(raw) - known):
        raise GoldenError(f"{path}: unknown recipe key {clip(repr(unknown[0]))} (known: {', '.join(sorted(known))})")
    if sum(raw.get(k) is not None for k in ("preset", "file", "text")) != 1:
        raise GoldenError(f'{path}: the recipe needs exactly one of "preset", "file", "text"')
    for key, (kind, what) in _RECIPE_FIELDS.items():
        value = raw.get(key)
        if value is None and key not in ("iterations", "seed"):
            continue
        ok = isinstance(value, kind) and (kind is bool or not isinstance(value, bool))
        if kind is int:
            ok = ok and value >= 0
        elif key in ("preset", "file"):
            ok = ok and value != "" and "\0" not in value
        if not ok:
            raise GoldenError(f"{path}: recipe {key!r} must be {what}, not {clip(json.dumps(value))}")
    return Recipe(**raw), recorded


def make_folder(path: str | os.PathLike) -> None:
    """Create the folder of a golden file when it does not exist yet (and its parents).

    Raises
    ------
    GoldenError
        ``path: cannot create folder 'x': reason``.
    """
    folder = Path(path).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as exc:  # ValueError: a NUL character
        reason = os_reason(exc) if isinstance(exc, OSError) else "a file name cannot hold a NUL character"
        raise GoldenError(f"{path}: cannot create folder {str(folder)!r}: {reason}") from None


def write_golden(path: str | os.PathLike, recipe: Recipe, recorded: dict) -> Path:
    """Write a golden file atomically (sorted keys, one value per line, so diffs review well).

    Its folder is created when missing.
    """
    make_folder(path)
    data = {"lsys3d_golden": GOLDEN_FORMAT, "recipe": recipe.as_json(), "report": recorded}
    text = json.dumps(data, indent=1, sort_keys=True) + "\n"
    return write_bytes(path, [text.encode("utf-8")])


# ---------------------------------------------------------------- comparison


def _close(a, e, rtol: float, atol: float) -> bool:
    if isinstance(a, list) and isinstance(e, list):
        return len(a) == len(e) and all(_close(x, y, rtol, atol) for x, y in zip(a, e, strict=True))
    if _is_number(a) and _is_number(e):
        return math.isclose(a, e, rel_tol=rtol, abs_tol=atol)
    return a == e


def _exact(value) -> bool:
    if isinstance(value, list):
        return all(_exact(v) for v in value)
    return not isinstance(value, float)


def compare(expected: dict, actual: dict, rtol: float = RTOL) -> tuple[list[Difference], list[str]]:
    """Differences between a recorded report and a new one, and warnings about how they were compared.

    Counts (integers, booleans) must match exactly; floats within ``rtol``
    (relative, with an absolute floor of ``rtol`` times the plant's size).
    The union's counts and measures must match exactly when the recorded
    manifold3d version is the installed one, and within :data:`UNION_RTOL`
    otherwise (with a warning).  A key only in the new report is listed but
    does not fail; a key missing from it fails.  ``versions`` are not compared.

    Examples
    --------
    >>> old = {"derive": {"modules": 10}, "bark": {"volume": 1.0}, "versions": {"manifold3d": "3.0"}}
    >>> new = {"derive": {"modules": 11}, "bark": {"volume": 1.0000001}, "versions": {"manifold3d": "3.0"}}
    >>> diffs, warnings = compare(old, new)
    >>> [(d.key, d.failed) for d in diffs], warnings
    ([('bark.volume', False), ('derive.modules', True)], [])
    """
    old_manifold = expected.get("versions", {}).get("manifold3d")
    new_manifold = actual.get("versions", {}).get("manifold3d")
    same_manifold = old_manifold == new_manifold
    warnings = []
    if not same_manifold:
        warnings.append(
            f"manifold3d {old_manifold} recorded these counts, {new_manifold} is installed: "
            f"the union's counts are compared within {UNION_RTOL:.0%}"
        )
    old, new = flatten(expected), flatten(actual)
    box = [abs(v) for k in ("interpret.bbox_min", "interpret.bbox_max") for v in old.get(k, [])]
    atol = rtol * max([1.0, *box])
    differences = []
    for key in sorted(set(old) | set(new)):
        if key.startswith("versions."):
            continue
        if key not in new:
            differences.append(Difference(key, old[key], None, True, "missing from the new report"))
            continue
        if key not in old:
            differences.append(Difference(key, None, new[key], False, "new key, not in the golden file"))
            continue
        e, a = old[key], new[key]
        if e == a:
            continue
        loose = key in _UNION_KEYS and not same_manifold and new.get("bark.unioned", False)
        if loose:
            ok = _close(a, e, UNION_RTOL, atol)
        elif _exact(e) and _exact(a):
            ok = False
        else:
            ok = _close(a, e, rtol, atol)
        note = "within tolerance" if ok else ""
        differences.append(Difference(key, e, a, not ok, note))
    return differences, warnings


def check(path: str | os.PathLike, update: bool = False, rtol: float = RTOL) -> CheckResult:
    """Regrow the asset of one golden file and compare it with the recorded report.

    Parameters
    ----------
    path : path-like
        The golden file.
    update : bool
        Rewrite the file with the new report when anything in it changed
        (differences, or the versions that produced it).
    rtol : float
        Relative tolerance of floating values.

    Returns
    -------
    CheckResult
        ``ok`` is False when any difference is outside its tolerance (and
        ``update`` is not set), or the file is missing.  A missing file is
        ``missing``; with ``update``, one named after a bundled preset
        (``koch.json``) is recorded for that preset at its own iterations and
        seed (:func:`preset_recipe`), and the result is ``created``.

    Raises
    ------
    GoldenError
        The golden file cannot be read; errors regrowing the asset (a grammar
        that no longer parses, say) are re-raised prefixed with the file's name.
    """
    path = Path(path)
    if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 <= rtol < math.inf:
        raise GoldenError(f"{path}: rtol must be a finite number >= 0, not {clip(repr(rtol))}")
    if _is_missing(path):
        return _missing(path, update)
    recipe, recorded = read_golden(path)
    _generate_options(recipe, str(path))  # a bad option fails before the work
    try:
        grammar = _grammar(recipe, path.parent)
        actual = _grow(recipe, grammar, str(path))
        text = grammar.text or ""
    except GoldenError:
        raise
    except LSystemError as exc:
        raise GoldenError(f"{path}: {exc}") from None
    differences, warnings = compare(recorded, actual, rtol)
    if recipe.grammar_sha256 and text and _sha256(text) != recipe.grammar_sha256:
        warnings.append("the grammar's text changed since this golden file was recorded")
    result = CheckResult(path, recipe, differences, warnings, actual)
    if update and (differences or recorded != actual):
        fresh = dataclasses.replace(recipe, grammar_sha256=_sha256(text) if text else recipe.grammar_sha256)
        write_golden(path, fresh, actual)
        result.updated = True
        result.differences = [dataclasses.replace(d, failed=False) for d in differences]
    return result


def _is_missing(path: Path) -> bool:
    try:
        return not path.exists() and not path.is_symlink()
    except (OSError, ValueError):  # a name too long, a NUL character: read_golden says what
        return False


def preset_recipe(path: str | os.PathLike) -> Recipe | None:
    """The recipe of a golden file named after a bundled preset (``tests/golden/koch.json``), or None.

    The preset at its own iterations and seed, default options; symbol-only
    grammars (whose turtle draws nothing) without the mesh, as in lsys3d's own
    ``tests/golden``.
    """
    path = Path(path)
    if path.suffix != ".json" or path.stem not in list_presets():
        return None
    grammar = load_preset(path.stem)
    _, skeleton = draw(grammar, grammar.iterations, grammar.seed)
    return Recipe(
        iterations=int(grammar.iterations),
        seed=int(grammar.seed),
        preset=path.stem,
        mesh=len(skeleton) > 0,
        grammar_sha256=_sha256(grammar.text or ""),
    )


def _missing(path: Path, update: bool) -> CheckResult:
    recipe = preset_recipe(path) if update else None
    if recipe is None:
        return CheckResult(path, None, [], [], {}, missing=True)
    actual = grow(recipe)
    write_golden(path, recipe, actual)
    return CheckResult(path, recipe, [], [], actual, updated=True, missing=True, created=True)


def summarize(differences: list[Difference]) -> str:
    """What failed, in words: ``3 counts differ, 2 values (bark.area, bbox.max) differ beyond tolerance``.

    Counts (integers, flags) are compared exactly, values (floats) within a
    tolerance; keys the new report lacks are named apart.  Empty when nothing failed.

    Examples
    --------
    >>> summarize([Difference("derive.modules", 10, 11, True), Difference("bark.area", 1.0, 1.5, True)])
    '1 count differs, 1 value (bark.area) differs beyond tolerance'
    """
    failed = [d for d in differences if d.failed]
    missing = [d.key for d in failed if d.actual is None]
    counts = [d.key for d in failed if d.actual is not None and d.is_count]
    values = [d.key for d in failed if d.actual is not None and not d.is_count]
    parts = []
    if counts:
        parts.append(f"{len(counts)} count{'s differ' if len(counts) > 1 else ' differs'}")
    if values:
        named = ", ".join(values[:4]) + (", ..." if len(values) > 4 else "")
        parts.append(f"{len(values)} value{'s' if len(values) > 1 else ''} ({named}) "
                     f"{'differ' if len(values) > 1 else 'differs'} beyond tolerance")  # fmt: skip
    if missing:
        named = ", ".join(missing[:4]) + (", ..." if len(missing) > 4 else "")
        parts.append(f"{len(missing)} key{'s' if len(missing) > 1 else ''} ({named}) missing from the new report")
    return ", ".join(parts)


def format_changes(differences: list[Difference]) -> str:
    """What an update changed, one line per key: ``  bark.faces: 37,770 -> 37,820  +50 (+0.132%)``."""
    lines = []
    for d in differences:
        change = d.change()
        lines.append(
            f"  {d.key}: {_show(d.expected)} -> {_show(d.actual)}" + ("" if change == "changed" else f"  {change}")
        )
    return "\n".join(lines)


def _show(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.9g}"
    if isinstance(value, int) and not isinstance(value, bool):
        return f"{value:,}"
    if isinstance(value, list):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return json.dumps(value) if isinstance(value, str) else str(value)


def format_differences(differences: list[Difference], limit: int | None = None) -> str:
    """The differences as an aligned text table (key, golden, now, change), one line per key.

    With ``limit``, at most that many rows, the failed ones first, and a last line saying how many more.
    """
    rows = [("key", "golden", "now", "change")]
    cut: list[Difference] = []
    if limit is not None and len(differences) > limit:
        ranked = sorted(differences, key=lambda d: not d.failed)  # stable: keys stay sorted within each group
        differences, cut = ranked[:limit], ranked[limit:]
    for d in differences:
        mark = "" if d.failed else f"  ({d.note})" if d.note and d.change() != d.note else ""
        rows.append((d.key, _show(d.expected), _show(d.actual), d.change() + mark))
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    lines = [f"  {r[0]:<{widths[0]}}  {r[1]:>{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]}".rstrip() for r in rows]
    if cut:
        failed = sum(d.failed for d in cut)
        lines.append(f"  ... and {len(cut)} more" + (f" ({failed} of them failed)" if failed else " (none failed)"))
    return "\n".join(lines)
