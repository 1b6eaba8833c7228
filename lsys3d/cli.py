"""The ``lsys3d`` command: each subcommand is a few calls into the public API."""

from __future__ import annotations

import argparse
import json
import logging
import sys

from . import __version__
from .derive import DEFAULT_MAX_MODULES, derive
from .errors import LSystemError
from .presets import DEFAULT_PRESET, describe, list_presets, load
from .stats import skeleton_stats
from .turtle import interpret

EXIT_USER_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def _grammar_args(p: argparse.ArgumentParser, optional: bool = False):
    if optional:
        p.add_argument(
            "grammar", nargs="?", default=DEFAULT_PRESET, help=f"grammar file or preset (default: {DEFAULT_PRESET})"
        )
    else:
        p.add_argument("grammar", help="a grammar file (.toml) or the name of a bundled preset")
    p.add_argument("-n", "--iterations", type=int, default=None, help="number of generations (default: the grammar's)")
    p.add_argument("--seed", type=int, default=None, help="seed of stochastic rules (default: the grammar's)")
    p.add_argument(
        "--max-modules",
        type=int,
        default=DEFAULT_MAX_MODULES,
        help=f"size limit of derivation (default {DEFAULT_MAX_MODULES:,})",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lsys3d", description="Grow 3D plants and fractals from L-systems.")
    parser.add_argument("--version", action="version", version=f"lsys3d {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    parser.add_argument("-v", "--verbose", action="store_true", help="log each stage with its timing")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("derive", help="print the derived module string")
    _grammar_args(p)
    p.set_defaults(func=cmd_derive)

    p = sub.add_parser("stats", help="print counts and extents of the drawn plant")
    _grammar_args(p)
    p.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    p.set_defaults(func=cmd_stats)

    p = sub.add_parser("presets", help="list the bundled presets")
    p.set_defaults(func=cmd_presets)
    return parser


def cmd_derive(args) -> int:
    grammar = load(args.grammar)
    result = derive(grammar, args.iterations, args.seed, max_modules=args.max_modules)
    out = sys.stdout
    out.write(str(result))
    out.write("\n")
    return 0


def cmd_stats(args) -> int:
    grammar = load(args.grammar)
    modules = derive(grammar, args.iterations, args.seed, max_modules=args.max_modules)
    stats = skeleton_stats(modules, interpret(modules, grammar, seed=args.seed))
    print_stats(stats, args.json)
    return 0


def print_stats(stats: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(stats, sort_keys=True))
        return
    width = max(map(len, stats))
    for key, value in stats.items():
        if isinstance(value, float):
            value = f"{value:.6g}"
        elif isinstance(value, list):
            value = "  ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in value)
        print(f"{key:<{width}}  {value}")


def cmd_presets(args) -> int:
    names = list_presets()
    width = max(map(len, names))
    for name in names:
        print(f"{name:<{width}}  {describe(name)}")
    return 0


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(format="lsys3d: %(message)s", level=logging.DEBUG if args.verbose else logging.WARNING)
    try:
        return args.func(args)
    except LSystemError as exc:
        print(f"lsys3d: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("lsys3d: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return 0
