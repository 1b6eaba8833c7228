"""The ``lsys3d`` command: each subcommand is a few calls into the public API.

The stages' modules are imported when a subcommand runs (and its flags, which come from the options classes,
when it is parsed): ``lsys3d --help`` and ``lsys3d presets`` load neither numba nor usd-core.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import json
import logging
import math
import os
import signal
import sys
import threading
import time
import warnings
from typing import TYPE_CHECKING

from .errors import LSystemError, OptionsError, SeedWarning, clip, printable
from .options import add_arguments, from_arguments
from .version import __version__

if TYPE_CHECKING:
    from .pipeline import GenerateOptions

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
            raise argparse.ArgumentTypeError(f"expected a whole number, not {clip(repr(text))}") from None
        if value < lowest:
            raise argparse.ArgumentTypeError(f"must be at least {lowest}, not {clip(str(value))}")
        return value

    parse.__name__ = "whole number"  # argparse names the type in its messages
    return parse


def _grammar_args(p: argparse.ArgumentParser, optional: bool = False, mesh: bool = True):
    """The grammar, its iterations and seed, and the options of :class:`GenerateOptions` as flags.

    ``mesh=False`` (``derive``) adds only the derivation's limit.
    """
    from .lsystem.dialects import suffixes_text
    from .lsystem.presets import DEFAULT_PRESET
    from .pipeline import GenerateOptions

    what = f"a grammar file ({suffixes_text()}) or the name of a bundled preset ('lsys3d presets')"
    if optional:
        p.add_argument("grammar", nargs="?", default=DEFAULT_PRESET, help=f"{what} (default: {DEFAULT_PRESET})")
    else:
        p.add_argument("grammar", help=what)
    p.add_argument(
        "-n", "--iterations", type=_at_least(0), default=None, help="number of generations (default: the grammar's)"
    )
    p.add_argument("--seed", type=_at_least(0), default=None, help="seed of stochastic rules (default: the grammar's)")
    if not mesh:
        add_arguments(p, GenerateOptions, only={"max_modules"})
        return
    add_arguments(p, GenerateOptions)
    p.add_argument(
        "--turtle",
        metavar="KEY=VALUE",
        action="append",
        type=_turtle_setting,
        default=[],
        help="override a [turtle] setting of the grammar, e.g. --turtle width_jitter=0.2 --turtle branch_drop=0.1 "
        "(repeatable; the keys are those of the [turtle] table, see docs/turtle.md)",
    )


def _generate_options(args) -> GenerateOptions:
    """The :class:`GenerateOptions` of the flags given (and ``--turtle`` settings)."""
    from .pipeline import GenerateOptions

    options = from_arguments(GenerateOptions, args)
    if args.turtle:
        options = options.replace(turtle=dict(args.turtle))
    return options


def _tolerance(text: str) -> float:
    """An argparse type: a finite number >= 0 (``-1`` or ``nan`` would make every comparison fail or pass)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, not {clip(repr(text))}") from None
    if not 0 <= value < math.inf:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, not {clip(text)}")
    return value


_tolerance.__name__ = "number"


def _turtle_setting(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` with a TOML value (``0.2``, ``"normal"``, ``[0, -1, 0]``); a bare word is a string."""
    from .turtle.options import TurtleOverrides, parse_setting

    try:
        key, parsed = parse_setting(text)
        TurtleOverrides({key: parsed})
    except OptionsError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return key, parsed


def _shard(text: str) -> tuple[int, int]:
    from .library.jobs import parse_shard

    try:
        return parse_shard(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _size(text: str) -> int:
    from .library.batch import parse_bytes

    try:
        return parse_bytes(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _Progress:
    """Stage names (and the union's percentage) on stderr while attached to a terminal; silent when piped or -q.

    As a context manager it also counts the kernels numba compiles on a first run (:mod:`lsys3d.compiling`),
    so minutes of compiling do not look like a hang, and clears its line on the way out.
    """

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.stage = ""
        self._watch = contextlib.nullcontext()

    def __call__(self, stage: str, event: str, seconds: float) -> None:
        if not self.enabled:
            return
        if event == "start":
            self.stage = stage
            sys.stderr.write(f"\rlsys3d: {stage}...\x1b[K")
        elif event == "progress":  # `seconds` is the fraction done
            sys.stderr.write(f"\rlsys3d: {stage} {seconds:.0%}\x1b[K")
        else:
            sys.stderr.write(f"\rlsys3d: {stage} {seconds:.2f} s\x1b[K")
        sys.stderr.flush()

    def compiling(self, done: int, total: int, kernel: str) -> None:
        """A kernel being compiled (see :func:`lsys3d.compiling.watch`)."""
        stage = f" ({self.stage})" if self.stage else ""
        sys.stderr.write(
            f"\rlsys3d: compiling lsys3d's kernels (first run only): {done} of up to {total}{stage}...\x1b[K"
        )
        sys.stderr.flush()

    def __enter__(self) -> _Progress:
        if self.enabled:
            from . import compiling

            self._watch = compiling.watch(self.compiling)
        self._watch.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._watch.__exit__(*exc)
        self.clear()

    def clear(self) -> None:
        if self.enabled:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, like every other error (subcommand parsers inherit the class)."""

    def error(self, message: str):
        self.exit(EXIT_USAGE, printable(f"lsys3d: error: {_one_line(message)} (see '{self.prog} --help')") + "\n")


def _output_flags(p: argparse.ArgumentParser, default) -> None:
    p.add_argument("-q", "--quiet", action="store_true", default=default, help="print nothing but errors")
    p.add_argument("-v", "--verbose", action="store_true", default=default, help="log each stage with its timing")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``lsys3d`` parser.

    With ``command``, only that subcommand gets its arguments (the others are listed with their help; ``""``:
    none does): their flags come from the options classes, whose modules take a while to import, so
    ``lsys3d --help`` or ``lsys3d presets`` imports none of them.  Without, every subcommand gets its arguments.
    """
    parser = _Parser(prog="lsys3d", description="Grow 3D plants and fractals from L-systems.")
    parser.add_argument("--version", action="version", version=f"lsys3d {__version__}")
    _output_flags(parser, default=False)
    # -q and -v also after the subcommand (lsys3d generate -q); SUPPRESS keeps the top level's value when absent.
    # Separate actions, not one parser shared as a parent: argparse shares parents' actions and their defaults.
    common = argparse.ArgumentParser(add_help=False)
    _output_flags(common, default=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name, (help_text, arguments) in _SUBCOMMANDS.items():
        p = sub.add_parser(name, parents=[common], help=help_text)
        if command is None or command == name:
            arguments(p)
    return parser


def _command(argv: list[str]) -> str | None:
    """The subcommand named in ``argv``: its first word that is not an option (the top level's take no value)."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word
    return None


def _generate_arguments(p: argparse.ArgumentParser) -> None:
    from .exchange.common import ExportOptions

    _grammar_args(p, optional=True)
    p.add_argument(
        "-o",
        "--output",
        default=DEFAULT_OUTPUT,
        help=f"output file; its suffix picks the format (default {DEFAULT_OUTPUT})",
    )
    add_arguments(p, ExportOptions)
    leaves = p.add_mutually_exclusive_group()
    leaves.add_argument(
        "--instance-leaves", dest="instance_leaves", action="store_true", default=None, help="leaves as instances"
    )
    leaves.add_argument(
        "--merge-leaves", dest="instance_leaves", action="store_false", help="leaves as one merged mesh"
    )
    p.add_argument(
        "--variants",
        type=_at_least(1),
        default=1,
        metavar="N",
        help="grow N siblings with seeds SEED, SEED+1, ...: a USD output holds them as the variants of the "
        "variant set 'seed'; any other is written as <stem>_0<suffix> ... <stem>_<N-1><suffix> (default 1)",
    )
    p.set_defaults(func=cmd_generate)


def _preview_arguments(p: argparse.ArgumentParser) -> None:
    from .render.preview import PreviewOptions

    _grammar_args(p, optional=True)
    p.add_argument("-o", "--output", default=DEFAULT_PICTURE, help=f"the .png to write (default {DEFAULT_PICTURE})")
    add_arguments(p, PreviewOptions)
    p.set_defaults(func=cmd_preview)


def _derive_arguments(p: argparse.ArgumentParser) -> None:
    _grammar_args(p, mesh=False)
    p.add_argument(
        "--interpretation",
        action="store_true",
        help="print the string the turtle reads instead: the derived string cut at the cut symbol and rewritten "
        "by the grammar's homomorphism (interpretation) rules, as 'generate' draws it",
    )
    p.set_defaults(func=cmd_derive)


def _stats_arguments(p: argparse.ArgumentParser) -> None:
    _grammar_args(p)
    p.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    p.add_argument("--mesh", action="store_true", help="also build the mesh and report its counts and measures")
    p.add_argument(
        "--golden",
        metavar="FILE",
        help="also write the report with its recipe as a golden file, for 'lsys3d check'",
    )
    p.set_defaults(func=cmd_stats)


def _check_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("golden", nargs="+", metavar="GOLDEN.json", help="golden files written by 'stats --golden'")
    p.add_argument("--update", action="store_true", help="rewrite the golden files that changed, and say what changed")
    p.add_argument(
        "--rtol",
        type=_tolerance,
        default=None,
        help="relative tolerance of floating values (default 1e-6)",
    )
    p.set_defaults(func=cmd_check)


def _batch_arguments(p: argparse.ArgumentParser) -> None:
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


def _forest_arguments(p: argparse.ArgumentParser) -> None:
    from .library.forest import ForestOptions

    p.add_argument("library", metavar="LIBRARY", help="a library.usda written by 'lsys3d batch' (or its folder)")
    p.add_argument(
        "-o", "--output", default="forest.usdc", help="the forest: .usdc, .usda, .usd or .glb (default forest.usdc)"
    )
    add_arguments(p, ForestOptions)
    p.add_argument(
        "--species", action="append", default=[], help="scatter only this species (repeatable; default: all)"
    )
    p.set_defaults(func=cmd_forest)


def _edit_arguments(p: argparse.ArgumentParser) -> None:
    from .lsystem.presets import DEFAULT_PRESET
    from .pipeline import GenerateOptions

    p.add_argument(
        "grammar",
        nargs="?",
        default=DEFAULT_PRESET,
        help=f"the grammar file to edit (.toml, .lpy, .l, .ls; made on the first save when missing), or a preset's "
        f"name, opened read-only (default: {DEFAULT_PRESET})",
    )
    p.add_argument(
        "--port", type=_at_least(0), default=8737, help="the port to listen on; 0: any free one (default 8737)"
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="the address to listen on (default 127.0.0.1, this machine only); any other needs a token, made "
        "unless --token gives one",
    )
    p.add_argument("--token", default=None, help="the token every API call must carry (default: none on 127.0.0.1)")
    p.add_argument("--no-browser", action="store_true", help="do not open the page in the default browser")
    p.add_argument(
        "--jobs", type=_at_least(1), default=2, metavar="N", help="worker processes growing trees at once (default 2)"
    )
    add_arguments(p, GenerateOptions, only={"max_modules", "max_segments", "max_triangles"})
    p.set_defaults(func=cmd_edit)


def _presets_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="a JSON list of {name, group, description}")
    p.set_defaults(func=cmd_presets)


_SUBCOMMANDS = {
    "generate": ("grow a plant and write it as a mesh asset (.glb, .usdc, ...)", _generate_arguments),
    "preview": ("grow a plant and render a shaded picture of it (.png) with Blender", _preview_arguments),
    "derive": ("print the derived module string (--interpretation: the string the turtle reads)", _derive_arguments),
    "stats": ("print counts and extents of the drawn plant", _stats_arguments),
    "check": ("regrow the assets of golden files and compare their counts", _check_arguments),
    "batch": ("grow every job of a jobs file into a folder, with a manifest and library.usda", _batch_arguments),
    "forest": (
        "scatter a library's assets over an area: USD PointInstancer or one .glb with instancing",
        _forest_arguments,
    ),
    "edit": ("edit a grammar in the browser: the tree redrawn as you type, sliders, export and save", _edit_arguments),
    "presets": ("list the bundled presets: species, figures, curves and plants in a scene", _presets_arguments),
}
"""Each subcommand's help line and the function that adds its arguments, in the order ``--help`` lists them."""


def cmd_derive(args) -> int:
    from .lsystem.derive import derive
    from .lsystem.presets import load
    from .pipeline import GenerateOptions

    grammar = load(args.grammar)
    options = from_arguments(GenerateOptions, args)
    result = derive(grammar, args.iterations, args.seed, max_modules=options.limits.max_modules)
    if args.interpretation:
        from .lsystem.derive import interpretation

        result = interpretation(
            grammar, result, args.seed, max_modules=options.limits.max_modules, iterations=args.iterations
        )
    out = sys.stdout
    for piece in result.iter_text():  # never the whole text at once: it can be gigabytes
        out.write(piece)
    out.write("\n")
    return 0


def cmd_generate(args) -> int:
    from .exchange import check_output, export
    from .exchange.common import ExportOptions
    from .lsystem.presets import load
    from .pipeline import run_stage

    export_options = from_arguments(ExportOptions, args).replace(instance_leaves=args.instance_leaves)
    path = check_output(args.output, export_options)  # before minutes of work, not after
    drawing = path.suffix.lower() == ".svg"
    options = _generate_options(args)
    if options.rig.enabled and path.suffix.lower() not in (".glb", ".gltf", ".usda", ".usdc", ".usd", ".usdz"):
        raise OptionsError(
            f"--rig: a {path.suffix.lower()} file holds no joints, skin or animation; write .glb, .gltf or USD"
        )
    if drawing:  # a line drawing of the skeleton: the union's minutes would be thrown away
        options = options.with_flat(union=False)
    if args.variants > 1:
        return _generate_siblings(args, options, export_options)
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    with _compiling_ahead(options), progress:
        tree = _grow(load(args.grammar), args.iterations, args.seed, options, progress)
        path = run_stage("export", export, tree, args.output, export_options, progress=progress)
    if not args.quiet and drawing:
        segments, leaves = len(tree.skeleton), tree.skeleton.n_leaves
        _print(f"wrote {path}: {segments:,} segments, {leaves:,} leaves ({time.perf_counter() - t0:.1f} s)")
    elif not args.quiet:
        # the leaves as built: the leaf stage's clusters, not the turtle's leaf symbols
        bark, leaves, organs = tree.bark, tree.skeleton.n_polygons + len(tree.leaves.transforms), len(tree.organs)
        levels = "".join(f", LOD{lod.level} {lod.triangles:,}" for lod in tree.lods)
        if levels:
            levels = f"; triangles of the levels of detail{levels}"
        _print(
            f"wrote {path}: {len(bark.vertices):,} vertices, {len(bark.faces):,} faces, {leaves:,} leaves"
            + (f", {organs:,} organs" if organs else "")
            + f"{levels} ({time.perf_counter() - t0:.1f} s)"
        )
    return 0


def _generate_siblings(args, options, export_options) -> int:
    """``generate --variants N``: the grammar grown with seeds SEED .. SEED+N-1, written by export_variants."""
    from .exchange import check_output, export_variants, variant_paths
    from .lsystem.presets import load
    from .pipeline import grow, run_stage, warn_if_identical

    for target in variant_paths(args.output, args.variants):
        check_output(target, export_options)
    grammar = load(args.grammar)
    warn_if_identical(grammar, options, args.variants, cli=True)
    first = grammar.seed if args.seed is None else args.seed
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    with _compiling_ahead(options), progress:
        trees = [grow(grammar, args.iterations, first + i, options, progress) for i in range(args.variants)]
        paths = run_stage("export", export_variants, trees, args.output, export_options, progress=progress)
    if not args.quiet:
        if len(paths) == 1:
            _print(
                f"wrote {paths[0]}: {len(trees)} variants seed_{first} .. seed_{first + len(trees) - 1} of the "
                f"variant set 'seed' ({time.perf_counter() - t0:.1f} s)"
            )
        else:
            for path, tree in zip(paths, trees, strict=True):
                bark = tree.bark
                _print(
                    f"wrote {path}: seed {tree.provenance.seed}, {len(bark.vertices):,} vertices, "
                    f"{len(bark.faces):,} faces, {tree.skeleton.n_leaves:,} leaves"
                )
            _print(f"{len(paths)} files in {time.perf_counter() - t0:.1f} s")
    return 0


def _compiling_ahead(options):
    """On a first run, the cleanup's kernels compiled by a helper process on the other core while this one
    derives, draws, sweeps and unions, and the last stages' by whichever is idle first
    (:func:`lsys3d.firstrun.ahead`); nothing when they are cached or the cleanup is off."""
    if not (options.union.enabled and options.cleanup.enabled):
        return contextlib.nullcontext()
    from . import firstrun

    return firstrun.ahead()


def _grow(grammar, iterations, seed, options, progress=None):
    """:func:`lsys3d.pipeline.grow`, after the warning ``generate`` gives of a seed that changes nothing, in the
    command line's words (``--seed S`` other than the grammar's own)."""
    from .pipeline import grow, warn_if_identical

    if seed is not None and seed != grammar.seed:
        warn_if_identical(grammar, options, 2, cli=True)
    return grow(grammar, iterations, seed, options, progress)


def cmd_preview(args) -> int:
    from .lsystem.presets import load
    from .pipeline import run_stage
    from .render.preview import PreviewOptions, PreviewSession

    options = from_arguments(PreviewOptions, args)
    progress = _Progress(sys.stderr.isatty() and not args.quiet)
    t0 = time.perf_counter()
    # Blender is found (no Blender: no minutes of work) and started now: it loads while the tree grows
    with PreviewSession(args.output, options) as session, progress:
        tree = _grow(load(args.grammar), args.iterations, args.seed, _generate_options(args), progress)
        path = run_stage("render", session.render, tree, progress=progress)
    if not args.quiet:
        width, height = options.size
        _print(
            f"wrote {path}: {width}x{height}, {options.view} view, {options.quality} ({time.perf_counter() - t0:.1f} s)"
        )
    return 0


def cmd_stats(args) -> int:
    from .lsystem.presets import load
    from .stats import flatten, report

    grammar = load(args.grammar)
    options = _generate_options(args)
    if args.golden:  # a golden file that cannot be written fails before the work, not after
        from pathlib import Path

        from .exchange.atomic import check_target
        from .golden.golden import make_folder

        make_folder(args.golden)
        check_target(Path(args.golden), no_clobber=False)
    n = grammar.iterations if args.iterations is None else args.iterations
    seed = grammar.seed if args.seed is None else args.seed
    if args.mesh:
        tree = _grow(grammar, n, seed, options)
        result = report(tree.modules, tree.skeleton, tree)
    else:
        from .pipeline import draw

        result = report(*draw(grammar, n, seed, options))
    if args.golden:
        from .golden.golden import recipe_for, write_golden

        recipe = recipe_for(grammar, n, seed, options, mesh=args.mesh, golden_path=args.golden)
        write_golden(args.golden, recipe, result)
    if args.json:
        _print(json.dumps(result, sort_keys=True))
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
        _print(f"{key:<{width}}  {value}")


def cmd_check(args) -> int:
    from .golden.golden import RTOL, check, format_changes, format_differences, summarize

    failed = missing = errors = 0
    for path in args.golden:
        try:
            result = check(path, update=args.update, rtol=RTOL if args.rtol is None else args.rtol)
        except LSystemError as exc:  # one bad file does not stop the others
            errors += 1
            _print(f"lsys3d: error: {_one_line(str(exc))}", file=sys.stderr)
            continue
        for warning in result.warnings:
            _print(f"{path}: warning: {warning}")
        if result.created:
            _print(f"recorded {path} ({result.recipe.describe()}): it was missing; a new golden file of the preset")
        elif result.missing:
            missing += 1
            why = (
                "its name is no bundled preset's, so --update cannot tell what to grow"
                if args.update
                else "'lsys3d check --update' records a file named after a bundled preset (koch.json)"
            )
            _print(f"MISSING {path}: no such golden file; {why}; 'lsys3d stats GRAMMAR --golden {path}' records any")
        elif result.updated:
            n = len(result.differences)
            what = f"{n} key{'s' if n > 1 else ''} changed" if n else "only the versions that produced it changed"
            _print(f"updated {path} ({result.recipe.describe()}): {what}")
            if result.differences:
                _print(format_changes(result.differences))
        elif result.ok:
            within = sum(not d.failed for d in result.differences)
            extra = f" ({within} within tolerance)" if within else ""
            if not args.quiet:
                _print(f"ok      {path} ({result.recipe.describe()}){extra}")
        else:
            failed += 1
            _print(f"FAILED  {path} ({result.recipe.describe()}): {summarize(result.differences)}")
            _print(format_differences(result.differences))
    if failed or missing or errors:
        counts = (
            (failed, "differ" if failed > 1 else "differs"),
            (missing, "missing"),
            (errors, "could not be checked"),
        )
        what = ", ".join(f"{n} {word}" for n, word in counts if n)
        hint = "; 'lsys3d check --update' records the new counts" if failed and not args.update else ""
        _print(f"{len(args.golden)} golden file{'s' if len(args.golden) > 1 else ''}: {what}{hint}")
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
        if event.kind == "failed" and event.total > 1:  # a batch of one job says it in its one error line
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
    from .library.batch import batch, plan

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
    if len(result.failed) == 1 and len(the.jobs) == 1:  # its failure, printed once
        job_id = result.failed[0]
        print(f"lsys3d: error: {job_id} failed: {_one_line(result.errors[job_id])}", file=sys.stderr)
        return EXIT_USER_ERROR
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
    from .library.forest import ForestOptions, forest

    options = from_arguments(ForestOptions, args).replace(species=tuple(args.species))
    t0 = time.perf_counter()
    path = forest(args.library, args.output, options)
    if not args.quiet:
        width, depth = options.area
        _print(
            f"wrote {path}: {options.count:,} instances on {width:g} x {depth:g} m ({time.perf_counter() - t0:.1f} s)"
        )
    return 0


LOOPBACK = ("127.0.0.1", "localhost", "::1")


def cmd_edit(args) -> int:
    import secrets
    import socket
    import webbrowser

    from .pipeline import GenerateOptions

    try:
        import uvicorn

        from .edit.server import EditSettings, make_app
    except ImportError as exc:
        raise LSystemError(
            f"lsys3d edit needs the 'edit' extra ({exc.name} is missing): pip install 'lsys3d[edit]'"
        ) from None
    local = args.host in LOOPBACK
    token = args.token or (None if local else secrets.token_urlsafe(18))
    limits = from_arguments(GenerateOptions, args).limits
    hosts = ("127.0.0.1", "localhost", "[::1]") if local else None
    settings = EditSettings(args.grammar, limits=limits, workers=args.jobs, token=token, hosts=hosts)
    family = socket.AF_INET6 if ":" in args.host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((args.host, args.port))
    except OSError as exc:
        sock.close()
        raise LSystemError(f"lsys3d edit: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}") from None
    port = sock.getsockname()[1]
    shown_host = f"[{args.host}]" if ":" in args.host else args.host
    url = f"http://{shown_host}:{port}/" + (f"?token={token}" if token else "")
    terminal = sys.stderr.isatty() and not args.quiet

    def announce(text: str) -> None:
        if terminal:
            sys.stderr.write(f"\rlsys3d: {text}\x1b[K" if text else "\r\x1b[K")
            sys.stderr.flush()

    # asyncio's child watcher warns when a worker it killed was reaped first; nothing the user can act on
    logging.getLogger("asyncio").setLevel(logging.ERROR)
    app = make_app(settings, announce=announce)
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="on"))

    def open_page() -> None:  # once the server listens
        while not server.started and not server.should_exit:
            time.sleep(0.05)
        if not server.started:
            return
        if not args.quiet:
            announce("")
            _print(f"lsys3d edit: {url} (Ctrl-C to stop)")
            sys.stdout.flush()
        if not args.no_browser:
            webbrowser.open(url)

    threading.Thread(target=open_page, daemon=True).start()
    server.run(sockets=[sock])
    return 0


def cmd_presets(args) -> int:
    from .lsystem.presets import GROUPS, list_presets, preset_info

    infos = [preset_info(name) for name in list_presets()]
    if args.json:
        _print(json.dumps([info.to_json() for info in infos], indent=1))
        return 0
    width = max(len(info.name) for info in infos)
    for group in GROUPS:  # species first: what a TD grows; then the textbook's figures and curves
        members = [info for info in infos if info.group == group]
        if members:
            _print(f"{group}:")
            for info in members:
                _print(f"  {info.name:<{width}}  {info.description}")
    return 0


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the program is so that every cleanup (``finally``, temporary files) runs,
    exactly as for Ctrl-C (SIGINT, Python's KeyboardInterrupt)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def _signals_interrupt():
    """SIGTERM and SIGHUP end the command like Ctrl-C, with its cleanup (a signal left ignored stays ignored).

    Only the first one interrupts: a second one while the first unwinds would cut its cleanup short.
    """
    if threading.current_thread() is not threading.main_thread():  # only the main thread may set handlers
        yield
        return
    raised = []

    def interrupt(signum, frame):
        if not raised:
            raised.append(signum)
            raise Interrupted(signum)

    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        signum = getattr(signal, name, None)
        if signum is not None and signal.getsignal(signum) is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, interrupt)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """A Python warning (numpy's RuntimeWarning...) as one log line, not the three of ``warnings``' default;
    lsys3d's own (:class:`~lsys3d.errors.SeedWarning`) as its message alone."""
    if issubclass(category, SeedWarning):
        logging.getLogger("lsys3d").warning("%s", _one_line(str(message)))
        return
    logging.getLogger("lsys3d").warning(
        "warning: %s (%s, %s:%d)", _one_line(str(message)), category.__name__, os.path.basename(filename), lineno
    )


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command(argv) or "")  # no subcommand named: none of their arguments
    args = parser.parse_args(argv)
    from .arrays import small_pages  # numpy, numba: after the parser, so --help and usage errors go without

    small_pages()  # numpy's huge pages stall on this kind of machine; this process is the command line's own
    level = logging.INFO if args.verbose else logging.ERROR if args.quiet else logging.WARNING
    logging.basicConfig(format="lsys3d: %(message)s", level=level)
    with _signals_interrupt(), warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            return args.func(args)
        except LSystemError as exc:
            _print(f"lsys3d: error: {_one_line(str(exc))}", file=sys.stderr)
            return EXIT_USER_ERROR
        except MemoryError:
            _print(
                "lsys3d: error: out of memory; use fewer iterations, or lower --max-modules, --max-segments or "
                "--max-triangles",
                file=sys.stderr,
            )
            return EXIT_USER_ERROR
        except Interrupted as exc:
            _print(f"lsys3d: interrupted ({signal.Signals(exc.signum).name})", file=sys.stderr)
            return 128 + exc.signum
        except KeyboardInterrupt:
            _print("lsys3d: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        except BrokenPipeError:
            return 0


def run() -> None:
    """The ``lsys3d`` program (its console script, ``python -m lsys3d``): :func:`main`, then the process ends
    at once, its output flushed and its exit handlers run, without Python's teardown of every object numba
    and LLVM made (about 0.2 s after a warm ``lsys3d generate``, 0.4 s after a first run's compiling), unless
    a thread other than the main one still runs (then Python ends it as usual).  Call :func:`main` to run a
    command inside a Python process that goes on."""
    code = main() or 0
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # (a reader gone, a stream closed: nothing to write to)
            stream.flush()
    atexit._run_exitfuncs()  # logging's handlers flushed, multiprocessing's children joined: what exit runs
    os._exit(code)


def _one_line(message: str) -> str:
    """An error message on one line, even when it quotes a rule written over several (TOML multi-line strings)."""
    return " ".join(part.strip() for part in message.splitlines() if part.strip())


def _print(*values, file=None) -> None:
    """``print`` for every line the command writes: whatever it echoes from the user (a file name, a preset, a
    golden file's keys) is escaped, so it cannot drive the terminal or fail to encode."""
    print(*(printable(str(v)) for v in values), file=file)
