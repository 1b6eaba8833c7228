"""The ``lsys3d`` command: each subcommand is a few calls into the public API."""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import re
import sys
import time

from . import __version__
from .derive import DEFAULT_MAX_MODULES, derive
from .errors import LSystemError
from .presets import DEFAULT_PRESET, describe, list_presets, load
from .sweep import DEFAULT_MAX_TRIANGLES
from .turtle import DEFAULT_MAX_SEGMENTS, TurtleOptions

DEFAULT_OUTPUT = "tree.glb"
DEFAULT_PICTURE = "tree.png"

EXIT_USER_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def _at_least(lowest: int):
    """An argparse type: a whole number >= ``lowest`` (anything else is a usage error, exit 2)."""

    def parse(text: str) -> int:
        try:
            value = int(text.replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, not {text!r}") from None
        if value < lowest:
            raise argparse.ArgumentTypeError(f"must be at least {lowest}, not {value}")
        return value

    parse.__name__ = "whole number"  # argparse names the type in its messages
    return parse


def _grammar_args(p: argparse.ArgumentParser, optional: bool = False):
    if optional:
        p.add_argument(
            "grammar", nargs="?", default=DEFAULT_PRESET, help=f"grammar file or preset (default: {DEFAULT_PRESET})"
        )
    else:
        p.add_argument("grammar", help="a grammar file (.toml) or the name of a bundled preset")
    p.add_argument(
        "-n", "--iterations", type=_at_least(0), default=None, help="number of generations (default: the grammar's)"
    )
    p.add_argument("--seed", type=_at_least(0), default=None, help="seed of stochastic rules (default: the grammar's)")
    p.add_argument(
        "--max-modules",
        type=_at_least(1),
        default=DEFAULT_MAX_MODULES,
        help=f"size limit of derivation (default {DEFAULT_MAX_MODULES:,})",
    )


def _mesh_args(p: argparse.ArgumentParser):
    p.add_argument("--sides", type=_at_least(3), default=None, help="vertices around the trunk's tubes (default 8)")
    p.add_argument("--no-union", action="store_true", help="skip the union: the tube soup, a fast preview")
    p.add_argument(
        "--max-segments",
        type=_at_least(1),
        default=DEFAULT_MAX_SEGMENTS,
        help=f"most segments the turtle draws (default {DEFAULT_MAX_SEGMENTS:,})",
    )
    p.add_argument(
        "--max-triangles",
        type=_at_least(1),
        default=DEFAULT_MAX_TRIANGLES,
        help=f"most tube triangles before the union (default {DEFAULT_MAX_TRIANGLES:,})",
    )
    p.add_argument(
        "--turtle",
        metavar="KEY=VALUE",
        action="append",
        type=_turtle_setting,
        default=[],
        help="override a [turtle] setting of the grammar, e.g. --turtle width_jitter=0.2 --turtle branch_drop=0.1 "
        "(repeatable; the variation keys are angle_jitter, length_jitter, width_jitter, branch_roll, branch_drop, "
        "jitter_distribution)",
    )
    p.add_argument(
        "--bark-displacement",
        type=_between(0.0, 0.5),
        default=0.0,
        metavar="F",
        help="procedural bark: displace the tubes by noise up to this fraction of their radius (0..0.5; default 0)",
    )
    p.add_argument(
        "--bark-color-variation",
        type=_between(0.0, 1.0),
        default=0.0,
        metavar="F",
        help="vary the bark colour by noise up to this fraction, as vertex colours (0..1; default 0)",
    )


def _generate_args(p: argparse.ArgumentParser) -> None:
    """The arguments of ``generate`` (but ``--variants``); batch jobs name their options the same way."""
    _grammar_args(p, optional=True)
    _mesh_args(p)
    p.add_argument(
        "-o",
        "--output",
        default=DEFAULT_OUTPUT,
        help=f"output file; its suffix picks the format (default {DEFAULT_OUTPUT})",
    )
    p.add_argument("--units", choices=("m", "cm"), default="m", help="length unit of a USD file (default m)")
    p.add_argument("--up-axis", choices=("Y", "Z"), default="Y", help="up axis of a USD file (default Y)")
    leaves = p.add_mutually_exclusive_group()
    leaves.add_argument(
        "--instance-leaves", dest="instance_leaves", action="store_true", default=None, help="leaves as instances"
    )
    leaves.add_argument(
        "--merge-leaves", dest="instance_leaves", action="store_false", help="leaves as one merged mesh"
    )
    p.add_argument("--skeleton-curves", action="store_true", help="also write the branch skeleton as curves")
    p.add_argument("--hairline", action="store_true", help="SVG: lines one pixel wide instead of as wide as branches")
    p.add_argument("--no-clobber", action="store_true", help="refuse to overwrite an existing file")


def _export_options(args):
    from .exchange import ExportOptions

    return ExportOptions(
        units=args.units,
        up_axis=args.up_axis,
        instance_leaves=args.instance_leaves,
        skeleton_curves=args.skeleton_curves,
        no_clobber=args.no_clobber,
        hairline=args.hairline,
    )


#: generate's options a batch job may not set: the batch decides the files, the seeds and the output.
_NOT_JOB_OPTIONS = frozenset({"output", "seed", "no-clobber", "variants", "quiet", "verbose", "help"})


class OptionNameError(ValueError):
    """An option of :func:`options_from_names` that is unknown or has a bad value; ``key`` names it."""

    def __init__(self, key: str | None, message: str):
        self.key = key
        super().__init__(message)


def options_from_names(names: dict) -> tuple[int | None, object, object]:
    """generate's options given by their CLI names, as ``(iterations, GenerateOptions, ExportOptions)``.

    ``names`` maps long option names without the dashes to TOML values:
    ``{"sides": 6, "no-union": True, "iterations": 4, "turtle": {"width_jitter": 0.2}}``.
    A switch takes ``true`` (``false`` leaves it off), a repeatable option
    (``turtle``) a list of ``KEY=VALUE`` strings or a table.  The values go
    through the very parser of ``lsys3d generate``, so every check and default
    is the command's own.  Used by the jobs files of :mod:`lsys3d.jobs`.

    Raises
    ------
    OptionNameError
        An unknown name or a bad value; ``key`` is the name at fault (None
        when argparse does not say).

    Examples
    --------
    >>> n, options, export = options_from_names({"sides": 6, "iterations": 3, "up-axis": "Z"})
    >>> n, options.sweep.sides, export.up_axis
    (3, 6, 'Z')
    """
    parser = _Parser(prog="options", add_help=False)
    _generate_args(parser)
    parser.raise_errors = True
    flags = {}  # long name -> takes a value
    for action in parser._actions:
        for option in action.option_strings:
            if option.startswith("--") and option[2:] not in _NOT_JOB_OPTIONS:
                flags[option[2:]] = action.nargs != 0
    argv = ["grammar"]
    for key, value in names.items():
        name = str(key).replace("_", "-")
        if name not in flags:
            raise OptionNameError(key, f"unknown option {key!r} (known: {', '.join(sorted(flags))})")
        takes_value = flags[name]
        if isinstance(value, bool):
            if takes_value:
                raise OptionNameError(key, f"{key}: expected a value, not {str(value).lower()}")
            argv += [f"--{name}"] if value else []
        elif not takes_value:
            raise OptionNameError(key, f"{key}: a switch takes true or false, not {value!r}")
        elif isinstance(value, dict):
            if name != "turtle":
                raise OptionNameError(key, f"{key}: expected a value, not a table")
            for k, v in value.items():
                argv += [f"--{name}", f"{k}={_toml_value(v)}"]
        elif isinstance(value, list):
            if name != "turtle":
                raise OptionNameError(key, f"{key}: expected one value, not a list")
            for item in value:
                argv += [f"--{name}", str(item)]
        else:
            argv += [f"--{name}", repr(value) if isinstance(value, float) else str(value)]
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        m = re.match(r"argument (?:-\w/)?--([\w-]+)(?:/[-\w]+)?: (.*)", str(exc))
        if m:
            key = next((k for k in names if str(k).replace("_", "-") == m.group(1)), m.group(1))
            raise OptionNameError(key, f"{key}: {m.group(2)}") from None
        raise OptionNameError(None, str(exc)) from None
    try:
        export_options = _export_options(args)
        options = _generate_options(args)
    except (ValueError, LSystemError) as exc:
        raise OptionNameError(None, str(exc)) from None
    try:  # the values too, not only the keys: a job should not fail on a setting known to be wrong
        TurtleOptions(**options.turtle)
    except LSystemError as exc:
        key = next((k for k in names if str(k) == "turtle"), "turtle")
        raise OptionNameError(key, f"{key}: {getattr(exc, 'reason', exc)}") from None
    return args.iterations, options, export_options


def _toml_value(value) -> str:
    """A TOML literal of a plain value (what ``--turtle KEY=VALUE`` parses)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def _generate_options(args):
    from .pipeline import GenerateOptions

    options = GenerateOptions(
        union=not args.no_union,
        max_modules=args.max_modules,
        max_segments=args.max_segments,
        max_tube_triangles=args.max_triangles,
    )
    if args.sides is not None:
        options = dataclasses.replace(options, sweep=dataclasses.replace(options.sweep, sides=args.sides))
    if args.bark_displacement:
        bark = dataclasses.replace(options.sweep, bark_displacement=args.bark_displacement)
        options = dataclasses.replace(options, sweep=bark)
    if args.bark_color_variation:
        options = dataclasses.replace(options, bark_color_variation=args.bark_color_variation)
    if args.turtle:
        options = dataclasses.replace(options, turtle=dict(args.turtle))
    return options


def _between(lowest: float, highest: float):
    """An argparse type: a number in [lowest, highest] (anything else is a usage error, exit 2)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, not {text!r}") from None
        if not lowest <= value <= highest:
            raise argparse.ArgumentTypeError(f"must be between {lowest:g} and {highest:g}, not {text}")
        return value

    parse.__name__ = "number"
    return parse


def _turtle_setting(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` with a TOML value (``0.2``, ``"normal"``, ``[0, -1, 0]``); a bare word is a string."""
    import tomllib

    key, sep, value = text.partition("=")
    key = key.strip()
    known = {f.name for f in dataclasses.fields(TurtleOptions)} - {"angle", "seed"}
    if not sep or key not in known:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with KEY one of {', '.join(sorted(known))}, not {text!r}")
    try:
        parsed = tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return key, parsed


def _shard(text: str) -> tuple[int, int]:
    from .jobs import parse_shard

    try:
        return parse_shard(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _size(text: str) -> int:
    from .batch import parse_bytes

    try:
        return parse_bytes(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _area(text: str) -> tuple[float, float]:
    """``WxD`` in metres (or one number for a square)."""
    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*(?:[xX]\s*([0-9.eE+]+)\s*)?", text)
    try:
        values = [float(v) for v in m.groups() if v] if m else []
    except ValueError:
        values = []
    if not values or not all(0 < v < 1e9 for v in values):
        raise argparse.ArgumentTypeError(f"expected WIDTHxDEPTH in metres, e.g. 100x80, not {text!r}")
    return values[0], values[-1]


def _bounds(positive: bool):
    """An argparse type: ``LO,HI`` (or one number for both), finite, LO <= HI (> 0 when ``positive``)."""

    def parse(text: str) -> tuple[float, float]:
        parts = text.split(",")
        try:
            values = [float(v) for v in parts]
        except ValueError:
            values = []
        if len(values) not in (1, 2) or not all(abs(v) < 1e9 for v in values):
            raise argparse.ArgumentTypeError(f"expected LO,HI (two numbers) or one number, not {text!r}")
        lo, hi = values[0], values[-1]
        if lo > hi or (positive and lo <= 0):
            raise argparse.ArgumentTypeError(f"expected LO <= HI{' and both > 0' if positive else ''}, not {text!r}")
        return lo, hi

    parse.__name__ = "bounds"
    return parse


def _pixels(text: str) -> tuple[int, int]:
    """``WxH`` (or one number for a square) as a (width, height) pair."""
    m = re.fullmatch(r"\s*(\d+)\s*(?:[xX]\s*(\d+)\s*)?", text)
    if not m or not all(1 <= int(v) <= 16384 for v in m.groups() if v):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels (1..16384), e.g. 800x600, not {text!r}")
    width = int(m.group(1))
    return width, int(m.group(2) or width)


class _Progress:
    """Stage names on stderr while attached to a terminal; silent when piped or with -q."""

    def __init__(self, enabled: bool):
        self.enabled = enabled

    def __call__(self, stage: str, event: str, seconds: float) -> None:
        if not self.enabled:
            return
        if event == "start":
            sys.stderr.write(f"\rlsys3d: {stage}...\x1b[K")
        else:
            sys.stderr.write(f"\rlsys3d: {stage} {seconds:.2f} s\x1b[K")
        sys.stderr.flush()

    def clear(self) -> None:
        if self.enabled:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, like every other error (subcommand parsers inherit the class)."""

    raise_errors = False  # True: raise _UsageError instead of exiting (options_from_names)

    def error(self, message: str):
        if self.raise_errors:
            raise _UsageError(message)
        self.exit(EXIT_USAGE, f"lsys3d: error: {message} (see '{self.prog} --help')\n")


def _output_flags(p: argparse.ArgumentParser, default) -> None:
    p.add_argument("-q", "--quiet", action="store_true", default=default, help="print nothing but errors")
    p.add_argument("-v", "--verbose", action="store_true", default=default, help="log each stage with its timing")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="lsys3d", description="Grow 3D plants and fractals from L-systems.")
    parser.add_argument("--version", action="version", version=f"lsys3d {__version__}")
    _output_flags(parser, default=False)
    # -q and -v also after the subcommand (lsys3d generate -q); SUPPRESS keeps the top level's value when absent.
    # Separate actions, not one parser shared as a parent: argparse shares parents' actions and their defaults.
    common = argparse.ArgumentParser(add_help=False)
    _output_flags(common, default=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    def add(name: str, **kw) -> argparse.ArgumentParser:
        return sub.add_parser(name, parents=[common], **kw)

    p = add("generate", help="grow a plant and write it as a mesh asset (.glb, .usdc, ...)")
    _generate_args(p)
    p.add_argument(
        "--variants",
        type=_at_least(1),
        default=1,
        metavar="N",
        help="grow N siblings with seeds SEED, SEED+1, ...: a USD output holds them as the variants of the "
        "variant set 'seed'; any other is written as <stem>_0<suffix> ... <stem>_<N-1><suffix> (default 1)",
    )
    p.set_defaults(func=cmd_generate)

    p = add("preview", help="grow a plant and render a shaded picture of it (.png) with Blender")
    _grammar_args(p, optional=True)
    _mesh_args(p)
    p.add_argument("-o", "--output", default=DEFAULT_PICTURE, help=f"the .png to write (default {DEFAULT_PICTURE})")
    p.add_argument("--size", type=_pixels, default=(800, 800), metavar="WxH", help="image size (default 800x800)")
    p.add_argument("--view", choices=("front", "side", "iso"), default="front", help="camera (default front)")
    p.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel (default 16, denoised)")
    p.add_argument(
        "--blender",
        metavar="PATH",
        default=None,
        help="a blender executable or a Python that imports bpy (default: $LSYS3D_BLENDER, this Python, PATH)",
    )
    p.add_argument("--no-clobber", action="store_true", help="refuse to overwrite an existing file")
    p.set_defaults(func=cmd_preview)

    p = add("derive", help="print the derived module string")
    _grammar_args(p)
    p.set_defaults(func=cmd_derive)

    p = add("stats", help="print counts and extents of the drawn plant")
    _grammar_args(p)
    p.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    p.add_argument("--mesh", action="store_true", help="also build the mesh and report its counts and measures")
    p.add_argument(
        "--golden",
        metavar="FILE",
        help="also write the report with its recipe as a golden file, for 'lsys3d check'",
    )
    _mesh_args(p)
    p.set_defaults(func=cmd_stats)

    p = add("check", help="regrow the assets of golden files and compare their counts")
    p.add_argument("golden", nargs="+", metavar="GOLDEN.json", help="golden files written by 'stats --golden'")
    p.add_argument("--update", action="store_true", help="rewrite the golden files that changed, and say what changed")
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance of floating values (default 1e-6)")
    p.set_defaults(func=cmd_check)

    p = add("batch", help="grow every job of a jobs file into a folder, with a manifest and library.usda")
    p.add_argument("jobs", metavar="JOBS.toml", help="the jobs file (see docs/batch.md)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="the folder of the assets (made if missing)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=os.environ.get("DASK_SCHEDULER_ADDRESS") or None,
        help="run on the Dask cluster of this scheduler, e.g. tcp://10.0.0.5:8786 (default: $DASK_SCHEDULER_ADDRESS, "
        "else processes on this machine)",
    )
    p.add_argument(
        "--shard", type=_shard, metavar="I/N", help="run only the I-th of N slices of the jobs (1 <= I <= N)"
    )
    p.add_argument("--workers", type=_at_least(1), metavar="N", help="local worker processes (default: one per core)")
    p.add_argument(
        "--memory",
        type=_size,
        metavar="SIZE",
        help="memory the local workers may use in all, e.g. 8G (default: what is available at the start)",
    )
    p.add_argument("--no-library", action="store_true", help="do not write OUTDIR/library.usda")
    p.add_argument("--dry-run", action="store_true", help="list the jobs, whether each would run, its predicted size")
    p.set_defaults(func=cmd_batch)

    from .forest import ForestOptions

    forest = ForestOptions()
    p = add("forest", help="scatter a library's assets over an area: USD PointInstancer or one .glb with instancing")
    p.add_argument("library", metavar="LIBRARY", help="a library.usda written by 'lsys3d batch' (or its folder)")
    p.add_argument(
        "-o", "--output", default="forest.usdc", help="the forest: .usdc, .usda, .usd or .glb (default forest.usdc)"
    )
    p.add_argument(
        "--area",
        type=_area,
        default=forest.area,
        metavar="WxD",
        help="width x depth in metres, centred on the origin (default {:g}x{:g})".format(*forest.area),
    )
    p.add_argument("--count", type=_at_least(1), default=forest.count, help=f"instances (default {forest.count})")
    p.add_argument("--seed", type=_at_least(0), default=forest.seed, help=f"seed (default {forest.seed})")
    p.add_argument(
        "--scale",
        type=_bounds(positive=True),
        default=forest.scale,
        metavar="LO,HI",
        help="scale of each instance, drawn in LO..HI (default {:g},{:g})".format(*forest.scale),
    )
    p.add_argument(
        "--yaw",
        type=_bounds(positive=False),
        default=forest.yaw,
        metavar="LO,HI",
        help="turn about the up axis in degrees, drawn in LO..HI (default {:g},{:g})".format(*forest.yaw),
    )
    p.add_argument(
        "--spacing",
        type=_between(0.0, 100.0),
        default=forest.spacing,
        metavar="F",
        help=f"trunks at least F times the sum of two crown radii apart (default {forest.spacing:g}: crowns touch)",
    )
    p.add_argument(
        "--species", action="append", default=[], help="scatter only this species (repeatable; default: all)"
    )
    p.add_argument("--no-clobber", action="store_true", help="refuse to overwrite an existing file")
    p.set_defaults(func=cmd_forest)

    p = add("presets", help="list the bundled presets")
    p.set_defaults(func=cmd_presets)
    return parser


def cmd_derive(args) -> int:
    grammar = load(args.grammar)
    result = derive(grammar, args.iterations, args.seed, max_modules=args.max_modules)
    out = sys.stdout
    out.write(str(result))
    out.write("\n")
    return 0


def cmd_generate(args) -> int:
    from .exchange import check_output, export
    from .pipeline import generate, run_stage

    export_options = _export_options(args)
    path = check_output(args.output, export_options)  # before minutes of work, not after
    drawing = path.suffix.lower() == ".svg"
    options = _generate_options(args)
    if drawing:  # a line drawing of the skeleton: the union's minutes would be thrown away
        options = dataclasses.replace(options, union=False)
    if args.variants > 1:
        return _generate_siblings(args, options, export_options)
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    try:
        tree = generate(load(args.grammar), args.iterations, args.seed, options=options, progress=progress)
        path = run_stage("export", export, tree, args.output, export_options, progress=progress)
    finally:
        progress.clear()
    if not args.quiet and drawing:
        segments, leaves = len(tree.skeleton), tree.skeleton.n_leaves
        print(f"wrote {path}: {segments:,} segments, {leaves:,} leaves ({time.perf_counter() - t0:.1f} s)")
    elif not args.quiet:
        bark, leaves = tree.bark, tree.skeleton.n_leaves
        print(
            f"wrote {path}: {len(bark.vertices):,} vertices, {len(bark.faces):,} faces, {leaves:,} leaves "
            f"({time.perf_counter() - t0:.1f} s)"
        )
    return 0


def _generate_siblings(args, options, export_options) -> int:
    """``generate --variants N``: the grammar grown with seeds SEED .. SEED+N-1, written by export_variants."""
    from .exchange import check_output, export_variants, variant_paths
    from .pipeline import generate, run_stage

    for target in variant_paths(args.output, args.variants):
        check_output(target, export_options)
    grammar = load(args.grammar)
    first = grammar.seed if args.seed is None else args.seed
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    try:
        trees = [
            generate(grammar, args.iterations, first + i, options=options, progress=progress)
            for i in range(args.variants)
        ]
        paths = run_stage("export", export_variants, trees, args.output, export_options, progress=progress)
    finally:
        progress.clear()
    if not args.quiet:
        if len(paths) == 1:
            print(
                f"wrote {paths[0]}: {len(trees)} variants seed_{first} .. seed_{first + len(trees) - 1} of the "
                f"variant set 'seed' ({time.perf_counter() - t0:.1f} s)"
            )
        else:
            for path, tree in zip(paths, trees, strict=True):
                bark = tree.bark
                print(
                    f"wrote {path}: seed {tree.provenance['seed']}, {len(bark.vertices):,} vertices, "
                    f"{len(bark.faces):,} faces, {tree.skeleton.n_leaves:,} leaves"
                )
            print(f"{len(paths)} files in {time.perf_counter() - t0:.1f} s")
    return 0


def cmd_preview(args) -> int:
    from .pipeline import generate, run_stage
    from .preview import PreviewOptions, check_preview, preview

    options = PreviewOptions(size=args.size, view=args.view, samples=args.samples, blender=args.blender)
    options = dataclasses.replace(options, no_clobber=args.no_clobber)
    check_preview(args.output, options)  # no Blender, no minutes of work
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    try:
        tree = generate(
            load(args.grammar), args.iterations, args.seed, options=_generate_options(args), progress=progress
        )
        path = run_stage("render", preview, tree, args.output, options, progress=progress)
    finally:
        progress.clear()
    if not args.quiet:
        width, height = options.size
        print(f"wrote {path}: {width}x{height}, {options.view} view ({time.perf_counter() - t0:.1f} s)")
    return 0


def cmd_stats(args) -> int:
    from .stats import flatten, report

    grammar = load(args.grammar)
    options = _generate_options(args)
    if args.golden:  # a golden file that cannot be written fails before the work, not after
        from pathlib import Path

        from .exchange.atomic import check_target

        check_target(Path(args.golden), no_clobber=False)
    n = grammar.iterations if args.iterations is None else args.iterations
    seed = grammar.seed if args.seed is None else args.seed
    if args.mesh:
        from .pipeline import generate

        tree = generate(grammar, n, seed, options=options)
        result = report(tree.modules, tree.skeleton, tree)
    else:
        from .pipeline import draw

        result = report(*draw(grammar, n, seed, options))
    if args.golden:
        from .golden import recipe_for, write_golden

        recipe = recipe_for(grammar, n, seed, options, mesh=args.mesh, golden_path=args.golden)
        write_golden(args.golden, recipe, result)
    if args.json:
        print(json.dumps(result, sort_keys=True))
    else:
        print_table(flatten(result))
    return 0


def print_table(stats: dict) -> None:
    width = max(map(len, stats))
    for key, value in stats.items():
        if isinstance(value, float):
            value = f"{value:.6g}"
        elif isinstance(value, list):
            value = "  ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in value)
        print(f"{key:<{width}}  {value}")


def cmd_check(args) -> int:
    from .golden import RTOL, check, format_differences

    failed = 0
    for path in args.golden:
        try:
            result = check(path, update=args.update, rtol=RTOL if args.rtol is None else args.rtol)
        except LSystemError as exc:  # one bad file does not stop the others
            failed += 1
            print(f"lsys3d: error: {exc}", file=sys.stderr)
            continue
        for warning in result.warnings:
            print(f"{path}: warning: {warning}")
        if result.updated:
            what = ", ".join(d.key for d in result.differences) or "only the versions that produced it"
            print(f"updated {path} ({result.recipe.describe()}): {what}")
            if result.differences:
                print(format_differences(result.differences))
        elif result.ok:
            within = sum(not d.failed for d in result.differences)
            extra = f" ({within} within tolerance)" if within else ""
            if not args.quiet:
                print(f"ok      {path} ({result.recipe.describe()}){extra}")
        else:
            failed += 1
            n = sum(d.failed for d in result.differences)
            print(f"FAILED  {path} ({result.recipe.describe()}): {n} difference{'s' if n > 1 else ''}")
            print(format_differences(result.differences))
    if failed:
        print(f"{failed} of {len(args.golden)} golden files differ; 'lsys3d check --update' records the new counts")
        return EXIT_USER_ERROR
    return 0


class _BatchProgress:
    """A batch's progress bar on stderr while attached to a terminal; failures are always printed, one line each."""

    WIDTH = 24

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self.shown = False

    def __call__(self, event) -> None:
        if event.kind == "failed":
            self.clear()
            print(f"lsys3d: {event.job_id} failed: {_one_line(event.error or '')}", file=sys.stderr)
        if not self.enabled:
            return
        finished = event.done + event.failed
        remaining = event.total - event.skipped - finished
        elapsed = time.perf_counter() - self.t0
        eta = f", ETA {_duration(elapsed / finished * remaining)}" if finished and remaining else ""
        filled = round(self.WIDTH * (finished + event.skipped) / max(event.total, 1))
        bar = "#" * filled + "." * (self.WIDTH - filled)
        skipped = f", {event.skipped} skipped" if event.skipped else ""
        failed = f", {event.failed} failed" if event.failed else ""
        sys.stderr.write(f"\rlsys3d batch [{bar}] {finished + event.skipped}/{event.total}{failed}{skipped}{eta}\x1b[K")
        sys.stderr.flush()
        self.shown = True

    def clear(self) -> None:
        if self.enabled and self.shown:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self.shown = False


def _duration(seconds: float) -> str:
    seconds = round(seconds)
    if seconds < 60:
        return f"{seconds}s"
    if seconds < 3600:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"


def cmd_batch(args) -> int:
    from .batch import batch, plan

    the = plan(args.jobs, args.output, args.shard)
    if args.dry_run:
        return _print_plan(the)
    bar = _BatchProgress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    try:
        result = batch(
            the,
            args.output,
            scheduler=args.scheduler,
            workers=args.workers,
            memory=args.memory,
            library=not args.no_library,
            progress=bar,
        )
    finally:
        bar.clear()
    total = len(result.done) + len(result.skipped) + len(result.failed)
    if not args.quiet:
        print(
            f"{total} jobs: {len(result.done)} done, {len(result.skipped)} skipped, {len(result.failed)} failed "
            f"({time.perf_counter() - t0:.1f} s); manifest {result.manifest}"
        )
        if result.library:
            print(f"library {result.library}: {result.library_variants} assets")
    if result.failed:
        shown = ", ".join(result.failed[:10]) + (
            f" and {len(result.failed) - 10} more" if len(result.failed) > 10 else ""
        )
        print(f"lsys3d: error: {len(result.failed)} of {total} jobs failed: {shown}", file=sys.stderr)
        return EXIT_USER_ERROR
    return 0


def _print_plan(the) -> int:
    skipped = set(the.skipped)
    width = max((len(job.id) for job in the.jobs), default=2)
    for job in the.jobs:
        if job.id in skipped:
            what = "done, skip"
        elif job.grammar_error:
            what = f"fails: {_one_line(job.grammar_error)}"
        else:
            size = the.size_of(job)
            what = (
                f"run  {size.modules:,} modules, {size.segments:,} segments, ~{size.tube_triangles:,} tube "
                f"triangles, ~{size.bytes / 1e6:,.0f} MB"
            )
        print(f"{job.id:<{width}}  {' '.join(job.paths)}  {what}")
    print(f"{len(the.jobs)} jobs: {len(the.to_run)} to run, {len(the.skipped)} done")
    return 0


def cmd_forest(args) -> int:
    from .forest import ForestOptions, forest

    options = ForestOptions(
        area=args.area,
        count=args.count,
        seed=args.seed,
        scale=args.scale,
        yaw=args.yaw,
        spacing=args.spacing,
        species=tuple(args.species),
        no_clobber=args.no_clobber,
    )
    t0 = time.perf_counter()
    path = forest(args.library, args.output, options)
    if not args.quiet:
        width, depth = options.area
        print(
            f"wrote {path}: {options.count:,} instances on {width:g} x {depth:g} m ({time.perf_counter() - t0:.1f} s)"
        )
    return 0


def cmd_presets(args) -> int:
    names = list_presets()
    width = max(map(len, names))
    for name in names:
        print(f"{name:<{width}}  {describe(name)}")
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING
    logging.basicConfig(format="lsys3d: %(message)s", level=level)
    try:
        return args.func(args)
    except LSystemError as exc:
        print(f"lsys3d: error: {_one_line(str(exc))}", file=sys.stderr)
        return EXIT_USER_ERROR
    except MemoryError:
        print(
            "lsys3d: error: out of memory; use fewer iterations, or lower --max-modules, --max-segments or "
            "--max-triangles",
            file=sys.stderr,
        )
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("lsys3d: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return 0


def _one_line(message: str) -> str:
    """An error message on one line, even when it quotes a rule written over several (TOML multi-line strings)."""
    return " ".join(part.strip() for part in message.splitlines() if part.strip())
