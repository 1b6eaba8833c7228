"""Jobs files: the assets a batch grows, as a plain list of :class:`Job`.

A jobs file is TOML::

    [defaults]                  # optional: what every [[jobs]] entry starts from
    formats = ["glb", "usdc"]

    [[jobs]]
    grammar = "tree3d"          # a preset or a path relative to the jobs file (or a list of them)
    seeds = "0-49"              # "A-B" (both included), a whole number, or a list of both
    formats = ["glb", "usdc"]   # file suffixes, see lsys3d.exchange.SUPPORTED_SUFFIXES
    options = { sides = 6 }     # generate's options by their CLI names
    name = "oak"                # optional: names the folder, the files and the job ids

Each entry's grammars times its seeds are its jobs, in file order; a job is
one grammar grown with one seed and written in every format, to
``<name>/<name>_s<seed>.<format>`` (its id is ``<name>_s<seed>``).  The name
is the grammar's own ``name`` (a preset's name), or the file's stem.  Ids
depend on nothing but the jobs file, so they are the same in every run.

Mistakes in the jobs file itself are :class:`~lsys3d.errors.BatchError`\\ s
that point at the value (``jobs.toml:7:9: seeds: ...``), raised before any
work.  A grammar file that exists but does not parse is not one: its jobs
carry the error and fail in the batch, beside the others.
"""

from __future__ import annotations

import itertools
import os
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BatchError, ExportError, GrammarError, LSystemError, OptionsError, clip
from ..exchange import SUPPORTED_SUFFIXES, ExportOptions
from ..exchange.gltf import check_options
from ..exchange.library import USD_FORMATS
from ..external import FileRefused, read_file
from ..lsystem.derive import derive, predict_counts
from ..lsystem.dialects import GRAMMAR_SUFFIXES
from ..lsystem.grammar import Grammar, read_text
from ..lsystem.presets import list_presets, load_preset, preset_text
from ..options import flat_fields
from ..pipeline import GenerateOptions
from ..turtle import TurtleOptions

__all__ = [
    "MAX_JOBS",
    "MAX_JOBS_FILE_BYTES",
    "Job",
    "JobSize",
    "parse_shard",
    "predict_size",
    "read_jobs",
    "shard",
]

MAX_JOBS = 100_000
"""Most jobs one jobs file may make (counted before the list is built); split a larger library into several."""

MAX_JOBS_FILE_BYTES = 4 << 20
"""Largest jobs file read."""

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")
_ENTRY_KEYS = ("formats", "grammar", "name", "options", "seeds")
_DEFAULT_KEYS = ("formats", "options", "seeds")


@dataclass(frozen=True)
class Job:
    """One asset of a batch: a grammar grown with one seed and written in one or more formats.

    Plain data (it travels to worker processes and Dask workers): the
    grammar goes as its text, so a worker needs no access to the jobs file.

    Attributes
    ----------
    id : str
        ``<name>_s<seed>``; unique in the job list and stable across runs.
    name : str
        The folder and file-name prefix (the species, in the library).
    seed : int
    iterations : int or None
        Generations (the grammar's own when not set in the options); None
        when the grammar does not parse.
    formats : tuple of str
        File suffixes without the dot, e.g. ``("glb", "usdc")``.
    options : GenerateOptions
    export_options : ExportOptions
    grammar_source : str
        ``presets/<name>.toml`` or the grammar file's absolute path.
    grammar_text : str
        The grammar's TOML text ("" when the file cannot be read).
    where : str
        The jobs file entry that made the job (``jobs.toml:12``), for messages.
    grammar_error : str or None
        Why the grammar cannot be read: the job fails with this message.
    """

    id: str
    name: str
    seed: int
    iterations: int | None
    formats: tuple[str, ...]
    options: GenerateOptions
    export_options: ExportOptions
    grammar_source: str
    grammar_text: str
    where: str = ""
    grammar_error: str | None = None

    @property
    def paths(self) -> tuple[str, ...]:
        """The files the job writes, relative to the output folder (``/``-separated), in format order."""
        return tuple(f"{self.name}/{self.id}.{f}" for f in self.formats)

    def grammar(self) -> Grammar:
        """The grammar, parsed from its text (raises its :class:`~lsys3d.errors.GrammarError`)."""
        return Grammar.from_text(self.grammar_text, source=self.grammar_source)


# ---------------------------------------------------------------- locations in the jobs file


class _Locator:
    """Line and column of values in the jobs file's text (tomllib gives none)."""

    def __init__(self, text: str, source: str):
        self.source = source
        self.lines = text.splitlines()
        self.headers = [i for i, ln in enumerate(self.lines) if re.match(r"\s*\[\[\s*jobs\s*\]\]", ln)]
        # table headers, but not the sub-tables of an entry ([jobs.options])
        self.tables = [i for i, ln in enumerate(self.lines) if re.match(r"\s*\[(?!\s*jobs\s*\.)", ln)]
        self.defaults = next((i for i, ln in enumerate(self.lines) if re.match(r"\s*\[\s*defaults\s*\]", ln)), None)

    def _span(self, start: int | None) -> range:
        if start is None:
            return range(len(self.lines))
        end = next((t for t in self.tables if t > start), len(self.lines))
        return range(start, end)

    def _start(self, entry: int | None) -> int | None:
        if entry is None:
            return self.defaults
        return self.headers[entry] if entry < len(self.headers) else None

    def find(self, entry: int | None, *keys: str) -> tuple[int | None, int | None]:
        """Where the value of ``keys[0]`` (then ``keys[1]`` in it...) is, in entry ``entry`` (None: [defaults])."""
        start = self._start(entry)
        span = self._span(start)
        line, col = (start + 1, 1) if start is not None else (None, None)
        first = span.start
        for key in keys:
            name = re.escape(str(key))
            pattern = re.compile(rf"(?:^|[\s{{,])[\"']?{name}[\"']?\s*=\s*")
            table = re.compile(rf"\s*\[\s*(?:jobs|defaults)\s*\.\s*[\"']?{name}[\"']?\s*\]")  # [jobs.options]
            for i in range(first, span.stop):
                m = pattern.search(self.lines[i], 0 if i != first or key == keys[0] else col - 1)
                if m:
                    line, col, first = i + 1, m.end() + 1, i
                    break
                if table.match(self.lines[i]):
                    line, col, first = i + 1, 1, i + 1
                    break
            else:
                break
        return line, col

    def error(self, message: str, entry: int | None = None, *keys: str) -> BatchError:
        line, col = self.find(entry, *keys) if (entry is not None or keys) else (None, None)
        return BatchError(message, self.source, line, col)

    def entry_line(self, entry: int) -> int | None:
        return self.headers[entry] + 1 if entry < len(self.headers) else None


# ---------------------------------------------------------------- values


def _seeds(value, loc: _Locator, entry: int | None) -> list[tuple[int, int]]:
    """Seed ranges ``(first, last)`` of a ``seeds`` value, checked, in the order given."""
    items = value if isinstance(value, list) else [value]
    ranges = []
    for item in items:
        if isinstance(item, bool) or not isinstance(item, (int, str)):
            raise loc.error(
                f'seeds: expected "A-B", a whole number or a list of them, not {clip(repr(item))}', entry, "seeds"
            )
        if isinstance(item, int):
            first = last = item
        else:
            m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", item)
            if not m:
                raise loc.error(
                    f'seeds: expected "A-B" with whole numbers A <= B, not {clip(repr(item))}', entry, "seeds"
                )
            first, last = int(m.group(1)), int(m.group(2) or m.group(1))
        if first < 0 or last < first:
            raise loc.error(f"seeds: {item!r} is not a range of whole numbers >= 0, first <= last", entry, "seeds")
        if last >= 1 << 63:
            raise loc.error(f"seeds: {item!r} is larger than 2**63 - 1", entry, "seeds")
        ranges.append((first, last))
    if not ranges:
        raise loc.error("seeds: the list is empty", entry, "seeds")
    spans = sorted(ranges)
    for (_, a1), (b0, _) in itertools.pairwise(spans):
        if b0 <= a1:
            raise loc.error(f"seeds: seed {b0} is given twice", entry, "seeds")
    return ranges


def _formats(value, loc: _Locator, entry: int | None) -> tuple[str, ...]:
    items = value if isinstance(value, list) else [value]
    known = [s[1:] for s in SUPPORTED_SUFFIXES]
    out: list[str] = []
    for item in items:
        if not isinstance(item, str):
            raise loc.error(f'formats: expected file suffixes such as "glb", not {clip(repr(item))}', entry, "formats")
        fmt = item.strip().lower().removeprefix(".")
        if fmt not in known:
            raise loc.error(f"formats: unknown format {item!r} (known: {', '.join(known)})", entry, "formats")
        if fmt in out:
            raise loc.error(f"formats: {item!r} is given twice", entry, "formats")
        out.append(fmt)
    if not out:
        raise loc.error("formats: the list is empty", entry, "formats")
    return tuple(out)


class OptionNameError(ValueError):
    """An option of :func:`options_from_names` that is unknown or has a bad value; ``key`` names it."""

    def __init__(self, key: str | None, message: str):
        self.key = key
        super().__init__(message)


#: generate's options a batch job may not set: the batch decides the files, the seeds and the output.
NOT_JOB_OPTIONS = frozenset({"output", "seed", "no_clobber", "variants"})


def options_from_names(names: dict) -> tuple[int | None, GenerateOptions, ExportOptions]:
    """generate's options given by their CLI names, as ``(iterations, GenerateOptions, ExportOptions)``.

    ``names`` maps the names of ``lsys3d generate``'s flags, with dashes or
    underscores and without the leading ``--``, to TOML values: ``{"sides": 6,
    "no-union": true, "iterations": 4, "turtle": {"width_jitter": 0.2}}``.  A
    flag's name is the flat name of an options field (:mod:`lsys3d.options`),
    so every range, check and default is the field's own; ``no-X = true`` is
    ``X = false``.  ``instance-leaves`` / ``merge-leaves`` choose the leaves'
    form; ``turtle`` takes a table of ``[turtle]`` settings.

    Raises
    ------
    OptionNameError
        An unknown name or a bad value; ``key`` is the name at fault.

    Examples
    --------
    >>> n, options, export = options_from_names({"sides": 6, "iterations": 3, "up-axis": "Z", "no-union": True})
    >>> n, options.sweep.sides, options.union.enabled, export.up_axis
    (3, 6, False, 'Z')
    """
    generate_names = set(flat_fields(GenerateOptions)) | {"turtle"}
    export_names = set(flat_fields(ExportOptions)) - NOT_JOB_OPTIONS - {"instance_leaves"}
    known = sorted(
        {n.replace("_", "-") for n in generate_names | export_names}
        | {"iterations", "instance-leaves", "merge-leaves"}
        | {f"no-{n.replace('_', '-')}" for n, v in GenerateOptions().plain().items() if v is True}
    )
    iterations = None
    options, export = GenerateOptions(), ExportOptions()
    for key, value in names.items():
        name = str(key).replace("-", "_")
        try:
            if name == "iterations":
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise OptionsError(f"must be a whole number >= 0, not {clip(repr(value))}")
                iterations = value
            elif name in ("instance_leaves", "merge_leaves"):
                if not isinstance(value, bool):
                    raise OptionsError(f"a switch takes true or false, not {clip(repr(value))}")
                export = export.replace(instance_leaves=value if name == "instance_leaves" else not value)
            elif name.startswith("no_") and name[3:] in generate_names | export_names:
                if not isinstance(value, bool):
                    raise OptionsError(f"a switch takes true or false, not {clip(repr(value))}")
                target = name[3:]
                if target in generate_names:
                    options = options.with_flat(**{target: not value})
                else:
                    export = export.with_flat(**{target: not value})
            elif name in generate_names:
                options = options.with_flat(**{name: value})
            elif name in export_names:
                export = export.with_flat(**{name: value})
            else:
                raise OptionNameError(key, f"unknown option {clip(repr(key))} (known: {', '.join(known)})")
        except OptionsError as exc:
            message = str(exc)
            message = message.split(": ", 1)[1] if re.match(r"^[A-Z]\w*\.\w+: ", message) else message
            raise OptionNameError(key, f"{key}: {message}") from None
    return iterations, options, export


def _options(entry: dict, defaults: dict, formats: tuple[str, ...], loc: _Locator, k: int, formats_at: int | None):
    """``(iterations, GenerateOptions, ExportOptions)`` of the defaults' and an entry's options (errors: the key)."""
    try:
        iterations, options, export_options = options_from_names({**defaults, **entry})
    except OptionNameError as exc:
        at = None if exc.key is not None and exc.key not in entry and exc.key in defaults else k
        keys = ("options", str(exc.key)) if exc.key is not None else ("options",)
        raise loc.error(f"options: {exc}", at, *keys) from None
    if {"glb", "gltf"} & set(formats):
        try:
            check_options(export_options, "formats")
        except ExportError as exc:
            raise loc.error(str(exc), formats_at, "formats") from None
    return iterations, options, export_options


# ---------------------------------------------------------------- grammars


@dataclass(frozen=True)
class _Grammar:
    source: str
    text: str
    stem: str
    grammar: Grammar | None
    error: str | None


def _read_grammar(spec: str, folder: Path, loc: _Locator, entry: int) -> _Grammar:
    path = folder / spec
    is_path = spec.endswith(GRAMMAR_SUFFIXES) or "/" in spec or os.sep in spec or path.exists()
    if not is_path:
        if spec not in list_presets():
            raise loc.error(
                f"grammar: no bundled preset named {spec!r} and no file {str(path)!r} (see 'lsys3d presets')",
                entry,
                "grammar",
            )
        return _Grammar(f"presets/{spec}.toml", preset_text(spec), spec, load_preset(spec), None)
    path = path.resolve()
    if not path.is_file():
        raise loc.error(f"grammar: no such grammar file {str(path)!r}", entry, "grammar")
    source = str(path)
    try:
        text = read_text(path)
    except GrammarError as exc:  # too large, not UTF-8, not a regular file: the job fails with the message
        return _Grammar(source, "", path.stem, None, str(exc))
    try:
        grammar = Grammar.from_text(text, source=source)
    except LSystemError as exc:
        return _Grammar(source, text, path.stem, None, str(exc))
    return _Grammar(source, text, path.stem, grammar, None)


# ---------------------------------------------------------------- the jobs file


def read_jobs(path: str | os.PathLike) -> list[Job]:
    """Read a jobs file into its job list (the cross product of each entry's grammars and seeds).

    Parameters
    ----------
    path : path-like
        The jobs file (TOML); grammar files are found relative to its folder.

    Returns
    -------
    list of Job
        In file order: entry by entry, grammar by grammar, seed by seed.

    Raises
    ------
    BatchError
        ``jobs.toml:line:col: what`` for a mistake in the jobs file: TOML
        syntax, an unknown key, bad seeds, formats or options, an unknown
        preset, a missing grammar file, two entries making the same job,
        more than :data:`MAX_JOBS` jobs.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "jobs.toml").write_text('[[jobs]]\\ngrammar = "koch"\\nseeds = "3-4"\\nformats = ["svg"]\\n')
    >>> [(job.id, job.paths) for job in read_jobs(folder / "jobs.toml")]
    [('koch_s3', ('koch/koch_s3.svg',)), ('koch_s4', ('koch/koch_s4.svg',))]
    """
    path = Path(path)
    source = str(path)
    try:
        raw = read_file(path, MAX_JOBS_FILE_BYTES, "jobs file", "lsys3d.library.jobs.MAX_JOBS_FILE_BYTES")
    except FileRefused as exc:
        raise BatchError(exc.reason, source) from None
    try:
        text = raw.decode("utf-8")
        data = tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise BatchError(f"the jobs file is not UTF-8 text (byte {exc.start})", source) from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
        reason = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", str(exc))
        line, col = (int(m.group(1)), int(m.group(2))) if m else (None, None)
        raise BatchError(f"TOML syntax error: {reason}", source, line, col) from None
    loc = _Locator(text, source)
    unknown = sorted(set(data) - {"jobs", "defaults"})
    if unknown:
        line = next(
            (i + 1 for i, ln in enumerate(loc.lines) if re.match(rf"\s*\[?\s*{re.escape(unknown[0])}\b", ln)), None
        )
        raise BatchError(f"unknown key {unknown[0]!r} (known: defaults, jobs)", source, line, 1 if line else None)
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict):
        raise loc.error("defaults must be a table", None, "defaults")
    entries = data.get("jobs")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise BatchError('no jobs: the file needs one or more [[jobs]] tables (grammar = "...", seeds = ...)', source)
    for key in sorted(set(defaults) - set(_DEFAULT_KEYS)):
        raise loc.error(f"defaults: unknown key {key!r} (known: {', '.join(_DEFAULT_KEYS)})", None, key)
    folder = path.parent
    grammars: dict[str, _Grammar] = {}
    plans = []
    total = 0
    for k, entry in enumerate(entries):
        for key in sorted(set(entry) - set(_ENTRY_KEYS)):
            raise loc.error(f"unknown key {key!r} (known: {', '.join(_ENTRY_KEYS)})", k, key)
        specs = entry.get("grammar")
        if isinstance(specs, str):
            specs = [specs]
        if not isinstance(specs, list) or not specs or not all(isinstance(s, str) and s.strip() for s in specs):
            raise loc.error('grammar: expected a preset name or a grammar file, e.g. grammar = "tree3d"', k, "grammar")
        name = entry.get("name")
        if name is not None:
            if not isinstance(name, str) or not _NAME.fullmatch(name):
                raise loc.error(
                    f"name: {clip(repr(name))} cannot name files: use letters, digits, '.', '_' and '-' "
                    "(at most 100, starting with a letter or digit)",
                    k,
                    "name",
                )
            if len(specs) > 1:
                raise loc.error("name: one name for several grammars would give their jobs the same ids", k, "name")
        merged = {**defaults, **entry}
        if "formats" not in merged:
            raise loc.error('formats: missing; e.g. formats = ["glb", "usdc"]', k)
        formats_at = k if "formats" in entry else None
        formats = _formats(merged["formats"], loc, formats_at)
        for at, table in ((None, defaults.get("options", {})), (k, entry.get("options", {}))):
            if not isinstance(table, dict):
                raise loc.error("options: expected a table, e.g. options = { sides = 6 }", at, "options")
        iterations, options, export_options = _options(
            entry.get("options", {}), defaults.get("options", {}), formats, loc, k, formats_at
        )
        if formats == ("svg",):  # a line drawing of the skeleton: the union's work would be thrown away
            options = options.with_flat(union=False)
        seed_at = k if "seeds" in entry else None
        seeds = _seeds(merged["seeds"], loc, seed_at) if "seeds" in merged else None
        for spec in specs:
            spec = spec.strip()
            if spec not in grammars:
                grammars[spec] = _read_grammar(spec, folder, loc, k)
            g = grammars[spec]
            ranges = seeds if seeds is not None else [(g.grammar.seed, g.grammar.seed)] if g.grammar else [(0, 0)]
            total += sum(last - first + 1 for first, last in ranges)
            if total > MAX_JOBS:
                raise loc.error(f"more than {MAX_JOBS:,} jobs (lsys3d.library.jobs.MAX_JOBS)", k, "seeds")
            plans.append((k, spec, g, name, ranges, formats, iterations, options, export_options))

    _check_library_frame(plans, loc)
    jobs: list[Job] = []
    made: dict[str, int] = {}
    for k, spec, g, name, ranges, formats, iterations, options, export_options in plans:
        job_name = name or _default_name(g, spec, loc, k)
        n = iterations if iterations is not None else (g.grammar.iterations if g.grammar else None)
        entry_where = f"{source}:{loc.entry_line(k)}" if loc.entry_line(k) else source
        for first, last in ranges:
            for seed in range(first, last + 1):
                job_id = f"{job_name}_s{seed}"
                if job_id in made:
                    other = loc.entry_line(made[job_id])
                    at = f" (line {other})" if other else ""
                    raise loc.error(
                        f"job {job_id!r} is also made by entry {made[job_id] + 1}{at}; give one of them another "
                        'name (name = "...")',
                        k,
                        "name" if name else "grammar",
                    )
                made[job_id] = k
                jobs.append(
                    Job(
                        id=job_id,
                        name=job_name,
                        seed=seed,
                        iterations=n,
                        formats=formats,
                        options=options,
                        export_options=export_options,
                        grammar_source=g.source,
                        grammar_text=g.text,
                        where=entry_where,
                        grammar_error=g.error,
                    )
                )
    return jobs


def _check_library_frame(plans, loc: _Locator) -> None:
    """The USD files of one library must share units and up axis (a USD stage has one of each)."""
    first = None
    for k, _spec, _g, _name, _ranges, formats, _n, _options, export_options in plans:
        if not set(formats) & set(USD_FORMATS):
            continue
        frame = (export_options.units, export_options.up_axis)
        if first is None:
            first = (k, frame)
        elif frame != first[1]:
            raise loc.error(
                f"options: units {frame[0]!r} and up-axis {frame[1]!r} differ from those of entry {first[0] + 1} "
                f"({first[1][0]!r}, {first[1][1]!r}): the USD files of one library share them",
                k,
                "options",
            )


def _default_name(g: _Grammar, spec: str, loc: _Locator, entry: int) -> str:
    """The grammar's ``name`` when it can name files, else the file's stem."""
    own = g.grammar.name if g.grammar is not None else None
    for candidate in (own, g.stem):
        if candidate and _NAME.fullmatch(candidate):
            return candidate
    raise loc.error(
        f'grammar {spec!r}: its name cannot name files; give the entry a name, e.g. name = "plant"', entry, "grammar"
    )


# ---------------------------------------------------------------- shards


def parse_shard(text: str) -> tuple[int, int]:
    """``"I/N"`` (1 <= I <= N) as ``(I, N)``.

    >>> parse_shard("2/5")
    (2, 5)
    """
    m = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", str(text))
    if not m or not 1 <= int(m.group(1)) <= int(m.group(2)):
        raise ValueError(f"expected I/N with 1 <= I <= N, e.g. 1/4, not {text!r}")
    return int(m.group(1)), int(m.group(2))


def shard(jobs: Sequence[Job], index: int, count: int) -> list[Job]:
    """Shard ``index`` of ``count`` (1-based): every ``count``-th job from the ``index``-th.

    Round robin, so each shard gets its share of every entry (cheap and
    expensive grammars alike); the shards of one ``count`` cover the job
    list exactly once.

    >>> shard(list(range(10)), 2, 3)
    [1, 4, 7]
    """
    if not 1 <= index <= count:
        raise ValueError(f"shard {index}/{count}: expected 1 <= I <= N")
    return list(jobs[index - 1 :: count])


# ---------------------------------------------------------------- size before running

BYTES_PER_MODULE = 64
"""Peak bytes per module of the derived string (derivation, turtle): measured by ``benchmarks/bench_memory.py``."""

BYTES_PER_TUBE_TRIANGLE = 2_500
"""Peak bytes per tube triangle of a job with the union (sweep, union, leaves, stats, every writer).

Measured by ``benchmarks/bench_memory.py`` (a job's whole peak over its tube
triangles, the jobs of over 80,000 of them): 1.5-2.2 kB, trees and flat presets
alike (it was 1.8-2.3 kB for trees and up to 4.5 kB for the flat presets whose
crossing tubes quadruple the union's triangles, before the union and the cleanup
stopped making full-size temporaries).  Kept above the largest: the model must
never predict less than a job takes."""

BYTES_PER_SOUP_TRIANGLE = 700
"""The same without the union (``no-union``): 0.6 kB measured (0.64 for tree3d at 7 generations, 0.61 for bush
at 8)."""

JOB_OVERHEAD = 32 << 20
"""Bytes a job takes besides its arrays (writers' buffers, USD's stage, Python objects)."""

RINGS_PER_SEGMENT = 1.5
"""Tube rings per drawn segment (a ring at each joint, more where a chain splits at a sharp bend): an upper
estimate, measured 1.5 for the branching presets, fewer where straight joints merge."""


@dataclass(frozen=True)
class JobSize:
    """A job's size, predicted before it runs.

    Attributes
    ----------
    modules : int
        Modules after derivation.
    segments : int
        Segments the turtle draws (an upper bound: dropped branches draw none).
    tube_triangles : int
        Tube triangles before the union (an estimate: ``segments`` times
        ``2 * sides *`` :data:`RINGS_PER_SEGMENT`).
    bytes : int
        Memory the job takes at its peak, beyond a worker's own.
    """

    modules: int
    segments: int
    tube_triangles: int
    bytes: int


def predict_size(grammar: Grammar, iterations: int, seed: int, options: GenerateOptions) -> JobSize:
    """Predict a job's size and peak memory before running it.

    Module and segment counts come from the growth matrix
    (:func:`lsys3d.lsystem.derive.predict_counts`) when the grammar's growth does not
    depend on chance, conditions or context, else from deriving the string
    with the job's seed (the cheap stage).  A job that will stop at one of
    ``options``' limits is predicted as what it builds before it stops.
    """
    counts = None
    try:
        counts = predict_counts(grammar, iterations)
        if counts is None:
            modules = derive(grammar, iterations, seed, max_modules=options.limits.max_modules)
            per_code = np.bincount(modules.symbols, minlength=len(modules.alphabet))
            counts = {}
            for code in np.flatnonzero(per_code).tolist():
                symbol = modules.alphabet[code]
                counts[symbol] = counts.get(symbol, 0) + int(per_code[code])
        draw = TurtleOptions.from_grammar(grammar, options.turtle).draw
    except LSystemError:  # it fails before building anything big
        return JobSize(0, 0, 0, JOB_OVERHEAD)
    modules = sum(counts.values())
    if modules > options.limits.max_modules:
        return JobSize(modules, 0, 0, JOB_OVERHEAD)
    segments = sum(counts.get(symbol, 0) for symbol in draw)
    module_bytes = JOB_OVERHEAD + BYTES_PER_MODULE * modules
    if segments > options.limits.max_segments:
        return JobSize(modules, segments, 0, module_bytes)
    triangles = int(segments * 2 * options.sweep.sides * RINGS_PER_SEGMENT)
    if triangles > options.limits.max_triangles:
        return JobSize(modules, segments, triangles, module_bytes)
    per_triangle = BYTES_PER_TUBE_TRIANGLE if options.union.enabled else BYTES_PER_SOUP_TRIANGLE
    return JobSize(modules, segments, triangles, module_bytes + per_triangle * triangles)
